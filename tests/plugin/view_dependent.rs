//! View-dependent models in the plugin: within their allocation along a moving camera,
//! coarsest out of view, back to regions when the component goes, skinned ones keep regions.

use bevy::prelude::*;
use bevy_aslod::mesh::IndexedMesh;
use bevy_aslod::multires::BuildOptions;
use bevy_aslod::plugin::{
    AslodStats, LodRegion, MultiresInstance, MultiresMesh, PartitionSpec, RefineCamera,
    VariableLevel, ViewDependent,
};
use glam::Vec3;

use super::models::{app, spawn_model as model};

const MESHES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/testdata/meshes/");

/// The cow in 8 clusters, with the refinement data (about 10 units long, 6 high).
pub(super) fn cow() -> MultiresMesh {
    let (mesh, _) = IndexedMesh::load(format!("{MESHES}cow.obj")).expect("cow.obj loads");
    let partition = PartitionSpec::Clusters(8)
        .partition(&mesh)
        .expect("partition");
    MultiresMesh::from_indexed(&mesh, &partition)
        .expect("regions build")
        .with_refinement(&mesh, &BuildOptions::default())
        .expect("refinement data builds")
}

fn camera(app: &mut App, at: Vec3, target: Vec3) -> Entity {
    app.world_mut()
        .spawn((
            Camera3d::default(),
            Projection::Perspective(PerspectiveProjection {
                aspect_ratio: 16.0 / 9.0,
                ..default()
            }),
            Transform::from_translation(at).looking_at(target, Vec3::Y),
        ))
        .id()
}

/// The cow, added to the app's assets.
fn add_cow(app: &mut App) -> Handle<MultiresMesh> {
    app.world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(cow())
}

fn instance(app: &App, entity: Entity) -> &MultiresInstance {
    app.world()
        .get::<MultiresInstance>(entity)
        .expect("an instance")
}

fn index_count(app: &App, entity: Entity) -> usize {
    let mesh = app.world().get::<Mesh3d>(entity).expect("a Mesh3d");
    app.world()
        .resource::<Assets<Mesh>>()
        .get(&mesh.0)
        .and_then(Mesh::indices)
        .map_or(0, |i| i.len())
}

#[test]
fn a_view_dependent_model_stays_within_its_allocation_along_a_moving_camera() {
    let mut app = app(3_000);
    let asset = add_cow(&mut app);
    let fine = model(&mut app, &asset, Vec3::ZERO);
    app.world_mut()
        .entity_mut(fine)
        .insert(ViewDependent::default());
    // A second, region-based model shares the budget.
    let regions = model(&mut app, &asset, Vec3::new(15.0, 0.0, 0.0));
    let cam = camera(&mut app, Vec3::new(0.0, 2.0, 20.0), Vec3::ZERO);
    let full = app
        .world()
        .resource::<Assets<MultiresMesh>>()
        .get(&asset)
        .unwrap()
        .max_triangles();
    let mut seen = Vec::new();
    for frame in 0..60 {
        // In close, out and round: the allocation and the view both change.
        let t = frame as f32 / 60.0;
        let at = Vec3::new(
            4.0 * (t * 6.0).sin(),
            0.5,
            0.6 + 4.0 * (t * 6.0).cos().abs(),
        );
        *app.world_mut().get_mut::<Transform>(cam).unwrap() =
            Transform::from_translation(at).looking_at(Vec3::ZERO, Vec3::Y);
        app.update();
        if frame < 2 {
            continue; // the level child is made, then the first allocation reaches it
        }
        let stats = *app.world().resource::<AslodStats>();
        let fine_instance = instance(&app, fine);
        let report = *fine_instance.refinement().expect("refined");
        let allocated = report.allocated.expect("a budgeted model gets a count");
        assert!(
            report.triangles <= allocated as usize,
            "frame {frame}: {} triangles over the allocation {allocated}",
            report.triangles
        );
        assert!(stats.triangles <= 3_000, "frame {frame}: {stats:?}");
        // What the child's mesh holds is what the cache says.
        let level = fine_instance
            .variable_level_entity()
            .expect("a level child");
        assert_eq!(
            index_count(&app, level),
            3 * report.triangles,
            "frame {frame}"
        );
        let shown = fine_instance.triangle_count() + instance(&app, regions).triangle_count();
        assert_eq!(stats.triangles as usize, shown, "frame {frame}");
        seen.push(report.triangles);
    }
    let (lo, hi) = (seen.iter().min().unwrap(), seen.iter().max().unwrap());
    assert!(
        hi > lo && *hi < full,
        "the level follows the view: {lo}..{hi} of {full}"
    );
    // The regions are hidden, the level is drawn, with the model's material.
    let world = app.world();
    let level = instance(&app, fine).variable_level_entity().unwrap();
    assert!(
        world
            .get::<MeshMaterial3d<StandardMaterial>>(level)
            .is_some()
    );
    for &r in instance(&app, fine).region_entities() {
        assert_eq!(world.get::<Visibility>(r), Some(&Visibility::Hidden));
    }
}

