//! Importer tests against the shared test data: real meshes, a skinned character, and the
//! glTF-Validator's malformed files. Also PLY and OBJ round trips with files written here.

mod common;

use bevy_aslod::mesh::{
    IndexedMesh, LoadLimits, MeshError, load_gltf, load_gltf_slice, load_gltf_slice_with_limits,
    load_obj, load_ply, parse_obj, parse_ply, write_obj, write_obj_groups,
};
use common::glb;
use glam::{Vec2, Vec3};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

const MESHES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/testdata/meshes");
const ROBOT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/testdata/characters/RobotExpressive.glb"
);
const MALFORMED: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/testdata/gltf-malformed"
);

fn mesh_path(name: &str) -> PathBuf {
    Path::new(MESHES).join(name)
}

/// Runs `f`, failing the test (with the input's name) if it panics.
fn no_panic<T>(what: &str, f: impl FnOnce() -> T) -> T {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(value) => value,
        Err(_) => panic!("importer panicked on {what}"),
    }
}

/// A fresh scratch directory for files a test writes.
fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("bevy_aslod_import_{}_{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

// ---------------------------------------------------------------------------------------------
// OBJ

#[test]
fn obj_meshes_have_readme_counts() {
    // (file, triangles, vertices; None where vt makes one vertex per (v, vt) pair).
    let expected = [
        ("stanford-bunny.obj", 69_451, Some(35_947)),
        ("cow.obj", 5_804, Some(2_903)),
        ("fandisk.obj", 12_946, Some(6_475)),
        ("spot.obj", 5_856, None),
    ];
    for (name, triangles, vertices) in expected {
        let mesh = load_obj(&mesh_path(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(mesh.triangle_count(), triangles, "{name} triangles");
        match vertices {
            Some(v) => {
                assert_eq!(mesh.vertex_count(), v, "{name} vertices");
                assert!(mesh.uvs.is_none() && mesh.normals.is_none(), "{name}");
            }
            None => {
                // Spot has 2,930 positions and 3,225 texture coordinates; seams split vertices.
                assert!(
                    mesh.vertex_count() >= 3_225,
                    "{name}: {}",
                    mesh.vertex_count()
                );
                assert_eq!(mesh.uvs.as_ref().map(Vec::len), Some(mesh.vertex_count()));
            }
        }
        let (validated, report) =
            IndexedMesh::load(mesh_path(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(
            validated.triangle_count() + report.degenerate_triangles_dropped,
            triangles,
            "{name}"
        );
    }
}

#[test]
fn obj_without_attributes_keeps_v_order() {
    let path = mesh_path("stanford-bunny.obj");
    let mesh = load_obj(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let v_lines: Vec<Vec3> = text
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Vec3::new(c[0], c[1], c[2])
        })
        .collect();
    assert_eq!(mesh.positions, v_lines);
}

#[test]
fn obj_round_trips_through_write_obj() {
    for name in ["spot.obj", "cow.obj"] {
        let mesh = load_obj(&mesh_path(name)).unwrap();
        let mut out = Vec::new();
        write_obj(&mesh, &mut out).unwrap();
        let back = parse_obj(std::str::from_utf8(&out).unwrap()).unwrap();
        assert_eq!(back, mesh, "{name}");
    }

    // Every attribute combination writes the matching face syntax and reads back exactly.
    let mut mesh = IndexedMesh::new(
        vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.1, -2.5e-7, 3.0e9)],
        vec![0, 1, 2, 2, 1, 3],
    );
    for (uvs, normals) in [(false, false), (true, false), (false, true), (true, true)] {
        mesh.uvs = uvs.then(|| vec![Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::splat(0.3)]);
        mesh.normals = normals.then(|| vec![Vec3::Z, Vec3::Z, Vec3::Y, Vec3::X]);
        let mut out = Vec::new();
        write_obj(&mesh, &mut out).unwrap();
        assert_eq!(parse_obj(std::str::from_utf8(&out).unwrap()).unwrap(), mesh);
    }
}

#[test]
fn obj_groups_are_written() {
    let mesh = IndexedMesh::new(
        vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE],
        vec![0, 1, 2, 2, 1, 3],
    );
    let groups = [("first part".to_owned(), 0..1), ("second".to_owned(), 1..2)];
    let mut out = Vec::new();
    write_obj_groups(&mesh, &groups, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(
        text.contains("g first_part\nf 1 2 3\ng second\nf 3 2 4\n"),
        "{text}"
    );
    assert_eq!(parse_obj(&text).unwrap(), mesh);

    let bad = [("past the end".to_owned(), 1..3)];
    let err = write_obj_groups(&mesh, &bad, &mut Vec::new()).unwrap_err();
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput);
}

#[test]
fn obj_face_syntax() {
    let text = "\
# a quad with UVs and normals, then a triangle by relative indices
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0 1.0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
f 1/1/1 2/2/1 3/3/1 4/4/1
f -4/-4/-1 -2/-2/-1 -1/-1/-1
";
    let mesh = parse_obj(text).unwrap();
    assert_eq!(mesh.triangle_count(), 3);
    // The relative triangle repeats existing corners, so it adds no vertex.
    assert_eq!(mesh.vertex_count(), 4);
    assert_eq!(mesh.indices, vec![0, 1, 2, 0, 2, 3, 0, 2, 3]);
    assert_eq!(mesh.normals.as_deref(), Some(&[Vec3::Z; 4][..]));

    // One position with two texture coordinates becomes two vertices (a seam).
    let seam =
        parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 1\nf 1/1 2/1 3/1\nf 1/2 3/1 2/1\n")
            .unwrap();
    assert_eq!(seam.vertex_count(), 4);
    assert_eq!(seam.positions[3], Vec3::ZERO);
    assert_eq!(seam.uvs.as_ref().unwrap()[3], Vec2::ONE);

    let v_n = parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n").unwrap();
    assert!(v_n.uvs.is_none());
    assert_eq!(v_n.normals.as_ref().map(Vec::len), Some(3));
}

#[test]
fn obj_errors_name_the_line() {
    let cases = [
        ("v 0 0 0\nv 1 0\n", "line 2"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 0\n", "line 5"),
        ("v 0 0 0\nf 1 -2 1\n", "line 2"),
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", "line 3"),
        ("v 0 0 nan\n", "line 1"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n", "line 4"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 3/1\n", "line 4"),
    ];
    for (text, line) in cases {
        let err = parse_obj(text).expect_err(text);
        assert!(
            matches!(err, MeshError::Parse { format: "OBJ", .. }),
            "{err}"
        );
        assert!(err.to_string().contains(line), "{text:?}: {err}");
    }
}

// ---------------------------------------------------------------------------------------------
// PLY

/// A mesh with every attribute PLY carries, two triangles and a quad.
fn ply_sample() -> (IndexedMesh, Vec<Vec<u32>>) {
    let positions = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.5),
        Vec3::new(1.0, 1.0, -0.25),
        Vec3::new(0.0, 1.0, 2.0),
        Vec3::new(-1.0, 0.5, 1.5e-3),
    ];
    let normals = positions
        .iter()
        .map(|p| (*p + Vec3::Z).normalize())
        .collect();
    let uvs = positions.iter().map(|p| p.truncate() * 0.5).collect();
    let faces = vec![vec![0, 1, 2, 3], vec![0, 3, 4]];
    let mesh = IndexedMesh {
        positions,
        normals: Some(normals),
        uvs: Some(uvs),
        indices: vec![0, 1, 2, 0, 2, 3, 0, 3, 4],
        ..IndexedMesh::default()
    };
    (mesh, faces)
}

