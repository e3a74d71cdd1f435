//! `Spawn`: a model's state and children come and go with its asset and its components.
//! New models whose asset is loaded get their region children and state
//! ([`spawn_regions`]); a changed asset rebuilds them ([`mark_modified`]); a
//! [`ViewDependent`] that comes or goes adds or removes the child drawing its level
//! ([`sync_view_dependent`]); a model that goes frees what it made
//! ([`remove_region_meshes`]).

use super::asset::MultiresMesh;
use super::components::{Geomorph, LodRegion, MultiresModel, ViewDependentLevel};
use super::geomorph::RegionGeomorphs;
use super::instance::{AllocationSlot, MultiresInstance, Rebuild, RegionStaging};
use super::messages::{MultiresBuildFailed, MultiresModelReady};
use super::shared::{NoSharedLevels, SharedAsset, SharedLevels, SharedMeshes, SharedState, ladder};
use super::skin::binding::SkinBinding;
use super::skin::{MultiresSkin, SkinPose, SkinState, initial_region_mesh, skinned_on_gpu};
use super::view_dependent::{ViewDependent, ViewDependentState};
use crate::bevy_mesh::to_bevy_mesh;
use crate::mesh::IndexedMesh;
use crate::regions::{RegionCaches, RegionMesh};
use crate::skin::SkinRegionKind;
use bevy::camera::primitives::{Aabb, MeshAabb};
use bevy::camera::visibility::RenderLayers;
use bevy::camera::visibility::{DynamicSkinnedMeshBounds, NoAutoAabb, NoFrustumCulling};
use bevy::ecs::entity::{EntityHashMap, EntityHashSet};
use bevy::ecs::query::{QueryData, QueryItem};
use bevy::mesh::Indices;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::pbr::MAX_JOINTS;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;

/// Everything the plugin keeps on a model once its asset is loaded (removed at once before
/// it is built: on a rebuild, or when someone removed its `MultiresInstance`).
type ModelState = (
    MultiresInstance,
    AllocationSlot,
    RegionStaging,
    SkinState,
    SkinPose,
    RegionGeomorphs,
    ViewDependentState,
    SharedState,
    Rebuild,
);

/// A model [`spawn_regions`] builds: new, or marked [`Rebuild`].
#[derive(QueryData)]
pub(super) struct ModelToBuild {
    entity: Entity,
    model: &'static MultiresModel,
    joints: Option<&'static MultiresSkin>,
    shared: Option<&'static SharedLevels>,
    opted_out: Has<NoSharedLevels>,
    geomorph: Has<Geomorph>,
    /// Its instance before the rebuild, if any.
    built: Option<&'static MultiresInstance>,
    rebuild: Has<Rebuild>,
}

/// The models [`spawn_regions`] builds this frame.
type ToBuild<'w, 's> = Query<'w, 's, ModelToBuild, Or<(Without<MultiresInstance>, With<Rebuild>)>>;

/// What decides how a built model shares: see [`ladder`].
type SharingOf = (
    Entity,
    &'static MultiresInstance,
    Option<&'static SharedLevels>,
    Has<NoSharedLevels>,
    Has<Geomorph>,
    Option<&'static SharedState>,
    Option<&'static MultiresSkin>,
);

