//! The polygon budget: one global triangle count `P` split among every region in view
//! (ASLOD, section 3).
//!
//! Each frame, for every region `i`:
//!
//! 1. its bind-pose [`Obb`] (fitted once, offline, by [`fit_obb`]) is moved into the world by
//!    [`Obb::transformed`];
//! 2. [`ProjectedAreaCamera::projected_area`] gives its screen area `Aᵢ` in pixels²
//!    (Schmalstieg & Tobler's table method, clipped to the near plane and the viewport);
//! 3. [`allocate`] turns the weights `wᵢ = cᵢ · Aᵢ` (`cᵢ` a user priority) into triangle counts
//!
//!    ```text
//!    pᵢ = P' · wᵢ^(1/α) / Σⱼ wⱼ^(1/α),     P' = P − fixed cost of conventional meshes,
//!    ```
//!
//!    clamped to `[minᵢ, maxᵢ]` with the surplus passed on (water-filling), rounded so that
//!    `Σ pᵢ ≤ P'`, and held by a hysteresis ε.
//!
//! This module is plain Rust on glam; the Bevy plugin calls it every frame.
//!
//! # Choosing α
//!
//! α sets how strongly size wins. With two regions whose weights differ by a factor of 100
//! (one region ten times wider on screen than the other):
//!
//! | α | `pᵢ ∝` | share of the larger region | reads as |
//! |---|---|---|---|
//! | 1 | `wᵢ` | 99 % | proportional to area |
//! | 2 | `√wᵢ` | 91 % | proportional to on-screen size (width) |
//! | **3** (default) | `∛wᵢ` | 82 % | the paper's choice; Funkhouser & Séquin's benefit |
//! | 6 | `wᵢ^(1/6)` | 68 % | mild preference for size |
//! | ∞ | `1` | 50 % | equal split (use `f32::INFINITY`) |
//!
//! Below 1 the largest regions take more than their area's share; as α → 0 the single largest
//! takes everything it can hold. The default, [`DEFAULT_ALPHA`] `= 3`, is the paper's: with
//! `wᵢ = 2·Aᵢ·cᵢ` it reproduces the discrete optimisation of Funkhouser & Séquin (1993), whose
//! benefit grows with area but with diminishing returns per triangle, so small regions keep
//! enough triangles to hold their silhouette while large ones still get most of the budget.
//! The constant factor 2 cancels in the formula, so [`RegionInput::from_area`] uses
//! `wᵢ = cᵢ · Aᵢ`.
//!
//! # Conventions
//!
//! Counts are triangles. Areas are pixels² of the viewport given to [`ProjectedAreaCamera`].
//! Weights need no normalisation: [`allocate`] divides by the largest one itself.

mod allocate;
mod error;
mod hull;
mod obb;
mod projected_area;

pub use allocate::{
    AllocationParams, AllocationReport, Allocator, DEFAULT_ALPHA, RegionInput, allocate,
};
pub use error::BudgetError;
pub use obb::{Obb, fit_aabb, fit_obb, fit_obb_pca};
pub use projected_area::{ProjectedAreaCamera, silhouette};
