//! The `.mrm` file (Hoxha's MR-model): multiresolution assets baked once and loaded without
//! rebuilding. A file holds either **assets** ([`MrmFile`]: each a [`BakedMesh`], everything
//! the plugin's `MultiresMesh` is made of, under a key) or, as every version 1 file does,
//! **one progressive mesh** ([`read_progressive`]). `aslod bake` writes the first kind,
//! `aslod info` lists either, and the plugin's `MrmLoader` loads assets through Bevy's asset
//! server.
//!
//! ```
//! use bevy_aslod::mesh::IndexedMesh;
//! use bevy_aslod::mrm::{self, BakedMesh, BuildInfo, MrmFile};
//! use bevy_aslod::multires::BuildOptions;
//! use bevy_aslod::regions::Partition;
//!
//! let path = "../shared/testdata/meshes/cow.obj";
//! let (mesh, _) = IndexedMesh::load(path)?;
//! let partition = Partition::clusters(&mesh, 8)?;
//! let options = BuildOptions::default();
//! let cow = BakedMesh::build(&mesh, &partition, &options)?;
//! let file = MrmFile {
//!     build: BuildInfo {
//!         source_name: "cow.obj".into(),
//!         source_hash: mrm::source_hash(&std::fs::read(path)?),
//!         partition: "clusters:8".into(),
//!         writer: "a doctest".into(),
//!         rigid_delta: None,
//!         options,
//!     },
//!     meshes: vec![("Mesh0/Primitive0".into(), cow)],
//! };
//! let bytes = mrm::write(&file);
//! assert_eq!(mrm::read(&bytes)?, file);
//! // A damaged file is an error that names where, never a wrong mesh.
//! let mut damaged = bytes.clone();
//! damaged[bytes.len() / 2] ^= 0x10;
//! assert!(mrm::read(&damaged).is_err());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Layout (format version 5)
//!
//! Little-endian throughout. Every file is a **container**, and so are the assets and
//! regions inside it: a header and a section table,
//!
//! | offset | bytes | field |
//! |---:|---:|---|
//! | 0 | 8 | magic `ASLODMRM` |
//! | 8 | 4 | format version (`u32`, this reader: [`FORMAT_VERSION`]; nested containers carry the file's) |
//! | 12 | 4 | section count `n` |
//! | 16 | 24 × `n` | per section: tag (4 ASCII bytes), CRC-32 of its bytes (`u32`), offset from the container's start (`u64`), length (`u64`) |
//! | 16 + 24`n` | 4 | CRC-32 of every byte before it |
//!
//! then the sections, each starting where the previous one ends, the last one ending at the
//! end of the container, in the order listed below (each at most once). A string is its
//! length in bytes (`u32`) and UTF-8.
//!
//! **A file of assets** (its first section is `SRC `):
//!
//! | tag | contents |
//! |---|---|
//! | `SRC ` | source hash (`u64`, FNV-1a of the source file); source name, partition, writer (strings); skinned (`u8`) and δ (`f32`); the [`BuildOptions`]: `min_triangles` (`u64`), `max_error` (`f32`), `border_weight`, `min_normal_cos`, `regularization`, `local_weight`, `weight_exponent` (`f64` each), `view_dependent` (`u8`), `pair_distance` (`f32`), `operator` (`u8`: 0 edge, 1 triangle); from version 3, `normal_weight`, `uv_weight`, `color_weight` (`f64` each; 0 for older files); from version 4, `weld_distance` (`f32`) and `permissive` (`u8`) (0 and off for older files); from version 5, `root_ratio` (`f32`; 0 for older files) |
//! | `KEYS` | asset count `A` (`u32`); per asset: its key (string) and its container's length (`u64`) |
//! | `ASET` | the `A` asset containers, one after the other |
//!
//! **An asset** (a container in `ASET`):
//!
//! | tag | required | contents |
//! |---|---|---|
//! | `HEAD` | yes | source vertex count `V` (`u32`); attribute flags (`u8`, as `MESH` below); skinned (`u8`); refinement data (`u8`); a zero byte; region count `R` (`u32`) |
//! | `POS ` … `ATTR` | as below | the source's vertex table (every region's local table is a subset of it) |
//! | `PART` | yes | `V` region ids (`u32`), every region holding a vertex |
//! | `OBBS` | yes | `R` boxes: centre, three axes (columns), half extents (15 × `f32`) |
//! | `RGNS` | yes | `R` (`u32`), `R` container lengths (`u64`), then the `R` region containers |
//! | `SKIN` | flag | joint count `J` (`u32`); `R` (`u32`); per region its kind (`u8`: 0 rigid, 1 deformable), a zero byte and two bones (`u16`; a rigid one's second is 0); `J` inverse bind matrices (16 × `f32`, by columns); vertices with over two influences and vertices normalised (`u32` each); joint name count (`u32`: 0 or `J`) and the names (strings) |
//! | `VARI` | flag | the whole mesh as one progressive mesh with view data: a nested container laid out as a progressive-mesh file (below) |
//! | `ROOT` | no | from version 5, the merged root ([`MergedRoot`](crate::regions::MergedRoot)), when the asset has one: a nested container (below) |
//!
//! **A region** (a container in `RGNS`):
//!
//! | tag | required | contents |
//! |---|---|---|
//! | `RGN ` | yes | local vertex count `L`, own vertices, base triangles, index count `I`, steps `S`, corner records `C`, pairs `P` (`u32` each); layout, view data and two zero bytes (`u8` each, as `MESH`); bounds of its own vertices (min, max: 6 × `f32`); counts of border triangles, fin-prone triangles, neighbours, position links and front events (`u32` each) |
//! | `GLOB` | yes | `L` source vertex ids (`u32`): local vertex → source vertex |
//! | `IDX ` … `VIEW` | as below | the region's records over its local vertices (`FLDS` from version 4) |
//! | `LIST` | yes | border triangles, fin-prone triangles, neighbour regions, position links (`u32` each, in that order); front events (step, region, corner, before, after: 5 × `u32`) |
//!
//! **The merged root** (a container in `ROOT`):
//!
//! | tag | required | contents |
//! |---|---|---|
//! | `RHED` | yes | local vertex count `L`, base triangles, index count `I`, steps `S`, corner records `C`, pairs `P`, region count `R` (`u32` each); layout (`u8`, as `MESH`) and three zero bytes |
//! | `GLOB` | yes | `L` source vertex ids (`u32`) |
//! | `IDX ` … `ERRS` | yes | the root's records over its local vertices |
//! | `KEPT` | yes | `R` levels (`u32`): each region's level when the root was made from it |
//!
//! **A progressive mesh** (its first section is `MESH`; every version 1 file):
//!
//! | tag | required | contents |
//! |---|---|---|
//! | `MESH` | yes | vertex count `V` (`u32`); attribute flags (`u8`: 1 normals, 2 UVs, 4 joints, 8 weights, 16 tangents, 32 further attributes); layout (`u8`: 1 narrow, 0 wide); view data (`u8`: 0 or 1); a zero byte; base triangles, index count `I`, steps `S`, corner records `C`, pairs `P` (`u32` each) |
//! | `POS ` | yes | `V` positions, 3 × `f32` |
//! | `NRM ` | flag 1 | `V` normals, 3 × `f32` |
//! | `UV0 ` | flag 2 | `V` texture coordinates, 2 × `f32` |
//! | `JNT ` | flag 4 | `V` × 4 joint indices, `u16` |
//! | `WGT ` | flag 8 | `V` × 4 weights, `f32` |
//! | `TAN ` | flag 16 | `V` tangents, 4 × `f32` (from version 3) |
//! | `ATTR` | flag 32 | further attributes (from version 3): their count `K` (`u32`, at most 32); per attribute its name (string), Bevy id (`u64`), scalar type (`u8`: 0 `f32`, 1 `f16`, 2 `u32`, 3 `i32`, 4 `u16`, 5 `i16`, 6 unorm16, 7 snorm16, 8 `u8`, 9 `i8`, 10 unorm8, 11 snorm8, 12 `f64`, 13 BGRA unorm8), component count (`u8`: 1, 2 or 4; 3 for 32- and 64-bit scalars; 4 for BGRA), two zero bytes, then `V` records |
//! | `IDX ` | yes | the full-detail index buffer in slot order (base triangles first: coarse to fine), `I` indices (`u16` narrow, `u32` wide) |
//! | `STEP` | yes | `S` step headers, `corners << (p + 1 + r) \| pairs << r \| removed` with the widths `p` and `r` of `FLDS` (`u16` narrow, `u32` wide) |
//! | `CORN` | yes | `C` corner records, `corner << p \| pair`: the corner's index in `IDX ` and its pair's among the step's (3 bytes narrow, `u32` wide) |
//! | `PAIR` | yes | `P` `[old, new]` vertex pairs (2 × `u16` narrow, 2 × `u32` wide) |
//! | `FLDS` | from version 4 | the records' field widths: `p`, the bits of a corner record's pair selector (`u8`, 1 to 8; a header's pair count takes `p + 1` bits), and `r`, the bits of a header's removed-triangle count (`u8`, 2 to 8); a narrow mesh's `p + 1 + r` is under 16. Files before version 4 have none: `p` = 1 and `r` = 2 (`corners << 4 \| pairs << 2 \| removed`, `corner << 1 \| pair`) |
//! | `ERRS` | yes | the simplification table (Hoxha's value per collapse): `S` errors relative to the diagonal, the top 16 bits of an `f32`, monotone |
//! | `VIEW` | flag | diagonal (`f32`); vertex width (`u8`: 1 for `u16`); `S` `[u, w]` pairs; `S` sphere centre offsets (3 × `i8`); `S` radii and `S` errors (`u16`, as `ERRS`); `S` normal cones (2 octahedral bytes and a half-angle byte) |
//!
//! Reading checks, before anything is built: the magic, the version (a newer one is
//! [`MrmError::NewerVersion`]), every checksum, the order and contiguity of the sections,
//! that every count fits its section (so nothing is allocated beyond what the file's size
//! justifies), and the records themselves (their field widths, every index and pair names
//! a vertex, every step removes live triangles and rewrites corners of the triangles that
//! stay with its own pairs, every stored bound is finite; every region, border triangle,
//! front event and position link a region names is in range), so assets read from any file
//! are memory-safe for every polygon cache, region cache and refinement. What is not
//! re-derived: that the view data's bounds nest (a file whose bounds were edited refines
//! crack-free but not monotonically, so [`ToleranceSearch`](crate::refine::ToleranceSearch)
//! may then report a level over its count), that the errors are the build's, and that a
//! file's borders and fronts are the ones its build found (edited ones stay in range but may
//! crack).

