//! Stanford PLY import (ASCII, binary little-endian and binary big-endian).
//!
//! Reads the `vertex` element's `x y z`, optional `nx ny nz` and texture coordinates (`s t`,
//! `u v`, `texture_u texture_v` or `texture_s texture_t`), the `face` element's
//! `vertex_indices` (or `vertex_index`) list, and the `tristrips` element's `vertex_indices`
//! list. Every other element and property is read past and ignored. Any property type works
//! for any of these, so integer coordinates and `uint` indices are fine.
//!
//! The parser never trusts a count from the header: it allocates only as data arrives, and a
//! file that ends early gives an error naming the element and the line or byte. A header
//! whose `vertex` count is over [`LoadLimits::vertices`] is refused before any data is read,
//! and faces stop at [`LoadLimits::triangles`] as they are read.

use super::{IndexedMesh, LoadLimits, MeshError, MeshResult};
use glam::{Vec2, Vec3};
use std::path::Path;

/// Reads and parses a PLY file within the default [`LoadLimits`]; see [`parse_ply`].
///
/// # Errors
/// [`MeshError::Io`] when the file cannot be read, otherwise the errors of
/// [`parse_ply_with_limits`].
pub fn load_ply(path: &Path) -> MeshResult<IndexedMesh> {
    let limits = LoadLimits::default();
    parse_ply_with_limits(&limits.read_file(path)?, &limits)
}

/// Parses a PLY file held in memory, within the default [`LoadLimits`] (see
/// [`parse_ply_with_limits`]).
///
/// ASCII data holds one element instance per line. Faces are fan-triangulated. Triangle strips are split at `-1` restart markers and turned
/// into triangles of alternating winding, as strips are drawn; triangles of a strip that
/// repeat a vertex are skipped (strips use them to turn corners). Normals and texture
/// coordinates are kept when all their components are present.
///
/// The mesh is not validated; call [`IndexedMesh::validate`] before using it.
///
/// # Errors
/// [`MeshError::Parse`] for a malformed header (naming the header line), data that ends early
/// or is not a number (naming the element, and the line or byte), an ASCII line with more
/// values than its element's properties, a property declared twice, a vertex element without
/// `x`, `y` and `z`, or a face index that is not a whole number, is negative or refers to no
/// vertex; [`MeshError::LimitExceeded`] as [`parse_ply_with_limits`].
///
/// # Example
/// ```
/// use bevy_aslod::mesh::parse_ply;
///
/// let ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
///     property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
///     0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
/// let mesh = parse_ply(ply)?;
/// assert_eq!(mesh.triangle_count(), 1);
/// # Ok::<(), bevy_aslod::mesh::MeshError>(())
/// ```
pub fn parse_ply(bytes: &[u8]) -> MeshResult<IndexedMesh> {
    parse_ply_with_limits(bytes, &LoadLimits::default())
}