/// Writes `mesh` as binary PLY, with an unknown vertex property and an unknown element
/// holding list properties that the reader must skip.
fn write_binary_ply(mesh: &IndexedMesh, faces: &[Vec<u32>], big_endian: bool) -> Vec<u8> {
    let format = if big_endian {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment written by tests/import.rs\n\
         element vertex {}\nproperty double x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty float nx\nproperty float ny\nproperty float nz\n\
         property float s\nproperty float t\n\
         element material 2\nproperty list uint short flags\nproperty int id\n\
         element face {}\nproperty uchar quality\nproperty list uchar uint vertex_indices\n\
         end_header\n",
        mesh.vertex_count(),
        faces.len()
    )
    .into_bytes();
    macro_rules! put {
        ($v:expr) => {
            if big_endian {
                out.extend_from_slice(&$v.to_be_bytes())
            } else {
                out.extend_from_slice(&$v.to_le_bytes())
            }
        };
    }
    let normals = mesh.normals.as_ref().unwrap();
    let uvs = mesh.uvs.as_ref().unwrap();
    for i in 0..mesh.vertex_count() {
        let p = mesh.positions[i];
        put!(f64::from(p.x));
        put!(p.y);
        put!(p.z);
        put!(200u8);
        for c in normals[i].to_array() {
            put!(c);
        }
        put!(uvs[i].x);
        put!(uvs[i].y);
    }
    for m in 0..2i32 {
        put!(3u32);
        for flag in [1i16, -2, 3] {
            put!(flag);
        }
        put!(m);
    }
    for face in faces {
        put!(7u8);
        put!(face.len() as u8);
        for &i in face {
            put!(i);
        }
    }
    out
}

#[test]
fn ply_binary_round_trips_both_endians() {
    let (mesh, faces) = ply_sample();
    for big_endian in [false, true] {
        let bytes = write_binary_ply(&mesh, &faces, big_endian);
        let back = parse_ply(&bytes).unwrap();
        assert_eq!(back, mesh, "big endian: {big_endian}");
    }
    let dir = scratch_dir("ply");
    let path = dir.join("sample.ply");
    std::fs::write(&path, write_binary_ply(&mesh, &faces, false)).unwrap();
    assert_eq!(load_ply(&path).unwrap(), mesh);
    let (validated, _) = IndexedMesh::load(&path).unwrap();
    assert_eq!(validated.triangle_count(), 3);
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn ply_ascii_with_mixed_types() {
    let text = "ply\r\nformat ascii 1.0\r\ncomment CRLF header, odd types\r\n\
        element vertex 4\r\nproperty int8 x\r\nproperty short y\r\nproperty double z\r\n\
        property float texture_u\r\nproperty float texture_v\r\nproperty list uchar int junk\r\n\
        element face 2\r\nproperty list uint8 int32 vertex_index\r\nend_header\r\n\
        0 0 0.5 0 0 2 7 8\r\n1 0 0.5 1 0 0\r\n1 1 0.5 1 1 1 9\r\n-1 1 0.5 0 1 0\r\n\
        3 0 1 2\r\n3 0 2 3\r\n";
    let mesh = parse_ply(text.as_bytes()).unwrap();
    assert_eq!(mesh.positions[3], Vec3::new(-1.0, 1.0, 0.5));
    assert_eq!(mesh.uvs.as_ref().unwrap()[2], Vec2::ONE);
    assert!(mesh.normals.is_none());
    assert_eq!(mesh.indices, vec![0, 1, 2, 0, 2, 3]);
}

#[test]
fn ply_tristrips_with_restart_markers() {
    let header = "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n\
        property float z\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n";
    let vertices = "0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 0 0\n2 1 0\n3 0 0\n3 1 0\n";
    // Strip 0 1 2 3, restart, strip 4 5 6 6 7 5 (the repeated 6 turns a corner).
    let strips = "11 0 1 2 3 -1 4 5 6 6 7 5\n";
    let mesh = parse_ply(format!("{header}{vertices}{strips}").as_bytes()).unwrap();
    // Odd triangles of a strip swap their first two corners; those repeating a vertex are
    // skipped but still count for the alternation.
    assert_eq!(mesh.indices, vec![0, 1, 2, 2, 1, 3, 4, 5, 6, 7, 6, 5]);
}

#[test]
fn ply_errors_name_the_place() {
    let (mesh, faces) = ply_sample();
    let bytes = write_binary_ply(&mesh, &faces, false);
    let err = parse_ply(&bytes[..bytes.len() - 2]).unwrap_err();
    let message = err.to_string();
    assert!(
        message.contains("byte") && message.contains("`face` 1"),
        "{message}"
    );

    let bad_index = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
        property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n";
    let message = parse_ply(bad_index.as_bytes()).unwrap_err().to_string();
    assert!(
        message.contains("`face` 0") && message.contains("9"),
        "{message}"
    );

    let bad_number = bad_index.replace("1 0 0\n", "1 zero 0\n");
    let message = parse_ply(bad_number.as_bytes()).unwrap_err().to_string();
    assert!(
        message.contains("line 11") && message.contains("zero"),
        "{message}"
    );

    let bad_header = bad_index.replace("property float y", "property quad y");
    let message = parse_ply(bad_header.as_bytes()).unwrap_err().to_string();
    assert!(message.contains("header line 5"), "{message}");
}

#[test]
fn ply_truncated_or_garbled_input_never_panics() {
    let (mesh, faces) = ply_sample();
    let mut inputs = vec![
        write_binary_ply(&mesh, &faces, false),
        write_binary_ply(&mesh, &faces, true),
    ];
    let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
        property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    inputs.push(ascii.as_bytes().to_vec());
    for input in &inputs {
        for len in 0..=input.len() {
            let prefix = &input[..len];
            let result = no_panic(&format!("a {len}-byte prefix"), || parse_ply(prefix));
            // Dropping only the final newline of the ASCII file leaves it valid.
            if len + 1 < input.len() && len + 4 > input.len() {
                assert!(result.is_err(), "a {len}-byte prefix parsed");
            }
        }
        // Deterministic byte corruption (xorshift), a few bytes at a time.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..2_000 {
            let mut garbled = input.clone();
            for _ in 0..3 {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let at = (state as usize) % garbled.len();
                garbled[at] = (state >> 32) as u8;
            }
            no_panic("garbled PLY", || {
                parse_ply(&garbled).map(|mut m| m.validate())
            })
            .ok();
        }
    }
}

// ---------------------------------------------------------------------------------------------
// glTF: the character

