//! Convex hulls: a 3D quickhull (Barber, Dobkin & Huhdanpaa 1996) for the OBB fit, and a 2D
//! monotone chain (Andrew 1979) for the OBB fit and the near-plane clip, both in `f64`.
//!
//! The 3D hull only feeds [`fit_obb`](super::fit_obb) with candidate directions (its face
//! normals), a reduced point set (its vertices) and silhouettes, so it favours never failing
//! over exactness: points within `eps` of a face count as inside, and a topology it cannot
//! continue returns [`Hull3::Failed`], on which the caller falls back to the full point set.

use glam::{DVec2, DVec3};
use std::collections::HashMap;

/// The result of [`convex_hull_3d`].
#[derive(Debug)]
pub(super) enum Hull3 {
    /// A full-dimensional hull.
    Solid(SolidHull),
    /// Every point lies within `eps` of the plane with this unit normal.
    Flat {
        /// The plane's unit normal.
        normal: DVec3,
    },
    /// Every point lies within `eps` of the line with this unit direction.
    Line {
        /// The line's unit direction.
        direction: DVec3,
    },
    /// Every point lies within `eps` of one point.
    Point,
    /// The hull ran into a topology it could not continue (numerical trouble).
    Failed,
}

/// A closed triangulated convex surface, with the adjacency that finds its silhouette.
#[derive(Debug)]
pub(super) struct SolidHull {
    /// Indices of the hull's vertices into the input points, ascending.
    pub vertices: Vec<u32>,
    /// Each face's corners (input point indices), counter-clockwise seen from outside.
    pub faces: Vec<[u32; 3]>,
    /// Each face's outward unit normal.
    pub normals: Vec<DVec3>,
    /// Each face's neighbours across its edges `(v0, v1)`, `(v1, v2)`, `(v2, v0)`.
    pub neighbors: Vec<[u32; 3]>,
}

impl SolidHull {
    /// The silhouette loop seen along `n`: the corners of the edges between faces facing `n`
    /// and faces that do not, in order, into `out` (input point indices). `front` and `next`
    /// are scratch space. `false` when the loop is not one simple cycle (numerical trouble),
    /// and then `out` is not to be used.
    pub fn silhouette(
        &self,
        n: DVec3,
        front: &mut Vec<bool>,
        next: &mut Vec<u32>,
        out: &mut Vec<u32>,
    ) -> bool {
        front.clear();
        front.extend(self.normals.iter().map(|f| f.dot(n) > 0.0));
        out.clear();
        let mut edges = 0;
        let mut start = u32::MAX;
        for (f, face) in self.faces.iter().enumerate() {
            if !front[f] {
                continue;
            }
            for e in 0..3 {
                if !front[self.neighbors[f][e] as usize] {
                    let (a, b) = (face[e], face[(e + 1) % 3]);
                    if next.len() <= a as usize {
                        next.resize(a as usize + 1, u32::MAX);
                    }
                    next[a as usize] = b;
                    start = a;
                    edges += 1;
                }
            }
        }
        if edges < 3 {
            return false;
        }
        let mut v = start;
        loop {
            out.push(v);
            v = match next.get(v as usize) {
                Some(&w) if w != u32::MAX => w,
                _ => break,
            };
            if v == start || out.len() > edges {
                break;
            }
        }
        // Reset the scratch entries this call set: the loop's vertices when it visited every
        // silhouette edge, else every corner of a front face.
        let closed = v == start && out.len() == edges;
        if closed {
            for &a in out.iter() {
                next[a as usize] = u32::MAX;
            }
        } else {
            for (face, _) in self.faces.iter().zip(front.iter()).filter(|(_, f)| **f) {
                for &a in face {
                    if let Some(slot) = next.get_mut(a as usize) {
                        *slot = u32::MAX;
                    }
                }
            }
        }
        closed
    }
}

struct Face {
    v: [u32; 3],
    normal: DVec3,
    offset: f64,
    outside: Vec<u32>,
    alive: bool,
}

impl Face {
    #[inline]
    fn distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.offset
    }

    #[inline]
    fn edges(&self) -> [(u32, u32); 3] {
        let [a, b, c] = self.v;
        [(a, b), (b, c), (c, a)]
    }
}

