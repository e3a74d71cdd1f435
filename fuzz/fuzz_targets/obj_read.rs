//! The OBJ reader on arbitrary text: it must return an error or a mesh that validates (or
//! fails validation with an error), never panic, and stay near-linear in its input and within
//! [`LoadLimits::SMALL`]'s memory bound.
//!
//! `cargo +nightly fuzz run obj_read ../shared/testdata/meshes -- -max_total_time=300
//! -rss_limit_mb=1024` (from the crate's root).
#![no_main]

use bevy_aslod::mesh::{LoadLimits, parse_obj_with_limits};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(mut mesh) = parse_obj_with_limits(&text, &LoadLimits::SMALL) {
        let _ = mesh.validate();
    }
});
