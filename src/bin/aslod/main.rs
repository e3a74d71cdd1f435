//! `aslod`: build, inspect and compare progressive meshes from the command line.

mod bake;
mod compare;
mod extract;
mod info;
mod mannequin;

use bake::BakeArgs;
use bevy_aslod::mesh::IndexedMesh;
use bevy_aslod::multires::{BuildOptions, ProgressiveMesh};
use bevy_aslod::regions::{GridPlane, Partition};
use clap::{Parser, Subcommand};
use compare::CompareArgs;
use extract::ViewArgs;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "aslod", version, about = "Progressive meshes for bevy_aslod")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write the level with at most N triangles (or the coarsest within an error, or the
    /// view-dependent level seen from an eye) as OBJ.
    #[command(group(clap::ArgGroup::new("level").required(true).args(["triangles", "error", "eye", "counts"])))]
    Extract {
        /// Input mesh (.obj, .ply, .gltf, .glb).
        input: PathBuf,
        /// Triangle count to reach (at most).
        #[arg(long, conflicts_with = "error")]
        triangles: Option<usize>,
        /// Error bound, relative to the bounding-box diagonal (not with `--regions`).
        #[arg(long, conflicts_with = "regions")]
        error: Option<f32>,
        /// Output OBJ file.
        #[arg(short, long)]
        output: PathBuf,
        /// Cut the mesh into regions first: `grid:NxM` (over the XZ plane) or `clusters:K`.
        /// Each region's triangles go into an OBJ group of their own.
        #[arg(long)]
        regions: Option<String>,
        /// Triangle count of each region, in region order (instead of `--triangles` spread
        /// evenly over the regions).
        #[arg(
            long,
            value_delimiter = ',',
            requires = "regions",
            conflicts_with = "triangles"
        )]
        counts: Option<Vec<usize>>,
        #[command(flatten)]
        view: ViewArgs,
    },
    /// Compare our progressive mesh with meshoptimizer: build time and error per ratio.
    Compare(CompareArgs),
    /// Print a mesh's counts, its progressive sequence and its memory use; for a `.mrm`
    /// file, its sections and their sizes.
    Info {
        /// Input mesh (.obj, .ply, .gltf, .glb) or baked file (.mrm).
        input: PathBuf,
    },
    /// Build multiresolution assets and write them as a `.mrm` file the plugin loads without
    /// building: an OBJ or PLY as one asset (key `Mesh0/Primitive0`), a glTF scene as one
    /// asset per triangle primitive under Bevy's label (`Mesh{m}/Primitive{p}`), skinned
    /// primitives cut by influence.
    Bake(BakeArgs),
    /// Generate the procedural mannequin (ASLOD section 7): a skinned, animated binary glTF
    /// with 10 rigid and 9 deformable regions and the "Aerobics" loop.
    Mannequin {
        /// Output .glb file.
        #[arg(short, long, default_value = "assets/mannequin.glb")]
        output: PathBuf,
        /// Polygonising grid cell in metres; triangles grow as its inverse square
        /// (default: about 30,000 triangles).
        #[arg(long)]
        cell_size: Option<f32>,
    },
}

/// Writes the library's log records (importer warnings, say) to standard error, at the level
/// `ASLOD_LOG` names (`error`, `warn`, `info`, `debug` or `trace`; `warn` by default).
struct StderrLog;

impl log::Log for StderrLog {
    fn enabled(&self, metadata: &log::Metadata<'_>) -> bool {
        metadata.level() <= log::max_level()
    }

    fn log(&self, record: &log::Record<'_>) {
        if self.enabled(record.metadata()) {
            eprintln!(
                "aslod: {}: {}",
                record.level().as_str().to_lowercase(),
                record.args()
            );
        }
    }

    fn flush(&self) {}
}

fn install_logger() {
    static LOGGER: StderrLog = StderrLog;
    let level = std::env::var("ASLOD_LOG")
        .ok()
        .and_then(|l| l.parse::<log::LevelFilter>().ok())
        .unwrap_or(log::LevelFilter::Warn);
    if log::set_logger(&LOGGER).is_ok() {
        log::set_max_level(level);
    }
}

