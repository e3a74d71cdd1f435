//! What can go wrong when building or loading a [`MultiresMesh`](super::MultiresMesh).

use crate::mesh::MeshError;
use crate::mrm::BakeError;
use crate::regions::RegionError;
use thiserror::Error;

/// What can go wrong when building a [`MultiresMesh`](super::MultiresMesh).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum MultiresError {
    /// The source mesh could not be read or is invalid.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Partitioning or building the regions failed.
    #[error(transparent)]
    Region(#[from] RegionError),
    /// The skin's influences are invalid.
    #[error(transparent)]
    Skin(#[from] crate::skin::SkinError),
    /// A skinned build was asked of a mesh without joints or weights.
    #[error("the mesh has no joints or weights (JOINTS_0/WEIGHTS_0): it is not skinned")]
    NotSkinned,
    /// Building the asset panicked (a bug in this crate; please report it with the mesh).
    #[error("building the multiresolution mesh panicked")]
    BuildPanicked,
    /// The view-dependent data could not be prepared.
    #[error(transparent)]
    Refine(#[from] crate::refine::RefineError),
    /// An inverse bind matrix has a NaN or infinite entry.
    #[error("inverse bind matrix {joint} is not finite")]
    NonFiniteBindpose {
        /// The joint.
        joint: usize,
    },
    /// Baked data whose parts do not fit together (see [`MultiresMesh::from_baked`](super::MultiresMesh::from_baked)).
    #[error("baked asset: {0}")]
    Baked(&'static str),
}

impl From<BakeError> for MultiresError {
    fn from(e: BakeError) -> Self {
        match e {
            BakeError::Mesh(e) => Self::Mesh(e),
            BakeError::Region(e) => Self::Region(e),
            BakeError::Skin(e) => Self::Skin(e),
            BakeError::NotSkinned => Self::NotSkinned,
            BakeError::NonFiniteBindpose { joint } => Self::NonFiniteBindpose { joint },
        }
    }
}
