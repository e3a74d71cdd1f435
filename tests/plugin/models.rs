//! The Bevy plugin without a GPU: region children, budget split, despawn, run-time changes.

use bevy::diagnostic::DiagnosticsStore;
use bevy::prelude::*;
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, AslodViewport, CountInBudget, LodPriority, LodRegion,
    MultiresInstance, MultiresMesh, MultiresModel, NoSharedLevels, PartitionSpec, PolygonBudget,
    RegionSplit, RegionUpload, diagnostics,
};
use bevy_aslod::regions::{GridPlane, Partition};
use glam::Vec3;

/// The benches' scene: its bumpy 16×16 patch is the terrain here.
#[allow(dead_code)]
#[path = "../../benches/common/scene.rs"]
pub(super) mod scene;

pub(super) use scene::patch as terrain;

pub(super) fn asset() -> MultiresMesh {
    let mesh = terrain(25);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 2, 2).expect("grid");
    MultiresMesh::from_indexed(&mesh, &partition).expect("valid terrain")
}

pub(super) fn app(budget: u32) -> App {
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, AssetPlugin::default(), TransformPlugin))
        .init_asset::<Mesh>()
        .init_asset::<StandardMaterial>()
        .add_plugins(AslodPlugin::default().with_budget(budget))
        // No render target in a headless app: give cameras a viewport.
        .insert_resource(AslodViewport(Vec2::new(1280.0, 720.0)));
    app
}

pub(super) fn spawn_camera(app: &mut App, at: Vec3) -> Entity {
    app.world_mut()
        .spawn((
            Camera3d::default(),
            Projection::Perspective(PerspectiveProjection {
                aspect_ratio: 16.0 / 9.0,
                ..default()
            }),
            Transform::from_translation(at).looking_at(Vec3::ZERO, Vec3::Y),
        ))
        .id()
}

pub(super) fn spawn_model(app: &mut App, handle: &Handle<MultiresMesh>, at: Vec3) -> Entity {
    let material = app
        .world_mut()
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial::default());
    app.world_mut()
        .spawn((
            MultiresModel(handle.clone()),
            MeshMaterial3d(material),
            Transform::from_translation(at),
        ))
        .id()
}

fn add_asset(app: &mut App) -> Handle<MultiresMesh> {
    app.world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(asset())
}

fn triangles(app: &mut App, model: Entity) -> usize {
    app.world()
        .get::<MultiresInstance>(model)
        .expect("the plugin added an instance")
        .triangle_count()
}

/// The asset's coarsest total: every region at its base.
fn coarsest(app: &App, handle: &Handle<MultiresMesh>) -> usize {
    app.world()
        .resource::<Assets<MultiresMesh>>()
        .get(handle)
        .expect("asset")
        .min_triangles()
}

fn stats(app: &App) -> AslodStats {
    *app.world().resource::<AslodStats>()
}

fn region_children(app: &mut App) -> Vec<(Entity, LodRegion)> {
    let mut q = app.world_mut().query::<(Entity, &LodRegion)>();
    q.iter(app.world()).map(|(e, r)| (e, *r)).collect()
}

#[test]
fn models_get_one_child_per_region_with_mesh_and_material() {
    let mut app = app(2_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    app.update();

    let children = region_children(&mut app);
    assert_eq!(children.len(), 4, "2x2 grid: four region children");
    let world = app.world();
    let material = world
        .get::<MeshMaterial3d<StandardMaterial>>(model)
        .unwrap()
        .0
        .clone();
    for (entity, _) in &children {
        assert_eq!(
            world.get::<ChildOf>(*entity).map(ChildOf::parent),
            Some(model)
        );
        let mesh = world.get::<Mesh3d>(*entity).expect("region has a Mesh3d");
        let mesh = world
            .resource::<Assets<Mesh>>()
            .get(&mesh.0)
            .expect("mesh asset");
        assert!(
            mesh.indices().is_some_and(|i| !i.is_empty()),
            "indices uploaded"
        );
        assert_eq!(
            world
                .get::<MeshMaterial3d<StandardMaterial>>(*entity)
                .unwrap()
                .0,
            material
        );
    }
    let mut regions: Vec<usize> = children.iter().map(|(_, r)| r.region).collect();
    regions.sort_unstable();
    assert_eq!(regions, vec![0, 1, 2, 3]);
    let s = stats(&app);
    assert!(s.allocated && s.regions == 4 && s.models == 1, "{s:?}");
}

#[test]
fn changing_a_models_material_changes_its_regions() {
    let mut app = app(2_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    let other = spawn_model(&mut app, &handle, Vec3::new(20.0, 0.0, 0.0));
    app.update();
    app.update();
    let region_materials =
        |app: &mut App, model: Entity| -> Vec<Option<AssetId<StandardMaterial>>> {
            let mut q = app
                .world_mut()
                .query::<(&ChildOf, Option<&MeshMaterial3d<StandardMaterial>>)>();
            q.iter(app.world())
                .filter(|(parent, _)| parent.parent() == model)
                .map(|(_, m)| m.map(|m| m.0.id()))
                .collect()
        };
    let other_before = region_materials(&mut app, other);

    let red = app
        .world_mut()
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial::from_color(Color::srgb(1.0, 0.0, 0.0)));
    app.world_mut()
        .entity_mut(model)
        .insert(MeshMaterial3d(red.clone()));
    app.update();
    let now = region_materials(&mut app, model);
    assert_eq!(now.len(), 4);
    assert!(now.iter().all(|m| *m == Some(red.id())), "{now:?}");
    assert_eq!(
        region_materials(&mut app, other),
        other_before,
        "the other model keeps its own"
    );

    app.world_mut()
        .entity_mut(model)
        .remove::<MeshMaterial3d<StandardMaterial>>();
    app.update();
    let now = region_materials(&mut app, model);
    assert!(now.iter().all(Option::is_none), "{now:?}");

    // Removed and given back in one frame: the regions end with the new one.
    let blue = app
        .world_mut()
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial::from_color(Color::srgb(0.0, 0.0, 1.0)));
    app.world_mut()
        .entity_mut(model)
        .insert(MeshMaterial3d(red));
    app.update();
    app.world_mut()
        .entity_mut(model)
        .remove::<MeshMaterial3d<StandardMaterial>>()
        .insert(MeshMaterial3d(blue.clone()));
    app.update();
    let now = region_materials(&mut app, model);
    assert!(now.iter().all(|m| *m == Some(blue.id())), "{now:?}");
}

