//! The "aerobic class" routine of ASLOD section 7 as keyframes: arm raises, squats, side steps
//! and a turn, each a smooth bump that starts and ends in the bind pose, so the loop closes.

use super::skeleton::BoneDef;
use glam::{Quat, Vec3};
use std::f32::consts::PI;

/// The routine's phases, in seconds of a 6-second loop.
const ARM_RAISES: (f32, f32) = (0.0, 1.5);
const SQUATS: (f32, f32) = (1.5, 3.0);
const SIDE_STEPS: (f32, f32) = (3.0, 4.5);
const TURN: (f32, f32) = (4.5, 6.0);

/// `sin^2` over `[t0, t1]`, zero outside: rises from 0 to 1 and back with zero slope at both
/// ends, so consecutive bumps join smoothly.
fn bump(t: f32, t0: f32, t1: f32) -> f32 {
    if t <= t0 || t >= t1 {
        0.0
    } else {
        (PI * (t - t0) / (t1 - t0)).sin().powi(2)
    }
}

/// `count` equal bumps one after the other over `[t0, t1]`.
fn bumps(t: f32, (t0, t1): (f32, f32), count: usize) -> f32 {
    let len = (t1 - t0) / count as f32;
    (0..count)
        .map(|i| bump(t, t0 + i as f32 * len, t0 + (i + 1) as f32 * len))
        .sum()
}

/// The pose at one instant: local rotations (relative to the bind pose, where every joint's
/// rotation is the identity) and the root's offset from its bind position.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Pose {
    pub rotations: Vec<Quat>,
    pub root_offset: Vec3,
}

/// Per-side bone indices, looked up by name so the routine reads in anatomical terms.
struct Side {
    upper_arm: usize,
    forearm: usize,
    thigh: usize,
    shin: usize,
    /// +1 for the character's left (+X), -1 for its right.
    sign: f32,
}

fn index(bones: &[BoneDef], name: &str) -> usize {
    bones
        .iter()
        .position(|b| b.name == name)
        .unwrap_or_else(|| panic!("no bone {name}"))
}

/// The pose of the routine at time `t` (seconds, in `[0, duration)`) for a loop of
/// `duration` seconds; the routine's phases are scaled to fit.
pub(super) fn pose(bones: &[BoneDef], t: f32, duration: f32) -> Pose {
    let t = t.rem_euclid(duration) * 6.0 / duration;
    let chest = index(bones, "chest");
    let sides = [("L", 1.0), ("R", -1.0)].map(|(s, sign)| Side {
        upper_arm: index(bones, &format!("upper_arm_{s}")),
        forearm: index(bones, &format!("forearm_{s}")),
        thigh: index(bones, &format!("thigh_{s}")),
        shin: index(bones, &format!("shin_{s}")),
        sign,
    });
    let mut rotations = vec![Quat::IDENTITY; bones.len()];
    let mut root_offset = Vec3::ZERO;

    // Phase envelopes.
    let raise = bumps(t, ARM_RAISES, 2);
    let squat = bumps(t, SQUATS, 2);
    let steps = bump(t, SIDE_STEPS.0, SIDE_STEPS.1);
    let step_phase = ((t - SIDE_STEPS.0) / (SIDE_STEPS.1 - SIDE_STEPS.0)).clamp(0.0, 1.0);
    let pumps = bumps(t, SIDE_STEPS, 4);
    let turn = bump(t, TURN.0, TURN.1);
    let turn_bounce = bumps(t, TURN, 4);
    // A light knee bounce on every arm raise and every turn step.
    let bounce = 0.3 * raise + 0.35 * turn_bounce;

    // The side step: the pelvis sways left then right; the leg on the leading side lifts out.
    let sway = 0.12 * (2.0 * PI * step_phase).sin() * steps;
    root_offset.x += sway;
    // Chest: lean forward in the squats, twist and bend with the steps.
    rotations[chest] = Quat::from_rotation_x(0.35 * squat)
        * Quat::from_rotation_y(0.3 * (2.0 * PI * step_phase).sin() * steps)
        * Quat::from_rotation_z(-0.15 * (2.0 * PI * step_phase).sin() * steps);

    // Both legs flex alike in the squats and bounces; the pelvis drops and moves back so that
    // the ankles of a planar two-link leg stay put.
    let hip_flex = 1.0 * squat + 0.3 * bounce;
    let knee_flex = 1.45 * squat + 0.6 * bounce;
    let (drop, back) = {
        let [thigh, shin] =
            [sides[0].thigh, sides[0].shin].map(|b| (bones[b].end - bones[b].pivot).length());
        let shin_angle = hip_flex - knee_flex;
        (
            thigh * (1.0 - hip_flex.cos()) + shin * (1.0 - shin_angle.cos()),
            thigh * hip_flex.sin() + shin * shin_angle.sin(),
        )
    };
    for side in &sides {
        let s = side.sign;
        // Arms: sideways raise (about +Z for the left arm), forward raise (about -X), elbow
        // flexion about the axis that swings the forearm to the front.
        let lift_out = 2.2 * raise + 0.7 * pumps + 0.9 * turn;
        let lift_forward = 1.25 * squat + 0.4 * pumps;
        rotations[side.upper_arm] =
            Quat::from_rotation_z(s * lift_out) * Quat::from_rotation_x(-lift_forward);
        let d = bones[side.forearm].direction();
        let elbow_axis = d.cross(Vec3::Z).normalize();
        let elbow = 0.5 * raise + 0.25 * squat + 1.9 * pumps + 1.1 * turn;
        rotations[side.forearm] = Quat::from_axis_angle(elbow_axis, elbow);

        // Legs: the leading leg of each half of the side step lifts out to the side.
        let half = 0.5 * (SIDE_STEPS.1 - SIDE_STEPS.0);
        let leading = if s > 0.0 {
            bump(t, SIDE_STEPS.0, SIDE_STEPS.0 + half)
        } else {
            bump(t, SIDE_STEPS.0 + half, SIDE_STEPS.1)
        };
        rotations[side.thigh] =
            Quat::from_rotation_z(s * 0.4 * leading) * Quat::from_rotation_x(-hip_flex);
        rotations[side.shin] = Quat::from_rotation_x(knee_flex + 0.9 * leading);
    }
    root_offset.y -= drop;
    root_offset.z -= back;

    // The turn: half way round and back, about the vertical.
    let root = index(bones, "pelvis");
    rotations[root] = Quat::from_rotation_y(PI * turn);

    Pose {
        rotations,
        root_offset,
    }
}

/// Keyframe times: `rate` per second over `duration`, the last at `duration` exactly.
pub(super) fn key_times(duration: f32, rate: f32) -> Vec<f32> {
    let count = (duration * rate).round().max(1.0) as usize;
    (0..=count)
        .map(|i| duration * i as f32 / count as f32)
        .collect()
}
