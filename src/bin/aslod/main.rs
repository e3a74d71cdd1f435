//! `aslod`: build, inspect and compare progressive meshes from the command line.

use bevy_aslod::distance::{Distance, DistanceOptions, MeshRef, mesh_distance};
use bevy_aslod::mannequin::{MannequinOptions, generate};
use bevy_aslod::mesh::{IndexedMesh, write_obj, write_obj_groups};
use bevy_aslod::mrm;
use bevy_aslod::multires::{
    BuildOptions, CollapseOperator, PolygonCache, ProgressiveMesh, indexed_mesh_bytes,
};
use bevy_aslod::refine::{self, Criteria, ScreenSpaceError, VariableMesh, View};
use bevy_aslod::regions::{GridPlane, Partition, RegionCaches, RegionMesh};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::{BufWriter, IsTerminal};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use glam::{Quat, Vec3};

#[derive(Parser)]
#[command(name = "aslod", version, about = "Progressive meshes for bevy_aslod")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Args)]
struct BakeArgs {
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

#[derive(Subcommand)]
enum Command {
    /// Write the level with at most N triangles (or the coarsest within an error, or the
    /// view-dependent level seen from an eye) as OBJ.
    #[command(group(clap::ArgGroup::new("level").required(true).args(["triangles", "error", "eye"])))]
    Extract {
        /// Input mesh (.obj, .ply, .gltf, .glb).
        input: PathBuf,
        /// Triangle count to reach (at most).
        #[arg(long, conflicts_with = "error")]
        triangles: Option<usize>,
        /// Error bound, relative to the bounding-box diagonal.
        #[arg(long)]
        error: Option<f32>,
        /// Output OBJ file.
        #[arg(short, long)]
        output: PathBuf,
        /// Cut the mesh into regions first: `grid:NxM` (over the XZ plane) or `clusters:K`.
        /// Each region's triangles go into an OBJ group of their own.
        #[arg(long)]
        regions: Option<String>,
        /// Triangle count of each region, in region order (default: `--triangles` spread
        /// evenly over the regions).
        #[arg(long, value_delimiter = ',', requires = "regions")]
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

/// The view-dependent mode of `extract` (the `refine` module).
#[derive(clap::Args)]
struct ViewArgs {
    /// View-dependent level seen from this eye, `X,Y,Z` in the mesh's coordinates.
    #[arg(long, value_delimiter = ',', value_name = "X,Y,Z", allow_hyphen_values = true, conflicts_with_all = ["triangles", "error", "regions"])]
    eye: Option<Vec<f32>>,
    /// Where the eye looks: a direction `X,Y,Z` (default: towards the mesh's centre).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "X,Y,Z",
        allow_hyphen_values = true,
        requires = "eye"
    )]
    look: Option<Vec<f32>>,
    /// Screen-space error tolerance in pixels (the `screen` criterion).
    #[arg(
        long,
        default_value_t = 1.0,
        allow_negative_numbers = true,
        requires = "eye"
    )]
    tolerance: f32,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 45.0, requires = "eye")]
    fov: f32,
    /// Viewport size in pixels, `WxH`.
    #[arg(long, default_value = "800x600", requires = "eye")]
    viewport: String,
    /// The criteria, any of `frustum`, `back-facing`, `screen`, `silhouette`.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "frustum,back-facing,screen",
        requires = "eye"
    )]
    criteria: Vec<String>,
}

#[derive(clap::Args)]
struct CompareArgs {
    /// Input mesh (.obj, .ply, .gltf, .glb).
    input: PathBuf,
    /// Triangle ratios to compare at.
    #[arg(long, value_delimiter = ',', default_value = "0.5,0.1,0.02")]
    ratios: Vec<f64>,
    /// Timing runs per method; the median is reported.
    #[arg(long, default_value_t = 5)]
    runs: usize,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Also measure the cost of partitioning: the same mesh cut into these regions
    /// (`grid:NxM` or `clusters:K`), each region at the same ratio.
    #[arg(long)]
    regions: Option<String>,
    /// Also compare on this many copies of the mesh turned by pseudo-random rotations (seeds
    /// 1 to N), and print the geometric mean of the ratios: which collapse wins a near-tie
    /// depends on the rounding, so one orientation is one draw.
    #[arg(long, default_value_t = 0)]
    rotations: usize,
    /// Our build's `BuildOptions::local_weight` (default: the crate's default).
    #[arg(long)]
    local_weight: Option<f64>,
    /// Our build's `BuildOptions::weight_exponent` (default: the crate's default).
    #[arg(long)]
    weight_exponent: Option<f64>,
    /// Our build's collapse operator: `edge` or Hoxha's `triangle` (default: the crate's).
    #[arg(long, value_parser = parse_operator)]
    operator: Option<CollapseOperator>,
}