/// [`parse_ply`] within `limits`: the header's `vertex` count is checked against
/// [`vertices`](LoadLimits::vertices) before any data is read, and the triangles against
/// [`triangles`](LoadLimits::triangles) as each face or strip is read.
///
/// # Errors
/// As [`parse_ply`], and [`MeshError::LimitExceeded`] naming the limit the file exceeds.
///
/// # Example
/// ```
/// use bevy_aslod::mesh::{LoadLimits, MeshError, parse_ply_with_limits};
///
/// // Four thousand million vertices named in a header of a hundred bytes.
/// let ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
///     property float x\nproperty float y\nproperty float z\nend_header\n";
/// let e = parse_ply_with_limits(ply, &LoadLimits::default()).unwrap_err();
/// assert!(matches!(e, MeshError::LimitExceeded { limit: "vertices", .. }));
/// ```
pub fn parse_ply_with_limits(bytes: &[u8], limits: &LoadLimits) -> MeshResult<IndexedMesh> {
    let header = parse_header(bytes)?;
    for element in header
        .elements
        .iter()
        .filter(|e| e.name == "vertex" && !e.properties.is_empty())
    {
        LoadLimits::check("vertices", element.count as u64, limits.vertices)?;
    }
    let body = &bytes[header.body_start..];
    let mut cursor = match header.format {
        Format::Ascii => Cursor::Ascii {
            data: body,
            pos: 0,
            line: header.body_line,
        },
        Format::Binary { big_endian } => Cursor::Binary {
            data: body,
            pos: 0,
            offset: header.body_start,
            big_endian,
        },
    };

    let mut out = Collected::default();
    for element in &header.elements {
        read_element(element, &mut cursor, &mut out, limits)?;
    }
    out.into_mesh()
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    Binary { big_endian: bool },
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// Decodes one value from exactly `self.size()` bytes. `f64` holds every type exactly.
    fn decode(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:literal) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                f64::from(if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                })
            }};
        }
        match self {
            Self::I8 => get!(i8, 1),
            Self::U8 => get!(u8, 1),
            Self::I16 => get!(i16, 2),
            Self::U16 => get!(u16, 2),
            Self::I32 => get!(i32, 4),
            Self::U32 => get!(u32, 4),
            Self::F32 => get!(f32, 4),
            Self::F64 => get!(f64, 8),
        }
    }
}

/// What a property feeds into the mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Position(usize),
    Normal(usize),
    Uv(usize),
    FaceIndices,
    StripIndices,
    Ignored,
}

#[derive(Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
    role: Role,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

#[derive(Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Offset of the first byte after the `end_header` line.
    body_start: usize,
    /// 1-based line number of the first body line (for ASCII errors).
    body_line: usize,
}

fn header_error(line: usize, message: impl Into<String>) -> MeshError {
    MeshError::parse("PLY", format!("header line {line}"), message)
}

fn parse_header(bytes: &[u8]) -> MeshResult<Header> {
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0;
    let mut line_number = 0;
    loop {
        line_number += 1;
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(header_error(
                line_number,
                "the header has no `end_header` line",
            ));
        };
        let raw = &bytes[pos..pos + len];
        pos += len + 1;
        // Lossy, so that a stray byte in a comment does not reject the file.
        let text = String::from_utf8_lossy(raw);
        let line = text.trim_end_matches('\r');
        let mut words = line.split_whitespace();
        let keyword = words.next().unwrap_or("");
        if line_number == 1 {
            if line.trim() != "ply" {
                return Err(header_error(
                    1,
                    "not a PLY file (the first line must be `ply`)",
                ));
            }
            continue;
        }
        match keyword {
            "" | "comment" | "obj_info" => {}
            "format" => {
                format = Some(match words.next() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Binary { big_endian: false },
                    Some("binary_big_endian") => Format::Binary { big_endian: true },
                    other => {
                        return Err(header_error(
                            line_number,
                            format!("unknown format `{}`", other.unwrap_or("")),
                        ));
                    }
                });
            }
            "element" => {
                let (Some(name), Some(count), None) = (words.next(), words.next(), words.next())
                else {
                    return Err(header_error(
                        line_number,
                        "expected `element <name> <count>`",
                    ));
                };
                let count = count.parse().map_err(|_| {
                    header_error(
                        line_number,
                        format!("element `{name}`: bad count `{count}`"),
                    )
                })?;
                elements.push(Element {
                    name: name.to_owned(),
                    count,
                    properties: Vec::new(),
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(header_error(line_number, "a property before any element"));
                };
                let words: Vec<&str> = words.collect();
                let scalar = |name: &str| {
                    Scalar::parse(name).ok_or_else(|| {
                        header_error(line_number, format!("unknown property type `{name}`"))
                    })
                };
                let (kind, name) = match words.as_slice() {
                    ["list", count, item, name] => (
                        Kind::List {
                            count: scalar(count)?,
                            item: scalar(item)?,
                        },
                        *name,
                    ),
                    [ty, name] => (Kind::Scalar(scalar(ty)?), *name),
                    _ => {
                        return Err(header_error(
                            line_number,
                            "expected `property <type> <name>` or \
                             `property list <count type> <item type> <name>`",
                        ));
                    }
                };
                if let Kind::List {
                    count: Scalar::F32 | Scalar::F64,
                    ..
                } = kind
                {
                    return Err(header_error(
                        line_number,
                        format!("list `{name}`: the count type must be an integer type"),
                    ));
                }
                if element.properties.iter().any(|p| p.name == name) {
                    return Err(header_error(
                        line_number,
                        format!(
                            "element `{}`: property `{name}` declared twice",
                            element.name
                        ),
                    ));
                }
                let role = role_of(&element.name, name, &kind);
                element.properties.push(Property {
                    name: name.to_owned(),
                    kind,
                    role,
                });
            }
            "end_header" => break,
            other => {
                return Err(header_error(
                    line_number,
                    format!("unknown header keyword `{other}`"),
                ));
            }
        }
    }
    let format = format.ok_or_else(|| header_error(line_number, "no `format` line"))?;
    resolve_uv_roles(&mut elements);
    Ok(Header {
        format,
        elements,
        body_start: pos,
        body_line: line_number + 1,
    })
}

