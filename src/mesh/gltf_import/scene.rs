//! The scene walk: skins, and the meshes placed by the node hierarchy with their transforms.

use super::accessors::{Data, type_error};
use super::container::gltf_error;
use crate::mesh::{MeshError, MeshResult};
use glam::{Mat4, Quat, Vec3};
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
#[derive(Clone)]
pub(super) struct Instance<'a> {
    pub(super) mesh: gltf::Mesh<'a>,
    pub(super) skin: Option<usize>,
    /// Mesh space to world space (identity for skinned meshes, whose node transform the
    /// specification says to ignore).
    pub(super) transform: Mat4,
    /// The copies its node places through `EXT_mesh_gpu_instancing` (unskinned nodes).
    pub(super) gpu: Option<GpuInstancing<'a>>,
}

impl<'a> Instance<'a> {
    /// How many times the mesh is placed: once, or once per GPU instance.
    pub(super) fn copies(&self) -> u64 {
        self.gpu.as_ref().map_or(1, |g| g.count as u64)
    }

    /// The instance once per copy, each with its transform: itself, or its node's
    /// transform times each GPU instance's translation, rotation and scale.
    ///
    /// # Errors
    /// An instancing accessor of the wrong type.
    pub(super) fn placements(&self, data: &Data<'_>) -> MeshResult<Vec<Instance<'a>>> {
        let Some(gpu) = &self.gpu else {
            return Ok(vec![self.clone()]);
        };
        let what = |name: &str| format!("nodes[{}] EXT_mesh_gpu_instancing {name}", gpu.node);
        let read3 = |accessor: &Option<gltf::Accessor<'_>>, name: &str, default: Vec3| {
            accessor.as_ref().map_or(Ok(vec![default; gpu.count]), |a| {
                let values = data.read_floats::<3>(a, &what(name))?;
                Ok::<_, MeshError>(values.into_iter().map(Vec3::from).collect())
            })
        };
        let translations = read3(&gpu.translation, "TRANSLATION", Vec3::ZERO)?;
        let scales = read3(&gpu.scale, "SCALE", Vec3::ONE)?;
        let rotations: Vec<Quat> = match &gpu.rotation {
            Some(a) => data
                .read_floats::<4>(a, &what("ROTATION"))?
                .into_iter()
                .map(|q| Quat::from_array(q).normalize())
                .collect(),
            None => vec![Quat::IDENTITY; gpu.count],
        };
        Ok((0..gpu.count)
            .map(|i| {
                let copy =
                    Mat4::from_scale_rotation_translation(scales[i], rotations[i], translations[i]);
                Instance {
                    transform: self.transform * copy,
                    gpu: None,
                    ..self.clone()
                }
            })
            .collect())
    }
}

/// A node's `EXT_mesh_gpu_instancing`: accessors of per-copy translation, rotation and
/// scale (each optional), all of `count` elements.
#[derive(Clone)]
pub(super) struct GpuInstancing<'a> {
    node: usize,
    pub(super) count: usize,
    pub(super) translation: Option<gltf::Accessor<'a>>,
    pub(super) rotation: Option<gltf::Accessor<'a>>,
    pub(super) scale: Option<gltf::Accessor<'a>>,
}

impl GpuInstancing<'_> {
    /// Its accessors.
    pub(super) fn accessors(&self) -> impl Iterator<Item = &gltf::Accessor<'_>> {
        [&self.translation, &self.rotation, &self.scale]
            .into_iter()
            .flatten()
    }
}

/// The name of the glTF extension that places one mesh many times on one node.
pub(super) const GPU_INSTANCING: &str = "EXT_mesh_gpu_instancing";

/// Node `node`'s `EXT_mesh_gpu_instancing`, if it has one.
///
/// # Errors
/// An extension without attributes, naming an accessor the document lacks, of another type
/// than the specification's, or whose accessors differ in count.
pub(super) fn gpu_instancing<'a>(
    document: &'a Document,
    node: &gltf::Node<'a>,
) -> MeshResult<Option<GpuInstancing<'a>>> {
    let Some(extension) = node.extension_value(GPU_INSTANCING) else {
        return Ok(None);
    };
    let n = node.index();
    let at = format!("nodes[{n}].extensions.{GPU_INSTANCING}");
    let attributes = extension
        .get("attributes")
        .and_then(|a| a.as_object())
        .ok_or_else(|| gltf_error(format!("{at}: no attributes")))?;
    let accessor = |name: &str, dimensions: Dimensions| -> MeshResult<_> {
        let Some(index) = attributes.get(name) else {
            return Ok(None);
        };
        let accessor = index
            .as_u64()
            .and_then(|i| document.accessors().nth(usize::try_from(i).ok()?))
            .ok_or_else(|| gltf_error(format!("{at}.attributes.{name}: no accessor {index}")))?;
        if accessor.dimensions() != dimensions {
            return Err(type_error(
                &accessor,
                &format!("{at}.attributes.{name}"),
                &format!("{dimensions:?}"),
            ));
        }
        Ok(Some(accessor))
    };
    let translation = accessor("TRANSLATION", Dimensions::Vec3)?;
    let rotation = accessor("ROTATION", Dimensions::Vec4)?;
    let scale = accessor("SCALE", Dimensions::Vec3)?;
    let counts: Vec<usize> = [&translation, &rotation, &scale]
        .into_iter()
        .flatten()
        .map(gltf::Accessor::count)
        .collect();
    let Some(&count) = counts.first() else {
        return Err(gltf_error(format!(
            "{at}: none of TRANSLATION, ROTATION and SCALE"
        )));
    };
    if counts.iter().any(|&c| c != count) {
        return Err(gltf_error(format!(
            "{at}: its accessors hold {counts:?} elements; they must hold the same number"
        )));
    }
    Ok(Some(GpuInstancing {
        node: n,
        count,
        translation,
        rotation,
        scale,
    }))
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
                gpu: None,
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
                    // A skinned mesh is placed by its joints, not its node.
                    gpu: match skin {
                        Some(_) => None,
                        None => gpu_instancing(document, node)?,
                    },
                });
            }
            let children: Vec<usize> = node.children().map(|c| c.index()).collect();
            stack.extend(children.into_iter().rev().map(|c| (c, world)));
        }
    }
    Ok(instances)
}
