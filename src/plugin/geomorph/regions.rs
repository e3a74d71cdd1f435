//! The geomorphs of a region model ([`Geomorphs`] beside its polygon caches), and its part in
//! `SelectLod`'s two passes: a refinement waits for the second, which grants it what every
//! model's coarsenings left free.

use super::output::{Clock, MorphOutput, RegionMorphs};
use crate::regions::{Geomorphs, RegionCaches, RegionMesh};
use bevy::prelude::*;

/// The geomorphs of one region model (skinned or not), added while it has a
/// [`Geomorph`](crate::plugin::Geomorph) and removed once they have ended and `Upload` has
/// written every vertex back at rest.
#[derive(Component, Debug)]
pub(crate) struct RegionGeomorphs {
    pub(crate) morphs: Geomorphs,
    /// The time `SelectLod` applied the morphs at (`Deform` blends skinned ones at it).
    pub(crate) now: f32,
    /// The model's first allocation was taken, at once (it would otherwise count its full
    /// detail for the morph time): later ones morph.
    first_taken: bool,
    /// `SelectLod`'s first pass left this model's refinements to its second.
    waiting: bool,
    /// The refinements the first pass started: (region, triangles wanted), as
    /// [`Geomorphs::begin_allocation`] gives them.
    wanted: Vec<(u32, u32)>,
    /// What the grant gave them.
    grants: Vec<RegionGrant>,
    /// Unskinned models: the vertices `Upload` writes (skinned ones are blended by
    /// `Deform`, from the morphs).
    pub(crate) output: Option<MorphOutput>,
}

/// Triangles granted to one region's refinement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RegionGrant {
    pub(crate) region: u32,
    pub(crate) triangles: u32,
}

impl RegionGeomorphs {
    /// Morphs of `seconds` over `regions`; `output` for an unskinned model.
    pub(crate) fn new(regions: &RegionMesh, seconds: f32, output: Option<MorphOutput>) -> Self {
        Self {
            morphs: Geomorphs::new(regions, seconds),
            now: 0.0,
            first_taken: false,
            waiting: false,
            wanted: Vec::new(),
            grants: Vec::new(),
            output,
        }
    }

    /// The morph time, and whether the vertices are interpolated on the GPU.
    pub(crate) fn current(&self) -> (f32, bool) {
        (
            self.morphs.duration(),
            self.output.as_ref().is_some_and(|o| o.gpu),
        )
    }

    /// Starts over with `seconds` (`0`: back to rest), from the levels shown.
    pub(crate) fn restart(&mut self, regions: &RegionMesh, seconds: f32, gpu: bool) {
        self.morphs = Geomorphs::new(regions, seconds);
        if let Some(output) = &mut self.output {
            if seconds > 0.0 {
                output.restart(gpu);
            } else {
                output.rewrite();
            }
        }
    }

    /// Whether the model's allocations morph: its first one was taken.
    pub(crate) fn morphs_allocations(&self) -> bool {
        self.first_taken
    }

    /// `SelectLod`'s first pass for an allocation that morphs: starts the coarsenings and
    /// notes the refinements for the grant. Returns the triangles shown.
    pub(crate) fn begin(
        &mut self,
        regions: &RegionMesh,
        caches: &mut RegionCaches,
        targets: &[u32],
        now: f32,
    ) -> u64 {
        self.morphs
            .begin_allocation(regions, caches, targets, now, &mut self.wanted);
        self.waiting = true;
        caches.total_triangles() as u64
    }

    /// The refinements waiting for the grant: (region, triangles wanted).
    pub(crate) fn wanted(&self) -> &[(u32, u32)] {
        if self.waiting { &self.wanted } else { &[] }
    }

    /// Notes what the grant gave a region's refinement.
    pub(crate) fn push_grant(&mut self, grant: RegionGrant) {
        self.grants.push(grant);
    }

    /// `SelectLod`'s second pass: refines the waiting regions by what they were granted.
    /// Returns false when the first pass left nothing to this one.
    pub(crate) fn apply_grants(
        &mut self,
        regions: &RegionMesh,
        caches: &mut RegionCaches,
        now: f32,
    ) -> bool {
        if !std::mem::take(&mut self.waiting) {
            return false;
        }
        for grant in self.grants.drain(..) {
            let (r, n) = (grant.region as usize, grant.triangles as usize);
            self.morphs.grant(regions, caches, r, n, now);
        }
        true
    }

    /// After the caches took this frame's levels (at once when `allocated` is the model's
    /// first allocation): ends what arrived, and stages the vertices `Upload` writes
    /// (skinned models are written in `Deform`, from the morphs).
    pub(crate) fn finish(
        &mut self,
        regions: &RegionMesh,
        caches: &mut RegionCaches,
        allocated: bool,
        clock: Clock,
    ) {
        self.first_taken |= allocated;
        self.morphs.update(regions, caches, clock.now);
        self.now = clock.now;
        if let Some(output) = &mut self.output {
            let mut source = RegionMorphs {
                morphs: &mut self.morphs,
                regions,
            };
            output.stage(&mut source, clock);
        }
    }

    /// Whether the morphs ended and every vertex is back at rest: the state can go.
    pub(crate) fn is_done(&self) -> bool {
        let duration = self.morphs.duration();
        match &self.output {
            Some(output) => output.is_done(duration),
            None => duration == 0.0,
        }
    }
}
