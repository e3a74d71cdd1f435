//! Variable-resolution levels (`refine`): over random cameras, tolerances and criteria, on the
//! test meshes and the mannequin, every level is crack-free and never folds a triangle; a
//! uniform cut is the polygon cache's level; an incremental update lands where a fresh
//! extraction does; and with nothing to drop, the mesh stays whole.

mod common;

use bevy_aslod::mesh::{IndexedMesh, weld_positions};
use bevy_aslod::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
use bevy_aslod::refine::{
    Criteria, Criterion, Illumination, LevelCut, Node, RefineError, ScreenSpaceError,
    SphereOfInterest, ToleranceSearch, VariableCache, VariableMesh, View, extract,
};
use common::{assert_closed, config, grid, normal, testdata_mesh, triangle_multiset};
use glam::Vec3;
use proptest::prelude::*;
use std::collections::HashMap;
use std::sync::OnceLock;

/// A test mesh with its variable mesh, built once per test binary.
struct Subject {
    mesh: IndexedMesh,
    vm: VariableMesh,
    closed: bool,
    /// Built with the topology compromise: a part folds flat before it vanishes, so its last
    /// triangles face away from their full-detail sides.
    folds: bool,
    /// Welded position id of every vertex (the smallest vertex index at its position).
    position: Vec<u32>,
    centre: Vec3,
    size: f32,
}

fn subject(name: &str) -> &'static Subject {
    static SUBJECTS: OnceLock<HashMap<&'static str, Subject>> = OnceLock::new();
    let all = SUBJECTS.get_or_init(|| {
        let mut all = HashMap::new();
        for (name, mesh, closed, pairs) in [
            ("cow", testdata_mesh("cow.obj"), true, 0.0),
            ("fandisk", testdata_mesh("fandisk.obj"), true, 0.0),
            ("spot", testdata_mesh("spot.obj"), true, 0.0),
            ("bunny", testdata_mesh("stanford-bunny.obj"), false, 0.0),
            ("mannequin", mannequin(), true, 0.0),
            ("terrain", terrain(), false, 0.0),
            ("parts", parts(), true, PARTS_PAIR_DISTANCE),
        ] {
            let options = BuildOptions::default()
                .with_view_dependent(true)
                .with_pair_distance(pairs);
            let pm = ProgressiveMesh::build(&mesh, &options).expect("test mesh builds");
            let (lo, hi) = mesh.bounds().expect("non-empty");
            let position = weld_positions(&mesh.positions).remap;
            let vm = VariableMesh::new(pm).expect("view data kept");
            all.insert(
                name,
                Subject {
                    mesh,
                    vm,
                    closed,
                    folds: pairs > 0.0,
                    position,
                    centre: (lo + hi) * 0.5,
                    size: (hi - lo).length(),
                },
            );
        }
        all
    });
    &all[name]
}

#[cfg(feature = "mannequin")]
fn mannequin() -> IndexedMesh {
    use bevy_aslod::mannequin::{MannequinOptions, generate};
    generate(&MannequinOptions::default())
        .expect("default mannequin")
        .mesh
}

/// Without the mannequin feature, the cow once more.
#[cfg(not(feature = "mannequin"))]
fn mannequin() -> IndexedMesh {
    testdata_mesh("cow.obj")
}

/// An open, bumpy 40×40 height field: a mesh with a border, whose corners and edges make
/// ear collapses (one triangle, no corner moved).
fn terrain() -> IndexedMesh {
    let heights: Vec<f32> = (0..1600)
        .map(|i| ((i * 37 % 101) as f32 / 101.0 - 0.5) * 0.8)
        .collect();
    grid(40, 40, &heights)
}

/// The topology compromise's distance for [`parts`] (relative to the diagonal).
const PARTS_PAIR_DISTANCE: f32 = 0.02;

