//! Shared levels: the instances of one asset that show a region at the same levels draw one
//! Bevy mesh, made once and dropped when no instance shows it ([`SharedLevels`]). Every
//! model whose asset has more than one instance shares (see [`ladder`]), unless it has a
//! [`Geomorph`](super::Geomorph) or [`NoSharedLevels`]. A skinned asset's level meshes hold
//! its vertices in bind space with their joints and weights, and Bevy skins them on the GPU
//! for each instance's joints ([`SharedSkin`]).
//!
//! A region's index buffer is a function of its own level and of the levels of the regions
//! whose steps move its border corners (its *dependencies*), whatever path the caches took
//! there (`tests/regions.rs` holds this). So a level mesh is keyed by the asset, the region
//! and those levels, and `Upload` finds it without writing the instance's indices. The key
//! maps to a weak id: the instances' `Mesh3d`s hold the only strong handles, so Bevy drops a
//! level mesh once the last instance showing it moves on, and the key is forgotten when its
//! `AssetEvent::Removed` comes ([`forget_dropped`]).
//!
//! A level mesh holds only the vertices its triangles use, so a ladder of levels costs about
//! what a chain of discrete levels does.

use super::asset::MultiresMesh;
use super::components::LodRegion;
use super::instance::MultiresInstance;
use super::skin::binding::SkinBinding;
use crate::bevy_mesh::to_bevy_mesh;
use crate::mesh::{IndexedMesh, optimize_vertex_cache};
use crate::regions::{RegionCaches, RegionMesh};
use bevy::asset::AssetId;
use bevy::camera::primitives::Aabb;
use bevy::mesh::Indices;
use bevy::mesh::skinning::SkinnedMeshInverseBindposes;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use std::sync::Arc;

/// How a [`MultiresModel`](super::MultiresModel) shares its region meshes with every other
/// instance of its asset: each region shows a level from a ladder whose steps are `ratio`
/// apart in triangles (the step at or below its allocation), and the instances showing a
/// region at the same levels draw the same Bevy mesh. Mesh memory is then bounded by the
/// asset and its ladder, not by the number of instances: about `1 / (1 - 1/ratio)` times the
/// asset while every step is in use (3× at the default 1.5, as a chain of discrete levels
/// each half the one before costs 2×).
///
/// **Sharing is the default.** A model without a [`Geomorph`](super::Geomorph) shares with
/// the default ladder as soon as its asset has a second instance
/// ([`MultiresScene`](super::MultiresScene) models included); it keeps sharing until it is
/// rebuilt. Insert this component to choose the ratio, or to share a
/// model with a `Geomorph` too (which then changes its regions' levels at once;
/// view-dependent levels still morph), and [`NoSharedLevels`] to keep a model on meshes of
/// its own.
///
/// A shared model draws up to `1 - 1/ratio` fewer triangles than it was allocated (the
/// budget still holds). A shared skinned model (with its [`MultiresSkin`](super::MultiresSkin))
/// is skinned by Bevy on the GPU, as a plain skinned mesh is: its regions are Bevy skinned
/// meshes on the joints they use, culled by bounds that follow those joints. One that is
/// not shared is skinned on the CPU by the paper's blend (section 5.4), which is also what
/// geomorphs on skinned regions need. A skinned model Bevy cannot skin (no `MultiresSkin`,
/// one listing fewer joints than its skin, or a region over 256 joints) keeps its own
/// meshes, with a warning when it has this component. Adding, changing or removing the
/// component rebuilds the model when that changes how it shares.
///
/// ```
/// use bevy::prelude::*;
/// use bevy_aslod::prelude::*;
///
/// fn place_rocks(mut commands: Commands, rock: Handle<MultiresMesh>) {
///     for i in 0..1000 {
///         let at = Vec3::new((i % 40) as f32 * 4.0, 0.0, (i / 40) as f32 * 4.0);
///         commands.spawn((
///             MultiresModel(rock.clone()),
///             SharedLevels::default(),
///             Transform::from_translation(at),
///         ));
///     }
/// }
/// # let _ = place_rocks;
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Default)]
pub struct SharedLevels {
    /// The ratio of triangles between a ladder step and the next coarser one. Must be above
    /// `1`: smaller values (and NaN) are raised to [`MIN_RATIO`](Self::MIN_RATIO), with a
    /// warning when the model is built.
    ///
    /// Default: [`DEFAULT_RATIO`](Self::DEFAULT_RATIO).
    pub ratio: f32,
}

