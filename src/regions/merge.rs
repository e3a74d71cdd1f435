//! The merged root: the whole model as one progressive mesh below the detail where its
//! regions' held borders cost more than view-dependence buys.
//!
//! Every region is simplified with its border held, at every level, so that neighbours at
//! different levels meet without cracks. Far away, where the whole model is a few hundred
//! triangles, the held borders take most of them. The root starts where the regions stop
//! paying their way: every region at its *kept* level (the levels a view of the whole model
//! gives them at the root's ratio of the model's triangles), assembled into one mesh, and
//! simplified from there with no border held. At its finest level the root is exactly those
//! regions' triangles, so a switch from the regions at their kept levels to the root changes
//! nothing on screen; below it, the borders the regions held are free to collapse.
//!
//! Every root level is a subset of the source mesh's vertices, like every region level. The
//! root has no neighbour to match: a model draws either its regions or its root.

use super::{ErrorCurves, RegionCaches, RegionError, RegionMesh};
use crate::bounds::Obb;
use crate::mesh::IndexedMesh;
use crate::multires::{BuildOptions, ProgressiveMesh, build};

/// The whole model as one progressive mesh, from its regions at their kept levels down (see
/// the [module docs](self)).
///
/// ```
/// use bevy_aslod::mesh::IndexedMesh;
/// use bevy_aslod::multires::{BuildOptions, PolygonCache};
/// use bevy_aslod::regions::{GridPlane, Partition, RegionMesh};
/// use glam::Vec3;
///
/// // A bumpy 17x17-vertex patch cut into 2x2 regions, with a root at 30 % of its triangles.
/// let mut positions = Vec::new();
/// for z in 0..17 {
///     for x in 0..17 {
///         positions.push(Vec3::new(x as f32, ((x * 7 + z * 3) % 5) as f32 * 0.2, z as f32));
///     }
/// }
/// let mut indices = Vec::new();
/// for z in 0..16u32 {
///     for x in 0..16u32 {
///         let i = z * 17 + x;
///         indices.extend_from_slice(&[i, i + 17, i + 1, i + 1, i + 17, i + 18]);
///     }
/// }
/// let mesh = IndexedMesh::new(positions, indices);
/// let partition = Partition::grid(&mesh, GridPlane::XZ, 2, 2)?;
/// let options = BuildOptions::default().with_root_ratio(0.3);
/// let regions = RegionMesh::build(&mesh, &partition, &options)?;
/// let root = regions.root().expect("four regions and a ratio above zero");
/// assert!(root.max_triangles() <= mesh.triangle_count() / 2);
/// assert_eq!(root.kept_levels().len(), 4);
/// // Far away the model is one mesh of a few triangles, in source-mesh vertices.
/// let mut cache = PolygonCache::new(root.progressive_mesh());
/// cache.set_triangle_count(root.progressive_mesh(), 8);
/// let drawn: Vec<u32> = cache.indices().iter().map(|&v| root.global_vertices()[v as usize]).collect();
/// assert!(drawn.len() / 3 <= 8 && drawn.iter().all(|&v| (v as usize) < mesh.vertex_count()));
/// # Ok::<(), bevy_aslod::regions::RegionError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct MergedRoot {
    /// The root's sequence, over a local vertex table (the vertices the kept levels use).
    pub(crate) mesh: ProgressiveMesh,
    /// Local vertex -> vertex of the source mesh.
    pub(crate) global: Vec<u32>,
    /// Per region, its level when the root was made from it.
    pub(crate) kept: Vec<u32>,
}

impl MergedRoot {
    /// The root's progressive sequence, over a local vertex table (see
    /// [`global_vertices`](Self::global_vertices)).
    #[inline]
    #[must_use]
    pub fn progressive_mesh(&self) -> &ProgressiveMesh {
        &self.mesh
    }

    /// Local vertex index -> vertex index in the source mesh.
    #[inline]
    #[must_use]
    pub fn global_vertices(&self) -> &[u32] {
        &self.global
    }

    /// Per region, the level it was at when the root was made: the root's finest level is
    /// every region at this level.
    #[inline]
    #[must_use]
    pub fn kept_levels(&self) -> &[u32] {
        &self.kept
    }

    /// Triangles of the root's finest level (the regions' at their kept levels).
    #[inline]
    #[must_use]
    pub fn max_triangles(&self) -> usize {
        self.mesh.max_triangles()
    }

    /// Triangles of the root's coarsest level.
    #[inline]
    #[must_use]
    pub fn min_triangles(&self) -> usize {
        self.mesh.min_triangles()
    }

    /// Bytes the root adds to its regions.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.mesh.memory_bytes() + self.global.len() * 4 + self.kept.len() * 4
    }
}

/// Builds the root of `regions` (made from `mesh`, validated) at `ratio` (in `0..=1`) of the
/// regions' full-detail triangles: the regions' kept levels share that many triangles at
/// equal error, every region seen alike from all sides.
pub(crate) fn build_root(
    mesh: &IndexedMesh,
    regions: &RegionMesh,
    ratio: f32,
    options: &BuildOptions,
) -> Result<MergedRoot, RegionError> {
    let obbs: Vec<Obb> = regions.regions().iter().map(|r| r.obb()).collect();
    let curves = ErrorCurves::new(regions, &obbs);
    let areas: Vec<f32> = obbs.iter().map(Obb::mean_projected_area).collect();
    let full: usize = regions.regions().iter().map(|r| r.max_triangles()).sum();
    let total = (f64::from(ratio) * full as f64).round() as u32;
    let mut counts = vec![0u32; regions.regions().len()];
    curves.split(&areas, total, &mut counts);

    let mut caches = RegionCaches::new(regions);
    let (mut assembled, mut part) = (Vec::new(), Vec::new());
    let mut kept = Vec::with_capacity(counts.len());
    // Every level first: a border corner takes its neighbour's representative at the
    // neighbour's level.
    for (r, &n) in counts.iter().enumerate() {
        caches.set_triangle_count(regions, r, n as usize);
        kept.push(caches.level(r) as u32);
    }
    for r in 0..counts.len() {
        caches.write_global_indices(regions, r, &mut part);
        assembled.extend_from_slice(&part);
    }
    let mut global = assembled.clone();
    global.sort_unstable();
    global.dedup();
    let mut sub = mesh.subset(&global);
    sub.indices = assembled
        .iter()
        .map(|v| global.binary_search(v).map_or(0, |i| i as u32))
        .collect();
    let triangles = sub.triangle_count();
    // The regions keep no view data, nor does their root.
    let options = BuildOptions {
        view_dependent: false,
        ..options.clone()
    };
    let built = build::build(
        &sub,
        &options,
        &build::Constraints::default(),
        triangles,
        &mut |_, _| {},
    )?;
    Ok(MergedRoot {
        mesh: built.mesh,
        global,
        kept,
    })
}
