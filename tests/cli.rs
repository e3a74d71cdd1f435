//! The `aslod` command line, run as a user runs it.

use std::process::Command;

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
