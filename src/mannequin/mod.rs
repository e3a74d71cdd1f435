//! The procedural mannequin: a skinned, animated humanoid written as a `.glb`, standing in for
//! the laser-scanned mannequin of ASLOD section 7 (29,799 triangles, 19 regions: 10 rigid and
//! 9 deformable, dancing an "aerobic class" routine).
//!
//! The pipeline, in the order [`generate`] runs it:
//!
//! 1. **Body.** An implicit surface: capsules and ellipsoids around the bones, merged with a
//!    polynomial smooth minimum (torso, and each side's limbs into the torso), in an A-pose.
//! 2. **Polygonise.** Naive surface nets on a regular grid of
//!    [`cell_size`](MannequinOptions::cell_size): one vertex per crossed cell, one quad per
//!    crossed grid edge, split along the shorter diagonal. Before that, the few cells where a
//!    saddle of the surface crosses a cell ambiguously are mended by nudging the level set
//!    past their nearest corner, so the result is closed and manifold.
//! 3. **Smooth.** Taubin's λ|μ smoothing removes the grid's staircase without shrinking.
//! 4. **Regions.** Each vertex goes to the nearest bone's rigid region, or, near a joint, to
//!    that joint's deformable band (section 5.2's automatic "distance to a joint" criterion);
//!    the bands are then widened on the mesh wherever their two rigid sides come within
//!    three edges, so every band separates its rigid regions.
//! 5. **Weights.** [`shortest_path_weights`] (section 5.5): rigid vertices follow their bone,
//!    deformable ones blend by their shortest-path distances to the band's two borders.
//! 6. **Normalise.** Feet on `y = 0`, scaled to [`height`](MannequinOptions::height); normals
//!    from the triangles.
//! 7. **Animate.** A loop of arm raises, squats, side steps and a half turn and back, sampled
//!    into LINEAR keyframes: a rotation per joint, and the pelvis's translation.
//!
//! The skeleton has 10 bones, so that the regions match the paper's count: `pelvis` (the root,
//! which also carries the hips' translation), `chest` (which carries the neck and head),
//! `upper_arm_L/R`, `forearm_L/R` (with the hands), `thigh_L/R` and `shin_L/R` (with the
//! feet). The 9 deformable regions are the joints between them: the waist, shoulders, elbows,
//! hips and knees.
//!
//! Conventions: metres, right-handed, Y up, facing +Z, the character's left at +X. Everything
//! is deterministic: the same options give the same bytes.
//!
//! # Example
//! ```
//! use bevy_aslod::mannequin::{MannequinOptions, generate};
//!
//! // A coarse mannequin for a quick look; the default is the paper's ~30,000 triangles.
//! let options = MannequinOptions::default().with_cell_size(0.03);
//! let mannequin = generate(&options)?;
//! assert_eq!(mannequin.regions.len(), 19);
//! let glb = mannequin.to_glb();
//! assert_eq!(&glb[..4], b"glTF");
//! # Ok::<(), bevy_aslod::mannequin::MannequinError>(())
//! ```

mod animation;
mod glb;
mod regions;
mod skeleton;
mod surface;

use crate::mesh::IndexedMesh;
use crate::skin::{SkinError, SkinRegionKind, shortest_path_weights};
use glam::{Quat, UVec3, Vec3};
use skeleton::{BONES, Body};

/// How to generate the mannequin. The defaults give the paper's size; change a field with its
/// setter: `MannequinOptions::default().with_cell_size(0.02)`.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct MannequinOptions {
    /// Edge of the polygonising grid's cells, in metres of the design (a 1.75 m figure).
    /// Triangle count grows as the inverse square. Must be in `[0.005, 0.1]`.
    ///
    /// Default: `0.0126` (about 30,000 triangles).
    pub cell_size: f32,
    /// Taubin smoothing iterations (each a shrinking and an inflating step).
    ///
    /// Default: `12`.
    pub smoothing_iterations: usize,
    /// Height of the figure, feet on `y = 0` to the top of the head, in metres. Must be
    /// positive.
    ///
    /// Default: `1.75`.
    pub height: f32,
    /// Length of the animation loop in seconds; the routine's phases scale to it. Must be
    /// positive.
    ///
    /// Default: `6.0`.
    pub duration: f32,
    /// Keyframes per second. Must be positive.
    ///
    /// Default: `20.0`.
    pub keyframe_rate: f32,
}

with_setters!(MannequinOptions {
    cell_size: f32 => with_cell_size,
    smoothing_iterations: usize => with_smoothing_iterations,
    height: f32 => with_height,
    duration: f32 => with_duration,
    keyframe_rate: f32 => with_keyframe_rate,
});

impl Default for MannequinOptions {
    fn default() -> Self {
        Self {
            cell_size: 0.0126,
            smoothing_iterations: 12,
            height: 1.75,
            duration: 6.0,
            keyframe_rate: 20.0,
        }
    }
}

