//! The procedural mannequin: size, closed manifold skin, regions, weights, animation, and the
//! `.glb` it writes read back by this crate's importer and by the `gltf` crate.

use bevy_aslod::mannequin::{Mannequin, MannequinOptions, generate};
use bevy_aslod::mesh::load_gltf_slice;
use bevy_aslod::skin::{DEFAULT_RIGID_DELTA, Influences, SkinRegionKind, decompose};
use glam::Vec3;
use std::sync::OnceLock;

/// The paper's mannequin has 29,799 triangles; ours must be within 10 %.
const TRIANGLES: std::ops::RangeInclusive<usize> = 26_820..=32_778;

fn mannequin() -> &'static Mannequin {
    static M: OnceLock<Mannequin> = OnceLock::new();
    M.get_or_init(|| generate(&MannequinOptions::default()).expect("default options"))
}

fn glb() -> &'static [u8] {
    static G: OnceLock<Vec<u8>> = OnceLock::new();
    G.get_or_init(|| mannequin().to_glb())
}

fn influences(m: &Mannequin) -> Influences {
    Influences {
        joints: m.mesh.joints.clone().expect("joints"),
        weights: m.mesh.weights.clone().expect("weights"),
    }
}

/// Every (undirected) edge with the triangles that use it, as `(min, max, triangle, forward)`,
/// sorted.
fn edge_uses(indices: &[u32]) -> Vec<(u32, u32, usize, bool)> {
    let mut edges: Vec<(u32, u32, usize, bool)> = indices
        .chunks_exact(3)
        .enumerate()
        .flat_map(|(t, tri)| {
            (0..3).map(move |e| {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                (a.min(b), a.max(b), t, a < b)
            })
        })
        .collect();
    edges.sort_unstable();
    edges
}

#[test]
fn generating_twice_gives_the_same_bytes() {
    let again = generate(&MannequinOptions::default()).expect("default options");
    assert_eq!(&again, mannequin());
    assert!(
        again.to_glb() == glb(),
        "the .glb bytes differ between runs"
    );
}

#[test]
fn size_and_orientation() {
    let m = mannequin();
    let t = m.mesh.triangle_count();
    assert!(TRIANGLES.contains(&t), "{t} triangles");
    let (lo, hi) = m.mesh.bounds().expect("vertices");
    assert!(lo.y.abs() < 1e-5, "feet at y = {}", lo.y);
    assert!((hi.y - 1.75).abs() < 1e-4, "height {}", hi.y);
    // Symmetric about x = 0, arms out in an A-pose.
    assert!((lo.x + hi.x).abs() < 0.01, "x from {} to {}", lo.x, hi.x);
    assert!(hi.x > 0.5 && hi.x < 0.8, "span {}", hi.x);
    // Facing +Z: the toes reach further forward than the heels reach back.
    let feet: Vec<Vec3> = m
        .mesh
        .positions
        .iter()
        .copied()
        .filter(|p| p.y < 0.05)
        .collect();
    let front = feet.iter().map(|p| p.z).fold(f32::MIN, f32::max);
    let back = feet.iter().map(|p| p.z).fold(f32::MAX, f32::min);
    assert!(
        front > 0.1 && front > -back + 0.05,
        "feet from z {back} to {front}"
    );
}

#[test]
fn skin_is_closed_manifold_and_outward() {
    let m = &mannequin().mesh;
    let (v, t) = (m.vertex_count(), m.triangle_count());
    // Every edge is used by exactly two triangles, once in each direction.
    let edges = edge_uses(&m.indices);
    let mut e = 0;
    let mut edge_count = 0;
    while e < edges.len() {
        let (a, b, _, _) = edges[e];
        let mut n = e;
        while n < edges.len() && (edges[n].0, edges[n].1) == (a, b) {
            n += 1;
        }
        assert_eq!(n - e, 2, "edge {a}-{b} is used by {} triangles", n - e);
        assert_ne!(
            edges[e].3,
            edges[e + 1].3,
            "edge {a}-{b}: inconsistent winding"
        );
        edge_count += 1;
        e = n;
    }
    // Every vertex's triangles form a single fan (no pinched vertices).
    let mut around: Vec<Vec<(u32, u32)>> = vec![Vec::new(); v];
    for tri in m.indices.chunks_exact(3) {
        for c in 0..3 {
            around[tri[c] as usize].push((tri[(c + 1) % 3], tri[(c + 2) % 3]));
        }
    }
    for (vertex, fan) in around.iter().enumerate() {
        assert!(
            fan.len() >= 3,
            "vertex {vertex} has {} triangles",
            fan.len()
        );
        let mut at = fan[0].1;
        let mut steps = 1;
        while at != fan[0].0 {
            let next = fan.iter().find(|&&(a, _)| a == at).expect("closed fan");
            at = next.1;
            steps += 1;
            assert!(steps <= fan.len(), "vertex {vertex}: fan does not close");
        }
        assert_eq!(steps, fan.len(), "vertex {vertex} joins several fans");
    }
    // One closed surface of genus 0: V - E + F = 2.
    assert_eq!(
        v as i64 - edge_count as i64 + t as i64,
        2,
        "Euler characteristic"
    );
    // No degenerate triangles, and outward facing: a positive enclosed volume (in m^3, a
    // person is about 0.07).
    let mut volume = 0.0;
    for tri in m.indices.chunks_exact(3) {
        let [a, b, c] = [tri[0], tri[1], tri[2]].map(|i| m.positions[i as usize]);
        assert!((b - a).cross(c - a).length() > 1e-9, "degenerate triangle");
        volume += a.dot(b.cross(c)) / 6.0;
    }
    assert!((0.04..0.12).contains(&volume), "volume {volume} m^3");
    // Normals are unit and point outwards on average.
    let normals = m.normals.as_ref().expect("normals");
    assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
}

