//! Baked `.mrm` files through Bevy's asset server: the loader's first and labeled assets,
//! and a glTF character whose `MultiresScene` loads its assets from the file it was baked
//! into instead of building them (falling back to building when the file is missing).

use super::skinned::{app, app_with};
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::mesh::LoadLimits;
use bevy_aslod::mrm::{self, BuildInfo, MrmFile};
use bevy_aslod::multires::BuildOptions;
use bevy_aslod::plugin::{
    AslodPlugin, MultiresBuildFailed, MultiresMesh, MultiresModel, MultiresScene,
    MultiresSceneConverted, MultiresSceneModels,
};
use bevy_aslod::regions::Partition;
use bevy_aslod::skin::DEFAULT_RIGID_DELTA;
use std::path::PathBuf;

const ROBOT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/testdata/characters/RobotExpressive.glb"
);

/// A folder of the test `name` for the asset server, with the robot (linked, not copied) and
/// `robot.mrm` baked from it the way `aslod bake` does.
pub(super) fn asset_folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aslod-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("robot.glb");
    if !link.exists() {
        std::os::unix::fs::symlink(ROBOT, &link).unwrap();
    }
    let single = |m: &_| Partition::grid(m, Default::default(), 1, 1);
    let (options, delta) = (BuildOptions::default(), DEFAULT_RIGID_DELTA);
    let meshes = mrm::bake_gltf(ROBOT.as_ref(), &single, &options, delta, &mut |_| {}).unwrap();
    let file = MrmFile {
        build: BuildInfo {
            source_name: "RobotExpressive.glb".into(),
            source_hash: mrm::source_hash(&std::fs::read(ROBOT).unwrap()),
            partition: "single".into(),
            writer: "tests/plugin/baked.rs".into(),
            rigid_delta: Some(DEFAULT_RIGID_DELTA),
            options: BuildOptions::default(),
        },
        meshes,
    };
    std::fs::write(dir.join("robot.mrm"), mrm::write(&file)).unwrap();
    dir
}

/// Spawns the robot as a `MultiresScene` with `scene`, runs until it is converted and
/// returns the handles of its models.
fn convert(app: &mut App, scene: MultiresScene) -> Vec<Handle<MultiresMesh>> {
    let models = scene_models(app, scene);
    let models: Vec<Entity> = models.models().collect();
    assert!(!models.is_empty());
    models
        .iter()
        .map(|&e| app.world().get::<MultiresModel>(e).unwrap().0.clone())
        .collect()
}

