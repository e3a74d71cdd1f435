//! A textured, normal-mapped PBR asset (the shared test data's WaterBottle, which has no
//! TANGENT attribute, so Bevy's glTF loader makes tangents) under a `MultiresScene`: at
//! `FullDetail` it draws like plain Bevy, normal map and occlusion map included (without its
//! tangents 1.6% of the pixels differ), and at 5% of its triangles it draws with every
//! attribute present and finite, and lit and textured as the reference is. The same for a
//! generated sphere with vertex colours, a second UV set and a custom attribute that the
//! example's material reads (darker stripes where it is lost).

use super::example_run::{example_binary, require_vulkan};
use std::path::Path;
use std::process::Command;

#[test]
fn a_textured_asset_draws_like_plain_bevy_at_full_detail() {
    if !require_vulkan("render") {
        return;
    }
    check("textured", &[]);
}

/// Vertex colours, a second UV set and a custom attribute read by a material (the example's
/// generated sphere: colour bands across its rows, stripes of its `_TINT`) draw like plain
/// Bevy too.
#[test]
fn vertex_colours_and_a_custom_attribute_draw_like_plain_bevy_at_full_detail() {
    if !require_vulkan("render") {
        return;
    }
    check("textured-procedural", &["--procedural"]);
}

/// Runs the example on two views with `extra` arguments into a folder called `name`, and
/// checks its report.
fn check(name: &str, extra: &[&str]) {
    let binary = example_binary("textured");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::new(&binary)
        .args(["--views", "2", "--ratios", "0.05", "--no-peer", "--out"])
        .arg(&dir)
        .args(extra)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run the textured example");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "textured failed: {}\n{log}",
        output.status
    );
    let text = std::fs::read_to_string(dir.join("report.json")).expect("report.json");
    let report: serde_json::Value = serde_json::from_str(&text).expect("valid json");
    for view in report["views"].as_array().expect("views") {
        let varied = view["varied"].as_f64().expect("varied");
        assert!(
            varied > 0.05,
            "the asset is not in view ({varied:.3}); see {}",
            dir.display()
        );
        let full = &view["full_detail"];
        let fraction = full["fraction_over_2"].as_f64().expect("fraction");
        assert!(
            fraction <= 0.001,
            "view {}: {:.4}% of pixels differ by more than 2/255 (max {}) from plain Bevy; see {}",
            view["view"],
            100.0 * fraction,
            full["max_channel_difference"],
            dir.display()
        );
        // A level drawn with NaN normals or a missing attribute comes out unlit or
        // untextured: its mean colour leaves the reference's (the bottle with NaN normals:
        // 105/255 off in red; its 5% level itself: about 10).
        let mean = |v: &serde_json::Value| -> Vec<f64> {
            v.as_array()
                .expect("rgb")
                .iter()
                .map(|c| c.as_f64().expect("channel"))
                .collect()
        };
        let (reference, coarse) = (
            mean(&view["mean_color"]),
            mean(&view["ratios"][0]["ours"]["mean_color"]),
        );
        let off = reference
            .iter()
            .zip(&coarse)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            off <= 30.0,
            "view {}: the 5% level's mean colour {coarse:?} is {off:.0}/255 from the reference's {reference:?}; see {}",
            view["view"],
            dir.display()
        );
    }
    for coarse in report["coarse_attributes"]
        .as_array()
        .expect("coarse_attributes")
    {
        let problems = coarse["problems"].as_array().expect("problems");
        assert!(
            problems.is_empty(),
            "at ratio {}: {problems:?}",
            coarse["ratio"]
        );
    }
}

/// A flat-shaded asset (the example's bumpy sphere, `--procedural --flat`: every triangle its
/// own three vertices with the face's normal, so every edge is a seam) at a tenth of its
/// triangles keeps its hard edges: drawn at least as close to plain Bevy at full detail as
/// meshoptimizer's `Permissive` levels at the same counts (its plain simplification cannot
/// remove a triangle of it). The images are in the test's output folder.
#[test]
fn a_flat_shaded_asset_keeps_its_hard_edges_at_a_tenth() {
    if !require_vulkan("render") {
        return;
    }
    let binary = example_binary("textured");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("textured-flat");
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::new(&binary)
        .args(["--procedural", "--flat", "--views", "2", "--ratios", "0.1"])
        .args(["--peer-permissive", "--out"])
        .arg(&dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run the textured example");
    assert!(
        output.status.success(),
        "textured failed: {}\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    let text = std::fs::read_to_string(dir.join("report.json")).expect("report.json");
    let report: serde_json::Value = serde_json::from_str(&text).expect("valid json");
    let row = &report["summary"]["ratios"][0];
    let (ours, peer) = (
        row["ours"]["median_psnr"].as_f64().expect("ours"),
        row["meshopt"]["median_psnr"].as_f64().expect("meshopt"),
    );
    eprintln!("flat-shaded sphere at 10 %: ours {ours:.1} dB, meshopt Permissive {peer:.1} dB");
    assert!(
        ours >= peer,
        "ours {ours:.1} dB against meshoptimizer's {peer:.1} dB; see {}",
        dir.display()
    );
    let full = report["full_triangles"].as_u64().expect("full");
    for view in report["views"].as_array().expect("views") {
        let shown = view["ratios"][0]["triangles"].as_u64().expect("triangles");
        assert!(
            shown * 8 <= full,
            "{shown} of {full}: the sphere did not reduce"
        );
    }
}
