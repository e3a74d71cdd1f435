//! Diagnostic paths the plugin registers with Bevy's `DiagnosticsStore`.

use bevy::diagnostic::{Diagnostic, DiagnosticPath, RegisterDiagnostic};
use bevy::prelude::*;

/// Triangles rendered by all region instances.
pub const TRIANGLES: DiagnosticPath = DiagnosticPath::const_new("aslod/triangles");
/// The budget `P`.
pub const BUDGET: DiagnosticPath = DiagnosticPath::const_new("aslod/budget");
/// Time in `Allocate`, ms.
pub const ALLOCATION_MS: DiagnosticPath = DiagnosticPath::const_new("aslod/allocation_ms");
/// Time in `SelectLod` and `Upload`, ms.
pub const UPDATE_MS: DiagnosticPath = DiagnosticPath::const_new("aslod/update_ms");
/// Regions whose index buffer was rewritten this frame.
pub const REGIONS_CHANGED: DiagnosticPath = DiagnosticPath::const_new("aslod/regions_changed");
/// Time in `Deform`, ms.
pub const DEFORM_MS: DiagnosticPath = DiagnosticPath::const_new("aslod/deform_ms");

/// The frame time a [`FrameTarget`](super::FrameTarget) aims at, in milliseconds.
pub const TARGET_MS: DiagnosticPath = DiagnosticPath::const_new("aslod/target_ms");
/// The smoothed frame time the budget controller measured, in milliseconds.
pub const FRAME_MS: DiagnosticPath = DiagnosticPath::const_new("aslod/frame_ms");

pub(super) fn register(app: &mut App) {
    app.register_diagnostic(Diagnostic::new(TRIANGLES))
        .register_diagnostic(Diagnostic::new(BUDGET))
        .register_diagnostic(Diagnostic::new(ALLOCATION_MS).with_suffix("ms"))
        .register_diagnostic(Diagnostic::new(UPDATE_MS).with_suffix("ms"))
        .register_diagnostic(Diagnostic::new(REGIONS_CHANGED))
        .register_diagnostic(Diagnostic::new(DEFORM_MS).with_suffix("ms"))
        .register_diagnostic(Diagnostic::new(TARGET_MS).with_suffix("ms"))
        .register_diagnostic(Diagnostic::new(FRAME_MS).with_suffix("ms"));
}
