//! glTF 2.0 import (`.gltf` with external or embedded buffers, and `.glb`).
//!
//! A glTF scene is flattened into one [`IndexedMesh`]: every triangle primitive of every node
//! is transformed to world space and appended. Images are never decoded.
//!
//! Untrusted files are checked before anything is indexed: the GLB container is walked by
//! hand (the `gltf` crate's own errors do not say what is wrong, and some headers make it
//! overflow), the JSON is validated with a report that names each pointer, and every accessor
//! is decoded here with explicit bounds checks rather than by the `gltf` reader, which can
//! panic or silently stop short on inconsistent counts, strides or sparse data.

use super::{IndexedMesh, MeshError, MeshResult, ValidationReport};
use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::json::validation::{Error as JsonError, Validate};
use gltf::mesh::{Mode, Semantic};
use gltf::{Accessor, Document, Primitive};
use std::borrow::Cow;
use std::path::Path;

/// Accessors without a buffer view are zeros of the declared count; a count above this
/// would only exhaust memory, so such files are rejected.
const MAX_ZERO_FILLED_ELEMENTS: usize = 1 << 24;

/// The result of [`load_gltf`]: the flattened mesh and what else the file held.
#[derive(Clone, Debug)]
pub struct GltfImport {
    /// Every triangle primitive of the scene in one mesh, already validated.
    ///
    /// Positions and normals are in world space, except for skinned meshes: the transform of
    /// a skinned mesh's node is ignored, as the glTF specification requires, so their vertices
    /// stay in bind (mesh) space and the skin's joints place them. Joint indices refer to the
    /// joint list of the lowest-numbered skin that a node uses ([`skins`](Self::skins)); other
    /// skins are remapped to it through their joint nodes.
    ///
    /// Normals are kept only when every primitive has them. Texture coordinates, joints and
    /// weights are kept when any primitive has them, and are zero for the vertices of
    /// primitives without.
    pub mesh: IndexedMesh,
    /// Number of triangle primitives flattened into the mesh (each instance counts).
    pub primitives: usize,
    /// How many of those primitives have morph targets. Only their base shape is imported.
    pub morph_target_primitives: usize,
    /// Every skin of the document, in document order.
    pub skins: Vec<GltfSkinInfo>,
    /// What [`IndexedMesh::validate`] dropped from the flattened mesh.
    pub report: ValidationReport,
    /// A region id per vertex, when the file paints regions (ASLOD's artists painted them with
    /// vertex colours): the custom attribute `_REGION` (integer or float scalar), or else
    /// `COLOR_0` quantised to 8 bits per channel (RGB packed into one id, so each distinct
    /// colour is one region). Vertices of primitives without either get `u32::MAX`. Feed the
    /// ids to `regions::Partition::from_ids`, which renumbers them.
    pub region_ids: Option<Vec<u32>>,
}

/// A glTF skin: the joints that deform a skinned mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfSkinInfo {
    /// The skin's name, if the file gives one.
    pub name: Option<String>,
    /// The joints, as indices of glTF nodes; a vertex's joint `j` is node `joints[j]`.
    pub joints: Vec<usize>,
    /// One inverse bind matrix per joint (identity when the file gives none).
    pub inverse_bind_matrices: Vec<Mat4>,
}

/// Reads a `.gltf` or `.glb` file and flattens its default scene into one mesh; see
/// [`load_gltf_slice`]. External buffers are resolved relative to the file's directory.
///
/// # Errors
/// [`MeshError::Io`] when the file cannot be read, otherwise the errors of
/// [`load_gltf_slice`].
pub fn load_gltf(path: &Path) -> MeshResult<GltfImport> {
    let bytes = std::fs::read(path).map_err(|e| MeshError::io(path, e))?;
    load_gltf_slice(&bytes, path.parent())
}

