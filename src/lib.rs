#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

#[cfg(feature = "bevy")]
pub mod bevy_mesh;
pub mod budget;
#[cfg(feature = "distance")]
pub mod distance;
#[cfg(feature = "mannequin")]
pub mod mannequin;
pub mod mesh;
pub mod multires;
#[cfg(feature = "bevy")]
pub mod plugin;
pub mod regions;
pub mod skin;

/// The types most users need: `use bevy_aslod::prelude::*;`.
pub mod prelude {
    pub use crate::mesh::{IndexedMesh, MeshError};
    pub use crate::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
    #[cfg(feature = "bevy")]
    pub use crate::plugin::{
        AslodOverlay, AslodPlugin, AslodStats, AslodSystems, AslodViewport, CountInBudget,
        FullDetail, LodPriority, LodRegion, MultiresError, MultiresInstance,
        MultiresMaterialPlugin, MultiresMesh, MultiresModel, MultiresScene, MultiresSceneModels,
        MultiresSkin, PartitionSpec, PolygonBudget, RegionUpload,
    };
}
