//! Renders the `silvretta` example offscreen (Vulkan; lavapipe on machines without a GPU) and
//! checks its screenshots and triangle counts. Skipped, with a message, only where no Vulkan
//! driver is installed.

use super::example_run::{example_binary, require_vulkan, varied_fraction};
use std::path::Path;
use std::process::Command;

#[test]
fn silvretta_renders_offscreen_with_counts_under_budget() {
    if !require_vulkan("silvretta_render") {
        return;
    }
    let binary = example_binary("silvretta");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("silvretta-shots");
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::new(&binary)
        .args(["--headless", "--frames", "6", "--screenshot"])
        .arg(&dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run the silvretta example");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "silvretta failed: {}\n{log}",
        output.status
    );

    for name in ["corner", "corner_regions", "top", "top_regions"] {
        let png = dir.join(format!("{name}.png"));
        assert!(png.exists(), "{} missing\n{log}", png.display());
        let varied = varied_fraction(&png);
        assert!(
            varied > 0.1,
            "{name}.png looks blank: {varied:.3} of pixels differ"
        );
    }

    let text = std::fs::read_to_string(dir.join("counts.json")).expect("counts.json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("valid json");
    let budget = json["budget"].as_u64().expect("budget");
    assert_eq!(budget, 10_000);
    for view in ["corner", "top"] {
        let v = &json["views"][view];
        let counts: Vec<u64> = v["regions"]
            .as_array()
            .expect("regions")
            .iter()
            .map(|c| c.as_u64().expect("count"))
            .collect();
        assert_eq!(counts.len(), 36, "{view}: 6x6 regions");
        let total: u64 = counts.iter().sum();
        assert_eq!(v["total"].as_u64(), Some(total));
        assert!(total <= budget, "{view}: {total} > {budget}");
        assert!(total > budget / 2, "{view}: the budget is used ({total})");
    }
    let timing = &json["frame_time"];
    let lod = timing["budget"]["triangles"]
        .as_u64()
        .expect("triangles at the budget");
    assert!(lod <= budget, "timed at {lod} triangles");
    assert_eq!(timing["full_detail"]["triangles"].as_u64(), Some(135_200));
    for half in ["budget", "full_detail"] {
        let median = timing[half]["frame"]["median_ms"].as_f64().expect("median");
        assert!(median > 0.0 && median.is_finite(), "{half}: {median}");
    }
    let corner = &json["views"]["corner"];
    let count = |r: &serde_json::Value| {
        corner["regions"][r.as_u64().unwrap() as usize]
            .as_u64()
            .unwrap()
    };
    let (near, far) = (
        count(&corner["nearest_region"]),
        count(&corner["farthest_region"]),
    );
    assert!(
        near > 2 * far,
        "corner view: nearest region {near} vs farthest {far}"
    );
    let top: Vec<u64> = json["views"]["top"]["regions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_u64().unwrap())
        .collect();
    let (lo, hi) = (*top.iter().min().unwrap(), *top.iter().max().unwrap());
    assert!(hi as f64 <= 1.5 * lo as f64, "top view uneven: {lo}..{hi}");
}
