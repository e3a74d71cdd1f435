//! The skeleton binding of a skinned [`MultiresMesh`](crate::plugin::MultiresMesh): what
//! each region is and how its local vertices are placed.

use crate::mrm::BakedSkin;
use crate::plugin::error::MultiresError;
use crate::regions::RegionMesh;
use crate::skin::{Influences, SkinRegionKind};
use glam::Mat4;

/// The skeleton binding of a skinned [`MultiresMesh`](crate::plugin::MultiresMesh): what each region is and how its
/// vertices are placed. Built by [`MultiresMesh::from_skinned`](crate::plugin::MultiresMesh::from_skinned).
#[derive(Clone, Debug, PartialEq)]
pub struct SkinBinding {
    /// Per region: rigid on one bone, or deformable between two.
    pub(super) kinds: Vec<SkinRegionKind>,
    /// Per region, per local vertex: the influences that place it. A vertex of a rigid
    /// region has its bone alone, with weight 1.
    pub(super) local: Vec<Influences>,
    /// Per region: the joints its local vertices depend on, sorted, without repeats.
    pub(super) region_joints: Vec<Vec<u16>>,
    /// One inverse bind matrix per joint.
    pub(super) inverse_bindposes: Vec<Mat4>,
    /// Vertices with more than two influences (they blend with all of them).
    more_than_two: usize,
    /// Vertices whose weights were renormalised or whose unused slots were cleared.
    normalised: usize,
    /// The joints' names in joint order, from a baked file (empty when built here).
    joint_names: Vec<String>,
}

impl SkinBinding {
    /// The binding of baked regions: how each local vertex is placed (by its rigid
    /// region's bone, or by all its influences, normalised again from the source's), and
    /// the joints each region depends on.
    pub(crate) fn from_baked(regions: &RegionMesh, skin: BakedSkin) -> Result<Self, MultiresError> {
        let BakedSkin {
            kinds,
            inverse_bindposes,
            more_than_two,
            normalised,
            joint_names,
        } = skin;
        if kinds.len() != regions.regions().len() {
            return Err(MultiresError::Baked("one skin kind per region is needed"));
        }
        let source = regions.source_vertices();
        let (Some(joints), Some(weights)) = (&source.joints, &source.weights) else {
            return Err(MultiresError::NotSkinned);
        };
        let (influences, _) = Influences::new(joints, weights, inverse_bindposes.len())?;
        let region_of = regions.partition().region_of();
        let placed = |g: usize| -> ([u16; 4], [f32; 4]) {
            match kinds[region_of[g] as usize] {
                SkinRegionKind::Rigid { bone } => ([bone, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
                SkinRegionKind::Deformable { .. } => (influences.joints[g], influences.weights[g]),
            }
        };
        let mut local = Vec::with_capacity(kinds.len());
        let mut region_joints = Vec::with_capacity(kinds.len());
        for region in regions.regions() {
            let (joints, weights): (Vec<_>, Vec<_>) = region
                .global_vertices()
                .iter()
                .map(|&g| placed(g as usize))
                .unzip();
            let mut used: Vec<u16> = joints
                .iter()
                .zip(&weights)
                .flat_map(|(j, w)| j.iter().zip(w).filter(|(_, w)| **w > 0.0).map(|(j, _)| *j))
                .collect();
            used.sort_unstable();
            used.dedup();
            region_joints.push(used);
            local.push(Influences { joints, weights });
        }
        Ok(Self {
            kinds,
            local,
            region_joints,
            inverse_bindposes,
            more_than_two,
            normalised,
            joint_names,
        })
    }

    /// The joints' names in joint order, as the file it was baked into gave them (an
    /// unnamed joint is `""`); empty for a binding built from a mesh.
    #[inline]
    #[must_use]
    pub fn joint_names(&self) -> &[String] {
        &self.joint_names
    }

    /// Per region: rigid or deformable, and its bones.
    #[inline]
    #[must_use]
    pub fn kinds(&self) -> &[SkinRegionKind] {
        &self.kinds
    }

    /// Number of joints the skin refers to.
    #[inline]
    #[must_use]
    pub fn joint_count(&self) -> usize {
        self.inverse_bindposes.len()
    }

    /// The inverse bind matrices, one per joint.
    #[inline]
    #[must_use]
    pub fn inverse_bindposes(&self) -> &[Mat4] {
        &self.inverse_bindposes
    }

    /// Vertices that had more than two influences: they join the region of their two
    /// largest and blend with all of them.
    #[inline]
    #[must_use]
    pub fn more_than_two(&self) -> usize {
        self.more_than_two
    }

    /// Vertices whose weights were normalised on import (they did not sum to one, or named
    /// a joint out of range with a zero weight).
    #[inline]
    #[must_use]
    pub fn normalised(&self) -> usize {
        self.normalised
    }

    /// The influences that place region `region`'s local vertices (rigid ones by their bone
    /// alone).
    ///
    /// # Panics
    /// When `region` is out of range.
    #[inline]
    #[must_use]
    pub fn local_influences(&self, region: usize) -> &Influences {
        &self.local[region]
    }

    /// The joints region `region`'s local vertices depend on (with a weight above zero),
    /// ascending, without repeats.
    ///
    /// # Panics
    /// When `region` is out of range.
    #[inline]
    #[must_use]
    pub fn region_joints(&self, region: usize) -> &[u16] {
        &self.region_joints[region]
    }

    /// Rigid regions: how many, and deformable regions: how many.
    #[must_use]
    pub fn rigid_deformable_counts(&self) -> (usize, usize) {
        let rigid = self
            .kinds
            .iter()
            .filter(|k| matches!(k, SkinRegionKind::Rigid { .. }))
            .count();
        (rigid, self.kinds.len() - rigid)
    }
}