mod asset;
mod bake;
mod container;
mod progressive;

pub use bake::bake_gltf;

use crate::bounds::Obb;
use crate::mesh::{LoadLimits, MeshError};
use crate::multires::{BuildOptions, ProgressiveMesh};
use crate::regions::{RegionError, RegionMesh};
use crate::skin::{SkinError, SkinRegionKind};
use glam::Mat4;
use thiserror::Error;

/// The format version this crate writes and the newest it reads. Version 1 files hold a
/// progressive mesh only, versions 1 and 2 no tangents or further attributes, and versions
/// 1 to 3 the classic record widths (no `FLDS`); they still load.
pub const FORMAT_VERSION: u32 = 5;

/// Everything a multiresolution asset holds, without Bevy: what an `.mrm` file stores per
/// entry, and what the plugin's `MultiresMesh` is made from without building anything.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedMesh {
    /// The regions with their progressive sequences, borders and fronts.
    pub regions: RegionMesh,
    /// One box per region, in region order (what the budget projects).
    pub obbs: Vec<Obb>,
    /// The skeleton binding of a skinned asset.
    pub skin: Option<BakedSkin>,
    /// The whole mesh as one progressive mesh with view-dependent data, for refinement.
    pub variable: Option<ProgressiveMesh>,
}

/// The skeleton binding of a skinned [`BakedMesh`]. The per-vertex influences are the
/// source's joints and weights (in the regions' vertex tables), normalised again at load.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedSkin {
    /// Per region: rigid on one bone, or deformable between two.
    pub kinds: Vec<SkinRegionKind>,
    /// One inverse bind matrix per joint.
    pub inverse_bindposes: Vec<Mat4>,
    /// The joints' names, in joint order, when the source named them (empty otherwise):
    /// what pairs a baked skin with the skeleton of the scene that shows it.
    pub joint_names: Vec<String>,
    /// Vertices with more than two influences.
    pub more_than_two: usize,
    /// Vertices whose weights were normalised.
    pub normalised: usize,
}