#[test]
fn weights_are_two_bone_and_normalised() {
    let m = mannequin();
    let weights = m.mesh.weights.as_ref().expect("weights");
    let joints = m.mesh.joints.as_ref().expect("joints");
    for (v, (w, j)) in weights.iter().zip(joints).enumerate() {
        assert!(
            w.iter().all(|x| (0.0..=1.0).contains(x)),
            "vertex {v}: {w:?}"
        );
        assert!(
            (w.iter().sum::<f32>() - 1.0).abs() < 1e-5,
            "vertex {v}: {w:?}"
        );
        assert_eq!(w[2..], [0.0, 0.0], "vertex {v} has more than two bones");
        assert!(j.iter().all(|&b| (b as usize) < m.joints.len()));
        assert!(w[0] >= w[1]);
    }
}

#[test]
fn regions_from_the_weights_are_ours() {
    let m = mannequin();
    let skin = decompose(&m.mesh.positions, &influences(m), DEFAULT_RIGID_DELTA);
    let rigid = skin.kinds.iter().filter(|k| k.is_rigid()).count();
    let deformable = skin.kinds.len() - rigid;
    assert_eq!((rigid, deformable), (10, 9), "{:?}", skin.kinds);
    assert_eq!(m.regions.len(), 19);
    // The plugin derives exactly our regions.
    for (v, &r) in skin.region_of.iter().enumerate() {
        assert_eq!(
            skin.kinds[r as usize], m.regions[m.region_of[v] as usize].kind,
            "vertex {v}"
        );
    }
    // Every region is one connected piece, and no edge joins two different rigid regions: the
    // deformable bands separate them.
    let region_count = m.regions.len();
    let mut parent: Vec<usize> = (0..m.mesh.vertex_count()).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for (a, b, _, _) in edge_uses(&m.mesh.indices) {
        let (ra, rb) = (m.region_of[a as usize], m.region_of[b as usize]);
        let (ka, kb) = (m.regions[ra as usize].kind, m.regions[rb as usize].kind);
        assert!(
            ra == rb || !(ka.is_rigid() && kb.is_rigid()),
            "rigid regions {} and {} touch",
            m.regions[ra as usize].name,
            m.regions[rb as usize].name
        );
        if ra == rb {
            let (x, y) = (find(&mut parent, a as usize), find(&mut parent, b as usize));
            parent[x] = y;
        }
        // A deformable vertex only borders rigid regions of its own two bones.
        for (k, other) in [(ka, kb), (kb, ka)] {
            if let (SkinRegionKind::Deformable { bones }, SkinRegionKind::Rigid { bone }) =
                (k, other)
            {
                assert!(bones.contains(&bone), "{k:?} touches {other:?}");
            }
        }
    }
    let mut roots = vec![Vec::new(); region_count];
    for v in 0..m.mesh.vertex_count() {
        let root = find(&mut parent, v);
        let r = m.region_of[v] as usize;
        if !roots[r].contains(&root) {
            roots[r].push(root);
        }
    }
    for (r, pieces) in roots.iter().enumerate() {
        assert_eq!(
            pieces.len(),
            1,
            "region {} has {} pieces",
            m.regions[r].name,
            pieces.len()
        );
    }
}