/// 36 small spheres, 0.2 apart, built with the topology compromise: parts merge and vanish.
fn parts() -> IndexedMesh {
    let part = common::sphere(4, 6, &[0.0], false);
    let mut mesh = IndexedMesh::new(Vec::new(), Vec::new());
    for i in 0..36u32 {
        let offset = Vec3::new((i % 6) as f32, 0.0, (i / 6) as f32) * 2.2;
        let base = mesh.positions.len() as u32;
        mesh.positions
            .extend(part.positions.iter().map(|&p| p + offset));
        mesh.indices.extend(part.indices.iter().map(|&v| v + base));
    }
    mesh
}

const NAMES: [&str; 7] = [
    "cow",
    "fandisk",
    "spot",
    "bunny",
    "mannequin",
    "terrain",
    "parts",
];

/// A random camera around a mesh: anywhere from inside it to far away, looking at it or
/// not, with any field of view and viewport.
#[derive(Clone, Debug)]
struct Camera {
    direction: Vec3,
    distance: f32,
    look_off: Vec3,
    fov: f32,
    height: f32,
}

fn arb_camera() -> impl Strategy<Value = Camera> {
    (
        prop::array::uniform3(-1.0f32..1.0),
        0.05f32..4.0,
        prop::array::uniform3(-0.6f32..0.6),
        0.2f32..2.2,
        100.0f32..2000.0,
    )
        .prop_map(|(d, distance, off, fov, height)| Camera {
            direction: Vec3::from(d).try_normalize().unwrap_or(Vec3::Z),
            distance,
            look_off: Vec3::from(off),
            fov,
            height,
        })
}

impl Camera {
    fn view(&self, s: &Subject) -> View {
        let eye = s.centre + self.direction * self.distance * s.size;
        let target = s.centre + self.look_off * s.size;
        let forward = (target - eye).try_normalize().unwrap_or(-self.direction);
        let up = if forward.cross(Vec3::Y).length() > 1e-3 {
            Vec3::Y
        } else {
            Vec3::X
        };
        View::perspective(eye, forward, up, self.fov, 4.0 / 3.0, 1e-3, self.height)
            .expect("a valid camera")
    }

    /// The camera moved by a small step (a frame of a smooth motion).
    fn nudged(&self, k: f32) -> Self {
        let turn = glam::Quat::from_rotation_y(0.03 * k);
        Self {
            direction: turn * self.direction,
            distance: self.distance * (1.0 + 0.01 * k),
            ..self.clone()
        }
    }
}

/// Random criteria: each built-in on or off, with random settings.
#[derive(Clone, Debug)]
struct CriteriaSpec {
    frustum: bool,
    back_facing: bool,
    tolerance: Option<f32>,
    sphere: Option<(Vec3, f32)>,
    silhouette: bool,
    light: Option<Vec3>,
}

fn arb_criteria() -> impl Strategy<Value = CriteriaSpec> {
    (
        any::<bool>(),
        any::<bool>(),
        prop::option::of(prop_oneof![0.0f32..2.0, 0.0f32..60.0]),
        prop::option::of((prop::array::uniform3(-0.5f32..0.5), 0.0f32..0.6)),
        any::<bool>(),
        prop::option::of(prop::array::uniform3(-1.0f32..1.0)),
    )
        .prop_map(
            |(frustum, back_facing, tolerance, sphere, silhouette, light)| CriteriaSpec {
                frustum,
                back_facing,
                tolerance,
                sphere: sphere.map(|(c, r)| (Vec3::from(c), r)),
                silhouette,
                light: light.map(Vec3::from),
            },
        )
}

impl CriteriaSpec {
    fn criteria(&self, s: &Subject) -> Criteria {
        Criteria::default()
            .with_frustum(self.frustum)
            .with_back_facing(self.back_facing)
            .with_screen_space(self.tolerance.map(|t| ScreenSpaceError::new(t).unwrap()))
            .with_sphere_of_interest(
                self.sphere.map(|(c, r)| {
                    SphereOfInterest::new(s.centre + c * s.size, r * s.size).unwrap()
                }),
            )
            .with_silhouette(self.silhouette)
            .with_illumination(self.light.and_then(|l| Illumination::new(l).ok()))
    }
}

