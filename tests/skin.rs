//! Skinning core: weight validation, the rigid/deformable decomposition, shortest-path weights
//! and linear blend skinning.

mod common;

use bevy_aslod::mesh::{IndexedMesh, weld_positions};
use bevy_aslod::skin::*;
use common::sphere;
use glam::{Mat4, Quat, Vec3};
use proptest::prelude::*;

/// A small deterministic generator (xorshift64*), so the tests need no RNG crate.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
    fn below(&mut self, n: u32) -> u32 {
        (self.next() % u64::from(n)) as u32
    }
    fn vec3(&mut self) -> Vec3 {
        Vec3::new(
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
        )
    }
    /// A random rigid transform with a uniform scale.
    fn matrix(&mut self) -> Mat4 {
        let axis = self.vec3().try_normalize().unwrap_or(Vec3::Y);
        Mat4::from_scale_rotation_translation(
            Vec3::splat(self.range(0.5, 2.0)),
            Quat::from_axis_angle(axis, self.range(-3.0, 3.0)),
            self.vec3() * 5.0,
        )
    }
}

/// An open tube along +Y: `rings` rings of `segments` vertices, ring `r` at height `r`.
/// With `seam`, the first column is duplicated at the end (a UV seam: two vertices at one
/// position). Vertex `(r, s)` is `r * cols + s`.
fn tube(rings: u32, segments: u32, seam: bool) -> IndexedMesh {
    let cols = if seam { segments + 1 } else { segments };
    let mut positions = Vec::new();
    for r in 0..rings {
        for s in 0..cols {
            let theta = std::f32::consts::TAU * (s % segments) as f32 / segments as f32;
            positions.push(Vec3::new(theta.cos(), r as f32, theta.sin()));
        }
    }
    let at = |r: u32, s: u32| r * cols + if seam { s } else { s % segments };
    let mut indices = Vec::new();
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s), at(r + 1, s + 1));
            indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    IndexedMesh::new(positions, indices)
}

/// Kinds of a three-region painting: rigid on bone 2 (id 0), rigid on bone 5 (id 1), and
/// deformable between them (id 2).
const KINDS: [SkinRegionKind; 3] = [
    SkinRegionKind::Rigid { bone: 2 },
    SkinRegionKind::Rigid { bone: 5 },
    SkinRegionKind::Deformable { bones: [2, 5] },
];

/// Rings `0..a_end` rigid on bone 2, rings `b_start..` rigid on bone 5, the rest deformable.
fn paint_tube(mesh: &IndexedMesh, a_end: u32, b_start: u32) -> Vec<u32> {
    mesh.positions
        .iter()
        .map(|p| {
            let ring = p.y as u32;
            if ring < a_end {
                0
            } else if ring >= b_start {
                1
            } else {
                2
            }
        })
        .collect()
}

fn assert_influence_invariants(inf: &Influences, joint_count: usize, context: &str) {
    assert_eq!(inf.joints.len(), inf.weights.len(), "{context}");
    for (v, (j, w)) in inf.joints.iter().zip(&inf.weights).enumerate() {
        let sum: f32 = w.iter().sum();
        assert!(
            (sum - 1.0).abs() < 1e-5,
            "{context}: vertex {v} sums to {sum}"
        );
        for k in 0..4 {
            assert!((0.0..=1.0).contains(&w[k]), "{context}: vertex {v} {w:?}");
            if k > 0 {
                assert!(w[k - 1] >= w[k], "{context}: vertex {v} not sorted {w:?}");
            }
            if w[k] == 0.0 {
                assert_eq!(j[k], 0, "{context}: vertex {v} unused slot {j:?} {w:?}");
            } else {
                assert!(
                    usize::from(j[k]) < joint_count,
                    "{context}: vertex {v} {j:?}"
                );
                for m in 0..k {
                    assert_ne!(j[m], j[k], "{context}: vertex {v} duplicate joint {j:?}");
                }
            }
        }
        assert!(w[0] > 0.0, "{context}: vertex {v} has no weight");
    }
}

