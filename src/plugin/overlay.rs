//! The debug overlay: every region's world box, drawn with gizmos.

use super::{AslodOverlay, MultiresInstance};
use bevy::gizmos::config::GizmoConfigStore;
use bevy::prelude::*;

/// Adds [`draw_overlay`] when gizmos are available (so headless apps without them work).
pub(super) fn add_if_gizmos(app: &mut App) {
    if app.world().contains_resource::<GizmoConfigStore>() {
        app.add_systems(
            PostUpdate,
            draw_overlay
                .after(super::AslodSystems::Upload)
                .run_if(|overlay: Res<AslodOverlay>| overlay.0),
        );
    }
}

/// The 12 edges of a box, as corner pairs in [`Obb::corner`](crate::budget::Obb::corner)'s
/// numbering: corners that differ in one bit.
const EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Draws each region's world box, blue at its coarsest level to red at full detail.
fn draw_overlay(models: Query<(&MultiresInstance, &GlobalTransform)>, mut gizmos: Gizmos) {
    for (instance, transform) in &models {
        let affine = transform.affine();
        for (r, region) in instance.regions.regions().iter().enumerate() {
            let corners = instance.obbs[r].transformed(&affine).corners();
            let (lo, hi) = (region.min_triangles(), region.max_triangles());
            let t = if hi > lo {
                instance.caches.triangle_count(r).saturating_sub(lo) as f32 / (hi - lo) as f32
            } else {
                1.0
            };
            let color = Color::srgb(t, 0.2, 1.0 - t);
            for (a, b) in EDGES {
                gizmos.line(corners[a], corners[b], color);
            }
        }
    }
}