fn parse_operator(s: &str) -> Result<CollapseOperator, String> {
    match s {
        "edge" => Ok(CollapseOperator::Edge),
        "triangle" => Ok(CollapseOperator::Triangle),
        _ => Err(format!("{s:?}: expected edge or triangle")),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Extract {
            input,
            output,
            view: view @ ViewArgs { eye: Some(_), .. },
            ..
        } => extract_view(&input, &view, &output),
        Command::Extract {
            input,
            triangles,
            output,
            regions: Some(spec),
            error: _,
            counts,
            ..
        } => extract_regions(&input, &spec, triangles, counts, &output).map(|_| ()),
        Command::Extract {
            input,
            triangles,
            error,
            output,
            ..
        } => extract(&input, triangles, error, &output),
        Command::Compare(args) => compare(&args),
        Command::Info { input } => info(&input),
        Command::Bake(args) => bake(&args),
        Command::Mannequin { output, cell_size } => mannequin(&output, cell_size),
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

fn extract(input: &Path, triangles: Option<usize>, error: Option<f32>, output: &Path) -> CliResult {
    let mesh = load(input)?;
    let pm = build(&mesh)?;
    let mut cache = PolygonCache::new(&pm);
    let reached = match (triangles, error) {
        (Some(n), _) => cache.set_triangle_count(&pm, n),
        (None, Some(e)) => cache.set_max_error(&pm, e),
        (None, None) => unreachable!("clap requires one of them"),
    };
    let mut out = pm.vertices().clone();
    out.indices = cache.indices().to_vec();
    let file = std::fs::File::create(output)?;
    write_obj(&out, &mut BufWriter::new(file))?;
    eprintln!(
        "wrote {} triangles (level {}, error {:.6} of the diagonal) to {}",
        reached,
        cache.level(),
        pm.level_error(cache.level()),
        output.display()
    );
    Ok(())
}

/// Writes the view-dependent level seen from `--eye` (frustum, back faces and screen-space
/// error by default).
fn extract_view(input: &Path, args: &ViewArgs, output: &Path) -> CliResult {
    let mesh = load(input)?;
    let (lo, hi) = mesh.bounds().ok_or("the mesh is empty")?;
    let vector = |name: &str, v: &[f32]| match v {
        &[x, y, z] => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("--{name} takes three numbers, X,Y,Z")),
    };
    let eye = vector("eye", args.eye.as_deref().unwrap_or_default())?;
    let look = match args.look.as_deref() {
        Some(look) => vector("look", look)?,
        None => (lo + hi) * 0.5 - eye,
    };
    let (width, height) = args
        .viewport
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse::<f32>().ok()?, h.parse::<f32>().ok()?)))
        .ok_or_else(|| format!("bad --viewport {:?}: expected WxH", args.viewport))?;
    let up = if look.cross(Vec3::Y).length() > 1e-3 * look.length() {
        Vec3::Y
    } else {
        Vec3::Z
    };
    let view = View::perspective(
        eye,
        look,
        up,
        args.fov.to_radians(),
        width / height,
        1e-4 * (hi - lo).length(),
        height,
    )?;
    let mut criteria = Criteria::default();
    for c in &args.criteria {
        criteria = match c.as_str() {
            "frustum" => criteria.with_frustum(true),
            "back-facing" => criteria.with_back_facing(true),
            "screen" => criteria.with_screen_space(Some(ScreenSpaceError::new(args.tolerance)?)),
            "silhouette" => criteria.with_silhouette(true),
            other => return Err(format!("unknown criterion {other:?}").into()),
        };
    }
    let pm = build_with(&mesh, &BuildOptions::default().with_view_dependent(true))?;
    let vm = VariableMesh::new(pm)?;
    let mut indices = Vec::new();
    let start = Instant::now();
    let stats = refine::extract(&vm, &criteria, &view, &mut indices)?;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let mut out = vm.mesh().vertices().clone();
    out.indices = indices;
    let file = std::fs::File::create(output)?;
    write_obj(&out, &mut BufWriter::new(file))?;
    eprintln!(
        "wrote {} of {} triangles ({} collapses performed, extracted in {ms:.2} ms) to {}",
        stats.triangles,
        vm.mesh().max_triangles(),
        stats.performed,
        output.display()
    );
    Ok(())
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

