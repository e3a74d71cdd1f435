//! `aslod bake`: build multiresolution assets and write them as a `.mrm` file.

use crate::{CliResult, build_with, load, parse_cut};
use bevy_aslod::mesh::LoadLimits;
use bevy_aslod::mrm;
use bevy_aslod::multires::BuildOptions;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub(crate) struct BakeArgs {
    /// Input mesh (.obj, .ply, .gltf, .glb).
    input: PathBuf,
    /// Output `.mrm` file.
    #[arg(short, long)]
    output: PathBuf,
    /// How unskinned meshes are cut into regions: `single`, `grid:NxM` (ground plane) or
    /// `clusters:K`.
    #[arg(long, default_value = "single")]
    regions: String,
    /// Add the whole mesh's view-dependent refinement data (for `ViewDependent` models;
    /// about doubles the file).
    #[arg(long)]
    view: bool,
    /// δ of skinned primitives: a vertex whose dominant weight is at least 1 − δ is rigid.
    #[arg(long, default_value_t = bevy_aslod::skin::DEFAULT_RIGID_DELTA)]
    rigid_delta: f32,
    /// Write the whole (flattened) input as one progressive mesh instead (the version 1
    /// layout `aslod info` and `mrm::read_progressive` read), with view data.
    #[arg(long)]
    progressive: bool,
}

