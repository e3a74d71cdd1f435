//! Geomorphs between variable-resolution levels: the level shown follows a target level
//! over a time `T` instead of at once.

use super::{RefineError, VariableCache, VariableMesh};
use crate::multires::morph::{MorphGroup, MorphTables, Motion, Toward, VertexMorph};
use glam::Vec3;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Geomorphs for one instance of a [`VariableMesh`]: the level it shows
/// ([`shown`](Self::shown)) follows a target level (a [`VariableCache`] moved by
/// [`update`](VariableCache::update), [`extract`](VariableCache::extract) or a
/// [`ToleranceSearch`](super::ToleranceSearch)) collapse by collapse, and its vertices are
/// shown where [`position`](Self::position) says.
///
/// - **A collapse the target undoes** is undone in the shown level at once (as far as a
///   budget lets it, see [`grant`](Self::grant)): the vertices it brings back start where
///   their representative is shown and move to their own places over
///   [`duration`](Self::duration) seconds.
/// - **A collapse the target performs** waits: its vanishing vertices move onto their
///   representatives at the target level first, and the shown level performs it when they
///   arrive (after the collapses it depends on). Until then its triangles are shown and
///   counted.
/// - A collapse the target takes back while its vertices are on their way turns them back
///   from where they are.
///
/// Each collapse moves only its own vertices and every level is one the cache could show,
/// so the shown mesh stays closed where the target's is. A duration of `0` shows the target
/// level as it is.
///
/// Memory per instance: a second [`VariableCache`] and the vertices in motion. The tables a
/// morph reads (about 50 bytes per vertex) are made by the mesh's first `VariableGeomorphs`
/// and shared.
///
/// ```
/// use bevy_aslod::mesh::IndexedMesh;
/// use bevy_aslod::multires::{BuildOptions, ProgressiveMesh};
/// use bevy_aslod::refine::{LevelCut, VariableCache, VariableGeomorphs, VariableMesh, View};
/// use glam::Vec3;
///
/// let (mesh, _) = IndexedMesh::load("../shared/testdata/meshes/cow.obj")?;
/// let options = BuildOptions::default().with_view_dependent(true);
/// let cow = VariableMesh::new(ProgressiveMesh::build(&mesh, &options)?)?;
/// let view = View::perspective(Vec3::Z, Vec3::NEG_Z, Vec3::Y, 1.0, 1.0, 0.1, 10.0)?;
///
/// let mut target = VariableCache::new(&cow);
/// let mut morphs = VariableGeomorphs::new(&cow, &target, 0.25);
/// // The target drops to the coarsest level at t = 0: the cow keeps its triangles while
/// // the vanishing vertices move, and takes the target's level when they arrive.
/// target.update(&cow, &LevelCut(usize::MAX), &view)?;
/// let full = cow.mesh().max_triangles();
/// assert_eq!(morphs.follow(&cow, &target, usize::MAX, 0.0)?, full);
/// assert_eq!(morphs.follow(&cow, &target, usize::MAX, 0.25)?, target.triangle_count());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct VariableGeomorphs {
    motion: Motion,
    shown: VariableCache,
    /// Collapses the target performs and the shown level does not yet, by step: when their
    /// vertices arrive.
    pending: BTreeMap<u32, f32>,
    /// Collapses the target undid and the shown level still performs, coarsest first, as
    /// [`begin`](Self::begin) found them.
    undo: Vec<u32>,
}

impl VariableGeomorphs {
    /// Morphs of `duration` seconds (negative or NaN count as `0`: off) for an instance of
    /// `mesh` that shows `level` now.
    #[must_use]
    pub fn new(mesh: &VariableMesh, level: &VariableCache, duration: f32) -> Self {
        let tables = mesh
            .morph_tables
            .get_or_init(|| {
                let vertices = mesh.mesh.vertices();
                let mut tables = MorphTables::new(
                    vertices.positions.clone(),
                    vertices.normals.clone(),
                    vec![0; vertices.vertex_count()],
                    std::iter::once((&mesh.mesh, None)),
                )
                .with_attributes(vertices);
                // The view data names every collapse's two vertices, also where the records
                // rewrite no corner.
                let moves = (0..mesh.collapse_count())
                    .filter_map(|step| mesh.collapse(step).map(|[u, w]| (step, u, w)));
                tables.add_unrecorded_moves(0, moves);
                Arc::new(tables)
            })
            .clone();
        Self {
            motion: Motion::new(tables, duration),
            shown: level.clone(),
            pending: BTreeMap::new(),
            undo: Vec::new(),
        }
    }

    /// The morph time in seconds (`0`: off).
    #[inline]
    #[must_use]
    pub fn duration(&self) -> f32 {
        self.motion.duration
    }

