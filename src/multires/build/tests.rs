//! Unit tests of the build: the adjacency arena, incremental re-ranks, costs and options,
//! edge classes and local errors.

use super::{BuildOptions, Builder, CollapseOperator, Constraints, Scratch, build, settle};
use crate::mesh::{IndexedMesh, test_grid};
use crate::multires::ProgressiveMesh;
use glam::Vec3;

/// The arena adjacency behaves as a `Vec` per position under pushes past its room
/// (lists move), swap-removes and takes, in a long pseudo-random sequence.
#[test]
fn adjacency_lists_match_vecs() {
    use super::Adjacency;
    let counts = [0u32, 1, 3, 6, 2];
    let mut arena = Adjacency::with_counts(&counts);
    let mut vecs: Vec<Vec<u32>> = vec![Vec::new(); counts.len()];
    let mut state = 12345u64;
    let mut taken = Vec::new();
    for step in 0..5000u32 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let p = ((state >> 33) % counts.len() as u64) as u32;
        match (state >> 20) % 7 {
            0..=3 => {
                arena.push(p, step);
                vecs[p as usize].push(step);
            }
            4 | 5 => {
                let list = &vecs[p as usize];
                if let Some(&t) = list.get(((state >> 40) as usize) % list.len().max(1)) {
                    arena.remove(p, t);
                    let i = list.iter().position(|&s| s == t).unwrap();
                    vecs[p as usize].swap_remove(i);
                }
            }
            _ => {
                arena.take(p, &mut taken);
                assert_eq!(taken, std::mem::take(&mut vecs[p as usize]));
            }
        }
        for (q, list) in vecs.iter().enumerate() {
            assert_eq!(&arena[q], list.as_slice(), "position {q} after step {step}");
        }
    }
    assert_eq!(arena.len(), counts.len());
}

/// A triangle hanging between three closed bodies, one corner on each (found by review):
/// when one of those corners collapses onto another, the third loses both as neighbours
/// without becoming a neighbour of the survivor, so nothing re-ranks it then; its stale
/// entry must not survive the shortcuts later (`check_rerank` runs on every re-rank).
#[test]
fn a_vertex_pinched_off_by_a_collapse_is_re_ranked_in_full_later() {
    let mut positions: Vec<glam::Vec3> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    // A closed body: its faces turned outwards; returns its first vertex.
    let mut body = |corners: &[[f32; 3]], faces: &[[u32; 3]]| -> u32 {
        let base = positions.len() as u32;
        positions.extend(corners.iter().map(|&c| glam::Vec3::from_array(c)));
        let centre = corners
            .iter()
            .map(|&c| glam::Vec3::from_array(c))
            .sum::<glam::Vec3>()
            / corners.len() as f32;
        for f in faces {
            let p = |i: u32| positions[(base + i) as usize];
            let outward = (p(f[1]) - p(f[0]))
                .cross(p(f[2]) - p(f[0]))
                .dot(p(f[0]) - centre);
            let [a, b, c] = f.map(|i| base + i);
            indices.extend(if outward > 0.0 { [a, b, c] } else { [a, c, b] });
        }
        base
    };
    let tetrahedron = |x: f32, dir: f32| {
        let far = x + 3.0 * dir;
        [
            [x, 0.0, 0.0],
            [far, 1.0, 1.0],
            [far, -1.0, 1.0],
            [far, 0.0, -1.5],
        ]
    };
    let faces = [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 2, 3]];
    let u = body(&tetrahedron(0.0, -1.0), &faces);
    let w = body(&tetrahedron(0.01, 1.0), &faces);
    let octahedron = [
        [0.0, 10.0, 0.0],
        [1.0, 9.0, 0.0],
        [0.0, 9.0, 1.0],
        [-1.0, 9.0, 0.0],
        [0.0, 9.0, -1.0],
        [0.0, 8.0, 0.0],
    ];
    let eight = [
        [0, 1, 2],
        [0, 2, 3],
        [0, 3, 4],
        [0, 4, 1],
        [5, 1, 2],
        [5, 2, 3],
        [5, 3, 4],
        [5, 4, 1],
    ];
    let y = body(&octahedron, &eight);
    indices.extend([u, w, y]);
    let mesh = IndexedMesh::new(positions, indices);
    let n = mesh.triangle_count();
    build(
        &mesh,
        &BuildOptions::default(),
        &Constraints::default(),
        n,
        &mut |_, _| {},
    )
    .unwrap();
}