fn role_of(element: &str, property: &str, kind: &Kind) -> Role {
    match (element, property, kind) {
        ("vertex", "x", Kind::Scalar(_)) => Role::Position(0),
        ("vertex", "y", Kind::Scalar(_)) => Role::Position(1),
        ("vertex", "z", Kind::Scalar(_)) => Role::Position(2),
        ("vertex", "nx", Kind::Scalar(_)) => Role::Normal(0),
        ("vertex", "ny", Kind::Scalar(_)) => Role::Normal(1),
        ("vertex", "nz", Kind::Scalar(_)) => Role::Normal(2),
        ("face", "vertex_indices" | "vertex_index", Kind::List { .. }) => Role::FaceIndices,
        ("tristrips", "vertex_indices", Kind::List { .. }) => Role::StripIndices,
        _ => Role::Ignored,
    }
}

/// Picks the first texture-coordinate naming scheme whose two properties are both present.
fn resolve_uv_roles(elements: &mut [Element]) {
    const SCHEMES: [[&str; 2]; 4] = [
        ["s", "t"],
        ["u", "v"],
        ["texture_u", "texture_v"],
        ["texture_s", "texture_t"],
    ];
    let Some(vertex) = elements.iter_mut().find(|e| e.name == "vertex") else {
        return;
    };
    let scalar_named = |props: &[Property], name: &str| {
        props
            .iter()
            .position(|p| p.name == name && matches!(p.kind, Kind::Scalar(_)))
    };
    for [u, v] in SCHEMES {
        if let (Some(iu), Some(iv)) = (
            scalar_named(&vertex.properties, u),
            scalar_named(&vertex.properties, v),
        ) {
            vertex.properties[iu].role = Role::Uv(0);
            vertex.properties[iv].role = Role::Uv(1);
            return;
        }
    }
}

/// Reads values from the body, ASCII tokens or binary, and knows where it is for errors.
enum Cursor<'a> {
    Ascii {
        data: &'a [u8],
        pos: usize,
        line: usize,
    },
    Binary {
        data: &'a [u8],
        pos: usize,
        /// Offset of `data` in the file, so that errors give file offsets.
        offset: usize,
        big_endian: bool,
    },
}