#[test]
fn a_view_dependent_model_out_of_view_goes_to_its_coarsest_level() {
    let mut app = app(100_000);
    let asset = add_cow(&mut app);
    let fine = model(&mut app, &asset, Vec3::ZERO);
    app.world_mut()
        .entity_mut(fine)
        .insert(ViewDependent::default());
    let cam = camera(&mut app, Vec3::new(0.0, 0.0, 15.0), Vec3::ZERO);
    for _ in 0..3 {
        app.update();
    }
    let vm = app
        .world()
        .resource::<Assets<MultiresMesh>>()
        .get(&asset)
        .unwrap()
        .variable()
        .unwrap()
        .clone();
    let near = instance(&app, fine).triangle_count();
    assert!(near > vm.mesh().min_triangles(), "in view: {near}");
    // Turn the camera away.
    *app.world_mut().get_mut::<Transform>(cam).unwrap() =
        Transform::from_xyz(0.0, 0.0, 15.0).looking_at(Vec3::new(0.0, 0.0, 30.0), Vec3::Y);
    app.update();
    assert_eq!(
        instance(&app, fine).triangle_count(),
        vm.mesh().min_triangles()
    );
    // A phantom camera marked for refinement drives it although it is not active.
    app.world_mut().spawn((
        Camera3d::default(),
        Camera {
            is_active: false,
            ..default()
        },
        RefineCamera,
        Transform::from_xyz(0.0, 0.0, 15.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    app.update();
    let phantom = instance(&app, fine).triangle_count();
    assert!(
        phantom > vm.mesh().min_triangles(),
        "refined for the phantom: {phantom}"
    );
}

#[test]
fn removing_view_dependent_returns_the_model_to_its_regions_without_a_leak() {
    let mut app = app(4_000);
    let asset = add_cow(&mut app);
    let m = model(&mut app, &asset, Vec3::ZERO);
    camera(&mut app, Vec3::new(0.0, 2.0, 20.0), Vec3::ZERO);
    app.update();
    app.update();
    let meshes_before = app.world().resource::<Assets<Mesh>>().len();
    let regions_before = instance(&app, m).triangle_count();
    for round in 0..3 {
        app.world_mut()
            .entity_mut(m)
            .insert(ViewDependent::default());
        app.update();
        app.update();
        assert!(instance(&app, m).refinement().is_some(), "round {round}");
        assert_eq!(
            app.world().resource::<Assets<Mesh>>().len(),
            meshes_before + 1
        );
        let mut levels = app
            .world_mut()
            .query_filtered::<Entity, With<VariableLevel>>();
        assert_eq!(levels.iter(app.world()).count(), 1);

        app.world_mut().entity_mut(m).remove::<ViewDependent>();
        app.update();
        app.update();
        assert!(instance(&app, m).refinement().is_none(), "round {round}");
        assert_eq!(
            app.world().resource::<Assets<Mesh>>().len(),
            meshes_before,
            "round {round}: the level's mesh is freed"
        );
        let mut levels = app
            .world_mut()
            .query_filtered::<Entity, With<VariableLevel>>();
        assert_eq!(levels.iter(app.world()).count(), 0, "round {round}");
        let world = app.world();
        for &r in instance(&app, m).region_entities() {
            assert_eq!(world.get::<Visibility>(r), Some(&Visibility::Inherited));
        }
        assert_eq!(
            instance(&app, m).triangle_count(),
            regions_before,
            "round {round}"
        );
    }
    let region_count = app
        .world()
        .resource::<Assets<MultiresMesh>>()
        .get(&asset)
        .unwrap()
        .region_count();
    let mut regions = app.world_mut().query::<&LodRegion>();
    assert_eq!(
        regions.iter(app.world()).count(),
        region_count,
        "the regions stay"
    );
    // Despawning a view-dependent model frees everything too.
    app.world_mut()
        .entity_mut(m)
        .insert(ViewDependent::default());
    app.update();
    app.world_mut().entity_mut(m).despawn();
    app.update();
    assert_eq!(app.world().resource::<Assets<Mesh>>().len(), 0);
}

#[test]
fn a_tolerance_only_model_counts_as_fixed_cost() {
    let mut app = app(5_000);
    let asset = add_cow(&mut app);
    let fine = model(&mut app, &asset, Vec3::ZERO);
    app.world_mut()
        .entity_mut(fine)
        .insert(ViewDependent::tolerance(2.0));
    camera(&mut app, Vec3::new(0.0, 2.0, 20.0), Vec3::ZERO);
    for _ in 0..4 {
        app.update();
    }
    let report = *instance(&app, fine).refinement().unwrap();
    assert_eq!(report.allocated, None);
    assert_eq!(report.tolerance_px, 2.0);
    let stats = *app.world().resource::<AslodStats>();
    assert_eq!(stats.fixed_cost as usize, report.triangles, "{stats:?}");
    // A finer tolerance keeps more.
    app.world_mut()
        .entity_mut(fine)
        .insert(ViewDependent::tolerance(0.25));
    app.update();
    app.update();
    assert!(instance(&app, fine).triangle_count() > report.triangles);
}

#[test]
fn with_several_cameras_a_model_refines_for_the_one_that_sees_it_largest_or_the_marked_one() {
    let mut app = app(100_000);
    let asset = add_cow(&mut app);
    let fine = model(&mut app, &asset, Vec3::ZERO);
    app.world_mut()
        .entity_mut(fine)
        .insert(ViewDependent::default().with_tolerance_px(Some(1.0)));
    let near = camera(&mut app, Vec3::new(0.0, 2.0, 15.0), Vec3::ZERO);
    let far = camera(&mut app, Vec3::new(0.0, 2.0, -60.0), Vec3::ZERO);
    let refined_for = |app: &mut App| {
        app.update();
        app.update();
        instance(app, fine).refinement().and_then(|r| r.camera)
    };
    assert_eq!(refined_for(&mut app), Some(near));
    *app.world_mut().get_mut::<Transform>(far).unwrap() =
        Transform::from_xyz(0.0, 2.0, -12.0).looking_at(Vec3::ZERO, Vec3::Y);
    assert_eq!(refined_for(&mut app), Some(far));
    app.world_mut().entity_mut(near).insert(RefineCamera);
    assert_eq!(refined_for(&mut app), Some(near));
}

#[test]
fn a_tolerance_only_model_coming_into_view_never_takes_the_others_budget() {
    let mut app = app(6_000);
    let asset = add_cow(&mut app);
    let fine = model(&mut app, &asset, Vec3::ZERO);
    app.world_mut()
        .entity_mut(fine)
        .insert(ViewDependent::tolerance(2.0));
    model(&mut app, &asset, Vec3::new(12.0, 0.0, 0.0));
    // Looking away first: the view-dependent model sits at its coarsest level.
    let cam = camera(
        &mut app,
        Vec3::new(6.0, 2.0, 25.0),
        Vec3::new(6.0, 2.0, 60.0),
    );
    for _ in 0..3 {
        app.update();
    }
    *app.world_mut().get_mut::<Transform>(cam).unwrap() =
        Transform::from_xyz(6.0, 2.0, 25.0).looking_at(Vec3::new(6.0, 0.0, 0.0), Vec3::Y);
    for frame in 0..4 {
        app.update();
        let stats = *app.world().resource::<AslodStats>();
        let shown = instance(&app, fine).triangle_count();
        assert_eq!(
            stats.fixed_cost as usize, shown,
            "frame {frame}: this frame's count"
        );
        assert!(stats.triangles <= 6_000, "frame {frame}: {stats:?}");
    }
}
