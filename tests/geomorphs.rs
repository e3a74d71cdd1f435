//! Geomorphs between region levels and between variable-resolution levels: random level
//! changes on closed meshes,
//! sampled at random morph times, never open an edge or jump; at the end of a morph every
//! vertex is at its own position and the levels are the ones asked for; a duration of 0 is
//! the plain caches.

mod common;

use bevy_aslod::mesh::{IndexedMesh, weld_positions};
use bevy_aslod::multires::{BuildOptions, ProgressiveMesh};
use bevy_aslod::refine::{
    LevelCut, SphereOfInterest, VariableCache, VariableGeomorphs, VariableMesh, View,
};
use bevy_aslod::regions::{Geomorphs, Partition, RegionCaches, RegionMesh, VertexMorph};
use common::{
    Rng, assert_closed, border_edges, grid, sphere, testdata_mesh, welded_directed_edges,
};
use glam::Vec3;
use std::collections::HashSet;

const T: f32 = 0.25;

fn regions(mesh: &IndexedMesh, k: usize) -> RegionMesh {
    regions_with(mesh, k, &BuildOptions::default())
}

fn regions_with(mesh: &IndexedMesh, k: usize, options: &BuildOptions) -> RegionMesh {
    let partition = Partition::clusters(mesh, k).unwrap();
    RegionMesh::build(mesh, &partition, options).unwrap()
}

/// Every region's triangles, in source vertices.
fn assemble(mesh: &RegionMesh, caches: &mut RegionCaches) -> Vec<u32> {
    let (mut all, mut part) = (Vec::new(), Vec::new());
    for r in 0..mesh.regions().len() {
        caches.write_global_indices(mesh, r, &mut part);
        all.extend_from_slice(&part);
    }
    all
}

/// The shown mesh is closed, and vertices at one source position (seams, and the copies a
/// border shares) are shown at one position: no crack opens.
fn assert_crack_free(
    mesh: &IndexedMesh,
    morphs: &Geomorphs,
    indices: &[u32],
    now: f32,
    closed: bool,
    at: &str,
) {
    if closed {
        assert_closed(&mesh.positions, indices, at);
    } else {
        // Open: every inner edge keeps its twin, the outline stays the outline.
        let edges = welded_directed_edges(&mesh.positions, indices);
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "{at}: edge {a}->{b} used {n} times");
        }
        let outline = border_edges(&mesh.positions, indices);
        let full = border_edges(&mesh.positions, &mesh.indices);
        assert!(
            outline.len() <= full.len(),
            "{at}: {} open edges",
            outline.len()
        );
    }
    let weld = weld_positions(&mesh.positions);
    let used: HashSet<u32> = indices.iter().copied().collect();
    for &g in &used {
        let first = weld.remap[g as usize];
        if first != g && used.contains(&first) {
            assert_eq!(
                morphs.position(g, now),
                morphs.position(first, now),
                "{at}: vertex {g} and {first} share a position but are shown apart"
            );
        }
    }
}

/// The triangles shown at `now` as position triples (exact bits, each rotated to start at
/// its least), without the flat ones: the surface, whichever vertices make it.
fn triangles_shown(position: impl Fn(u32) -> Vec3, indices: &[u32]) -> Vec<[[u32; 3]; 3]> {
    let mut out: Vec<[[u32; 3]; 3]> = indices
        .chunks_exact(3)
        .filter_map(|t| {
            let p = [t[0], t[1], t[2]].map(|g| position(g).to_array().map(f32::to_bits));
            if p[0] == p[1] || p[1] == p[2] || p[2] == p[0] {
                return None;
            }
            let first = (0..3).min_by_key(|&i| p[i]).unwrap_or(0);
            Some([p[first], p[(first + 1) % 3], p[(first + 2) % 3]])
        })
        .collect();
    out.sort_unstable();
    out
}

fn shown(position: impl Fn(u32) -> Vec3, indices: &[u32]) -> Vec<(u32, Vec3)> {
    let used: HashSet<u32> = indices.iter().copied().collect();
    used.into_iter().map(|g| (g, position(g))).collect()
}

