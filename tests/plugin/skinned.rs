//! Skinned characters through the plugin (no GPU: the renderer is created without a
//! backend): RobotExpressive from the shared test data, loaded by Bevy's own glTF loader and
//! animated by its `AnimationPlayer`, checked against a reference linear blend skinning
//! computed here from the glTF's inverse bind matrices and the joints' global transforms.

use bevy::app::ScheduleRunnerPlugin;
use bevy::gltf::Gltf;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
use bevy::render::settings::{Backends, RenderCreation, WgpuSettings};
use bevy::time::TimeUpdateStrategy;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, AslodViewport, Geomorph, MultiresInstance, MultiresMesh,
    MultiresScene, MultiresSceneModels, MultiresSourceMesh, PolygonBudget, SharedLevels,
    VariableLevel, ViewDependent,
};
use std::collections::HashMap;
use std::time::Duration;

const TESTDATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/testdata");
const ROBOT: &str = "characters/RobotExpressive.glb";
const ASSETS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets");
const MANNEQUIN: &str = "mannequin.glb";

pub(crate) fn app(budget: u32, root: &str) -> App {
    app_with(AslodPlugin::default().with_budget(budget), root)
}

/// A headless app with `plugin`, loading assets from `root`.
pub(crate) fn app_with(plugin: AslodPlugin, root: &str) -> App {
    app_with_backends(plugin, root, None)
}

/// A headless app with `plugin`, loading assets from `root`, whose renderer uses `backends`
/// (`None`: no GPU, no render world). With a backend the render world runs inside
/// `App::update` (no pipelined rendering), so a test can read it after each frame.
pub(crate) fn app_with_backends(
    plugin: AslodPlugin,
    root: &str,
    backends: Option<Backends>,
) -> App {
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(AssetPlugin {
                file_path: root.into(),
                ..default()
            })
            .set(RenderPlugin {
                render_creation: RenderCreation::Automatic(Box::new(WgpuSettings {
                    backends,
                    ..default()
                })),
                ..default()
            })
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                ..default()
            })
            .disable::<WinitPlugin>()
            .disable::<PipelinedRenderingPlugin>(),
        ScheduleRunnerPlugin::run_once(),
    ))
    .add_plugins(plugin)
    .insert_resource(AslodViewport(Vec2::new(1280.0, 720.0)));
    // `App::run` would do this; tests drive `update` by hand. The glTF loader registers here.
    app.finish();
    app.cleanup();
    app
}

/// Spawns scene 0 of the glTF at `path` as a `MultiresScene`; returns its root.
fn spawn_scene(app: &mut App, path: &'static str) -> Entity {
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset(path));
    app.world_mut()
        .spawn((
            WorldAssetRoot(scene),
            MultiresScene::default(),
            Transform::default(),
        ))
        .id()
}