/// A criterion that is not monotone: each collapse is performed or not by a coin with
/// probability `p`, whatever the view. It drives the dependency rules hardest (a monotone
/// criterion never asks for a collapse without the ones below it).
#[derive(Clone, Copy, Debug)]
struct Coin {
    seed: u64,
    p: f64,
}

impl Criterion for Coin {
    fn coarsen(&self, node: &Node, _view: &View) -> bool {
        let mut x = (u64::from(node.step) ^ self.seed).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        x ^= x >> 29;
        x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
        x ^= x >> 32;
        (x as f64 / u64::MAX as f64) < self.p
    }
}

/// Crack-free and fold-free: no directed edge is used twice; a closed mesh stays closed;
/// no drawn triangle uses a vertex that a performed collapse moved away (a triangle left
/// behind by a neighbour that moved on is a crack, on open meshes too); and every drawn
/// triangle faces the side its full-detail triangle faced.
fn assert_sound(s: &Subject, cache: &VariableCache, context: &str) {
    let indices = cache.indices();
    let positions = &s.mesh.positions;
    let edges = common::welded_directed_edges(positions, indices);
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "{context}: edge {a}->{b} used {n} times");
    }
    if s.closed {
        assert_closed(positions, indices, context);
    }
    let mut gone = vec![false; positions.len()];
    for step in 0..s.vm.collapse_count() {
        if cache.is_performed(step) {
            gone[s.vm.collapse(step).unwrap()[0] as usize] = true;
        }
    }
    let full = s.vm.mesh().full_indices();
    for (t, &slot) in indices.chunks_exact(3).zip(cache.triangle_slots()) {
        for &v in t {
            assert!(
                !gone[s.position[v as usize] as usize],
                "{context}: triangle {t:?} (slot {slot}) keeps vertex {v}, which a performed \
                 collapse moved away: a crack"
            );
        }
        let then = &full[3 * slot as usize..3 * slot as usize + 3];
        assert!(
            s.folds || normal(positions, t).dot(normal(positions, then)) > 0.0,
            "{context}: triangle {t:?} faces away from its full-detail {then:?}"
        );
    }
}

