//! The plugin in brief: a dancing glTF character under one triangle budget, an orbit camera
//! (Left/Right, W/S) and the count on screen. The app keeps its own window settings, and a
//! picture-in-picture camera from above is marked `NoLodAllocation`: it shows the levels the
//! main camera chose and takes no budget. `--frames N` exits N frames after it shows.

use bevy::camera::Viewport;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::plugin::{MultiresSceneConverted, NoLodAllocation};
use bevy_aslod::prelude::*;

const MODEL: &str = "mannequin.glb";
/// `--frames N`: exit N frames after the character shows.
static FRAMES: std::sync::LazyLock<Option<u32>> = std::sync::LazyLock::new(|| {
    let mut args = std::env::args().skip_while(|a| a != "--frames");
    args.nth(1)?.parse().ok()
});

fn main() -> AppExit {
    let window = Window {
        title: "bevy_aslod: basic".into(),
        resolution: (960, 540).into(),
        ..default()
    };
    App::new()
        .add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(window),
            ..default()
        }))
        .add_plugins(AslodPlugin::default().with_budget(2_000))
        .add_systems(Startup, setup)
        .add_systems(Update, (dance, orbit, converted, show_count))
        .run()
}

fn setup(mut commands: Commands, assets: Res<AssetServer>) {
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(MODEL));
    // `MultiresScene` makes every mesh of the glTF scene multiresolution when it spawns,
    // here from the file baked beside it (`aslod bake`), so nothing is built at start-up.
    let multires = MultiresScene::default().with_baked("mannequin.mrm");
    commands.spawn((WorldAssetRoot(scene), multires));
    let sun = Transform::from_xyz(2.0, 4.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y);
    let eye = Transform::from_xyz(0.0, 1.0, 3.0).looking_at(Vec3::Y, Vec3::Y);
    commands.spawn((DirectionalLight::default(), sun));
    commands.spawn((Camera3d::default(), eye));
    // A view from above in the corner: it draws what the main camera's budget chose.
    let above = Transform::from_xyz(0.0, 4.0, 0.01).looking_at(Vec3::Y, Vec3::Y);
    let corner = Viewport {
        physical_position: UVec2::new(16, 16),
        physical_size: UVec2::new(192, 108),
        ..default()
    };
    let camera = Camera {
        order: 1,
        viewport: Some(corner),
        ..default()
    };
    commands.spawn((Camera3d::default(), camera, above, NoLodAllocation));
    commands.spawn(Text::default());
}

/// Plays the glTF's clip on the character's `AnimationPlayer` once the scene has spawned it.
fn dance(
    mut commands: Commands,
    assets: Res<AssetServer>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
    mut new: Query<(Entity, &mut AnimationPlayer), Added<AnimationPlayer>>,
) {
    for (entity, mut player) in &mut new {
        let clip = assets.load(GltfAssetLabel::Animation(0).from_asset(MODEL));
        let (graph, node) = AnimationGraph::from_clip(clip);
        player.play(node).repeat();
        let graph = AnimationGraphHandle(graphs.add(graph));
        commands.entity(entity).insert(graph);
    }
}

/// Left/Right orbit the camera around the character, W/S move it closer or away.
fn orbit(
    time: Res<Time>,
    keys: Res<ButtonInput<KeyCode>>,
    mut camera: Single<&mut Transform, With<Camera3d>>,
) {
    let dt = time.delta_secs();
    let axis = |neg, pos| (keys.pressed(pos) as i8 - keys.pressed(neg) as i8) as f32 * dt;
    let turn = Quat::from_rotation_y(axis(KeyCode::ArrowRight, KeyCode::ArrowLeft) * 1.5);
    camera.rotate_around(Vec3::Y, turn);
    let zoom = 1.0 - axis(KeyCode::KeyS, KeyCode::KeyW);
    camera.translation = Vec3::Y + ((camera.translation - Vec3::Y) * zoom).clamp_length(0.5, 50.0);
}

/// Says once the scene's meshes are multiresolution (the plugin's message, no polling).
fn converted(mut scenes: MessageReader<MultiresSceneConverted>) {
    for scene in scenes.read() {
        info!("{} models in the scene", scene.models.models().count());
    }
}

/// The triangles the plugin shows this frame, against the budget, and the cameras that
/// split it.
fn show_count(
    stats: Res<AslodStats>,
    mut text: Single<&mut Text>,
    mut shown: Local<u32>,
    mut exit: MessageWriter<AppExit>,
) {
    text.0 = format!(
        "{} triangles / budget {} / {} camera(s) in the split",
        stats.triangles, stats.budget, stats.cameras
    );
    *shown += u32::from(stats.triangles > 0);
    if Some(*shown) == *FRAMES {
        println!("{}", text.0);
        exit.write(AppExit::Success);
    }
}
