//! The scene walk: skins, and the meshes placed by the node hierarchy with their transforms.

use super::accessors::{Data, type_error};
use super::container::gltf_error;
use crate::mesh::MeshResult;
use glam::Mat4;
use gltf::Document;
use gltf::accessor::{DataType, Dimensions};

/// A glTF skin: the joints that deform a skinned mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfSkinInfo {
    /// The skin's name, if the file gives one.
    pub name: Option<String>,
    /// The joints, as indices of glTF nodes; a vertex's joint `j` is node `joints[j]`.
    pub joints: Vec<usize>,
    /// One inverse bind matrix per joint (identity when the file gives none).
    pub inverse_bind_matrices: Vec<Mat4>,
    /// The joint nodes' names, in joint order (empty for an unnamed node).
    pub joint_names: Vec<String>,
}

pub(super) fn read_skin(data: &Data<'_>, skin: &gltf::Skin<'_>) -> MeshResult<GltfSkinInfo> {
    let s = skin.index();
    let joints: Vec<usize> = skin.joints().map(|node| node.index()).collect();
    if joints.is_empty() {
        return Err(gltf_error(format!(
            "skins[{s}].joints: the joint list is empty; a skin needs at least one joint"
        )));
    }
    let inverse_bind_matrices = match skin.inverse_bind_matrices() {
        None => vec![Mat4::IDENTITY; joints.len()],
        Some(accessor) => {
            let what = format!("skins[{s}].inverseBindMatrices");
            if accessor.dimensions() != Dimensions::Mat4 || accessor.data_type() != DataType::F32 {
                return Err(type_error(&accessor, &what, "MAT4 of F32"));
            }
            let mut matrices: Vec<Mat4> = data
                .read_floats::<16>(&accessor, &what)?
                .iter()
                .map(Mat4::from_cols_array)
                .collect();
            if matrices.len() < joints.len() {
                return Err(gltf_error(format!(
                    "{what}: {} matrices for {} joints",
                    matrices.len(),
                    joints.len()
                )));
            }
            matrices.truncate(joints.len());
            matrices
        }
    };
    let joint_names = skin
        .joints()
        .map(|node| node.name().unwrap_or_default().to_owned())
        .collect();
    Ok(GltfSkinInfo {
        name: skin.name().map(str::to_owned),
        joints,
        inverse_bind_matrices,
        joint_names,
    })
}

/// One mesh placed in the scene.
pub(super) struct Instance<'a> {
    pub(super) mesh: gltf::Mesh<'a>,
    pub(super) skin: Option<usize>,
    /// Mesh space to world space (identity for skinned meshes, whose node transform the
    /// specification says to ignore).
    pub(super) transform: Mat4,
}

pub(super) fn collect_instances(document: &Document) -> MeshResult<Vec<Instance<'_>>> {
    let node_count = document.nodes().len();
    let traversals: Vec<Vec<usize>> = if let Some(scene) = document.default_scene() {
        vec![scene.nodes().map(|n| n.index()).collect()]
    } else if document.scenes().len() > 0 {
        document
            .scenes()
            .map(|scene| scene.nodes().map(|n| n.index()).collect())
            .collect()
    } else if node_count > 0 {
        let mut is_child = vec![false; node_count];
        for node in document.nodes() {
            for child in node.children() {
                is_child[child.index()] = true;
            }
        }
        vec![(0..node_count).filter(|&n| !is_child[n]).collect()]
    } else {
        return Ok(document
            .meshes()
            .map(|mesh| Instance {
                mesh,
                skin: None,
                transform: Mat4::IDENTITY,
            })
            .collect());
    };

    let nodes: Vec<gltf::Node<'_>> = document.nodes().collect();
    let mut instances = Vec::new();
    for roots in traversals {
        // A node reached twice means a cycle (or a shared child); either would repeat forever
        // or duplicate geometry, and both are invalid glTF.
        let mut visited = vec![false; node_count];
        let mut stack: Vec<(usize, Mat4)> =
            roots.iter().rev().map(|&n| (n, Mat4::IDENTITY)).collect();
        while let Some((n, parent)) = stack.pop() {
            if std::mem::replace(&mut visited[n], true) {
                return Err(gltf_error(format!(
                    "nodes[{n}]: reached twice from the scene roots (a cycle or a node with two \
                     parents)"
                )));
            }
            let node = &nodes[n];
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            if let Some(mesh) = node.mesh() {
                let skin = node.skin().map(|s| s.index());
                instances.push(Instance {
                    mesh,
                    skin,
                    transform: if skin.is_some() {
                        Mat4::IDENTITY
                    } else {
                        world
                    },
                });
            }
            let children: Vec<usize> = node.children().map(|c| c.index()).collect();
            stack.extend(children.into_iter().rev().map(|c| (c, world)));
        }
    }
    Ok(instances)
}
