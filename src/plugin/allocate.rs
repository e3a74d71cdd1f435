//! `Allocate`: the projected area of every region of every model in the frame's cameras, and
//! one α allocation of the budget over all of them at once ([`FrameAllocation`]).

use super::cameras::FrameCameras;
use super::components::{
    AslodStats, CountInBudget, FullDetail, LodPriority, PolygonBudget, RegionSplit,
};
use super::diagnostics;
use super::instance::{AllocationSlot, MultiresInstance};
use super::tasks::{ComputePool, par_chunks};
use super::view_dependent::ViewDependentState;
use crate::bounds::Obb;
use crate::budget::{Allocator, ProjectedAreaCamera, RegionInput};
use bevy::camera::visibility::RenderLayers;
use bevy::diagnostic::Diagnostics;
use bevy::ecs::query::QueryItem;
use bevy::ecs::system::NonSendMarker;
use bevy::platform::time::Instant;
use bevy::prelude::*;

/// The frame's allocation, for `SelectLod`: one count per input, and which allocation it is.
#[derive(Resource, Default)]
pub(crate) struct FrameAllocation {
    /// Counts the allocations; a model's [`AllocationSlot`] names the last one it took part
    /// in.
    pub(crate) serial: u64,
    /// Whether `Allocate` made allocation `serial` this frame (none without a usable camera,
    /// or with a budget it could not use): only then do the models take their counts.
    pub(crate) this_frame: bool,
    /// Per input, its triangles.
    pub(crate) counts: Vec<u32>,
}

impl FrameAllocation {
    /// The counts of a model's inputs from `slot` on, when this frame's allocation included
    /// it.
    pub(crate) fn counts_of(&self, slot: &AllocationSlot, len: usize) -> Option<&[u32]> {
        self.counts
            .get(slot.first..slot.first + len)
            .filter(|_| self.includes(slot))
    }

    /// Whether this frame's allocation included the model of `slot`.
    pub(crate) fn includes(&self, slot: &AllocationSlot) -> bool {
        self.this_frame && slot.allocation == self.serial
    }
}

/// What `Allocate` keeps from frame to frame.
#[derive(Resource, Default)]
pub(crate) struct AllocatorScratch {
    allocator: Allocator,
    inputs: Vec<RegionInput>,
    warned_budget: bool,
}

/// What `Allocate` reads of a model, and its slot, which it writes.
type ModelQuery = (
    &'static MultiresInstance,
    &'static mut AllocationSlot,
    &'static GlobalTransform,
    Option<&'static LodPriority>,
    Option<&'static ViewDependentState>,
    Option<&'static RenderLayers>,
);

/// One model in `Allocate`.
type ModelItem<'w, 's> = QueryItem<'w, 's, ModelQuery>;

