//! A budget in milliseconds: before each split, [`control_budget`] moves
//! [`PolygonBudget::total`] so that frames take about [`FrameTarget::ms`].
//!
//! The frame's cost is measured where it can be ([`FrameSource`]): from GPU timestamps when
//! the app has Bevy's `RenderDiagnosticsPlugin` and the device has timestamp queries, else
//! from the frame's wall time.

use super::components::{AslodStats, FrameSource, FrameTarget, PolygonBudget};
use super::diagnostics;
use crate::budget::{ControllerState, FrameTimeController};
use bevy::diagnostic::{Diagnostics, DiagnosticsStore};
use bevy::platform::time::Instant;
use bevy::prelude::*;

/// Frames without a fresh GPU timestamp after which the controller reads the wall time again.
const GPU_SILENCE: u32 = 8;

/// The controller of the current [`FrameTarget`] (made anew when the target changes).
#[derive(Resource, Default)]
pub(crate) struct BudgetControl {
    controller: Option<(FrameTarget, FrameTimeController)>,
    /// The target last warned about as unusable.
    warned: Option<FrameTarget>,
    /// When the newest GPU timestamp used was read back.
    gpu_seen: Option<Instant>,
    /// Frames since the last fresh GPU timestamp.
    gpu_silent: u32,
}

/// The main world's time from `First` to `Last`, for [`FrameSource::GpuTimestamps`].
#[derive(Resource, Default)]
pub(crate) struct MainWorldClock {
    start: Option<Instant>,
    last_ms: Option<f32>,
}

/// The controller's resources, and the main world's clock in `First` and `Last`.
pub(super) fn add(app: &mut App) {
    app.init_resource::<BudgetControl>()
        .init_resource::<MainWorldClock>()
        .add_systems(First, start_main_clock)
        .add_systems(Last, stop_main_clock);
}

/// Starts the main world's clock (in `First`).
fn start_main_clock(mut clock: ResMut<MainWorldClock>) {
    clock.start = Some(Instant::now());
}

/// Stops it (in `Last`).
fn stop_main_clock(mut clock: ResMut<MainWorldClock>) {
    if let Some(start) = clock.start.take() {
        clock.last_ms = Some(start.elapsed().as_secs_f32() * 1e3);
    }
}

/// The GPU's time for the newest frame whose timestamps came back since `seen`: the sum of
/// the top-level render spans (`render/<span>/elapsed_gpu`) measured after it.
fn fresh_gpu_ms(store: &DiagnosticsStore, seen: Option<Instant>) -> Option<(f32, Instant)> {
    let mut sum = 0.0;
    let mut newest = None;
    for diagnostic in store.iter() {
        let mut parts = diagnostic.path().components();
        let top_level_gpu = parts.next() == Some("render")
            && parts.next().is_some()
            && parts.next() == Some("elapsed_gpu")
            && parts.next().is_none();
        let Some(m) = diagnostic.measurement().filter(|_| top_level_gpu) else {
            continue;
        };
        if seen.is_some_and(|seen| m.time <= seen) || !m.value.is_finite() {
            continue;
        }
        sum += m.value as f32;
        newest = Some(newest.map_or(m.time, |t: Instant| t.max(m.time)));
    }
    newest.map(|t| (sum, t))
}

/// Sets the frame's budget from the last frame's time when [`PolygonBudget::frame_target`]
/// is set; publishes the target, the smoothed frame time and the controller's state.
pub(crate) fn control_budget(
    mut budget: ResMut<PolygonBudget>,
    time: Res<Time<Real>>,
    mut control: ResMut<BudgetControl>,
    mut stats: ResMut<AslodStats>,
    store: Option<Res<DiagnosticsStore>>,
    clock: Res<MainWorldClock>,
    mut diag: Diagnostics,
) {
    let Some(target) = budget.frame_target else {
        control.controller = None;
        (stats.target_ms, stats.frame_ms) = (0.0, 0.0);
        stats.controller = ControllerState::default();
        stats.frame_source = FrameSource::None;
        return;
    };
    if control.controller.as_ref().map(|(t, _)| *t) != Some(target) {
        // A new or changed target starts from the budget there is.
        match FrameTimeController::new(target.ms, target.min..=target.max, budget.total) {
            Ok(c) => control.controller = Some((target, c)),
            Err(e) => {
                control.controller = None;
                if control.warned != Some(target) {
                    warn!("PolygonBudget::frame_target ignored: {e}");
                    control.warned = Some(target);
                }
                return;
            }
        }
    }
    // GPU timestamps when they come, else (and after a silence) the wall time.
    let gpu = store.and_then(|store| fresh_gpu_ms(&store, control.gpu_seen));
    let measured = match gpu {
        Some((gpu_ms, at)) => {
            control.gpu_seen = Some(at);
            control.gpu_silent = 0;
            Some(gpu_ms.max(clock.last_ms.unwrap_or(0.0)))
        }
        None => {
            control.gpu_silent = control.gpu_silent.saturating_add(1);
            None
        }
    };
    let (ms, source) = match measured {
        Some(ms) => (Some(ms), FrameSource::GpuTimestamps),
        // Between two read-backs the controller holds, as long as they keep coming.
        None if control.gpu_seen.is_some() && control.gpu_silent <= GPU_SILENCE => {
            (None, FrameSource::GpuTimestamps)
        }
        None => (Some(time.delta_secs() * 1e3), FrameSource::FrameDelta),
    };
    stats.frame_source = source;
    let Some(ms) = ms else {
        return;
    };
    let Some((_, controller)) = control.controller.as_mut() else {
        return;
    };
    let total = controller.update(ms);
    if budget.total != total {
        budget.total = total;
    }
    stats.target_ms = controller.target_ms();
    stats.frame_ms = controller.smoothed_ms().unwrap_or(0.0);
    stats.controller = controller.state();
    diag.add_measurement(&diagnostics::TARGET_MS, || f64::from(stats.target_ms));
    diag.add_measurement(&diagnostics::FRAME_MS, || f64::from(stats.frame_ms));
}