/// A material extension with nothing of its own: enough for a second material type.
#[derive(Asset, bevy::render::render_resource::AsBindGroup, Reflect, Clone, Default)]
struct Plain {}

impl bevy::pbr::MaterialExtension for Plain {}

type Extended = bevy::pbr::ExtendedMaterial<StandardMaterial, Plain>;

#[test]
fn regions_inherit_any_material_with_a_material_plugin() {
    let mut app = app(1_000);
    app.init_asset::<Extended>()
        .add_plugins(bevy_aslod::plugin::MultiresMaterialPlugin::<Extended>::default());
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let material = app
        .world_mut()
        .resource_mut::<Assets<Extended>>()
        .add(Extended::default());
    let model = app
        .world_mut()
        .spawn((
            MultiresModel(handle),
            MeshMaterial3d(material.clone()),
            Transform::default(),
        ))
        .id();
    app.update();
    app.update();
    let regions: Vec<Entity> = app
        .world()
        .get::<MultiresInstance>(model)
        .unwrap()
        .region_entities()
        .to_vec();
    assert_eq!(regions.len(), 4);
    for &r in &regions {
        let m = app.world().get::<MeshMaterial3d<Extended>>(r);
        assert_eq!(m.map(|m| m.id()), Some(material.id()), "region {r}");
        assert!(
            app.world()
                .get::<MeshMaterial3d<StandardMaterial>>(r)
                .is_none()
        );
    }
    // Taking the material away takes it from the regions too.
    app.world_mut()
        .entity_mut(model)
        .remove::<MeshMaterial3d<Extended>>();
    app.update();
    for &r in &regions {
        assert!(
            app.world().get::<MeshMaterial3d<Extended>>(r).is_none(),
            "region {r}"
        );
    }
}

