//! Sampled Hausdorff and RMS distance between two triangle meshes.
//!
//! This is the measuring stick for simplification quality: it answers "how far does the
//! simplified surface stray from the original?" the way Metro (Cignoni et al. 1998) does, by
//! sampling points on one surface and finding, for each, the closest point on the other.
//!
//! * [`mesh_distance`] is the symmetric measure: the larger of the two one-sided Hausdorff
//!   distances, and the RMS over both directions' samples, each also given relative to the
//!   bounding-box diagonal of the first mesh.
//! * [`one_sided`] is the directed measure from the samples of one mesh to a [`Bvh`] of another,
//!   for callers that compare many meshes against one reference and build its BVH once.
//! * [`Bvh`] answers exact closest-point queries against a triangle soup;
//!   [`point_triangle_distance_sq`] is the exact point-to-triangle distance it is built on.
//!
//! # Sampling
//!
//! Each direction draws exactly [`DistanceOptions::samples`] points on the surface of the mesh it
//! starts from. The points are spread by area with systematic (stratified) sampling: triangle `i`
//! gets `floor(N·C_i/A + u) − floor(N·C_{i−1}/A + u)` points, where `C_i` is the cumulative area of
//! the first `i` triangles, `A` the total area and `u` one seeded random offset, so every
//! triangle receives its area share rounded up or down, and the counts add up to exactly `N`.
//! Within a triangle the points are uniform, drawn from a splitmix64 stream seeded by
//! [`DistanceOptions::seed`] and the triangle's index. On top of these, every vertex that a
//! triangle references is a sample ([`DistanceOptions::include_vertices`]), and optionally every
//! edge midpoint ([`DistanceOptions::include_edge_midpoints`]).
//!
//! The area samples are an unbiased estimate of the surface: they define the RMS. The vertex and
//! edge samples (and the refinement below) only raise the maximum (a vertex is where a
//! simplifier most often leaves its largest error), so they count towards the Hausdorff distance
//! but not towards the RMS; only when a mesh has no area at all (every triangle degenerate) does
//! its RMS fall back to them.
//!
//! The distance from a surface peaks sharply (often on a ridge where the closest point jumps from
//! one part of the other surface to another), so samples alone miss the peak by up to about
//! their spacing: on the Stanford bunny against a 10 % simplification, 200 000 samples per side
//! land 3 to 12 % below the true Hausdorff distance, depending on the seed. Hence a refinement
//! step ([`DistanceOptions::refine`]): the farthest samples, at most one per triangle, start a
//! pattern search over their triangle that climbs to the nearby maximum. That brings the same
//! measurement to within 0.02 % of its converged value for any seed, for a few per cent more time.
//!
//! Every point evaluated lies on the surface and its closest-point distance is exact (up to `f32`
//! rounding), so the result is a lower bound of the true Hausdorff distance that sampling and
//! refinement push up towards it; it never overestimates.
//!
//! # Determinism
//!
//! The samples depend only on the mesh and the seed, so results are bit-identical from run to run
//! and independent of [`DistanceOptions::threads`]: queries are split into fixed-size chunks (each
//! query starts from the answer of the point before it in its chunk), and sums are taken in sample
//! order. Swapping the two meshes of [`mesh_distance`] swaps the two directions and leaves
//! [`Distance::hausdorff_abs`] and [`Distance::rms_abs`] unchanged. With one seed, two
//! simplifications of the same mesh are measured from the same samples of the original (common
//! random numbers), so their difference is not blurred by sampling noise.
//!
//! # Invalid input
//!
//! Nothing here panics on bad input. Triangles with an index out of range or a non-finite corner
//! are ignored (trailing indices that do not form a whole triangle too); vertices that no
//! remaining triangle references are not sampled, so a simplifier's output that indexes into the
//! original vertex buffer is measured correctly. Degenerate (zero-area) triangles are kept: their
//! closest points lie on their edges, and they never produce a NaN. A mesh with no valid triangle
//! is empty: the distance between an empty and a non-empty mesh is `f32::INFINITY`, between two
//! empty meshes it is `0`. A direction with no samples at all (with `samples: 0` and vertex
//! sampling off) measures `0`.

use glam::{DVec3, Vec3, Vec3A};
use std::sync::{Mutex, PoisonError};

/// A borrowed triangle mesh: positions and a triangle-list index buffer.
///
/// Every three consecutive indices form a triangle. See the [module documentation](self) for how
/// invalid triangles are treated.
#[derive(Clone, Copy, Debug)]
pub struct MeshRef<'a> {
    /// Vertex positions.
    pub positions: &'a [Vec3],
    /// Triangle list: three indices into [`positions`](Self::positions) per triangle.
    pub indices: &'a [u32],
}

impl<'a> MeshRef<'a> {
    /// Borrows positions and indices as a mesh.
    #[inline]
    #[must_use]
    pub fn new(positions: &'a [Vec3], indices: &'a [u32]) -> Self {
        Self { positions, indices }
    }
}

impl<'a> From<&'a crate::mesh::IndexedMesh> for MeshRef<'a> {
    #[inline]
    fn from(mesh: &'a crate::mesh::IndexedMesh) -> Self {
        Self::new(&mesh.positions, &mesh.indices)
    }
}

