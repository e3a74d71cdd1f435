//! `aslod info`: a mesh's counts, progressive sequence and memory use, or a `.mrm` file's sections.

use crate::bake::max_triangles;
use crate::{CliResult, build, load};
use bevy_aslod::mesh::LoadLimits;
use bevy_aslod::mrm;
use bevy_aslod::multires::indexed_mesh_bytes;
use std::path::Path;
use std::time::Instant;

/// `info` for a `.mrm` file: its sections, then what it holds (read and checked).
fn info_mrm(input: &Path) -> CliResult {
    // The CLI reads within the default limits, as every loader does.
    let bytes = LoadLimits::default().read_file(input)?;
    let kind = mrm::kind(&bytes)?;
    let version = u32::from_le_bytes(bytes[8..12].try_into()?);
    println!(
        "{} ({} bytes, format version {version})",
        input.display(),
        bytes.len()
    );
    for (tag, length) in mrm::sections(&bytes)? {
        println!("  {tag:<4} {length:>12} bytes");
    }
    let start = Instant::now();
    if kind == mrm::MrmKind::Progressive {
        let pm = mrm::read_progressive(&bytes)?;
        println!(
            "  triangles {} / vertices {}, levels {} (base mesh {} triangles), view data {}; read in {:.1} ms",
            pm.max_triangles(),
            pm.vertices().vertex_count(),
            pm.level_count(),
            pm.min_triangles(),
            if pm.has_view_data() { "yes" } else { "no" },
            start.elapsed().as_secs_f64() * 1e3
        );
        return Ok(());
    }
    let file = mrm::read(&bytes)?;
    let read_ms = start.elapsed().as_secs_f64() * 1e3;
    let b = &file.build;
    println!(
        "  from {} (FNV-1a {:016x}), regions {}, by {}; read in {read_ms:.1} ms",
        b.source_name, b.source_hash, b.partition, b.writer
    );
    for (key, m) in &file.meshes {
        let skin = m.skin.as_ref().map_or("no skin".to_owned(), |s| {
            format!("skinned, {} joints", s.inverse_bindposes.len())
        });
        println!(
            "  {key}: {} vertices, {} regions, {} to {} triangles, {skin}, view data {}",
            m.regions.vertex_count(),
            m.regions.regions().len(),
            m.regions
                .regions()
                .iter()
                .map(|r| r.min_triangles())
                .sum::<usize>(),
            max_triangles(m),
            if m.variable.is_some() { "yes" } else { "no" },
        );
    }
    for (name, length) in mrm::entry_sections(&bytes)? {
        println!("    {name:<28} {length:>12} bytes");
    }
    Ok(())
}

pub(crate) fn info(input: &Path) -> CliResult {
    if input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mrm"))
    {
        return info_mrm(input);
    }
    let is_gltf = input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"));
    // A glTF scene: how many mesh primitives it places, and how many copies nodes place
    // through `EXT_mesh_gpu_instancing` (each one is in the mesh, as a viewer draws it).
    let (mesh, placed) = if is_gltf {
        let import = bevy_aslod::mesh::load_gltf(input)?;
        let placed = (import.primitives, import.gpu_instances);
        (import.mesh, Some(placed))
    } else {
        (load(input)?, None)
    };
    let start = Instant::now();
    let pm = build(&mesh)?;
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let source = indexed_mesh_bytes(&mesh);
    let ours = pm.memory_bytes();
    println!("{}", input.display());
    println!(
        "  triangles {} / vertices {}",
        mesh.triangle_count(),
        mesh.vertex_count()
    );
    if let Some((primitives, gpu_instances)) = placed {
        println!(
            "  placed primitives {primitives} (GPU instances, EXT_mesh_gpu_instancing: {gpu_instances})"
        );
    }
    println!(
        "  levels {} (base mesh {} triangles, base error {:.5} of the diagonal)",
        pm.level_count(),
        pm.min_triangles(),
        pm.level_error(pm.level_count() - 1)
    );
    println!("  build {build_ms:.1} ms");
    let t = mesh.triangle_count() as f64;
    println!(
        "  memory {} bytes = {:.1} bytes/triangle ({:.2}x the indexed mesh: {:.1} bytes/triangle)",
        ours,
        ours as f64 / t,
        ours as f64 / source as f64,
        source as f64 / t
    );
    Ok(())
}
