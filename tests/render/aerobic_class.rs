//! Runs the `aerobic_class` example offscreen for 30 frames, twice with LOD and twice without
//! (Vulkan; lavapipe on machines without a GPU), and checks its report: non-blank
//! screenshots, the charts, one CSV row per frame and run, and a summary whose largest total is
//! within the 5,000-triangle budget and whose frame-time statistics are all there.

use super::example_run::{example_binary, pixels_apart, require_vulkan, varied_fraction};
use std::path::Path;
use std::process::Command;

const FRAMES: usize = 30;
const REPEAT: usize = 2;

#[test]
fn aerobic_class_report_stays_within_budget() {
    if !require_vulkan("aerobic_class") {
        return;
    }
    let binary = example_binary("aerobic_class");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("aerobic-report");
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::new(&binary)
        .args(["--headless", "--frames", &FRAMES.to_string()])
        .args(["--repeat", &REPEAT.to_string(), "--report"])
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
    assert_eq!(summary["repeat"].as_u64(), Some(REPEAT as u64));
    let largest = summary["largest_total"].as_u64().expect("largest_total");
    assert!(largest <= 5_000, "largest total {largest} > 5,000");
    assert!(
        largest >= 4_500,
        "the budget is used: largest total {largest}"
    );
    let full = summary["full_detail_total"].as_u64().expect("full detail");
    assert!(full > 80_000, "no-LOD run is at full detail: {full}");
    for key in ["with_lod", "without_lod"] {
        let series = &summary[key];
        assert_eq!(series["runs"].as_u64(), Some(REPEAT as u64), "{key}");
        let median = series["median_ms"].as_f64().expect("median");
        assert!(median > 0.0 && median.is_finite(), "{key}: median {median}");
        for field in [
            "p95_ms",
            "mean_ms",
            "cv",
            "cv_all_frames",
            "cv_noise",
            "cv_systematic",
            "cpu_idle",
            "cpu_steal",
            "run_to_run_ms",
            "frame_to_frame_ms",
        ] {
            let value = series[field].as_f64();
            assert!(
                value.is_some_and(|v| v.is_finite() && v >= 0.0),
                "{key}.{field}: {value:?}"
            );
        }
        let r = series["in_view_correlation"].as_f64();
        assert!(
            r.is_some_and(|r| (-1.0..=1.0).contains(&r)),
            "{key}.in_view_correlation: {r:?}"
        );
        assert!(series["p95_ms"].as_f64() >= series["median_ms"].as_f64());
    }
    // The camera path takes dancers into and out of view.
    let (lo, hi) = (
        summary["full_detail_in_view_min"]
            .as_u64()
            .expect("in view min"),
        summary["full_detail_in_view_max"]
            .as_u64()
            .expect("in view max"),
    );
    assert!(
        lo < hi && hi <= full,
        "full detail in view {lo}..{hi} of {full}"
    );

    let csv = std::fs::read_to_string(dir.join("frames.csv")).expect("frames.csv");
    let mut lines = csv.lines();
    let header = lines.next().expect("header");
    assert!(
        header.starts_with(
            "run,frame,frame_ms,mannequin_1,mannequin_2,mannequin_3,total,no_lod_frame_ms,no_lod_total,in_view_full_detail"
        ),
        "{header}"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|c| c.parse().expect("number")).collect())
        .collect();
    assert_eq!(rows.len(), FRAMES * REPEAT);
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row[0] as usize, i / FRAMES + 1, "row {i}: run");
        assert_eq!(row[1] as usize, i % FRAMES + 1, "row {i}: frame");
        let total = row[6];
        assert!(total <= 5_000.0, "row {i}: total {total}");
        // The mannequins' triangles plus the floor's two make the total.
        assert_eq!(row[3] + row[4] + row[5] + 2.0, total, "row {i}");
        // Without LOD every region is at full detail, in view or not.
        assert_eq!(row[8], full as f64, "row {i}: no-LOD total");
        assert!(row[9] <= full as f64, "row {i}: in view {}", row[9]);
    }
    // Every run shows the same frames: the same triangles in view.
    for i in FRAMES..rows.len() {
        assert_eq!(
            rows[i][9],
            rows[i - FRAMES][9],
            "row {i}: in view differs by run"
        );
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

/// A crowd drawn both ways under a budget that keeps near dancers fine: sharing level meshes
/// that Bevy skins on the GPU (`--gpu-skinning`), and skinned on the CPU by the paper's blend
/// (the class's default). The same scripted frame, 0.6 s into the dance, must come out the
/// same: at most 0.1 % of pixels more than 2/255 apart.
#[test]
fn dancers_skinned_by_bevy_draw_as_cpu_skinned_ones() {
    if !require_vulkan("aerobic_class_gpu_skinning") {
        return;
    }
    let binary = example_binary("aerobic_class");
    let shot = |cpu: bool| {
        let name = if cpu { "crowd-cpu" } else { "crowd-gpu" };
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
        let _ = std::fs::remove_dir_all(&dir);
        let mut command = Command::new(&binary);
        command
            .args(["--headless", "--frames", "12", "--count", "12"])
            .args(["--budget", "4000000", "--size", "480x270", "--report"])
            .arg(&dir);
        if !cpu {
            command.arg("--gpu-skinning");
        }
        let output = command
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("run the aerobic_class example");
        assert!(
            output.status.success(),
            "aerobic_class {name} failed: {}\n{}",
            output.status,
            String::from_utf8_lossy(&output.stderr)
        );
        // The last scripted frame: the dancers well into the routine.
        dir.join("frame_012.png")
    };
    let (gpu, cpu) = (shot(false), shot(true));
    assert!(varied_fraction(&gpu) > 0.05, "the crowd is drawn");
    let apart = pixels_apart(&gpu, &cpu, 2);
    assert!(apart <= 0.001, "{:.3} % of pixels apart", apart * 100.0);
}