/// Why [`generate`] failed.
#[derive(Debug, thiserror::Error)]
pub enum MannequinError {
    /// An option is out of its range.
    #[error("invalid mannequin option {name} = {value}: {expected}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// The value given.
        value: f32,
        /// What it must be.
        expected: &'static str,
    },
    /// The sampled body could not be made into a manifold surface at this cell size (never
    /// seen; a slightly different `cell_size` avoids it).
    #[error("the polygonised body is not manifold at this cell size")]
    NotManifold,
    /// The shortest-path weights could not be computed (a region cut off from both its
    /// borders, which the default options never produce).
    #[error("skin weights: {0}")]
    Skin(#[from] SkinError),
}

/// One joint (bone) of the skeleton, in bind pose.
#[derive(Clone, Debug, PartialEq)]
pub struct MannequinJoint {
    /// The glTF node name, such as `upper_arm_L`.
    pub name: &'static str,
    /// The parent joint's index; `None` for the root (`pelvis`).
    pub parent: Option<usize>,
    /// Where the joint rotates, in world space (the model's frame) in bind pose.
    pub pivot: Vec3,
    /// The bind-pose translation relative to the parent's pivot (the glTF node's
    /// `translation`). Every bind rotation is the identity.
    pub translation: Vec3,
}

/// A keyframed skeleton animation, sampled at fixed times with LINEAR interpolation.
#[derive(Clone, Debug, PartialEq)]
pub struct MannequinAnimation {
    /// The animation's name (`Aerobics`).
    pub name: String,
    /// Key times in seconds, ascending, from 0 to the loop's length.
    pub times: Vec<f32>,
    /// Per joint, its local rotation at each key time. The first and last keys are equal, so
    /// the loop closes.
    pub rotations: Vec<Vec<Quat>>,
    /// The root's local translation at each key time (its bind translation plus the hips'
    /// sway, drop and shift).
    pub root_translations: Vec<Vec3>,
}

impl MannequinAnimation {
    /// The loop's length in seconds.
    #[must_use]
    pub fn duration(&self) -> f32 {
        self.times.last().copied().unwrap_or(0.0)
    }
}

/// A skin region: what it depends on and what it is called.
#[derive(Clone, Debug, PartialEq)]
pub struct MannequinRegion {
    /// `chest`, `elbow_L`, ...: the bone's name for a rigid region, the joint's for a
    /// deformable one.
    pub name: &'static str,
    /// The bone (rigid) or the two bones (deformable) the region follows.
    pub kind: SkinRegionKind,
}

/// The generated mannequin: a skinned mesh, its regions, skeleton and animation.
#[derive(Clone, Debug, PartialEq)]
pub struct Mannequin {
    /// The skin in bind pose, with normals, joints and weights (two bones at most per vertex,
    /// largest first, summing to 1).
    pub mesh: IndexedMesh,
    /// Per vertex, its region (an index into [`regions`](Self::regions)).
    pub region_of: Vec<u32>,
    /// The regions: the rigid region of bone `b` is region `b`; then the deformable regions,
    /// one per joint, in the order of their child bones.
    pub regions: Vec<MannequinRegion>,
    /// The skeleton, parents before children; joint `j` is the skin's joint `j`.
    pub joints: Vec<MannequinJoint>,
    /// The "Aerobics" loop.
    pub animation: MannequinAnimation,
}

impl Mannequin {
    /// The mannequin as binary glTF 2.0: one mesh with one primitive (`POSITION`, `NORMAL`,
    /// `JOINTS_0` as unsigned shorts, `WEIGHTS_0`, the region id as the float attribute
    /// `_REGION`, `u32` indices), a PBR material, a skin with inverse bind matrices, a scene
    /// holding the skeleton's root and, beside it, the mesh's node, and the animation.
    ///
    /// Deterministic: the same mannequin always gives the same bytes.
    #[must_use]
    pub fn to_glb(&self) -> Vec<u8> {
        glb::write(self)
    }
}

/// The deformable band of the joint between `child` and its parent.
fn band(child: &skeleton::BoneDef) -> regions::Band {
    let (before, after, radius) = match child.name.trim_end_matches(['L', 'R']) {
        "chest" => (0.03, 0.05, 0.35),
        "upper_arm_" => (0.045, 0.09, 0.15),
        "forearm_" => (0.045, 0.045, 0.1),
        "thigh_" => (0.035, 0.08, 0.19),
        "shin_" => (0.045, 0.045, 0.11),
        _ => (0.04, 0.04, 0.1),
    };
    // The groin: a ball below the hip joint, a little towards the middle, takes in the crotch.
    let extra = child.name.starts_with("thigh_").then(|| {
        let inward = -child.pivot.x.signum();
        (child.pivot + Vec3::new(0.015 * inward, -0.09, 0.0), 0.12)
    });
    regions::Band {
        before,
        after,
        radius,
        extra,
    }
}

/// The deformable region's name, by its child bone.
fn joint_name(child: &str) -> &'static str {
    match child {
        "chest" => "waist",
        "upper_arm_L" => "shoulder_L",
        "upper_arm_R" => "shoulder_R",
        "forearm_L" => "elbow_L",
        "forearm_R" => "elbow_R",
        "thigh_L" => "hip_L",
        "thigh_R" => "hip_R",
        "shin_L" => "knee_L",
        "shin_R" => "knee_R",
        _ => "joint",
    }
}