/// Gives every new [`MultiresModel`] whose asset is loaded its region children and state,
/// and every [`Rebuild`] one new ones. Any old state goes first (as on despawn, the observer
/// frees its regions), and the new state is added, so materials, levels and geomorphs start
/// over. A skinned asset with a [`MultiresSkin`] puts each rigid region under its joint
/// entity instead. A model shares level meshes as [`ladder`] says, counting this frame's new
/// models: the first instance of an asset that gets a second is rebuilt to share.
#[allow(clippy::too_many_arguments)]
pub(super) fn spawn_regions(
    mut commands: Commands,
    models: ToBuild,
    built: Query<SharingOf, Without<Rebuild>>,
    assets: Res<Assets<MultiresMesh>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>,
    mut shared_meshes: ResMut<SharedMeshes>,
    mut ready: MessageWriter<MultiresModelReady>,
) {
    if models.is_empty() {
        return;
    }
    let totals = instances_once_built(&models, &assets, &shared_meshes);
    share_first_instances(&mut commands, &totals, &built, &assets, &shared_meshes);
    for item in &models {
        let (entity, model, joints) = (item.entity, item.model, item.joints);
        let asset = assets.get(&model.0);
        if item.rebuild || asset.is_some() {
            commands.entity(entity).remove::<ModelState>();
        }
        let Some(asset) = asset else {
            continue; // not loaded yet
        };
        shared_meshes.count_instance(model.0.id());
        let regions = asset.regions().clone();
        let binding = match (asset.skin(), joints) {
            (Some(binding), Some(_)) => Some(binding.clone()),
            (Some(_), None) => {
                warn!(
                    "MultiresModel {entity} shows a skinned mesh but has no MultiresSkin: drawn in its bind pose"
                );
                None
            }
            _ => None,
        };
        let instances = totals.get(&model.0.id()).copied().unwrap_or(1);
        let shared = sharing(&item, asset, instances, &mut shared_meshes, &mut bindposes);
        // Skinned on the CPU (not shared), regions start as their bind pose (rigid ones in
        // their bone's space): the state's buffers and the meshes alike. Shared ones are
        // skinned by Bevy from their level meshes.
        let cpu_skin = binding.as_deref().filter(|_| shared.is_none());
        let initial: Option<Vec<_>> = cpu_skin.map(|b| {
            (0..regions.regions().len())
                .map(|r| initial_region_mesh(b, &regions, r))
                .collect()
        });
        let skin = initial.as_deref().map(SkinState::new);
        let place = Placement {
            model: entity,
            binding: cpu_skin,
            joints,
        };
        let (handles, region_entities) = match &shared {
            Some(state) => {
                spawn_shared_region_entities(&mut commands, entity, &state.asset, joints)
            }
            None => spawn_region_entities(&mut commands, &mut meshes, &regions, &place, initial),
        };
        let targets = regions
            .regions()
            .iter()
            .map(|r| r.min_triangles() as u32)
            .collect();
        let staging = RegionStaging::new(&regions);
        let model_asset = model.0.id();
        let instance = MultiresInstance {
            asset: model_asset,
            caches: region_caches(&regions, shared.is_some()),
            bounds: asset.bounds(),
            obbs: asset.obbs().clone(),
            curves: asset.error_curves().clone(),
            targets,
            mesh_ids: handles.iter().map(Handle::id).collect(),
            meshes: handles,
            region_entities,
            skinned_boxes: binding.as_ref().map(|_| Vec::new()),
            level: None,
            regions,
        };
        let mut model = commands.entity(entity);
        model.insert((instance, AllocationSlot::default()));
        // Skinned models stage their index buffers in their skin state.
        match skin {
            Some(skin) => model.insert(skin),
            None => model.insert(staging),
        };
        if let Some(binding) = binding {
            model.insert(SkinPose::new(binding));
        }
        if let Some(shared) = shared {
            model.insert(shared);
        }
        ready.write(MultiresModelReady {
            model: entity,
            asset: model_asset,
        });
    }
}

/// How a model being built shares, as [`ladder`] says with its asset's `instances` (once
/// this frame's are built): its state, or `None` for meshes of its own.
fn sharing(
    item: &QueryItem<ModelToBuild>,
    asset: &MultiresMesh,
    instances: u32,
    table: &mut SharedMeshes,
    bindposes: &mut Assets<SkinnedMeshInverseBindposes>,
) -> Option<SharedState> {
    let entity = item.entity;
    let cpu_only = cpu_only(asset, item.joints);
    if item.shared.is_some() && cpu_only {
        warn!(
            "MultiresModel {entity} has SharedLevels but Bevy cannot skin it (no MultiresSkin, fewer joints than its skin, or a region over {MAX_JOINTS} joints): its regions keep their own meshes"
        );
    }
    let ladder = ladder(
        item.shared.copied(),
        item.opted_out,
        item.geomorph,
        cpu_only,
        instances,
    )?;
    if ladder.effective_ratio() != ladder.ratio {
        warn!(
            "MultiresModel {entity}: SharedLevels ratio {} is not above {}; {} is used",
            ladder.ratio,
            SharedLevels::MIN_RATIO,
            SharedLevels::MIN_RATIO
        );
    }
    let id = item.model.0.id();
    Some(SharedState {
        asset: table.asset(id, asset.regions(), asset.skin(), bindposes),
        ladder,
    })
}

