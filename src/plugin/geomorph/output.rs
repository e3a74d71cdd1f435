//! What moves under geomorphs and how it reaches the GPU, for region models and
//! view-dependent levels alike: [`MorphOutput`] stages, per mesh, the vertices `Upload`
//! writes, from any [`MorphSource`] (a model's region [`Geomorphs`], or a level's
//! [`VariableGeomorphs`]).
//!
//! - On the CPU, every mesh whose vertices move now or moved last frame is written whole,
//!   positions, normals and further attributes (UVs, tangents, `f32` attributes) where the
//!   morphs show them (once more at rest after a morph).
//! - With a material that interpolates on the GPU ([`GpuGeomorph`](super::GpuGeomorph)), a
//!   vertex is written once, when a morph starts on it, with the morph attributes
//!   ([`ATTRIBUTE_MORPH_FROM`], [`ATTRIBUTE_MORPH_NORMAL_FROM`], and for UVs and tangents
//!   [`ATTRIBUTE_MORPH_UV_FROM`], [`ATTRIBUTE_MORPH_TANGENT_FROM`]) that the shaders beside
//!   this file read; the meshes get those attributes the first time they are written.

use super::material::{
    ATTRIBUTE_MORPH_FROM, ATTRIBUTE_MORPH_NORMAL_FROM, ATTRIBUTE_MORPH_TANGENT_FROM,
    ATTRIBUTE_MORPH_UV_FROM,
};
use crate::plugin::render::UploadTarget;
use crate::refine::VariableGeomorphs;
use crate::regions::{Geomorphs, MorphGroup, MorphKind, RegionMesh, VertexMorph};
use bevy::asset::AssetId;
use bevy::mesh::{MeshVertexAttribute, VertexAttributeValues};
use bevy::prelude::*;

/// The time of a frame: `Time`'s elapsed seconds, and the same wrapped as the shaders see it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Clock {
    pub(crate) now: f32,
    pub(crate) shader: f32,
}

impl Clock {
    /// This frame's time.
    pub(crate) fn of(time: &Time) -> Self {
        Self {
            now: time.elapsed_secs(),
            // The shaders' clock (`globals.time`) is the same time, wrapped.
            shader: time.elapsed_secs_wrapped(),
        }
    }
}

/// How a model's geomorphs follow its [`Geomorph`](super::Geomorph) and material this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MorphChange {
    /// As they are.
    Keep,
    /// None yet: they start.
    Start,
    /// Another morph time or another material path: they start over from what is shown.
    Restart,
    /// The morph time went to zero: every vertex goes back to rest, written once more, and
    /// the state goes once that is done ([`MorphOutput::is_done`]).
    End,
}

impl MorphChange {
    /// What morphs of `current` (their duration, and whether they run on the GPU) do when
    /// `seconds` (`0`, negative or NaN: none) and `gpu` are wanted.
    pub(crate) fn of(current: Option<(f32, bool)>, seconds: f32, gpu: bool) -> Self {
        let wanted = seconds > 0.0;
        match current {
            None if wanted => Self::Start,
            Some((duration, on_gpu)) if wanted && (duration != seconds || on_gpu != gpu) => {
                Self::Restart
            }
            Some((duration, _)) if !wanted && duration > 0.0 => Self::End,
            _ => Self::Keep,
        }
    }
}

/// Morphs seen as meshes whose vertices move: what [`MorphOutput`] stages from.
pub(crate) trait MorphSource {
    /// The morph time in seconds.
    fn duration(&self) -> f32;
    /// Whether any vertex of mesh `mesh` moves now.
    fn is_moving(&self, mesh: usize) -> bool;
    /// Vertices of mesh `mesh`.
    fn vertex_count(&self, mesh: usize) -> usize;
    /// Where every vertex of mesh `mesh` is shown at `now`.
    fn write_positions(&self, mesh: usize, now: f32, out: &mut Vec<Vec3>);
    /// The normal every vertex of mesh `mesh` is shown with at `now` (empty without normals).
    fn write_normals(&self, mesh: usize, now: f32, out: &mut Vec<Vec3>);
    /// The further attributes morphs interpolate, in the order of `write_attributes`.
    fn attribute_groups(&self) -> &[MorphGroup];
    /// The further attributes every vertex of mesh `mesh` is shown with at `now` (`None`:
    /// their own), `attribute_groups`' values per vertex (empty when none).
    fn write_attributes(&self, mesh: usize, now: Option<f32>, out: &mut Vec<f32>);
    /// The runs of vertices (mesh, first, last; in mesh order) that a morph started or
    /// restarted on since the last call.
    fn take_restarted(&mut self) -> Vec<(u32, u32, u32)>;
    /// The morphs of vertices `lo..=hi` of mesh `mesh`.
    fn vertex_morphs(
        &self,
        mesh: usize,
        lo: u32,
        hi: u32,
    ) -> impl Iterator<Item = VertexMorph> + '_;
}

