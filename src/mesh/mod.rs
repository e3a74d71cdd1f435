//! Indexed triangle meshes: the input of every other module.
//!
//! An [`IndexedMesh`] is a vertex table (positions plus optional normals, UVs, tangents, skin
//! joints/weights and any further [`VertexAttribute`]s, all of equal length) and a `u32` index buffer of triangles. Importers for
//! OBJ, PLY and glTF/GLB live in the submodules; [`IndexedMesh::validate`] checks the invariants
//! every importer guarantees, and returns a [`MeshError`] that names the defect and where it is.
//!
//! Conventions: right-handed, Y up (Bevy's), counter-clockwise front faces. Counts are triangle
//! counts, never index counts, unless a name says `index`.

mod attributes;
mod error;
mod gltf_import;
mod limits;
mod obj;
mod ply;
mod tangents;
mod vertex_cache;
pub(crate) mod weld;

pub(crate) use attributes::gather_all;
pub use attributes::{
    AttributeFormat, COLOR_ID, STANDARD_IDS, Scalar, TANGENT_ID, UV_1_ID, VertexAttribute,
};
pub use error::{MeshError, MeshResult};
#[cfg(feature = "gltf_instancing")]
pub(crate) use gltf_import::gpu_instances;
pub use gltf_import::{
    GltfImport, GltfPrimitive, GltfSkinInfo, load_gltf, load_gltf_primitives,
    load_gltf_primitives_with_limits, load_gltf_slice, load_gltf_slice_with_limits,
    load_gltf_with_limits,
};
pub use limits::LoadLimits;
pub use obj::{
    MAX_CONCAVE_CORNERS, load_obj, parse_obj, parse_obj_with_limits, write_obj, write_obj_groups,
};
pub use ply::{load_ply, parse_ply, parse_ply_with_limits};
pub use vertex_cache::{optimize_vertex_cache, vertex_cache_misses};
pub use weld::{WeldMap, weld_positions, weld_positions_within};

use glam::{Vec2, Vec3, Vec4};
use std::path::Path;

/// The largest position coordinate (in absolute value) [`IndexedMesh::validate`] accepts:
/// squared distances of larger ones leave `f32`'s range, and every cost built on them with it.
pub const MAX_COORDINATE: f32 = 1e18;

/// An indexed triangle mesh with optional per-vertex attributes.
///
/// Every attribute that is present has exactly one entry per position. Triangles are three
/// consecutive entries of [`indices`](Self::indices), counter-clockwise when seen from the
/// front.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IndexedMesh {
    /// Vertex positions. Must be finite.
    pub positions: Vec<Vec3>,
    /// Optional vertex normals, one per position.
    pub normals: Option<Vec<Vec3>>,
    /// Optional texture coordinates (glTF `TEXCOORD_0`), one per position.
    pub uvs: Option<Vec<Vec2>>,
    /// Optional skin joint indices (glTF `JOINTS_0`), up to four influences per vertex.
    pub joints: Option<Vec<[u16; 4]>>,
    /// Optional skin weights (glTF `WEIGHTS_0`), matching [`joints`](Self::joints).
    pub weights: Option<Vec<[f32; 4]>>,
    /// Optional tangents (glTF `TANGENT`, Bevy's `ATTRIBUTE_TANGENT`): `xyz` a unit tangent,
    /// `w` the handedness (±1) of the bitangent `w · normal × tangent`. Skinned like normals.
    pub tangents: Option<Vec<Vec4>>,
    /// Every further attribute (a second UV set, vertex colours, custom attributes), carried
    /// as bytes, each under a distinct id.
    pub attributes: Vec<VertexAttribute>,
    /// Triangle list: `3 * triangle_count()` vertex indices.
    pub indices: Vec<u32>,
}

/// What [`IndexedMesh::validate`] found and fixed on the way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ValidationReport {
    /// Triangles dropped because two or more corners were the same vertex or the triangle had
    /// zero area.
    pub degenerate_triangles_dropped: usize,
}

impl IndexedMesh {
    /// Creates a mesh from positions and triangle indices, with no other attributes.
    ///
    /// The mesh is not validated; call [`validate`](Self::validate) before trusting it.
    #[must_use]
    pub fn new(positions: Vec<Vec3>, indices: Vec<u32>) -> Self {
        Self {
            positions,
            indices,
            ..Self::default()
        }
    }

    /// Number of vertices.
    #[inline]
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles (`indices.len() / 3`).
    #[inline]
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The three vertex indices of triangle `t`.
    ///
    /// # Panics
    /// Panics when `t >= triangle_count()`.
    #[inline]
    #[must_use]
    pub fn triangle(&self, t: usize) -> [u32; 3] {
        [
            self.indices[3 * t],
            self.indices[3 * t + 1],
            self.indices[3 * t + 2],
        ]
    }

