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
//! | [`PolygonBudget`] | resource | `P`, α, hysteresis ε |
//! | [`AslodViewport`] | resource (optional) | viewport size for cameras without a known one |
//! | [`AslodOverlay`] | resource | draws every region's world box with gizmos |
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

mod asset;
mod geomorph;
mod loader;
mod overlay;
mod refine;
mod render;
mod scene;
mod skin;
mod systems;
mod tasks;

pub use asset::{MultiresError, MultiresMesh, PartitionSpec};
pub use geomorph::{
    ATTRIBUTE_MORPH_FROM, ATTRIBUTE_MORPH_NORMAL_FROM, GeomorphExtension, GeomorphMaterial,
    GeomorphMaterialPlugin, GpuGeomorph,
};
pub use loader::{MrmLoadError, MrmLoader};
pub use overlay::{MAX_OVERLAY_LABELS, OverlayLabel};
pub use refine::{RefineCamera, Refinement, VariableLevel, ViewDependent};
pub use render::{RegionUpload, RegionUploadStats};
pub use scene::{MultiresScene, MultiresSceneModels, MultiresSourceMesh};
pub use skin::{MultiresSkin, SkinBinding};

use crate::budget::{AllocationParams, DEFAULT_ALPHA, DEFAULT_BUDGET, Obb};
use crate::regions::{RegionCaches, RegionMesh};
use bevy::diagnostic::{Diagnostic, DiagnosticPath, RegisterDiagnostic};
use bevy::prelude::*;
use std::sync::Arc;

/// Multiresolution meshes under one global polygon budget.
///
/// Systems, all in [`PostUpdate`]:
///
/// | set | runs | does |
/// |---|---|---|
/// | [`AslodSystems::Spawn`] | before [`TransformSystems::Propagate`] | gives new [`MultiresModel`]s their region children; rebuilds them when their asset is modified (hot reload) |
/// | [`AslodSystems::Allocate`] | after propagation | projected area of every region's world box, budget split |
/// | [`AslodSystems::SelectLod`] | after `Allocate` | moves each region's polygon cache to its count |
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
/// `init_asset` in a headless app).
#[derive(Clone, Debug, Default)]
pub struct AslodPlugin {
    /// The budget put in the [`PolygonBudget`] resource at start-up.
    pub budget: PolygonBudget,
    /// Whether the overlay starts on.
    pub overlay: bool,
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
}

impl Plugin for AslodPlugin {
    fn build(&self, app: &mut App) {
        app.init_asset::<MultiresMesh>()
            .register_asset_loader(MrmLoader)
            .register_type::<PolygonBudget>()
            .register_type::<FullDetail>()
            .register_type::<Geomorph>()
            .register_type::<RegionUpload>()
            .init_resource::<RegionUpload>()
            .init_resource::<render::RenderWrites>()
            .insert_resource(self.budget.clone())
            .insert_resource(AslodOverlay(self.overlay))
            .init_resource::<FullDetail>()
            .init_resource::<AslodStats>()
            .init_resource::<systems::AslodScratch>()
            .init_resource::<scene::SceneAssetCache>()
            .add_observer(systems::remove_region_meshes);
        diagnostics::register(app);
        systems::configure(app);
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
    }
}

/// Gives the regions of every [`MultiresModel`] the model's `MeshMaterial3d<M>`, and keeps them
/// following it when it changes or is removed, like Bevy's `MaterialPlugin<M>` for a
/// material type. [`AslodPlugin`] adds it for `StandardMaterial`; add one for each other
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
        app.add_systems(
            PostUpdate,
            systems::propagate_materials::<M>
                .in_set(AslodSystems::Spawn)
                .in_set(systems::MaterialSystems)
                .after(systems::spawn_regions),
        );
    }
}

