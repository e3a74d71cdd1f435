//! Spawning copies of one multiresolution mesh, for the plugin bench and the `render_cost`
//! example.

use bevy::prelude::*;
use bevy_aslod::plugin::{MultiresMesh, MultiresModel, NoSharedLevels};

/// Adds `asset` and one default material to the app, and spawns a model of them at each of
/// `at`, each on region meshes of its own ([`NoSharedLevels`]): the benches measure how
/// levels reach each instance's meshes ([`RegionUpload`](bevy_aslod::plugin::RegionUpload)).
pub fn spawn_models(app: &mut App, asset: MultiresMesh, at: impl IntoIterator<Item = Vec3>) {
    let world = app.world_mut();
    let handle = world.resource_mut::<Assets<MultiresMesh>>().add(asset);
    let material = world
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial::default());
    for at in at {
        world.spawn((
            MultiresModel(handle.clone()),
            MeshMaterial3d(material.clone()),
            Transform::from_translation(at),
            NoSharedLevels,
        ));
    }
}