impl SharedLevels {
    /// The default ladder ratio, `1.5`.
    pub const DEFAULT_RATIO: f32 = 1.5;
    /// The smallest ratio used, `1.05` (finer ladders share less and hold more meshes).
    pub const MIN_RATIO: f32 = 1.05;

    /// The ratio the ladder uses: [`ratio`](Self::ratio), or [`MIN_RATIO`](Self::MIN_RATIO)
    /// when that is below it or NaN.
    #[must_use]
    pub fn effective_ratio(self) -> f32 {
        if self.ratio >= Self::MIN_RATIO {
            self.ratio
        } else {
            Self::MIN_RATIO
        }
    }

    /// The ladder step at or below `target` for a region of `full` triangles whose coarsest
    /// level has `min`: `full`, `full / ratio`, `full / ratio²`, … rounded down, and never
    /// below `min`.
    ///
    /// ```
    /// use bevy_aslod::prelude::SharedLevels;
    ///
    /// let ladder = SharedLevels { ratio: 2.0 };
    /// assert_eq!(ladder.step_at_or_below(1000, 10, 1000), 1000);
    /// assert_eq!(ladder.step_at_or_below(1000, 10, 999), 500);
    /// assert_eq!(ladder.step_at_or_below(1000, 10, 300), 250);
    /// assert_eq!(ladder.step_at_or_below(1000, 10, 12), 10);
    /// ```
    #[must_use]
    pub fn step_at_or_below(self, full: usize, min: usize, target: usize) -> usize {
        if target >= full {
            return full;
        }
        if target <= min {
            return min.min(full);
        }
        let ratio = f64::from(self.effective_ratio());
        let mut k = ((full as f64 / target as f64).ln() / ratio.ln())
            .ceil()
            .max(0.0);
        let mut step = (full as f64 * ratio.powf(-k)).floor() as usize;
        // Rounding may land a step above the target: the next one is below it.
        while step > target {
            k += 1.0;
            step = (full as f64 * ratio.powf(-k)).floor() as usize;
        }
        step.max(min)
    }
}

impl Default for SharedLevels {
    fn default() -> Self {
        Self {
            ratio: Self::DEFAULT_RATIO,
        }
    }
}

/// Keeps a [`MultiresModel`](super::MultiresModel) on region meshes of its own, whatever
/// other instances its asset has and even with [`SharedLevels`]: its regions show the levels
/// it was allocated exactly, and its geomorphs morph. Each such instance holds its regions'
/// vertex and index data (the asset's size in mesh memory, per instance). Adding or
/// removing it rebuilds a model whose sharing it changes.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct NoSharedLevels;

/// The ladder a model shares with, or `None` for meshes of its own: never with
/// [`NoSharedLevels`] (`opted_out`) or when it is skinned and Bevy cannot skin it
/// (`cpu_only`: see [`skinned_on_gpu`](super::skin::skinned_on_gpu)); else its explicit
/// [`SharedLevels`]; else the default ladder once its asset has more than one instance,
/// unless it has a [`Geomorph`](super::Geomorph) (region geomorphs move vertices per
/// instance).
pub(super) fn ladder(
    explicit: Option<SharedLevels>,
    opted_out: bool,
    geomorph: bool,
    cpu_only: bool,
    instances: u32,
) -> Option<SharedLevels> {
    if opted_out || cpu_only {
        return None;
    }
    match explicit {
        Some(ladder) => Some(ladder),
        None if !geomorph && instances > 1 => Some(SharedLevels::default()),
        None => None,
    }
}

/// What a shared model keeps: its asset's shared data and its ladder.
#[derive(Component, Debug)]
pub(super) struct SharedState {
    pub(super) asset: Arc<SharedAsset>,
    pub(super) ladder: SharedLevels,
}

impl SharedState {
    /// The triangles region `r` of `regions` shows for an allocation of `target`: its ladder
    /// step.
    pub(super) fn step(&self, regions: &RegionMesh, r: usize, target: usize) -> usize {
        let region = &regions.regions()[r];
        self.ladder
            .step_at_or_below(region.max_triangles(), region.min_triangles(), target)
    }
}

