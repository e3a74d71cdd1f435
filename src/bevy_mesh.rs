//! Conversion between [`IndexedMesh`] and Bevy's [`Mesh`] (feature `bevy`).
//!
//! The plugin builds its assets from Bevy meshes and hands each region's index buffer back
//! to Bevy as a mesh; these two functions are that boundary.

use crate::mesh::{AttributeFormat, IndexedMesh, MeshError, Scalar, VertexAttribute};
use bevy::asset::RenderAssetUsages;
use bevy::mesh::{
    Indices, Mesh, MeshVertexAttribute, PrimitiveTopology, VertexAttributeValues, VertexFormat,
};
use glam::{Vec2, Vec3, Vec4};
use std::collections::HashMap;
use std::sync::{Mutex, PoisonError};

/// A Bevy mesh with `mesh`'s vertex attributes (every one it has: positions, normals, UVs,
/// tangents, joints and weights, and its further [`VertexAttribute`]s under their own names
/// and ids) and the triangles `indices` (which may be any polygon cache's index buffer over
/// `mesh`'s vertices).
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
    if let Some(tangents) = &mesh.tangents {
        out.insert_attribute(
            Mesh::ATTRIBUTE_TANGENT,
            tangents.iter().map(|t| t.to_array()).collect::<Vec<_>>(),
        );
    }
    if let (Some(joints), Some(weights)) = (&mesh.joints, &mesh.weights) {
        out.insert_attribute(
            Mesh::ATTRIBUTE_JOINT_INDEX,
            VertexAttributeValues::Uint16x4(joints.clone()),
        );
        out.insert_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights.clone());
    }
    for a in &mesh.attributes {
        out.insert_attribute(bevy_attribute(a), values(a.format, &a.data));
    }
    out.insert_indices(Indices::U32(indices.to_vec()));
    out
}

