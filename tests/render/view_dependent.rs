//! Renders the `view_dependent` example offscreen and checks its three shots (frustum,
//! orientation, screen-space error) are drawn and each refines the bunny between its coarsest
//! level and full detail. Skipped, with a message, only where no Vulkan driver is installed.

use super::example_run::{example_binary, require_vulkan, varied_fraction};
use std::path::Path;
use std::process::Command;

#[test]
fn view_dependent_shots_are_drawn_and_refined() {
    if !require_vulkan("view_dependent_render") {
        return;
    }
    let binary = example_binary("view_dependent");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("view-dependent-shots");
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::new(&binary)
        .args([
            "--headless",
            "--frames",
            "4",
            "--size",
            "480x270",
            "--screenshot",
        ])
        .arg(&dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run the view_dependent example");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "view_dependent failed: {}\n{log}",
        output.status
    );
    let text = std::fs::read_to_string(dir.join("counts.json")).expect("counts.json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("valid json");
    for name in ["frustum", "orientation", "screen_space"] {
        let png = dir.join(format!("{name}.png"));
        assert!(png.exists(), "{} missing\n{log}", png.display());
        let varied = varied_fraction(&png);
        assert!(
            varied > 0.1,
            "{name}.png looks blank: {varied:.3} of pixels differ"
        );
        let shot = &json[name];
        let n = shot["triangles"].as_u64().expect("triangles");
        let full = shot["full_detail"].as_u64().expect("full detail");
        let coarsest = shot["coarsest"].as_u64().expect("coarsest");
        assert_eq!(full, 69_451, "the Stanford bunny");
        assert!(
            coarsest < n && n < full,
            "{name}: {n} of {coarsest}..{full}"
        );
        assert_eq!(shot["shown_by_the_plugin"].as_u64(), Some(n), "{name}");
    }
}
