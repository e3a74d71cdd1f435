//! Skinned multiresolution models (ASLOD section 5): the binding stored in the asset
//! ([`binding`]), the pose read from the joints at the start of `Allocate` ([`SkinPose`],
//! [`update_skins`]), and for models skinned on the CPU the per-instance deformation state
//! ([`SkinState`]), the `Deform` step ([`deform`]) and what `Upload` writes of it.
//!
//! Two paths draw a skinned model. A model that shares level meshes
//! ([`SharedLevels`](super::SharedLevels), the default once an asset has a second instance)
//! is skinned by Bevy on the GPU: its level meshes carry each vertex in bind space with the
//! joints and weights below, and its region entities are Bevy `SkinnedMesh`es, so the
//! plugin reads only the pose, for the allocation's boxes. Any other is skinned here, on the
//! CPU, as the paper does; that path is also the reference the GPU path is tested against.
//! Both place every vertex alike, so both sides of a border agree on either path.
//!
//! Spaces: `G_j` is joint `j`'s `GlobalTransform`, `IB_j` its inverse bind matrix and `G_R`
//! the model root's `GlobalTransform`. Bevy's own skinning puts a vertex at
//! `Σ wₖ G_jₖ IB_jₖ p`. Here:
//! - a rigid region of bone `b` is a child of `b`'s joint entity and stores `IB_b p`: the
//!   joint's transform places it, nothing is recomputed while it animates;
//! - a deformable region is a child of the model root and stores `G_R⁻¹ Σ wₖ G_jₖ IB_jₖ p`,
//!   recomputed for the vertices its cache refers to when one of its joints moved or its
//!   cache changed;
//! - the few vertices of *other* regions that a region's border triangles use are placed the
//!   way their own region places them (a rigid vertex by its bone alone), converted into the
//!   drawing region's space, so both sides of a border put a shared vertex at one position;
//! - under geomorphs, a moving vertex is skinned from where its morph shows it in bind space
//!   (`Geomorphs::position`), and a moving rigid region writes its own vertices too.

pub(crate) mod binding;

use super::components::AslodStats;
use super::diagnostics;
use super::geomorph::{MorphTarget, RegionGeomorphs};
use super::instance::MultiresInstance;
use super::render::{UploadTarget, swap_indices};
use super::tasks::par_chunks;
use crate::bounds::Obb;
use crate::mesh::IndexedMesh;
use crate::regions::{Geomorphs, MorphKind, RegionCaches, RegionMesh};
use crate::skin::{Influences, SkinRegionKind, blend, blend_with_tangents};
use bevy::diagnostic::Diagnostics;
use bevy::ecs::system::NonSendMarker;
use bevy::mesh::VertexAttributeValues;
use bevy::pbr::MAX_JOINTS;
use bevy::platform::time::Instant;
use bevy::prelude::*;
use binding::SkinBinding;
use glam::{Affine3A, Mat3, Mat4, Vec3, Vec4};
use std::sync::Arc;

/// The joints of a skinned [`MultiresModel`](super::MultiresModel), in the skin's joint
/// order (as in Bevy's `SkinnedMesh::joints`). A skinned model without it is drawn in its
/// bind pose, with a warning.
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Default)]
pub struct MultiresSkin {
    /// The joint entities.
    pub joints: Vec<Entity>,
}

/// Whether Bevy can skin a model of skin `binding` with joints `joints` on the GPU: it lists
/// every joint of the skin, and each region uses at most Bevy's [`MAX_JOINTS`]. Otherwise
/// the model is skinned on the CPU, in `Deform`.
pub(super) fn skinned_on_gpu(binding: &SkinBinding, joints: Option<&MultiresSkin>) -> bool {
    joints.is_some_and(|j| j.joints.len() >= binding.joint_count())
        && binding.region_joints.iter().all(|j| j.len() <= MAX_JOINTS)
}

