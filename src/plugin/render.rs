//! Handing level changes to Bevy's renderer: a changed region costs its index data, a
//! skinned region the vertices `Deform` blended, a geomorph the vertices it moves, and
//! nothing else.
//!
//! Changing a mesh through `Assets::<Mesh>::get_mut` raises `AssetEvent::Modified`, and Bevy
//! then clones the whole mesh into the render world and writes all of its vertices and
//! indices to the GPU again. The plugin instead changes its region meshes with
//! `get_mut_untracked` (so the main world's copy stays current for picking and for any later
//! re-extraction) and queues the new bytes in [`RenderWrites`]. One extract system moves the
//! queue to the render world, where [`apply_writes`] runs right after Bevy's own mesh
//! preparation:
//!
//! - index data: the region mesh's index allocation in the `MeshAllocator` is replaced by one
//!   of the new size; `RenderMesh::buffer_info` takes the new count (direct draws read it),
//!   and the main world marks the region entity's `Aabb` changed, so Bevy rebuilds that
//!   instance's `MeshInputUniform` from the new slice (GPU preprocessing reads the index range
//!   from there);
//! - vertex data (skinned regions, geomorphs): the run of vertices is written in place into the
//!   mesh's vertex slice, interleaved as Bevy packs it;
//! - the frame's bytes go to the GPU in one staging write, then one copy per run of
//!   destinations that follow each other, in one submission before the frame's draws.
//!
//! `docs/render-path.md` has the whole path and the Bevy change that would make it cheaper.
//!
//! Every view, pass and material draws the same `RenderMesh` and slices, so shadows,
//! prepasses and several cameras see the change in the frame that asked for it; nothing is
//! throttled by `RenderAssetBytesPerFrame`.

use super::components::{LodRegion, ViewDependentLevel};
use super::instance::empty_indices;
use bevy::asset::AssetId;
use bevy::camera::primitives::Aabb;
use bevy::mesh::{Indices, Mesh};
use bevy::platform::collections::HashSet;
use bevy::prelude::*;
use bevy::render::mesh::allocator::{
    ElementClass, ElementLayout, MeshAllocationKey, MeshAllocator, MeshAllocatorSettings,
    allocate_and_free_meshes,
};
use bevy::render::mesh::{RenderMesh, RenderMeshBufferInfo};
use bevy::render::render_asset::{ExtractedAssets, RenderAssets, prepare_assets};
use bevy::render::render_resource::{
    Buffer, BufferDescriptor, BufferUsages, COPY_BUFFER_ALIGNMENT, CommandEncoderDescriptor,
    IndexFormat,
};
use bevy::render::renderer::{RenderDevice, RenderQueue};
use bevy::render::{ExtractSchedule, MainWorld, Render, RenderApp, RenderSystems};
use std::ops::Range;

/// How the plugin hands a region's new level to the renderer.
#[derive(Resource, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Resource, Default)]
pub enum RegionUpload {
    /// Index data only (and the blended vertices of skinned regions), written into the mesh
    /// allocator's buffers in the render world. The region meshes change without
    /// `AssetEvent::Modified` (an app without a render sub-app sees them change too, and
    /// nothing is queued).
    #[default]
    IndicesOnly,
    /// Through `Assets::<Mesh>::get_mut`: Bevy re-extracts and re-uploads the whole region
    /// mesh, vertices included, on every change. Kept to compare against.
    WholeMesh,
}

/// One region mesh's new index buffer: `count` indices in `bytes` of the batch's arena.
#[derive(Clone, Debug)]
struct IndexWrite {
    mesh: AssetId<Mesh>,
    bytes: Range<usize>,
    count: u32,
    wide: bool,
}

/// A run of vertices of one region mesh, from vertex `first`, as interleaved records in
/// `bytes` of the batch's arena.
#[derive(Clone, Debug)]
struct VertexWrite {
    mesh: AssetId<Mesh>,
    first: u32,
    bytes: Range<usize>,
}

/// The writes of one frame: their bytes in one arena, reused from frame to frame.
#[derive(Default, Debug)]
pub(crate) struct WriteBatch {
    arena: Vec<u8>,
    indices: Vec<IndexWrite>,
    vertices: Vec<VertexWrite>,
}

impl WriteBatch {
    fn clear(&mut self) {
        self.arena.clear();
        self.indices.clear();
        self.vertices.clear();
    }