/// Whether a model of `asset` with joints `joints` must keep its own meshes: it is skinned
/// and Bevy cannot skin it ([`skinned_on_gpu`]), so the plugin blends it on the CPU.
fn cpu_only(asset: &MultiresMesh, joints: Option<&MultiresSkin>) -> bool {
    asset
        .skin()
        .is_some_and(|binding| !skinned_on_gpu(binding, joints))
}

/// Per asset, the models that will show it once `models` are built: those built, and each
/// new one whose asset is loaded (a model rebuilt for the asset it showed counts once).
fn instances_once_built(
    models: &ToBuild,
    assets: &Assets<MultiresMesh>,
    table: &SharedMeshes,
) -> HashMap<AssetId<MultiresMesh>, u32> {
    let mut totals = HashMap::default();
    for item in models {
        let id = item.model.0.id();
        if !assets.contains(id) {
            continue;
        }
        let total = totals.entry(id).or_insert_with(|| table.instances(id));
        if item.built.is_none_or(|built| built.asset != id) {
            *total += 1;
        }
    }
    totals
}

/// Marks [`Rebuild`] each built model that would share once its asset has the instances
/// in `totals` but does not: the one instance an asset had before this frame's.
fn share_first_instances(
    commands: &mut Commands,
    totals: &HashMap<AssetId<MultiresMesh>, u32>,
    built: &Query<SharingOf, Without<Rebuild>>,
    assets: &Assets<MultiresMesh>,
    table: &SharedMeshes,
) {
    let growing = |id: &AssetId<MultiresMesh>| {
        table.instances(*id) == 1 && totals.get(id).is_some_and(|&n| n > 1)
    };
    if !totals.keys().any(growing) {
        return;
    }
    for model in built {
        if let Some(&total) = totals.get(&model.1.asset)
            && shares_otherwise(&model, assets, total)
        {
            commands.entity(model.0).insert(Rebuild);
        }
    }
}

/// Whether a built model shares otherwise than [`ladder`] says it should once its asset
/// has `instances` built models.
fn shares_otherwise(
    (_, instance, explicit, opted_out, geomorph, state, joints): &QueryItem<SharingOf>,
    assets: &Assets<MultiresMesh>,
    instances: u32,
) -> bool {
    let cpu_only = assets
        .get(instance.asset)
        .is_some_and(|asset| cpu_only(asset, *joints));
    let wanted = ladder(
        explicit.copied(),
        *opted_out,
        *geomorph,
        cpu_only,
        instances,
    );
    state.map(|s| s.ladder) != wanted
}

/// Writes a [`MultiresBuildFailed`] for each model whose asset failed to load (once per
/// model and asset).
pub(super) fn report_failed_loads(
    models: Query<(Entity, &MultiresModel), Without<MultiresInstance>>,
    server: Res<AssetServer>,
    mut reported: Local<EntityHashMap<AssetId<MultiresMesh>>>,
    mut failed: MessageWriter<MultiresBuildFailed>,
) {
    reported.retain(|entity, _| models.contains(*entity));
    for (entity, model) in &models {
        let id = model.0.id();
        if reported.get(&entity) == Some(&id) {
            continue;
        }
        if let bevy::asset::LoadState::Failed(error) = server.load_state(id) {
            reported.insert(entity, id);
            failed.write(MultiresBuildFailed {
                entity,
                error: error.to_string(),
            });
        }
    }
}

/// Where a model's region children go: under the model, or (skinned, rigid) under their
/// bone's joint entity.
struct Placement<'a> {
    model: Entity,
    binding: Option<&'a SkinBinding>,
    joints: Option<&'a MultiresSkin>,
}