    /// Axis-aligned bounds `(min, max)` of the positions, or `None` for an empty mesh.
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
        )
    }

    /// Length of the diagonal of the bounding box (0 for an empty mesh).
    #[must_use]
    pub fn diagonal(&self) -> f32 {
        // In f64: squared f32 extents overflow above about 1.8e19.
        self.bounds().map_or(0.0, |(lo, hi)| {
            (hi.as_dvec3() - lo.as_dvec3()).length() as f32
        })
    }

    /// Checks the mesh invariants and drops degenerate triangles.
    ///
    /// Checks, in this order: the mesh has vertices and triangles, the index count is a multiple
    /// of three, every attribute has one entry per position, every coordinate is finite, every
    /// index is in range (and no position coordinate exceeds [`MAX_COORDINATE`]). Then drops
    /// triangles whose corners repeat a vertex or whose area is
    /// zero, and reports how many. Joint weights are not checked here; skinning validates them.
    ///
    /// # Errors
    /// Returns the first [`MeshError`] found; the mesh is left unchanged in that case.
    ///
    /// # Example
    /// ```
    /// use bevy_aslod::mesh::{IndexedMesh, MeshError};
    /// use glam::Vec3;
    ///
    /// let mut mesh = IndexedMesh::new(
    ///     vec![Vec3::ZERO, Vec3::X, Vec3::Y],
    ///     vec![0, 1, 2, 0, 0, 1],
    /// );
    /// let report = mesh.validate()?;
    /// assert_eq!(report.degenerate_triangles_dropped, 1);
    /// assert_eq!(mesh.triangle_count(), 1);
    ///
    /// let mut broken = IndexedMesh::new(vec![Vec3::ZERO], vec![0, 0, 7]);
    /// assert!(matches!(broken.validate(), Err(MeshError::IndexOutOfRange { index: 7, .. })));
    /// # Ok::<(), MeshError>(())
    /// ```
    pub fn validate(&mut self) -> MeshResult<ValidationReport> {
        let n = self.positions.len();
        if n == 0 || self.indices.is_empty() {
            return Err(MeshError::Empty);
        }
        if !self.indices.len().is_multiple_of(3) {
            return Err(MeshError::IndexCountNotMultipleOfThree {
                count: self.indices.len(),
            });
        }
        let check_len = |attribute: &'static str, len: Option<usize>| match len {
            Some(found) if found != n => Err(MeshError::AttributeCountMismatch {
                attribute,
                expected: n,
                found,
            }),
            _ => Ok(()),
        };
        check_len("NORMAL", self.normals.as_ref().map(Vec::len))?;
        check_len("TEXCOORD_0", self.uvs.as_ref().map(Vec::len))?;
        check_len("JOINTS_0", self.joints.as_ref().map(Vec::len))?;
        check_len("WEIGHTS_0", self.weights.as_ref().map(Vec::len))?;
        check_len("TANGENT", self.tangents.as_ref().map(Vec::len))?;
        self.validate_attributes()?;
        if let Some(vertex) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFiniteCoordinate {
                attribute: "POSITION",
                vertex,
            });
        }
        if let Some(vertex) = self
            .positions
            .iter()
            .position(|p| p.abs().max_element() > MAX_COORDINATE)
        {
            return Err(MeshError::CoordinateOutOfRange {
                vertex,
                value: self.positions[vertex].abs().max_element(),
            });
        }
        if let Some(vertex) = self
            .normals
            .as_ref()
            .and_then(|v| v.iter().position(|p| !p.is_finite()))
        {
            return Err(MeshError::NonFiniteCoordinate {
                attribute: "NORMAL",
                vertex,
            });
        }
        if let Some(vertex) = self
            .uvs
            .as_ref()
            .and_then(|v| v.iter().position(|p| !p.is_finite()))
        {
            return Err(MeshError::NonFiniteCoordinate {
                attribute: "TEXCOORD_0",
                vertex,
            });
        }
        if let Some(vertex) = self
            .tangents
            .as_ref()
            .and_then(|v| v.iter().position(|p| !p.is_finite()))
        {
            return Err(MeshError::NonFiniteCoordinate {
                attribute: "TANGENT",
                vertex,
            });
        }
        if let Some(pos) = self.indices.iter().position(|&i| i as usize >= n) {
            return Err(MeshError::IndexOutOfRange {
                triangle: pos / 3,
                index: self.indices[pos],
                vertex_count: n,
            });
        }
        let before = self.triangle_count();
        let positions = &self.positions;
        let mut kept = Vec::with_capacity(self.indices.len());
        for tri in self.indices.chunks_exact(3) {
            let (a, b, c) = (tri[0], tri[1], tri[2]);
            if a == b || b == c || a == c {
                continue;
            }
            let (pa, pb, pc) = (
                positions[a as usize],
                positions[b as usize],
                positions[c as usize],
            );
            // In f64: the f32 area of a triangle with edges below about 1e-12 underflows to 0.
            let (da, db, dc) = (pa.as_dvec3(), pb.as_dvec3(), pc.as_dvec3());
            if (db - da).cross(dc - da) == glam::DVec3::ZERO {
                continue;
            }
            kept.extend_from_slice(tri);
        }
        let dropped = before - kept.len() / 3;
        if kept.is_empty() {
            return Err(MeshError::AllTrianglesDegenerate { count: before });
        }
        self.indices = kept;
        Ok(ValidationReport {
            degenerate_triangles_dropped: dropped,
        })
    }

    /// The further attribute with Bevy id `id`, if the mesh has it.
    #[must_use]
    pub fn attribute(&self, id: u64) -> Option<&VertexAttribute> {
        self.attributes.iter().find(|a| a.id == id)
    }

    /// The vertex table of `vertices`, in that order, every attribute included, with no
    /// triangles.
    #[must_use]
    pub fn subset(&self, vertices: &[u32]) -> Self {
        fn pick<T: Copy>(v: &Option<Vec<T>>, vertices: &[u32]) -> Option<Vec<T>> {
            v.as_ref()
                .map(|v| vertices.iter().map(|&i| v[i as usize]).collect())
        }
        Self {
            positions: vertices
                .iter()
                .map(|&i| self.positions[i as usize])
                .collect(),
            normals: pick(&self.normals, vertices),
            uvs: pick(&self.uvs, vertices),
            joints: pick(&self.joints, vertices),
            weights: pick(&self.weights, vertices),
            tangents: pick(&self.tangents, vertices),
            attributes: gather_all(&self.attributes, vertices),
            indices: Vec::new(),
        }
    }

    /// The vertex table alone: every attribute, no triangles.
    #[must_use]
    pub fn vertex_table(&self) -> Self {
        Self {
            positions: self.positions.clone(),
            normals: self.normals.clone(),
            uvs: self.uvs.clone(),
            joints: self.joints.clone(),
            weights: self.weights.clone(),
            tangents: self.tangents.clone(),
            attributes: self.attributes.clone(),
            indices: Vec::new(),
        }
    }

    /// Appends `other`'s vertices. Attributes this table does not have are left out, and
    /// ones `other` lacks are zero.
    pub fn append_vertices(&mut self, other: &Self) {
        fn extend<T: Copy + Default>(to: &mut Option<Vec<T>>, from: &Option<Vec<T>>, n: usize) {
            if let Some(to) = to.as_mut() {
                match from {
                    Some(from) => to.extend_from_slice(from),
                    None => to.resize(to.len() + n, T::default()),
                }
            }
        }
        let n = other.positions.len();
        self.positions.extend_from_slice(&other.positions);
        extend(&mut self.normals, &other.normals, n);
        extend(&mut self.uvs, &other.uvs, n);
        extend(&mut self.joints, &other.joints, n);
        extend(&mut self.weights, &other.weights, n);
        extend(&mut self.tangents, &other.tangents, n);
        for a in &mut self.attributes {
            let size = a.format.size();
            match other.attribute(a.id).filter(|b| b.format == a.format) {
                Some(b) => a.data.extend_from_slice(&b.data),
                None => a.data.resize(a.data.len() + n * size, 0),
            }
        }
    }

    /// Bytes of the vertex attributes and the index buffer.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        let n = self.vertex_count();
        n * 12
            + self.normals.as_ref().map_or(0, |_| n * 12)
            + self.uvs.as_ref().map_or(0, |_| n * 8)
            + self.joints.as_ref().map_or(0, |_| n * 8)
            + self.weights.as_ref().map_or(0, |_| n * 16)
            + self.tangents.as_ref().map_or(0, |_| n * 16)
            + self.attributes.iter().map(|a| a.data.len()).sum::<usize>()
            + self.indices.len() * 4
    }

    /// Checks a vertex table without triangles (as files store it): one entry per position in
    /// every attribute, and the further attributes as [`validate`](Self::validate) does.
    pub(crate) fn validate_vertex_table(&self) -> MeshResult<()> {
        let n = self.positions.len();
        for (attribute, len) in [
            ("NORMAL", self.normals.as_ref().map(Vec::len)),
            ("TEXCOORD_0", self.uvs.as_ref().map(Vec::len)),
            ("JOINTS_0", self.joints.as_ref().map(Vec::len)),
            ("WEIGHTS_0", self.weights.as_ref().map(Vec::len)),
            ("TANGENT", self.tangents.as_ref().map(Vec::len)),
        ] {
            if let Some(found) = len.filter(|&l| l != n) {
                return Err(MeshError::AttributeCountMismatch {
                    attribute,
                    expected: n,
                    found,
                });
            }
        }
        self.validate_attributes()
    }

    /// Checks the further attributes: 1 to 4 components, one record per vertex, distinct ids
    /// that are not the named attributes', finite floats.
    fn validate_attributes(&self) -> MeshResult<()> {
        let n = self.positions.len();
        for (k, a) in self.attributes.iter().enumerate() {
            let bad = |problem: String| {
                Err(MeshError::BadAttribute {
                    name: a.name.clone(),
                    id: a.id,
                    problem,
                })
            };
            if !a.format.is_valid() {
                return bad(format!(
                    "{} components of {:?}, a format no vertex buffer has",
                    a.format.components, a.format.scalar
                ));
            }
            if a.data.len() != n * a.format.size() {
                return bad(format!(
                    "{} bytes, expected {} ({n} vertices of {} bytes)",
                    a.data.len(),
                    n * a.format.size(),
                    a.format.size()
                ));
            }
            if STANDARD_IDS.contains(&a.id) && a.id != UV_1_ID && a.id != COLOR_ID {
                return bad("the id of an attribute the mesh keeps by name".to_string());
            }
            if self.attributes[..k].iter().any(|b| b.id == a.id) {
                return bad("a second attribute with this id".to_string());
            }
            if let Some(vertex) = a.first_non_finite() {
                return bad(format!("vertex {vertex} is NaN or infinite"));
            }
        }
        Ok(())
    }

    /// Loads a mesh from a file, choosing the importer by extension (`obj`, `ply`, `gltf`,
    /// `glb`), and validates it. A glTF file is flattened into one mesh in world space.
    ///
    /// # Errors
    /// [`MeshError::UnsupportedFormat`] for other extensions, [`MeshError::Io`] when the file
    /// cannot be read, and any parse or validation error of the chosen importer.
    pub fn load(path: impl AsRef<Path>) -> MeshResult<(Self, ValidationReport)> {
        Self::load_with_limits(path, &LoadLimits::default())
    }

    /// [`load`](Self::load) within `limits`: the file's size is checked before it is read,
    /// a glTF's decoded data while it is decoded, and the mesh's vertices and triangles.
    ///
    /// # Errors
    /// As [`load`](Self::load), and [`MeshError::LimitExceeded`] naming the limit a file
    /// exceeds.
    pub fn load_with_limits(
        path: impl AsRef<Path>,
        limits: &LoadLimits,
    ) -> MeshResult<(Self, ValidationReport)> {
        let path = path.as_ref();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let mut mesh = match ext.as_str() {
            "obj" => {
                parse_obj_with_limits(&String::from_utf8_lossy(&limits.read_file(path)?), limits)?
            }
            "ply" => parse_ply_with_limits(&limits.read_file(path)?, limits)?,
            // The glTF importer validates already and keeps its own report.
            "gltf" | "glb" => {
                let import = load_gltf_with_limits(path, limits)?;
                return Ok((import.mesh, import.report));
            }
            _ => {
                return Err(MeshError::UnsupportedFormat {
                    path: path.display().to_string(),
                });
            }
        };
        limits.check_mesh(&mesh)?;
        let report = mesh.validate()?;
        Ok((mesh, report))
    }
}

/// An `n`×`n`-vertex grid in the XZ plane, one unit apart, at heights `height(x, z)`: the
/// unit tests' terrain.
#[cfg(test)]
pub(crate) fn test_grid(n: u32, height: impl Fn(u32, u32) -> f32) -> IndexedMesh {
    let mut positions = Vec::new();
    for z in 0..n {
        for x in 0..n {
            positions.push(glam::Vec3::new(x as f32, height(x, z), z as f32));
        }
    }
    let mut indices = Vec::new();
    for z in 0..n - 1 {
        for x in 0..n - 1 {
            let i = z * n + x;
            indices.extend_from_slice(&[i, i + n, i + 1, i + 1, i + n, i + n + 1]);
        }
    }
    IndexedMesh::new(positions, indices)
}
