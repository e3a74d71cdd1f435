//! Runs the `budget_tuning` example offscreen on the terrain (Vulkan; lavapipe on machines
//! without a GPU): a short sweep, whose PSNR must grow with the budget and whose triangles
//! stay within it, and a short run under a frame-time target, whose budget stays within the
//! controller's bounds and holds every frame.

use super::example_run::{example_binary, require_vulkan, varied_fraction};
use std::path::Path;
use std::process::Command;

fn run(binary: &Path, args: &[&str], dir: &Path) -> serde_json::Value {
    let _ = std::fs::remove_dir_all(dir);
    let output = Command::new(binary)
        .args(args)
        .arg("--out")
        .arg(dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run the budget_tuning example");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "budget_tuning {args:?} failed: {}\n{log}",
        output.status
    );
    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    serde_json::from_str(&text).expect("valid json")
}

#[test]
fn budget_tuning_sweeps_budgets_and_holds_a_frame_target() {
    if !require_vulkan("budget_tuning_render") {
        return;
    }
    let binary = example_binary("budget_tuning");
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));

    let dir = tmp.join("budget-tuning-sweep");
    let small = ["--size", "64x36", "--error-size", "160x90", "--repeat", "1"];
    let mut args = vec!["--scene", "terrain", "--frames", "10", "--views", "1"];
    args.extend(small);
    args.extend(["--budgets", "1000,4000,16000"]);
    let summary = run(&binary, &args, &dir);
    assert_eq!(summary["full_detail_triangles"], 135_200);
    let budgets = summary["budgets"].as_array().expect("budgets");
    assert_eq!(budgets.len(), 3);
    for b in budgets {
        let (p, drawn) = (
            b["budget"].as_f64().unwrap(),
            b["triangles"].as_f64().unwrap(),
        );
        assert!(drawn <= p && drawn > 0.5 * p, "{b}: triangles drawn off P");
        assert!(b["median_ms"].as_f64().unwrap() > 0.0);
    }
    let psnr: Vec<f64> = budgets
        .iter()
        .map(|b| b["psnr_median"].as_f64().unwrap())
        .collect();
    assert!(
        psnr[0] < psnr[2] && psnr[0] > 5.0,
        "PSNR against full detail should grow with P: {psnr:?}"
    );
    assert!(summary.get("knee").is_some() && summary.get("first_good").is_some());
    for png in [
        "error_vs_budget.png",
        "frame_vs_budget.png",
        "view0_full.png",
    ] {
        let varied = varied_fraction(&dir.join(png));
        assert!(varied > 0.05, "{png} looks blank: {varied:.3}");
    }
    let csv = std::fs::read_to_string(dir.join("sweep.csv")).expect("sweep.csv");
    assert_eq!(
        csv.lines().count(),
        5,
        "header, three budgets, full detail:\n{csv}"
    );

    let dir = tmp.join("budget-tuning-target");
    let mut args = vec!["--scene", "terrain", "--frames", "40", "--target-ms", "40"];
    args.extend(small);
    args.extend(["--min", "2000", "--max", "60000", "--budget", "20000"]);
    let summary = run(&binary, &args, &dir);
    assert_eq!(summary["target"]["frames_over_budget"], 0, "{summary}");
    let csv = std::fs::read_to_string(dir.join("control.csv")).expect("control.csv");
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 80, "40 fixed and 40 controlled frames");
    for row in rows.iter().filter(|r| r[0] == "target") {
        let p: u32 = row[4].parse().expect("budget");
        assert!(
            (2_000..=60_000).contains(&p),
            "P {p} outside the bounds: {row:?}"
        );
        assert_ne!(
            row[7], "Waiting",
            "the controller measured no frame: {row:?}"
        );
    }
    for png in ["control.png", "after_step.png"] {
        assert!(varied_fraction(&dir.join(png)) > 0.05, "{png} looks blank");
    }
}