/// Parses glTF JSON or a GLB container held in memory and flattens it into one mesh.
///
/// The nodes imported are those of the default scene; without one, those of every scene;
/// without scenes, every root node; and in a file with meshes but no nodes at all, every mesh
/// once, untransformed. Primitives of mode triangles, triangle strip and triangle fan are
/// imported (points and lines are skipped) with `POSITION`, `NORMAL`, `TEXCOORD_0`,
/// `JOINTS_0` and `WEIGHTS_0`. Normals are transformed by the inverse transpose and
/// renormalised, and a mirroring transform flips the winding so that front faces stay
/// counter-clockwise. See [`GltfImport::mesh`] for the handling of skins and of attributes
/// that only some primitives have.
///
/// External buffers are read from `base_dir`; `data:` URIs and the GLB `BIN` chunk need none.
///
/// # Errors
/// - [`MeshError::Gltf`] for a defective GLB container (the message says `empty file`,
///   `truncated GLB header`, `GLB length mismatch`, `truncated chunk`, `unaligned chunk` or
///   `BOM`), invalid JSON, unresolved references (naming the pointer, as in
///   `accessors[0].bufferView: unresolved reference 5`), unreadable or short buffers,
///   accessors that reach past their buffer view, attribute types this importer cannot read,
///   and skins without joints (`skins[i].joints`).
/// - [`MeshError::AttributeCountMismatch`] when the attributes of one primitive have
///   different counts.
/// - [`MeshError::IndexOutOfRange`] when a primitive's index refers to no vertex of it (the
///   triangle is counted within the primitive).
/// - [`MeshError::IndexCountNotMultipleOfThree`] for a triangle-list primitive whose index
///   count is not a multiple of three.
/// - Any error of [`IndexedMesh::validate`] on the flattened mesh.
pub fn load_gltf_slice(bytes: &[u8], base_dir: Option<&Path>) -> MeshResult<GltfImport> {
    let (json, bin) = if bytes.starts_with(b"glTF") {
        split_glb(bytes)?
    } else if bytes.is_empty() {
        return Err(gltf_error("empty file: no GLB header and no JSON"));
    } else {
        (bytes, None)
    };
    // Some exporters pad the JSON chunk with NULs instead of spaces; tolerate that.
    let end = json.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    let document = parse_document(&json[..end])?;
    let buffers = load_buffers(&document, bin, base_dir)?;
    let data = Data { buffers };

    // Skins first: a file may be nothing but a broken skin.
    let skins = document
        .skins()
        .map(|skin| read_skin(&data, &skin))
        .collect::<MeshResult<Vec<_>>>()?;

    let instances = collect_instances(&document)?;
    let mut builder = Builder::new(&skins, &instances);
    for instance in &instances {
        for primitive in instance.mesh.primitives() {
            builder.add_primitive(&data, &primitive, instance)?;
        }
    }
    let mut import = builder.finish(skins);
    import.report = import.mesh.validate()?;
    Ok(import)
}

fn gltf_error(message: impl Into<String>) -> MeshError {
    MeshError::Gltf {
        message: message.into(),
    }
}

// ---------------------------------------------------------------------------------------------
// GLB container and JSON

/// Splits a GLB file into its JSON and optional BIN chunk, naming any container defect.
fn split_glb(bytes: &[u8]) -> MeshResult<(&[u8], Option<&[u8]>)> {
    let u32_at = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    let (Some(version), Some(declared)) = (u32_at(4), u32_at(8)) else {
        return Err(gltf_error(format!(
            "truncated GLB header: it needs 12 bytes, the file has {}",
            bytes.len()
        )));
    };
    if version != 2 {
        return Err(gltf_error(format!(
            "unsupported GLB version {version} (expected 2)"
        )));
    }
    // Walk the chunks that are really there, so that a file cut short is reported as the
    // truncated chunk it is, and a wrong total length after that.
    let end = bytes.len().min(declared.max(12));
    let (mut json, mut bin) = (None, None);
    let mut pos = 12;
    let mut chunk = 0;
    while pos < end {
        let (Some(length), Some(kind)) = (u32_at(pos), bytes.get(pos + 4..pos + 8)) else {
            return Err(gltf_error(format!(
                "truncated chunk header: chunk {chunk} at byte {pos} needs 8 bytes, {} remain",
                end - pos
            )));
        };
        let name = String::from_utf8_lossy(kind)
            .trim_end_matches('\0')
            .to_owned();
        if !length.is_multiple_of(4) {
            return Err(gltf_error(format!(
                "unaligned chunk: chunk {chunk} ({name}) at byte {pos} has length {length}, \
                 not a multiple of 4"
            )));
        }
        let start = pos + 8;
        if length > end - start {
            return Err(gltf_error(format!(
                "truncated chunk: chunk {chunk} ({name}) declares {length} bytes at byte \
                 {start}, only {} remain",
                end - start
            )));
        }
        let content = &bytes[start..start + length];
        match (chunk, kind) {
            (0, b"JSON") => json = Some(content),
            (0, _) => {
                return Err(gltf_error(format!(
                    "the first GLB chunk must be JSON, found `{name}`"
                )));
            }
            (1, b"BIN\0") => bin = Some(content),
            // Unknown chunks must be ignored.
            _ => {}
        }
        pos = start + length;
        chunk += 1;
    }
    if declared != bytes.len() {
        return Err(gltf_error(format!(
            "GLB length mismatch: the header declares {declared} bytes, the file has {}",
            bytes.len()
        )));
    }
    let json = json.ok_or_else(|| gltf_error("GLB has no JSON chunk"))?;
    Ok((json, bin))
}

