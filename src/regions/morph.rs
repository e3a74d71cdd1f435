//! Geomorphs between region levels (Hoppe; Güdükbay et al.'s future work 5): a level change
//! moves vertices over a time `T` instead of at once.

use super::{RegionCaches, RegionMesh};
pub use crate::multires::morph::{MorphGroup, MorphKind, VertexMorph};
use crate::multires::morph::{MorphTables, Motion, Toward};
use glam::Vec3;
use std::sync::Arc;

/// A coarsening waiting for its vertices to arrive: the level, and when.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pending {
    level: usize,
    end: f32,
}

/// Geomorphs for one instance of a [`RegionMesh`] beside its [`RegionCaches`]: level changes
/// go through [`set_triangle_count`](Self::set_triangle_count) and vertices are shown where
/// [`position`](Self::position) says.
///
/// - **Refining** changes the triangles at once; every vertex that appears starts where its
///   representative at the old level is shown and moves to its own position over
///   [`duration`](Self::duration) seconds.
/// - **Coarsening** keeps the old triangles: the vertices that vanish move onto their
///   representatives at the new level first, and the region takes the new level when they
///   arrive ([`update`](Self::update)). Until then it shows, and counts, its old triangles
///   ([`RegionCaches::triangle_count`] is what a budget must charge it).
/// - A region that changes again while morphing continues from where its vertices are.
/// - Positions belong to source vertices, not to regions: a border vertex moves the same way
///   in every region that draws it, so borders stay closed during a morph.
///
/// A duration of `0` is the plain caches: every change at once, every vertex at its own
/// position. The tables a morph reads (about 50 bytes per source vertex) are made by the
/// mesh's first `Geomorphs` and shared by the others; an instance keeps only its vertices in
/// motion.
///
/// ```
/// use bevy_aslod::mesh::IndexedMesh;
/// use bevy_aslod::multires::BuildOptions;
/// use bevy_aslod::regions::{Geomorphs, GridPlane, Partition, RegionCaches, RegionMesh};
/// use glam::Vec3;
///
/// let mut positions = Vec::new();
/// for z in 0..9 {
///     for x in 0..9 {
///         positions.push(Vec3::new(x as f32, ((x * 7 + z * 3) % 5) as f32 * 0.2, z as f32));
///     }
/// }
/// let mut indices = Vec::new();
/// for z in 0..8u32 {
///     for x in 0..8u32 {
///         let i = z * 9 + x;
///         indices.extend_from_slice(&[i, i + 9, i + 1, i + 1, i + 9, i + 10]);
///     }
/// }
/// let mesh = IndexedMesh::new(positions, indices);
/// let partition = Partition::grid(&mesh, GridPlane::XZ, 2, 2)?;
/// let regions = RegionMesh::build(&mesh, &partition, &BuildOptions::default())?;
/// let mut caches = RegionCaches::new(&regions);
/// let mut morphs = Geomorphs::new(&regions, 0.25);
/// // Coarsen region 0 at t = 0: it keeps its triangles until t = 0.25.
/// let full = caches.triangle_count(0);
/// morphs.set_triangle_count(&regions, &mut caches, 0, 4, 0.0);
/// assert!(morphs.is_coarsening(0));
/// assert_eq!(caches.triangle_count(0), full);
/// morphs.update(&regions, &mut caches, 0.25);
/// assert!(caches.triangle_count(0) <= 4);
/// # Ok::<(), bevy_aslod::regions::RegionError>(())
/// ```
#[derive(Clone, Debug)]
pub struct Geomorphs {
    /// The positions in motion, and the mesh's tables (shared by every instance).
    motion: Motion,
    pending: Vec<Option<Pending>>,
}

impl Geomorphs {
    /// Morphs of `duration` seconds (negative or NaN count as `0`: off) for an instance of
    /// `mesh`.
    #[must_use]
    pub fn new(mesh: &RegionMesh, duration: f32) -> Self {
        let tables = mesh
            .morph_tables
            .get_or_init(|| {
                let source = mesh.source_vertices();
                Arc::new(
                    MorphTables::new(
                        source.positions.clone(),
                        source.normals.clone(),
                        mesh.partition().region_of().to_vec(),
                        mesh.regions()
                            .iter()
                            .map(|r| (&r.mesh, Some(r.global.as_slice()))),
                    )
                    .with_attributes(&source),
                )
            })
            .clone();
        Self {
            motion: Motion::new(tables, duration),
            pending: vec![None; mesh.regions().len()],
        }
    }
}

impl Geomorphs {
    /// The morph time in seconds (`0`: off).
    #[inline]
    #[must_use]
    pub fn duration(&self) -> f32 {
        self.motion.duration
    }