/// No jump: what was shown (`before`) stays where it was; what appears is where a shown
/// vertex was, or (`own_place(g)`) at its own place.
fn assert_no_jump(
    before: &[(u32, Vec3)],
    after: &[(u32, Vec3)],
    own_place: impl Fn(u32, Vec3) -> bool,
    at: &str,
) {
    let was: std::collections::HashMap<u32, Vec3> = before.iter().copied().collect();
    let positions: Vec<Vec3> = before.iter().map(|&(_, p)| p).collect();
    for &(g, p) in after {
        match was.get(&g) {
            Some(&q) => assert_eq!(p, q, "{at}: vertex {g} jumped"),
            None => assert!(
                positions.contains(&p) || own_place(g, p),
                "{at}: vertex {g} appeared off the mesh"
            ),
        }
    }
}

#[test]
fn random_level_changes_stay_crack_free_and_never_jump() {
    for (name, mesh, k, closed) in [
        (
            "sphere",
            sphere(16, 24, &[0.0, 0.04, -0.02, 0.01], true),
            6,
            true,
        ),
        ("cow", testdata_mesh("cow.obj"), 8, true),
        // Open: ears collapse, whose records keep a corner in place.
        (
            "terrain",
            grid(24, 24, &[0.0, 0.1, -0.05, 0.2, 0.0]),
            5,
            false,
        ),
    ] {
        // The topology kept (`permissive(false)`): the check is that the shown surface stays
        // closed, which a permissive level (a part erased, a pinch) need not be.
        let rm = regions_with(&mesh, k, &BuildOptions::default().with_permissive(false));
        let mut caches = RegionCaches::new(&rm);
        let mut morphs = Geomorphs::new(&rm, T);
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        let mut now = 0.0f32;
        for request in 0..60 {
            // Requests come at random: often within a morph, sometimes after it.
            now += rng.unit() * 0.4;
            morphs.update(&rm, &mut caches, now);
            let before_indices = assemble(&rm, &mut caches);
            let before = shown(|g| morphs.position(g, now), &before_indices);
            let levels: Vec<usize> = (0..rm.regions().len()).map(|r| caches.level(r)).collect();
            let regions_changed = 1 + (rng.next() % rm.regions().len() as u64) as usize;
            for _ in 0..regions_changed {
                let r = (rng.next() % rm.regions().len() as u64) as usize;
                let max = rm.regions()[r].max_triangles();
                let count = (rng.unit() * max as f32) as usize;
                morphs.set_triangle_count(&rm, &mut caches, r, count, now);
            }
            // What appears is where a shown vertex is (or, when its region had it all along
            // and only a neighbour's triangle that starts flat brings it in, at its own place).
            let after = shown(|g| morphs.position(g, now), &assemble(&rm, &mut caches));
            let own_place = |g: u32, p: Vec3| {
                let level = levels[rm.partition().region_of()[g as usize] as usize];
                morphs.stand_in(g, level) == morphs.stand_in(g, 0)
                    && p == mesh.positions[g as usize]
            };
            assert_no_jump(
                &before,
                &after,
                own_place,
                &format!("{name}, request {request}"),
            );
            // Sampled at random times within the morph.
            for _ in 0..3 {
                let at = now + rng.unit() * T;
                let mut c = caches.clone();
                let mut m = morphs.clone();
                let landing = triangles_shown(|g| m.position(g, at), &assemble(&rm, &mut c));
                m.update(&rm, &mut c, at);
                let indices = assemble(&rm, &mut c);
                let context = format!("{name}, request {request}");
                assert_crack_free(&mesh, &m, &indices, at, closed, &context);
                // A coarsening that lands swaps triangles whose vertices have arrived for
                // the coarser ones: the same surface, no pop. Checked on closed meshes: on an
                // open outline an ear's vertex can vanish without a recorded move, and its
                // triangles go at once.
                let landed = triangles_shown(|g| m.position(g, at), &indices);
                assert!(
                    !closed || landed == landing,
                    "{context}: the surface changed as a coarsening landed"
                );
            }
        }
        // At the end, every vertex shown is at its own position, and the levels are the last
        // ones asked for.
        now += T;
        morphs.update(&rm, &mut caches, now);
        assert!(!morphs.is_morphing(), "{name}: still morphing");
        let indices = assemble(&rm, &mut caches);
        for &g in &indices {
            assert_eq!(
                morphs.position(g, now),
                mesh.positions[g as usize],
                "{name}"
            );
        }
    }
}