/// Spawns the robot and a camera, waits until the plugin converted it and the Dance clip
/// plays (paused, so the test sets the time). Returns the scene root, the clip's node, the
/// player and the clip's length in seconds.
fn spawn_character(
    app: &mut App,
    path: &'static str,
    clip_name: &str,
) -> (Entity, AnimationNodeIndex, Entity, f32) {
    let gltf: Handle<Gltf> = app.world().resource::<AssetServer>().load(path);
    let root = spawn_scene(app, path);
    app.world_mut().spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 2.5, 9.0).looking_at(Vec3::new(0.0, 2.0, 0.0), Vec3::Y),
    ));
    let mut clip = None;
    for _ in 0..3_000 {
        app.update();
        if clip.is_none() {
            let gltfs = app.world().resource::<Assets<Gltf>>();
            clip = gltfs
                .get(&gltf)
                .and_then(|g| g.named_animations.get(clip_name).cloned());
        }
        let converted = app.world().get::<MultiresSceneModels>(root).is_some();
        let player = app
            .world_mut()
            .query_filtered::<Entity, With<AnimationPlayer>>()
            .iter(app.world())
            .next();
        // Everything the glTF needs loaded too: a dependency that lands later may make the
        // scene spawn again, with new entities.
        let settled = app
            .world()
            .resource::<AssetServer>()
            .is_loaded_with_dependencies(&gltf);
        if let (Some(clip), true, Some(player), true) = (clip.clone(), converted, player, settled) {
            let length = app
                .world()
                .resource::<Assets<AnimationClip>>()
                .get(&clip)
                .expect("clip loaded with the glTF")
                .duration();
            let (graph, node) = AnimationGraph::from_clip(clip);
            let graph = app
                .world_mut()
                .resource_mut::<Assets<AnimationGraph>>()
                .add(graph);
            app.world_mut()
                .entity_mut(player)
                .insert(AnimationGraphHandle(graph));
            app.world_mut()
                .get_mut::<AnimationPlayer>(player)
                .expect("player")
                .play(node)
                .set_speed(0.0);
            for _ in 0..3 {
                app.update();
            }
            return (root, node, player, length);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let meshes = app.world_mut().query::<&Mesh3d>().iter(app.world()).count();
    let load = app.world().resource::<AssetServer>().load_state(&gltf);
    panic!(
        "the robot did not load and convert in time: clip {clip:?}, converted {}, meshes {meshes}, gltf {load:?}",
        app.world().get::<MultiresSceneModels>(root).is_some()
    );
}

fn seek(app: &mut App, player: Entity, node: AnimationNodeIndex, t: f32) {
    app.world_mut()
        .get_mut::<AnimationPlayer>(player)
        .expect("player")
        .animation_mut(node)
        .expect("playing")
        .seek_to(t);
    app.update();
}

fn positions(mesh: &Mesh) -> &[[f32; 3]] {
    match mesh.attribute(Mesh::ATTRIBUTE_POSITION) {
        Some(VertexAttributeValues::Float32x3(p)) => p,
        _ => panic!("positions"),
    }
}

/// Per skinned model: (vertex of the source mesh, reference world position, drawn world
/// position) for every vertex a region draws; also the skinned meshes' height as posed.
fn compare(app: &mut App, root: Entity) -> (f32, usize, Vec<(u32, Vec3, Vec3)>) {
    let world = app.world();
    let models = world.get::<MultiresSceneModels>(root).expect("converted");
    let meshes = world.resource::<Assets<Mesh>>();
    let mut out = Vec::new();
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    let mut triangles = 0;
    for &model in &models.skinned {
        let instance = world.get::<MultiresInstance>(model).expect("instance");
        let source_entity = world.get::<ChildOf>(model).expect("parent").parent();
        let skin = world.get::<SkinnedMesh>(source_entity).expect("skin");
        let source = meshes
            .get(
                &world
                    .get::<MultiresSourceMesh>(source_entity)
                    .expect("source")
                    .0,
            )
            .expect("source mesh");
        let p = positions(source);
        let Some(VertexAttributeValues::Uint16x4(joints)) =
            source.attribute(Mesh::ATTRIBUTE_JOINT_INDEX)
        else {
            panic!("joints")
        };
        let Some(VertexAttributeValues::Float32x4(weights)) =
            source.attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT)
        else {
            panic!("weights")
        };
        let matrices = skinning_matrices(world, skin);
        let reference = |v: usize| -> Vec3 {
            let pos = Vec3::from(p[v]);
            let sum: f32 = weights[v].iter().sum();
            (0..4)
                .map(|k| {
                    matrices[joints[v][k] as usize].transform_point3(pos) * (weights[v][k] / sum)
                })
                .sum()
        };
        for v in 0..p.len() {
            // The model's height as it stands now (the mesh's own units are tiny: its
            // armature scales it).
            lo = lo.min(reference(v));
            hi = hi.max(reference(v));
        }
        triangles += instance.triangle_count();
        for (r, &entity) in instance.region_entities().iter().enumerate() {
            let global = world
                .get::<GlobalTransform>(entity)
                .expect("region transform");
            let mesh = meshes.get(&instance.meshes()[r]).expect("region mesh");
            let drawn = positions(mesh);
            let map = instance.regions().regions()[r].global_vertices();
            let Some(indices) = mesh.indices() else {
                continue;
            };
            if let Some(skinned) = skinned_by_bevy(world, entity, mesh) {
                // A shared level mesh: its vertices are the region's, by bind position.
                let table = &instance.regions().regions()[r]
                    .progressive_mesh()
                    .vertices();
                let mut local: HashMap<[u32; 3], Vec<usize>> = HashMap::new();
                for (v, p) in table.positions.iter().enumerate() {
                    local
                        .entry(p.to_array().map(f32::to_bits))
                        .or_default()
                        .push(v);
                }
                for i in indices.iter() {
                    let at = skinned[i];
                    let v = local[&drawn[i].map(f32::to_bits)]
                        .iter()
                        .map(|&l| map[l] as usize)
                        .min_by(|&a, &b| {
                            let (a, b) = (reference(a).distance(at), reference(b).distance(at));
                            a.total_cmp(&b)
                        })
                        .expect("a vertex of the region");
                    out.push((v as u32, reference(v), at));
                }
                continue;
            }
            for i in indices.iter() {
                let v = map[i] as usize;
                out.push((
                    v as u32,
                    reference(v),
                    global.transform_point(Vec3::from(drawn[i])),
                ));
            }
        }
    }
    (hi.y - lo.y, triangles, out)
}