    /// Whether any vertex is moving or any coarsening waits.
    #[must_use]
    pub fn is_morphing(&self) -> bool {
        self.motion.is_moving() || self.pending.iter().any(Option::is_some)
    }

    /// Asks region `region` for the finest level with at most `triangles` triangles at time
    /// `now` (seconds, any clock that only goes forward). Returns the triangles it shows
    /// now.
    ///
    /// # Panics
    /// When `region` is out of range, or `mesh` is not the caches' mesh.
    pub fn set_triangle_count(
        &mut self,
        mesh: &RegionMesh,
        caches: &mut RegionCaches,
        region: usize,
        triangles: usize,
        now: f32,
    ) -> usize {
        let duration = self.motion.duration;
        if duration == 0.0 {
            return caches.set_triangle_count(mesh, region, triangles);
        }
        let tables = Arc::clone(&self.motion.tables);
        let removed_at = &tables.removed_at[region];
        let shown = caches.level(region);
        let counts = &tables.counts[region];
        let goal = counts
            .iter()
            .position(|&c| c <= triangles)
            .unwrap_or(counts.len() - 1);
        let goal_count = counts[goal];
        let before = self.pending[region].map_or(shown, |p| p.level);
        if goal == before {
            return caches.triangle_count(region);
        }

        // Vertices heading for representatives at a level no longer wanted turn back.
        let turned = goal.max(shown)..before.max(shown);
        for step in removed_at.get(turned).unwrap_or_default() {
            for &p in step {
                self.motion.retarget(p, Toward::Own, below(0), now);
            }
        }
        if goal <= shown {
            // Refine now: what appears starts on its representative at the shown level.
            self.pending[region] = None;
            for step in &removed_at[goal..shown] {
                for &p in step {
                    self.motion.appear(p, below(shown), now);
                }
            }
            caches.set_triangle_count(mesh, region, goal_count)
        } else {
            // Coarsen later: what vanishes moves onto its representative at the goal first
            // (a vertex already on its way there keeps going).
            for step in &removed_at[shown..goal] {
                for &p in step {
                    let to = Toward::Position(tables.representative(p, below(goal)));
                    if self.motion.heading(p) != Some(to) {
                        self.motion.retarget(p, to, below(goal), now);
                    }
                }
            }
            self.pending[region] = Some(Pending {
                level: goal,
                end: now + duration,
            });
            caches.triangle_count(region)
        }
    }

    /// Applies one frame's allocation (`counts`, one per region, as the budget's allocator
    /// gives them for the view, whatever is morphing) under the budget `budget`, so that the
    /// triangles shown never exceed it:
    ///
    /// - regions asked for fewer triangles coarsen (or keep coarsening toward the new
    ///   count), and count their old triangles until their vertices arrive;
    /// - a coarsening region asked for at least what it shows turns back, at no cost: it
    ///   shows those triangles already;
    /// - regions asked for more take only what is left under `budget`, largest request first,
    ///   so a refinement that needs the triangles of a coarsening elsewhere waits for them
    ///   (at most [`duration`](Self::duration)).
    ///
    /// The allocation does not depend on what is morphing, so the levels it asks for stay put
    /// while the view does (counting a morph's triangles in the allocation itself would feed
    /// back into the next one, and levels near a step would go back and forth).
    ///
    /// Returns the triangles shown, all regions together. With a duration of `0`, every count
    /// is applied as it is.
    ///
    /// # Panics
    /// When `counts` does not have one entry per region, or `mesh` is not the caches' mesh.
    pub fn apply_allocation(
        &mut self,
        mesh: &RegionMesh,
        caches: &mut RegionCaches,
        counts: &[u32],
        budget: usize,
        now: f32,
    ) -> usize {
        let mut refine = Vec::new();
        self.begin_allocation(mesh, caches, counts, now, &mut refine);
        refine.sort_by_key(|&(_, wanted)| std::cmp::Reverse(wanted));
        let mut total = caches.total_triangles();
        for (r, wanted) in refine {
            let grant = (wanted as usize).min(budget.saturating_sub(total));
            total += self.grant(mesh, caches, r as usize, grant, now);
        }
        total
    }

