//! Building the progressive sequence: QEM-ranked half-edge collapses.
//!
//! Garland & Heckbert, "Surface Simplification Using Quadric Error Metrics" (1997), for the
//! error metric; Hoppe, "Progressive Meshes" (1996), for recording every collapse so that it
//! can be undone; Hoxha's MR-model and MOM for storing triangles in removal order.
//!
//! The phases, in the order they run:
//! 1. weld vertices by position, so attribute seams are one point to the topology;
//! 2. build vertex -> triangle adjacency and classify every position (manifold, border,
//!    complex, pinned);
//! 3. fill quadrics: face planes, plus edge planes along borders and attribute seams;
//! 4. rank every position's cheapest valid half-edge collapse in a priority queue (its
//!    quadric error, scaled by the quadric weight the vertex has absorbed, plus its local error,
//!    the removed vertex's height over its moved fan);
//! 5. pop, re-validate, perform, record, and re-rank the one-ring of the surviving vertex;
//! 6. lay the triangles out in removal order and pack the records.

use super::ProgressiveMesh;
use super::heap::IndexedHeap;
use super::hierarchy::ViewData;
use super::quadric::{AttributeQuadrics, Quadric};
use super::records::{Layout, Unpacked, error_to_u16};
use crate::mesh::{IndexedMesh, MeshError, weld_positions_within};
use glam::{DVec3, Vec3};

/// Settings of [`ProgressiveMesh::build`]. Start from `default()` and change a field with its
/// setter:
///
/// ```
/// use bevy_aslod::multires::BuildOptions;
/// let fast = BuildOptions::default().with_local_weight(0.0).with_min_triangles(100);
/// assert_eq!((fast.local_weight, fast.min_triangles), (0.0, 100));
/// ```
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct BuildOptions {
    /// Stop collapsing at this many triangles (the base mesh may end up larger when nothing
    /// more can collapse without breaking the surface). Default: `0`, as coarse as possible.
    pub min_triangles: usize,
    /// Stop collapsing when the next collapse's error (relative to the bounding-box diagonal)
    /// would exceed this. Default: `f32::INFINITY`. The error table stores errors rounded up
    /// by up to 0.8 % (16 bits), so [`ProgressiveMesh::level_error`] of the last level may
    /// read slightly above this bound. With a [`weight_exponent`](Self::weight_exponent),
    /// collapses are ranked by a scaled cost and this bound applies to the unscaled error,
    /// so the build may stop while collapses with a smaller error are still queued.
    pub max_error: f32,
    /// How strongly open borders keep their shape, relative to the faces. Default: `10.0`
    /// (meshoptimizer's value). Negative or non-finite values count as `0.0` (with a
    /// warning); for borders that hardly move, use a large finite value.
    pub border_weight: f64,
    /// Reject a collapse when a moved triangle's normal turns by more than this angle, as a
    /// cosine. Default: `0.25` (about 75°; meshoptimizer's value). `0.0` is the plain
    /// "never flip" rule.
    pub min_normal_cos: f64,
    /// Weight of a point quadric at each vertex's own position, relative to the vertex's
    /// face and edge weights: every collapse then also pays `regularization` times its
    /// squared length. Too small to change the shape, it decides between collapses whose
    /// plane error is (nearly) equal, as on a flat face, in favour of the shortest edge.
    /// It also enters the error table: a collapse on a flat face records about
    /// `√regularization` times its edge length (3e-4 of it at the default) instead of 0.
    /// Default: `1e-7` (meshoptimizer's default). `0.0` turns it off; negative or non-finite
    /// values count as `0.0` (with a warning).
    pub regularization: f64,
    /// Weight of the collapse's local error: the squared distance from the vertex that
    /// goes to the planes of the triangles that replace its fan (the worst one), added to the
    /// quadric's mean. The quadric averages over everything merged into the vertex, so a
    /// vertex that absorbed a large flat area lets its curved side move almost for free; the
    /// local error is not diluted, and keeps the Hausdorff distance down. It also enters the
    /// error table ([`ProgressiveMesh::level_error`] is the square root of the quadric's mean
    /// plus this, relative to the diagonal). Default: `0.7` (chosen with
    /// [`weight_exponent`](Self::weight_exponent) on rotated copies of the test meshes against
    /// meshoptimizer; see the README). `0.0` is the plain quadric error; negative or
    /// non-finite values count as `0.0` (with a warning).
    pub local_weight: f64,
    /// How much the surface a vertex has absorbed counts when collapses are ranked: the
    /// quadric's mean error is multiplied by `(weight / mean) ^ weight_exponent`, where
    /// `weight` is the quadric weight merged into the vertex that goes (each face adds the
    /// square root of its doubled area, border and seam edges their length times their
    /// weight) and `mean` the mean weight, before any collapse, of the vertices that may move
    /// (not those pinned, such as another region's). `0.0` ranks by the mean alone
    /// (meshoptimizer's normalisation); `1.0` by the weighted sum of squared distances
    /// (Garland and Heckbert's), which measures how much surface moves and so the RMS
    /// distance, but lets small features go first. In between, a vertex that stands for a
    /// large area pays more to move, which lowers the RMS distance at coarse levels.
    /// Only the order changes: the error table records the unscaled error. Default: `0.25`
    /// (see the README). Values outside `0.0..=1.0` are clamped to that range, non-finite
    /// ones count as `0.0` (with a warning).
    pub weight_exponent: f64,
    /// Keep the data view-dependent refinement needs (the `refine` module): for every collapse,
    /// which vertex went onto which, and a bounding sphere, a cone of normals and an error
    /// bound over everything it and the collapses below it change. About 7 bytes per
    /// triangle. Only whole meshes keep it ([`ProgressiveMesh::build`]); region builds ignore
    /// it. Default: `false`.
    pub view_dependent: bool,
    /// Güdükbay et al.'s topology compromise: also collapse a vertex onto one of another
    /// connected part that is closer than this distance (relative to the bounding-box
    /// diagonal) without an edge between them, so nearby parts merge, and let a closed part
    /// that has come down to a tetrahedron fold flat and vanish. Coarse levels of meshes
    /// made of many small parts then go far below what edge collapses alone reach (each
    /// closed part stops at a tetrahedron). A merged vertex joins two fans, and a vanishing
    /// part folds flat before it goes (its last two triangles face each other), so such levels
    /// are not manifold everywhere; vertices with attribute seams never pair. Whole meshes
    /// only ([`ProgressiveMesh::build`]). `0.0` turns it off; negative or non-finite values
    /// count as `0.0` (with a warning). Default: `0.0`.
    pub pair_distance: f32,
    /// The simplification operator: edge collapses, or Hoxha's triangle collapses (three
    /// vertices to one, four triangles removed; [`CollapseOperator`]). Default:
    /// [`CollapseOperator::Edge`] (see `docs/performance.md`, "Collapse operators").
    pub operator: CollapseOperator,
    /// Weight of the vertex normals in the collapse cost (see
    /// [`uv_weight`](Self::uv_weight)). Default: `0.25`.
    pub normal_weight: f64,
    /// Weight of the first UV set in the collapse cost. Each attribute vertex keeps an
    /// attribute quadric (Hoppe 1999's metric, in meshoptimizer's form and units, as its
    /// `simplify_with_attributes`): over the triangles merged into it, each attribute as the
    /// linear function that interpolates it across its triangle. A collapse also pays how far
    /// the values of the vertex that takes its place, times the weight, are from those
    /// functions there, integrated over the triangles (each weighs its area): an attribute
    /// off by 1 over a patch of size d costs what moving the patch by d does, whatever the
    /// mesh's scale. Attributes that vary linearly cost nothing to simplify; creases in them
    /// (a fold in the UVs, a sharp turn of the normals, a colour border) do. Only the order
    /// of collapses changes: the error table stays geometric. `0.0` turns a term off;
    /// negative or non-finite values count as `0.0` (with a warning).
    ///
    /// Default: `0.25`. The defaults (normals, UVs and colours 0.25 each) were chosen on
    /// rendered images against meshoptimizer's and on geometric distance (`aslod compare`):
    /// with [`permissive`](Self::permissive) collapses crossing seams at their attribute
    /// cost, normals at 0.5 cost FlightHelmet up to 1.7× meshoptimizer's geometric error and
    /// at 0.1 cost WaterBottle 2 dB at half its triangles; see `docs/performance.md`, "Real
    /// assets", "Textured assets in pixels" and "Attribute terms".
    pub uv_weight: f64,
    /// Weight of the vertex colours ([`COLOR_ID`](crate::mesh::COLOR_ID), RGBA as floats)
    /// in the collapse cost (see [`uv_weight`](Self::uv_weight)). Default: `0.25`.
    pub color_weight: f64,
    /// Vertices closer than this (relative to the bounding-box diagonal) are one point to the
    /// topology, as vertices at equal positions are ([`weld_positions_within`]): exported
    /// meshes often leave the two sides of a seam a few float steps apart, which exact
    /// equality sees as open borders. Two corners of one triangle are never welded. The
    /// levels still use the source vertices, each at its own position. Default: `1e-6`
    /// (about ten float steps of a coordinate near the diagonal's size; the finest scans in
    /// `../shared/testdata` space their vertices 1e-3 apart). `0.0` welds equal positions only.
    ///
    /// [`weld_positions_within`]: crate::mesh::weld_positions_within
    pub weld_distance: f32,
    /// Collapses past the walls of real assets. Ranked by cost with every other collapse, a
    /// collapse may cross an attribute seam (each attribute vertex of the vertex that goes
    /// then takes the one at the target that costs it the least attribute error, and pays
    /// that error), move a non-manifold vertex, or an open border's vertex off its border,
    /// and let a small part go (its last collapse pays the length it moves, the size of what
    /// goes). Once nothing else is left, the permissive tail also lets collapses pinch the
    /// surface into non-manifold edges, and remove every triangle of a non-manifold edge.
    /// Flat-shaded and split-vertex meshes, many-part props and non-manifold assets then
    /// reduce to a few triangles instead of stopping where their seams, borders and parts do
    /// (a whole mesh keeps at least one triangle; a region may give up all of its own, its
    /// neighbours' borders staying where they are). Levels still use a subset of the source
    /// vertices. Region builds keep their borders: a collapse of a vertex next to another
    /// region's, or onto one, follows the strict rules. Ignored with
    /// [`view_dependent`](Self::view_dependent) (its refinement needs manifold steps).
    /// Default: `true`; `false` keeps the topology (closed stays closed, seams stay seams).
    pub permissive: bool,
    /// Partitioned meshes ([`RegionMesh`](crate::regions::RegionMesh)): the share of the
    /// regions' full-detail triangles at which the merged root starts, the whole model as
    /// one progressive mesh made from every region at the level a view of the whole model
    /// gives it there, simplified on with no border held
    /// ([`MergedRoot`](crate::regions::MergedRoot)). `0.3` puts the partition's cost at 20 %
    /// and 5 % of the triangles within a few percent of the whole mesh simplified at once
    /// (`docs/performance.md`, "A far model is one mesh"). `0.0` builds no root; values
    /// outside `0..=1` or not finite build none, with a warning. Whole meshes ignore it.
    /// Default: `0.0` (the plugin does not draw the root yet).
    pub root_ratio: f32,
}

/// The simplification operator of a build ([`BuildOptions::operator`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CollapseOperator {
    /// Half-edge collapses: one vertex onto a neighbour, two triangles removed (one on an
    /// open border), the cheapest first.
    #[default]
    Edge,
    /// Hoxha et al.'s triangle collapse (section 2.2): a triangle's three vertices become one
    /// of them and the triangle goes with its three neighbours. Ranked by its cheapest edge
    /// `u → w`; the third vertex then follows onto `w` (of the two triangles on the edge, the
    /// apex that costs less, if its collapse onto `w` passes every check an edge collapse
    /// must). The survivor `w` is thus the original vertex the cheapest of the triangle's
    /// moves goes to, and every level uses a subset of the original vertices. It is recorded
    /// as the two edge collapses it is made of, so it stays exactly reversible, its halfway
    /// level is a valid level too, and it keeps every invariant of edge collapses (closed
    /// stays closed, no fold-over, crack-free regions). Where neither apex may follow (a
    /// border ear, a pinned vertex), the step stays an edge collapse.
    Triangle,
}

