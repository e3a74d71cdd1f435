//! Conversion between [`IndexedMesh`] and Bevy's [`Mesh`] (feature `bevy`).
//!
//! The plugin builds its assets from Bevy meshes and hands each region's index buffer back
//! to Bevy as a mesh; these two functions are that boundary.

use crate::mesh::{IndexedMesh, MeshError};
use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues};
use glam::{Vec2, Vec3};

/// A Bevy mesh with `mesh`'s vertex attributes and the triangles `indices` (which may be any
/// polygon cache's index buffer over `mesh`'s vertices).
///
/// The mesh keeps its data in the main world too, so its indices can be rewritten when the
/// level of detail changes.
#[must_use]
pub fn to_bevy_mesh(mesh: &IndexedMesh, indices: &[u32]) -> Mesh {
    let mut out = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::MAIN_WORLD | RenderAssetUsages::RENDER_WORLD,
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        mesh.positions
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
    );
    if let Some(normals) = &mesh.normals {
        out.insert_attribute(
            Mesh::ATTRIBUTE_NORMAL,
            normals.iter().map(|n| n.to_array()).collect::<Vec<_>>(),
        );
    }
    if let Some(uvs) = &mesh.uvs {
        out.insert_attribute(
            Mesh::ATTRIBUTE_UV_0,
            uvs.iter().map(|uv| uv.to_array()).collect::<Vec<_>>(),
        );
    }
    if let (Some(joints), Some(weights)) = (&mesh.joints, &mesh.weights) {
        out.insert_attribute(
            Mesh::ATTRIBUTE_JOINT_INDEX,
            VertexAttributeValues::Uint16x4(joints.clone()),
        );
        out.insert_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights.clone());
    }
    out.insert_indices(Indices::U32(indices.to_vec()));
    out
}

/// An [`IndexedMesh`] from a Bevy triangle-list mesh (positions, and normals, UVs, joints and
/// weights where present). A mesh without indices is read as one triangle per three
/// vertices. The result is validated.
///
/// # Errors
/// [`MeshError::Parse`] when the mesh is not a triangle list, has no positions, has an
/// attribute in an unexpected format, or its data is only in the render world; any
/// validation error of [`IndexedMesh::validate`].
pub fn from_bevy_mesh(mesh: &Mesh) -> Result<IndexedMesh, MeshError> {
    let fail = |what: &str| MeshError::parse("Bevy mesh", "attributes", what.to_string());
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(fail("only triangle lists can be multiresolution meshes"));
    }
    let attribute = |id| {
        mesh.try_attribute_option(id)
            .map_err(|_| fail("mesh data was moved to the render world (RenderAssetUsages)"))
    };
    let positions = match attribute(Mesh::ATTRIBUTE_POSITION.id)? {
        Some(VertexAttributeValues::Float32x3(p)) => p.iter().map(|&p| Vec3::from(p)).collect(),
        Some(_) => return Err(fail("POSITION is not Float32x3")),
        None => return Err(fail("the mesh has no POSITION attribute")),
    };
    let normals = match attribute(Mesh::ATTRIBUTE_NORMAL.id)? {
        Some(VertexAttributeValues::Float32x3(n)) => {
            Some(n.iter().map(|&n| Vec3::from(n)).collect())
        }
        Some(_) => return Err(fail("NORMAL is not Float32x3")),
        None => None,
    };
    let uvs = match attribute(Mesh::ATTRIBUTE_UV_0.id)? {
        Some(VertexAttributeValues::Float32x2(uv)) => {
            Some(uv.iter().map(|&uv| Vec2::from(uv)).collect())
        }
        Some(_) => return Err(fail("UV_0 is not Float32x2")),
        None => None,
    };
    let joints = match attribute(Mesh::ATTRIBUTE_JOINT_INDEX.id)? {
        Some(VertexAttributeValues::Uint16x4(j)) => Some(j.clone()),
        Some(_) => return Err(fail("JOINT_INDEX is not Uint16x4")),
        None => None,
    };
    let weights = match attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT.id)? {
        Some(VertexAttributeValues::Float32x4(w)) => Some(w.clone()),
        Some(_) => return Err(fail("JOINT_WEIGHT is not Float32x4")),
        None => None,
    };
    let n = mesh.count_vertices();
    let indices = match mesh
        .try_indices_option()
        .map_err(|_| fail("mesh data was moved to the render world (RenderAssetUsages)"))?
    {
        Some(Indices::U16(i)) => i.iter().map(|&i| u32::from(i)).collect(),
        Some(Indices::U32(i)) => i.clone(),
        None => (0..n as u32).collect(),
    };
    let mut out = IndexedMesh {
        positions,
        normals,
        uvs,
        joints,
        weights,
        indices,
    };
    out.validate()?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_attributes_and_triangles() {
        let mut mesh = IndexedMesh::new(
            vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE],
            vec![0, 1, 2, 2, 1, 3],
        );
        mesh.normals = Some(vec![Vec3::Z; 4]);
        mesh.uvs = Some(vec![Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE]);
        let bevy_mesh = to_bevy_mesh(&mesh, &mesh.indices);
        assert_eq!(from_bevy_mesh(&bevy_mesh).unwrap(), mesh);
    }

    #[test]
    fn line_lists_are_rejected() {
        let lines = Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default())
            .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; 2]);
        let err = from_bevy_mesh(&lines).unwrap_err();
        assert!(err.to_string().contains("triangle lists"), "{err}");
    }
}