    /// The first half of [`apply_allocation`](Self::apply_allocation), for a budget shared
    /// with other instances: coarsens the regions asked for fewer triangles, turns back the
    /// coarsening ones asked for at least what they show, and puts the refinements wanted in
    /// `refine` (region, triangles more than it shows), in region order. Grant them with
    /// [`grant`](Self::grant) out of what is free.
    ///
    /// # Panics
    /// When `counts` does not have one entry per region, or `mesh` is not the caches' mesh.
    pub fn begin_allocation(
        &mut self,
        mesh: &RegionMesh,
        caches: &mut RegionCaches,
        counts: &[u32],
        now: f32,
        refine: &mut Vec<(u32, u32)>,
    ) {
        assert_eq!(counts.len(), self.pending.len(), "one count per region");
        refine.clear();
        for (r, &count) in counts.iter().enumerate() {
            let (count, shown) = (count as usize, caches.triangle_count(r));
            if self.motion.duration == 0.0 || count < shown {
                self.set_triangle_count(mesh, caches, r, count, now);
            } else if self.is_coarsening(r) {
                self.set_triangle_count(mesh, caches, r, shown, now);
            }
            let shown = caches.triangle_count(r);
            if count > shown {
                refine.push((r as u32, (count - shown) as u32));
            }
        }
    }

    /// Refines region `region` by at most `triangles` more than it shows (a refinement
    /// [`begin_allocation`](Self::begin_allocation) found, granted out of a budget); returns
    /// the triangles it added.
    ///
    /// # Panics
    /// When `region` is out of range or `mesh` is not the caches' mesh.
    pub fn grant(
        &mut self,
        mesh: &RegionMesh,
        caches: &mut RegionCaches,
        region: usize,
        triangles: usize,
        now: f32,
    ) -> usize {
        if triangles == 0 {
            return 0;
        }
        let shown = caches.triangle_count(region);
        let reached = self.set_triangle_count(mesh, caches, region, shown + triangles, now);
        reached.saturating_sub(shown)
    }

    /// Ends what has arrived by `now`: coarsenings take their level, finished morphs go.
    /// Call once a frame before drawing.
    ///
    /// # Panics
    /// When `mesh` is not the caches' mesh.
    pub fn update(&mut self, mesh: &RegionMesh, caches: &mut RegionCaches, now: f32) {
        for region in 0..self.pending.len() {
            let Some(p) = self.pending[region] else {
                continue;
            };
            if now < p.end {
                continue;
            }
            self.pending[region] = None;
            let shown = caches.level(region);
            let tables = Arc::clone(&self.motion.tables);
            caches.set_triangle_count(mesh, region, tables.counts[region][p.level]);
            for step in shown..p.level {
                for &p in &tables.removed_at[region][step] {
                    self.motion.end(p);
                }
            }
        }
        // Appearing and returning positions end at their time.
        self.motion.end_due(now);
    }

    /// Whether region `region`'s vertices (its own, or its neighbours' that its border
    /// triangles use) may be in motion: the regions whose positions must be written again
    /// this frame.
    ///
    /// # Panics
    /// When `region` is out of range or `mesh` is not this instance's mesh.
    #[must_use]
    pub fn is_region_moving(&self, mesh: &RegionMesh, region: usize) -> bool {
        self.motion.is_sequence_moving(region)
            || mesh.regions()[region]
                .neighbors
                .iter()
                .any(|&n| self.motion.is_sequence_moving(n as usize))
    }

    /// Where source vertex `g` is shown at `now`.
    ///
    /// # Panics
    /// When `g` is not a vertex of the mesh.
    #[must_use]
    pub fn position(&self, g: u32, now: f32) -> Vec3 {
        self.motion.position(g, now)
    }

    /// The normal source vertex `g` is shown with at `now` (interpolated and normalised),
    /// when the mesh has normals.
    ///
    /// # Panics
    /// When `g` is not a vertex of the mesh.
    #[must_use]
    pub fn normal(&self, g: u32, now: f32) -> Option<Vec3> {
        self.motion.normal(g, now)
    }

    /// Source vertex `g`'s morph as a vertex shader interpolates it (the same positions and
    /// normals as [`position`](Self::position) and [`normal`](Self::normal) at any time up
    /// to the next level change).
    ///
    /// # Panics
    /// When `g` is not a vertex of the mesh.
    #[must_use]
    pub fn vertex_morph(&self, g: u32) -> VertexMorph {
        self.motion.vertex_morph(g)
    }

