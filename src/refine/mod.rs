//! Variable-resolution levels inside one mesh: MOM's two-stage extraction (Ribelles et al.)
//! and Güdükbay et al.'s view-dependent refinement, on the crate's progressive sequence.
//!
//! A uniform level performs the first `L` collapses of a [`ProgressiveMesh`]. A
//! variable-resolution level performs any subset that respects the collapses' dependencies,
//! chosen collapse by collapse by a [`Criterion`] of the view: outside the frustum, facing
//! away, too small to see (Hoppe's criteria, as Güdükbay et al. use them), or outside a
//! sphere of interest, off the silhouette, unlit (MOM's). The near or lit or silhouette parts
//! of one mesh keep detail that the rest gives up; ASLOD's regions are the coarse version of
//! the same idea.
//!
//! - [`VariableMesh`] wraps a progressive mesh built with
//!   [`BuildOptions::view_dependent`](crate::multires::BuildOptions::view_dependent), and
//!   holds what the criteria read per collapse (a [`Node`]) and the dependency graph.
//! - [`extract`] runs MOM's algorithm from full detail: fine to coarse, a flag per triangle.
//!   It needs one bit per triangle beyond the output index buffer.
//! - [`VariableCache`] is one instance's level (like a
//!   [`PolygonCache`](crate::multires::PolygonCache)): [`VariableCache::extract`] from scratch,
//!   or [`VariableCache::update`] from its last level, performing or undoing only the collapses
//!   on its front, whose decision may have changed, and editing its index buffer in place
//!   (the frame-to-frame coherence both papers leave as future work).
//!
//! Every level is crack-free: a collapse is performed only when every triangle slot it removes
//! or changes holds the version the sequence had at that point, so each drawn triangle is one
//! the uniform sequence also draws, with the same neighbours along every edge.
//!
//! ```
//! use bevy_aslod::mesh::IndexedMesh;
//! use bevy_aslod::multires::{BuildOptions, ProgressiveMesh};
//! use bevy_aslod::refine::{Criteria, ScreenSpaceError, VariableCache, VariableMesh, View};
//! use glam::Vec3;
//!
//! let (mesh, _) = IndexedMesh::load("../shared/testdata/meshes/cow.obj")?;
//! let options = BuildOptions::default().with_view_dependent(true);
//! let cow = VariableMesh::new(ProgressiveMesh::build(&mesh, &options)?)?;
//!
//! // Seen from the front, an 800×600 view: no more than half a pixel of error anywhere.
//! let (lo, hi) = mesh.bounds().unwrap();
//! let centre = (lo + hi) * 0.5;
//! let eye = centre + Vec3::new(0.0, 0.0, 2.0 * (hi - lo).length());
//! let view = View::perspective(eye, centre - eye, Vec3::Y, 0.6, 4.0 / 3.0, 0.01, 600.0)?;
//! let criteria = Criteria::default()
//!     .with_frustum(true)
//!     .with_back_facing(true)
//!     .with_screen_space(Some(ScreenSpaceError::new(0.5)?));
//!
//! let mut cache = VariableCache::new(&cow);
//! let stats = cache.extract(&cow, &criteria, &view)?;
//! assert!(stats.triangles < cow.mesh().max_triangles());
//! assert_eq!(cache.indices().len(), 3 * stats.triangles);
//!
//! // The camera moves a little: only the front of the last level is looked at.
//! let view = View::perspective(eye + Vec3::X * 0.05, centre - eye, Vec3::Y, 0.6, 4.0 / 3.0,
//!     0.01, 600.0)?;
//! let step = cache.update(&cow, &criteria, &view)?;
//! assert!(step.evaluated < stats.evaluated);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod budget;
mod cache;
mod criteria;
mod error;
mod extract;
mod morph;
mod view;

pub use budget::{BudgetFit, ToleranceSearch};
pub use cache::VariableCache;
pub use criteria::{
    BackFacing, Criteria, Criterion, Frustum, Illumination, LevelCut, Node, ScreenSpaceError,
    Silhouette, SphereOfInterest,
};
pub use error::RefineError;
pub use extract::RefineStats;
pub use morph::VariableGeomorphs;
pub use view::View;

use crate::multires::records::{Corner, Header, Records};
use crate::multires::{CacheIndex, ProgressiveMesh};
use extract::{Bits, drawn, first_stage};

/// Calls `$body` with `$r` bound to the records of either layout.
macro_rules! with_records {
    ($layout:expr, $r:ident => $body:expr) => {
        match $layout {
            $crate::multires::records::Layout::Narrow($r) => $body,
            $crate::multires::records::Layout::Wide($r) => $body,
        }
    };
}
pub(crate) use with_records;

