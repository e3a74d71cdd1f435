//! Starting a glTF clip on converted scenes, for the Bevy benches and the `render_cost` example.

use bevy::gltf::Gltf;
use bevy::platform::time::Instant;
use bevy::prelude::*;
use bevy_aslod::plugin::{MultiresSceneModels, NoSharedLevels};
use std::time::Duration;

/// Runs the app until every scene root is converted (`MultiresScene`) and the glTF's clip
/// `name` (or its first) is loaded, then plays it on a loop on every player, player `i`
/// `i × phase` seconds in.
pub fn start_clip(
    app: &mut App,
    gltf: &Handle<Gltf>,
    roots: &[Entity],
    name: Option<&str>,
    phase: f32,
) -> Result<(), String> {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(300) {
        app.update();
        let converted = roots
            .iter()
            .all(|&r| app.world().get::<MultiresSceneModels>(r).is_some());
        let clip = app
            .world()
            .resource::<Assets<Gltf>>()
            .get(gltf)
            .and_then(|g| match name {
                Some(name) => g.named_animations.get(name).cloned(),
                None => g.animations.first().cloned(),
            });
        let players: Vec<Entity> = app
            .world_mut()
            .query_filtered::<Entity, With<AnimationPlayer>>()
            .iter(app.world())
            .collect();
        if let (true, Some(clip), true) = (converted, clip, players.len() >= roots.len()) {
            let (graph, node) = AnimationGraph::from_clip(clip);
            let graph = app
                .world_mut()
                .resource_mut::<Assets<AnimationGraph>>()
                .add(graph);
            for (i, &p) in players.iter().enumerate() {
                app.world_mut()
                    .entity_mut(p)
                    .insert(AnimationGraphHandle(graph.clone()));
                if let Some(mut player) = app.world_mut().get_mut::<AnimationPlayer>(p) {
                    player.play(node).repeat().seek_to(i as f32 * phase);
                }
            }
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    Err("the scene did not load and convert in five minutes".into())
}

/// Runs the app until `n` animation players exist (plain scenes spawned, for the crowd).
///
/// # Errors
/// When they have not come in five minutes.
pub fn wait_for_players(app: &mut App, n: usize) -> Result<(), String> {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(300) {
        app.update();
        let players = app
            .world_mut()
            .query_filtered::<(), With<AnimationPlayer>>()
            .iter(app.world())
            .count();
        if players >= n {
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    Err("the crowd did not spawn in five minutes".into())
}

/// The paper's CPU blend for the crowd under `roots`: each converted scene's skinned models
/// get `NoSharedLevels`, meshes of their own that the plugin skins.
pub fn skin_on_cpu(app: &mut App, roots: &[Entity]) {
    let models: Vec<Entity> = roots
        .iter()
        .filter_map(|&r| app.world().get::<MultiresSceneModels>(r))
        .flat_map(|m| m.skinned.clone())
        .collect();
    for model in models {
        app.world_mut().entity_mut(model).insert(NoSharedLevels);
    }
}
