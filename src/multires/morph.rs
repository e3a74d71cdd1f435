//! Vertex motion under geomorphs, shared by region levels
//! ([`Geomorphs`](crate::regions::Geomorphs)) and variable-resolution levels
//! ([`VariableGeomorphs`](crate::refine::VariableGeomorphs)): which collapse moves each
//! position where, and the positions in motion with their normals and further attributes
//! (UVs, tangents, `f32` attributes: [`MorphAttributes`]).
//!
//! A level is a set of performed collapses, given to the functions here as `done(step)`:
//! a prefix of a region's sequence, or any set closed under a variable mesh's dependencies.

use super::ProgressiveMesh;
use crate::mesh::{IndexedMesh, Scalar, VertexAttribute};
use crate::util::{Buckets, buckets};
use glam::{Vec2, Vec3, Vec3A, Vec4};
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::Arc;

/// Where a morphing position is heading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Toward {
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

/// The further attributes of one vertex in motion: the values it was shown with when its
/// morph started, toward vertex `to`'s own (its own, or its representative's).
#[derive(Clone, Debug, PartialEq)]
struct AttributeMorph {
    from: Box<[f32]>,
    to: u32,
}

/// What a group of a geomorph's further attribute values is, and so how it is interpolated
/// (see [`Geomorphs::write_attributes`](crate::regions::Geomorphs::write_attributes)).
#[derive(Clone, Debug, PartialEq)]
pub enum MorphKind {
    /// The first UV set (two values), interpolated.
    Uv,
    /// Tangents (four values): the direction interpolated and normalised, the handedness
    /// (w) the vertex's own.
    Tangent,
    /// A further attribute of `f32` components (its name, id and format; no data),
    /// interpolated.
    Attribute(VertexAttribute),
}

/// One attribute among the further attribute values a geomorph writes per vertex (see
/// [`Geomorphs::write_attributes`](crate::regions::Geomorphs::write_attributes)).
#[derive(Clone, Debug, PartialEq)]
pub struct MorphGroup {
    /// Which attribute, and how it is interpolated.
    pub kind: MorphKind,
    /// Its first value among a vertex's.
    pub offset: usize,
    /// How many values it has.
    pub len: usize,
}

/// The attributes besides positions and normals that geomorphs interpolate, as `f32`s per
/// vertex: the first UV set, tangents, and every further attribute of `f32` components.
/// Others (integers, normalised and half floats) are not interpolated: a vertex in motion
/// shows its own.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MorphAttributes {
    pub(crate) groups: Vec<MorphGroup>,
    /// Values per vertex.
    pub(crate) stride: usize,
    values: Vec<f32>,
}

impl MorphAttributes {
    /// The attributes of `mesh` that geomorphs interpolate; `None` when it has none.
    pub(crate) fn of(mesh: &IndexedMesh) -> Option<Self> {
        let n = mesh.positions.len();
        // Per group, where its values come from: the UVs, the tangents, or a further
        // attribute (its index).
        let mut groups = Vec::new();
        let mut sources = Vec::new();
        let mut stride = 0;
        let mut add = |kind, len, source: Option<usize>| {
            groups.push(MorphGroup {
                kind,
                offset: stride,
                len,
            });
            sources.push(source);
            stride += len;
        };
        let uvs = mesh.uvs.as_ref().filter(|u| u.len() == n);
        let tangents = mesh.tangents.as_ref().filter(|t| t.len() == n);
        if uvs.is_some() {
            add(MorphKind::Uv, 2, None);
        }
        if tangents.is_some() {
            add(MorphKind::Tangent, 4, None);
        }
        for (k, a) in mesh.attributes.iter().enumerate() {
            let len = usize::from(a.format.components);
            if a.format.scalar == Scalar::F32 && len > 0 && a.data.len() == n * 4 * len {
                add(MorphKind::Attribute(a.without_data()), len, Some(k));
            }
        }
        if stride == 0 {
            return None;
        }
        let mut values = Vec::with_capacity(n * stride);
        for v in 0..n {
            for (group, source) in groups.iter().zip(&sources) {
                match (&group.kind, source) {
                    (MorphKind::Uv, _) => values.extend(uvs.map_or([0.0; 2], |u| u[v].to_array())),
                    (MorphKind::Tangent, _) => {
                        values.extend(tangents.map_or([0.0; 4], |t| t[v].to_array()));
                    }
                    (MorphKind::Attribute(_), Some(k)) => {
                        let record =
                            &mesh.attributes[*k].data[v * 4 * group.len..(v + 1) * 4 * group.len];
                        values.extend(
                            record
                                .chunks_exact(4)
                                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                        );
                    }
                    (MorphKind::Attribute(_), None) => {}
                }
            }
        }
        Some(Self {
            groups,
            stride,
            values,
        })
    }

