//! `aslod compare`: our progressive mesh against meshoptimizer, in build time, memory and error.

use crate::extract::assemble;
use crate::{CliResult, load, partition};
use bevy_aslod::bounds::Obb;
use bevy_aslod::distance::{Distance, DistanceOptions, MeshRef, mesh_distance};
use bevy_aslod::mesh::IndexedMesh;
use bevy_aslod::multires::{
    BuildOptions, CollapseOperator, PolygonCache, ProgressiveMesh, indexed_mesh_bytes,
};
use bevy_aslod::regions::{ErrorCurves, MergedRoot, RegionMesh};
use glam::{Quat, Vec3};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub(crate) struct CompareArgs {
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
    /// With `--regions`, how the ratio's triangles are shared among the regions: `ratio`
    /// (each region at the ratio) or `error` (at equal error, every region seen alike from
    /// all sides: what the plugin's `RegionSplit::ScreenError` does).
    #[arg(long, default_value = "ratio", value_parser = ["ratio", "error"], requires = "regions")]
    split: String,
    /// With `--regions`, the merged root's share of the triangles
    /// (`BuildOptions::root_ratio`): below it the partitioned rows draw the whole model as one
    /// mesh, as the frontier would for a view of the whole model. `0` draws the regions alone.
    #[arg(long, default_value_t = 0.3, requires = "regions")]
    root: f32,
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
    /// Our build's `BuildOptions::normal_weight` (default: the crate's default).
    #[arg(long)]
    normal_weight: Option<f64>,
    /// Our build's `BuildOptions::uv_weight` (default: the crate's default).
    #[arg(long)]
    uv_weight: Option<f64>,
}

