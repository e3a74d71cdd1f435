//! Geomorphs between region levels (Hoppe; Güdükbay et al.'s future work 5): a level change
//! moves vertices over a time `T` instead of at once.

use super::{RegionCaches, RegionMesh};
use crate::skin::{Buckets, buckets};
use glam::Vec3;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::Arc;

/// Where a morphing position is heading.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Toward {
    /// Its own place (it appeared, or stays after all).
    Own,
    /// Wherever this position is shown: the representative it vanishes onto.
    Position(u32),
}

/// One position in motion: from where it was shown when the morph started to where it
/// rests at the end (its own place, or its representative's), in a straight line. Both ends
/// are fixed when the morph starts, so a GPU can interpolate it from two positions and a
/// start time ([`VertexMorph`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Morph {
    from: Vec3,
    to: Vec3,
    start: f32,
    toward: Toward,
}

/// The normal of one vertex in motion (seam copies have normals of their own): from the one
/// it was shown with to its own or its representative vertex's, over its position's morph.
#[derive(Clone, Copy, Debug, PartialEq)]
struct NormalMorph {
    from: Vec3,
    to: Vec3,
}

/// One vertex's morph as a vertex shader interpolates it: shown at `from + (to - from) * t`
/// with `t = ((now - start) / duration).clamp(0, 1)` (`to` itself at `t = 1`), its normal at
/// `normal_from.lerp(normal_to, t)`, normalised. A vertex at rest has `from == to`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexMorph {
    /// Where the vertex was shown when its morph started.
    pub from: Vec3,
    /// Where it rests when the morph ends.
    pub to: Vec3,
    /// Its normal when the morph started (zero when the mesh has none).
    pub normal_from: Vec3,
    /// Its normal at the end (zero when the mesh has none).
    pub normal_to: Vec3,
    /// When the morph started, on the clock of the `now` arguments.
    pub start: f32,
}

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
    duration: f32,
    /// What a mesh's morphs are made of, shared by every instance of the mesh.
    tables: Arc<MorphTables>,
    morphs: HashMap<u32, Morph, VertexHash>,
    normal_morphs: HashMap<u32, NormalMorph, VertexHash>,
    /// Morphs toward their own place by end time (as `f32` bits, which order non-negative
    /// times), to end them when due; an entry whose morph restarted since is skipped.
    ends: BinaryHeap<Reverse<(u32, u32)>>,
    pending: Vec<Option<Pending>>,
    /// Per region: copies of positions in motion among its own vertices.
    moving: Vec<usize>,
    /// Positions whose morph started since the last
    /// [`take_restarted`](Self::take_restarted), each once (`marked`).
    restarted: Vec<u32>,
    marked: Vec<bool>,
}

/// A [`RegionMesh`]'s morph tables (made once per mesh, on the first [`Geomorphs`]).
#[derive(Debug)]
pub(crate) struct MorphTables {
    /// Per source vertex: its position (the first vertex there). Morphs move positions, so
    /// every copy of a seam vertex moves alike, even one its region no longer draws.
    position_of: Vec<u32>,
    /// Per position: the source vertices there.
    copies: Buckets,
    /// Per region, per step: the positions that step removes.
    removed_at: Vec<Vec<Vec<u32>>>,
    /// Per position: the owner's step that removes it (`u32::MAX`: never) and the position
    /// it goes onto.
    parent: Vec<(u32, u32)>,
    /// Per source vertex: the step that moves it and the vertex its corners go to, for
    /// normals (`u32::MAX`: no recorded move).
    vertex_parent: Vec<(u32, u32)>,
    /// Per region: the triangle count of each level.
    counts: Vec<Vec<usize>>,
    /// Per source vertex: its region.
    region_of: Vec<u32>,
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
}

impl Geomorphs {
    /// Morphs of `duration` seconds (negative or NaN count as `0`: off) for an instance of
    /// `mesh`.
    #[must_use]
    pub fn new(mesh: &RegionMesh, duration: f32) -> Self {
        let tables = mesh
            .morph_tables
            .get_or_init(|| Arc::new(MorphTables::new(mesh)))
            .clone();
        let regions = mesh.regions().len();
        Self {
            duration: if duration > 0.0 { duration } else { 0.0 },
            tables,
            morphs: HashMap::default(),
            normal_morphs: HashMap::default(),
            ends: BinaryHeap::new(),
            pending: vec![None; regions],
            moving: vec![0; regions],
            restarted: Vec::new(),
            marked: Vec::new(),
        }
    }
}

