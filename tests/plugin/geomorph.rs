//! Geomorphs in the plugin: a camera cut makes the cow's regions change level over the
//! morph time instead of at once; the budget holds in every frame; at rest every region
//! mesh is back at its own vertex positions; removing `Geomorph` ends the morphs;
//! view-dependent models morph too.

use super::models::app;
use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_aslod::plugin::{
    ATTRIBUTE_MORPH_FROM, ATTRIBUTE_MORPH_NORMAL_FROM, AslodStats, GpuGeomorph, MultiresInstance,
    MultiresMesh, MultiresModel, ViewDependent,
};
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
    // The topology kept (`permissive(false)`): the budget test below counts the frames whose
    // shown total changes. After a cut the models' refinements keep waiting once the
    // coarsenings land (until the allocation next changes) with either build; a permissive
    // build's levels give 4 such frames in the run, a strict one's enough to pass.
    let options = bevy_aslod::multires::BuildOptions::default().with_permissive(false);
    MultiresMesh::from_indexed_with(&mesh, &partition, &options).expect("the cow builds")
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

/// An app under the test budget whose clock runs 1/60 s a frame, with `asset` added.
fn morph_app(asset: &MultiresMesh) -> (App, Handle<MultiresMesh>) {
    let mut app = app(BUDGET);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(
        1.0 / 60.0,
    )));
    let handle = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(asset.clone());
    (app, handle)
}

