//! The plugin's systems, one per step of the runtime loop.

use super::refine::{FineMorph, FineState, Goal, RefineCamera, VariableLevel, ViewDependent};
use super::render::{self, RegionUpload, RenderWrites};
use super::skin::{self, MultiresSkin, SkinState, initial_region_mesh};
use super::tasks::{ComputePool, par_chunks};
use super::{
    ATTRIBUTE_MORPH_FROM, ATTRIBUTE_MORPH_NORMAL_FROM, AslodStats, AslodSystems, AslodViewport,
    CountInBudget, FullDetail, Geomorph, GpuGeomorph, InputRun, LodPriority, LodRegion, MorphState,
    MultiresInstance, MultiresMesh, MultiresModel, PolygonBudget, StagedIndices, VertexRun,
    diagnostics,
};
use crate::bevy_mesh::to_bevy_mesh;
use crate::budget::{Allocator, Obb, ProjectedAreaCamera, RegionInput};
use crate::refine::View;
use crate::regions::RegionCaches;
use crate::skin::SkinRegionKind;
use bevy::asset::AssetId;
use bevy::camera::primitives::{Aabb, MeshAabb};
use bevy::camera::visibility::{NoAutoAabb, NoFrustumCulling};
use bevy::diagnostic::Diagnostics;
use bevy::ecs::system::NonSendMarker;
use bevy::mesh::Indices;
use bevy::mesh::VertexAttributeValues;
use bevy::platform::time::Instant;
use bevy::prelude::*;
use bevy::transform::TransformSystems;

/// Where every [`MultiresMaterialPlugin`](super::MultiresMaterialPlugin) copies its model
/// materials to the regions: in [`AslodSystems::Spawn`], after the regions are made.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) struct MaterialSystems;

/// A camera a view-dependent model may refine for.
#[derive(Clone, Copy, Debug)]
struct CameraView {
    entity: Entity,
    clip_from_world: Mat4,
    /// Viewport height in pixels.
    height: f32,
    /// Its projected areas (`None` for a camera they cannot use).
    projector: Option<ProjectedAreaCamera>,
    /// Active: it renders, and the allocation weighs regions by what it sees.
    active: bool,
    /// Marked [`RefineCamera`].
    marked: bool,
}

/// Buffers kept across frames.
#[derive(Resource, Default)]
pub(crate) struct AslodScratch {
    allocator: Allocator,
    cameras: Vec<ProjectedAreaCamera>,
    /// The cameras view-dependent models may refine for.
    views: Vec<CameraView>,
    inputs: Vec<RegionInput>,
    counts: Vec<u32>,
    /// Counts the allocations; [`MultiresInstance::input_run`] names the one it took part in.
    serial: u64,
    /// This frame's allocation, for `SelectLod`: its serial, or `None` when `Allocate` made
    /// none (no usable camera, or a budget it could not use).
    allocated: Option<u64>,
    warned_budget: bool,
}

pub(super) fn configure(app: &mut App) {
    app.init_resource::<MaterialsGiven>()
        .configure_sets(
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
                .after(bevy::camera::CameraUpdateSystems),
        )
        .add_systems(
            PostUpdate,
            (
                (
                    super::scene::convert_scenes,
                    rebuild_modified,
                    spawn_regions,
                    sync_view_dependent,
                )
                    .chain()
                    .in_set(AslodSystems::Spawn),
                warn_without_material
                    .in_set(AslodSystems::Spawn)
                    .after(spawn_regions)
                    .after(MaterialSystems),
                (update_skins, allocate)
                    .chain()
                    .in_set(AslodSystems::Allocate),
                select_lod.in_set(AslodSystems::SelectLod),
                deform.in_set(AslodSystems::Deform),
                upload.in_set(AslodSystems::Upload),
            ),
        );
}