/// A progressive mesh ready for view-dependent refinement: the mesh, each collapse's
/// [`Node`], and the dependencies between collapses that the incremental path walks.
///
/// Shared by every instance (each keeps its own [`VariableCache`]).
///
/// Memory, beyond the progressive mesh (whose view-dependent data adds about 7 bytes per
/// triangle, see [`BuildOptions::view_dependent`](crate::multires::BuildOptions::view_dependent)):
/// the decoded nodes (48 bytes per collapse) and, for the incremental path, three record
/// offsets per collapse and the dependency graph both ways (about 4 bytes per edge, each way);
/// [`memory_bytes`](Self::memory_bytes) counts them.
#[derive(Clone, Debug)]
pub struct VariableMesh {
    mesh: ProgressiveMesh,
    nodes: Vec<Node>,
    graph: Graph,
    /// The geomorph tables, made by the mesh's first [`VariableGeomorphs`] and shared.
    morph_tables: std::sync::OnceLock<std::sync::Arc<crate::multires::morph::MorphTables>>,
}

impl VariableMesh {
    /// Prepares `mesh` for refinement.
    ///
    /// # Errors
    /// [`RefineError::NoViewData`] when `mesh` was built without
    /// [`BuildOptions::view_dependent`](crate::multires::BuildOptions::view_dependent).
    pub fn new(mesh: ProgressiveMesh) -> Result<Self, RefineError> {
        let Some(view) = mesh.view.as_ref() else {
            return Err(RefineError::NoViewData);
        };
        let positions = &mesh.vertices.positions;
        let diagonal = view.diagonal;
        let nodes = (0..view.len())
            .map(|i| {
                let (axis, angle) = view.cone_of(i);
                let (center, radius) = view.sphere_of(i, positions);
                Node {
                    step: i as u32,
                    center,
                    radius,
                    error: view.error_of(i) * diagonal,
                    axis,
                    cone_angle: angle,
                    cone_cos: angle.cos(),
                    cone_sin: angle.sin(),
                }
            })
            .collect();
        let graph = with_records!(&mesh.records, r => Graph::new(r));
        Ok(Self {
            nodes,
            graph,
            mesh,
            morph_tables: std::sync::OnceLock::new(),
        })
    }

    /// The progressive mesh.
    #[inline]
    #[must_use]
    pub fn mesh(&self) -> &ProgressiveMesh {
        &self.mesh
    }

    /// The progressive mesh, giving up the refinement data.
    #[must_use]
    pub fn into_mesh(self) -> ProgressiveMesh {
        self.mesh
    }

    /// Number of collapses.
    #[inline]
    #[must_use]
    pub fn collapse_count(&self) -> usize {
        self.nodes.len()
    }

    /// The bounds the criteria read for collapse `step`, or `None` past the last collapse.
    #[inline]
    #[must_use]
    pub fn node(&self, step: usize) -> Option<&Node> {
        self.nodes.get(step)
    }

    /// Which vertex collapse `step` moved onto which: `[u, w]`, vertex ids into
    /// [`ProgressiveMesh::vertices`] (the first vertex at each position), or `None` past the
    /// last collapse.
    #[inline]
    #[must_use]
    pub fn collapse(&self, step: usize) -> Option<[u32; 2]> {
        self.mesh.view.as_ref()?.moved.get(step)
    }

    /// The collapses `step` depends on: for every triangle it removes or changes, the last
    /// earlier collapse that touched it (empty past the last collapse).
    #[inline]
    #[must_use]
    pub fn dependencies(&self, step: usize) -> &[u32] {
        let g = &self.graph;
        match (g.deps_start.get(step), g.deps_start.get(step + 1)) {
            (Some(&from), Some(&to)) => &g.deps[from as usize..to as usize],
            _ => &[],
        }
    }

    #[inline]
    fn dependents(&self, step: usize) -> &[u32] {
        let g = &self.graph;
        &g.children[g.children_start[step] as usize..g.children_start[step + 1] as usize]
    }

    /// Bytes of the refinement data beyond the progressive mesh (see the type's docs).
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        let g = &self.graph;
        self.nodes.len() * size_of::<Node>()
            + 4 * (g.first_removed.len()
                + g.corner_start.len()
                + g.pair_start.len()
                + g.deps_start.len()
                + g.deps.len()
                + g.children_start.len()
                + g.children.len())
    }
}