#[test]
fn robot_expressive_loads_with_skins() {
    let import = load_gltf(Path::new(ROBOT)).unwrap();
    let mesh = &import.mesh;
    assert_eq!(import.primitives, 19);
    assert_eq!(import.morph_target_primitives, 3);
    assert_eq!(
        mesh.triangle_count() + import.report.degenerate_triangles_dropped,
        3_237
    );
    assert_eq!(mesh.vertex_count(), 7_214);
    assert_eq!(mesh.normals.as_ref().map(Vec::len), Some(7_214));
    // The file has no TEXCOORD_0 at all (flat-coloured materials).
    assert!(mesh.uvs.is_none());
    let joints = mesh.joints.as_ref().expect("joints");
    let weights = mesh.weights.as_ref().expect("weights");
    assert_eq!((joints.len(), weights.len()), (7_214, 7_214));

    // Four of the primitives are skinned: their weights sum to one, the rest are zero.
    let skinned = weights
        .iter()
        .filter(|w| (w.iter().sum::<f32>() - 1.0).abs() < 1e-3)
        .count();
    let unskinned = weights
        .iter()
        .filter(|w| w.iter().all(|&x| x == 0.0))
        .count();
    assert_eq!(skinned + unskinned, 7_214);
    assert_eq!(skinned, 256 + 298 + 256 + 298);
    assert!(joints.iter().flatten().all(|&j| j < 43));

    assert!(
        mesh.normals
            .iter()
            .flatten()
            .all(|n| (n.length() - 1.0).abs() < 1e-3)
    );
    let (lo, hi) = mesh.bounds().unwrap();
    assert!(
        hi.y - lo.y > 1.0 && lo.is_finite() && hi.is_finite(),
        "{lo} {hi}"
    );

    assert_eq!(import.skins.len(), 4);
    for skin in &import.skins {
        assert_eq!(skin.joints.len(), 43);
        assert_eq!(skin.inverse_bind_matrices.len(), 43);
        assert_eq!(skin.joints, import.skins[0].joints);
        assert!(skin.inverse_bind_matrices.iter().all(|m| m.is_finite()));
    }

    // The generic loader takes the same path.
    let (same, _) = IndexedMesh::load(ROBOT).unwrap();
    assert_eq!(&same, mesh);
}

#[test]
fn truncated_or_garbled_glb_never_panics() {
    let bytes = std::fs::read(ROBOT).unwrap();
    let mut cuts: Vec<usize> = (0..64).collect();
    cuts.extend((1..200).map(|k| k * bytes.len() / 200));
    for len in cuts {
        let result = no_panic(&format!("a {len}-byte prefix"), || {
            load_gltf_slice(&bytes[..len], None)
        });
        assert!(result.is_err(), "a {len}-byte prefix loaded");
    }
    // Corrupt header and chunk-header fields.
    for at in 0..20 {
        for value in [0u8, 1, 3, 0x7f, 0xff] {
            let mut garbled = bytes.clone();
            garbled[at] = value;
            no_panic(&format!("byte {at} = {value}"), || {
                load_gltf_slice(&garbled, None)
            })
            .ok();
        }
    }
}

// ---------------------------------------------------------------------------------------------
// glTF: the validator's malformed files

/// What our message must contain for each validator error code.
fn expected_substring(code: &str) -> Option<&'static str> {
    Some(match code {
        "GLB_UNEXPECTED_END_OF_HEADER" => "empty file",
        "GLB_LENGTH_MISMATCH" => "GLB length mismatch",
        "GLB_UNEXPECTED_END_OF_CHUNK_DATA" => "truncated chunk",
        "GLB_CHUNK_LENGTH_UNALIGNED" => "unaligned chunk",
        "INVALID_JSON" => "BOM",
        "UNRESOLVED_REFERENCE" => "unresolved reference",
        "EMPTY_ENTITY" => "empty",
        "SKIN_NO_COMMON_ROOT" => "skins[",
        "MESH_PRIMITIVE_UNEQUAL_ACCESSOR_COUNT" => "unequal attribute counts",
        "ACCESSOR_INDEX_OOB" => "index out of range",
        _ => return None,
    })
}

/// `/accessors/0/sparse/indices/bufferView` -> `accessors[0].sparse.indices.bufferView`, the
/// form our messages use.
fn pointer_to_path(pointer: &str) -> String {
    let mut path = String::new();
    for segment in pointer.split('/').skip(1) {
        if segment.parse::<usize>().is_ok() {
            path.push_str(&format!("[{segment}]"));
        } else {
            if !path.is_empty() {
                path.push('.');
            }
            path.push_str(segment);
        }
    }
    path
}

/// The buffers the test data lacks (the validator's `.bin` files were not copied), rebuilt
/// from what the reports say about them.
fn reconstructed_sidecar(uri: &str) -> Option<Vec<u8>> {
    match uri {
        // "element at index 5 has value 5 ... maximum vertex index available (3)".
        "index_buffer_oob.bin" => Some(vec![0, 1, 2, 3, 2, 5]),
        // "3 degenerate triangles (out of 3)".
        "index_buffer_degenerate_triangle.bin" => Some(vec![0, 0, 1, 1, 2, 2, 2, 0, 2]),
        _ => None,
    }
}

/// Every `.report.json` under the malformed directory, with its glTF file.
fn malformed_files() -> Vec<(PathBuf, serde_json::Value)> {
    fn walk(dir: &Path, out: &mut Vec<(PathBuf, serde_json::Value)>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().flatten().collect();
        entries.sort_by_key(|e| e.path());
        for entry in entries {
            let path = entry.path();
            if path.is_dir() {
                walk(&path, out);
            } else if let Some(name) = path.to_str().and_then(|p| p.strip_suffix(".report.json")) {
                let report = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
                out.push((PathBuf::from(name), report));
            }
        }
    }
    let mut out = Vec::new();
    walk(Path::new(MALFORMED), &mut out);
    out
}

/// External buffers of a `.gltf` that are missing next to it.
fn missing_sidecars(path: &Path) -> Vec<String> {
    if path.extension().is_none_or(|e| e != "gltf") {
        return Vec::new();
    }
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    json["buffers"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|b| b["uri"].as_str())
        .filter(|uri| !uri.starts_with("data:"))
        .filter(|uri| !path.with_file_name(uri).exists())
        .map(str::to_owned)
        .collect()
}

/// Loads `path`; when its external buffers are missing from the test data, checks that the
/// error names them, then loads a copy next to rebuilt buffers instead.
fn load_malformed(path: &Path) -> Result<bevy_aslod::mesh::GltfImport, MeshError> {
    let name = path.display().to_string();
    let result = no_panic(&name, || load_gltf(path));
    let missing = missing_sidecars(path);
    if missing.is_empty() {
        return result;
    }
    let message = result.expect_err(&name).to_string();
    assert!(
        message.contains("buffers[0].uri") && message.contains(&missing[0]),
        "{name}: {message}"
    );
    let dir = scratch_dir(path.file_stem().unwrap().to_str().unwrap());
    let copy = dir.join(path.file_name().unwrap());
    std::fs::copy(path, &copy).unwrap();
    for uri in &missing {
        let data = reconstructed_sidecar(uri).unwrap_or_else(|| panic!("no rebuild of {uri}"));
        std::fs::write(dir.join(uri), data).unwrap();
    }
    let result = no_panic(&name, || load_gltf(&copy));
    std::fs::remove_dir_all(dir).ok();
    result
}

