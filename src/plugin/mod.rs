//! The Bevy plugin: multiresolution models under one polygon budget (feature `bevy`).
//!
//! Mark an entity with [`MultiresModel`] (a handle to a [`MultiresMesh`] asset) next to a
//! `MeshMaterial3d<StandardMaterial>` (or another material with a [`MultiresMaterialPlugin`])
//! and a `Transform`. The plugin gives it one child per
//! region, each with its own `Mesh3d` (owned by the plugin), the model's material and a
//! [`LodRegion`], and keeps the instance's levels of detail in a [`MultiresInstance`] on the
//! model. Every frame it splits [`PolygonBudget::total`] among all regions of all models in
//! view (ASLOD's runtime loop, section 5.4) and rewrites the index buffers of the regions
//! whose level changed. A level change reaches the GPU as that region's index data alone
//! (a skinned region's blended vertices as well): the plugin writes it into Bevy's mesh
//! buffers itself instead of having Bevy re-upload the whole mesh ([`RegionUpload`]).
//!
//! | component / resource | on | meaning |
//! |---|---|---|
//! | [`MultiresModel`] | model root | which [`MultiresMesh`] to show |
//! | [`LodPriority`] | model root (optional) | the user constant `c` in `w = c·A`; default `1` |
//! | [`CountInBudget`] | a conventional `Mesh3d` entity | its triangles are fixed cost |
//! | [`ViewDependent`] | model root (optional) | refine the model per frame as one variable-resolution mesh instead of by regions |
//! | [`RefineCamera`] | a camera (optional) | the camera view-dependent models refine for |
//! | [`NoLodAllocation`] | a camera (optional) | the camera takes no part in the budget split |
//! | [`LodCameraWeight`] | a camera (optional) | the weight of its view in the split; default `1` |
//! | `RenderLayers` | model root, camera (optional) | a camera weighs only the models it draws; the model's layers go to its regions |
//! | [`PolygonBudget`] | resource | `P`, α, hysteresis ε, how a model's regions share its triangles ([`RegionSplit`]); or a frame time to aim at ([`FrameTarget`]) |
//! | [`AslodViewport`] | resource (optional) | viewport size for cameras without a known one |
//! | [`AslodOverlay`] | resource | draws every region's world box with gizmos, its triangles and a status line ([`status_line`]) |
//! | [`AslodStats`] | resource | what the last frame did (also as diagnostics) |
//! | [`RegionUpload`] | resource | how level changes reach the renderer; default indices only |
//! | [`RegionUploadStats`] | render-world resource | bytes the plugin wrote to the GPU last frame |
//! | [`MultiresMaterialPlugin<M>`] | plugin | regions take the model's `MeshMaterial3d<M>` |
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_aslod::plugin::{AslodPlugin, MultiresMesh, MultiresModel, PartitionSpec};
//!
//! fn setup(
//!     mut commands: Commands,
//!     mut multires: ResMut<Assets<MultiresMesh>>,
//!     mut materials: ResMut<Assets<StandardMaterial>>,
//! ) {
//!     let sphere = Mesh::from(Sphere::new(1.0).mesh().ico(5).unwrap());
//!     let Ok(asset) = MultiresMesh::from_bevy_mesh(&sphere, PartitionSpec::Clusters(8)) else {
//!         return;
//!     };
//!     commands.spawn((
//!         MultiresModel(multires.add(asset)),
//!         MeshMaterial3d(materials.add(StandardMaterial::default())),
//!         Transform::default(),
//!     ));
//!     commands.spawn((Camera3d::default(), Transform::from_xyz(0.0, 0.0, 5.0)));
//! }
//!
//! App::new()
//!     .add_plugins((DefaultPlugins, AslodPlugin::default().with_budget(20_000)))
//!     .add_systems(Startup, setup)
//!     .run();
//! ```

mod allocate;
mod asset;
mod cameras;
mod components;
mod control;
pub mod diagnostics;
mod error;
mod geomorph;
#[cfg(feature = "gltf_instancing")]
mod gltf_instancing;
mod instance;
mod loader;
mod materials;
mod messages;
mod overlay;
mod render;
mod scene;
mod select;
mod sets;
mod shared;
mod skin;
mod spawn;
mod tasks;
mod upload;
mod view_dependent;