/// Builds the regions, sets each to its count, writes the assembled mesh with one OBJ group
/// per region, and returns the assembled triangles.
fn extract_regions(
    input: &Path,
    spec: &str,
    triangles: Option<usize>,
    counts: Option<Vec<usize>>,
    output: &Path,
) -> Result<Vec<u32>, Box<dyn std::error::Error>> {
    let mesh = load(input)?;
    let regions = RegionMesh::build(&mesh, &partition(&mesh, spec)?, &BuildOptions::default())?;
    let k = regions.regions().len();
    let counts = match (counts, triangles) {
        (Some(c), _) if c.len() == k => c,
        (Some(c), _) => {
            return Err(format!("--counts has {} entries for {k} regions", c.len()).into());
        }
        (None, Some(n)) => (0..k).map(|r| n / k + usize::from(r < n % k)).collect(),
        (None, None) => return Err("give --triangles or --counts".into()),
    };
    let (assembled, groups) = assemble(&regions, &counts);
    let mut out = mesh.clone();
    out.indices = assembled.clone();
    let file = std::fs::File::create(output)?;
    write_obj_groups(&out, &groups, &mut BufWriter::new(file))?;
    eprintln!(
        "wrote {} triangles in {k} regions to {}",
        assembled.len() / 3,
        output.display()
    );
    Ok(assembled)
}

/// Every region at its count, assembled in source-mesh indices, with a group per region.
fn assemble(
    regions: &RegionMesh,
    counts: &[usize],
) -> (Vec<u32>, Vec<(String, std::ops::Range<usize>)>) {
    let mut caches = RegionCaches::new(regions);
    for (r, &n) in counts.iter().enumerate() {
        caches.set_triangle_count(regions, r, n);
    }
    let (mut all, mut groups, mut part) = (Vec::new(), Vec::new(), Vec::new());
    for r in 0..regions.regions().len() {
        let start = all.len() / 3;
        caches.write_global_indices(regions, r, &mut part);
        all.extend_from_slice(&part);
        groups.push((format!("region_{r}"), start..all.len() / 3));
    }
    (all, groups)
}

