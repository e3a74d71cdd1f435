//! Turning the meshes of a spawned scene (typically a glTF character) into multiresolution
//! models, so Bevy's own loader, joints and `AnimationPlayer` drive them.

use super::asset::{MultiresMesh, PartitionSpec};
use super::components::{CountInBudget, Geomorph, MultiresModel};
use super::error::MultiresError;
use super::messages::MultiresBuildFailed;
use super::skin::MultiresSkin;
use crate::bevy_mesh::{drawn_triangles, from_bevy_mesh};
use crate::mesh::{IndexedMesh, LoadLimits, MeshError};
use crate::multires::BuildOptions;
use crate::skin::DEFAULT_RIGID_DELTA;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::tasks::futures::check_ready;
use bevy::tasks::{AsyncComputeTaskPool, Task, TaskPool};

/// Put on the root of a scene (next to the glTF loader's scene root component): once the
/// scene has spawned and its meshes are loaded, the plugin turns every mesh under it into a
/// multiresolution model under the global budget.
///
/// - A skinned mesh (`SkinnedMesh`) becomes a skinned model: regions by influence, rigid
///   regions under their joints, deformable regions blended on the CPU from the same
///   joints, so the scene's `AnimationPlayer` drives it as before.
/// - An unskinned mesh becomes a [`MultiresModel`] on the same entity (cut as
///   [`static_partition`](Self::static_partition) says): if it hangs under a joint, the
///   hierarchy animates it (ASLOD section 4).
/// - A mesh with morph targets stays conventional and counts against the budget as fixed
///   cost ([`CountInBudget`]), with a warning (once).
/// - A [`Geomorph`] on this entity goes to every model it makes.
///
/// The original mesh handle moves to [`MultiresSourceMesh`] on its entity. Assets are built
/// once per source mesh, on Bevy's [`AsyncComputeTaskPool`], and shared by every scene that
/// shows it; until all of a scene's assets are ready, the scene keeps showing its original
/// meshes (skinned by Bevy as usual), so no frame stalls on the build. When it is done the
/// plugin adds [`MultiresSceneModels`] to this entity.
///
/// **Baked scenes.** With [`baked`](Self::baked) naming an `.mrm` file made from the same
/// glTF (`aslod bake scene.glb -o scene.mrm`), nothing is built: the asset of each mesh
/// primitive is loaded from the file's entry with the same key as the primitive's Bevy label
/// (`Mesh0/Primitive0` is `"scene.mrm#Mesh0/Primitive0"`). The glTF still supplies the
/// skeleton, the materials and the animations. An entry that is missing, fails to load, or
/// does not fit (a skinned entry with another joint count than the mesh's skin, or a skinned
/// entry for an unskinned mesh, or joints named otherwise than the skin's joint entities'
/// `Name`s) is built as without a baked file, with a warning.
#[derive(Component, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Default)]
pub struct MultiresScene {
    /// δ: a skinned vertex whose dominant weight is at least `1 − δ` is rigid. Default
    /// [`DEFAULT_RIGID_DELTA`], so imported skinning stays exact.
    pub rigid_delta: f32,
    /// How unskinned meshes are cut into regions. Default [`PartitionSpec::Single`].
    pub static_partition: PartitionSpec,
    /// How unskinned meshes are built (attribute weights, local weight, …). Skinned meshes
    /// build with the default options. Default: `BuildOptions::default()`. (Not reflected.)
    #[reflect(ignore)]
    pub build_options: BuildOptions,
    /// The asset path of an `.mrm` file baked from this scene's glTF, to load instead of
    /// building. Default `None`. (Its own δ and partition apply, not the two above.)
    pub baked: Option<String>,
}

impl Default for MultiresScene {
    fn default() -> Self {
        Self {
            rigid_delta: DEFAULT_RIGID_DELTA,
            static_partition: PartitionSpec::Single,
            build_options: BuildOptions::default(),
            baked: None,
        }
    }
}

