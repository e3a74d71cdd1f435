//! The import plan: what decoding a glTF will ask for, summed from the document alone, so that
//! a file over a [`LoadLimits`] is refused before anything its counts name is allocated.

use super::accessors::{stride_within, view_within};
use crate::mesh::{LoadLimits, MeshResult};
use gltf::Accessor;
use gltf::Document;
use gltf::mesh::{Mode, Semantic};

/// What an import will decode and build, from the accessors' declared counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Plan {
    /// Vertices of the imported mesh: every triangle primitive's `POSITION` count, once per
    /// time its mesh is read.
    pub(super) vertices: u64,
    /// Triangles of the imported mesh (before degenerate ones are dropped).
    pub(super) triangles: u64,
    /// Bytes the accessors decode to, as [`LoadLimits::decoded_bytes`] counts them: every
    /// attribute the importer carries and every index as 4-byte values per component, the
    /// skins' inverse bind matrices as 64 bytes each.
    pub(super) decoded_bytes: u64,
}

impl Plan {
    /// Sums what reading `meshes` (each with how many times the import reads it), the
    /// `accessors` it reads besides (GPU instances), and every skin of `document` asks for,
    /// and checks it against `limits`.
    ///
    /// # Errors
    /// [`MeshError::LimitExceeded`](crate::mesh::MeshError::LimitExceeded) naming the first
    /// of `vertices`, `triangles`, `decoded_bytes` and (the largest skin's) `joints` the sums
    /// exceed.
    pub(super) fn check<'a>(
        document: &Document,
        meshes: impl IntoIterator<Item = (gltf::Mesh<'a>, u64)>,
        accessors: impl IntoIterator<Item = Accessor<'a>>,
        limits: &LoadLimits,
    ) -> MeshResult<Self> {
        let mut plan = Self::default();
        let mut joints = 0;
        for skin in document.skins() {
            joints = joints.max(skin.joints().len() as u64);
            if let Some(matrices) = skin.inverse_bind_matrices() {
                plan.decode(&matrices)?;
            }
        }
        for accessor in accessors {
            plan.decode(&accessor)?;
        }
        for (mesh, times) in meshes {
            let mut once = Self::default();
            for primitive in mesh.primitives() {
                once.add(&primitive)?;
            }
            plan.vertices = plan
                .vertices
                .saturating_add(once.vertices.saturating_mul(times));
            plan.triangles = plan
                .triangles
                .saturating_add(once.triangles.saturating_mul(times));
            plan.decoded_bytes = plan
                .decoded_bytes
                .saturating_add(once.decoded_bytes.saturating_mul(times));
        }
        LoadLimits::check("vertices", plan.vertices, limits.vertices)?;
        LoadLimits::check("triangles", plan.triangles, limits.triangles)?;
        LoadLimits::check("decoded_bytes", plan.decoded_bytes, limits.decoded_bytes)?;
        LoadLimits::check("joints", joints, limits.joints)?;
        Ok(plan)
    }

    /// Counts an accessor decoded once, as 4-byte values per component, after checking
    /// that its elements fit in its buffer view and the view in its buffer's declared length
    /// (which the buffer's data is checked to have before anything is decoded): then no
    /// element decoded but those of an accessor without a view, zeros, lacks bytes of the
    /// file behind it.
    ///
    /// # Errors
    /// As [`view_within`] and [`stride_within`].
    fn decode(&mut self, accessor: &Accessor<'_>) -> MeshResult<()> {
        if let Some(view) = accessor.view() {
            view_within(&view, view.buffer().length())?;
            stride_within(accessor, &view, view.length())?;
        }
        let components = accessor.dimensions().multiplicity() as u64;
        let bytes = (accessor.count() as u64).saturating_mul(4 * components);
        self.decoded_bytes = self.decoded_bytes.saturating_add(bytes);
        Ok(())
    }

    /// Counts one primitive as the flattening builder reads it.
    ///
    /// # Errors
    /// As [`decode`](Self::decode).
    fn add(&mut self, primitive: &gltf::Primitive<'_>) -> MeshResult<()> {
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Ok(());
        }
        let Some(positions) = primitive.get(&Semantic::Positions) else {
            return Ok(());
        };
        let vertices = positions.count();
        self.vertices = self.vertices.saturating_add(vertices as u64);
        let mut has_region = false;
        for (semantic, accessor) in primitive.attributes() {
            if is_carried(&semantic) {
                self.decode(&accessor)?;
            }
            has_region |= matches!(&semantic, Semantic::Extras(name) if name == "REGION");
        }
        // Without `_REGION`, the region ids are `COLOR_0` read a second time.
        if let (false, Some(colors)) = (has_region, primitive.get(&Semantic::Colors(0))) {
            self.decode(&colors)?;
        }
        let corners = match primitive.indices() {
            Some(indices) => {
                self.decode(&indices)?;
                indices.count()
            }
            None => vertices,
        } as u64;
        let triangles = match mode {
            Mode::Triangles => corners / 3,
            _ => corners.saturating_sub(2),
        };
        self.triangles = self.triangles.saturating_add(triangles);
        Ok(())
    }
}

/// Whether the importer reads an attribute into the mesh (the others are dropped, by name).
pub(super) fn is_carried(semantic: &Semantic) -> bool {
    matches!(
        semantic,
        Semantic::Positions
            | Semantic::Normals
            | Semantic::Tangents
            | Semantic::TexCoords(0 | 1)
            | Semantic::Colors(0)
            | Semantic::Joints(0)
            | Semantic::Weights(0)
    ) || matches!(semantic, Semantic::Extras(name) if name == "REGION")
}
