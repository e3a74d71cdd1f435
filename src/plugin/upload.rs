//! `Upload`: what `SelectLod` and `Deform` staged goes into the models' meshes, and its
//! bytes to the renderer ([`render`](super::render)): swapped-in index buffers, blended
//! vertices of skinned regions, and the vertices geomorphs move.

use super::components::{AslodStats, LodRegion};
use super::diagnostics;
use super::geomorph::RegionGeomorphs;
use super::instance::{MultiresInstance, RegionStaging, StagedIndices};
use super::render::{RegionLike, RegionUpload, RenderWrites, UploadTarget, swap_staged};
use super::shared::{SharedMeshes, SharedState, SharedUpload};
use super::skin::SkinState;
use super::view_dependent::ViewDependentState;
use bevy::camera::primitives::Aabb;
use bevy::diagnostic::Diagnostics;
use bevy::platform::time::Instant;
use bevy::prelude::*;

/// What `Upload` touches of a model.
type ModelQuery = (
    &'static mut MultiresInstance,
    Option<&'static mut RegionStaging>,
    Option<&'static mut SkinState>,
    Option<&'static mut RegionGeomorphs>,
    Option<&'static mut ViewDependentState>,
    Option<&'static SharedState>,
);

/// `Upload`: swap in the index buffers `SelectLod` wrote for dirty regions, write what
/// `Deform` produced for skinned ones and what geomorphs move, and nothing else. On the
/// direct path ([`RegionUpload::IndicesOnly`]) the meshes change without a change event and
/// the new bytes go to the renderer on their own.
#[allow(clippy::too_many_arguments)]
pub(crate) fn upload(
    mut models: Query<ModelQuery>,
    mut meshes: ResMut<Assets<Mesh>>,
    mode: Res<RegionUpload>,
    mut writes: ResMut<RenderWrites>,
    mut aabbs: Query<&'static mut Aabb, RegionLike>,
    mut drawn: Query<&'static mut Mesh3d, With<LodRegion>>,
    mut shared_meshes: ResMut<SharedMeshes>,
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
    let mut shared_upload = SharedUpload {
        table: &mut shared_meshes,
        drawn: &mut drawn,
        bytes: 0,
        scratch: Vec::new(),
    };
    for (mut instance, staging, skin, morphs, view, shared) in &mut models {
        if let Some(mut view) = view {
            changed += usize::from(view.upload(&mut target));
            // (Its geomorphs may have gone: it shows the refined level now.)
            instance.level = Some(view.summary());
        }
        if let Some(mut skin) = skin {
            changed += skin.upload(&instance, &mut target);
        }
        swapped.clear();
        match (staging, shared) {
            (Some(mut staging), Some(shared)) => {
                let staging = &mut *staging;
                for &r in &staging.ready {
                    staging.staged[r as usize].ready = false;
                }
                let ready = staging.ready.drain(..);
                changed += shared_upload.apply(shared, &mut instance, target.meshes, ready);
            }
            (Some(mut staging), None) => {
                changed += upload_staged(&instance, &mut staging, &mut target, &mut swapped);
            }
            _ => {}
        }
        if let Some(output) = morphs.and_then(|m| m.into_inner().output.as_mut()) {
            output.upload(&instance.mesh_ids, &mut target, |r| {
                swapped.contains(&(r as u32))
            });
        }
    }
    stats.upload_bytes = target.bytes + shared_upload.bytes as u64;
    stats.shared_meshes = shared_upload.table.level_count(target.meshes);
    stats.regions_changed = changed;
    stats.upload_ms = start.elapsed().as_secs_f64() * 1e3;
    stats.update_ms += stats.upload_ms;
    let (triangles, update_ms) = (stats.triangles as f64, stats.update_ms);
    diag.add_measurement(&diagnostics::TRIANGLES, || triangles);
    diag.add_measurement(&diagnostics::UPDATE_MS, || update_ms);
    diag.add_measurement(&diagnostics::REGIONS_CHANGED, || changed as f64);
}

/// Swaps the index buffers `SelectLod` staged for an unskinned model's regions into their
/// meshes (only those regions: their staging slots and meshes), noting them in `swapped`.
/// Returns how many changed.
fn upload_staged(
    instance: &MultiresInstance,
    staging: &mut RegionStaging,
    target: &mut UploadTarget,
    swapped: &mut Vec<u32>,
) -> usize {
    let mut changed = 0;
    let RegionStaging { staged, ready, .. } = staging;
    for r in ready.drain(..) {
        let StagedIndices { ready, indices } = &mut staged[r as usize];
        if !std::mem::take(ready) {
            continue;
        }
        let r = r as usize;
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
    changed
}