/// A 12 x 12 grid with bumps of up to 0.4 and an open border.
fn bumpy_grid() -> IndexedMesh {
    test_grid(12, |x, z| ((x * 7 + z * 13) % 5) as f32 * 0.1)
}

/// Every recorded move of the whole build of [`bumpy_grid`] with `options`.
fn grid_moves(options: &BuildOptions) -> Vec<(u32, u32, u32)> {
    let grid = bumpy_grid();
    let n = grid.triangle_count();
    build(&grid, options, &Constraints::default(), n, &mut |_, _| {})
        .unwrap()
        .moves
}

/// Exponents outside 0..=1 are clamped, NaN counts as 0.
#[test]
fn weight_exponents_outside_zero_to_one_are_clamped() {
    let grid = bumpy_grid();
    let moves = |weight_exponent: f64| {
        grid_moves(&BuildOptions {
            weight_exponent,
            ..BuildOptions::default()
        })
    };
    assert_eq!(moves(-1.0), moves(0.0));
    assert_eq!(moves(f64::NAN), moves(0.0));
    assert_eq!(moves(5.0), moves(1.0));
    assert_ne!(moves(1.0), moves(0.0), "the exponent matters on this grid");
    for (given, used) in [
        (-1.0, 0.0),
        (f64::NAN, 0.0),
        (f64::INFINITY, 0.0),
        (f64::NEG_INFINITY, 0.0),
        (5.0, 1.0),
        (0.3, 0.3),
    ] {
        let options = BuildOptions {
            weight_exponent: given,
            ..BuildOptions::default()
        };
        let builder = Builder::new(&grid, &options, None, None);
        assert_eq!(builder.weight_exponent, used, "{given}");
    }
}

#[test]
fn costs_scale_the_quadric_error_and_table_errors_do_not() {
    // The exponent scales the quadric error in the ranking only: the error recorded for a
    // collapse is the mean quadric error plus the local error (a build's table is checked
    // in `tests/multires.rs`).
    let grid = test_grid(10, |x, z| ((x * 3 + z * 5) % 4) as f32 * 0.2);
    let options = BuildOptions {
        weight_exponent: 1.0,
        ..BuildOptions::default()
    };
    let mut builder = Builder::new(&grid, &options, None, None);
    builder.fill_quadrics();
    let mut fan = Vec::new();
    let (mut checked, mut apart) = (0, 0);
    for u in 0..builder.adj.len() as u32 {
        if builder.pos[u as usize] != u || builder.adj[u as usize].is_empty() {
            continue;
        }
        builder.fan_into(u, &mut fan);
        let w = fan[0].0;
        let Some(scaled) = builder.quadric_cost(u, w) else {
            continue;
        };
        let mean = builder.quadrics[u as usize].error(builder.points[w as usize]);
        let local = options.local_weight * builder.local_error(u, w, &fan);
        let cost = builder.cost(u, w, scaled, &fan);
        assert_eq!(builder.table_error(u, w, cost), settle(mean + local));
        let weight = builder.quadrics[u as usize].weight();
        assert!((scaled - mean * weight / builder.mean_weight).abs() <= 1e-12 * scaled.abs());
        checked += 1;
        if (weight / builder.mean_weight - 1.0).abs() > 0.1 && mean > 0.0 {
            apart += 1;
        }
    }
    assert!(checked > 50, "{checked} vertices checked");
    assert!(
        apart > 10,
        "only {apart} vertices whose scale is not about 1"
    );
}

/// Negative border weights count as 0 (they would make a vertex lighter as it absorbs
/// others, which the re-ranking relies on never happening): the same sequence as 0.
#[test]
fn negative_border_weights_count_as_zero() {
    let moves = |border_weight: f64| {
        grid_moves(&BuildOptions {
            border_weight,
            ..BuildOptions::default()
        })
    };
    assert_eq!(moves(-10.0), moves(0.0));
    assert_eq!(moves(f64::NAN), moves(0.0));
    assert_ne!(
        moves(10.0),
        moves(0.0),
        "the border weight matters on this grid"
    );
}

