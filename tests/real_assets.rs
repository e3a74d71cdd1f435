//! Real assets reduce: every mesh and every primitive in `../shared/testdata` comes down to at
//! most max(2 % of its triangles, 64) at its coarsest level, each level is a subset of the
//! source's vertices, and the full detail comes back exactly. Flat-shaded meshes (every
//! corner its own vertex) reduce too.

mod common;

use bevy_aslod::mesh::{IndexedMesh, load_gltf_primitives};
use bevy_aslod::multires::{BuildOptions, PolygonCache, ProgressiveMesh};
use bevy_aslod::regions::{GridPlane, Partition, RegionMesh};
use common::triangle_multiset;
use glam::{Vec2, Vec3};

const TESTDATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/testdata");

/// The most triangles a coarsest level may keep: 2 % of the mesh, or 64.
fn bound(triangles: usize) -> usize {
    (triangles / 50).max(64)
}

/// Every file of the test data with triangles: the scans and the glTF assets.
fn assets() -> Vec<String> {
    [
        "meshes/cow.obj",
        "meshes/fandisk.obj",
        "meshes/spot.obj",
        "meshes/stanford-bunny.obj",
        "characters/RobotExpressive.glb",
        "characters/KayKit_Knight.glb",
        "characters/KayKit_Rig_Medium_General.glb",
        "textured/WaterBottle.glb",
        "textured/FlightHelmet.glb",
    ]
    .iter()
    .map(|f| format!("{TESTDATA}/{f}"))
    .collect()
}

/// Builds `mesh` and checks the coarsest level's bound, that every level names only source
/// vertices, and that full detail comes back triangle for triangle.
fn check(name: &str, mesh: &IndexedMesh) -> (usize, usize) {
    let pm = ProgressiveMesh::build(mesh, &BuildOptions::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let (full, coarsest) = (pm.max_triangles(), pm.min_triangles());
    assert!(
        coarsest <= bound(full),
        "{name}: coarsest level {coarsest} of {full} triangles, above {}",
        bound(full)
    );
    assert!(coarsest >= 1, "{name}: the coarsest level has no triangle");
    assert_eq!(
        pm.vertices().positions,
        mesh.positions,
        "{name}: vertex table"
    );
    let mut cache = PolygonCache::new(&pm);
    let vertices = mesh.vertex_count() as u32;
    for step in 0..=8 {
        let target = full - (full - coarsest) * step / 8;
        cache.set_triangle_count(&pm, target);
        assert!(
            cache.indices().iter().all(|&v| v < vertices),
            "{name}: a level names a vertex past the source's"
        );
    }
    cache.set_triangle_count(&pm, usize::MAX);
    assert_eq!(
        triangle_multiset(cache.indices()),
        triangle_multiset(&pm.full_indices()),
        "{name}: full detail after the coarsest level"
    );
    (full, coarsest)
}

/// Each whole file, and each glTF primitive on its own (as `MultiresScene` builds them, one
/// region each), reaches the bound.
#[test]
fn every_real_asset_reduces_to_a_few_dozen_triangles() {
    for path in assets() {
        let (mesh, _) = IndexedMesh::load(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let (full, coarsest) = check(&path, &mesh);
        eprintln!("{path}: {full} -> {coarsest}");
        if !path.ends_with(".glb") {
            continue;
        }
        let (primitives, _) = load_gltf_primitives(path.as_ref()).expect("loads");
        for primitive in primitives {
            let name = format!("{path} {}", primitive.key);
            let (full, coarsest) = check(&name, &primitive.mesh);
            eprintln!("  {}: {full} -> {coarsest}", primitive.key);
            // One region, as a static prop in a scene: the same bound.
            let single = Partition::grid(&primitive.mesh, GridPlane::XZ, 1, 1).expect("one cell");
            let regions = RegionMesh::build(&primitive.mesh, &single, &BuildOptions::default())
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            let min: usize = regions.regions().iter().map(|r| r.min_triangles()).sum();
            assert!(min <= bound(full), "{name}: one region keeps {min}");
        }
    }
}

/// A UV sphere of 528 triangles flat-shaded: every triangle has its own three vertices,
/// with the face's normal and its own UVs, so every edge is an attribute seam.
fn flat_shaded_sphere() -> IndexedMesh {
    let smooth = common::sphere(12, 24, &[], false);
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut indices = Vec::new();
    for t in smooth.indices.chunks_exact(3) {
        let p = [0, 1, 2].map(|k| smooth.positions[t[k] as usize]);
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
        for (k, &corner) in p.iter().enumerate() {
            indices.push(positions.len() as u32);
            positions.push(corner);
            normals.push(n);
            uvs.push(Vec2::new(k as f32 * 0.5, corner.y));
        }
    }
    let mut mesh = IndexedMesh::new(positions, indices);
    mesh.normals = Some(normals);
    mesh.uvs = Some(uvs);
    mesh
}

/// A flat-shaded mesh reduces (with the strict rules it cannot move a vertex), and its
/// coarse levels keep the sphere's size: no collapse takes it apart.
#[test]
fn a_flat_shaded_mesh_reduces() {
    let mesh = flat_shaded_sphere();
    let strict = ProgressiveMesh::build(&mesh, &BuildOptions::default().with_permissive(false))
        .expect("valid");
    assert_eq!(
        strict.min_triangles(),
        strict.max_triangles(),
        "every edge is a seam: the strict rules move nothing"
    );
    let (full, coarsest) = check("flat-shaded sphere", &mesh);
    assert!(coarsest <= 64, "{full} -> {coarsest}");
    // At a tenth, the level still spans the sphere (radius 1) on every axis.
    let pm = ProgressiveMesh::build(&mesh, &BuildOptions::default()).expect("valid");
    let mut cache = PolygonCache::new(&pm);
    cache.set_triangle_count(&pm, full / 10);
    let (lo, hi) = cache
        .indices()
        .iter()
        .map(|&v| mesh.positions[v as usize])
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(p), hi.max(p)));
    assert!(
        (hi - lo).min_element() > 1.6,
        "the tenth level shrank: {lo} .. {hi}"
    );
}

