//! A polygon budget set in milliseconds: [`FrameTimeController`] moves `P` so that frames take
//! about a target time (Funkhouser and Séquin's goal, with Hoppe's regulation of the rate).
//!
//! The controller integrates the log-ratio of the target to the measured frame time into
//! `ln P`: `ln P ← ln P + k · ln(T / m̄)`, where `m̄` is the measured time smoothed over a few
//! frames. If the frame costs `a + b·P`, `d ln m / d ln P = bP / (a + bP) ≤ 1`, so with
//! `k = 0.25` each frame removes at least a quarter of the error the triangles can remove, and
//! the loop stays stable with the measurement two frames late (as pipelined rendering makes
//! it). Within a dead band of ±3 % around the target `P` holds still, so measurement noise
//! does not make it wander; a step is at most ×1.25 or ÷1.25 per frame; `P` stays within its
//! bounds.
//!
//! ```
//! use bevy_aslod::budget::{ControllerState, FrameTimeController};
//!
//! // Frames cost 2 ms plus 0.1 ms per thousand triangles; the target is 8 ms.
//! let mut control = FrameTimeController::new(8.0, 1_000..=1_000_000, 10_000).unwrap();
//! let mut budget = control.budget();
//! for _ in 0..200 {
//!     let frame_ms = 2.0 + 1e-4 * budget as f32;
//!     budget = control.update(frame_ms);
//! }
//! // (8 − 2) / 1e-4 = 60,000 triangles, within the dead band.
//! assert!((budget as f32 - 60_000.0).abs() < 0.05 * 60_000.0);
//! assert_eq!(control.state(), ControllerState::Steady);
//! ```

use super::BudgetError;
use std::ops::RangeInclusive;

/// The share of the log error applied per frame.
const GAIN: f64 = 0.25;
/// Within this log-ratio of the target (about ±3 %) the budget holds still.
const DEAD_BAND: f64 = 0.03;
/// The largest change of `ln P` in one frame (×1.25).
const MAX_STEP: f64 = 0.223_143_551_314_209_76;
/// The weight of a new frame in the smoothed frame time.
const SMOOTHING: f64 = 0.35;

/// What a [`FrameTimeController`] is doing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "bevy", derive(bevy::reflect::Reflect))]
pub enum ControllerState {
    /// No frame measured yet.
    #[default]
    Waiting,
    /// Moving `P` towards the target.
    Settling,
    /// Within the dead band: `P` holds.
    Steady,
    /// Frames are slower than the target at the smallest `P` allowed.
    AtMinimum,
    /// Frames are faster than the target at the largest `P` allowed.
    AtMaximum,
}

/// Sets the polygon budget `P` from measured frame times so that frames take about a target
/// time (see the [module documentation](self)).
#[derive(Clone, Debug, PartialEq)]
pub struct FrameTimeController {
    target_ms: f32,
    min: u32,
    max: u32,
    log_p: f64,
    smoothed_ms: Option<f64>,
    state: ControllerState,
}

impl FrameTimeController {
    /// A controller aiming at `target_ms` per frame, keeping `P` within `range`, starting from
    /// `start` (clamped into the range).
    ///
    /// # Errors
    /// [`BudgetError::InvalidTarget`] for a target that is not a positive, finite time;
    /// [`BudgetError::InvalidRange`] for a range that is empty or starts at `0`.
    pub fn new(
        target_ms: f32,
        range: RangeInclusive<u32>,
        start: u32,
    ) -> Result<Self, BudgetError> {
        let (min, max) = (*range.start(), *range.end());
        if min == 0 || min > max {
            return Err(BudgetError::InvalidRange { min, max });
        }
        let mut control = Self {
            target_ms: 1.0,
            min,
            max,
            log_p: f64::from(start.clamp(min, max)).ln(),
            smoothed_ms: None,
            state: ControllerState::Waiting,
        };
        control.set_target_ms(target_ms)?;
        Ok(control)
    }

