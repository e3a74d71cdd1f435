//! The glTF/GLB importer on arbitrary bytes, within [`LoadLimits::SMALL`] (whose peak memory
//! is under 400 MB, so a run under `-rss_limit_mb=1024` that runs out of memory has found a
//! read that breaks the bound): an error or a validated mesh, never a panic. No base
//! directory, so external URIs are refused.
//!
//! `cargo +nightly fuzz run gltf_read ../shared/testdata/gltf-malformed -- -max_total_time=300
//! -rss_limit_mb=1024` (from the crate's root; the malformed glTF corpus seeds it).
#![no_main]

use bevy_aslod::mesh::{LoadLimits, load_gltf_slice_with_limits};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = load_gltf_slice_with_limits(data, None, &LoadLimits::SMALL);
});