/// Spawns one child per region, each with its own mesh (skinned regions: their `initial`
/// bind-pose meshes); returns the meshes and the entities, by region.
fn spawn_region_entities(
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    regions: &RegionMesh,
    place: &Placement,
    initial: Option<Vec<IndexedMesh>>,
) -> (Vec<Handle<Mesh>>, Vec<Entity>) {
    let mut initial = initial.map(Vec::into_iter);
    let mut handles = Vec::with_capacity(regions.regions().len());
    let mut entities = Vec::with_capacity(regions.regions().len());
    for (r, region) in regions.regions().iter().enumerate() {
        let (mesh, parent, rigid) = match (place.binding, initial.as_mut().and_then(Iterator::next))
        {
            (Some(binding), Some(mesh)) => match binding.kinds()[r] {
                SkinRegionKind::Rigid { bone } => {
                    match place.joints.and_then(|j| j.joints.get(bone as usize)) {
                        Some(&joint) => (mesh, joint, true),
                        None => {
                            warn!(
                                "MultiresModel {}: joint {bone} is missing; its rigid region stays at the model",
                                place.model
                            );
                            (mesh, place.model, false)
                        }
                    }
                }
                SkinRegionKind::Deformable { .. } => (mesh, place.model, false),
            },
            _ => (
                region.progressive_mesh().vertices().clone(),
                place.model,
                false,
            ),
        };
        let (bevy_mesh, aabb) = placeholder_mesh(mesh, region.fits_u16());
        let handle = meshes.add(bevy_mesh);
        let mut child = commands.spawn((
            Mesh3d(handle.clone()),
            LodRegion { region: r },
            Transform::default(),
            ChildOf(parent),
            aabb,
            NoAutoAabb,
        ));
        if place.binding.is_some() && !rigid {
            // Its vertices move every frame: Bevy's box from the bind pose is stale.
            child.insert(NoFrustumCulling);
        }
        entities.push(child.id());
        handles.push(handle);
    }
    (handles, entities)
}

/// Spawns one child per region of a shared model, each with the box of all its vertices and
/// no mesh yet: its first `Upload` puts it on the level mesh of its levels. A skinned
/// model's children are skinned by Bevy, on the joints of `joints` their region uses, and
/// culled by bounds Bevy moves with those joints.
fn spawn_shared_region_entities(
    commands: &mut Commands,
    model: Entity,
    asset: &SharedAsset,
    joints: Option<&MultiresSkin>,
) -> (Vec<Handle<Mesh>>, Vec<Entity>) {
    let entities = asset
        .boxes
        .iter()
        .enumerate()
        .map(|(r, &aabb)| {
            let child = (
                Mesh3d::default(),
                LodRegion { region: r },
                Transform::default(),
                ChildOf(model),
                aabb,
                NoAutoAabb,
            );
            let mut child = commands.spawn(child);
            if let (Some(skin), Some(joints)) = (&asset.skin, joints) {
                let region_joints = skin.binding.region_joints(r).iter();
                child.insert((
                    SkinnedMesh {
                        inverse_bindposes: skin.inverse_bindposes[r].clone(),
                        joints: region_joints.map(|&j| joints.joints[j as usize]).collect(),
                    },
                    DynamicSkinnedMeshBounds,
                ));
            }
            child.id()
        })
        .collect();
    (vec![Handle::default(); asset.boxes.len()], entities)
}

/// The Bevy mesh of a region or a variable-resolution level before its first level: the
/// vertex table (joints and weights left out: the plugin skins on the CPU) and one degenerate
/// triangle in the index width the levels use, so the renderer gives the mesh its index
/// allocation from the start. With it, the box of every vertex, as Bevy would compute it: the
/// plugin keeps it, since level changes do not go through the asset's change events.
fn placeholder_mesh(vertices: IndexedMesh, narrow: bool) -> (Mesh, Aabb) {
    let mut mesh = to_bevy_mesh(
        &IndexedMesh {
            joints: None,
            weights: None,
            ..vertices
        },
        &[],
    );
    mesh.insert_indices(if narrow {
        Indices::U16(vec![0; 3])
    } else {
        Indices::U32(vec![0; 3])
    });
    let aabb = mesh.compute_aabb().unwrap_or_default();
    (mesh, aabb)
}

