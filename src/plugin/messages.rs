//! What the plugin tells the app, as Bevy [`Message`]s: read them with a
//! `MessageReader` instead of polling for `Added<MultiresInstance>` or logs.
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_aslod::plugin::{MultiresBuildFailed, MultiresModelReady, MultiresSceneConverted};
//!
//! fn on_aslod(
//!     mut ready: MessageReader<MultiresModelReady>,
//!     mut failed: MessageReader<MultiresBuildFailed>,
//!     mut scenes: MessageReader<MultiresSceneConverted>,
//! ) {
//!     for m in ready.read() {
//!         info!("{} shows its regions", m.model);
//!     }
//!     for f in failed.read() {
//!         warn!("{} stays as it was: {}", f.entity, f.error);
//!     }
//!     for s in scenes.read() {
//!         info!("scene {}: {} models", s.scene, s.models.models().count());
//!     }
//! }
//! # App::new().add_systems(Update, on_aslod);
//! ```

use super::asset::MultiresMesh;
use bevy::prelude::*;

/// A `MultiresModel` got its regions: its asset is loaded (or built)
/// and the plugin spawned what draws it. Written again after a rebuild (another handle, or
/// a hot-reloaded asset).
#[derive(Message, Clone, Debug, PartialEq, Eq)]
pub struct MultiresModelReady {
    /// The model entity.
    pub model: Entity,
    /// The asset it shows.
    pub asset: AssetId<MultiresMesh>,
}

/// Something could not become multiresolution: a `MultiresModel`'s
/// asset failed to load (the model draws nothing), or a `MultiresScene`
/// mesh failed to build or to load from its baked file (the mesh stays conventional and
/// counts its triangles against the budget). Written once per entity and asset.
#[derive(Message, Clone, Debug, PartialEq, Eq)]
pub struct MultiresBuildFailed {
    /// The model entity, or the scene's mesh entity.
    pub entity: Entity,
    /// What went wrong.
    pub error: String,
}
