//! Refinement of the maximum: a pattern search from the farthest samples up to the nearby peak.

use super::MeshRef;
use super::bvh::Bvh;
use super::sample::Samples;
use glam::Vec3A;

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
pub(super) fn refine_maximum(
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
