#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

#[cfg(feature = "bevy")]
pub mod bevy_mesh;
pub mod budget;
pub mod distance;
pub mod mannequin;
pub mod mesh;
pub mod multires;
#[cfg(feature = "bevy")]
pub mod plugin;
pub mod regions;
pub mod skin;

/// The types most users need.
pub mod prelude {
    pub use crate::mesh::{IndexedMesh, MeshError};
    pub use crate::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
    #[cfg(feature = "bevy")]
    pub use crate::plugin::{
        AslodOverlay, AslodPlugin, AslodStats, AslodSystems, AslodViewport, CountInBudget,
        LodPriority, LodRegion, MultiresInstance, MultiresMesh, MultiresModel, PartitionSpec,
        PolygonBudget,
    };
}