    /// The budget now.
    #[must_use]
    pub fn budget(&self) -> u32 {
        // `ln P` stays within [ln min, ln max], so the cast cannot overflow.
        (self.log_p.exp().round() as u32).clamp(self.min, self.max)
    }

    /// The target frame time in milliseconds.
    #[must_use]
    pub fn target_ms(&self) -> f32 {
        self.target_ms
    }

    /// Aims at another frame time, from the budget it has now.
    ///
    /// # Errors
    /// [`BudgetError::InvalidTarget`] for a time that is not positive and finite (the
    /// target stays as it was).
    pub fn set_target_ms(&mut self, target_ms: f32) -> Result<(), BudgetError> {
        if !(target_ms.is_finite() && target_ms > 0.0) {
            return Err(BudgetError::InvalidTarget(target_ms));
        }
        self.target_ms = target_ms;
        Ok(())
    }

    /// The bounds of `P`.
    #[must_use]
    pub fn range(&self) -> RangeInclusive<u32> {
        self.min..=self.max
    }

    /// The smoothed frame time the last update used (`None` before the first).
    #[must_use]
    pub fn smoothed_ms(&self) -> Option<f32> {
        self.smoothed_ms.map(|m| m as f32)
    }

    /// What the controller is doing.
    #[must_use]
    pub fn state(&self) -> ControllerState {
        self.state
    }