with_setters!(BuildOptions {
    min_triangles: usize => with_min_triangles,
    max_error: f32 => with_max_error,
    border_weight: f64 => with_border_weight,
    min_normal_cos: f64 => with_min_normal_cos,
    regularization: f64 => with_regularization,
    local_weight: f64 => with_local_weight,
    weight_exponent: f64 => with_weight_exponent,
    view_dependent: bool => with_view_dependent,
    pair_distance: f32 => with_pair_distance,
    operator: CollapseOperator => with_operator,
    normal_weight: f64 => with_normal_weight,
    uv_weight: f64 => with_uv_weight,
    color_weight: f64 => with_color_weight,
    weld_distance: f32 => with_weld_distance,
    permissive: bool => with_permissive,
    root_ratio: f32 => with_root_ratio,
});

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            min_triangles: 0,
            max_error: f32::INFINITY,
            border_weight: 10.0,
            min_normal_cos: 0.25,
            regularization: 1e-7,
            local_weight: 0.7,
            weight_exponent: 0.25,
            view_dependent: false,
            pair_distance: 0.0,
            operator: CollapseOperator::Edge,
            normal_weight: 0.25,
            uv_weight: 0.25,
            color_weight: 0.25,
            weld_distance: 1e-6,
            permissive: true,
            root_ratio: 0.0,
        }
    }
}

/// How a position may take part in collapses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// Interior of a manifold fan: may collapse along any edge.
    Manifold,
    /// On an open border: may collapse only along a border edge, so the outline keeps its
    /// vertices in order.
    Border,
    /// Non-manifold edge, inconsistent winding, or neighbour counts that do not fit one fan:
    /// never removed. The counts are all that is checked, as in meshoptimizer: two fans that
    /// meet only at the vertex, every edge used once each way (one such vertex on the cow),
    /// pass as manifold, and such a vertex may collapse, taking both fans along.
    Complex,
    /// Pinned by the caller (for example a vertex of another region): never removed and never
    /// a target.
    Pinned,
}

/// A directed edge's part in the edge quadrics (see `Builder::classify_edges`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum EdgeClass {
    Inner,
    Border,
    Seam,
}

/// The most vertex pairs or removed triangles a permissive collapse may record in one step,
/// with room left for the identity pairs of the corners it pins (the records hold 256 and
/// 255: `records::Fields::MAX_BITS`).
const MAX_STEP_ITEMS: usize = 240;

/// The most pair candidates (the topology compromise) a position keeps, nearest first.
const MAX_PAIRS: usize = 8;

/// One performed collapse, before the final layout.
struct Collapse {
    /// Range of `removed` this collapse removed (two triangles, one on an open border, more
    /// on a non-manifold edge in the permissive tail).
    removed: std::ops::Range<usize>,
    /// Range of `rewrites` this collapse wrote.
    rewrites: std::ops::Range<usize>,
    /// The error table's entry: the largest collapse error so far.
    error: f32,
    /// This collapse's own error (relative to the diagonal), before the running maximum.
    own_error: f32,
    /// The position ids of the vertex that went and the one it went onto.
    moved: [u32; 2],
}

/// One corner rewrite: triangle, corner, old vertex, new vertex.
type Rewrite = (u32, u8, u32, u32);

struct Builder<'a> {
    mesh: &'a IndexedMesh,
    options: &'a BuildOptions,
    /// Attribute vertex -> position id (the smallest vertex index at that position).
    pos: Vec<u32>,
    /// Positions relative to `centre`, the bounding box's centre.
    points: Vec<DVec3>,
    centre: DVec3,
    tris: Vec<[u32; 3]>,
    alive: Vec<bool>,
    /// Position id -> incident live triangles.
    adj: Adjacency,
    kind: Vec<Kind>,
    quadrics: Vec<Quadric>,
    /// The queue: each position's cheapest collapse cost; its target is in `target`.
    heap: IndexedHeap,
    target: Vec<u32>,
    /// Per position: its next re-rank must be a full one, because its queued collapse is the
    /// cheapest valid one rather than the cheapest, or may be stale (it lost `u` and `w` as
    /// neighbours in a collapse without being `w`'s neighbour after it, a vertex with more
    /// than one fan, so nothing re-ranked it then).
    full_rank_due: Vec<bool>,
    /// Per position: a lower bound on the [`level`](Builder::level)led costs of its other
    /// candidates (exact when ranked in full, but for candidates that could not win, which
    /// [`choose`](Builder::choose) prices by their (scaled) quadric error alone).
    runner_up: Vec<f64>,
    collapses: Vec<Collapse>,
    /// The triangles each collapse removed, in order.
    removed: Vec<u32>,
    rewrites: Vec<Rewrite>,
    moves: Vec<(u32, u32, u32)>,
    live_triangles: usize,
    /// False when every position has one attribute vertex: no seams to respect.
    has_seams: bool,
    /// Per position: a vertex that fronts are drawn along (another region's vertex); empty
    /// when there is none, so no fronts to respect.
    anchor: Vec<bool>,
    inv_diagonal: f64,
    /// Costs at or below this, `(1e-7 × the diagonal)²`, count as 0 (see `level`).
    cost_floor: f64,
    /// [`BuildOptions::local_weight`], made non-negative.
    local_weight: f64,
    /// [`BuildOptions::weight_exponent`], clamped to `0.0..=1.0`.
    weight_exponent: f64,
    /// The mean quadric weight of a position before any collapse (see `fill_quadrics`).
    mean_weight: f64,
    /// Per position: `(weight / mean_weight) ^ weight_exponent`, the factor on its quadric
    /// error (kept up to date as it absorbs others).
    scale: Vec<f64>,
    scratch: Scratch,
    candidates: Vec<(f64, u32)>,
    /// The positions of the triangles around the vertex last collapsed, before it was.
    moved_ring: Vec<u32>,
    /// Per position: the points its representative takes in another region, from which level
    /// on (see [`Constraints::chains`]); empty for all but the foreign vertices of a region
    /// whose neighbour is built.
    band: Vec<Vec<(u32, DVec3)>>,
    /// Scratch: the triangles around the vertex being collapsed.
    adj_u: Vec<u32>,
    /// Per position, the positions of other connected parts closer than
    /// [`BuildOptions::pair_distance`] (the topology compromise); empty when it is off.
    pairs: Vec<Vec<u32>>,
    /// Per attribute vertex, its weighted attributes (normal, UV, colour, each times its
    /// weight), `attribute_stride` values each; empty when no term is on.
    attributes: Vec<f64>,
    attribute_stride: usize,
    /// Per attribute vertex, its attribute quadric (empty when no term is on).
    attribute_quadrics: AttributeQuadrics,
    /// [`BuildOptions::permissive`], but for view-dependent builds: collapses may cross
    /// attribute seams, move complex vertices and open borders off their border, remove
    /// every triangle of a non-manifold edge, and erase small parts.
    permissive: bool,
    /// The permissive tail: every other collapse ran out, so collapses may also pinch the
    /// surface (break the link condition).
    pinch: bool,
}

/// Per position, its live triangles: every list in one arena, in position order (so the
/// lists of nearby vertices sit near each other in memory, and reaching one is one load
/// instead of two), each with room to grow; a list that outgrows its room moves to the end.
/// Lists keep the order of `Vec` with `push` and `swap_remove`.
struct Adjacency {
    start: Vec<usize>,
    len: Vec<u32>,
    cap: Vec<u32>,
    data: Vec<u32>,
}

impl Adjacency {
    /// Empty lists with room for `counts[p]` triangles at position `p`, and some more.
    fn with_counts(counts: &[u32]) -> Self {
        let mut start = Vec::with_capacity(counts.len());
        let mut cap = Vec::with_capacity(counts.len());
        let mut next = 0usize;
        for &c in counts {
            // A vertex that survives a collapse takes its neighbour's triangles.
            let room = if c == 0 {
                0
            } else {
                c.saturating_add(c / 2 + 2)
            };
            start.push(next);
            cap.push(room);
            next += room as usize;
        }
        Self {
            start,
            len: vec![0; counts.len()],
            cap,
            data: vec![0; next],
        }
    }

    /// Positions.
    fn len(&self) -> usize {
        self.start.len()
    }

    /// Appends `t` to `p`'s list.
    #[inline]
    fn push(&mut self, p: u32, t: u32) {
        let p = p as usize;
        if self.len[p] == self.cap[p] {
            let (from, len) = (self.start[p], self.len[p] as usize);
            let to = self.data.len();
            let room = self.cap[p].saturating_mul(2).max(8);
            self.data.resize(to + room as usize, 0);
            self.data.copy_within(from..from + len, to);
            self.start[p] = to;
            self.cap[p] = room;
        }
        self.data[self.start[p] + self.len[p] as usize] = t;
        self.len[p] += 1;
    }

    /// Removes the first `t` from `p`'s list, the last entry taking its place.
    #[inline]
    fn remove(&mut self, p: u32, t: u32) {
        let p = p as usize;
        let (from, len) = (self.start[p], self.len[p] as usize);
        let list = &mut self.data[from..from + len];
        if let Some(i) = list.iter().position(|&s| s == t) {
            list[i] = list[len - 1];
            self.len[p] -= 1;
        }
    }

    /// Moves `p`'s list into `out` (cleared first), leaving it empty.
    fn take(&mut self, p: u32, out: &mut Vec<u32>) {
        out.clear();
        out.extend_from_slice(&self[p as usize]);
        self.len[p as usize] = 0;
    }
}

impl std::ops::Index<usize> for Adjacency {
    type Output = [u32];

    #[inline]
    fn index(&self, p: usize) -> &[u32] {
        let from = self.start[p];
        &self.data[from..from + self.len[p] as usize]
    }
}

/// Buffers reused across collapse evaluations.
#[derive(Default)]
struct Scratch {
    /// Attribute-vertex mapping (old -> new) of the collapse being checked.
    map: Vec<(u32, u32)>,
    neighbors: Vec<u32>,
    /// The seam neighbours of the position being ranked (see
    /// [`Builder::seam_neighbors_into`]).
    seams: Vec<u32>,
    corners: Vec<(u32, u32, u32)>,
    /// `mark[p] == stamp` marks position `p` in the current set, without clearing.
    mark: Vec<u32>,
    stamp: u32,
    /// The far edge of each triangle around the position being ranked, in winding order:
    /// its two positions and their points (see [`Builder::local_error`]).
    fan: Vec<(u32, u32, DVec3, DVec3)>,
    /// The wedges around the position being ranked (see [`Builder::wedges_into`]).
    wedges: Vec<(u32, u32, u32)>,
}

impl Scratch {
    fn next_stamp(&mut self) -> u32 {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.mark.fill(0);
            self.stamp = 1;
        }
        self.stamp
    }
}

/// Positions of a triangle's corners that are not `p`, in winding order after `p`.
#[inline]
fn others(tri: [u32; 3], pos: &[u32], p: u32) -> Option<(usize, u32, u32)> {
    let q = [
        pos[tri[0] as usize],
        pos[tri[1] as usize],
        pos[tri[2] as usize],
    ];
    (0..3)
        .find(|&k| q[k] == p)
        .map(|k| (k, q[(k + 1) % 3], q[(k + 2) % 3]))
}