/// The per-position edge classification agrees with the definition, edge by edge, on
/// meshes with holes (bunny), UV seams (spot) and a hand-made seam and border.
#[test]
fn edge_classes_match_a_scan_of_every_edge() {
    use super::{Builder, EdgeClass};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/meshes");
    let mut meshes: Vec<IndexedMesh> = ["spot.obj", "stanford-bunny.obj"]
        .iter()
        .map(|name| IndexedMesh::load(dir.join(name)).expect("a test mesh").0)
        .collect();
    // Two triangles on the edge 0-1, which the second one runs as 1-3: vertex 1 is shared,
    // vertices 0 and 3 only share a position, so the edge is a seam (both ways) with the
    // attribute split at one end only; the other four edges are borders.
    //   2 --- 1
    //   |  /  |
    //  0/3 -- 4
    let square = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
    ];
    meshes.push(IndexedMesh::new(
        square.iter().map(|&p| glam::Vec3::from_array(p)).collect(),
        vec![0, 1, 2, 3, 4, 1],
    ));
    for mesh in &meshes {
        let options = BuildOptions::default();
        let builder = Builder::new(mesh, &options, None, None);
        let classes = builder.classify_edges();
        // Every directed edge by its two positions: (triangle, start vertex, end vertex).
        type Edges = Vec<(usize, u32, u32)>;
        let mut by_positions: std::collections::HashMap<(u32, u32), Edges> = Default::default();
        for (t, tri) in builder.tris.iter().enumerate() {
            for k in 0..3 {
                let (v0, v1) = (tri[k], tri[(k + 1) % 3]);
                let key = (builder.pos[v0 as usize], builder.pos[v1 as usize]);
                by_positions.entry(key).or_default().push((t, v0, v1));
            }
        }
        for (t, tri) in builder.tris.iter().enumerate() {
            for k in 0..3 {
                let (v0, v1) = (tri[k], tri[(k + 1) % 3]);
                let (p0, p1) = (builder.pos[v0 as usize], builder.pos[v1 as usize]);
                let twins: Vec<(u32, u32)> = by_positions
                    .get(&(p1, p0))
                    .into_iter()
                    .flatten()
                    .filter(|e| e.0 != t)
                    .map(|e| (e.1, e.2))
                    .collect();
                let expected = match twins.as_slice() {
                    [] => EdgeClass::Border,
                    [(w0, w1)] if (*w0, *w1) != (v1, v0) => EdgeClass::Seam,
                    _ => EdgeClass::Inner,
                };
                assert_eq!(classes[3 * t + k], expected, "triangle {t} corner {k}");
            }
        }
    }
    let small = meshes.last().unwrap();
    let options = BuildOptions::default();
    let builder = Builder::new(small, &options, None, None);
    let classes = builder.classify_edges();
    assert_eq!(classes.iter().filter(|&&c| c == EdgeClass::Seam).count(), 2);
    assert_eq!(
        classes.iter().filter(|&&c| c == EdgeClass::Border).count(),
        4
    );
}

/// Every incremental re-rank after a collapse leaves the same queued collapse as a full
/// rank would (`Builder::check_rerank` asserts it for every vertex around every
/// collapse, in test builds): on real meshes with borders and holes (bunny), UV seams
/// (spot), sharp creases (fandisk), and on regions, whose fronts take the other path.
#[test]
fn incremental_reranks_match_full_ranks() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/meshes");
    // The defaults; and without a local weight, where a vertex next to `u` takes the
    // shortcuts too, with the weight exponent's factor in its costs (the factor depends on
    // the vertex's own quadric only, which a collapse elsewhere leaves alone).
    let variants = [
        BuildOptions::default(),
        BuildOptions {
            local_weight: 0.0,
            ..BuildOptions::default()
        },
        BuildOptions {
            local_weight: 0.0,
            weight_exponent: 1.0,
            ..BuildOptions::default()
        },
    ];
    for (i, options) in variants.iter().enumerate() {
        let build_all = |mesh: &IndexedMesh| {
            let n = mesh.triangle_count();
            build(mesh, options, &Constraints::default(), n, &mut |_, _| {}).unwrap();
        };
        // The bunny with the defaults only: it is the slowest.
        let names: &[&str] = if i == 0 {
            &["spot.obj", "fandisk.obj", "stanford-bunny.obj"]
        } else {
            &["spot.obj", "fandisk.obj"]
        };
        for name in names {
            let (mesh, _) = IndexedMesh::load(dir.join(name)).expect("a test mesh");
            build_all(&mesh);
            if *name != "stanford-bunny.obj" {
                let partition = crate::regions::Partition::clusters(&mesh, 8).unwrap();
                crate::regions::RegionMesh::build(&mesh, &partition, options).unwrap();
            }
        }
        check_small_meshes(options, &build_all);
    }
}