#[test]
fn a_camera_cut_morphs_under_the_budget_and_comes_to_rest() {
    let asset = cow();
    let (mut app, handle) = morph_app(&asset);
    let model = app
        .world_mut()
        .spawn((MultiresModel(handle), Geomorph(T), Transform::default()))
        .id();
    let camera = app
        .world_mut()
        .spawn((Camera3d::default(), Transform::from_xyz(0.0, 0.0, 40.0)))
        .id();
    // A new model takes its first levels at once: its caches start at full detail (5,804
    // triangles), which it must not keep counting for the morph time.
    for frame in 0..60 {
        app.update();
        let shown = app.world().resource::<AslodStats>().triangles;
        assert!(
            shown <= u64::from(BUDGET),
            "frame {frame}: {shown} triangles"
        );
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

/// One region mesh's vertices as the geomorph vertex shader draws them at `time` (the shaders'
/// clock), from its positions, normals and morph attributes.
fn drawn_on_gpu(mesh: &Mesh, time: f32) -> Vec<Vec3> {
    let (
        Some(VertexAttributeValues::Float32x3(to)),
        Some(VertexAttributeValues::Float32x4(from)),
        Some(VertexAttributeValues::Float32x4(normal_from)),
    ) = (
        mesh.attribute(Mesh::ATTRIBUTE_POSITION),
        mesh.attribute(ATTRIBUTE_MORPH_FROM),
        mesh.attribute(ATTRIBUTE_MORPH_NORMAL_FROM),
    )
    else {
        panic!("a GPU geomorph region mesh has its morph attributes");
    };
    to.iter()
        .zip(from)
        .zip(normal_from)
        .map(|((&to, &[x, y, z, start]), &[.., inv])| {
            let (to, from) = (Vec3::from(to), Vec3::new(x, y, z));
            let elapsed = time - start;
            let t = if elapsed < 0.0 || inv <= 0.0 {
                1.0
            } else {
                (elapsed * inv).clamp(0.0, 1.0)
            };
            if t < 1.0 { from + (to - from) * t } else { to }
        })
        .collect()
}

fn region_meshes(app: &App, model: Entity) -> Vec<Mesh> {
    let instance = app.world().get::<MultiresInstance>(model).unwrap();
    let meshes = app.world().resource::<Assets<Mesh>>();
    instance
        .region_entities()
        .iter()
        .map(|&e| {
            meshes
                .get(&app.world().get::<Mesh3d>(e).unwrap().0)
                .unwrap()
                .clone()
        })
        .collect()
}

/// Two apps of one model of `asset` under geomorphs (view-dependent or not), written from the
/// CPU and (the second) interpolated on the GPU, each a second at `distance` in front of it,
/// then cut to `near` (each in an app of its own: two models would share the budget).
fn cpu_and_gpu_apps(
    asset: &MultiresMesh,
    view_dependent: bool,
    distance: f32,
    near: Transform,
) -> [(App, Entity); 2] {
    [false, true].map(|on_gpu| {
        let (mut app, handle) = morph_app(asset);
        let mut model =
            app.world_mut()
                .spawn((MultiresModel(handle), Geomorph(T), Transform::default()));
        if on_gpu {
            model.insert(GpuGeomorph);
        }
        if view_dependent {
            model.insert(ViewDependent::default());
        }
        let model = model.id();
        let camera = app
            .world_mut()
            .spawn((Camera3d::default(), Transform::from_xyz(0.0, 0.0, distance)))
            .id();
        for _ in 0..60 {
            app.update();
        }
        *app.world_mut().get_mut::<Transform>(camera).unwrap() = near;
        (app, model)
    })
}

/// The same cut drawn by a model whose material interpolates on the GPU and one written
/// from the CPU: every
/// vertex a triangle uses is drawn at the same place in every frame, and the GPU model's
/// vertices are written only in the frames a morph starts.
#[test]
fn gpu_geomorphs_draw_what_cpu_geomorphs_write_and_write_less() {
    let near = Transform::from_xyz(0.4, 0.1, 0.9).looking_at(Vec3::new(0.3, 0.0, 0.0), Vec3::Y);
    let mut apps = cpu_and_gpu_apps(&cow(), false, 40.0, near);
    let [(cpu_app, cpu), (gpu_app, gpu)] = &mut apps;
    let (mut cpu_writes, mut gpu_writes) = (0, 0);
    let (mut last_cpu, mut last_gpu) = (region_meshes(cpu_app, *cpu), region_meshes(gpu_app, *gpu));
    for frame in 0..40 {
        cpu_app.update();
        gpu_app.update();
        let time = gpu_app.world().resource::<Time>().elapsed_secs_wrapped();
        let (now_cpu, now_gpu) = (region_meshes(cpu_app, *cpu), region_meshes(gpu_app, *gpu));
        for (r, (c, g)) in now_cpu.iter().zip(&now_gpu).enumerate() {
            let Some(VertexAttributeValues::Float32x3(written)) =
                c.attribute(Mesh::ATTRIBUTE_POSITION)
            else {
                panic!("positions");
            };
            let drawn = drawn_on_gpu(g, time);
            let indices: Vec<usize> = c.indices().unwrap().iter().collect();
            assert_eq!(
                indices,
                g.indices().unwrap().iter().collect::<Vec<_>>(),
                "frame {frame}, region {r}: the two models show other levels"
            );
            for i in indices {
                let d = drawn[i].distance(Vec3::from(written[i]));
                assert!(
                    d < 1e-4,
                    "frame {frame}, region {r}, vertex {i}: drawn {d} away from the CPU's"
                );
            }
        }
        let moved = |a: &[Mesh], b: &[Mesh]| {
            a.iter().zip(b).any(|(a, b)| {
                a.attribute(Mesh::ATTRIBUTE_POSITION) != b.attribute(Mesh::ATTRIBUTE_POSITION)
                    || a.attribute(ATTRIBUTE_MORPH_FROM) != b.attribute(ATTRIBUTE_MORPH_FROM)
            })
        };
        cpu_writes += usize::from(moved(&last_cpu, &now_cpu));
        gpu_writes += usize::from(moved(&last_gpu, &now_gpu));
        (last_cpu, last_gpu) = (now_cpu, now_gpu);
    }
    assert!(
        cpu_writes >= 10,
        "the CPU model wrote in {cpu_writes} frames"
    );
    assert!(
        gpu_writes * 3 <= cpu_writes,
        "the GPU model wrote in {gpu_writes} frames, the CPU model in {cpu_writes}"
    );
}

/// Several models under one budget: when the camera cuts from one to another, the far one's
/// regions coarsen while the near one's refine, and the refinements wait for the triangles
/// the coarsenings free, so the models together never show more than the budget.
#[test]
fn models_sharing_the_budget_never_show_more_than_it_during_morphs() {
    let (mut app, handle) = morph_app(&cow());
    for x in [-3.0, 0.0, 3.0] {
        app.world_mut().spawn((
            MultiresModel(handle.clone()),
            Geomorph(T),
            Transform::from_xyz(x, 0.0, 0.0),
        ));
    }
    let camera = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            Transform::from_xyz(-3.0, 0.0, 1.2).looking_at(Vec3::new(-3.0, 0.0, 0.0), Vec3::Y),
        ))
        .id();
    let (mut changes, mut last) = (0, 0);
    for frame in 0..120 {
        if frame % 40 == 20 {
            let x = [3.0, 0.0, -3.0][frame / 40];
            *app.world_mut().get_mut::<Transform>(camera).unwrap() =
                Transform::from_xyz(x, 0.0, 1.2).looking_at(Vec3::new(x, 0.0, 0.0), Vec3::Y);
        }
        app.update();
        let shown = app.world().resource::<AslodStats>().triangles;
        assert!(
            shown <= u64::from(BUDGET),
            "frame {frame}: {shown} triangles"
        );
        let instances: Vec<&MultiresInstance> = app
            .world_mut()
            .query::<&MultiresInstance>()
            .iter(app.world())
            .collect();
        let total: usize = instances.iter().map(|i| i.caches().total_triangles()).sum();
        assert_eq!(
            total as u64, shown,
            "frame {frame}: the stats count what is shown"
        );
        changes += usize::from(frame >= 20 && shown != last);
        last = shown;
    }
    // Each cut: the coarsenings start (their triangles still shown), land a morph time later,
    // and only then the refinements that waited for them take the triangles.
    assert!(changes >= 6, "the shown count changed in {changes} frames");
}