impl<'a> Builder<'a> {
    fn new(
        mesh: &'a IndexedMesh,
        options: &'a BuildOptions,
        pinned: Option<&[bool]>,
        anchors: Option<&[bool]>,
    ) -> Self {
        let n = mesh.positions.len();
        let bounds = mesh.bounds();
        let diagonal = bounds.map_or(0.0, |(lo, hi)| f64::from((hi - lo).length()));
        let weld = weld_positions_within(
            &mesh.positions,
            &mesh.indices,
            (f64::from(options.weld_distance) * diagonal) as f32,
        );
        // Relative to the bounds' centre: quadric terms grow with |p|², and a cost is their
        // difference, so coordinates far from the origin would round costs away.
        let centre = bounds.map_or(DVec3::ZERO, |(lo, hi)| {
            (lo.as_dvec3() + hi.as_dvec3()) * 0.5
        });
        let points = mesh
            .positions
            .iter()
            .map(|p| p.as_dvec3() - centre)
            .collect();
        let tris: Vec<[u32; 3]> = mesh
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        let mut counts = vec![0u32; n];
        for &v in &mesh.indices {
            counts[weld.remap[v as usize] as usize] += 1;
        }
        let mut adj = Adjacency::with_counts(&counts);
        for (t, tri) in tris.iter().enumerate() {
            for &v in tri {
                adj.push(weld.remap[v as usize], t as u32);
            }
        }
        let inv_diagonal = if diagonal > 0.0 { 1.0 / diagonal } else { 1.0 };
        let mut builder = Self {
            mesh,
            options,
            pos: weld.remap,
            points,
            centre,
            alive: vec![true; tris.len()],
            live_triangles: tris.len(),
            has_seams: weld.unique < n,
            anchor: Vec::new(),
            tris,
            adj,
            kind: vec![Kind::Manifold; n],
            quadrics: vec![Quadric::default(); n],
            heap: IndexedHeap::new(n),
            target: vec![u32::MAX; n],
            full_rank_due: vec![false; n],
            runner_up: vec![f64::INFINITY; n],
            collapses: Vec::new(),
            removed: Vec::new(),
            rewrites: Vec::new(),
            moves: Vec::new(),
            inv_diagonal,
            cost_floor: 1e-14 / (inv_diagonal * inv_diagonal),
            local_weight: non_negative(options.local_weight),
            weight_exponent: unit_interval(options.weight_exponent),
            mean_weight: 1.0,
            scale: vec![1.0; n],
            scratch: Scratch {
                mark: vec![0; n],
                ..Scratch::default()
            },
            candidates: Vec::new(),
            moved_ring: Vec::new(),
            band: Vec::new(),
            adj_u: Vec::new(),
            pairs: Vec::new(),
            attributes: Vec::new(),
            attribute_stride: 0,
            attribute_quadrics: AttributeQuadrics::default(),
            permissive: options.permissive && !options.view_dependent,
            pinch: false,
        };
        (builder.attributes, builder.attribute_stride) = attribute_table(mesh, options);
        builder.classify(pinned);
        let distance = f64::from(options.pair_distance);
        if distance > 0.0 && distance.is_finite() && pinned.is_none() {
            builder.find_pairs(distance * diagonal);
        }
        // Fronts run along the anchors: the vertices given, or else every pinned one.
        if let Some(anchors) = anchors.or(pinned)
            && anchors.contains(&true)
        {
            builder.anchor = vec![false; n];
            for (v, &a) in anchors.iter().enumerate() {
                if a {
                    builder.anchor[builder.pos[v] as usize] = true;
                }
            }
        }
        builder
    }

    /// The topology compromise's candidates: for every position, those of other connected
    /// parts within `distance` (nearest first, at most [`MAX_PAIRS`]), found in a hash grid of
    /// cell `distance`.
    fn find_pairs(&mut self, distance: f64) {
        let n = self.points.len();
        // Connected parts, by union-find over the triangles' positions.
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn root(parent: &mut [u32], mut x: u32) -> u32 {
            while parent[x as usize] != x {
                parent[x as usize] = parent[parent[x as usize] as usize];
                x = parent[x as usize];
            }
            x
        }
        for tri in &self.tris {
            let p = tri.map(|v| self.pos[v as usize]);
            for k in 1..3 {
                let (a, b) = (root(&mut parent, p[0]), root(&mut parent, p[k]));
                parent[a as usize] = b;
            }
        }
        let cell = |p: DVec3| (p / distance).floor().as_i64vec3();
        let mut grid: std::collections::HashMap<glam::I64Vec3, Vec<u32>> =
            std::collections::HashMap::new();
        for p in 0..n as u32 {
            if self.pos[p as usize] == p && !self.adj[p as usize].is_empty() {
                grid.entry(cell(self.points[p as usize]))
                    .or_default()
                    .push(p);
            }
        }
        self.pairs = vec![Vec::new(); n];
        let mut near: Vec<(f64, u32)> = Vec::new();
        for p in 0..n as u32 {
            if self.pos[p as usize] != p || self.adj[p as usize].is_empty() {
                continue;
            }
            let at = self.points[p as usize];
            let c = cell(at);
            let part = root(&mut parent, p);
            near.clear();
            for q in crate::mesh::weld::cells_around(&grid, c) {
                let d = self.points[q as usize].distance(at);
                if d <= distance && root(&mut parent, q) != part {
                    near.push((d, q));
                }
            }
            near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            self.pairs[p as usize].extend(near.iter().take(MAX_PAIRS).map(|&(_, q)| q));
        }
    }

    /// Phase 2: manifold, border, complex or pinned, per position.
    fn classify(&mut self, pinned: Option<&[bool]>) {
        let mut neighbors: Vec<(u32, i32, u32)> = Vec::new();
        for p in 0..self.adj.len() as u32 {
            if self.pos[p as usize] != p {
                continue;
            }
            // For every directed edge p->x (+1) and x->p (-1) around p, count uses.
            neighbors.clear();
            for &t in &self.adj[p as usize] {
                let (_, a, b) =
                    others(self.tris[t as usize], &self.pos, p).expect("adjacency is consistent");
                neighbors.push((a, 1, t));
                neighbors.push((b, -1, t));
            }
            neighbors.sort_unstable();
            let mut kind = Kind::Manifold;
            let mut border_edges = 0;
            let mut i = 0;
            while i < neighbors.len() {
                let x = neighbors[i].0;
                let mut j = i;
                let (mut out, mut inc) = (0, 0);
                while j < neighbors.len() && neighbors[j].0 == x {
                    if neighbors[j].1 > 0 {
                        out += 1;
                    } else {
                        inc += 1;
                    }
                    j += 1;
                }
                match (out, inc) {
                    (1, 1) => {}
                    (1, 0) | (0, 1) => border_edges += 1,
                    _ => kind = Kind::Complex,
                }
                i = j;
            }
            let distinct = {
                let mut d = 0;
                let mut last = u32::MAX;
                for &(x, _, _) in &neighbors {
                    if x != last {
                        d += 1;
                        last = x;
                    }
                }
                d
            };
            let tri_count = self.adj[p as usize].len();
            if kind == Kind::Manifold {
                // One fan: as many triangles as neighbours when closed, one fewer when open.
                kind = match border_edges {
                    0 if tri_count == distinct => Kind::Manifold,
                    2 if tri_count + 1 == distinct => Kind::Border,
                    _ => Kind::Complex,
                };
            }
            if tri_count == 0 {
                kind = Kind::Complex;
            }
            self.kind[p as usize] = kind;
        }
        if let Some(pinned) = pinned {
            for (v, &is_pinned) in pinned.iter().enumerate() {
                if is_pinned {
                    self.kind[self.pos[v] as usize] = Kind::Pinned;
                }
            }
        }
    }

    /// Takes the chains of other regions' vertices (see [`Constraints::chains`]), per vertex,
    /// into `band`, per position.
    fn set_chains(&mut self, chains: &[Vec<(u32, Vec3)>]) {
        if chains.iter().all(Vec::is_empty) {
            return;
        }
        self.band = vec![Vec::new(); self.points.len()];
        for (v, chain) in chains.iter().enumerate() {
            if !chain.is_empty() {
                self.band[self.pos[v] as usize] = chain
                    .iter()
                    .map(|&(level, p)| (level, p.as_dvec3() - self.centre))
                    .collect();
            }
        }
    }

    /// What each directed edge (triangle `t`, corner `k` to `k + 1`, at `3t + k`) is: a
    /// border (no triangle runs the other way along it), a seam (exactly one does, with
    /// other attribute vertices at either end) or inner. Gathered per position, from the
    /// edges leaving it and those arriving at it around its triangles.
    fn classify_edges(&self) -> Vec<EdgeClass> {
        let mut class = vec![EdgeClass::Inner; 3 * self.tris.len()];
        // (triangle, corner, far position, corner vertex, far vertex) of the edges leaving,
        // (triangle, start position, start vertex, end vertex) of those arriving.
        let mut leaving: Vec<(u32, usize, u32, u32, u32)> = Vec::new();
        let mut arriving: Vec<(u32, u32, u32, u32)> = Vec::new();
        for p in 0..self.adj.len() as u32 {
            let around = &self.adj[p as usize];
            leaving.clear();
            arriving.clear();
            for &t in around {
                let tri = self.tris[t as usize];
                for k in 0..3 {
                    let (v0, v1) = (tri[k], tri[(k + 1) % 3]);
                    let (p0, p1) = (self.pos[v0 as usize], self.pos[v1 as usize]);
                    if p0 == p {
                        leaving.push((t, k, p1, v0, v1));
                    }
                    if p1 == p {
                        arriving.push((t, p0, v0, v1));
                    }
                }
            }
            for &(t, k, p1, v0, v1) in &leaving {
                let (mut twins, mut seam) = (0, false);
                for &(s, start, w0, w1) in &arriving {
                    if s != t && start == p1 {
                        twins += 1;
                        seam |= w0 != v1 || w1 != v0;
                    }
                }
                class[3 * t as usize + k] = match (twins, seam) {
                    (0, _) => EdgeClass::Border,
                    (1, true) => EdgeClass::Seam,
                    _ => EdgeClass::Inner,
                };
            }
        }
        class
    }