#[test]
fn malformed_gltf_errors_name_the_defect() {
    let files = malformed_files();
    assert!(files.len() >= 11, "found {} reports", files.len());
    let mut checked = 0;
    for (path, report) in files {
        if report["issues"]["numErrors"].as_u64().unwrap() == 0 {
            continue;
        }
        let name = path.display().to_string();
        let message = match load_malformed(&path) {
            Ok(_) => panic!("{name} loaded"),
            Err(e) => e.to_string(),
        };
        let errors = report["issues"]["messages"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|m| m["severity"] == 0);
        for error in errors {
            let code = error["code"].as_str().unwrap();
            let expected = expected_substring(code)
                .unwrap_or_else(|| panic!("{name}: no expectation for {code}"));
            assert!(message.contains(expected), "{name}: {code}: {message}");
            if let Some(pointer) = error["pointer"].as_str().filter(|p| !p.is_empty()) {
                let path = pointer_to_path(pointer);
                if code != "ACCESSOR_INDEX_OOB" && code != "MESH_PRIMITIVE_UNEQUAL_ACCESSOR_COUNT" {
                    assert!(message.contains(&path), "{name}: {path}: {message}");
                }
            }
        }
        checked += 1;
    }
    assert_eq!(checked, 10);
}

#[test]
fn malformed_errors_have_the_right_variants() {
    let load = |rel: &str| load_malformed(&Path::new(MALFORMED).join(rel)).unwrap_err();
    assert!(matches!(
        load("mesh_data/index_buffer_oob.gltf"),
        MeshError::IndexOutOfRange {
            triangle: 1,
            index: 5,
            vertex_count: 4
        }
    ));
    assert!(matches!(
        load("mesh/accessor_unequal_count.gltf"),
        MeshError::AttributeCountMismatch {
            attribute: "COLOR_0",
            expected: 3,
            found: 4
        }
    ));
    let message = load("accessor/unresolved_bufferviews.gltf").to_string();
    assert!(
        message.contains("accessors[0].bufferView: unresolved reference 0"),
        "{message}"
    );
    assert!(message.contains("accessors[0].sparse.values.bufferView: unresolved reference 1"));
}

#[test]
fn degenerate_triangle_file_matches_reality() {
    // The validator reports only infos for this file: three triangles, each repeating a vertex,
    // over positions that have no buffer view and so are all zero. Every triangle is
    // degenerate, so nothing is left to load.
    let path = Path::new(MALFORMED).join("mesh_data/index_buffer_degenerate_triangle.gltf");
    let err = load_malformed(&path).unwrap_err();
    assert!(
        matches!(err, MeshError::AllTrianglesDegenerate { count: 3 }),
        "{err}"
    );
}

// ---------------------------------------------------------------------------------------------
// glTF: small files built here

/// A unit square in the XY plane (normals +Z) as a GLB, drawn by `indices` in `mode`, with
/// `nodes` as the node array of the default scene.
fn square_glb(indices: &[u16], mode: u32, nodes: &str) -> Vec<u8> {
    let positions = [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    for _ in 0..4 {
        bin.extend([0.0f32, 0.0, 1.0].iter().flat_map(|c| c.to_le_bytes()));
    }
    let index_offset = bin.len();
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let node_count = nodes.matches("\"mesh\"").count();
    let roots: Vec<String> = (0..node_count).map(|i| i.to_string()).collect();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{roots}]}}],
        "nodes":[{nodes}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":2,"mode":{mode}}}]}}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
          {{"bufferView":0,"byteOffset":48,"componentType":5126,"count":4,"type":"VEC3"}},
          {{"bufferView":1,"componentType":5123,"count":{count},"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteLength":96}},
          {{"buffer":0,"byteOffset":{index_offset},"byteLength":{index_len}}}],
        "buffers":[{{"byteLength":{bin_len}}}]}}"#,
        roots = roots.join(","),
        count = indices.len(),
        index_len = indices.len() * 2,
        bin_len = bin.len(),
    );
    glb(&json, &bin)
}

/// The unit normal of each triangle, from its winding.
fn face_normals(mesh: &IndexedMesh) -> Vec<Vec3> {
    (0..mesh.triangle_count())
        .map(|t| {
            let [a, b, c] = mesh.triangle(t).map(|i| mesh.positions[i as usize]);
            (b - a).cross(c - a).normalize()
        })
        .collect()
}

#[test]
fn degenerate_triangle_is_dropped_and_reported() {
    let bytes = square_glb(&[0, 1, 2, 1, 1, 3, 2, 1, 3], 4, r#"{"mesh":0}"#);
    let import = load_gltf_slice(&bytes, None).unwrap();
    assert_eq!(import.report.degenerate_triangles_dropped, 1);
    assert_eq!(import.mesh.triangle_count(), 2);
}

#[test]
fn node_transforms_and_mirroring() {
    let nodes = r#"{"mesh":0,"translation":[10,0,0]},
        {"mesh":0,"scale":[-1,1,1]},
        {"mesh":0,"rotation":[0.7071068,0,0,0.7071068]}"#;
    let bytes = square_glb(&[0, 1, 2, 2, 1, 3], 4, nodes);
    let import = load_gltf_slice(&bytes, None).unwrap();
    let mesh = &import.mesh;
    assert_eq!(import.primitives, 3);
    assert_eq!((mesh.vertex_count(), mesh.triangle_count()), (12, 6));
    assert_eq!(mesh.positions[1], Vec3::new(11.0, 0.0, 0.0));
    assert_eq!(mesh.positions[5], Vec3::new(-1.0, 0.0, 0.0));
    let normals = mesh.normals.as_ref().unwrap();
    let faces = face_normals(mesh);
    // Mirroring keeps the normal (+Z) and flips the winding so the front still faces it.
    for (t, face) in faces[..4].iter().enumerate() {
        assert!(face.abs_diff_eq(Vec3::Z, 1e-6), "{t}: {face}");
    }
    assert!(normals[..8].iter().all(|n| n.abs_diff_eq(Vec3::Z, 1e-6)));
    // A quarter turn about X takes +Z to -Y.
    assert!(faces[4..].iter().all(|f| f.abs_diff_eq(Vec3::NEG_Y, 1e-5)));
    assert!(
        normals[8..]
            .iter()
            .all(|n| n.abs_diff_eq(Vec3::NEG_Y, 1e-5))
    );
}

#[test]
fn strips_and_fans() {
    let strip = load_gltf_slice(&square_glb(&[0, 1, 2, 3], 5, r#"{"mesh":0}"#), None).unwrap();
    // Odd strip triangles are (i, i + 2, i + 1), as the specification writes them.
    assert_eq!(strip.mesh.indices, vec![0, 1, 2, 1, 3, 2]);
    let fan = load_gltf_slice(&square_glb(&[0, 1, 3, 2], 6, r#"{"mesh":0}"#), None).unwrap();
    assert_eq!(fan.mesh.indices, vec![1, 3, 0, 3, 2, 0]);
    for mesh in [&strip.mesh, &fan.mesh] {
        assert!(
            face_normals(mesh)
                .iter()
                .all(|f| f.abs_diff_eq(Vec3::Z, 1e-6))
        );
    }
    // Points and lines are skipped, which leaves nothing here.
    let lines = load_gltf_slice(&square_glb(&[0, 1, 2, 3], 1, r#"{"mesh":0}"#), None);
    assert!(matches!(lines, Err(MeshError::Empty)));
}

#[test]
fn small_glb_prefixes_never_panic() {
    let bytes = square_glb(&[0, 1, 2, 2, 1, 3], 4, r#"{"mesh":0}"#);
    for len in 0..bytes.len() {
        let result = no_panic(&format!("a {len}-byte prefix"), || {
            load_gltf_slice(&bytes[..len], None)
        });
        assert!(result.is_err());
    }
    // Out-of-range index in an otherwise valid file.
    let bad = square_glb(&[0, 1, 2, 2, 1, 4], 4, r#"{"mesh":0}"#);
    assert!(matches!(
        load_gltf_slice(&bad, None),
        Err(MeshError::IndexOutOfRange {
            triangle: 1,
            index: 4,
            vertex_count: 4
        })
    ));
}

#[test]
fn attributes_only_some_primitives_have() {
    // Mesh 0 has normals but no UVs; mesh 1 has UVs (read with a byte stride from the
    // positions) but no normals.
    let positions = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut bin: Vec<u8> = positions.iter().flat_map(|c| c.to_le_bytes()).collect();
    for _ in 0..3 {
        bin.extend([0.0f32, 0.0, 1.0].iter().flat_map(|c| c.to_le_bytes()));
    }
    let json = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0,1]}],
        "nodes":[{"mesh":0},{"mesh":1,"translation":[0,0,1]}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1}}]},
                  {"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_0":2}}]}],
        "accessors":[
          {"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},
          {"bufferView":0,"byteOffset":36,"componentType":5126,"count":3,"type":"VEC3"},
          {"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"}],
        "bufferViews":[{"buffer":0,"byteLength":72},{"buffer":0,"byteLength":36,"byteStride":12}],
        "buffers":[{"byteLength":72}]}"#;
    let import = load_gltf_slice(&glb(json, &bin), None).unwrap();
    let mesh = &import.mesh;
    assert_eq!((mesh.vertex_count(), mesh.triangle_count()), (6, 2));
    assert!(mesh.normals.is_none());
    let uvs = mesh.uvs.as_ref().unwrap();
    assert_eq!(uvs[..3], [Vec2::ZERO; 3]);
    assert_eq!(uvs[3..], [Vec2::ZERO, Vec2::X, Vec2::Y]);
    assert_eq!(mesh.positions[5], Vec3::new(0.0, 1.0, 1.0));
    assert!(mesh.joints.is_none() && mesh.weights.is_none());
}