    /// Vertex `g`'s own values.
    fn vertex(&self, g: u32) -> &[f32] {
        &self.values[g as usize * self.stride..(g as usize + 1) * self.stride]
    }

    /// The values a vertex whose own are `own` shows at `t` (`0.0..=1.0`) of a morph from
    /// `from` to `to`, appended to `out`.
    fn interpolate(&self, from: &[f32], to: &[f32], own: &[f32], t: f32, out: &mut Vec<f32>) {
        for group in &self.groups {
            let range = group.offset..group.offset + group.len;
            let (from, to, own) = (&from[range.clone()], &to[range.clone()], &own[range]);
            if t >= 1.0 {
                out.extend_from_slice(to);
            } else {
                out.extend(from.iter().zip(to).map(|(&a, &b)| a + (b - a) * t));
            }
            if group.kind == MorphKind::Tangent {
                let at = out.len() - 4;
                let to_dir = Vec3A::new(to[0], to[1], to[2]);
                let dir = Vec3A::new(out[at], out[at + 1], out[at + 2]).normalize_or(to_dir);
                out[at..at + 3].copy_from_slice(&dir.to_array());
                out[at + 3] = own[3];
            }
        }
    }
}

/// One vertex's morph as a vertex shader interpolates it: shown at `from + (to - from) * t`
/// with `t = ((now - start) / duration).clamp(0, 1)` (`to` itself at `t = 1`), its normal at
/// `normal_from.lerp(normal_to, t)`, normalised, its first UV set at
/// `uv_from.lerp(uv_to, t)`, its tangent's direction as its normal's and its handedness
/// `tangent_to.w`. A vertex at rest has `from == to`.
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
    /// Its first UV set when the morph started (zero when the mesh has none).
    pub uv_from: Vec2,
    /// Its first UV set at the end (zero when the mesh has none).
    pub uv_to: Vec2,
    /// Its tangent when the morph started (zero when the mesh has none; `w` as `tangent_to`).
    pub tangent_from: Vec4,
    /// Its tangent at the end, with its own handedness (zero when the mesh has none).
    pub tangent_to: Vec4,
    /// When the morph started, on the clock of the `now` arguments.
    pub start: f32,
}

/// What a mesh's morphs are made of (made once per mesh, shared by its instances).
#[derive(Debug)]
pub(crate) struct MorphTables {
    /// Per vertex: its position (the first vertex there). Morphs move positions, so every
    /// copy of a seam vertex moves alike, even one no triangle uses any more.
    pub(crate) position_of: Vec<u32>,
    /// Per position: the vertices there.
    copies: Buckets,
    /// Per sequence (region), per step: the positions that step removes.
    pub(crate) removed_at: Vec<Vec<Vec<u32>>>,
    /// Per position: the step of its sequence that removes it (`u32::MAX`: never) and the
    /// position it goes onto.
    parent: Vec<(u32, u32)>,
    /// Per vertex: the step that moves it and the vertex its corners go to, for normals and
    /// further attributes (`u32::MAX`: no recorded move), from the records of the sequence
    /// that moves its position only.
    vertex_parent: Vec<(u32, u32)>,
    /// Per sequence: the triangle count of each level.
    pub(crate) counts: Vec<Vec<usize>>,
    /// Per vertex: its sequence (region).
    region_of: Vec<u32>,
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    /// The further attributes morphs interpolate ([`with_attributes`](Self::with_attributes)).
    attributes: Option<MorphAttributes>,
}

