//! [`LoadLimits`]: how much a file may make the importers read and allocate.

use super::{MeshError, MeshResult};
use std::io::Read;
use std::path::Path;

/// How much one file may make the importers read and allocate. Every count a limit guards
/// is summed from the file's own metadata (a glTF's accessor counts times the nodes that
/// show them, an OBJ's lines, a PLY's header, a `.mrm` file's section headers) and checked
/// before anything proportional to it is allocated; exceeding one is
/// [`MeshError::LimitExceeded`], naming it. The same limits hold for every reader and entry
/// point: [`IndexedMesh::load_with_limits`](super::IndexedMesh::load_with_limits) and the
/// OBJ, PLY and glTF readers, `mrm::read_with_limits`, the plugin's `.mrm` loader and
/// `MultiresScene` (through `AslodPlugin::load_limits`), and the `aslod` command line.
///
/// # Peak memory
/// A read within the limits allocates at most [`peak_bytes`](Self::peak_bytes):
///
/// `3 × file_bytes + 256 × json_bytes + decoded_bytes + 128 B × vertices + 512 B × triangles`
///
/// The file is held whole while it is read, and a `data:` URI in a glTF's JSON also as the
/// parsed string and the buffer it decodes to; the rest of the JSON takes up to about 200
/// bytes per byte once parsed (a list of empty objects, measured); a vertex takes at most
/// about 100 bytes with every attribute; a triangle its indices and, for a glTF primitive
/// with a normal map and no tangents, MikkTSpace's working memory of about 500 bytes
/// (`tests/limits.rs` checks the bound on every real test file, and that crafted files over
/// a limit are refused before they allocate more than a small multiple of their size).
///
/// The defaults keep that bound under 8 GB (6.4 GB) and still read a real game asset of a few
/// million triangles: a 512 MiB file, 4 MiB of glTF JSON, 1 GiB of decoded attribute data,
/// 4 Mi (4,194,304) vertices and triangles, 65,536 joints per skin, a million assets in one
/// `.mrm` file. A server reading files from untrusted sources on a smaller machine lowers
/// them; a pipeline with larger trusted files raises them (building a progressive mesh then
/// takes about 300–550 bytes per triangle, `docs/performance.md`, "Bounded import").
///
/// # Example
/// ```
/// use bevy_aslod::mesh::{IndexedMesh, LoadLimits, MeshError};
///
/// let limits = LoadLimits { file_bytes: 1_000, ..LoadLimits::default() };
/// let e = IndexedMesh::load_with_limits("../shared/testdata/meshes/cow.obj", &limits).unwrap_err();
/// assert!(matches!(e, MeshError::LimitExceeded { limit: "file_bytes", .. }));
/// assert!(LoadLimits::default().peak_bytes() < 8_000_000_000);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoadLimits {
    /// Bytes of the file, together with every external buffer a glTF names (summed from
    /// their declared lengths before any is read).
    pub file_bytes: u64,
    /// Bytes of a glTF's JSON (the whole `.gltf`, or a GLB's JSON chunk) outside its strings
    /// of 1 KiB or more, checked before it is parsed. Those (`data:` URIs, mostly) parse
    /// into one allocation each and count against [`file_bytes`](Self::file_bytes) only.
    pub json_bytes: u64,
    /// Bytes of attribute and index data decoded from a glTF's accessors, in total (an
    /// accessor read once per node that shows its mesh counts each time), and of the vertices
    /// a `.mrm` file's regions copy.
    pub decoded_bytes: u64,
    /// Vertices of the mesh read (of all of a `.mrm` file's assets together; for an OBJ, also
    /// each of its `v`, `vt` and `vn` lists).
    pub vertices: u64,
    /// Triangles of the mesh read (of all of a `.mrm` file's assets together).
    pub triangles: u64,
    /// Joints of one skin.
    pub joints: u64,
    /// Assets (keys) in one `.mrm` file.
    pub keys: u64,
}

impl Default for LoadLimits {
    fn default() -> Self {
        Self {
            file_bytes: 512 << 20,
            json_bytes: 4 << 20,
            decoded_bytes: 1 << 30,
            vertices: 1 << 22,
            triangles: 1 << 22,
            joints: 65_536,
            keys: 1 << 20,
        }
    }
}

impl LoadLimits {
    /// No limits at all (every one at `u64::MAX`): for files from trusted sources only.
    pub const UNLIMITED: Self = Self {
        file_bytes: u64::MAX,
        json_bytes: u64::MAX,
        decoded_bytes: u64::MAX,
        vertices: u64::MAX,
        triangles: u64::MAX,
        joints: u64::MAX,
        keys: u64::MAX,
    };

    /// Small limits, whose [`peak_bytes`](Self::peak_bytes) is under 400 MB: a 16 MiB file,
    /// 256 KiB of glTF JSON, 64 MiB decoded, 256 Ki vertices and triangles. For a server
    /// reading untrusted files on a small machine, and for the fuzz targets, which run under
    /// `-rss_limit_mb=1024` (`fuzz/`).
    ///
    /// ```
    /// use bevy_aslod::mesh::LoadLimits;
    ///
    /// assert!(LoadLimits::SMALL.peak_bytes() < 400_000_000);
    /// ```
    pub const SMALL: Self = Self {
        file_bytes: 16 << 20,
        json_bytes: 256 << 10,
        decoded_bytes: 64 << 20,
        vertices: 1 << 18,
        triangles: 1 << 18,
        joints: 65_536,
        keys: 65_536,
    };

    /// Bytes parsing one byte of glTF JSON may take, at most (about 200 measured).
    pub const JSON_FACTOR: u64 = 256;
    /// Bytes one vertex may take while it is read, at most.
    pub const BYTES_PER_VERTEX: u64 = 128;
    /// Bytes one triangle may take while it is read, at most.
    pub const BYTES_PER_TRIANGLE: u64 = 512;

    /// The most bytes a read within these limits allocates at once (see "Peak memory"
    /// above), saturating at `u64::MAX`.
    #[must_use]
    pub const fn peak_bytes(&self) -> u64 {
        self.file_bytes
            .saturating_mul(3)
            .saturating_add(self.json_bytes.saturating_mul(Self::JSON_FACTOR))
            .saturating_add(self.decoded_bytes)
            .saturating_add(self.vertices.saturating_mul(Self::BYTES_PER_VERTEX))
            .saturating_add(self.triangles.saturating_mul(Self::BYTES_PER_TRIANGLE))
    }

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
        // Room for the length the file has now, so that reading does not double the buffer
        // as it grows (a file that grows meanwhile still stops at the limit).
        let mut bytes = Vec::with_capacity(usize::try_from(length).unwrap_or(0).saturating_add(1));
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