/// A model's region geomorphs as meshes: one per region, in its local vertices.
pub(crate) struct RegionMorphs<'a> {
    pub(crate) morphs: &'a mut Geomorphs,
    pub(crate) regions: &'a RegionMesh,
}

impl MorphSource for RegionMorphs<'_> {
    fn duration(&self) -> f32 {
        self.morphs.duration()
    }

    fn is_moving(&self, region: usize) -> bool {
        self.morphs.is_region_moving(self.regions, region)
    }

    fn vertex_count(&self, region: usize) -> usize {
        self.regions.regions()[region].global_vertices().len()
    }

    fn write_positions(&self, region: usize, now: f32, out: &mut Vec<Vec3>) {
        self.morphs.write_positions(self.regions, region, now, out);
    }

    fn write_normals(&self, region: usize, now: f32, out: &mut Vec<Vec3>) {
        self.morphs.write_normals(self.regions, region, now, out);
    }

    fn attribute_groups(&self) -> &[MorphGroup] {
        self.morphs.attribute_groups()
    }

    fn write_attributes(&self, region: usize, now: Option<f32>, out: &mut Vec<f32>) {
        self.morphs.write_attributes(self.regions, region, now, out);
    }

    fn take_restarted(&mut self) -> Vec<(u32, u32, u32)> {
        let runs = self.morphs.take_restarted(self.regions);
        let runs = runs.into_iter().enumerate();
        runs.filter_map(|(r, run)| run.map(|(lo, hi)| (r as u32, lo, hi)))
            .collect()
    }

    fn vertex_morphs(
        &self,
        region: usize,
        lo: u32,
        hi: u32,
    ) -> impl Iterator<Item = VertexMorph> + '_ {
        let global = &self.regions.regions()[region].global_vertices()[lo as usize..=hi as usize];
        global.iter().map(|&g| self.morphs.vertex_morph(g))
    }
}

/// A view-dependent level's geomorphs as one mesh: the whole vertex table.
pub(crate) struct LevelMorphs<'a> {
    pub(crate) morphs: &'a mut VariableGeomorphs,
    /// The mesh's vertices.
    pub(crate) vertices: usize,
}

impl MorphSource for LevelMorphs<'_> {
    fn duration(&self) -> f32 {
        self.morphs.duration()
    }

    fn is_moving(&self, _: usize) -> bool {
        self.morphs.is_morphing()
    }

    fn vertex_count(&self, _: usize) -> usize {
        self.vertices
    }

    fn write_positions(&self, _: usize, now: f32, out: &mut Vec<Vec3>) {
        self.morphs.write_positions(now, out);
    }

    fn write_normals(&self, _: usize, now: f32, out: &mut Vec<Vec3>) {
        self.morphs.write_normals(now, out);
    }

    fn attribute_groups(&self) -> &[MorphGroup] {
        self.morphs.attribute_groups()
    }

    fn write_attributes(&self, _: usize, now: Option<f32>, out: &mut Vec<f32>) {
        self.morphs.write_attributes(now, out);
    }

    fn take_restarted(&mut self) -> Vec<(u32, u32, u32)> {
        let runs = self.morphs.take_restarted();
        runs.into_iter().map(|(lo, hi)| (0, lo, hi)).collect()
    }

    fn vertex_morphs(&self, _: usize, lo: u32, hi: u32) -> impl Iterator<Item = VertexMorph> + '_ {
        (lo..=hi).map(|v| self.morphs.vertex_morph(v))
    }
}

