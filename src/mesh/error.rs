//! The error type of mesh import and validation.

use thiserror::Error;

/// Result alias for mesh import and validation.
pub type MeshResult<T> = Result<T, MeshError>;

/// Everything that can be wrong with an input mesh. Each variant names the defect and where
/// it is, so the message can be shown to a user as it is.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum MeshError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file extension names no format this crate reads.
    #[error("unsupported mesh format: {path} (expected .obj, .ply, .gltf or .glb)")]
    UnsupportedFormat {
        /// The file.
        path: String,
    },
    /// The file could not be parsed.
    #[error("{format} parse error at {location}: {message}")]
    Parse {
        /// `OBJ`, `PLY`, `glTF`.
        format: &'static str,
        /// Where: `line 12`, `byte 40`, `accessor 3`, ...
        location: String,
        /// What is wrong.
        message: String,
    },
    /// The mesh has no vertices or no triangles.
    #[error("the mesh is empty: it has no vertices or no triangles")]
    Empty,
    /// Every triangle was degenerate, so nothing is left.
    #[error("all {count} triangles are degenerate (repeated vertex or zero area)")]
    AllTrianglesDegenerate {
        /// How many triangles there were.
        count: usize,
    },
    /// The index buffer length is not a multiple of three.
    #[error("index count {count} is not a multiple of 3")]
    IndexCountNotMultipleOfThree {
        /// The index count.
        count: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "index out of range: triangle {triangle} uses vertex {index}, but there are only {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The offending index.
        index: u32,
        /// How many vertices there are.
        vertex_count: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("non-finite {attribute} coordinate (NaN or infinite) at vertex {vertex}")]
    NonFiniteCoordinate {
        /// The attribute (`POSITION`, `NORMAL`, `TEXCOORD_0`).
        attribute: &'static str,
        /// The vertex.
        vertex: usize,
    },
    /// A position coordinate is beyond [`MAX_COORDINATE`](super::MAX_COORDINATE).
    #[error(
        "position coordinate {value:e} at vertex {vertex} is beyond ±1e18 (MAX_COORDINATE); \
         scale the mesh down"
    )]
    CoordinateOutOfRange {
        /// The first vertex beyond the range.
        vertex: usize,
        /// Its largest coordinate, in absolute value.
        value: f32,
    },
    /// An attribute does not have one entry per vertex.
    #[error("unequal attribute counts: {attribute} has {found} entries, POSITION has {expected}")]
    AttributeCountMismatch {
        /// The attribute.
        attribute: &'static str,
        /// The position count.
        expected: usize,
        /// The attribute's count.
        found: usize,
    },
    /// A further vertex attribute ([`VertexAttribute`](super::VertexAttribute)) is malformed.
    #[error("vertex attribute {name:?} (id {id}): {problem}")]
    BadAttribute {
        /// The attribute's name.
        name: String,
        /// Its Bevy id.
        id: u64,
        /// What is wrong with it.
        problem: String,
    },
    /// The mesh is larger than the crate's index types can address.
    #[error("the mesh is too large: {count} {what}, more than the {limit} this crate can index")]
    TooLarge {
        /// What there is too much of: `triangles`, `vertices`, ...
        what: &'static str,
        /// How many there are.
        count: u64,
        /// The most there may be.
        limit: u64,
    },
    /// A file asks for more than a [`LoadLimits`](super::LoadLimits) allows.
    #[error(
        "the file needs {value} for LoadLimits::{limit}, above its {max}; raise \
         LoadLimits::{limit} if the file is trusted"
    )]
    LimitExceeded {
        /// The limit's field name: `file_bytes`, `decoded_bytes`, `vertices`, `triangles`
        /// or `joints`.
        limit: &'static str,
        /// What the file needs.
        value: u64,
        /// The limit.
        max: u64,
    },
    /// A glTF document is structurally invalid (unresolved references, bad GLB container,
    /// missing buffers, ...).
    #[error("invalid glTF: {message}")]
    Gltf {
        /// What is wrong, including the glTF path where known (`accessors[2].bufferView`).
        message: String,
    },
}

impl MeshError {
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.display().to_string(),
            source,
        }
    }

    pub(crate) fn parse(
        format: &'static str,
        location: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self::Parse {
            format,
            location: location.into(),
            message: message.into(),
        }
    }
}