/// How a file's assets were built, and from what.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildInfo {
    /// The source file's name (no directory).
    pub source_name: String,
    /// FNV-1a (64 bits) of the source file's bytes ([`source_hash`]): a tool can tell
    /// whether a baked file is stale.
    pub source_hash: u64,
    /// How the regions were cut, as the baking tool describes it (for example `clusters 16`).
    pub partition: String,
    /// The tool and crate version that wrote the file.
    pub writer: String,
    /// The rigid threshold δ of skinned assets.
    pub rigid_delta: Option<f32>,
    /// The build options.
    pub options: BuildOptions,
}

/// A `.mrm` file of assets: how they were built, and each one under its key (for a glTF
/// scene, Bevy's label of the primitive, such as `Mesh0/Primitive0`).
#[derive(Clone, Debug, PartialEq)]
pub struct MrmFile {
    /// How the assets were built.
    pub build: BuildInfo,
    /// The assets, each under a unique, non-empty key.
    pub meshes: Vec<(String, BakedMesh)>,
}

/// What a file holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MrmKind {
    /// One progressive mesh ([`read_progressive`]); every version 1 file.
    Progressive,
    /// Assets ([`read`]).
    Assets,
}

/// What can go wrong when building a [`BakedMesh`].
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum BakeError {
    /// The source mesh is invalid.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Partitioning or building the regions failed.
    #[error(transparent)]
    Region(#[from] RegionError),
    /// The skin's influences are invalid.
    #[error(transparent)]
    Skin(#[from] SkinError),
    /// A skinned build was asked of a mesh without joints or weights.
    #[error("the mesh has no joints or weights (JOINTS_0/WEIGHTS_0): it is not skinned")]
    NotSkinned,
    /// An inverse bind matrix has a NaN or infinite entry.
    #[error("inverse bind matrix {joint} is not finite")]
    NonFiniteBindpose {
        /// The joint.
        joint: usize,
    },
}

/// FNV-1a, 64 bits, of `bytes`: the source hash of [`BuildInfo`].
#[must_use]
pub fn source_hash(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The `.mrm` bytes of a file of assets.
#[must_use]
pub fn write(file: &MrmFile) -> Vec<u8> {
    asset::write(file)
}

/// Reads a file of assets, checking all of it (see the module docs), within
/// [`LoadLimits::default()`].
///
/// # Errors
/// An [`MrmError`] naming the section and byte offset of the first problem found;
/// [`MrmError::Invalid`] for a progressive-mesh file (read it with [`read_progressive`]).
pub fn read(bytes: &[u8]) -> Result<MrmFile, MrmError> {
    read_with_limits(bytes, &LoadLimits::default())
}

/// Reads a file of assets as [`read`] does, within `limits`: the file's bytes, its keys,
/// each asset's vertices, triangles (over its regions) and joints, and the bytes of the
/// regions' vertex tables (`decoded_bytes`), each checked before it is allocated.
///
/// # Errors
/// As [`read`], and [`MrmError::LimitExceeded`] naming the first limit the file exceeds.
///
/// # Example
/// ```
/// use bevy_aslod::mesh::LoadLimits;
/// use bevy_aslod::mrm::{self, MrmError};
///
/// let bytes = std::fs::read("assets/mannequin.mrm").unwrap();
/// // The mannequin's skin has 10 joints.
/// let limits = LoadLimits { joints: 9, ..LoadLimits::default() };
/// let read = mrm::read_with_limits(&bytes, &limits);
/// assert!(matches!(read, Err(MrmError::LimitExceeded { limit: "joints", .. })));
/// ```
pub fn read_with_limits(bytes: &[u8], limits: &LoadLimits) -> Result<MrmFile, MrmError> {
    within("file_bytes", bytes.len(), limits.file_bytes)?;
    match kind(bytes)? {
        MrmKind::Assets => asset::read(bytes, limits),
        MrmKind::Progressive => Err(MrmError::Invalid {
            section: "MESH".into(),
            offset: 16,
            what: "the file holds a progressive mesh, not assets",
        }),
    }
}

/// The sections inside each asset of a file of assets (`key: TAG`) and of its regions,
/// summed over them (`key: RGNS/TAG`), with their sizes in bytes: what `aslod info` prints.
///
/// # Errors
/// As [`read`], for the containers.
pub fn entry_sections(bytes: &[u8]) -> Result<Vec<(String, u64)>, MrmError> {
    asset::entry_sections(bytes)
}

/// Whether a file holds a progressive mesh or assets, from its header and first section's
/// tag (nothing else is checked: reading does that).
///
/// # Errors
/// [`MrmError::NotMrm`], [`MrmError::NewerVersion`], [`MrmError::Truncated`] for a file
/// shorter than its header, [`MrmError::Invalid`] when the first section is neither kind's.
pub fn kind(bytes: &[u8]) -> Result<MrmKind, MrmError> {
    if !bytes.iter().zip(container::MAGIC).all(|(a, b)| *a == b) {
        return Err(MrmError::NotMrm);
    }
    let Some((version, tag)) = container::peek(bytes) else {
        return Err(MrmError::Truncated {
            section: "header".into(),
            offset: 0,
            needed: 16,
        });
    };
    if version > FORMAT_VERSION {
        return Err(MrmError::NewerVersion {
            file: version,
            supported: FORMAT_VERSION,
        });
    }
    match &tag {
        b"MESH" => Ok(MrmKind::Progressive),
        b"SRC " if version >= 2 => Ok(MrmKind::Assets),
        _ => Err(MrmError::Invalid {
            section: container::tag_name(tag),
            offset: 16,
            what: "the first section is neither a mesh's nor assets'",
        }),
    }
}

/// Why a `.mrm` file cannot be read. Every variant about the contents names the section and
/// the byte offset in the file.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum MrmError {
    /// The file does not start with the `.mrm` magic number.
    #[error("not an .mrm file (no ASLODMRM magic number)")]
    NotMrm,
    /// The file was written by a newer format version.
    #[error(
        "the file has .mrm format version {file}; this reader knows versions up to {supported}"
    )]
    NewerVersion {
        /// The file's version.
        file: u32,
        /// The newest version this reader knows.
        supported: u32,
    },
    /// The file ends before a section or value it declares.
    #[error("{section} at byte {offset}: the file ends before its {needed} bytes")]
    Truncated {
        /// The section.
        section: String,
        /// Where it starts.
        offset: u64,
        /// The bytes it needs.
        needed: u64,
    },
    /// A section's bytes do not match its checksum.
    #[error("{section} at byte {offset}: checksum mismatch (the file is damaged)")]
    Checksum {
        /// The section.
        section: String,
        /// Where it starts.
        offset: u64,
    },
    /// A required section is not in the file.
    #[error("the section {0} is missing")]
    MissingSection(String),
    /// A value cannot be right.
    #[error("{section} at byte {offset}: {what}")]
    Invalid {
        /// The section.
        section: String,
        /// Where the value is.
        offset: u64,
        /// What is wrong with it.
        what: &'static str,
    },
    /// A vertex table's attributes are inconsistent (a count, a format, a non-finite value).
    #[error("vertex attributes: {0}")]
    Attributes(String),
    /// The file asks for more than a [`LoadLimits`] allows.
    #[error(
        "the file needs {value} for LoadLimits::{limit}, above its {max}; raise \
         LoadLimits::{limit} if the file is trusted"
    )]
    LimitExceeded {
        /// The limit's field name in [`LoadLimits`].
        limit: &'static str,
        /// What the file asks for.
        value: u64,
        /// The limit.
        max: u64,
    },
}