/// What every shared instance of one asset has in common.
#[derive(Debug)]
pub(super) struct SharedAsset {
    /// Tells this asset's keys from those of an asset built before a hot reload.
    serial: u64,
    /// Per region, the regions whose levels its index buffer depends on: itself first, then
    /// those whose steps move its corners, ascending.
    dependencies: Vec<Box<[u32]>>,
    /// Per region, the box of all its vertices (any level's triangles lie inside).
    pub(super) boxes: Vec<Aabb>,
    /// A skinned asset's skin, as Bevy skins its level meshes.
    pub(super) skin: Option<SharedSkin>,
}

/// How Bevy skins a shared skinned asset's level meshes: each region's meshes name only the
/// joints its vertices use (so Bevy extracts a few matrices per region, not the skeleton),
/// in the order of [`SkinBinding::region_joints`].
#[derive(Debug)]
pub(super) struct SharedSkin {
    pub(super) binding: Arc<SkinBinding>,
    /// Per region: the inverse bind matrices of its joints.
    pub(super) inverse_bindposes: Vec<Handle<SkinnedMeshInverseBindposes>>,
}

impl SharedSkin {
    fn new(binding: Arc<SkinBinding>, assets: &mut Assets<SkinnedMeshInverseBindposes>) -> Self {
        let inverse_bindposes = (0..binding.kinds().len())
            .map(|r| {
                let matrices: Vec<_> = binding
                    .region_joints(r)
                    .iter()
                    .map(|&j| binding.inverse_bindposes()[j as usize])
                    .collect();
                assets.add(SkinnedMeshInverseBindposes::from(matrices))
            })
            .collect();
        Self {
            binding,
            inverse_bindposes,
        }
    }

    /// The joints and weights of region `r`'s local vertices `used`, as its level mesh
    /// carries them: joint indices into the region's joints.
    fn influences(&self, r: usize, used: &[u32]) -> (Vec<[u16; 4]>, Vec<[f32; 4]>) {
        let local = self.binding.local_influences(r);
        let joints = self.binding.region_joints(r);
        used.iter()
            .map(|&v| {
                let (j, w) = (local.joints[v as usize], local.weights[v as usize]);
                let slot = |k: usize| -> u16 {
                    if w[k] > 0.0 {
                        joints.binary_search(&j[k]).unwrap_or(0) as u16
                    } else {
                        0
                    }
                };
                ([slot(0), slot(1), slot(2), slot(3)], w)
            })
            .unzip()
    }
}

/// A level mesh's key: the asset, the region, and the levels of the region's dependencies.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct LevelKey {
    asset: u64,
    region: u32,
    levels: Box<[u32]>,
}

/// The level meshes of every shared asset.
#[derive(Resource, Debug, Default)]
pub(super) struct SharedMeshes {
    assets: HashMap<AssetId<MultiresMesh>, Arc<SharedAsset>>,
    levels: HashMap<LevelKey, AssetId<Mesh>>,
    /// Every level mesh made, with its key, to forget it once Bevy drops it.
    made: HashMap<AssetId<Mesh>, LevelKey>,
    /// Per asset (by serial), one full set of caches that makes its level meshes: shared
    /// instances keep their levels alone ([`RegionCaches::levels_only`]), so the index
    /// buffers are held once per asset, not once per instance.
    level_caches: HashMap<u64, RegionCaches>,
    /// Built models (those with a `MultiresInstance`) per asset.
    instances: HashMap<AssetId<MultiresMesh>, u32>,
    next_serial: u64,
}

impl SharedMeshes {
    /// The shared data of asset `id` (made on first use).
    /// `skin`: a skinned asset's binding, which Bevy skins its level meshes by (with
    /// `bindposes` to keep their inverse bind matrices).
    pub(super) fn asset(
        &mut self,
        id: AssetId<MultiresMesh>,
        regions: &RegionMesh,
        skin: Option<&Arc<SkinBinding>>,
        bindposes: &mut Assets<SkinnedMeshInverseBindposes>,
    ) -> Arc<SharedAsset> {
        if let Some(asset) = self.assets.get(&id) {
            return asset.clone();
        }
        let asset = Arc::new(SharedAsset {
            serial: self.next_serial,
            dependencies: dependencies(regions),
            boxes: regions
                .regions()
                .iter()
                .map(|r| {
                    let positions = &r.progressive_mesh().vertices().positions;
                    Aabb::enclosing(positions.iter().copied()).unwrap_or_default()
                })
                .collect(),
            skin: skin.map(|binding| SharedSkin::new(binding.clone(), bindposes)),
        });
        self.next_serial += 1;
        self.assets.insert(id, asset.clone());
        asset
    }