/// Replaces the `k`-th run of digits in `text` by `value`, for each `(k, value)`.
fn replace_numbers(text: &str, edits: &[(usize, u32)]) -> String {
    let mut out = String::with_capacity(text.len());
    let mut run = 0;
    let mut chars = text.char_indices().peekable();
    while let Some((_, c)) = chars.next() {
        if !c.is_ascii_digit() {
            out.push(c);
            continue;
        }
        let mut digits = c.to_string();
        while let Some(&(_, d)) = chars.peek().filter(|(_, d)| d.is_ascii_digit()) {
            digits.push(d);
            chars.next();
        }
        match edits.iter().find(|(k, _)| *k == run) {
            Some((_, value)) => out.push_str(&value.to_string()),
            None => out.push_str(&digits),
        }
        run += 1;
    }
    out
}

/// An OBJ with every statement the reader knows: positions, UVs, normals, a concave face,
/// relative indices, comments and a group.
const OBJ_SEED: &str = "# seed\nv 0 0 0\nv 3 0 0\nv 3 2 0\nv 2 2 0\nv 2 1 0\nv 1 1 0\n\
    v 1 2 0\nv 0 2 0\nvt 0 0\nvt 1 1\nvn 0 0 1\ng part\nf 1/1/1 2/2/1 3/1/1 4/2/1 5/1/1 \
    6/2/1 7/1/1 8/2/1\nf -3//1 -2//1 -1//1\r\n";

proptest::proptest! {
    #[test]
    fn mutated_obj_never_panics(
        edits in proptest::collection::vec((0usize..200, proptest::num::u8::ANY), 1..6),
    ) {
        let mut bytes = OBJ_SEED.as_bytes().to_vec();
        for (at, value) in edits {
            let at = at % bytes.len();
            // Mostly characters the grammar uses, so that statements stay half-valid.
            let grammar = b"0123456789-/ .\nfve";
            bytes[at] = match value % 4 {
                0 => grammar[usize::from(value) % grammar.len()],
                _ => value,
            };
        }
        let _ = parse_obj(&String::from_utf8_lossy(&bytes)).map(|mut m| m.validate());
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..512)) {
        let _ = parse_ply(&bytes);
        let _ = parse_obj(&String::from_utf8_lossy(&bytes));
        let _ = load_gltf_slice(&bytes, None);
        let mut glb_like = b"glTF\x02\0\0\0".to_vec();
        glb_like.extend_from_slice(&bytes);
        let _ = load_gltf_slice(&glb_like, None);
    }

    #[test]
    fn ply_header_with_arbitrary_body_never_panics(
        body in proptest::collection::vec(proptest::num::u8::ANY, 0..256),
        big_endian in proptest::bool::ANY,
    ) {
        let (mesh, faces) = ply_sample();
        let valid = write_binary_ply(&mesh, &faces, big_endian);
        let header_end = valid.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        let mut bytes = valid[..header_end].to_vec();
        bytes.extend_from_slice(&body);
        let _ = parse_ply(&bytes).map(|mut m| m.validate());
    }

    #[test]
    fn gltf_with_wrong_numbers_never_panics(
        edits in proptest::collection::vec((0usize..60, proptest::num::u32::ANY), 1..4),
    ) {
        let bytes = square_glb(&[0, 1, 2, 2, 1, 3], 4, r#"{"mesh":0}"#);
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let json = std::str::from_utf8(&bytes[20..20 + json_len]).unwrap();
        let bin = &bytes[20 + json_len + 8..];
        // Small values hit in-range-but-wrong cases more often than arbitrary u32s.
        let edits: Vec<(usize, u32)> =
            edits.iter().map(|&(k, v)| (k, if v % 2 == 0 { v % 100 } else { v })).collect();
        let json = replace_numbers(json, &edits);
        let _ = load_gltf_slice(&glb(&json, bin), None);
    }
}

const WATER_BOTTLE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/testdata/textured/WaterBottle.glb"
);

/// The bottle's material has a normal map and its mesh no TANGENT: the importer makes
/// MikkTSpace tangents, as Bevy's glTF loader does. They are unit, perpendicular to the
/// normals, with a handedness of ±1, and point where U grows.
#[test]
fn a_normal_mapped_gltf_without_tangents_gets_them() {
    let mesh = load_gltf(Path::new(WATER_BOTTLE))
        .expect("WaterBottle imports")
        .mesh;
    let (normals, uvs) = (mesh.normals.as_ref().unwrap(), mesh.uvs.as_ref().unwrap());
    let tangents = mesh.tangents.as_ref().expect("tangents made");
    assert_eq!(tangents.len(), mesh.positions.len());
    let mut along_u = 0;
    let triangles: Vec<&[u32]> = mesh.indices.chunks_exact(3).collect();
    for t in &triangles {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
        let (e1, e2) = (
            mesh.positions[b] - mesh.positions[a],
            mesh.positions[c] - mesh.positions[a],
        );
        let (d1, d2) = (uvs[b] - uvs[a], uvs[c] - uvs[a]);
        let det = d1.x * d2.y - d2.x * d1.y;
        if det.abs() < 1e-8 {
            continue;
        }
        // The direction in which U grows on this triangle.
        let du = ((e1 * d2.y - e2 * d1.y) / det).normalize_or_zero();
        along_u += usize::from(tangents[a].truncate().dot(du) > 0.5);
    }
    // MikkTSpace gives a vertex whose triangles have degenerate UVs a neighbour's tangent,
    // not always in its own surface: nearly all are.
    let mut in_surface = 0;
    for (v, t) in tangents.iter().enumerate() {
        assert!(
            (t.truncate().length() - 1.0).abs() < 1e-3,
            "vertex {v}: {t}"
        );
        assert!(t.w == 1.0 || t.w == -1.0, "vertex {v}: handedness {}", t.w);
        in_surface += usize::from(t.truncate().dot(normals[v]).abs() < 1e-2);
    }
    assert!(
        in_surface * 100 > tangents.len() * 99,
        "{in_surface} of {} tangents lie in the surface",
        tangents.len()
    );
    eprintln!("{in_surface} of {} tangents in the surface", tangents.len());
    assert!(
        along_u * 10 > triangles.len() * 9,
        "{along_u} of {} triangles have tangents along U",
        triangles.len()
    );
}