    /// Takes the time the last frame took and returns the budget for the next. A time that
    /// is not positive and finite (a paused clock, a first frame) is skipped.
    pub fn update(&mut self, frame_ms: f32) -> u32 {
        if !(frame_ms.is_finite() && frame_ms > 0.0) {
            return self.budget();
        }
        let frame_ms = f64::from(frame_ms);
        let smoothed = match self.smoothed_ms {
            Some(m) => m + SMOOTHING * (frame_ms - m),
            None => frame_ms,
        };
        self.smoothed_ms = Some(smoothed);
        let error = (f64::from(self.target_ms) / smoothed).ln();
        let (lo, hi) = (f64::from(self.min).ln(), f64::from(self.max).ln());
        if error.abs() <= DEAD_BAND {
            self.state = ControllerState::Steady;
            return self.budget();
        }
        self.log_p = (self.log_p + (GAIN * error).clamp(-MAX_STEP, MAX_STEP)).clamp(lo, hi);
        self.state = if error < 0.0 && self.log_p <= lo {
            ControllerState::AtMinimum
        } else if error > 0.0 && self.log_p >= hi {
            ControllerState::AtMaximum
        } else {
            ControllerState::Settling
        };
        self.budget()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64 in [-1, 1).
    struct Noise(u64);

    impl Noise {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 23) as f32 - 1.0
        }
    }

    /// A frame that costs `a + b·P` ms (`P` of `lag` frames before), times `1 ± noise`.
    struct Scene {
        a: f32,
        b: f32,
        noise: f32,
        lag: usize,
        rng: Noise,
        history: Vec<u32>,
    }

    impl Scene {
        fn new(a: f32, b: f32, noise: f32, lag: usize) -> Self {
            Self {
                a,
                b,
                noise,
                lag,
                rng: Noise(0x2545_F491_4F6C_DD1D),
                history: Vec::new(),
            }
        }

        /// Shows `budget` this frame; returns the frame time measured now.
        fn frame(&mut self, budget: u32) -> f32 {
            self.history.push(budget);
            let k = self.history.len().saturating_sub(1 + self.lag);
            let p = self.history[k] as f32;
            (self.a + self.b * p) * (1.0 + self.noise * self.rng.next())
        }
    }

    fn median(mut v: Vec<f32>) -> f32 {
        v.sort_by(f32::total_cmp);
        v[v.len() / 2]
    }

    /// Runs `frames` frames; returns (budget, frame time) per frame.
    fn run(control: &mut FrameTimeController, scene: &mut Scene, frames: usize) -> Vec<(u32, f32)> {
        let mut budget = control.budget();
        (0..frames)
            .map(|_| {
                let ms = scene.frame(budget);
                let shown = budget;
                budget = control.update(ms);
                (shown, ms)
            })
            .collect()
    }

    #[test]
    fn it_converges_holds_still_and_recovers_from_a_load_step() {
        // 1 ms fixed, 0.1 ms per thousand triangles, ±8 % noise, measured two frames late.
        let target = 10.0;
        let mut control = FrameTimeController::new(target, 1_000..=2_000_000, 5_000).unwrap();
        let mut scene = Scene::new(1.0, 1e-4, 0.08, 2);
        let before = run(&mut control, &mut scene, 300);
        let steady = &before[100..];
        let med = median(steady.iter().map(|f| f.1).collect());
        assert!((med / target - 1.0).abs() <= 0.1, "median {med} ms");
        let mut times: Vec<f32> = steady.iter().map(|f| f.1).collect();
        times.sort_by(f32::total_cmp);
        let p95 = times[times.len() * 95 / 100];
        assert!(p95 <= 1.3 * target, "p95 {p95} ms");
        for w in steady.windows(2) {
            let change = (w[1].0 as f32 / w[0].0 as f32 - 1.0).abs();
            assert!(change <= 0.05, "P moved {:.1}% in a frame", change * 100.0);
        }
        // The load doubles (the camera turns to a dense area): settles within 30 frames.
        scene.b *= 2.0;
        let after = run(&mut control, &mut scene, 200);
        let settled = after[30..].iter().map(|f| f.1).collect::<Vec<_>>();
        let med = median(settled.clone());
        assert!(
            (med / target - 1.0).abs() <= 0.1,
            "median {med} ms after the step"
        );
        let equilibrium = (target - scene.a) / scene.b;
        let p = median(after[30..].iter().map(|f| f.0 as f32).collect());
        assert!(
            (p / equilibrium - 1.0).abs() <= 0.1,
            "P {p} against {equilibrium} after the step"
        );
    }

    #[test]
    fn it_stays_within_its_bounds() {
        // The fixed cost alone is above the target: P goes to its minimum and stays.
        let mut control = FrameTimeController::new(5.0, 2_000..=50_000, 20_000).unwrap();
        let mut scene = Scene::new(8.0, 1e-4, 0.05, 1);
        let frames = run(&mut control, &mut scene, 200);
        assert!(frames.iter().all(|f| (2_000..=50_000).contains(&f.0)));
        assert_eq!(control.budget(), 2_000);
        assert_eq!(control.state(), ControllerState::AtMinimum);
        // Far faster than the target: P goes to its maximum.
        let mut control = FrameTimeController::new(100.0, 2_000..=50_000, 20_000).unwrap();
        let mut scene = Scene::new(1.0, 1e-5, 0.05, 1);
        run(&mut control, &mut scene, 200);
        assert_eq!(control.budget(), 50_000);
        assert_eq!(control.state(), ControllerState::AtMaximum);
    }

    #[test]
    fn bad_targets_ranges_and_frames_are_refused_or_skipped() {
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let made = FrameTimeController::new(bad, 1..=10, 5);
            assert!(matches!(made, Err(BudgetError::InvalidTarget(_))), "{bad}");
        }
        for (min, max) in [(0, 10), (20, 10)] {
            let made = FrameTimeController::new(8.0, min..=max, 5);
            assert!(
                matches!(made, Err(BudgetError::InvalidRange { .. })),
                "{min}..={max}"
            );
        }
        let mut control = FrameTimeController::new(8.0, 1_000..=10_000, 50_000).unwrap();
        assert_eq!(control.budget(), 10_000, "the start is clamped");
        for skipped in [0.0, -3.0, f32::NAN, f32::INFINITY] {
            assert_eq!(control.update(skipped), 10_000);
        }
        assert_eq!(control.state(), ControllerState::Waiting);
        assert!(control.set_target_ms(-1.0).is_err());
        assert_eq!(control.target_ms(), 8.0);
    }
}