// --- Influences::new --------------------------------------------------------------------------

fn assert_close4(a: [f32; 4], b: [f32; 4], context: &str) {
    for k in 0..4 {
        assert!((a[k] - b[k]).abs() < 1e-6, "{context}: {a:?} != {b:?}");
    }
}

#[test]
fn influences_are_sorted_cleaned_merged_and_normalised() {
    let joints = [[1, 4, 9, 3], [2, 7, 0, 0], [3, 3, 1, 0], [0, 6, 0, 0]];
    let weights = [
        [0.1, 0.4, 0.0, 0.5],   // slot 2 unused with joint 9: cleared; three influences
        [0.2, 0.2, 0.0, 0.0],   // sums to 0.4: renormalised; the tie sorts by joint
        [0.25, 0.25, 0.5, 0.0], // joint 3 twice: merged, then tied with joint 1
        [1.0, -1e-7, 0.0, 0.0], // a tiny negative: clamped, its joint cleared
    ];
    let (inf, report) = Influences::new(&joints, &weights, 10).expect("valid");
    assert_eq!(inf.len(), 4);
    assert_eq!(inf.joints[0], [3, 4, 1, 0]);
    assert_close4(inf.weights[0], [0.5, 0.4, 0.1, 0.0], "vertex 0");
    assert_eq!(inf.joints[1], [2, 7, 0, 0]);
    assert_close4(inf.weights[1], [0.5, 0.5, 0.0, 0.0], "vertex 1");
    assert_eq!(inf.joints[2], [1, 3, 0, 0]);
    assert_close4(inf.weights[2], [0.5, 0.5, 0.0, 0.0], "vertex 2");
    assert_eq!(inf.joints[3], [0, 0, 0, 0]);
    assert_eq!(inf.weights[3], [1.0, 0.0, 0.0, 0.0]);
    assert_eq!(
        report,
        WeightReport {
            renormalised: 1,
            more_than_two: 1,
            unused_slots_cleared: 2,
            duplicate_joints_merged: 1,
        }
    );
    assert_influence_invariants(&inf, 10, "hand-made");
}

#[test]
fn bad_weights_give_the_named_error() {
    let one = [[1.0, 0.0, 0.0, 0.0]];
    assert_eq!(
        Influences::new(&[[0; 4]], &one, 0),
        Err(SkinError::NoJoints),
        "no joints"
    );
    assert_eq!(
        Influences::new(&[[0; 4], [0; 4]], &one, 1),
        Err(SkinError::LengthMismatch {
            what: "weights",
            expected: 2,
            found: 1
        })
    );
    let joints = [[0, 0, 0, 0], [0, 3, 0, 0]];
    let ok = [1.0, 0.0, 0.0, 0.0];
    let cases: [([f32; 4], SkinError); 5] = [
        (
            [0.5, -0.5, 0.0, 0.0],
            SkinError::NegativeWeight {
                vertex: 1,
                weight: -0.5,
            },
        ),
        (
            [0.5, f32::NAN, 0.0, 0.0],
            SkinError::NonFiniteWeight { vertex: 1, slot: 1 },
        ),
        (
            [f32::INFINITY, 0.0, 0.0, 0.0],
            SkinError::NonFiniteWeight { vertex: 1, slot: 0 },
        ),
        ([0.0; 4], SkinError::ZeroWeights { vertex: 1 }),
        (
            [0.5, 0.5, 0.0, 0.0],
            SkinError::JointOutOfRange {
                vertex: 1,
                joint: 3,
                joint_count: 3,
            },
        ),
    ];
    for (w, expected) in cases {
        let got = Influences::new(&joints, &[ok, w], 3);
        assert_eq!(got, Err(expected.clone()), "weights {w:?}");
        // The message names the vertex.
        assert!(expected.to_string().contains("vertex 1"), "{expected}");
    }
    // An out-of-range joint with zero weight is garbage in an unused slot, not an error.
    let (inf, report) = Influences::new(&joints, &[ok, [1.0, 0.0, 0.0, 0.0]], 3).expect("ok");
    assert_eq!(inf.joints[1], [0, 0, 0, 0]);
    assert_eq!(report.unused_slots_cleared, 1);
}