pub use asset::{MultiresMesh, PartitionSpec};
pub use cameras::{LodCameraWeight, NoLodAllocation, RefineCamera};
/// [`ViewDependentLevel`] under the name of what it draws, a variable-resolution level.
pub use components::ViewDependentLevel as VariableLevel;
pub use components::{
    AslodOverlay, AslodStats, AslodViewport, CountInBudget, FrameSource, FrameTarget, FullDetail,
    Geomorph, LodPriority, LodRegion, MultiresModel, PolygonBudget, RegionSplit,
    ViewDependentLevel,
};
pub use error::MultiresError;
pub use geomorph::{
    ATTRIBUTE_MORPH_FROM, ATTRIBUTE_MORPH_NORMAL_FROM, ATTRIBUTE_MORPH_TANGENT_FROM,
    ATTRIBUTE_MORPH_UV_FROM, GeomorphExtension, GeomorphMaterial, GeomorphMaterialPlugin,
    GpuGeomorph,
};
pub use instance::{MultiresInstance, Refinement};
pub use loader::{MrmLoadError, MrmLoader};
pub use materials::MultiresMaterialPlugin;
pub use messages::{MultiresBuildFailed, MultiresModelReady};
pub use overlay::{MAX_OVERLAY_LABELS, OverlayLabel, OverlayStatus, status_line};
pub use render::{RegionUpload, RegionUploadStats};
pub use scene::{
    GltfMeshInstances, MultiresScene, MultiresSceneConverted, MultiresSceneModels,
    MultiresSourceMesh,
};
pub use sets::AslodSystems;
pub use shared::{NoSharedLevels, SharedLevels};
pub use skin::MultiresSkin;
pub use skin::binding::SkinBinding;
pub use view_dependent::ViewDependent;

use bevy::prelude::*;
use bevy::transform::TransformSystems;
use sets::MaterialSystems;

/// Multiresolution meshes under one global polygon budget.
///
/// Systems, all in [`PostUpdate`]:
///
/// | set | runs | does |
/// |---|---|---|
/// | [`AslodSystems::Spawn`] | before [`TransformSystems::Propagate`] | gives new [`MultiresModel`]s their region children; rebuilds them when their asset is modified (hot reload); starts and stops view-dependent levels; copies materials to the regions |
/// | [`AslodSystems::Allocate`] | after propagation | reads skinned models' joints and the cameras, aims view-dependent models, takes the projected area of every region's world box and splits the budget |
/// | [`AslodSystems::SelectLod`] | after `Allocate` | starts and stops geomorphs, moves each region's polygon cache (and each view-dependent level) to its count, grants geomorph refinements what is free |
/// | [`AslodSystems::Deform`] | after `SelectLod` | blends the cached vertices of skinned regions whose joints moved or whose cache changed |
/// | [`AslodSystems::Upload`] | after `Deform` | rewrites the index buffers (and blended vertices) of changed regions |
///
/// Everything runs before the renderer extracts meshes. With a render sub-app, one extract
/// system takes the new index and vertex bytes to the render world, and one system in
/// `RenderSystems::PrepareAssets` (after Bevy's mesh allocation and preparation) writes them
/// into the mesh allocator's buffers ([`RegionUpload`]). An observer removes a model's region
/// meshes from `Assets<Mesh>` when its [`MultiresInstance`] goes away (despawn). With
/// `GizmoPlugin` present, a debug system draws region boxes while [`AslodOverlay`] is on.
///
/// Needs `Assets<Mesh>` and `Assets<StandardMaterial>` (`DefaultPlugins`, or
/// `init_asset` in a headless app). Add it after `DefaultPlugins` (Bevy's `PbrPlugin`): it
/// then sets up [`GeomorphMaterial`] too; added before, it says so at start-up with a warning
/// and works without it.
#[derive(Clone, Debug, Default)]
pub struct AslodPlugin {
    /// The budget put in the [`PolygonBudget`] resource at start-up.
    pub budget: PolygonBudget,
    /// Whether the overlay starts on.
    pub overlay: bool,
    /// What one file or scene mesh may make the plugin read and build: the [`MrmLoader`]
    /// reads `.mrm` files within them, and a [`MultiresScene`] mesh with more vertices,
    /// triangles or joints than they allow stays conventional (fixed cost), with a warning
    /// naming the limit. Default [`LoadLimits::default()`](crate::mesh::LoadLimits).
    pub load_limits: crate::mesh::LoadLimits,
}