/// RobotExpressive has no normal maps: it gets no tangents, and keeps UVs and normals.
#[test]
fn a_gltf_without_normal_maps_gets_no_tangents() {
    let mesh = load_gltf(Path::new(ROBOT))
        .expect("RobotExpressive imports")
        .mesh;
    assert!(mesh.tangents.is_none());
    assert!(mesh.normals.is_some());
}

/// Vertex colours go out on the `v` lines (`v x y z r g b`), and the file reads back.
#[test]
fn obj_writes_vertex_colours() {
    use bevy_aslod::mesh::{COLOR_ID, VertexAttribute};
    let mut mesh = IndexedMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        indices: vec![0, 1, 2],
        ..Default::default()
    };
    mesh.attributes.push(VertexAttribute::from_f32(
        "Vertex_Color",
        COLOR_ID,
        &[
            [1.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0, 0.5],
        ],
    ));
    let mut bytes = Vec::new();
    write_obj(&mesh, &mut bytes).unwrap();
    let text = String::from_utf8(bytes).unwrap();
    assert!(text.contains("v 1 0 0 0 1 0\n"), "{text}");
    let back = parse_obj(&text).unwrap();
    assert_eq!(back.positions, mesh.positions);
}

/// TEXCOORD_1 and COLOR_0 (RGB, read as RGBA with alpha 1) are carried; TEXCOORD_2, COLOR_1
/// and a custom attribute are not, and the import names them.
#[test]
fn attributes_the_importer_cannot_carry_are_named() {
    use bevy_aslod::mesh::{COLOR_ID, UV_1_ID};
    let positions = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut bin: Vec<u8> = positions.iter().flat_map(|c| c.to_le_bytes()).collect();
    // Three VEC2 sets and three VEC3 sets of 3 vertices.
    let vec2s = [0.25f32, 0.5, 0.75, 1.0, 0.0, 0.125];
    let vec3s = [1.0f32, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    bin.extend(vec2s.iter().flat_map(|c| c.to_le_bytes()));
    bin.extend(vec3s.iter().flat_map(|c| c.to_le_bytes()));
    let json = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
        "nodes":[{"mesh":0}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_1":1,"TEXCOORD_2":1,
            "COLOR_0":2,"COLOR_1":2,"_WIND":2}}]}],
        "accessors":[
          {"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},
          {"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"},
          {"bufferView":2,"componentType":5126,"count":3,"type":"VEC3"}],
        "bufferViews":[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":24},
          {"buffer":0,"byteOffset":60,"byteLength":36}],
        "buffers":[{"byteLength":96}]}"#;
    let import = load_gltf_slice(&glb(json, &bin), None).unwrap();
    assert_eq!(
        import.dropped_attributes,
        ["COLOR_1", "TEXCOORD_2", "_WIND"]
    );
    let mesh = &import.mesh;
    let uv1 = mesh
        .attribute(UV_1_ID)
        .expect("TEXCOORD_1")
        .to_f32::<2>()
        .unwrap();
    assert_eq!(uv1, [[0.25, 0.5], [0.75, 1.0], [0.0, 0.125]]);
    let colors = mesh
        .attribute(COLOR_ID)
        .expect("COLOR_0")
        .to_f32::<4>()
        .unwrap();
    assert_eq!(colors[1], [0.0, 1.0, 0.0, 1.0]);
    assert!(mesh.tangents.is_none(), "no normal map, no tangents");
}

// ---------------------------------------------------------------------------------------------
// Crafted input: each of these read wrong data, or panicked, before its fix.

