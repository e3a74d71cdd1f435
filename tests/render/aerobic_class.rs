//! Runs the `aerobic_class` example offscreen for 30 frames (Vulkan; lavapipe on machines
//! without a GPU) and checks its report: a non-blank screenshot, the charts, one CSV row per
//! frame and a summary whose largest total is within the 5,000-triangle budget.

use super::example_run::{example_binary, require_vulkan, varied_fraction};
use std::path::Path;
use std::process::Command;

const FRAMES: usize = 30;

#[test]
fn aerobic_class_report_stays_within_budget() {
    if !require_vulkan("aerobic_class") {
        return;
    }
    let binary = example_binary("aerobic_class");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("aerobic-report");
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::new(&binary)
        .args(["--headless", "--frames", &FRAMES.to_string(), "--report"])
        .arg(&dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run the aerobic_class example");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "aerobic_class failed: {}\n{log}",
        output.status
    );

    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    let summary: serde_json::Value = serde_json::from_str(&text).expect("valid json");
    assert_eq!(summary["budget"].as_u64(), Some(5_000));
    assert_eq!(summary["dancers"].as_u64(), Some(3));
    assert_eq!(summary["frames"].as_u64(), Some(FRAMES as u64));
    let largest = summary["largest_total"].as_u64().expect("largest_total");
    assert!(largest <= 5_000, "largest total {largest} > 5,000");
    assert!(
        largest >= 4_500,
        "the budget is used: largest total {largest}"
    );
    let full = summary["full_detail_total"].as_u64().expect("full detail");
    assert!(full > 80_000, "no-LOD run is at full detail: {full}");
    for key in ["with_lod", "without_lod"] {
        let median = summary[key]["median_ms"].as_f64().expect("median");
        assert!(median > 0.0 && median.is_finite(), "{key}: median {median}");
    }

    let csv = std::fs::read_to_string(dir.join("frames.csv")).expect("frames.csv");
    let mut lines = csv.lines();
    let header = lines.next().expect("header");
    assert!(
        header.starts_with(
            "frame,frame_ms,mannequin_1,mannequin_2,mannequin_3,total,no_lod_frame_ms,no_lod_total"
        ),
        "{header}"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|c| c.parse().expect("number")).collect())
        .collect();
    assert_eq!(rows.len(), FRAMES);
    for row in &rows {
        let total = row[5];
        assert!(total <= 5_000.0, "frame {}: total {total}", row[0]);
        // The mannequins' triangles plus the floor's two make the total.
        assert_eq!(row[2] + row[3] + row[4] + 2.0, total, "frame {}", row[0]);
        // Without LOD every region is at full detail, in view or not.
        assert_eq!(row[7], full as f64, "frame {}: no-LOD total", row[0]);
    }

    let shots = summary["screenshots"].as_array().expect("screenshots");
    assert_eq!(shots.len(), 3, "{shots:?}");
    for shot in shots {
        let png = dir.join(shot.as_str().expect("name"));
        let varied = varied_fraction(&png);
        assert!(varied > 0.1, "{} looks blank: {varied:.3}", png.display());
    }
    for chart in ["frame_time.png", "allocation.png"] {
        let varied = varied_fraction(&dir.join(chart));
        assert!(varied > 0.01, "{chart} looks blank: {varied:.4}");
    }
}