/// The vertices of a model's meshes that `Upload` writes under geomorphs (see the module
/// doc), one list of runs per mesh.
#[derive(Debug)]
pub(crate) struct MorphOutput {
    /// The material interpolates on the GPU: a vertex is written when a morph starts on it.
    pub(crate) gpu: bool,
    /// The meshes have the morph attributes (added once, by `Upload`).
    attributes: bool,
    /// Per mesh: on the CPU, its vertices moved last frame (so it is written once more at
    /// rest); on the GPU, all of its vertices must be written again.
    moved: Vec<bool>,
    /// Per mesh: the (first) run of its vertices `Upload` writes. One slot per mesh, kept
    /// from frame to frame with its buffers, side by side (`Upload` looks at every one).
    runs: Vec<VertexRun>,
    /// This frame's further runs of a mesh (a view-dependent level's vertices restart in
    /// runs far apart; a region's in one), after its first.
    more: Vec<(u32, VertexRun)>,
    /// The further attributes the runs carry (UVs, tangents, `f32` attributes), as the
    /// source gave them at the first `stage`.
    targets: Option<Vec<MorphTarget>>,
}

impl MorphOutput {
    /// Output for `meshes` meshes; on the GPU, every vertex is written first.
    pub(crate) fn new(meshes: usize, gpu: bool) -> Self {
        Self {
            gpu,
            attributes: false,
            moved: vec![gpu; meshes],
            runs: vec![VertexRun::default(); meshes],
            more: Vec::new(),
            targets: None,
        }
    }

    /// The morphs started over (`gpu`: on the GPU from now on) or ended: every vertex is
    /// written again.
    pub(crate) fn restart(&mut self, gpu: bool) {
        self.gpu = gpu;
        self.rewrite();
    }

    /// Every vertex is written again at the next [`stage`](Self::stage).
    pub(crate) fn rewrite(&mut self) {
        self.moved.fill(true);
    }

    /// Whether morphs of `duration` seconds have nothing left to write: they ended, and the
    /// meshes are at rest.
    pub(crate) fn is_done(&self, duration: f32) -> bool {
        duration == 0.0 && !self.moved.contains(&true)
    }

    /// Stages the vertices to write for `Upload`. On the CPU: the positions, normals and
    /// further attributes of every mesh whose vertices move now or moved last frame. On the GPU: the runs of each
    /// mesh's vertices that a morph started on, with their morph attributes (the whole mesh
    /// when it must be written again).
    pub(crate) fn stage(&mut self, source: &mut impl MorphSource, clock: Clock) {
        if self.targets.is_none() {
            self.targets = Some(MorphTarget::all(source.attribute_groups()));
        }
        if !self.gpu {
            self.more.clear();
            for (m, (moved, run)) in self.moved.iter_mut().zip(&mut self.runs).enumerate() {
                let moving = source.is_moving(m);
                if moving || *moved {
                    source.write_positions(m, clock.now, &mut run.positions);
                    source.write_normals(m, clock.now, &mut run.normals);
                    source.write_attributes(m, Some(clock.now), &mut run.attributes);
                    run.at_rest();
                }
                *moved = moving;
            }
            return;
        }
        let duration = source.duration();
        let restarted = source.take_restarted();
        let mut rest = restarted.as_slice();
        let mut more = 0;
        for (m, (moved, run)) in self.moved.iter_mut().zip(&mut self.runs).enumerate() {
            let n = rest.partition_point(|&(mesh, ..)| mesh as usize == m);
            let (mine, after) = rest.split_at(n);
            rest = after;
            let count = source.vertex_count(m);
            let whole = [(m as u32, 0, count.saturating_sub(1) as u32)];
            let rewrite = std::mem::take(moved);
            let mine = if rewrite { &whole[..] } else { mine };
            let Some((&(_, lo, hi), further)) = mine.split_first().filter(|_| count > 0) else {
                continue;
            };
            run.stage_morphs(lo, source.vertex_morphs(m, lo, hi), duration, clock);
            // The shaders interpolate positions, normals, UVs and tangents only: every other
            // further attribute is its own (written with the whole mesh, which the CPU may
            // have morphed; UVs and tangents then take their morphs' ends below).
            if rewrite {
                source.write_attributes(m, None, &mut run.attributes);
            }
            for &(_, lo, hi) in further {
                if more == self.more.len() {
                    self.more.push((m as u32, VertexRun::default()));
                }
                let (mesh, run) = &mut self.more[more];
                *mesh = m as u32;
                run.stage_morphs(lo, source.vertex_morphs(m, lo, hi), duration, clock);
                more += 1;
            }
        }
        self.more.truncate(more);
    }

