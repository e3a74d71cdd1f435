//! The error type of the skinning core.

use thiserror::Error;

/// What can be wrong with skin weights, a region painting or the mesh they belong to. Each
/// variant names the vertex, joint or region where the defect was found.
///
/// Everything that is not an error is normalised as documented on
/// [`Influences::new`](super::Influences::new) and counted in its
/// [`WeightReport`](super::WeightReport).
#[derive(Clone, Debug, PartialEq, Error)]
#[non_exhaustive]
pub enum SkinError {
    /// The skeleton has no joints, so no vertex can follow one.
    #[error("the skeleton has no joints")]
    NoJoints,
    /// Two per-vertex arrays that must be parallel have different lengths.
    #[error("{what} has {found} entries, expected {expected} (one per vertex)")]
    LengthMismatch {
        /// Which array is too long or too short.
        what: &'static str,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        found: usize,
    },
    /// A slot with a non-zero weight names a joint the skeleton does not have.
    #[error(
        "vertex {vertex}: joint {joint} has a non-zero weight but the skeleton has {joint_count} joints"
    )]
    JointOutOfRange {
        /// The vertex index.
        vertex: usize,
        /// The joint index found in the slot.
        joint: u16,
        /// Number of joints in the skeleton.
        joint_count: usize,
    },
    /// A weight is below `-1e-6` (smaller negatives are rounding noise and clamp to 0).
    #[error("vertex {vertex}: weight {weight} is negative")]
    NegativeWeight {
        /// The vertex index.
        vertex: usize,
        /// The offending weight.
        weight: f32,
    },
    /// A weight is NaN or infinite.
    #[error("vertex {vertex}: the weight in slot {slot} is NaN or infinite")]
    NonFiniteWeight {
        /// The vertex index.
        vertex: usize,
        /// The slot (0..4) of the offending weight.
        slot: usize,
    },
    /// All four weights of a vertex are zero: it follows no joint.
    #[error("vertex {vertex}: all weights are zero")]
    ZeroWeights {
        /// The vertex index.
        vertex: usize,
    },
    /// A vertex is painted with a region id that has no kind.
    #[error("vertex {vertex}: region {region} does not exist (there are {region_count} regions)")]
    RegionOutOfRange {
        /// The vertex index.
        vertex: usize,
        /// The region id found.
        region: u32,
        /// Number of region kinds given.
        region_count: usize,
    },
    /// A triangle corner refers to a vertex the mesh does not have.
    #[error(
        "index {corner}: vertex {index} is out of range (the mesh has {vertex_count} vertices)"
    )]
    IndexOutOfRange {
        /// Position of the corner in the index buffer.
        corner: usize,
        /// The vertex index found there.
        index: u32,
        /// Number of vertices in the mesh.
        vertex_count: usize,
    },
    /// A vertex of a deformable region cannot reach the rigid region of either of the
    /// region's bones along the region's edges, so it has no shortest-path weight.
    #[error(
        "deformable region {region}: vertex {vertex} reaches neither bone's rigid region \
         (is the region painted next to its two rigid regions?)"
    )]
    NoRegionBorder {
        /// The deformable region.
        region: u32,
        /// The first vertex of the region found unreachable.
        vertex: usize,
    },
}
