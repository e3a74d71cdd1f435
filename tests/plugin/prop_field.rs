//! A scene of real props: a glTF level that places FlightHelmet (six primitives, 94,722
//! triangles) 400 times, every copy a node hierarchy over the same six meshes, converted by
//! `MultiresScene`. The budget of 50,000 triangles holds every frame, the near copies keep
//! far more than the far ones, and `PolygonBudget::min_pixels` leaves the smallest out.

use super::attributes::common::instancing;
use super::skinned::app;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::plugin::{
    AslodStats, MultiresInstance, MultiresModel, MultiresScene, MultiresSceneModels, PolygonBudget,
};

#[path = "../../examples/common/field.rs"]
mod field;
use field::prop_field;

const HELMET: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/testdata/textured/FlightHelmet.glb"
);

/// Copies of the prop along each side of the square field.
pub(crate) const SIDE: usize = 20;
/// Metres between neighbouring copies.
pub(crate) const SPACING: f32 = 1.5;

/// Spawns `field.glb` of `dir`'s asset folder as a `MultiresScene` and runs until it is
/// converted and every model has its asset; returns the models.
pub(crate) fn spawn_field(app: &mut App) -> Vec<Entity> {
    let gltf = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("field.glb"));
    let root = app
        .world_mut()
        .spawn((
            WorldAssetRoot(gltf),
            MultiresScene::default(),
            Transform::default(),
        ))
        .id();
    for _ in 0..20_000 {
        app.update();
        let Some(models) = app.world().get::<MultiresSceneModels>(root) else {
            continue;
        };
        let models: Vec<Entity> = models.models().collect();
        let ready = models
            .iter()
            .all(|&e| app.world().get::<MultiresInstance>(e).is_some());
        if ready {
            return models;
        }
    }
    panic!("the field was not converted");
}