/// `G_j IB_j` for each joint of `skin`, in its order.
fn skinning_matrices(world: &World, skin: &SkinnedMesh) -> Vec<Mat4> {
    let bindposes = world.resource::<Assets<SkinnedMeshInverseBindposes>>();
    let ib = bindposes.get(&skin.inverse_bindposes).expect("bindposes");
    skin.joints
        .iter()
        .zip(ib.iter())
        .map(|(&j, ib)| world.get::<GlobalTransform>(j).expect("joint").to_matrix() * *ib)
        .collect()
}

/// Where Bevy's skinning shader puts each vertex of a region `entity` draws from `mesh`, when
/// Bevy skins it (a shared level mesh): `Σ wₖ G_jₖ IB_jₖ p` over the joints its
/// `SkinnedMesh` lists.
fn skinned_by_bevy(world: &World, entity: Entity, mesh: &Mesh) -> Option<Vec<Vec3>> {
    let matrices = skinning_matrices(world, world.get::<SkinnedMesh>(entity)?);
    let (
        Some(VertexAttributeValues::Uint16x4(joints)),
        Some(VertexAttributeValues::Float32x4(weights)),
    ) = (
        mesh.attribute(Mesh::ATTRIBUTE_JOINT_INDEX),
        mesh.attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT),
    )
    else {
        panic!("a level mesh Bevy skins carries joints and weights");
    };
    let skinned = positions(mesh).iter().zip(joints.iter().zip(weights));
    Some(
        skinned
            .map(|(&p, (j, w))| {
                (0..4)
                    .map(|k| matrices[j[k] as usize].transform_point3(Vec3::from(p)) * w[k])
                    .sum()
            })
            .collect(),
    )
}

/// The largest distance between a drawn vertex and where reference skinning puts it.
fn worst(pairs: &[(u32, Vec3, Vec3)]) -> f32 {
    pairs
        .iter()
        .map(|(_, a, b)| a.distance(*b))
        .fold(0.0f32, f32::max)
}