/// How [`mesh_distance`] and [`one_sided`] sample the surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DistanceOptions {
    /// Area samples drawn on each mesh (per direction), spread by area. Default `200_000`.
    ///
    /// More samples tighten the Hausdorff estimate (which can only be underestimated) and the
    /// RMS; the cost is linear. `0` leaves only the vertex and edge samples.
    pub samples: usize,
    /// Seed of the sample positions. The same seed gives bit-identical results, and the same
    /// samples on the same mesh whatever it is compared with. Default `0`.
    pub seed: u64,
    /// Also sample every vertex referenced by a triangle (for the maximum only). Default `true`.
    pub include_vertices: bool,
    /// Also sample the midpoint of every triangle edge (for the maximum only). Default `false`.
    ///
    /// An edge shared by two triangles is sampled twice, which costs time but changes nothing.
    pub include_edge_midpoints: bool,
    /// Samples refined by local search: the farthest samples (at most one per triangle) start a
    /// pattern search over their triangle that climbs to the nearby maximum of the distance.
    /// Default `64`; `0` turns it off.
    ///
    /// Sampling alone underestimates the Hausdorff distance by up to about the sample spacing,
    /// because the distance peaks sharply (often on a ridge where the closest point jumps). The
    /// search closes most of that gap for a few thousand extra queries. It only counts towards
    /// the maximum, never the RMS, and since every point it evaluates lies on the surface it can
    /// never overestimate.
    pub refine: usize,
    /// Worker threads for the closest-point queries; `0` uses all available cores. The result
    /// does not depend on it. Default `0`.
    pub threads: usize,
}

impl Default for DistanceOptions {
    fn default() -> Self {
        Self {
            samples: 200_000,
            seed: 0,
            include_vertices: true,
            include_edge_midpoints: false,
            refine: 64,
            threads: 0,
        }
    }
}

/// The symmetric distance between two meshes, as returned by [`mesh_distance`].
///
/// The `_abs` fields are in the meshes' units; the others are divided by
/// [`diagonal`](Self::diagonal) (if the diagonal is zero, a relative value is `0` where the
/// absolute one is `0`, else infinite).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Distance {
    /// Symmetric Hausdorff distance relative to the diagonal: `hausdorff_abs / diagonal`.
    pub hausdorff: f32,
    /// Root-mean-square distance relative to the diagonal: `rms_abs / diagonal`.
    pub rms: f32,
    /// Length of the bounding-box diagonal of mesh `a` (over the vertices its valid triangles
    /// reference), used to normalise the relative values.
    pub diagonal: f32,
    /// Symmetric Hausdorff distance: the larger of [`a_to_b_abs`](Self::a_to_b_abs) and
    /// [`b_to_a_abs`](Self::b_to_a_abs).
    pub hausdorff_abs: f32,
    /// Root-mean-square distance over the area samples of both directions together (each
    /// direction draws the same number, so this is `sqrt((rms_ab² + rms_ba²) / 2)`).
    pub rms_abs: f32,
    /// One-sided Hausdorff distance from the samples of `a` to the surface of `b`.
    pub a_to_b_abs: f32,
    /// One-sided Hausdorff distance from the samples of `b` to the surface of `a`.
    pub b_to_a_abs: f32,
}

/// Symmetric sampled Hausdorff and RMS distance between meshes `a` and `b`.
///
/// Builds a [`Bvh`] of each mesh, samples each one as described in the
/// [module documentation](self), and measures every sample's distance to the other surface. The
/// Hausdorff distance is the larger of the two one-sided maxima; the RMS is taken over the area
/// samples of both directions combined. Relative values use the bounding-box diagonal of `a`.
///
/// If exactly one mesh is empty (has no valid triangle) the distances are `f32::INFINITY`; if both
/// are, they are `0`.
#[must_use]
pub fn mesh_distance(a: MeshRef, b: MeshRef, opts: &DistanceOptions) -> Distance {
    let bvh_a = Bvh::new(a.positions, a.indices);
    let bvh_b = Bvh::new(b.positions, b.indices);
    let ab = one_sided_stats(a, &bvh_b, opts);
    let ba = one_sided_stats(b, &bvh_a, opts);

    let (hausdorff_abs, rms_abs) = if ab.empty && ba.empty {
        (0.0, 0.0)
    } else if ab.empty || ba.empty {
        (f32::INFINITY, f32::INFINITY)
    } else {
        (
            ab.max_d2.max(ba.max_d2).sqrt(),
            rms(ab.rms_sum + ba.rms_sum, ab.rms_count + ba.rms_count),
        )
    };
    let diagonal = bvh_a.bounds().map_or(0.0, |(lo, hi)| (hi - lo).length());
    let relative = |abs: f32| {
        if diagonal > 0.0 {
            abs / diagonal
        } else if abs == 0.0 {
            0.0
        } else {
            f32::INFINITY
        }
    };
    let one = |s: &Stats, other: &Stats| {
        if s.empty {
            0.0
        } else if other.empty {
            f32::INFINITY
        } else {
            s.max_d2.sqrt()
        }
    };
    Distance {
        hausdorff: relative(hausdorff_abs),
        rms: relative(rms_abs),
        diagonal,
        hausdorff_abs,
        rms_abs,
        a_to_b_abs: one(&ab, &ba),
        b_to_a_abs: one(&ba, &ab),
    }
}

/// One-sided sampled distance from the surface of `from` to the triangles in `to`.
///
/// Returns `(max, rms)` in absolute units: the largest distance of any sample of `from` (area,
/// vertex and edge samples) to `to`, and the RMS distance of the area samples. A `from` with no
/// valid triangle gives `(0, 0)`; an empty `to` gives infinite distances.
#[must_use]
pub fn one_sided(from: MeshRef, to: &Bvh, opts: &DistanceOptions) -> (f32, f32) {
    let s = one_sided_stats(from, to, opts);
    (s.max_d2.sqrt(), rms(s.rms_sum, s.rms_count))
}

/// Squared distances of one direction: the maximum over every sample and the sum and count of
/// the samples that define the RMS.
#[derive(Clone, Copy, Debug, Default)]
struct Stats {
    /// Whether the mesh measured from has no valid triangle.
    empty: bool,
    max_d2: f32,
    rms_sum: f64,
    rms_count: usize,
}

/// Root mean square from a sum of squares and a count (`0` for no samples).
fn rms(sum: f64, count: usize) -> f32 {
    if count == 0 {
        0.0
    } else {
        (sum / count as f64).sqrt() as f32
    }
}