/// Builds a face `a, b, c` (counter-clockwise seen from outside), or `None` when the three points
/// are collinear.
fn make_face(points: &[DVec3], v: [u32; 3]) -> Option<Face> {
    let [a, b, c] = v.map(|i| points[i as usize]);
    let normal = (b - a).cross(c - a).try_normalize()?;
    Some(Face {
        v,
        normal,
        offset: normal.dot(a),
        outside: Vec::new(),
        alive: true,
    })
}

/// The convex hull of `points`; `eps` is the distance below which a point counts as on a plane.
pub(super) fn convex_hull_3d(points: &[DVec3], eps: f64) -> Hull3 {
    if points.is_empty() {
        return Hull3::Point;
    }
    // Initial simplex from the axis extremes: the farthest pair, then the point farthest from
    // their line, then the point farthest from that plane.
    let mut extremes = [0usize; 6];
    for (i, p) in points.iter().enumerate() {
        for axis in 0..3 {
            if p[axis] < points[extremes[2 * axis]][axis] {
                extremes[2 * axis] = i;
            }
            if p[axis] > points[extremes[2 * axis + 1]][axis] {
                extremes[2 * axis + 1] = i;
            }
        }
    }
    let (mut i0, mut i1, mut best) = (0, 0, -1.0);
    for a in 0..6 {
        for b in a + 1..6 {
            let d = points[extremes[a]].distance_squared(points[extremes[b]]);
            if d > best {
                (i0, i1, best) = (extremes[a], extremes[b], d);
            }
        }
    }
    if best.sqrt() <= eps {
        return Hull3::Point;
    }
    let (p0, p1) = (points[i0], points[i1]);
    let direction = (p1 - p0).normalize();
    let (i2, d2) = farthest(points, |p| {
        let r = p - p0;
        (r - direction * r.dot(direction)).length()
    });
    if d2 <= eps {
        return Hull3::Line { direction };
    }
    let normal = (p1 - p0).cross(points[i2] - p0).normalize();
    let (i3, d3) = farthest(points, |p| normal.dot(p - p0).abs());
    if d3 <= eps {
        return Hull3::Flat { normal };
    }
    match quickhull(points, [i0, i1, i2, i3].map(|i| i as u32), eps) {
        Some(hull) => hull,
        None => Hull3::Failed,
    }
}

fn farthest(points: &[DVec3], distance: impl Fn(DVec3) -> f64) -> (usize, f64) {
    let mut best = (0, -1.0);
    for (i, &p) in points.iter().enumerate() {
        let d = distance(p);
        if d > best.1 {
            best = (i, d);
        }
    }
    best
}