/// Hot reload: every model showing a [`MultiresMesh`] that changed is marked [`Rebuild`], so
/// [`spawn_regions`] builds it anew from the new asset.
pub(super) fn mark_modified(
    mut commands: Commands,
    mut events: MessageReader<AssetEvent<MultiresMesh>>,
    models: Query<(Entity, &MultiresModel), With<MultiresInstance>>,
) {
    let mut modified = Vec::new();
    for event in events.read() {
        if let AssetEvent::Modified { id } = event {
            modified.push(*id);
        }
    }
    if modified.is_empty() {
        return;
    }
    for (model, handle) in &models {
        if modified.contains(&handle.0.id()) {
            commands.entity(model).insert(Rebuild);
        }
    }
}

/// Every model whose [`MultiresModel`] handle changed to another asset is marked
/// [`Rebuild`], as a `Mesh3d` given another mesh draws it: its old regions go, and the new
/// asset's come once it is loaded.
pub(super) fn mark_handle_changed(
    mut commands: Commands,
    models: Query<(Entity, &MultiresModel, &MultiresInstance), Changed<MultiresModel>>,
) {
    for (entity, model, instance) in &models {
        if model.0.id() != instance.asset {
            commands.entity(entity).insert(Rebuild);
        }
    }
}

/// A new instance's caches: a shared model's level meshes are made from its asset's caches,
/// so it keeps its levels alone.
fn region_caches(regions: &RegionMesh, shared: bool) -> RegionCaches {
    if shared {
        RegionCaches::levels_only(regions)
    } else {
        RegionCaches::new(regions)
    }
}

/// The components whose removal may change how a model shares.
#[derive(bevy::ecs::system::SystemParam)]
pub(super) struct RemovedSharing<'w, 's> {
    ladders: RemovedComponents<'w, 's, SharedLevels>,
    opt_outs: RemovedComponents<'w, 's, NoSharedLevels>,
    geomorphs: RemovedComponents<'w, 's, Geomorph>,
}

/// Every built model whose [`SharedLevels`] came, changed or went, or whose
/// [`NoSharedLevels`] or [`Geomorph`] came or went, is marked [`Rebuild`] when [`ladder`]
/// now says otherwise than how it shares: its regions move between their own meshes and the
/// shared ones.
#[allow(clippy::type_complexity)]
pub(super) fn mark_shared_changed(
    mut commands: Commands,
    changed: Query<
        Entity,
        (
            With<MultiresInstance>,
            Or<(
                Changed<SharedLevels>,
                Added<NoSharedLevels>,
                Added<Geomorph>,
            )>,
        ),
    >,
    mut removed: RemovedSharing,
    built: Query<SharingOf, Without<Rebuild>>,
    assets: Res<Assets<MultiresMesh>>,
    table: Res<SharedMeshes>,
) {
    let removed = removed
        .ladders
        .read()
        .chain(removed.opt_outs.read())
        .chain(removed.geomorphs.read());
    for model in changed.iter().chain(removed) {
        if let Ok(model) = built.get(model)
            && shares_otherwise(&model, &assets, table.instances(model.1.asset))
        {
            commands.entity(model.0).try_insert(Rebuild);
        }
    }
}

