//! `aslod mannequin`: generate the procedural, skinned and animated mannequin as binary glTF.

use crate::CliResult;
use bevy_aslod::mannequin::{MannequinOptions, generate};
use std::path::Path;
use std::time::Instant;

pub(crate) fn mannequin(output: &Path, cell_size: Option<f32>) -> CliResult {
    let mut options = MannequinOptions::default();
    if let Some(cell) = cell_size {
        options.cell_size = cell;
    }
    let start = Instant::now();
    let mannequin = generate(&options)?;
    let generate_ms = start.elapsed().as_secs_f64() * 1e3;
    let glb = mannequin.to_glb();
    if let Some(dir) = output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(output, &glb)?;
    let rigid = mannequin
        .regions
        .iter()
        .filter(|r| r.kind.is_rigid())
        .count();
    eprintln!(
        "wrote {}: {} triangles, {} vertices, {} regions ({} rigid, {} deformable), {} joints, \
         animation {:?} {:.1} s in {} keys, {} bytes (generated in {:.0} ms)",
        output.display(),
        mannequin.mesh.triangle_count(),
        mannequin.mesh.vertex_count(),
        mannequin.regions.len(),
        rigid,
        mannequin.regions.len() - rigid,
        mannequin.joints.len(),
        mannequin.animation.name,
        mannequin.animation.duration(),
        mannequin.animation.times.len(),
        glb.len(),
        generate_ms
    );
    Ok(())
}