    /// Per region, the run of its local vertices (first and last) that a morph started or
    /// restarted on since the last call: what a GPU copy of [`vertex_morph`](Self::vertex_morph)
    /// must take again. `None` for a region with none. (Positions are noted until taken, at
    /// most once each.)
    ///
    /// # Panics
    /// When `mesh` is not this instance's mesh.
    pub fn take_restarted(&mut self, mesh: &RegionMesh) -> Vec<Option<(u32, u32)>> {
        let mut runs = vec![None; mesh.regions().len()];
        self.motion.take_restarted(|motion, restarted| {
            // A position's vertices live in their owners' regions and in the neighbours'
            // that draw them.
            let region_of = mesh.partition().region_of();
            let mut touched = vec![false; runs.len()];
            for &p in restarted {
                for &g in motion.tables.copies_of(p) {
                    let owner = region_of[g as usize] as usize;
                    touched[owner] = true;
                    for &n in &mesh.regions()[owner].neighbors {
                        touched[n as usize] = true;
                    }
                }
            }
            for (r, run) in runs.iter_mut().enumerate() {
                if !touched[r] {
                    continue;
                }
                let global = &mesh.regions()[r].global;
                let marked = |&g: &u32| motion.is_marked(g);
                if let (Some(lo), Some(hi)) = (
                    global.iter().position(marked),
                    global.iter().rposition(marked),
                ) {
                    *run = Some((lo as u32, hi as u32));
                }
            }
        });
        runs
    }

    /// Whether region `region` is coarsening: it shows its old triangles until its vertices
    /// arrive. A budget counts them as fixed and leaves the region alone until then (asking
    /// it for its old count again would turn the morph back).
    ///
    /// # Panics
    /// When `region` is out of range.
    #[inline]
    #[must_use]
    pub fn is_coarsening(&self, region: usize) -> bool {
        self.pending[region].is_some()
    }

    /// The source vertex whose position stands for vertex `g` at `level` of its region: `g`
    /// itself while present, else the one it was collapsed onto, and so on.
    ///
    /// # Panics
    /// When `g` is not a vertex of the mesh.
    #[must_use]
    pub fn stand_in(&self, g: u32, level: usize) -> u32 {
        let tables = &self.motion.tables;
        tables.representative(tables.position_of[g as usize], below(level))
    }

    /// Writes where each of region `region`'s local vertices is shown at `now` into `out`
    /// (resized to its local vertex table).
    ///
    /// # Panics
    /// When `region` is out of range or `mesh` is not this instance's mesh.
    pub fn write_positions(&self, mesh: &RegionMesh, region: usize, now: f32, out: &mut Vec<Vec3>) {
        out.clear();
        out.extend(
            mesh.regions()[region]
                .global
                .iter()
                .map(|&g| self.position(g, now)),
        );
    }

    /// Writes the normal each of region `region`'s local vertices is shown with at `now`
    /// into `out` (left empty when the mesh has no normals).
    ///
    /// # Panics
    /// When `region` is out of range or `mesh` is not this instance's mesh.
    pub fn write_normals(&self, mesh: &RegionMesh, region: usize, now: f32, out: &mut Vec<Vec3>) {
        out.clear();
        if !self.motion.has_normals() {
            return;
        }
        out.extend(
            mesh.regions()[region]
                .global
                .iter()
                .map(|&g| self.normal(g, now).unwrap_or(Vec3::Y)),
        );
    }

    /// The further attributes every vertex of region `region` of `mesh` is shown with at
    /// `now` (`None`: their own, as at rest), [`attribute_groups`](Self::attribute_groups)'
    /// values per vertex, into `out` (cleared; left empty when the mesh has none to
    /// interpolate): UVs and `f32` attributes interpolated from what was shown when the
    /// morph started to the values of the vertex that stands there at its end, tangents too
    /// but normalised and keeping their own handedness. Attributes of other formats are not
    /// interpolated: a moving vertex keeps its own.
    pub fn write_attributes(
        &self,
        mesh: &RegionMesh,
        region: usize,
        now: Option<f32>,
        out: &mut Vec<f32>,
    ) {
        out.clear();
        for &g in &mesh.regions()[region].global {
            self.motion.write_attributes(g, now, out);
        }
    }

    /// The further attributes source vertex `g` is shown with at `now` (`None`: its own),
    /// [`attribute_groups`](Self::attribute_groups)' values, appended to `out` (nothing when
    /// the mesh has none to interpolate). As [`write_attributes`](Self::write_attributes).
    pub fn write_vertex_attributes(&self, g: u32, now: Option<f32>, out: &mut Vec<f32>) {
        self.motion.write_attributes(g, now, out);
    }

    /// The further attributes morphs interpolate (UVs, tangents, `f32` attributes), in the
    /// order [`write_attributes`](Self::write_attributes) writes them; empty when none.
    #[must_use]
    pub fn attribute_groups(&self) -> &[MorphGroup] {
        self.motion.attribute_groups()
    }
}

/// The level of a region's first `level` steps, as the steps it performed.
fn below(level: usize) -> impl Fn(u32) -> bool + Copy {
    move |step| (step as usize) < level
}
