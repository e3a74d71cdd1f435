//! Every vertex attribute on every path of the plugin: at random budgets, each vertex the
//! regions, a view-dependent level, geomorphs at rest and skinned regions draw carries
//! exactly its source vertex's attributes (tangents, a second UV set, colours, custom
//! attributes of several formats). A `Vertex_SourceId` attribute names each drawn vertex's
//! source vertex.

use super::models::app;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_aslod::bevy_mesh::from_bevy_mesh;
use bevy_aslod::mesh::{AttributeFormat, IndexedMesh, Scalar, VertexAttribute};
use bevy_aslod::multires::BuildOptions;
use bevy_aslod::plugin::{
    Geomorph, MultiresInstance, MultiresMesh, MultiresModel, MultiresSkin, PolygonBudget,
    ViewDependent,
};
use bevy_aslod::regions::Partition;
use glam::{Mat4, Vec2, Vec3};
use std::time::Duration;

#[allow(unused_imports)]
#[path = "../common/mod.rs"]
pub(crate) mod common;

const SOURCE_ID: &str = "Vertex_SourceId";

/// A bumpy sphere with normals, UVs, tangents, further attributes of five formats and the
/// source id of each vertex.
fn source() -> IndexedMesh {
    let noise: Vec<f32> = (0..97).map(|i| ((i * 37) % 11) as f32 * 0.01).collect();
    let mut mesh = common::sphere(24, 32, &noise, true);
    mesh.normals = Some(mesh.positions.iter().map(|p| p.normalize()).collect());
    common::add_further_attributes(&mut mesh);
    // Tangents in the surface, as MikkTSpace makes them, handedness kept.
    let normals = mesh.normals.clone().unwrap();
    for (t, n) in mesh.tangents.as_mut().unwrap().iter_mut().zip(&normals) {
        *t = n.cross(Vec3::Y).normalize_or(Vec3::X).extend(t.w);
    }
    mesh.attributes.push(source_ids(mesh.positions.len()));
    mesh.validate().expect("the test mesh is valid");
    mesh
}

/// Checks every vertex `mesh` draws against the source vertex its id names: every attribute
/// equal, positions and normals too unless `deformed`, where tangents must stay unit and
/// perpendicular to the normals instead. Returns how many vertices it checked.
fn check_drawn(mesh: &Mesh, source: &IndexedMesh, deformed: bool, what: &str) -> usize {
    let drawn = from_bevy_mesh(mesh).unwrap_or_else(|e| panic!("{what}: {e}"));
    let id = drawn
        .attribute(988_540_920)
        .unwrap_or_else(|| panic!("{what}: no {SOURCE_ID}"));
    assert_eq!(drawn.attributes.len(), source.attributes.len(), "{what}");
    let mut checked = 0;
    for &v in &drawn.indices {
        let v = v as usize;
        let g = u32::from_le_bytes(id.record(v).try_into().unwrap()) as usize;
        for (a, b) in drawn.attributes.iter().zip(&source.attributes) {
            assert_eq!(
                (&a.name, a.id, a.format),
                (&b.name, b.id, b.format),
                "{what}"
            );
            assert_eq!(a.record(v), b.record(g), "{what}: {} of vertex {g}", a.name);
        }
        assert_eq!(
            drawn.uvs.as_ref().unwrap()[v],
            source.uvs.as_ref().unwrap()[g],
            "{what}"
        );
        let (t, t0) = (
            drawn.tangents.as_ref().unwrap()[v],
            source.tangents.as_ref().unwrap()[g],
        );
        assert_eq!(t.w, t0.w, "{what}: the handedness of vertex {g}");
        if deformed {
            // Blended vertices keep unnormalised normals and tangents, as Bevy's vertex shader
            // normalises both.
            let n = drawn.normals.as_ref().unwrap()[v].normalize();
            let t = t.truncate().normalize();
            assert!(t.is_finite(), "{what}: vertex {g}'s tangent {t}");
            // Tangents turn with the blended matrix, normals with its inverse transpose (as in
            // Bevy's shader): they stay perpendicular. Left unturned, a blended tangent is
            // 0.08 off here.
            assert!(
                n.dot(t).abs() < 1e-3,
                "{what}: vertex {g}'s tangent left its surface (n·t = {})",
                n.dot(t)
            );
        } else {
            assert_eq!(
                drawn.positions[v], source.positions[g],
                "{what}: position of {g}"
            );
            assert_eq!(t, t0, "{what}: tangent of vertex {g}");
        }
        checked += 1;
    }
    checked
}