    /// Writes the staged runs into the meshes (`ids`, one per mesh); on the GPU, first gives
    /// the meshes the morph attributes (a change Bevy uploads whole, once). `swapped(m)`:
    /// mesh `m`'s index buffer changed this frame (on the whole-mesh path it was counted
    /// whole already).
    pub(crate) fn upload(
        &mut self,
        ids: &[AssetId<Mesh>],
        target: &mut UploadTarget,
        swapped: impl Fn(usize) -> bool,
    ) {
        // The frame the meshes change layout, Bevy uploads them whole (with what is written
        // below): no vertex run goes to their old allocations.
        let relayout = self.gpu && !self.attributes;
        if relayout {
            for &id in ids {
                if let Some(mesh) = target.meshes.get_mut(id) {
                    add_morph_attributes(mesh.into_inner());
                }
            }
            self.attributes = true;
        }
        let first = self
            .runs
            .iter_mut()
            .enumerate()
            .map(|(m, run)| (m, run, false));
        let more = self
            .more
            .iter_mut()
            .map(|(m, run)| (*m as usize, run, true));
        for (m, run, further) in first.chain(more) {
            if run.ready
                && let Some(&id) = ids.get(m)
                && let Some(mesh) = target.mesh(id)
                && let Some(written) = run.write(mesh, self.targets.as_deref().unwrap_or(&[]))
                && !relayout
            {
                // (Counted whole once: when its indices changed too, or by its first run.)
                target.vertices_changed(id, &written, swapped(m) || further);
            }
        }
    }
}

/// A run of a mesh's vertices that `Upload` writes under geomorphs, from vertex `first`
/// (`ready` when new): positions, normals and further attributes, and on the GPU the morph
/// attributes (empty: written from the CPU, at rest).
#[derive(Clone, Debug, Default)]
struct VertexRun {
    first: u32,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    /// The further attributes (`MorphOutput::targets`' values per vertex), when the run
    /// writes them.
    attributes: Vec<f32>,
    from: Vec<[f32; 4]>,
    normal_from: Vec<[f32; 4]>,
    /// On the GPU: the UVs' and tangents' ends (written to the mesh's own) and starts.
    uv_to: Vec<[f32; 2]>,
    uv_from: Vec<[f32; 2]>,
    tangent_to: Vec<[f32; 4]>,
    tangent_from: Vec<[f32; 4]>,
    ready: bool,
}

impl VertexRun {
    /// The positions and normals written are the whole mesh's, drawn as they are.
    fn at_rest(&mut self) {
        self.first = 0;
        self.from.clear();
        self.normal_from.clear();
        self.clear_gpu_attributes();
        self.ready = true;
    }

    fn clear_gpu_attributes(&mut self) {
        self.uv_to.clear();
        self.uv_from.clear();
        self.tangent_to.clear();
        self.tangent_from.clear();
    }

    /// Stages the vertices from `first` on with their morphs (`duration` seconds), for a
    /// material that interpolates them.
    fn stage_morphs(
        &mut self,
        first: u32,
        morphs: impl Iterator<Item = VertexMorph>,
        duration: f32,
        clock: Clock,
    ) {
        let inv = if duration > 0.0 {
            duration.recip()
        } else {
            0.0
        };
        self.positions.clear();
        self.normals.clear();
        self.attributes.clear();
        self.from.clear();
        self.normal_from.clear();
        self.clear_gpu_attributes();
        for m in morphs {
            // The start on the shaders' clock: as long ago as on the CPU's.
            let start = clock.shader - (clock.now - m.start);
            self.positions.push(m.to);
            self.normals.push(m.normal_to);
            self.from.push(m.from.extend(start).to_array());
            self.normal_from.push(m.normal_from.extend(inv).to_array());
            self.uv_to.push(m.uv_to.to_array());
            self.uv_from.push(m.uv_from.to_array());
            self.tangent_to.push(m.tangent_to.to_array());
            self.tangent_from.push(m.tangent_from.to_array());
        }
        self.first = first;
        self.ready = true;
    }