#[test]
fn uploaded_indices_match_the_caches() {
    let mut app = app(1_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    app.update();
    app.update();
    let world = app.world();
    let instance = world.get::<MultiresInstance>(model).unwrap();
    let regions = world
        .resource::<Assets<MultiresMesh>>()
        .get(&handle)
        .unwrap()
        .regions()
        .clone();
    let mut caches = instance.caches().clone();
    for (r, mesh) in instance.meshes().iter().enumerate() {
        let mesh = world.resource::<Assets<Mesh>>().get(mesh).unwrap();
        let written = mesh.indices().unwrap().len() / 3;
        assert!(written <= instance.caches().triangle_count(r));
        assert!(!instance.caches().is_dirty(r), "uploaded regions are clean");
        // Small regions get 16-bit buffers, holding what the cache writes.
        let Some(bevy::mesh::Indices::U16(uploaded)) = mesh.indices() else {
            panic!("region {r}: expected 16-bit indices");
        };
        let mut expected = Vec::new();
        caches.write_indices(&regions, r, &mut expected);
        assert!(
            expected
                .iter()
                .copied()
                .eq(uploaded.iter().map(|&i| u32::from(i))),
            "region {r}: the mesh holds other indices than the cache"
        );
    }
}

/// `AssetEvent::Modified` events of `Mesh` assets seen so far.
#[derive(Resource, Default)]
struct ModifiedMeshes(usize);

fn count_modified(mut events: MessageReader<AssetEvent<Mesh>>, mut seen: ResMut<ModifiedMeshes>) {
    seen.0 += events
        .read()
        .filter(|e| matches!(e, AssetEvent::Modified { .. }))
        .count();
}

/// Level changes over a camera that closes in: regions changed, and mesh change events seen.
fn level_changes(mode: RegionUpload) -> (usize, usize) {
    let mut app = app(3_000);
    app.insert_resource(mode)
        .init_resource::<ModifiedMeshes>()
        .add_systems(Last, count_modified);
    let handle = add_asset(&mut app);
    let camera = spawn_camera(&mut app, Vec3::new(0.0, 40.0, 80.0));
    // Meshes of their own: shared level meshes are made, not modified.
    for at in [Vec3::ZERO, Vec3::new(20.0, 0.0, 0.0)] {
        let model = spawn_model(&mut app, &handle, at);
        app.world_mut().entity_mut(model).insert(NoSharedLevels);
    }
    let mut changed = 0;
    for step in 0..12 {
        let at = Vec3::new(0.0, 40.0, 80.0) * (1.0 - step as f32 / 14.0);
        *app.world_mut().get_mut::<Transform>(camera).unwrap() =
            Transform::from_translation(at).looking_at(Vec3::ZERO, Vec3::Y);
        app.update();
        changed += stats(&app).regions_changed;
    }
    // The last frame's events reach readers a frame later.
    for _ in 0..2 {
        app.update();
        changed += stats(&app).regions_changed;
    }
    (changed, app.world().resource::<ModifiedMeshes>().0)
}

#[test]
fn level_changes_leave_the_mesh_assets_unmodified() {
    // Indices only: the meshes change without a change event, so Bevy does not re-extract
    // and re-upload their vertices.
    let (changed, modified) = level_changes(RegionUpload::IndicesOnly);
    assert!(changed >= 8, "levels changed {changed} times");
    assert_eq!(
        modified, 0,
        "{modified} mesh change events for {changed} level changes"
    );
    // The whole-mesh path raises one per change: the count above is what it looks for.
    let (changed, modified) = level_changes(RegionUpload::WholeMesh);
    assert!(changed >= 8, "levels changed {changed} times");
    assert!(
        modified >= changed,
        "{modified} events for {changed} changes"
    );
}

#[test]
fn region_entities_keep_the_box_of_their_mesh() {
    let mut app = app(1_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    spawn_model(&mut app, &handle, Vec3::ZERO);
    for _ in 0..3 {
        app.update();
    }
    let world = app.world_mut();
    let mut regions = world.query::<(&Mesh3d, &bevy::camera::primitives::Aabb)>();
    let mut n = 0;
    for (mesh, aabb) in regions.iter(world) {
        let mesh = world.resource::<Assets<Mesh>>().get(&mesh.0).unwrap();
        use bevy::camera::primitives::MeshAabb;
        assert_eq!(Some(*aabb), mesh.compute_aabb());
        n += 1;
    }
    assert_eq!(n, 4, "every region has its box");
}

#[test]
fn moving_the_camera_closer_gives_more_triangles() {
    let mut app = app(1_000);
    let handle = add_asset(&mut app);
    let near = spawn_model(&mut app, &handle, Vec3::ZERO);
    let other = spawn_model(&mut app, &handle, Vec3::new(40.0, 0.0, 0.0));
    // First close to the other model, the first one far off to the side.
    let camera = spawn_camera(&mut app, Vec3::new(40.0, 40.0, 90.0));
    *app.world_mut().get_mut::<Transform>(camera).unwrap() =
        Transform::from_xyz(40.0, 40.0, 90.0).looking_at(Vec3::new(30.0, 0.0, 0.0), Vec3::Y);
    app.update();
    let far_view = triangles(&mut app, near);

    *app.world_mut().get_mut::<Transform>(camera).unwrap() =
        Transform::from_xyz(0.0, 6.0, 14.0).looking_at(Vec3::ZERO, Vec3::Y);
    app.update();
    let close_view = triangles(&mut app, near);
    assert!(
        close_view > far_view,
        "closer camera: {close_view} triangles, farther: {far_view}"
    );
    assert!(triangles(&mut app, near) > triangles(&mut app, other));
}

/// Per region, the triangles a model of a 33×33 grid shows, flat on its left half and bumpy
/// on its right (two regions), seen from straight above under `split`.
fn halves(split: RegionSplit) -> (Vec<u32>, u64) {
    let mut positions = Vec::new();
    for z in 0..33 {
        for x in 0..33 {
            let y = if x > 16 {
                0.6 * ((x as f32 * 1.3).sin() * (z as f32 * 0.9).cos())
            } else {
                0.0
            };
            positions.push(Vec3::new(x as f32 - 16.0, y, z as f32 - 16.0));
        }
    }
    let mut indices = Vec::new();
    for z in 0..32u32 {
        for x in 0..32u32 {
            let i = z * 33 + x;
            indices.extend_from_slice(&[i, i + 33, i + 1, i + 1, i + 33, i + 34]);
        }
    }
    let mesh = bevy_aslod::mesh::IndexedMesh::new(positions, indices);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 2, 1).expect("grid");
    let asset = MultiresMesh::from_indexed(&mesh, &partition).expect("valid grid");
    let mut app = app(600);
    app.world_mut().resource_mut::<PolygonBudget>().split = split;
    let handle = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(asset);
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    let camera = spawn_camera(&mut app, Vec3::ZERO);
    *app.world_mut().get_mut::<Transform>(camera).unwrap() =
        Transform::from_xyz(0.0, 40.0, 0.0).looking_at(Vec3::ZERO, Vec3::Z);
    app.update();
    app.update();
    let counts = app
        .world()
        .get::<MultiresInstance>(model)
        .expect("an instance")
        .targets()
        .to_vec();
    (counts, stats(&app).triangles)
}

/// `RegionSplit::ScreenError` (the default) gives a model's triangles to the region whose
/// shape needs them; `Area` splits them by size on screen alone. Both within the budget.
#[test]
fn a_model_shares_its_triangles_by_error_unless_told_by_area() {
    let (by_error, total_error) = halves(RegionSplit::default());
    let (by_area, total_area) = halves(RegionSplit::Area);
    assert!(
        total_error <= 600 && total_area <= 600,
        "{total_error}, {total_area}"
    );
    let (flat, bumpy) = (by_error[0], by_error[1]);
    assert!(bumpy > 4 * flat, "by error: flat {flat}, bumpy {bumpy}");
    let (flat, bumpy) = (by_area[0], by_area[1]);
    assert!(
        flat.abs_diff(bumpy) * 5 < flat + bumpy,
        "by area, as large on screen: flat {flat}, bumpy {bumpy}"
    );
}

#[test]
fn models_out_of_view_stay_coarse_and_those_in_view_get_the_budget() {
    let mut app = app(100_000);
    let handle = add_asset(&mut app);
    // The camera at z = 40 looks at the origin (towards -z).
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 40.0));
    let seen = spawn_model(&mut app, &handle, Vec3::ZERO);
    let behind = spawn_model(&mut app, &handle, Vec3::new(0.0, 0.0, 80.0));
    let beside = spawn_model(&mut app, &handle, Vec3::new(400.0, 0.0, 0.0));
    app.update();
    let coarsest = coarsest(&app, &handle);
    assert!(
        triangles(&mut app, seen) > coarsest,
        "the model in view gets detail"
    );
    assert_eq!(triangles(&mut app, behind), coarsest, "behind the camera");
    assert_eq!(triangles(&mut app, beside), coarsest, "far off to the side");
}

