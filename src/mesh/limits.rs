//! [`LoadLimits`]: how much a file may make the importers read and allocate.

use super::{MeshError, MeshResult};
use std::io::Read;
use std::path::Path;

/// How much one file may make the importers read and allocate, checked before anything is
/// allocated. The defaults are generous for real assets (a 2 GiB file, 2 GiB of decoded
/// attribute data, 100 million vertices and triangles, 65,536 joints per skin, a million
/// assets in one `.mrm` file); a server
/// baking files from untrusted sources may lower them, a pipeline with larger trusted files
/// may raise them. Exceeding one is [`MeshError::LimitExceeded`], naming it.
///
/// # Example
/// ```
/// use bevy_aslod::mesh::{IndexedMesh, LoadLimits, MeshError};
///
/// let limits = LoadLimits { file_bytes: 1_000, ..LoadLimits::default() };
/// let e = IndexedMesh::load_with_limits("../shared/testdata/meshes/cow.obj", &limits).unwrap_err();
/// assert!(matches!(e, MeshError::LimitExceeded { limit: "file_bytes", .. }));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoadLimits {
    /// Bytes of the file, and of each external buffer a glTF names.
    pub file_bytes: u64,
    /// Bytes of attribute and index data decoded from a glTF's accessors, in total (an
    /// accessor read once per node that shows its mesh counts each time).
    pub decoded_bytes: u64,
    /// Vertices of the mesh read.
    pub vertices: u64,
    /// Triangles of the mesh read.
    pub triangles: u64,
    /// Joints of one skin.
    pub joints: u64,
    /// Assets (keys) in one `.mrm` file.
    pub keys: u64,
}

impl Default for LoadLimits {
    fn default() -> Self {
        Self {
            file_bytes: 2 << 30,
            decoded_bytes: 2 << 30,
            vertices: 100_000_000,
            triangles: 100_000_000,
            joints: 65_536,
            keys: 1 << 20,
        }
    }
}

impl LoadLimits {
    /// No limits at all (every one at `u64::MAX`): for files from trusted sources only.
    pub const UNLIMITED: Self = Self {
        file_bytes: u64::MAX,
        decoded_bytes: u64::MAX,
        vertices: u64::MAX,
        triangles: u64::MAX,
        joints: u64::MAX,
        keys: u64::MAX,
    };

    /// `Ok` when `value` is within limit `name` of value `max`.
    pub(crate) fn check(name: &'static str, value: u64, max: u64) -> MeshResult<()> {
        if value > max {
            return Err(MeshError::LimitExceeded {
                limit: name,
                value,
                max,
            });
        }
        Ok(())
    }

    /// Reads a whole file within [`file_bytes`](Self::file_bytes): its length is checked
    /// first, and no more than the limit is ever read (a device or a growing file stops
    /// there).
    ///
    /// # Errors
    /// [`MeshError::Io`] when the file cannot be read, [`MeshError::LimitExceeded`] when it
    /// is longer than the limit.
    pub fn read_file(&self, path: &Path) -> MeshResult<Vec<u8>> {
        let file = std::fs::File::open(path).map_err(|e| MeshError::io(path, e))?;
        let length = file.metadata().map_err(|e| MeshError::io(path, e))?.len();
        Self::check("file_bytes", length, self.file_bytes)?;
        let mut bytes = Vec::new();
        file.take(self.file_bytes.saturating_add(1))
            .read_to_end(&mut bytes)
            .map_err(|e| MeshError::io(path, e))?;
        Self::check("file_bytes", bytes.len() as u64, self.file_bytes)?;
        Ok(bytes)
    }

    /// `Ok` when `mesh` is within [`vertices`](Self::vertices) and
    /// [`triangles`](Self::triangles).
    pub(crate) fn check_mesh(&self, mesh: &super::IndexedMesh) -> MeshResult<()> {
        Self::check("vertices", mesh.positions.len() as u64, self.vertices)?;
        Self::check("triangles", (mesh.indices.len() / 3) as u64, self.triangles)
    }
}
