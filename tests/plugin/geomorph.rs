//! Geomorphs in the plugin: a camera cut makes the cow's regions change level over the
//! morph time instead of at once; the budget holds in every frame; at rest every region
//! mesh is back at its own vertex positions; removing `Geomorph` ends the morphs.

use super::models::app;
use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_aslod::plugin::{AslodStats, MultiresInstance, MultiresMesh, MultiresModel};
use bevy_aslod::prelude::*;
use bevy_aslod::regions::Partition;
use std::time::Duration;

const T: f32 = 0.25;
const BUDGET: u32 = 2_000;

fn cow() -> MultiresMesh {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/testdata/meshes/cow.obj"
    );
    let (mesh, _) = IndexedMesh::load(path).expect("the cow");
    let partition = Partition::clusters(&mesh, 8).expect("clusters");
    MultiresMesh::from_indexed(&mesh, &partition).expect("the cow builds")
}

/// Each region mesh's positions and whether they are the region's own.
fn at_rest(app: &App, model: Entity, asset: &MultiresMesh) -> Vec<bool> {
    let instance = app
        .world()
        .get::<MultiresInstance>(model)
        .expect("instance");
    let meshes = app.world().resource::<Assets<Mesh>>();
    instance
        .region_entities()
        .iter()
        .enumerate()
        .map(|(r, &e)| {
            let mesh = meshes
                .get(&app.world().get::<Mesh3d>(e).unwrap().0)
                .unwrap();
            let Some(VertexAttributeValues::Float32x3(p)) =
                mesh.attribute(Mesh::ATTRIBUTE_POSITION)
            else {
                panic!("positions");
            };
            let own = &asset.regions().regions()[r]
                .progressive_mesh()
                .vertices()
                .positions;
            p.iter().zip(own).all(|(a, b)| *a == b.to_array())
        })
        .collect()
}

#[test]
fn a_camera_cut_morphs_under_the_budget_and_comes_to_rest() {
    let mut app = app(BUDGET);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(
        1.0 / 60.0,
    )));
    let asset = cow();
    let handle = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(asset.clone());
    let model = app
        .world_mut()
        .spawn((MultiresModel(handle), Geomorph(T), Transform::default()))
        .id();
    let camera = app
        .world_mut()
        .spawn((Camera3d::default(), Transform::from_xyz(0.0, 0.0, 40.0)))
        .id();
    for _ in 0..60 {
        app.update();
    }
    assert!(
        at_rest(&app, model, &asset).iter().all(|&r| r),
        "at rest far away"
    );
    // The cut: close on one side, so the near regions refine and the far ones coarsen.
    *app.world_mut().get_mut::<Transform>(camera).unwrap() =
        Transform::from_xyz(0.4, 0.1, 0.9).looking_at(Vec3::new(0.3, 0.0, 0.0), Vec3::Y);
    let mut moving_frames = 0;
    for frame in 0..30 {
        app.update();
        let shown = app.world().resource::<AslodStats>().triangles;
        assert!(
            shown <= u64::from(BUDGET),
            "frame {frame}: {shown} triangles"
        );
        if at_rest(&app, model, &asset).contains(&false) {
            moving_frames += 1;
        }
    }
    assert!(
        moving_frames >= 10,
        "vertices moved over {moving_frames} frames"
    );
    for _ in 0..30 {
        app.update();
    }
    assert!(
        at_rest(&app, model, &asset).iter().all(|&r| r),
        "at rest after the morph"
    );
    // Without the component, level changes are at once and every vertex is at its place.
    app.world_mut().entity_mut(model).remove::<Geomorph>();
    *app.world_mut().get_mut::<Transform>(camera).unwrap() = Transform::from_xyz(0.0, 0.0, 40.0);
    app.update();
    app.update();
    assert!(at_rest(&app, model, &asset).iter().all(|&r| r));
}