impl MorphTables {
    /// The tables, interpolating the further attributes of `mesh` (the mesh whose vertices
    /// they were made for) too.
    pub(crate) fn with_attributes(mut self, mesh: &IndexedMesh) -> Self {
        self.attributes =
            MorphAttributes::of(mesh).filter(|a| a.values.len() / a.stride == self.positions.len());
        self
    }

    /// The tables of a mesh whose vertices (`positions`, `normals`) are split among
    /// `sequences`: each a progressive mesh and the mesh vertex of each of its vertices
    /// (`None`: the same numbers). `region_of` gives each vertex's sequence.
    pub(crate) fn new<'a>(
        positions: Vec<Vec3>,
        normals: Option<Vec<Vec3>>,
        region_of: Vec<u32>,
        sequences: impl ExactSizeIterator<Item = (&'a ProgressiveMesh, Option<&'a [u32]>)>,
    ) -> Self {
        let n = positions.len();
        let position_of = crate::mesh::weld_positions(&positions).remap;
        let copies = buckets(&position_of, n);
        let mut parent = vec![(u32::MAX, u32::MAX); n];
        let mut vertex_parent = vec![(u32::MAX, u32::MAX); n];
        let mut driver = vec![u32::MAX; n];
        let mut removed_at = Vec::with_capacity(sequences.len());
        let mut counts = Vec::with_capacity(sequences.len());
        for (seq, (pm, global)) in sequences.enumerate() {
            let global = |v: u32| global.map_or(v, |g| g[v as usize]);
            let mut at: Vec<Vec<u32>> = vec![Vec::new(); pm.records.step_count()];
            for (step, old, new) in pm.records.step_pairs() {
                let (g, to) = (global(old), global(new));
                let (p, q) = (position_of[g as usize], position_of[to as usize]);
                // Identity pairs (a corner that keeps its vertex: an ear's far corner) move
                // nothing.
                if p == q {
                    continue;
                }
                if parent[p as usize].0 == u32::MAX {
                    parent[p as usize] = (step as u32, q);
                    driver[p as usize] = seq as u32;
                    at[step].push(p);
                }
                // A position moves with the first sequence that moves it, whose steps then
                // drive its morph; a vertex that sequences share (on a border) takes its
                // attributes from that sequence's records only (another's steps mean
                // nothing to that sequence's levels).
                if driver[p as usize] == seq as u32 && vertex_parent[g as usize].0 == u32::MAX {
                    vertex_parent[g as usize] = (step as u32, to);
                }
            }
            removed_at.push(at);
            counts.push(pm.level_triangle_counts());
        }
        // A vertex whose every triangle goes with the collapse that moves its position (a
        // flat-shaded corner, a part erased, in a permissive build) has no rewritten corner,
        // so no pair: it takes a copy's move at that step, or else a vertex at the target, so
        // that its attributes go where its position goes.
        for g in 0..n {
            let (step, q) = parent[position_of[g] as usize];
            if vertex_parent[g].0 != u32::MAX || step == u32::MAX {
                continue;
            }
            let sibling = copies.get(position_of[g] as usize).iter().find_map(|&c| {
                let (s, to) = vertex_parent[c as usize];
                (s == step).then_some(to)
            });
            if let Some(to) = sibling.or_else(|| copies.get(q as usize).first().copied()) {
                vertex_parent[g] = (step, to);
            }
        }
        Self {
            position_of,
            copies,
            removed_at,
            parent,
            vertex_parent,
            counts,
            region_of,
            positions,
            normals,
            attributes: None,
        }
    }

    /// Adds the moves of sequence `seq` that its records do not show (`moves`: step, the
    /// vertex it removes and the vertex it keeps): a vertex whose triangles all go with the
    /// collapse (an ear's tip on an open outline) is rewritten nowhere, but still has a place
    /// to vanish onto.
    pub(crate) fn add_unrecorded_moves(
        &mut self,
        seq: usize,
        moves: impl Iterator<Item = (usize, u32, u32)>,
    ) {
        for (step, u, w) in moves {
            let (p, q) = (self.position_of[u as usize], self.position_of[w as usize]);
            if p == q || self.parent[p as usize].0 != u32::MAX {
                continue;
            }
            self.parent[p as usize] = (step as u32, q);
            if let Some(at) = self.removed_at.get_mut(seq).and_then(|s| s.get_mut(step)) {
                at.push(p);
            }
            for &g in self.copies.get(p as usize) {
                if self.vertex_parent[g as usize].0 == u32::MAX {
                    self.vertex_parent[g as usize] = (step as u32, w);
                }
            }
        }
    }

    /// The vertices at position `p`.
    pub(crate) fn copies_of(&self, p: u32) -> &[u32] {
        self.copies.get(p as usize)
    }

    /// The position that stands for position `p` at the level whose performed steps `done`
    /// says.
    pub(crate) fn representative(&self, p: u32, done: impl Fn(u32) -> bool) -> u32 {
        follow(&self.parent, p, done)
    }

    /// The vertex whose attributes stand for vertex `g` at the level `done` says (as far as
    /// its recorded moves go: a copy no triangle uses any more moves no further).
    fn vertex_representative(&self, g: u32, done: impl Fn(u32) -> bool) -> u32 {
        follow(&self.vertex_parent, g, done)
    }
}

