//! `SelectLod`: every model takes its part of the frame's allocation, in phases that read in
//! order:
//!
//! 1. [`sync_geomorphs`]: geomorphs start, change or end as each model's
//!    [`Geomorph`] and material say;
//! 2. [`select_lod`], first pass (in parallel over models): each region's polygon cache to
//!    its count, and each view-dependent level to its goal. Under geomorphs a coarsening
//!    starts and keeps its old triangles for the morph time, and a refinement waits, as a
//!    [`RefinementRequest`];
//! 3. the grant: what the models asked for and do not show yet goes to the waiting
//!    refinements, largest first, so the triangles shown never exceed what the allocation
//!    gave all models together;
//! 4. second pass (in parallel): the granted refinements, and the index buffers and moving
//!    vertices `Upload` writes. Skinned models write theirs in `Deform`.

use super::allocate::FrameAllocation;
use super::components::{AslodStats, FullDetail, Geomorph, LodRegion, PolygonBudget};
use super::geomorph::{Clock, GpuGeomorph, MorphChange, MorphOutput, RegionGeomorphs, RegionGrant};
use super::instance::{AllocationSlot, MultiresInstance, RegionStaging, StagedIndices};
use super::shared::SharedState;
use super::skin::SkinState;
use super::tasks::par_chunks;
use super::view_dependent::ViewDependentState;
use bevy::camera::visibility::VisibilitySystems;
use bevy::ecs::query::QueryItem;
use bevy::ecs::schedule::ScheduleConfigs;
use bevy::ecs::system::NonSendMarker;
use bevy::ecs::system::ScheduleSystem;
use bevy::mesh::Indices;
use bevy::platform::time::Instant;
use bevy::prelude::*;

/// Milliseconds [`sync_geomorphs`] took this frame (for [`AslodStats::update_ms`]).
#[derive(Resource, Default)]
pub(crate) struct SyncTime(f64);

/// Starts, changes or ends every model's geomorphs as its [`Geomorph`] and material
/// ([`GpuGeomorph`]) say: a region model's [`RegionGeomorphs`] come, change and, once
/// `Upload` has written every vertex back at rest, go here; a view-dependent level's live in
/// its state. A view-dependent model's regions do not morph; skinned models morph on the
/// CPU, in `Deform`. (Its commands are applied before [`select_lod`], which follows it.)
#[allow(clippy::type_complexity)]
pub(crate) fn sync_geomorphs(
    mut spent: ResMut<SyncTime>,
    mut commands: Commands,
    mut models: Query<
        (
            Entity,
            &MultiresInstance,
            Option<&Geomorph>,
            Has<GpuGeomorph>,
            Has<SkinState>,
            Option<&mut RegionGeomorphs>,
            Option<&mut RegionStaging>,
            Option<&mut ViewDependentState>,
            Has<SharedState>,
        ),
        // The others have no geomorph to start, change or end.
        Or<(
            With<Geomorph>,
            With<RegionGeomorphs>,
            With<ViewDependentState>,
        )>,
    >,
) {
    let start = Instant::now();
    for (entity, instance, geomorph, gpu, skinned, morphs, staging, view, shared) in &mut models {
        // Ended geomorphs that `Upload` wrote back at rest go.
        let morphs = match morphs {
            Some(m) if m.is_done() => {
                commands.entity(entity).remove::<RegionGeomorphs>();
                None
            }
            other => other,
        };
        let seconds = geomorph.map_or(0.0, |m| m.0);
        // Shared level meshes are drawn by many instances: their regions do not morph.
        let region_seconds = if view.is_some() || shared {
            0.0
        } else {
            seconds
        };
        let region_gpu = gpu && !skinned;
        let current = morphs.as_ref().map(|m| m.current());
        let change = MorphChange::of(current, region_seconds, region_gpu);
        let regions = &instance.regions;
        match (change, morphs) {
            (MorphChange::Start, _) => {
                let meshes = regions.regions().len();
                let output = (!skinned).then(|| MorphOutput::new(meshes, region_gpu));
                let morphs = RegionGeomorphs::new(regions, region_seconds, output);
                commands.entity(entity).insert(morphs);
            }
            (MorphChange::Restart | MorphChange::End, Some(mut morphs)) => {
                morphs.restart(regions, region_seconds, region_gpu);
            }
            _ => {}
        }
        if change != MorphChange::Keep
            && let Some(mut staging) = staging
        {
            staging.settled = false;
        }
        if let Some(mut view) = view {
            view.sync_morph(seconds, gpu);
        }
    }
    spent.0 = start.elapsed().as_secs_f64() * 1e3;
}