/// Gives every new [`MultiresModel`] whose asset is loaded its region children. A skinned
/// asset with a [`MultiresSkin`] puts each rigid region under its joint entity instead.
#[allow(clippy::type_complexity)]
pub(super) fn spawn_regions(
    mut commands: Commands,
    models: Query<(Entity, &MultiresModel, Option<&MultiresSkin>), Without<MultiresInstance>>,
    assets: Res<Assets<MultiresMesh>>,
    mut meshes: ResMut<Assets<Mesh>>,
) {
    for (entity, model, joints) in &models {
        let Some(asset) = assets.get(&model.0) else {
            continue; // not loaded yet
        };
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
        // Skinned regions start as their bind pose (rigid ones in their bone's space): the
        // state's buffers and the meshes alike.
        let initial: Option<Vec<_>> = binding.as_ref().map(|b| {
            (0..regions.regions().len())
                .map(|r| initial_region_mesh(b, &regions, r))
                .collect()
        });
        let state = binding
            .as_ref()
            .zip(initial.as_deref())
            .map(|(b, meshes)| SkinState::new(b.clone(), meshes));
        let mut initial = initial.map(Vec::into_iter);
        let mut handles = Vec::with_capacity(regions.regions().len());
        let mut region_entities = Vec::with_capacity(regions.regions().len());
        for (r, region) in regions.regions().iter().enumerate() {
            let (mesh, parent, rigid) = match (&binding, initial.as_mut().and_then(Iterator::next))
            {
                (Some(binding), Some(mesh)) => match binding.kinds()[r] {
                    SkinRegionKind::Rigid { bone } => {
                        match joints.and_then(|j| j.joints.get(bone as usize)) {
                            Some(&joint) => (mesh, joint, true),
                            None => {
                                warn!(
                                    "MultiresModel {entity}: joint {bone} is missing; its rigid region stays at the model"
                                );
                                (mesh, entity, false)
                            }
                        }
                    }
                    SkinRegionKind::Deformable { .. } => (mesh, entity, false),
                },
                _ => (region.progressive_mesh().vertices().clone(), entity, false),
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
            if state.is_some() && !rigid {
                // Its vertices move every frame: Bevy's box from the bind pose is stale.
                child.insert(NoFrustumCulling);
            }
            region_entities.push(child.id());
            handles.push(handle);
        }
        let targets = regions
            .regions()
            .iter()
            .map(|r| r.min_triangles() as u32)
            .collect();
        let staged = regions
            .regions()
            .iter()
            .map(|region| StagedIndices {
                ready: false,
                indices: empty_indices(region.fits_u16()),
            })
            .collect();
        commands.entity(entity).insert(MultiresInstance {
            caches: RegionCaches::new(&regions),
            bounds: asset.bounds(),
            obbs: asset.obbs().clone(),
            regions,
            targets,
            input_run: InputRun::default(),
            mesh_ids: handles.iter().map(Handle::id).collect(),
            meshes: handles,
            skin: state,
            staged,
            ready: Vec::new(),
            settled: false,
            shown: 0,
            region_entities,
            fine: None,
            morph: None,
        });
    }
}

/// The Bevy mesh of a region or a variable-resolution level before its first level: the
/// vertex table (joints and weights left out: the plugin skins on the CPU) and one degenerate
/// triangle in the index width the levels use, so the renderer gives the mesh its index
/// allocation from the start. With it, the box of every vertex, as Bevy would compute it: the
/// plugin keeps it, since level changes do not go through the asset's change events.
fn placeholder_mesh(vertices: crate::mesh::IndexedMesh, narrow: bool) -> (Mesh, Aabb) {
    let mut mesh = to_bevy_mesh(
        &crate::mesh::IndexedMesh {
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

/// The models whose regions took a material this frame (from any
/// [`MultiresMaterialPlugin`](super::MultiresMaterialPlugin)).
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
    new_levels: Query<(Entity, &ChildOf), Added<VariableLevel>>,
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

/// Hot reload: when a [`MultiresMesh`] changes, every model showing it loses its instance
/// (whose observer despawns the regions and frees their meshes), so `spawn_regions` builds
/// them anew from the new asset.
fn rebuild_modified(
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
        if !modified.contains(&handle.0.id()) {
            continue;
        }
        commands.entity(model).remove::<MultiresInstance>();
    }
}

/// Starts and stops the view-dependent refinement of models as their [`ViewDependent`] comes
/// and goes: gives the model a child drawing its variable-resolution level and hides its
/// regions, or despawns that child, frees its mesh and shows the regions again.
#[allow(clippy::type_complexity)]
pub(super) fn sync_view_dependent(
    mut commands: Commands,
    mut models: Query<(
        Entity,
        &mut MultiresInstance,
        &MultiresModel,
        Option<Ref<ViewDependent>>,
    )>,
    assets: Res<Assets<MultiresMesh>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut warned: Local<bevy::ecs::entity::EntityHashSet>,
) {
    for (entity, mut instance, model, settings) in &mut models {
        match (instance.fine.is_some(), settings) {
            (false, None) => {}
            (true, Some(settings)) => {
                if settings.is_changed()
                    && let Some(fine) = &mut instance.fine
                {
                    fine.set_settings((*settings).clone());
                }
            }
            (true, None) => {
                let Some(fine) = instance.fine.take() else {
                    continue;
                };
                commands.entity(fine.entity).try_despawn();
                meshes.remove(&fine.handle);
                for &region in &instance.region_entities {
                    commands.entity(region).try_insert(Visibility::Inherited);
                }
                // The regions kept their levels and their meshes; the next allocation moves them.
                instance.settled = false;
                warned.remove(&entity);
            }
            (false, Some(settings)) => {
                let variable = assets.get(&model.0).and_then(|a| a.variable().cloned());
                let reason = if instance.is_skinned() {
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
                        VariableLevel,
                        Transform::default(),
                        ChildOf(entity),
                        aabb,
                        NoAutoAabb,
                    ))
                    .id();
                for &region in &instance.region_entities {
                    commands.entity(region).try_insert(Visibility::Hidden);
                }
                instance.fine = Some(FineState::new(
                    variable,
                    child,
                    handle,
                    narrow,
                    (*settings).clone(),
                ));
            }
        }
    }
}

/// Removes a model's region entities (those under the model and those under joints) and
/// their meshes when its instance goes away.
pub(super) fn remove_region_meshes(
    remove: On<Remove, MultiresInstance>,
    mut commands: Commands,
    instances: Query<&MultiresInstance>,
    meshes: Option<ResMut<Assets<Mesh>>>,
) {
    let Ok(instance) = instances.get(remove.entity) else {
        return;
    };
    for entity in instance.drawn_entities() {
        commands.entity(entity).try_despawn();
    }
    let Some(mut meshes) = meshes else {
        return;
    };
    for handle in instance
        .meshes
        .iter()
        .chain(instance.fine.as_ref().map(|f| &f.handle))
    {
        meshes.remove(handle);
    }
}

/// The viewport of a camera in pixels: its own, else [`AslodViewport`].
fn viewport_size(camera: &Camera, fallback: Option<&AslodViewport>) -> Option<Vec2> {
    camera
        .physical_viewport_size()
        .map(|s| s.as_vec2())
        .filter(|s| s.x > 0.0 && s.y > 0.0)
        .or(fallback.map(|v| v.0))
}

/// `Allocate`: projected area of every region of every model, maximum over cameras, budget
/// split over all of them at once.
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn allocate(
    budget: Res<PolygonBudget>,
    full_detail: Res<FullDetail>,
    viewport: Option<Res<AslodViewport>>,
    cameras: Query<
        (
            Entity,
            &Camera,
            &GlobalTransform,
            &Projection,
            Has<RefineCamera>,
        ),
        With<Camera3d>,
    >,
    mut models: Query<(
        &mut MultiresInstance,
        &GlobalTransform,
        Option<&LodPriority>,
    )>,
    fixed: Query<&Mesh3d, With<CountInBudget>>,
    meshes: Res<Assets<Mesh>>,
    mut scratch: ResMut<AslodScratch>,
    mut stats: ResMut<AslodStats>,
    mut diag: Diagnostics,
    _main_thread: NonSendMarker,
) {
    let start = Instant::now();
    let scratch = &mut *scratch;
    stats.allocated = false;
    scratch.allocated = None;
    stats.budget = budget.total;
    scratch.cameras.clear();
    scratch.views.clear();
    // A phantom `RefineCamera` with no render target of its own refines for the viewport of
    // the first active camera.
    let active_size = cameras
        .iter()
        .filter(|c| c.1.is_active)
        .find_map(|c| viewport_size(c.1, viewport.as_deref()));
    for (entity, camera, transform, projection, marked) in &cameras {
        if !camera.is_active && !marked {
            continue;
        }
        let size = viewport_size(camera, viewport.as_deref())
            .or(active_size.filter(|_| marked && !camera.is_active));
        let Some(size) = size else {
            continue;
        };
        // `camera_system` fills `clip_from_view`; before it has run (or without a renderer)
        // it is the default identity, and the projection gives the right matrix.
        let mut clip_from_view = camera.clip_from_view();
        if clip_from_view == Mat4::IDENTITY || clip_from_view == Mat4::ZERO {
            clip_from_view = projection.get_clip_from_view();
        }
        let projector = match ProjectedAreaCamera::from_world_from_view(
            transform.to_matrix(),
            clip_from_view,
            size,
        ) {
            Ok(c) => Some(c),
            Err(e) => {
                debug!("skipping a camera for LOD allocation: {e}");
                None
            }
        };
        if camera.is_active
            && let Some(c) = projector
        {
            scratch.cameras.push(c);
        }
        scratch.views.push(CameraView {
            entity,
            clip_from_world: clip_from_view * transform.to_matrix().inverse(),
            height: size.y,
            projector,
            active: camera.is_active,
            marked,
        });
    }
    stats.cameras = scratch.cameras.len();
    if scratch.cameras.is_empty() || models.is_empty() {
        return;
    }

    let fixed_cost: u64 = fixed
        .iter()
        .filter_map(|m| meshes.get(&m.0))
        .map(|m| match m.indices() {
            Some(i) => i.len() as u64 / 3,
            None => m.count_vertices() as u64 / 3,
        })
        .sum();

    // Each model's regions fill one run of `inputs`, in query order, and the model notes
    // where its run starts (`SelectLod` reads its targets from the same run of `counts`, in
    // parallel); the runs are filled in parallel on the compute pool.
    scratch.serial += 1;
    let serial = scratch.serial;
    let items: Vec<_> = models
        .iter_mut()
        .map(|item| (item.0.input_len(), item))
        .collect();
    let model_count = items.len();
    let total: usize = items.iter().map(|(n, _)| n).sum();
    // Every input is written below (each model fills its whole run): no need to clear.
    scratch.inputs.resize(total, RegionInput::default());
    let mut jobs = Vec::with_capacity(items.len());
    let mut rest = scratch.inputs.as_mut_slice();
    let mut offset = 0;
    for (n, item) in items {
        let (run, tail) = rest.split_at_mut(n);
        jobs.push((item, offset, run));
        offset += n;
        rest = tail;
    }
    let cameras = &scratch.cameras;
    let views = &scratch.views;
    let full_detail = full_detail.0;
    // Returns the counts of the view-dependent models without a budget, refined here: they
    // are fixed cost.
    let fill = |chunk: &mut [AreaJob<'_>]| {
        let mut scratch = AreaScratch::default();
        let mut tolerance_only = 0u64;
        for ((instance, transform, priority), offset, out) in chunk {
            instance.input_run = InputRun {
                allocation: serial,
                first: *offset,
            };
            if instance.fine.is_some() {
                fine_input(instance, transform, *priority, views, full_detail, out);
                // A model with only a pixel tolerance is refined now: its count is this
                // frame's fixed cost for the allocation.
                if let Some(fine) = instance.fine.as_mut().filter(|f| !f.settings.budgeted) {
                    fine.select();
                    tolerance_only += fine.triangle_count() as u64;
                }
                continue;
            }
            region_inputs(
                instance,
                transform,
                *priority,
                cameras,
                full_detail,
                &mut scratch,
                out,
            );
        }
        tolerance_only
    };
    let tolerance_only: u64 = par_chunks(&mut jobs, fill).into_iter().sum();
    let fixed_cost = u32::try_from(fixed_cost + tolerance_only).unwrap_or(u32::MAX);
    stats.models = model_count;
    stats.regions = scratch.inputs.len();
    stats.fixed_cost = fixed_cost;

    let params = budget.params(fixed_cost);
    if full_detail {
        // No LOD: every region at its full detail, whatever the budget and the view.
        scratch.counts.clear();
        scratch.counts.extend(scratch.inputs.iter().map(|i| i.max));
    } else {
        match scratch.allocator.allocate_with(
            &params,
            &scratch.inputs,
            &mut scratch.counts,
            &ComputePool,
        ) {
            Ok(report) => {
                scratch.warned_budget = false;
                if report.infeasible {
                    debug!("polygon budget below the sum of the coarsest levels");
                }
            }
            Err(e) => {
                if !scratch.warned_budget {
                    warn!("LOD allocation skipped: {e}");
                    scratch.warned_budget = true;
                }
                return;
            }
        }
    }
    stats.allocated = true;
    scratch.allocated = Some(serial);
    let ms = start.elapsed().as_secs_f64() * 1e3;
    stats.allocation_ms = ms;
    diag.add_measurement(&diagnostics::ALLOCATION_MS, || ms);
    diag.add_measurement(&diagnostics::BUDGET, || f64::from(budget.total));
}

/// The user priority `c` of a model (see [`LodPriority`]).
fn priority_of(priority: Option<&LodPriority>) -> f32 {
    priority
        .map(|p| p.0)
        .filter(|c| c.is_finite() && *c > 0.0)
        .unwrap_or(if priority.is_some() { 0.0 } else { 1.0 })
}

/// A view-dependent model in `Allocate`: what it refines for this frame ([`Goal`]) and, when
/// it is budgeted, its one allocation input: its bounds' largest projected area, between its
/// coarsest level and the most it can use.
fn fine_input(
    instance: &mut MultiresInstance,
    transform: &GlobalTransform,
    priority: Option<&LodPriority>,
    views: &[CameraView],
    full_detail: bool,
    out: &mut [RegionInput],
) {
    let bounds = instance.bounds.transformed(&transform.affine());
    let area_of = |cam: &ProjectedAreaCamera| {
        let a = if cam.may_see(&bounds) {
            cam.projected_area(&bounds)
        } else {
            0.0
        };
        if a.is_finite() { a } else { 0.0 }
    };
    let Some(fine) = &mut instance.fine else {
        return;
    };
    let marked = views.iter().find(|v| v.marked);
    // What each camera that counts sees of it: the active ones and the marked one.
    let seen = || {
        views
            .iter()
            .filter(|v| v.active || marked.is_some_and(|m| m.entity == v.entity))
            .filter_map(|v| Some((v, area_of(v.projector.as_ref()?))))
    };
    fine.goal = if full_detail {
        Goal::Full
    } else {
        // The marked camera, else the active one that sees the model largest.
        let chosen = marked.or_else(|| {
            seen()
                .filter(|(_, a)| *a > 0.0)
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(v, _)| v)
        });
        match chosen {
            None => Goal::Coarsest,
            Some(v) => {
                match View::from_clip_from_local(
                    v.clip_from_world * transform.to_matrix(),
                    v.height,
                ) {
                    Ok(view) => Goal::Refine(view, v.entity),
                    Err(e) => {
                        warn_once!(
                            "a ViewDependent model refines uniformly: its camera cannot drive a refinement ({e})"
                        );
                        Goal::Uniform
                    }
                }
            }
        }
    };
    let Some(input) = out.first_mut() else {
        return; // not budgeted
    };
    let pm = fine.mesh.mesh();
    let (min, max) = if full_detail {
        (pm.max_triangles(), pm.max_triangles())
    } else {
        (pm.min_triangles(), fine.max_useful())
    };
    fine.capped = !full_detail && max < pm.max_triangles();
    // Weighed by what the active cameras see, and what the camera it refines for sees.
    let area = if full_detail {
        0.0
    } else {
        seen().map(|(_, a)| a).fold(0.0, f32::max)
    };
    *input = RegionInput::from_area(
        area,
        priority_of(priority),
        min as u32,
        max as u32,
        fine.triangle_count() as u32,
    );
}

/// One model of `Allocate` and the run of inputs it fills.
type AreaJob<'a> = (
    (
        Mut<'a, MultiresInstance>,
        &'a GlobalTransform,
        Option<&'a LodPriority>,
    ),
    usize,
    &'a mut [RegionInput],
);

