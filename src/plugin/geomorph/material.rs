//! Geomorphs interpolated on the GPU: a material extension whose vertex shaders
//! (`geomorph.wgsl`, `geomorph_prepass.wgsl`, with `geomorph_common.wgsl` beside this file)
//! move each vertex from where its morph started to where it rests, by the render world's
//! clock.
//!
//! A region mesh of a [`GpuGeomorph`] model carries two more vertex attributes,
//! [`ATTRIBUTE_MORPH_FROM`] (the position a morph starts from, and its start time) and
//! [`ATTRIBUTE_MORPH_NORMAL_FROM`] (the normal it starts with, and `1 / T`), and where it has
//! UVs and tangents [`ATTRIBUTE_MORPH_UV_FROM`] and [`ATTRIBUTE_MORPH_TANGENT_FROM`]; its
//! position, normal, UVs and tangent are the morph's ends. The plugin writes a vertex's
//! values once, when a morph starts on it, not each frame it moves. Other attributes (a
//! second UV set, colours, custom ones) are not interpolated here: a moving vertex keeps its
//! own.

use crate::plugin::components::MultiresModel;
use crate::plugin::materials::MultiresMaterialPlugin;
use crate::plugin::sets::AslodSystems;
use bevy::asset::embedded_asset;
use bevy::mesh::{MeshVertexAttribute, MeshVertexBufferLayoutRef};
use bevy::pbr::{
    ExtendedMaterial, MaterialExtension, MaterialExtensionKey, MaterialExtensionPipeline,
    MaterialPlugin,
};
use bevy::prelude::*;
use bevy::render::render_resource::{
    AsBindGroup, RenderPipelineDescriptor, SpecializedMeshPipelineError, VertexFormat,
};
use bevy::shader::{ShaderRef, load_shader_library};

/// Where a morphing vertex started (`xyz`, in the mesh's space) and when (`w`, seconds on
/// the clock of Bevy's `Time`, wrapped as the shaders' `globals.time` is).
pub const ATTRIBUTE_MORPH_FROM: MeshVertexAttribute =
    MeshVertexAttribute::new("Aslod_MorphFrom", 0x0A51_0D01, VertexFormat::Float32x4);

/// The normal a morphing vertex started with (`xyz`), and `1 / T` for its model's morph
/// time `T` (`w`; `0`: at rest).
pub const ATTRIBUTE_MORPH_NORMAL_FROM: MeshVertexAttribute = MeshVertexAttribute::new(
    "Aslod_MorphNormalFrom",
    0x0A51_0D02,
    VertexFormat::Float32x4,
);

/// The first UV set a morphing vertex started with; its end is the mesh's `ATTRIBUTE_UV_0`.
/// Present on meshes with UVs.
pub const ATTRIBUTE_MORPH_UV_FROM: MeshVertexAttribute =
    MeshVertexAttribute::new("Aslod_MorphUvFrom", 0x0A51_0D03, VertexFormat::Float32x2);

/// The tangent a morphing vertex started with (`xyz`; the handedness is the end's, the mesh's
/// `ATTRIBUTE_TANGENT`). Present on meshes with tangents.
pub const ATTRIBUTE_MORPH_TANGENT_FROM: MeshVertexAttribute = MeshVertexAttribute::new(
    "Aslod_MorphTangentFrom",
    0x0A51_0D04,
    VertexFormat::Float32x4,
);

/// The material extension that interpolates geomorphs in the vertex shaders (main pass,
/// prepass, shadows, deferred) of any base material drawn by Bevy's mesh pipeline, such as
/// `StandardMaterial` ([`GeomorphMaterial`]). On meshes without the morph attributes it
/// draws as the base material does.
#[derive(Asset, AsBindGroup, Reflect, Clone, Copy, Debug, Default, PartialEq)]
pub struct GeomorphExtension {}

/// `StandardMaterial` with geomorphs on the GPU: give it to a [`MultiresModel`] with a
/// [`Geomorph`](crate::plugin::Geomorph) (the `base` is the `StandardMaterial` it would have had).
///
/// ```
/// use bevy::prelude::*;
/// use bevy_aslod::plugin::{Geomorph, GeomorphMaterial, MultiresMesh, MultiresModel};
///
/// fn spawn_terrain(
///     commands: &mut Commands,
///     materials: &mut Assets<GeomorphMaterial>,
///     asset: Handle<MultiresMesh>,
/// ) -> Entity {
///     let material = materials.add(GeomorphMaterial {
///         base: StandardMaterial::from_color(Color::srgb(0.6, 0.55, 0.5)),
///         extension: default(),
///     });
///     commands
///         .spawn((MultiresModel(asset), Geomorph::default(), MeshMaterial3d(material)))
///         .id()
/// }
/// # let mut world = World::new();
/// # let mut materials = Assets::<GeomorphMaterial>::default();
/// # let mut queue = bevy::ecs::world::CommandQueue::default();
/// # let model = spawn_terrain(&mut Commands::new(&mut queue, &world), &mut materials, Handle::default());
/// # queue.apply(&mut world);
/// # assert_eq!(world.get::<Geomorph>(model), Some(&Geomorph(0.25)));
/// ```
pub type GeomorphMaterial = ExtendedMaterial<StandardMaterial, GeomorphExtension>;

const SHADER: &str = "embedded://bevy_aslod/plugin/geomorph/geomorph.wgsl";
const PREPASS_SHADER: &str = "embedded://bevy_aslod/plugin/geomorph/geomorph_prepass.wgsl";

impl MaterialExtension for GeomorphExtension {
    fn vertex_shader() -> ShaderRef {
        SHADER.into()
    }