#[test]
fn the_end_of_a_morph_is_the_target_level_exactly() {
    let mesh = testdata_mesh("cow.obj");
    let rm = regions(&mesh, 8);
    let mut rng = Rng(7);
    let mut caches = RegionCaches::new(&rm);
    let mut plain = RegionCaches::new(&rm);
    let mut morphs = Geomorphs::new(&rm, T);
    let mut now = 0.0;
    for _ in 0..20 {
        for r in 0..rm.regions().len() {
            let count = (rng.unit() * rm.regions()[r].max_triangles() as f32) as usize;
            morphs.set_triangle_count(&rm, &mut caches, r, count, now);
            plain.set_triangle_count(&rm, r, count);
        }
        now += T;
        morphs.update(&rm, &mut caches, now);
        assert_eq!(assemble(&rm, &mut caches), assemble(&rm, &mut plain));
        let mut out = Vec::new();
        for r in 0..rm.regions().len() {
            morphs.write_positions(&rm, r, now, &mut out);
            let own: Vec<Vec3> = rm.regions()[r]
                .global_vertices()
                .iter()
                .map(|&g| mesh.positions[g as usize])
                .collect();
            assert_eq!(out, own);
        }
    }
}

#[test]
fn a_coarsening_region_counts_its_old_triangles_until_they_go() {
    let mesh = testdata_mesh("cow.obj");
    let rm = regions(&mesh, 4);
    let mut caches = RegionCaches::new(&rm);
    let mut morphs = Geomorphs::new(&rm, T);
    let full = caches.triangle_count(0);
    assert_eq!(
        morphs.set_triangle_count(&rm, &mut caches, 0, 10, 0.0),
        full
    );
    morphs.update(&rm, &mut caches, 0.2);
    assert_eq!(caches.triangle_count(0), full, "still morphing");
    morphs.update(&rm, &mut caches, T);
    assert!(caches.triangle_count(0) < full);
    // Refining is at once; the region's vertices then move until T has passed.
    assert_eq!(
        morphs.set_triangle_count(&rm, &mut caches, 0, usize::MAX, 1.0),
        full
    );
    morphs.update(&rm, &mut caches, 1.0);
    assert!(morphs.is_region_moving(&rm, 0));
    morphs.update(&rm, &mut caches, 1.0 + T);
    assert!((0..rm.regions().len()).all(|r| !morphs.is_region_moving(&rm, r)));
    assert!(!morphs.is_morphing());
}

#[test]
fn a_duration_of_zero_is_the_plain_caches() {
    let mesh = sphere(12, 16, &[0.0, 0.03], true);
    let rm = regions(&mesh, 5);
    let mut rng = Rng(3);
    let mut caches = RegionCaches::new(&rm);
    let mut plain = RegionCaches::new(&rm);
    for off in [
        Geomorphs::new(&rm, 0.0),
        Geomorphs::new(&rm, -1.0),
        Geomorphs::new(&rm, f32::NAN),
    ] {
        let mut off = off;
        assert_eq!(off.duration(), 0.0);
        for step in 0..50 {
            let r = (rng.next() % rm.regions().len() as u64) as usize;
            let count = (rng.unit() * rm.regions()[r].max_triangles() as f32) as usize;
            let now = step as f32 * 0.01;
            assert_eq!(
                off.set_triangle_count(&rm, &mut caches, r, count, now),
                plain.set_triangle_count(&rm, r, count)
            );
            off.update(&rm, &mut caches, now);
            assert!(!off.is_morphing());
            let indices = assemble(&rm, &mut caches);
            assert_eq!(indices, assemble(&rm, &mut plain));
            for &g in &indices {
                assert_eq!(off.position(g, now), mesh.positions[g as usize]);
            }
        }
    }
}

