//! The `.mrm` asset loader: baked files become [`MultiresMesh`] assets without building.

use super::asset::MultiresMesh;
use super::error::MultiresError;
use crate::mesh::LoadLimits;
use crate::mrm::{self, MrmError};
use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, AsyncReadExt, LoadContext};
use bevy::reflect::TypePath;
use thiserror::Error;

/// Loads `.mrm` files of assets (`aslod bake`): `asset_server.load("bunny.mrm")` gives the
/// file's first asset as a [`MultiresMesh`], and every asset is also a labeled sub-asset
/// under its key (for a baked glTF scene, Bevy's primitive label:
/// `"scene.mrm#Mesh0/Primitive0"`). Registered by [`AslodPlugin`](super::AslodPlugin); with
/// Bevy's `file_watcher` feature a re-baked file reloads like any asset.
///
/// Files are read within [`limits`](Self::limits) (set through
/// [`AslodPlugin::load_limits`](super::AslodPlugin::load_limits)): no more than
/// `file_bytes` is read, and a file that asks for more keys, vertices, triangles, joints or
/// decoded bytes fails to load with [`MrmError::LimitExceeded`] naming the limit.
#[derive(Clone, Copy, Debug, Default, TypePath)]
pub struct MrmLoader {
    /// What one file may make the loader read and allocate.
    pub limits: LoadLimits,
}

/// Why an `.mrm` file did not load.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum MrmLoadError {
    /// The file could not be read.
    #[error("reading the .mrm file: {0}")]
    Io(#[from] std::io::Error),
    /// The file is damaged, from a newer version, or holds a progressive mesh only.
    #[error(transparent)]
    Mrm(#[from] MrmError),
    /// The file's data does not make an asset.
    #[error(transparent)]
    Multires(#[from] MultiresError),
    /// The file holds no asset.
    #[error("the .mrm file holds no asset")]
    Empty,
}

impl AssetLoader for MrmLoader {
    type Asset = MultiresMesh;
    type Settings = ();
    type Error = MrmLoadError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        load_context: &mut LoadContext<'_>,
    ) -> Result<MultiresMesh, MrmLoadError> {
        // One byte past the limit is enough to know a file is too long.
        let mut bytes = Vec::new();
        reader
            .take(self.limits.file_bytes.saturating_add(1))
            .read_to_end(&mut bytes)
            .await?;
        let file = mrm::read_with_limits(&bytes, &self.limits)?;
        let mut first = None;
        for (key, baked) in file.meshes {
            let asset = MultiresMesh::from_baked(baked)?;
            if first.is_none() {
                first = Some(asset.clone());
            }
            load_context.add_labeled_asset(key, asset);
        }
        first.ok_or(MrmLoadError::Empty)
    }

    fn extensions(&self) -> &[&str] {
        &["mrm"]
    }
}