/// Per-region deformation state of one instance.
#[derive(Debug, Default)]
struct RegionSkin {
    /// The region's current index buffer (local vertices).
    indices: Vec<u32>,
    /// Local vertices `indices` refers to, each once.
    referenced: Vec<u32>,
    /// Local vertices written this frame (a subset of `referenced`).
    written: Vec<u32>,
    /// Deformed positions and normals in the region entity's space, as the mesh attributes
    /// they become: `Upload` swaps them with the mesh's (double buffering). Every referenced
    /// vertex is written each time the region is blended, and a rigid region's own vertices
    /// never change, so whichever buffer is in the mesh is current where it is drawn.
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    /// Whether the source has normals (otherwise `normals` is not blended nor uploaded).
    has_normals: bool,
    /// Deformed tangents, turned like the normals (`w`, the handedness, kept), when the
    /// source has tangents; swapped with the mesh's as the positions are.
    tangents: Vec<[f32; 4]>,
    /// `stamp[v] == generation` marks `v` as referenced.
    stamp: Vec<u32>,
    generation: u32,
    indices_changed: bool,
    /// Under geomorphs: the `Deform`s left that write the region from its morphs: while
    /// it moves, and twice after, at rest, so both of its buffers end current (a rigid
    /// region's `referenced` holds its own vertices only then).
    morph_passes: u8,
    /// Under geomorphs: the bind-space positions and normals the region's vertices are
    /// skinned from (the source's, moving ones where their morph shows them).
    morph_positions: Vec<Vec3>,
    morph_normals: Vec<Vec3>,
    /// Under geomorphs, when the mesh has further attributes to interpolate: the bind-space
    /// tangents the region is skinned from (as the positions), and the further attributes
    /// of its vertices where the morphs show them (`Geomorphs::attribute_groups`' values per
    /// local vertex), which `Upload` writes for the vertices written.
    morph_tangents: Vec<Vec4>,
    morph_attributes: Vec<f32>,
    /// `morph_attributes` holds this frame's values of the vertices written.
    attributes_written: bool,
}

impl RegionSkin {
    fn refresh_referenced(&mut self, own_vertices: usize, rigid: bool) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.stamp.fill(0);
            self.generation = 1;
        }
        self.referenced.clear();
        for &v in &self.indices {
            let Some(s) = self.stamp.get_mut(v as usize) else {
                continue;
            };
            if *s != self.generation {
                *s = self.generation;
                // A rigid region's own vertices never change: only its foreign ones do.
                if !rigid || v as usize >= own_vertices {
                    self.referenced.push(v);
                }
            }
        }
    }
}

/// The pose of a skinned instance, read from its joints at the start of `Allocate`
/// ([`update_skins`]): what places its regions' boxes for the allocation, and (skinned on the
/// CPU) the matrices `Deform` blends with. Every skinned model with a [`MultiresSkin`] has
/// one, whoever skins its vertices.
#[derive(Component, Debug)]
pub(crate) struct SkinPose {
    binding: Arc<SkinBinding>,
    /// `S_j = G_R⁻¹ G_j IB_j`: skinning matrices in the model root's space.
    matrices: Vec<Mat4>,
    /// Per joint: whether `S_j` changed this frame.
    moved: Vec<bool>,
    /// Per joint: `G_j`.
    joint_globals: Vec<Affine3A>,
    /// `G_R`.
    root_global: Affine3A,
    first_frame: bool,
}

impl SkinPose {
    pub(crate) fn new(binding: Arc<SkinBinding>) -> Self {
        let joints = binding.joint_count();
        Self {
            binding,
            matrices: vec![Mat4::IDENTITY; joints],
            moved: vec![true; joints],
            joint_globals: vec![Affine3A::IDENTITY; joints],
            root_global: Affine3A::IDENTITY,
            first_frame: true,
        }
    }
}