    /// The level shown: its [`indices`](VariableCache::indices) are what to draw, with the
    /// vertices where [`position`](Self::position) says.
    #[inline]
    #[must_use]
    pub fn shown(&self) -> &VariableCache {
        &self.shown
    }

    /// Marks the shown index buffer as uploaded (see [`VariableCache::clear_changed`]).
    #[inline]
    pub fn clear_changed(&mut self) {
        self.shown.clear_changed();
    }

    /// Whether any vertex is moving or any collapse waits for its vertices.
    #[must_use]
    pub fn is_morphing(&self) -> bool {
        self.motion.is_moving() || !self.pending.is_empty()
    }

    /// Moves the shown level toward `target` at time `now` (seconds, any clock that only goes
    /// forward) with at most `budget` triangles shown, or as many as it shows already
    /// (coarsenings keep their triangles until they land, refinements take what is left):
    /// [`begin`](Self::begin) then [`grant`](Self::grant). Returns the triangles shown.
    ///
    /// # Errors
    /// [`RefineError::MeshMismatch`] when `target` or this instance was made for another
    /// mesh than `mesh`.
    pub fn follow(
        &mut self,
        mesh: &VariableMesh,
        target: &VariableCache,
        budget: usize,
        now: f32,
    ) -> Result<usize, RefineError> {
        let wanted = self.begin(mesh, target, now)?;
        let free = budget.saturating_sub(self.shown.triangle_count());
        self.grant(mesh, target, wanted.min(free), now)?;
        Ok(self.shown.triangle_count())
    }

    /// The first half of [`follow`](Self::follow), for a budget shared with other
    /// instances: lands the collapses whose vertices arrived by `now`, starts the vertices
    /// of the collapses `target` newly performs on their way, turns back those it no longer
    /// performs, and returns the triangles the shown level would add by undoing what
    /// `target` undid (grant them, or part of them, with [`grant`](Self::grant)).
    ///
    /// # Errors
    /// [`RefineError::MeshMismatch`] when `target` or this instance was made for another
    /// mesh than `mesh`.
    pub fn begin(
        &mut self,
        mesh: &VariableMesh,
        target: &VariableCache,
        now: f32,
    ) -> Result<usize, RefineError> {
        target.check(mesh)?;
        self.shown.check(mesh)?;
        self.undo.clear();
        if self.motion.duration == 0.0 {
            let changed = self.shown.changed || self.shown.indices() != target.indices();
            self.shown.clone_from(target);
            self.shown.changed = changed;
            return Ok(0);
        }
        let tables = Arc::clone(&self.motion.tables);
        let goal = |s: u32| target.is_performed(s as usize);
        let mut wanted = 0;
        // The collapses where the two levels differ.
        let words = target
            .performed
            .words()
            .iter()
            .zip(self.shown.performed.words());
        for (w, (&t, &s)) in words.enumerate() {
            let mut diff = t ^ s;
            while diff != 0 {
                let step = (64 * w) as u32 + diff.trailing_zeros();
                diff &= diff - 1;
                if t >> (step & 63) & 1 == 0 {
                    self.undo.push(step);
                    wanted += mesh.mesh.records.removed_by(step as usize);
                    continue;
                }
                // To perform: its vertices head for their representatives at the target
                // (again, when the target changed above them).
                let mut moved = false;
                for &p in &tables.removed_at[0][step as usize] {
                    let to = Toward::Position(tables.representative(p, goal));
                    if self.motion.heading(p) != Some(to) {
                        self.motion.retarget(p, to, goal, now);
                        moved = true;
                    }
                }
                if moved || !self.pending.contains_key(&step) {
                    self.pending.insert(step, now + self.motion.duration);
                }
            }
        }
        // Waiting collapses the target no longer performs turn back; those whose vertices
        // arrived land, after what they depend on (a lower step).
        // (`retain` visits them in step order.)
        let (motion, shown) = (&mut self.motion, &mut self.shown);
        self.pending.retain(|&step, &mut end| {
            let removed = &tables.removed_at[0][step as usize];
            if !goal(step) {
                for &p in removed {
                    motion.retarget(p, Toward::Own, goal, now);
                }
                false
            } else if now >= end && shown.is_candidate(mesh, step as usize) {
                shown.perform(mesh, step as usize);
                for &p in removed {
                    motion.end(p);
                }
                false
            } else {
                true
            }
        });
        self.motion.end_due(now);
        self.undo.reverse();
        Ok(wanted)
    }

