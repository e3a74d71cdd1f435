//! Region children draw their model's material: [`MultiresMaterialPlugin`] copies a model's
//! `MeshMaterial3d<M>` to the entities that draw it, and keeps them following it.

use super::components::ViewDependentLevel;
use super::instance::MultiresInstance;
use super::sets::MaterialSystems;
use bevy::prelude::*;

/// Gives the regions of every [`MultiresModel`](super::MultiresModel) the model's `MeshMaterial3d<M>`, and keeps them
/// following it when it changes or is removed, like Bevy's `MaterialPlugin<M>` for a
/// material type. [`AslodPlugin`](super::AslodPlugin) adds it for `StandardMaterial`; add one for each other
/// material a multiresolution model uses (an `ExtendedMaterial`, your own `Material`).
///
/// ```
/// use bevy::pbr::{ExtendedMaterial, MaterialExtension};
/// use bevy::prelude::*;
/// use bevy::render::render_resource::AsBindGroup;
/// use bevy_aslod::plugin::{AslodPlugin, MultiresMaterialPlugin};
///
/// #[derive(Asset, AsBindGroup, Reflect, Clone, Default)]
/// struct Outline {}
/// impl MaterialExtension for Outline {}
///
/// type Outlined = ExtendedMaterial<StandardMaterial, Outline>;
///
/// let mut app = App::new();
/// app.add_plugins((MinimalPlugins, AssetPlugin::default()))
///     .init_asset::<Mesh>()
///     .init_asset::<Outlined>()
///     .add_plugins((AslodPlugin::default(), MultiresMaterialPlugin::<Outlined>::default()));
/// app.update();
/// ```
pub struct MultiresMaterialPlugin<M: Material>(std::marker::PhantomData<fn() -> M>);

impl<M: Material> Default for MultiresMaterialPlugin<M> {
    fn default() -> Self {
        Self(std::marker::PhantomData)
    }
}

impl<M: Material> Plugin for MultiresMaterialPlugin<M> {
    fn build(&self, app: &mut App) {
        app.add_systems(PostUpdate, propagate_materials::<M>.in_set(MaterialSystems));
    }
}

/// The models whose regions took a material this frame (from any
/// [`MultiresMaterialPlugin`]).
#[derive(Resource, Default)]
pub(super) struct MaterialsGiven(Vec<Entity>);

/// A model's `MeshMaterial3d<M>` was added, changed or removed, or its regions were just
/// made: its regions follow. Changes to the material asset itself need nothing, the regions
/// share its handle.
#[allow(clippy::type_complexity)]
pub(super) fn propagate_materials<M: Material>(
    mut commands: Commands,
    changed: Query<
        (Entity, &MultiresInstance, &MeshMaterial3d<M>),
        Or<(Changed<MeshMaterial3d<M>>, Added<MultiresInstance>)>,
    >,
    // Removed and not given back (in the same frame) by the time this runs.
    instances: Query<&MultiresInstance, Without<MeshMaterial3d<M>>>,
    mut removed: RemovedComponents<MeshMaterial3d<M>>,
    new_levels: Query<(Entity, &ChildOf), Added<ViewDependentLevel>>,
    materials: Query<&MeshMaterial3d<M>>,
    mut given: ResMut<MaterialsGiven>,
) {
    for (model, instance, material) in &changed {
        given.0.push(model);
        for region in instance.drawn_entities() {
            if let Ok(mut region) = commands.get_entity(region) {
                region.try_insert(material.clone());
            }
        }
    }
    // A view-dependent model's level, made after its regions took their material.
    for (level, parent) in &new_levels {
        if let Ok(material) = materials.get(parent.parent()) {
            commands.entity(level).try_insert(material.clone());
        }
    }
    for model in removed.read() {
        // Despawned models have no instance any more: nothing to do.
        let Ok(instance) = instances.get(model) else {
            continue;
        };
        for region in instance.drawn_entities() {
            if let Ok(mut region) = commands.get_entity(region) {
                region.try_remove::<MeshMaterial3d<M>>();
            }
        }
    }
}

/// Warns about new models none of whose materials reached their regions.
pub(super) fn warn_without_material(
    new: Query<Entity, Added<MultiresInstance>>,
    mut given: ResMut<MaterialsGiven>,
) {
    for model in &new {
        if !given.0.contains(&model) {
            warn!(
                "MultiresModel {model} has no MeshMaterial3d of a material with a MultiresMaterialPlugin (StandardMaterial has one): its regions will not render"
            );
        }
    }
    given.0.clear();
}