/// Buffers [`region_inputs`] reuses from model to model.
#[derive(Default)]
struct AreaScratch {
    /// The cameras moved into the model's space.
    local: Vec<ProjectedAreaCamera>,
    /// The largest area of each region over the cameras so far, and one camera's areas.
    areas: Vec<f32>,
    one: Vec<f32>,
}

/// One model's [`RegionInput`]s: each region's box, its largest projected area over the
/// cameras (skipped without LOD, which does not use it), the model's priority. Unskinned
/// boxes stay in the model's space and the cameras move into it (four boxes at a time, see
/// [`ProjectedAreaCamera::projected_areas`]); skinned ones are already in the world.
fn region_inputs(
    instance: &MultiresInstance,
    transform: &GlobalTransform,
    priority: Option<&LodPriority>,
    cameras: &[ProjectedAreaCamera],
    full_detail: bool,
    scratch: &mut AreaScratch,
    out: &mut [RegionInput],
) {
    let AreaScratch { local, areas, one } = scratch;
    let c = priority_of(priority);
    let affine = transform.affine();
    let skinned = instance.skin.as_ref().map(|s| s.world_obbs.as_slice());
    // Every region box lies inside the model's box: when that one is out of every view, so
    // are they (skinned regions move with their bones, so not for them). The world box
    // contains the model's box, so this never culls a visible model.
    let culled = !full_detail && skinned.is_none() && {
        let bounds = instance.bounds.transformed(&affine);
        !cameras.iter().any(|cam| cam.may_see(&bounds))
    };
    // Model space needs an invertible transform; a flattened model (a zero scale on one
    // axis, still drawn as a sheet) keeps world-space boxes.
    local.clear();
    let in_model = skinned.is_none() && !full_detail && !culled && {
        local.extend(cameras.iter().filter_map(|cam| cam.for_model(&affine)));
        local.len() == cameras.len()
    };
    let max_area = |cams: &[ProjectedAreaCamera], obb: &Obb| {
        cams.iter()
            .map(|cam| cam.projected_area(obb))
            .fold(0.0f32, f32::max)
    };
    if in_model {
        areas.clear();
        areas.resize(instance.obbs.len(), 0.0);
        one.resize(instance.obbs.len(), 0.0);
        for camera in local.iter() {
            camera.projected_areas(&instance.obbs, one);
            for (max, &area) in areas.iter_mut().zip(one.iter()) {
                *max = max.max(area);
            }
        }
    }
    for ((r, region), input) in instance.regions.regions().iter().enumerate().zip(out) {
        let area = if full_detail || culled {
            0.0
        } else if in_model {
            areas[r]
        } else {
            let obb = skinned
                .and_then(|boxes| boxes.get(r).copied())
                .unwrap_or_else(|| instance.obbs[r].transformed(&affine));
            max_area(cameras, &obb)
        };
        let area = if area.is_finite() { area } else { 0.0 };
        let shown = instance.caches.triangle_count(r) as u32;
        // Geomorphs or not, the allocation is the view's (`Geomorphs::apply_allocation`
        // holds the budget while regions morph).
        let (min, max) = (region.min_triangles() as u32, region.max_triangles() as u32);
        *input = RegionInput::from_area(area, c, min, max, shown);
    }
}