/// A refinement waiting for `SelectLod`'s grant: `triangles` wanted by what of model
/// `model` (its index in this frame's pass). Ordered by size, then model, then what, so the
/// grant (largest first) is the same from run to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct RefinementRequest {
    triangles: u32,
    model: u32,
    what: Refines,
}

/// What a [`RefinementRequest`] refines.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Refines {
    /// One of the model's regions.
    Region(u32),
    /// The level of a view-dependent model.
    Level,
}

/// What `SelectLod` touches of a model.
type ModelQuery = (
    &'static mut MultiresInstance,
    &'static AllocationSlot,
    Option<&'static mut RegionStaging>,
    Option<&'static mut RegionGeomorphs>,
    Option<&'static mut ViewDependentState>,
    Option<&'static SharedState>,
);

/// One model in `SelectLod`.
type ModelItem<'w, 's> = QueryItem<'w, 's, ModelQuery>;

/// Triangles over the first pass: shown, asked for, and shown by the models whose
/// refinements wait for the second pass.
#[derive(Clone, Copy, Debug, Default)]
struct Sums {
    shown: u64,
    target: u64,
    deferred: u64,
}

impl std::ops::Add for Sums {
    type Output = Self;

    fn add(self, b: Self) -> Self {
        Self {
            shown: self.shown + b.shown,
            target: self.target + b.target,
            deferred: self.deferred + b.deferred,
        }
    }
}

/// `SelectLod`: each model's caches to its counts, in parallel over models on the compute
/// task pool, in the phases of the module doc. Unskinned models also write the index
/// buffers of their dirty regions here (copying them is the costly part of an update), for
/// `Upload` to swap in.
pub(crate) fn select_lod(
    mut models: Query<ModelQuery>,
    allocation: Res<FrameAllocation>,
    time: Res<Time>,
    sync: Res<SyncTime>,
    mut stats: ResMut<AslodStats>,
    _main_thread: NonSendMarker,
) {
    let start = Instant::now();
    let clock = Clock::of(&time);
    let mut items: Vec<ModelItem> = models.iter_mut().collect();
    let first = par_chunks(&mut items, |chunk| {
        let taken = chunk
            .iter_mut()
            .map(|m| take_allocation(m, &allocation, clock));
        taken.fold(Sums::default(), |a, b| a + b)
    });
    let sums = first.into_iter().fold(Sums::default(), |a, b| a + b);
    grant_refinements(&mut items, sums.target.saturating_sub(sums.shown));
    let second = par_chunks(&mut items, |chunk| {
        chunk
            .iter_mut()
            .map(|m| apply_grants(m, clock))
            .sum::<u64>()
    });
    stats.triangles = sums.shown - sums.deferred + second.into_iter().sum::<u64>();
    stats.update_ms = sync.0 + start.elapsed().as_secs_f64() * 1e3;
}