/// The per-collapse offsets and the dependency graph, from one replay of the records.
#[derive(Clone, Debug)]
struct Graph {
    /// Per collapse: its first removed slot, and its first corner and pair record.
    first_removed: Vec<u32>,
    corner_start: Vec<u32>,
    pair_start: Vec<u32>,
    /// Per collapse, the collapses it depends on (`deps[deps_start[i]..deps_start[i + 1]]`):
    /// for every slot it removes or changes, the last earlier collapse that touched it.
    deps_start: Vec<u32>,
    deps: Vec<u32>,
    /// The same edges the other way: the collapses that depend on each.
    children_start: Vec<u32>,
    children: Vec<u32>,
}

impl Graph {
    fn new<V: CacheIndex, H: Header, C: Corner>(records: &Records<V, H, C>) -> Self {
        let steps = records.steps.len();
        let slots = records.indices.len() / 3;
        let mut last = vec![u32::MAX; slots];
        let mut count = slots;
        let (mut corner, mut pair) = (0usize, 0usize);
        let mut graph = Self {
            first_removed: Vec::with_capacity(steps),
            corner_start: Vec::with_capacity(steps),
            pair_start: Vec::with_capacity(steps),
            deps_start: Vec::with_capacity(steps + 1),
            deps: Vec::with_capacity(4 * steps),
            children_start: Vec::new(),
            children: Vec::new(),
        };
        let mut touched = Vec::new();
        for (step, (nc, np, removed)) in records.headers().enumerate() {
            let first = count - removed;
            graph.first_removed.push(first as u32);
            graph.corner_start.push(corner as u32);
            graph.pair_start.push(pair as u32);
            graph.deps_start.push(graph.deps.len() as u32);
            touched.clear();
            touched.extend(first as u32..count as u32);
            touched.extend(
                records.corners[corner..corner + nc]
                    .iter()
                    .map(|&c| (records.corner_slot(c) / 3) as u32),
            );
            let from = graph.deps.len();
            for &s in &touched {
                let d = last[s as usize];
                if d != u32::MAX {
                    graph.deps.push(d);
                }
            }
            for &s in &touched {
                last[s as usize] = step as u32;
            }
            graph.deps[from..].sort_unstable();
            let unique = {
                let mut kept = from;
                for k in from..graph.deps.len() {
                    if kept == from || graph.deps[k] != graph.deps[kept - 1] {
                        graph.deps[kept] = graph.deps[k];
                        kept += 1;
                    }
                }
                kept
            };
            graph.deps.truncate(unique);
            count = first;
            corner += nc;
            pair += np;
        }
        graph.deps_start.push(graph.deps.len() as u32);
        // The reverse edges, by counting.
        let mut counts = vec![0u32; steps + 1];
        for &d in &graph.deps {
            counts[d as usize + 1] += 1;
        }
        for i in 0..steps {
            counts[i + 1] += counts[i];
        }
        graph.children = vec![0; graph.deps.len()];
        let mut fill = counts.clone();
        for step in 0..steps {
            for k in graph.deps_start[step]..graph.deps_start[step + 1] {
                let d = graph.deps[k as usize] as usize;
                graph.children[fill[d] as usize] = step as u32;
                fill[d] += 1;
            }
        }
        graph.children_start = counts;
        graph
    }
}

/// Extracts a variable-resolution level of `mesh` into `indices` from scratch, with MOM's
/// two-stage algorithm (fine to coarse, a flag per triangle), and returns what it did.
///
/// `indices` ends up holding the level's triangles, in slot order (base triangles first);
/// along the way it holds the whole full-detail index buffer, and the only other memory is
/// one bit per triangle. With [`LevelCut`]`(L)` the result is exactly the uniform level `L`
/// of a [`PolygonCache`](crate::multires::PolygonCache), triangle for triangle.
///
/// # Errors
/// [`RefineError`] from the criterion's [`validate`](Criterion::validate).
pub fn extract<K: Criterion + ?Sized>(
    mesh: &VariableMesh,
    criterion: &K,
    view: &View,
    indices: &mut Vec<u32>,
) -> Result<RefineStats, RefineError> {
    criterion.validate()?;
    let pm = &mesh.mesh;
    indices.clear();
    indices.extend(pm.records.indices_as::<u32>());
    let slots = indices.len() / 3;
    let mut frozen = Bits::new(slots);
    let (evaluated, performed) = with_records!(&pm.records, r => first_stage(
        r, &mesh.nodes, criterion, view, indices, &mut frozen, None,
    ));
    // The second stage: keep the drawn slots, in order, in place.
    let base = pm.min_triangles();
    let mut kept = 0;
    for s in 0..slots {
        if drawn(s, base, &frozen) {
            indices.copy_within(3 * s..3 * s + 3, 3 * kept);
            kept += 1;
        }
    }
    indices.truncate(3 * kept);
    Ok(RefineStats {
        triangles: kept,
        performed,
        evaluated,
        changed: performed,
    })
}