/// `SelectLod`: each region's cache to its target, in parallel over models on the compute
/// task pool. Unskinned models also write the index buffers of their dirty regions here
/// (copying them is the costly part of an update), for `Upload` to swap in;
/// skinned models write theirs in `Deform`.
fn select_lod(
    mut models: Query<(&mut MultiresInstance, Option<&Geomorph>, Has<GpuGeomorph>)>,
    scratch: Res<AslodScratch>,
    time: Res<Time>,
    mut stats: ResMut<AslodStats>,
    _main_thread: NonSendMarker,
) {
    let start = Instant::now();
    let now = time.elapsed_secs();
    // The shaders' clock (`globals.time`) is the same time, wrapped.
    let clock = Clock {
        now,
        shader: time.elapsed_secs_wrapped(),
    };
    let mut instances: Vec<Mut<MultiresInstance>> = models
        .iter_mut()
        .map(|(mut instance, morph, gpu)| {
            let seconds = morph.map_or(0.0, |m| m.0);
            if seconds > 0.0 || instance.morph.is_some() {
                sync_geomorph(&mut instance, seconds, gpu);
            }
            if let Some(fine) = &mut instance.fine
                && (seconds > 0.0 || fine.morph.is_some())
            {
                fine.sync_morph(seconds, gpu);
            }
            instance
        })
        .collect();
    // The models this frame's allocation covered take their targets from its counts.
    let fresh = scratch.allocated;
    let counts = &scratch.counts;
    // First pass: every model's caches to its targets, except geomorph refinements, which
    // wait for the second (a coarsening region keeps its old triangles for the morph time,
    // so what is free is known only once every model has started its coarsenings).
    let totals = par_chunks(&mut instances, |chunk| {
        let mut sums = Sums::default();
        for instance in chunk {
            let InputRun { allocation, first } = instance.input_run;
            if let Some(fine) = &mut instance.fine {
                let this_frame = fresh == Some(allocation);
                if !this_frame {
                    fine.goal = Goal::Keep;
                }
                fine.target = counts
                    .get(first)
                    .copied()
                    .filter(|_| this_frame && fine.settings.budgeted);
                // Tolerance-only models were refined in `Allocate`.
                if fine.settings.budgeted {
                    fine.select();
                }
                let target = fine.triangle_count() as u64;
                let shown = fine.begin_morph(now) as u64;
                // Under geomorphs its refinements and vertices wait for the second pass.
                let deferred = fine.morph.is_some();
                instance.shown = shown;
                instance.settled = false;
                sums.add(shown, target);
                sums.deferred += if deferred { shown } else { 0 };
                continue;
            }
            let run = counts
                .get(first..first + instance.targets.len())
                .filter(|_| fresh == Some(allocation));
            // The same targets as last frame on a settled model: nothing moves (most models
            // out of view, whose regions all sit at their minimum, and far ones).
            let same = run.is_none_or(|run| run == instance.targets.as_slice());
            if same && instance.settled {
                sums.add(instance.shown, instance.shown);
                continue;
            }
            let instance = &mut **instance;
            let allocated = run.is_some();
            if let Some(run) = run {
                instance.targets.copy_from_slice(run);
            }
            let target: u64 = instance.targets.iter().map(|&t| u64::from(t)).sum();
            if let Some(morph) = &mut instance.morph
                && morph.allocated
            {
                let (regions, caches) = (&instance.regions, &mut instance.caches);
                let targets = &instance.targets;
                let m = &mut morph.morphs;
                m.begin_allocation(regions, caches, targets, now, &mut morph.refine);
                morph.second_pass = true;
                let shown = caches.total_triangles() as u64;
                sums.add(shown, target);
                sums.deferred += shown;
                continue;
            }
            let mut shown = 0;
            for (r, &target) in instance.targets.iter().enumerate() {
                shown += instance
                    .caches
                    .set_triangle_count(&instance.regions, r, target as usize)
                    as u64;
            }
            // A new model's caches start at full detail: its first allocation is taken at
            // once, under geomorphs too (it would count full detail for the morph time).
            if let Some(morph) = &mut instance.morph {
                morph.allocated |= allocated;
                let skinned = instance.skin.is_some();
                finish_morphs(
                    morph,
                    &instance.regions,
                    &mut instance.caches,
                    skinned,
                    clock,
                );
            }
            instance.shown = shown;
            sums.add(shown, target);
            finish_select(instance);
        }
        sums
    });
    let sums = totals.into_iter().fold(Sums::default(), |a, b| Sums {
        shown: a.shown + b.shown,
        target: a.target + b.target,
        deferred: a.deferred + b.deferred,
    });
    // What the models asked for and do not show yet, refinements under geomorphs take, largest
    // first: the triangles shown never exceed what the allocation gave all models together.
    let mut free = sums.target.saturating_sub(sums.shown);
    let mut wanted: Vec<(u32, u32, u32)> = Vec::new();
    // (A view-dependent model asks as region `FINE`.)
    const FINE: u32 = u32::MAX;
    for (i, instance) in instances.iter().enumerate() {
        if let Some(morph) = &instance.morph
            && morph.second_pass
        {
            wanted.extend(morph.refine.iter().map(|&(r, n)| (n, i as u32, r)));
        }
        if let Some(m) = instance.fine.as_ref().and_then(|f| f.morph.as_ref())
            && m.wanted > 0
        {
            wanted.push((m.wanted, i as u32, FINE));
        }
    }
    wanted.sort_unstable_by(|a, b| b.cmp(a));
    for (n, i, r) in wanted {
        let grant = u64::from(n).min(free);
        free -= grant;
        let instance = &mut *instances[i as usize];
        match (&mut instance.fine, &mut instance.morph) {
            (Some(fine), _) if r == FINE => {
                if let Some(m) = &mut fine.morph {
                    m.wanted = grant as u32;
                }
            }
            (_, Some(morph)) => morph.grants.push((r, grant as u32)),
            _ => {}
        }
    }
    // Second pass: the geomorph models' refinements, morphs and index buffers.
    let totals = par_chunks(&mut instances, |chunk| {
        let mut triangles = 0u64;
        for instance in chunk {
            let instance = &mut **instance;
            if let Some(fine) = &mut instance.fine
                && fine.morph.is_some()
            {
                // What it wanted, now what it was granted (nothing when it wanted nothing).
                let granted = fine
                    .morph
                    .as_mut()
                    .map_or(0, |m| std::mem::take(&mut m.wanted));
                instance.shown = fine.finish_morph(granted, now) as u64;
                triangles += instance.shown;
                let n = fine.mesh.mesh().vertices().vertex_count();
                if let Some(m) = &mut fine.morph {
                    stage_fine_vertices(m, n, clock);
                }
                continue;
            }
            let Some(morph) = &mut instance.morph else {
                continue;
            };
            if !std::mem::take(&mut morph.second_pass) {
                continue;
            }
            let (regions, caches) = (&instance.regions, &mut instance.caches);
            for (r, grant) in morph.grants.drain(..) {
                morph
                    .morphs
                    .grant(regions, caches, r as usize, grant as usize, now);
            }
            finish_morphs(morph, regions, caches, instance.skin.is_some(), clock);
            instance.shown = caches.total_triangles() as u64;
            triangles += instance.shown;
            finish_select(instance);
        }
        triangles
    });
    stats.triangles = sums.shown - sums.deferred + totals.into_iter().sum::<u64>();
    stats.update_ms = start.elapsed().as_secs_f64() * 1e3;
}