/// `Allocate`: projected area of every region of every model, maximum over the active
/// cameras, budget split over all of them at once. A view-dependent model is one input
/// (none with only a pixel tolerance, whose count is fixed cost, like the
/// [`CountInBudget`] meshes'); `FullDetail(true)` gives every input its full detail.
#[allow(clippy::too_many_arguments)]
pub(crate) fn allocate(
    budget: Res<PolygonBudget>,
    full_detail: Res<FullDetail>,
    cameras: Res<FrameCameras>,
    mut models: Query<ModelQuery>,
    fixed: Query<&Mesh3d, With<CountInBudget>>,
    meshes: Res<Assets<Mesh>>,
    mut frame: ResMut<FrameAllocation>,
    mut scratch: ResMut<AllocatorScratch>,
    mut stats: ResMut<AslodStats>,
    mut diag: Diagnostics,
    _main_thread: NonSendMarker,
) {
    let start = Instant::now();
    let (frame, scratch) = (&mut *frame, &mut *scratch);
    frame.this_frame = false;
    if cameras.active.is_empty() || models.is_empty() {
        return;
    }
    let fixed_cost: u64 = fixed
        .iter()
        .filter_map(|m| meshes.get(&m.0))
        .map(crate::bevy_mesh::drawn_triangles)
        .sum();
    frame.serial += 1;
    let mut items: Vec<ModelItem> = models.iter_mut().collect();
    let view_dependent = fill_inputs(
        &mut items,
        &mut scratch.inputs,
        &cameras,
        (full_detail.0, budget.min_area(full_detail.0)),
        frame.serial,
    );
    let fixed_cost = u32::try_from(fixed_cost + view_dependent).unwrap_or(u32::MAX);
    stats.models = items.len();
    stats.regions = scratch.inputs.len();
    stats.fixed_cost = fixed_cost;

    let params = budget.params(fixed_cost);
    if full_detail.0 {
        // No LOD: every region at its full detail, whatever the budget and the view.
        frame.counts.clear();
        frame.counts.extend(scratch.inputs.iter().map(|i| i.max));
    } else {
        match scratch.allocator.allocate_with(
            &params,
            &scratch.inputs,
            &mut frame.counts,
            &ComputePool,
        ) {
            Ok(report) => {
                scratch.warned_budget = false;
                if report.infeasible {
                    debug!("polygon budget below the sum of the coarsest levels");
                }
                if budget.split == RegionSplit::ScreenError {
                    split_by_error(
                        &mut items,
                        &scratch.inputs,
                        &mut frame.counts,
                        budget.hysteresis,
                    );
                }
            }
            Err(e) => {
                if !scratch.warned_budget {
                    warn!("LOD allocation skipped: {e}");
                    scratch.warned_budget = true;
                }
                return;
            }
        }
    }
    stats.allocated = true;
    frame.this_frame = true;
    let ms = cameras.ms + start.elapsed().as_secs_f64() * 1e3;
    stats.allocation_ms = ms;
    diag.add_measurement(&diagnostics::ALLOCATION_MS, || ms);
    diag.add_measurement(&diagnostics::BUDGET, || f64::from(budget.total));
}

/// Fills every model's run of `inputs` (in query order, in parallel on the compute pool)
/// and notes in its slot where the run starts (`SelectLod` reads its counts from the same
/// run, in parallel). Returns the triangles of the view-dependent models without a budget:
/// fixed cost.
/// `(full_detail, min_area)`: whether [`FullDetail`] is on, and the projected area in pixels²
/// below which a model shows nothing (`0`: none).
fn fill_inputs(
    items: &mut [ModelItem],
    inputs: &mut Vec<RegionInput>,
    cameras: &FrameCameras,
    (full_detail, min_area): (bool, f32),
    serial: u64,
) -> u64 {
    let lens: Vec<usize> = items.iter().map(input_len).collect();
    // Every input is written below (each model fills its whole run): no need to clear.
    inputs.resize(lens.iter().sum(), RegionInput::default());
    let mut jobs = Vec::with_capacity(items.len());
    let mut rest = inputs.as_mut_slice();
    let mut first = 0;
    for (item, n) in items.iter_mut().zip(lens) {
        let (run, tail) = rest.split_at_mut(n);
        jobs.push((item, first, run));
        first += n;
        rest = tail;
    }
    let fill = |chunk: &mut [(&mut ModelItem, usize, &mut [RegionInput])]| {
        let mut scratch = AreaScratch::default();
        let mut fixed = 0u64;
        for ((instance, slot, transform, priority, view_dependent, layers), first, out) in chunk {
            slot.allocation = serial;
            slot.first = *first;
            slot.too_small = false;
            let c = priority_of(*priority);
            match view_dependent {
                Some(state) if state.is_budgeted() => {
                    out[0] = state.allocation_input(c, full_detail);
                }
                // Refined in `aim_view_dependent`: its count is fixed cost.
                Some(state) => fixed += state.triangle_count() as u64,
                None => {
                    let model = ModelInputs {
                        instance,
                        transform,
                        priority: c,
                        layers: *layers,
                    };
                    let area = model.fill(cameras, full_detail, &mut scratch, out);
                    if area < min_area {
                        // Too small to matter: nothing to draw, nothing to count.
                        slot.too_small = true;
                        for input in out.iter_mut() {
                            *input = RegionInput::from_area(0.0, 0.0, 0, 0, input.current);
                        }
                    }
                }
            }
        }
        fixed
    };
    par_chunks(&mut jobs, fill).into_iter().sum()
}