fn check(
    name: &'static str,
    value: f32,
    ok: bool,
    expected: &'static str,
) -> Result<(), MannequinError> {
    if ok {
        Ok(())
    } else {
        Err(MannequinError::InvalidOption {
            name,
            value,
            expected,
        })
    }
}

/// Generates the mannequin; see the [module documentation](self) for the steps.
///
/// Takes about a second at the default size in an optimised build.
///
/// # Errors
/// - [`MannequinError::InvalidOption`] for an option out of its documented range;
/// - [`MannequinError::NotManifold`] if the polygoniser cannot mend an ambiguous cell;
/// - [`MannequinError::Skin`] if the shortest-path weights fail, which the tests show the
///   default options never do.
pub fn generate(options: &MannequinOptions) -> Result<Mannequin, MannequinError> {
    let o = options;
    check(
        "cell_size",
        o.cell_size,
        (0.005..=0.1).contains(&o.cell_size),
        "in [0.005, 0.1]",
    )?;
    check(
        "height",
        o.height,
        o.height > 0.0 && o.height.is_finite(),
        "positive",
    )?;
    check(
        "duration",
        o.duration,
        o.duration > 0.0 && o.duration.is_finite(),
        "positive",
    )?;
    check(
        "keyframe_rate",
        o.keyframe_rate,
        o.keyframe_rate > 0.0 && o.keyframe_rate * o.duration <= 1e5,
        "positive, at most 100,000 keys",
    )?;

    // 1-3: the body, polygonised and smoothed, in the design frame.
    let body = Body::new();
    let (lo, hi) = (Vec3::new(-0.72, -0.06, -0.22), Vec3::new(0.72, 1.82, 0.26));
    let dims = ((hi - lo) / o.cell_size).ceil().as_uvec3() + UVec3::ONE;
    // Centre the grid on x = 0 so both sides are sampled alike.
    let origin = Vec3::new(-0.5 * (dims.x - 1) as f32 * o.cell_size, lo.y, lo.z);
    let mut grid = surface::Grid::sample(origin, o.cell_size, dims, |p| body.distance(p));
    grid.make_manifold().ok_or(MannequinError::NotManifold)?;
    let (mut positions, indices) = surface::surface_nets(&grid);
    let adjacency = surface::Adjacency::new(positions.len(), &indices);
    surface::taubin(&mut positions, &adjacency, o.smoothing_iterations);

    // 4: regions.
    let bands: Vec<regions::Band> = BONES.iter().map(band).collect();
    let region_of = regions::assign(&positions, &adjacency, &BONES, &bands);
    let mut region_list: Vec<MannequinRegion> = BONES
        .iter()
        .enumerate()
        .map(|(b, bone)| MannequinRegion {
            name: bone.name,
            kind: SkinRegionKind::Rigid { bone: b as u16 },
        })
        .collect();
    for (c, bone) in BONES.iter().enumerate().skip(1) {
        let parent = bone.parent.expect("only the root has no parent");
        region_list.push(MannequinRegion {
            name: joint_name(bone.name),
            kind: SkinRegionKind::Deformable {
                bones: [parent as u16, c as u16],
            },
        });
    }

    // 6: normalise (feet on the floor, the requested height), then normals.
    let (min_y, max_y) = positions
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), p| {
            (a.min(p.y), b.max(p.y))
        });
    let scale = o.height / (max_y - min_y);
    let place = |p: Vec3| (p - Vec3::new(0.0, min_y, 0.0)) * scale;
    for p in &mut positions {
        *p = place(*p);
    }
    let normals = surface::vertex_normals(&positions, &indices);
    let mut mesh = IndexedMesh::new(positions, indices);
    mesh.normals = Some(normals);

    // 5: weights.
    let kinds: Vec<SkinRegionKind> = region_list.iter().map(|r| r.kind).collect();
    let influences = shortest_path_weights(&mesh, &region_of, &kinds)?;
    mesh.joints = Some(influences.joints);
    mesh.weights = Some(influences.weights);

    let joints: Vec<MannequinJoint> = BONES
        .iter()
        .map(|b| {
            let pivot = place(b.pivot);
            MannequinJoint {
                name: b.name,
                parent: b.parent,
                pivot,
                translation: pivot - b.parent.map_or(Vec3::ZERO, |p| place(BONES[p].pivot)),
            }
        })
        .collect();

    // 7: the animation. Offsets scale with the figure.
    let times = animation::key_times(o.duration, o.keyframe_rate);
    let poses: Vec<animation::Pose> = times
        .iter()
        .map(|&t| animation::pose(&BONES, t, o.duration))
        .collect();
    let rotations = (0..BONES.len())
        .map(|j| poses.iter().map(|p| p.rotations[j]).collect())
        .collect();
    let root_translations = poses
        .iter()
        .map(|p| joints[0].translation + p.root_offset * scale)
        .collect();

    Ok(Mannequin {
        mesh,
        region_of,
        regions: region_list,
        joints,
        animation: MannequinAnimation {
            name: "Aerobics".to_string(),
            times,
            rotations,
            root_translations,
        },
    })
}