/// Triangles over a pass of `SelectLod`: shown, asked for, and shown by the models whose
/// refinements wait for the second pass.
#[derive(Clone, Copy, Debug, Default)]
struct Sums {
    shown: u64,
    target: u64,
    deferred: u64,
}

impl Sums {
    fn add(&mut self, shown: u64, target: u64) {
        self.shown += shown;
        self.target += target;
    }
}

/// After a geomorph model's caches took this frame's levels: ends what arrived, and stages
/// the vertices `Upload` writes (skinned models are written in `Deform`, from the morphs,
/// which writes a region once more at rest after its morph).
fn finish_morphs(
    morph: &mut MorphState,
    regions: &crate::regions::RegionMesh,
    caches: &mut crate::regions::RegionCaches,
    skinned: bool,
    clock: Clock,
) {
    morph.morphs.update(regions, caches, clock.now);
    morph.now = clock.now;
    if skinned {
        morph.moved.fill(false);
    } else {
        morph.stage(regions, clock);
    }
}

/// After a model's caches took this frame's levels: whether it is settled, and (unskinned)
/// the index buffers of its dirty regions for `Upload`.
fn finish_select(instance: &mut MultiresInstance) {
    // Skinned models write their buffers in `Deform`, and morphing ones move: never
    // skipped.
    instance.settled = instance.skin.is_none()
        && instance
            .morph
            .as_ref()
            .is_none_or(|m| !m.morphs.is_morphing());
    if instance.skin.is_some() {
        return;
    }
    // Only the dirty regions' staging slots are touched.
    for r in 0..instance.staged.len() {
        if !instance.caches.is_dirty(r) {
            continue;
        }
        let StagedIndices { ready, indices } = &mut instance.staged[r];
        let (caches, regions) = (&mut instance.caches, &instance.regions);
        match indices {
            Indices::U16(buffer) => caches.write_indices_u16(regions, r, buffer),
            Indices::U32(buffer) => caches.write_indices(regions, r, buffer),
        };
        if !std::mem::replace(ready, true) {
            instance.ready.push(r as u32);
        }
    }
}

/// Starts or ends an unskinned region model's geomorphs as its [`Geomorph`] says (ending
/// them puts every vertex back at its own place at the next `Upload`), on the GPU when its
/// material interpolates them.
fn sync_geomorph(instance: &mut MultiresInstance, seconds: f32, gpu: bool) {
    let wanted = seconds > 0.0 && instance.fine.is_none();
    // Skinned models blend their moving vertices in `Deform`, on the CPU.
    let gpu = gpu && instance.skin.is_none();
    match (&mut instance.morph, wanted) {
        (None, true) => {
            let n = instance.regions.regions().len();
            instance.morph = Some(MorphState {
                morphs: crate::regions::Geomorphs::new(&instance.regions, seconds),
                allocated: false,
                second_pass: false,
                refine: Vec::new(),
                grants: Vec::new(),
                now: 0.0,
                gpu,
                attributes: false,
                moved: vec![gpu; n],
                runs: vec![VertexRun::default(); n],
            });
            instance.settled = false;
        }
        (Some(m), true) if m.morphs.duration() != seconds || m.gpu != gpu => {
            m.morphs = crate::regions::Geomorphs::new(&instance.regions, seconds);
            m.gpu = gpu;
            m.moved.fill(true);
            instance.settled = false;
        }
        (Some(m), false) if m.morphs.duration() > 0.0 => {
            // Every region back at rest, written once more with its own positions, then the
            // state goes (`upload_morphs`).
            m.morphs = crate::regions::Geomorphs::new(&instance.regions, 0.0);
            m.moved.fill(true);
            instance.settled = false;
        }
        _ => {}
    }
}