/// Near-coincident positions (float noise on a seam) weld within the default distance, so a
/// sphere whose two halves were exported a few float steps apart is one closed surface.
#[test]
fn float_noise_on_a_seam_welds() {
    let mut mesh = common::sphere(12, 24, &[0.0, 0.01, -0.005], false);
    // Split the vertices with x > 0 into copies nudged by 1e-7 (about one float step).
    let mut copy_of = vec![u32::MAX; mesh.positions.len()];
    let mut indices = mesh.indices.clone();
    for t in indices.chunks_exact_mut(3) {
        let centre: f32 = t.iter().map(|&v| mesh.positions[v as usize].x).sum();
        if centre <= 0.0 {
            continue;
        }
        for v in t.iter_mut() {
            if mesh.positions[*v as usize].x.abs() < 1e-3 {
                if copy_of[*v as usize] == u32::MAX {
                    copy_of[*v as usize] = mesh.positions.len() as u32;
                    let p = mesh.positions[*v as usize];
                    mesh.positions.push(p + Vec3::splat(1e-7));
                    if let Some(uvs) = &mut mesh.uvs {
                        let uv = uvs[*v as usize];
                        uvs.push(uv);
                    }
                }
                *v = copy_of[*v as usize];
            }
        }
    }
    mesh.indices = indices;
    let strict = BuildOptions::default().with_permissive(false);
    let welded = ProgressiveMesh::build(&mesh, &strict).expect("valid");
    let apart =
        ProgressiveMesh::build(&mesh, &strict.clone().with_weld_distance(0.0)).expect("valid");
    // Welded, the sphere is one closed surface and stops where the unsplit one does (a
    // tetrahedron, under the strict rules); apart, its two open halves each come down to a
    // triangle.
    let whole = ProgressiveMesh::build(
        &common::sphere(12, 24, &[0.0, 0.01, -0.005], false),
        &strict,
    )
    .expect("valid");
    assert_eq!(
        welded.min_triangles(),
        whole.min_triangles(),
        "welded: one closed surface"
    );
    assert_eq!(apart.min_triangles(), 2, "apart: two open halves");
}

/// Every primitive as `MultiresScene` builds it (`mrm::bake_gltf`, which `aslod bake` and
/// the scene share) reaches the bound, except skinned ones cut into several regions: one per
/// bone (rigid) and blended ones between two, each region's border held by the strict
/// rules, they stop where their borders do (RobotExpressive's hands keep 89 of 124 and 124
/// of 148, the Knight's limbs about a quarter; hierarchical regions would let the borders
/// go). Those are printed (`--nocapture`), not held to the bound.
#[test]
fn scene_primitives_reach_the_bound_unless_region_borders_hold_them() {
    use bevy_aslod::mrm::bake_gltf;
    use bevy_aslod::skin::DEFAULT_RIGID_DELTA;
    let single = |m: &IndexedMesh| Partition::grid(m, GridPlane::XZ, 1, 1);
    let mut held = 0;
    for file in [
        "characters/RobotExpressive.glb",
        "characters/KayKit_Knight.glb",
        "textured/FlightHelmet.glb",
    ] {
        let path = format!("{TESTDATA}/{file}");
        let baked = bake_gltf(
            path.as_ref(),
            &single,
            &BuildOptions::default(),
            DEFAULT_RIGID_DELTA,
            &mut |_| {},
        )
        .unwrap_or_else(|e| panic!("{path}: {e}"));
        for (key, mesh) in &baked {
            let regions = mesh.regions.regions();
            let full: usize = regions.iter().map(|r| r.max_triangles()).sum();
            let min: usize = regions.iter().map(|r| r.min_triangles()).sum();
            let by_borders = mesh.skin.is_some() && regions.len() > 1;
            eprintln!(
                "{file} {key}: {full} -> {min} in {} regions{}",
                regions.len(),
                if by_borders { ", skinned" } else { "" }
            );
            if by_borders {
                held += 1;
            } else {
                assert!(min <= bound(full), "{file} {key}: {min} of {full}");
            }
        }
    }
    // The exceptions are the skinned limbs and hands, not the whole characters.
    assert!(held <= 10, "{held} primitives held by their region borders");
}
