//! A budget in milliseconds: before each split, [`control_budget`] moves
//! [`PolygonBudget::total`] so that frames take about [`FrameTarget::ms`].

use super::components::{AslodStats, FrameTarget, PolygonBudget};
use super::diagnostics;
use crate::budget::{ControllerState, FrameTimeController};
use bevy::diagnostic::Diagnostics;
use bevy::prelude::*;

/// The controller of the current [`FrameTarget`] (made anew when the target changes).
#[derive(Resource, Default)]
pub(crate) struct BudgetControl {
    controller: Option<(FrameTarget, FrameTimeController)>,
    /// The target last warned about as unusable.
    warned: Option<FrameTarget>,
}

/// Sets the frame's budget from the last frame's time when [`PolygonBudget::frame_target`]
/// is set; publishes the target, the smoothed frame time and the controller's state.
pub(crate) fn control_budget(
    mut budget: ResMut<PolygonBudget>,
    time: Res<Time<Real>>,
    mut control: ResMut<BudgetControl>,
    mut stats: ResMut<AslodStats>,
    mut diag: Diagnostics,
) {
    let Some(target) = budget.frame_target else {
        control.controller = None;
        (stats.target_ms, stats.frame_ms) = (0.0, 0.0);
        stats.controller = ControllerState::default();
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
    let Some((_, controller)) = control.controller.as_mut() else {
        return;
    };
    let total = controller.update(time.delta_secs() * 1e3);
    if budget.total != total {
        budget.total = total;
    }
    stats.target_ms = controller.target_ms();
    stats.frame_ms = controller.smoothed_ms().unwrap_or(0.0);
    stats.controller = controller.state();
    diag.add_measurement(&diagnostics::TARGET_MS, || f64::from(stats.target_ms));
    diag.add_measurement(&diagnostics::FRAME_MS, || f64::from(stats.frame_ms));
}
