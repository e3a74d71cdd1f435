//! The PLY reader (ASCII and both binary byte orders) on arbitrary bytes: an error or a mesh
//! that validates or fails validation with an error, never a panic.
//!
//! `cargo +nightly fuzz run ply_read -- -max_total_time=300` (from the crate's root).
#![no_main]

use bevy_aslod::mesh::parse_ply;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(mut mesh) = parse_ply(data) {
        let _ = mesh.validate();
    }
});