impl MultiresScene {
    /// Loads the scene's assets from a baked `.mrm` file (see [`baked`](Self::baked)).
    #[must_use]
    pub fn with_baked(mut self, path: impl Into<String>) -> Self {
        self.baked = Some(path.into());
        self
    }

    /// Builds unskinned meshes with `options` (see [`build_options`](Self::build_options)).
    #[must_use]
    pub fn with_build_options(mut self, options: BuildOptions) -> Self {
        self.build_options = options;
        self
    }
}

/// What the plugin made of a [`MultiresScene`].
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct MultiresSceneModels {
    /// Model roots of the skinned meshes (children of the original mesh entities).
    pub skinned: Vec<Entity>,
    /// Unskinned mesh entities that became models in place, and the models made for the
    /// copies of a node with [`GltfMeshInstances`] (children of its mesh entities).
    pub rigid: Vec<Entity>,
    /// Meshes kept conventional (morph targets, or a build error), counted in the budget.
    pub fixed: Vec<Entity>,
    /// Skinned vertices with more than two influences, over all skinned meshes.
    pub more_than_two: usize,
}

impl MultiresSceneModels {
    /// Every model root of the scene, skinned first.
    pub fn models(&self) -> impl Iterator<Item = Entity> + '_ {
        self.skinned.iter().chain(&self.rigid).copied()
    }
}

/// The copies a glTF node places through `EXT_mesh_gpu_instancing`, each a transform in the
/// node's space. Bevy 0.19's glTF loader ignores the extension and draws the node's mesh
/// once; with the `gltf_instancing` feature (default) the plugin's loader extension puts
/// this on the node's entity, and a [`MultiresScene`] makes one model per copy, children of
/// the mesh entity (sharing their asset's level meshes). Without a `MultiresScene` nothing
/// reads it. Skinned nodes ignore the extension.
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq)]
#[reflect(Component, Default)]
pub struct GltfMeshInstances(pub Vec<Transform>);

/// The mesh an entity showed before it became multiresolution (kept, not dropped).
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct MultiresSourceMesh(pub Handle<Mesh>);

/// Built assets by source mesh (and skin), shared by every scene instance. A built asset is
/// held (pinned) only until the scenes waiting for it have their models; from then on the
/// models hold it, and once none does Bevy drops it and its entry goes (a later scene builds
/// it again). Entries of source meshes that are gone go too.
#[derive(Resource, Default)]
pub(crate) struct SceneAssetCache {
    built: HashMap<BuildKey, Built>,
    warned_morph: bool,
}

/// The [`AslodPlugin::load_limits`](super::AslodPlugin::load_limits) scene meshes are held to.
#[derive(Resource, Clone, Copy, Debug, Default)]
pub(crate) struct SceneLimits(pub(crate) LoadLimits);

/// The scene's mesh, copied for the build once it is within `limits` (checked before the
/// copy: a mesh over them stays conventional, and the build's warning names the limit).
fn indexed_within(
    mesh: &Mesh,
    joints: usize,
    limits: &LoadLimits,
) -> Result<IndexedMesh, MeshError> {
    LoadLimits::check("vertices", mesh.count_vertices() as u64, limits.vertices)?;
    LoadLimits::check("triangles", drawn_triangles(mesh), limits.triangles)?;
    LoadLimits::check("joints", joints as u64, limits.joints)?;
    from_bevy_mesh(mesh)
}

/// What an asset is built from: the mesh, its skin, and the scene's options (δ's bits, the
/// static partition and the build options, by their printed form), so scenes with different
/// options do not share an asset.
type BuildKey = (
    AssetId<Mesh>,
    Option<AssetId<SkinnedMeshInverseBindposes>>,
    u32,
    PartitionSpec,
    String,
);

fn build_key(mesh: &Mesh3d, skin: Option<&SkinnedMesh>, options: &MultiresScene) -> BuildKey {
    (
        mesh.0.id(),
        skin.map(|s| s.inverse_bindposes.id()),
        options.rigid_delta.to_bits(),
        options.static_partition,
        format!("{:?}", options.build_options),
    )
}

