//! Indexed triangle meshes: the input of every other module.
//!
//! An [`IndexedMesh`] is a vertex table (positions plus optional normals, UVs and skin
//! joints/weights, all of equal length) and a `u32` index buffer of triangles. Importers for
//! OBJ, PLY and glTF/GLB live in the submodules; [`IndexedMesh::validate`] checks the invariants
//! every importer guarantees, and returns a [`MeshError`] that names the defect and where it is.
//!
//! Conventions: right-handed, Y up (Bevy's), counter-clockwise front faces. Counts are triangle
//! counts, never index counts, unless a name says `index`.

mod error;
mod gltf_import;
mod obj;
mod ply;
mod weld;

pub use error::{MeshError, MeshResult};
pub use gltf_import::{
    GltfImport, GltfPrimitive, GltfSkinInfo, load_gltf, load_gltf_primitives, load_gltf_slice,
};
pub use obj::{load_obj, parse_obj, write_obj, write_obj_groups};
pub use ply::{load_ply, parse_ply};
pub use weld::{WeldMap, weld_positions};

use glam::{Vec2, Vec3};
use std::path::Path;

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
        self.bounds().map_or(0.0, |(lo, hi)| (hi - lo).length())
    }

    /// Checks the mesh invariants and drops degenerate triangles.
    ///
    /// Checks, in this order: the mesh has vertices and triangles, the index count is a multiple
    /// of three, every attribute has one entry per position, every coordinate is finite, every
    /// index is in range. Then drops triangles whose corners repeat a vertex or whose area is
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
        if let Some(vertex) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFiniteCoordinate {
                attribute: "POSITION",
                vertex,
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
            if (pb - pa).cross(pc - pa).length_squared() == 0.0 {
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

    /// Loads a mesh from a file, choosing the importer by extension (`obj`, `ply`, `gltf`,
    /// `glb`), and validates it. A glTF file is flattened into one mesh in world space.
    ///
    /// # Errors
    /// [`MeshError::UnsupportedFormat`] for other extensions, [`MeshError::Io`] when the file
    /// cannot be read, and any parse or validation error of the chosen importer.
    pub fn load(path: impl AsRef<Path>) -> MeshResult<(Self, ValidationReport)> {
        let path = path.as_ref();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let mut mesh = match ext.as_str() {
            "obj" => load_obj(path)?,
            "ply" => load_ply(path)?,
            // The glTF importer validates already and keeps its own report.
            "gltf" | "glb" => {
                let import = load_gltf(path)?;
                return Ok((import.mesh, import.report));
            }
            _ => {
                return Err(MeshError::UnsupportedFormat {
                    path: path.display().to_string(),
                });
            }
        };
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