#[test]
fn an_allocation_under_geomorphs_never_shows_more_than_the_budget_and_settles() {
    let mesh = testdata_mesh("cow.obj");
    let rm = regions(&mesh, 8);
    let mut caches = RegionCaches::new(&rm);
    for r in 0..rm.regions().len() {
        caches.set_triangle_count(&rm, r, 0);
    }
    let mut morphs = Geomorphs::new(&rm, T);
    let budget = mesh.triangle_count() / 4;
    let least: usize = rm.regions().iter().map(|r| r.min_triangles()).sum();
    let mut rng = Rng(11);
    let mut now = 0.0;
    for frame in 0..300 {
        // Random wishes that sum to the budget, each at least its region's coarsest level
        // (as an allocator gives them): regions trade triangles every frame.
        let weights: Vec<f32> = (0..rm.regions().len()).map(|_| rng.unit() + 0.01).collect();
        let sum: f32 = weights.iter().sum();
        let counts: Vec<u32> = weights
            .iter()
            .zip(rm.regions())
            .map(|(w, region)| {
                (region.min_triangles() as f32 + w / sum * (budget - least) as f32) as u32
            })
            .collect();
        let total = morphs.apply_allocation(&rm, &mut caches, &counts, budget, now);
        assert!(
            total <= budget,
            "frame {frame}: {total} shown, budget {budget}"
        );
        now += 1.0 / 60.0;
        morphs.update(&rm, &mut caches, now);
        assert!(
            caches.total_triangles() <= budget,
            "frame {frame} after update"
        );
        // Every 50 frames the wishes stay put for a while (a still view): coarsenings land
        // within T, the refinements that waited for their triangles within T more, and the
        // levels are the ones asked for.
        if frame % 50 == 49 {
            for _ in 0..31 {
                morphs.apply_allocation(&rm, &mut caches, &counts, budget, now);
                now += 1.0 / 60.0;
                morphs.update(&rm, &mut caches, now);
            }
            assert!(!morphs.is_morphing(), "frame {frame}: still morphing");
            let mut plain = RegionCaches::new(&rm);
            for (r, &count) in counts.iter().enumerate() {
                plain.set_triangle_count(&rm, r, count as usize);
                assert_eq!(
                    caches.level(r),
                    plain.level(r),
                    "frame {frame}, region {r}: asked {count}, shows {} (plain {}), all {} of {budget}",
                    caches.triangle_count(r),
                    plain.triangle_count(r),
                    caches.total_triangles()
                );
            }
        }
    }
}

/// What a vertex shader shows from a copy of [`Geomorphs::vertex_morph`] per region vertex,
/// taken again only where [`Geomorphs::take_restarted`] says, is what the CPU shows.
#[test]
fn a_gpu_copy_taken_at_restarts_shows_what_the_cpu_does() {
    let mesh = testdata_mesh("cow.obj");
    let rm = regions(&mesh, 8);
    let mut caches = RegionCaches::new(&rm);
    let mut morphs = Geomorphs::new(&rm, T);
    let mut gpu: Vec<Vec<VertexMorph>> = rm
        .regions()
        .iter()
        .map(|r| {
            r.global_vertices()
                .iter()
                .map(|&g| morphs.vertex_morph(g))
                .collect()
        })
        .collect();
    let mut rng = Rng(11);
    let mut now = 0.0f32;
    for request in 0..80 {
        now += rng.unit() * 0.3;
        let r = (rng.next() % rm.regions().len() as u64) as usize;
        let count = (rng.unit() * rm.regions()[r].max_triangles() as f32) as usize;
        morphs.set_triangle_count(&rm, &mut caches, r, count, now);
        morphs.update(&rm, &mut caches, now);
        for (r, run) in morphs.take_restarted(&rm).into_iter().enumerate() {
            if let Some((lo, hi)) = run {
                let global = rm.regions()[r].global_vertices();
                for i in lo..=hi {
                    gpu[r][i as usize] = morphs.vertex_morph(global[i as usize]);
                }
            }
        }
        for _ in 0..3 {
            let at = now + rng.unit() * 0.3;
            let mut c = caches.clone();
            let mut m = morphs.clone();
            m.update(&rm, &mut c, at);
            for (r, copy) in gpu.iter().enumerate() {
                let mut part = Vec::new();
                c.write_indices(&rm, r, &mut part);
                let global = rm.regions()[r].global_vertices();
                for &i in &part {
                    let (v, g) = (copy[i as usize], global[i as usize]);
                    let t = ((at - v.start) / T).clamp(0.0, 1.0);
                    let p = if t >= 1.0 {
                        v.to
                    } else {
                        v.from + (v.to - v.from) * t
                    };
                    assert_eq!(
                        p,
                        m.position(g, at),
                        "request {request}: vertex {g} in region {r}: {v:?} at {at}, t {t}, cpu {:?}",
                        m.vertex_morph(g)
                    );
                    let n = v.normal_from.lerp(v.normal_to, t).normalize_or(v.normal_to);
                    let cpu = m.normal(g, at).unwrap_or(Vec3::ZERO);
                    assert!(
                        n.distance(cpu) < 1e-5,
                        "request {request}: vertex {g}'s normal {n} against {cpu}"
                    );
                }
            }
        }
    }
}

// Variable-resolution levels (`VariableGeomorphs`).

fn variable(mesh: &IndexedMesh) -> VariableMesh {
    let options = BuildOptions::default().with_view_dependent(true);
    VariableMesh::new(ProgressiveMesh::build(mesh, &options).unwrap()).unwrap()
}