/// [`incremental_reranks_match_full_ranks`] on small meshes.
fn check_small_meshes(options: &BuildOptions, build_all: &dyn Fn(&IndexedMesh)) {
    // A bumpy grid; the same with a UV seam down its middle (the middle column's vertices
    // doubled, the right half using the copies); a fin of three triangles on one edge
    // beside a separate quad.
    let grid = test_grid(20, |x, z| ((x * 7 + z * 13) % 5) as f32 * 0.1);
    build_all(&grid);
    let mut seamed = grid.clone();
    let copies: Vec<u32> = (0..20)
        .map(|z| {
            seamed.positions.push(grid.positions[z * 20 + 10]);
            (seamed.positions.len() - 1) as u32
        })
        .collect();
    for tri in seamed.indices.chunks_exact_mut(3) {
        if tri.iter().any(|&v| v % 20 > 10) {
            for v in tri.iter_mut() {
                if *v % 20 == 10 {
                    *v = copies[*v as usize / 20];
                }
            }
        }
    }
    assert!(super::Builder::new(&seamed, options, None, None).has_seams);
    build_all(&seamed);
    let fin = IndexedMesh::new(
        [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [5.0, 0.0, 0.0],
            [6.0, 0.0, 0.0],
            [6.0, 1.0, 0.0],
            [5.0, 1.0, 0.0],
        ]
        .map(glam::Vec3::from_array)
        .to_vec(),
        vec![0, 1, 2, 1, 0, 3, 0, 1, 4, 5, 6, 7, 5, 7, 8],
    );
    build_all(&fin);
}

#[test]
fn local_error_is_the_height_of_the_removed_vertex_over_the_moved_fan() {
    //        0 (apex, z = 1)          seen from above:      2
    //       /|\                                          / | \
    //      / | \                                       3 - 0 - 1
    //  3 -/--+--\- 1  (ring, z = 0)                      \ | /
    //                                                      4
    // Moving the apex onto 1 turns its triangles (0,2,3) and (0,3,4) into (1,2,3) and
    // (1,3,4), both in the plane z = 0: the apex goes 1 away from them, so the local error
    // is 1 (squared), and the collapse costs the (scaled) quadric error plus
    // `local_weight` times that.
    let positions = vec![Vec3::Z, Vec3::X, Vec3::Y, Vec3::NEG_X, Vec3::NEG_Y];
    let indices = vec![0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1];
    let mesh = IndexedMesh::new(positions, indices);
    let options = BuildOptions::default();
    let mut builder = Builder::new(&mesh, &options, None, None);
    builder.fill_quadrics();
    let mut fan = Vec::new();
    builder.fan_into(0, &mut fan);
    assert_eq!(builder.local_error(0, 1, &fan), 1.0);
    let quadric = builder
        .quadric_cost(0, 1)
        .expect("an inner vertex may move");
    let (cost, target, _) = builder.choose(0, false, None).expect("the apex can move");
    assert_eq!(target, 1, "four equal costs: the lowest index wins");
    assert_eq!(cost, settle(quadric + options.local_weight));
    // Moving 2 onto 1 along the open border removes (0,1,2) and turns (0,2,3) into
    // (0,1,3), in the plane y = 0, which 2 lies 1 away from: the outline's cut counts.
    builder.fan_into(2, &mut fan);
    assert_eq!(builder.local_error(2, 1, &fan), 1.0);

    // A flat grid: no collapse inside it moves a vertex off the plane of its fan.
    let grid = test_grid(4, |_, _| 0.0);
    let mut builder = Builder::new(&grid, &options, None, None);
    builder.fill_quadrics();
    for u in 0..grid.vertex_count() as u32 {
        builder.fan_into(u, &mut fan);
        let mut ring = Vec::new();
        let mut scratch = Scratch {
            mark: vec![0; grid.vertex_count()],
            ..Scratch::default()
        };
        builder.neighbors_into(u, &mut ring, &mut scratch);
        for w in ring {
            assert_eq!(builder.local_error(u, w, &fan), 0.0, "{u} -> {w}");
        }
    }
}

/// On a flat face every collapse costs exactly 0. Equal costs go to the target that has
/// absorbed the least, so the face does not pour into one vertex (whose averaged quadric
/// would then barely see its other sides).
#[test]
fn a_flat_face_does_not_pour_into_one_vertex() {
    let mesh = test_grid(12, |_, _| 0.0);
    let built = build(
        &mesh,
        &BuildOptions::default(),
        &Constraints::default(),
        mesh.triangle_count(),
        &mut |_, _| {},
    )
    .unwrap();
    // How many collapses each vertex absorbed over the first half of the sequence.
    let half = (built.mesh.level_count() - 1) / 2;
    let mut absorbed = vec![0u32; mesh.vertex_count()];
    for &(step, _, new) in &built.moves {
        if (step as usize) < half {
            absorbed[new as usize] += 1;
        }
    }
    let most = *absorbed.iter().max().unwrap();
    assert!(
        most <= 8,
        "one vertex absorbed {most} of the first {half} collapses"
    );
}