    fn is_empty(&self) -> bool {
        self.indices.is_empty() && self.vertices.is_empty()
    }

    /// Queues `indices` as the mesh's whole index buffer. An empty level is written as one
    /// degenerate triangle, which draws nothing: a mesh without an index allocation would be
    /// drawn as unindexed vertices.
    fn push_indices(&mut self, mesh: AssetId<Mesh>, indices: &Indices) {
        let start = self.arena.len();
        let (count, wide) = match indices {
            Indices::U16(i) if i.is_empty() => {
                self.arena
                    .extend_from_slice(bytemuck::cast_slice(&[0u16; 3]));
                (3, false)
            }
            Indices::U32(i) if i.is_empty() => {
                self.arena
                    .extend_from_slice(bytemuck::cast_slice(&[0u32; 3]));
                (3, true)
            }
            Indices::U16(i) => {
                self.arena.extend_from_slice(bytemuck::cast_slice(i));
                (i.len() as u32, false)
            }
            Indices::U32(i) => {
                self.arena.extend_from_slice(bytemuck::cast_slice(i));
                (i.len() as u32, true)
            }
        };
        self.indices.push(IndexWrite {
            mesh,
            bytes: start..self.arena.len(),
            count,
            wide,
        });
    }

    /// Queues vertices `run` of `mesh`, packed from its attributes as Bevy packs them (each
    /// vertex's attributes one after another, in the mesh's attribute order).
    fn push_vertices(&mut self, id: AssetId<Mesh>, mesh: &Mesh, run: Range<u32>) -> bool {
        let Ok(attributes) = mesh.try_attributes() else {
            return false;
        };
        let attributes: Vec<(usize, &[u8])> = attributes
            .map(|(a, values)| (a.format.size() as usize, values.get_bytes()))
            .collect();
        let stride: usize = attributes.iter().map(|(size, _)| size).sum();
        let (lo, hi) = (run.start as usize, run.end as usize);
        if attributes.iter().any(|(size, b)| b.len() < hi * size) {
            return false;
        }
        let start = self.arena.len();
        self.arena.reserve((hi - lo) * stride);
        for v in lo..hi {
            for &(size, bytes) in &attributes {
                self.arena
                    .extend_from_slice(&bytes[v * size..(v + 1) * size]);
            }
        }
        self.vertices.push(VertexWrite {
            mesh: id,
            first: run.start,
            bytes: start..self.arena.len(),
        });
        true
    }
}

/// The main world's queue of writes for the renderer, taken by the extract step. Writes are
/// queued only when a render sub-app exists to take them.
#[derive(Resource, Default, Debug)]
pub(crate) struct RenderWrites {
    /// Whether a render sub-app takes the writes (set when the plugin finishes building).
    pub(crate) enabled: bool,
    pub(crate) batch: WriteBatch,
}

/// What the plugin wrote to the GPU for region meshes in the last rendered frame (a resource
/// of the render world, reset each frame). Bevy's own uploads (new meshes, meshes changed
/// through `Assets::get_mut`) are not counted here.
#[derive(Resource, Reflect, Clone, Copy, Debug, Default, PartialEq)]
#[reflect(Resource, Default)]
pub struct RegionUploadStats {
    /// Milliseconds the render world spent on the writes (allocation, staging, copies).
    pub write_ms: f64,
    /// Index bytes written.
    pub index_bytes: u64,
    /// Vertex bytes written (blended vertices of skinned regions, and the vertices of
    /// geomorphs: where a morph starts with [`GeomorphMaterial`](super::GeomorphMaterial),
    /// every moving vertex each frame without it).
    pub vertex_bytes: u64,
    /// Region meshes whose index buffer was replaced.
    pub index_writes: u32,
    /// Vertex runs written.
    pub vertex_writes: u32,
    /// Writes kept for the next frame because their mesh was not prepared yet.
    pub deferred: u32,
    /// GPU copies the writes took (runs that follow each other in a buffer go as one).
    pub copies: u32,
}

/// The render world's writes: this frame's, and those whose mesh was not prepared yet.
#[derive(Resource, Default)]
struct PendingWrites {
    batch: WriteBatch,
    deferred: WriteBatch,
    /// The meshes Bevy unloads this frame: their deferred writes go with them.
    removed: HashSet<AssetId<Mesh>>,
}