/// A random variable-resolution target: detail kept inside a random sphere, or a uniform
/// level.
fn random_target(vm: &VariableMesh, mesh: &IndexedMesh, target: &mut VariableCache, rng: &mut Rng) {
    let view = View::perspective(Vec3::Z, Vec3::NEG_Z, Vec3::Y, 1.0, 1.0, 0.1, 10.0).unwrap();
    if rng.below(4) == 0 {
        let level = rng.below(vm.mesh().level_triangle_counts().len());
        target.update(vm, &LevelCut(level), &view).unwrap();
    } else {
        let centre = mesh.positions[rng.below(mesh.positions.len())];
        let (lo, hi) = mesh.bounds().unwrap();
        let radius = rng.unit() * 0.5 * (hi - lo).length();
        let sphere = SphereOfInterest::new(centre, radius).unwrap();
        target.update(vm, &sphere, &view).unwrap();
    }
}

#[test]
fn variable_levels_morph_crack_free_without_jumps_and_land_on_the_target() {
    for (name, mesh, closed) in [
        (
            "sphere",
            sphere(16, 24, &[0.0, 0.04, -0.02, 0.01], true),
            true,
        ),
        ("cow", testdata_mesh("cow.obj"), true),
        ("terrain", grid(24, 24, &[0.0, 0.1, -0.05, 0.2, 0.0]), false),
        // Open, with collapses whose removed vertex goes with all its triangles, rewritten
        // nowhere: it still morphs onto the kept vertex first.
        ("bunny", testdata_mesh("stanford-bunny.obj"), false),
    ] {
        let vm = variable(&mesh);
        let vertices = &vm.mesh().vertices().positions;
        let mut target = VariableCache::new(&vm);
        let mut morphs = VariableGeomorphs::new(&vm, &target, T);
        let mut rng = Rng(0x51_7CC1_B727_220A);
        let mut now = 0.0f32;
        for request in 0..50 {
            now += rng.unit() * 0.4;
            let at = format!("{name}, request {request}");
            let shown_before = morphs.shown().indices().to_vec();
            let before = shown(|v| morphs.position(v, now), &shown_before);
            random_target(&vm, &mesh, &mut target, &mut rng);
            // Half the requests under a budget of what is shown (refinements wait).
            let budget = if rng.below(2) == 0 {
                shown_before.len() / 3
            } else {
                usize::MAX
            };
            let triangles = morphs.follow(&vm, &target, budget, now).unwrap();
            assert_eq!(triangles, morphs.shown().triangle_count());
            assert!(
                triangles <= budget.max(shown_before.len() / 3),
                "{at}: over the budget"
            );
            let after = shown(|v| morphs.position(v, now), morphs.shown().indices());
            // A vertex shown without a morph is at its own place.
            let own_place = |v: u32, p: Vec3| p == vertices[v as usize];
            assert_no_jump(&before, &after, own_place, &at);
            for _ in 0..3 {
                let t = now + rng.unit() * T;
                let mut m = morphs.clone();
                let landing = triangles_shown(|v| m.position(v, t), m.shown().indices());
                m.follow(&vm, &target, 0, t).unwrap();
                let indices = m.shown().indices();
                if closed {
                    assert_closed(vertices, indices, &at);
                }
                let landed = triangles_shown(|v| m.position(v, t), indices);
                assert_eq!(
                    landed, landing,
                    "{at}: the surface changed as collapses landed"
                );
            }
        }
        now += T;
        morphs.follow(&vm, &target, usize::MAX, now).unwrap();
        assert!(!morphs.is_morphing(), "{name}: still morphing");
        assert_eq!(
            common::triangle_multiset(morphs.shown().indices()),
            common::triangle_multiset(target.indices()),
            "{name}: the level shown is not the target's"
        );
        let mut out = Vec::new();
        morphs.write_positions(now, &mut out);
        assert_eq!(&out, vertices, "{name}: a vertex is not at its own place");
    }
}

