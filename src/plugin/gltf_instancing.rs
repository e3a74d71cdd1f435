//! glTF `EXT_mesh_gpu_instancing` in Bevy scenes. Bevy 0.19's glTF loader ignores the
//! extension and draws a node's mesh once; [`GpuInstancingHandler`], a loader extension,
//! keeps each such node's copies as [`GltfMeshInstances`] on its entity, and
//! [`MultiresScene`](super::MultiresScene) makes a model per copy.

use super::scene::GltfMeshInstances;
use crate::mesh::{LoadLimits, gpu_instances};
use bevy::asset::LoadContext;
use bevy::gltf::GltfLoaderSettings;
use bevy::gltf::extensions::{
    ErasedGltfExtensionHandler, GltfExtensionHandler, GltfExtensionHandlers,
};
use bevy::mesh::MeshVertexAttribute;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::tasks::ConditionalSendFuture;

/// The loader extension: one clone per glTF load.
#[derive(Clone, Default)]
struct GpuInstancingHandler {
    limits: LoadLimits,
    /// The document, kept from the root when it uses the extension (to decode the copies
    /// once the buffers are read).
    document: Option<gltf::Document>,
    /// Per node index, its copies' transforms in its space (decoded with the first
    /// primitive, when Bevy has read the buffers).
    copies: HashMap<usize, Vec<Transform>>,
}

impl GltfExtensionHandler for GpuInstancingHandler {
    fn dyn_clone(&self) -> Box<dyn ErasedGltfExtensionHandler> {
        Box::new(self.clone())
    }

    fn on_root(
        &mut self,
        _load_context: &mut LoadContext<'_>,
        gltf: &gltf::Gltf,
        _settings: &GltfLoaderSettings,
    ) {
        let uses = gltf
            .document
            .extensions_used()
            .any(|name| name == "EXT_mesh_gpu_instancing");
        self.document = uses.then(|| gltf.document.clone());
    }

    fn on_gltf_primitive(
        &mut self,
        load_context: &mut LoadContext<'_>,
        _gltf_document: &gltf::Gltf,
        _gltf_mesh: &gltf::Mesh,
        _gltf_primitive: &gltf::Primitive,
        buffer_data: &[Vec<u8>],
        _custom_vertex_attributes: &HashMap<Box<str>, MeshVertexAttribute>,
        _gltf_mesh_on_skinned_nodes: bool,
        _gltf_mesh_on_non_skinned_nodes: bool,
        _user_mesh: &mut Option<Mesh>,
    ) -> impl ConditionalSendFuture<Output = ()> {
        // Once per file: the document goes once its copies are decoded.
        if let Some(document) = self.document.take() {
            match gpu_instances(&document, buffer_data, &self.limits) {
                Ok(nodes) => {
                    self.copies = nodes
                        .into_iter()
                        .map(|(node, copies)| {
                            let copies = copies.iter().map(|&m| Transform::from_matrix(m));
                            (node, copies.collect())
                        })
                        .collect();
                }
                Err(error) => warn!(
                    "{}: EXT_mesh_gpu_instancing is ignored (each node draws its mesh once): {error}",
                    load_context.path()
                ),
            }
        }
        async {}
    }

    fn on_gltf_node(
        &mut self,
        _load_context: &mut LoadContext<'_>,
        gltf_node: &gltf::Node,
        entity: &mut EntityWorldMut,
    ) {
        if let Some(copies) = self.copies.get(&gltf_node.index()) {
            entity.insert(GltfMeshInstances(copies.clone()));
        }
    }
}

/// Registers the loader extension (with the plugin's load limits) with Bevy's glTF loader,
/// whether its plugin comes before or after this one.
pub(super) fn register(app: &mut App, limits: LoadLimits) {
    app.init_resource::<GltfExtensionHandlers>();
    let handlers = app.world().resource::<GltfExtensionHandlers>().0.clone();
    bevy::tasks::block_on(handlers.write()).push(Box::new(GpuInstancingHandler {
        limits,
        ..default()
    }));
}