/// The plugin's system sets, in [`PostUpdate`], in this order.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AslodSystems {
    /// Spawns region children for new models. Before [`TransformSystems::Propagate`].
    Spawn,
    /// Splits the budget among all regions in view. After [`TransformSystems::Propagate`]
    /// (needs world transforms) and camera updates. Runs on the main thread, which works
    /// through its parallel loop alongside the compute pool (so it does not overlap the app's
    /// other non-`Send` systems); likewise `SelectLod` and `Deform`.
    Allocate,
    /// Moves each region's polygon cache to its allocated count and writes the index buffers
    /// that changed. After `Allocate`.
    SelectLod,
    /// Blends the cached vertices of skinned regions. After `SelectLod`.
    Deform,
    /// Writes the index buffers of changed regions into their meshes and queues the new
    /// bytes for the renderer ([`RegionUpload`]). After `Deform`.
    Upload,
}

/// The global polygon budget and how it is split (the paper's allocator node).
#[derive(Resource, Reflect, Clone, Debug, PartialEq)]
#[reflect(Resource, Default)]
pub struct PolygonBudget {
    /// `P`: the most triangles all multiresolution regions and the [`CountInBudget`] meshes
    /// may show together. Must be positive; `0` is warned about and skipped.
    ///
    /// Default: `100_000` ([`DEFAULT_BUDGET`], as the core allocator's).
    pub total: u32,
    /// α: `pᵢ ∝ wᵢ^(1/α)`; `1` proportional to screen area, larger flattens towards an equal
    /// split. Must be positive.
    ///
    /// Default: `3` ([`DEFAULT_ALPHA`], the paper's).
    pub alpha: f32,
    /// Hysteresis ε: a region keeps its level while its new target stays within this many
    /// triangles of its current count.
    ///
    /// Default: `0`.
    pub hysteresis: u32,
}

impl Default for PolygonBudget {
    fn default() -> Self {
        Self {
            total: DEFAULT_BUDGET,
            alpha: DEFAULT_ALPHA,
            hysteresis: 0,
        }
    }
}

impl PolygonBudget {
    /// The allocator's parameters for a fixed cost.
    #[must_use]
    pub fn params(&self, fixed_cost: u32) -> AllocationParams {
        AllocationParams {
            budget: self.total,
            fixed_cost,
            alpha: self.alpha,
            hysteresis: self.hysteresis,
        }
    }
}

/// The "no LOD" switch: while it is `true`, every region of every model is kept at its full
/// detail, whatever the budget and wherever the camera looks (regions out of view too), so an
/// app can compare the same scene with and without LOD. Like the budget, it is applied in
/// `Allocate`, which needs an active 3D camera. Skinned regions still blend only when their
/// bones move. Default `false`.
#[derive(Resource, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Resource, Default)]
pub struct FullDetail(pub bool);

/// The user priority `c` of a model: its regions weigh `c · A`. Without it `c = 1`; `0`
/// keeps the model at its coarsest level. Negative or non-finite values count as `0`.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component)]
pub struct LodPriority(pub f32);

impl Default for LodPriority {
    fn default() -> Self {
        Self(1.0)
    }
}

/// A multiresolution model: the plugin gives this entity one child per region of the mesh.
/// Put it next to a `MeshMaterial3d<StandardMaterial>` (or of another material with a
/// [`MultiresMaterialPlugin`]) and a `Transform`.
///
/// The children are made once, when the asset is loaded, with the material the model has
/// then; changing the handle or the material later does not rebuild them: despawn the model
/// and spawn it again.
#[derive(Component, Clone, Debug, PartialEq, Eq)]
#[require(Transform, Visibility)]
pub struct MultiresModel(pub Handle<MultiresMesh>);

/// Geomorphs on a [`MultiresModel`]: its level changes take this many seconds instead of
/// a frame (`regions::Geomorphs`). A refining region changes its triangles at once and its
/// new vertices grow out of their representatives; a coarsening region keeps its triangles,
/// and counts them, until its vanishing vertices have reached their representatives. The
/// allocation is the view's, whatever is morphing; the budget holds because refinements only
/// take the triangles that are free, so one that needs a coarsening's triangles waits for
/// them (a lower [`PolygonBudget`] is met once the coarsening regions arrive, after the
/// morph time). Borders stay closed: a vertex moves the same way in every region that draws
/// it. `0` (or no component) changes levels at once; [`Default`] is
/// [`DEFAULT_SECONDS`](Self::DEFAULT_SECONDS). A model's first levels (when it is new, or
/// gets the component) are taken at once. A [`MultiresScene`] with one gives it to every
/// model it makes.
///
/// Unskinned models with a [`GeomorphMaterial`] (or another material with [`GpuGeomorph`])
/// are interpolated by the vertex shaders: a vertex is written once, when a morph starts
/// on it. With any other material their moving regions' positions and normals are written
/// from the CPU each frame they move. Skinned models blend their moving vertices in
/// `Deform`, from where the morphs show them in the bind pose.
///
/// [`ViewDependent`] models morph between their variable-resolution levels
/// (`refine::VariableGeomorphs`) the same way, collapse by collapse.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Default)]
pub struct Geomorph(pub f32);

