//! The `textured` example's custom attribute, read by a material: `_TINT`, a brightness per
//! vertex, which [`TintMaterial`] (`StandardMaterial` with the vertex shader in `tint.wgsl`
//! beside this file) multiplies into the vertex colour. The generated sphere carries it,
//! so its pixels show whether every path kept it.

use bevy::asset::uuid_handle;
use bevy::gltf::GltfPlugin;
use bevy::mesh::{MeshVertexAttribute, MeshVertexBufferLayoutRef};
use bevy::pbr::{
    ExtendedMaterial, MaterialExtension, MaterialExtensionKey, MaterialExtensionPipeline,
};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::render_resource::{
    AsBindGroup, RenderPipelineDescriptor, SpecializedMeshPipelineError, VertexFormat,
};
use bevy::shader::ShaderRef;
use bevy_aslod::plugin::MultiresMaterialPlugin;

/// The custom attribute, as Bevy names it.
pub const ATTRIBUTE_TINT: MeshVertexAttribute =
    MeshVertexAttribute::new("Vertex_Tint", 0x7E57_0001, VertexFormat::Float32);

/// Its name in the glTF file.
pub const GLTF_TINT: &str = "_TINT";

const SHADER: Handle<Shader> = uuid_handle!("6a0e5c2e-3f4b-4d8e-9a61-2b7d0c9e4f11");

/// The material extension that reads the tint.
#[derive(Asset, AsBindGroup, Reflect, Clone, Copy, Debug, Default)]
pub struct TintExtension {}

/// `StandardMaterial` whose vertex colour takes the tint.
pub type TintMaterial = ExtendedMaterial<StandardMaterial, TintExtension>;

impl MaterialExtension for TintExtension {
    fn vertex_shader() -> ShaderRef {
        SHADER.into()
    }

    fn specialize(
        _pipeline: &MaterialExtensionPipeline,
        descriptor: &mut RenderPipelineDescriptor,
        layout: &MeshVertexBufferLayoutRef,
        _key: MaterialExtensionKey<Self>,
    ) -> Result<(), SpecializedMeshPipelineError> {
        if !layout.0.contains(ATTRIBUTE_TINT) {
            return Ok(());
        }
        let tint = layout
            .0
            .get_layout(&[ATTRIBUTE_TINT.at_shader_location(12)])?;
        if let Some(buffer) = descriptor.vertex.buffers.first_mut() {
            buffer.attributes.extend(tint.attributes);
            descriptor.vertex.shader_defs.push("TINT".into());
        }
        Ok(())
    }
}

/// The glTF loader that knows `_TINT`. The `gltf` crate hands Bevy the name without its
/// leading underscore, which is the name Bevy matches.
pub fn gltf_plugin() -> GltfPlugin {
    GltfPlugin::default().add_custom_vertex_attribute(&GLTF_TINT[1..], ATTRIBUTE_TINT)
}

/// Adds the material (for plain meshes and for multiresolution models) and its shader, and a
/// system that draws every `StandardMaterial` mesh with the tint instead.
pub fn add_tint(app: &mut App) {
    app.add_plugins((
        MaterialPlugin::<TintMaterial>::default(),
        MultiresMaterialPlugin::<TintMaterial>::default(),
    ));
    let source = include_str!("tint.wgsl");
    let _ = app
        .world_mut()
        .resource_mut::<Assets<Shader>>()
        .insert(&SHADER, Shader::from_wgsl(source, file!()));
    app.init_resource::<Tinted>()
        .add_systems(PreUpdate, use_tint);
}

/// Each `StandardMaterial` and its tinted twin.
#[derive(Resource, Default)]
struct Tinted(HashMap<AssetId<StandardMaterial>, Handle<TintMaterial>>);

/// Swaps every entity's `StandardMaterial` for its tinted twin.
fn use_tint(
    mut commands: Commands,
    standard: Query<(Entity, &MeshMaterial3d<StandardMaterial>)>,
    bases: Res<Assets<StandardMaterial>>,
    mut tinted: ResMut<Assets<TintMaterial>>,
    mut twins: ResMut<Tinted>,
) {
    for (entity, material) in &standard {
        let Some(base) = bases.get(&material.0) else {
            continue;
        };
        let twin = twins.0.entry(material.0.id()).or_insert_with(|| {
            tinted.add(TintMaterial {
                base: base.clone(),
                extension: TintExtension {},
            })
        });
        commands
            .entity(entity)
            .remove::<MeshMaterial3d<StandardMaterial>>()
            .insert(MeshMaterial3d(twin.clone()));
    }
}