/// [`RegionSplit::ScreenError`]: every region model's triangles (its runs of `counts`, in
/// `items`' order as [`fill_inputs`] laid them out) shared again among its regions by error
/// ([`ErrorCurves::split`](crate::regions::ErrorCurves::split)), in parallel over models. A
/// model shows at most its total (what the split leaves unused, at most a thousandth of it
/// and a triangle, is not handed to other models), so the budget holds; under hysteresis a
/// region keeps its current count when the new one is within ε of it and the model's total
/// allows.
fn split_by_error(
    items: &mut [ModelItem],
    inputs: &[RegionInput],
    counts: &mut [u32],
    hysteresis: u32,
) {
    let mut jobs = Vec::with_capacity(items.len());
    let (mut inputs, mut rest) = (inputs, counts);
    for item in items.iter_mut() {
        let n = input_len(item).min(rest.len());
        let (run, tail) = std::mem::take(&mut rest).split_at_mut(n);
        let (model_inputs, input_tail) = inputs.split_at(n);
        (rest, inputs) = (tail, input_tail);
        if item.4.is_none() && n > 1 {
            jobs.push((item.0, &mut *item.1, model_inputs, run));
        }
    }
    par_chunks(&mut jobs, |chunk| {
        let (mut areas, mut scratch) = (Vec::new(), Vec::new());
        for (instance, slot, inputs, counts) in chunk {
            let total: u32 = counts.iter().sum();
            let at = |bound: fn(&RegionInput) -> u32| {
                inputs
                    .iter()
                    .zip(counts.iter())
                    .all(|(i, &c)| c == bound(i))
            };
            // Nothing to share when every region is at its coarsest, or at its full detail.
            if at(|i| i.min) || at(|i| i.max) {
                continue;
            }
            areas.clear();
            areas.extend(inputs.iter().map(|i| i.weight));
            slot.tolerance =
                instance
                    .curves
                    .split_from(&areas, total, slot.tolerance, &mut scratch, counts);
            if hysteresis > 0 {
                keep_within(inputs, counts, total, hysteresis);
            }
        }
    });
}

/// Hysteresis after [`split_by_error`]: each region in view whose count is within
/// `hysteresis` of its current one (a count within its levels) goes back to it, in region
/// order, while the model's sum stays at most `total`; as in the allocator, a region out of
/// view does not keep its count.
fn keep_within(inputs: &[RegionInput], counts: &mut [u32], total: u32, hysteresis: u32) {
    let mut sum: u64 = counts.iter().map(|&c| u64::from(c)).sum();
    for (input, count) in inputs.iter().zip(counts.iter_mut()) {
        let keeps = input.weight > 0.0 && (input.min..=input.max).contains(&input.current);
        if keeps && *count != input.current && count.abs_diff(input.current) <= hysteresis {
            let kept = sum - u64::from(*count) + u64::from(input.current);
            if kept <= u64::from(total) {
                *count = input.current;
                sum = kept;
            }
        }
    }
}

/// How many allocation inputs a model fills: one per region, one for a budgeted
/// view-dependent model, none for a tolerance-only one.
fn input_len(item: &ModelItem) -> usize {
    match item.4 {
        None => item.0.regions.regions().len(),
        Some(state) => usize::from(state.is_budgeted()),
    }
}

/// The cameras that draw a model on `layers`, and their weights: all of the frame's active
/// cameras as they are when every one draws the model (weights only when some are not 1),
/// else those whose layers meet the model's, gathered into `seen` and `weights`.
fn cameras_drawing<'a>(
    frame: &'a FrameCameras,
    layers: Option<&RenderLayers>,
    seen: &'a mut Vec<ProjectedAreaCamera>,
    weights: &'a mut Vec<f32>,
) -> (&'a [ProjectedAreaCamera], Option<&'a [f32]>) {
    if frame.plain && layers.is_none() {
        return (&frame.active, None);
    }
    if frame.shares.iter().all(|share| share.sees(layers)) {
        return (&frame.active, Some(&frame.weights));
    }
    seen.clear();
    weights.clear();
    for (camera, share) in frame.active.iter().zip(&frame.shares) {
        if share.sees(layers) {
            seen.push(*camera);
            weights.push(share.weight);
        }
    }
    (seen, Some(weights))
}

/// The user priority `c` of a model (see [`LodPriority`]).
fn priority_of(priority: Option<&LodPriority>) -> f32 {
    priority
        .map(|p| p.0)
        .filter(|c| c.is_finite() && *c > 0.0)
        .unwrap_or(if priority.is_some() { 0.0 } else { 1.0 })
}