/// The first pass for one model: its counts from this frame's allocation (when it took
/// part), its caches moved to them; under geomorphs, its coarsenings started and its
/// refinements waiting.
fn take_allocation(model: &mut ModelItem, allocation: &FrameAllocation, clock: Clock) -> Sums {
    let (instance, slot, staging, morphs, view, shared) = model;
    if let Some(view) = view {
        let this_frame = allocation.includes(slot);
        let count = allocation.counts.get(slot.first).copied();
        let (shown, target, waits) = view.take_allocation(this_frame, count, clock.now);
        if let Some(staging) = staging {
            staging.shown = shown;
            staging.settled = false;
        }
        let deferred = if waits { shown } else { 0 };
        return Sums {
            shown,
            target,
            deferred,
        };
    }
    // Too small to draw: its regions are hidden and keep their levels.
    if slot.too_small && allocation.includes(slot) {
        return Sums::default();
    }
    let run = allocation.counts_of(slot, instance.targets.len());
    // The same targets as last frame on a settled model: nothing moves (most models out of
    // view, whose regions all sit at their minimum, and far ones).
    let same = run.is_none_or(|run| run == instance.targets.as_slice());
    if same && let Some(staging) = staging.as_ref().filter(|s| s.settled) {
        let shown = staging.shown;
        return Sums {
            shown,
            target: shown,
            deferred: 0,
        };
    }
    let instance = &mut **instance;
    let allocated = run.is_some();
    if let Some(run) = run {
        instance.targets.copy_from_slice(run);
    }
    let target: u64 = instance.targets.iter().map(|&t| u64::from(t)).sum();
    if let Some(morphs) = morphs.as_mut().filter(|m| m.morphs_allocations()) {
        let (regions, caches) = (&instance.regions, &mut instance.caches);
        let shown = morphs.begin(regions, caches, &instance.targets, clock.now);
        return Sums {
            shown,
            target,
            deferred: shown,
        };
    }
    let mut shown = 0;
    for (r, &target) in instance.targets.iter().enumerate() {
        let target = match shared {
            Some(shared) => shared.step(&instance.regions, r, target as usize),
            None => target as usize,
        };
        shown += instance
            .caches
            .set_triangle_count(&instance.regions, r, target) as u64;
    }
    // A new model's caches start at full detail: its first allocation is taken at once,
    // under geomorphs too (it would count full detail for the morph time).
    if let Some(morphs) = morphs {
        morphs.finish(&instance.regions, &mut instance.caches, allocated, clock);
    }
    let shared = shared.is_some();
    finish_select(
        instance,
        staging.as_deref_mut(),
        morphs.as_deref(),
        shared,
        shown,
    );
    Sums {
        shown,
        target,
        deferred: 0,
    }
}

/// The grant: the waiting refinements of every model take what is `free`, largest first.
fn grant_refinements(items: &mut [ModelItem], mut free: u64) {
    let mut requests = Vec::new();
    for (i, (_, _, _, morphs, view, _)) in items.iter().enumerate() {
        let model = i as u32;
        if let Some(morphs) = morphs {
            let wanted = morphs.wanted().iter();
            requests.extend(wanted.map(|&(region, triangles)| RefinementRequest {
                triangles,
                model,
                what: Refines::Region(region),
            }));
        }
        if let Some(view) = view
            && view.wanted() > 0
        {
            requests.push(RefinementRequest {
                triangles: view.wanted(),
                model,
                what: Refines::Level,
            });
        }
    }
    requests.sort_unstable_by(|a, b| b.cmp(a));
    for request in requests {
        let granted = u64::from(request.triangles).min(free);
        free -= granted;
        let (_, _, _, morphs, view, _) = &mut items[request.model as usize];
        match (request.what, morphs, view) {
            (Refines::Level, _, Some(view)) => view.set_granted(granted as u32),
            (Refines::Region(region), Some(morphs), _) => morphs.push_grant(RegionGrant {
                region,
                triangles: granted as u32,
            }),
            _ => {}
        }
    }
}