impl Geomorph {
    /// The default morph time: a quarter second.
    pub const DEFAULT_SECONDS: f32 = 0.25;
}

impl Default for Geomorph {
    fn default() -> Self {
        Self(Self::DEFAULT_SECONDS)
    }
}

/// A region child of a [`MultiresModel`]: which region of the mesh its `Mesh3d` shows.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(Component)]
pub struct LodRegion {
    /// Index into the mesh's regions.
    pub region: usize,
}

/// A conventional (not multiresolution) `Mesh3d` whose triangles count against the budget
/// as fixed cost: `P' = P − Σ its triangles`.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component)]
pub struct CountInBudget;

/// The per-instance state of a [`MultiresModel`], added by the plugin: one polygon cache per
/// region, the allocated counts and the region meshes.
#[derive(Component, Debug)]
pub struct MultiresInstance {
    regions: Arc<RegionMesh>,
    obbs: Arc<[Obb]>,
    /// A box around every region's box, in the model's space: a model whose box is out of
    /// every view skips its regions' projections (unskinned models only).
    bounds: Obb,
    caches: RegionCaches,
    targets: Vec<u32>,
    /// Where this model's regions sit in `Allocate`'s inputs and counts. `SelectLod` copies
    /// its `targets` from those counts when that allocation is this frame's.
    input_run: InputRun,
    meshes: Vec<Handle<Mesh>>,
    /// `meshes`' ids, for `Upload`: reading one from its handle follows the handle's pointer,
    /// a cache miss per region mesh.
    mesh_ids: Vec<AssetId<Mesh>>,
    /// Skinned models: the deformation state.
    skin: Option<skin::SkinState>,
    /// Every region entity, by region (a skinned model's rigid regions live under their
    /// joints, the others under the model).
    region_entities: Vec<Entity>,
    /// Unskinned models: per region, the index buffer `SelectLod` wrote for `Upload`.
    staged: Vec<StagedIndices>,
    /// The regions whose `staged` flag `SelectLod` raised since the last `Upload`, each once.
    ready: Vec<u32>,
    /// Unskinned models: `SelectLod` left every region at its target and wrote every dirty
    /// one, so the same targets again leave nothing to do (only `SelectLod` moves the caches).
    settled: bool,
    /// The triangles `SelectLod` left the instance showing, all regions together.
    shown: u64,
    /// A [`ViewDependent`] model: its variable-resolution level, drawn instead of the
    /// regions (which are hidden and keep their levels).
    fine: Option<refine::FineState>,
    /// A [`Geomorph`] model: its morphs and the vertex data `SelectLod` wrote for `Upload`.
    morph: Option<MorphState>,
}

/// The geomorphs of one unskinned instance.
#[derive(Debug)]
struct MorphState {
    morphs: crate::regions::Geomorphs,
    /// The time `SelectLod` applied the morphs at (`Deform` blends skinned ones at it).
    now: f32,
    /// An allocation was applied (the first one is taken at once).
    allocated: bool,
    /// `SelectLod`'s first pass left this model's refinements (`refine`: region, triangles
    /// wanted) to its second, which applies `grants` (region, triangles granted).
    second_pass: bool,
    refine: Vec<(u32, u32)>,
    grants: Vec<(u32, u32)>,
    /// The material interpolates on the GPU ([`GpuGeomorph`]): a vertex is written when a
    /// morph starts on it, with the morph attributes.
    gpu: bool,
    /// The region meshes have the morph attributes (added once, by `Upload`).
    attributes: bool,
    /// Per region: its vertices moved last frame (so it is written once more at rest), or
    /// (on the GPU) must all be written again.
    moved: Vec<bool>,
    /// Per region: the vertices `Upload` writes into its mesh.
    runs: Vec<VertexRun>,
}