    fn prepass_vertex_shader() -> ShaderRef {
        PREPASS_SHADER.into()
    }

    fn deferred_vertex_shader() -> ShaderRef {
        PREPASS_SHADER.into()
    }

    fn specialize(
        _pipeline: &MaterialExtensionPipeline,
        descriptor: &mut RenderPipelineDescriptor,
        layout: &MeshVertexBufferLayoutRef,
        _key: MaterialExtensionKey<Self>,
    ) -> Result<(), SpecializedMeshPipelineError> {
        let mesh = &layout.0;
        if !(mesh.contains(ATTRIBUTE_MORPH_FROM) && mesh.contains(ATTRIBUTE_MORPH_NORMAL_FROM)) {
            return Ok(());
        }
        // Both passes read the morph at locations 8 and 9, after Bevy's own attributes, and
        // the UVs' and tangents' starts at 10 and 11 where the mesh has them.
        let mut attributes = vec![
            ATTRIBUTE_MORPH_FROM.at_shader_location(8),
            ATTRIBUTE_MORPH_NORMAL_FROM.at_shader_location(9),
        ];
        let mut defs = vec!["ASLOD_GEOMORPH"];
        if mesh.contains(ATTRIBUTE_MORPH_UV_FROM) && mesh.contains(Mesh::ATTRIBUTE_UV_0) {
            attributes.push(ATTRIBUTE_MORPH_UV_FROM.at_shader_location(10));
            defs.push("ASLOD_GEOMORPH_UV");
        }
        if mesh.contains(ATTRIBUTE_MORPH_TANGENT_FROM) && mesh.contains(Mesh::ATTRIBUTE_TANGENT) {
            attributes.push(ATTRIBUTE_MORPH_TANGENT_FROM.at_shader_location(11));
            defs.push("ASLOD_GEOMORPH_TANGENT");
        }
        let morph = mesh.get_layout(&attributes)?;
        if let Some(buffer) = descriptor.vertex.buffers.first_mut() {
            buffer.attributes.extend(morph.attributes);
            let shader_defs = &mut descriptor.vertex.shader_defs;
            shader_defs.extend(defs.into_iter().map(Into::into));
        }
        Ok(())
    }
}

/// Marks a [`MultiresModel`] whose material interpolates geomorphs on the GPU: its region
/// meshes get the morph attributes, and a morph costs one write of its vertices when it
/// starts. [`GeomorphMaterialPlugin`] keeps it on every model with its material; insert it
/// yourself for a material of your own whose vertex shader reads the attributes as
/// `geomorph.wgsl` does. Without it a [`Geomorph`](crate::plugin::Geomorph) model's moving
/// vertices are written from the CPU each frame.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct GpuGeomorph;

/// Draws [`MultiresModel`]s with `ExtendedMaterial<B, GeomorphExtension>`: adds Bevy's
/// `MaterialPlugin` for it (unless added already), a
/// [`MultiresMaterialPlugin`](crate::plugin::MultiresMaterialPlugin), and keeps [`GpuGeomorph`] on
/// the models that have the material. [`AslodPlugin`](crate::plugin::AslodPlugin) adds it for
/// `StandardMaterial` when the app renders with Bevy's `PbrPlugin`.
pub struct GeomorphMaterialPlugin<B: Material>(std::marker::PhantomData<fn() -> B>);

impl<B: Material> Default for GeomorphMaterialPlugin<B> {
    fn default() -> Self {
        Self(std::marker::PhantomData)
    }
}

type M<B> = ExtendedMaterial<B, GeomorphExtension>;

impl<B: Material> Plugin for GeomorphMaterialPlugin<B>
where
    MaterialPlugin<M<B>>: Plugin,
{
    fn build(&self, app: &mut App) {
        if !app.is_plugin_added::<MaterialPlugin<M<B>>>() {
            app.add_plugins(MaterialPlugin::<M<B>>::default());
        }
        if !app.is_plugin_added::<MultiresMaterialPlugin<M<B>>>() {
            app.add_plugins(MultiresMaterialPlugin::<M<B>>::default());
        }
        if !app.world().contains_resource::<ShadersEmbedded>() {
            app.init_resource::<ShadersEmbedded>();
            embed_shaders(app);
        }
        app.register_type::<GpuGeomorph>()
            .add_systems(PostUpdate, mark_gpu_models::<B>.in_set(AslodSystems::Spawn));
    }
}

/// The geomorph shaders are embedded (by the first [`GeomorphMaterialPlugin`]).
#[derive(Resource, Default)]
struct ShadersEmbedded;

/// Embeds the shaders (an app that draws materials only: the shader library is a
/// `Handle<Shader>`).
fn embed_shaders(app: &mut App) {
    load_shader_library!(app, "geomorph_common.wgsl");
    embedded_asset!(app, "geomorph.wgsl");
    embedded_asset!(app, "geomorph_prepass.wgsl");
}

/// Keeps [`GpuGeomorph`] on the models that have the geomorph material `B`.
#[allow(clippy::type_complexity)]
fn mark_gpu_models<B: Material>(
    mut commands: Commands,
    added: Query<Entity, (With<MultiresModel>, Added<MeshMaterial3d<M<B>>>)>,
    mut removed: RemovedComponents<MeshMaterial3d<M<B>>>,
    models: Query<(), With<MultiresModel>>,
) {
    for entity in &added {
        commands.entity(entity).insert(GpuGeomorph);
    }
    for entity in removed.read() {
        if models.contains(entity) {
            commands.entity(entity).remove::<GpuGeomorph>();
        }
    }
}