/// Parses and validates the JSON, reporting every problem with its pointer.
fn parse_document(json: &[u8]) -> MeshResult<Document> {
    if json.starts_with(b"\xEF\xBB\xBF") {
        return Err(gltf_error(
            "the JSON starts with a UTF-8 BOM (byte order mark), which glTF forbids",
        ));
    }
    let root: gltf::json::Root = gltf::json::deserialize::from_slice(json)
        .map_err(|e| gltf_error(format!("invalid JSON: {e}")))?;

    // The `gltf` crate's validation indexes the POSITION accessor without checking it.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &primitive.attributes {
                if index.value() >= root.accessors.len() {
                    let name = match semantic {
                        gltf::json::validation::Checked::Valid(s) => semantic_name(s),
                        gltf::json::validation::Checked::Invalid => "?",
                    };
                    return Err(gltf_error(format!(
                        "meshes[{m}].primitives[{p}].attributes[\"{name}\"]: unresolved \
                         reference {}",
                        index.value()
                    )));
                }
            }
        }
    }

    let mut problems = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |path, error| {
        problems.push((path().0, error));
    });
    // The crate insists on a bufferView, but the specification says an accessor without one
    // is all zeros (possibly with sparse values on top), and the readers below handle that.
    problems.retain(|(path, error)| {
        !(*error == JsonError::Missing
            && path.starts_with("accessors[")
            && path.ends_with("].bufferView"))
    });
    if !problems.is_empty() {
        let value = gltf::json::deserialize::from_slice::<gltf::json::Value>(json).ok();
        let messages: Vec<String> = problems
            .iter()
            .map(|(path, error)| {
                let what = match error {
                    JsonError::IndexOutOfBounds => {
                        let target = value.as_ref().and_then(|v| lookup(v, path));
                        match target {
                            Some(t) => format!("unresolved reference {t}"),
                            None => "unresolved reference".to_owned(),
                        }
                    }
                    JsonError::Invalid => "invalid value".to_owned(),
                    JsonError::Missing => "missing".to_owned(),
                    JsonError::Oversize => "too large for this platform".to_owned(),
                    JsonError::Unsupported => "not supported".to_owned(),
                };
                format!("{path}: {what}")
            })
            .collect();
        return Err(gltf_error(messages.join("; ")));
    }
    Ok(Document::from_json_without_validation(root))
}

/// Follows a `gltf-json` path such as `accessors[0].sparse.indices.bufferView` or
/// `meshes[0].primitives[0].attributes["POSITION"]` to the value it names.
fn lookup<'v>(root: &'v gltf::json::Value, path: &str) -> Option<&'v gltf::json::Value> {
    let mut value = root;
    let mut rest = path;
    while !rest.is_empty() {
        rest = rest.strip_prefix('.').unwrap_or(rest);
        if let Some(after) = rest.strip_prefix("[\"") {
            let (key, tail) = after.split_once("\"]")?;
            value = value.get(key)?;
            rest = tail;
        } else if let Some(after) = rest.strip_prefix('[') {
            let (index, tail) = after.split_once(']')?;
            value = value.get(index.parse::<usize>().ok()?)?;
            rest = tail;
        } else {
            let end = rest.find(['.', '[']).unwrap_or(rest.len());
            value = value.get(&rest[..end])?;
            rest = &rest[end..];
        }
    }
    Some(value)
}

// ---------------------------------------------------------------------------------------------
// Buffers and accessors

/// The contents of the document's buffers, by buffer index.
struct Data<'a> {
    buffers: Vec<Cow<'a, [u8]>>,
}

fn load_buffers<'a>(
    document: &Document,
    bin: Option<&'a [u8]>,
    base_dir: Option<&Path>,
) -> MeshResult<Vec<Cow<'a, [u8]>>> {
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let i = buffer.index();
        let data: Cow<'a, [u8]> = match buffer.source() {
            gltf::buffer::Source::Bin => Cow::Borrowed(bin.ok_or_else(|| {
                gltf_error(format!(
                    "buffers[{i}]: refers to the GLB BIN chunk, but there is none"
                ))
            })?),
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let data = gltf::buffer::Data::from_source(buffer.source(), None)
                    .map_err(|e| gltf_error(format!("buffers[{i}].uri: bad data URI: {e}")))?;
                Cow::Owned(data.0)
            }
            gltf::buffer::Source::Uri(uri) => Cow::Owned(
                read_external(uri, base_dir)
                    .map_err(|message| gltf_error(format!("buffers[{i}].uri: {message}")))?,
            ),
        };
        if data.len() < buffer.length() {
            return Err(gltf_error(format!(
                "buffers[{i}]: byteLength is {} but only {} bytes of data exist",
                buffer.length(),
                data.len()
            )));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// Reads a buffer stored in a file next to the glTF.
fn read_external(uri: &str, base_dir: Option<&Path>) -> Result<Vec<u8>, String> {
    if uri.contains(':') {
        return Err(format!("unsupported URI scheme in `{uri}`"));
    }
    let relative = percent_decode(uri).ok_or_else(|| format!("malformed URI `{uri}`"))?;
    let base = base_dir.ok_or_else(|| {
        format!("external file `{relative}` cannot be resolved without a base directory")
    })?;
    let path = base.join(&relative);
    std::fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))
}

fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