enum Built {
    /// Loading from a baked file; built from the inputs if that fails or does not fit.
    Loading(Handle<MultiresMesh>, Box<BuildInputs>),
    /// Building on the async compute pool.
    Pending(Task<Result<MultiresMesh, MultiresError>>),
    /// Built: the asset, its vertices with more than two influences, and the handle that
    /// keeps it until a scene's models hold it.
    Ok(AssetId<MultiresMesh>, usize, Option<Handle<MultiresMesh>>),
    /// The build failed, for this reason.
    Failed(String),
}

/// What one source mesh's asset is built from.
struct BuildInputs {
    indexed: Result<IndexedMesh, MeshError>,
    inverse_bindposes: Option<Vec<Mat4>>,
    /// The skin's joints' `Name`s (empty for a joint without one).
    joint_names: Vec<String>,
    rigid_delta: f32,
    static_partition: PartitionSpec,
    build_options: BuildOptions,
}

impl BuildInputs {
    /// Starts the build on the async compute pool.
    fn spawn(self) -> Built {
        Built::Pending(
            AsyncComputeTaskPool::get_or_init(TaskPool::default).spawn(async move {
                // A panic in the build (a bug) leaves the mesh conventional instead of taking
                // the app down.
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    build(
                        self.indexed,
                        self.inverse_bindposes,
                        self.rigid_delta,
                        self.static_partition,
                        &self.build_options,
                    )
                }))
                .unwrap_or(Err(MultiresError::BuildPanicked))
            }),
        )
    }

    /// Whether a baked asset can stand for the mesh these inputs describe: skinned for a
    /// skinned mesh, with as many joints, named alike where both sides name them.
    fn fits(&self, asset: &MultiresMesh) -> bool {
        match (&self.inverse_bindposes, asset.skin()) {
            (Some(ib), Some(skin)) => {
                let names = skin.joint_names();
                skin.joint_count() == ib.len()
                    && names
                        .iter()
                        .zip(&self.joint_names)
                        .all(|(baked, here)| baked.is_empty() || here.is_empty() || baked == here)
            }
            (None, None) => true,
            _ => false,
        }
    }
}

/// Builds one source mesh's asset (runs on the async compute pool).
fn build(
    mesh: Result<IndexedMesh, MeshError>,
    inverse_bindposes: Option<Vec<Mat4>>,
    rigid_delta: f32,
    static_partition: PartitionSpec,
    build_options: &BuildOptions,
) -> Result<MultiresMesh, MultiresError> {
    let indexed = mesh?;
    match inverse_bindposes {
        Some(ib) => MultiresMesh::from_skinned(&indexed, &ib, rigid_delta),
        None => {
            let partition = static_partition.partition(&indexed)?;
            MultiresMesh::from_indexed_with(&indexed, &partition, build_options)
        }
    }
}

impl SceneAssetCache {
    /// Lets go of every built asset: from now on only models hold them.
    fn unpin(&mut self) {
        for built in self.built.values_mut() {
            if let Built::Ok(_, _, pin) = built {
                *pin = None;
            }
        }
    }