pub(crate) fn bake(args: &BakeArgs) -> CliResult {
    use bevy_aslod::mrm::{BakedMesh, BuildInfo, MrmFile};
    let start = Instant::now();
    if args.progressive {
        let mesh = load(&args.input)?;
        let pm = build_with(&mesh, &BuildOptions::default().with_view_dependent(true))?;
        let bytes = mrm::write_progressive(&pm);
        std::fs::write(&args.output, &bytes)?;
        println!(
            "{}: one progressive mesh, {} triangles, {} levels, built in {:.0} ms; {} bytes ({:.1} bytes/triangle)",
            args.output.display(),
            pm.max_triangles(),
            pm.level_count(),
            start.elapsed().as_secs_f64() * 1e3,
            bytes.len(),
            bytes.len() as f64 / pm.max_triangles().max(1) as f64
        );
        return Ok(());
    }
    let source = LoadLimits::default().read_file(&args.input)?;
    let gltf = args
        .input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"));
    let cut = parse_cut(&args.regions)?;
    let options = BuildOptions::default().with_view_dependent(args.view);
    let bar = ProgressBar::new_spinner();
    if std::io::stderr().is_terminal() {
        bar.set_style(ProgressStyle::with_template(
            "baking {spinner} {pos} done, {msg}",
        )?);
        bar.enable_steady_tick(std::time::Duration::from_millis(120));
    } else {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let meshes = if gltf {
        let mut first = true;
        mrm::bake_gltf(
            &args.input,
            &|mesh| cut.partition(mesh),
            &options,
            args.rigid_delta,
            &mut |key| {
                if !std::mem::take(&mut first) {
                    bar.inc(1);
                }
                bar.set_message(key.to_owned());
            },
        )?
    } else {
        let mesh = load(&args.input)?;
        bar.set_message(format!("{} triangles", mesh.triangle_count()));
        let baked = BakedMesh::build(&mesh, &cut.partition(&mesh)?, &options)?;
        vec![("Mesh0/Primitive0".to_owned(), baked)]
    };
    bar.finish_and_clear();
    let any_skin = meshes.iter().any(|(_, m)| m.skin.is_some());
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let file = MrmFile {
        build: BuildInfo {
            source_name: args
                .input
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            source_hash: mrm::source_hash(&source),
            partition: if any_skin {
                format!("{} (unskinned), by influence (skinned)", args.regions)
            } else {
                args.regions.clone()
            },
            writer: format!("aslod bake {}", env!("CARGO_PKG_VERSION")),
            rigid_delta: any_skin.then_some(args.rigid_delta),
            options,
        },
        meshes,
    };
    let bytes = mrm::write(&file);
    std::fs::write(&args.output, &bytes)?;
    let triangles: usize = file.meshes.iter().map(|(_, m)| max_triangles(m)).sum();
    println!(
        "{}: {} assets, {} triangles, built in {build_ms:.0} ms; {} bytes ({:.1} bytes/triangle)",
        args.output.display(),
        file.meshes.len(),
        triangles,
        bytes.len(),
        bytes.len() as f64 / triangles.max(1) as f64
    );
    Ok(())
}

pub(crate) fn max_triangles(m: &bevy_aslod::mrm::BakedMesh) -> usize {
    m.regions.regions().iter().map(|r| r.max_triangles()).sum()
}

#[cfg(test)]
mod tests {
    use super::bake;
    use crate::info::info;
    use crate::{Cli, Command};
    use bevy_aslod::mrm;
    use clap::Parser;

    #[test]
    fn bake_writes_a_file_that_info_and_the_reader_accept() {
        let cow = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shared/testdata/meshes/cow.obj"
        );
        let out = std::env::temp_dir().join(format!("aslod-bake-{}.mrm", std::process::id()));
        let run = |extra: &[&str]| {
            let mut argv = vec!["aslod", "bake", cow, "-o", out.to_str().unwrap()];
            argv.extend_from_slice(extra);
            let Command::Bake(args) = Cli::parse_from(argv).command else {
                panic!("parsed as bake");
            };
            bake(&args).unwrap();
            info(&out).unwrap();
            std::fs::read(&out).unwrap()
        };
        let pm = mrm::read_progressive(&run(&["--progressive"])).unwrap();
        assert!(pm.has_view_data());
        assert_eq!(pm.max_triangles(), 5804);
        let file = mrm::read(&run(&["--regions", "clusters:8", "--view"])).unwrap();
        let (key, baked) = &file.meshes[0];
        assert_eq!(key, "Mesh0/Primitive0");
        assert!(baked.regions.regions().len() > 4 && baked.variable.is_some());
        assert_eq!(file.build.partition, "clusters:8");
        let source = std::fs::read(cow).unwrap();
        assert_eq!(file.build.source_hash, mrm::source_hash(&source));
        // A glTF scene: one asset per primitive, the skinned ones with their joints' names.
        let robot = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shared/testdata/characters/RobotExpressive.glb"
        );
        let out_robot = out.with_extension("robot.mrm");
        let cli = Cli::parse_from(["aslod", "bake", robot, "-o", out_robot.to_str().unwrap()]);
        let Command::Bake(args) = cli.command else {
            panic!("parsed as bake");
        };
        bake(&args).unwrap();
        let file = mrm::read(&std::fs::read(&out_robot).unwrap()).unwrap();
        assert!(file.meshes.len() > 1);
        let skinned = file.meshes.iter().filter_map(|(_, m)| m.skin.as_ref());
        assert!(skinned.clone().count() > 0);
        assert!(
            skinned
                .clone()
                .all(|s| s.joint_names.iter().any(|n| !n.is_empty()))
        );
        std::fs::remove_file(&out_robot).ok();
        // A normal-mapped glTF without tangents: the baked asset keeps the tangents the
        // importer makes, in every region's table.
        let bottle = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shared/testdata/textured/WaterBottle.glb"
        );
        let out_bottle = out.with_extension("bottle.mrm");
        let cli = Cli::parse_from(["aslod", "bake", bottle, "-o", out_bottle.to_str().unwrap()]);
        let Command::Bake(args) = cli.command else {
            panic!("parsed as bake");
        };
        bake(&args).unwrap();
        let file = mrm::read(&std::fs::read(&out_bottle).unwrap()).unwrap();
        assert!(!file.meshes.is_empty());
        for (key, baked) in &file.meshes {
            for region in baked.regions.regions() {
                let v = region.progressive_mesh().vertices();
                assert!(
                    v.tangents.is_some() && v.uvs.is_some(),
                    "{key}: tangents and UVs"
                );
            }
        }
        std::fs::remove_file(&out_bottle).ok();
        std::fs::write(&out, b"ASLODMRM").unwrap();
        assert!(info(&out).unwrap_err().to_string().contains("header"));
        std::fs::remove_file(&out).ok();
    }
}
