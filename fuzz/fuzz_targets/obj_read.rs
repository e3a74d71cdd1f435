//! The OBJ reader on arbitrary text: it must return an error or a mesh that validates (or
//! fails validation with an error), never panic, and stay near-linear in its input.
//!
//! `cargo +nightly fuzz run obj_read ../shared/testdata/meshes -- -max_total_time=300` (from
//! the crate's root).
#![no_main]

use bevy_aslod::mesh::parse_obj;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(mut mesh) = parse_obj(&String::from_utf8_lossy(data)) {
        let _ = mesh.validate();
    }
});