/// `Ok` when `value` is within limit `limit` of value `max`.
fn within(limit: &'static str, value: usize, max: u64) -> Result<(), MrmError> {
    let value = value as u64;
    if value > max {
        return Err(MrmError::LimitExceeded { limit, value, max });
    }
    Ok(())
}

impl MrmError {
    /// The same error in a container that starts `base` bytes into the file.
    fn shifted(self, base: u64) -> Self {
        match self {
            Self::Truncated {
                section,
                offset,
                needed,
            } => Self::Truncated {
                section,
                offset: offset + base,
                needed,
            },
            Self::Checksum { section, offset } => Self::Checksum {
                section,
                offset: offset + base,
            },
            Self::Invalid {
                section,
                offset,
                what,
            } => Self::Invalid {
                section,
                offset: offset + base,
                what,
            },
            Self::NotMrm if base > 0 => Self::Invalid {
                section: "nested container".into(),
                offset: base,
                what: "no ASLODMRM magic number",
            },
            other => other,
        }
    }
}

/// The `.mrm` bytes of a progressive mesh.
#[must_use]
pub fn write_progressive(mesh: &ProgressiveMesh) -> Vec<u8> {
    progressive::write(mesh)
}

/// Reads a progressive mesh from `.mrm` bytes, checking all of them (see the module docs),
/// within [`LoadLimits::default()`].
///
/// # Errors
/// An [`MrmError`] naming the section and byte offset of the first problem found.
pub fn read_progressive(bytes: &[u8]) -> Result<ProgressiveMesh, MrmError> {
    read_progressive_with_limits(bytes, &LoadLimits::default())
}

