//! The mannequin's bones and the blended primitives that model its body around them.
//!
//! Everything here is in the *design frame*: metres, Y up, facing +Z, the character's left at
//! +X, in an A-pose (arms 35 degrees from vertical, legs slightly apart). The generator
//! normalises the polygonised surface afterwards (feet on `y = 0`, a chosen height) and moves
//! the joints with it.

use glam::{Mat3, Vec3};

/// The bones, in skin-joint order (also the glTF node order). A parent always comes before its
/// children, so a deformable region's bone pair `[parent, child]` is ascending.
pub(super) const BONES: [BoneDef; 10] = [
    BoneDef::new("pelvis", None, [0.0, 0.95, -0.01], [0.0, 1.03, -0.01], 0.13),
    BoneDef::new("chest", Some(0), [0.0, 1.10, -0.01], [0.0, 1.70, 0.0], 0.12),
    BoneDef::new("upper_arm_L", Some(1), SHOULDER_L, ELBOW_L, 0.045),
    BoneDef::new(
        "upper_arm_R",
        Some(1),
        mirror(SHOULDER_L),
        mirror(ELBOW_L),
        0.045,
    ),
    BoneDef::new("forearm_L", Some(2), ELBOW_L, HAND_END_L, 0.032),
    BoneDef::new(
        "forearm_R",
        Some(3),
        mirror(ELBOW_L),
        mirror(HAND_END_L),
        0.032,
    ),
    BoneDef::new("thigh_L", Some(0), HIP_L, KNEE_L, 0.07),
    BoneDef::new("thigh_R", Some(0), mirror(HIP_L), mirror(KNEE_L), 0.07),
    BoneDef::new("shin_L", Some(6), KNEE_L, ANKLE_L, 0.045),
    BoneDef::new("shin_R", Some(7), mirror(KNEE_L), mirror(ANKLE_L), 0.045),
];

const SHOULDER_L: [f32; 3] = [0.185, 1.43, -0.015];
const UPPER_ARM_LENGTH: f32 = 0.29;
const FOREARM_LENGTH: f32 = 0.26;
const HAND_LENGTH: f32 = 0.18;
const ELBOW_L: [f32; 3] = along(SHOULDER_L, UPPER_ARM_LENGTH);
const WRIST_L: [f32; 3] = along(ELBOW_L, FOREARM_LENGTH);
const HAND_END_L: [f32; 3] = along(WRIST_L, HAND_LENGTH);
const HIP_L: [f32; 3] = [0.1, 0.93, 0.0];
const KNEE_L: [f32; 3] = [0.125, 0.5, 0.015];
const ANKLE_L: [f32; 3] = [0.13, 0.085, -0.01];

/// The sine and cosine of 35 degrees, how far the arms hang out from vertical in the bind pose
/// (an A-pose keeps them clear of the torso, so the polygoniser never sees a gap narrower than
/// a cell). Constants, because const fns cannot call `sin`.
const ARM_SIN: f32 = 0.573_576_4;
const ARM_COS: f32 = 0.819_152_04;

const fn along(p: [f32; 3], length: f32) -> [f32; 3] {
    [p[0] + ARM_SIN * length, p[1] - ARM_COS * length, p[2]]
}

const fn mirror(p: [f32; 3]) -> [f32; 3] {
    [-p[0], p[1], p[2]]
}

/// One bone: its pivot (where it rotates, the joint with its parent), the end of its segment
/// and a typical flesh radius, used to decide which bone a skin vertex is nearest to.
#[derive(Clone, Copy, Debug)]
pub(super) struct BoneDef {
    pub name: &'static str,
    pub parent: Option<usize>,
    pub pivot: Vec3,
    pub end: Vec3,
    pub radius: f32,
}

impl BoneDef {
    const fn new(
        name: &'static str,
        parent: Option<usize>,
        pivot: [f32; 3],
        end: [f32; 3],
        radius: f32,
    ) -> Self {
        Self {
            name,
            parent,
            pivot: Vec3::from_array(pivot),
            end: Vec3::from_array(end),
            radius,
        }
    }

    /// Distance from `p` to the bone's segment, less its flesh radius.
    pub fn surface_distance(&self, p: Vec3) -> f32 {
        let ab = self.end - self.pivot;
        let t = ((p - self.pivot).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
        (p - (self.pivot + t * ab)).length() - self.radius
    }

    /// Unit direction from the pivot to the end of the segment.
    pub fn direction(&self) -> Vec3 {
        (self.end - self.pivot).normalize()
    }
}

/// A primitive of the implicit body: negative inside.
#[derive(Clone, Copy, Debug)]
enum Shape {
    /// A capsule whose radius runs linearly from `ra` at `a` to `rb` at `b` (a cone-sphere
    /// approximation, smooth enough for polygonising).
    Capsule { a: Vec3, b: Vec3, ra: f32, rb: f32 },
    /// An ellipsoid with orthonormal `axes` (columns) and semi-axis `radii` along them.
    Ellipsoid {
        center: Vec3,
        axes: Mat3,
        radii: Vec3,
    },
}

impl Shape {
    fn capsule(a: [f32; 3], b: [f32; 3], ra: f32, rb: f32) -> Self {
        Self::Capsule {
            a: Vec3::from_array(a),
            b: Vec3::from_array(b),
            ra,
            rb,
        }
    }

    fn ellipsoid(center: [f32; 3], radii: [f32; 3]) -> Self {
        Self::Ellipsoid {
            center: Vec3::from_array(center),
            axes: Mat3::IDENTITY,
            radii: Vec3::from_array(radii),
        }
    }

