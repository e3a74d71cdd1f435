//! Renders the `skinned_character` example offscreen (RobotExpressive dancing; Vulkan,
//! lavapipe on machines without a GPU) and checks its screenshots and counts.

use super::example_run::{example_binary, require_vulkan, varied_fraction};
use std::path::Path;
use std::process::Command;

#[test]
fn robot_renders_offscreen_with_rigid_and_deformable_regions() {
    if !require_vulkan("skinned_character_render") {
        return;
    }
    let binary = example_binary("skinned_character");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("character-shots");
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::new(&binary)
        .args(["--headless", "--frames", "5", "--screenshot"])
        .arg(&dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run the skinned_character example");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "skinned_character failed: {}\n{log}",
        output.status
    );
    for name in ["character", "character_overlay"] {
        let png = dir.join(format!("{name}.png"));
        assert!(png.exists(), "{} missing\n{log}", png.display());
        let varied = varied_fraction(&png);
        assert!(varied > 0.05, "{name}.png looks blank: {varied:.3}");
    }
    let text = std::fs::read_to_string(dir.join("counts.json")).expect("counts.json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("valid json");
    assert_eq!(json["clip"].as_str(), Some("Dance"), "the default clip");
    assert_eq!(json["skinned_models"].as_u64(), Some(4), "{json}");
    let regions = json["regions"].as_array().expect("regions");
    let count = |kind: &str| regions.iter().filter(|r| r["kind"] == kind).count();
    assert!(count("rigid") > 0 && count("deformable") > 0, "{json}");
    let total = json["triangles"].as_u64().expect("triangles");
    assert!(total <= json["budget"].as_u64().expect("budget"));
    assert!(json["vertices_with_more_than_two_influences"].as_u64() > Some(0));
}