    /// Phase 3: face quadrics, and edge quadrics that hold borders and seams in place.
    fn fill_quadrics(&mut self) {
        let s = self.attribute_stride;
        if s > 0 {
            self.attribute_quadrics = AttributeQuadrics::new(self.mesh.positions.len(), s);
            for tri in &self.tris {
                let points = tri.map(|v| self.points[self.pos[v as usize] as usize]);
                // Area weights: an attribute error integrated over the surface, in the units
                // of position errors (meshoptimizer's choice).
                let weight = 0.5
                    * (points[1] - points[0])
                        .cross(points[2] - points[0])
                        .length();
                let values = tri.map(|v| &self.attributes[v as usize * s..(v as usize + 1) * s]);
                self.attribute_quadrics
                    .add_triangle(*tri, points, values, weight);
            }
        }
        for tri in &self.tris {
            let [a, b, c] = tri.map(|v| self.pos[v as usize]);
            let (pa, pb, pc) = (
                self.points[a as usize],
                self.points[b as usize],
                self.points[c as usize],
            );
            let cross = (pb - pa).cross(pc - pa);
            let len = cross.length();
            if len == 0.0 {
                continue;
            }
            let n = cross / len;
            // sqrt(area) weights scale the error linearly with size, which keeps
            // silhouettes better than area weights (meshoptimizer does the same).
            let q = Quadric::from_plane(n, -n.dot(pa), len.sqrt());
            for p in [a, b, c] {
                self.quadrics[p as usize].add(&q);
            }
        }
        // Border edges: directed edges with no opposite twin. Seam edges: an edge whose two
        // triangles use different attribute vertices at either end.
        let edges = self.classify_edges();
        for t in 0..self.tris.len() {
            let tri = self.tris[t];
            for k in 0..3 {
                let (v0, v1, v2) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                let (p0, p1) = (self.pos[v0 as usize], self.pos[v1 as usize]);
                let weight = match edges[3 * t + k] {
                    EdgeClass::Border => non_negative(self.options.border_weight),
                    EdgeClass::Seam => 0.5,
                    EdgeClass::Inner => continue,
                };
                let (a, b, c) = (
                    self.points[p0 as usize],
                    self.points[p1 as usize],
                    self.points[self.pos[v2 as usize] as usize],
                );
                let e = b - a;
                let len_sq = e.length_squared();
                if len_sq == 0.0 {
                    continue;
                }
                // The plane through the edge, perpendicular to the triangle.
                let perp = ((c - a) * len_sq - e * (c - a).dot(e)).normalize_or_zero();
                if perp == DVec3::ZERO {
                    continue;
                }
                let mut q = Quadric::from_plane(perp, -perp.dot(a), len_sq.sqrt() * weight);
                // Mixing in the face plane, at the edge's weight but without adding to the
                // normalising area, stabilises collapses along the border in both directions
                // (as meshoptimizer does).
                let face = (b - a).cross(c - a);
                let area2 = face.length();
                if area2 > 0.0 {
                    let n = face / area2;
                    q.add(
                        &Quadric::from_plane(n, -n.dot(a), area2.sqrt() * weight).without_weight(),
                    );
                }
                self.quadrics[p0 as usize].add(&q);
                self.quadrics[p1 as usize].add(&q);
            }
        }
        // Regularization: a point quadric at each position (meshoptimizer's
        // `fillVertexQuadrics`).
        let factor = non_negative(self.options.regularization);
        if factor > 0.0 {
            for (q, &p) in self.quadrics.iter_mut().zip(&self.points) {
                let w = q.weight() * factor;
                if w > 0.0 {
                    q.add(&Quadric::from_point(p, w));
                }
            }
        }
        if self.weight_exponent > 0.0 {
            let (sum, count) = (0..self.quadrics.len())
                .filter(|&p| {
                    self.pos[p] == p as u32
                        && self.kind[p] != Kind::Pinned
                        && self.quadrics[p].weight() > 0.0
                })
                .fold((0.0, 0usize), |(sum, count), p| {
                    (sum + self.quadrics[p].weight(), count + 1)
                });
            if count > 0 {
                self.mean_weight = sum / count as f64;
            }
            for p in 0..self.quadrics.len() {
                self.scale[p] = self.scale_of(p as u32);
            }
        }
    }

    /// `(weight / mean_weight) ^ weight_exponent` for position `p` (see
    /// [`BuildOptions::weight_exponent`]).
    #[inline]
    fn scale_of(&self, p: u32) -> f64 {
        if self.weight_exponent > 0.0 {
            (self.quadrics[p as usize].weight() / self.mean_weight).powf(self.weight_exponent)
        } else {
            1.0
        }
    }

    /// Collects the distinct neighbour positions of `p` into `out`.
    fn neighbors_into(&self, p: u32, out: &mut Vec<u32>, scratch: &mut Scratch) {
        out.clear();
        let stamp = scratch.next_stamp();
        for &t in &self.adj[p as usize] {
            for &v in &self.tris[t as usize] {
                let q = self.pos[v as usize];
                if q != p && scratch.mark[q as usize] != stamp {
                    scratch.mark[q as usize] = stamp;
                    out.push(q);
                }
            }
        }
    }

    fn is_border_edge(&self, u: u32, w: u32) -> bool {
        self.adj[u as usize]
            .iter()
            .filter(|&&t| {
                self.tris[t as usize]
                    .iter()
                    .any(|&v| self.pos[v as usize] == w)
            })
            .count()
            == 1
    }

    /// True when a triangle around `u` (and `w`, when given) has an anchor corner (another
    /// region's vertex).
    ///
    /// A vertex next to an anchor is on a region's front. It may collapse along the front,
    /// onto a vertex that shares such a triangle with it (the two are consecutive on the
    /// front), or onto an inner vertex, which then takes its place on the front with the same
    /// foreign neighbours; never onto a vertex elsewhere on a front. The band of border
    /// triangles between two regions then stays a strip between two polylines that each side
    /// decimates in order, so no level of either side can fold it (a boundary collapses the
    /// same way). Vertices pinned for other reasons (junctions) are not anchors: a triangle
    /// with a junction corner is not a border triangle, and counting it let a front vertex
    /// step onto another stretch of the front (the two sides of the band then crossed).
    fn touches_anchor(&self, u: u32, w: Option<u32>) -> bool {
        self.adj[u as usize].iter().any(|&t| {
            let tri = self.tris[t as usize];
            let has = |p: u32| tri.iter().any(|&v| self.pos[v as usize] == p);
            w.is_none_or(has)
                && tri
                    .iter()
                    .any(|&v| self.anchor[self.pos[v as usize] as usize])
        })
    }

    /// True when the two triangles on edge `u-x` use different attribute vertices at either
    /// end.
    fn is_seam_edge(&self, u: u32, x: u32) -> bool {
        let mut first: Option<(u32, u32)> = None;
        for &t in &self.adj[u as usize] {
            let tri = self.tris[t as usize];
            let (Some(ku), Some(kx)) = (
                tri.iter().position(|&v| self.pos[v as usize] == u),
                tri.iter().position(|&v| self.pos[v as usize] == x),
            ) else {
                continue;
            };
            let wedges = (tri[ku], tri[kx]);
            match first {
                None => first = Some(wedges),
                Some(f) if f != wedges => return true,
                Some(_) => {}
            }
        }
        false
    }

    /// The neighbours `x` of `u` whose edge `u-x` is a [seam edge](Self::is_seam_edge), sorted,
    /// into `out` (cleared; empty when the mesh has no seams): one pass over `u`'s triangles,
    /// whose corners go through `corners` (a buffer).
    fn seam_neighbors_into(&self, u: u32, out: &mut Vec<u32>, corners: &mut Vec<(u32, u32, u32)>) {
        out.clear();
        corners.clear();
        if !self.has_seams {
            return;
        }
        for &t in &self.adj[u as usize] {
            let tri = self.tris[t as usize];
            if let Some(k) = tri.iter().position(|&v| self.pos[v as usize] == u) {
                for j in [(k + 1) % 3, (k + 2) % 3] {
                    corners.push((self.pos[tri[j] as usize], tri[k], tri[j]));
                }
            }
        }
        corners.sort_unstable();
        for pair in corners.windows(2) {
            if pair[0].0 == pair[1].0 && pair[0] != pair[1] && out.last() != Some(&pair[0].0) {
                out.push(pair[0].0);
            }
        }
    }

    /// True when any edge at `u` is a seam edge.
    fn touches_seam(&self, u: u32, scratch: &mut Scratch) -> bool {
        let mut neighbors = std::mem::take(&mut scratch.neighbors);
        self.neighbors_into(u, &mut neighbors, scratch);
        let touches = neighbors.iter().any(|&x| self.is_seam_edge(u, x));
        scratch.neighbors = neighbors;
        touches
    }

    /// Every rule a half-edge collapse `u -> w` must pass; fills `scratch_map` with the
    /// attribute-vertex mapping (old -> new) when it does.
    fn is_valid(&mut self, u: u32, w: u32) -> bool {
        let mut scratch = std::mem::take(&mut self.scratch);
        let ok = self.check_collapse(u, w, &mut scratch);
        self.scratch = scratch;
        ok
    }

    fn check_collapse(&self, u: u32, w: u32, scratch: &mut Scratch) -> bool {
        let loose = self.is_loose(u, w);
        let mut apexes = [u32::MAX; 2];
        let map = &mut scratch.map;
        map.clear();
        // Triangles on the edge u-w: they disappear. Their corners tell which attribute
        // vertex at w replaces each attribute vertex at u (seams collapse side by side).
        let mut edge_tris = 0;
        for &t in &self.adj[u as usize] {
            let tri = self.tris[t as usize];
            let (Some(ku), Some(kw)) = (
                tri.iter().position(|&v| self.pos[v as usize] == u),
                tri.iter().position(|&v| self.pos[v as usize] == w),
            ) else {
                continue;
            };
            if edge_tris < 2 {
                apexes[edge_tris] = self.pos[tri[3 - ku - kw] as usize];
            }
            edge_tris += 1;
            let (a, b) = (tri[ku], tri[kw]);
            match map.iter().find(|m| m.0 == a) {
                // A permissive collapse keeps the first (a non-manifold edge's triangles may
                // pair an attribute vertex with several).
                Some(&(_, existing)) if existing != b && !loose => return false,
                Some(_) => {}
                None => map.push((a, b)),
            }
        }
        if edge_tris == 0 {
            return self.check_pair(u, w, scratch);
        }
        // A step's records hold at most 255 removed triangles (`Fields::MAX_BITS`).
        if edge_tris > 2 && (!loose || edge_tris > MAX_STEP_ITEMS) {
            return false;
        }
        // A permissive collapse never takes the last triangles: a mesh keeps at least one.
        if loose && self.live_triangles <= edge_tris {
            return false;
        }
        // Never erase a whole component (w must keep at least one triangle)...
        let last = self.adj[u as usize].len() + self.adj[w as usize].len() == 2 * edge_tris;
        // ...unless the topology compromise lets a part vanish: u's only two triangles are a
        // tetrahedron folded flat, the same three positions facing each other.
        let flat = (!self.pairs.is_empty() || loose)
            && self.adj[u as usize].len() == 2
            && edge_tris == 2
            && apexes[0] == apexes[1];
        if flat {
            return true;
        }
        if last {
            // Permissive: a small part may go, the edge's triangles were all it had.
            return loose;
        }
        // A vertex on an attribute seam (or at the end of one) moves only along the seam;
        // anything else would drag one side's attributes across to the other.
        if !loose && self.has_seams && self.touches_seam(u, scratch) && !self.is_seam_edge(u, w) {
            return false;
        }
        // Link condition: the only common neighbours of u and w are the apexes of the edge's
        // triangles. Anything else would pinch the surface into a non-manifold edge (which
        // the permissive tail allows).
        let stamp = scratch.next_stamp();
        if !(loose && self.pinch) {
            for &t in &self.adj[w as usize] {
                for &v in &self.tris[t as usize] {
                    scratch.mark[self.pos[v as usize] as usize] = stamp;
                }
            }
            for &t in &self.adj[u as usize] {
                for &v in &self.tris[t as usize] {
                    let x = self.pos[v as usize];
                    if x != u && x != w && scratch.mark[x as usize] == stamp && !apexes.contains(&x)
                    {
                        return false;
                    }
                }
            }
        }
        let pu = self.points[u as usize];
        let pw = self.points[w as usize];
        for &t in &self.adj[u as usize] {
            let tri = self.tris[t as usize];
            let (k, a, b) = others(tri, &self.pos, u).expect("adjacency is consistent");
            if a == w || b == w {
                continue;
            }
            // Every attribute vertex at u needs a partner at w, or a seam would tear; the
            // permissive tail gives it the one at w that costs the least attribute error.
            if !scratch.map.iter().any(|m| m.0 == tri[k]) {
                if !loose {
                    return false;
                }
                let partner = self.partner(tri[k], w);
                if partner == u32::MAX {
                    return false;
                }
                scratch.map.push((tri[k], partner));
            }
            if loose {
                // A triangle that lands on one already there (a part folding flat on its way
                // out) turns over by design; any other must not.
                let lands = self.adj[w as usize].iter().any(|&s| {
                    let o = self.tris[s as usize];
                    let has = |p: u32| o.iter().any(|&v| self.pos[v as usize] == p);
                    has(a) && has(b)
                });
                let (pa, pb) = (self.points[a as usize], self.points[b as usize]);
                if !lands
                    && (self.turns_by(pu, pw, pa, pb, self.options.min_normal_cos.min(0.0))
                        || self.faces_away(t, pw, pa, pb))
                {
                    return false;
                }
                continue;
            }
            // No triangle (w, a, b) may exist already (the tetrahedron case). After the link
            // condition, only a triangle spanning both apexes can.
            let duplicate = apexes.contains(&a)
                && apexes.contains(&b)
                && self.adj[w as usize].iter().any(|&s| {
                    let o = self.tris[s as usize];
                    let has = |p: u32| o.iter().any(|&v| self.pos[v as usize] == p);
                    has(a) && has(b)
                });
            if duplicate {
                // A closed tetrahedron (u in three triangles, all of it) may fold flat on its
                // way out (topology compromise): its other two triangles come onto the same
                // positions facing each other, every edge still used once each way.
                return !self.pairs.is_empty() && self.adj[u as usize].len() == 3;
            }
            // No flip: the moved triangle must keep facing the same way.
            let (pa, pb) = (self.points[a as usize], self.points[b as usize]);
            if self.turns(pu, pw, pa, pb) || self.faces_away(t, pw, pa, pb) {
                return false;
            }
            // Nor wherever another region, built before this one, takes the corners it owns.
            if !self.band.is_empty() && self.turns_in_band(t, pu, pw, a, b) {
                return false;
            }
        }
        // A step's records hold at most 256 vertex pairs: the attribute vertices a permissive
        // collapse moves, and the corners it pins where it moves none (at most two a removed
        // triangle).
        scratch.map.len() + 2 * edge_tris <= MAX_STEP_ITEMS
    }