/// The deformation state of an instance skinned on the CPU (the paper's blend: it stages its
/// index buffers here instead of in a `RegionStaging`, and blends in `Deform`).
#[derive(Component, Debug)]
pub(crate) struct SkinState {
    regions: Vec<RegionSkin>,
    /// Under geomorphs: the further attributes they interpolate (see
    /// `RegionSkin::morph_attributes`).
    morph_targets: Vec<MorphTarget>,
}

impl SkinState {
    /// `initial`: each region's mesh from [`initial_region_mesh`], which both buffers start as.
    pub(crate) fn new(initial: &[IndexedMesh]) -> Self {
        let region_state = initial
            .iter()
            .map(|mesh| {
                let n = mesh.positions.len();
                RegionSkin {
                    positions: mesh.positions.iter().map(|p| p.to_array()).collect(),
                    normals: mesh.normals.as_ref().map_or_else(
                        || vec![[0.0, 1.0, 0.0]; n],
                        |normals| normals.iter().map(|n| n.to_array()).collect(),
                    ),
                    has_normals: mesh.normals.is_some(),
                    tangents: mesh.tangents.as_ref().map_or_else(Vec::new, |tangents| {
                        tangents.iter().map(|t| t.to_array()).collect()
                    }),
                    stamp: vec![0; n],
                    ..default()
                }
            })
            .collect();
        Self {
            regions: region_state,
            morph_targets: Vec::new(),
        }
    }

    /// Writes the index buffers of the regions whose cache changed, and the vertices they
    /// refer to; under geomorphs, notes which regions move (a moving rigid region refers to
    /// its own vertices too, until both its buffers hold them at rest).
    fn refresh_indices(
        &mut self,
        binding: &SkinBinding,
        caches: &mut RegionCaches,
        regions: &RegionMesh,
        morphs: Option<&Geomorphs>,
    ) {
        for (r, state) in self.regions.iter_mut().enumerate() {
            let moving = morphs.is_some_and(|m| m.is_region_moving(regions, r));
            let had_own = state.morph_passes > 0;
            state.morph_passes = if moving {
                3
            } else {
                state.morph_passes.saturating_sub(1)
            };
            let with_own = state.morph_passes > 0;
            let rigid = matches!(binding.kinds[r], SkinRegionKind::Rigid { .. });
            let own = regions.regions()[r].own_vertices;
            if caches.is_dirty(r) {
                caches.write_indices(regions, r, &mut state.indices);
                state.indices_changed = true;
                state.refresh_referenced(own, rigid && !with_own);
            } else if rigid && with_own != had_own {
                // (`indices` is not the mesh's buffer after `Upload`: own vertices are
                // added whole, or taken out.)
                if with_own {
                    state.referenced.extend(0..own as u32);
                } else {
                    state.referenced.retain(|&v| v as usize >= own);
                }
            }
        }
    }
}

impl SkinPose {
    /// Reads the joints' and the root's global transforms: skinning matrices, which joints
    /// moved, and every region's world box (its box `obbs` placed by its bones, into
    /// `world`). Returns whether a joint had no `GlobalTransform`.
    fn update_matrices(
        &mut self,
        root: &GlobalTransform,
        joints: &[Entity],
        globals: &Query<&GlobalTransform>,
        obbs: &[Obb],
        world: &mut Vec<Obb>,
    ) -> bool {
        self.root_global = root.affine();
        let root_inv = Mat4::from(self.root_global.inverse());
        let mut missing = false;
        for (j, ib) in self.binding.inverse_bindposes.iter().enumerate() {
            let global = match joints.get(j).map(|&e| globals.get(e)) {
                Some(Ok(g)) => g.affine(),
                // Past the listed joints (warned apart): the bind pose stays.
                None => self.joint_globals[j],
                Some(Err(_)) => {
                    missing = true;
                    self.joint_globals[j]
                }
            };
            self.joint_globals[j] = global;
            let s = root_inv * Mat4::from(global) * *ib;
            self.moved[j] = self.first_frame || s != self.matrices[j];
            self.matrices[j] = s;
        }
        self.first_frame = false;
        let root = Mat4::from(self.root_global);
        world.clear();
        for (r, kind) in self.binding.kinds.iter().enumerate() {
            let Some(obb) = obbs.get(r) else { continue };
            let at = |bone: u16| {
                let m = root
                    * self
                        .matrices
                        .get(bone as usize)
                        .copied()
                        .unwrap_or_default();
                obb.transformed(&Affine3A::from_mat4(m))
            };
            world.push(match *kind {
                SkinRegionKind::Rigid { bone } => at(bone),
                SkinRegionKind::Deformable { bones: [a, b] } => enclose(&at(a), &at(b)),
            });
        }
        missing
    }
}

