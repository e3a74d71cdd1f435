// The README's Bevy examples compile with the `bevy` feature; without it the crate keeps a
// short page of its own.
#![cfg_attr(feature = "bevy", doc = include_str!("../README.md"))]
#![cfg_attr(
    not(feature = "bevy"),
    doc = "Multiresolution meshes under one polygon budget: the core (`mesh`, `multires`, \
           `regions`, `refine`, `budget`, `mrm`) without Bevy. The README, the crate's page \
           with the default `bevy` feature, shows the plugin."
)]
#![warn(missing_docs)]

/// `with_FIELD` setters for an options struct that is `#[non_exhaustive]` (so that code outside
/// the crate, which cannot write its struct literal, sets fields by chaining from `default()`):
/// `with_setters!(Options { field: Type => with_field, ... });`
macro_rules! with_setters {
    ($ty:ty { $($field:ident: $fty:ty => $name:ident),* $(,)? }) => {
        impl $ty {
            $(
                #[doc = concat!("Sets [`", stringify!($field), "`](Self::", stringify!($field), ").")]
                #[inline]
                #[must_use]
                pub const fn $name(mut self, $field: $fty) -> Self {
                    self.$field = $field;
                    self
                }
            )*
        }
    };
}

#[cfg(feature = "bevy")]
pub mod bevy_mesh;
pub mod bounds;
pub mod budget;
#[cfg(feature = "distance")]
pub mod distance;
pub mod executor;
#[cfg(feature = "mannequin")]
pub mod mannequin;
pub mod mesh;
pub mod mrm;
pub mod multires;
#[cfg(feature = "bevy")]
pub mod plugin;
pub mod refine;
pub mod regions;
pub mod skin;
pub(crate) mod util;

/// The types most users need: `use bevy_aslod::prelude::*;`.
pub mod prelude {
    pub use crate::mesh::{IndexedMesh, MeshError};
    pub use crate::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
    #[cfg(feature = "bevy")]
    pub use crate::plugin::{
        AslodOverlay, AslodPlugin, AslodStats, AslodSystems, AslodViewport, CountInBudget,
        FullDetail, Geomorph, GeomorphMaterial, GpuGeomorph, LodPriority, LodRegion, MultiresError,
        MultiresInstance, MultiresMaterialPlugin, MultiresMesh, MultiresModel, MultiresScene,
        MultiresSceneModels, MultiresSkin, NoSharedLevels, PartitionSpec, PolygonBudget,
        RefineCamera, RegionSplit, RegionUpload, SharedLevels, ViewDependent,
    };
}