#[test]
fn models_off_the_view_axis_are_seen() {
    // Before `camera_system` runs, `Camera::clip_from_view` is the identity; the projection
    // must be used instead, or only models on the view axis would count.
    let mut app = app(100_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 40.0));
    let side = spawn_model(&mut app, &handle, Vec3::new(18.0, 0.0, 0.0));
    app.update();
    let coarsest = coarsest(&app, &handle);
    assert!(
        triangles(&mut app, side) > coarsest,
        "a visible model off the axis gets detail"
    );
}

#[test]
fn flattened_and_mirrored_models_are_seen() {
    // A zero scale on one axis has no model space to move the camera into: such a model
    // (still drawn, as a sheet) is measured with world-space boxes instead.
    let mut app = app(100_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 40.0));
    let flat = spawn_model(&mut app, &handle, Vec3::new(-10.0, 0.0, 0.0));
    let mirrored = spawn_model(&mut app, &handle, Vec3::new(10.0, 0.0, 0.0));
    app.world_mut().get_mut::<Transform>(flat).unwrap().scale = Vec3::new(1.0, 0.0, 1.0);
    app.world_mut()
        .get_mut::<Transform>(mirrored)
        .unwrap()
        .scale = Vec3::new(-1.0, 1.0, 1.0);
    app.update();
    let coarsest = coarsest(&app, &handle);
    assert!(
        triangles(&mut app, flat) > coarsest,
        "the flattened model gets detail"
    );
    assert!(
        triangles(&mut app, mirrored) > coarsest,
        "the mirrored model gets detail"
    );
}

#[test]
fn total_stays_within_the_budget_every_frame() {
    const P: u32 = 1_200;
    let mut app = app(P);
    let handle = add_asset(&mut app);
    let models: Vec<Entity> = (0..3)
        .map(|i| spawn_model(&mut app, &handle, Vec3::new(i as f32 * 20.0, 0.0, 0.0)))
        .collect();
    let camera = spawn_camera(&mut app, Vec3::new(0.0, 30.0, 80.0));
    for frame in 0..30 {
        let angle = frame as f32 * 0.2;
        let at = Vec3::new(angle.cos() * 40.0, 8.0 + frame as f32, angle.sin() * 40.0);
        *app.world_mut().get_mut::<Transform>(camera).unwrap() =
            Transform::from_translation(at).looking_at(Vec3::new(20.0, 0.0, 0.0), Vec3::Y);
        app.update();
        let total: usize = models.iter().map(|&m| triangles(&mut app, m)).sum();
        assert!(total <= P as usize, "frame {frame}: {total} > {P}");
        assert_eq!(stats(&app).triangles, total as u64);
    }
    let total: usize = models.iter().map(|&m| triangles(&mut app, m)).sum();
    assert!(total > P as usize / 2, "the budget is used: {total}");
}