impl Data<'_> {
    /// The bytes of a buffer view, checked against its buffer.
    fn view_bytes(&self, view: &gltf::buffer::View<'_>) -> MeshResult<&[u8]> {
        let buffer = &self.buffers[view.buffer().index()];
        view.offset()
            .checked_add(view.length())
            .and_then(|end| buffer.get(view.offset()..end))
            .ok_or_else(|| {
                gltf_error(format!(
                    "bufferViews[{}]: bytes {}..{} lie outside buffers[{}] ({} bytes)",
                    view.index(),
                    view.offset(),
                    view.offset().saturating_add(view.length()),
                    view.buffer().index(),
                    buffer.len()
                ))
            })
    }

    /// Decodes every element of an accessor, sparse substitution included, with `decode`
    /// getting exactly one element's bytes. Nothing is read that was not bounds-checked.
    fn read<T: Clone>(
        &self,
        accessor: &Accessor<'_>,
        zero: T,
        decode: impl Fn(&[u8]) -> T,
    ) -> MeshResult<Vec<T>> {
        let a = accessor.index();
        let count = accessor.count();
        let size = accessor.size();
        if count == 0 {
            return Err(gltf_error(format!(
                "accessors[{a}].count: must be at least 1"
            )));
        }
        let mut out = match accessor.view() {
            Some(view) => {
                let bytes = self.view_bytes(&view)?;
                let stride = view.stride().unwrap_or(size);
                if stride < size {
                    return Err(gltf_error(format!(
                        "accessors[{a}]: bufferViews[{}].byteStride {stride} is smaller than \
                         the element size {size}",
                        view.index()
                    )));
                }
                let start = accessor.offset();
                let needed = stride
                    .checked_mul(count - 1)
                    .and_then(|n| n.checked_add(start))
                    .and_then(|n| n.checked_add(size));
                if needed.is_none_or(|n| n > bytes.len()) {
                    return Err(gltf_error(format!(
                        "accessors[{a}]: {count} elements of {size} bytes (stride {stride}, \
                         offset {start}) do not fit in bufferViews[{}] ({} bytes)",
                        view.index(),
                        bytes.len()
                    )));
                }
                (0..count)
                    .map(|i| decode(&bytes[start + i * stride..][..size]))
                    .collect()
            }
            None if count > MAX_ZERO_FILLED_ELEMENTS => {
                return Err(gltf_error(format!(
                    "accessors[{a}]: {count} zero-initialised elements is more than this \
                     importer accepts ({MAX_ZERO_FILLED_ELEMENTS})"
                )));
            }
            None => vec![zero; count],
        };

        if let Some(sparse) = accessor.sparse() {
            let n = sparse.count();
            if n > count {
                return Err(gltf_error(format!(
                    "accessors[{a}].sparse.count: {n} exceeds the accessor count {count}"
                )));
            }
            let indices = sparse.indices();
            let index_size = indices.index_type().size();
            let index_bytes = self.view_bytes(&indices.view())?;
            let index_bytes = n
                .checked_mul(index_size)
                .and_then(|len| index_bytes.get(indices.offset()..)?.get(..len))
                .ok_or_else(|| {
                    gltf_error(format!(
                        "accessors[{a}].sparse.indices: {n} indices do not fit in their buffer \
                         view"
                    ))
                })?;
            let values = sparse.values();
            let value_bytes = self.view_bytes(&values.view())?;
            let value_bytes = n
                .checked_mul(size)
                .and_then(|len| value_bytes.get(values.offset()..)?.get(..len))
                .ok_or_else(|| {
                    gltf_error(format!(
                        "accessors[{a}].sparse.values: {n} values do not fit in their buffer \
                         view"
                    ))
                })?;
            for (k, raw) in index_bytes.chunks_exact(index_size).enumerate() {
                let target = match *raw {
                    [b] => usize::from(b),
                    [b0, b1] => usize::from(u16::from_le_bytes([b0, b1])),
                    [b0, b1, b2, b3] => u32::from_le_bytes([b0, b1, b2, b3]) as usize,
                    _ => unreachable!("sparse index sizes are 1, 2 or 4"),
                };
                let slot = out.get_mut(target).ok_or_else(|| {
                    gltf_error(format!(
                        "accessors[{a}].sparse.indices: index {target} is out of range \
                         ({count} elements)"
                    ))
                })?;
                *slot = decode(&value_bytes[k * size..][..size]);
            }
        }
        Ok(out)
    }

    /// Reads `N`-component float data: `f32`, or integers (normalized or not, as
    /// `KHR_mesh_quantization` allows).
    fn read_floats<const N: usize>(
        &self,
        accessor: &Accessor<'_>,
        what: &str,
    ) -> MeshResult<Vec<[f32; N]>> {
        let ty = accessor.data_type();
        if accessor.dimensions().multiplicity() != N {
            return Err(type_error(accessor, what, &format!("{N} components")));
        }
        let normalized = accessor.normalized();
        let c = ty.size();
        self.read(accessor, [0.0; N], |b| {
            std::array::from_fn(|j| component_f32(&b[j * c..j * c + c], ty, normalized))
        })
    }

    /// Reads `N`-component unsigned integer data of the given component types.
    fn read_uints<const N: usize>(
        &self,
        accessor: &Accessor<'_>,
        what: &str,
        allowed: &[DataType],
    ) -> MeshResult<Vec<[u32; N]>> {
        let ty = accessor.data_type();
        if accessor.dimensions().multiplicity() != N || !allowed.contains(&ty) {
            let types: Vec<String> = allowed.iter().map(|t| format!("{t:?}")).collect();
            let expected = format!("{N} components of type {}", types.join(" or "));
            return Err(type_error(accessor, what, &expected));
        }
        let c = ty.size();
        self.read(accessor, [0; N], |b| {
            std::array::from_fn(|j| match b[j * c..j * c + c] {
                [x] => u32::from(x),
                [x0, x1] => u32::from(u16::from_le_bytes([x0, x1])),
                [x0, x1, x2, x3] => u32::from_le_bytes([x0, x1, x2, x3]),
                _ => 0,
            })
        })
    }
}