#[test]
fn four_hundred_real_props_stay_within_the_budget() {
    let dir = std::env::temp_dir().join(format!("aslod-field-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    prop_field(HELMET.as_ref(), &dir, SIDE, SPACING);
    let budget = 50_000;
    let mut app = app(budget, dir.to_str().unwrap());
    // Low over one corner of the field, looking across it: the nearest helmets fill the
    // view, the farthest are a few pixels.
    let half = (SIDE as f32 - 1.0) * 0.5 * SPACING;
    app.world_mut().spawn((
        Camera3d::default(),
        Transform::from_xyz(-half - 1.0, 0.8, -half - 1.0)
            .looking_at(Vec3::new(half, 0.0, half), Vec3::Y),
    ));
    let models = spawn_field(&mut app);
    assert_eq!(models.len(), SIDE * SIDE * 6, "six models a copy");
    let shown = |app: &App| app.world().resource::<AslodStats>().triangles;
    for frame in 0..20 {
        app.update();
        let stats = app.world().resource::<AslodStats>();
        assert!(stats.allocated, "frame {frame}: no allocation");
        assert!(
            shown(&app) <= u64::from(budget),
            "frame {frame}: {} triangles over the budget",
            shown(&app)
        );
    }
    // The budget is spent where it shows: the nearest copy's six models hold far more than
    // the farthest copy's.
    let triangles_at = |app: &App, at: Vec3| -> usize {
        models
            .iter()
            .filter(|&&e| {
                let placed = app.world().get::<GlobalTransform>(e).unwrap().translation();
                placed.distance(at) < 0.5 * SPACING
            })
            .map(|&e| {
                app.world()
                    .get::<MultiresInstance>(e)
                    .unwrap()
                    .triangle_count()
            })
            .sum()
    };
    let near = triangles_at(&app, Vec3::new(-half, 0.0, -half));
    let far = triangles_at(&app, Vec3::new(half, 0.0, half));
    eprintln!(
        "field: {} triangles shown, nearest copy {near}, farthest {far}",
        shown(&app)
    );
    assert!(shown(&app) > u64::from(budget) / 2, "the budget is used");
    // α = 3 (the paper's) flattens the split: a copy a hundred times larger on screen gets
    // about five times the triangles.
    assert!(
        near > 5 * far.max(1),
        "nearest {near} against farthest {far}"
    );

    // With a minimum size of 8 pixels the far copies show nothing and count nothing.
    app.world_mut().resource_mut::<PolygonBudget>().min_pixels = 8.0;
    app.update();
    app.update();
    let hidden = models
        .iter()
        .filter(|&&e| {
            let instance = app.world().get::<MultiresInstance>(e).unwrap();
            instance
                .region_entities()
                .iter()
                .all(|&r| app.world().get::<Visibility>(r) == Some(&Visibility::Hidden))
        })
        .count();
    eprintln!("min_pixels 8: {hidden} of {} models hidden", models.len());
    assert!(hidden > 0, "no model is below 8 pixels");
    assert!(hidden < models.len(), "every model is hidden");
    // The nearest copy fills the view: drawn, with its triangles counted.
    let nearest: Vec<Entity> = models
        .iter()
        .copied()
        .filter(|&e| {
            let placed = app.world().get::<GlobalTransform>(e).unwrap().translation();
            placed.distance(Vec3::new(-half, 0.0, -half)) < 0.5 * SPACING
        })
        .collect();
    assert_eq!(nearest.len(), 6);
    for e in nearest {
        let instance = app.world().get::<MultiresInstance>(e).unwrap();
        let drawn = instance
            .region_entities()
            .iter()
            .all(|&r| app.world().get::<Visibility>(r) != Some(&Visibility::Hidden));
        assert!(drawn, "a model of the nearest copy is hidden");
    }
    assert!(shown(&app) <= u64::from(budget));
    // Back to no minimum: every region is drawn again.
    app.world_mut().resource_mut::<PolygonBudget>().min_pixels = 0.0;
    app.update();
    app.update();
    let still_hidden = models
        .iter()
        .flat_map(|&e| {
            app.world()
                .get::<MultiresInstance>(e)
                .unwrap()
                .region_entities()
                .to_vec()
        })
        .filter(|&r| app.world().get::<Visibility>(r) == Some(&Visibility::Hidden))
        .count();
    assert_eq!(still_hidden, 0);
    std::fs::remove_dir_all(&dir).ok();
}

/// Writes `field.glb` into `dir`: one bumpy 800-triangle grid mesh placed by `n` nodes in a
/// row, 3 m apart.
fn grid_field(dir: &std::path::Path, n: usize) {
    let side = 21;
    let mut bin = Vec::new();
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for z in 0..side {
        for x in 0..side {
            let p = Vec3::new(
                x as f32 * 0.1,
                ((x * 7 + z * 13) % 5) as f32 * 0.02,
                z as f32 * 0.1,
            );
            (lo, hi) = (lo.min(p), hi.max(p));
            bin.extend(p.to_array().iter().flat_map(|c| c.to_le_bytes()));
        }
    }
    let positions = bin.len();
    for z in 0..side - 1 {
        for x in 0..side - 1 {
            let i = (z * side + x) as u16;
            let s = side as u16;
            for v in [i, i + s, i + 1, i + 1, i + s, i + s + 1] {
                bin.extend(v.to_le_bytes());
            }
        }
    }
    let indices = (side - 1) * (side - 1) * 6;
    let nodes: Vec<_> = (0..n)
        .map(|i| serde_json::json!({ "mesh": 0, "translation": [i as f32 * 3.0, 0.0, 0.0] }))
        .collect();
    let json = serde_json::json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": (0..n).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 }, "indices": 1 }] }],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": side * side, "type": "VEC3",
              "min": lo.to_array(), "max": hi.to_array() },
            { "bufferView": 1, "componentType": 5123, "count": indices, "type": "SCALAR" },
        ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": positions },
            { "buffer": 0, "byteOffset": positions, "byteLength": bin.len() - positions },
        ],
        "buffers": [{ "byteLength": bin.len() }],
    });
    let bytes = field::glb(&serde_json::to_vec(&json).unwrap(), &bin);
    std::fs::write(dir.join("field.glb"), bytes).unwrap();
}