/// A run of a mesh's vertices that `Upload` writes under geomorphs, from vertex `first`
/// (`ready` when new): positions and normals, and on the GPU the morph attributes (empty:
/// written from the CPU, at rest).
#[derive(Clone, Debug, Default)]
struct VertexRun {
    first: u32,
    positions: Vec<glam::Vec3>,
    normals: Vec<glam::Vec3>,
    from: Vec<[f32; 4]>,
    normal_from: Vec<[f32; 4]>,
    ready: bool,
}

/// Where a model's regions sat in the last allocation that included it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct InputRun {
    /// That allocation's serial number (`AslodScratch::serial`).
    allocation: u64,
    /// The model's first region in that allocation's inputs and counts.
    first: usize,
}

/// One unskinned region's index buffer between `SelectLod` and `Upload`.
#[derive(Debug)]
struct StagedIndices {
    /// `SelectLod` wrote a new level into `indices` that `Upload` has not swapped in yet.
    ready: bool,
    /// The new level, for `Upload` to swap into the region's mesh; after the swap, the mesh's
    /// old buffer, so steady state allocates nothing. 16-bit wherever the region's vertices
    /// fit (half the bytes to write, keep and upload).
    indices: bevy::mesh::Indices,
}

impl MultiresInstance {
    /// The instance's polygon caches (read-only).
    #[inline]
    #[must_use]
    pub fn caches(&self) -> &RegionCaches {
        &self.caches
    }

    /// The regions this instance shows.
    #[inline]
    #[must_use]
    pub fn regions(&self) -> &RegionMesh {
        &self.regions
    }

    /// Per region, the triangle count the last allocation gave it (taken over in
    /// [`AslodSystems::SelectLod`]: between `Allocate` and `SelectLod` it still holds the
    /// previous frame's).
    #[inline]
    #[must_use]
    pub fn targets(&self) -> &[u32] {
        &self.targets
    }

    /// Per region, the Bevy mesh the plugin writes.
    #[inline]
    #[must_use]
    pub fn meshes(&self) -> &[Handle<Mesh>] {
        &self.meshes
    }

    /// Whether the instance is skinned and animated by joints.
    #[inline]
    #[must_use]
    pub fn is_skinned(&self) -> bool {
        self.skin.is_some()
    }

    /// The world-space box of every region as the last `Allocate` saw it (skinned models:
    /// moved with their bones), else `None`.
    #[must_use]
    pub fn skinned_world_boxes(&self) -> Option<&[Obb]> {
        self.skin.as_ref().map(|s| s.world_obbs.as_slice())
    }

    /// Per region, the entity that draws it.
    #[inline]
    #[must_use]
    pub fn region_entities(&self) -> &[Entity] {
        &self.region_entities
    }

    /// Triangles the instance shows now: all regions together, or its variable-resolution
    /// level while it is [`ViewDependent`].
    #[inline]
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        match &self.fine {
            Some(fine) => fine.shown_count(),
            None => self.caches.total_triangles(),
        }
    }

    /// What the model's view-dependent refinement did last frame, while it is
    /// [`ViewDependent`] (and not skinned).
    #[inline]
    #[must_use]
    pub fn refinement(&self) -> Option<&Refinement> {
        self.fine.as_ref().map(|f| &f.report)
    }

    /// The entity drawing the model's variable-resolution level, while it is [`ViewDependent`].
    #[inline]
    #[must_use]
    pub fn variable_level_entity(&self) -> Option<Entity> {
        self.fine.as_ref().map(|f| f.entity)
    }

    /// Every entity that draws the model: the regions, and the variable-resolution level.
    fn drawn_entities(&self) -> impl Iterator<Item = Entity> + '_ {
        self.region_entities
            .iter()
            .copied()
            .chain(self.fine.as_ref().map(|f| f.entity))
    }

    /// How many allocation inputs the model fills: one per region, one for a budgeted
    /// view-dependent model, none for a tolerance-only one.
    fn input_len(&self) -> usize {
        match &self.fine {
            None => self.regions.regions().len(),
            Some(fine) => usize::from(fine.settings.budgeted),
        }
    }
}