#[test]
fn huge_weights_do_not_overflow_the_sum() {
    let (inf, report) =
        Influences::new(&[[0, 1, 2, 3]], &[[f32::MAX; 4]], 4).expect("finite weights");
    assert_close4(inf.weights[0], [0.25; 4], "f32::MAX x 4");
    assert_eq!(report.renormalised, 1);
}

#[test]
fn empty_influences_are_fine() {
    let (inf, report) = Influences::new(&[], &[], 1).expect("empty");
    assert!(inf.is_empty());
    assert_eq!(report, WeightReport::default());
    let skin = decompose(&[], &inf, DEFAULT_RIGID_DELTA);
    assert!(skin.kinds.is_empty() && skin.region_of.is_empty());
}

// --- decompose --------------------------------------------------------------------------------

/// Random influences on `n` vertices over `joint_count` joints: a third single-bone, a third
/// two-bone, the rest three or four bones.
fn random_influences(rng: &mut Rng, n: usize, joint_count: u32) -> Influences {
    let mut joints = Vec::with_capacity(n);
    let mut weights = Vec::with_capacity(n);
    for _ in 0..n {
        let count = match rng.below(3) {
            0 => 1,
            1 => 2,
            _ => 3 + rng.below(2) as usize,
        };
        let mut j = [0u16; 4];
        let mut w = [0f32; 4];
        for k in 0..count {
            j[k] = rng.below(joint_count) as u16;
            w[k] = rng.range(0.05, 1.0);
        }
        joints.push(j);
        weights.push(w);
    }
    Influences::new(&joints, &weights, joint_count as usize)
        .expect("valid random weights")
        .0
}

#[test]
fn every_vertex_is_in_one_region_whose_kind_matches_its_weights() {
    let mesh = sphere(12, 16, &[0.0, 0.05, -0.03], false);
    let mut rng = Rng(0x5eed);
    let inf = random_influences(&mut rng, mesh.vertex_count(), 6);
    let skin = decompose(&mesh.positions, &inf, DEFAULT_RIGID_DELTA);
    assert_eq!(skin.region_of.len(), mesh.vertex_count());
    assert_eq!(skin.rigid.len(), mesh.vertex_count());
    assert!(
        skin.kinds.windows(2).all(|k| k[0] < k[1]),
        "kinds sorted and unique: {:?}",
        skin.kinds
    );
    assert!(
        skin.region_sizes().iter().all(|&s| s > 0),
        "no empty region"
    );
    let mut more = 0;
    for v in 0..mesh.vertex_count() {
        let (j, w) = (inf.joints[v], inf.weights[v]);
        let kind = skin.kinds[skin.region_of[v] as usize];
        let expected = if w[0] >= 1.0 - DEFAULT_RIGID_DELTA {
            SkinRegionKind::Rigid { bone: j[0] }
        } else {
            SkinRegionKind::Deformable {
                bones: [j[0].min(j[1]), j[0].max(j[1])],
            }
        };
        assert_eq!(kind, expected, "vertex {v}: {j:?} {w:?}");
        assert_eq!(skin.rigid[v], kind.is_rigid(), "vertex {v}");
        if w[2] > 0.0 {
            more += 1;
        }
    }
    assert!(more > 0, "the test covers three- and four-bone vertices");
    assert_eq!(skin.more_than_two, more);
}

