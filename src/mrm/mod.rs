//! The `.mrm` file (Hoxha's MR-model): a multiresolution mesh baked once and loaded without
//! rebuilding. **Partial:** a file holds one [`ProgressiveMesh`] (its vertex table with every
//! attribute, its records, its simplification table and its view-dependent data), which
//! `aslod bake` writes and `aslod info` lists; regions, the skin binding and a Bevy asset
//! loader are not written yet.
//!
//! ```
//! use bevy_aslod::mesh::IndexedMesh;
//! use bevy_aslod::mrm;
//! use bevy_aslod::multires::{BuildOptions, ProgressiveMesh};
//!
//! let (mesh, _) = IndexedMesh::load("../shared/testdata/meshes/cow.obj")?;
//! let cow = ProgressiveMesh::build(&mesh, &BuildOptions::default())?;
//! let bytes = mrm::write_progressive(&cow);
//! assert_eq!(mrm::read_progressive(&bytes)?, cow);
//! // A damaged file is an error that names where, never a wrong mesh.
//! let mut damaged = bytes.clone();
//! damaged[bytes.len() / 2] ^= 0x10;
//! assert!(mrm::read_progressive(&damaged).is_err());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Layout (format version 1)
//!
//! Little-endian throughout. The header and the section table:
//!
//! | offset | bytes | field |
//! |---:|---:|---|
//! | 0 | 8 | magic `ASLODMRM` |
//! | 8 | 4 | format version (`u32`, this reader: [`FORMAT_VERSION`]) |
//! | 12 | 4 | section count `n` |
//! | 16 | 24 × `n` | per section: tag (4 ASCII bytes), CRC-32 of its bytes (`u32`), offset in the file (`u64`), length (`u64`) |
//! | 16 + 24`n` | 4 | CRC-32 of every byte before it |
//!
//! Then the sections, each starting where the previous one ends, the last one ending at the
//! end of the file, in this order (each at most once):
//!
//! | tag | required | contents |
//! |---|---|---|
//! | `MESH` | yes | vertex count `V` (`u32`); attribute flags (`u8`: 1 normals, 2 UVs, 4 joints, 8 weights); layout (`u8`: 1 narrow, 0 wide); view data (`u8`: 0 or 1); a zero byte; base triangles, index count `I`, steps `S`, corner records `C`, pairs `P` (`u32` each) |
//! | `POS ` | yes | `V` positions, 3 × `f32` |
//! | `NRM ` | flag 1 | `V` normals, 3 × `f32` |
//! | `UV0 ` | flag 2 | `V` texture coordinates, 2 × `f32` |
//! | `JNT ` | flag 4 | `V` × 4 joint indices, `u16` |
//! | `WGT ` | flag 8 | `V` × 4 weights, `f32` |
//! | `IDX ` | yes | the full-detail index buffer in slot order (base triangles first: coarse to fine), `I` indices (`u16` narrow, `u32` wide) |
//! | `STEP` | yes | `S` step headers, `corners << 4 \| pairs << 2 \| removed` (`u16` narrow, `u32` wide) |
//! | `CORN` | yes | `C` corner records, `corner << 1 \| pair` (3 bytes narrow, `u32` wide) |
//! | `PAIR` | yes | `P` `[old, new]` vertex pairs (2 × `u16` narrow, 2 × `u32` wide) |
//! | `ERRS` | yes | the simplification table: `S` errors relative to the diagonal, the top 16 bits of an `f32`, monotone |
//! | `VIEW` | flag | diagonal (`f32`); vertex width (`u8`: 1 for `u16`); `S` `[u, w]` pairs; `S` sphere centre offsets (3 × `i8`); `S` radii and `S` errors (`u16`, as `ERRS`); `S` normal cones (2 octahedral bytes and a half-angle byte) |
//!
//! Reading checks, before anything is built: the magic, the version (a newer one is
//! [`MrmError::NewerVersion`]), both kinds of checksum, the order and contiguity of the
//! sections, that every count fits its section (so nothing is allocated beyond what the
//! file's size justifies), and the records themselves (every index and pair names a vertex,
//! every step removes live triangles and rewrites corners of the triangles that stay, every
//! stored bound is finite), so a mesh read from any file is memory-safe for every polygon
//! cache and refinement. What is not re-derived: that the view data's bounds nest (a file
//! whose bounds were edited refines crack-free but not monotonically, so
//! [`ToleranceSearch`](crate::refine::ToleranceSearch) may then report a level over its
//! count) and that the errors are the build's.

mod container;
mod progressive;

use crate::multires::ProgressiveMesh;
use thiserror::Error;

/// The format version this crate writes and the newest it reads.
pub const FORMAT_VERSION: u32 = 1;

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
}

/// The `.mrm` bytes of a progressive mesh.
#[must_use]
pub fn write_progressive(mesh: &ProgressiveMesh) -> Vec<u8> {
    progressive::write(mesh)
}

/// Reads a progressive mesh from `.mrm` bytes, checking all of them (see the module docs).
///
/// # Errors
/// An [`MrmError`] naming the section and byte offset of the first problem found.
pub fn read_progressive(bytes: &[u8]) -> Result<ProgressiveMesh, MrmError> {
    let sections = container::read(bytes, FORMAT_VERSION, &progressive::SECTIONS)?;
    progressive::read(&sections)
}

/// The sections of a `.mrm` file (tag and length in bytes), after checking the header, the
/// table and every section's checksum.
///
/// # Errors
/// As [`read_progressive`], for the container.
pub fn sections(bytes: &[u8]) -> Result<Vec<(String, u64)>, MrmError> {
    let sections = container::read(bytes, FORMAT_VERSION, &progressive::SECTIONS)?;
    Ok(sections
        .iter()
        .map(|s| (container::tag_name(s.tag), s.bytes.len() as u64))
        .collect())
}