/// Quickhull from the tetrahedron `tetra`. `None` on a topology it cannot continue.
fn quickhull(points: &[DVec3], tetra: [u32; 4], eps: f64) -> Option<Hull3> {
    let mut faces: Vec<Face> = Vec::new();
    let mut edge_face: HashMap<(u32, u32), usize> = HashMap::new();
    let centroid = tetra.iter().map(|&i| points[i as usize]).sum::<DVec3>() / 4.0;
    for skip in 0..4 {
        let mut v = [0u32; 3];
        let mut n = 0;
        for (k, &i) in tetra.iter().enumerate() {
            if k != skip {
                v[n] = i;
                n += 1;
            }
        }
        let mut face = make_face(points, v)?;
        if face.distance(centroid) > 0.0 {
            face = make_face(points, [v[0], v[2], v[1]])?;
        }
        add_face(&mut faces, &mut edge_face, face)?;
    }
    // Each point goes to the outside set of the face it is farthest above.
    let on_hull = |i: u32| tetra.contains(&i);
    for (i, &p) in points.iter().enumerate() {
        let i = i as u32;
        if !on_hull(i) {
            assign(&mut faces, 0..4, i, p, eps);
        }
    }

    // Faces only receive outside points when they are created, so one pass in creation order
    // (which includes the faces appended on the way) visits every non-empty outside set.
    let mut state: Vec<u8> = Vec::new(); // 0 unknown, 1 visible, 2 not visible
    let mut touched: Vec<usize> = Vec::new();
    let mut visible: Vec<usize> = Vec::new();
    let mut horizon: Vec<(u32, u32)> = Vec::new();
    let mut orphans: Vec<u32> = Vec::new();
    let mut fi = 0;
    while fi < faces.len() {
        if !faces[fi].alive || faces[fi].outside.is_empty() {
            fi += 1;
            continue;
        }
        let eye = *faces[fi]
            .outside
            .iter()
            .max_by(|&&a, &&b| {
                let face = &faces[fi];
                face.distance(points[a as usize])
                    .total_cmp(&face.distance(points[b as usize]))
                    .then(b.cmp(&a))
            })
            .expect("outside set is not empty");
        let eye_point = points[eye as usize];

        // The faces the eye sees, found by a flood fill from `fi`, and the horizon around them.
        state.resize(faces.len(), 0);
        visible.clear();
        horizon.clear();
        touched.clear();
        state[fi] = 1;
        touched.push(fi);
        visible.push(fi);
        let mut next = 0;
        while next < visible.len() {
            let g = visible[next];
            next += 1;
            for (a, b) in faces[g].edges() {
                let h = *edge_face.get(&(b, a))?;
                if state[h] == 0 {
                    touched.push(h);
                    state[h] = if faces[h].distance(eye_point) > eps {
                        visible.push(h);
                        1
                    } else {
                        2
                    };
                }
                if state[h] == 2 {
                    horizon.push((a, b));
                }
            }
        }
        for &t in &touched {
            state[t] = 0;
        }

        orphans.clear();
        for &g in &visible {
            faces[g].alive = false;
            orphans.append(&mut faces[g].outside);
            for e in faces[g].edges() {
                edge_face.remove(&e);
            }
        }
        let first_new = faces.len();
        for &(a, b) in &horizon {
            let face = make_face(points, [a, b, eye])?;
            add_face(&mut faces, &mut edge_face, face)?;
        }
        let new_faces = first_new..faces.len();
        for &i in &orphans {
            if i != eye {
                assign(&mut faces, new_faces.clone(), i, points[i as usize], eps);
            }
        }
        fi += 1;
    }

    // Renumber the live faces densely and look up their neighbours.
    let mut dense = vec![u32::MAX; faces.len()];
    let mut live = 0;
    for (f, face) in faces.iter().enumerate() {
        if face.alive {
            dense[f] = live;
            live += 1;
        }
    }
    let mut is_vertex = vec![false; points.len()];
    let mut hull = SolidHull {
        vertices: Vec::new(),
        faces: Vec::with_capacity(live as usize),
        normals: Vec::with_capacity(live as usize),
        neighbors: Vec::with_capacity(live as usize),
    };
    for face in faces.iter().filter(|f| f.alive) {
        for v in face.v {
            is_vertex[v as usize] = true;
        }
        let mut neighbors = [0u32; 3];
        for (k, (a, b)) in face.edges().into_iter().enumerate() {
            neighbors[k] = dense[*edge_face.get(&(b, a))?];
            if neighbors[k] == u32::MAX {
                return None;
            }
        }
        hull.faces.push(face.v);
        hull.normals.push(face.normal);
        hull.neighbors.push(neighbors);
    }
    hull.vertices = (0..points.len() as u32)
        .filter(|&i| is_vertex[i as usize])
        .collect();
    Some(Hull3::Solid(hull))
}

/// Appends `face` and registers its directed edges; `None` when an edge is already taken (the
/// surface would not be a 2-manifold).
fn add_face(
    faces: &mut Vec<Face>,
    edge_face: &mut HashMap<(u32, u32), usize>,
    face: Face,
) -> Option<()> {
    let id = faces.len();
    for e in face.edges() {
        if edge_face.insert(e, id).is_some() {
            return None;
        }
    }
    faces.push(face);
    Some(())
}

/// Puts point `i` into the outside set of the face among `candidates` it is farthest above, if
/// it is more than `eps` above any.
fn assign(faces: &mut [Face], candidates: std::ops::Range<usize>, i: u32, p: DVec3, eps: f64) {
    let mut best = (usize::MAX, eps);
    for f in candidates {
        let d = faces[f].distance(p);
        if d > best.1 {
            best = (f, d);
        }
    }
    if best.0 != usize::MAX {
        faces[best.0].outside.push(i);
    }
}