    /// How many built models show asset `id`.
    pub(super) fn instances(&self, id: AssetId<MultiresMesh>) -> u32 {
        self.instances.get(&id).copied().unwrap_or(0)
    }

    /// Counts a model built for asset `id`.
    pub(super) fn count_instance(&mut self, id: AssetId<MultiresMesh>) {
        *self.instances.entry(id).or_insert(0) += 1;
    }

    /// Uncounts a model of asset `id` that lost its instance (despawned or rebuilt).
    pub(super) fn uncount_instance(&mut self, id: AssetId<MultiresMesh>) {
        if let Some(n) = self.instances.get_mut(&id) {
            *n -= 1;
            if *n == 0 {
                self.instances.remove(&id);
            }
        }
    }

    /// Level meshes alive in `meshes` (a dropped one is forgotten a frame or two later).
    pub(super) fn level_count(&self, meshes: &Assets<Mesh>) -> usize {
        self.levels
            .values()
            .filter(|&&id| meshes.contains(id))
            .count()
    }
}

/// Per region, itself and the regions whose front events rewrite its corners.
fn dependencies(regions: &RegionMesh) -> Vec<Box<[u32]>> {
    let n = regions.regions().len();
    let mut deps: Vec<Vec<u32>> = (0..n as u32).map(|r| vec![r]).collect();
    for (q, region) in regions.regions().iter().enumerate() {
        for event in &region.front_events {
            let list = &mut deps[event.region as usize];
            if !list.contains(&(q as u32)) {
                list.push(q as u32);
            }
        }
    }
    deps.into_iter()
        .map(|mut list| {
            list[1..].sort_unstable();
            list.into_boxed_slice()
        })
        .collect()
}

/// What `Upload` needs to put a shared model's regions on their level meshes.
pub(super) struct SharedUpload<'a, 'w, 's> {
    pub(super) table: &'a mut SharedMeshes,
    pub(super) drawn: &'a mut Query<'w, 's, &'static mut Mesh3d, With<LodRegion>>,
    /// Bytes of the level meshes made this frame.
    pub(super) bytes: usize,
    /// Reused for the indices of a level mesh being made.
    pub(super) scratch: Vec<u32>,
}

impl SharedUpload<'_, '_, '_> {
    /// Puts each region of `regions` on the mesh of its current levels, making those that
    /// no instance shows yet. Returns how many regions changed mesh.
    pub(super) fn apply(
        &mut self,
        state: &SharedState,
        instance: &mut MultiresInstance,
        meshes: &mut Assets<Mesh>,
        regions: impl Iterator<Item = u32>,
    ) -> usize {
        let mut changed = 0;
        for r in regions {
            let r = r as usize;
            let key = LevelKey {
                asset: state.asset.serial,
                region: r as u32,
                levels: state.asset.dependencies[r]
                    .iter()
                    .map(|&q| instance.caches.level(q as usize) as u32)
                    .collect(),
            };
            let found = self
                .table
                .levels
                .get(&key)
                .and_then(|&id| meshes.get_strong_handle(id));
            let handle = match found {
                Some(handle) => handle,
                None => {
                    let regions = &instance.regions;
                    let caches = self
                        .table
                        .level_caches
                        .entry(state.asset.serial)
                        .or_insert_with(|| RegionCaches::new(regions));
                    // The region's buffer depends on its dependencies' levels alone.
                    for &q in &state.asset.dependencies[r] {
                        caches.set_level(regions, q as usize, instance.caches.level(q as usize));
                    }
                    let skin = state.asset.skin.as_ref();
                    let mesh = level_mesh(regions, caches, r, skin, &mut self.scratch);
                    self.bytes += mesh_bytes(&mesh);
                    let handle = meshes.add(mesh);
                    self.table.levels.insert(key.clone(), handle.id());
                    self.table.made.insert(handle.id(), key);
                    handle
                }
            };
            if instance.mesh_ids[r] == handle.id() {
                continue;
            }
            if let Ok(mut drawn) = self.drawn.get_mut(instance.region_entities[r]) {
                drawn.0 = handle.clone();
            }
            instance.mesh_ids[r] = handle.id();
            instance.meshes[r] = handle;
            changed += 1;
        }
        changed
    }
}