/// Reads a progressive mesh as [`read_progressive`] does, within `limits` (the file's
/// bytes, its vertices and its triangles, checked before they are allocated).
///
/// # Errors
/// As [`read_progressive`], and [`MrmError::LimitExceeded`] naming the first limit the file
/// exceeds.
pub fn read_progressive_with_limits(
    bytes: &[u8],
    limits: &LoadLimits,
) -> Result<ProgressiveMesh, MrmError> {
    within("file_bytes", bytes.len(), limits.file_bytes)?;
    let sections = container::read(bytes, 0, FORMAT_VERSION, &progressive::SECTIONS)?;
    let version = container::peek(bytes).map_or(FORMAT_VERSION, |(v, _)| v);
    progressive::read(&sections, version, limits)
}

/// The sections of a `.mrm` file (tag and length in bytes), after checking the header, the
/// table and every section's checksum.
///
/// # Errors
/// As [`read_progressive`], for the container.
pub fn sections(bytes: &[u8]) -> Result<Vec<(String, u64)>, MrmError> {
    let expected: &[([u8; 4], bool)] = match kind(bytes)? {
        MrmKind::Progressive => &progressive::SECTIONS,
        MrmKind::Assets => &asset::FILE_SECTIONS,
    };
    let sections = container::read(bytes, 0, FORMAT_VERSION, expected)?;
    Ok(sections
        .iter()
        .map(|s| (container::tag_name(s.tag), s.bytes.len() as u64))
        .collect())
}