/// Plays `clip_name` of `path` and checks full detail at 10 times, then reduced detail at
/// 10 other times (when `reduce`): every drawn vertex where reference skinning puts it.
/// `by_bevy`: the models share level meshes, which Bevy skins.
fn check_against_reference(
    root_dir: &str,
    path: &'static str,
    clip_name: &str,
    reduce: bool,
    by_bevy: bool,
) {
    let mut app = app(1_000_000, root_dir);
    let (root, node, player, length) = spawn_character(&mut app, path, clip_name);
    let models = app
        .world()
        .get::<MultiresSceneModels>(root)
        .expect("models")
        .clone();
    assert!(!models.skinned.is_empty(), "{path} has skinned meshes");
    if by_bevy {
        for &model in &models.skinned {
            app.world_mut()
                .entity_mut(model)
                .insert(SharedLevels::default());
        }
        for _ in 0..3 {
            app.update();
        }
        for &model in &models.skinned {
            let instance = app.world().get::<MultiresInstance>(model).expect("built");
            for &region in instance.region_entities() {
                assert!(
                    app.world().get::<SkinnedMesh>(region).is_some(),
                    "a shared skinned region is skinned by Bevy"
                );
            }
        }
    }
    assert!(length > 0.5, "{clip_name} lasts {length} s");
    let mut full = 0;
    for i in 0..10 {
        let t = (i as f32 + 0.5) * length / 10.0;
        seek(&mut app, player, node, t);
        let (height, triangles, pairs) = compare(&mut app, root);
        full = full.max(triangles);
        assert!(!pairs.is_empty());
        let worst = worst(&pairs);
        assert!(
            worst <= 1e-4 * height,
            "{path} t = {t}: deviation {worst} > 1e-4 of the height {height}"
        );
    }
    if !reduce {
        return;
    }
    let stats = *app.world().resource::<AslodStats>();
    let (lo, hi) = level_range(&mut app);
    assert_eq!(hi as u64, stats.triangles, "full detail before");
    let budget = stats.fixed_cost + ((3 * lo + hi) / 4) as u32;
    app.world_mut().resource_mut::<PolygonBudget>().total = budget;
    for i in 0..10 {
        seek(&mut app, player, node, (i as f32 + 0.25) * length / 10.0);
        let stats = *app.world().resource::<AslodStats>();
        assert!(
            stats.triangles + u64::from(stats.fixed_cost) <= u64::from(budget),
            "total {} + fixed {} > P = {budget}",
            stats.triangles,
            stats.fixed_cost
        );
        let (height, triangles, pairs) = compare(&mut app, root);
        assert!(triangles < full, "reduced: {triangles} of {full}");
        let worst = worst(&pairs);
        assert!(
            worst <= 1e-4 * height,
            "{path} reduced detail: deviation {worst} > 1e-4 of {height}"
        );
    }
}

/// The correctness target: RobotExpressive's Dance at 10 times. (Its skinned
/// primitives are small pieces cut into 10-15 regions each and cannot lose a triangle, so
/// reduced detail is checked on the mannequin.)
#[test]
fn robot_dance_matches_reference_skinning() {
    check_against_reference(TESTDATA, ROBOT, "Dance", false, false);
}

/// The mannequin at full and reduced detail: drawn vertices sit where full-detail skinning
/// puts them, and the total stays within the budget.
#[test]
fn mannequin_matches_reference_skinning_at_full_and_reduced_detail() {
    check_against_reference(ASSETS, MANNEQUIN, "Aerobics", true, false);
}

/// RobotExpressive's four skinned primitives on one skeleton, shared and skinned by Bevy.
#[test]
fn robot_skinned_by_bevy_matches_reference_skinning() {
    check_against_reference(TESTDATA, ROBOT, "Dance", false, true);
}

/// The same on the path crowds take: the mannequin's instances share level meshes, which
/// Bevy skins on the GPU from their joints and weights; every vertex it draws, on both
/// sides of every region border, lands where reference skinning puts it.
#[test]
fn mannequin_skinned_by_bevy_matches_reference_skinning() {
    check_against_reference(ASSETS, MANNEQUIN, "Aerobics", true, true);
}

/// Issue 6's invariant while animated: at every level the budget gives (from the coarsest
/// to full detail) and at several times of the dance, the mannequin's drawn triangles,
/// gathered over all its regions (rigid and deformable) in source-vertex numbering, form a
/// closed surface (every edge used exactly twice, in opposite directions), every source
/// vertex is drawn at one place in the world whichever region draws it (no cracks), and
/// the total stays within P.
#[test]
fn mannequin_stays_watertight_while_animated_at_every_level() {
    let mut app = app(1_000_000, ASSETS);
    let (root, node, player, length) = spawn_character(&mut app, MANNEQUIN, "Aerobics");
    let (lo, hi) = level_range(&mut app);
    for (step, fraction) in [0.0f32, 0.02, 0.1, 0.3, 0.7, 1.0].into_iter().enumerate() {
        let budget = lo as u32 + ((hi - lo) as f32 * fraction) as u32;
        app.world_mut().resource_mut::<PolygonBudget>().total = budget.max(1);
        for k in 0..3 {
            let t = (step as f32 * 0.37 + k as f32 * 0.29) % 1.0 * length;
            seek(&mut app, player, node, t);
            let stats = *app.world().resource::<AslodStats>();
            assert!(
                stats.triangles + u64::from(stats.fixed_cost) <= u64::from(budget.max(1)),
                "P = {budget}: {} triangles + {} fixed",
                stats.triangles,
                stats.fixed_cost
            );
            let (height, triangles, pairs) = compare(&mut app, root);
            assert_eq!(triangles as u64, stats.triangles);
            // What the region meshes draw is what the caches hold: nothing stale, nothing
            // missing (cancelled fins, which no partition here has, are counted by neither).
            assert!(!pairs.is_empty());
            assert_eq!(
                pairs.len() as u64,
                3 * stats.triangles,
                "P = {budget}: drawn indices"
            );
            assert_watertight(&pairs, height, &format!("P = {budget}, t = {t}"));
        }
    }
}