impl MorphTables {
    fn new(mesh: &RegionMesh) -> Self {
        let n = mesh.vertex_count();
        let source = mesh.source_vertices();
        let position_of = crate::mesh::weld_positions(&source.positions).remap;
        let copies = buckets(&position_of, n);
        let mut parent = vec![(u32::MAX, u32::MAX); n];
        let mut vertex_parent = vec![(u32::MAX, u32::MAX); n];
        let mut removed_at = Vec::with_capacity(mesh.regions().len());
        let mut counts = Vec::with_capacity(mesh.regions().len());
        for region in mesh.regions() {
            let pm = &region.mesh;
            let mut at: Vec<Vec<u32>> = vec![Vec::new(); pm.records.step_count()];
            for (step, old, new) in pm.records.step_pairs() {
                let (g, to) = (region.global[old as usize], region.global[new as usize]);
                let (p, q) = (position_of[g as usize], position_of[to as usize]);
                // Identity pairs (a corner that keeps its vertex: an ear's far corner) move
                // nothing.
                if p == q {
                    continue;
                }
                vertex_parent[g as usize] = (step as u32, to);
                if parent[p as usize].0 == u32::MAX {
                    parent[p as usize] = (step as u32, q);
                    at[step].push(p);
                }
            }
            removed_at.push(at);
            counts.push(pm.level_triangle_counts());
        }
        Self {
            position_of,
            copies,
            removed_at,
            parent,
            vertex_parent,
            counts,
            region_of: mesh.partition().region_of().to_vec(),
            positions: source.positions,
            normals: source.normals,
        }
    }
}

impl Geomorphs {
    /// The morph time in seconds (`0`: off).
    #[inline]
    #[must_use]
    pub fn duration(&self) -> f32 {
        self.duration
    }