proptest! {
    #![proptest_config(config(160))]

    /// A fresh extraction is sound, and the cache and the free function agree; then along a
    /// few frames of a smooth motion and a jump to a random camera, every incremental update
    /// lands exactly where a fresh extraction does.
    #[test]
    fn levels_are_sound_and_updates_match_fresh_extractions(
        which in 0..NAMES.len(),
        camera in arb_camera(),
        jump in arb_camera(),
        spec in arb_criteria(),
        other in arb_criteria(),
    ) {
        let s = subject(NAMES[which]);
        let criteria = spec.criteria(s);
        let view = camera.view(s);
        let mut cache = VariableCache::new(&s.vm);
        let stats = cache.extract(&s.vm, &criteria, &view).unwrap();
        assert_sound(s, &cache, &format!("{} fresh", NAMES[which]));
        let mut flat = Vec::new();
        let free = extract(&s.vm, &criteria, &view, &mut flat).unwrap();
        prop_assert_eq!(free, stats);
        prop_assert_eq!(triangle_multiset(&flat), triangle_multiset(cache.indices()));

        let mut frames: Vec<(View, Criteria)> =
            (1..=3).map(|k| (camera.nudged(k as f32).view(s), criteria)).collect();
        frames.push((jump.view(s), criteria));
        frames.push((jump.view(s), other.criteria(s)));
        for (k, (view, criteria)) in frames.iter().enumerate() {
            let stats = cache.update(&s.vm, criteria, view).unwrap();
            let context = format!("{} update {k}", NAMES[which]);
            assert_sound(s, &cache, &context);
            extract(&s.vm, criteria, view, &mut flat).unwrap();
            prop_assert_eq!(
                triangle_multiset(cache.indices()),
                triangle_multiset(&flat),
                "{}: the update differs from a fresh extraction", context
            );
            prop_assert_eq!(stats.triangles, flat.len() / 3);
        }
    }

    /// With a criterion that is not monotone (a coin per collapse), every level, fresh or
    /// updated, is still sound: the dependency rules (MOM's flags per slot, the ear rule)
    /// keep it crack-free on their own.
    #[test]
    fn levels_of_any_criterion_are_sound(
        which in 0..NAMES.len(),
        seeds in prop::collection::vec(any::<u64>(), 3),
        p in 0.05f64..0.95,
    ) {
        let s = subject(NAMES[which]);
        let view = arb_camera_fixed().view(s);
        let mut cache = VariableCache::new(&s.vm);
        let mut flat = Vec::new();
        for (k, &seed) in seeds.iter().enumerate() {
            let coin = Coin { seed, p };
            let fresh = extract(&s.vm, &coin, &view, &mut flat).unwrap();
            let mut again = VariableCache::new(&s.vm);
            again.extract(&s.vm, &coin, &view).unwrap();
            assert_sound(s, &again, &format!("{} coin {k}", NAMES[which]));
            prop_assert_eq!(triangle_multiset(again.indices()), triangle_multiset(&flat));
            prop_assert!(fresh.performed > 0 || p < 0.2);
            cache.update(&s.vm, &coin, &view).unwrap();
            assert_sound(s, &cache, &format!("{} coin update {k}", NAMES[which]));
        }
    }

    /// "Perform every collapse before L, none after" is the polygon cache at level L,
    /// triangle for triangle and in the same order, and the incremental path gets there too.
    #[test]
    fn a_uniform_cut_is_the_polygon_cache_level(which in 0..NAMES.len(), f in 0.0f64..=1.0) {
        let s = subject(NAMES[which]);
        let pm = s.vm.mesh();
        let level = (f * (pm.level_count() - 1) as f64) as usize;
        let view = arb_camera_fixed().view(s);
        let mut flat = Vec::new();
        extract(&s.vm, &LevelCut(level), &view, &mut flat).unwrap();
        let mut uniform = PolygonCache::new(pm);
        uniform.set_level(pm, level);
        prop_assert_eq!(&flat[..], uniform.indices());
        let mut cache = VariableCache::new(&s.vm);
        cache.update(&s.vm, &LevelCut(level), &view).unwrap();
        prop_assert_eq!(triangle_multiset(cache.indices()), triangle_multiset(uniform.indices()));
    }
}