/// The second pass for one model: its granted refinements and what `Upload` writes; a
/// view-dependent model's level goes to its instance. Returns the triangles it shows, when
/// it waited for this pass (else `0`: the first pass counted them).
fn apply_grants(model: &mut ModelItem, clock: Clock) -> u64 {
    let (instance, _, staging, morphs, view, _) = model;
    if let Some(view) = view {
        let shown = view.finish_morph(clock);
        if let (Some(shown), Some(staging)) = (shown, staging.as_mut()) {
            staging.shown = shown;
        }
        instance.level = Some(view.summary());
        return shown.unwrap_or(0);
    }
    let Some(morphs) = morphs else {
        return 0;
    };
    let instance = &mut **instance;
    let (regions, caches) = (&instance.regions, &mut instance.caches);
    if !morphs.apply_grants(regions, caches, clock.now) {
        return 0;
    }
    morphs.finish(regions, caches, false, clock);
    let shown = caches.total_triangles() as u64;
    finish_select(
        instance,
        staging.as_deref_mut(),
        Some(&**morphs),
        false,
        shown,
    );
    shown
}

/// `SelectLod`'s systems in order: [`sync_geomorphs`], [`select_lod`], and
/// [`hide_too_small`] before Bevy propagates visibility (so a model that shrank below
/// `min_pixels` is not drawn in this frame).
pub(crate) fn systems() -> ScheduleConfigs<ScheduleSystem> {
    (
        sync_geomorphs,
        select_lod,
        hide_too_small.before(VisibilitySystems::VisibilityPropagate),
    )
        .chain()
}

/// Hides the region entities of the models too small to draw
/// ([`PolygonBudget::min_pixels`](super::PolygonBudget::min_pixels)) and shows them again
/// once they are not; view-dependent models, whose regions hide behind their level (and show
/// again when it goes), are left alone. With `min_pixels` off and nothing hidden it visits no
/// model; `hidden` counts the models it left hidden.
pub(crate) fn hide_too_small(
    budget: Res<PolygonBudget>,
    full_detail: Res<FullDetail>,
    mut hidden: Local<usize>,
    mut models: Query<(
        &MultiresInstance,
        &mut AllocationSlot,
        Has<ViewDependentState>,
    )>,
    mut regions: Query<&mut Visibility, With<LodRegion>>,
) {
    if budget.min_area(full_detail.0) == 0.0 && *hidden == 0 {
        return;
    }
    *hidden = 0;
    for (instance, mut slot, view_dependent) in &mut models {
        // A view-dependent model's regions are hidden behind its level, and shown when it goes.
        let hide = slot.too_small && !view_dependent;
        *hidden += usize::from(hide);
        if hide == slot.hidden {
            continue;
        }
        slot.hidden = hide;
        if view_dependent {
            continue;
        }
        let visibility = if slot.hidden {
            Visibility::Hidden
        } else {
            Visibility::Inherited
        };
        for &region in &instance.region_entities {
            if let Ok(mut v) = regions.get_mut(region) {
                v.set_if_neq(visibility);
            }
        }
    }
}

/// After a model's caches took this frame's levels (`shown` triangles): whether it is
/// settled, and (unskinned) the index buffers of its dirty regions for `Upload`; a `shared`
/// model's dirty regions are only marked, for `Upload` to find their level meshes.
fn finish_select(
    instance: &mut MultiresInstance,
    staging: Option<&mut RegionStaging>,
    morphs: Option<&RegionGeomorphs>,
    shared: bool,
    shown: u64,
) {
    // Skinned models write their buffers in `Deform` (and are never skipped), and morphing
    // ones move.
    let Some(staging) = staging else {
        return;
    };
    staging.shown = shown;
    staging.settled = morphs.is_none_or(|m| !m.morphs.is_morphing());
    // Only the dirty regions' staging slots are touched.
    let (caches, regions) = (&mut instance.caches, &instance.regions);
    for r in 0..staging.staged.len() {
        if !caches.is_dirty(r) {
            continue;
        }
        let StagedIndices { ready, indices } = &mut staging.staged[r];
        if shared {
            caches.mark_written(r);
        } else {
            match indices {
                Indices::U16(buffer) => caches.write_indices_u16(regions, r, buffer),
                Indices::U32(buffer) => caches.write_indices(regions, r, buffer),
            };
        }
        if !std::mem::replace(ready, true) {
            staging.ready.push(r as u32);
        }
    }
}
