//! Tangents for normal maps, made as Bevy's glTF loader makes them: MikkTSpace
//! (`bevy_mikktspace`, the crate Bevy uses) over the triangles, once, at full detail.
//!
//! Levels of detail are subsets of the source vertices, so tangents made here stay valid at
//! every level.

use super::IndexedMesh;
use glam::{Vec2, Vec3, Vec4};

/// MikkTSpace's view of an indexed triangle list, and the tangents it writes back.
struct Geometry<'a> {
    positions: &'a [Vec3],
    normals: &'a [Vec3],
    uvs: &'a [Vec2],
    triangles: &'a [[u32; 3]],
    tangents: Vec<Vec4>,
}

impl Geometry<'_> {
    fn vertex(&self, face: usize, vert: usize) -> usize {
        self.triangles[face][vert] as usize
    }
}

impl bevy_mikktspace::Geometry for Geometry<'_> {
    fn num_faces(&self) -> usize {
        self.triangles.len()
    }

    fn num_vertices_of_face(&self, _: usize) -> usize {
        3
    }

    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.positions[self.vertex(face, vert)].to_array()
    }

    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.normals[self.vertex(face, vert)].to_array()
    }

    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        self.uvs[self.vertex(face, vert)].to_array()
    }

    fn set_tangent(
        &mut self,
        tangent_space: Option<bevy_mikktspace::TangentSpace>,
        face: usize,
        vert: usize,
    ) {
        let v = self.vertex(face, vert);
        self.tangents[v] = Vec4::from(tangent_space.unwrap_or_default().tangent_encoded());
    }
}

/// MikkTSpace tangents of the triangles over `positions`, `normals` and `uvs` (of equal
/// length; every index in range), with the handedness Bevy gives them (MikkTSpace's sign
/// flipped, as `Mesh::generate_tangents` does). A vertex no triangle uses gets zero. `None`
/// when MikkTSpace fails.
pub(crate) fn mikktspace(
    positions: &[Vec3],
    normals: &[Vec3],
    uvs: &[Vec2],
    triangles: &[[u32; 3]],
) -> Option<Vec<Vec4>> {
    let mut geometry = Geometry {
        positions,
        normals,
        uvs,
        triangles,
        tangents: vec![Vec4::ZERO; positions.len()],
    };
    // Its error type has no values today; a later version's error means no tangents.
    bevy_mikktspace::generate_tangents(&mut geometry).ok()?;
    for t in &mut geometry.tangents {
        t.w = -t.w;
    }
    Some(geometry.tangents)
}

impl IndexedMesh {
    /// Gives the mesh MikkTSpace tangents, as Bevy's `Mesh::generate_tangents` and its glTF
    /// loader make them, replacing any it had. Call it once, at full detail, before the
    /// build: every level keeps them.
    ///
    /// # Errors
    /// [`MeshError::Parse`](super::MeshError::Parse) when the mesh has no normals or no UVs
    /// (tangents follow the first UV set); any error of [`validate`](Self::validate).
    ///
    /// ```
    /// use bevy_aslod::mesh::IndexedMesh;
    /// use glam::{Vec2, Vec3};
    ///
    /// let mut quad = IndexedMesh {
    ///     positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
    ///     normals: Some(vec![Vec3::Z; 4]),
    ///     uvs: Some(vec![Vec2::new(0.0, 1.0), Vec2::ONE, Vec2::X, Vec2::ZERO]),
    ///     indices: vec![0, 1, 2, 0, 2, 3],
    ///     ..Default::default()
    /// };
    /// quad.generate_tangents()?;
    /// // U grows along +X: the tangent is +X.
    /// assert!(quad.tangents.unwrap().iter().all(|t| t.truncate().distance(Vec3::X) < 1e-5));
    /// # Ok::<(), bevy_aslod::mesh::MeshError>(())
    /// ```
    pub fn generate_tangents(&mut self) -> super::MeshResult<()> {
        self.validate()?;
        let (Some(normals), Some(uvs)) = (&self.normals, &self.uvs) else {
            return Err(super::MeshError::parse(
                "mesh",
                "tangents",
                "tangents need normals and UVs".to_string(),
            ));
        };
        let triangles: Vec<[u32; 3]> = self
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        self.tangents = Some(
            mikktspace(&self.positions, normals, uvs, &triangles).ok_or_else(|| {
                super::MeshError::parse("mesh", "tangents", "MikkTSpace failed".to_string())
            })?,
        );
        Ok(())
    }
}