    /// Collects the baked assets that loaded (building those that did not load or fit) and
    /// the builds that finished: their assets join `Assets<MultiresMesh>`.
    fn poll(
        &mut self,
        multires: &mut Assets<MultiresMesh>,
        meshes: &Assets<Mesh>,
        server: &AssetServer,
    ) {
        // Assets no model holds any more, and source meshes that are gone, leave the cache.
        self.built.retain(|key, built| {
            meshes.contains(key.0)
                && match built {
                    Built::Ok(id, _, pin) => pin.is_some() || multires.contains(*id),
                    _ => true,
                }
        });
        for built in self.built.values_mut() {
            if let Built::Loading(handle, _) = built {
                let asset = multires.get(&*handle);
                let failed = server.load_state(handle.id()).is_failed();
                if asset.is_none() && !failed {
                    continue;
                }
                let Built::Loading(handle, inputs) =
                    std::mem::replace(built, Built::Failed(String::new()))
                else {
                    continue;
                };
                let path = handle.path().map(ToString::to_string).unwrap_or_default();
                match multires.get(&handle) {
                    Some(asset) if inputs.fits(asset) => {
                        let more = asset.skin().map_or(0, |s| s.more_than_two());
                        *built = Built::Ok(handle.id(), more, Some(handle));
                    }
                    Some(_) => {
                        warn!(
                            "{path}: the baked asset does not fit its mesh (skin or joint count); building it"
                        );
                        *built = inputs.spawn();
                    }
                    None => {
                        warn!("{path}: the baked asset did not load; building it");
                        *built = inputs.spawn();
                    }
                }
                continue;
            }
            let Built::Pending(task) = built else {
                continue;
            };
            let Some(result) = check_ready(task) else {
                continue;
            };
            *built = match result {
                Ok(asset) => {
                    // Said once per source mesh, not once per scene that shows it.
                    let more = asset.skin().map_or(0, |s| s.more_than_two());
                    if more > 0 {
                        info!(
                            "{more} skinned vertices have more than two influences: they join the region of their two largest and blend with all of them"
                        );
                    }
                    let handle = multires.add(asset);
                    Built::Ok(handle.id(), more, Some(handle))
                }
                Err(e) => {
                    warn!("a mesh stays conventional (fixed cost): {e}");
                    Built::Failed(e.to_string())
                }
            };
        }
    }
}

/// The mesh entities of scenes, as `convert_scenes` reads them.
/// Where [`GltfMeshInstances`] may be: on a mesh entity, or on its node (the parent of a
/// primitive's entity).
type GpuCopies<'w, 's> =
    Query<'w, 's, (Option<&'static GltfMeshInstances>, Option<&'static ChildOf>)>;

/// The copies placed of mesh entity `entity`'s mesh, if its node places any.
fn copies_of<'a>(copies: &'a GpuCopies, entity: Entity) -> Option<&'a [Transform]> {
    let (own, parent) = copies.get(entity).ok()?;
    let found = own.or_else(|| copies.get(parent?.parent()).ok()?.0)?;
    Some(&found.0)
}

type MeshEntities<'w, 's> = Query<
    'w,
    's,
    (
        &'static Mesh3d,
        Option<&'static SkinnedMesh>,
        Option<&'static MeshMaterial3d<StandardMaterial>>,
    ),
>;

/// Converts the meshes of every spawned [`MultiresScene`] once they are all loaded: starts
/// the builds it needs (or the loads from its baked file), then, once they are all done,
/// makes its models.
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn convert_scenes(
    mut commands: Commands,
    scenes: Query<(Entity, &MultiresScene, Option<&Geomorph>), Without<MultiresSceneModels>>,
    children: Query<&Children>,
    mesh_entities: MeshEntities,
    meshes: Res<Assets<Mesh>>,
    bindposes: Option<Res<Assets<SkinnedMeshInverseBindposes>>>,
    mut multires: ResMut<Assets<MultiresMesh>>,
    mut cache: ResMut<SceneAssetCache>,
    server: Res<AssetServer>,
    names: Query<&'static Name>,
    limits: Res<SceneLimits>,
    copies: GpuCopies,
    mut messages: SceneMessages,
) {
    // Apps without skinning (no `Assets<SkinnedMeshInverseBindposes>`) can still convert
    // unskinned scenes.
    let Some(bindposes) = bindposes else {
        if !scenes.is_empty() {
            warn_once!(
                "MultiresScene needs Assets<SkinnedMeshInverseBindposes> (Bevy's mesh plugin)"
            );
        }
        return;
    };
    cache.poll(&mut multires, &meshes, &server);
    if scenes.is_empty() {
        // No scene waits for an asset: the models hold what they show.
        cache.unpin();
    }
    for (root, options, geomorph) in &scenes {
        let found: Vec<Entity> = children
            .iter_descendants(root)
            .filter(|&e| mesh_entities.contains(e))
            .collect();
        if found.is_empty() {
            continue; // not spawned yet
        }
        let loaded = found.iter().all(|&e| {
            let Ok((mesh, skin, _)) = mesh_entities.get(e) else {
                return false;
            };
            meshes.contains(&mesh.0)
                && skin.is_none_or(|s| bindposes.contains(&s.inverse_bindposes))
        });
        if !loaded {
            continue;
        }
        // Start the builds this scene needs that nobody started; convert once all are done.
        let sources = SceneSources {
            meshes: &meshes,
            bindposes: &bindposes,
            names: &names,
            server: &server,
            limits: &limits.0,
        };
        let mut pending = false;
        for &entity in &found {
            let Ok((mesh3d, skin, _)) = mesh_entities.get(entity) else {
                continue;
            };
            pending |= cache.start_build(mesh3d, skin, options, &sources);
        }
        if pending {
            continue;
        }
        let result = cache.make_models(
            &mut commands,
            &found,
            &mesh_entities,
            &meshes,
            &mut multires,
            geomorph,
            options,
            &mut messages.failed,
            &copies,
        );
        messages.converted.write(MultiresSceneConverted {
            scene: root,
            models: result.clone(),
        });
        commands.entity(root).insert(result);
    }
}

