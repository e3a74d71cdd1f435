//! Renders the `silvretta` example offscreen (Vulkan; lavapipe on machines without a GPU) and
//! checks its screenshots and triangle counts. Skipped, with a message, only where no Vulkan
//! driver is installed.
#![cfg(feature = "bevy")]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The example binary next to this test's own (`target/<profile>/examples/silvretta`),
/// built with cargo when it is missing.
fn example_binary() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/silvretta_render-<hash>
    let profile_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("test binary lies in target/<profile>/deps");
    let binary = profile_dir
        .join("examples")
        .join(format!("silvretta{}", std::env::consts::EXE_SUFFIX));
    let status = Command::new(env!("CARGO"))
        .args(["build", "--example", "silvretta", "--features", "bevy"])
        .args(if profile_dir.ends_with("release") {
            &["--release"][..]
        } else {
            &[][..]
        })
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .status()
        .expect("run cargo build --example silvretta");
    assert!(status.success(), "cargo build --example silvretta failed");
    assert!(binary.exists(), "{} was not built", binary.display());
    binary
}

/// Whether a Vulkan driver (ICD) is installed.
fn vulkan_available() -> bool {
    if std::env::var_os("VK_ICD_FILENAMES").is_some()
        || std::env::var_os("VK_DRIVER_FILES").is_some()
    {
        return true;
    }
    [
        "/usr/share/vulkan/icd.d",
        "/etc/vulkan/icd.d",
        "/usr/local/share/vulkan/icd.d",
    ]
    .iter()
    .filter_map(|d| std::fs::read_dir(d).ok())
    .flatten()
    .flatten()
    .any(|e| e.path().extension().is_some_and(|x| x == "json"))
}

/// The fraction of a PNG's pixels that differ from its first pixel (0 for a blank frame).
fn varied_fraction(path: &Path) -> f64 {
    let image = bevy::image::Image::from_buffer(
        &std::fs::read(path).expect("read png"),
        bevy::image::ImageType::Extension("png"),
        bevy::image::CompressedImageFormats::NONE,
        true,
        bevy::image::ImageSampler::Default,
        bevy::asset::RenderAssetUsages::default(),
    )
    .expect("decode png");
    let data = image.data.expect("pixel data");
    let first = &data[..4];
    let pixels = data.chunks_exact(4).count();
    let differing = data.chunks_exact(4).filter(|p| p != &first).count();
    differing as f64 / pixels as f64
}

#[test]
fn silvretta_renders_offscreen_with_counts_under_budget() {
    if !vulkan_available() {
        eprintln!(
            "SKIPPED silvretta_render: no Vulkan driver found (install mesa-vulkan-drivers for lavapipe)"
        );
        return;
    }
    let binary = example_binary();
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
