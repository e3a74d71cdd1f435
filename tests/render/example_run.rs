//! Running an example binary offscreen from an integration test, and judging its PNGs.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The example binary next to the calling test's own (`target/<profile>/examples/NAME`),
/// built with cargo first so it is up to date.
pub fn example_binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/<test>-<hash>
    let profile_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("test binary lies in target/<profile>/deps");
    let binary = profile_dir
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    // The features this test was built with, so the library is not built a second time.
    let features: Vec<&str> = [
        ("bevy", cfg!(feature = "bevy")),
        ("ui", cfg!(feature = "ui")),
        ("cli", cfg!(feature = "cli")),
        ("mannequin", cfg!(feature = "mannequin")),
        ("distance", cfg!(feature = "distance")),
    ]
    .into_iter()
    .filter_map(|(name, on)| on.then_some(name))
    .collect();
    let status = Command::new(env!("CARGO"))
        .args([
            "build",
            "--example",
            name,
            "--features",
            &features.join(","),
        ])
        .args(if profile_dir.ends_with("release") {
            &["--release"][..]
        } else {
            &[][..]
        })
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .status()
        .unwrap_or_else(|e| panic!("run cargo build --example {name}: {e}"));
    assert!(status.success(), "cargo build --example {name} failed");
    assert!(binary.exists(), "{} was not built", binary.display());
    binary
}

/// Whether a Vulkan driver (ICD) is installed.
pub fn vulkan_available() -> bool {
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

/// Whether a render test can run: `true` with a Vulkan driver. Without one it prints that
/// the test is skipped and returns `false`, unless `ASLOD_REQUIRE_RENDER` is set (CI sets
/// it), where it fails.
pub fn require_vulkan(test: &str) -> bool {
    if vulkan_available() {
        return true;
    }
    assert!(
        std::env::var_os("ASLOD_REQUIRE_RENDER").is_none(),
        "{test}: no Vulkan driver found (install mesa-vulkan-drivers for lavapipe)"
    );
    eprintln!("SKIPPED {test}: no Vulkan driver found (install mesa-vulkan-drivers for lavapipe)");
    false
}

/// The fraction of a PNG's pixels that differ from its first pixel (0 for a blank frame).
pub fn varied_fraction(path: &Path) -> f64 {
    let data = png_pixels(path);
    let first = &data[..4];
    let pixels = data.chunks_exact(4).count();
    let differing = data.chunks_exact(4).filter(|p| p != &first).count();
    differing as f64 / pixels as f64
}

/// The fraction of pixels where two PNGs of one size differ by more than `tolerance` (of 255)
/// in a channel.
pub fn pixels_apart(a: &Path, b: &Path, tolerance: u8) -> f64 {
    let (a, b) = (png_pixels(a), png_pixels(b));
    assert_eq!(a.len(), b.len(), "images of one size");
    let apart = a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > tolerance))
        .count();
    apart as f64 / (a.len() / 4) as f64
}

/// A PNG's RGBA8 pixels.
fn png_pixels(path: &Path) -> Vec<u8> {
    let image = bevy::image::Image::from_buffer(
        &std::fs::read(path).unwrap_or_else(|e| panic!("read {}: {e}", path.display())),
        bevy::image::ImageType::Extension("png"),
        bevy::image::CompressedImageFormats::NONE,
        true,
        bevy::image::ImageSampler::Default,
        bevy::asset::RenderAssetUsages::default(),
    )
    .expect("decode png");
    image.data.expect("pixel data")
}