fn parse_operator(s: &str) -> Result<CollapseOperator, String> {
    match s {
        "edge" => Ok(CollapseOperator::Edge),
        "triangle" => Ok(CollapseOperator::Triangle),
        _ => Err(format!("{s:?}: expected edge or triangle")),
    }
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

/// meshoptimizer's `simplify` of `mesh` to `target_triangles` (positions only, seams kept as
/// its attribute-free default does).
fn meshopt_simplify(mesh: &IndexedMesh, target_triangles: usize) -> Vec<u32> {
    meshopt_simplify_with(mesh, target_triangles, meshopt::SimplifyOptions::None)
}

/// meshoptimizer's `simplify` with `options` (`Permissive`: its way past seams and
/// non-manifold walls, the peer where plain `simplify` is stuck).
fn meshopt_simplify_with(
    mesh: &IndexedMesh,
    target_triangles: usize,
    options: meshopt::SimplifyOptions,
) -> Vec<u32> {
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
        options,
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
    /// meshoptimizer's `simplify` with `Permissive`: its triangles and distance.
    permissive_triangles: usize,
    permissive: Distance,
}

pub(crate) fn compare(args: &CompareArgs) -> CliResult {
    let report = measure(args)?;
    if args.json {
        print_json(args, &report)
    } else {
        print_table(args, &report);
        Ok(())
    }
}

/// What [`compare`] measured, printed by [`print_json`] or [`print_table`].
struct Report {
    /// The input's triangles and vertices.
    triangles: usize,
    vertices: usize,
    /// Timing runs per method (at least 1).
    runs: usize,
    /// The smallest ratio (at most 1).
    smallest: f64,
    /// Our progressive mesh's levels.
    level_count: usize,
    /// Median build times: ours (the whole sequence), meshopt's to the smallest ratio and
    /// to 1%.
    ours_ms: f64,
    meshopt_smallest_ms: f64,
    meshopt_1pc_ms: f64,
    /// Memory of the indexed mesh and of our progressive mesh.
    source_bytes: usize,
    ours_bytes: usize,
    rows: Vec<Row>,
    rotated: Vec<RotatedRow>,
    /// Per ratio with `--regions`.
    partitioned: Vec<Partitioned>,
    /// With `--regions`: the regions' bytes, the root's, and the root's finest triangles.
    partition_sizes: PartitionSizes,
    coarsest: Coarsest,
}

/// A ratio with `--regions`: the assembled triangles, their distance to the mesh, and the
/// whole mesh's distance at that ratio.
/// Triangles, distance to the source, the whole mesh's at the same ratio, and whether the
/// merged root was drawn.
type Partitioned = (usize, Distance, Distance, bool);

/// The regions' bytes, the merged root's, and the root's triangles at its finest.
type PartitionSizes = (usize, usize, usize);

/// The default [`BuildOptions`] with `--local-weight`, `--weight-exponent`, `--operator`,
/// `--normal-weight` and `--uv-weight`.
fn build_options(args: &CompareArgs) -> BuildOptions {
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
    if let Some(w) = args.normal_weight {
        build_options.normal_weight = w;
    }
    if let Some(w) = args.uv_weight {
        build_options.uv_weight = w;
    }
    if args.regions.is_some() {
        build_options.root_ratio = args.root;
    }
    build_options
}

/// Builds ours and meshopt's (timed), then measures both at every ratio, on rotated copies
/// and against the partitioned mesh.
fn measure(args: &CompareArgs) -> Result<Report, Box<dyn std::error::Error>> {
    let (input, ratios) = (args.input.as_path(), args.ratios.as_slice());
    let (runs, regions_spec) = (args.runs.max(1), args.regions.as_deref());
    let mesh = load(input)?;
    let t = mesh.triangle_count();
    let smallest = ratios.iter().copied().fold(1.0f64, f64::min);
    let target_of = |r: f64| ((r * t as f64).round() as usize).max(1);
    let build_options = build_options(args);

    let (ours_ms, pm) = time_ms(runs, || ProgressiveMesh::build(&mesh, &build_options));
    let pm = pm?;
    let (meshopt_smallest_ms, _) = time_ms(runs, || meshopt_simplify(&mesh, target_of(smallest)));
    let (meshopt_1pc_ms, _) = time_ms(runs, || meshopt_simplify(&mesh, target_of(0.01)));

    let mut cache = PolygonCache::new(&pm);
    let mut rows = Vec::new();
    for &ratio in ratios {
        let target = target_of(ratio);
        let (ours_triangles, ours, simplified, meshopt) =
            distances_at(&mesh, &pm, &mut cache, target);
        let permissive = meshopt_simplify_with(&mesh, target, meshopt::SimplifyOptions::Permissive);
        rows.push(Row {
            permissive_triangles: permissive.len() / 3,
            permissive: mesh_distance(
                MeshRef::new(&mesh.positions, &mesh.indices),
                MeshRef::new(&mesh.positions, &permissive),
                &DistanceOptions::default(),
            ),
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
    let coarsest = Coarsest {
        ours: pm.min_triangles(),
        meshopt: meshopt_simplify(&mesh, 0).len() / 3,
        permissive: meshopt_simplify_with(&mesh, 0, meshopt::SimplifyOptions::Permissive).len() / 3,
    };
    let source_bytes = indexed_mesh_bytes(&mesh);
    let ours_bytes = pm.memory_bytes();
    let rotated = compare_rotated(&mesh, ratios, args.rotations, &build_options)?;
    let (partitioned, partition_sizes) = match regions_spec {
        Some(spec) => {
            compare_partitioned(&mesh, spec, args.split == "error", &rows, &build_options)?
        }
        None => (Vec::new(), (0, 0, 0)),
    };
    Ok(Report {
        triangles: t,
        vertices: mesh.vertex_count(),
        runs,
        smallest,
        level_count: pm.level_count(),
        ours_ms,
        meshopt_smallest_ms,
        meshopt_1pc_ms,
        source_bytes,
        ours_bytes,
        rows,
        rotated,
        partitioned,
        partition_sizes,
        coarsest,
    })
}

/// The coarsest level each side reaches: our base mesh, and meshoptimizer's `simplify` to no
/// triangles, plain and `Permissive`.
#[derive(Clone, Copy)]
struct Coarsest {
    ours: usize,
    meshopt: usize,
    permissive: usize,
}

/// The cost of partitioning: `mesh` cut by `spec`, every region at each row's ratio (or, `by_error`,
/// the ratio's triangles shared at equal error), against the whole mesh (the row's
/// distance).
fn compare_partitioned(
    mesh: &IndexedMesh,
    spec: &str,
    by_error: bool,
    rows: &[Row],
    build_options: &BuildOptions,
) -> Result<(Vec<Partitioned>, PartitionSizes), Box<dyn std::error::Error>> {
    let options = DistanceOptions::default();
    let original = MeshRef::new(&mesh.positions, &mesh.indices);
    let mut partitioned = Vec::new();
    let regions = RegionMesh::build(mesh, &partition(mesh, spec)?, build_options)?;
    let root = regions.root();
    let obbs: Vec<Obb> = regions.regions().iter().map(|r| r.obb()).collect();
    let curves = ErrorCurves::new(&regions, &obbs);
    // Every region seen alike from all sides: its projected area is its box's mean one.
    let areas: Vec<f32> = obbs.iter().map(Obb::mean_projected_area).collect();
    let full: usize = regions.regions().iter().map(|r| r.max_triangles()).sum();
    for row in rows {
        let ratio = row.ratio;
        let mut counts: Vec<usize> = regions
            .regions()
            .iter()
            .map(|r| (ratio * r.max_triangles() as f64).round() as usize)
            .collect();
        if by_error {
            let mut shared = vec![0; counts.len()];
            let total = counts.iter().sum::<usize>().try_into().unwrap_or(u32::MAX);
            curves.split(&areas, total, &mut shared);
            counts = shared.into_iter().map(|c| c as usize).collect();
        }
        // The frontier for a view of the whole model: the root once every region would be
        // at or below its kept level, that is once the total is below the root's finest.
        let target = (ratio * full as f64).round() as usize;
        let on_root = root.is_some_and(|root| target < root.max_triangles());
        let assembled = match root.filter(|_| on_root) {
            Some(root) => {
                let pm = root.progressive_mesh();
                let mut cache = PolygonCache::new(pm);
                cache.set_triangle_count(pm, target);
                cache
                    .indices()
                    .iter()
                    .map(|&v| root.global_vertices()[v as usize])
                    .collect()
            }
            None => assemble(&regions, &counts).0,
        };
        let d = mesh_distance(
            original,
            MeshRef::new(&mesh.positions, &assembled),
            &options,
        );
        partitioned.push((assembled.len() / 3, d, row.ours, on_root));
    }
    let root_bytes = root.map_or(0, MergedRoot::memory_bytes);
    let sizes = (
        regions.memory_bytes() - root_bytes,
        root_bytes,
        root.map_or(0, MergedRoot::max_triangles),
    );
    Ok((partitioned, sizes))
}

/// Prints the [`Report`] as JSON.
fn print_json(args: &CompareArgs, report: &Report) -> CliResult {
    let (input, ratios, regions_spec) = (
        args.input.as_path(),
        args.ratios.as_slice(),
        args.regions.as_deref(),
    );
    let Report {
        triangles: t,
        vertices,
        runs,
        ours_ms,
        meshopt_smallest_ms,
        meshopt_1pc_ms,
        source_bytes,
        ours_bytes,
        ref rows,
        ref rotated,
        ref partitioned,
        coarsest,
        ..
    } = *report;
    let value = serde_json::json!({
        "input": input.display().to_string(),
        "triangles": t,
        "vertices": vertices,
        "coarsest": {
            "ours": coarsest.ours,
            "meshopt": coarsest.meshopt,
            "meshopt_permissive": coarsest.permissive,
        },
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
            "split": args.split,
            "root": args.root,
            "region_bytes": report.partition_sizes.0,
            "root_bytes": report.partition_sizes.1,
            "root_triangles": report.partition_sizes.2,
            "rows": partitioned.iter().zip(ratios).map(|((n, d, whole, on_root), ratio)| serde_json::json!({
                "ratio": ratio,
                "frontier": if *on_root { "root" } else { "regions" },
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
            "meshopt_permissive": {"triangles": r.permissive_triangles, "hausdorff": r.permissive.hausdorff, "rms": r.permissive.rms},
            "hausdorff_ratio": r.ours.hausdorff / r.meshopt.hausdorff,
            "rms_ratio": r.ours.rms / r.meshopt.rms,
        })).collect::<Vec<_>>(),
    });
    println!("{}", serde_json::to_string_pretty(&value)?);
    Ok(())
}

/// Prints the [`Report`] as tables.
fn print_table(args: &CompareArgs, report: &Report) {
    let (input, ratios, regions_spec) = (
        args.input.as_path(),
        args.ratios.as_slice(),
        args.regions.as_deref(),
    );
    let Report {
        triangles: t,
        vertices,
        runs,
        smallest,
        level_count,
        ours_ms,
        meshopt_smallest_ms,
        meshopt_1pc_ms,
        source_bytes,
        ours_bytes,
        ref rows,
        ref rotated,
        ref partitioned,
        partition_sizes,
        coarsest,
    } = *report;
    println!(
        "{}: {} triangles, {} vertices (median of {} runs)",
        input.display(),
        t,
        vertices,
        runs
    );
    println!(
        "build: ours (all {} levels) {:.1} ms | meshopt to {:.0}% {:.1} ms | meshopt to 1% {:.1} ms | ours / meshopt 1% = {:.2}x",
        level_count,
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
        "coarsest level: ours {} | meshopt {} | meshopt Permissive {} triangles",
        coarsest.ours, coarsest.meshopt, coarsest.permissive
    );
    println!(
        "{:>6} {:>8} | {:>8} {:>10} {:>10} | {:>8} {:>10} {:>10} | {:>7} {:>7} | {:>7} | {:>8} {:>10} {:>10} | {:>7} {:>7}",
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
        "pinched",
        "permiss.",
        "hausdorff",
        "rms",
        "H ratio",
        "RMS rat"
    );
    for r in rows {
        println!(
            "{:>6} {:>8} | {:>8} {:>10.6} {:>10.6} | {:>8} {:>10.6} {:>10.6} | {:>7.3} {:>7.3} | {:>7} | {:>8} {:>10.6} {:>10.6} | {:>7.3} {:>7.3}",
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
            format!("{}/{}", r.ours_pinched, r.meshopt_pinched),
            r.permissive_triangles,
            r.permissive.hausdorff,
            r.permissive.rms,
            r.ours.hausdorff / r.permissive.hausdorff,
            r.ours.rms / r.permissive.rms,
        );
    }
    println!("pinched: edges shared by more than two triangles (non-manifold), ours/meshopt");
    println!(
        "permiss.: meshoptimizer's simplify with Permissive (crosses seams and non-manifold edges)"
    );
    if let Some(spec) = regions_spec {
        print_partitioned(spec, args.split == "error", ratios, partitioned);
        let (regions, root, root_triangles) = partition_sizes;
        println!(
            "regions {regions} bytes; merged root {root} bytes ({root_triangles} triangles at its finest)"
        );
    }
    print_rotated(args.rotations, rotated);
}

/// The `--regions` table of [`print_table`]: `partitioned` (cut by `spec`) per ratio.
fn print_partitioned(spec: &str, by_error: bool, ratios: &[f64], partitioned: &[Partitioned]) {
    let how = if by_error {
        "the ratio's triangles shared at equal error"
    } else {
        "every region at the ratio"
    };
    println!("partitioned ({spec}), {how}, against the whole mesh:");
    println!(
        "{:>6} {:>8} {:>8} {:>10} {:>10} | {:>9} {:>9}",
        "ratio", "drawn", "tris", "hausdorff", "rms", "H vs one", "RMS vs one"
    );
    for ((n, d, whole, on_root), ratio) in partitioned.iter().zip(ratios) {
        println!(
            "{:>6} {:>8} {:>8} {:>10.6} {:>10.6} | {:>9.3} {:>9.3}",
            ratio,
            if *on_root { "root" } else { "regions" },
            n,
            d.hausdorff,
            d.rms,
            d.hausdorff / whole.hausdorff,
            d.rms / whole.rms
        );
    }
}

/// The `--rotations` table of [`print_table`]: `rotated` over `copies` copies, if any.
fn print_rotated(copies: usize, rotated: &[RotatedRow]) {
    if rotated.is_empty() {
        return;
    }
    println!(
        "{} rotated copies: geometric mean of ours / meshopt, and copies at most 1:",
        copies
    );
    println!(
        "{:>6} | {:>7} {:>7} | {:>7} {:>7} | {:>9}",
        "ratio", "H ratio", "RMS rat", "H <= 1", "RMS <= 1", "pinched"
    );
    for r in rotated {
        println!(
            "{:>6} | {:>7.3} {:>7.3} | {:>7} {:>7} | {:>9}",
            r.ratio,
            r.hausdorff_ratio,
            r.rms_ratio,
            format!("{}/{}", r.hausdorff_at_most, copies),
            format!("{}/{}", r.rms_at_most, copies),
            format!(
                "{}/{}-{}",
                r.ours_pinched_max, r.meshopt_pinched.0, r.meshopt_pinched.1
            )
        );
    }
    println!("pinched: our most in one copy / meshopt's fewest-most");
}

#[cfg(test)]
mod tests {
    use super::pinched_edges;
    use glam::Vec3;

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