/// A box with `a`'s axes that holds both `a` and `b`: cheap and conservative, for a
/// deformable region whose vertices lie between its two bones' placements.
fn enclose(a: &Obb, b: &Obb) -> Obb {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for p in a.corners().into_iter().chain(b.corners()) {
        let local = a.axes.transpose() * (p - a.center);
        lo = lo.min(local);
        hi = hi.max(local);
    }
    Obb {
        center: a.center + a.axes * ((lo + hi) * 0.5),
        axes: a.axes,
        half_extents: (hi - lo) * 0.5,
    }
}

/// What the region meshes of a skinned instance start with: rigid regions in their bone's
/// space (`IB_b p`, normals by the inverse transpose), deformable ones as the source.
pub(crate) fn initial_region_mesh(
    binding: &SkinBinding,
    regions: &RegionMesh,
    region: usize,
) -> IndexedMesh {
    let source = regions.regions()[region].progressive_mesh().vertices();
    let mut mesh = IndexedMesh {
        joints: None,
        weights: None,
        ..source.clone()
    };
    if let SkinRegionKind::Rigid { bone } = binding.kinds[region]
        && let Some(ib) = binding.inverse_bindposes.get(bone as usize)
    {
        let normal_matrix = crate::skin::normal_matrix(Mat3::from_mat4(*ib));
        for p in &mut mesh.positions {
            *p = ib.transform_point3(*p);
        }
        if let Some(normals) = &mut mesh.normals {
            for n in normals {
                *n = (normal_matrix * *n).normalize_or(*n);
            }
        }
        // Tangents lie in the surface: they turn with the linear part itself.
        let linear = Mat3::from_mat4(*ib);
        if let Some(tangents) = &mut mesh.tangents {
            for t in tangents {
                let xyz = t.truncate();
                *t = (linear * xyz).normalize_or(xyz).extend(t.w);
            }
        }
    }
    mesh
}

/// One region's work in `Deform`.
struct Job<'a> {
    region: &'a mut RegionSkin,
    influences: &'a Influences,
    source: &'a IndexedMesh,
    /// Under geomorphs: where the region's vertices are shown in bind space now, and the
    /// region's source vertices.
    morph: Option<(&'a Geomorphs, f32, &'a [u32])>,
    matrices: &'a [Mat4],
    /// For a rigid region: root space -> its joint's space.
    to_local: Option<Affine3A>,
}