/// Buffers [`ModelInputs::fill`] reuses from model to model.
#[derive(Default)]
struct AreaScratch {
    /// The cameras moved into the model's space.
    local: Vec<ProjectedAreaCamera>,
    /// The largest area of each region over the cameras so far, and one camera's areas.
    areas: Vec<f32>,
    one: Vec<f32>,
    /// The cameras that draw the model and their weights, when not all of them at 1.
    seen: Vec<ProjectedAreaCamera>,
    weights: Vec<f32>,
}

/// A region model as `Allocate` weighs it.
struct ModelInputs<'a> {
    instance: &'a MultiresInstance,
    transform: &'a GlobalTransform,
    /// Its priority `c`.
    priority: f32,
    /// Its render layers (none: the default layer).
    layers: Option<&'a RenderLayers>,
}

impl ModelInputs<'_> {
    /// The model's [`RegionInput`]s: each region's box, its largest weighted projected area
    /// over the cameras that draw its layers (skipped without LOD, which does not use it), the
    /// model's priority. Unskinned boxes of models with more than two regions stay in the
    /// model's space and the cameras move into it (four boxes at a time, see
    /// [`ProjectedAreaCamera::projected_areas`]); skinned ones are already in the world, and
    /// one or two boxes move there.
    /// Returns the sum of the regions' areas (0 out of view or at full detail).
    fn fill(
        &self,
        frame: &FrameCameras,
        full_detail: bool,
        scratch: &mut AreaScratch,
        out: &mut [RegionInput],
    ) -> f32 {
        let AreaScratch {
            local,
            areas,
            one,
            seen,
            weights,
        } = scratch;
        let (cameras, weights) = cameras_drawing(frame, self.layers, seen, weights);
        let weight = |k: usize| weights.map_or(1.0, |w| w[k]);
        let instance = self.instance;
        let affine = self.transform.affine();
        let skinned = instance.skinned_world_boxes();
        // Every region box lies inside the model's box: when that one is out of every view,
        // so are they (skinned regions move with their bones, so not for them). The world box
        // contains the model's box, so this never culls a visible model.
        // One or two boxes are cheaper moved into the world than the cameras into the
        // model's space (an f64 inverse per camera), and out of view their areas are zero.
        let few = instance.obbs.len() <= 2;
        let culled = !full_detail && skinned.is_none() && !few && {
            let bounds = instance.bounds.transformed(&affine);
            !cameras.iter().any(|cam| cam.may_see(&bounds))
        };
        // Model space needs an invertible transform; a flattened model (a zero scale on one
        // axis, still drawn as a sheet) keeps world-space boxes.
        local.clear();
        let in_model = skinned.is_none() && !full_detail && !culled && !few && {
            local.extend(cameras.iter().filter_map(|cam| cam.for_model(&affine)));
            local.len() == cameras.len()
        };
        let max_area = |cams: &[ProjectedAreaCamera], obb: &Obb| {
            cams.iter()
                .enumerate()
                .map(|(k, cam)| cam.projected_area(obb) * weight(k))
                .fold(0.0f32, f32::max)
        };
        if in_model {
            areas.clear();
            areas.resize(instance.obbs.len(), 0.0);
            one.resize(instance.obbs.len(), 0.0);
            for (k, camera) in local.iter().enumerate() {
                camera.projected_areas(&instance.obbs, one);
                let w = weight(k);
                for (max, &area) in areas.iter_mut().zip(one.iter()) {
                    *max = max.max(area * w);
                }
            }
        }
        let mut total = 0.0;
        for ((r, region), input) in instance.regions.regions().iter().enumerate().zip(out) {
            let area = if full_detail || culled {
                0.0
            } else if in_model {
                areas[r]
            } else {
                let obb = skinned
                    .and_then(|boxes| boxes.get(r).copied())
                    .unwrap_or_else(|| instance.obbs[r].transformed(&affine));
                max_area(cameras, &obb)
            };
            let area = if area.is_finite() { area } else { 0.0 };
            total += area;
            let shown = instance.caches.triangle_count(r) as u32;
            // Geomorphs or not, the allocation is the view's (`Geomorphs::apply_allocation`
            // holds the budget while regions morph).
            let (min, max) = (region.min_triangles() as u32, region.max_triangles() as u32);
            *input = RegionInput::from_area(area, self.priority, min, max, shown);
        }
        total
    }
}