/// Notes the meshes Bevy unloads this frame, before `prepare_assets` drains the list.
fn note_removed(extracted: Res<ExtractedAssets<RenderMesh>>, mut pending: ResMut<PendingWrites>) {
    pending.removed.clear();
    pending.removed.extend(extracted.removed.iter().copied());
}

impl RenderWrites {
    /// Queues a region mesh's new index buffer (`indices` is the mesh's buffer after the
    /// change); returns the bytes queued.
    pub(crate) fn indices(&mut self, mesh: AssetId<Mesh>, indices: &Indices) -> usize {
        let before = self.batch.arena.len();
        self.batch.push_indices(mesh, indices);
        self.batch.arena.len() - before
    }

    /// Queues the vertices of `mesh` from `lo` to `hi` (inclusive), as the mesh holds them;
    /// returns the bytes queued.
    pub(crate) fn vertices(&mut self, id: AssetId<Mesh>, mesh: &Mesh, lo: u32, hi: u32) -> usize {
        let before = self.batch.arena.len();
        if !self.batch.push_vertices(id, mesh, lo..hi + 1) {
            warn_once!(
                "a skinned region mesh's vertex data cannot be read; its vertices are not updated"
            );
        }
        self.batch.arena.len() - before
    }
}

/// The entities `Upload` writes meshes of: regions and variable-resolution levels.
pub(crate) type RegionLike = Or<(With<LodRegion>, With<ViewDependentLevel>)>;

/// Where `Upload` writes: the meshes, how, the renderer's queue and the region boxes it marks
/// changed (so Bevy rebuilds those instances' draw data from the new index slices).
pub(crate) struct UploadTarget<'a, 'w, 's> {
    pub(crate) meshes: &'a mut Assets<Mesh>,
    pub(crate) direct: bool,
    pub(crate) writes: &'a mut RenderWrites,
    pub(crate) aabbs: &'a mut Query<'w, 's, &'static mut Aabb, RegionLike>,
    /// Bytes handed to the renderer this frame.
    pub(crate) bytes: u64,
}