    fn mirrored(self) -> Self {
        let m = |v: Vec3| Vec3::new(-v.x, v.y, v.z);
        match self {
            Self::Capsule { a, b, ra, rb } => Self::Capsule {
                a: m(a),
                b: m(b),
                ra,
                rb,
            },
            Self::Ellipsoid {
                center,
                axes,
                radii,
            } => Self::Ellipsoid {
                center: m(center),
                axes: Mat3::from_cols(m(axes.x_axis), m(axes.y_axis), m(axes.z_axis)),
                radii,
            },
        }
    }

    fn distance(&self, p: Vec3) -> f32 {
        match *self {
            Self::Capsule { a, b, ra, rb } => {
                let ab = b - a;
                let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
                (p - (a + t * ab)).length() - (ra + (rb - ra) * t)
            }
            Self::Ellipsoid {
                center,
                axes,
                radii,
            } => {
                // Inigo Quilez's bound: exact on the surface, a good gradient near it.
                let q = axes.transpose() * (p - center);
                let k0 = (q / radii).length();
                let k1 = (q / (radii * radii)).length();
                if k1 == 0.0 {
                    -radii.min_element()
                } else {
                    k0 * (k0 - 1.0) / k1
                }
            }
        }
    }
}

/// Polynomial smooth minimum: blends two distances over a width `k`.
fn smin(a: f32, b: f32, k: f32) -> f32 {
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

/// The implicit body: the torso blended with each side's limbs.
pub(super) struct Body {
    torso: Vec<(Shape, f32)>,
    left: Vec<(Shape, f32)>,
    right: Vec<(Shape, f32)>,
}

/// How softly the limbs of each side merge into the torso.
const LIMB_TO_TORSO_BLEND: f32 = 0.05;

impl Body {
    pub fn new() -> Self {
        let torso = vec![
            (
                Shape::ellipsoid([0.0, 0.93, -0.01], [0.165, 0.13, 0.115]),
                0.0,
            ),
            (
                Shape::ellipsoid([0.0, 1.1, 0.0], [0.145, 0.16, 0.105]),
                0.07,
            ),
            (
                Shape::ellipsoid([0.0, 1.29, 0.0], [0.165, 0.17, 0.11]),
                0.07,
            ),
            (
                Shape::ellipsoid([0.075, 0.9, -0.05], [0.085, 0.1, 0.085]),
                0.04,
            ),
            (
                Shape::ellipsoid([-0.075, 0.9, -0.05], [0.085, 0.1, 0.085]),
                0.04,
            ),
            // The shoulder girdle, a little behind the chest's centre.
            (
                Shape::capsule([-0.14, 1.41, -0.02], [0.14, 1.41, -0.02], 0.06, 0.06),
                0.06,
            ),
            (
                Shape::capsule([0.0, 1.4, -0.01], [0.0, 1.58, 0.0], 0.052, 0.05),
                0.04,
            ),
            (
                Shape::ellipsoid([0.0, 1.655, 0.01], [0.078, 0.105, 0.095]),
                0.04,
            ),
            // The jaw, so that the face shows where the front is.
            (
                Shape::ellipsoid([0.0, 1.595, 0.035], [0.06, 0.055, 0.06]),
                0.04,
            ),
        ];
        let d = Vec3::new(ARM_SIN, -ARM_COS, 0.0);
        let thin = Vec3::new(ARM_COS, ARM_SIN, 0.0);
        let hand_center = Vec3::from_array(WRIST_L) + 0.085 * d;
        let left = vec![
            (Shape::capsule(SHOULDER_L, ELBOW_L, 0.053, 0.039), 0.0),
            (Shape::capsule(ELBOW_L, WRIST_L, 0.04, 0.027), 0.025),
            (
                Shape::Ellipsoid {
                    center: hand_center,
                    axes: Mat3::from_cols(thin, d, Vec3::Z),
                    radii: Vec3::new(0.022, 0.09, 0.045),
                },
                0.025,
            ),
            (Shape::capsule(HIP_L, KNEE_L, 0.082, 0.052), 0.0),
            (Shape::capsule(KNEE_L, ANKLE_L, 0.05, 0.033), 0.025),
            (
                Shape::ellipsoid([0.122, 0.35, -0.025], [0.047, 0.1, 0.05]),
                0.03,
            ),
            (
                Shape::ellipsoid([0.132, 0.04, 0.05], [0.045, 0.04, 0.125]),
                0.03,
            ),
        ];
        let right = left.iter().map(|&(s, k)| (s.mirrored(), k)).collect();
        Self { torso, left, right }
    }

    /// Signed distance (approximately) from `p` to the skin: negative inside.
    pub fn distance(&self, p: Vec3) -> f32 {
        let torso = blend(&self.torso, p);
        // The two sides meet the torso but never each other, so no web grows between the legs.
        let limbs = blend(&self.left, p).min(blend(&self.right, p));
        smin(torso, limbs, LIMB_TO_TORSO_BLEND)
    }
}

/// The shapes merged in order, each with its own blend width (0: a hard union).
fn blend(shapes: &[(Shape, f32)], p: Vec3) -> f32 {
    shapes.iter().fold(f32::INFINITY, |acc, &(shape, k)| {
        let d = shape.distance(p);
        if k > 0.0 { smin(acc, d, k) } else { acc.min(d) }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arm_constants_match_the_angle() {
        let a = 35f32.to_radians();
        assert!((a.sin() - ARM_SIN).abs() < 1e-6);
        assert!((a.cos() - ARM_COS).abs() < 1e-6);
    }

    #[test]
    fn parents_come_first() {
        for (i, b) in BONES.iter().enumerate() {
            assert!(b.parent.is_none_or(|p| p < i), "{}", b.name);
        }
    }
}