/// The convex hull of `points`, counter-clockwise, without collinear vertices, into `hull`.
/// `points` is sorted in place.
///
/// `total_cmp` orders −0 before +0, so points with both zeros at the smallest or largest x
/// reach the chain out of order and one can be left off the hull; the near-plane clip sorts its
/// points itself, by value.
pub(super) fn convex_hull_2d(points: &mut [DVec2], hull: &mut Vec<DVec2>) {
    points.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    monotone_chain(points, hull);
}

/// Where [`monotone_chain`] builds a hull. The OBB fit keeps its hulls in a `Vec` (offline, of
/// any size); the near-plane clip of [`ProjectedAreaCamera`](crate::budget::ProjectedAreaCamera) runs
/// for every box that straddles the plane, every frame, and keeps its few points in a fixed
/// array on the stack. So the one hull is generic over where its points go, and neither
/// allocates per call.
pub(crate) trait PointStack {
    /// Removes every point.
    fn clear(&mut self);
    /// Puts `p` on top.
    fn push(&mut self, p: DVec2);
    /// Removes the top point.
    fn pop(&mut self);
    /// The points, the top one last.
    fn as_slice(&self) -> &[DVec2];
}

impl PointStack for Vec<DVec2> {
    #[inline]
    fn clear(&mut self) {
        Vec::clear(self);
    }

    #[inline]
    fn push(&mut self, p: DVec2) {
        Vec::push(self, p);
    }

    #[inline]
    fn pop(&mut self) {
        Vec::pop(self);
    }

    #[inline]
    fn as_slice(&self) -> &[DVec2] {
        self
    }
}

