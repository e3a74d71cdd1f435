//! Baking: building [`BakedMesh`]es from meshes (cut by a partition, or by skin influence) and
//! from glTF files ([`bake_gltf`]). What they are written as and read back from is in `asset`.

use super::{BakeError, BakedMesh, BakedSkin};
use crate::multires::BuildOptions;
use crate::regions::{Partition, Region, RegionMesh};
use crate::skin::SkinRegionKind;
use glam::Mat4;

impl BakedMesh {
    /// Builds the regions of `mesh` cut by `partition` and fits their boxes; with
    /// [`BuildOptions::view_dependent`], the whole mesh's refinement data as well.
    ///
    /// # Errors
    /// [`BakeError::Region`] or [`BakeError::Mesh`] when the mesh cannot be partitioned or
    /// built.
    pub fn build(
        mesh: &crate::mesh::IndexedMesh,
        partition: &Partition,
        options: &BuildOptions,
    ) -> Result<Self, BakeError> {
        let regions = RegionMesh::build(mesh, partition, options)?;
        let variable = options
            .view_dependent
            .then(|| crate::multires::ProgressiveMesh::build(mesh, options))
            .transpose()?;
        Ok(Self::from_regions(regions, None, variable))
    }

    /// Wraps built regions: fits one box per region (on its own vertices).
    #[must_use]
    pub fn from_regions(
        regions: RegionMesh,
        skin: Option<BakedSkin>,
        variable: Option<crate::multires::ProgressiveMesh>,
    ) -> Self {
        let obbs = regions.regions().iter().map(Region::obb).collect();
        Self {
            regions,
            obbs,
            skin,
            variable,
        }
    }

    /// Builds a skinned asset: regions by influence (a vertex whose dominant weight is at
    /// least `1 − rigid_delta` goes to its bone's rigid region, any other to the deformable
    /// region of its two largest influences), one progressive sequence per region, with
    /// default [`BuildOptions`]. Weights that do not sum to one are normalised (counted in
    /// [`BakedSkin::normalised`], with a warning).
    ///
    /// # Errors
    /// [`BakeError::NotSkinned`] for a mesh without joints or weights,
    /// [`BakeError::NonFiniteBindpose`], [`BakeError::Skin`] for bad influences, and the
    /// errors of [`build`](Self::build).
    pub fn build_skinned(
        mesh: &crate::mesh::IndexedMesh,
        inverse_bindposes: &[Mat4],
        joint_names: Vec<String>,
        rigid_delta: f32,
    ) -> Result<Self, BakeError> {
        use crate::skin::{Influences, decompose};
        let (Some(joints), Some(weights)) = (&mesh.joints, &mesh.weights) else {
            return Err(BakeError::NotSkinned);
        };
        if let Some(joint) = inverse_bindposes.iter().position(|m| !m.is_finite()) {
            return Err(BakeError::NonFiniteBindpose { joint });
        }
        let (influences, report) = Influences::new(joints, weights, inverse_bindposes.len())?;
        let normalised = report.renormalised + report.unused_slots_cleared;
        if normalised > 0 {
            log::warn!(
                "{} skinned vertices had weights not summing to one and {} named an unused joint \
                 out of range: normalised",
                report.renormalised,
                report.unused_slots_cleared
            );
        }
        let decomposition = decompose(&mesh.positions, &influences, rigid_delta);
        let (partition, _) = Partition::from_ids(mesh, &decomposition.region_of)?;
        // `from_ids` moves seam copies to the region of the first vertex at their position
        // and renumbers the ids in increasing order: follow both to find each region's kind.
        let weld = crate::mesh::weld_positions(&mesh.positions);
        let mut kinds = vec![None; partition.region_count()];
        for (v, &r) in partition.region_of().iter().enumerate() {
            let original = decomposition.region_of[weld.remap[v] as usize] as usize;
            kinds[r as usize] = Some(decomposition.kinds[original]);
        }
        let kinds = kinds
            .into_iter()
            .map(|k| k.unwrap_or(SkinRegionKind::Rigid { bone: 0 }))
            .collect();
        let regions = RegionMesh::build(mesh, &partition, &BuildOptions::default())?;
        let skin = BakedSkin {
            kinds,
            inverse_bindposes: inverse_bindposes.to_vec(),
            joint_names,
            more_than_two: decomposition.more_than_two,
            normalised,
        };
        Ok(Self::from_regions(regions, Some(skin), None))
    }
}

/// Builds every triangle primitive of a glTF file ([`load_gltf_primitives`]), each under its
/// Bevy label: skinned ones by influence ([`BakedMesh::build_skinned`], with the skin's joint
/// names), the others cut by `partition` ([`BakedMesh::build`]). With
/// [`BuildOptions::view_dependent`] every asset gets its refinement mesh. `progress` hears
/// each primitive's key before it is built.
///
/// # Errors
/// [`BakeError::Mesh`] when the file cannot be read, and the errors of the builds.
///
/// [`load_gltf_primitives`]: crate::mesh::load_gltf_primitives
pub fn bake_gltf(
    path: &std::path::Path,
    partition: &dyn Fn(&crate::mesh::IndexedMesh) -> Result<Partition, crate::regions::RegionError>,
    options: &BuildOptions,
    rigid_delta: f32,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<(String, BakedMesh)>, BakeError> {
    let (primitives, skins) = crate::mesh::load_gltf_primitives(path)?;
    let mut out = Vec::with_capacity(primitives.len());
    for p in primitives {
        progress(&p.key);
        let baked = match p.skin.and_then(|s| skins.get(s)) {
            Some(skin) => {
                let mut baked = BakedMesh::build_skinned(
                    &p.mesh,
                    &skin.inverse_bind_matrices,
                    skin.joint_names.clone(),
                    rigid_delta,
                )?;
                if options.view_dependent {
                    baked.variable =
                        Some(crate::multires::ProgressiveMesh::build(&p.mesh, options)?);
                }
                baked
            }
            None => BakedMesh::build(&p.mesh, &partition(&p.mesh)?, options)?,
        };
        out.push((p.key, baked));
    }
    Ok(out)
}