/// The fewest and the most triangles the models' regions can show together.
fn level_range(app: &mut App) -> (usize, usize) {
    app.world_mut()
        .query::<&MultiresInstance>()
        .iter(app.world())
        .flat_map(|i| i.regions().regions().iter())
        .fold((0, 0), |(lo, hi), r| {
            (lo + r.min_triangles(), hi + r.max_triangles())
        })
}

/// One place per source vertex, and closed: each directed edge once, and its reverse once.
fn assert_watertight(pairs: &[(u32, Vec3, Vec3)], height: f32, at: &str) {
    let mut place: HashMap<u32, Vec3> = Default::default();
    for &(v, _, drawn) in pairs {
        let first = *place.entry(v).or_insert(drawn);
        assert!(
            first.distance(drawn) <= 1e-5 * height,
            "{at}: vertex {v} drawn at {first} and {drawn}"
        );
    }
    let mut edges: HashMap<(u32, u32), u32> = Default::default();
    for tri in pairs.chunks_exact(3) {
        let (a, b, c) = (tri[0].0, tri[1].0, tri[2].0);
        for e in [(a, b), (b, c), (c, a)] {
            *edges.entry(e).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "{at}: edge {a}-{b} used {n} times one way");
        assert_eq!(
            edges.get(&(b, a)),
            Some(&1),
            "{at}: edge {a}-{b} has no twin (a crack or a hole)"
        );
    }
}

/// Geomorphs on the dancing mannequin: when the budget rises, its regions refine over the
/// morph time while it dances, never over the budget and never open; when it falls, they
/// coarsen without opening; held still, the morphs end with every drawn vertex where
/// reference skinning puts it.
#[test]
fn a_dancing_skinned_model_morphs_closed_and_comes_to_rest() {
    let mut app = app(1_000_000, ASSETS);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f32(
        1.0 / 60.0,
    )));
    let (root, node, player, length) = spawn_character(&mut app, MANNEQUIN, "Aerobics");
    let models: Vec<Entity> = app
        .world()
        .get::<MultiresSceneModels>(root)
        .expect("converted")
        .models()
        .collect();
    for &model in &models {
        app.world_mut().entity_mut(model).insert(Geomorph(0.25));
    }
    let (lo, hi) = level_range(&mut app);
    let mut t = 0.0;
    let dance = |app: &mut App, t: &mut f32| {
        *t = (*t + 1.0 / 60.0) % length;
        seek(app, player, node, *t);
    };
    for (budget, rising) in [(lo + (hi - lo) / 50, false), (hi, true), (lo, false)] {
        let budget = budget as u32;
        app.world_mut().resource_mut::<PolygonBudget>().total = budget;
        let mut moving = 0;
        for frame in 0..40 {
            dance(&mut app, &mut t);
            let stats = *app.world().resource::<AslodStats>();
            if rising {
                assert!(
                    stats.triangles <= u64::from(budget),
                    "P = {budget}, frame {frame}: {} triangles",
                    stats.triangles
                );
            }
            let (height, _, pairs) = compare(&mut app, root);
            assert_watertight(&pairs, height, &format!("P = {budget}, frame {frame}"));
            if worst(&pairs) > 1e-4 * height {
                moving += 1;
            }
        }
        assert!(
            moving >= 10,
            "P = {budget}: vertices off their skinned places in {moving} frames"
        );
        // Held still, the levels settle and the morphs end: coarsenings within T, and the
        // refinements that waited for their triangles within T more.
        for _ in 0..45 {
            seek(&mut app, player, node, t);
        }
        let (height, _, pairs) = compare(&mut app, root);
        assert!(
            worst(&pairs) <= 1e-4 * height,
            "P = {budget}: at rest, a vertex {} from its place",
            worst(&pairs)
        );
    }
}