fn type_error(accessor: &Accessor<'_>, what: &str, expected: &str) -> MeshError {
    gltf_error(format!(
        "{what} (accessors[{}]): expected {expected}, found {:?} of {:?}",
        accessor.index(),
        accessor.dimensions(),
        accessor.data_type()
    ))
}

/// One component as a float, with the specification's normalization formulas.
fn component_f32(b: &[u8], ty: DataType, normalized: bool) -> f32 {
    match (ty, b) {
        (DataType::F32, &[b0, b1, b2, b3]) => f32::from_le_bytes([b0, b1, b2, b3]),
        (DataType::U32, &[b0, b1, b2, b3]) => u32::from_le_bytes([b0, b1, b2, b3]) as f32,
        (DataType::I8, &[x]) if normalized => (f32::from(x as i8) / 127.0).max(-1.0),
        (DataType::I8, &[x]) => f32::from(x as i8),
        (DataType::U8, &[x]) if normalized => f32::from(x) / 255.0,
        (DataType::U8, &[x]) => f32::from(x),
        (DataType::I16, &[x0, x1]) => {
            let v = f32::from(i16::from_le_bytes([x0, x1]));
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        (DataType::U16, &[x0, x1]) => {
            let v = f32::from(u16::from_le_bytes([x0, x1]));
            if normalized { v / 65535.0 } else { v }
        }
        _ => 0.0,
    }
}

/// The attribute name as written in glTF, for error messages.
fn semantic_name(semantic: &Semantic) -> &'static str {
    const COLOR: [&str; 4] = ["COLOR_0", "COLOR_1", "COLOR_2", "COLOR_3"];
    const TEXCOORD: [&str; 4] = ["TEXCOORD_0", "TEXCOORD_1", "TEXCOORD_2", "TEXCOORD_3"];
    const JOINTS: [&str; 4] = ["JOINTS_0", "JOINTS_1", "JOINTS_2", "JOINTS_3"];
    const WEIGHTS: [&str; 4] = ["WEIGHTS_0", "WEIGHTS_1", "WEIGHTS_2", "WEIGHTS_3"];
    let set = |names: [&'static str; 4], n: u32, other: &'static str| {
        names.get(n as usize).copied().unwrap_or(other)
    };
    match *semantic {
        Semantic::Positions => "POSITION",
        Semantic::Normals => "NORMAL",
        Semantic::Tangents => "TANGENT",
        Semantic::Colors(n) => set(COLOR, n, "COLOR_n"),
        Semantic::TexCoords(n) => set(TEXCOORD, n, "TEXCOORD_n"),
        Semantic::Joints(n) => set(JOINTS, n, "JOINTS_n"),
        Semantic::Weights(n) => set(WEIGHTS, n, "WEIGHTS_n"),
        Semantic::Extras(_) => "_custom",
    }
}

// ---------------------------------------------------------------------------------------------
// Skins and scene traversal

fn read_skin(data: &Data<'_>, skin: &gltf::Skin<'_>) -> MeshResult<GltfSkinInfo> {
    let s = skin.index();
    let joints: Vec<usize> = skin.joints().map(|node| node.index()).collect();
    if joints.is_empty() {
        return Err(gltf_error(format!(
            "skins[{s}].joints: the joint list is empty; a skin needs at least one joint"
        )));
    }
    let inverse_bind_matrices = match skin.inverse_bind_matrices() {
        None => vec![Mat4::IDENTITY; joints.len()],
        Some(accessor) => {
            let what = format!("skins[{s}].inverseBindMatrices");
            if accessor.dimensions() != Dimensions::Mat4 || accessor.data_type() != DataType::F32 {
                return Err(type_error(&accessor, &what, "MAT4 of F32"));
            }
            let mut matrices: Vec<Mat4> = data
                .read_floats::<16>(&accessor, &what)?
                .iter()
                .map(Mat4::from_cols_array)
                .collect();
            if matrices.len() < joints.len() {
                return Err(gltf_error(format!(
                    "{what}: {} matrices for {} joints",
                    matrices.len(),
                    joints.len()
                )));
            }
            matrices.truncate(joints.len());
            matrices
        }
    };
    Ok(GltfSkinInfo {
        name: skin.name().map(str::to_owned),
        joints,
        inverse_bind_matrices,
    })
}

/// One mesh placed in the scene.
struct Instance<'a> {
    mesh: gltf::Mesh<'a>,
    skin: Option<usize>,
    /// Mesh space to world space (identity for skinned meshes, whose node transform the
    /// specification says to ignore).
    transform: Mat4,
}