#[test]
fn glb_declaring_a_length_shorter_than_its_chunks_is_refused() {
    let mut bytes = square_glb(&[0, 1, 2, 2, 1, 3], 4, r#"{"mesh":0}"#);
    for declared in [13u32, 16, 19, 20, 24] {
        bytes[8..12].copy_from_slice(&declared.to_le_bytes());
        let result = no_panic(&format!("declared length {declared}"), || {
            load_gltf_slice(&bytes, None)
        });
        let Err(e) = result else {
            panic!("declared length {declared} loaded");
        };
        assert!(e.to_string().contains("length"), "{e}");
    }
}

#[test]
fn obj_with_a_byte_order_mark_keeps_its_first_vertex() {
    let mesh = parse_obj("\u{feff}v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert_eq!(mesh.vertex_count(), 3);
    assert_eq!(mesh.positions[0], Vec3::ZERO);
}

#[test]
fn obj_line_endings_cr_crlf_and_lf_read_alike() {
    let lf = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 3 2 4\n";
    let expected = parse_obj(lf).unwrap();
    for (name, text) in [
        ("CR", lf.replace('\n', "\r")),
        ("CRLF", lf.replace('\n', "\r\n")),
    ] {
        let mesh = parse_obj(&text).unwrap();
        assert_eq!(mesh.positions, expected.positions, "{name}");
        assert_eq!(mesh.indices, expected.indices, "{name}");
    }
    // Errors name the same line whatever the endings.
    let bad = "v 0 0 0\r\nv 1 0 0\r\nv 0 1\r\n";
    let e = parse_obj(bad).unwrap_err().to_string();
    assert!(e.contains("line 3"), "{e}");
    let e = parse_obj(&bad.replace("\r\n", "\r"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 3"), "{e}");
}

/// Twice the signed area of triangle `t` of `mesh` in the XY plane.
fn signed_area_xy(mesh: &IndexedMesh, t: usize) -> f32 {
    let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[mesh.indices[3 * t + k] as usize]);
    (b - a).truncate().perp_dot((c - a).truncate())
}

#[test]
fn obj_concave_polygons_are_triangulated_inside_their_outline() {
    // A U (a notch from the top) and an arrow head, each starting at a corner that does not
    // see the whole outline: a fan from it makes triangles outside the outline, flipped.
    let shapes = [
        (
            "U",
            "v 3 2 0\nv 2 2 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\nv 3 0 0\n\
             f 1 2 3 4 5 6 7 8\n",
            5.0,
        ),
        (
            "arrow",
            "v 0 2 0\nv 1 0 0\nv 2 2 0\nv 1 1 0\nf 1 2 3 4\n",
            1.0,
        ),
    ];
    for (name, text, area) in shapes {
        let mesh = parse_obj(text).unwrap();
        let corners = mesh.vertex_count();
        assert_eq!(mesh.triangle_count(), corners - 2, "{name}");
        let areas: Vec<f32> = (0..mesh.triangle_count())
            .map(|t| signed_area_xy(&mesh, t))
            .collect();
        let sign = areas[0].signum();
        assert!(
            areas.iter().all(|a| a.signum() == sign && a.abs() > 1e-6),
            "{name}: {areas:?}"
        );
        let total: f32 = areas.iter().map(|a| a.abs() / 2.0).sum();
        assert!(
            (total - area).abs() < 1e-5,
            "{name}: area {total}, expected {area}"
        );
    }
    // A concave comb of 300 corners is past the bound: an error naming it.
    let mut comb = String::new();
    for i in 0..150 {
        comb += &format!("v {i} 0 0\n");
    }
    for i in (0..150).rev() {
        comb += &format!("v {i} {} 0\n", 1 + i % 2);
    }
    comb += "f";
    for k in 1..=300 {
        comb += &format!(" {k}");
    }
    let e = parse_obj(&comb).unwrap_err().to_string();
    assert!(e.contains("concave face of 300 corners"), "{e}");
    // Convex polygons keep the fan (and its triangle order).
    let quad = parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
    assert_eq!(quad.indices, vec![0, 1, 2, 0, 2, 3]);
}

/// An ASCII PLY of three vertices with `vertex` properties `props` and one face given by
/// `body` lines after the vertices.
fn ascii_ply(props: &str, index_type: &str, vertices: &str, faces: &str) -> Vec<u8> {
    format!(
        "ply\nformat ascii 1.0\nelement vertex 3\n{props}element face 1\n\
         property list uchar {index_type} vertex_indices\nend_header\n{vertices}{faces}"
    )
    .into_bytes()
}

const XYZ: &str = "property float x\nproperty float y\nproperty float z\n";

#[test]
fn ply_float_index_lists_must_hold_integers() {
    let vertices = "0 0 0\n1 0 0\n0 1 0\n";
    let good = parse_ply(&ascii_ply(XYZ, "float", vertices, "3 0 1 2\n")).unwrap();
    assert_eq!(good.indices, vec![0, 1, 2]);
    for face in ["3 nan 1 2\n", "3 0.5 1 2\n", "3 0 1 inf\n"] {
        let e = parse_ply(&ascii_ply(XYZ, "float", vertices, face)).unwrap_err();
        assert!(e.to_string().contains("index"), "{face:?}: {e}");
    }
    // Binary: a NaN float index.
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n".to_vec();
    bytes.extend_from_slice(XYZ.as_bytes());
    bytes.extend_from_slice(
        b"element face 1\nproperty list uchar float vertex_indices\nend_header\n",
    );
    for v in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        v.iter()
            .for_each(|c| bytes.extend_from_slice(&c.to_le_bytes()));
    }
    bytes.push(3);
    for i in [f32::NAN, 1.0, 2.0] {
        bytes.extend_from_slice(&i.to_le_bytes());
    }
    let e = parse_ply(&bytes).unwrap_err();
    assert!(e.to_string().contains("index"), "{e}");
}

#[test]
fn ply_ascii_lines_hold_one_element_each() {
    // One extra value on the first vertex line would shift every value after it.
    let extra = ascii_ply(XYZ, "int", "0 0 0 7\n1 0 0\n0 1 0\n", "3 0 1 2\n");
    let e = parse_ply(&extra).unwrap_err().to_string();
    assert!(e.contains("line 10"), "{e}");
    // One missing value borrows from the next line.
    let short = ascii_ply(XYZ, "int", "0 0\n1 0 0\n0 1 0\n", "3 0 1 2\n");
    assert!(parse_ply(&short).is_err());
    // Trailing spaces, CRLF and blank lines at the end stay fine.
    let fine = ascii_ply(XYZ, "int", "0 0 0 \r\n1 0 0\r\n0 1 0\n", "3 0 1 2\n\n");
    assert_eq!(parse_ply(&fine).unwrap().triangle_count(), 1);
}

#[test]
fn ply_properties_declared_twice_are_refused() {
    let props = "property float x\nproperty float x\nproperty float y\n";
    let e = parse_ply(&ascii_ply(
        props,
        "int",
        "0 0 0\n1 0 0\n0 1 0\n",
        "3 0 1 2\n",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("`x`") && e.contains("twice"), "{e}");
}

/// The square of [`square_glb`] as a `.gltf` whose buffer is the external file `uri`, and
/// that buffer's bytes.
fn square_gltf(uri: &str) -> (String, Vec<u8>) {
    let glb = square_glb(&[0, 1, 2, 2, 1, 3], 4, r#"{"mesh":0}"#);
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = std::str::from_utf8(&glb[20..20 + json_len])
        .unwrap()
        .trim_end();
    let bin = glb[20 + json_len + 8..].to_vec();
    let json = json.replace(
        r#""buffers":[{"byteLength""#,
        &format!(r#""buffers":[{{"uri":"{uri}","byteLength""#),
    );
    (json, bin)
}

#[test]
fn external_buffers_stay_inside_the_gltf_folder() {
    let dir = scratch_dir("confined");
    let folder = dir.join("asset");
    std::fs::create_dir_all(folder.join("sub")).unwrap();
    let (_, bin) = square_gltf("");
    // A secret next to the folder, a buffer inside it with more bytes than it declares.
    std::fs::write(dir.join("secret.bin"), &bin).unwrap();
    let mut padded = bin.clone();
    padded.extend_from_slice(&[0xAB; 64]);
    std::fs::write(folder.join("sub/square.bin"), &padded).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(dir.join("secret.bin"), folder.join("link.bin")).ok();

    let load = |uri: &str| {
        let (json, _) = square_gltf(uri);
        let path = folder.join("square.gltf");
        std::fs::write(&path, json).unwrap();
        no_panic(uri, || load_gltf(&path))
    };
    let mesh = load("sub/square.bin").expect("a buffer inside the folder loads");
    assert_eq!(mesh.mesh.triangle_count(), 2);
    assert!(load("./sub/square.bin").is_ok());
    let refused = [
        ("../secret.bin", "plain relative path"),
        ("sub/../../secret.bin", "plain relative path"),
        ("/etc/passwd", "plain relative path"),
        ("/dev/zero", "plain relative path"),
        ("%2Fdev%2Fzero", "plain relative path"),
        ("..%2Fsecret.bin", "plain relative path"),
        ("sub", "not a regular file"),
        #[cfg(unix)]
        ("link.bin", "outside the glTF's folder"),
    ];
    for (uri, expected) in refused {
        let e = load(uri).expect_err(uri).to_string();
        assert!(e.contains(expected), "{uri}: {e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A glTF of a few hundred bytes: a mesh whose POSITION accessor has no buffer view (zeros
/// of `count` elements), shown by `nodes` nodes, skinned with `joints` joints.
fn zero_filled_gltf(count: usize, nodes: usize, joints: usize) -> Vec<u8> {
    let node_list: Vec<String> = (0..nodes)
        .map(|_| r#"{"mesh":0,"skin":0}"#.to_string())
        .chain((0..joints).map(|_| "{}".to_string()))
        .collect();
    let joint_list: Vec<String> = (nodes..nodes + joints).map(|j| j.to_string()).collect();
    let roots: Vec<String> = (0..nodes + joints).map(|j| j.to_string()).collect();
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{}]}}],
        "nodes":[{}],"skins":[{{"joints":[{}]}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "accessors":[{{"componentType":5126,"count":{count},"type":"VEC3","min":[0,0,0],"max":[0,0,0]}}]}}"#,
        roots.join(","),
        node_list.join(","),
        joint_list.join(","),
    )
    .into_bytes()
}

#[test]
fn load_limits_stop_a_small_file_before_it_allocates() {
    let limit_of = |bytes: &[u8], limits: &LoadLimits| match no_panic("a zero-filled glTF", || {
        load_gltf_slice_with_limits(bytes, None, limits)
    }) {
        Err(MeshError::LimitExceeded { limit, .. }) => limit,
        other => panic!(
            "expected a limit, got {:?}",
            other.map(|i| i.mesh.vertex_count())
        ),
    };
    // 999,999 vertices of 12 bytes per node: the second node passes 20 MB.
    let file = zero_filled_gltf(999_999, 3, 2);
    assert!(file.len() < 1_000);
    let defaults = LoadLimits::default();
    let tight = LoadLimits {
        decoded_bytes: 20_000_000,
        ..defaults
    };
    for (limits, expected) in [
        (tight, "decoded_bytes"),
        (
            LoadLimits {
                vertices: 1_500_000,
                ..defaults
            },
            "vertices",
        ),
        (
            LoadLimits {
                joints: 1,
                ..defaults
            },
            "joints",
        ),
        (
            LoadLimits {
                file_bytes: 100,
                ..defaults
            },
            "file_bytes",
        ),
    ] {
        assert_eq!(limit_of(&file, &limits), expected);
    }
    // The error says which limit and how to raise it.
    let e = load_gltf_slice_with_limits(&file, None, &tight)
        .unwrap_err()
        .to_string();
    assert!(e.contains("LoadLimits::decoded_bytes"), "{e}");
    // Within the defaults, the limits pass it on to the importer's other checks.
    assert!(!matches!(
        load_gltf_slice_with_limits(&file, None, &LoadLimits::default()),
        Err(MeshError::LimitExceeded { .. })
    ));
}

#[test]
fn joint_maps_are_linear_in_joints_and_primitives() {
    // One skin of 20,000 joints, one mesh of 60 primitives (the same triangle) on a skinned
    // node. Mapped per primitive by a linear search, this took minutes.
    let (joints, primitives) = (20_000, 60);
    let bin: Vec<u8> = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .chain([0u8; 12])
        .collect();
    let nodes: Vec<&str> = std::iter::once(r#"{"mesh":0,"skin":0}"#)
        .chain(std::iter::repeat_n("{}", joints))
        .collect();
    let joint_list: Vec<String> = (1..=joints).map(|j| j.to_string()).collect();
    let primitive = r#"{"attributes":{"POSITION":0,"JOINTS_0":1,"WEIGHTS_0":2}}"#;
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":[{}],"skins":[{{"joints":[{}]}}],
        "meshes":[{{"primitives":[{}]}}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
          {{"bufferView":1,"componentType":5121,"count":3,"type":"VEC4"}},
          {{"bufferView":2,"componentType":5121,"normalized":true,"count":3,"type":"VEC4"}}],
        "bufferViews":[{{"buffer":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":12}},
          {{"buffer":0,"byteOffset":36,"byteLength":12}}],
        "buffers":[{{"byteLength":{}}}]}}"#,
        nodes.join(","),
        joint_list.join(","),
        vec![primitive; primitives].join(","),
        bin.len()
    );
    let dir = scratch_dir("joints");
    let path = dir.join("many_joints.glb");
    std::fs::write(&path, glb(&json, &bin)).unwrap();
    let start = std::time::Instant::now();
    let (read, skins) = bevy_aslod::mesh::load_gltf_primitives(&path).unwrap();
    assert_eq!((read.len(), skins[0].joints.len()), (primitives, joints));
    assert!(start.elapsed().as_secs() < 20, "{:?}", start.elapsed());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn tiny_triangles_are_kept_and_huge_coordinates_refused() {
    // Edges of 1e-13: the f32 area underflows to 0, yet the triangle is not degenerate.
    for scale in [1e-13f32, 1e-20] {
        let mut tiny = IndexedMesh::new(
            vec![Vec3::ZERO, Vec3::X * scale, Vec3::Y * scale],
            vec![0, 1, 2],
        );
        let report = tiny.validate().unwrap();
        assert_eq!(report.degenerate_triangles_dropped, 0, "{scale}");
    }
    // A diagonal whose f32 square overflows.
    let big = IndexedMesh::new(
        vec![Vec3::ZERO, Vec3::X * 1e18, Vec3::Y * 1e18],
        vec![0, 1, 2],
    );
    let d = big.diagonal();
    assert!(
        d.is_finite() && (d / 1.4142135e18 - 1.0).abs() < 1e-6,
        "{d}"
    );
    // Beyond MAX_COORDINATE: an error naming the vertex.
    let mut huge = IndexedMesh::new(vec![Vec3::ZERO, Vec3::X * 1e20, Vec3::Y], vec![0, 1, 2]);
    match huge.validate() {
        Err(MeshError::CoordinateOutOfRange { vertex: 1, .. }) => {}
        other => panic!("expected CoordinateOutOfRange at vertex 1, got {other:?}"),
    }
}

#[test]
fn gpu_instancing_places_the_mesh_once_per_instance() {
    use common::instancing::instanced_quads;
    let translations = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 0.0, 10.0]];
    let bytes = instanced_quads(&translations, [0.0, 5.0, 0.0], "");
    let import = load_gltf_slice(&bytes, None).unwrap();
    assert_eq!(import.gpu_instances, 3);
    assert_eq!(import.primitives, 3);
    assert_eq!(import.mesh.triangle_count(), 6);
    let p = &import.mesh.positions;
    // Node transform times each copy's: the first at the node, the third 10 along Z.
    assert_eq!(p[1], Vec3::new(1.0, 5.0, 0.0));
    assert_eq!(p[8 + 1], Vec3::new(1.0, 5.0, 10.0));
    // The second turned a quarter about Y and doubled: (1, 0, 0) goes to (0, 0, -2).
    assert!(
        (p[4 + 1] - Vec3::new(10.0, 5.0, -2.0)).length() < 1e-5,
        "{}",
        p[5]
    );

    // An accessor of another type, or one the file lacks, is a named error.
    let bad = instanced_quads(&translations, [0.0; 3], r#","SCALE":2"#);
    let error = load_gltf_slice(&bad, None).unwrap_err().to_string();
    assert!(error.contains("EXT_mesh_gpu_instancing"), "{error}");
    let bad = instanced_quads(&translations, [0.0; 3], r#","SCALE":99"#);
    let error = load_gltf_slice(&bad, None).unwrap_err().to_string();
    assert!(error.contains("no accessor 99"), "{error}");

    // The copies count against the limits before anything is decoded.
    let many = vec![[0.0; 3]; 1_000];
    let limits = LoadLimits {
        triangles: 1_999,
        ..LoadLimits::default()
    };
    let error = load_gltf_slice_with_limits(&instanced_quads(&many, [0.0; 3], ""), None, &limits)
        .unwrap_err()
        .to_string();
    assert!(error.contains("triangles"), "{error}");
}