#[test]
fn four_influence_vertices_join_their_two_largest() {
    let joints = [[7, 1, 3, 5], [2, 4, 6, 0]];
    let weights = [[0.1, 0.2, 0.3, 0.4], [0.3, 0.1, 0.6, 0.0]];
    let (inf, report) = Influences::new(&joints, &weights, 8).expect("valid");
    assert_eq!(report.more_than_two, 2);
    let skin = decompose(&[Vec3::X, Vec3::Y], &inf, DEFAULT_RIGID_DELTA);
    assert_eq!(skin.more_than_two, 2);
    assert_eq!(
        skin.kinds,
        [
            SkinRegionKind::Deformable { bones: [2, 6] },
            SkinRegionKind::Deformable { bones: [3, 5] },
        ]
    );
    assert_eq!(skin.region_of, [1, 0]);
    assert_eq!(skin.rigid, [false, false]);
}

#[test]
fn delta_is_clamped_and_separates_rigid_from_deformable() {
    let joints = [[0, 1, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]];
    let weights = [
        [0.999, 0.001, 0.0, 0.0],
        [0.6, 0.4, 0.0, 0.0],
        [1.0, 0.0, 0.0, 0.0],
    ];
    let (inf, _) = Influences::new(&joints, &weights, 2).expect("valid");
    let positions = [Vec3::X, Vec3::Y, Vec3::Z];
    let count_rigid = |delta: f32| {
        decompose(&positions, &inf, delta)
            .rigid
            .iter()
            .filter(|&&r| r)
            .count()
    };
    assert_eq!(count_rigid(DEFAULT_RIGID_DELTA), 1);
    assert_eq!(count_rigid(f32::NAN), 1, "NaN means the default");
    assert_eq!(count_rigid(-1.0), 1, "clamped to 0");
    assert_eq!(count_rigid(0.01), 2);
    assert_eq!(count_rigid(0.45), 3);
    assert_eq!(count_rigid(10.0), 3, "clamped to 0.5");
    let skin = decompose(&positions, &inf, 0.01);
    assert_eq!(
        skin.kinds[skin.region_of[0] as usize],
        SkinRegionKind::Rigid { bone: 0 }
    );
}

#[test]
fn seam_copies_share_their_region() {
    let mesh = sphere(8, 10, &[0.0], true);
    let weld = weld_positions(&mesh.positions);
    assert!(
        weld.unique < mesh.vertex_count(),
        "the sphere has seam copies"
    );
    // Weights by vertex index, so seam copies disagree.
    let mut rng = Rng(7);
    let inf = random_influences(&mut rng, mesh.vertex_count(), 5);
    let skin = decompose(&mesh.positions, &inf, 0.1);
    let mut disagreeing = 0;
    for v in 0..mesh.vertex_count() {
        let first = weld.remap[v] as usize;
        assert_eq!(skin.region_of[v], skin.region_of[first], "vertex {v}");
        assert_eq!(skin.rigid[v], skin.rigid[first], "vertex {v}");
        let own = decompose(
            &[mesh.positions[v]],
            &Influences {
                joints: vec![inf.joints[v]],
                weights: vec![inf.weights[v]],
            },
            0.1,
        );
        if own.kinds[0] != skin.kinds[skin.region_of[v] as usize] {
            disagreeing += 1;
        }
    }
    assert!(
        disagreeing > 0,
        "the test covers copies with different weights"
    );
}