#[test]
fn a_thousand_scene_instances_share_level_meshes_by_default() {
    let dir = std::env::temp_dir().join(format!("aslod-grid-field-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    grid_field(&dir, 1_000);
    let budget = 100_000;
    let mut app = app(budget, dir.to_str().unwrap());
    // Along the row from one end: the copies stand at every distance.
    app.world_mut().spawn((
        Camera3d::default(),
        Transform::from_xyz(-2.0, 1.0, 0.5).looking_at(Vec3::new(3_000.0, 0.0, 0.5), Vec3::Y),
    ));
    let models = spawn_field(&mut app);
    assert_eq!(models.len(), 1_000);
    for _ in 0..6 {
        app.update();
    }
    let stats = app.world().resource::<AslodStats>();
    assert!(stats.triangles <= u64::from(budget));
    // Every copy draws one of a few level meshes (a ladder of steps 1.5× apart), not a
    // mesh of its own.
    let mut drawn = std::collections::HashSet::new();
    for &model in &models {
        let instance = app.world().get::<MultiresInstance>(model).unwrap();
        for &region in instance.region_entities() {
            drawn.insert(app.world().get::<Mesh3d>(region).unwrap().0.id());
        }
    }
    let levels = app.world().resource::<AslodStats>().shared_meshes;
    eprintln!(
        "1,000 copies draw {} meshes; {levels} level meshes alive",
        drawn.len()
    );
    assert!(
        drawn.len() > 1,
        "the near copies are finer than the far ones"
    );
    assert!(drawn.len() <= 20, "{} meshes for 1,000 copies", drawn.len());
    assert!(drawn.len() <= levels);
    assert!(
        app.world().resource::<Assets<Mesh>>().len() < 40,
        "{} meshes in all",
        app.world().resource::<Assets<Mesh>>().len()
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn gpu_instanced_nodes_become_one_model_per_copy() {
    let dir = std::env::temp_dir().join(format!("aslod-gpu-field-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let at: Vec<[f32; 3]> = (0..20).map(|i| [i as f32 * 3.0, 0.0, 0.0]).collect();
    let node_at = [0.0, 2.0, 0.0];
    std::fs::write(
        dir.join("field.glb"),
        instancing::instanced_quads(&at, node_at, ""),
    )
    .unwrap();
    let mut app = app(10_000, dir.to_str().unwrap());
    app.world_mut().spawn((
        Camera3d::default(),
        Transform::from_xyz(-5.0, 5.0, 5.0).looking_at(Vec3::new(30.0, 0.0, 0.0), Vec3::Y),
    ));
    let models = spawn_field(&mut app);
    assert_eq!(models.len(), 20, "one model per copy, none for the node");
    for _ in 0..3 {
        app.update();
    }
    // Each at the node's transform times its copy's (the second copy also turned and
    // scaled).
    let mut placed: Vec<Vec3> = models
        .iter()
        .map(|&m| app.world().get::<GlobalTransform>(m).unwrap().translation())
        .collect();
    placed.sort_by(|a, b| a.x.total_cmp(&b.x));
    for (p, t) in placed.iter().zip(&at) {
        assert_eq!(*p, Vec3::from(*t) + Vec3::from(node_at));
    }
    let second = models
        .iter()
        .map(|&m| app.world().get::<GlobalTransform>(m).unwrap())
        .find(|g| g.translation().x == 3.0)
        .unwrap();
    assert!((second.scale() - Vec3::splat(2.0)).length() < 1e-5);
    // They share one asset's level meshes, and draw the 20 copies (those in view at full
    // detail, two triangles; one out of view may show its coarsest level, one).
    let stats = app.world().resource::<AslodStats>();
    assert!((36..=40).contains(&stats.triangles), "{}", stats.triangles);
    assert!(stats.shared_meshes >= 1);
    let assets: std::collections::HashSet<_> = models
        .iter()
        .map(|&m| app.world().get::<MultiresModel>(m).unwrap().0.id())
        .collect();
    assert_eq!(assets.len(), 1);
    std::fs::remove_dir_all(&dir).ok();
}