/// The detail moves from one end of the cow to the other and back: the collapses the new
/// target performs keep their triangles until they land, so its refinements wait for them
/// under a budget that fits either target, and the level settles on each target.
#[test]
fn variable_levels_under_a_budget_never_show_more_and_settle() {
    let mesh = testdata_mesh("cow.obj");
    let vm = variable(&mesh);
    let view = View::perspective(Vec3::Z, Vec3::NEG_Z, Vec3::Y, 1.0, 1.0, 0.1, 10.0).unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    let radius = 0.2 * (hi - lo).length();
    // The vertices furthest apart along the longest axis.
    let axis = (hi - lo).max_position();
    let along = |a: &&Vec3, b: &&Vec3| a[axis].total_cmp(&b[axis]);
    let first = *mesh.positions.iter().min_by(along).unwrap();
    let last = *mesh.positions.iter().max_by(along).unwrap();
    let mut ends = [first, last].map(|centre| {
        let mut cache = VariableCache::new(&vm);
        let sphere = SphereOfInterest::new(centre, radius).unwrap();
        cache.update(&vm, &sphere, &view).unwrap();
        cache
    });
    let budget = ends
        .iter()
        .map(VariableCache::triangle_count)
        .max()
        .unwrap();
    let [a, b] = &mut ends;
    let mut morphs = VariableGeomorphs::new(&vm, a, T);
    let mut now = 0.0;
    let mut waited = 0;
    for round in 0..4 {
        let target = if round % 2 == 0 { &*b } else { &*a };
        for frame in 0..40 {
            now += 1.0 / 60.0;
            let shown = morphs.follow(&vm, target, budget, now).unwrap();
            assert!(
                shown <= budget,
                "round {round}, frame {frame}: {shown} of {budget}"
            );
            let settled = common::triangle_multiset(morphs.shown().indices())
                == common::triangle_multiset(target.indices());
            waited += usize::from(frame > 0 && shown == budget && !settled);
        }
        assert!(!morphs.is_morphing(), "round {round}: still morphing");
        assert_eq!(
            common::triangle_multiset(morphs.shown().indices()),
            common::triangle_multiset(target.indices()),
            "round {round}"
        );
    }
    assert!(waited > 0, "no refinement waited for the budget");
}

#[test]
fn variable_levels_with_a_duration_of_zero_show_the_target() {
    let mesh = testdata_mesh("cow.obj");
    let vm = variable(&mesh);
    let mut target = VariableCache::new(&vm);
    let mut morphs = VariableGeomorphs::new(&vm, &target, 0.0);
    let mut rng = Rng(5);
    for frame in 0..20 {
        random_target(&vm, &mesh, &mut target, &mut rng);
        let shown = morphs.follow(&vm, &target, 0, frame as f32).unwrap();
        assert_eq!(shown, target.triangle_count());
        assert_eq!(morphs.shown().indices(), target.indices());
        assert!(!morphs.is_morphing());
    }
}

/// A GPU copy of [`VariableGeomorphs::vertex_morph`], taken again only in the runs
/// [`VariableGeomorphs::take_restarted`] gives, shows what the CPU does.
#[test]
fn a_gpu_copy_of_variable_morphs_shows_what_the_cpu_does() {
    let mesh = testdata_mesh("cow.obj");
    let vm = variable(&mesh);
    let mut target = VariableCache::new(&vm);
    let mut morphs = VariableGeomorphs::new(&vm, &target, T);
    let n = vm.mesh().vertices().vertex_count() as u32;
    let mut gpu: Vec<VertexMorph> = (0..n).map(|v| morphs.vertex_morph(v)).collect();
    let mut rng = Rng(13);
    let mut now = 0.0f32;
    for request in 0..40 {
        now += rng.unit() * 0.3;
        random_target(&vm, &mesh, &mut target, &mut rng);
        morphs.follow(&vm, &target, usize::MAX, now).unwrap();
        for (lo, hi) in morphs.take_restarted() {
            for v in lo..=hi {
                gpu[v as usize] = morphs.vertex_morph(v);
            }
        }
        let t = now + rng.unit() * 0.3;
        let mut m = morphs.clone();
        m.follow(&vm, &target, 0, t).unwrap();
        for &v in m.shown().indices() {
            let g = gpu[v as usize];
            let k = ((t - g.start) / T).clamp(0.0, 1.0);
            let p = if k >= 1.0 {
                g.to
            } else {
                g.from + (g.to - g.from) * k
            };
            assert_eq!(p, m.position(v, t), "request {request}: vertex {v}");
        }
    }
}