#[test]
fn despawning_a_model_removes_its_regions_and_meshes() {
    let mut app = app(2_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    let keep = spawn_model(&mut app, &handle, Vec3::new(30.0, 0.0, 0.0));
    app.update();
    assert_eq!(region_children(&mut app).len(), 8);
    let meshes_before = app.world().resource::<Assets<Mesh>>().len();
    assert_eq!(meshes_before, 8);

    app.world_mut().despawn(model);
    app.update();
    let left = region_children(&mut app);
    assert_eq!(left.len(), 4, "only the other model's regions are left");
    for (e, _) in left {
        assert_eq!(
            app.world().get::<ChildOf>(e).map(ChildOf::parent),
            Some(keep)
        );
    }
    assert_eq!(
        app.world().resource::<Assets<Mesh>>().len(),
        4,
        "meshes removed"
    );
}

#[test]
fn changing_the_budget_at_run_time_changes_the_total() {
    let mut app = app(2_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let a = spawn_model(&mut app, &handle, Vec3::ZERO);
    let b = spawn_model(&mut app, &handle, Vec3::new(-20.0, 0.0, 0.0));
    app.update();
    let before = triangles(&mut app, a) + triangles(&mut app, b);
    assert!(before <= 2_000);

    app.world_mut().resource_mut::<PolygonBudget>().total = 500;
    app.update();
    let after = triangles(&mut app, a) + triangles(&mut app, b);
    assert!(after <= 500, "{after} > 500");
    assert!(after < before, "{after} !< {before}");
    assert_eq!(stats(&app).budget, 500);
}

#[test]
fn conventional_meshes_count_against_the_budget() {
    let mut app = app(1_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    // 200 triangles of fixed cost.
    let positions: Vec<[f32; 3]> = (0..600).map(|i| [i as f32, (i % 3) as f32, 0.0]).collect();
    let mesh = Mesh::new(
        bevy::mesh::PrimitiveTopology::TriangleList,
        bevy::asset::RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions);
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    app.world_mut().spawn((Mesh3d(mesh), CountInBudget));
    app.update();
    assert_eq!(stats(&app).fixed_cost, 200);
    assert!(triangles(&mut app, model) <= 800);
}

#[test]
fn without_a_camera_nothing_is_allocated_and_models_stay_coarse() {
    let mut app = app(100_000);
    let handle = add_asset(&mut app);
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    app.update();
    assert!(!stats(&app).allocated);
    let coarsest = coarsest(&app, &handle);
    assert_eq!(triangles(&mut app, model), coarsest);
}

#[test]
fn zero_priority_keeps_a_model_coarse() {
    let mut app = app(2_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    app.world_mut().entity_mut(model).insert(LodPriority(0.0));
    app.update();
    let coarsest = coarsest(&app, &handle);
    assert_eq!(triangles(&mut app, model), coarsest);
}

#[test]
fn a_zero_budget_is_skipped_not_a_panic() {
    let mut app = app(0);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    spawn_model(&mut app, &handle, Vec3::ZERO);
    app.update();
    assert!(!stats(&app).allocated);
}

#[test]
fn diagnostics_are_published() {
    let mut app = app(2_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    spawn_model(&mut app, &handle, Vec3::ZERO);
    app.update();
    app.update();
    let store = app.world().resource::<DiagnosticsStore>();
    for path in [
        &diagnostics::TRIANGLES,
        &diagnostics::BUDGET,
        &diagnostics::ALLOCATION_MS,
        &diagnostics::UPDATE_MS,
        &diagnostics::REGIONS_CHANGED,
    ] {
        let d = store
            .get(path)
            .unwrap_or_else(|| panic!("{path:?} registered"));
        assert!(d.measurement().is_some(), "{path:?} measured");
    }
    let tris = store.get(&diagnostics::TRIANGLES).unwrap().value().unwrap();
    assert!(tris > 0.0 && tris <= 2_000.0);
}

#[test]
fn bad_bevy_meshes_are_errors() {
    let mesh = Mesh::new(
        bevy::mesh::PrimitiveTopology::LineList,
        bevy::asset::RenderAssetUsages::default(),
    );
    assert!(MultiresMesh::from_bevy_mesh(&mesh, PartitionSpec::Single).is_err());
    let empty = Mesh::new(
        bevy::mesh::PrimitiveTopology::TriangleList,
        bevy::asset::RenderAssetUsages::default(),
    );
    assert!(MultiresMesh::from_bevy_mesh(&empty, PartitionSpec::Clusters(4)).is_err());
}

#[test]
fn from_bevy_mesh_builds_regions() {
    let mesh = Mesh::from(Plane3d::default().mesh().size(8.0, 8.0).subdivisions(15));
    let asset = MultiresMesh::from_bevy_mesh(
        &mesh,
        PartitionSpec::Grid {
            plane: GridPlane::XZ,
            nx: 2,
            ny: 2,
        },
    )
    .expect("a plane is valid");
    assert_eq!(asset.region_count(), 4);
    assert_eq!(asset.obbs().len(), 4);
    assert_eq!(asset.max_triangles(), 2 * 16 * 16);
}

#[test]
fn build_async_gives_the_same_regions() {
    let mesh = terrain(25);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 2, 2).expect("grid");
    let task = MultiresMesh::build_async(mesh, partition);
    let built = bevy::tasks::block_on(task).expect("valid terrain");
    let direct = asset();
    assert_eq!(built.regions().as_ref(), direct.regions().as_ref());
    assert_eq!(built.obbs().len(), 4);
}

#[test]
fn hot_reloading_the_asset_rebuilds_the_regions() {
    let mut app = app(5_000);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let handle = add_asset(&mut app);
    spawn_model(&mut app, &handle, Vec3::ZERO);
    app.update();
    assert_eq!(region_children(&mut app).len(), 4, "2x2 grid");
    // Replace the asset in place with a 3x3 partition of the same terrain.
    let mesh = terrain(25);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 3, 3).expect("grid");
    let reloaded = MultiresMesh::from_indexed(&mesh, &partition).expect("valid terrain");
    app.world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .insert(handle.id(), reloaded)
        .expect("the handle's asset exists");
    app.update();
    app.update();
    assert_eq!(
        region_children(&mut app).len(),
        9,
        "the model shows the reloaded asset's regions"
    );
    assert_eq!(
        app.world().resource::<Assets<Mesh>>().len(),
        9,
        "old region meshes freed"
    );
}

/// Every public component and resource is in the type registry with its `Component` or
/// `Resource` data and `Default`, so an inspector can show, edit and add it.
#[test]
fn public_components_and_resources_are_reflected() {
    use bevy::ecs::reflect::{ReflectComponent, ReflectResource};
    use bevy::reflect::std_traits::ReflectDefault;
    use bevy_aslod::plugin::{
        AslodOverlay, FullDetail, Geomorph, GpuGeomorph, MultiresScene, MultiresSceneModels,
        MultiresSkin, MultiresSourceMesh, OverlayLabel, RefineCamera, RegionUploadStats,
        SharedLevels, VariableLevel, ViewDependent,
    };
    use std::any::TypeId;

    let app = app(1_000);
    let registry = app.world().resource::<AppTypeRegistry>().read();
    let components = [
        (TypeId::of::<MultiresModel>(), "MultiresModel"),
        (TypeId::of::<LodPriority>(), "LodPriority"),
        (TypeId::of::<LodRegion>(), "LodRegion"),
        (TypeId::of::<CountInBudget>(), "CountInBudget"),
        (TypeId::of::<VariableLevel>(), "VariableLevel"),
        (TypeId::of::<Geomorph>(), "Geomorph"),
        (TypeId::of::<GpuGeomorph>(), "GpuGeomorph"),
        (TypeId::of::<SharedLevels>(), "SharedLevels"),
        (TypeId::of::<ViewDependent>(), "ViewDependent"),
        (TypeId::of::<RefineCamera>(), "RefineCamera"),
        (TypeId::of::<MultiresScene>(), "MultiresScene"),
        (TypeId::of::<MultiresSceneModels>(), "MultiresSceneModels"),
        (TypeId::of::<MultiresSourceMesh>(), "MultiresSourceMesh"),
        (TypeId::of::<MultiresSkin>(), "MultiresSkin"),
        (TypeId::of::<OverlayLabel>(), "OverlayLabel"),
    ];
    let resources = [
        (TypeId::of::<PolygonBudget>(), "PolygonBudget"),
        (TypeId::of::<FullDetail>(), "FullDetail"),
        (TypeId::of::<AslodOverlay>(), "AslodOverlay"),
        (TypeId::of::<AslodStats>(), "AslodStats"),
        (TypeId::of::<AslodViewport>(), "AslodViewport"),
        (TypeId::of::<RegionUpload>(), "RegionUpload"),
        (TypeId::of::<RegionUploadStats>(), "RegionUploadStats"),
    ];
    for (id, name) in components {
        let ty = registry
            .get(id)
            .unwrap_or_else(|| panic!("{name} is not registered"));
        assert!(
            ty.data::<ReflectComponent>().is_some(),
            "{name}: reflect(Component)"
        );
        assert!(
            ty.data::<ReflectDefault>().is_some(),
            "{name}: reflect(Default)"
        );
    }
    for (id, name) in resources {
        let ty = registry
            .get(id)
            .unwrap_or_else(|| panic!("{name} is not registered"));
        assert!(
            ty.data::<ReflectResource>().is_some(),
            "{name}: reflect(Resource)"
        );
        assert!(
            ty.data::<ReflectDefault>().is_some(),
            "{name}: reflect(Default)"
        );
    }
}

/// The messages of type `M` written in the last two updates.
fn messages<M: Message + Clone>(app: &App) -> Vec<M> {
    let messages = app.world().resource::<Messages<M>>();
    messages.get_cursor().read(messages).cloned().collect()
}

#[test]
fn changing_a_models_handle_rebuilds_it() {
    use bevy_aslod::plugin::MultiresModelReady;
    let mut app = app(2_000);
    let first = add_asset(&mut app);
    let mesh = terrain(25);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 3, 3).unwrap();
    let second = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(MultiresMesh::from_indexed(&mesh, &partition).unwrap());
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let model = spawn_model(&mut app, &first, Vec3::ZERO);
    app.update();
    assert_eq!(region_children(&mut app).len(), 4);
    let ready = messages::<MultiresModelReady>(&app);
    assert_eq!(ready.len(), 1);
    assert_eq!((ready[0].model, ready[0].asset), (model, first.id()));

    app.world_mut()
        .entity_mut(model)
        .insert(MultiresModel(second.clone()));
    app.update();
    app.update();
    assert_eq!(region_children(&mut app).len(), 9, "the old regions went");
    let instance = app.world().get::<MultiresInstance>(model).unwrap();
    assert_eq!(instance.region_entities().len(), 9);
    let ready = messages::<MultiresModelReady>(&app);
    assert_eq!(ready.last().map(|m| m.asset), Some(second.id()));
    // The same handle again changes nothing.
    let before = instance.region_entities().to_vec();
    app.world_mut()
        .entity_mut(model)
        .insert(MultiresModel(second));
    app.update();
    let instance = app.world().get::<MultiresInstance>(model).unwrap();
    assert_eq!(instance.region_entities(), &before[..]);
}

#[test]
fn a_model_whose_asset_fails_to_load_is_reported() {
    use bevy_aslod::plugin::MultiresBuildFailed;
    let mut app = app(2_000);
    let handle: Handle<MultiresMesh> = app
        .world()
        .resource::<AssetServer>()
        .load("no-such-file.mrm");
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    let mut cursor = app
        .world()
        .resource::<Messages<MultiresBuildFailed>>()
        .get_cursor();
    let mut read = |app: &App| -> Vec<MultiresBuildFailed> {
        let messages = app.world().resource::<Messages<MultiresBuildFailed>>();
        cursor.read(messages).cloned().collect()
    };
    let mut failed = Vec::new();
    for _ in 0..500 {
        app.update();
        failed.extend(read(&app));
        if !failed.is_empty() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    assert_eq!(failed.len(), 1, "{failed:?}");
    assert_eq!(failed[0].entity, model);
    assert!(
        failed[0].error.contains("no-such-file.mrm"),
        "{}",
        failed[0].error
    );
    // Once per model and asset.
    for _ in 0..5 {
        app.update();
        assert!(read(&app).is_empty());
    }
}

/// Two models, `near` in front of a second camera and `far` seen by the first, under one
/// budget; `setup` changes the second camera and `near`. Returns the triangles of both.
fn two_cameras(setup: impl FnOnce(&mut App, Entity, Entity)) -> (usize, usize) {
    let mut app = app(1_500);
    let handle = add_asset(&mut app);
    let first = spawn_camera(&mut app, Vec3::new(100.0, 10.0, 20.0));
    app.world_mut().entity_mut(first).insert(
        Transform::from_xyz(100.0, 10.0, 20.0).looking_at(Vec3::new(100.0, 0.0, 0.0), Vec3::Y),
    );
    let far = spawn_model(&mut app, &handle, Vec3::new(100.0, 0.0, 0.0));
    let near = spawn_model(&mut app, &handle, Vec3::ZERO);
    let second = spawn_camera(&mut app, Vec3::new(0.0, 3.0, 6.0));
    setup(&mut app, second, near);
    for _ in 0..3 {
        app.update();
    }
    (triangles(&mut app, near), triangles(&mut app, far))
}

#[test]
fn cameras_opt_out_weigh_their_share_and_respect_render_layers() {
    use bevy::camera::visibility::RenderLayers;
    use bevy_aslod::plugin::{LodCameraWeight, NoLodAllocation};
    let both = two_cameras(|_, _, _| {});
    let without = two_cameras(|app, second, _| {
        app.world_mut().despawn(second);
    });
    assert!(
        both.0 > without.0,
        "the second camera asks for detail: {both:?} {without:?}"
    );
    let opted_out = two_cameras(|app, second, _| {
        app.world_mut().entity_mut(second).insert(NoLodAllocation);
    });
    assert_eq!(opted_out, without, "a camera marked out changes nothing");
    let zero = two_cameras(|app, second, _| {
        app.world_mut()
            .entity_mut(second)
            .insert(LodCameraWeight(0.0));
    });
    assert_eq!(zero, without);
    let half = two_cameras(|app, second, _| {
        app.world_mut()
            .entity_mut(second)
            .insert(LodCameraWeight(0.01));
    });
    assert!(
        half.0 < both.0 && half.0 >= without.0,
        "{half:?} {both:?} {without:?}"
    );

    // On layer 1, `near` is weighed by a camera that renders layer 1 only, and its regions
    // take its layers.
    let mut app = app(1_500);
    let handle = add_asset(&mut app);
    let model = spawn_model(&mut app, &handle, Vec3::ZERO);
    let camera = spawn_camera(&mut app, Vec3::new(0.0, 3.0, 6.0));
    app.world_mut()
        .entity_mut(model)
        .insert(RenderLayers::layer(1));
    app.update();
    app.update();
    assert_eq!(
        triangles(&mut app, model),
        coarsest(&app, &handle),
        "no camera draws it"
    );
    for (region, _) in region_children(&mut app) {
        assert_eq!(
            app.world().get::<RenderLayers>(region),
            Some(&RenderLayers::layer(1))
        );
    }
    app.world_mut()
        .entity_mut(camera)
        .insert(RenderLayers::layer(1));
    app.update();
    app.update();
    assert!(triangles(&mut app, model) > coarsest(&app, &handle));
    app.world_mut().entity_mut(model).remove::<RenderLayers>();
    app.update();
    for (region, _) in region_children(&mut app) {
        assert!(app.world().get::<RenderLayers>(region).is_none());
    }
}

#[test]
fn a_frame_time_target_moves_the_budget_within_its_bounds() {
    use bevy::time::TimeUpdateStrategy;
    use bevy_aslod::budget::ControllerState;
    use std::time::Duration;
    let mut app = app(2_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    for k in 0..6 {
        spawn_model(&mut app, &handle, Vec3::new(k as f32 * 3.0 - 7.5, 0.0, 0.0));
    }
    // Above every model's coarsest level together, so the split is feasible at the minimum.
    let min = 6 * coarsest(&app, &handle) as u32 + 100;
    let max = 50_000;
    app.insert_resource(PolygonBudget::target_ms(10.0, min..=max));
    let run = |app: &mut App, frame: Duration, frames: usize| {
        app.insert_resource(TimeUpdateStrategy::ManualDuration(frame));
        for _ in 0..frames {
            app.update();
            let p = app.world().resource::<PolygonBudget>().total;
            assert!((min..=max).contains(&p), "P = {p}");
            let s = stats(app);
            if s.allocated {
                assert!(s.triangles <= u64::from(p), "{} over {p}", s.triangles);
            }
        }
        let s = stats(app);
        (
            app.world().resource::<PolygonBudget>().total,
            s.controller,
            s.target_ms,
        )
    };
    // Frames of 20 ms, slower than the 10 ms aimed at: P falls to its minimum.
    assert_eq!(
        run(&mut app, Duration::from_millis(20), 60),
        (min, ControllerState::AtMinimum, 10.0)
    );
    // Frames of 2 ms: P rises to its maximum (about 1.25× a frame: 30 frames from the bottom).
    assert_eq!(
        run(&mut app, Duration::from_millis(2), 60),
        (max, ControllerState::AtMaximum, 10.0)
    );
    // Within the dead band it holds.
    let held = run(&mut app, Duration::from_micros(10_100), 60);
    let again = run(&mut app, Duration::from_micros(10_100), 10);
    assert_eq!(held.0, again.0);
    assert_eq!(again.1, ControllerState::Steady);
    // Without a target, `total` is the app's again.
    app.world_mut().resource_mut::<PolygonBudget>().frame_target = None;
    app.world_mut().resource_mut::<PolygonBudget>().total = 1_234;
    app.update();
    assert_eq!(app.world().resource::<PolygonBudget>().total, 1_234);
    assert_eq!(stats(&app).target_ms, 0.0);
}

/// A GPU span's time, fed into the store each frame as `RenderDiagnosticsPlugin` would.
#[derive(Resource, Clone, Copy)]
struct FakeGpu(Option<f64>);

fn feed_gpu(gpu: Res<FakeGpu>, mut store: ResMut<bevy::diagnostic::DiagnosticsStore>) {
    use bevy::diagnostic::{Diagnostic, DiagnosticMeasurement, DiagnosticPath};
    let Some(ms) = gpu.0 else { return };
    // A top-level span, counted; a nested one, which is part of it, and a CPU one, not.
    for (path, value) in [
        ("render/main_pass/elapsed_gpu", ms),
        ("render/main_pass/shadows/elapsed_gpu", 50.0),
        ("render/main_pass/elapsed_cpu", 50.0),
    ] {
        let path = DiagnosticPath::new(path);
        if store.get(&path).is_none() {
            store.add(Diagnostic::new(path.clone()));
        }
        store
            .get_mut(&path)
            .expect("added")
            .add_measurement(DiagnosticMeasurement {
                time: bevy::platform::time::Instant::now(),
                value,
            });
    }
}

#[test]
fn gpu_timestamps_drive_the_target_when_they_come() {
    use bevy::time::TimeUpdateStrategy;
    use bevy_aslod::plugin::FrameSource;
    use std::time::Duration;
    let mut app = app(2_000);
    let handle = add_asset(&mut app);
    spawn_camera(&mut app, Vec3::new(0.0, 10.0, 20.0));
    spawn_model(&mut app, &handle, Vec3::ZERO);
    let (min, max) = (coarsest(&app, &handle) as u32 + 100, 50_000);
    app.insert_resource(PolygonBudget::target_ms(10.0, min..=max))
        .insert_resource(FakeGpu(None))
        .add_systems(PreUpdate, feed_gpu)
        // Frames of 20 ms by the wall clock, as under a 50 Hz vsync.
        .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
            20,
        )));
    let run = |app: &mut App, frames: usize| {
        for _ in 0..frames {
            app.update();
            let p = app.world().resource::<PolygonBudget>().total;
            assert!((min..=max).contains(&p), "P = {p}");
        }
        let s = stats(app);
        (
            app.world().resource::<PolygonBudget>().total,
            s.frame_source,
        )
    };
    // The wall time alone: 20 ms against 10, P falls to its minimum.
    assert_eq!(run(&mut app, 60), (min, FrameSource::FrameDelta));
    // The GPU takes 2 ms (the 50 ms nested and CPU spans are not counted): P rises to its
    // maximum although every frame still lasts 20 ms.
    app.world_mut().resource_mut::<FakeGpu>().0 = Some(2.0);
    assert_eq!(run(&mut app, 60), (max, FrameSource::GpuTimestamps));
    assert!(stats(&app).frame_ms < 5.0, "{}", stats(&app).frame_ms);
    // The timestamps stop: after a few frames the wall time is read again.
    app.world_mut().resource_mut::<FakeGpu>().0 = None;
    assert_eq!(run(&mut app, 60), (min, FrameSource::FrameDelta));
}