impl Cursor<'_> {
    fn location(&self) -> String {
        match self {
            Self::Ascii { line, .. } => format!("line {line}"),
            Self::Binary { pos, offset, .. } => format!("byte {}", offset + pos),
        }
    }

    /// Ends one element instance: in ASCII, the rest of its line must be blank (one instance
    /// per line, so that a value too many or too few cannot shift every value after it).
    fn end_instance(&mut self) -> Result<(), String> {
        let Self::Ascii { data, pos, line } = self else {
            return Ok(());
        };
        while let Some(&b) = data.get(*pos) {
            match b {
                b'\n' => {
                    *pos += 1;
                    *line += 1;
                    return Ok(());
                }
                b if b.is_ascii_whitespace() => *pos += 1,
                _ => return Err("more values on its line than its properties".into()),
            }
        }
        Ok(())
    }

    /// Reads one value of type `ty`; `Err` says what went wrong, without the location.
    fn read(&mut self, ty: Scalar) -> Result<f64, String> {
        match self {
            Self::Binary {
                data,
                pos,
                big_endian,
                ..
            } => {
                let bytes = data
                    .get(*pos..)
                    .and_then(|rest| rest.get(..ty.size()))
                    .ok_or("unexpected end of data")?;
                *pos += ty.size();
                Ok(ty.decode(bytes, *big_endian))
            }
            Self::Ascii { data, pos, line } => {
                while let Some(&b) = data.get(*pos) {
                    if !b.is_ascii_whitespace() {
                        break;
                    }
                    if b == b'\n' {
                        *line += 1;
                    }
                    *pos += 1;
                }
                let start = *pos;
                while data.get(*pos).is_some_and(|b| !b.is_ascii_whitespace()) {
                    *pos += 1;
                }
                if start == *pos {
                    return Err("unexpected end of data".into());
                }
                let token = String::from_utf8_lossy(&data[start..*pos]);
                let value: f64 = token
                    .parse()
                    .map_err(|_| format!("`{token}` is not a number"))?;
                let integral = !matches!(ty, Scalar::F32 | Scalar::F64);
                if integral && value.fract() != 0.0 {
                    return Err(format!("`{token}` is not an integer"));
                }
                Ok(value)
            }
        }
    }
}

