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
//!
//! [`IndexedMesh`]: super::IndexedMesh

mod accessors;
mod container;
mod flatten;
mod plan;
mod scene;

pub use flatten::GltfImport;
use glam::Mat4;
pub use scene::GltfSkinInfo;

#[cfg(doc)]
use super::MeshError;
use super::{LoadLimits, MeshResult};
use accessors::Data;
use container::{gltf_error, load_buffers, parse_document, split_glb};
use flatten::Builder;
use plan::Plan;
use scene::{collect_instances, read_skin};
use std::collections::HashMap;
use std::path::Path;
use std::rc::Rc;

/// Reads a `.gltf` or `.glb` file and flattens its default scene into one mesh; see
/// [`load_gltf_slice`]. External buffers are resolved relative to the file's directory.
///
/// # Errors
/// [`MeshError::Io`] when the file cannot be read, otherwise the errors of
/// [`load_gltf_slice`].
pub fn load_gltf(path: &Path) -> MeshResult<GltfImport> {
    load_gltf_with_limits(path, &LoadLimits::default())
}

/// [`load_gltf`] within `limits` (the file's and each external buffer's size, the data
/// decoded, the vertices, triangles and joints).
///
/// # Errors
/// As [`load_gltf`], and [`MeshError::LimitExceeded`] naming the limit the file exceeds.
pub fn load_gltf_with_limits(path: &Path, limits: &LoadLimits) -> MeshResult<GltfImport> {
    let bytes = limits.read_file(path)?;
    load_gltf_slice_with_limits(&bytes, path.parent(), limits)
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
/// - [`MeshError::TooLarge`] when the scene holds more vertices than 32-bit indices address.
/// - Any error of [`IndexedMesh::validate`] on the flattened mesh.
///
/// [`IndexedMesh::validate`]: super::IndexedMesh::validate
pub fn load_gltf_slice(bytes: &[u8], base_dir: Option<&Path>) -> MeshResult<GltfImport> {
    load_gltf_slice_with_limits(bytes, base_dir, &LoadLimits::default())
}

/// [`load_gltf_slice`] within `limits`.
///
/// # Errors
/// As [`load_gltf_slice`], and [`MeshError::LimitExceeded`] naming the limit the file
/// exceeds.
pub fn load_gltf_slice_with_limits(
    bytes: &[u8],
    base_dir: Option<&Path>,
    limits: &LoadLimits,
) -> MeshResult<GltfImport> {
    LoadLimits::check("file_bytes", bytes.len() as u64, limits.file_bytes)?;
    let (document, bin) = parse(bytes, limits)?;
    let instances = collect_instances(&document)?;
    let plan = Plan::check(
        &document,
        instances.iter().map(|i| (i.mesh.clone(), i.copies())),
        instances
            .iter()
            .filter_map(|i| i.gpu.as_ref())
            .flat_map(|g| g.accessors().cloned()),
        limits,
    )?;
    let (data, skins) = load(&document, bytes.len(), bin, base_dir, limits)?;
    let mut builder = Builder::new(&skins, &instances, &plan);
    let mut gpu_instances = 0;
    for instance in &instances {
        if let Some(gpu) = &instance.gpu {
            gpu_instances += gpu.count;
        }
        for placed in instance.placements(&data)? {
            for primitive in placed.mesh.primitives() {
                builder.add_primitive(&data, &primitive, &placed)?;
            }
        }
    }
    let mut import = builder.finish(skins);
    import.gpu_instances = gpu_instances;
    import.report = import.mesh.validate()?;
    Ok(import)
}

/// Per node that places its unskinned mesh through `EXT_mesh_gpu_instancing`: the node's
/// index and each copy's transform in the node's space, decoded from `buffers` (the
/// document's, in order, as Bevy's glTF loader holds them).
///
/// # Errors
/// A malformed extension or accessor (named), or more copies in all than
/// [`LoadLimits::triangles`] (each copy draws at least one triangle).
#[cfg(feature = "gltf_instancing")]
pub(crate) fn gpu_instances(
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    limits: &LoadLimits,
) -> MeshResult<Vec<(usize, Vec<Mat4>)>> {
    let data = Data {
        buffers: buffers
            .iter()
            .map(|b| std::borrow::Cow::Borrowed(b.as_slice()))
            .collect(),
    };
    let mut out = Vec::new();
    let mut copies = 0u64;
    for node in document.nodes() {
        let (Some(mesh), None) = (node.mesh(), node.skin()) else {
            continue;
        };
        let Some(gpu) = scene::gpu_instancing(document, &node)? else {
            continue;
        };
        copies += gpu.count as u64;
        LoadLimits::check("triangles", copies, limits.triangles)?;
        let instance = scene::Instance {
            mesh,
            skin: None,
            transform: Mat4::IDENTITY,
            gpu: Some(gpu),
        };
        let placed = instance.placements(&data)?;
        out.push((node.index(), placed.iter().map(|p| p.transform).collect()));
    }
    Ok(out)
}

/// The document, its JSON within [`LoadLimits::json_bytes`], and the GLB `BIN` chunk if
/// there is one.
fn parse<'a>(
    bytes: &'a [u8],
    limits: &LoadLimits,
) -> MeshResult<(gltf::Document, Option<&'a [u8]>)> {
    let (json, bin) = if bytes.starts_with(b"glTF") {
        split_glb(bytes)?
    } else if bytes.is_empty() {
        return Err(gltf_error("empty file: no GLB header and no JSON"));
    } else {
        (bytes, None)
    };
    // Some exporters pad the JSON chunk with NULs instead of spaces; tolerate that.
    let end = json.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    let json = &json[..end];
    LoadLimits::check("json_bytes", structure_bytes(json), limits.json_bytes)?;
    Ok((parse_document(json)?, bin))
}