    /// Writes the run into `mesh` (its further attributes into `targets`); returns the
    /// vertices written (first and last), or `None` when nothing was new or the mesh lacks
    /// room for it.
    fn write(&mut self, mesh: &mut Mesh, targets: &[MorphTarget]) -> Option<[u32; 2]> {
        if !std::mem::take(&mut self.ready) {
            return None;
        }
        let (first, n) = (self.first as usize, self.positions.len());
        let mut written = true;
        let stride = MorphTarget::stride(targets);
        if stride > 0 && self.attributes.len() == n * stride {
            for target in targets {
                let records = self.attributes.chunks_exact(stride).enumerate();
                target.write(mesh, records.map(|(i, v)| (first + i, v)));
            }
        }
        for (attribute, values) in [
            (Mesh::ATTRIBUTE_POSITION, &self.positions),
            (Mesh::ATTRIBUTE_NORMAL, &self.normals),
        ] {
            if let Ok(Some(VertexAttributeValues::Float32x3(slots))) =
                mesh.try_attribute_mut_option(attribute)
                && let Some(slots) = slots.get_mut(first..first + values.len())
            {
                for (slot, v) in slots.iter_mut().zip(values) {
                    *slot = v.to_array();
                }
            }
        }
        // On the GPU, the UVs' and tangents' ends and starts (after the further attributes,
        // which a whole mesh's run writes as their own; empty on the CPU path), where the
        // morphs have them.
        let has = |kind: MorphKind| targets.iter().any(|t| t.group.kind == kind);
        if has(MorphKind::Uv) {
            write_floats(mesh, Mesh::ATTRIBUTE_UV_0, run_records(first, &self.uv_to));
            write_floats(
                mesh,
                ATTRIBUTE_MORPH_UV_FROM,
                run_records(first, &self.uv_from),
            );
        }
        if has(MorphKind::Tangent) {
            let (to, from) = (&self.tangent_to, &self.tangent_from);
            write_floats(mesh, Mesh::ATTRIBUTE_TANGENT, run_records(first, to));
            write_floats(mesh, ATTRIBUTE_MORPH_TANGENT_FROM, run_records(first, from));
        }
        for (attribute, values) in [
            (ATTRIBUTE_MORPH_FROM, &self.from),
            (ATTRIBUTE_MORPH_NORMAL_FROM, &self.normal_from),
        ] {
            let slots = match mesh.try_attribute_mut_option(attribute) {
                Ok(Some(VertexAttributeValues::Float32x4(slots))) => slots,
                _ => continue,
            };
            if values.is_empty() {
                // Written from the CPU: the morph attributes say "at rest".
                for (slot, p) in slots.iter_mut().skip(first).zip(&self.positions) {
                    *slot = p.extend(0.0).to_array();
                }
            } else if let Some(slots) = slots.get_mut(first..first + values.len()) {
                slots.copy_from_slice(values);
            } else {
                written = false;
            }
        }
        (n > 0 && written).then(|| [first as u32, (first + n) as u32 - 1])
    }
}

/// A further attribute that morphs interpolate, with the Bevy attribute it is written to
/// (found once, not per frame: a custom attribute's name is interned under a lock).
#[derive(Clone, Debug)]
pub(crate) struct MorphTarget {
    pub(crate) group: MorphGroup,
    attribute: MeshVertexAttribute,
}

impl MorphTarget {
    /// The targets of `groups`, in their order.
    pub(crate) fn all(groups: &[MorphGroup]) -> Vec<Self> {
        groups
            .iter()
            .map(|group| Self {
                attribute: match &group.kind {
                    MorphKind::Uv => Mesh::ATTRIBUTE_UV_0,
                    MorphKind::Tangent => Mesh::ATTRIBUTE_TANGENT,
                    MorphKind::Attribute(a) => crate::bevy_mesh::bevy_attribute(a),
                },
                group: group.clone(),
            })
            .collect()
    }

