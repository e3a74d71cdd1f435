//! `aslod extract`: a level by triangle count or error, per region, or seen from an eye, as OBJ.

use crate::{CliResult, build, build_with, load, partition};
use bevy_aslod::mesh::{write_obj, write_obj_groups};
use bevy_aslod::multires::{BuildOptions, PolygonCache};
use bevy_aslod::refine::{self, Criteria, ScreenSpaceError, VariableMesh, View};
use bevy_aslod::regions::{RegionCaches, RegionMesh};
use glam::Vec3;
use std::io::BufWriter;
use std::path::Path;
use std::time::Instant;

/// The view-dependent mode of `extract` (the `refine` module).
#[derive(clap::Args)]
pub(crate) struct ViewArgs {
    /// View-dependent level seen from this eye, `X,Y,Z` in the mesh's coordinates.
    #[arg(long, value_delimiter = ',', value_name = "X,Y,Z", allow_hyphen_values = true, conflicts_with_all = ["triangles", "error", "regions"])]
    pub(crate) eye: Option<Vec<f32>>,
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

pub(crate) fn extract(
    input: &Path,
    triangles: Option<usize>,
    error: Option<f32>,
    output: &Path,
) -> CliResult {
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
pub(crate) fn extract_view(input: &Path, args: &ViewArgs, output: &Path) -> CliResult {
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

/// Builds the regions, sets each to its count, writes the assembled mesh with one OBJ group
/// per region, and returns the assembled triangles.
pub(crate) fn extract_regions(
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
pub(crate) fn assemble(
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

#[cfg(test)]
mod tests {
    use super::extract_view;
    use crate::{Cli, Command};
    use bevy_aslod::mesh::IndexedMesh;
    use clap::Parser;

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
}
