//! Level changes as the renderer draws them (Vulkan; lavapipe on machines without a GPU):
//! the `render_cost` example changes the levels of three models and a dancing mannequin over
//! several frames under two cameras, then draws the same final levels as plain meshes built fresh, and the screenshots
//! must match. Skipped, with a message, only where no Vulkan driver is installed.

use super::example_run::{example_binary, require_vulkan};
use std::path::Path;
use std::process::Command;

#[test]
fn level_changes_draw_the_same_as_fresh_meshes() {
    if !require_vulkan("render") {
        return;
    }
    let binary = example_binary("render_cost");
    // With Bevy's GPU mesh preprocessing (the draw's index range is rebuilt from the mesh
    // allocator) and without it (the draw reads the render mesh's index count).
    for cpu in [false, true] {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(if cpu {
            "level-changes-cpu"
        } else {
            "level-changes-gpu"
        });
        let _ = std::fs::remove_dir_all(&dir);
        let mut command = Command::new(&binary);
        command.arg("--check").arg(&dir);
        if cpu {
            command.arg("--cpu-building");
        }
        let output = command
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("run the render_cost example");
        let log = String::from_utf8_lossy(&output.stderr);
        assert!(
            output.status.success(),
            "render_cost --check failed: {}\n{log}",
            output.status
        );
        let text = std::fs::read_to_string(dir.join("check.json")).expect("check.json");
        let json: serde_json::Value = serde_json::from_str(&text).expect("valid json");
        let changed = json["regions_changed"].as_u64().expect("regions_changed");
        assert!(changed >= 40, "levels changed only {changed} times");
        assert_eq!(json["changed_while_still"].as_u64(), Some(0), "{json}");
        let blended = json["vertices_blended"].as_u64().expect("vertices_blended");
        assert!(
            blended > 1_000,
            "the mannequin's regions blended {blended} vertices"
        );
        assert_views_match(&json, &dir, &format!("cpu building: {cpu}"));
    }
}

/// Every view of `json` drew something and at most 0.02% of its pixels differ from the
/// fresh meshes'.
fn assert_views_match(json: &serde_json::Value, dir: &Path, what: &str) {
    for (i, view) in json["views"].as_array().expect("views").iter().enumerate() {
        let varied = json["varied"][i].as_f64().expect("varied");
        assert!(varied > 0.2, "view {i} ({what}) looks blank ({varied:.3})");
        let fraction = view["fraction_differing"].as_f64().expect("fraction");
        let max = view["max_channel_difference"].as_u64().expect("max");
        assert!(
            fraction <= 0.0002,
            "view {i} ({what}): {fraction:.4} of pixels differ (max {max}) from the fresh meshes; see {}",
            dir.display()
        );
    }
}

/// 200 instances of one asset with `SharedLevels`, at mixed levels, draw like plain meshes
/// built fresh at those levels (under a depth prepass, a shadow-casting light and two
/// cameras), while holding far fewer meshes than regions.
#[test]
fn shared_levels_draw_the_same_as_fresh_meshes() {
    if !require_vulkan("render") {
        return;
    }
    let binary = example_binary("render_cost");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("level-changes-shared");
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::new(&binary)
        .args(["--shared", "--check"])
        .arg(&dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run the render_cost example");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "render_cost --shared --check failed: {}\n{log}",
        output.status
    );
    let text = std::fs::read_to_string(dir.join("check.json")).expect("check.json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("valid json");
    let regions = json["regions"].as_u64().expect("regions");
    assert_eq!(regions, 200 * 16);
    let levels = json["distinct_levels"].as_u64().expect("distinct_levels");
    assert!(
        levels > 16 * 3,
        "the regions show only {levels} (region, level) pairs"
    );
    let shared = json["shared_meshes"].as_u64().expect("shared_meshes");
    assert!(
        shared > 0 && shared < regions / 4,
        "{shared} level meshes for {regions} regions"
    );
    assert!(json["regions_changed"].as_u64().expect("changed") > 200);
    assert_views_match(&json, &dir, "shared levels");
}