/// Starts and stops the view-dependent refinement of models as their [`ViewDependent`] comes
/// and goes: gives the model a child drawing its variable-resolution level and hides its
/// regions, or despawns that child, frees its mesh and shows the regions again. Skinned
/// models keep their regions.
#[allow(clippy::type_complexity)]
pub(super) fn sync_view_dependent(
    mut commands: Commands,
    mut models: Query<
        (
            Entity,
            &mut MultiresInstance,
            &MultiresModel,
            Option<Ref<ViewDependent>>,
            Option<&mut ViewDependentState>,
            Option<&mut RegionStaging>,
            Has<SkinPose>,
        ),
        // The others have no refinement to start or stop.
        Or<(With<ViewDependent>, With<ViewDependentState>)>,
    >,
    assets: Res<Assets<MultiresMesh>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut warned: Local<EntityHashSet>,
) {
    for (entity, mut instance, model, settings, state, staging, skinned) in &mut models {
        match (state, settings) {
            (None, None) => {}
            (Some(mut state), Some(settings)) => {
                if settings.is_changed() {
                    state.set_settings((*settings).clone());
                }
            }
            (Some(state), None) => {
                commands.entity(state.entity).try_despawn();
                meshes.remove(&state.handle);
                commands.entity(entity).remove::<ViewDependentState>();
                instance.level = None;
                for &region in &instance.region_entities {
                    commands.entity(region).try_insert(Visibility::Inherited);
                }
                // The regions kept their levels and their meshes; the next allocation moves them.
                if let Some(mut staging) = staging {
                    staging.settled = false;
                }
                warned.remove(&entity);
            }
            (None, Some(settings)) => {
                let variable = assets.get(&model.0).and_then(|a| a.variable().cloned());
                let reason = if skinned {
                    Some("it is skinned, and skinned models keep their regions")
                } else if variable.is_none() {
                    Some("its MultiresMesh has no refinement data (MultiresMesh::with_refinement)")
                } else {
                    None
                };
                if let Some(reason) = reason {
                    if warned.insert(entity) {
                        warn!(
                            "MultiresModel {entity} is ViewDependent but keeps its regions: {reason}"
                        );
                    }
                    continue;
                }
                let Some(variable) = variable else { continue };
                let narrow = variable.mesh().vertices().vertex_count() <= usize::from(u16::MAX);
                let (mesh, aabb) = placeholder_mesh(variable.mesh().vertices().clone(), narrow);
                let handle = meshes.add(mesh);
                let child = commands
                    .spawn((
                        Mesh3d(handle.clone()),
                        ViewDependentLevel,
                        Transform::default(),
                        ChildOf(entity),
                        aabb,
                        NoAutoAabb,
                    ))
                    .id();
                for &region in &instance.region_entities {
                    commands.entity(region).try_insert(Visibility::Hidden);
                }
                let state =
                    ViewDependentState::new(variable, child, handle, narrow, (*settings).clone());
                instance.level = Some(state.summary());
                commands.entity(entity).insert(state);
            }
        }
    }
}

/// A model's `RenderLayers` go to the entities that draw it (its regions, under it or under
/// joints, and its view-dependent level), when they are made and whenever the model's
/// layers change or go: they draw for the cameras the model is meant for.
#[allow(clippy::type_complexity)]
pub(super) fn sync_render_layers(
    mut commands: Commands,
    models: Query<
        (
            &MultiresInstance,
            Option<&RenderLayers>,
            Option<&ViewDependentState>,
        ),
        Or<(
            Changed<RenderLayers>,
            Added<MultiresInstance>,
            Added<ViewDependentState>,
        )>,
    >,
    mut removed: RemovedComponents<RenderLayers>,
    all: Query<(&MultiresInstance, Option<&ViewDependentState>), Without<RenderLayers>>,
) {
    let drawn_by = |instance: &MultiresInstance, state: Option<&ViewDependentState>| {
        let level = state.map(|s| s.entity);
        instance.region_entities.clone().into_iter().chain(level)
    };
    for (instance, layers, state) in &models {
        let Some(layers) = layers else { continue };
        for entity in drawn_by(instance, state) {
            commands.entity(entity).try_insert(layers.clone());
        }
    }
    for model in removed.read() {
        if let Ok((instance, state)) = all.get(model) {
            for entity in drawn_by(instance, state) {
                commands.entity(entity).try_remove::<RenderLayers>();
            }
        }
    }
}

/// Removes a model's region entities (those under the model and those under joints), the
/// child drawing its view-dependent level, and their meshes, when its instance goes away.
pub(super) fn remove_region_meshes(
    remove: On<Remove, MultiresInstance>,
    mut commands: Commands,
    instances: Query<(
        &MultiresInstance,
        Option<&ViewDependentState>,
        Has<SharedState>,
    )>,
    meshes: Option<ResMut<Assets<Mesh>>>,
    table: Option<ResMut<SharedMeshes>>,
) {
    let Ok((instance, view_dependent, shared)) = instances.get(remove.entity) else {
        return;
    };
    if let Some(mut table) = table {
        table.uncount_instance(instance.asset);
    }
    for entity in instance.drawn_entities() {
        commands.entity(entity).try_despawn();
    }
    let Some(mut meshes) = meshes else {
        return;
    };
    // Level meshes other instances may show go when Bevy drops their last handle.
    let own = if shared {
        &[][..]
    } else {
        &instance.meshes[..]
    };
    for handle in own.iter().chain(view_dependent.map(|v| &v.handle)) {
        meshes.remove(handle);
    }
}