/// Spawns the robot as a `MultiresScene` with `scene` and runs until it is converted.
fn scene_models(app: &mut App, scene: MultiresScene) -> MultiresSceneModels {
    let gltf = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("robot.glb"));
    let root = app
        .world_mut()
        .spawn((WorldAssetRoot(gltf), scene, Transform::default()))
        .id();
    for _ in 0..3_000 {
        app.update();
        if let Some(models) = app.world().get::<MultiresSceneModels>(root) {
            return models.clone();
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    panic!("the scene was not converted");
}

#[test]
fn a_baked_scene_loads_its_assets_instead_of_building() {
    let dir = asset_folder("baked");
    let mut app = app(20_000, dir.to_str().unwrap());
    let handles = convert(&mut app, MultiresScene::default().with_baked("robot.mrm"));
    for handle in &handles {
        let path = handle
            .path()
            .expect("loaded from the file, not built")
            .to_string();
        assert!(path.starts_with("robot.mrm#Mesh"), "{path}");
    }
    let assets = app.world().resource::<Assets<MultiresMesh>>();
    assert!(
        handles
            .iter()
            .any(|h| assets.get(h).unwrap().skin().is_some())
    );

    // The file's first asset is the default one.
    let first: Handle<MultiresMesh> = app.world().resource::<AssetServer>().load("robot.mrm");
    for _ in 0..1_000 {
        app.update();
        if app
            .world()
            .resource::<Assets<MultiresMesh>>()
            .contains(&first)
        {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let assets = app.world().resource::<Assets<MultiresMesh>>();
    let first = assets.get(&first).expect("robot.mrm loads");
    assert!(first.max_triangles() > 0);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_missing_baked_file_builds_instead() {
    let dir = asset_folder("missing");
    let mut app = app(20_000, dir.to_str().unwrap());
    let handles = convert(&mut app, MultiresScene::default().with_baked("missing.mrm"));
    assert!(
        handles.iter().all(|h| h.path().is_none()),
        "built, not loaded"
    );
}

/// The messages of type `M` written in the last two updates.
fn messages<M: Message + Clone>(app: &App) -> Vec<M> {
    let messages = app.world().resource::<Messages<M>>();
    messages.get_cursor().read(messages).cloned().collect()
}

/// Writes `name` into `dir`: the cow in `regions` clusters, baked.
pub(super) fn bake_cow(dir: &std::path::Path, name: &str, regions: usize) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/testdata/meshes/cow.obj"
    );
    let (mesh, _) = bevy_aslod::mesh::IndexedMesh::load(path).unwrap();
    let partition = Partition::clusters(&mesh, regions).unwrap();
    let options = BuildOptions::default();
    let cow = mrm::BakedMesh::build(&mesh, &partition, &options).unwrap();
    let file = MrmFile {
        build: BuildInfo {
            source_name: "cow.obj".into(),
            source_hash: mrm::source_hash(&std::fs::read(path).unwrap()),
            partition: format!("clusters:{regions}"),
            writer: "tests/plugin/baked.rs".into(),
            rigid_delta: None,
            options,
        },
        meshes: vec![("Mesh0/Primitive0".into(), cow)],
    };
    std::fs::write(dir.join(name), mrm::write(&file)).unwrap();
}

#[test]
fn a_rebaked_file_reloads_and_its_models_rebuild() {
    let dir = std::env::temp_dir().join(format!("aslod-reload-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    bake_cow(&dir, "cow.mrm", 4);
    let mut app = app(20_000, dir.to_str().unwrap());
    let handle: Handle<MultiresMesh> = app.world().resource::<AssetServer>().load("cow.mrm");
    let model = app
        .world_mut()
        .spawn((MultiresModel(handle.clone()), Transform::default()))
        .id();
    app.world_mut()
        .spawn((Camera3d::default(), Transform::from_xyz(0.0, 0.0, 3.0)));
    let regions = |app: &mut App| -> Option<usize> {
        let instance = app
            .world()
            .get::<bevy_aslod::plugin::MultiresInstance>(model)?;
        Some(instance.region_entities().len())
    };
    let mut before = None;
    for _ in 0..1_000 {
        app.update();
        before = regions(&mut app);
        if before.is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let before = before.expect("the model spawned its regions from the file");
    // Re-baked with more regions, then reloaded (what Bevy's file watcher does on a change).
    bake_cow(&dir, "cow.mrm", 12);
    app.world().resource::<AssetServer>().reload("cow.mrm");
    let mut after = before;
    for _ in 0..1_000 {
        app.update();
        if let Some(n) = regions(&mut app).filter(|&n| n != before) {
            after = n;
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    assert!(
        after > before,
        "{before} regions before the reload, {after} after"
    );
    let asset = app
        .world()
        .resource::<Assets<MultiresMesh>>()
        .get(&handle)
        .unwrap();
    assert_eq!(asset.region_count(), after);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn load_limits_hold_for_mrm_files_and_scene_meshes() {
    let dir = asset_folder("limits");
    let root = dir.to_str().unwrap();
    let plugin = |limits| AslodPlugin::default().with_load_limits(limits);
    let defaults = LoadLimits::default();

    // The loader refuses a file with more keys than allowed, naming the limit.
    let mut app = app_with(
        plugin(LoadLimits {
            keys: 1,
            ..defaults
        }),
        root,
    );
    let handle: Handle<MultiresMesh> = app.world().resource::<AssetServer>().load("robot.mrm");
    let mut state = String::new();
    for _ in 0..1_000 {
        app.update();
        let load = app.world().resource::<AssetServer>().load_state(&handle);
        if let bevy::asset::LoadState::Failed(e) = load {
            state = e.to_string();
            break;
        }
        assert!(
            !load.is_loaded(),
            "robot.mrm loaded past a limit of one key"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    assert!(state.contains("LoadLimits::keys"), "{state}");

    // Scene meshes over a limit stay conventional: skinned ones over `joints`, all over
    // `vertices`.
    let baseline = scene_models(
        &mut app_with(plugin(defaults), root),
        MultiresScene::default(),
    );
    assert!(!baseline.skinned.is_empty() && !baseline.rigid.is_empty());
    let few_joints = LoadLimits {
        joints: 1,
        ..defaults
    };
    let models = scene_models(
        &mut app_with(plugin(few_joints), root),
        MultiresScene::default(),
    );
    assert!(models.skinned.is_empty());
    assert_eq!(models.rigid.len(), baseline.rigid.len());
    assert_eq!(
        models.fixed.len(),
        baseline.fixed.len() + baseline.skinned.len()
    );
    let few_vertices = LoadLimits {
        vertices: 1,
        ..defaults
    };
    let mut app = app_with(plugin(few_vertices), root);
    let models = scene_models(&mut app, MultiresScene::default());
    assert_eq!(models.models().count(), 0);
    // The app hears of each mesh that failed, and of the scene.
    let failed = messages::<MultiresBuildFailed>(&app);
    assert_eq!(failed.len(), baseline.models().count(), "{failed:?}");
    for f in &failed {
        assert!(models.fixed.contains(&f.entity));
        assert!(f.error.contains("LoadLimits::vertices"), "{}", f.error);
    }
    let converted = messages::<MultiresSceneConverted>(&app);
    assert_eq!(converted.len(), 1);
    assert_eq!(converted[0].models, models);
    std::fs::remove_dir_all(&dir).ok();
}