    /// Undoes what [`begin`](Self::begin) found `target` undid, coarsest collapse first, as
    /// long as the triangles added stay within `triangles`; returns the triangles added.
    /// What does not fit waits for the next `begin`.
    ///
    /// # Errors
    /// [`RefineError::MeshMismatch`] when `target` or this instance was made for another
    /// mesh than `mesh`.
    pub fn grant(
        &mut self,
        mesh: &VariableMesh,
        target: &VariableCache,
        triangles: usize,
        now: f32,
    ) -> Result<usize, RefineError> {
        target.check(mesh)?;
        self.shown.check(mesh)?;
        let tables = Arc::clone(&self.motion.tables);
        let mut added = 0;
        for &step in &self.undo {
            let s = step as usize;
            let cost = mesh.mesh.records.removed_by(s);
            if added + cost > triangles || target.is_performed(s) || !self.shown.is_maximal(mesh, s)
            {
                continue;
            }
            // What appears starts where its representative is shown, before the undo.
            for &p in &tables.removed_at[0][s] {
                let shown = &self.shown;
                self.motion
                    .appear(p, |c: u32| shown.is_performed(c as usize), now);
            }
            self.shown.undo(mesh, s);
            added += cost;
        }
        self.undo.clear();
        Ok(added)
    }

    /// Where vertex `v` of the mesh's vertex table is shown at `now`.
    ///
    /// # Panics
    /// When `v` is not a vertex of the mesh.
    #[must_use]
    pub fn position(&self, v: u32, now: f32) -> Vec3 {
        self.motion.position(v, now)
    }

    /// The normal vertex `v` is shown with at `now` (interpolated and normalised), when the
    /// mesh has normals.
    ///
    /// # Panics
    /// When `v` is not a vertex of the mesh.
    #[must_use]
    pub fn normal(&self, v: u32, now: f32) -> Option<Vec3> {
        self.motion.normal(v, now)
    }

    /// Vertex `v`'s morph as a vertex shader interpolates it (the same positions and
    /// normals as [`position`](Self::position) and [`normal`](Self::normal) at any time up
    /// to the next change of the shown level).
    ///
    /// # Panics
    /// When `v` is not a vertex of the mesh.
    #[must_use]
    pub fn vertex_morph(&self, v: u32) -> VertexMorph {
        self.motion.vertex_morph(v)
    }

    /// The runs of vertices (first and last, in order) that a morph started or restarted on
    /// since the last call: what a GPU copy of [`vertex_morph`](Self::vertex_morph) must take
    /// again. Runs less than 16 vertices apart are one.
    pub fn take_restarted(&mut self) -> Vec<(u32, u32)> {
        const GAP: u32 = 16;
        let mut vertices = Vec::new();
        self.motion.take_restarted(|motion, restarted| {
            for &p in restarted {
                vertices.extend_from_slice(motion.tables.copies_of(p));
            }
        });
        vertices.sort_unstable();
        let mut runs: Vec<(u32, u32)> = Vec::new();
        for v in vertices {
            match runs.last_mut() {
                Some((_, hi)) if v <= *hi + GAP => *hi = v,
                _ => runs.push((v, v)),
            }
        }
        runs
    }

    /// Writes where every vertex of the mesh is shown at `now` into `out`.
    pub fn write_positions(&self, now: f32, out: &mut Vec<Vec3>) {
        let n = self.motion.tables.position_of.len() as u32;
        out.clear();
        out.extend((0..n).map(|v| self.position(v, now)));
    }

    /// Writes the normal every vertex is shown with at `now` into `out` (left empty when the
    /// mesh has no normals).
    pub fn write_normals(&self, now: f32, out: &mut Vec<Vec3>) {
        out.clear();
        if !self.motion.has_normals() {
            return;
        }
        let n = self.motion.tables.position_of.len() as u32;
        out.extend((0..n).map(|v| self.normal(v, now).unwrap_or(Vec3::Y)));
    }

    /// The further attributes every vertex is shown with at `now` (`None`: their own, as at
    /// rest), [`attribute_groups`](Self::attribute_groups)' values per vertex, into `out`
    /// (cleared; left empty when the mesh has none to interpolate). As
    /// [`Geomorphs::write_attributes`](crate::regions::Geomorphs::write_attributes).
    pub fn write_attributes(&self, now: Option<f32>, out: &mut Vec<f32>) {
        out.clear();
        let n = self.motion.tables.position_of.len() as u32;
        for v in 0..n {
            self.motion.write_attributes(v, now, out);
        }
    }

    /// The further attributes morphs interpolate (UVs, tangents, `f32` attributes), in the
    /// order [`write_attributes`](Self::write_attributes) writes them; empty when none.
    #[must_use]
    pub fn attribute_groups(&self) -> &[MorphGroup] {
        self.motion.attribute_groups()
    }
}