/// The messages `convert_scenes` writes.
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct SceneMessages<'w> {
    failed: MessageWriter<'w, MultiresBuildFailed>,
    converted: MessageWriter<'w, MultiresSceneConverted>,
}

/// What a scene's builds are started from.
struct SceneSources<'a, 'w, 's> {
    meshes: &'a Assets<Mesh>,
    bindposes: &'a Assets<SkinnedMeshInverseBindposes>,
    names: &'a Query<'w, 's, &'static Name>,
    server: &'a AssetServer,
    limits: &'a LoadLimits,
}

impl SceneAssetCache {
    /// Starts the build (or the load from the baked file) of one mesh of a scene unless it
    /// was started already; returns whether it is still under way.
    fn start_build(
        &mut self,
        mesh3d: &Mesh3d,
        skin: Option<&SkinnedMesh>,
        options: &MultiresScene,
        sources: &SceneSources<'_, '_, '_>,
    ) -> bool {
        let Some(mesh) = sources.meshes.get(&mesh3d.0) else {
            return false;
        };
        if mesh.has_morph_targets() {
            return false;
        }
        let key = build_key(mesh3d, skin, options);
        let built = self.built.entry(key).or_insert_with(|| {
            // The conversion copies the mesh here; the build runs on the pool.
            let inputs = BuildInputs {
                indexed: indexed_within(mesh, skin.map_or(0, |s| s.joints.len()), sources.limits),
                inverse_bindposes: skin.map(|skin| {
                    sources
                        .bindposes
                        .get(&skin.inverse_bindposes)
                        .map(|b| b.to_vec())
                        .unwrap_or_default()
                }),
                joint_names: skin.map_or_else(Vec::new, |skin| {
                    skin.joints
                        .iter()
                        .map(|&j| {
                            sources
                                .names
                                .get(j)
                                .map_or_else(|_| String::new(), |n| n.as_str().to_owned())
                        })
                        .collect()
                }),
                rigid_delta: options.rigid_delta,
                static_partition: options.static_partition,
                build_options: options.build_options.clone(),
            };
            let label = mesh3d.0.path().and_then(|p| p.label());
            match (&options.baked, label) {
                (Some(file), Some(label)) => Built::Loading(
                    sources.server.load(format!("{file}#{label}")),
                    Box::new(inputs),
                ),
                _ => inputs.spawn(),
            }
        });
        matches!(built, Built::Pending(_) | Built::Loading(..))
    }