/// An [`IndexedMesh`] from a Bevy triangle-list or triangle-strip mesh: positions, and
/// normals, UVs, tangents, joints and weights where present, and every other attribute
/// (`UV_1`, colours, custom attributes of any format) as a [`VertexAttribute`]. A mesh
/// without indices is read as one triangle per three vertices (a strip: per vertex after the
/// second); a strip becomes a list of the same winding, split at primitive restarts. The
/// result is validated.
///
/// # Errors
/// [`MeshError::Parse`] when the mesh is not a triangle list or strip, has no positions, has a
/// standard attribute in an unexpected format, or its data is only in the render world; any
/// validation error of [`IndexedMesh::validate`].
pub fn from_bevy_mesh(mesh: &Mesh) -> Result<IndexedMesh, MeshError> {
    let fail = |what: &str| MeshError::parse("Bevy mesh", "attributes", what.to_string());
    let topology = mesh.primitive_topology();
    if !matches!(
        topology,
        PrimitiveTopology::TriangleList | PrimitiveTopology::TriangleStrip
    ) {
        return Err(fail(
            "only triangle lists and strips can be multiresolution meshes",
        ));
    }
    let moved = || fail("mesh data was moved to the render world (RenderAssetUsages)");
    let mut out = IndexedMesh::default();
    for (attribute, data) in mesh.try_attributes().map_err(|_| moved())? {
        let wrong = || {
            fail(&format!(
                "{} is {:?}, not {:?}",
                attribute.name,
                VertexFormat::from(data),
                attribute.format
            ))
        };
        match (attribute.id, data) {
            (id, VertexAttributeValues::Float32x3(p)) if id == Mesh::ATTRIBUTE_POSITION.id => {
                out.positions = p.iter().map(|&p| Vec3::from(p)).collect();
            }
            (id, VertexAttributeValues::Float32x3(n)) if id == Mesh::ATTRIBUTE_NORMAL.id => {
                out.normals = Some(n.iter().map(|&n| Vec3::from(n)).collect());
            }
            (id, VertexAttributeValues::Float32x2(uv)) if id == Mesh::ATTRIBUTE_UV_0.id => {
                out.uvs = Some(uv.iter().map(|&uv| Vec2::from(uv)).collect());
            }
            (id, VertexAttributeValues::Float32x4(t)) if id == Mesh::ATTRIBUTE_TANGENT.id => {
                out.tangents = Some(t.iter().map(|&t| Vec4::from(t)).collect());
            }
            (id, VertexAttributeValues::Uint16x4(j)) if id == Mesh::ATTRIBUTE_JOINT_INDEX.id => {
                out.joints = Some(j.clone());
            }
            (id, VertexAttributeValues::Float32x4(w)) if id == Mesh::ATTRIBUTE_JOINT_WEIGHT.id => {
                out.weights = Some(w.clone());
            }
            (id, _)
                if [
                    Mesh::ATTRIBUTE_POSITION.id,
                    Mesh::ATTRIBUTE_NORMAL.id,
                    Mesh::ATTRIBUTE_UV_0.id,
                    Mesh::ATTRIBUTE_TANGENT.id,
                    Mesh::ATTRIBUTE_JOINT_INDEX.id,
                    Mesh::ATTRIBUTE_JOINT_WEIGHT.id,
                ]
                .contains(&id) =>
            {
                return Err(wrong());
            }
            (_, data) => {
                let Some(format) = core_format(VertexFormat::from(data)) else {
                    return Err(fail(&format!(
                        "{} has the format {:?}, which a vertex table cannot hold",
                        attribute.name, attribute.format
                    )));
                };
                out.attributes.push(VertexAttribute {
                    name: attribute.name.to_string(),
                    id: attribute_id(attribute),
                    format,
                    data: data.get_bytes().to_vec(),
                });
            }
        }
    }
    if out.positions.is_empty() && mesh.attribute(Mesh::ATTRIBUTE_POSITION).is_none() {
        return Err(fail("the mesh has no POSITION attribute"));
    }
    // Bevy keeps attributes sorted by id; the table keeps that order.
    out.attributes.sort_by_key(|a| a.id);
    let n = mesh.count_vertices();
    let (indices, restart) = match mesh.try_indices_option().map_err(|_| moved())? {
        Some(Indices::U16(i)) => (
            i.iter().map(|&i| u32::from(i)).collect(),
            u32::from(u16::MAX),
        ),
        Some(Indices::U32(i)) => (i.clone(), u32::MAX),
        None => ((0..n as u32).collect(), u32::MAX),
    };
    out.indices = if topology == PrimitiveTopology::TriangleStrip {
        strip_to_list(&indices, restart)
    } else {
        indices
    };
    out.validate()?;
    Ok(out)
}

/// A triangle strip's triangles as a list: one per three consecutive indices, every second
/// one with its first two corners swapped so that all keep the strip's winding, runs split
/// at the primitive-restart value `restart`. Triangles that repeat a vertex (strips use them
/// to turn) stay, for validation to drop.
fn strip_to_list(strip: &[u32], restart: u32) -> Vec<u32> {
    let mut out = Vec::with_capacity(strip.len().saturating_sub(2) * 3);
    for run in strip.split(|&i| i == restart) {
        for (k, w) in run.windows(3).enumerate() {
            if k % 2 == 0 {
                out.extend_from_slice(&[w[0], w[1], w[2]]);
            } else {
                out.extend_from_slice(&[w[1], w[0], w[2]]);
            }
        }
    }
    out
}

/// The triangles a Bevy mesh draws: a list's indices (or vertices) over three, a strip's two
/// fewer than each run between primitive restarts, none for lines and points. What the plugin
/// counts for a conventional mesh in the budget.
#[must_use]
pub fn drawn_triangles(mesh: &Mesh) -> u64 {
    /// Each run between restarts draws its length less two.
    fn strip<T: PartialEq>(indices: &[T], restart: T) -> u64 {
        indices
            .split(|i| *i == restart)
            .map(|run| run.len().saturating_sub(2) as u64)
            .sum()
    }
    let vertices = mesh.count_vertices();
    match (mesh.primitive_topology(), mesh.indices()) {
        (PrimitiveTopology::TriangleList, Some(i)) => (i.len() / 3) as u64,
        (PrimitiveTopology::TriangleList, None) => (vertices / 3) as u64,
        (PrimitiveTopology::TriangleStrip, Some(Indices::U16(i))) => strip(i, u16::MAX),
        (PrimitiveTopology::TriangleStrip, Some(Indices::U32(i))) => strip(i, u32::MAX),
        (PrimitiveTopology::TriangleStrip, None) => vertices.saturating_sub(2) as u64,
        _ => 0,
    }
}

