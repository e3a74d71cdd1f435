//! The debug overlay (ASLOD Figure 10): every region's world box, drawn with gizmos, and its
//! triangle count as a screen-space label; and a status line with the budget, and under a
//! frame-time target the target, the measured frame time and the controller's state.

use super::components::{AslodOverlay, AslodStats};
use super::instance::MultiresInstance;
use super::sets::AslodSystems;
use super::view_dependent::ViewDependentState;
use crate::bounds::Obb;
use crate::budget::ControllerState;
#[cfg(feature = "ui")]
use bevy::camera::Camera;
use bevy::gizmos::config::GizmoConfigStore;
use bevy::prelude::*;

/// The most labels shown at once (the nearest regions win), so a crowd stays readable.
pub const MAX_OVERLAY_LABELS: usize = 256;

/// Adds the overlay systems when gizmos are available (so headless apps without them work):
/// the boxes, and with the crate's `ui` feature the labels and the status line.
pub(super) fn add_if_gizmos(app: &mut App) {
    if !app.world().contains_resource::<GizmoConfigStore>() {
        return;
    }
    app.add_systems(
        PostUpdate,
        draw_overlay
            .after(AslodSystems::Upload)
            .run_if(|overlay: Res<AslodOverlay>| overlay.0),
    );
    #[cfg(feature = "ui")]
    app.add_systems(
        PostUpdate,
        (place_labels, show_status)
            .after(AslodSystems::Upload)
            .run_if(|overlay: Res<AslodOverlay>| overlay.0),
    )
    .add_systems(
        PostUpdate,
        hide_labels.run_if(|overlay: Res<AslodOverlay>| !overlay.0),
    );
}

/// A UI text node of the overlay that shows one region's triangle count (with the crate's
/// `ui` feature).
#[derive(Component, Reflect, Debug, Default)]
#[reflect(Component, Default)]
pub struct OverlayLabel;

/// The overlay's status line (top right, with the crate's `ui` feature): [`status_line`] of
/// the frame's [`AslodStats`].
#[derive(Component, Reflect, Debug, Default)]
#[reflect(Component, Default)]
pub struct OverlayStatus;

/// The overlay's status line: `P` and the triangles drawn, and under a frame-time target
/// ([`PolygonBudget::frame_target`](super::PolygonBudget::frame_target)) the target, the
/// smoothed frame time the controller measured and what it is doing.
///
/// ```
/// use bevy_aslod::plugin::{AslodStats, status_line};
///
/// let stats = AslodStats { budget: 20_000, triangles: 19_870, ..Default::default() };
/// assert_eq!(status_line(&stats), "P 20000 · 19870 triangles");
/// ```
pub fn status_line(stats: &AslodStats) -> String {
    let mut line = format!("P {} · {} triangles", stats.budget, stats.triangles);
    if stats.target_ms > 0.0 {
        let state = match stats.controller {
            ControllerState::Waiting => "waiting",
            ControllerState::Settling => "settling",
            ControllerState::Steady => "steady",
            ControllerState::AtMinimum => "at its smallest P",
            ControllerState::AtMaximum => "at its largest P",
        };
        line += &format!(
            " · target {:.1} ms · frame {:.1} ms · {state}",
            stats.target_ms, stats.frame_ms
        );
    }
    line
}

#[cfg(feature = "ui")]
/// Writes the status line into its text node (made on first use).
fn show_status(
    mut commands: Commands,
    stats: Res<AslodStats>,
    mut status: Query<(&mut Text, &mut Visibility), With<OverlayStatus>>,
) {
    let line = status_line(&stats);
    match status.single_mut() {
        Ok((mut text, mut visibility)) => {
            if text.0 != line {
                text.0 = line;
            }
            visibility.set_if_neq(Visibility::Inherited);
        }
        Err(_) => {
            commands.spawn((
                Text(line),
                Node {
                    position_type: PositionType::Absolute,
                    right: Val::Px(8.0),
                    top: Val::Px(8.0),
                    ..default()
                },
                TextFont::from_font_size(14.0),
                TextColor(Color::srgb(1.0, 1.0, 0.3)),
                OverlayStatus,
            ));
        }
    }
}

/// The 12 edges of a box, as corner pairs in [`Obb::corner`](crate::bounds::Obb::corner)'s
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

/// What the overlay reads of a model.
type ModelItem<'a> = (
    &'a MultiresInstance,
    &'a GlobalTransform,
    Option<&'a ViewDependentState>,
);