/// Follows `moves` (per item: the step that moves it, `u32::MAX` for none, and where to)
/// from `start` while the move's step is done. Each move goes to a later step's item, so the
/// chain ends; the bound guards a damaged file's sequences.
fn follow(moves: &[(u32, u32)], mut at: u32, done: impl Fn(u32) -> bool) -> u32 {
    for _ in 0..moves.len() {
        match moves.get(at as usize) {
            Some(&(step, to)) if step != u32::MAX && done(step) => at = to,
            _ => break,
        }
    }
    at
}

/// The positions of one instance in motion, with their copies' normals.
#[derive(Clone, Debug)]
pub(crate) struct Motion {
    pub(crate) duration: f32,
    pub(crate) tables: Arc<MorphTables>,
    morphs: HashMap<u32, Morph, VertexHash>,
    normal_morphs: HashMap<u32, NormalMorph, VertexHash>,
    attribute_morphs: HashMap<u32, AttributeMorph, VertexHash>,
    /// Morphs toward their own place by end time (as `f32` bits, which order non-negative
    /// times), to end them when due; an entry whose morph restarted since is skipped.
    ends: BinaryHeap<Reverse<(u32, u32)>>,
    /// Per sequence: copies of positions in motion among its own vertices.
    moving: Vec<usize>,
    /// Positions whose morph started since the last [`take_restarted`](Self::take_restarted),
    /// each once (`marked`).
    restarted: Vec<u32>,
    marked: Vec<bool>,
}

impl Motion {
    /// Nothing in motion; `duration` in seconds (negative or NaN count as `0`).
    pub(crate) fn new(tables: Arc<MorphTables>, duration: f32) -> Self {
        let sequences = tables.counts.len();
        Self {
            duration: if duration > 0.0 { duration } else { 0.0 },
            tables,
            morphs: HashMap::default(),
            normal_morphs: HashMap::default(),
            attribute_morphs: HashMap::default(),
            ends: BinaryHeap::new(),
            moving: vec![0; sequences],
            restarted: Vec::new(),
            marked: Vec::new(),
        }
    }

    /// Whether any position is in motion.
    pub(crate) fn is_moving(&self) -> bool {
        !self.morphs.is_empty()
    }

    /// Whether a position in motion has a copy among sequence `r`'s vertices.
    pub(crate) fn is_sequence_moving(&self, r: usize) -> bool {
        self.moving.get(r).is_some_and(|&m| m > 0)
    }

    /// Where position `p` is heading, when it moves.
    pub(crate) fn heading(&self, p: u32) -> Option<Toward> {
        self.morphs.get(&p).map(|m| m.toward)
    }