impl AslodPlugin {
    /// Sets the total budget `P` in triangles.
    #[must_use]
    pub fn with_budget(mut self, total: u32) -> Self {
        self.budget.total = total;
        self
    }

    /// Sets α (see [the table](crate::budget#choosing-α)).
    #[must_use]
    pub fn with_alpha(mut self, alpha: f32) -> Self {
        self.budget.alpha = alpha;
        self
    }

    /// Sets the hysteresis ε in triangles.
    #[must_use]
    pub fn with_hysteresis(mut self, triangles: u32) -> Self {
        self.budget.hysteresis = triangles;
        self
    }

    /// Starts with the debug overlay on.
    #[must_use]
    pub fn with_overlay(mut self, on: bool) -> Self {
        self.overlay = on;
        self
    }

    /// Sets the [`load_limits`](Self::load_limits).
    ///
    /// ```
    /// use bevy_aslod::mesh::LoadLimits;
    /// use bevy_aslod::plugin::AslodPlugin;
    ///
    /// // A server that bakes or shows files from untrusted sources.
    /// let plugin = AslodPlugin::default().with_load_limits(LoadLimits {
    ///     file_bytes: 64 << 20,
    ///     vertices: 1_000_000,
    ///     triangles: 1_000_000,
    ///     ..LoadLimits::default()
    /// });
    /// assert_eq!(plugin.load_limits.vertices, 1_000_000);
    /// ```
    #[must_use]
    pub fn with_load_limits(mut self, limits: crate::mesh::LoadLimits) -> Self {
        self.load_limits = limits;
        self
    }
}