/// The viewport size in pixels for cameras whose size is not known yet (no render target,
/// as in a headless test, or the first frame). A camera with a known viewport
/// (`Camera::physical_viewport_size`) uses its own. Without this resource such cameras are
/// skipped; with no usable camera, allocation does nothing that frame.
#[derive(Resource, Clone, Copy, Debug, PartialEq)]
pub struct AslodViewport(pub Vec2);

/// Whether the debug overlay is on (ASLOD Figure 10): each region's world box, coloured from
/// blue (coarsest) to red (full detail), and its triangle count as a label ([`OverlayLabel`]
/// UI nodes, at most [`MAX_OVERLAY_LABELS`]). Needs `GizmoPlugin`, part of `DefaultPlugins`.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AslodOverlay(pub bool);

/// What the plugin did in the last frame; also published as diagnostics ([`diagnostics`]).
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq)]
pub struct AslodStats {
    /// Triangles of all region instances after `SelectLod`.
    pub triangles: u64,
    /// `P` of the frame.
    pub budget: u32,
    /// Triangles of the [`CountInBudget`] meshes.
    pub fixed_cost: u32,
    /// Models and regions seen.
    pub models: usize,
    /// Region instances seen.
    pub regions: usize,
    /// Cameras used.
    pub cameras: usize,
    /// Whether the allocation ran this frame (a camera, a valid budget).
    pub allocated: bool,
    /// Milliseconds in `Allocate`.
    pub allocation_ms: f64,
    /// Milliseconds in `SelectLod` and `Upload`.
    pub update_ms: f64,
    /// Milliseconds in `Upload` alone (part of `update_ms`).
    pub upload_ms: f64,
    /// Milliseconds in `Deform` (skinned models; near `0` when no joint moved).
    pub deform_ms: f64,
    /// Vertices blended in `Deform`.
    pub vertices_blended: usize,
    /// Regions whose index buffer was rewritten.
    pub regions_changed: usize,
    /// Bytes of region mesh data handed to the renderer in `Upload`: the new index buffers
    /// and blended vertex runs ([`RegionUpload::IndicesOnly`], `0` without a render sub-app),
    /// or every changed mesh's whole vertex and index data ([`RegionUpload::WholeMesh`]).
    pub upload_bytes: u64,
}

/// Diagnostic paths the plugin registers with Bevy's `DiagnosticsStore`.
pub mod diagnostics {
    use super::*;

    /// Triangles rendered by all region instances.
    pub const TRIANGLES: DiagnosticPath = DiagnosticPath::const_new("aslod/triangles");
    /// The budget `P`.
    pub const BUDGET: DiagnosticPath = DiagnosticPath::const_new("aslod/budget");
    /// Time in `Allocate`, ms.
    pub const ALLOCATION_MS: DiagnosticPath = DiagnosticPath::const_new("aslod/allocation_ms");
    /// Time in `SelectLod` and `Upload`, ms.
    pub const UPDATE_MS: DiagnosticPath = DiagnosticPath::const_new("aslod/update_ms");
    /// Regions whose index buffer was rewritten this frame.
    pub const REGIONS_CHANGED: DiagnosticPath = DiagnosticPath::const_new("aslod/regions_changed");
    /// Time in `Deform`, ms.
    pub const DEFORM_MS: DiagnosticPath = DiagnosticPath::const_new("aslod/deform_ms");

    pub(super) fn register(app: &mut App) {
        app.register_diagnostic(Diagnostic::new(TRIANGLES))
            .register_diagnostic(Diagnostic::new(BUDGET))
            .register_diagnostic(Diagnostic::new(ALLOCATION_MS).with_suffix("ms"))
            .register_diagnostic(Diagnostic::new(UPDATE_MS).with_suffix("ms"))
            .register_diagnostic(Diagnostic::new(REGIONS_CHANGED))
            .register_diagnostic(Diagnostic::new(DEFORM_MS).with_suffix("ms"));
    }
}