    /// Position `p` appears at the level `shown` says (one of its steps is undone): it
    /// starts where its representative there is shown and moves to its own place.
    pub(crate) fn appear(&mut self, p: u32, shown: impl Fn(u32) -> bool + Copy, now: f32) {
        let from = self.tables.representative(p, shown);
        let normals: Vec<(u32, NormalMorph)> = self
            .tables
            .copies_of(p)
            .iter()
            .map(|&g| {
                let rep = self.tables.vertex_representative(g, shown);
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
        let attributes = self.attribute_morphs_of(p, |g, motion| {
            let rep = motion.tables.vertex_representative(g, shown);
            (motion.shown_attributes(rep, now), g)
        });
        let morph = Morph {
            from: self.position_of_p(from, now),
            to: self.tables.positions[p as usize],
            start: now,
            toward: Toward::Own,
        };
        self.start(p, morph);
        self.normal_morphs.extend(normals);
        self.attribute_morphs.extend(attributes);
    }

    /// The attribute morphs of position `p`'s copies (none when the mesh has no further
    /// attributes to interpolate), `from_to` giving each copy's start values and the vertex
    /// whose own values it heads for.
    fn attribute_morphs_of(
        &self,
        p: u32,
        from_to: impl Fn(u32, &Self) -> (Box<[f32]>, u32),
    ) -> Vec<(u32, AttributeMorph)> {
        if self.tables.attributes.is_none() {
            return Vec::new();
        }
        self.tables
            .copies_of(p)
            .iter()
            .map(|&g| {
                let (from, to) = from_to(g, self);
                (g, AttributeMorph { from, to })
            })
            .collect()
    }

    /// Starts position `p` toward `toward` from where it is shown now (nothing when it is
    /// at rest at its own place and stays there); its copies' normals toward their
    /// representatives at the level `goal` says (vanishing) or their own.
    pub(crate) fn retarget(
        &mut self,
        p: u32,
        toward: Toward,
        goal: impl Fn(u32) -> bool + Copy,
        now: f32,
    ) {
        if toward == Toward::Own && !self.morphs.contains_key(&p) {
            return;
        }
        let normals: Vec<(u32, NormalMorph)> = self
            .tables
            .copies_of(p)
            .iter()
            .map(|&g| {
                let to = match toward {
                    Toward::Own => self.own_normal(g),
                    Toward::Position(_) => {
                        self.own_normal(self.tables.vertex_representative(g, goal))
                    }
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
        let attributes = self.attribute_morphs_of(p, |g, motion| {
            let to = match toward {
                Toward::Own => g,
                Toward::Position(_) => motion.tables.vertex_representative(g, goal),
            };
            (motion.shown_attributes(g, now), to)
        });
        let morph = Morph {
            from: self.position_of_p(p, now),
            to,
            start: now,
            toward,
        };
        self.start(p, morph);
        self.normal_morphs.extend(normals);
        self.attribute_morphs.extend(attributes);
    }

    /// Ends the morphs toward their own place that are due by `now`.
    pub(crate) fn end_due(&mut self, now: f32) {
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

    /// Ends position `p`'s morph (and its copies' normals').
    pub(crate) fn end(&mut self, p: u32) {
        if self.morphs.remove(&p).is_some() {
            self.count_moving(p, false);
        }
        for &g in self.tables.copies_of(p) {
            self.normal_morphs.remove(&g);
            self.attribute_morphs.remove(&g);
        }
    }

    /// Where vertex `g` is shown at `now`.
    pub(crate) fn position(&self, g: u32, now: f32) -> Vec3 {
        self.position_of_p(self.tables.position_of[g as usize], now)
    }

    /// The normal vertex `g` is shown with at `now` (interpolated and normalised), when the
    /// mesh has normals.
    pub(crate) fn normal(&self, g: u32, now: f32) -> Option<Vec3> {
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

    /// The further attributes ([`MorphAttributes`]) vertex `g` is shown with at `now`,
    /// appended to `out` (nothing when the mesh has none to interpolate).
    /// `None` for `now`: its own values, as at rest.
    pub(crate) fn write_attributes(&self, g: u32, now: Option<f32>, out: &mut Vec<f32>) {
        let Some(table) = &self.tables.attributes else {
            return;
        };
        let own = table.vertex(g);
        let p = self.tables.position_of[g as usize];
        let (Some(now), Some(m), Some(am)) =
            (now, self.morphs.get(&p), self.attribute_morphs.get(&g))
        else {
            out.extend_from_slice(own);
            return;
        };
        table.interpolate(
            &am.from,
            table.vertex(am.to),
            own,
            self.progress(m, now),
            out,
        );
    }

    /// [`write_attributes`](Self::write_attributes) of one vertex, on its own.
    fn shown_attributes(&self, g: u32, now: f32) -> Box<[f32]> {
        let mut out = Vec::new();
        self.write_attributes(g, Some(now), &mut out);
        out.into_boxed_slice()
    }

    /// Vertex `g`'s morph as a vertex shader interpolates it.
    pub(crate) fn vertex_morph(&self, g: u32) -> VertexMorph {
        let p = self.tables.position_of[g as usize];
        let own = self.tables.positions[p as usize];
        let own_normal = self.own_normal(g);
        let m = self.morphs.get(&p);
        let nm = m.and(self.normal_morphs.get(&g));
        let mut morph = VertexMorph {
            from: m.map_or(own, |m| m.from),
            to: m.map_or(own, |m| m.to),
            normal_from: nm.map_or(own_normal, |n| n.from),
            normal_to: nm.map_or(own_normal, |n| n.to),
            uv_from: Vec2::ZERO,
            uv_to: Vec2::ZERO,
            tangent_from: Vec4::ZERO,
            tangent_to: Vec4::ZERO,
            start: m.map_or(0.0, |m| m.start),
        };
        let Some(table) = &self.tables.attributes else {
            return morph;
        };
        let own = table.vertex(g);
        let am = m.and(self.attribute_morphs.get(&g));
        let from = am.map_or(own, |a| &a.from[..]);
        let to = am.map_or(own, |a| table.vertex(a.to));
        for group in &table.groups {
            let o = group.offset;
            match group.kind {
                MorphKind::Uv => {
                    morph.uv_from = Vec2::new(from[o], from[o + 1]);
                    morph.uv_to = Vec2::new(to[o], to[o + 1]);
                }
                MorphKind::Tangent => {
                    morph.tangent_from = Vec4::new(from[o], from[o + 1], from[o + 2], own[o + 3]);
                    morph.tangent_to = Vec4::new(to[o], to[o + 1], to[o + 2], own[o + 3]);
                }
                MorphKind::Attribute(_) => {}
            }
        }
        morph
    }

    /// The further attributes morphs interpolate, in the order
    /// [`write_attributes`](Self::write_attributes) writes them; empty when none.
    pub(crate) fn attribute_groups(&self) -> &[MorphGroup] {
        self.tables
            .attributes
            .as_ref()
            .map_or(&[], |a| a.groups.as_slice())
    }

    /// Whether the mesh has normals.
    pub(crate) fn has_normals(&self) -> bool {
        self.tables.normals.is_some()
    }

    /// The positions whose morph started since the last call, each once; `visit` sees each
    /// while it is still marked (see [`is_marked`](Self::is_marked)).
    pub(crate) fn take_restarted(&mut self, mut visit: impl FnMut(&Self, &[u32])) {
        if self.restarted.is_empty() {
            return;
        }
        let restarted = std::mem::take(&mut self.restarted);
        visit(self, &restarted);
        for &p in &restarted {
            self.marked[p as usize] = false;
        }
        self.restarted = restarted;
        self.restarted.clear();
    }

    /// Whether vertex `g`'s position is noted for [`take_restarted`](Self::take_restarted).
    pub(crate) fn is_marked(&self, g: u32) -> bool {
        self.marked[self.tables.position_of[g as usize] as usize]
    }

    /// How far morph `m` has come at `now`, `0.0..=1.0`.
    fn progress(&self, m: &Morph, now: f32) -> f32 {
        ((now - m.start) / self.duration).clamp(0.0, 1.0)
    }

    /// Where position `p` is shown at `now`.
    pub(crate) fn position_of_p(&self, p: u32, now: f32) -> Vec3 {
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

    /// Counts position `p` in (or out of) the moving positions of the sequences its copies
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
