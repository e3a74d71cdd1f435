//! Bounding volumes of point sets: the [`Obb`] (oriented bounding box) and its fits
//! ([`fit_obb`], tight, from the convex hull; [`fit_obb_pca`], fast; [`fit_aabb`],
//! axis-aligned), and the convex hulls they are built on (a 3D quickhull and a 2D monotone
//! chain, in `f64`, crate-internal).
//!
//! The boxes are fitted once, offline (per region when [`regions`](crate::regions) partitions a
//! mesh, stored in an [`mrm`](crate::mrm) asset), and moved into the world every frame by
//! [`Obb::transformed`] for the [`budget`](crate::budget), which projects them to screen areas
//! (its near-plane clip reuses the 2D hull). Plain Rust on glam, below every other module that
//! uses them.
//!
//! ```
//! use bevy_aslod::bounds::{fit_aabb, fit_obb};
//! use glam::Vec3;
//!
//! let points = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.5)];
//! let tight = fit_obb(&points).expect("finite points");
//! let aligned = fit_aabb(&points).expect("finite points");
//! for p in points {
//!     assert!(tight.contains_point(p, 1e-5) && aligned.contains_point(p, 1e-5));
//! }
//! ```

mod hull;
mod obb;

pub(crate) use hull::{PointStack, monotone_chain};
pub use obb::{Obb, fit_aabb, fit_obb, fit_obb_pca};