proptest! {
    #![proptest_config(config(64))]

    /// A budget search along a camera path with a jump and a changing budget: every level
    /// is within its budget (or the coarsest one), is the level a fresh extraction gives at
    /// the tolerance it reports, and, when the search converged, half that tolerance would
    /// not have fitted (so it is not far from the most detail within the budget).
    #[test]
    fn a_budget_search_fits_the_budget_with_the_most_detail(
        which in 0..NAMES.len(),
        camera in arb_camera(),
        jump in arb_camera(),
        spec in arb_criteria(),
        budgets in prop::collection::vec(0.0f64..1.0, 5),
        floor in prop::option::of(0.0f32..4.0),
    ) {
        let s = subject(NAMES[which]);
        let criteria = spec.criteria(s).with_screen_space(None);
        let pm = s.vm.mesh();
        let (min, max) = (pm.min_triangles(), pm.max_triangles());
        let mut cache = VariableCache::new(&s.vm);
        let mut search = ToleranceSearch::default();
        let mut flat = Vec::new();
        let views = [camera.view(s), camera.nudged(1.0).view(s), jump.view(s),
            jump.nudged(1.0).view(s), jump.nudged(2.0).view(s)];
        for (k, (view, &b)) in views.iter().zip(&budgets).enumerate() {
            let budget = min / 2 + (b * (max - min / 2) as f64) as usize;
            let fit = search.fit(&mut cache, &s.vm, &criteria, view, budget,
                floor.unwrap_or(0.0)).unwrap();
            let context = format!("{} frame {k} budget {budget}", NAMES[which]);
            prop_assert_eq!(fit.triangles, cache.triangle_count(), "{}", context);
            prop_assert!(fit.updates <= search.max_updates + 1, "{}", context);
            if fit.tolerance_px.is_finite() {
                prop_assert!(fit.within && fit.triangles <= budget, "{}", context);
                let reference = criteria.with_screen_space(Some(
                    ScreenSpaceError::new(fit.tolerance_px).unwrap()));
                extract(&s.vm, &reference, view, &mut flat).unwrap();
                prop_assert_eq!(triangle_multiset(cache.indices()), triangle_multiset(&flat),
                    "{}: not the level of its tolerance", context);
                let lower = ((1.0 - search.slack) * budget as f32) as usize;
                let floor = floor.unwrap_or(0.0);
                if fit.updates < search.max_updates && fit.triangles < lower
                    && fit.tolerance_px > floor.max(2e-3) * 2.0
                {
                    let finer = criteria.with_screen_space(Some(
                        ScreenSpaceError::new(fit.tolerance_px / 2.0).unwrap()));
                    extract(&s.vm, &finer, view, &mut flat).unwrap();
                    prop_assert!(flat.len() / 3 > budget,
                        "{}: half the tolerance {} also fits ({} triangles)", context,
                        fit.tolerance_px, flat.len() / 3);
                }
            } else {
                // The fallback: the largest tolerance cut at the finest uniform level that fits.
                let cut = fit.level_cut.expect("a level cut");
                prop_assert_eq!(fit.within, min <= budget, "{}", context);
                prop_assert!(!fit.within || fit.triangles <= budget, "{}", context);
                let top = criteria.with_screen_space(Some(
                    ScreenSpaceError::new(ToleranceSearch::MAX_TOLERANCE_PX).unwrap()));
                extract(&s.vm, &(top, LevelCut(cut)), view, &mut flat).unwrap();
                prop_assert_eq!(triangle_multiset(cache.indices()), triangle_multiset(&flat),
                    "{}: not the level of its cut", context);
            }
        }
    }
}

fn arb_camera_fixed() -> Camera {
    Camera {
        direction: Vec3::Z,
        distance: 2.0,
        look_off: Vec3::ZERO,
        fov: 0.8,
        height: 600.0,
    }
}

#[test]
fn nothing_to_drop_keeps_the_original_mesh_exactly() {
    for name in NAMES {
        let s = subject(name);
        let view = arb_camera_fixed().view(s);
        let full = s.vm.mesh().full_indices();
        let zero = ScreenSpaceError::new(0.0).unwrap();
        let mut flat = Vec::new();
        for stats in [
            extract(&s.vm, &Criteria::default(), &view, &mut flat).unwrap(),
            extract(&s.vm, &zero, &view, &mut flat).unwrap(),
        ] {
            assert_eq!(flat, full, "{name}");
            assert_eq!((stats.performed, stats.triangles), (0, full.len() / 3));
        }
        let mut cache = VariableCache::new(&s.vm);
        let coarse = ScreenSpaceError::new(1e6).unwrap();
        cache.update(&s.vm, &coarse, &view).unwrap();
        assert!(cache.triangle_count() < full.len() / 3);
        cache.update(&s.vm, &zero, &view).unwrap();
        assert_eq!(
            triangle_multiset(cache.indices()),
            triangle_multiset(&full),
            "{name}"
        );
        assert_eq!(cache.indices().len(), full.len());
    }
}

#[test]
fn a_mesh_without_view_data_or_a_cache_of_another_mesh_is_an_error() {
    let s = subject("cow");
    let plain = ProgressiveMesh::build(&s.mesh, &BuildOptions::default()).unwrap();
    assert!(!plain.has_view_data());
    assert!(matches!(
        VariableMesh::new(plain),
        Err(RefineError::NoViewData)
    ));
    let spot = subject("spot");
    let mut cache = VariableCache::new(&spot.vm);
    let view = arb_camera_fixed().view(s);
    assert!(matches!(
        cache.update(&s.vm, &Criteria::default(), &view),
        Err(RefineError::MeshMismatch { .. })
    ));
}