/// Stages the vertices of a view-dependent model's level (`n` of them) for `Upload`, as
/// [`MorphState::stage`] does for a region.
fn stage_fine_vertices(m: &mut FineMorph, n: usize, clock: Clock) {
    let restarted = m.morphs.take_restarted();
    if !m.gpu {
        let moving = m.morphs.is_morphing();
        if moving || m.moved {
            m.runs.resize_with(1, VertexRun::default);
            let run = &mut m.runs[0];
            m.morphs.write_positions(clock.now, &mut run.positions);
            m.morphs.write_normals(clock.now, &mut run.normals);
            run.at_rest();
        }
        m.moved = moving;
        return;
    }
    let runs = if std::mem::take(&mut m.moved) {
        vec![(0, n.saturating_sub(1) as u32)]
    } else {
        restarted
    };
    if n == 0 || runs.is_empty() {
        return;
    }
    m.runs.resize_with(runs.len(), VertexRun::default);
    for (run, (lo, hi)) in m.runs.iter_mut().zip(runs) {
        let morphs = (lo..=hi).map(|v| m.morphs.vertex_morph(v));
        run.stage_morphs(lo, morphs, m.morphs.duration(), clock);
    }
}

/// The time of a frame: `Time`'s elapsed seconds, and the same wrapped as the shaders see it.
#[derive(Clone, Copy, Debug)]
struct Clock {
    now: f32,
    shader: f32,
}

impl MorphState {
    /// Stages the vertices to write for `Upload`. On the CPU: the positions and normals of
    /// every region whose vertices move now or moved last frame. On the GPU: the run of each
    /// region's vertices that a morph started on, with their morph attributes (the whole
    /// region when it must be written again).
    fn stage(&mut self, regions: &crate::regions::RegionMesh, clock: Clock) {
        let now = clock.now;
        if !self.gpu {
            for r in 0..self.moved.len() {
                let moving = self.morphs.is_region_moving(regions, r);
                if moving || self.moved[r] {
                    let run = &mut self.runs[r];
                    self.morphs
                        .write_positions(regions, r, now, &mut run.positions);
                    self.morphs.write_normals(regions, r, now, &mut run.normals);
                    run.at_rest();
                }
                self.moved[r] = moving;
            }
            return;
        }
        let duration = self.morphs.duration();
        for (r, run) in self.morphs.take_restarted(regions).into_iter().enumerate() {
            let global = regions.regions()[r].global_vertices();
            let run = if std::mem::take(&mut self.moved[r]) {
                Some((0, global.len().saturating_sub(1) as u32))
            } else {
                run
            };
            let Some((lo, hi)) = run.filter(|_| !global.is_empty()) else {
                continue;
            };
            let vertices = global[lo as usize..=hi as usize].iter().copied();
            self.runs[r].stage_morphs(
                lo,
                vertices.map(|g| self.morphs.vertex_morph(g)),
                duration,
                clock,
            );
        }
    }
}

impl VertexRun {
    /// The positions and normals written are the whole mesh's, drawn as they are.
    fn at_rest(&mut self) {
        self.first = 0;
        self.from.clear();
        self.normal_from.clear();
        self.ready = true;
    }

    /// Stages the vertices from `first` on with their morphs (`duration` seconds), for a
    /// material that interpolates them.
    fn stage_morphs(
        &mut self,
        first: u32,
        morphs: impl Iterator<Item = crate::regions::VertexMorph>,
        duration: f32,
        clock: Clock,
    ) {
        let inv = if duration > 0.0 {
            duration.recip()
        } else {
            0.0
        };
        self.positions.clear();
        self.normals.clear();
        self.from.clear();
        self.normal_from.clear();
        for m in morphs {
            // The start on the shaders' clock: as long ago as on the CPU's.
            let start = clock.shader - (clock.now - m.start);
            self.positions.push(m.to);
            self.normals.push(m.normal_to);
            self.from.push(m.from.extend(start).to_array());
            self.normal_from.push(m.normal_from.extend(inv).to_array());
        }
        self.first = first;
        self.ready = true;
    }

    /// Writes the run into `mesh`; returns the vertices written (first and last), or `None`
    /// when nothing was new or the mesh lacks room for it.
    fn write(&mut self, mesh: &mut Mesh) -> Option<[u32; 2]> {
        if !std::mem::take(&mut self.ready) {
            return None;
        }
        let (first, n) = (self.first as usize, self.positions.len());
        let mut written = true;
        for (attribute, values) in [
            (Mesh::ATTRIBUTE_POSITION, &self.positions),
            (Mesh::ATTRIBUTE_NORMAL, &self.normals),
        ] {
            if let Ok(Some(VertexAttributeValues::Float32x3(slots))) =
                mesh.try_attribute_mut_option(attribute)
                && let Some(slots) = slots.get_mut(first..first + values.len())
            {
                for (slot, v) in slots.iter_mut().zip(values) {
                    *slot = v.to_array();
                }
            }
        }
        for (attribute, values) in [
            (ATTRIBUTE_MORPH_FROM, &self.from),
            (ATTRIBUTE_MORPH_NORMAL_FROM, &self.normal_from),
        ] {
            let slots = match mesh.try_attribute_mut_option(attribute) {
                Ok(Some(VertexAttributeValues::Float32x4(slots))) => slots,
                _ => continue,
            };
            if values.is_empty() {
                // Written from the CPU: the morph attributes say "at rest".
                for (slot, p) in slots.iter_mut().skip(first).zip(&self.positions) {
                    *slot = p.extend(0.0).to_array();
                }
            } else if let Some(slots) = slots.get_mut(first..first + values.len()) {
                slots.copy_from_slice(values);
            } else {
                written = false;
            }
        }
        (n > 0 && written).then(|| [first as u32, (first + n) as u32 - 1])
    }
}

/// Reads the joints of every skinned model (before `allocate`, which needs the region
/// boxes): skinning matrices, which joints moved, each region's world box.
fn update_skins(
    mut models: Query<(&mut MultiresInstance, &GlobalTransform, &MultiresSkin)>,
    globals: Query<&GlobalTransform>,
) {
    for (mut instance, root, joints) in &mut models {
        let instance = &mut *instance;
        let Some(state) = &mut instance.skin else {
            continue;
        };
        if state.update_matrices(root, &joints.joints, &globals, &instance.obbs) {
            warn_once!(
                "a skinned MultiresModel names a joint entity without a GlobalTransform; that joint keeps its last pose"
            );
        }
    }
}