impl Plugin for AslodPlugin {
    fn build(&self, app: &mut App) {
        register_types(app);
        // Shared skinned models keep their inverse bind matrices there (Bevy's `MeshPlugin`
        // registers it in a full app; a headless one may not have it).
        if !app
            .world()
            .contains_resource::<Assets<bevy::mesh::skinning::SkinnedMeshInverseBindposes>>()
        {
            app.init_asset::<bevy::mesh::skinning::SkinnedMeshInverseBindposes>();
        }
        app.init_asset::<MultiresMesh>()
            .register_asset_loader(MrmLoader {
                limits: self.load_limits,
            })
            .add_message::<MultiresModelReady>()
            .add_message::<MultiresBuildFailed>()
            .add_message::<MultiresSceneConverted>()
            .init_resource::<RegionUpload>()
            .init_resource::<render::RenderWrites>()
            .insert_resource(self.budget.clone())
            .insert_resource(AslodOverlay(self.overlay))
            .init_resource::<FullDetail>()
            .init_resource::<AslodStats>()
            .init_resource::<cameras::FrameCameras>()
            .init_resource::<allocate::FrameAllocation>()
            .init_resource::<allocate::AllocatorScratch>()
            .init_resource::<select::SyncTime>()
            .init_resource::<scene::SceneAssetCache>()
            .insert_resource(scene::SceneLimits(self.load_limits))
            .init_resource::<materials::MaterialsGiven>()
            .init_resource::<shared::SharedMeshes>()
            .add_observer(spawn::remove_region_meshes);
        #[cfg(feature = "gltf_instancing")]
        gltf_instancing::register(app, self.load_limits);
        diagnostics::register(app);
        control::add(app);
        app.configure_sets(
            PostUpdate,
            AslodSystems::Spawn.before(TransformSystems::Propagate),
        )
        .configure_sets(
            PostUpdate,
            (
                AslodSystems::Allocate,
                AslodSystems::SelectLod,
                AslodSystems::Deform,
                AslodSystems::Upload,
            )
                .chain()
                .after(TransformSystems::Propagate)
                .after(bevy::camera::CameraUpdateSystems)
                // Level meshes `Upload` makes are extracted in the frame that asked for them.
                .before(bevy::asset::AssetEventSystems),
        )
        .configure_sets(
            PostUpdate,
            MaterialSystems
                .in_set(AslodSystems::Spawn)
                .after(spawn::spawn_regions),
        )
        .add_systems(
            PostUpdate,
            (
                (
                    // What marks models for `spawn_regions` (new scene models, `Rebuild`)
                    // needs one sync point before it, not one after each: none of them reads
                    // what another's commands write.
                    (
                        scene::convert_scenes,
                        shared::forget_dropped,
                        spawn::mark_modified,
                        spawn::mark_handle_changed,
                        spawn::mark_shared_changed,
                    )
                        .chain_ignore_deferred(),
                    ApplyDeferred,
                    spawn::spawn_regions,
                    spawn::report_failed_loads,
                    spawn::sync_view_dependent,
                    spawn::sync_render_layers,
                )
                    .chain()
                    .in_set(AslodSystems::Spawn),
                materials::warn_without_material
                    .in_set(AslodSystems::Spawn)
                    .after(spawn::spawn_regions)
                    .after(MaterialSystems),
                (
                    skin::update_skins,
                    control::control_budget,
                    cameras::gather_cameras,
                    view_dependent::aim_view_dependent,
                    allocate::allocate,
                )
                    .chain()
                    .in_set(AslodSystems::Allocate),
                select::systems().in_set(AslodSystems::SelectLod),
                skin::deform.in_set(AslodSystems::Deform),
                upload::upload.in_set(AslodSystems::Upload),
            ),
        );
        if !app.is_plugin_added::<MultiresMaterialPlugin<StandardMaterial>>() {
            app.add_plugins(MultiresMaterialPlugin::<StandardMaterial>::default());
        }
        if app.is_plugin_added::<bevy::pbr::PbrPlugin>()
            && !app.is_plugin_added::<GeomorphMaterialPlugin<StandardMaterial>>()
        {
            app.add_plugins(GeomorphMaterialPlugin::<StandardMaterial>::default());
        }
    }

    fn finish(&self, app: &mut App) {
        overlay::add_if_gizmos(app);
        render::finish(app);
        // Bevy builds a plugin as it is added, so the geomorph material can only be added
        // after the `PbrPlugin` it builds on.
        if app.is_plugin_added::<bevy::pbr::PbrPlugin>()
            && !app.is_plugin_added::<GeomorphMaterialPlugin<StandardMaterial>>()
        {
            warn!(
                "AslodPlugin was added before PbrPlugin, so GeomorphMaterial is not set up (models drawn with it show nothing; other materials morph on the CPU as usual): add AslodPlugin after DefaultPlugins, or GeomorphMaterialPlugin::<StandardMaterial> after PbrPlugin"
            );
        }
    }
}

/// Registers the plugin's reflected types.
fn register_types(app: &mut App) {
    app.register_type::<PolygonBudget>()
        .register_type::<FullDetail>()
        .register_type::<AslodOverlay>()
        .register_type::<AslodStats>()
        .register_type::<FrameSource>()
        .register_type::<AslodViewport>()
        .register_type::<RegionUpload>()
        .register_type::<RegionUploadStats>()
        .register_type::<MultiresModel>()
        .register_type::<LodPriority>()
        .register_type::<LodRegion>()
        .register_type::<CountInBudget>()
        .register_type::<VariableLevel>()
        .register_type::<Geomorph>()
        .register_type::<GpuGeomorph>()
        .register_type::<SharedLevels>()
        .register_type::<NoSharedLevels>()
        .register_type::<ViewDependent>()
        .register_type::<RefineCamera>()
        .register_type::<NoLodAllocation>()
        .register_type::<LodCameraWeight>()
        .register_type::<MultiresScene>()
        .register_type::<MultiresSceneModels>()
        .register_type::<MultiresSourceMesh>()
        .register_type::<GltfMeshInstances>()
        .register_type::<MultiresSkin>()
        .register_type::<OverlayLabel>()
        .register_type::<OverlayStatus>();
}
