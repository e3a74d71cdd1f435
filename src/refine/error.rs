//! The error type of view-dependent refinement.

use thiserror::Error;

/// What can be wrong with the input of a view-dependent extraction. Nothing is clamped
/// silently: a bad camera, tolerance or criterion is an error that names it.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
#[non_exhaustive]
pub enum RefineError {
    /// The progressive mesh was built without the view-dependent data.
    #[error(
        "the progressive mesh has no view-dependent data: build it with \
         BuildOptions::default().with_view_dependent(true)"
    )]
    NoViewData,
    /// A screen-space tolerance was NaN, infinite or negative.
    #[error("the screen-space tolerance must be finite and not negative (got {0} pixels)")]
    InvalidTolerance(f32),
    /// The camera cannot be used: what is wrong with it.
    #[error("unusable camera: {0}")]
    InvalidCamera(&'static str),
    /// A criterion's settings cannot be used: what is wrong with them.
    #[error("unusable criterion: {0}")]
    InvalidCriterion(&'static str),
    /// A cache was used with a mesh other than the one it was made for.
    #[error("the cache holds {cache} triangles, the mesh {mesh}: it was made for another mesh")]
    MeshMismatch {
        /// Triangles (slots) of the cache.
        cache: usize,
        /// Triangles of the mesh.
        mesh: usize,
    },
}