/// `Deform`: blend the cached vertices of skinned regions whose joints moved or whose cache
/// changed, in parallel over regions.
fn deform(
    mut models: Query<&mut MultiresInstance>,
    mut stats: ResMut<AslodStats>,
    mut diag: Diagnostics,
    _main_thread: NonSendMarker,
) {
    let start = Instant::now();
    let mut skinned: Vec<Mut<MultiresInstance>> =
        models.iter_mut().filter(|i| i.skin.is_some()).collect();
    let mut work = Vec::with_capacity(skinned.len());
    for instance in &mut skinned {
        let instance = &mut **instance;
        if let Some(state) = &mut instance.skin {
            let morph = instance.morph.as_ref().map(|m| (&m.morphs, m.now));
            work.push((&mut instance.caches, &*instance.regions, state, morph));
        }
    }
    let blended = skin::deform(&mut work);
    let ms = start.elapsed().as_secs_f64() * 1e3;
    stats.deform_ms = ms;
    stats.vertices_blended = blended;
    diag.add_measurement(&diagnostics::DEFORM_MS, || ms);
}

/// Makes `buffer` the mesh's index buffer by swapping (the old one comes back in `buffer`): no
/// copy, and no allocation in steady state. False, with a warning, when the mesh's data is no
/// longer in the main world.
fn swap_indices(mesh: &mut Mesh, buffer: &mut Vec<u32>) -> bool {
    let mut staged = Indices::U32(std::mem::take(buffer));
    let swapped = swap_staged(mesh, &mut staged);
    if let Indices::U32(old) = staged {
        *buffer = old;
    }
    swapped
}

/// [`swap_indices`] for a staged buffer of either width; `buffer` keeps its width (a buffer of
/// the other width that comes back from the mesh, its first one, is dropped).
fn swap_staged(mesh: &mut Mesh, buffer: &mut Indices) -> bool {
    let narrow = matches!(buffer, Indices::U16(_));
    match mesh.try_indices_mut_option() {
        Ok(Some(indices)) => std::mem::swap(indices, buffer),
        Ok(None) => mesh.insert_indices(std::mem::replace(buffer, empty_indices(narrow))),
        Err(_) => {
            warn_once!(
                "a region mesh's data is no longer in the main world; its LOD is not updated"
            );
            return false;
        }
    }
    if matches!(buffer, Indices::U16(_)) != narrow {
        *buffer = empty_indices(narrow);
    }
    true
}

/// An empty index buffer, 16-bit when `narrow`.
pub(super) fn empty_indices(narrow: bool) -> Indices {
    if narrow {
        Indices::U16(Vec::new())
    } else {
        Indices::U32(Vec::new())
    }
}

/// The entities `Upload` writes meshes of: regions and variable-resolution levels.
type RegionLike = Or<(With<LodRegion>, With<VariableLevel>)>;

/// Where `Upload` writes: the meshes, how, the renderer's queue and the region boxes it marks
/// changed (so Bevy rebuilds those instances' draw data from the new index slices).
struct UploadTarget<'a, 'w, 's> {
    meshes: &'a mut Assets<Mesh>,
    direct: bool,
    writes: &'a mut RenderWrites,
    aabbs: &'a mut Query<'w, 's, &'static mut Aabb, RegionLike>,
    /// Bytes handed to the renderer this frame.
    bytes: u64,
}

impl UploadTarget<'_, '_, '_> {
    /// The region mesh to change: without a change event on the direct path (its bytes go to
    /// the renderer through [`RenderWrites`]), with one on the whole-mesh path.
    fn mesh(&mut self, id: AssetId<Mesh>) -> Option<&mut Mesh> {
        if self.direct {
            self.meshes.get_mut_untracked(id)
        } else {
            self.meshes
                .get_mut(id)
                .map(bevy::asset::AssetMut::into_inner)
        }
    }

    /// After a region mesh's index buffer changed: queue it and mark the region's box changed
    /// (direct), or count what Bevy re-uploads (whole mesh).
    fn indices_changed(&mut self, id: AssetId<Mesh>, entity: Entity) {
        let Some(mesh) = self.meshes.get(id) else {
            return;
        };
        if !self.direct {
            self.bytes += render::whole_mesh_bytes(mesh);
            return;
        }
        if let Ok(mut aabb) = self.aabbs.get_mut(entity) {
            aabb.set_changed();
        }
        if self.writes.enabled
            && let Some(indices) = mesh.indices()
        {
            self.bytes += self.writes.indices(id, indices) as u64;
        }
    }

    /// After a skinned region's vertices `written` were blended into its mesh: queue the run
    /// from the lowest to the highest (direct), or count what Bevy re-uploads (whole mesh,
    /// unless its indices changed too and were counted already).
    fn vertices_changed(&mut self, id: AssetId<Mesh>, written: &[u32], counted: bool) {
        let Some(mesh) = self.meshes.get(id) else {
            return;
        };
        if !self.direct {
            if !counted {
                self.bytes += render::whole_mesh_bytes(mesh);
            }
            return;
        }
        let (Some(&lo), Some(&hi)) = (written.iter().min(), written.iter().max()) else {
            return;
        };
        if self.writes.enabled {
            self.bytes += self.writes.vertices(id, mesh, lo, hi) as u64;
        }
    }
}

/// Writes what `Deform` produced for one skinned instance into its region meshes: index
/// buffers that changed, and the vertices blended this frame (only those).
fn upload_skinned(instance: &mut MultiresInstance, target: &mut UploadTarget) -> usize {
    let Some(skin) = &mut instance.skin else {
        return 0;
    };
    let mut changed = 0;
    for (r, state) in skin.regions.iter_mut().enumerate() {
        if !state.indices_changed && state.written.is_empty() {
            continue;
        }
        let (Some(&id), Some(&entity)) =
            (instance.mesh_ids.get(r), instance.region_entities.get(r))
        else {
            continue;
        };
        let mut swapped = false;
        if let Some(mesh) = target.mesh(id) {
            // `state.indices` is rewritten whole before it is read again.
            swapped = state.indices_changed && swap_indices(mesh, &mut state.indices);
            if !state.written.is_empty() {
                // Swap the buffers (see `RegionSkin::positions`): no copy.
                let normals = state.has_normals.then_some(&mut state.normals);
                for (attribute, values) in [
                    (Mesh::ATTRIBUTE_POSITION, Some(&mut state.positions)),
                    (Mesh::ATTRIBUTE_NORMAL, normals),
                ] {
                    let Some(values) = values else { continue };
                    if let Ok(Some(VertexAttributeValues::Float32x3(slots))) =
                        mesh.try_attribute_mut_option(attribute)
                    {
                        if slots.len() == values.len() {
                            std::mem::swap(slots, values);
                        } else {
                            warn_once!(
                                "a skinned region mesh has the wrong vertex count; not updated"
                            );
                        }
                    }
                }
            }
        }
        if swapped {
            changed += 1;
            target.indices_changed(id, entity);
        }
        if !state.written.is_empty() {
            target.vertices_changed(id, &state.written, swapped);
        }
        state.indices_changed = false;
        state.written.clear();
    }
    changed
}