/// Strings at least this long (a `data:` URI's buffer or image, say) parse into one
/// allocation of about their size, so they count against [`LoadLimits::file_bytes`] only.
const LONG_STRING: usize = 1024;

/// The bytes of `json` outside its [long strings](LONG_STRING): what parses into many small
/// allocations, up to [`LoadLimits::JSON_FACTOR`] bytes a byte.
fn structure_bytes(json: &[u8]) -> u64 {
    let (mut long, mut start, mut escaped) = (0usize, None, false);
    for (i, &b) in json.iter().enumerate() {
        match (start, b) {
            (Some(_), _) if escaped => escaped = false,
            (Some(_), b'\\') => escaped = true,
            (Some(from), b'"') => {
                if i - from >= LONG_STRING {
                    long += i - from;
                }
                start = None;
            }
            (None, b'"') => start = Some(i + 1),
            _ => {}
        }
    }
    (json.len() - long) as u64
}

/// The document's buffers (the file of `file_bytes` and its external buffers within
/// [`LoadLimits::file_bytes`] together) and its skins, read first: a file may be nothing but
/// a broken skin. Call it once the [`Plan`] has passed, so that nothing is read for a file
/// over a limit.
fn load<'a>(
    document: &gltf::Document,
    file_bytes: usize,
    bin: Option<&'a [u8]>,
    base_dir: Option<&Path>,
    limits: &LoadLimits,
) -> MeshResult<(Data<'a>, Vec<GltfSkinInfo>)> {
    let buffers = load_buffers(document, file_bytes, bin, base_dir, limits)?;
    let data = Data { buffers };
    let skins = document
        .skins()
        .map(|skin| read_skin(&data, &skin))
        .collect::<MeshResult<Vec<_>>>()?;
    Ok((data, skins))
}

/// One triangle primitive of a glTF file, on its own, in its mesh's space: what Bevy's glTF
/// loader makes one `Mesh` asset of.
#[derive(Clone, Debug)]
pub struct GltfPrimitive {
    /// Bevy's label of the primitive's mesh asset: `Mesh{m}/Primitive{p}`, by document index.
    pub key: String,
    /// The primitive, validated; joints index [`skin`](Self::skin)'s joint list.
    pub mesh: crate::mesh::IndexedMesh,
    /// The skin of the first node that shows the mesh (document order), when one does.
    pub skin: Option<usize>,
}

/// Reads every triangle primitive of a `.gltf` or `.glb` file separately (see
/// [`load_gltf_slice`] for what is read and how), each in its own mesh space, with the
/// file's skins. Primitives without triangles (points, lines) are left out.
///
/// # Errors
/// As [`load_gltf`], naming the primitive for errors of its own.
pub fn load_gltf_primitives(path: &Path) -> MeshResult<(Vec<GltfPrimitive>, Vec<GltfSkinInfo>)> {
    load_gltf_primitives_with_limits(path, &LoadLimits::default())
}

/// [`load_gltf_primitives`] within `limits`.
///
/// # Errors
/// As [`load_gltf_primitives`], and [`MeshError::LimitExceeded`] naming the limit the file
/// exceeds.
pub fn load_gltf_primitives_with_limits(
    path: &Path,
    limits: &LoadLimits,
) -> MeshResult<(Vec<GltfPrimitive>, Vec<GltfSkinInfo>)> {
    let bytes = limits.read_file(path)?;
    let (document, bin) = parse(&bytes, limits)?;
    // Each mesh is read once, whatever the nodes that show it.
    Plan::check(
        &document,
        document.meshes().map(|mesh| (mesh, 1)),
        [],
        limits,
    )?;
    let (data, skins) = load(&document, bytes.len(), bin, path.parent(), limits)?;
    let instances = collect_instances(&document)?;
    let mut out = Vec::new();
    // The skin of the first node showing each mesh, and the joint maps per primary skin,
    // made once for all the primitives that share it.
    let mut first_skin: HashMap<usize, Option<usize>> = HashMap::new();
    for instance in &instances {
        first_skin
            .entry(instance.mesh.index())
            .or_insert(instance.skin);
    }
    let mut maps: HashMap<Option<usize>, Rc<flatten::JointMaps>> = HashMap::new();
    for mesh in document.meshes() {
        let skin = first_skin.get(&mesh.index()).copied().flatten();
        let instance = scene::Instance {
            mesh: mesh.clone(),
            skin,
            transform: Mat4::IDENTITY,
            gpu: None,
        };
        for primitive in mesh.primitives() {
            let key = format!("Mesh{}/Primitive{}", mesh.index(), primitive.index());
            let joint_maps = maps
                .entry(skin)
                .or_insert_with(|| Rc::new(flatten::joint_maps(&skins, skin)))
                .clone();
            let mut builder = Builder::with_joint_maps(&skins, joint_maps);
            builder.add_primitive(&data, &primitive, &instance)?;
            let mut import = builder.finish(Vec::new());
            if import.mesh.indices.is_empty() {
                continue;
            }
            import
                .mesh
                .validate()
                .map_err(|e| gltf_error(format!("{key}: {e}")))?;
            out.push(GltfPrimitive {
                key,
                mesh: import.mesh,
                skin,
            });
        }
    }
    Ok((out, skins))
}
