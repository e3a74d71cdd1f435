//! The polygon budget: one global triangle count `P` split among every region in view
//! (ASLOD, section 3).
//!
//! Each frame, for every region `i`:
//!
//! 1. its bind-pose [`Obb`] (fitted once, offline, by [`fit_obb`]; both from
//!    [`bounds`](crate::bounds)) is moved into the world by [`Obb::transformed`];
//! 2. [`ProjectedAreaCamera::projected_area`] gives its screen area `Aᵢ` in pixels²
//!    (Schmalstieg & Tobler's table method, clipped to the near plane and the viewport);
//!    [`ProjectedAreaCamera::projected_areas`] does many boxes, the common case four at a
//!    time, and [`ProjectedAreaCamera::may_see`] culls a whole model's box first;
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
//! ```
//! use bevy_aslod::budget::{
//!     AllocationParams, Allocator, ProjectedAreaCamera, RegionInput, fit_obb,
//! };
//! use glam::{Affine3A, Mat4, Vec2, Vec3};
//!
//! // Offline: one box per region, in the model's space.
//! let region_points = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.5)];
//! let local_box = fit_obb(&region_points).expect("finite points");
//!
//! // Every frame: the camera, then each instance of each region.
//! let view = Mat4::look_at_rh(Vec3::new(0.0, 2.0, 8.0), Vec3::ZERO, Vec3::Y);
//! let projection = Mat4::perspective_infinite_reverse_rh(0.8, 16.0 / 9.0, 0.1);
//! let camera = ProjectedAreaCamera::new(view, projection, Vec2::new(1920.0, 1080.0))?;
//! let instances = [Affine3A::IDENTITY, Affine3A::from_translation(Vec3::new(3.0, 0.0, -20.0))];
//! let regions: Vec<RegionInput> = instances
//!     .iter()
//!     .map(|model| {
//!         let area = camera.projected_area(&local_box.transformed(model));
//!         RegionInput::from_area(area, 1.0, 50, 20_000, 0)
//!     })
//!     .collect();
//!
//! let mut allocator = Allocator::new(); // keep it across frames
//! let mut counts = Vec::new();
//! let params = AllocationParams { budget: 10_000, ..Default::default() };
//! let report = allocator.allocate(&params, &regions, &mut counts)?;
//! assert!(report.total <= 10_000);
//! assert!(counts[0] > counts[1]); // the near instance gets more
//! # Ok::<(), bevy_aslod::budget::BudgetError>(())
//! ```
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
//! `wᵢ = 2·Aᵢ·cᵢ`, it says (after Wimmer & Schmalstieg 1998), the formula is equivalent to the
//! discrete optimisation of Funkhouser & Séquin (1993), whose benefit grows with area with
//! diminishing returns per triangle. In practice small regions keep enough triangles to hold
//! their silhouette while large ones still get most of the budget.
//! The constant factor 2 cancels in the formula, so [`RegionInput::from_area`] uses
//! `wᵢ = cᵢ · Aᵢ`.
//!
//! # Conventions
//!
//! Counts are triangles. Areas are pixels² of the viewport given to [`ProjectedAreaCamera`].
//! Weights need no normalisation: [`allocate`] divides by the largest one itself.

mod allocate;
mod error;
mod frame_time;
mod projected_area;

/// The boxes the budget projects, re-exported from [`bounds`](crate::bounds), where they live
/// (they were defined here before): `budget::Obb` and `budget::fit_obb` stay valid paths.
pub use crate::bounds::{Obb, fit_aabb, fit_obb, fit_obb_pca};
pub use allocate::{
    AllocationParams, AllocationReport, Allocator, DEFAULT_ALPHA, DEFAULT_BUDGET, Executor,
    RegionInput, Sequential, allocate,
};
pub use error::BudgetError;
pub use frame_time::{ControllerState, FrameTimeController};
pub use projected_area::{ProjectedAreaCamera, silhouette};