    /// Whether the permissive rules ([`BuildOptions::permissive`]) apply to collapsing `u`
    /// onto `w`: they are on, and neither is next to another region's vertex (region borders
    /// keep the strict rules, which keep them crack-free).
    #[inline]
    fn is_loose(&self, u: u32, w: u32) -> bool {
        self.permissive && self.off_fronts(u, w)
    }

    /// Neither `u` nor `w` is next to another region's vertex.
    #[inline]
    fn off_fronts(&self, u: u32, w: u32) -> bool {
        self.anchor.is_empty() || !(self.touches_anchor(u, None) || self.touches_anchor(w, None))
    }

    /// The attribute vertex at position `w` that attribute vertex `a` (at the vertex that
    /// goes) costs the least to become, by `a`'s attribute quadric at `w`; without attribute
    /// terms, the smallest.
    fn partner(&self, a: u32, w: u32) -> u32 {
        let s = self.attribute_stride;
        let pw = self.points[w as usize];
        let mut best = (f64::INFINITY, u32::MAX);
        for &t in &self.adj[w as usize] {
            for &b in &self.tris[t as usize] {
                if self.pos[b as usize] != w {
                    continue;
                }
                let cost = if s == 0 {
                    0.0
                } else {
                    let values = &self.attributes[b as usize * s..(b as usize + 1) * s];
                    self.attribute_quadrics.error(a, pw, values)
                };
                if (cost, b) < best {
                    best = (cost, b);
                }
            }
        }
        best.1
    }

    /// The attribute error of the attribute vertices at `u` that no triangle on the edge
    /// `u`-`w` pairs (only the permissive tail moves those, onto their
    /// [`partner`](Self::partner)s); `wedges` as [`attribute_error`](Self::attribute_error)
    /// takes them.
    fn unpaired_attribute_error(&self, u: u32, w: u32, wedges: &[(u32, u32, u32)]) -> f64 {
        let s = self.attribute_stride;
        if s == 0 || !self.is_loose(u, w) {
            return 0.0;
        }
        let pw = self.points[w as usize];
        let mut seen: Vec<u32> = wedges
            .iter()
            .filter(|&&(p, ..)| p == w)
            .map(|&(_, a, _)| a)
            .collect();
        let mut error = 0.0;
        for &(_, a, _) in wedges {
            if seen.contains(&a) {
                continue;
            }
            seen.push(a);
            let b = self.partner(a, w);
            if b != u32::MAX {
                let values = &self.attributes[b as usize * s..(b as usize + 1) * s];
                error += self.attribute_quadrics.error(a, pw, values);
            }
        }
        error
    }

    /// The terms of collapsing `u` onto `w` beyond its quadric and local errors: the paired
    /// attribute vertices' ([`attribute_error`](Self::attribute_error)), the unpaired ones'
    /// across seams, and what a part that goes leaves uncovered
    /// ([`erase_error`](Self::erase_error)).
    #[inline]
    fn extra_cost(&self, u: u32, w: u32, wedges: &[(u32, u32, u32)]) -> f64 {
        self.attribute_error(w, wedges)
            + self.unpaired_attribute_error(u, w, wedges)
            + self.erase_error(u, w)
    }

    /// With [`BuildOptions::permissive`], a collapse that leaves neither `u` nor `w` a
    /// triangle (every triangle around either lies on the edge `u`-`w`) takes a part away: a
    /// sheet's last triangle, or a part folded flat. Its planes all hold `w`, so its quadric
    /// costs nothing; it costs the squared length of the edge instead, the size of what goes.
    /// 0 for any other collapse (an ear on an open border keeps `w`'s other triangles).
    fn erase_error(&self, u: u32, w: u32) -> f64 {
        if !self.permissive {
            return 0.0;
        }
        let on_edge = |t: &u32, x: u32| {
            self.tris[*t as usize]
                .iter()
                .any(|&v| self.pos[v as usize] == x)
        };
        let erases = self.adj[u as usize].iter().all(|t| on_edge(t, w))
            && self.adj[w as usize].iter().all(|t| on_edge(t, u));
        if erases {
            self.points[u as usize].distance_squared(self.points[w as usize])
        } else {
            0.0
        }
    }

    /// The rules for collapsing `u` onto `w` of another part, with no edge between them (the
    /// topology compromise): `w` is one of `u`'s pair candidates, neither has an attribute
    /// seam (one attribute vertex each, mapped onto each other), they share no neighbour (the
    /// fans would share an edge), and no moved triangle turns over.
    fn check_pair(&self, u: u32, w: u32, scratch: &mut Scratch) -> bool {
        if !self.pairs.get(u as usize).is_some_and(|p| p.contains(&w)) {
            return false;
        }
        let wedge = |p: u32| -> Option<u32> {
            let mut one = None;
            for &t in &self.adj[p as usize] {
                for &v in &self.tris[t as usize] {
                    if self.pos[v as usize] == p {
                        match one {
                            None => one = Some(v),
                            Some(o) if o != v => return None,
                            Some(_) => {}
                        }
                    }
                }
            }
            one
        };
        let (Some(a), Some(b)) = (wedge(u), wedge(w)) else {
            return false;
        };
        let stamp = scratch.next_stamp();
        for &t in &self.adj[w as usize] {
            for &v in &self.tris[t as usize] {
                scratch.mark[self.pos[v as usize] as usize] = stamp;
            }
        }
        let (pu, pw) = (self.points[u as usize], self.points[w as usize]);
        for &t in &self.adj[u as usize] {
            let tri = self.tris[t as usize];
            if tri
                .iter()
                .any(|&v| scratch.mark[self.pos[v as usize] as usize] == stamp)
            {
                return false;
            }
            let (_, a, b) = others(tri, &self.pos, u).expect("adjacency is consistent");
            let (pa, pb) = (self.points[a as usize], self.points[b as usize]);
            if self.turns(pu, pw, pa, pb) || self.faces_away(t, pw, pa, pb) {
                return false;
            }
        }
        scratch.map.clear();
        scratch.map.push((a, b));
        true
    }

    /// True when moving the corner at `pu` of triangle `(pu, pa, pb)` to `pw` turns it by more
    /// than [`BuildOptions::min_normal_cos`] allows, or leaves it without area.
    #[inline]
    fn turns(&self, pu: DVec3, pw: DVec3, pa: DVec3, pb: DVec3) -> bool {
        self.turns_by(pu, pw, pa, pb, self.options.min_normal_cos)
    }

    /// [`turns`](Self::turns) with the cosine bound `min_cos`.
    #[inline]
    fn turns_by(&self, pu: DVec3, pw: DVec3, pa: DVec3, pb: DVec3, min_cos: f64) -> bool {
        let before = (pa - pu).cross(pb - pu);
        let after = (pa - pw).cross(pb - pw);
        let dot = before.dot(after);
        let lengths = (before.length_squared() * after.length_squared()).sqrt();
        dot <= min_cos * lengths || lengths == 0.0
    }

    /// True when triangle `t`, its corners moved to `pw`, `pa` and `pb` (in its winding),
    /// faces away from its full-detail side: a series of collapses that each turn it by
    /// less than [`turns`](Self::turns) allows can still turn it over.
    #[inline]
    fn faces_away(&self, t: u32, pw: DVec3, pa: DVec3, pb: DVec3) -> bool {
        let corners = &self.mesh.indices[3 * t as usize..3 * t as usize + 3];
        let [p0, p1, p2] = [0, 1, 2].map(|k| self.mesh.positions[corners[k] as usize].as_dvec3());
        (pa - pw).cross(pb - pw).dot((p1 - p0).cross(p2 - p0)) <= 0.0
    }

    /// [`turns`](Self::turns) at every level of the other region that owns `a` or `b`, with
    /// their representatives there in their place (both are in one region: a vertex next to
    /// two others is pinned); and whether the moved triangle `t` then faces away from where
    /// it faced at full detail (each region checks its own steps, so only this keeps the
    /// sum of both sides' turns from flipping it). A level where the two have met is
    /// skipped: that region has removed the triangle.
    fn turns_in_band(&self, t: u32, pu: DVec3, pw: DVec3, a: u32, b: u32) -> bool {
        let (chain_a, chain_b) = (&self.band[a as usize], &self.band[b as usize]);
        if chain_a.is_empty() && chain_b.is_empty() {
            return false;
        }
        let at = |chain: &[(u32, DVec3)], fixed: u32, level: u32| {
            chain
                .iter()
                .take_while(|&&(from, _)| from <= level)
                .last()
                .map_or(self.points[fixed as usize], |&(_, p)| p)
        };
        chain_a.iter().chain(chain_b).any(|&(level, _)| {
            let (pa, pb) = (at(chain_a, a, level), at(chain_b, b, level));
            if (pa - pb).length_squared() == 0.0 || (pa - pu).cross(pb - pu).length_squared() == 0.0
            {
                return false;
            }
            self.turns(pu, pw, pa, pb) || self.faces_away(t, pw, pa, pb)
        })
    }

    /// Phase 4: queues the cheapest collapse out of `u`. With `validate`, the cheapest one
    /// that passes every rule; without, the cheapest by cost alone, checked when popped
    /// (most vertices are re-ranked several times before their turn comes).
    ///
    /// `ring`, when given, is `u`'s neighbour positions (the caller has them at hand).
    fn rank(&mut self, u: u32, validate: bool, ring: Option<&[u32]>) {
        self.heap.remove(u);
        let chosen = self.choose(u, validate, ring);
        self.full_rank_due[u as usize] = validate;
        if let Some((cost, w, runner_up)) = chosen {
            self.target[u as usize] = w;
            self.runner_up[u as usize] = runner_up;
            self.heap.set(u, cost.to_bits());
        }
    }

