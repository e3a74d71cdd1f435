//! Geomorphs as the renderer draws them: the `geomorph` example drops and restores the budget
//! under a still camera and draws each frame without geomorphs, with them written from the
//! CPU, and with `GeomorphMaterial` interpolating them in the vertex shaders. The GPU run must
//! draw what the CPU run does, and spread the level changes over many frames where the run
//! without geomorphs changes a large share of the pixels at once. Once plain, once textured
//! (`--textured`: UVs and tangents morph too, under a checkered colour and a normal map).
//! Skipped, with a message, only where no Vulkan driver is installed.

use super::example_run::{example_binary, require_vulkan};
use std::path::Path;
use std::process::Command;

#[test]
fn gpu_geomorphs_draw_as_cpu_ones_and_do_not_pop() {
    if !require_vulkan("geomorph_render") {
        return;
    }
    let binary = example_binary("geomorph");
    for textured in [false, true] {
        check_run(&binary, textured);
    }
}

fn check_run(binary: &Path, textured: bool) {
    let name = if textured {
        "geomorph-textured"
    } else {
        "geomorph"
    };
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    let mut command = Command::new(binary);
    command.arg("--check").arg("--out").arg(&dir);
    if textured {
        command.arg("--textured");
    }
    let output = command
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run the geomorph example");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "{name} --check failed: {}\n{log}",
        output.status
    );
    let text = std::fs::read_to_string(dir.join("frames.json")).expect("frames.json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("valid json");
    let runs = json["runs"].as_array().expect("runs");
    let max = |i: usize| runs[i]["max_changed"].as_f64().expect("max_changed");
    let frames = |i: usize| runs[i]["frames_changing"].as_u64().expect("frames");
    // Without geomorphs, each budget step is one frame of many changed pixels.
    assert!(max(0) > 0.02 && frames(0) <= 4, "{json}");
    // With them, small changes over the morph time (15 frames at 60 fps), on both paths: at
    // most a fifth of the pop, a quarter textured (the checker under a moving vertex changes
    // more of its pixels each frame: 20 % of the pop, measured).
    let share = if textured { 4.0 } else { 5.0 };
    for i in [1, 2] {
        assert!(max(i) * share < max(0) && frames(i) >= 20, "{json}");
    }
    assert!(
        json["cpu_gpu_apart_max"].as_f64().expect("apart") <= 0.001,
        "{json}"
    );
    assert!(dir.join("geomorph-frames.png").exists());
}
