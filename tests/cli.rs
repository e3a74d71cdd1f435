//! The `aslod` command line, run as a user runs it.

use std::process::Command;

mod common;
use common::instancing;

/// `aslod info` on an OBJ whose faces give normals to only some corners: the importer's
/// warning reaches standard error.
#[test]
fn importer_warnings_reach_stderr() {
    let dir = std::env::temp_dir().join(format!("bevy_aslod_cli_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = dir.join("mixed_normals.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\nf 3 2 4\n",
    )
    .unwrap();
    let run = |log: Option<&str>| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_aslod"));
        command.arg("info").arg(&obj).env_remove("ASLOD_LOG");
        if let Some(level) = log {
            command.env("ASLOD_LOG", level);
        }
        let out = command.output().expect("aslod runs");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let stderr = run(None);
    assert!(
        stderr.contains("aslod: warn: OBJ: only some face corners have normals"),
        "{stderr}"
    );
    assert!(!run(Some("error")).contains("only some face corners"));
    std::fs::remove_dir_all(&dir).ok();
}

/// `aslod extract` with regions: `--counts` alone gives the levels, `--error` (which regions
/// do not take) is refused when the arguments are parsed, before anything is read.
#[test]
fn extract_takes_counts_alone_and_refuses_an_error_with_regions() {
    let dir = std::env::temp_dir().join(format!("bevy_aslod_cli_counts_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cow = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/testdata/meshes/cow.obj"
    );
    let out = dir.join("cow.obj");
    let extract = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_aslod"))
            .args(["extract", cow, "-o"])
            .arg(&out)
            .args(["--regions", "clusters:2"])
            .args(extra)
            .output()
            .expect("aslod runs")
    };
    let counts = extract(&["--counts", "100,200"]);
    let said = String::from_utf8_lossy(&counts.stderr);
    assert!(counts.status.success(), "{said}");
    assert!(said.contains("wrote 300 triangles in 2 regions"), "{said}");
    let error = extract(&["--error", "0.01"]);
    assert_eq!(error.status.code(), Some(2), "a usage error");
    let stderr = String::from_utf8_lossy(&error.stderr);
    assert!(
        stderr.contains("--error") && stderr.contains("--regions"),
        "{stderr}"
    );
    let both = extract(&["--counts", "100,200", "--triangles", "300"]);
    assert_eq!(
        both.status.code(),
        Some(2),
        "--counts and --triangles together"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `aslod info` counts the copies a node places through `EXT_mesh_gpu_instancing`.
#[test]
fn info_counts_gpu_instances() {
    let dir = std::env::temp_dir().join(format!("bevy_aslod_cli_gpu_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let glb = dir.join("instanced.glb");
    let at: Vec<[f32; 3]> = (0..5).map(|i| [i as f32 * 3.0, 0.0, 0.0]).collect();
    std::fs::write(&glb, instancing::instanced_quads(&at, [0.0; 3], "")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_aslod"))
        .arg("info")
        .arg(&glb)
        .output()
        .expect("aslod runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(stdout.contains("triangles 10 "), "{stdout}");
    assert!(
        stdout.contains("(GPU instances, EXT_mesh_gpu_instancing: 5)"),
        "{stdout}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