/// The Bevy mesh of region `r` at the caches' current levels: its triangles reordered for
/// the vertex cache ([`optimize_vertex_cache`]; the collapse order scatters them), only the
/// vertices they use, in the order they are first used, 16-bit indices where they fit. A
/// skinned asset's (`skin`) carries its vertices in bind space with their joints and
/// weights, and the bounds Bevy moves with the joints.
fn level_mesh(
    regions: &RegionMesh,
    caches: &mut RegionCaches,
    r: usize,
    skin: Option<&SharedSkin>,
    indices: &mut Vec<u32>,
) -> Mesh {
    caches.write_indices(regions, r, indices);
    let table = regions.regions()[r].progressive_mesh().vertices();
    // The level's own vertices first, so that reordering costs the level, not its region's
    // whole vertex table; then in order of first use again, as the new order uses them.
    let level = renumber_by_first_use(indices, table.vertex_count());
    optimize_vertex_cache(indices, level.len());
    let used: Vec<u32> = renumber_by_first_use(indices, level.len())
        .into_iter()
        .map(|i| level[i as usize])
        .collect();
    let (joints, weights) = match skin {
        Some(skin) => {
            let (joints, weights) = skin.influences(r, &used);
            (Some(joints), Some(weights))
        }
        None => (None, None),
    };
    let vertices = IndexedMesh {
        joints,
        weights,
        ..table.subset(&used)
    };
    let mut mesh = to_bevy_mesh(&vertices, &[]);
    mesh.insert_indices(if used.len() <= usize::from(u16::MAX) {
        Indices::U16(indices.iter().map(|&i| i as u16).collect())
    } else {
        Indices::U32(indices.clone())
    });
    if skin.is_some()
        && let Err(error) = mesh.generate_skinned_mesh_bounds()
    {
        warn_once!("a skinned level mesh has no joint bounds ({error}): culled by its last box");
    }
    mesh
}

/// Renumbers the vertices of `indices` (below `vertex_count`) in the order they are first
/// used; returns, per new number, the old one.
fn renumber_by_first_use(indices: &mut [u32], vertex_count: usize) -> Vec<u32> {
    let mut remap = vec![u32::MAX; vertex_count];
    let mut used = Vec::new();
    for i in indices.iter_mut() {
        let slot = &mut remap[*i as usize];
        if *slot == u32::MAX {
            *slot = used.len() as u32;
            used.push(*i);
        }
        *i = *slot;
    }
    used
}

/// A mesh's vertex and index bytes, as the renderer holds them.
fn mesh_bytes(mesh: &Mesh) -> usize {
    let vertices = mesh.count_vertices() * mesh.get_vertex_size() as usize;
    let indices = match mesh.indices() {
        Some(Indices::U16(i)) => i.len() * 2,
        Some(Indices::U32(i)) => i.len() * 4,
        None => 0,
    };
    vertices + indices
}