/// Bevy's numeric id of an attribute (`MeshVertexAttributeId` keeps it private; its order is
/// the id's, and the standard attributes' ids are their documented constants).
fn attribute_id(attribute: &MeshVertexAttribute) -> u64 {
    let probe = |id| MeshVertexAttribute::new("", id, attribute.format).id;
    // Ids can be compared but not read: bisection over u64 finds it in 64 comparisons.
    let (mut lo, mut hi) = (0u64, u64::MAX);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if probe(mid) < attribute.id {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The Bevy attribute of a further attribute: its name (interned: Bevy names attributes with
/// `&'static str`, so each distinct name is kept once for the life of the process), id and
/// format.
pub(crate) fn bevy_attribute(a: &VertexAttribute) -> MeshVertexAttribute {
    static NAMES: Mutex<Option<HashMap<String, &'static str>>> = Mutex::new(None);
    let mut names = NAMES.lock().unwrap_or_else(PoisonError::into_inner);
    let name = *names
        .get_or_insert_with(HashMap::new)
        .entry(a.name.clone())
        .or_insert_with(|| Box::leak(a.name.clone().into_boxed_str()));
    MeshVertexAttribute::new(name, a.id, bevy_format(a.format))
}

/// Bevy's vertex format of an attribute format, and back; and an attribute's values from its
/// bytes. One table, so the three cannot disagree.
macro_rules! formats {
    ($($scalar:ident $n:literal $format:ident $t:ty;)*) => {
        fn bevy_format(f: AttributeFormat) -> VertexFormat {
            match (f.scalar, f.components) {
                $((Scalar::$scalar, $n) => VertexFormat::$format,)*
                // Validated tables have 1 to 4 components; 3 exists only for 32-bit scalars.
                _ => VertexFormat::Float32x4,
            }
        }

        fn core_format(f: VertexFormat) -> Option<AttributeFormat> {
            match f {
                $(VertexFormat::$format => Some(AttributeFormat {
                    scalar: Scalar::$scalar,
                    components: $n,
                }),)*
                _ => None,
            }
        }

        fn values(f: AttributeFormat, bytes: &[u8]) -> VertexAttributeValues {
            match (f.scalar, f.components) {
                $((Scalar::$scalar, $n) => {
                    VertexAttributeValues::$format(bytemuck::pod_collect_to_vec::<u8, $t>(bytes))
                })*
                _ => VertexAttributeValues::Uint8x4(bytemuck::pod_collect_to_vec(bytes)),
            }
        }
    };
}

formats! {
    F32 1 Float32 f32; F32 2 Float32x2 [f32; 2]; F32 3 Float32x3 [f32; 3]; F32 4 Float32x4 [f32; 4];
    F16 1 Float16 half::f16; F16 2 Float16x2 [half::f16; 2]; F16 4 Float16x4 [half::f16; 4];
    U32 1 Uint32 u32; U32 2 Uint32x2 [u32; 2]; U32 3 Uint32x3 [u32; 3]; U32 4 Uint32x4 [u32; 4];
    I32 1 Sint32 i32; I32 2 Sint32x2 [i32; 2]; I32 3 Sint32x3 [i32; 3]; I32 4 Sint32x4 [i32; 4];
    U16 1 Uint16 u16; U16 2 Uint16x2 [u16; 2]; U16 4 Uint16x4 [u16; 4];
    I16 1 Sint16 i16; I16 2 Sint16x2 [i16; 2]; I16 4 Sint16x4 [i16; 4];
    Unorm16 1 Unorm16 u16; Unorm16 2 Unorm16x2 [u16; 2]; Unorm16 4 Unorm16x4 [u16; 4];
    Snorm16 1 Snorm16 i16; Snorm16 2 Snorm16x2 [i16; 2]; Snorm16 4 Snorm16x4 [i16; 4];
    U8 1 Uint8 u8; U8 2 Uint8x2 [u8; 2]; U8 4 Uint8x4 [u8; 4];
    I8 1 Sint8 i8; I8 2 Sint8x2 [i8; 2]; I8 4 Sint8x4 [i8; 4];
    Unorm8 1 Unorm8 u8; Unorm8 2 Unorm8x2 [u8; 2]; Unorm8 4 Unorm8x4 [u8; 4];
    Snorm8 1 Snorm8 i8; Snorm8 2 Snorm8x2 [i8; 2]; Snorm8 4 Snorm8x4 [i8; 4];
    F64 1 Float64 f64; F64 2 Float64x2 [f64; 2]; F64 3 Float64x3 [f64; 3]; F64 4 Float64x4 [f64; 4];
    Bgra8 4 Unorm8x4Bgra [u8; 4];
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit square of four vertices in the XY plane, without indices.
    fn quad(topology: PrimitiveTopology) -> Mesh {
        Mesh::new(topology, RenderAssetUsages::default()).with_inserted_attribute(
            Mesh::ATTRIBUTE_POSITION,
            vec![
                [0.0f32, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.0],
            ],
        )
    }

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

    /// Every format a Bevy attribute can have goes through an `IndexedMesh` and back, under
    /// its own name and id, with the same bytes; so do tangents, `UV_1` and colours.
    #[test]
    fn every_attribute_format_round_trips() {
        use bevy::mesh::VertexAttributeValues as V;
        let n = 4;
        let f = |k: usize| (0..n).map(move |i| (i * 10 + k) as f32 * 0.5);
        let custom: Vec<V> = vec![
            V::Float32(f(0).collect()),
            V::Float32x3(f(1).map(|x| [x, -x, 1.0]).collect()),
            V::Float16x2(f(2).map(|x| [half::f16::from_f32(x); 2]).collect()),
            V::Float16x4(f(2).map(|x| [half::f16::from_f32(x); 4]).collect()),
            V::Uint32x2((0..n as u32).map(|i| [i, i + 7]).collect()),
            V::Sint32x4((0..n as i32).map(|i| [i, -i, 3, 4]).collect()),
            V::Uint16x2((0..n as u16).map(|i| [i, 9]).collect()),
            V::Snorm16x4((0..n as i16).map(|i| [i, -i, 0, 1]).collect()),
            V::Uint8x4((0..n as u8).map(|i| [i, 1, 2, 3]).collect()),
            V::Unorm8x4((0..n as u8).map(|i| [i, 255, 0, 9]).collect()),
            V::Sint8x2((0..n as i8).map(|i| [i, -i]).collect()),
            V::Float64x3((0..n).map(|i| [i as f64, 0.25, -1.0]).collect()),
            V::Unorm8x4Bgra((0..n as u8).map(|i| [i, 9, 8, 7]).collect()),
        ];
        let mut bevy_mesh = quad(PrimitiveTopology::TriangleList)
            .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 0.0, 1.0]; n])
            .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, vec![[0.5f32, 0.5]; n])
            .with_inserted_attribute(Mesh::ATTRIBUTE_UV_1, vec![[0.25f32, 0.75]; n])
            .with_inserted_attribute(Mesh::ATTRIBUTE_TANGENT, vec![[1.0f32, 0.0, 0.0, -1.0]; n])
            .with_inserted_attribute(Mesh::ATTRIBUTE_COLOR, vec![[1.0f32, 0.5, 0.25, 1.0]; n])
            .with_inserted_indices(Indices::U16(vec![0, 1, 2, 2, 1, 3]));
        for (k, values) in custom.into_iter().enumerate() {
            let name: &'static str = Box::leak(format!("Vertex_Custom{k}").into_boxed_str());
            let attribute = MeshVertexAttribute::new(
                name,
                1_000 + k as u64 * 7_919,
                VertexFormat::from(&values),
            );
            bevy_mesh.insert_attribute(attribute, values);
        }
        let indexed = from_bevy_mesh(&bevy_mesh).expect("every format converts");
        assert_eq!(
            indexed.attributes.len(),
            15,
            "13 custom attributes, UV_1 and colours"
        );
        assert!(indexed.tangents.is_some());
        let back = to_bevy_mesh(&indexed, &indexed.indices);
        let ours: Vec<_> = back
            .attributes()
            .map(|(a, v)| (a.id, a.name, a.format, v.get_bytes().to_vec()))
            .collect();
        let theirs: Vec<_> = bevy_mesh
            .attributes()
            .map(|(a, v)| (a.id, a.name, a.format, v.get_bytes().to_vec()))
            .collect();
        assert_eq!(ours, theirs);
        // A subset of the vertices (as a level is) keeps each vertex's bytes.
        let sub = indexed.subset(&[3, 1]);
        for (a, b) in sub.attributes.iter().zip(&indexed.attributes) {
            assert_eq!(a.record(0), b.record(3), "{}", a.name);
            assert_eq!(a.record(1), b.record(1), "{}", a.name);
        }
    }

    /// Tangents made by the core are Bevy's: the same MikkTSpace tangents, with the same
    /// handedness, as `Mesh::generate_tangents` gives the same triangles.
    #[test]
    fn tangents_are_made_as_bevy_makes_them() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shared/testdata/textured/WaterBottle.glb"
        );
        let mut mesh = crate::mesh::load_gltf(std::path::Path::new(path))
            .expect("WaterBottle imports")
            .mesh;
        mesh.tangents = None;
        let mut bevy_mesh = to_bevy_mesh(&mesh, &mesh.indices);
        bevy_mesh.generate_tangents().expect("Bevy makes tangents");
        mesh.generate_tangents().expect("the core makes tangents");
        let Some(VertexAttributeValues::Float32x4(theirs)) =
            bevy_mesh.attribute(Mesh::ATTRIBUTE_TANGENT)
        else {
            panic!("Bevy's tangents");
        };
        let ours: Vec<[f32; 4]> = mesh
            .tangents
            .unwrap()
            .iter()
            .map(|t| t.to_array())
            .collect();
        assert_eq!(&ours, theirs);
    }

    #[test]
    fn line_lists_are_rejected() {
        let lines = Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default())
            .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; 2]);
        let err = from_bevy_mesh(&lines).unwrap_err();
        assert!(err.to_string().contains("triangle lists"), "{err}");
    }

    #[test]
    fn strips_become_lists_and_count_as_drawn() {
        let quad = |topology, indices: Option<Indices>| {
            let mut mesh = quad(topology);
            if let Some(indices) = indices {
                mesh.insert_indices(indices);
            }
            mesh
        };
        // A strip of four vertices: two triangles, both facing +Z like the list's.
        let strip = quad(PrimitiveTopology::TriangleStrip, None);
        let list = quad(
            PrimitiveTopology::TriangleList,
            Some(Indices::U16(vec![0, 1, 2, 2, 1, 3])),
        );
        let (from_strip, from_list) = (
            from_bevy_mesh(&strip).unwrap(),
            from_bevy_mesh(&list).unwrap(),
        );
        assert_eq!(from_strip.indices, vec![0, 1, 2, 2, 1, 3]);
        assert_eq!(from_strip.indices, from_list.indices);
        // Restarts split runs; counts follow what the GPU draws.
        let restarted = quad(
            PrimitiveTopology::TriangleStrip,
            Some(Indices::U16(vec![0, 1, 2, u16::MAX, 1, 3, 2])),
        );
        assert_eq!(
            from_bevy_mesh(&restarted).unwrap().indices,
            vec![0, 1, 2, 1, 3, 2]
        );
        assert_eq!(drawn_triangles(&strip), 2);
        assert_eq!(drawn_triangles(&restarted), 2);
        assert_eq!(drawn_triangles(&list), 2);
        for topology in [
            PrimitiveTopology::LineList,
            PrimitiveTopology::LineStrip,
            PrimitiveTopology::PointList,
        ] {
            let mesh = quad(topology, Some(Indices::U16(vec![0, 1, 2, 3, 0, 2])));
            assert_eq!(drawn_triangles(&mesh), 0, "{topology:?}");
            assert!(from_bevy_mesh(&mesh).is_err());
        }
    }
}