fn mesh_of(app: &App, entity: Entity) -> &Mesh {
    let handle = &app.world().get::<Mesh3d>(entity).expect("a Mesh3d").0;
    app.world()
        .resource::<Assets<Mesh>>()
        .get(handle)
        .expect("the mesh")
}

/// Checks every region mesh of `model` (or its view-dependent level); returns the vertices
/// checked.
fn check_model(
    app: &App,
    model: Entity,
    source: &IndexedMesh,
    deformed: bool,
    what: &str,
) -> usize {
    let instance = app
        .world()
        .get::<MultiresInstance>(model)
        .expect("an instance");
    let mut checked = 0;
    match instance.variable_level_entity() {
        Some(level) => checked += check_drawn(mesh_of(app, level), source, deformed, what),
        None => {
            for &e in instance.region_entities() {
                checked += check_drawn(mesh_of(app, e), source, deformed, what);
            }
        }
    }
    checked
}

/// `source` in 6 clusters.
fn clustered(source: &IndexedMesh) -> MultiresMesh {
    let partition = Partition::clusters(source, 6).expect("clusters");
    MultiresMesh::from_indexed(source, &partition).expect("builds")
}

/// An app with a camera, its clock at 1/60 s a frame, `asset` added.
fn attribute_app(asset: MultiresMesh) -> (App, Handle<MultiresMesh>) {
    let mut app = app(1_000);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(
        1.0 / 60.0,
    )));
    app.world_mut().spawn((
        Camera3d::default(),
        Transform::from_xyz(0.3, 0.5, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let handle = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(asset);
    (app, handle)
}

/// Runs `frames` frames at each of a run of random budgets, checking every frame's meshes
/// once the model is at rest (`rest` frames after the budget changed).
fn run_budgets(
    app: &mut App,
    model: Entity,
    source: &IndexedMesh,
    deformed: bool,
    rest: usize,
    what: &str,
) {
    let mut rng = common::Rng(0x5EED_A77E);
    let full = source.triangle_count();
    let mut checked = 0;
    for round in 0..6 {
        let budget = 100 + rng.below(full) as u32;
        app.world_mut().resource_mut::<PolygonBudget>().total = budget;
        for _ in 0..rest {
            app.update();
        }
        checked += check_model(
            app,
            model,
            source,
            deformed,
            &format!("{what}, budget {budget} (round {round})"),
        );
    }
    assert!(checked > 1_000, "{what}: only {checked} vertices drawn");
}

#[test]
fn regions_draw_every_vertex_with_its_source_attributes() {
    let source = source();
    let (mut app, handle) = attribute_app(clustered(&source));
    let model = app
        .world_mut()
        .spawn((MultiresModel(handle), Transform::default()))
        .id();
    run_budgets(&mut app, model, &source, false, 2, "regions");
}

#[test]
fn a_view_dependent_level_draws_every_vertex_with_its_source_attributes() {
    let source = source();
    let asset = clustered(&source)
        .with_refinement(&source, &BuildOptions::default())
        .expect("refinement data");
    let (mut app, handle) = attribute_app(asset);
    let model = app
        .world_mut()
        .spawn((
            MultiresModel(handle),
            ViewDependent::default(),
            Transform::default(),
        ))
        .id();
    app.update();
    app.update();
    assert!(
        app.world()
            .get::<MultiresInstance>(model)
            .unwrap()
            .variable_level_entity()
            .is_some(),
        "the model shows its view-dependent level"
    );
    run_budgets(&mut app, model, &source, false, 2, "view-dependent");
}

#[test]
fn geomorphs_at_rest_draw_every_vertex_with_its_source_attributes() {
    let source = source();
    let (mut app, handle) = attribute_app(clustered(&source));
    let model = app
        .world_mut()
        .spawn((MultiresModel(handle), Geomorph(0.1), Transform::default()))
        .id();
    // 0.1 s is 6 frames; 20 frames leave every morph landed.
    run_budgets(&mut app, model, &source, false, 20, "geomorphs at rest");
}

#[test]
fn skinned_regions_draw_every_vertex_with_its_source_attributes() {
    let mut source = source();
    // Joint 0 holds the lower half, joint 1 the upper, and a band around the equator blends.
    let (joints, weights) = source
        .positions
        .iter()
        .map(|p| match p.y {
            y if y < -0.2 => ([0, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
            y if y > 0.2 => ([1, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]),
            y => ([0, 1, 0, 0], [0.5 - y * 2.5, 0.5 + y * 2.5, 0.0, 0.0]),
        })
        .unzip();
    source.joints = Some(joints);
    source.weights = Some(weights);
    let asset = MultiresMesh::from_skinned(&source, &[Mat4::IDENTITY; 2], 0.01).expect("builds");
    let (mut app, handle) = attribute_app(asset);
    let lower = app.world_mut().spawn(Transform::default()).id();
    let upper = app.world_mut().spawn(Transform::default()).id();
    let model = app
        .world_mut()
        .spawn((
            MultiresModel(handle),
            MultiresSkin {
                joints: vec![lower, upper],
            },
            Transform::default(),
        ))
        .id();
    run_budgets(&mut app, model, &source, true, 2, "skinned, bind pose");
    // Turn the upper joint: tangents turn with the surface.
    app.world_mut().entity_mut(upper).insert(
        Transform::from_rotation(Quat::from_rotation_z(0.6))
            .with_translation(Vec3::new(0.2, 0.0, 0.0)),
    );
    run_budgets(&mut app, model, &source, true, 2, "skinned, turned");
}

/// A bumpy sphere whose UVs are each vertex's `(x, z)`, whose `Vertex_Place` is its position
/// and whose tangents point along it, with the source id of each vertex.
fn placed_sphere() -> IndexedMesh {
    let mut source = common::sphere(16, 24, &[0.0, 0.03, -0.02], true);
    source.normals = Some(source.positions.iter().map(|p| p.normalize()).collect());
    source.uvs = Some(
        source
            .positions
            .iter()
            .map(|p| Vec2::new(p.x, p.z))
            .collect(),
    );
    let place: Vec<[f32; 3]> = source.positions.iter().map(|p| p.to_array()).collect();
    source.attributes = vec![
        VertexAttribute::from_f32("Vertex_Place", 988_540_921, &place),
        source_ids(source.positions.len()),
    ];
    source.tangents = Some(
        source
            .positions
            .iter()
            .map(|p| p.normalize().extend(1.0))
            .collect(),
    );
    source
}

/// Each vertex's source id, as the attribute `Vertex_SourceId`.
fn source_ids(n: usize) -> VertexAttribute {
    VertexAttribute {
        name: SOURCE_ID.into(),
        id: 988_540_920,
        format: AttributeFormat {
            scalar: Scalar::U32,
            components: 1,
        },
        data: (0..n as u32).flat_map(u32::to_le_bytes).collect(),
    }
}

/// `source` skinned to one joint (one rigid region) in its bind pose, spawned with
/// `Geomorph(seconds)`.
fn one_joint_model(source: &IndexedMesh, seconds: f32) -> (App, Entity) {
    let mut source = source.clone();
    let n = source.positions.len();
    source.joints = Some(vec![[0; 4]; n]);
    source.weights = Some(vec![[1.0, 0.0, 0.0, 0.0]; n]);
    let asset = MultiresMesh::from_skinned(&source, &[Mat4::IDENTITY], 0.01).expect("builds");
    let (mut app, handle) = attribute_app(asset);
    let joint = app.world_mut().spawn(Transform::default()).id();
    let model = app
        .world_mut()
        .spawn((
            MultiresModel(handle),
            MultiresSkin {
                joints: vec![joint],
            },
            Geomorph(seconds),
            Transform::default(),
        ))
        .id();
    (app, model)
}

/// Moving vertices carry their `f32` attributes with them (CPU geomorphs): on a
/// [`placed_sphere`], every vertex drawn in the middle of morphs has the UV and place its
/// morphing position says.
#[test]
fn geomorphs_in_motion_carry_uvs_and_float_attributes_along() {
    let source = placed_sphere();
    // One region: a vertex on a border between regions can move with its neighbour's
    // collapse while its own region keeps it, with its own attributes.
    let n = source.positions.len();
    let (partition, _) = Partition::from_ids(&source, &vec![0; n]).expect("one region");
    let asset = MultiresMesh::from_indexed(&source, &partition).expect("builds");
    let (mut app, handle) = attribute_app(asset);
    let model = app
        .world_mut()
        .spawn((MultiresModel(handle), Geomorph(1.0), Transform::default()))
        .id();
    check_attributes_in_motion(&mut app, model, &source);
}

/// The same on a skinned model in its bind pose (one joint: one rigid region), whose
/// tangents are skinned from where the morphs show them.
#[test]
fn skinned_geomorphs_in_motion_carry_uvs_and_float_attributes_along() {
    let source = placed_sphere();
    let (mut app, model) = one_joint_model(&source, 1.0);
    check_attributes_in_motion(&mut app, model, &source);
}

/// Steps `model`, a [`placed_sphere`] under one-second geomorphs, through budget changes,
/// checking every drawn vertex's UV, place and tangent against its drawn position in the
/// middle of the morphs.
fn check_attributes_in_motion(app: &mut App, model: Entity, source: &IndexedMesh) {
    app.update();
    app.update();
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-4;
    let mut moving = 0;
    for budget in [250, 1_500, 120, 1_000] {
        app.world_mut().resource_mut::<PolygonBudget>().total = budget;
        // A second at 60 frames a second: these frames are all in the middle of morphs.
        for frame in 0..8 {
            app.update();
            let instance = app.world().get::<MultiresInstance>(model).unwrap();
            for &e in instance.region_entities() {
                let drawn = from_bevy_mesh(mesh_of(app, e)).expect("a region mesh");
                let places = drawn.attribute(988_540_921).unwrap().to_f32::<3>().unwrap();
                let ids = drawn.attribute(988_540_920).unwrap();
                for &v in &drawn.indices {
                    let v = v as usize;
                    let (p, uv, at) = (
                        drawn.positions[v],
                        drawn.uvs.as_ref().unwrap()[v],
                        places[v],
                    );
                    let what = format!("budget {budget}, frame {frame}, vertex {v}");
                    assert!(
                        close(uv.x, p.x) && close(uv.y, p.z),
                        "{what}: UV {uv} at {p}"
                    );
                    assert!(
                        (0..3).all(|k| close(at[k], p[k])),
                        "{what}: place {at:?} at {p}"
                    );
                    let t = drawn.tangents.as_ref().unwrap()[v];
                    let along = t.truncate().normalize().dot(p.normalize());
                    assert!(along > 0.999, "{what}: tangent {t} at {p}");
                    let g = u32::from_le_bytes(ids.record(v).try_into().unwrap()) as usize;
                    moving += usize::from(p != source.positions[g]);
                }
            }
        }
    }
    assert!(moving > 100, "only {moving} vertices drawn in motion");
}

/// A skinned vertex that leaves its level halfway to its stand-in's attributes is back at its
/// own once the morphs rest: after geomorphs end in the middle of a coarsening, a refinement
/// without them draws every vertex with its source attributes.
#[test]
fn skinned_vertices_come_back_with_their_own_attributes_after_geomorphs() {
    let source = placed_sphere();
    let (mut app, model) = one_joint_model(&source, 0.5);
    for _ in 0..3 {
        app.update();
    }
    // Coarsen; halfway through, the morphs end; then refine without them.
    app.world_mut().resource_mut::<PolygonBudget>().total = 150;
    for _ in 0..20 {
        app.update();
    }
    app.world_mut().entity_mut(model).remove::<Geomorph>();
    for _ in 0..10 {
        app.update();
    }
    app.world_mut().resource_mut::<PolygonBudget>().total = 1_000_000;
    for _ in 0..3 {
        app.update();
    }
    let instance = app.world().get::<MultiresInstance>(model).unwrap();
    let mut checked = 0;
    for &e in instance.region_entities() {
        let drawn = from_bevy_mesh(mesh_of(&app, e)).expect("a region mesh");
        let ids = drawn.attribute(988_540_920).unwrap();
        for &v in &drawn.indices {
            let v = v as usize;
            let g = u32::from_le_bytes(ids.record(v).try_into().unwrap()) as usize;
            let (uv, own) = (
                drawn.uvs.as_ref().unwrap()[v],
                source.uvs.as_ref().unwrap()[g],
            );
            assert!(
                uv.distance(own) < 1e-5,
                "vertex {g}: UV {uv}, its own {own}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 3 * source.triangle_count(), "full detail");
}