/// A mesh whose further attributes follow its positions: UVs `(x, z)`, an `f32` attribute
/// equal to the position, and tangents along the position (handedness alternating by
/// vertex). Interpolated as geomorphs interpolate them, such attributes stay what the
/// morphing positions say, at every time.
fn with_position_attributes(mut mesh: IndexedMesh) -> IndexedMesh {
    use bevy_aslod::mesh::VertexAttribute;
    let p = &mesh.positions;
    mesh.uvs = Some(p.iter().map(|q| glam::Vec2::new(q.x, q.z)).collect());
    mesh.tangents = Some(
        p.iter()
            .enumerate()
            .map(|(v, q)| q.normalize().extend(if v % 2 == 0 { 1.0 } else { -1.0 }))
            .collect(),
    );
    let record: Vec<[f32; 3]> = p.iter().map(|q| q.to_array()).collect();
    mesh.attributes = vec![VertexAttribute::from_f32(
        "Vertex_Place",
        988_540_917,
        &record,
    )];
    mesh
}

/// Checks that the attributes `values` (`groups`' per vertex) of `vertices` agree with their
/// shown `positions` where `drawn` says a triangle uses the vertex, and that tangents are
/// unit with their own handedness.
fn assert_attributes_follow(
    groups: &[bevy_aslod::regions::MorphGroup],
    values: &[f32],
    (vertices, drawn): (&[u32], impl Fn(usize) -> bool),
    positions: &[Vec3],
    at: &str,
) {
    use bevy_aslod::regions::MorphKind;
    let stride = groups.iter().map(|g| g.len).sum::<usize>();
    assert_eq!(groups.len(), 3, "{at}: UVs, tangents and the f32 attribute");
    assert_eq!(values.len(), vertices.len() * stride, "{at}");
    for (i, ((&g, p), record)) in vertices
        .iter()
        .zip(positions)
        .zip(values.chunks_exact(stride))
        .enumerate()
    {
        if !drawn(i) {
            continue;
        }
        for group in groups {
            let v = &record[group.offset..group.offset + group.len];
            let close = |a: f32, b: f32| (a - b).abs() <= 1e-4 * (1.0 + b.abs());
            match &group.kind {
                MorphKind::Uv => assert!(
                    close(v[0], p.x) && close(v[1], p.z),
                    "{at}: vertex {g}'s UV {v:?} at {p}"
                ),
                MorphKind::Attribute(a) => {
                    assert_eq!(a.name, "Vertex_Place");
                    assert!(
                        (0..3).all(|k| close(v[k], p[k])),
                        "{at}: vertex {g}'s attribute {v:?} at {p}"
                    );
                }
                MorphKind::Tangent => {
                    let length = Vec3::new(v[0], v[1], v[2]).length();
                    assert!((length - 1.0).abs() < 1e-4, "{at}: tangent {v:?}");
                    let own = if g % 2 == 0 { 1.0 } else { -1.0 };
                    assert_eq!(v[3], own, "{at}: vertex {g}'s handedness");
                }
            }
        }
    }
}

#[test]
fn morphing_vertices_carry_their_attributes_along() {
    // One region: a vertex on a border between regions can move with its neighbour's
    // collapse while its own region keeps it, and so its own attributes.
    let mesh = with_position_attributes(sphere(12, 16, &[0.0, 0.03], true));
    let rm = regions(&mesh, 1);
    let mut rng = Rng(0xA77E);
    let mut caches = RegionCaches::new(&rm);
    let mut morphs = Geomorphs::new(&rm, T);
    let groups = morphs.attribute_groups().to_vec();
    let (mut positions, mut values, mut indices) = (Vec::new(), Vec::new(), Vec::new());
    let mut now = 0.0f32;
    let mut moved = false;
    for round in 0..30 {
        for r in 0..rm.regions().len() {
            let count = (rng.unit() * rm.regions()[r].max_triangles() as f32) as usize;
            morphs.set_triangle_count(&rm, &mut caches, r, count, now);
        }
        now += rng.unit() * 0.2;
        morphs.update(&rm, &mut caches, now);
        moved |= morphs.is_morphing();
        for r in 0..rm.regions().len() {
            morphs.write_positions(&rm, r, now, &mut positions);
            morphs.write_attributes(&rm, r, Some(now), &mut values);
            let vertices = rm.regions()[r].global_vertices();
            caches.write_global_indices(&rm, r, &mut indices);
            let drawn = |i: usize| indices.contains(&vertices[i]);
            let at = format!("round {round}, region {r}");
            assert_attributes_follow(&groups, &values, (vertices, drawn), &positions, &at);
            // At rest, every vertex shows its own.
            morphs.write_attributes(&rm, r, None, &mut values);
            let own: Vec<Vec3> = vertices
                .iter()
                .map(|&g| mesh.positions[g as usize])
                .collect();
            assert_attributes_follow(&groups, &values, (vertices, |_| true), &own, &at);
        }
    }
    assert!(moved, "the rounds morphed");
}