#[test]
fn the_animation_loops_and_bends_the_joints() {
    let m = mannequin();
    let a = &m.animation;
    assert_eq!(a.name, "Aerobics");
    assert!((a.duration() - 6.0).abs() < 1e-6);
    assert_eq!(a.rotations.len(), m.joints.len());
    for keys in &a.rotations {
        assert_eq!(keys.len(), a.times.len());
        assert_eq!(keys.first(), keys.last(), "the loop must close");
        assert!(keys.iter().all(|q| q.is_normalized()));
    }
    assert_eq!(a.root_translations.first(), a.root_translations.last());
    let max_angle = |name: &str| {
        let j = m.joints.iter().position(|j| j.name == name).expect(name);
        a.rotations[j]
            .iter()
            .map(|q| q.to_axis_angle().1)
            .fold(0.0f32, f32::max)
    };
    for name in [
        "upper_arm_L",
        "upper_arm_R",
        "forearm_L",
        "forearm_R",
        "thigh_L",
        "thigh_R",
        "shin_L",
        "shin_R",
        "chest",
    ] {
        let angle = max_angle(name);
        assert!(angle > 0.3, "{name} bends at most {angle} rad");
    }
    // Squats: the hips go down; the turn: the pelvis spins half way round.
    let lowest = a
        .root_translations
        .iter()
        .map(|t| t.y)
        .fold(f32::MAX, f32::min);
    assert!(a.root_translations[0].y - lowest > 0.15, "squat depth");
    assert!(max_angle("pelvis") > 3.0, "turn");
}

#[test]
fn the_glb_reads_back() {
    let m = mannequin();
    let bytes = glb();
    assert_eq!(bytes.len() % 4, 0);
    // This crate's importer: the skinned mesh in bind space, its skin and its regions.
    let import = load_gltf_slice(bytes, None).expect("our importer reads it");
    assert_eq!(import.report.degenerate_triangles_dropped, 0);
    assert_eq!(import.mesh.positions, m.mesh.positions);
    assert_eq!(import.mesh.indices, m.mesh.indices);
    assert_eq!(import.mesh.joints, m.mesh.joints);
    assert_eq!(import.mesh.weights, m.mesh.weights);
    assert_eq!(import.region_ids.as_deref(), Some(&m.region_of[..]));
    assert_eq!(import.skins.len(), 1);
    assert_eq!(
        import.skins[0].joints,
        (0..m.joints.len()).collect::<Vec<_>>()
    );
    for (j, matrix) in import.skins[0].inverse_bind_matrices.iter().enumerate() {
        let bind = matrix.inverse().transform_point3(Vec3::ZERO);
        assert!(bind.abs_diff_eq(m.joints[j].pivot, 1e-5), "joint {j}");
    }

    // The gltf crate: structure, names and the animation.
    let gltf = gltf::Gltf::from_slice(bytes).expect("gltf parses it");
    let doc = &gltf.document;
    assert_eq!(doc.meshes().len(), 1);
    assert_eq!(doc.meshes().next().unwrap().primitives().len(), 1);
    let names: Vec<&str> = doc.nodes().filter_map(|n| n.name()).collect();
    for joint in &m.joints {
        assert!(names.contains(&joint.name), "{}", joint.name);
    }
    let scene = doc.default_scene().expect("a default scene");
    let roots: Vec<Option<&str>> = scene.nodes().map(|n| n.name()).collect();
    assert_eq!(roots, [Some("pelvis"), Some("mannequin")]);
    let animation = doc.animations().next().expect("an animation");
    assert_eq!(animation.name(), Some("Aerobics"));
    assert_eq!(animation.channels().count(), m.joints.len() + 1);
    let input = animation.samplers().next().unwrap().input();
    assert_eq!(input.max().and_then(|v| v[0].as_f64()), Some(6.0));
    let position = doc.meshes().next().unwrap().primitives().next().unwrap();
    let bounds = position.bounding_box();
    assert!((bounds.max[1] - 1.75).abs() < 1e-4);
}

#[test]
fn the_committed_asset_matches() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/mannequin.glb");
    let bytes = std::fs::read(path).expect("assets/mannequin.glb (aslod mannequin -o ...)");
    let import = load_gltf_slice(&bytes, None).expect("reads");
    let m = mannequin();
    assert_eq!(import.mesh.triangle_count(), m.mesh.triangle_count());
    assert_eq!(import.mesh.vertex_count(), m.mesh.vertex_count());
    assert_eq!(import.skins.len(), 1);
    assert_eq!(import.skins[0].joints.len(), m.joints.len());
    let weights = (import.mesh.joints.unwrap(), import.mesh.weights.unwrap());
    let influences = Influences {
        joints: weights.0,
        weights: weights.1,
    };
    let skin = decompose(&import.mesh.positions, &influences, DEFAULT_RIGID_DELTA);
    assert_eq!(skin.region_count(), 19);
    let gltf = gltf::Gltf::from_slice(&bytes).expect("gltf parses it");
    assert_eq!(gltf.document.animations().count(), 1);
}

#[test]
fn bad_options_are_errors() {
    for options in [
        MannequinOptions::default().with_cell_size(0.0),
        MannequinOptions::default().with_height(f32::NAN),
        MannequinOptions::default().with_keyframe_rate(-1.0),
    ] {
        assert!(generate(&options).is_err(), "{options:?}");
    }
}