impl UploadTarget<'_, '_, '_> {
    /// The region mesh to change: without a change event on the direct path (its bytes go to
    /// the renderer through [`RenderWrites`]), with one on the whole-mesh path.
    #[inline]
    pub(crate) fn mesh(&mut self, id: AssetId<Mesh>) -> Option<&mut Mesh> {
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
    #[inline]
    pub(crate) fn indices_changed(&mut self, id: AssetId<Mesh>, entity: Entity) {
        let Some(mesh) = self.meshes.get(id) else {
            return;
        };
        if !self.direct {
            self.bytes += whole_mesh_bytes(mesh);
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
    #[inline]
    pub(crate) fn vertices_changed(&mut self, id: AssetId<Mesh>, written: &[u32], counted: bool) {
        let Some(mesh) = self.meshes.get(id) else {
            return;
        };
        if !self.direct {
            if !counted {
                self.bytes += whole_mesh_bytes(mesh);
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

/// Makes `buffer` the mesh's index buffer by swapping (the old one comes back in `buffer`): no
/// copy, and no allocation in steady state. False, with a warning, when the mesh's data is no
/// longer in the main world.
pub(crate) fn swap_indices(mesh: &mut Mesh, buffer: &mut Vec<u32>) -> bool {
    let mut staged = Indices::U32(std::mem::take(buffer));
    let swapped = swap_staged(mesh, &mut staged);
    if let Indices::U32(old) = staged {
        *buffer = old;
    }
    swapped
}

/// [`swap_indices`] for a staged buffer of either width; `buffer` keeps its width (a buffer of
/// the other width that comes back from the mesh, its first one, is dropped).
#[inline]
pub(crate) fn swap_staged(mesh: &mut Mesh, buffer: &mut Indices) -> bool {
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

/// One frame's bytes for the GPU, and where each run goes: written to the GPU at once and
/// copied into place there.
#[derive(Resource, Default)]
struct Staging {
    buffer: Option<Buffer>,
    bytes: Vec<u8>,
    /// `bytes` in the order of the copies' destinations.
    packed: Vec<u8>,
    /// Source offset, destination, destination offset, size: each a multiple of 4.
    copies: Vec<(u64, Buffer, u64, u64)>,
    /// Copies the last submission made of them.
    merged: usize,
}

impl Staging {
    /// Queues `bytes` for `buffer` at `offset` (a multiple of 4; the slabs' slots are). The
    /// size is rounded up to 4 bytes, which the allocation's last slot holds.
    fn push(&mut self, buffer: &Buffer, offset: u64, bytes: &[u8]) {
        let start = self.bytes.len() as u64;
        self.bytes.extend_from_slice(bytes);
        let size = (bytes.len() as u64).next_multiple_of(COPY_BUFFER_ALIGNMENT);
        self.bytes.resize((start + size) as usize, 0);
        self.copies.push((start, buffer.clone(), offset, size));
    }

    /// Writes the staged bytes and copies each run into place, in one submission (before
    /// the frame's draws, which are submitted later).
    fn submit(&mut self, device: &RenderDevice, queue: &RenderQueue) {
        if self.copies.is_empty() {
            return;
        }
        let needed = self.bytes.len() as u64;
        if self.buffer.as_ref().is_none_or(|b| b.size() < needed) {
            self.buffer = Some(device.create_buffer(&BufferDescriptor {
                label: Some("aslod region staging"),
                size: needed.next_power_of_two(),
                usage: BufferUsages::COPY_SRC | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        let Some(staging) = &self.buffer else {
            return;
        };
        // In the order of their places, so runs that follow each other in a buffer go as one
        // copy from one stretch of the staging buffer.
        self.copies
            .sort_unstable_by_key(|(_, dst, offset, _)| (dst.id(), *offset));
        self.packed.clear();
        let mut merged: Vec<(u64, &Buffer, u64, u64)> = Vec::with_capacity(self.copies.len());
        for (src, dst, offset, size) in &self.copies {
            let at = self.packed.len() as u64;
            self.packed
                .extend_from_slice(&self.bytes[*src as usize..(*src + *size) as usize]);
            match merged.last_mut() {
                Some(last) if last.1.id() == dst.id() && last.2 + last.3 == *offset => {
                    last.3 += size;
                }
                _ => merged.push((at, dst, *offset, *size)),
            }
        }
        queue.write_buffer(staging, 0, &self.packed);
        self.merged = merged.len();
        let mut encoder = device.create_command_encoder(&CommandEncoderDescriptor {
            label: Some("aslod region copies"),
        });
        for (src, dst, offset, size) in merged {
            encoder.copy_buffer_to_buffer(staging, src, dst, offset, size);
        }
        queue.submit([encoder.finish()]);
        self.copies.clear();
    }
}

/// Adds the render-world half when the app has a render sub-app.
pub(super) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
        return;
    };
    render_app
        .init_resource::<PendingWrites>()
        .init_resource::<Staging>()
        .init_resource::<RegionUploadStats>()
        .add_systems(ExtractSchedule, extract_writes)
        .add_systems(
            Render,
            note_removed
                .in_set(RenderSystems::PrepareAssets)
                .before(prepare_assets::<RenderMesh>),
        )
        .add_systems(
            Render,
            apply_writes
                .in_set(RenderSystems::PrepareAssets)
                .after(allocate_and_free_meshes)
                .after(prepare_assets::<RenderMesh>),
        );
    app.world_mut().resource_mut::<RenderWrites>().enabled = true;
}

/// Moves the main world's queued writes to the render world (the two arenas trade places, so
/// neither allocates in steady state).
fn extract_writes(mut main: ResMut<MainWorld>, mut pending: ResMut<PendingWrites>) {
    let Some(mut writes) = main.get_resource_mut::<RenderWrites>() else {
        return;
    };
    pending.batch.clear();
    std::mem::swap(&mut pending.batch, &mut writes.batch);
}

/// Writes the frame's index and vertex data into the mesh allocator's buffers, after Bevy
/// has allocated and prepared the meshes it extracted this frame.
#[allow(clippy::too_many_arguments)]
fn apply_writes(
    mut pending: ResMut<PendingWrites>,
    mut allocator: ResMut<MeshAllocator>,
    settings: Res<MeshAllocatorSettings>,
    mut meshes: ResMut<RenderAssets<RenderMesh>>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mut staging: ResMut<Staging>,
    mut stats: ResMut<RegionUploadStats>,
) {
    let start = bevy::platform::time::Instant::now();
    *stats = RegionUploadStats::default();
    let pending = &mut *pending;
    if pending.batch.is_empty() && pending.deferred.is_empty() {
        return;
    }
    // Deferred writes are older than this frame's: they go first, and a newer write of the
    // same mesh replaces them.
    let mut deferred = std::mem::take(&mut pending.deferred);
    let removed = std::mem::take(&mut pending.removed);
    let batches = [&deferred, &pending.batch];
    let mut gpu = Gpu {
        allocator: &mut allocator,
        settings: &settings,
        meshes: &mut meshes,
        device: &device,
        queue: &queue,
    };
    let mut later = WriteBatch::default();
    let ready = ready_index_writes(&batches, &gpu, &removed, &mut later);
    gpu.reallocate(&batches, &ready);
    // The bytes go to the GPU in one write into a staging buffer and one copy per region
    // into its place in the slabs: a queue write per region costs a staging allocation each.
    let staging = &mut *staging;
    staging.bytes.clear();
    staging.copies.clear();
    gpu.stage_indices(&batches, &ready, staging, &mut stats);
    gpu.stage_vertices(&batches, &removed, staging, &mut later, &mut stats);
    staging.submit(&device, &queue);
    stats.copies = staging.merged as u32;
    stats.write_ms = start.elapsed().as_secs_f64() * 1e3;
    stats.deferred = (later.indices.len() + later.vertices.len()) as u32;
    deferred.clear();
    pending.deferred = later;
    pending.removed = removed;
}

/// An index write whose mesh Bevy has prepared: its batch, its place in the batch, its
/// allocation and the slab layout it goes into.
type ReadyIndexWrite = (usize, usize, MeshAllocationKey, ElementLayout);

/// The index writes to make now: only the newest write of each mesh counts (two
/// allocations of one key in a stage would leave the first copy without a place to go). A
/// mesh Bevy has not prepared yet (its first frame was throttled, say) keeps its write for
/// the next frame, in `later`; a mesh that is gone takes its writes along.
fn ready_index_writes(
    batches: &[&WriteBatch; 2],
    gpu: &Gpu,
    removed: &HashSet<AssetId<Mesh>>,
    later: &mut WriteBatch,
) -> Vec<ReadyIndexWrite> {
    let mut ready = Vec::new();
    let mut seen = HashSet::new();
    let mut layouts = [None; 2];
    for (b, batch) in batches.iter().enumerate().rev() {
        for (w, write) in batch.indices.iter().enumerate().rev() {
            if !seen.insert(write.mesh) {
                continue;
            }
            let key = MeshAllocationKey::new(write.mesh, ElementClass::Index);
            // A mesh Bevy has prepared has its allocations. Every index slab of one width has
            // the same element layout: it is looked up once per width.
            let format = gpu
                .meshes
                .get(write.mesh)
                .and_then(RenderMesh::index_format);
            let layout = format.and_then(|format| {
                let slot = &mut layouts[usize::from(format == IndexFormat::Uint32)];
                if slot.is_none() {
                    *slot = gpu
                        .allocator
                        .mesh_slabs(&write.mesh)
                        .and_then(|slabs| slabs.index_slab_id)
                        .and_then(|slab| gpu.allocator.slabs.get(&slab))
                        .map(|slab| *slab.element_layout());
                }
                *slot
            });
            match (layout, format) {
                (Some(layout), Some(format)) => {
                    if (format == IndexFormat::Uint32) != write.wide {
                        warn_once!("a region mesh's index width changed; its level is not updated");
                        continue;
                    }
                    ready.push((b, w, key, layout));
                }
                // A mesh that is gone (its model despawned) takes its writes along.
                _ if removed.contains(&write.mesh) => {}
                _ => {
                    let bytes = &batch.arena[write.bytes.clone()];
                    let start = later.arena.len();
                    later.arena.extend_from_slice(bytes);
                    later.indices.push(IndexWrite {
                        bytes: start..later.arena.len(),
                        ..write.clone()
                    });
                }
            }
        }
    }
    ready
}

/// The render world's side of the writes: Bevy's mesh allocator and meshes, and the GPU.
struct Gpu<'a> {
    allocator: &'a mut MeshAllocator,
    settings: &'a MeshAllocatorSettings,
    meshes: &'a mut RenderAssets<RenderMesh>,
    device: &'a RenderDevice,
    queue: &'a RenderQueue,
}

impl Gpu<'_> {
    /// Replaces the index allocations of the `ready` writes by ones of their new sizes, in
    /// one allocation stage. Every old allocation goes first, so the new ones can fill the
    /// merged holes one after another (and their copies merge, in [`Staging::submit`]).
    fn reallocate(&mut self, batches: &[&WriteBatch; 2], ready: &[ReadyIndexWrite]) {
        let mut free = self.allocator.stage_deallocation();
        for (_, _, key, _) in ready {
            free.free(key);
        }
        free.commit();
        let mut stage = self.allocator.stage_allocation();
        for &(b, w, key, layout) in ready {
            let write = &batches[b].indices[w];
            stage.allocate(&key, write.bytes.len() as u64, layout, self.settings);
        }
        stage.commit(self.device, self.queue);
    }

    /// Stages the bytes of the `ready` index writes for their new allocations, and gives
    /// their meshes the new index counts.
    fn stage_indices(
        &mut self,
        batches: &[&WriteBatch; 2],
        ready: &[ReadyIndexWrite],
        staging: &mut Staging,
        stats: &mut RegionUploadStats,
    ) {
        let settings = self.settings;
        for &(b, w, key, _) in ready {
            let batch = batches[b];
            let write = &batch.indices[w];
            let bytes = &batch.arena[write.bytes.clone()];
            // The allocator gives data this large a slab of its own (its rule, on whole slots).
            let large = (bytes.len() as u64).next_multiple_of(COPY_BUFFER_ALIGNMENT)
                >= settings.large_threshold.min(settings.max_slab_size);
            if large {
                // A slab of its own is created with its data.
                self.allocator.copy_element_data(
                    &key,
                    bytes.len(),
                    |mut slice| slice.copy_from_slice(bytes),
                    self.device,
                    self.queue,
                );
            } else {
                // Makes the new allocation resident without writing, so its place is known.
                self.allocator
                    .copy_element_data(&key, 0, |_| {}, self.device, self.queue);
                let Some(slice) = self.allocator.mesh_index_slice(&write.mesh) else {
                    continue;
                };
                let element = if write.wide { 4 } else { 2 };
                staging.push(slice.buffer, u64::from(slice.range.start) * element, bytes);
            }
            if let Some(mesh) = self.meshes.get_mut(write.mesh)
                && let RenderMeshBufferInfo::Indexed { count, .. } = &mut mesh.buffer_info
            {
                *count = write.count;
            }
            stats.index_bytes += bytes.len() as u64;
            stats.index_writes += 1;
        }
    }

    /// Stages the vertex runs, in place: the allocation keeps its size and offset. A mesh
    /// not prepared yet keeps its runs for the next frame, in `later`.
    fn stage_vertices(
        &self,
        batches: &[&WriteBatch; 2],
        removed: &HashSet<AssetId<Mesh>>,
        staging: &mut Staging,
        later: &mut WriteBatch,
        stats: &mut RegionUploadStats,
    ) {
        for batch in batches {
            for write in &batch.vertices {
                let bytes = &batch.arena[write.bytes.clone()];
                let stride = self
                    .meshes
                    .get(write.mesh)
                    .map(|m| m.layout.0.layout().array_stride);
                match (self.allocator.mesh_vertex_slice(&write.mesh), stride) {
                    (Some(slice), Some(stride)) if stride > 0 => {
                        let count = bytes.len() as u64 / stride;
                        if u64::from(write.first) + count
                            > u64::from(slice.range.end - slice.range.start)
                        {
                            warn_once!(
                                "a skinned region's vertex run lies outside its mesh; not written"
                            );
                            continue;
                        }
                        let offset =
                            (u64::from(slice.range.start) + u64::from(write.first)) * stride;
                        staging.push(slice.buffer, offset, bytes);
                        stats.vertex_bytes += bytes.len() as u64;
                        stats.vertex_writes += 1;
                    }
                    _ if removed.contains(&write.mesh) => {}
                    _ => {
                        let start = later.arena.len();
                        later.arena.extend_from_slice(bytes);
                        later.vertices.push(VertexWrite {
                            bytes: start..later.arena.len(),
                            ..write.clone()
                        });
                    }
                }
            }
        }
    }
}

/// The bytes Bevy uploads again when a mesh is re-extracted: its whole vertex table and its
/// index buffer (as `RenderMesh::byte_len` counts them).
pub(crate) fn whole_mesh_bytes(mesh: &Mesh) -> u64 {
    let vertex_size: u64 = mesh
        .try_attributes()
        .map(|a| a.map(|(a, _)| a.format.size()).sum())
        .unwrap_or(0);
    let index_bytes = mesh.get_index_buffer_bytes().map_or(0, <[u8]>::len);
    vertex_size * mesh.count_vertices() as u64 + index_bytes as u64
}