fn collect_instances(document: &Document) -> MeshResult<Vec<Instance<'_>>> {
    let node_count = document.nodes().len();
    let traversals: Vec<Vec<usize>> = if let Some(scene) = document.default_scene() {
        vec![scene.nodes().map(|n| n.index()).collect()]
    } else if document.scenes().len() > 0 {
        document
            .scenes()
            .map(|scene| scene.nodes().map(|n| n.index()).collect())
            .collect()
    } else if node_count > 0 {
        let mut is_child = vec![false; node_count];
        for node in document.nodes() {
            for child in node.children() {
                is_child[child.index()] = true;
            }
        }
        vec![(0..node_count).filter(|&n| !is_child[n]).collect()]
    } else {
        return Ok(document
            .meshes()
            .map(|mesh| Instance {
                mesh,
                skin: None,
                transform: Mat4::IDENTITY,
            })
            .collect());
    };

    let nodes: Vec<gltf::Node<'_>> = document.nodes().collect();
    let mut instances = Vec::new();
    for roots in traversals {
        // A node reached twice means a cycle (or a shared child); either would repeat forever
        // or duplicate geometry, and both are invalid glTF.
        let mut visited = vec![false; node_count];
        let mut stack: Vec<(usize, Mat4)> =
            roots.iter().rev().map(|&n| (n, Mat4::IDENTITY)).collect();
        while let Some((n, parent)) = stack.pop() {
            if std::mem::replace(&mut visited[n], true) {
                return Err(gltf_error(format!(
                    "nodes[{n}]: reached twice from the scene roots (a cycle or a node with two \
                     parents)"
                )));
            }
            let node = &nodes[n];
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            if let Some(mesh) = node.mesh() {
                let skin = node.skin().map(|s| s.index());
                instances.push(Instance {
                    mesh,
                    skin,
                    transform: if skin.is_some() {
                        Mat4::IDENTITY
                    } else {
                        world
                    },
                });
            }
            let children: Vec<usize> = node.children().map(|c| c.index()).collect();
            stack.extend(children.into_iter().rev().map(|c| (c, world)));
        }
    }
    Ok(instances)
}

// ---------------------------------------------------------------------------------------------
// Flattening

/// Accumulates the flattened mesh.
struct Builder {
    mesh: IndexedMesh,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    region_ids: Vec<u32>,
    any_region_ids: bool,
    /// Which attributes some, and which all, primitives had.
    any_normals: bool,
    all_normals: bool,
    any_uvs: bool,
    any_joints: bool,
    any_weights: bool,
    /// Per skin, the map from its joint indices to those of the primary skin (`None` when a
    /// joint node is missing there, which drops the joints).
    joint_maps: Vec<Option<Vec<u16>>>,
    /// Per skin, its number of joints.
    joint_counts: Vec<usize>,
    joints_unmappable: bool,
    primitives: usize,
    morph_target_primitives: usize,
}