#[test]
fn decompose_tolerates_mismatched_lengths() {
    let (inf, _) = Influences::new(&[[0; 4]; 3], &[[1.0, 0.0, 0.0, 0.0]; 3], 1).expect("ok");
    for positions in [&[][..], &[Vec3::X; 5][..]] {
        let skin = decompose(positions, &inf, DEFAULT_RIGID_DELTA);
        assert_eq!(skin.region_of, [0, 0, 0]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn garbage_weights_never_panic(
        rows in prop::collection::vec(
            (any::<[u16; 4]>(), prop::array::uniform4(prop_oneof![
                4 => 0.0f32..1.0,
                1 => Just(0.0f32),
                1 => any::<f32>(),
                1 => -1e-6f32..0.0,
            ])),
            0..40,
        ),
        joint_count in 0usize..8,
        small_joints in any::<bool>(),
        delta in any::<f32>(),
    ) {
        let joints: Vec<[u16; 4]> = rows
            .iter()
            .map(|(j, _)| if small_joints { j.map(|x| x % 9) } else { *j })
            .collect();
        let weights: Vec<[f32; 4]> = rows.iter().map(|(_, w)| *w).collect();
        match Influences::new(&joints, &weights, joint_count) {
            Ok((inf, report)) => {
                assert_influence_invariants(&inf, joint_count, "proptest");
                prop_assert!(report.more_than_two <= inf.len());
                let positions: Vec<Vec3> =
                    (0..inf.len()).map(|v| Vec3::splat((v % 5) as f32)).collect();
                let skin = decompose(&positions, &inf, delta);
                prop_assert_eq!(skin.region_of.len(), inf.len());
                for &r in &skin.region_of {
                    prop_assert!((r as usize) < skin.kinds.len());
                }
                let matrices = vec![Mat4::IDENTITY; joint_count];
                let all: Vec<u32> = (0..inf.len() as u32).collect();
                let mut out = vec![Vec3::ZERO; inf.len()];
                blend_with_rigid(&matrices, &positions, None, &inf, &skin.rigid, &all, &mut out, None);
                for (o, p) in out.iter().zip(&positions) {
                    prop_assert!(o.distance(*p) < 1e-4, "identity pose moves {p} to {o}");
                }
            }
            Err(e) => {
                // Every error names its defect in the message.
                prop_assert!(!e.to_string().is_empty());
            }
        }
    }
}

// --- shortest_path_weights --------------------------------------------------------------------

/// The weight of bone 5 (the far bone) for vertex `v`.
fn weight_of(inf: &Influences, v: usize, bone: u16) -> f32 {
    (0..4)
        .filter(|&k| inf.joints[v][k] == bone && inf.weights[v][k] > 0.0)
        .map(|k| inf.weights[v][k])
        .sum()
}

#[test]
fn shortest_path_weights_rise_ring_by_ring_from_a_to_b() {
    for seam in [false, true] {
        let mesh = tube(14, 12, seam);
        let region_of = paint_tube(&mesh, 4, 10);
        let inf = shortest_path_weights(&mesh, &region_of, &KINDS).expect("painted tube");
        assert_influence_invariants(&inf, 6, "tube");
        let mut ring_min = [f32::INFINITY; 14];
        let mut ring_max = [f32::NEG_INFINITY; 14];
        for (v, p) in mesh.positions.iter().enumerate() {
            let ring = p.y as usize;
            let s = weight_of(&inf, v, 5);
            assert!((0.0..=1.0).contains(&s));
            assert!((weight_of(&inf, v, 2) + s - 1.0).abs() < 1e-6, "vertex {v}");
            match region_of[v] {
                0 => assert_eq!(
                    (inf.joints[v], inf.weights[v]),
                    ([2, 0, 0, 0], [1.0, 0.0, 0.0, 0.0])
                ),
                1 => assert_eq!(
                    (inf.joints[v], inf.weights[v]),
                    ([5, 0, 0, 0], [1.0, 0.0, 0.0, 0.0])
                ),
                _ => assert!(s > 0.0 && s < 1.0, "vertex {v} inside D has s = {s}"),
            }
            ring_min[ring] = ring_min[ring].min(s);
            ring_max[ring] = ring_max[ring].max(s);
        }
        for r in 0..13 {
            if !(3..10).contains(&r) {
                assert_eq!(ring_min[r], ring_max[r], "rigid ring {r} is constant");
            } else {
                assert!(
                    ring_max[r] < ring_min[r + 1],
                    "seam {seam}: ring {r} ({}..{}) is not below ring {} ({}..{})",
                    ring_min[r],
                    ring_max[r],
                    r + 1,
                    ring_min[r + 1],
                    ring_max[r + 1]
                );
            }
        }
        // Rings 4..=9 are deformable; the borders are rings 3 and 10: ring 4 is 1/7 of the way.
        assert!((ring_min[4] - 1.0 / 7.0).abs() < 1e-5, "{}", ring_min[4]);
        assert!((ring_max[9] - 6.0 / 7.0).abs() < 1e-5, "{}", ring_max[9]);
        // Seam copies get the same weights.
        let weld = weld_positions(&mesh.positions);
        for v in 0..mesh.vertex_count() {
            let first = weld.remap[v] as usize;
            assert_eq!(inf.weights[v], inf.weights[first], "seam copy {v}");
        }
        // The output is already what Influences::new would make of it.
        let (again, report) = Influences::new(&inf.joints, &inf.weights, 6).expect("valid");
        assert_eq!(again.joints, inf.joints);
        assert_eq!(report.renormalised, 0);
    }
}

#[test]
fn shortest_path_weights_are_monotone_along_every_edge_towards_b() {
    // On the tube, every edge that climbs one ring inside D (or onto its border) raises s.
    let mesh = tube(12, 9, false);
    let region_of = paint_tube(&mesh, 3, 9);
    let inf = shortest_path_weights(&mesh, &region_of, &KINDS).expect("painted tube");
    for t in mesh.indices.chunks_exact(3) {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            let (pa, pb) = (mesh.positions[a], mesh.positions[b]);
            if pb.y > pa.y {
                assert!(
                    weight_of(&inf, b, 5) >= weight_of(&inf, a, 5),
                    "edge {a}->{b} goes up but s falls"
                );
            }
        }
    }
}

#[test]
fn shortest_path_fallbacks_and_errors() {
    let mesh = tube(6, 6, false);
    // D touches only bone 2's region: every vertex follows bone 2.
    let region_of: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| if p.y < 2.0 { 0 } else { 2 })
        .collect();
    let inf = shortest_path_weights(&mesh, &region_of, &KINDS).expect("one-sided");
    assert!(inf.joints.iter().all(|j| *j == [2, 0, 0, 0]));
    assert!(inf.weights.iter().all(|w| *w == [1.0, 0.0, 0.0, 0.0]));

    // D touches neither: named error.
    let only_d = vec![2u32; mesh.vertex_count()];
    assert_eq!(
        shortest_path_weights(&mesh, &only_d, &KINDS),
        Err(SkinError::NoRegionBorder {
            region: 2,
            vertex: 0
        })
    );
    // A deformable vertex no edge reaches.
    let mut lonely = mesh.clone();
    lonely.positions.push(Vec3::splat(9.0));
    let mut painted = paint_tube(&mesh, 2, 4);
    painted.push(2);
    assert!(matches!(
        shortest_path_weights(&lonely, &painted, &KINDS),
        Err(SkinError::NoRegionBorder { region: 2, vertex }) if vertex == mesh.vertex_count()
    ));

    let painted = paint_tube(&mesh, 2, 4);
    assert_eq!(
        shortest_path_weights(&mesh, &painted[1..], &KINDS),
        Err(SkinError::LengthMismatch {
            what: "region_of",
            expected: mesh.vertex_count(),
            found: mesh.vertex_count() - 1
        })
    );
    let mut bad_region = painted.clone();
    bad_region[7] = 3;
    assert_eq!(
        shortest_path_weights(&mesh, &bad_region, &KINDS),
        Err(SkinError::RegionOutOfRange {
            vertex: 7,
            region: 3,
            region_count: 3
        })
    );
    let mut bad_index = mesh.clone();
    bad_index.indices[4] = 1000;
    assert_eq!(
        shortest_path_weights(&bad_index, &painted, &KINDS),
        Err(SkinError::IndexOutOfRange {
            corner: 4,
            index: 1000,
            vertex_count: mesh.vertex_count()
        })
    );
    // Empty input: no vertices, no weights.
    let empty = shortest_path_weights(&IndexedMesh::default(), &[], &[]).expect("empty");
    assert!(empty.is_empty());
}