    /// Values per vertex of `targets` together.
    pub(crate) fn stride(targets: &[Self]) -> usize {
        targets.last().map_or(0, |t| t.group.offset + t.group.len)
    }

    /// Writes the attribute into `mesh`: each `(vertex, values)` of `records` holds the
    /// vertex's values for every target, this one's at its offset.
    pub(crate) fn write<'a>(
        &self,
        mesh: &mut Mesh,
        records: impl Iterator<Item = (usize, &'a [f32])>,
    ) {
        let range = self.group.offset..self.group.offset + self.group.len;
        let records = records.filter_map(|(v, r)| r.get(range.clone()).map(|r| (v, r)));
        write_floats(mesh, self.attribute, records);
    }
}

/// Writes `records` (a vertex and its values) into `mesh`'s `attribute`, when the mesh has it
/// as `f32`s of as many components; vertices past its end are left out.
fn write_floats<'a>(
    mesh: &mut Mesh,
    attribute: MeshVertexAttribute,
    records: impl Iterator<Item = (usize, &'a [f32])>,
) {
    match mesh.try_attribute_mut_option(attribute) {
        Ok(Some(VertexAttributeValues::Float32(slots))) => {
            for (v, r) in records {
                if let (Some(slot), Some(&x)) = (slots.get_mut(v), r.first()) {
                    *slot = x;
                }
            }
        }
        Ok(Some(VertexAttributeValues::Float32x2(slots))) => copy_records(slots, records),
        Ok(Some(VertexAttributeValues::Float32x3(slots))) => copy_records(slots, records),
        Ok(Some(VertexAttributeValues::Float32x4(slots))) => copy_records(slots, records),
        _ => {}
    }
}

/// Copies `records` (a vertex and its `N` values) into `slots`.
fn copy_records<'a, const N: usize>(
    slots: &mut [[f32; N]],
    records: impl Iterator<Item = (usize, &'a [f32])>,
) {
    for (v, r) in records {
        if let (Some(slot), Ok(r)) = (slots.get_mut(v), <[f32; N]>::try_from(r)) {
            *slot = r;
        }
    }
}

/// `values` as the records of the vertices from `first` on.
fn run_records<const N: usize>(
    first: usize,
    values: &[[f32; N]],
) -> impl Iterator<Item = (usize, &[f32])> {
    values
        .iter()
        .enumerate()
        .map(move |(i, v)| (first + i, &v[..]))
}

/// Gives a mesh the morph attributes, every vertex at rest.
fn add_morph_attributes(mesh: &mut Mesh) {
    if mesh.contains_attribute(ATTRIBUTE_MORPH_FROM) {
        return;
    }
    let Some(VertexAttributeValues::Float32x3(positions)) =
        mesh.attribute(Mesh::ATTRIBUTE_POSITION)
    else {
        return;
    };
    let rest: Vec<[f32; 4]> = positions.iter().map(|&[x, y, z]| [x, y, z, 0.0]).collect();
    let normals: Vec<[f32; 4]> = match mesh.attribute(Mesh::ATTRIBUTE_NORMAL) {
        Some(VertexAttributeValues::Float32x3(n)) => {
            n.iter().map(|&[x, y, z]| [x, y, z, 0.0]).collect()
        }
        _ => vec![[0.0; 4]; rest.len()],
    };
    mesh.insert_attribute(ATTRIBUTE_MORPH_FROM, rest);
    mesh.insert_attribute(ATTRIBUTE_MORPH_NORMAL_FROM, normals);
    if let Some(VertexAttributeValues::Float32x2(uvs)) = mesh.attribute(Mesh::ATTRIBUTE_UV_0) {
        let uvs = uvs.clone();
        mesh.insert_attribute(ATTRIBUTE_MORPH_UV_FROM, uvs);
    }
    if let Some(VertexAttributeValues::Float32x4(tangents)) =
        mesh.attribute(Mesh::ATTRIBUTE_TANGENT)
    {
        let tangents = tangents.clone();
        mesh.insert_attribute(ATTRIBUTE_MORPH_TANGENT_FROM, tangents);
    }
}