/// The convex hull of `points`, which are sorted by x then y, counter-clockwise, without
/// collinear vertices, into `hull`: Andrew's monotone chain.
pub(crate) fn monotone_chain<H: PointStack>(points: &[DVec2], hull: &mut H) {
    hull.clear();
    if points.len() < 3 {
        for &p in points {
            hull.push(p);
        }
    } else {
        let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
        // Whether the top two points and `p` make no left turn (so the top one goes).
        let no_left_turn = |hull: &H, p: DVec2| {
            let h = hull.as_slice();
            cross(h[h.len() - 2], h[h.len() - 1], p) <= 0.0
        };
        // Lower hull, then upper hull.
        for &p in points {
            while hull.as_slice().len() >= 2 && no_left_turn(hull, p) {
                hull.pop();
            }
            hull.push(p);
        }
        let lower_len = hull.as_slice().len() + 1;
        for &p in points.iter().rev().skip(1) {
            while hull.as_slice().len() >= lower_len && no_left_turn(hull, p) {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop(); // the first point again
    }
    if matches!(hull.as_slice(), [a, b] if a == b) {
        hull.pop();
    }
}

/// The minimum-area rectangle around a convex polygon `hull` (counter-clockwise, no collinear
/// vertices) by rotating calipers (Toussaint 1983): one side of the optimum is flush with a hull
/// edge. Returns the area and the unit direction of that side.
pub(super) fn min_area_rect(hull: &[DVec2]) -> (f64, DVec2) {
    let n = hull.len();
    match n {
        0 | 1 => return (0.0, DVec2::X),
        2 => {
            return (0.0, (hull[1] - hull[0]).try_normalize().unwrap_or(DVec2::X));
        }
        _ => {}
    }
    let at = |i: usize| hull[i % n];
    let (mut j, mut k, mut l) = (1, 1, 1);
    let mut best = (f64::INFINITY, DVec2::X);
    for i in 0..n {
        let Some(d) = (at(i + 1) - at(i)).try_normalize() else {
            continue;
        };
        let inward = d.perp();
        // Farthest along the edge, farthest from it, then the far side along the edge: each
        // caliper only moves forward, so the whole sweep is O(n).
        if i == 0 {
            j = 1;
        }
        let mut steps = 0;
        while steps < n && d.dot(at(j + 1)) > d.dot(at(j)) {
            j += 1;
            steps += 1;
        }
        if i == 0 {
            k = j;
        }
        steps = 0;
        while steps < n && inward.dot(at(k + 1)) >= inward.dot(at(k)) {
            k += 1;
            steps += 1;
        }
        if i == 0 {
            l = k;
        }
        steps = 0;
        while steps < n && d.dot(at(l + 1)) <= d.dot(at(l)) {
            l += 1;
            steps += 1;
        }
        let width = d.dot(at(j) - at(l));
        let height = inward.dot(at(k) - at(i));
        let area = width * height;
        if area < best.0 {
            best = (area, d);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_min_area(hull: &[DVec2]) -> f64 {
        let n = hull.len();
        let mut best = f64::INFINITY;
        for i in 0..n {
            let d = (hull[(i + 1) % n] - hull[i]).normalize();
            let e = d.perp();
            let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
            for &p in hull {
                let q = DVec2::new(d.dot(p), e.dot(p));
                lo = lo.min(q);
                hi = hi.max(q);
            }
            best = best.min((hi - lo).x * (hi - lo).y);
        }
        best
    }

    #[test]
    fn calipers_match_brute_force() {
        let mut state = 7u64;
        let mut next = || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut hull = Vec::new();
        for round in 0..200 {
            let count = 3 + round % 40;
            let mut pts: Vec<DVec2> = (0..count)
                .map(|_| DVec2::new(next() * 4.0 - 2.0, next() - 0.5))
                .collect();
            convex_hull_2d(&mut pts, &mut hull);
            let (area, _) = min_area_rect(&hull);
            let expected = brute_min_area(&hull);
            assert!(
                (area - expected).abs() <= 1e-12 * expected.max(1.0),
                "round {round}: calipers {area}, brute force {expected}"
            );
        }
    }

    #[test]
    fn hull_2d_drops_collinear_and_duplicates() {
        let mut pts = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(0.0, 2.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 0.0),
        ];
        let mut hull = Vec::new();
        convex_hull_2d(&mut pts, &mut hull);
        assert_eq!(
            hull,
            vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(2.0, 0.0),
                DVec2::new(2.0, 2.0),
                DVec2::new(0.0, 2.0)
            ]
        );
        let mut same = vec![DVec2::ONE; 5];
        convex_hull_2d(&mut same, &mut hull);
        assert_eq!(hull.len(), 1);
    }

    #[test]
    fn hull_3d_of_a_cube_with_interior_points() {
        let mut pts = Vec::new();
        for i in 0..8 {
            pts.push(DVec3::new(
                (i & 1) as f64,
                ((i >> 1) & 1) as f64,
                ((i >> 2) & 1) as f64,
            ));
        }
        for i in 0..50 {
            let t = i as f64 / 50.0;
            pts.push(DVec3::new(t, 0.5, 0.25 + 0.5 * t));
            pts.push(DVec3::new(t, 0.0, 0.5)); // on a face
        }
        let Hull3::Solid(hull) = convex_hull_3d(&pts, 1e-9) else {
            panic!("expected a solid hull");
        };
        assert_eq!(hull.vertices, (0..8).collect::<Vec<u32>>());
        assert_eq!(hull.normals.len(), 12);
        for n in &hull.normals {
            assert!((n.abs().max_element() - 1.0).abs() < 1e-12, "normal {n}");
        }
        // Seen along +z, the silhouette is the top square (the side faces do not face +z).
        let (mut front, mut next, mut out) = (Vec::new(), Vec::new(), Vec::new());
        assert!(hull.silhouette(DVec3::Z, &mut front, &mut next, &mut out));
        out.sort_unstable();
        assert_eq!(out, vec![4, 5, 6, 7]);
        // Seen along a generic direction: a hexagon.
        let n = DVec3::new(0.3, -0.5, 0.8).normalize();
        assert!(hull.silhouette(n, &mut front, &mut next, &mut out));
        assert_eq!(out.len(), 6);
    }

    #[test]
    fn hull_3d_degenerate_inputs() {
        assert!(matches!(
            convex_hull_3d(&[DVec3::ONE; 4], 1e-9),
            Hull3::Point
        ));
        let line: Vec<DVec3> = (0..5).map(|i| DVec3::splat(i as f64)).collect();
        assert!(matches!(convex_hull_3d(&line, 1e-9), Hull3::Line { .. }));
        let flat: Vec<DVec3> = (0..9)
            .map(|i| DVec3::new((i % 3) as f64, (i / 3) as f64, 1.0))
            .collect();
        match convex_hull_3d(&flat, 1e-9) {
            Hull3::Flat { normal } => assert!((normal.z.abs() - 1.0).abs() < 1e-12),
            other => panic!("expected flat, got {other:?}"),
        }
    }
}