#[test]
fn shortest_path_weights_then_decompose_gives_back_the_painting() {
    let mesh = tube(10, 8, true);
    let region_of = paint_tube(&mesh, 3, 7);
    let inf = shortest_path_weights(&mesh, &region_of, &KINDS).expect("painted");
    let skin = decompose(&mesh.positions, &inf, DEFAULT_RIGID_DELTA);
    assert_eq!(skin.kinds, KINDS);
    assert_eq!(skin.region_of, region_of);
}

// --- blend ------------------------------------------------------------------------------------

/// The textbook formula, one influence at a time: the blended matrix on the position, its
/// inverse transpose on the normal (as Bevy's skinning shader), the normal normalised (`blend`
/// leaves its length to the shader).
fn naive(matrices: &[Mat4], p: Vec3, n: Vec3, j: [u16; 4], w: [f32; 4]) -> (Vec3, Vec3) {
    let mut pos = Vec3::ZERO;
    let mut blended = glam::Mat3::ZERO;
    for k in 0..4 {
        let m = matrices[j[k] as usize];
        pos += w[k] * m.transform_point3(p);
        blended += glam::Mat3::from_mat4(m) * w[k];
    }
    (pos, (blended.inverse().transpose() * n).normalize())
}

#[test]
fn blend_matches_the_naive_formula() {
    let mut rng = Rng(0xb1e4d);
    let matrices: Vec<Mat4> = (0..9).map(|_| rng.matrix()).collect();
    let n = 2000;
    let inf = random_influences(&mut rng, n, 9);
    let positions: Vec<Vec3> = (0..n).map(|_| rng.vec3() * 3.0).collect();
    let normals: Vec<Vec3> = (0..n).map(|_| rng.vec3().normalize()).collect();
    let all: Vec<u32> = (0..n as u32).collect();
    let mut out_p = vec![Vec3::ZERO; n];
    let mut out_n = vec![Vec3::ZERO; n];
    blend(
        &matrices,
        &positions,
        Some(&normals),
        &inf,
        &all,
        &mut out_p,
        Some(&mut out_n),
    );
    let mut four = 0;
    for v in 0..n {
        let (p, nor) = naive(
            &matrices,
            positions[v],
            normals[v],
            inf.joints[v],
            inf.weights[v],
        );
        assert!(
            out_p[v].distance(p) < 1e-4 * (1.0 + p.length()),
            "vertex {v}: {} vs {p}",
            out_p[v]
        );
        assert!(
            out_n[v].normalize().distance(nor) < 1e-4,
            "vertex {v}: {} vs {nor}",
            out_n[v].normalize()
        );
        assert_eq!(
            skin_position(
                &matrices,
                positions[v],
                inf.joints[v],
                inf.weights[v],
                false
            ),
            out_p[v],
            "skin_position agrees bit for bit"
        );
        assert_eq!(
            skin_normal(&matrices, normals[v], inf.joints[v], inf.weights[v], false),
            out_n[v]
        );
        four += usize::from(inf.weights[v][3] > 0.0);
    }
    assert!(four > 100, "the test covers four-influence vertices");

    // With tangents: the same positions and normals, and each tangent turned by the same
    // matrix as `skin_tangent` turns it, its handedness kept.
    let tangents: Vec<glam::Vec4> = (0..n)
        .map(|v| {
            rng.vec3()
                .normalize()
                .extend(if v % 2 == 0 { 1.0 } else { -1.0 })
        })
        .collect();
    let (mut tp, mut tn, mut tt) = (
        vec![Vec3::ZERO; n],
        vec![Vec3::ZERO; n],
        vec![[0.0f32; 4]; n],
    );
    bevy_aslod::skin::blend_with_tangents(
        &matrices,
        &positions,
        Some(&normals),
        &tangents,
        &inf,
        &all,
        &mut tp,
        Some(&mut tn),
        &mut tt,
    );
    assert_eq!((&tp, &tn), (&out_p, &out_n));
    for v in 0..n {
        let t = bevy_aslod::skin::skin_tangent(
            &matrices,
            tangents[v].truncate(),
            inf.joints[v],
            inf.weights[v],
            false,
        );
        assert_eq!(tt[v], [t.x, t.y, t.z, tangents[v].w], "vertex {v}");
    }

    // Without normals, positions are the same.
    let mut only_p = vec![Vec3::ZERO; n];
    blend(&matrices, &positions, None, &inf, &all, &mut only_p, None);
    assert_eq!(only_p, out_p);
}