fn main() -> ExitCode {
    install_logger();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Extract {
            input,
            output,
            view: view @ ViewArgs { eye: Some(_), .. },
            ..
        } => extract::extract_view(&input, &view, &output),
        Command::Extract {
            input,
            triangles,
            output,
            regions: Some(spec),
            counts,
            ..
        } => extract::extract_regions(&input, &spec, triangles, counts, &output).map(|_| ()),
        Command::Extract {
            input,
            triangles,
            error,
            output,
            ..
        } => extract::extract(&input, triangles, error, &output),
        Command::Compare(args) => compare::compare(&args),
        Command::Info { input } => info::info(&input),
        Command::Bake(args) => bake::bake(&args),
        Command::Mannequin { output, cell_size } => mannequin::mannequin(&output, cell_size),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

type CliResult = Result<(), Box<dyn std::error::Error>>;

fn load(input: &Path) -> Result<IndexedMesh, Box<dyn std::error::Error>> {
    let (mesh, report) = IndexedMesh::load(input)?;
    if report.degenerate_triangles_dropped > 0 {
        eprintln!(
            "note: dropped {} degenerate triangles",
            report.degenerate_triangles_dropped
        );
    }
    Ok(mesh)
}

/// Builds with a progress bar when stderr is a terminal.
fn build(mesh: &IndexedMesh) -> Result<ProgressiveMesh, Box<dyn std::error::Error>> {
    build_with(mesh, &BuildOptions::default())
}

/// [`build`] with options.
fn build_with(
    mesh: &IndexedMesh,
    options: &BuildOptions,
) -> Result<ProgressiveMesh, Box<dyn std::error::Error>> {
    let bar = if std::io::stderr().is_terminal() {
        let bar = ProgressBar::new(mesh.triangle_count() as u64);
        bar.set_style(
            ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} triangles removed")?
                .progress_chars("=> "),
        );
        bar.set_message("building");
        Some(bar)
    } else {
        None
    };
    let pm = ProgressiveMesh::build_with(mesh, options, None, &mut |done, _| {
        if let Some(bar) = &bar {
            bar.set_position(done as u64);
        }
    })?;
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    Ok(pm)
}

/// How a mesh is cut into regions: `single`, `grid:NxM` (ground plane) or `clusters:K`.
#[derive(Clone, Copy)]
enum Cut {
    Single,
    Grid(usize, usize),
    Clusters(usize),
}

impl Cut {
    fn partition(self, mesh: &IndexedMesh) -> Result<Partition, bevy_aslod::regions::RegionError> {
        match self {
            Self::Single => Partition::grid(mesh, GridPlane::XZ, 1, 1),
            Self::Grid(nx, ny) => Partition::grid(mesh, GridPlane::XZ, nx, ny),
            Self::Clusters(k) => Partition::clusters(mesh, k),
        }
    }
}

/// Parses a [`Cut`].
fn parse_cut(spec: &str) -> Result<Cut, Box<dyn std::error::Error>> {
    let bad = || format!("bad --regions {spec:?}: expected single, grid:NxM or clusters:K");
    if spec == "single" {
        return Ok(Cut::Single);
    }
    let (kind, arg) = spec.split_once(':').ok_or_else(bad)?;
    Ok(match kind {
        "grid" => {
            let (nx, ny) = arg.split_once('x').ok_or_else(bad)?;
            Cut::Grid(nx.parse()?, ny.parse()?)
        }
        "clusters" => Cut::Clusters(arg.parse()?),
        _ => return Err(bad().into()),
    })
}

/// Parses `grid:NxM` or `clusters:K` and cuts `mesh` so.
fn partition(mesh: &IndexedMesh, spec: &str) -> Result<Partition, Box<dyn std::error::Error>> {
    Ok(parse_cut(spec)?.partition(mesh)?)
}
