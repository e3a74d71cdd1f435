//! The glTF/GLB importer on arbitrary bytes, within small [`LoadLimits`] (so that a crafted
//! count cannot make the fuzzer run out of memory instead of finding a bug): an error or a
//! validated mesh, never a panic. No base directory, so external URIs are refused.
//!
//! `cargo +nightly fuzz run gltf_read ../shared/testdata/gltf-malformed -- -max_total_time=300`
//! (from the crate's root; the malformed glTF corpus seeds it).
#![no_main]

use bevy_aslod::mesh::{LoadLimits, load_gltf_slice_with_limits};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let limits = LoadLimits {
        decoded_bytes: 64 << 20,
        vertices: 1 << 20,
        triangles: 1 << 20,
        ..LoadLimits::default()
    };
    let _ = load_gltf_slice_with_limits(data, None, &limits);
});