    /// The collapse [`rank`](Self::rank) queues for `u`: `(cost, target)`, or `None`.
    ///
    /// Also returns the lowest [`level`](Self::level)led cost among the other candidates
    /// (`f64::INFINITY` when there is none), which [`rerank`](Self::rerank) uses; a
    /// candidate that could not win counts with its (scaled) quadric error alone, a lower
    /// bound.
    fn choose(&mut self, u: u32, validate: bool, ring: Option<&[u32]>) -> Option<(f64, u32, f64)> {
        // Vertices with more than 21,845 triangles are never removed (a step would rewrite more
        // than 65,535 corners): a guard against huge fans, whose ring scans grow quadratic.
        // Steps past 4,095 corners only make the records wide.
        let front = !self.anchor.is_empty() && self.touches_anchor(u, None);
        let movable = match self.kind[u as usize] {
            Kind::Manifold | Kind::Border => true,
            Kind::Complex => self.permissive && !front,
            Kind::Pinned => false,
        };
        if !movable
            || self.adj[u as usize].is_empty()
            || 3 * self.adj[u as usize].len() > usize::from(u16::MAX)
        {
            return None;
        }
        let mut fan = std::mem::take(&mut self.scratch.fan);
        fan.clear();
        if self.local_weight > 0.0 {
            self.fan_into(u, &mut fan);
        }
        let mut nu = std::mem::take(&mut self.scratch.neighbors);
        nu.clear();
        if let Some(ring) = ring {
            nu.extend_from_slice(ring);
        } else if self.local_weight > 0.0 {
            // The fan's far edges hold every neighbour.
            let stamp = self.scratch.next_stamp();
            for &(a, b, _, _) in &fan {
                for q in [a, b] {
                    if self.scratch.mark[q as usize] != stamp {
                        self.scratch.mark[q as usize] = stamp;
                        nu.push(q);
                    }
                }
            }
        } else {
            let mut scratch = std::mem::take(&mut self.scratch);
            self.neighbors_into(u, &mut nu, &mut scratch);
            self.scratch = scratch;
        }
        let mut wedges = std::mem::take(&mut self.scratch.wedges);
        self.wedges_into(u, &mut wedges);
        let mut candidates = std::mem::take(&mut self.candidates);
        candidates.clear();
        // The seam rule of `check_collapse`, which only u's triangles decide: a vertex on a
        // seam never goes off it, so those candidates are left out here rather than chosen
        // (their attribute error counts one side only) and refused at validation.
        let mut seams = std::mem::take(&mut self.scratch.seams);
        let mut corners = std::mem::take(&mut self.scratch.corners);
        self.seam_neighbors_into(u, &mut seams, &mut corners);
        self.scratch.corners = corners;
        for &w in &nu {
            if front && !self.touches_anchor(u, Some(w)) && self.touches_anchor(w, None) {
                continue;
            }
            // `is_loose(u, w)`, with `u`'s side known.
            let loose = self.permissive
                && !front
                && (self.anchor.is_empty() || !self.touches_anchor(w, None));
            if !seams.is_empty() && seams.binary_search(&w).is_err() && !loose {
                continue;
            }
            if let Some(e) = self.quadric_cost(u, w) {
                candidates.push((e, w));
            }
        }
        if let Some(pairs) = self.pairs.get(u as usize) {
            for &w in pairs {
                if !self.adj[w as usize].is_empty()
                    && !nu.contains(&w)
                    && let Some(e) = self.quadric_cost(u, w)
                {
                    candidates.push((e, w));
                }
            }
        }
        // The cheapest quadric error first. The attribute and local errors only add, so a
        // candidate whose quadric error alone, or with its attribute error, levels above the
        // best cost so far cannot win: it keeps that as a lower bound (all a runner-up needs;
        // without a local weight the second is the cost). The local error, the dearest, comes
        // last.
        let first = (0..candidates.len())
            .min_by(|&i, &j| candidates[i].0.total_cmp(&candidates[j].0))
            .unwrap_or(0);
        let mut best = f64::INFINITY;
        for i in (first..candidates.len()).chain(0..first) {
            let (q, w) = candidates[i];
            let bound = settle(q);
            candidates[i].0 = if !validate && self.level(bound) > best {
                bound
            } else {
                let q = q + self.extra_cost(u, w, &wedges);
                let bound = settle(q);
                if !validate && self.local_weight > 0.0 && self.level(bound) > best {
                    bound
                } else {
                    let cost = self.cost(u, w, q, &fan);
                    best = best.min(self.level(cost));
                    cost
                }
            };
        }
        self.scratch.neighbors = nu;
        self.scratch.fan = fan;
        self.scratch.wedges = wedges;
        self.scratch.seams = seams;
        let chosen = if validate {
            candidates.sort_unstable_by(|a, b| self.order(*a, *b));
            candidates
                .iter()
                .copied()
                .find(|&(_, w)| self.is_valid(u, w))
        } else {
            candidates.iter().copied().min_by(|a, b| self.order(*a, *b))
        };
        let chosen = chosen.map(|(cost, w)| {
            let runner_up = candidates
                .iter()
                .filter(|c| c.1 != w)
                .map(|c| self.level(c.0))
                .fold(f64::INFINITY, f64::min);
            (cost, w, runner_up)
        });
        self.candidates = candidates;
        chosen
    }

    /// The quadric error of moving `u` onto its neighbour `w`, scaled by `u`'s
    /// [`weight_exponent`](BuildOptions::weight_exponent) factor, or `None` when the kinds
    /// forbid it (the front rule is the caller's); [`cost`](Self::cost) adds the local
    /// error.
    #[inline]
    fn quadric_cost(&self, u: u32, w: u32) -> Option<f64> {
        if self.kind[w as usize] == Kind::Pinned
            || (self.kind[u as usize] == Kind::Border
                && !self.is_border_edge(u, w)
                && !self.is_loose(u, w))
        {
            return None;
        }
        // The error of moving u onto w, measured against u's planes (everything already
        // merged into u): meshoptimizer's choice, which beat the merged quadric
        // (Q_u + Q_w)(p_w) on Hausdorff distance in `aslod compare` on the bunny.
        Some(self.quadrics[u as usize].error(self.points[w as usize]) * self.scale[u as usize])
    }

    /// The error the table records for collapsing `u` onto `w`: the quadric's mean error
    /// (unscaled) plus [`local_weight`](BuildOptions::local_weight) times the local error,
    /// [`settle`]d. Without a [`weight_exponent`](BuildOptions::weight_exponent) it is the
    /// collapse's cost.
    fn table_error(&mut self, u: u32, w: u32, cost: f64) -> f64 {
        if self.weight_exponent == 0.0 && self.attribute_stride == 0 {
            return cost;
        }
        let quadric =
            self.quadrics[u as usize].error(self.points[w as usize]) + self.erase_error(u, w);
        if self.local_weight == 0.0 {
            return settle(quadric);
        }
        let mut fan = std::mem::take(&mut self.scratch.fan);
        self.fan_into(u, &mut fan);
        let local = self.local_weight * self.local_error(u, w, &fan);
        self.scratch.fan = fan;
        settle(quadric + local)
    }

    /// The cost of collapsing `u` onto `w`, whose quadric and
    /// [attribute](Self::attribute_error) errors sum to `errors`: that plus
    /// [`local_weight`](BuildOptions::local_weight) times the
    /// [`local_error`](Self::local_error) over `u`'s `fan`, [`settle`]d.
    #[inline]
    fn cost(&self, u: u32, w: u32, errors: f64, fan: &[(u32, u32, DVec3, DVec3)]) -> f64 {
        if self.local_weight > 0.0 {
            settle(errors + self.local_weight * self.local_error(u, w, fan))
        } else {
            settle(errors)
        }
    }

    /// Every corner next to `u`'s in its triangles, as `(position, attribute vertex at u,
    /// attribute vertex there)`, into `out` (cleared; left empty when no attribute term is
    /// on): the attribute-vertex maps of all of `u`'s collapses at once.
    fn wedges_into(&self, u: u32, out: &mut Vec<(u32, u32, u32)>) {
        out.clear();
        if self.attribute_stride == 0 {
            return;
        }
        for &t in &self.adj[u as usize] {
            let tri = self.tris[t as usize];
            if let Some((k, a, b)) = others(tri, &self.pos, u) {
                out.push((a, tri[k], tri[(k + 1) % 3]));
                out.push((b, tri[k], tri[(k + 2) % 3]));
            }
        }
    }

    /// The attribute error of collapsing `u` onto `w`, in the units of costs, from `u`'s
    /// [`wedges`](Self::wedges_into): for each attribute vertex at `u`, its
    /// [attribute quadric](AttributeQuadrics) at `w`'s place with the values of the
    /// attribute vertex at `w` that takes its place (as `check_collapse` maps them, from the
    /// triangles on the edge), summed. 0 when no attribute term is on, or `u` and `w` share
    /// no triangle.
    fn attribute_error(&self, w: u32, wedges: &[(u32, u32, u32)]) -> f64 {
        let s = self.attribute_stride;
        if s == 0 {
            return 0.0;
        }
        let pw = self.points[w as usize];
        let mut error = 0.0;
        let mut seen = [u32::MAX; 2];
        for &(p, a, b) in wedges {
            if p != w || seen.contains(&a) {
                continue;
            }
            if seen[0] == u32::MAX {
                seen[0] = a;
            } else {
                seen[1] = a;
            }
            let values = &self.attributes[b as usize * s..(b as usize + 1) * s];
            error += self.attribute_quadrics.error(a, pw, values);
        }
        error
    }

    /// The far edge of every triangle around `u`, in winding order, into `out` (cleared).
    fn fan_into(&self, u: u32, out: &mut Vec<(u32, u32, DVec3, DVec3)>) {
        out.clear();
        out.extend(self.adj[u as usize].iter().map(|&t| {
            let (_, a, b) =
                others(self.tris[t as usize], &self.pos, u).expect("adjacency is consistent");
            (a, b, self.points[a as usize], self.points[b as usize])
        }));
    }

    /// The local error of moving `u` onto `w`: the largest squared distance from `u` to the
    /// plane of a triangle of its fan once moved (the triangles on the edge `u`-`w` go). It
    /// is the height of the tetrahedron each moved triangle sweeps, so it also measures how
    /// far the fan turns; it depends only on `u`'s current triangles, whose far edges are
    /// `fan`.
    #[inline]
    fn local_error(&self, u: u32, w: u32, fan: &[(u32, u32, DVec3, DVec3)]) -> f64 {
        let pu = self.points[u as usize];
        let pw = self.points[w as usize];
        let mut worst: f64 = 0.0;
        for &(a, b, pa, pb) in fan {
            if a == w || b == w {
                continue;
            }
            let normal = (pa - pw).cross(pb - pw);
            let area_sq = normal.length_squared();
            if area_sq > 0.0 {
                let volume = normal.dot(pu - pw);
                worst = worst.max(volume * volume / area_sq);
            }
        }
        worst
    }

    /// The order of two candidates `(cost, target)`, cheapest first.
    ///
    /// Equal costs go to the target that has absorbed the least, so a flat face does not
    /// pour into one vertex. Costs are `settle`d, and costs below (1e-7 of the diagonal)²,
    /// the rounding of f32 coordinates, count as 0 (with `regularization = 0` every
    /// flat-face cost is that; with the default it is `1e-7 × edge²`, under this floor only
    /// for edges shorter than 3e-4 of the diagonal, where coordinate rounding decides).
    #[inline]
    fn order(&self, a: (f64, u32), b: (f64, u32)) -> std::cmp::Ordering {
        let weight = |w: u32| self.quadrics[w as usize].weight();
        self.level(a.0)
            .total_cmp(&self.level(b.0))
            .then_with(|| weight(a.1).total_cmp(&weight(b.1)))
            .then(a.1.cmp(&b.1))
    }

    /// A cost as [`order`](Self::order) compares it: below the floor, 0.
    #[inline]
    fn level(&self, cost: f64) -> f64 {
        if cost <= self.cost_floor { 0.0 } else { cost }
    }