#[test]
fn blending_a_subset_leaves_the_rest_untouched() {
    let mut rng = Rng(99);
    let matrices: Vec<Mat4> = (0..4).map(|_| rng.matrix()).collect();
    let n = 500;
    let inf = random_influences(&mut rng, n, 4);
    let positions: Vec<Vec3> = (0..n).map(|_| rng.vec3()).collect();
    let normals: Vec<Vec3> = (0..n).map(|_| rng.vec3().normalize()).collect();
    let subset: Vec<u32> = (0..n as u32).filter(|v| v % 3 == 1).collect();
    let sentinel = Vec3::splat(-123.0);
    let mut out_p = vec![sentinel; n];
    let mut out_n = vec![sentinel; n];
    blend(
        &matrices,
        &positions,
        Some(&normals),
        &inf,
        &subset,
        &mut out_p,
        Some(&mut out_n),
    );
    for v in 0..n {
        if v % 3 == 1 {
            assert_ne!(out_p[v], sentinel, "vertex {v} skinned");
            assert_ne!(out_n[v], sentinel, "vertex {v} skinned");
        } else {
            assert_eq!(out_p[v], sentinel, "vertex {v} untouched");
            assert_eq!(out_n[v], sentinel, "vertex {v} untouched");
        }
    }
}

