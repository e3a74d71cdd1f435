//! The PLY reader (ASCII and both binary byte orders) on arbitrary bytes: an error or a mesh
//! that validates or fails validation with an error, never a panic, within
//! [`LoadLimits::SMALL`]'s memory bound.
//!
//! `cargo +nightly fuzz run ply_read -- -max_total_time=300 -rss_limit_mb=1024` (from the
//! crate's root).
#![no_main]

use bevy_aslod::mesh::{LoadLimits, parse_ply_with_limits};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(mut mesh) = parse_ply_with_limits(data, &LoadLimits::SMALL) {
        let _ = mesh.validate();
    }
});