/// Every region's world box and how far its level is between coarsest (0) and full (1); for
/// a view-dependent model, its bounds and its variable-resolution level.
fn region_boxes<'a>(
    (instance, transform, view): ModelItem<'a>,
) -> impl Iterator<Item = (Obb, f32, usize)> + 'a {
    let affine = transform.affine();
    let skinned = instance.skinned_world_boxes();
    let level = view.map(|view| {
        let pm = view.mesh().mesh();
        let (lo, hi, count) = (pm.min_triangles(), pm.max_triangles(), view.shown_count());
        let t = if hi > lo {
            count.saturating_sub(lo) as f32 / (hi - lo) as f32
        } else {
            1.0
        };
        (instance.bounds.transformed(&affine), t, count)
    });
    let regions = if level.is_some() {
        &[][..]
    } else {
        instance.regions.regions()
    };
    regions
        .iter()
        .enumerate()
        .map(move |(r, region)| {
            // Skinned boxes are already in world space, moved with their bones.
            let obb = match skinned.and_then(|boxes| boxes.get(r)) {
                Some(obb) => *obb,
                None => instance.obbs[r].transformed(&affine),
            };
            let (lo, hi) = (region.min_triangles(), region.max_triangles());
            let count = instance.caches.triangle_count(r);
            let t = if hi > lo {
                count.saturating_sub(lo) as f32 / (hi - lo) as f32
            } else {
                1.0
            };
            (obb, t, count)
        })
        .chain(level)
}

/// Draws each region's world box, blue at its coarsest level to red at full detail.
fn draw_overlay(models: Query<ModelItem<'static>>, mut gizmos: Gizmos) {
    for model in &models {
        for (obb, t, _) in region_boxes(model) {
            let corners = obb.corners();
            let color = Color::srgb(t, 0.2, 1.0 - t);
            for (a, b) in EDGES {
                gizmos.line(corners[a], corners[b], color);
            }
        }
    }
}

#[cfg(feature = "ui")]
/// Puts a label with the triangle count at the centre of each region's box, as seen by the
/// first active camera; the nearest [`MAX_OVERLAY_LABELS`] regions whose centre is in its
/// viewport get one.
fn place_labels(
    mut commands: Commands,
    models: Query<ModelItem<'static>>,
    cameras: Query<(&Camera, &GlobalTransform)>,
    mut labels: Query<(&mut Text, &mut Node, &mut Visibility), With<OverlayLabel>>,
    mut wanted: Local<Vec<(f32, Vec2, usize)>>,
) {
    wanted.clear();
    let Some((camera, eye)) = cameras.iter().find(|(c, _)| c.is_active) else {
        return;
    };
    let viewport = camera.logical_viewport_rect();
    for model in &models {
        for (obb, _, count) in region_boxes(model) {
            // `world_to_viewport` only rejects points behind the camera or past its far plane.
            let Ok(pixel) = camera.world_to_viewport(eye, obb.center) else {
                continue;
            };
            if viewport.is_some_and(|rect| !rect.contains(pixel)) {
                continue;
            }
            wanted.push((eye.translation().distance(obb.center), pixel, count));
        }
    }
    wanted.sort_by(|a, b| a.0.total_cmp(&b.0));
    wanted.truncate(MAX_OVERLAY_LABELS);
    let mut next = wanted.iter();
    for (text, node, mut visibility) in &mut labels {
        match next.next() {
            Some(&(_, pixel, count)) => {
                set_label(text, node, pixel, count);
                visibility.set_if_neq(Visibility::Inherited);
            }
            None => {
                visibility.set_if_neq(Visibility::Hidden);
            }
        }
    }
    for &(_, pixel, count) in next {
        commands.spawn((
            Text(count.to_string()),
            Node {
                position_type: PositionType::Absolute,
                left: Val::Px(pixel.x),
                top: Val::Px(pixel.y),
                ..default()
            },
            TextFont::from_font_size(11.0),
            TextColor(Color::srgb(1.0, 1.0, 0.3)),
            OverlayLabel,
        ));
    }
}

#[cfg(feature = "ui")]
/// Moves and rewrites a label, touching (and so re-laying out) only what changed.
fn set_label(mut text: Mut<Text>, mut node: Mut<Node>, pixel: Vec2, count: usize) {
    let (left, top) = (Val::Px(pixel.x), Val::Px(pixel.y));
    if node.left != left || node.top != top {
        node.left = left;
        node.top = top;
    }
    let label = count.to_string();
    if text.0 != label {
        text.0 = label;
    }
}

#[cfg(feature = "ui")]
/// The overlay's text nodes: the labels and the status line.
type OverlayText = Or<(With<OverlayLabel>, With<OverlayStatus>)>;

#[cfg(feature = "ui")]
/// Hides the labels and the status line while the overlay is off.
fn hide_labels(mut labels: Query<&mut Visibility, OverlayText>) {
    for mut visibility in &mut labels {
        visibility.set_if_neq(Visibility::Hidden);
    }
}