fn bake(args: &BakeArgs) -> CliResult {
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
    let source = std::fs::read(&args.input)?;
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

fn max_triangles(m: &bevy_aslod::mrm::BakedMesh) -> usize {
    m.regions.regions().iter().map(|r| r.max_triangles()).sum()
}

/// `info` for a `.mrm` file: its sections, then what it holds (read and checked).
fn info_mrm(input: &Path) -> CliResult {
    let bytes = std::fs::read(input)?;
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

fn info(input: &Path) -> CliResult {
    if input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mrm"))
    {
        return info_mrm(input);
    }
    let mesh = load(input)?;
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

fn mannequin(output: &Path, cell_size: Option<f32>) -> CliResult {
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

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time_ms<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut times = Vec::with_capacity(runs);
    let mut last = None;
    for _ in 0..runs {
        let start = Instant::now();
        last = Some(f());
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    (median(times), last.expect("runs >= 1"))
}

fn meshopt_simplify(mesh: &IndexedMesh, target_triangles: usize) -> Vec<u32> {
    let bytes: Vec<u8> = mesh
        .positions
        .iter()
        .flat_map(|p| p.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let adapter =
        meshopt::VertexDataAdapter::new(&bytes, 12, 0).expect("12-byte stride divides the data");
    meshopt::simplify(
        &mesh.indices,
        &adapter,
        3 * target_triangles,
        f32::MAX,
        meshopt::SimplifyOptions::None,
        None,
    )
}

/// Ours against meshopt at one ratio over rotated copies of a mesh.
struct RotatedRow {
    ratio: f64,
    /// Geometric means of ours / meshopt's Hausdorff and RMS distances.
    hausdorff_ratio: f64,
    rms_ratio: f64,
    /// Copies where ours is at most meshopt's.
    hausdorff_at_most: usize,
    rms_at_most: usize,
    /// The most [`pinched_edges`] in one of our copies, and the fewest and the most in one of
    /// meshoptimizer's.
    ours_pinched_max: usize,
    meshopt_pinched: (usize, usize),
}

/// A pseudo-random rotation for `seed` (xorshift64: an axis, then an angle).
fn rotation(seed: u64) -> Quat {
    let mut x = 0x9E37_79B9_7F4A_7C15u64.wrapping_mul(seed + 1);
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f32 / (1u64 << 53) as f32
    };
    let axis = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5).normalize_or(Vec3::Y);
    Quat::from_axis_angle(axis, next() * std::f32::consts::TAU)
}

/// Ours (built with `options`) against meshopt on `copies` copies of `mesh` turned by
/// [`rotation`]s 1 to `copies`, per ratio.
fn compare_rotated(
    mesh: &IndexedMesh,
    ratios: &[f64],
    copies: usize,
    options: &BuildOptions,
) -> Result<Vec<RotatedRow>, Box<dyn std::error::Error>> {
    // ln of each ratio summed, and the copies at most 1, per ratio.
    let mut sums = vec![(0.0f64, 0.0f64, 0usize, 0usize); ratios.len()];
    // Pinched edges per ratio: our most, meshoptimizer's fewest and most.
    let mut pinched = vec![(0usize, usize::MAX, 0usize); ratios.len()];
    for seed in 1..=copies as u64 {
        let turn = rotation(seed);
        let mut turned = mesh.clone();
        for p in &mut turned.positions {
            *p = turn * *p;
        }
        if let Some(normals) = &mut turned.normals {
            for n in normals {
                *n = turn * *n;
            }
        }
        let pm = ProgressiveMesh::build(&turned, options)?;
        let mut cache = PolygonCache::new(&pm);
        for ((sum, pinch), &ratio) in sums.iter_mut().zip(&mut pinched).zip(ratios) {
            let target = ((ratio * mesh.triangle_count() as f64).round() as usize).max(1);
            let (_, ours, simplified, theirs) = distances_at(&turned, &pm, &mut cache, target);
            let theirs_pinched = pinched_edges(&turned.positions, &simplified);
            pinch.0 = pinch
                .0
                .max(pinched_edges(&pm.vertices().positions, cache.indices()));
            pinch.1 = pinch.1.min(theirs_pinched);
            pinch.2 = pinch.2.max(theirs_pinched);
            let h = quotient(ours.hausdorff, theirs.hausdorff);
            let r = quotient(ours.rms, theirs.rms);
            sum.0 += h.ln();
            sum.1 += r.ln();
            sum.2 += usize::from(h <= 1.0);
            sum.3 += usize::from(r <= 1.0);
        }
    }
    Ok(sums
        .iter()
        .zip(&pinched)
        .zip(ratios)
        .filter(|_| copies > 0)
        .map(
            |((&(h, r, hn, rn), &(ours, fewest, most)), &ratio)| RotatedRow {
                ratio,
                hausdorff_ratio: (h / copies as f64).exp(),
                rms_ratio: (r / copies as f64).exp(),
                hausdorff_at_most: hn,
                rms_at_most: rn,
                ours_pinched_max: ours,
                meshopt_pinched: (fewest, most),
            },
        )
        .collect())
}

/// Our level of at most `target` triangles (`pm`, moved there in `cache`) and meshopt's
/// simplification of `mesh` to `target`: each one's triangle count and distance to `mesh`,
/// and meshoptimizer's result itself.
fn distances_at(
    mesh: &IndexedMesh,
    pm: &ProgressiveMesh,
    cache: &mut PolygonCache,
    target: usize,
) -> (usize, Distance, Vec<u32>, Distance) {
    let options = DistanceOptions::default();
    let original = MeshRef::new(&mesh.positions, &mesh.indices);
    let ours_triangles = cache.set_triangle_count(pm, target);
    let ours = mesh_distance(
        original,
        MeshRef::new(&pm.vertices().positions, cache.indices()),
        &options,
    );
    let simplified = meshopt_simplify(mesh, target);
    let theirs = mesh_distance(
        original,
        MeshRef::new(&mesh.positions, &simplified),
        &options,
    );
    (ours_triangles, ours, simplified, theirs)
}

/// Edges shared by more than two triangles (positions welded by value): a surface pinched
/// into a non-manifold edge. Our levels never have one on a closed manifold input (the link
/// condition); meshoptimizer does not check for it.
fn pinched_edges(positions: &[Vec3], indices: &[u32]) -> usize {
    let weld = bevy_aslod::mesh::weld_positions(positions);
    let mut uses = std::collections::HashMap::new();
    for t in indices.chunks_exact(3) {
        for k in 0..3 {
            let (a, b) = (
                weld.remap[t[k] as usize],
                weld.remap[t[(k + 1) % 3] as usize],
            );
            *uses.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
        }
    }
    uses.values().filter(|&&n| n > 2).count()
}

/// `a / b` for distances: 1 when both are 0.
fn quotient(a: f32, b: f32) -> f64 {
    if a == b {
        1.0
    } else {
        f64::from(a) / f64::from(b)
    }
}

struct Row {
    ratio: f64,
    target: usize,
    ours_triangles: usize,
    ours: Distance,
    meshopt_triangles: usize,
    meshopt: Distance,
    /// [`pinched_edges`] of our level and of meshoptimizer's result.
    ours_pinched: usize,
    meshopt_pinched: usize,
}

fn compare(args: &CompareArgs) -> CliResult {
    let (input, ratios, json) = (args.input.as_path(), args.ratios.as_slice(), args.json);
    let (runs, regions_spec) = (args.runs.max(1), args.regions.as_deref());
    let mesh = load(input)?;
    let t = mesh.triangle_count();
    let smallest = ratios.iter().copied().fold(1.0f64, f64::min);
    let target_of = |r: f64| ((r * t as f64).round() as usize).max(1);
    let mut build_options = BuildOptions::default();
    if let Some(w) = args.local_weight {
        build_options.local_weight = w;
    }
    if let Some(e) = args.weight_exponent {
        build_options.weight_exponent = e;
    }
    if let Some(o) = args.operator {
        build_options.operator = o;
    }

    let (ours_ms, pm) = time_ms(runs, || ProgressiveMesh::build(&mesh, &build_options));
    let pm = pm?;
    let (meshopt_smallest_ms, _) = time_ms(runs, || meshopt_simplify(&mesh, target_of(smallest)));
    let (meshopt_1pc_ms, _) = time_ms(runs, || meshopt_simplify(&mesh, target_of(0.01)));

    let options = DistanceOptions::default();
    let original = MeshRef::new(&mesh.positions, &mesh.indices);
    let mut cache = PolygonCache::new(&pm);
    let mut rows = Vec::new();
    for &ratio in ratios {
        let target = target_of(ratio);
        let (ours_triangles, ours, simplified, meshopt) =
            distances_at(&mesh, &pm, &mut cache, target);
        rows.push(Row {
            ratio,
            target,
            ours_triangles,
            ours,
            meshopt_triangles: simplified.len() / 3,
            meshopt,
            ours_pinched: pinched_edges(&pm.vertices().positions, cache.indices()),
            meshopt_pinched: pinched_edges(&mesh.positions, &simplified),
        });
    }
    let source_bytes = indexed_mesh_bytes(&mesh);
    let ours_bytes = pm.memory_bytes();
    let rotated = compare_rotated(&mesh, ratios, args.rotations, &build_options)?;

    // The cost of partitioning: every region at the same ratio, against the whole mesh.
    let mut partitioned = Vec::new();
    if let Some(spec) = regions_spec {
        let regions = RegionMesh::build(&mesh, &partition(&mesh, spec)?, &build_options)?;
        for (row, &ratio) in rows.iter().zip(ratios) {
            let counts: Vec<usize> = regions
                .regions()
                .iter()
                .map(|r| (ratio * r.max_triangles() as f64).round() as usize)
                .collect();
            let (assembled, _) = assemble(&regions, &counts);
            let d = mesh_distance(
                original,
                MeshRef::new(&mesh.positions, &assembled),
                &options,
            );
            partitioned.push((assembled.len() / 3, d, row.ours));
        }
    }

    if json {
        let value = serde_json::json!({
            "input": input.display().to_string(),
            "triangles": t,
            "vertices": mesh.vertex_count(),
            "runs": runs,
            "build_ms": {
                "ours_full_sequence": ours_ms,
                "meshopt_smallest_ratio": meshopt_smallest_ms,
                "meshopt_1_percent": meshopt_1pc_ms,
                "ours_over_meshopt_1_percent": ours_ms / meshopt_1pc_ms,
            },
            "memory": {
                "indexed_mesh_bytes": source_bytes,
                "progressive_mesh_bytes": ours_bytes,
                "bytes_per_triangle": ours_bytes as f64 / t as f64,
                "ratio": ours_bytes as f64 / source_bytes as f64,
            },
            "partitioned": regions_spec.map(|spec| serde_json::json!({
                "regions": spec,
                "rows": partitioned.iter().zip(ratios).map(|((n, d, whole), ratio)| serde_json::json!({
                    "ratio": ratio,
                    "triangles": n,
                    "hausdorff": d.hausdorff,
                    "rms": d.rms,
                    "hausdorff_vs_whole": d.hausdorff / whole.hausdorff,
                    "rms_vs_whole": d.rms / whole.rms,
                })).collect::<Vec<_>>(),
            })),
            "rotated": (args.rotations > 0).then(|| serde_json::json!({
                "copies": args.rotations,
                "rows": rotated.iter().map(|r| serde_json::json!({
                    "ratio": r.ratio,
                    "hausdorff_ratio_geomean": r.hausdorff_ratio,
                    "rms_ratio_geomean": r.rms_ratio,
                    "hausdorff_at_most_meshopt": r.hausdorff_at_most,
                    "rms_at_most_meshopt": r.rms_at_most,
                    "ours_pinched_edges_max": r.ours_pinched_max,
                    "meshopt_pinched_edges_min": r.meshopt_pinched.0,
                    "meshopt_pinched_edges_max": r.meshopt_pinched.1,
                })).collect::<Vec<_>>(),
            })),
            "ratios": rows.iter().map(|r| serde_json::json!({
                "ratio": r.ratio,
                "target": r.target,
                "ours": {"triangles": r.ours_triangles, "hausdorff": r.ours.hausdorff, "rms": r.ours.rms, "pinched_edges": r.ours_pinched},
                "meshopt": {"triangles": r.meshopt_triangles, "hausdorff": r.meshopt.hausdorff, "rms": r.meshopt.rms, "pinched_edges": r.meshopt_pinched},
                "hausdorff_ratio": r.ours.hausdorff / r.meshopt.hausdorff,
                "rms_ratio": r.ours.rms / r.meshopt.rms,
            })).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }

    println!(
        "{}: {} triangles, {} vertices (median of {} runs)",
        input.display(),
        t,
        mesh.vertex_count(),
        runs
    );
    println!(
        "build: ours (all {} levels) {:.1} ms | meshopt to {:.0}% {:.1} ms | meshopt to 1% {:.1} ms | ours / meshopt 1% = {:.2}x",
        pm.level_count(),
        ours_ms,
        smallest * 100.0,
        meshopt_smallest_ms,
        meshopt_1pc_ms,
        ours_ms / meshopt_1pc_ms
    );
    println!(
        "memory: {:.1} bytes/triangle, {:.2}x the indexed mesh ({:.1} bytes/triangle)",
        ours_bytes as f64 / t as f64,
        ours_bytes as f64 / source_bytes as f64,
        source_bytes as f64 / t as f64
    );
    println!(
        "{:>6} {:>8} | {:>8} {:>10} {:>10} | {:>8} {:>10} {:>10} | {:>7} {:>7} | {:>7}",
        "ratio",
        "target",
        "ours",
        "hausdorff",
        "rms",
        "meshopt",
        "hausdorff",
        "rms",
        "H ratio",
        "RMS rat",
        "pinched"
    );
    for r in &rows {
        println!(
            "{:>6} {:>8} | {:>8} {:>10.6} {:>10.6} | {:>8} {:>10.6} {:>10.6} | {:>7.3} {:>7.3} | {:>7}",
            r.ratio,
            r.target,
            r.ours_triangles,
            r.ours.hausdorff,
            r.ours.rms,
            r.meshopt_triangles,
            r.meshopt.hausdorff,
            r.meshopt.rms,
            r.ours.hausdorff / r.meshopt.hausdorff,
            r.ours.rms / r.meshopt.rms,
            format!("{}/{}", r.ours_pinched, r.meshopt_pinched)
        );
    }
    println!("pinched: edges shared by more than two triangles (non-manifold), ours/meshopt");
    if let Some(spec) = regions_spec {
        println!("partitioned ({spec}), every region at the ratio, against the whole mesh:");
        println!(
            "{:>6} {:>8} {:>10} {:>10} | {:>9} {:>9}",
            "ratio", "tris", "hausdorff", "rms", "H vs one", "RMS vs one"
        );
        for ((n, d, whole), ratio) in partitioned.iter().zip(ratios) {
            println!(
                "{:>6} {:>8} {:>10.6} {:>10.6} | {:>9.3} {:>9.3}",
                ratio,
                n,
                d.hausdorff,
                d.rms,
                d.hausdorff / whole.hausdorff,
                d.rms / whole.rms
            );
        }
    }
    if !rotated.is_empty() {
        println!(
            "{} rotated copies: geometric mean of ours / meshopt, and copies at most 1:",
            args.rotations
        );
        println!(
            "{:>6} | {:>7} {:>7} | {:>7} {:>7} | {:>9}",
            "ratio", "H ratio", "RMS rat", "H <= 1", "RMS <= 1", "pinched"
        );
        for r in &rotated {
            println!(
                "{:>6} | {:>7.3} {:>7.3} | {:>7} {:>7} | {:>9}",
                r.ratio,
                r.hausdorff_ratio,
                r.rms_ratio,
                format!("{}/{}", r.hausdorff_at_most, args.rotations),
                format!("{}/{}", r.rms_at_most, args.rotations),
                format!(
                    "{}/{}-{}",
                    r.ours_pinched_max, r.meshopt_pinched.0, r.meshopt_pinched.1
                )
            );
        }
        println!("pinched: our most in one copy / meshopt's fewest-most");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{Cli, Command, bake, extract_view, info, pinched_edges};
    use bevy_aslod::mesh::IndexedMesh;
    use bevy_aslod::mrm;
    use clap::Parser;
    use glam::Vec3;

    /// `aslod extract --eye` writes a view-dependent level: fewer triangles than the mesh,
    /// more with a smaller tolerance, and bad values are errors that name them.
    #[test]
    fn extract_with_an_eye_writes_a_view_dependent_level() {
        let cow = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shared/testdata/meshes/cow.obj"
        );
        let dir = std::env::temp_dir().join(format!("aslod-extract-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut counts = Vec::new();
        for tolerance in ["4", "0.5"] {
            let out = dir.join(format!("cow_{tolerance}.obj"));
            let cli = Cli::parse_from([
                "aslod",
                "extract",
                cow,
                "--eye",
                "-0.4,0.3,1.6",
                "--look",
                "0.4,-0.3,-1.6",
                "--tolerance",
                tolerance,
                "-o",
                out.to_str().unwrap(),
            ]);
            let Command::Extract { view, .. } = cli.command else {
                panic!("parsed as extract");
            };
            extract_view(cow.as_ref(), &view, &out).unwrap();
            counts.push(IndexedMesh::load(&out).unwrap().0.triangle_count());
        }
        assert!(counts[0] < counts[1] && counts[1] < 5804, "{counts:?}");
        let cli = Cli::parse_from([
            "aslod",
            "extract",
            cow,
            "--eye",
            "0,0,1",
            "--fov",
            "0",
            "-o",
            "unused.obj",
        ]);
        let Command::Extract { view, .. } = cli.command else {
            panic!("parsed as extract");
        };
        let error = extract_view(cow.as_ref(), &view, "unused.obj".as_ref()).unwrap_err();
        assert!(error.to_string().contains("field of view"), "{error}");
        assert!(
            Cli::try_parse_from([
                "aslod",
                "extract",
                cow,
                "--eye",
                "0,0,1",
                "--triangles",
                "5",
                "-o",
                "x.obj"
            ])
            .is_err()
        );
        std::fs::remove_dir_all(&dir).ok();
    }

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
        std::fs::write(&out, b"ASLODMRM").unwrap();
        assert!(info(&out).unwrap_err().to_string().contains("header"));
        std::fs::remove_file(&out).ok();
    }

    #[test]
    fn pinched_edges_counts_edges_of_more_than_two_triangles() {
        // A closed tetrahedron: every edge has two triangles.
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let tetrahedron = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
        assert_eq!(pinched_edges(&positions, &tetrahedron), 0);
        // Three triangles on the edge 0-1 (a fin), one of them through a copy of vertex 0 at
        // the same position (positions are welded by value).
        let mut positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::NEG_Y, Vec3::Z];
        positions.push(Vec3::ZERO);
        let fin = [0, 1, 2, 1, 0, 3, 5, 1, 4];
        assert_eq!(pinched_edges(&positions, &fin), 1);
    }
}
