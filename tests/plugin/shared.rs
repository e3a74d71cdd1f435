//! `SharedLevels`: many instances of one asset share their level meshes, the mesh data they
//! hold does not grow with their number, and it goes when they do.

use super::models::app;
use bevy::mesh::Indices;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;
use bevy_aslod::plugin::{
    AslodStats, Geomorph, MultiresInstance, MultiresMesh, MultiresModel, MultiresSkin,
    NoSharedLevels, PolygonBudget, SharedLevels,
};
use bevy_aslod::regions::{GridPlane, Partition};

use super::models::scene;

/// A 3,200-triangle bumpy patch cut into 2×2 regions.
fn asset() -> MultiresMesh {
    let mesh = scene::patch(41);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 2, 2).expect("grid");
    MultiresMesh::from_indexed(&mesh, &partition).expect("valid terrain")
}

/// Vertex and index bytes of every `Mesh` asset (what the renderer would hold).
fn mesh_bytes(app: &App) -> usize {
    app.world()
        .resource::<Assets<Mesh>>()
        .iter()
        .map(|(_, mesh)| {
            let indices = match mesh.indices() {
                Some(Indices::U16(i)) => i.len() * 2,
                Some(Indices::U32(i)) => i.len() * 4,
                None => 0,
            };
            mesh.count_vertices() * mesh.get_vertex_size() as usize + indices
        })
        .sum()
}