#[test]
fn a_scene_shows_its_source_meshes_until_its_assets_are_built() {
    let mut app = app(20_000, ASSETS);
    let root = spawn_scene(&mut app, MANNEQUIN);
    // The scene's skinned mesh entities, found once the scene has spawned.
    let mut skinned: Vec<Entity> = Vec::new();
    let mut frames_waiting = 0;
    for _ in 0..3_000 {
        app.update();
        if skinned.is_empty() {
            let mut q = app
                .world_mut()
                .query_filtered::<Entity, With<SkinnedMesh>>();
            skinned = q.iter(app.world()).collect();
        }
        let converted = app.world().get::<MultiresSceneModels>(root).is_some();
        if converted {
            break;
        }
        // Spawned but not converted yet: the source meshes are still there to be drawn.
        for &e in &skinned {
            assert!(
                app.world().get::<Mesh3d>(e).is_some(),
                "entity {e} lost its mesh before its multiresolution asset was ready"
            );
        }
        frames_waiting += usize::from(!skinned.is_empty());
        std::thread::sleep(Duration::from_millis(2));
    }
    let models = app
        .world()
        .get::<MultiresSceneModels>(root)
        .expect("the mannequin was converted");
    assert!(!models.skinned.is_empty());
    assert!(!skinned.is_empty(), "the scene has skinned meshes");
    for &e in &skinned {
        let world = app.world();
        assert!(
            world.get::<Mesh3d>(e).is_none(),
            "{e}: replaced by its model"
        );
        assert!(
            world.get::<MultiresSourceMesh>(e).is_some(),
            "{e}: source kept"
        );
    }
    // The build is polled from the frame after it starts, at the earliest.
    assert!(
        frames_waiting >= 1,
        "frames ran while the assets were built"
    );
    println!("frames with the source meshes shown while building: {frames_waiting}");
}

#[test]
fn a_skinned_model_made_view_dependent_keeps_its_regions() {
    let mut app = app(2_000, TESTDATA);
    spawn_character(&mut app, ROBOT, "Dance");
    let models: Vec<Entity> = app
        .world_mut()
        .query_filtered::<Entity, With<MultiresInstance>>()
        .iter(app.world())
        .collect();
    assert!(!models.is_empty());
    for &m in &models {
        app.world_mut()
            .entity_mut(m)
            .insert(ViewDependent::default());
    }
    for _ in 0..3 {
        app.update();
    }
    let mut skinned = 0;
    for &m in &models {
        let instance = app.world().get::<MultiresInstance>(m).unwrap();
        if !instance.is_skinned() {
            continue;
        }
        skinned += 1;
        assert!(
            instance.refinement().is_none(),
            "a skinned model keeps its regions"
        );
        for &r in instance.region_entities() {
            assert_ne!(app.world().get::<Visibility>(r), Some(&Visibility::Hidden));
        }
    }
    assert_eq!(skinned, 4, "the robot's four skinned primitives");
    let mut levels = app.world_mut().query_filtered::<(), With<VariableLevel>>();
    assert_eq!(levels.iter(app.world()).count(), 0);
}

#[test]
fn despawned_scenes_leave_no_built_assets_behind() {
    let mut app = app(20_000, ASSETS);
    let count = |app: &App| app.world().resource::<Assets<MultiresMesh>>().len();
    let baseline = count(&app);
    for round in 0..2 {
        let root = spawn_scene(&mut app, MANNEQUIN);
        for _ in 0..3_000 {
            app.update();
            if app.world().get::<MultiresSceneModels>(root).is_some() {
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        assert!(
            app.world().get::<MultiresSceneModels>(root).is_some(),
            "round {round}: the mannequin was converted"
        );
        for _ in 0..3 {
            app.update();
        }
        assert!(count(&app) > baseline, "round {round}: its asset is built");
        app.world_mut().entity_mut(root).despawn();
        for _ in 0..5 {
            app.update();
        }
        assert_eq!(
            count(&app),
            baseline,
            "round {round}: the scene's assets outlive it"
        );
    }
}