#[test]
fn variable_levels_carry_their_attributes_along() {
    let mesh = with_position_attributes(sphere(16, 24, &[0.0, 0.04, -0.02, 0.01], true));
    let vm = variable(&mesh);
    let mut target = VariableCache::new(&vm);
    let mut morphs = VariableGeomorphs::new(&vm, &target, T);
    let groups = morphs.attribute_groups().to_vec();
    let n = vm.mesh().vertices().positions.len() as u32;
    let vertices: Vec<u32> = (0..n).collect();
    let (mut positions, mut values) = (Vec::new(), Vec::new());
    let mut rng = Rng(0x5EED);
    let mut now = 0.0f32;
    let mut moved = false;
    for request in 0..40 {
        now += rng.unit() * 0.2;
        random_target(&vm, &mesh, &mut target, &mut rng);
        morphs.follow(&vm, &target, usize::MAX, now).unwrap();
        moved |= morphs.is_morphing();
        morphs.write_positions(now, &mut positions);
        morphs.write_attributes(Some(now), &mut values);
        let at = format!("request {request}");
        let drawn = |i: usize| morphs.shown().indices().contains(&(i as u32));
        assert_attributes_follow(&groups, &values, (&vertices, drawn), &positions, &at);
    }
    assert!(moved, "the requests morphed");
}

/// What a vertex shader makes of `VertexMorph`'s UV and tangent ends is what the CPU path
/// writes, at any time of a morph.
#[test]
fn a_gpu_morph_interpolates_uvs_and_tangents_as_the_cpu_does() {
    use bevy_aslod::regions::MorphKind;
    let mesh = with_position_attributes(sphere(12, 16, &[0.0, 0.03], true));
    let rm = regions(&mesh, 1);
    let mut rng = Rng(0x6E0);
    let mut caches = RegionCaches::new(&rm);
    let mut morphs = Geomorphs::new(&rm, T);
    let groups = morphs.attribute_groups().to_vec();
    let uv = groups
        .iter()
        .find(|g| g.kind == MorphKind::Uv)
        .unwrap()
        .offset;
    let tangent = groups
        .iter()
        .find(|g| g.kind == MorphKind::Tangent)
        .unwrap()
        .offset;
    let (mut values, mut indices) = (Vec::new(), Vec::new());
    let mut now = 0.0f32;
    let mut moving = 0;
    for _ in 0..20 {
        let count = (rng.unit() * rm.regions()[0].max_triangles() as f32) as usize;
        morphs.set_triangle_count(&rm, &mut caches, 0, count, now);
        now += rng.unit() * 0.2;
        morphs.update(&rm, &mut caches, now);
        morphs.write_attributes(&rm, 0, Some(now), &mut values);
        caches.write_indices(&rm, 0, &mut indices);
        let stride = values.len() / rm.regions()[0].global_vertices().len();
        for &i in &indices {
            let g = rm.regions()[0].global_vertices()[i as usize];
            let v = morphs.vertex_morph(g);
            let t = ((now - v.start) / T).clamp(0.0, 1.0);
            let cpu = &values[i as usize * stride..(i as usize + 1) * stride];
            let gpu_uv = if t >= 1.0 {
                v.uv_to
            } else {
                v.uv_from.lerp(v.uv_to, t)
            };
            assert!(
                gpu_uv.distance(glam::Vec2::new(cpu[uv], cpu[uv + 1])) < 1e-5,
                "vertex {g}: UV {gpu_uv} on the GPU, {:?} on the CPU",
                &cpu[uv..uv + 2]
            );
            let dir = v.tangent_from.truncate().lerp(v.tangent_to.truncate(), t);
            let dir = if t >= 1.0 {
                v.tangent_to.truncate()
            } else {
                dir.normalize_or(v.tangent_to.truncate())
            };
            let cpu_tangent = glam::Vec4::from_slice(&cpu[tangent..tangent + 4]);
            assert!(
                dir.distance(cpu_tangent.truncate()) < 1e-5,
                "vertex {g}'s tangent"
            );
            assert_eq!(v.tangent_to.w, cpu_tangent.w, "vertex {g}'s handedness");
            moving += usize::from(v.from != v.to);
        }
    }
    assert!(moving > 0, "no vertex drawn in motion");
}