    /// Makes a scene's models once all of its assets are done: a skinned model under each
    /// skinned mesh, unskinned meshes models in place, the others conventional.
    #[allow(clippy::too_many_arguments)]
    fn make_models(
        &mut self,
        commands: &mut Commands,
        found: &[Entity],
        mesh_entities: &MeshEntities,
        meshes: &Assets<Mesh>,
        multires: &mut Assets<MultiresMesh>,
        geomorph: Option<&Geomorph>,
        options: &MultiresScene,
        failed: &mut MessageWriter<MultiresBuildFailed>,
        copies: &GpuCopies,
    ) -> MultiresSceneModels {
        let mut result = MultiresSceneModels::default();
        for &entity in found {
            let Ok((mesh3d, skin, material)) = mesh_entities.get(entity) else {
                continue;
            };
            let Some(mesh) = meshes.get(&mesh3d.0) else {
                continue;
            };
            if mesh.has_morph_targets() {
                if !self.warned_morph {
                    warn!(
                        "meshes with morph targets stay conventional: they count against the polygon budget at full detail"
                    );
                    self.warned_morph = true;
                }
                commands.entity(entity).insert(CountInBudget);
                result.fixed.push(entity);
                continue;
            }
            let key = build_key(mesh3d, skin, options);
            let built = match self.built.get(&key) {
                Some(Built::Ok(id, more, pin)) => pin
                    .clone()
                    .or_else(|| multires.get_strong_handle(*id))
                    .map(|handle| (handle, *more)),
                _ => None,
            };
            let Some((handle, more_than_two)) = built else {
                let error = match self.built.get(&key) {
                    Some(Built::Failed(e)) => e.clone(),
                    _ => "its asset is gone".to_owned(),
                };
                failed.write(MultiresBuildFailed { entity, error });
                commands.entity(entity).insert(CountInBudget);
                result.fixed.push(entity);
                continue;
            };
            let source = MultiresSourceMesh(mesh3d.0.clone());
            match skin {
                Some(skin) => {
                    result.more_than_two += more_than_two;
                    let model = child_model(
                        commands,
                        handle,
                        Transform::IDENTITY,
                        entity,
                        material,
                        geomorph,
                    )
                    .insert(MultiresSkin {
                        joints: skin.joints.clone(),
                    })
                    .id();
                    result.skinned.push(model);
                    commands.entity(entity).remove::<Mesh3d>().insert(source);
                }
                None => match copies_of(copies, entity) {
                    Some(placed) => {
                        commands.entity(entity).remove::<Mesh3d>().insert(source);
                        for &at in placed {
                            let model = child_model(
                                commands,
                                handle.clone(),
                                at,
                                entity,
                                material,
                                geomorph,
                            );
                            result.rigid.push(model.id());
                        }
                    }
                    None => {
                        let mut model = commands.entity(entity);
                        model
                            .remove::<Mesh3d>()
                            .insert((source, MultiresModel(handle)));
                        if let Some(&geomorph) = geomorph {
                            model.insert(geomorph);
                        }
                        result.rigid.push(entity);
                    }
                },
            }
        }
        result
    }
}

/// Spawns a model of `handle` at `at` under mesh entity `parent`, with the mesh's material
/// and the scene's geomorph.
fn child_model<'a>(
    commands: &'a mut Commands,
    handle: Handle<MultiresMesh>,
    at: Transform,
    parent: Entity,
    material: Option<&MeshMaterial3d<StandardMaterial>>,
    geomorph: Option<&Geomorph>,
) -> EntityCommands<'a> {
    let mut model = commands.spawn((MultiresModel(handle), at, ChildOf(parent)));
    if let Some(material) = material {
        model.insert(material.clone());
    }
    if let Some(&geomorph) = geomorph {
        model.insert(geomorph);
    }
    model
}

/// A [`MultiresScene`] is converted: the same
/// [`MultiresSceneModels`] the plugin put on its root.
#[derive(Message, Clone, Debug, PartialEq, Eq)]
pub struct MultiresSceneConverted {
    /// The scene root.
    pub scene: Entity,
    /// What became of its meshes.
    pub models: MultiresSceneModels,
}