#[test]
fn rigid_vertices_follow_their_dominant_bone_alone() {
    let mut rng = Rng(3);
    let matrices: Vec<Mat4> = (0..3).map(|_| rng.matrix()).collect();
    let joints = [[2, 0, 0, 0], [1, 2, 0, 0], [0, 1, 2, 0]];
    let weights = [
        [0.999_995, 0.000_005, 0.0, 0.0],
        [0.7, 0.3, 0.0, 0.0],
        [0.5, 0.3, 0.2, 0.0],
    ];
    let (inf, _) = Influences::new(&joints, &weights, 3).expect("valid");
    let positions = [Vec3::X, Vec3::Y, Vec3::Z];
    let rigid = [true, true, false];
    let mut out = [Vec3::ZERO; 3];
    blend_with_rigid(
        &matrices,
        &positions,
        None,
        &inf,
        &rigid,
        &[0, 1, 2],
        &mut out,
        None,
    );
    assert_eq!(out[0], matrices[2].transform_point3(positions[0]));
    assert_eq!(out[1], matrices[1].transform_point3(positions[1]));
    for v in 0..3 {
        assert_eq!(
            out[v],
            skin_position(
                &matrices,
                positions[v],
                inf.joints[v],
                inf.weights[v],
                rigid[v]
            ),
            "vertex {v}: blend_with_rigid and skin_position agree bit for bit"
        );
    }
    // A vertex past the end of `rigid` is blended.
    let mut short = [Vec3::ZERO; 3];
    blend_with_rigid(
        &matrices,
        &positions,
        None,
        &inf,
        &rigid[..2],
        &[2],
        &mut short,
        None,
    );
    assert_eq!(short[2], out[2]);
}

#[test]
fn identity_pose_leaves_the_mesh_in_place() {
    let mesh = tube(8, 8, true);
    let region_of = paint_tube(&mesh, 2, 6);
    let inf = shortest_path_weights(&mesh, &region_of, &KINDS).expect("painted");
    let matrices = vec![Mat4::IDENTITY; 6];
    let all: Vec<u32> = (0..mesh.vertex_count() as u32).collect();
    let mut out = vec![Vec3::ZERO; mesh.vertex_count()];
    blend(&matrices, &mesh.positions, None, &inf, &all, &mut out, None);
    for (o, p) in out.iter().zip(&mesh.positions) {
        assert!(o.distance(*p) < 1e-6);
    }
}
