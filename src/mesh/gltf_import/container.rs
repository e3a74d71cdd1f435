//! Reading the container: the GLB chunks, the validated JSON document and the buffers.

use crate::mesh::{LoadLimits, MeshError, MeshResult};
use gltf::Document;
use gltf::json::validation::{Error as JsonError, Validate};
use gltf::mesh::Semantic;
use std::borrow::Cow;
use std::path::Path;

pub(super) fn gltf_error(message: impl Into<String>) -> MeshError {
    MeshError::Gltf {
        message: message.into(),
    }
}

/// Splits a GLB file into its JSON and optional BIN chunk, naming any container defect.
pub(super) fn split_glb(bytes: &[u8]) -> MeshResult<(&[u8], Option<&[u8]>)> {
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
    // Bytes past the declared length are not the file's: refuse them before reading chunks.
    if declared < bytes.len() {
        return Err(length_mismatch(declared, bytes.len()));
    }
    // Walk the chunks that are really there, so that a file cut short is reported as the
    // truncated chunk it is, and a wrong total length after that.
    let end = bytes.len();
    let (mut json, mut bin) = (None, None);
    let mut pos = 12;
    let mut chunk = 0;
    while pos < end {
        let header = bytes.get(pos..end).filter(|rest| rest.len() >= 8);
        let (Some(length), Some(kind)) = (header.and(u32_at(pos)), header.map(|h| &h[4..8])) else {
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
        return Err(length_mismatch(declared, bytes.len()));
    }
    let json = json.ok_or_else(|| gltf_error("GLB has no JSON chunk"))?;
    Ok((json, bin))
}

/// A GLB whose header declares another length than the file has.
fn length_mismatch(declared: usize, actual: usize) -> MeshError {
    gltf_error(format!(
        "GLB length mismatch: the header declares {declared} bytes, the file has {actual}"
    ))
}

/// Parses and validates the JSON, reporting every problem with its pointer.
pub(super) fn parse_document(json: &[u8]) -> MeshResult<Document> {
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

/// The attribute name as written in glTF, for error messages.
pub(super) fn semantic_name(semantic: &Semantic) -> &'static str {
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

/// Every buffer of `document`: the GLB `bin` chunk, `data:` URIs, and files in `base_dir`.
/// The external files' declared lengths and the glTF's own `file_bytes` are summed against
/// [`LoadLimits::file_bytes`] before any is read (a file naming one large buffer many times
/// would otherwise read it as often).
pub(super) fn load_buffers<'a>(
    document: &Document,
    file_bytes: usize,
    bin: Option<&'a [u8]>,
    base_dir: Option<&Path>,
    limits: &LoadLimits,
) -> MeshResult<Vec<Cow<'a, [u8]>>> {
    let external = document
        .buffers()
        .filter(
            |b| matches!(b.source(), gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:")),
        )
        .fold(file_bytes as u64, |sum, b| {
            sum.saturating_add(b.length() as u64)
        });
    LoadLimits::check("file_bytes", external, limits.file_bytes)?;
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let i = buffer.index();
        LoadLimits::check("file_bytes", buffer.length() as u64, limits.file_bytes)?;
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
                read_external(uri, base_dir, buffer.length())
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

/// Reads the first `length` bytes of a buffer stored in a file in the glTF's own folder (or
/// below it). The URI must be relative, without `..`, and name a regular file whose real
/// path (symbolic links followed) stays inside that folder: a file naming `/etc/passwd`,
/// `../secret` or `/dev/zero` is refused before anything is read.
fn read_external(uri: &str, base_dir: Option<&Path>, length: usize) -> Result<Vec<u8>, String> {
    use std::io::Read;
    use std::path::Component;
    if uri.contains(':') {
        return Err(format!("unsupported URI scheme in `{uri}`"));
    }
    let relative = percent_decode(uri).ok_or_else(|| format!("malformed URI `{uri}`"))?;
    let relative_path = Path::new(&relative);
    if relative.starts_with(['/', '\\'])
        || relative.contains('\\')
        || relative_path
            .components()
            .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
    {
        return Err(format!(
            "`{relative}` is not a plain relative path (no absolute paths, `..` or \
             backslashes): external buffers must lie in the glTF's own folder"
        ));
    }
    let base = base_dir.ok_or_else(|| {
        format!("external file `{relative}` cannot be resolved without a base directory")
    })?;
    let base = if base.as_os_str().is_empty() {
        Path::new(".")
    } else {
        base
    };
    let path = base.join(relative_path);
    let cannot = |e: std::io::Error| format!("cannot read {}: {e}", path.display());
    let (real_base, real) = (
        base.canonicalize().map_err(cannot)?,
        path.canonicalize().map_err(cannot)?,
    );
    if !real.starts_with(&real_base) {
        return Err(format!(
            "`{relative}` leads outside the glTF's folder (to {})",
            real.display()
        ));
    }
    let file = std::fs::File::open(&real).map_err(cannot)?;
    if !file.metadata().map_err(cannot)?.is_file() {
        return Err(format!("`{relative}` is not a regular file"));
    }
    // Never more than the buffer declares, whatever the file holds.
    let mut data = Vec::new();
    file.take(length as u64)
        .read_to_end(&mut data)
        .map_err(cannot)?;
    Ok(data)
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