/// The patch skinned to two joints: its left side to joint 0, its right side to joint 1, and
/// a band between them blending (two rigid regions and a deformable one).
fn skinned_asset() -> MultiresMesh {
    let mut mesh = scene::patch(41);
    let (joints, weights) = mesh
        .positions
        .iter()
        .map(|p| match p.x {
            x if x < -1.0 => ([0, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
            x if x > 1.0 => ([1, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
            x => ([0, 1, 0, 0], [0.5 - x * 0.5, 0.5 + x * 0.5, 0.0, 0.0]),
        })
        .unzip();
    mesh.joints = Some(joints);
    mesh.weights = Some(weights);
    MultiresMesh::from_skinned(&mesh, &[Mat4::IDENTITY; 2], 0.01).expect("a skinned patch")
}

/// [`scene`] of [`skinned_asset`]: each model with its two joints (children of the model,
/// the second raised and turned).
fn skinned_scene(n: usize, shared: bool, budget: u32) -> (App, Vec<Entity>, Entity) {
    let (mut app, models, camera) = scene_of(skinned_asset(), n, shared, budget);
    for &model in &models {
        let world = app.world_mut();
        let lower = world.spawn((Transform::default(), ChildOf(model))).id();
        let turned = Transform::from_xyz(0.0, 1.0, 0.0).with_rotation(Quat::from_rotation_z(0.3));
        let upper = world.spawn((turned, ChildOf(model))).id();
        world.entity_mut(model).insert(MultiresSkin {
            joints: vec![lower, upper],
        });
    }
    (app, models, camera)
}

/// `n` instances on a square grid 20 units apart, shared or not, and a camera above one
/// corner looking across them, so that they stand at every distance.
fn scene(n: usize, shared: bool, budget: u32) -> (App, Vec<Entity>, Entity) {
    scene_of(asset(), n, shared, budget)
}

/// [`scene`] of `asset`.
fn scene_of(
    asset: MultiresMesh,
    n: usize,
    shared: bool,
    budget: u32,
) -> (App, Vec<Entity>, Entity) {
    let mut app = app(budget);
    let handle = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(asset);
    let side = scene::side(n);
    let models = (0..n)
        .map(|i| {
            let at = Vec3::new((i % side) as f32 * 20.0, 0.0, (i / side) as f32 * 20.0);
            let mut model = app.world_mut().spawn((
                MultiresModel(handle.clone()),
                Transform::from_translation(at),
            ));
            if shared {
                model.insert(SharedLevels::default());
            } else {
                model.insert(NoSharedLevels);
            }
            model.id()
        })
        .collect();
    let camera = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            Projection::Perspective(PerspectiveProjection {
                aspect_ratio: 16.0 / 9.0,
                ..default()
            }),
            Transform::from_xyz(-10.0, 15.0, -10.0).looking_at(Vec3::new(60.0, 0.0, 60.0), Vec3::Y),
        ))
        .id();
    (app, models, camera)
}

/// Moves the camera along a short path, `frames` frames, checking the budget each one.
fn walk(app: &mut App, models: &[Entity], camera: Entity, frames: usize) {
    let budget = app.world().resource::<PolygonBudget>().total as usize;
    for frame in 0..frames {
        let t = frame as f32 / frames as f32;
        let at = Vec3::new(-10.0 + 60.0 * t, 15.0 - 8.0 * t, -10.0 + 30.0 * t);
        *app.world_mut().get_mut::<Transform>(camera).unwrap() =
            Transform::from_translation(at).looking_at(at + Vec3::new(1.0, -0.3, 1.0), Vec3::Y);
        app.update();
        let total: usize = models
            .iter()
            .map(|&m| {
                app.world()
                    .get::<MultiresInstance>(m)
                    .unwrap()
                    .triangle_count()
            })
            .sum();
        assert!(total <= budget, "frame {frame}: {total} > {budget}");
        assert_eq!(app.world().resource::<AslodStats>().triangles, total as u64);
    }
}

/// Runs frames with the camera still, so that levels rest and the meshes dropped are gone.
fn settle(app: &mut App) {
    for _ in 0..3 {
        app.update();
    }
}

/// The asset's regions at full detail, in bytes as a level mesh holds them: every vertex
/// (12 bytes of position, 12 of normal) and 16-bit indices.
fn asset_bytes() -> usize {
    let mesh = scene::patch(41);
    mesh.positions.len() * 24 + mesh.indices.len() * 2
}

#[test]
fn shared_instances_hold_mesh_data_bounded_independently_of_their_number() {
    let mut bytes = Vec::new();
    let mut drawn = Vec::new();
    for n in [10, 1_000] {
        let budget = 150 * n as u32;
        let (mut app, models, camera) = scene(n, true, budget);
        walk(&mut app, &models, camera, 12);
        settle(&mut app);
        bytes.push(mesh_bytes(&app));
        drawn.push(app.world().resource::<AslodStats>().triangles);
        assert_eq!(
            app.world().resource::<AslodStats>().shared_meshes,
            app.world().resource::<Assets<Mesh>>().len(),
            "every mesh is a shared level mesh"
        );
    }
    // Levels of a region: 3,200 / 4 triangles down its ladder of ratio 1.5 to its base.
    let levels = 12;
    let bound = asset_bytes() * levels;
    assert!(
        bytes[1].abs_diff(bytes[0]) < bound,
        "10 instances hold {} B, 1,000 hold {} B: more than {bound} B apart",
        bytes[0],
        bytes[1]
    );
    assert!(drawn[1] > 10 * drawn[0], "1,000 instances draw: {drawn:?}");

    // Without sharing, the same 1,000 hold a copy each.
    let (mut app, models, camera) = scene(1_000, false, 150_000);
    walk(&mut app, &models, camera, 2);
    let own = mesh_bytes(&app);
    assert!(
        own > 20 * bytes[1],
        "own meshes {own} B, shared {} B",
        bytes[1]
    );
}

/// The crowd's case: skinned instances that share level meshes, which Bevy skins on the GPU
/// from their joints, hold mesh data that does not grow with their number; skinned on the
/// CPU, each holds its own.
#[test]
fn shared_skinned_instances_hold_mesh_data_bounded_independently_of_their_number() {
    let mut bytes = Vec::new();
    for n in [10, 500] {
        let (mut app, models, camera) = skinned_scene(n, true, 150 * n as u32);
        walk(&mut app, &models, camera, 12);
        settle(&mut app);
        bytes.push(mesh_bytes(&app));
        let world = app.world();
        assert_eq!(
            world.resource::<AslodStats>().shared_meshes,
            world.resource::<Assets<Mesh>>().len(),
            "every mesh is a shared level mesh"
        );
        for &model in &models {
            let instance = world.get::<MultiresInstance>(model).unwrap();
            assert!(instance.is_skinned());
            for &region in instance.region_entities() {
                let skin = world.get::<SkinnedMesh>(region).expect("skinned by Bevy");
                assert!(!skin.joints.is_empty() && skin.joints.len() <= 2);
            }
        }
    }
    // Every vertex: position and normal, four joints (16-bit) and four weights.
    let mesh = scene::patch(41);
    let asset_bytes = mesh.positions.len() * 48 + mesh.indices.len() * 2;
    let bound = asset_bytes * 12;
    assert!(
        bytes[1].abs_diff(bytes[0]) < bound,
        "10 instances hold {} B, 500 hold {} B: more than {bound} B apart",
        bytes[0],
        bytes[1]
    );
    let (mut app, models, camera) = skinned_scene(500, false, 75_000);
    walk(&mut app, &models, camera, 2);
    let own = mesh_bytes(&app);
    assert!(
        own > 20 * bytes[1],
        "skinned on the CPU {own} B, shared {} B",
        bytes[1]
    );
}

#[test]
fn shared_instances_hold_no_copy_of_the_asset_index_buffer() {
    // Shared instances keep their levels alone; the asset's caches make the level meshes.
    let (mut app, models, camera) = scene(50, true, 7_500);
    walk(&mut app, &models, camera, 6);
    settle(&mut app);
    let asset_indices = scene::patch(41).indices.len() * 2;
    for &m in &models {
        let caches = app.world().get::<MultiresInstance>(m).unwrap().caches();
        assert!(!caches.holds_indices());
        assert_eq!(caches.index_bytes(), 0);
    }
    // An instance of its own holds a copy (16-bit here).
    let (mut app, models, camera) = scene(2, false, 7_500);
    walk(&mut app, &models, camera, 2);
    let caches = app
        .world()
        .get::<MultiresInstance>(models[0])
        .unwrap()
        .caches();
    assert!(caches.holds_indices());
    assert!(
        caches.index_bytes() >= asset_indices,
        "{}",
        caches.index_bytes()
    );
}

/// Resident memory per extra instance, shared or not, with the camera looking away (no
/// level mesh made): `cargo test --all-features --test plugin -- --ignored
/// memory_per_instance --nocapture`. A measurement, not a check.
#[test]
#[ignore = "a measurement: run it alone, with --nocapture"]
fn memory_per_instance() {
    for shared in [true, false] {
        let (mut app, models, camera) = scene(1_000, shared, 1_000_000);
        app.world_mut()
            .entity_mut(camera)
            .insert(Transform::from_xyz(-10.0, 15.0, -10.0).looking_to(Vec3::NEG_X, Vec3::Y));
        for _ in 0..3 {
            app.update();
        }
        let before = super::soak::resident_bytes().unwrap_or(0);
        let handle = app
            .world()
            .get::<MultiresModel>(models[0])
            .unwrap()
            .0
            .clone();
        for i in 0..4_000 {
            let mut model = app.world_mut().spawn((
                MultiresModel(handle.clone()),
                Transform::from_xyz(i as f32 * 3.0, 0.0, -50.0),
            ));
            if shared {
                model.insert(SharedLevels::default());
            } else {
                model.insert(NoSharedLevels);
            }
        }
        for _ in 0..3 {
            app.update();
        }
        let after = super::soak::resident_bytes().unwrap_or(0);
        let index_bytes = app
            .world()
            .get::<MultiresInstance>(models[0])
            .unwrap()
            .caches()
            .index_bytes();
        println!(
            "{}: {:.1} KB per extra instance (its caches' index buffers: {index_bytes} B)",
            if shared { "SharedLevels" } else { "own meshes" },
            (after.saturating_sub(before)) as f64 / 4_000.0 / 1024.0
        );
    }
}

#[test]
fn instances_at_the_same_levels_draw_the_same_mesh() {
    let (mut app, mut models, camera) = scene(16, true, 20_000);
    // Three more copies on each spot: they are allocated alike, so they show the same levels.
    let copies: Vec<(MultiresModel, Transform)> = models
        .iter()
        .map(|&m| {
            let world = app.world();
            (
                world.get::<MultiresModel>(m).unwrap().clone(),
                *world.get::<Transform>(m).unwrap(),
            )
        })
        .collect();
    for _ in 0..3 {
        for copy in &copies {
            let model = app
                .world_mut()
                .spawn((copy.clone(), SharedLevels::default()));
            models.push(model.id());
        }
    }
    walk(&mut app, &models, camera, 4);
    settle(&mut app);
    let mut distinct = std::collections::HashSet::new();
    let mut regions = 0;
    for &m in &models {
        let instance = app.world().get::<MultiresInstance>(m).unwrap();
        for (&entity, handle) in instance.region_entities().iter().zip(instance.meshes()) {
            let drawn = app.world().get::<Mesh3d>(entity).unwrap();
            assert_eq!(drawn.0.id(), handle.id(), "the region draws its level mesh");
            let mesh = app.world().resource::<Assets<Mesh>>().get(handle).unwrap();
            let indices = mesh.indices().unwrap().len();
            let region = instance.region_entities().iter().position(|&e| e == entity);
            let want = instance.caches().triangle_count(region.unwrap());
            assert_eq!(
                indices,
                3 * want,
                "a level mesh holds its level's triangles"
            );
            distinct.insert(handle.id());
            regions += 1;
        }
    }
    assert_eq!(regions, 64 * 4);
    assert!(
        distinct.len() <= regions / 4,
        "{} meshes for {regions} regions",
        distinct.len()
    );
}

#[test]
fn despawning_shared_instances_frees_their_meshes() {
    let (mut app, models, camera) = scene(100, true, 30_000);
    walk(&mut app, &models, camera, 6);
    assert!(app.world().resource::<Assets<Mesh>>().len() > 4);
    // Half go: the meshes only they showed go with them.
    for &m in &models[..50] {
        app.world_mut().despawn(m);
    }
    walk(&mut app, &models[50..], camera, 3);
    settle(&mut app);
    let shown: std::collections::HashSet<_> = models[50..]
        .iter()
        .flat_map(|&m| {
            let instance = app.world().get::<MultiresInstance>(m).unwrap();
            instance.meshes().iter().map(Handle::id).collect::<Vec<_>>()
        })
        .collect();
    assert_eq!(app.world().resource::<Assets<Mesh>>().len(), shown.len());
    assert_eq!(
        app.world().resource::<AslodStats>().shared_meshes,
        shown.len()
    );
    // The rest go: nothing is left.
    for &m in &models[50..] {
        app.world_mut().despawn(m);
    }
    settle(&mut app);
    assert_eq!(app.world().resource::<Assets<Mesh>>().len(), 0);
    assert_eq!(app.world().resource::<AslodStats>().shared_meshes, 0);
}

/// Asserts that every model in `models` draws its own meshes.
fn assert_own_meshes(app: &App, models: &[Entity]) {
    for &m in models {
        let instance = app.world().get::<MultiresInstance>(m).unwrap();
        for (&entity, handle) in instance.region_entities().iter().zip(instance.meshes()) {
            assert_eq!(
                app.world().get::<Mesh3d>(entity).unwrap().0.id(),
                handle.id()
            );
        }
    }
}

#[test]
fn no_shared_levels_gives_a_model_its_own_meshes_again() {
    let (mut app, models, camera) = scene(4, true, 8_000);
    walk(&mut app, &models, camera, 3);
    // Without `SharedLevels` four instances still share, on the default ladder.
    for &m in &models {
        app.world_mut().entity_mut(m).remove::<SharedLevels>();
    }
    walk(&mut app, &models, camera, 3);
    settle(&mut app);
    assert_eq!(
        app.world().resource::<AslodStats>().shared_meshes,
        app.world().resource::<Assets<Mesh>>().len()
    );
    for &m in &models {
        app.world_mut().entity_mut(m).insert(NoSharedLevels);
    }
    walk(&mut app, &models, camera, 3);
    settle(&mut app);
    let meshes = app.world().resource::<Assets<Mesh>>().len();
    assert_eq!(
        meshes,
        4 * 4,
        "one mesh per region per model, shared ones dropped"
    );
    assert_own_meshes(&app, &models);
    // And back.
    for &m in &models {
        app.world_mut()
            .entity_mut(m)
            .remove::<NoSharedLevels>()
            .insert(SharedLevels { ratio: 0.5 });
    }
    walk(&mut app, &models, camera, 3);
    assert_eq!(
        app.world().resource::<AslodStats>().shared_meshes,
        app.world().resource::<Assets<Mesh>>().len()
    );
}

#[test]
fn the_instances_of_an_asset_share_by_default() {
    // One instance keeps its own meshes: it shows exactly the levels it was allocated.
    let (mut app, mut models, camera) = scene(1, false, 8_000);
    app.world_mut()
        .entity_mut(models[0])
        .remove::<NoSharedLevels>();
    walk(&mut app, &models, camera, 3);
    assert_eq!(app.world().resource::<AslodStats>().shared_meshes, 0);
    assert_own_meshes(&app, &models);
    // A second instance: both share.
    let handle = app
        .world()
        .get::<MultiresModel>(models[0])
        .unwrap()
        .0
        .clone();
    models.push(
        app.world_mut()
            .spawn((
                MultiresModel(handle.clone()),
                Transform::from_xyz(20.0, 0.0, 0.0),
            ))
            .id(),
    );
    walk(&mut app, &models, camera, 4);
    settle(&mut app);
    let shared = app.world().resource::<AslodStats>().shared_meshes;
    assert!(shared > 0);
    assert_eq!(shared, app.world().resource::<Assets<Mesh>>().len());
    // A model with a geomorph keeps its own meshes (its regions morph), as does one with
    // `NoSharedLevels`.
    let morphing = app
        .world_mut()
        .spawn((
            MultiresModel(handle),
            Geomorph(0.25),
            Transform::from_xyz(0.0, 0.0, 20.0),
        ))
        .id();
    app.world_mut().entity_mut(models[1]).insert(NoSharedLevels);
    models.push(morphing);
    walk(&mut app, &models, camera, 4);
    settle(&mut app);
    assert_own_meshes(&app, &models[1..]);
    let shared = app.world().resource::<AslodStats>().shared_meshes;
    assert_eq!(shared + 2 * 4, app.world().resource::<Assets<Mesh>>().len());
    // Without its geomorph, the model shares again.
    app.world_mut().entity_mut(morphing).remove::<Geomorph>();
    walk(&mut app, &models, camera, 4);
    settle(&mut app);
    let shared = app.world().resource::<AslodStats>().shared_meshes;
    assert_eq!(shared + 4, app.world().resource::<Assets<Mesh>>().len());
}