#[test]
fn the_view_data_holds_every_collapse_and_stays_small() {
    for name in NAMES {
        let s = subject(name);
        let pm = s.vm.mesh();
        let pairs = if s.folds { PARTS_PAIR_DISTANCE } else { 0.0 };
        let options = BuildOptions::default().with_pair_distance(pairs);
        let plain = ProgressiveMesh::build(&s.mesh, &options).unwrap();
        let extra = pm.memory_bytes() - plain.memory_bytes();
        let per_triangle = extra as f64 / pm.max_triangles() as f64;
        // 14 bytes per collapse; pair collapses that merge two parts remove no triangle.
        let limit = if s.folds { 12.0 } else { 8.0 };
        assert!(
            per_triangle <= limit,
            "{name}: {per_triangle:.2} bytes per triangle"
        );
        for step in 0..s.vm.collapse_count() {
            let [u, w] = s.vm.collapse(step).unwrap();
            assert_ne!(u, w, "{name}: collapse {step}");
            let node = s.vm.node(step).unwrap();
            assert!(node.radius >= 0.0 && node.error >= 0.0 && node.cone_angle >= 0.0);
            // Every bound holds the bounds of the collapses below it.
            for &d in s.vm.dependencies(step) {
                let below = s.vm.node(d as usize).unwrap();
                assert!(d < step as u32);
                assert!(
                    node.error >= below.error,
                    "{name}: error of {step} below {d}"
                );
                assert!(
                    node.center.distance(below.center) + below.radius <= node.radius * 1.0001,
                    "{name}: sphere of {step} does not hold {d}'s"
                );
                let between = node.axis.angle_between(below.axis);
                assert!(
                    node.cone_angle >= std::f32::consts::PI - 1e-6
                        || between + below.cone_angle <= node.cone_angle + 1e-3,
                    "{name}: cone of {step} does not hold {d}'s"
                );
            }
        }
    }
}

#[test]
fn bad_tolerances_and_cameras_are_errors() {
    for t in [f32::NAN, f32::INFINITY, -0.5] {
        assert!(matches!(
            ScreenSpaceError::new(t),
            Err(RefineError::InvalidTolerance(_))
        ));
    }
    assert!(View::perspective(Vec3::ZERO, Vec3::Z, Vec3::Y, 0.0, 1.0, 0.1, 600.0).is_err());
    assert!(View::perspective(Vec3::NAN, Vec3::Z, Vec3::Y, 1.0, 1.0, 0.1, 600.0).is_err());
    // The eye inside the mesh is a camera like any other: everything around it stays.
    let s = subject("spot");
    let inside = View::perspective(s.centre, Vec3::Z, Vec3::Y, 1.0, 1.0, 1e-3, 600.0).unwrap();
    let mut cache = VariableCache::new(&s.vm);
    let criteria = Criteria::default()
        .with_frustum(true)
        .with_screen_space(Some(ScreenSpaceError::new(2.0).unwrap()));
    cache.extract(&s.vm, &criteria, &inside).unwrap();
    assert_sound(s, &cache, "eye inside");
}

/// MOM's Figure 7 setting: a sphere of interest keeps full detail inside it and lets the rest
/// go; a larger sphere keeps more.
#[test]
fn a_growing_sphere_of_interest_keeps_more_detail() {
    let s = subject("bunny");
    let view = arb_camera_fixed().view(s);
    let mut last = 0;
    let mut flat = Vec::new();
    for r in [0.0, 0.05, 0.1, 0.2, 0.4, 2.0] {
        let sphere = SphereOfInterest::new(s.centre, r * s.size).unwrap();
        let stats = extract(&s.vm, &sphere, &view, &mut flat).unwrap();
        assert!(
            stats.triangles >= last,
            "radius {r}: {} < {last}",
            stats.triangles
        );
        last = stats.triangles;
    }
    assert_eq!(last, s.vm.mesh().max_triangles());
}