fn one_sided_stats(from: MeshRef, to: &Bvh, opts: &DistanceOptions) -> Stats {
    let samples = sample_surface(from, opts);
    let area = query_all(&samples.area, to, opts.threads);
    let extra = query_all(&samples.extra, to, opts.threads);
    let max_of = |d2: &[f32]| d2.iter().copied().fold(0.0f32, f32::max);
    let sum_of = |d2: &[f32]| d2.iter().map(|&d| f64::from(d)).sum::<f64>();
    let (rms_sum, rms_count) = if area.is_empty() {
        (sum_of(&extra), extra.len())
    } else {
        (sum_of(&area), area.len())
    };
    let sampled = max_of(&area).max(max_of(&extra));
    let refined = refine_maximum(from, to, &samples, &area, &extra, opts.refine);
    Stats {
        empty: samples.tris.is_empty(),
        max_d2: sampled.max(refined),
        rms_sum,
        rms_count,
    }
}

// ---------------------------------------------------------------------------------------------
// Sampling
// ---------------------------------------------------------------------------------------------

/// splitmix64 (Steele, Lea & Flood 2014): tiny, fast, and good enough for sample placement.
#[derive(Clone, Copy, Debug)]
struct SplitMix64(u64);

impl SplitMix64 {
    fn new(seed: u64) -> Self {
        Self(seed)
    }

    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)` with 24 bits of resolution.
    fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform in `[0, 1)` with 53 bits of resolution.
    fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// The stream of triangle `tri` under `seed`: independent of the order triangles are visited in.
fn triangle_rng(seed: u64, tri: usize) -> SplitMix64 {
    let mut mix = SplitMix64::new(seed ^ (tri as u64).wrapping_mul(0xD1B5_4A32_D192_ED03));
    SplitMix64::new(mix.next_u64())
}

/// The valid triangles of a mesh: `(triangle index, corner indices)`.
fn valid_triangles(mesh: MeshRef) -> Vec<(u32, [u32; 3])> {
    let n = mesh.positions.len();
    mesh.indices
        .chunks_exact(3)
        .enumerate()
        .filter_map(|(t, c)| {
            let tri = [c[0], c[1], c[2]];
            let ok = tri
                .iter()
                .all(|&i| (i as usize) < n && mesh.positions[i as usize].is_finite());
            ok.then_some((t as u32, tri))
        })
        .collect()
}

/// Sample points of one mesh, each list in a spatially coherent order.
struct Samples {
    /// The valid triangles `(triangle index, corners)`.
    tris: Vec<(u32, [u32; 3])>,
    /// Area samples: they define the RMS.
    area: Vec<Vec3A>,
    /// Entry of `tris` each area sample lies on.
    area_tri: Vec<u32>,
    /// Vertex and edge-midpoint samples: they only count towards the maximum.
    extra: Vec<Vec3A>,
    /// Entry of `tris` each extra sample lies on (one of them, for a shared vertex).
    extra_tri: Vec<u32>,
}

fn sample_surface(mesh: MeshRef, opts: &DistanceOptions) -> Samples {
    let tris = valid_triangles(mesh);
    let pos = |i: u32| Vec3A::from(mesh.positions[i as usize]);
    let corners = |t: &[u32; 3]| [pos(t[0]), pos(t[1]), pos(t[2])];

    // Systematic allocation of the area samples, in index-buffer order (so it depends only on the
    // mesh and the seed).
    let areas: Vec<f64> = tris
        .iter()
        .map(|(_, t)| {
            let [a, b, c] = corners(t);
            let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
            0.5 * (b - a).cross(c - a).length()
        })
        .collect();
    let total: f64 = areas.iter().sum();
    let mut counts = vec![0u32; tris.len()];
    let mut n_area = 0usize;
    if opts.samples > 0 && total.is_finite() && total > 0.0 {
        let scale = opts.samples as f64 / total;
        let offset = SplitMix64::new(opts.seed ^ 0x5851_F42D_4C95_7F2D).next_f64();
        let mut cumulative = 0.0f64;
        let mut previous = offset.floor();
        for (count, &area) in counts.iter_mut().zip(&areas) {
            cumulative += area;
            let next = (cumulative * scale + offset).floor();
            let k = (next - previous).max(0.0);
            previous = next;
            *count = k.min(u32::MAX as f64) as u32;
            n_area += *count as usize;
        }
    }

    // Visit triangles in Morton order of their centroids so that consecutive samples are close,
    // which lets each closest-point query start from its predecessor's answer.
    let order = morton_order(&tris, |(_, t)| {
        let [a, b, c] = corners(t);
        (a + b + c) * (1.0 / 3.0)
    });

    let mut area = Vec::with_capacity(n_area);
    let mut area_tri = Vec::with_capacity(n_area);
    let mut extra = Vec::new();
    let mut extra_tri = Vec::new();
    let vertex_count = if opts.include_vertices {
        mesh.positions.len()
    } else {
        0
    };
    let mut seen = vec![false; vertex_count];
    for &k in &order {
        let (t, ref idx) = tris[k as usize];
        let [a, b, c] = corners(idx);
        let count = counts[k as usize];
        if count > 0 {
            let (ab, ac) = (b - a, c - a);
            let mut rng = triangle_rng(opts.seed, t as usize);
            for _ in 0..count {
                let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                area.push(a + ab * u + ac * v);
                area_tri.push(k);
            }
        }
        if opts.include_vertices {
            for (&i, p) in idx.iter().zip([a, b, c]) {
                if !std::mem::replace(&mut seen[i as usize], true) {
                    extra.push(p);
                    extra_tri.push(k);
                }
            }
        }
        if opts.include_edge_midpoints {
            extra.extend([(a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5]);
            extra_tri.extend([k; 3]);
        }
    }
    Samples {
        tris,
        area,
        area_tri,
        extra,
        extra_tri,
    }
}

/// Spreads the low 10 bits of `v` to every third bit.
fn spread_bits(v: u32) -> u32 {
    let mut x = v & 0x3FF;
    x = (x | (x << 16)) & 0x0300_00FF;
    x = (x | (x << 8)) & 0x0300_F00F;
    x = (x | (x << 4)) & 0x030C_30C3;
    x = (x | (x << 2)) & 0x0924_9249;
    x
}

/// Indices `0..items.len()` sorted by the 30-bit Morton code of `key(item)`, ties by index.
fn morton_order<T>(items: &[T], key: impl Fn(&T) -> Vec3A) -> Vec<u32> {
    let keys: Vec<Vec3A> = items.iter().map(key).collect();
    let (lo, hi) = keys.iter().fold(
        (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let extent = hi - lo;
    let scale = Vec3A::select(
        extent.cmpgt(Vec3A::ZERO),
        Vec3A::splat(1023.0) / extent,
        Vec3A::ZERO,
    );
    let mut coded: Vec<(u32, u32)> = keys
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            // `as u32` saturates (and maps NaN to 0), so this cannot overflow the 10 bits.
            let q = ((p - lo) * scale).min(Vec3A::splat(1023.0));
            let code = spread_bits(q.x as u32)
                | (spread_bits(q.y as u32) << 1)
                | (spread_bits(q.z as u32) << 2);
            (code, i as u32)
        })
        .collect();
    coded.sort_unstable();
    coded.into_iter().map(|(_, i)| i).collect()
}

// ---------------------------------------------------------------------------------------------
// Queries
// ---------------------------------------------------------------------------------------------

/// Points per work unit. Fixed, so that each point's query (which starts from the answer for the
/// point before it in the same chunk) does not depend on the number of threads.
const CHUNK: usize = 2048;

/// Squared distance of each point of `points` to `bvh` (infinite if `bvh` is empty), each chunk
/// seeding a query with the previous point's closest triangle.
fn query_chunk(points: &[Vec3A], bvh: &Bvh, out: &mut [f32]) {
    let mut hint = None;
    for (&p, d2) in points.iter().zip(out) {
        *d2 = match bvh.closest_impl(p, hint) {
            Some((d2, slot)) => {
                hint = Some(slot);
                d2
            }
            None => f32::INFINITY,
        };
    }
}

/// Squared distance of every point to `bvh`, on up to `threads` threads (`0`: all cores).
fn query_all(points: &[Vec3A], bvh: &Bvh, threads: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; points.len()];
    let chunks = points.len().div_ceil(CHUNK);
    let threads = if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    }
    .min(chunks);
    if threads <= 1 {
        for (p, o) in points.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            query_chunk(p, bvh, o);
        }
    } else {
        let work = Mutex::new(points.chunks(CHUNK).zip(out.chunks_mut(CHUNK)));
        std::thread::scope(|scope| {
            for _ in 0..threads {
                scope.spawn(|| {
                    loop {
                        let next = work.lock().unwrap_or_else(PoisonError::into_inner).next();
                        let Some((p, o)) = next else { break };
                        query_chunk(p, bvh, o);
                    }
                });
            }
        });
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Refinement of the maximum
// ---------------------------------------------------------------------------------------------

/// Pattern-search directions in barycentric `(u, v)`: along the three edges, both ways.
const DIRECTIONS: [(f32, f32); 6] = [
    (1.0, 0.0),
    (-1.0, 0.0),
    (0.0, 1.0),
    (0.0, -1.0),
    (1.0, -1.0),
    (-1.0, 1.0),
];
/// First step of the search, in barycentric units.
const FIRST_STEP: f32 = 1.0 / 16.0;
/// Smallest step: the search resolves a maximum to this fraction of its triangle's size.
const LAST_STEP: f32 = 1.0 / 4096.0;
/// Candidates considered per refined start (the rest are on triangles already taken).
const CANDIDATES_PER_START: usize = 8;

/// Climbs from the `starts` farthest samples (at most one per triangle) to the nearby maximum of
/// the distance on their triangle, by pattern search in barycentric coordinates. Returns the
/// largest squared distance met. Every point it evaluates lies on `from`'s surface, so the result
/// is a valid (larger) sample of the one-sided Hausdorff distance.
fn refine_maximum(
    from: MeshRef,
    to: &Bvh,
    samples: &Samples,
    area_d2: &[f32],
    extra_d2: &[f32],
    starts: usize,
) -> f32 {
    if starts == 0 || to.is_empty() {
        return 0.0;
    }
    // The farthest samples, by distance then by position in the (deterministic) sample lists.
    let mut ranked: Vec<(f32, u32, u32)> = area_d2
        .iter()
        .zip(&samples.area_tri)
        .chain(extra_d2.iter().zip(&samples.extra_tri))
        .enumerate()
        .map(|(i, (&d2, &tri))| (d2, i as u32, tri))
        .collect();
    let order = |x: &(f32, u32, u32), y: &(f32, u32, u32)| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1));
    let keep = starts
        .saturating_mul(CANDIDATES_PER_START)
        .min(ranked.len());
    if keep == 0 {
        return 0.0;
    }
    if keep < ranked.len() {
        ranked.select_nth_unstable_by(keep - 1, order);
        ranked.truncate(keep);
    }
    ranked.sort_unstable_by(order);

    let mut taken: Vec<u32> = Vec::with_capacity(starts);
    let mut best = 0.0f32;
    for &(d2, i, tri) in &ranked {
        if taken.len() == starts {
            break;
        }
        if taken.contains(&tri) {
            continue;
        }
        taken.push(tri);
        let i = i as usize;
        let start = match samples.area.get(i) {
            Some(&p) => p,
            None => samples.extra[i - samples.area.len()],
        };
        let [a, b, c] = samples.tris[tri as usize]
            .1
            .map(|v| Vec3A::from(from.positions[v as usize]));
        best = best.max(climb(to, start, d2, a, b - a, c - a));
    }
    best
}

/// Pattern search for the largest distance to `to` over the triangle `(a, a + ab, a + ac)`,
/// starting from its point `start` at squared distance `start_d2`.
fn climb(to: &Bvh, start: Vec3A, start_d2: f32, a: Vec3A, ab: Vec3A, ac: Vec3A) -> f32 {
    // Barycentric coordinates of the start: least squares in f64.
    let (e0, e1, ap) = (ab.as_dvec3(), ac.as_dvec3(), (start - a).as_dvec3());
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let det = d00 * d11 - d01 * d01;
    if !det.is_finite() || det <= 1e-12 * d00 * d11 {
        return start_d2; // thin triangle: nothing to climb on
    }
    let (d20, d21) = (ap.dot(e0), ap.dot(e1));
    let mut uv = (
        ((d11 * d20 - d01 * d21) / det) as f32,
        ((d00 * d21 - d01 * d20) / det) as f32,
    );
    uv = clamp_barycentric(uv);
    let (mut best, mut hint) = (start_d2, None);
    let mut step = FIRST_STEP;
    let mut evaluations = 0;
    while step >= LAST_STEP && evaluations < 400 {
        let mut moved = false;
        for (du, dv) in DIRECTIONS {
            let next = clamp_barycentric((uv.0 + du * step, uv.1 + dv * step));
            if next == uv {
                continue;
            }
            evaluations += 1;
            let Some((d2, slot)) = to.closest_impl(a + ab * next.0 + ac * next.1, hint) else {
                return best;
            };
            hint = Some(slot);
            if d2 > best {
                (best, uv, moved) = (d2, next, true);
                break;
            }
        }
        if !moved {
            step *= 0.5;
        }
    }
    best
}

/// Brings `(u, v)` into the triangle `u, v >= 0, u + v <= 1` (rescaling when `u + v > 1`).
fn clamp_barycentric((u, v): (f32, f32)) -> (f32, f32) {
    let (u, v) = (u.max(0.0), v.max(0.0));
    let sum = u + v;
    if sum > 1.0 {
        (u / sum, v / sum)
    } else {
        (u, v)
    }
}

// ---------------------------------------------------------------------------------------------
// Point-triangle distance
// ---------------------------------------------------------------------------------------------

/// Exact squared distance from `p` to the triangle `(a, b, c)` (its closed surface, not its plane).
///
/// Ericson's closest-point-on-triangle (*Real-Time Collision Detection*, 5.1.5) for well-shaped
/// triangles. Thin ones (slivers, segments, points), on which its region tests can misfire, take
/// a slower `f64` path: the nearer of the plane (when the projection falls inside) and the three
/// edges. The result is never NaN for finite input.
#[must_use]
pub fn point_triangle_distance_sq(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let a = Vec3A::from(a);
    Tri::new(a, Vec3A::from(b), Vec3A::from(c)).d2(Vec3A::from(p))
}

/// A triangle prepared for distance queries: one corner, the two edges from it, and whether it
/// is too thin for the single-precision region tests.
#[derive(Clone, Copy, Debug)]
struct Tri {
    a: Vec3A,
    ab: Vec3A,
    ac: Vec3A,
    thin: bool,
}

/// A triangle is thin when `|ab × ac|² ≤ THIN · (longest edge)⁴`, i.e. its smallest angle is
/// below roughly `sqrt(THIN)` radians. Rounding in Ericson's `f32` region tests is far below this.
const THIN: f32 = 1e-6;

impl Tri {
    fn new(a: Vec3A, b: Vec3A, c: Vec3A) -> Self {
        let (ab, ac) = (b - a, c - a);
        let longest = ab
            .length_squared()
            .max(ac.length_squared())
            .max((c - b).length_squared());
        let n2 = ab.cross(ac).length_squared();
        Self {
            a,
            ab,
            ac,
            thin: n2.is_nan() || n2 <= THIN * longest * longest,
        }
    }

    /// Squared distance from `p`.
    #[inline]
    fn d2(&self, p: Vec3A) -> f32 {
        if self.thin {
            thin_d2(p - self.a, self.ab, self.ac)
        } else {
            ericson_d2(p - self.a, self.ab, self.ac)
        }
    }
}

/// Ericson's closest point on triangle `(0, ab, ac)` to `ap`, as a squared distance.
#[inline]
fn ericson_d2(ap: Vec3A, ab: Vec3A, ac: Vec3A) -> f32 {
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared(); // vertex a
    }
    let bp = ap - ab;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared(); // vertex b
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        // Edge ab; d1 - d3 = |ab|².
        let v = ratio(d1, d1 - d3);
        return (ap - ab * v).length_squared();
    }
    let cp = ap - ac;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared(); // vertex c
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        // Edge ac; d2 - d6 = |ac|².
        let w = ratio(d2, d2 - d6);
        return (ap - ac * w).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        // Edge bc; (d4 - d3) + (d5 - d6) = |bc|².
        let w = ratio(d4 - d3, (d4 - d3) + (d5 - d6));
        return (bp - (ac - ab) * w).length_squared();
    }
    // Face region: the distance to the plane, (n·ap)²/|n|², which is more accurate than going
    // through the barycentric coordinates (and exact for points on an axis-aligned plane).
    let n = ab.cross(ac);
    let (h, n2) = (n.dot(ap), n.length_squared());
    if n2 > 0.0 {
        h * (h / n2)
    } else {
        thin_d2(ap, ab, ac)
    }
}

/// `num / den` clamped to `[0, 1]`, `0` when `den` is not positive.
#[inline]
fn ratio(num: f32, den: f32) -> f32 {
    if den > 0.0 {
        (num / den).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Squared distance from `p` to triangle `(0, ab, ac)` for any shape, in `f64`: the three edges,
/// and the plane where the projection of `p` falls inside.
#[cold]
fn thin_d2(ap: Vec3A, ab: Vec3A, ac: Vec3A) -> f32 {
    fn segment(ap: DVec3, ab: DVec3) -> f64 {
        let len2 = ab.length_squared();
        let t = if len2 > 0.0 {
            (ap.dot(ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (ap - ab * t).length_squared()
    }
    let (ap, ab, ac) = (ap.as_dvec3(), ab.as_dvec3(), ac.as_dvec3());
    let mut best = segment(ap, ab)
        .min(segment(ap, ac))
        .min(segment(ap - ab, ac - ab));
    let n = ab.cross(ac);
    let n2 = n.length_squared();
    if n2 > 0.0 {
        let t = n.dot(ap) / n2;
        let q = ap - n * t;
        let inside = ab.cross(q).dot(n) >= 0.0
            && (ac - ab).cross(q - ab).dot(n) >= 0.0
            && (-ac).cross(q - ac).dot(n) >= 0.0;
        if inside {
            best = best.min(t * t * n2);
        }
    }
    best as f32
}

// ---------------------------------------------------------------------------------------------
// BVH
// ---------------------------------------------------------------------------------------------

/// A node of the flat BVH: an inner node's children are `first` and `first + 1`; a leaf holds
/// triangles `first .. first + count` of [`Bvh::tris`].
#[derive(Clone, Copy, Debug)]
struct Node {
    min: Vec3A,
    max: Vec3A,
    first: u32,
    count: u32,
}

impl Node {
    /// Squared distance from `p` to the node's box (`0` inside).
    #[inline]
    fn d2(&self, p: Vec3A) -> f32 {
        let d = (self.min - p).max(p - self.max).max(Vec3A::ZERO);
        d.length_squared()
    }
}

/// Most triangles in a leaf when splitting still pays. Larger leaves only appear when the
/// triangles' centroids coincide or the depth limit is reached.
const MAX_LEAF: usize = 4;
/// Depth limit, which bounds the traversal stack.
const MAX_DEPTH: usize = 60;
/// Bins per axis for the SAH split search.
const BINS: usize = 16;

/// A bounding-volume hierarchy over a triangle mesh, for exact closest-point queries.
///
/// Built top-down with a binned surface-area heuristic over the triangle centroids, stored as a
/// flat node array, and traversed iteratively, nearer child first, pruning every box farther than
/// the best triangle found so far. Triangles with an out-of-range index or a non-finite corner
/// are left out.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<Tri>,
    /// Mesh triangle index of each entry of `tris`.
    ids: Vec<u32>,
    /// Entry of `tris` of each mesh triangle (`u32::MAX` for an invalid one).
    slots: Vec<u32>,
}

impl Bvh {
    /// Builds the hierarchy over the triangles `indices` (three per triangle) into `positions`.
    #[must_use]
    pub fn new(positions: &[Vec3], indices: &[u32]) -> Self {
        let input = valid_triangles(MeshRef::new(positions, indices));
        if input.is_empty() {
            return Self::default();
        }
        let mut build: Vec<BuildTri> = input
            .iter()
            .map(|&(id, [i, j, k])| {
                let (a, b, c) = (
                    Vec3A::from(positions[i as usize]),
                    Vec3A::from(positions[j as usize]),
                    Vec3A::from(positions[k as usize]),
                );
                BuildTri {
                    min: a.min(b).min(c),
                    max: a.max(b).max(c),
                    centroid: (a + b + c) * (1.0 / 3.0),
                    id,
                }
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * build.len() / MAX_LEAF + 1);
        nodes.push(Node {
            min: Vec3A::ZERO,
            max: Vec3A::ZERO,
            first: 0,
            count: 0,
        });
        build_node(&mut nodes, &mut build, 0, 0, 0);
        let mut slots = vec![u32::MAX; indices.len() / 3];
        for (slot, t) in build.iter().enumerate() {
            slots[t.id as usize] = slot as u32;
        }
        let tris = build
            .iter()
            .map(|t| {
                let c = &indices[3 * t.id as usize..][..3];
                let [a, b, c] = [0, 1, 2].map(|k| Vec3A::from(positions[c[k] as usize]));
                Tri::new(a, b, c)
            })
            .collect();
        Self {
            nodes,
            tris,
            ids: build.iter().map(|t| t.id).collect(),
            slots,
        }
    }

    /// Number of triangles in the hierarchy (the valid triangles of the mesh).
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Whether the hierarchy holds no triangle.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Bounding box `(min, max)` of all triangles, or `None` if empty.
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let root = self.nodes.first()?;
        Some((root.min.into(), root.max.into()))
    }

    /// The closest triangle to `p`: `(squared distance, triangle index in the mesh)`, or `None`
    /// if the hierarchy is empty.
    ///
    /// The distance is exact (up to `f32` rounding). If several triangles are equally close, any
    /// one of them may be returned.
    #[must_use]
    pub fn closest_point(&self, p: Vec3) -> Option<(f32, u32)> {
        self.closest_impl(Vec3A::from(p), None)
            .map(|(d2, slot)| (d2, self.ids[slot as usize]))
    }

    /// Like [`closest_point`](Self::closest_point), but starts from a triangle expected to be close
    /// (typically the answer for a nearby point), which prunes the search sooner. The hint is a
    /// mesh triangle index; an invalid one is ignored. The returned distance is the same
    /// with or without a hint.
    #[must_use]
    pub fn closest_point_with_hint(&self, p: Vec3, hint: u32) -> Option<(f32, u32)> {
        let slot = self
            .slots
            .get(hint as usize)
            .copied()
            .filter(|&s| s != u32::MAX);
        self.closest_impl(Vec3A::from(p), slot)
            .map(|(d2, slot)| (d2, self.ids[slot as usize]))
    }

    /// Closest triangle as `(squared distance, slot in self.tris)`, starting from slot `hint`.
    fn closest_impl(&self, p: Vec3A, hint: Option<u32>) -> Option<(f32, u32)> {
        if self.tris.is_empty() {
            return None;
        }
        let (mut best, mut best_slot) = (f32::INFINITY, 0u32);
        if let Some(h) = hint.filter(|&h| (h as usize) < self.tris.len()) {
            let t = &self.tris[h as usize];
            best = t.d2(p);
            best_slot = h;
        }
        let mut stack = [(0u32, 0f32); MAX_DEPTH + 4];
        let mut sp = 0usize;
        let root = &self.nodes[0];
        let mut node = 0u32;
        let mut node_d2 = root.d2(p);
        loop {
            if node_d2 < best {
                let n = &self.nodes[node as usize];
                if n.count > 0 {
                    let first = n.first as usize;
                    for (k, t) in self.tris[first..first + n.count as usize]
                        .iter()
                        .enumerate()
                    {
                        let d2 = t.d2(p);
                        if d2 < best {
                            best = d2;
                            best_slot = (first + k) as u32;
                        }
                    }
                } else {
                    let (l, r) = (n.first, n.first + 1);
                    let dl = self.nodes[l as usize].d2(p);
                    let dr = self.nodes[r as usize].d2(p);
                    let ((near, dn), (far, df)) = if dl <= dr {
                        ((l, dl), (r, dr))
                    } else {
                        ((r, dr), (l, dl))
                    };
                    if df < best && sp < stack.len() {
                        stack[sp] = (far, df);
                        sp += 1;
                    }
                    node = near;
                    node_d2 = dn;
                    continue;
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            (node, node_d2) = stack[sp];
        }
        Some((best, best_slot))
    }
}

/// A triangle during construction: its bounds and centroid, and its index in the mesh.
#[derive(Clone, Copy, Debug)]
struct BuildTri {
    min: Vec3A,
    max: Vec3A,
    centroid: Vec3A,
    id: u32,
}

/// Bounding box accumulator.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    min: Vec3A,
    max: Vec3A,
}

impl Aabb {
    const EMPTY: Self = Self {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    fn grow(&mut self, min: Vec3A, max: Vec3A) {
        self.min = self.min.min(min);
        self.max = self.max.max(max);
    }

    /// Half the surface area (enough for the SAH); `0` when empty.
    fn half_area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3A::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

/// Builds node `index` over `tris[start..]` (the slice handed in), recursively.
fn build_node(
    nodes: &mut Vec<Node>,
    tris: &mut [BuildTri],
    index: usize,
    start: usize,
    depth: usize,
) {
    let mut bounds = Aabb::EMPTY;
    let mut centroids = Aabb::EMPTY;
    for t in tris.iter() {
        bounds.grow(t.min, t.max);
        centroids.grow(t.centroid, t.centroid);
    }
    let leaf = Node {
        min: bounds.min,
        max: bounds.max,
        first: start as u32,
        count: tris.len() as u32,
    };
    let extent = centroids.max - centroids.min;
    let widest = extent.max_element();
    if tris.len() <= MAX_LEAF || depth >= MAX_DEPTH || widest.is_nan() || widest <= 0.0 {
        nodes[index] = leaf;
        return;
    }

    // Binned SAH over all three axes, binned in one pass.
    let scale = Vec3A::select(
        extent.cmpgt(Vec3A::ZERO),
        Vec3A::splat(BINS as f32) / extent,
        Vec3A::ZERO,
    );
    let bin_of = |c: Vec3A| {
        // `as usize` saturates (NaN to 0), so only the upper end needs clamping.
        let b = (c - centroids.min) * scale;
        [b.x, b.y, b.z].map(|x| (x as usize).min(BINS - 1))
    };
    let mut bins = [[(Aabb::EMPTY, 0usize); BINS]; 3];
    for t in tris.iter() {
        for (axis, b) in bin_of(t.centroid).into_iter().enumerate() {
            bins[axis][b].0.grow(t.min, t.max);
            bins[axis][b].1 += 1;
        }
    }
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, split bin)
    for (axis, bins) in bins.iter().enumerate() {
        if scale[axis] <= 0.0 {
            continue;
        }
        // Sweep from the right to get the cost of every right part, then from the left.
        let mut right = [0.0f32; BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        for b in (1..BINS).rev() {
            acc.grow(bins[b].0.min, bins[b].0.max);
            n += bins[b].1;
            right[b] = if n > 0 {
                acc.half_area() * n as f32
            } else {
                0.0
            };
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        for b in 0..BINS - 1 {
            acc.grow(bins[b].0.min, bins[b].0.max);
            n += bins[b].1;
            if n == 0 || n == tris.len() {
                continue;
            }
            let cost = acc.half_area() * n as f32 + right[b + 1];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b + 1));
            }
        }
    }

    let mid = match best {
        Some((_, axis, split)) => {
            let mut mid = 0;
            for i in 0..tris.len() {
                if bin_of(tris[i].centroid)[axis] < split {
                    tris.swap(i, mid);
                    mid += 1;
                }
            }
            mid
        }
        None => 0,
    };
    let mid = if mid == 0 || mid == tris.len() {
        // No bin boundary separates the centroids: fall back to a median split on the widest axis.
        let axis = extent.max_position();
        let half = tris.len() / 2;
        tris.select_nth_unstable_by(half, |x, y| x.centroid[axis].total_cmp(&y.centroid[axis]));
        half
    } else {
        mid
    };

    let child = nodes.len();
    nodes[index] = Node {
        first: child as u32,
        count: 0,
        ..leaf
    };
    nodes.push(leaf);
    nodes.push(leaf);
    let (left, right) = tris.split_at_mut(mid);
    build_node(nodes, left, child, start, depth + 1);
    build_node(nodes, right, child + 1, start + mid, depth + 1);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dense barycentric grid: an upper bound on the true distance, tight as the grid refines.
    fn grid_d2(p: Vec3, a: Vec3, b: Vec3, c: Vec3, n: usize) -> f32 {
        let mut best = f32::INFINITY;
        for i in 0..=n {
            for j in 0..=n - i {
                let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                let q = a + (b - a) * u + (c - a) * v;
                best = best.min(p.distance_squared(q));
            }
        }
        best
    }

    fn random_vec(rng: &mut SplitMix64, scale: f32) -> Vec3 {
        Vec3::new(
            rng.next_f32() * 2.0 - 1.0,
            rng.next_f32() * 2.0 - 1.0,
            rng.next_f32() * 2.0 - 1.0,
        ) * scale
    }

    #[test]
    fn point_triangle_matches_dense_grid() {
        let mut rng = SplitMix64::new(7);
        for _ in 0..300 {
            let (a, b, c) = (
                random_vec(&mut rng, 1.0),
                random_vec(&mut rng, 1.0),
                random_vec(&mut rng, 1.0),
            );
            let p = random_vec(&mut rng, 2.0);
            let exact = point_triangle_distance_sq(p, a, b, c).sqrt();
            let grid = grid_d2(p, a, b, c, 200).sqrt();
            // The grid's spacing is at most ~2·sqrt(3)/200 ≈ 0.017.
            assert!(exact <= grid + 1e-5, "{exact} > {grid}");
            assert!(grid - exact < 0.02, "{exact} vs {grid}");
        }
    }

    #[test]
    fn thin_path_agrees_with_ericson() {
        let mut rng = SplitMix64::new(13);
        for _ in 0..2000 {
            let [a, b, c, p] = [1.0, 1.0, 1.0, 2.0].map(|s| Vec3A::from(random_vec(&mut rng, s)));
            let (ab, ac) = (b - a, c - a);
            let (fast, slow) = (ericson_d2(p - a, ab, ac), thin_d2(p - a, ab, ac));
            assert!((fast.sqrt() - slow.sqrt()).abs() < 1e-5, "{fast} vs {slow}");
        }
    }

    #[test]
    fn point_triangle_regions() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let d = |p: Vec3| point_triangle_distance_sq(p, a, b, c);
        assert_eq!(d(Vec3::new(0.25, 0.25, 2.0)), 4.0); // face
        assert_eq!(d(Vec3::new(-1.0, -1.0, 0.0)), 2.0); // vertex a
        assert_eq!(d(Vec3::new(2.0, 0.0, 0.0)), 1.0); // vertex b
        assert_eq!(d(Vec3::new(0.0, 3.0, 0.0)), 4.0); // vertex c
        assert_eq!(d(Vec3::new(0.5, -2.0, 0.0)), 4.0); // edge ab
        assert_eq!(d(Vec3::new(-3.0, 0.5, 0.0)), 9.0); // edge ac
        assert!((d(Vec3::new(1.0, 1.0, 0.0)) - 0.5).abs() < 1e-6); // edge bc
    }

    #[test]
    fn degenerate_triangles_are_finite() {
        let p = Vec3::new(0.3, 0.7, -0.2);
        // A point.
        let d = point_triangle_distance_sq(p, Vec3::ONE, Vec3::ONE, Vec3::ONE);
        assert!((d - p.distance_squared(Vec3::ONE)).abs() < 1e-6);
        // A segment, with a repeated corner in each position.
        let (s0, s1) = (Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0));
        let want = 0.7f32 * 0.7 + 0.2 * 0.2;
        for (a, b, c) in [(s0, s0, s1), (s0, s1, s0), (s1, s0, s0), (s0, s1, s1)] {
            let d = point_triangle_distance_sq(p, a, b, c);
            assert!((d - want).abs() < 1e-6, "{d} vs {want}");
        }
        // Collinear, distinct corners.
        let d = point_triangle_distance_sq(p, s0, Vec3::X, s1);
        assert!((d - want).abs() < 1e-6, "{d} vs {want}");
        // Sliver.
        let d = point_triangle_distance_sq(p, s0, s1, Vec3::new(1.0, 1e-20, 0.0));
        assert!(d.is_finite() && (d - want).abs() < 1e-5, "{d} vs {want}");
    }

    #[test]
    fn bvh_matches_brute_force() {
        let mut rng = SplitMix64::new(11);
        let mut positions = Vec::new();
        for _ in 0..300 {
            let centre = random_vec(&mut rng, 5.0);
            for _ in 0..3 {
                positions.push(centre + random_vec(&mut rng, 0.5));
            }
        }
        let indices: Vec<u32> = (0..positions.len() as u32).collect();
        let bvh = Bvh::new(&positions, &indices);
        assert_eq!(bvh.len(), 300);
        for q in 0..1000 {
            let p = random_vec(&mut rng, 7.0);
            let brute = indices
                .chunks_exact(3)
                .map(|t| {
                    let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
                    point_triangle_distance_sq(p, a, b, c)
                })
                .fold(f32::INFINITY, f32::min);
            let (d2, tri) = bvh.closest_point(p).unwrap();
            assert_eq!(d2, brute, "query {q}");
            let t = &indices[3 * tri as usize..3 * tri as usize + 3];
            let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
            assert_eq!(point_triangle_distance_sq(p, a, b, c), d2);
            let (h2, _) = bvh.closest_point_with_hint(p, q % 300).unwrap();
            assert_eq!(h2, brute, "hinted query {q}");
        }
    }

    #[test]
    fn systematic_allocation_is_exact() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(3.0, 0.0, 0.0)];
        let indices = [0, 1, 2, 1, 3, 2, 0, 0, 1];
        for samples in [0, 1, 7, 1000] {
            let opts = DistanceOptions {
                samples,
                seed: 3,
                ..DistanceOptions::default()
            };
            let s = sample_surface(MeshRef::new(&positions, &indices), &opts);
            assert_eq!(s.area.len(), samples);
            assert_eq!(s.extra.len(), 4);
        }
    }

    #[test]
    fn invalid_triangles_are_ignored() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::NAN];
        let indices = [0, 1, 2, 0, 1, 3, 0, 1, 9, 2];
        let bvh = Bvh::new(&positions, &indices);
        assert_eq!(bvh.len(), 1);
        assert_eq!(bvh.closest_point(Vec3::Z), Some((1.0, 0)));
        assert!(Bvh::new(&[], &[]).closest_point(Vec3::ZERO).is_none());
    }
}