/// The mesh data gathered while reading the elements.
#[derive(Default)]
struct Collected {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    /// Triangle corners as read (not yet range-checked), with the element instance each
    /// triangle came from, for errors.
    indices: Vec<i64>,
    sources: Vec<(&'static str, usize)>,
}

impl Collected {
    fn into_mesh(self) -> MeshResult<IndexedMesh> {
        let n = self.positions.len();
        let mut indices = Vec::with_capacity(self.indices.len());
        for (tri, &(element, instance)) in self.indices.chunks_exact(3).zip(&self.sources) {
            for &i in tri {
                let index = u32::try_from(i).ok().filter(|&i| (i as usize) < n);
                let Some(index) = index else {
                    return Err(MeshError::parse(
                        "PLY",
                        format!("element `{element}` {instance}"),
                        format!("vertex index {i} is out of range ({n} vertices)"),
                    ));
                };
                indices.push(index);
            }
        }
        Ok(IndexedMesh {
            positions: self.positions,
            normals: self.normals,
            uvs: self.uvs,
            indices,
            ..IndexedMesh::default()
        })
    }
}

fn read_element(
    element: &Element,
    cursor: &mut Cursor<'_>,
    out: &mut Collected,
    limits: &LoadLimits,
) -> MeshResult<()> {
    // An element with no properties has no data, whatever its count says.
    if element.properties.is_empty() {
        return Ok(());
    }
    let is_vertex = element.name == "vertex";
    let roles = |f: fn(&Role) -> bool| element.properties.iter().filter(|p| f(&p.role)).count();
    let has_normals = is_vertex && roles(|r| matches!(r, Role::Normal(_))) == 3;
    let has_uvs = is_vertex && roles(|r| matches!(r, Role::Uv(_))) == 2;
    if is_vertex {
        if roles(|r| matches!(r, Role::Position(_))) != 3 {
            return Err(MeshError::parse(
                "PLY",
                "element `vertex`",
                "the vertex element needs scalar `x`, `y` and `z` properties",
            ));
        }
        // Each property takes at least one byte, so the data bounds the real vertex count
        // however large the header's count is.
        let data_len = match cursor {
            Cursor::Ascii { data, .. } | Cursor::Binary { data, .. } => data.len(),
        };
        let reserve = element.count.min(data_len / element.properties.len());
        out.positions.reserve(reserve);
        out.normals = has_normals.then(|| Vec::with_capacity(reserve));
        out.uvs = has_uvs.then(|| Vec::with_capacity(reserve));
    }

    let mut list: Vec<i64> = Vec::new();
    for instance in 0..element.count {
        let (mut p, mut n, mut t) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 2]);
        for property in &element.properties {
            let err = |cursor: &Cursor<'_>, message: String| {
                MeshError::parse(
                    "PLY",
                    cursor.location(),
                    format!(
                        "element `{}` {instance}, property `{}`: {message}",
                        element.name, property.name
                    ),
                )
            };
            match property.kind {
                Kind::Scalar(ty) => {
                    let value = cursor.read(ty).map_err(|m| err(cursor, m))? as f32;
                    match property.role {
                        Role::Position(i) => p[i] = value,
                        Role::Normal(i) => n[i] = value,
                        Role::Uv(i) => t[i] = value,
                        _ => {}
                    }
                }
                Kind::List { count, item } => {
                    let len = cursor.read(count).map_err(|m| err(cursor, m))?;
                    if len < 0.0 {
                        return Err(err(cursor, format!("negative list length {len}")));
                    }
                    list.clear();
                    // Values are read one by one, so a bogus length fails at the end of data.
                    for _ in 0..len as u64 {
                        let value = cursor.read(item).map_err(|m| err(cursor, m))?;
                        if property.role != Role::Ignored {
                            // Float-typed lists must still hold whole indices (NaN would
                            // become vertex 0).
                            if !value.is_finite() || value.fract() != 0.0 {
                                return Err(err(
                                    cursor,
                                    format!("vertex index {value} is not an integer"),
                                ));
                            }
                            list.push(value as i64);
                        }
                    }
                    match property.role {
                        Role::FaceIndices => push_polygon(&list, instance, out),
                        Role::StripIndices => push_strip(&list, instance, out),
                        _ => {}
                    }
                    let triangles = out.sources.len() as u64;
                    LoadLimits::check("triangles", triangles, limits.triangles)?;
                }
            }
        }
        cursor.end_instance().map_err(|message| {
            MeshError::parse(
                "PLY",
                cursor.location(),
                format!("element `{}` {instance}: {message}", element.name),
            )
        })?;
        if is_vertex {
            out.positions.push(Vec3::from(p));
            if let Some(normals) = &mut out.normals {
                normals.push(Vec3::from(n));
            }
            if let Some(uvs) = &mut out.uvs {
                uvs.push(Vec2::from(t));
            }
        }
    }
    Ok(())
}

/// Fan-triangulates one face.
fn push_polygon(polygon: &[i64], instance: usize, out: &mut Collected) {
    for i in 1..polygon.len().saturating_sub(1) {
        out.indices
            .extend_from_slice(&[polygon[0], polygon[i], polygon[i + 1]]);
        out.sources.push(("face", instance));
    }
}

/// Converts a strip list with `-1` restart markers into triangles. Odd triangles of a strip
/// swap their first two corners, so that every triangle keeps the strip's winding.
fn push_strip(list: &[i64], instance: usize, out: &mut Collected) {
    for strip in list.split(|&i| i == -1) {
        for (k, w) in strip.windows(3).enumerate() {
            let (a, b, c) = if k % 2 == 0 {
                (w[0], w[1], w[2])
            } else {
                (w[1], w[0], w[2])
            };
            if a == b || b == c || a == c {
                continue;
            }
            out.indices.extend_from_slice(&[a, b, c]);
            out.sources.push(("tristrips", instance));
        }
    }
}