    /// Whether any vertex is moving or any coarsening waits.
    #[must_use]
    pub fn is_morphing(&self) -> bool {
        !self.morphs.is_empty() || self.pending.iter().any(Option::is_some)
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
        if self.duration == 0.0 {
            return caches.set_triangle_count(mesh, region, triangles);
        }
        let shown = caches.level(region);
        let counts = &self.tables.counts[region];
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
        for step in goal.max(shown)..before.max(shown) {
            for i in 0..self.tables.removed_at[region][step].len() {
                self.retarget(self.tables.removed_at[region][step][i], Toward::Own, 0, now);
            }
        }
        if goal <= shown {
            // Refine now: what appears starts on its representative at the shown level.
            self.pending[region] = None;
            for step in goal..shown {
                for i in 0..self.tables.removed_at[region][step].len() {
                    let p = self.tables.removed_at[region][step][i];
                    let from = self.representative(p, shown);
                    let normals: Vec<(u32, NormalMorph)> = self
                        .copies_of(p)
                        .iter()
                        .map(|&g| {
                            let rep = self.vertex_representative(g, shown);
                            let from = self.normal(rep, now).unwrap_or(Vec3::ZERO);
                            (
                                g,
                                NormalMorph {
                                    from,
                                    to: self.own_normal(g),
                                },
                            )
                        })
                        .collect();
                    let morph = Morph {
                        from: self.position_of_p(from, now),
                        to: self.tables.positions[p as usize],
                        start: now,
                        toward: Toward::Own,
                    };
                    self.start(p, morph);
                    self.normal_morphs.extend(normals);
                }
            }
            caches.set_triangle_count(mesh, region, goal_count)
        } else {
            // Coarsen later: what vanishes moves onto its representative at the goal first
            // (a vertex already on its way there keeps going).
            for step in shown..goal {
                for i in 0..self.tables.removed_at[region][step].len() {
                    let p = self.tables.removed_at[region][step][i];
                    let to = Toward::Position(self.representative(p, goal));
                    if self.morphs.get(&p).is_none_or(|m| m.toward != to) {
                        self.retarget(p, to, goal, now);
                    }
                }
            }
            self.pending[region] = Some(Pending {
                level: goal,
                end: now + self.duration,
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
            if self.duration == 0.0 || count < shown {
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
            caches.set_triangle_count(mesh, region, self.tables.counts[region][p.level]);
            for step in shown..p.level {
                for i in 0..self.tables.removed_at[region][step].len() {
                    self.end(self.tables.removed_at[region][step][i]);
                }
            }
        }
        // Appearing and returning positions end at their time.
        let duration = self.duration;
        while let Some(&Reverse((end, p))) = self.ends.peek() {
            if now < f32::from_bits(end) {
                break;
            }
            self.ends.pop();
            let due = self
                .morphs
                .get(&p)
                .is_some_and(|m| m.toward == Toward::Own && (m.start + duration).to_bits() == end);
            if due {
                self.end(p);
            }
        }
    }

    /// Whether region `region`'s vertices (its own, or its neighbours' that its border
    /// triangles use) may be in motion: the regions whose positions must be written again
    /// this frame.
    ///
    /// # Panics
    /// When `region` is out of range or `mesh` is not this instance's mesh.
    #[must_use]
    pub fn is_region_moving(&self, mesh: &RegionMesh, region: usize) -> bool {
        self.moving[region] > 0
            || mesh.regions()[region]
                .neighbors
                .iter()
                .any(|&n| self.moving.get(n as usize).is_some_and(|&m| m > 0))
    }

    /// Where source vertex `g` is shown at `now`.
    ///
    /// # Panics
    /// When `g` is not a vertex of the mesh.
    #[must_use]
    pub fn position(&self, g: u32, now: f32) -> Vec3 {
        self.position_of_p(self.tables.position_of[g as usize], now)
    }

    /// The normal source vertex `g` is shown with at `now` (interpolated and normalised),
    /// when the mesh has normals.
    ///
    /// # Panics
    /// When `g` is not a vertex of the mesh.
    #[must_use]
    pub fn normal(&self, g: u32, now: f32) -> Option<Vec3> {
        let own = self.tables.normals.as_ref()?[g as usize];
        let p = self.tables.position_of[g as usize];
        let (Some(m), Some(nm)) = (self.morphs.get(&p), self.normal_morphs.get(&g)) else {
            return Some(own);
        };
        let t = self.progress(m, now);
        if t >= 1.0 {
            return Some(nm.to);
        }
        Some(nm.from.lerp(nm.to, t).normalize_or(nm.to))
    }

    /// Source vertex `g`'s morph as a vertex shader interpolates it (the same positions and
    /// normals as [`position`](Self::position) and [`normal`](Self::normal) at any time up
    /// to the next level change).
    ///
    /// # Panics
    /// When `g` is not a vertex of the mesh.
    #[must_use]
    pub fn vertex_morph(&self, g: u32) -> VertexMorph {
        let p = self.tables.position_of[g as usize];
        let own = self.tables.positions[p as usize];
        let own_normal = self.own_normal(g);
        let m = self.morphs.get(&p);
        let nm = m.and(self.normal_morphs.get(&g));
        VertexMorph {
            from: m.map_or(own, |m| m.from),
            to: m.map_or(own, |m| m.to),
            normal_from: nm.map_or(own_normal, |n| n.from),
            normal_to: nm.map_or(own_normal, |n| n.to),
            start: m.map_or(0.0, |m| m.start),
        }
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
        if self.restarted.is_empty() {
            return runs;
        }
        // A position's vertices live in their owners' regions and in the neighbours' that
        // draw them.
        let region_of = mesh.partition().region_of();
        let mut touched = vec![false; runs.len()];
        for &p in &self.restarted {
            for &g in self.tables.copies.get(p as usize) {
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
            let marked = |&g: &u32| self.marked[self.tables.position_of[g as usize] as usize];
            if let (Some(lo), Some(hi)) = (
                global.iter().position(marked),
                global.iter().rposition(marked),
            ) {
                *run = Some((lo as u32, hi as u32));
            }
        }
        for p in self.restarted.drain(..) {
            self.marked[p as usize] = false;
        }
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
        self.representative(self.tables.position_of[g as usize], level)
    }

    /// How far morph `m` has come at `now`, `0.0..=1.0`.
    fn progress(&self, m: &Morph, now: f32) -> f32 {
        ((now - m.start) / self.duration).clamp(0.0, 1.0)
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
        if self.tables.normals.is_none() {
            return;
        }
        out.extend(
            mesh.regions()[region]
                .global
                .iter()
                .map(|&g| self.normal(g, now).unwrap_or(Vec3::Y)),
        );
    }

    /// Where position `p` is shown at `now`.
    fn position_of_p(&self, p: u32, now: f32) -> Vec3 {
        let Some(m) = self.morphs.get(&p) else {
            return self.tables.positions[p as usize];
        };
        let t = self.progress(m, now);
        if t >= 1.0 {
            return m.to;
        }
        m.from + (m.to - m.from) * t
    }

    /// Vertex `g`'s own normal (zero when the mesh has none).
    fn own_normal(&self, g: u32) -> Vec3 {
        self.tables
            .normals
            .as_ref()
            .map_or(Vec3::ZERO, |n| n[g as usize])
    }

    /// Puts morph `m` on position `p`, noted for [`take_restarted`](Self::take_restarted).
    fn start(&mut self, p: u32, m: Morph) {
        if m.toward == Toward::Own {
            let end = (m.start + self.duration).max(0.0);
            self.ends.push(Reverse((end.to_bits(), p)));
        }
        if self.morphs.insert(p, m).is_none() {
            self.count_moving(p, true);
        }
        if self.marked.is_empty() {
            self.marked = vec![false; self.tables.positions.len()];
        }
        if !std::mem::replace(&mut self.marked[p as usize], true) {
            self.restarted.push(p);
        }
    }

    /// Ends position `p`'s morph (and its copies' normals').
    fn end(&mut self, p: u32) {
        if self.morphs.remove(&p).is_some() {
            self.count_moving(p, false);
        }
        for &g in self.tables.copies.get(p as usize) {
            self.normal_morphs.remove(&g);
        }
    }

    /// Counts position `p` in (or out of) the moving positions of the regions its copies
    /// are in (seams, and vertices of skinned regions that meet in the bind pose, may lie in
    /// other regions than its first vertex's).
    fn count_moving(&mut self, p: u32, moving: bool) {
        for &g in self.tables.copies.get(p as usize) {
            let count = &mut self.moving[self.tables.region_of[g as usize] as usize];
            *count = if moving {
                *count + 1
            } else {
                count.saturating_sub(1)
            };
        }
    }

    /// The source vertices at position `p`.
    fn copies_of(&self, p: u32) -> &[u32] {
        self.tables.copies.get(p as usize)
    }

    /// Starts position `p` toward `toward` from where it is shown now (nothing when it is
    /// at rest at its own place and stays there); its copies' normals toward their
    /// representatives at `level` (vanishing) or their own.
    fn retarget(&mut self, p: u32, toward: Toward, level: usize, now: f32) {
        if toward == Toward::Own && !self.morphs.contains_key(&p) {
            return;
        }
        let normals: Vec<(u32, NormalMorph)> = self
            .copies_of(p)
            .iter()
            .map(|&g| {
                let to = match toward {
                    Toward::Own => self.own_normal(g),
                    Toward::Position(_) => self.own_normal(self.vertex_representative(g, level)),
                };
                let from = self.normal(g, now).unwrap_or(Vec3::ZERO);
                (g, NormalMorph { from, to })
            })
            .collect();
        // A representative is present at the level this morph heads for, and every vertex
        // present there rests at its own place: the end is fixed now.
        let to = match toward {
            Toward::Own => self.tables.positions[p as usize],
            Toward::Position(q) => self.tables.positions[q as usize],
        };
        let morph = Morph {
            from: self.position_of_p(p, now),
            to,
            start: now,
            toward,
        };
        self.start(p, morph);
        self.normal_morphs.extend(normals);
    }

    /// The position that stands for position `p` at `level` of its region.
    fn representative(&self, p: u32, level: usize) -> u32 {
        follow(&self.tables.parent, p, level)
    }

    /// The vertex whose attributes stand for vertex `g` at `level` (as far as its recorded
    /// moves go: a copy no triangle uses any more moves no further).
    fn vertex_representative(&self, g: u32, level: usize) -> u32 {
        follow(&self.tables.vertex_parent, g, level)
    }
}

/// Follows `moves` (per item: the step that moves it, `u32::MAX` for none, and where to)
/// from `start` while the move's step is below `level`. Each move goes to a later step's
/// item, so the chain ends; the bound guards a damaged file's regions.
fn follow(moves: &[(u32, u32)], mut at: u32, level: usize) -> u32 {
    for _ in 0..moves.len() {
        match moves.get(at as usize) {
            Some(&(step, to)) if step != u32::MAX && (step as usize) < level => at = to,
            _ => break,
        }
    }
    at
}

/// Hashes the vertex and position numbers the morph maps are keyed by (a multiplicative
/// hash: the keys are dense `u32`s, and SipHash cost a tenth of a frame of morphs).
#[derive(Clone, Copy, Debug, Default)]
struct U32Hasher(u64);

impl Hasher for U32Hasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }

    fn write_u32(&mut self, n: u32) {
        self.0 = (u64::from(n) ^ self.0).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

type VertexHash = BuildHasherDefault<U32Hasher>;