impl Builder {
    fn new(skins: &[GltfSkinInfo], instances: &[Instance<'_>]) -> Self {
        let primary = instances.iter().filter_map(|i| i.skin).min();
        let joint_maps = skins
            .iter()
            .map(|skin| {
                let primary = &skins[primary?].joints;
                skin.joints
                    .iter()
                    .map(|node| {
                        let j = primary.iter().position(|p| p == node)?;
                        u16::try_from(j).ok()
                    })
                    .collect()
            })
            .collect();
        Self {
            mesh: IndexedMesh::default(),
            normals: Vec::new(),
            uvs: Vec::new(),
            joints: Vec::new(),
            weights: Vec::new(),
            region_ids: Vec::new(),
            any_region_ids: false,
            any_normals: false,
            all_normals: true,
            any_uvs: false,
            any_joints: false,
            any_weights: false,
            joint_maps,
            joint_counts: skins.iter().map(|s| s.joints.len()).collect(),
            joints_unmappable: false,
            primitives: 0,
            morph_target_primitives: 0,
        }
    }

    fn add_primitive(
        &mut self,
        data: &Data<'_>,
        primitive: &Primitive<'_>,
        instance: &Instance<'_>,
    ) -> MeshResult<()> {
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            log::debug!("glTF: skipping a primitive of mode {mode:?}");
            return Ok(());
        }
        let at = format!(
            "meshes[{}].primitives[{}]",
            instance.mesh.index(),
            primitive.index()
        );
        let Some(position_accessor) = primitive.get(&Semantic::Positions) else {
            return Err(gltf_error(format!("{at}.attributes: no POSITION")));
        };
        let vertex_count = position_accessor.count();
        for (semantic, accessor) in primitive.attributes() {
            if accessor.count() != vertex_count {
                return Err(MeshError::AttributeCountMismatch {
                    attribute: semantic_name(&semantic),
                    expected: vertex_count,
                    found: accessor.count(),
                });
            }
        }

        let attribute = |semantic: Semantic| {
            let name = semantic_name(&semantic);
            primitive
                .get(&semantic)
                .map(|a| (a, format!("{at}.attributes.{name}")))
        };
        let positions = data.read_floats::<3>(&position_accessor, &format!("{at}.POSITION"))?;
        let normals = match attribute(Semantic::Normals) {
            Some((a, what)) => Some(data.read_floats::<3>(&a, &what)?),
            None => None,
        };
        let uvs = match attribute(Semantic::TexCoords(0)) {
            Some((a, what)) => Some(data.read_floats::<2>(&a, &what)?),
            None => None,
        };
        let joints = match attribute(Semantic::Joints(0)) {
            Some((a, what)) => {
                Some(data.read_uints::<4>(&a, &what, &[DataType::U8, DataType::U16])?)
            }
            None => None,
        };
        let weights = match attribute(Semantic::Weights(0)) {
            Some((a, what)) => {
                let ty = a.data_type();
                if ty != DataType::F32
                    && !(a.normalized() && matches!(ty, DataType::U8 | DataType::U16))
                {
                    return Err(type_error(&a, &what, "F32 or normalized U8/U16"));
                }
                Some(data.read_floats::<4>(&a, &what)?)
            }
            None => None,
        };
        let indices = match primitive.indices() {
            Some(a) => {
                let what = format!("{at}.indices");
                let allowed = [DataType::U8, DataType::U16, DataType::U32];
                data.read_uints::<1>(&a, &what, &allowed)?
                    .into_iter()
                    .map(|[i]| i)
                    .collect()
            }
            None => (0..vertex_count as u32).collect::<Vec<u32>>(),
        };
        if let Some(pos) = indices.iter().position(|&i| i as usize >= vertex_count) {
            return Err(MeshError::IndexOutOfRange {
                triangle: pos / 3,
                index: indices[pos],
                vertex_count,
            });
        }
        let triangles = triangulate(mode, &indices)?;

        let base = self.mesh.positions.len();
        if base + vertex_count > u32::MAX as usize {
            return Err(gltf_error(format!(
                "{at}: more than 2^32 vertices in the scene"
            )));
        }
        let m = instance.transform;
        let linear = Mat3::from_mat4(m);
        let det = linear.determinant();
        // The cofactor matrix is the inverse transpose times the determinant, and stays
        // finite for singular transforms; the sign keeps normals pointing outwards.
        let cofactor = Mat3::from_cols(
            linear.y_axis.cross(linear.z_axis),
            linear.z_axis.cross(linear.x_axis),
            linear.x_axis.cross(linear.y_axis),
        ) * if det < 0.0 { -1.0 } else { 1.0 };
        self.mesh
            .positions
            .extend(positions.iter().map(|&p| m.transform_point3(Vec3::from(p))));

        self.any_normals |= normals.is_some();
        self.all_normals &= normals.is_some();
        match &normals {
            Some(n) => self.normals.extend(
                n.iter()
                    .map(|&n| (cofactor * Vec3::from(n)).normalize_or_zero()),
            ),
            None => self.normals.resize(base + vertex_count, Vec3::ZERO),
        }
        self.any_uvs |= uvs.is_some();
        match &uvs {
            Some(t) => self.uvs.extend(t.iter().map(|&t| Vec2::from(t))),
            None => self.uvs.resize(base + vertex_count, Vec2::ZERO),
        }
        self.any_weights |= weights.is_some();
        match &weights {
            Some(w) => self.weights.extend_from_slice(w),
            None => self.weights.resize(base + vertex_count, [0.0; 4]),
        }
        self.any_joints |= joints.is_some();
        match &joints {
            Some(js) => {
                for j in js {
                    let mapped = self.map_joints(*j, instance.skin, &at)?;
                    self.joints.push(mapped);
                }
            }
            None => self.joints.resize(base + vertex_count, [0; 4]),
        }

        let ids = read_region_ids(data, primitive, &at)?;
        self.any_region_ids |= ids.is_some();
        match ids {
            Some(ids) => self.region_ids.extend_from_slice(&ids),
            None => self.region_ids.resize(base + vertex_count, u32::MAX),
        }

        let flip = det < 0.0;
        self.mesh.indices.reserve(triangles.len() * 3);
        for [a, b, c] in triangles {
            let (b, c) = if flip { (c, b) } else { (b, c) };
            self.mesh.indices.extend([a, b, c].map(|i| i + base as u32));
        }
        self.primitives += 1;
        if primitive.morph_targets().len() > 0 {
            self.morph_target_primitives += 1;
        }
        Ok(())
    }

