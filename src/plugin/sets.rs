//! The plugin's system sets (configured in [`AslodPlugin::build`](super::AslodPlugin)).

use bevy::prelude::*;

/// The plugin's system sets, in [`PostUpdate`], in this order.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AslodSystems {
    /// Spawns region children for new models. Before [`TransformSystems::Propagate`](bevy::transform::TransformSystems::Propagate).
    Spawn,
    /// Splits the budget among all regions in view. After [`TransformSystems::Propagate`](bevy::transform::TransformSystems::Propagate)
    /// (needs world transforms) and camera updates. Runs on the main thread, which works
    /// through its parallel loop alongside the compute pool (so it does not overlap the app's
    /// other non-`Send` systems); likewise `SelectLod` and `Deform`.
    Allocate,
    /// Moves each region's polygon cache to its allocated count and writes the index buffers
    /// that changed. After `Allocate`.
    SelectLod,
    /// Blends the cached vertices of skinned regions. After `SelectLod`.
    Deform,
    /// Writes the index buffers of changed regions into their meshes and queues the new
    /// bytes for the renderer ([`RegionUpload`](super::RegionUpload)). After `Deform`.
    Upload,
}

/// Where every [`MultiresMaterialPlugin`](super::MultiresMaterialPlugin) copies its model
/// materials to the regions: in [`AslodSystems::Spawn`], after the regions are made.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) struct MaterialSystems;