    /// Phase 5: removes the edge's triangles, moves u's corners to w, records both.
    fn perform(&mut self, u: u32, w: u32, error: f64) {
        let rewrite_start = self.rewrites.len();
        let removed_start = self.removed.len();
        let map = std::mem::take(&mut self.scratch.map);
        let mut adj_u = std::mem::take(&mut self.adj_u);
        self.adj.take(u, &mut adj_u);
        self.moved_ring.clear();
        for &t in &adj_u {
            let tri = self.tris[t as usize];
            self.moved_ring
                .extend(tri.iter().map(|&v| self.pos[v as usize]));
            let on_edge = tri.iter().any(|&v| self.pos[v as usize] == w);
            if on_edge {
                self.alive[t as usize] = false;
                self.live_triangles -= 1;
                self.removed.push(t);
                for &v in &tri {
                    let p = self.pos[v as usize];
                    if p != u {
                        self.adj.remove(p, t);
                    }
                }
            } else {
                for (k, &v) in tri.iter().enumerate() {
                    if self.pos[v as usize] == u {
                        let new = map
                            .iter()
                            .find(|m| m.0 == v)
                            .map(|m| m.1)
                            .expect("validated collapse maps every wedge");
                        self.tris[t as usize][k] = new;
                        self.rewrites.push((t, k as u8, v, new));
                    }
                }
                self.adj.push(w, t);
            }
        }
        let removed = std::mem::take(&mut self.removed);
        self.pin_survivors(&removed[removed_start..], u, rewrite_start);
        self.removed = removed;
        let step = self.collapses.len() as u32;
        self.moves
            .extend(map.iter().map(|&(old, new)| (step, old, new)));
        if self.attribute_stride > 0 {
            for &(old, new) in &map {
                self.attribute_quadrics.merge(old, new);
            }
        }
        self.scratch.map = map;
        self.adj_u = adj_u;
        let q = self.quadrics[u as usize];
        self.quadrics[w as usize].add(&q);
        self.scale[w as usize] = self.scale_of(w);
        let error = (error.sqrt() * self.inv_diagonal) as f32;
        let previous = self.collapses.last().map_or(0.0, |c| c.error);
        self.collapses.push(Collapse {
            removed: removed_start..self.removed.len(),
            rewrites: rewrite_start..self.rewrites.len(),
            // The table is monotone: a level's error is the largest collapse error so far.
            error: error.max(previous),
            own_error: error,
            moved: [u, w],
        });
        self.heap.remove(u);
    }

    /// Records an identity rewrite (a corner keeps its vertex) on a surviving triangle of every
    /// vertex of the removed triangles that no moved corner of this collapse leaves in a
    /// changed triangle: the far corners of an ear (a border vertex's only triangle, which
    /// moves no corner) or of a part that vanishes (the topology compromise).
    ///
    /// A uniform level never notices, but a variable-resolution cut does: the rewrite makes
    /// that triangle one the collapse changes, so when the collapse is not performed (its
    /// removed triangles stay drawn), the triangle keeps its version, and every later collapse
    /// that would move the vertex from under the kept triangles is blocked (MOM's flag rule,
    /// `refine`). Without it a kept ear would open a crack along its far edge. An ordinary
    /// collapse needs none: the triangles across its removed ones are changed and hold every
    /// such vertex.
    fn pin_survivors(&mut self, removed: &[u32], u: u32, rewrite_start: usize) {
        let mut loose: Vec<u32> = Vec::new();
        for &t in removed {
            for &v in &self.tris[t as usize] {
                let p = self.pos[v as usize];
                // Pinned vertices never move, nor do complex ones before the permissive tail:
                // nothing to keep them from.
                let held = p == u
                    || self.kind[p as usize] == Kind::Pinned
                    || (self.kind[p as usize] == Kind::Complex && !self.permissive)
                    || loose.contains(&p)
                    || self.rewrites[rewrite_start..].iter().any(|&(s, ..)| {
                        self.tris[s as usize]
                            .iter()
                            .any(|&x| self.pos[x as usize] == p)
                    });
                if !held {
                    loose.push(p);
                }
            }
        }
        while let Some(&p) = loose.first() {
            // A live triangle of p, one that also holds the other loose vertices if there is
            // one (an ear's neighbour across its far edge holds both).
            let holds = |t: u32| {
                loose
                    .iter()
                    .filter(|&&q| {
                        self.tris[t as usize]
                            .iter()
                            .any(|&x| self.pos[x as usize] == q)
                    })
                    .count()
            };
            let Some(t) = self.adj[p as usize]
                .iter()
                .copied()
                .filter(|&t| self.alive[t as usize])
                .max_by_key(|&t| (holds(t), std::cmp::Reverse(t)))
            else {
                loose.remove(0);
                continue;
            };
            let k = self.tris[t as usize]
                .iter()
                .position(|&x| self.pos[x as usize] == p)
                .expect("adjacency is consistent");
            let v = self.tris[t as usize][k];
            self.rewrites.push((t, k as u8, v, v));
            let tri = self.tris[t as usize];
            loose.retain(|&q| !tri.iter().any(|&x| self.pos[x as usize] == q));
        }
    }

    /// Brings the queued collapse of `x`, a neighbour of `w` after `u` collapsed onto `w`, up
    /// to date, doing what [`rank`](Self::rank)`(x, false)` would do (`moved_ring` holds the
    /// positions around `u` before the collapse).
    ///
    /// Points do not move, and only `w`'s quadric changed, so every candidate of `x` costs
    /// what it did (the weight exponent's factor depends on `x`'s own quadric only); `w` only
    /// lost ground (its weight, the tie-break, grew). A vertex that was
    /// not next to `u` keeps its triangles and candidates: its choice stands. One that was
    /// next to `u` lost the candidate `u` and may have gained `w` (or `w`'s kind rule may
    /// have changed): if its choice was neither, the rest of its candidates are as they
    /// were, so the choice stands unless `w` now beats it. A choice of `w` stands while its
    /// cost stays below every other candidate's (`runner_up`), since weights only break
    /// ties. Ranked in full instead: a choice of `w` that could tie, a choice of `u`, one
    /// made among the valid candidates only (validity depends on the neighbours' triangles,
    /// and an unvalidated rank resets it), a vertex out of the queue, one whose entry may be
    /// stale (pinched off an earlier collapse's ring, so not re-ranked then; both are
    /// `full_rank_due`), one on or next to a front (the front rule looks at the
    /// neighbours' triangles), and, with a [`local_weight`](BuildOptions::local_weight),
    /// attribute terms or seams, one that was next to `u` (its fan changed, and with it every
    /// local error, which attribute vertex takes each of its places and which of its edges
    /// are seams).
    fn rerank(&mut self, x: u32, u: u32, w: u32) {
        if self.permissive {
            // A permissive collapse's partners, kinds and erasures depend on the target's
            // triangles, which the collapse changed: rank in full.
            self.rank(x, false, None);
            return;
        }
        let xi = x as usize;
        let moved = self.moved_ring.contains(&x);
        let target = self.target[xi];
        let front = !self.anchor.is_empty()
            && (self.touches_anchor(x, None)
                || (moved && (self.anchor[u as usize] || self.anchor[w as usize])));
        // The local error looks at x's triangles, which a vertex next to u no longer has; the
        // attribute error at which attribute vertex of a neighbour takes each of x's places,
        // and the seam rule at which of x's edges are seams: the triangles u gave w change
        // both.
        let fan_changed =
            moved && (self.local_weight > 0.0 || self.attribute_stride > 0 || self.has_seams);
        if self.full_rank_due[xi] || front || fan_changed || !self.heap.contains(x) {
            self.rank(x, false, None);
            return;
        }
        if target == w {
            // Its cost to w is as it was (the queue's key); w's weight only matters against an
            // equal cost. Only the edge x-w of a vertex next to u may have changed its kind.
            let cost = f64::from_bits(self.heap.key(x));
            let allowed = !moved || self.kind[xi] != Kind::Border || self.is_border_edge(x, w);
            if !(allowed && self.level(cost) < self.runner_up[xi]) {
                self.rank(x, false, None);
            }
            return;
        }
        if !moved {
            return;
        }
        if target == u || self.adj[xi].is_empty() {
            self.rank(x, false, None);
            return;
        }
        // Not reached with a local weight, attribute terms or seams: x's fan changed, so it
        // was ranked in full above.
        debug_assert!(self.local_weight == 0.0 && self.attribute_stride == 0 && !self.has_seams);
        let Some(cost) = self.quadric_cost(x, w).map(settle) else {
            return;
        };
        let current = f64::from_bits(self.heap.key(x));
        if self.order((cost, w), (current, target)).is_lt() {
            self.target[xi] = w;
            self.heap.set(x, cost.to_bits());
            self.runner_up[xi] = self.level(current);
        } else {
            self.runner_up[xi] = self.runner_up[xi].min(self.level(cost));
        }
    }