/// Forgets the level meshes Bevy dropped (no instance showed them any more) and the shared
/// data of assets that changed or went (their instances are rebuilt, and make new level
/// meshes).
pub(super) fn forget_dropped(
    mut table: ResMut<SharedMeshes>,
    mut meshes: MessageReader<AssetEvent<Mesh>>,
    mut assets: MessageReader<AssetEvent<MultiresMesh>>,
) {
    for event in meshes.read() {
        if let AssetEvent::Removed { id } = event
            && let Some(key) = table.made.remove(id)
            && table.levels.get(&key) == Some(id)
        {
            table.levels.remove(&key);
        }
    }
    for event in assets.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event
            && let Some(asset) = table.assets.remove(id)
        {
            table.level_caches.remove(&asset.serial);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_grid;
    use crate::multires::BuildOptions;
    use crate::regions::{GridPlane, Partition};

    /// A bumpy 17×17-vertex grid cut into 3×3 regions.
    fn regions() -> RegionMesh {
        let mesh = test_grid(17, |x, z| ((x * 7 + z * 13) % 5) as f32 * 0.1);
        let partition = Partition::grid(&mesh, GridPlane::XZ, 3, 3).unwrap();
        RegionMesh::build(&mesh, &partition, &BuildOptions::default()).unwrap()
    }

    #[test]
    fn ladder_steps_are_below_the_target_and_ratio_apart() {
        let ladder = SharedLevels::default();
        let mut steps = std::collections::BTreeSet::new();
        for target in 0..=5000 {
            let step = ladder.step_at_or_below(5000, 40, target);
            assert!(step <= target.max(40), "{step} above {target}");
            assert!(step >= 40);
            steps.insert(step);
        }
        // 5000 / 1.5^k down to 40: 12 steps above the minimum, and the minimum.
        assert_eq!(steps.len(), 13, "{steps:?}");
        let nan = SharedLevels { ratio: f32::NAN };
        assert_eq!(nan.effective_ratio(), SharedLevels::MIN_RATIO);
        assert!(nan.step_at_or_below(100, 1, 50) <= 50);
    }

    #[test]
    fn a_level_mesh_depends_only_on_its_dependencies_levels() {
        let regions = regions();
        let deps = dependencies(&regions);
        for (r, list) in deps.iter().enumerate() {
            assert_eq!(list[0], r as u32);
        }
        assert!(
            deps.iter().any(|d| d.len() > 1),
            "the regions share borders"
        );
        // Two walks that end at the same levels write the same level meshes.
        let mut a = RegionCaches::new(&regions);
        let mut b = RegionCaches::new(&regions);
        let counts: Vec<usize> = regions
            .regions()
            .iter()
            .map(|r| r.max_triangles() / 3)
            .collect();
        for (r, &c) in counts.iter().enumerate() {
            a.set_triangle_count(&regions, r, c);
        }
        for (r, &c) in counts.iter().enumerate().rev() {
            b.set_triangle_count(&regions, r, c / 2);
            b.set_triangle_count(&regions, r, c);
        }
        for r in 0..counts.len() {
            let (mut x, mut y) = (Vec::new(), Vec::new());
            let mx = level_mesh(&regions, &mut a, r, None, &mut x);
            let my = level_mesh(&regions, &mut b, r, None, &mut y);
            assert_eq!(x, y);
            assert_eq!(mesh_bytes(&mx), mesh_bytes(&my));
            // Only the vertices the level uses.
            let table = regions.regions()[r]
                .progressive_mesh()
                .vertices()
                .vertex_count();
            assert!(mx.count_vertices() < table);
            assert_eq!(
                x.iter().max().map(|&m| m as usize + 1),
                Some(mx.count_vertices())
            );
        }
    }

    #[test]
    fn level_meshes_are_ordered_for_the_vertex_cache() {
        // One region of a 65×65 grid: its collapse order scatters the triangles.
        let mesh = test_grid(65, |x, z| ((x * 7 + z * 13) % 5) as f32 * 0.1);
        let partition = Partition::grid(&mesh, GridPlane::XZ, 1, 1).unwrap();
        let regions = RegionMesh::build(&mesh, &partition, &BuildOptions::default()).unwrap();
        let mut caches = RegionCaches::new(&regions);
        let half = regions.regions()[0].max_triangles() / 2;
        caches.set_triangle_count(&regions, 0, half);
        let mut raw = Vec::new();
        caches.write_indices(&regions, 0, &mut raw);
        let mut ordered = Vec::new();
        let level = level_mesh(&regions, &mut caches, 0, None, &mut ordered);
        let before = crate::mesh::vertex_cache_misses(&raw, 16);
        let after = crate::mesh::vertex_cache_misses(&ordered, 16);
        assert!(after < 0.8 * before, "{before} -> {after}");
        // Vertices in order of first use: each new index is the next one.
        let mut next = 0;
        for &i in &ordered {
            assert!(i <= next, "vertex {i} before {next}");
            next = next.max(i + 1);
        }
        assert_eq!(next as usize, level.count_vertices());
    }
}
