//! Runs `examples/basic.rs` in its own window settings for 30 frames after the character
//! shows (under `xvfb-run` when there is no display) and checks the count it printed: within
//! its 2,000-triangle budget, the budget used, and one camera in the split (its second
//! camera is marked `NoLodAllocation`).

use super::example_run::{example_binary, require_vulkan};
use std::process::Command;

#[test]
fn basic_example_runs_within_its_budget() {
    if !require_vulkan("basic") {
        return;
    }
    let binary = example_binary("basic");
    let has_display = std::env::var_os("DISPLAY").is_some();
    let mut command = if has_display {
        Command::new(&binary)
    } else {
        let mut xvfb = Command::new("xvfb-run");
        xvfb.args(["-a", "-s", "-screen 0 1280x720x24"])
            .arg(&binary);
        xvfb
    };
    let output = command
        .args(["--frames", "30"])
        // Bevy finds `assets/` beside the manifest.
        .env("CARGO_MANIFEST_DIR", env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap_or_else(|e| panic!("run basic (xvfb-run without a display: install xvfb): {e}"));
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "basic failed: {}\n{log}",
        output.status
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    let line = stdout
        .lines()
        .find(|l| l.contains("triangles / budget"))
        .unwrap_or_else(|| panic!("no count printed: {stdout}\n{log}"));
    let numbers: Vec<u64> = line
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    let [shown, budget, cameras] = numbers[..] else {
        panic!("unexpected count line: {line}");
    };
    assert_eq!(
        cameras, 1,
        "the picture-in-picture camera takes no share: {line}"
    );
    assert_eq!(budget, 2_000, "{line}");
    assert!(shown <= budget, "{line}");
    assert!(shown * 10 >= budget * 9, "the budget is used: {line}");
}