    /// Unit tests check every [`rerank`](Self::rerank) against a full rank (and that the
    /// runner-up bound holds).
    #[cfg(test)]
    fn check_rerank(&mut self, x: u32) {
        let queued = self
            .heap
            .contains(x)
            .then(|| (self.heap.key(x), self.target[x as usize]));
        let fresh = self.choose(x, false, None);
        if let Some((_, chosen, runner_up)) = fresh {
            // Against every other candidate's full cost: choose prices those that cannot
            // win by their quadric error alone, in an order that depends on the ring's.
            let mut fan = Vec::new();
            self.fan_into(x, &mut fan);
            let mut wedges = Vec::new();
            self.wedges_into(x, &mut wedges);
            let exact = self
                .candidates
                .iter()
                .filter(|c| c.1 != chosen)
                .map(|&(_, y)| {
                    let q = self.quadric_cost(x, y).expect("a candidate is allowed");
                    let q = q + self.extra_cost(x, y, &wedges);
                    self.level(self.cost(x, y, q, &fan))
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                runner_up <= exact,
                "vertex {x}: choose's runner-up is not a bound"
            );
            assert!(
                self.runner_up[x as usize] <= exact,
                "vertex {x}: the runner-up bound is above the runner-up"
            );
        }
        let fresh = fresh.map(|(cost, w, _)| (cost.to_bits(), w));
        assert_eq!(queued, fresh, "vertex {x} kept a stale collapse");
    }

    fn run(&mut self, progress: &mut dyn FnMut(usize, usize)) {
        self.fill_quadrics();
        for u in 0..self.adj.len() as u32 {
            if self.pos[u as usize] == u {
                self.rank(u, false, None);
            }
        }
        let total = self.tris.len();
        let mut ring = Vec::new();
        loop {
            let Some((bits, u)) = self.heap.pop() else {
                // Every collapse that keeps the surface from pinching ran out: go on in the
                // permissive tail, once.
                if self.pinch || !self.permissive {
                    break;
                }
                self.pinch = true;
                for u in 0..self.adj.len() as u32 {
                    if self.pos[u as usize] == u && !self.adj[u as usize].is_empty() {
                        self.rank(u, false, None);
                    }
                }
                continue;
            };
            if self.live_triangles <= self.options.min_triangles {
                break;
            }
            let w = self.target[u as usize];
            // Neighbourhoods change under earlier collapses: check again before acting.
            if !self.is_valid(u, w) {
                self.rank(u, true, None);
                continue;
            }
            let error = self.table_error(u, w, f64::from_bits(bits));
            if (error.sqrt() * self.inv_diagonal) as f32 > self.options.max_error {
                break;
            }
            self.perform(u, w, error);
            self.rerank_after(u, w, &mut ring);
            if self.options.operator == CollapseOperator::Triangle
                && !self.pinch
                && self.live_triangles > self.options.min_triangles
                && let Some((x, error)) = self.apex(w)
                && (error.sqrt() * self.inv_diagonal) as f32 <= self.options.max_error
            {
                self.perform(x, w, error);
                self.rerank_after(x, w, &mut ring);
            }
            if self.collapses.len().is_multiple_of(4096) {
                progress(total - self.live_triangles, total);
            }
        }
        progress(total - self.live_triangles, total);
    }

    /// Re-ranks what collapsing `u` onto `w` changed: `w` and its ring (into `ring`) now,
    /// the other vertices around `u` at their next rank.
    fn rerank_after(&mut self, u: u32, w: u32, ring: &mut Vec<u32>) {
        let mut scratch = std::mem::take(&mut self.scratch);
        self.neighbors_into(w, ring, &mut scratch);
        self.scratch = scratch;
        self.rank(w, false, Some(ring));
        for i in 0..self.moved_ring.len() {
            let p = self.moved_ring[i];
            if p != u && p != w && !ring.contains(&p) {
                self.full_rank_due[p as usize] = true;
            }
        }
        for &x in ring.iter() {
            self.rerank(x, u, w);
            #[cfg(test)]
            self.check_rerank(x);
        }
    }

    /// The triangle collapse's second half, after the last collapse moved a vertex onto
    /// `w`: the apex of one of the triangles it removed, onto `w`, with its table error, when
    /// one may go (the cheaper of two). Every rule of [`choose`](Self::choose) applies, and
    /// [`is_valid`](Self::is_valid) has filled the scratch map for the chosen one.
    fn apex(&mut self, w: u32) -> Option<(u32, f64)> {
        let last = self.collapses.last()?;
        let mut apexes = [u32::MAX; 2];
        for (k, &t) in self.removed[last.removed.clone()]
            .iter()
            .take(2)
            .enumerate()
        {
            apexes[k] = self.tris[t as usize]
                .iter()
                .map(|&v| self.pos[v as usize])
                .find(|&p| p != last.moved[0] && p != w)
                .unwrap_or(u32::MAX);
        }
        let mut eligible: Vec<(f64, u32)> = Vec::with_capacity(2);
        let mut fan = std::mem::take(&mut self.scratch.fan);
        for x in apexes {
            if x == u32::MAX
                || !matches!(self.kind[x as usize], Kind::Manifold | Kind::Border)
                || self.adj[x as usize].is_empty()
                || 3 * self.adj[x as usize].len() > usize::from(u16::MAX)
            {
                continue;
            }
            // The front rule of `choose`.
            if !self.anchor.is_empty()
                && self.touches_anchor(x, None)
                && !self.touches_anchor(x, Some(w))
                && self.touches_anchor(w, None)
            {
                continue;
            }
            let Some(q) = self.quadric_cost(x, w) else {
                continue;
            };
            fan.clear();
            if self.local_weight > 0.0 {
                self.fan_into(x, &mut fan);
            }
            let mut wedges = Vec::new();
            self.wedges_into(x, &mut wedges);
            let q = q + self.extra_cost(x, w, &wedges);
            eligible.push((self.cost(x, w, q, &fan), x));
        }
        self.scratch.fan = fan;
        // The cheaper apex first; the other when the cheaper one may not go.
        eligible.sort_unstable_by(|a, b| self.order(*a, *b));
        for (cost, x) in eligible {
            if self.is_valid(x, w) {
                return Some((x, self.table_error(x, w, cost)));
            }
        }
        None
    }

    /// Phase 6: removal-order layout and packed records.
    ///
    /// Triangles from `owned` on are context: they took part in the checks but are neither
    /// laid out nor recorded.
    ///
    /// `None` when not even the wide records hold the steps (2³¹ corners in all, or a step
    /// past 268 million corners); `build` refuses such meshes before.
    fn finish(self, owned: usize) -> Option<Built> {
        let tri_count = self.tris.len();
        let mut slot = vec![u32::MAX; tri_count];
        let mut order: Vec<u32> = Vec::with_capacity(owned);
        for (t, &alive) in self.alive[..owned].iter().enumerate() {
            if alive {
                order.push(t as u32);
            }
        }
        let base_triangles = order.len();
        for c in self.collapses.iter().rev() {
            for &t in &self.removed[c.removed.clone()] {
                if (t as usize) < owned {
                    order.push(t);
                }
            }
        }
        for (s, &t) in order.iter().enumerate() {
            slot[t as usize] = s as u32;
        }
        // The full-detail index buffer, in slot order, with the original corners.
        let mut indices = Vec::with_capacity(3 * owned);
        for &t in &order {
            indices.extend_from_slice(&self.mesh.indices[3 * t as usize..3 * t as usize + 3]);
        }
        let mut steps = Vec::with_capacity(self.collapses.len());
        let mut corners = Vec::with_capacity(self.rewrites.len());
        let mut pairs: Vec<[u32; 2]> = Vec::with_capacity(self.collapses.len() + 16);
        let mut errors = Vec::with_capacity(self.collapses.len());
        for c in &self.collapses {
            let first_pair = pairs.len();
            let first_corner = corners.len();
            for &(t, k, old, new) in &self.rewrites[c.rewrites.clone()] {
                if t as usize >= owned {
                    continue;
                }
                let pair = match pairs[first_pair..].iter().position(|p| *p == [old, new]) {
                    Some(i) => i,
                    None => {
                        pairs.push([old, new]);
                        pairs.len() - 1 - first_pair
                    }
                };
                let corner = 3 * slot[t as usize] + k as u32;
                corners.push((corner, pair as u32));
            }
            steps.push((
                corners.len() - first_corner,
                pairs.len() - first_pair,
                self.removed[c.removed.clone()]
                    .iter()
                    .filter(|&&t| (t as usize) < owned)
                    .count(),
            ));
            errors.push(error_to_u16(c.error));
        }
        let vertices = self.mesh.vertex_table();
        let records = Unpacked {
            indices,
            steps,
            corners,
            pairs,
        };
        // Regions keep no view-dependent data: their context triangles are not laid out.
        let view = (self.options.view_dependent && owned == tri_count).then(|| {
            let diagonal = self
                .mesh
                .bounds()
                .map_or(0.0, |(lo, hi)| (hi - lo).length());
            ViewData::compute(
                &vertices.positions,
                &records,
                self.collapses.iter().map(|c| c.moved).collect(),
                &self
                    .collapses
                    .iter()
                    .map(|c| c.own_error)
                    .collect::<Vec<_>>(),
                diagonal,
            )
        });
        let records = Layout::new(&records, vertices.vertex_count())?;
        Some(Built {
            mesh: ProgressiveMesh {
                vertices,
                base_triangles: base_triangles as u32,
                records,
                errors,
                view,
            },
            moves: self.moves,
        })
    }
}

/// `value` when it is finite and not negative, else 0. Negative quadric weights would make a
/// vertex lighter as it absorbs others (the re-ranking relies on the opposite) and reward
/// distance from the planes.
fn non_negative(value: f64) -> f64 {
    if value.is_finite() && value > 0.0 {
        value
    } else {
        0.0
    }
}

/// `value` clamped to `0.0..=1.0`, or 0 when it is not finite.
fn unit_interval(value: f64) -> f64 {
    if value.is_finite() {
        value.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// A collapse cost with its last 36 bits of mantissa cleared (kept to 2⁻¹⁶ ≈ 1.5e-5,
/// relative), so that costs that are equal but for rounding compare equal and go to the
/// tie-breaks instead of to whichever rounding came out lower. On a flat face every collapse
/// costs only the regularization, `1e-7 × edge²`, evaluated from quadrics whose terms are
/// about `|p|²`: its rounding noise is about `1e-16 × |p|² / (1e-7 × edge²)`, 1e-5 relative
/// for a vertex 100 edge lengths from the origin.
#[inline]
fn settle(cost: f64) -> f64 {
    f64::from_bits(cost.to_bits() & !((1 << 36) - 1))
}

/// What a build produces: the progressive mesh, and every attribute vertex's move.
pub(crate) struct Built {
    pub(crate) mesh: ProgressiveMesh,
    /// `(step, old, new)`: at `step` (0-based), attribute vertex `old` was replaced by `new`
    /// everywhere, context triangles included. Regions resolve their neighbours' vertices
    /// with it.
    pub(crate) moves: Vec<(u32, u32, u32)>,
}

/// What a region's build adds to a plain one, per vertex of the mesh given to [`build`].
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Constraints<'a> {
    /// Vertices that never move.
    pub(crate) pinned: Option<&'a [bool]>,
    /// Another region's vertices: fronts run along them (see [`Builder::touches_anchor`]).
    /// `None`: along every pinned vertex.
    pub(crate) anchors: Option<&'a [bool]>,
    /// For another region's vertex, the positions its representative takes there as that
    /// region coarsens: `(level, position)` from level 0 (itself) on, in order. Empty, or
    /// one entry, when it never moves or its region is not built yet. A collapse that moves a
    /// triangle with such a corner is checked for flips at every one of them.
    pub(crate) chains: Option<&'a [Vec<(u32, Vec3)>]>,
}

/// Runs the whole build. `mesh` must be validated. Triangles from `owned` on are context
/// (see [`Builder::finish`]).
pub(crate) fn build(
    mesh: &IndexedMesh,
    options: &BuildOptions,
    constraints: &Constraints,
    owned: usize,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Built, MeshError> {
    // Corner ids are packed with one flag bit into a u32.
    if mesh.indices.len() >= (1 << 31) {
        return Err(MeshError::TooLarge {
            what: "triangles",
            count: mesh.triangle_count() as u64,
            limit: ((1u64 << 31) - 1) / 3,
        });
    }
    for (name, value) in [
        ("border_weight", options.border_weight),
        ("regularization", options.regularization),
        ("local_weight", options.local_weight),
        ("normal_weight", options.normal_weight),
        ("uv_weight", options.uv_weight),
        ("color_weight", options.color_weight),
    ] {
        if non_negative(value) != value {
            log::warn!("BuildOptions::{name} = {value} is negative or not finite: 0 is used");
        }
    }
    let pairs = options.pair_distance;
    if !(pairs.is_finite() && pairs >= 0.0) {
        log::warn!("BuildOptions::pair_distance = {pairs} is negative or not finite: 0 is used");
    }
    let exponent = options.weight_exponent;
    if unit_interval(exponent) != exponent {
        log::warn!(
            "BuildOptions::weight_exponent = {exponent} is outside 0..=1 or not finite: {} is used",
            unit_interval(exponent)
        );
    }
    let mut builder = Builder::new(mesh, options, constraints.pinned, constraints.anchors);
    if let Some(chains) = constraints.chains {
        builder.set_chains(chains);
    }
    builder.run(progress);
    builder
        .finish(owned.min(mesh.triangle_count()))
        .ok_or(MeshError::TooLarge {
            what: "corners in the collapse records",
            count: mesh.indices.len() as u64,
            limit: u64::from(u32::MAX),
        })
}

/// Per attribute vertex of `mesh`, its attributes the collapse cost weighs (normals, the
/// first UV set, colours, each times its [weight](BuildOptions::uv_weight)), and how many
/// values each has (0: no term is on).
fn attribute_table(mesh: &IndexedMesh, options: &BuildOptions) -> (Vec<f64>, usize) {
    let colors = mesh
        .attribute(crate::mesh::COLOR_ID)
        .and_then(|c| c.to_f32::<4>());
    let weight =
        |w: f64, present: bool| (present && non_negative(w) > 0.0).then(|| non_negative(w));
    let (wn, wu, wc) = (
        weight(options.normal_weight, mesh.normals.is_some()),
        weight(options.uv_weight, mesh.uvs.is_some()),
        weight(options.color_weight, colors.is_some()),
    );
    let stride = 3 * usize::from(wn.is_some())
        + 2 * usize::from(wu.is_some())
        + 4 * usize::from(wc.is_some());
    if stride == 0 {
        return (Vec::new(), 0);
    }
    let mut out = Vec::with_capacity(stride * mesh.positions.len());
    for v in 0..mesh.positions.len() {
        if let (Some(w), Some(normals)) = (wn, &mesh.normals) {
            out.extend(normals[v].to_array().map(|x| f64::from(x) * w));
        }
        if let (Some(w), Some(uvs)) = (wu, &mesh.uvs) {
            out.extend(uvs[v].to_array().map(|x| f64::from(x) * w));
        }
        if let (Some(w), Some(colors)) = (wc, &colors) {
            out.extend(colors[v].map(|x| f64::from(x) * w));
        }
    }
    (out, stride)
}

#[cfg(test)]
mod tests;