/// The regularization makes a flat face collapse its shortest edges first: on a grid
/// stretched threefold along z, every early collapse runs along x (length 1). Without it
/// every collapse on the face costs 0, and the order comes from the tie-breaks alone.
#[test]
fn regularization_collapses_short_edges_first() {
    let mut mesh = test_grid(9, |_, _| 0.0);
    for p in &mut mesh.positions {
        p.z *= 3.0;
    }
    let run = |regularization| {
        let options = BuildOptions {
            regularization,
            ..BuildOptions::default()
        };
        let built = build(
            &mesh,
            &options,
            &Constraints::default(),
            mesh.triangle_count(),
            &mut |_, _| {},
        )
        .unwrap();
        built.moves[..20]
            .iter()
            .filter(|&&(_, old, new)| {
                let d = mesh.positions[old as usize] - mesh.positions[new as usize];
                (d.length() - 1.0).abs() > 1e-6
            })
            .count()
    };
    assert_eq!(run(1e-7), 0, "a long edge collapsed among the first 20");
    assert!(run(0.0) > 0, "the test needs the regularization to matter");
}

/// With the triangle operator most steps are the second half of a triangle collapse: the
/// vertex that goes is an apex of a triangle the step before removed, and it goes onto the
/// same vertex. With edge collapses alone that is the exception.
#[test]
fn triangle_collapses_follow_their_edge_onto_the_same_vertex() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/meshes");
    let (mesh, _) = IndexedMesh::load(dir.join("cow.obj")).unwrap();
    let share = |operator| {
        let options = BuildOptions::default().with_operator(operator);
        let built = build(
            &mesh,
            &options,
            &Constraints::default(),
            mesh.triangle_count(),
            &mut |_, _| {},
        )
        .unwrap();
        // Each step's target position (moves are attribute vertices: seams move in pairs).
        let pos = crate::mesh::weld_positions(&mesh.positions).remap;
        let mut targets: Vec<(u32, u32)> = built
            .moves
            .iter()
            .map(|&(step, _, new)| (step, pos[new as usize]))
            .collect();
        targets.dedup();
        let followed = targets
            .windows(2)
            .filter(|w| w[1].0 == w[0].0 + 1 && w[1].1 == w[0].1)
            .count();
        followed as f64 / targets.len() as f64
    };
    let (edge, triangle) = (
        share(CollapseOperator::Edge),
        share(CollapseOperator::Triangle),
    );
    println!("steps that finish a triangle: edge {edge:.3}, triangle {triangle:.3}");
    assert!(triangle > 0.3, "{triangle}");
    assert!(triangle > 2.0 * edge, "{triangle} against {edge}");
}

/// A flat-shaded fan of `n` triangles around one centre on the plane y = 0: every triangle
/// its own three vertices, normals up.
fn flat_fan(n: u32) -> IndexedMesh {
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    let angle = |k: u32| std::f32::consts::TAU * (k % n) as f32 / n as f32;
    for k in 0..n {
        let (a, b) = (angle(k), angle(k + 1));
        let first = positions.len() as u32;
        indices.extend_from_slice(&[first, first + 1, first + 2]);
        positions.extend_from_slice(&[
            Vec3::ZERO,
            Vec3::new(b.cos(), 0.0, b.sin()),
            Vec3::new(a.cos(), 0.0, a.sin()),
        ]);
    }
    let mut mesh = IndexedMesh::new(positions, indices);
    mesh.normals = Some(vec![Vec3::Y; mesh.positions.len()]);
    mesh
}

/// A permissive collapse moves every attribute vertex of the vertex that goes in one step,
/// which the records hold up to 256 of: moving the centre of a flat-shaded fan onto its rim
/// is valid with 100 triangles around it, and refused with 400 (the build would fail to pack
/// its records).
#[test]
fn permissive_collapses_fit_a_steps_records() {
    for (n, fits) in [(100, true), (400, false)] {
        let mesh = flat_fan(n);
        let options = BuildOptions::default();
        let mut builder = Builder::new(&mesh, &options, None, None);
        builder.fill_quadrics();
        let (centre, rim) = (builder.pos[0], builder.pos[1]);
        assert_eq!(builder.is_valid(centre, rim), fits, "a fan of {n}");
        assert!(
            ProgressiveMesh::build(&mesh, &options).is_ok(),
            "a fan of {n}"
        );
    }
}