    /// Checks a vertex's joints against its skin and maps them to the primary skin.
    fn map_joints(
        &mut self,
        joints: [u32; 4],
        skin: Option<usize>,
        at: &str,
    ) -> MeshResult<[u16; 4]> {
        let Some(s) = skin else {
            // No skin to check against; u8/u16 data always fits.
            return Ok(joints.map(|j| j as u16));
        };
        let count = self.joint_counts[s];
        let mut out = [0; 4];
        for (o, &j) in out.iter_mut().zip(&joints) {
            if j as usize >= count {
                return Err(gltf_error(format!(
                    "{at}.attributes.JOINTS_0: joint {j} is out of range for skins[{s}] \
                     ({count} joints)"
                )));
            }
            *o = match &self.joint_maps[s] {
                Some(map) => map[j as usize],
                None => {
                    self.joints_unmappable = true;
                    0
                }
            };
        }
        Ok(out)
    }

    fn finish(self, skins: Vec<GltfSkinInfo>) -> GltfImport {
        let mut mesh = self.mesh;
        if self.any_normals && !self.all_normals {
            log::warn!("glTF: only some primitives have normals; dropping normals");
        }
        mesh.normals = (self.any_normals && self.all_normals).then_some(self.normals);
        mesh.uvs = self.any_uvs.then_some(self.uvs);
        let keep_joints = self.any_joints && !self.joints_unmappable;
        if self.joints_unmappable {
            log::warn!(
                "glTF: skins with joints missing from the primary skin; dropping joints and \
                 weights"
            );
        }
        mesh.joints = keep_joints.then_some(self.joints);
        mesh.weights = (keep_joints && self.any_weights).then_some(self.weights);
        GltfImport {
            mesh,
            primitives: self.primitives,
            morph_target_primitives: self.morph_target_primitives,
            skins,
            report: ValidationReport::default(),
            region_ids: self.any_region_ids.then_some(self.region_ids),
        }
    }
}

/// A primitive's painted region ids: `_REGION`, or `COLOR_0` quantised (see
/// [`GltfImport::region_ids`]).
fn read_region_ids(
    data: &Data<'_>,
    primitive: &Primitive<'_>,
    at: &str,
) -> MeshResult<Option<Vec<u32>>> {
    if let Some(a) = primitive.get(&Semantic::Extras("REGION".to_string())) {
        let what = format!("{at}.attributes._REGION");
        let ids = if a.data_type() == DataType::F32 {
            data.read_floats::<1>(&a, &what)?
                .into_iter()
                .map(|[x]| {
                    if x.is_finite() && x >= 0.0 {
                        x.round() as u32
                    } else {
                        u32::MAX
                    }
                })
                .collect()
        } else {
            let allowed = [DataType::U8, DataType::U16, DataType::U32];
            data.read_uints::<1>(&a, &what, &allowed)?
                .into_iter()
                .map(|[x]| x)
                .collect()
        };
        return Ok(Some(ids));
    }
    let Some(a) = primitive.get(&Semantic::Colors(0)) else {
        return Ok(None);
    };
    let what = format!("{at}.attributes.COLOR_0");
    let quantise = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u32;
    let pack = |r: f32, g: f32, b: f32| quantise(r) << 16 | quantise(g) << 8 | quantise(b);
    let ids = if a.dimensions().multiplicity() == 3 {
        data.read_floats::<3>(&a, &what)?
            .into_iter()
            .map(|[r, g, b]| pack(r, g, b))
            .collect()
    } else {
        data.read_floats::<4>(&a, &what)?
            .into_iter()
            .map(|[r, g, b, _]| pack(r, g, b))
            .collect()
    };
    Ok(Some(ids))
}

/// Turns a primitive's index list into triangles (`TRIANGLES`, `TRIANGLE_STRIP` or
/// `TRIANGLE_FAN`), in the order and winding the specification defines.
fn triangulate(mode: Mode, indices: &[u32]) -> MeshResult<Vec<[u32; 3]>> {
    Ok(match mode {
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(i, w)| {
                if i % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[0], w[2], w[1]]
                }
            })
            .collect(),
        Mode::TriangleFan => match indices.split_first() {
            Some((&first, rest)) => rest.windows(2).map(|w| [w[0], w[1], first]).collect(),
            None => Vec::new(),
        },
        _ => {
            if !indices.len().is_multiple_of(3) {
                return Err(MeshError::IndexCountNotMultipleOfThree {
                    count: indices.len(),
                });
            }
            indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        }
    })
}