impl Job<'_> {
    /// Under geomorphs: brings the further attributes of every vertex of the region up to
    /// date where the morphs show them at `now` (not only the vertices written: one left
    /// out when its level went, halfway to its stand-in's values, must be back at its own
    /// by the passes at rest, which write these directly, without a second buffer), and the
    /// bind-space tangents of the vertices written with them. Returns whether the mesh has
    /// any to interpolate.
    fn morph_attributes(&mut self, morphs: &Geomorphs, now: f32, global: &[u32]) -> bool {
        let groups = morphs.attribute_groups();
        let Some(last) = groups.last() else {
            return false;
        };
        let stride = last.offset + last.len;
        let r = &mut *self.region;
        let n = self.source.positions.len();
        let tangent = groups.iter().find(|g| g.kind == MorphKind::Tangent);
        if let (Some(_), Some(source)) = (tangent, &self.source.tangents)
            && r.morph_tangents.len() != source.len()
        {
            r.morph_tangents.clone_from(source);
        }
        r.morph_attributes.clear();
        for &g in global {
            morphs.write_vertex_attributes(g, Some(now), &mut r.morph_attributes);
        }
        if r.morph_attributes.len() != n * stride {
            r.morph_attributes.clear();
            return false;
        }
        if let Some(t) = tangent {
            for &v in &r.written {
                let v = v as usize;
                if let Some(slot) = r.morph_tangents.get_mut(v) {
                    let at = v * stride + t.offset;
                    *slot = Vec4::from_slice(&r.morph_attributes[at..at + 4]);
                }
            }
        }
        r.attributes_written = true;
        true
    }

    fn run(&mut self) {
        let r = &mut *self.region;
        r.written.clear();
        r.written.extend_from_slice(&r.referenced);
        r.attributes_written = false;
        let morphed = match self.morph {
            Some((morphs, now, global)) => self.morph_attributes(morphs, now, global),
            None => false,
        };
        let r = &mut *self.region;
        let source_tangents = match &self.source.tangents {
            Some(_) if morphed && !r.morph_tangents.is_empty() => Some(r.morph_tangents.as_slice()),
            tangents => tangents.as_deref(),
        };
        let (source_positions, source_normals) = match self.morph {
            Some((morphs, now, global)) => {
                // Only the vertices written are read: those are brought up to date.
                if r.morph_positions.len() != self.source.positions.len() {
                    r.morph_positions.clone_from(&self.source.positions);
                    r.morph_normals = self
                        .source
                        .normals
                        .clone()
                        .unwrap_or_else(|| vec![Vec3::Y; self.source.positions.len()]);
                }
                for &v in &r.written {
                    let (v, g) = (v as usize, global[v as usize]);
                    r.morph_positions[v] = morphs.position(g, now);
                    if let Some(n) = morphs.normal(g, now) {
                        r.morph_normals[v] = n;
                    }
                }
                (
                    r.morph_positions.as_slice(),
                    self.source
                        .normals
                        .as_ref()
                        .map(|_| r.morph_normals.as_slice()),
                )
            }
            None => (
                self.source.positions.as_slice(),
                self.source.normals.as_deref(),
            ),
        };
        let positions: &mut [Vec3] = bytemuck::cast_slice_mut(&mut r.positions);
        let normals: &mut [Vec3] = bytemuck::cast_slice_mut(&mut r.normals);
        // Tangents turn with the same blended matrix as their vertex (the normal takes its
        // inverse transpose), as in Bevy's shader, which normalises both.
        match source_tangents {
            Some(tangents) => blend_with_tangents(
                self.matrices,
                source_positions,
                source_normals,
                tangents,
                self.influences,
                &r.written,
                positions,
                Some(&mut *normals),
                &mut r.tangents,
            ),
            None => blend(
                self.matrices,
                source_positions,
                source_normals,
                self.influences,
                &r.written,
                positions,
                Some(&mut *normals),
            ),
        }
        if let Some(to_local) = self.to_local {
            // Normals stay unnormalised, as `blend` leaves them: Bevy's vertex shader
            // normalises every normal.
            let normal_matrix = crate::skin::normal_matrix(Mat3::from(to_local.matrix3));
            let linear = Mat3::from(to_local.matrix3);
            for &v in &r.written {
                let v = v as usize;
                if let Some(p) = positions.get_mut(v) {
                    *p = to_local.transform_point3(*p);
                }
                if r.has_normals
                    && let Some(n) = normals.get_mut(v)
                {
                    *n = normal_matrix * *n;
                }
                if let Some(t) = r.tangents.get_mut(v) {
                    let xyz = linear * Vec3::new(t[0], t[1], t[2]);
                    *t = [xyz.x, xyz.y, xyz.z, t[3]];
                }
            }
        }
    }
}

