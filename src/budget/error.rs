//! The error type of the polygon budget.

use thiserror::Error;

/// What can be wrong with the input of [`allocate`](super::allocate) or
/// [`ProjectedAreaCamera::new`](super::ProjectedAreaCamera::new). Each variant names the defect
/// and, where there is one, the region it was found in.
///
/// Everything that is not an error is clamped as documented on
/// [`allocate`](super::allocate#errors-and-clamps): a fixed cost above the budget, a `current`
/// count outside `[min, max]`, and an infinite α (the equal split).
#[derive(Clone, Copy, Debug, PartialEq, Error)]
#[non_exhaustive]
pub enum BudgetError {
    /// α was zero, negative or NaN. Use `f32::INFINITY` for an equal split.
    #[error("alpha must be positive (got {0}); use f32::INFINITY for an equal split")]
    InvalidAlpha(f32),
    /// A region's weight was NaN, infinite or negative.
    #[error("region {region}: weight {weight} is not a finite, non-negative number")]
    InvalidWeight {
        /// The region's index in the input slice.
        region: usize,
        /// The offending weight.
        weight: f32,
    },
    /// The total polygon budget `P` was zero.
    #[error("the polygon budget is zero")]
    ZeroBudget,
    /// A region's lower bound was above its upper bound.
    #[error("region {region}: min {min} is above max {max}")]
    MinAboveMax {
        /// The region's index in the input slice.
        region: usize,
        /// The region's lower bound.
        min: u32,
        /// The region's upper bound.
        max: u32,
    },
    /// The camera matrices or the viewport cannot be used for projected areas.
    #[error("unusable camera: {0}")]
    InvalidCamera(&'static str),
    /// A frame-time target was zero, negative or not finite.
    #[error("the frame-time target must be a positive number of milliseconds (got {0})")]
    InvalidTarget(f32),
    /// A budget range was empty or started at zero.
    #[error("the budget range {min}..={max} is empty or starts at 0")]
    InvalidRange {
        /// Its lower end.
        min: u32,
        /// Its upper end.
        max: u32,
    },
}