/// The vertex positions of a view-dependent model's level mesh and its indices.
fn level_mesh(app: &App, model: Entity) -> Mesh {
    let level = app
        .world()
        .get::<MultiresInstance>(model)
        .and_then(MultiresInstance::variable_level_entity)
        .expect("a level child");
    let handle = &app.world().get::<Mesh3d>(level).expect("a mesh").0;
    app.world()
        .resource::<Assets<Mesh>>()
        .get(handle)
        .expect("the level mesh")
        .clone()
}

fn positions(mesh: &Mesh) -> Vec<Vec3> {
    match mesh.attribute(Mesh::ATTRIBUTE_POSITION) {
        Some(VertexAttributeValues::Float32x3(p)) => p.iter().map(|&p| Vec3::from(p)).collect(),
        _ => panic!("positions"),
    }
}

/// A view-dependent model under geomorphs, written from the CPU and interpolated on the GPU
/// (an app each): across a camera cut the budget holds in every frame, the triangles drawn
/// are the ones counted, the GPU draws what the CPU writes, the vertices move for about the
/// morph time and then rest at their own places on the refined level.
#[test]
fn view_dependent_geomorphs_stay_in_the_budget_and_come_to_rest() {
    let asset = super::view_dependent::cow();
    let own = asset
        .variable()
        .expect("refinement data")
        .mesh()
        .vertices()
        .positions
        .clone();
    let near = Transform::from_xyz(4.0, 1.0, 4.0).looking_at(Vec3::new(3.0, 0.0, 0.0), Vec3::Y);
    let mut apps = cpu_and_gpu_apps(&asset, true, 60.0, near);
    let [(cpu_app, cpu), (gpu_app, gpu)] = &mut apps;
    let mut moving = 0;
    for frame in 0..60 {
        cpu_app.update();
        gpu_app.update();
        for app in [&*cpu_app, &*gpu_app] {
            let shown = app.world().resource::<AslodStats>().triangles;
            assert!(
                shown <= u64::from(BUDGET),
                "frame {frame}: {shown} triangles"
            );
        }
        let (c, g) = (level_mesh(cpu_app, *cpu), level_mesh(gpu_app, *gpu));
        let indices: Vec<usize> = c.indices().unwrap().iter().collect();
        assert_eq!(
            indices,
            g.indices().unwrap().iter().collect::<Vec<_>>(),
            "frame {frame}: the two models show other levels"
        );
        let counted = app_instance(cpu_app, *cpu).triangle_count();
        assert_eq!(
            3 * counted,
            indices.len(),
            "frame {frame}: drawn is counted"
        );
        let time = gpu_app.world().resource::<Time>().elapsed_secs_wrapped();
        let (written, drawn) = (positions(&c), drawn_on_gpu(&g, time));
        for &i in &indices {
            let d = drawn[i].distance(written[i]);
            assert!(
                d < 1e-4,
                "frame {frame}, vertex {i}: drawn {d} away from the CPU's"
            );
        }
        moving += usize::from(indices.iter().any(|&i| written[i] != own[i]));
    }
    assert!(
        (10..=40).contains(&moving),
        "vertices moved in {moving} frames"
    );
    let instance = app_instance(cpu_app, *cpu);
    let refined = instance.refinement().expect("refined").triangles;
    assert_eq!(
        instance.triangle_count(),
        refined,
        "at rest on the refined level"
    );
    assert_eq!(
        positions(&level_mesh(cpu_app, *cpu)),
        own,
        "at rest at their own places"
    );
}

fn app_instance(app: &App, model: Entity) -> &MultiresInstance {
    app.world()
        .get::<MultiresInstance>(model)
        .expect("instance")
}