/// One skinned instance for [`deform`]: its caches, regions, deformation state, and its
/// geomorphs with the frame's time.
type DeformInput<'a> = (
    &'a mut RegionCaches,
    &'a RegionMesh,
    &'a mut SkinState,
    &'a SkinPose,
    Option<(&'a Geomorphs, f32)>,
);

/// For every skinned instance: refresh the index buffers of regions whose cache changed (in
/// parallel over instances), then blend, in parallel over regions, the vertices of each
/// region whose joints moved or whose buffer changed; both on the compute task pool and the
/// calling thread. Returns the vertices blended.
fn blend_instances(instances: &mut [DeformInput<'_>]) -> usize {
    par_chunks(instances, |chunk| {
        for (caches, regions, skin, pose, morph) in chunk {
            skin.refresh_indices(&pose.binding, caches, regions, morph.map(|(m, _)| m));
        }
    });

    let mut jobs: Vec<Job<'_>> = Vec::new();
    for (_, regions, skin, pose, morph) in instances.iter_mut() {
        let (skin, pose) = (&mut **skin, &**pose);
        let morph = *morph;
        if let Some((morphs, _)) = morph
            && skin.morph_targets.len() != morphs.attribute_groups().len()
        {
            skin.morph_targets = MorphTarget::all(morphs.attribute_groups());
        }
        for (r, state) in skin.regions.iter_mut().enumerate() {
            let region = &regions.regions()[r];
            let moved = pose.binding.region_joints[r]
                .iter()
                .any(|&j| pose.moved.get(j as usize).copied().unwrap_or(false));
            let morphing = state.morph_passes > 0;
            if !(moved || state.indices_changed || morphing) || state.referenced.is_empty() {
                state.written.clear();
                continue;
            }
            let to_local = match pose.binding.kinds[r] {
                SkinRegionKind::Rigid { bone } => {
                    let joint = pose
                        .joint_globals
                        .get(bone as usize)
                        .copied()
                        .unwrap_or(Affine3A::IDENTITY);
                    // A joint scaled to zero shows the region as a point whatever its
                    // local vertices are: keep them finite.
                    let inverse = joint.inverse();
                    Some(if inverse.is_finite() {
                        inverse * pose.root_global
                    } else {
                        pose.root_global
                    })
                }
                SkinRegionKind::Deformable { .. } => None,
            };
            jobs.push(Job {
                region: state,
                influences: &pose.binding.local[r],
                source: region.progressive_mesh().vertices(),
                morph: morph
                    .filter(|_| morphing)
                    .map(|(m, now)| (m, now, region.global_vertices())),
                matrices: &pose.matrices,
                to_local,
            });
        }
    }
    let blended: usize = jobs.iter().map(|j| j.region.referenced.len()).sum();
    par_chunks(&mut jobs, |chunk| {
        for job in chunk {
            job.run();
        }
    });
    blended
}

/// Reads the joints of every skinned model (at the start of `Allocate`, which needs the
/// region boxes): skinning matrices, which joints moved, each region's world box.
pub(crate) fn update_skins(
    mut models: Query<(
        &mut MultiresInstance,
        &mut SkinPose,
        &GlobalTransform,
        &MultiresSkin,
    )>,
    globals: Query<&GlobalTransform>,
) {
    for (mut instance, mut state, root, joints) in &mut models {
        let instance = &mut *instance;
        let Some(world) = &mut instance.skinned_boxes else {
            continue;
        };
        if joints.joints.len() < state.binding.joint_count() {
            warn_once!(
                "a skinned MultiresModel's MultiresSkin lists {} joints, its asset's skin has {}: the joints past the list keep their bind pose",
                joints.joints.len(),
                state.binding.joint_count()
            );
        }
        if state.update_matrices(root, &joints.joints, &globals, &instance.obbs, world) {
            warn_once!(
                "a skinned MultiresModel names a joint entity without a GlobalTransform; that joint keeps its last pose"
            );
        }
    }
}

/// `Deform`: blend the cached vertices of skinned regions whose joints moved or whose cache
/// changed, in parallel over regions (under geomorphs, from where the morphs show them).
pub(crate) fn deform(
    mut models: Query<(
        &mut MultiresInstance,
        &mut SkinState,
        &SkinPose,
        Option<&RegionGeomorphs>,
    )>,
    mut stats: ResMut<AslodStats>,
    mut diag: Diagnostics,
    _main_thread: NonSendMarker,
) {
    let start = Instant::now();
    let mut skinned: Vec<_> = models.iter_mut().collect();
    let mut work = Vec::with_capacity(skinned.len());
    for (instance, state, pose, morphs) in &mut skinned {
        let instance = &mut **instance;
        let morphs = morphs.map(|m| (&m.morphs, m.now));
        work.push((
            &mut instance.caches,
            &*instance.regions,
            &mut **state,
            &**pose,
            morphs,
        ));
    }
    let blended = blend_instances(&mut work);
    let ms = start.elapsed().as_secs_f64() * 1e3;
    stats.deform_ms = ms;
    stats.vertices_blended = blended;
    diag.add_measurement(&diagnostics::DEFORM_MS, || ms);
}

impl SkinState {
    /// `Upload`: writes what `Deform` produced into the instance's region meshes: index
    /// buffers that changed, and the vertices blended this frame (only those). Returns the
    /// regions whose index buffer changed.
    pub(crate) fn upload(
        &mut self,
        instance: &MultiresInstance,
        target: &mut UploadTarget,
    ) -> usize {
        let mut changed = 0;
        for (r, state) in self.regions.iter_mut().enumerate() {
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
                    state.swap_vertices(mesh);
                    state.write_morph_attributes(mesh, &self.morph_targets);
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
}

impl RegionSkin {
    /// Writes the further attributes of every vertex where the morphs show them (tangents
    /// went through the blend), when there are any this frame.
    fn write_morph_attributes(&mut self, mesh: &mut Mesh, targets: &[MorphTarget]) {
        let stride = MorphTarget::stride(targets);
        if !std::mem::take(&mut self.attributes_written) || stride == 0 {
            return;
        }
        for target in targets
            .iter()
            .filter(|t| t.group.kind != MorphKind::Tangent)
        {
            target.write(mesh, self.morph_attributes.chunks_exact(stride).enumerate());
        }
    }

    /// Swaps the blended positions and normals with the mesh's (see
    /// [`positions`](Self::positions)): no copy.
    fn swap_vertices(&mut self, mesh: &mut Mesh) {
        let normals = self.has_normals.then_some(&mut self.normals);
        for (attribute, values) in [
            (Mesh::ATTRIBUTE_POSITION, Some(&mut self.positions)),
            (Mesh::ATTRIBUTE_NORMAL, normals),
        ] {
            let Some(values) = values else { continue };
            if let Ok(Some(VertexAttributeValues::Float32x3(slots))) =
                mesh.try_attribute_mut_option(attribute)
            {
                if slots.len() == values.len() {
                    std::mem::swap(slots, values);
                } else {
                    warn_once!("a skinned region mesh has the wrong vertex count; not updated");
                }
            }
        }
        if !self.tangents.is_empty()
            && let Ok(Some(VertexAttributeValues::Float32x4(slots))) =
                mesh.try_attribute_mut_option(Mesh::ATTRIBUTE_TANGENT)
            && slots.len() == self.tangents.len()
        {
            std::mem::swap(slots, &mut self.tangents);
        }
    }
}
