//! Skinned multiresolution characters (ASLOD section 5): rigid and deformable regions,
//! shortest-path two-bone weights, linear blend skinning of cached vertices.
//!
//! A skin is cut into regions by how it depends on the skeleton (section 5.2), and each region
//! gets its own progressive sequence and polygon cache, as the regions of section 4 do:
//!
//! - a **rigid** region follows one bone: it is transformed, never deformed;
//! - a **deformable** region blends between two bones, for example an elbow between the
//!   upper and the lower arm.
//!
//! The pipeline, in the order it runs:
//!
//! 1. [`Influences::new`] validates glTF `JOINTS_0`/`WEIGHTS_0` and normalises them (sum 1,
//!    largest first), reporting what it fixed in a [`WeightReport`]. A mesh painted by region
//!    instead gets weights from [`shortest_path_weights`] (section 5.5).
//! 2. [`decompose`] assigns each vertex to the rigid region of its dominant bone, when that
//!    bone carries at least `1 - δ` of its weight, or else to the deformable region of its two
//!    largest influences.
//! 3. At runtime [`blend`] (or [`blend_with_rigid`]) skins only the vertices the caches refer
//!    to (section 5.4), writing into caller-owned buffers.
//!
//! Conventions: a vertex has at most [`MAX_INFLUENCES`] influences, stored largest weight
//! first; joint indices refer to the skin's joint list (glTF `skin.joints`), and `matrices[j]`
//! is joint `j`'s global transform times its inverse bind matrix. The paper allows one or two
//! bones per vertex; vertices with three or four influences are kept, counted, and blended
//! with all of them, but join the region of their two largest.
//!
//! # Example
//! A strip along X skinned to two bones, the second of which is raised by one unit.
//! ```
//! use bevy_aslod::skin::{
//!     DEFAULT_RIGID_DELTA, Influences, SkinRegionKind, blend_with_rigid, decompose,
//! };
//! use glam::{Mat4, Vec3};
//!
//! // Five vertices at x = 0..4: bone 0 holds x = 0, 1; bone 1 holds x = 3, 4; x = 2 is shared.
//! let positions: Vec<Vec3> = (0..5).map(|x| Vec3::new(x as f32, 0.0, 0.0)).collect();
//! let joints = [[0, 0, 0, 0], [0, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0]];
//! let weights = [
//!     [1.0, 0.0, 0.0, 0.0],
//!     [1.0, 0.0, 0.0, 0.0],
//!     [0.5, 0.5, 0.0, 0.0],
//!     [1.0, 0.0, 0.0, 0.0],
//!     [1.0, 0.0, 0.0, 0.0],
//! ];
//! let (influences, report) = Influences::new(&joints, &weights, 2)?;
//! assert_eq!(report.renormalised, 0);
//!
//! let skin = decompose(&positions, &influences, DEFAULT_RIGID_DELTA);
//! assert_eq!(skin.kinds[skin.region_of[2] as usize], SkinRegionKind::Deformable { bones: [0, 1] });
//! assert_eq!(skin.kinds[skin.region_of[4] as usize], SkinRegionKind::Rigid { bone: 1 });
//!
//! // Pose: bone 1 moves up by one. Skin only the vertices a cache refers to: 1, 2 and 4.
//! let matrices = [Mat4::IDENTITY, Mat4::from_translation(Vec3::Y)];
//! let mut out = positions.clone();
//! blend_with_rigid(&matrices, &positions, None, &influences, &skin.rigid, &[1, 2, 4], &mut out, None);
//! assert_eq!(out[1], Vec3::new(1.0, 0.0, 0.0));
//! assert_eq!(out[2], Vec3::new(2.0, 0.5, 0.0)); // halfway between the bones
//! assert_eq!(out[3], positions[3]); // not listed: untouched
//! assert_eq!(out[4], Vec3::new(4.0, 1.0, 0.0));
//! # Ok::<(), bevy_aslod::skin::SkinError>(())
//! ```

mod blend;
#[cfg(feature = "bevy")]
pub(crate) use blend::normal_matrix;
mod decompose;
mod error;
mod influences;
mod weights;

pub use blend::{
    blend, blend_with_rigid, blend_with_tangents, skin_normal, skin_position, skin_tangent,
};
pub use decompose::{SkinDecomposition, decompose};
pub use error::SkinError;
pub use influences::{Influences, WeightReport};
pub use weights::shortest_path_weights;

/// Most influences (joint and weight pairs) per vertex, as in glTF's `JOINTS_0`/`WEIGHTS_0`.
pub const MAX_INFLUENCES: usize = 4;

/// Default δ of [`decompose`]: a vertex whose dominant weight is at least `1 - δ` is rigid.
///
/// Small enough that only vertices an exporter wrote as single-bone (up to float rounding)
/// count as rigid.
pub const DEFAULT_RIGID_DELTA: f32 = 1e-5;

/// What a skin region depends on (section 5.2).
///
/// Ordered rigid before deformable, then by bone indices: the order of region ids that
/// [`decompose`] assigns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SkinRegionKind {
    /// Follows one bone (a joint index): transformed, never deformed.
    Rigid {
        /// The joint index.
        bone: u16,
    },
    /// Blends between two bones (joint indices, ascending: `bones[0] < bones[1]`).
    Deformable {
        /// The two joint indices, ascending.
        bones: [u16; 2],
    },
}

impl SkinRegionKind {
    /// True for [`SkinRegionKind::Rigid`].
    #[inline]
    #[must_use]
    pub fn is_rigid(self) -> bool {
        matches!(self, Self::Rigid { .. })
    }

    /// The bones the region depends on: one for a rigid region, two for a deformable one.
    #[inline]
    #[must_use]
    pub fn bones(&self) -> &[u16] {
        match self {
            Self::Rigid { bone } => std::slice::from_ref(bone),
            Self::Deformable { bones } => bones,
        }
    }
}