/// Writes the vertices `SelectLod` staged for a [`Geomorph`] model's regions into their
/// meshes; on the GPU, first gives the meshes the morph attributes (a change Bevy uploads
/// whole, once). `swapped`: the regions whose index buffer changed this frame.
fn upload_morphs(instance: &mut MultiresInstance, target: &mut UploadTarget, swapped: &[u32]) {
    let Some(morph) = &mut instance.morph else {
        return;
    };
    // The frame the meshes change layout, Bevy uploads them whole (with what is written
    // below): no vertex run goes to their old allocations.
    let relayout = morph.gpu && !morph.attributes;
    if relayout {
        for &id in &instance.mesh_ids {
            if let Some(mesh) = target.meshes.get_mut(id) {
                add_morph_attributes(mesh.into_inner());
            }
        }
        morph.attributes = true;
    }
    for (r, run) in morph.runs.iter_mut().enumerate() {
        if !run.ready {
            continue;
        }
        let Some(&id) = instance.mesh_ids.get(r) else {
            continue;
        };
        let Some(mesh) = target.mesh(id) else {
            continue;
        };
        if let Some(written) = run.write(mesh)
            && !relayout
        {
            // (A region whose indices changed too was counted whole already.)
            let counted = swapped.contains(&(r as u32));
            target.vertices_changed(id, &written, counted);
        }
    }
    if morph.morphs.duration() == 0.0 && !morph.moved.contains(&true) {
        instance.morph = None;
    }
}

/// Writes a view-dependent model's staged vertices (`upload_morphs` for its one mesh);
/// `swapped`: its indices were written this frame.
fn upload_fine_morph(fine: &mut FineState, target: &mut UploadTarget, swapped: bool) {
    let Some(m) = &mut fine.morph else {
        return;
    };
    let relayout = m.gpu && !m.attributes;
    if relayout && let Some(mesh) = target.meshes.get_mut(fine.id) {
        add_morph_attributes(mesh.into_inner());
        m.attributes = true;
    }
    for (i, run) in m.runs.iter_mut().enumerate() {
        if run.ready
            && let Some(mesh) = target.mesh(fine.id)
            && let Some(written) = run.write(mesh)
            && !relayout
        {
            // (Counted whole once, when its indices changed too or by the first run.)
            target.vertices_changed(fine.id, &written, swapped || i > 0);
        }
    }
    if m.morphs.duration() == 0.0 && !m.moved {
        fine.morph = None;
    }
}

/// Gives a region mesh the morph attributes, every vertex at rest.
fn add_morph_attributes(mesh: &mut Mesh) {
    if mesh.contains_attribute(ATTRIBUTE_MORPH_FROM) {
        return;
    }
    let Some(VertexAttributeValues::Float32x3(positions)) =
        mesh.attribute(Mesh::ATTRIBUTE_POSITION)
    else {
        return;
    };
    let rest: Vec<[f32; 4]> = positions.iter().map(|&[x, y, z]| [x, y, z, 0.0]).collect();
    let normals: Vec<[f32; 4]> = match mesh.attribute(Mesh::ATTRIBUTE_NORMAL) {
        Some(VertexAttributeValues::Float32x3(n)) => {
            n.iter().map(|&[x, y, z]| [x, y, z, 0.0]).collect()
        }
        _ => vec![[0.0; 4]; rest.len()],
    };
    mesh.insert_attribute(ATTRIBUTE_MORPH_FROM, rest);
    mesh.insert_attribute(ATTRIBUTE_MORPH_NORMAL_FROM, normals);
}

/// `Upload`: swap in the index buffers `SelectLod` wrote for dirty regions, write what
/// `Deform` produced for skinned ones, and nothing else. On the direct path
/// ([`RegionUpload::IndicesOnly`]) the meshes change without a change event and the new bytes
/// go to the renderer on their own.
#[allow(clippy::too_many_arguments)]
fn upload(
    mut models: Query<&mut MultiresInstance>,
    mut meshes: ResMut<Assets<Mesh>>,
    mode: Res<RegionUpload>,
    mut writes: ResMut<RenderWrites>,
    mut aabbs: Query<&'static mut Aabb, RegionLike>,
    mut stats: ResMut<AslodStats>,
    mut diag: Diagnostics,
) {
    let start = Instant::now();
    let mut changed = 0;
    // Per model: the regions whose index buffer `Upload` swapped.
    let mut swapped = Vec::new();
    let mut target = UploadTarget {
        meshes: &mut meshes,
        direct: *mode == RegionUpload::IndicesOnly,
        writes: &mut writes,
        aabbs: &mut aabbs,
        bytes: 0,
    };
    for mut instance in &mut models {
        let instance = &mut *instance;
        if let Some(fine) = &mut instance.fine {
            let swapped = std::mem::take(&mut fine.staged.ready)
                && target
                    .mesh(fine.id)
                    .is_some_and(|mesh| swap_staged(mesh, &mut fine.staged.indices));
            if swapped {
                changed += 1;
                target.indices_changed(fine.id, fine.entity);
            }
            upload_fine_morph(fine, &mut target, swapped);
        }
        changed += upload_skinned(instance, &mut target);
        // Only the regions `SelectLod` wrote: their staging slots and meshes.
        swapped.clear();
        for r in instance.ready.drain(..) {
            let r = r as usize;
            let StagedIndices { ready, indices } = &mut instance.staged[r];
            if !std::mem::take(ready) {
                continue;
            }
            let (Some(&id), Some(&entity)) =
                (instance.mesh_ids.get(r), instance.region_entities.get(r))
            else {
                continue;
            };
            // The mesh was removed by someone else: nothing to write.
            let Some(mesh) = target.mesh(id) else {
                continue;
            };
            if swap_staged(mesh, indices) {
                changed += 1;
                target.indices_changed(id, entity);
                swapped.push(r as u32);
            }
        }
        upload_morphs(instance, &mut target, &swapped);
    }
    stats.upload_bytes = target.bytes;
    stats.regions_changed = changed;
    stats.upload_ms = start.elapsed().as_secs_f64() * 1e3;
    stats.update_ms += stats.upload_ms;
    let (triangles, update_ms) = (stats.triangles as f64, stats.update_ms);
    diag.add_measurement(&diagnostics::TRIANGLES, || triangles);
    diag.add_measurement(&diagnostics::UPDATE_MS, || update_ms);
    diag.add_measurement(&diagnostics::REGIONS_CHANGED, || changed as f64);
}
