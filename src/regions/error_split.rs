//! Splitting one model's triangles among its regions so that every region shows about the
//! same error on screen ([`ErrorCurves`]).
//!
//! The budget allocation weighs a region by its projected area alone (ASLOD's `w = c·A`), so
//! two regions of equal size on screen get equal counts whatever their shape: a flat back
//! and a detailed face alike. Simplifying the whole mesh at once would instead spend the
//! triangles where they remove the most error. [`ErrorCurves::split`] does that across a
//! model's regions: it keeps the model's total and gives each region the level whose
//! geometric error, scaled to pixels by that region's own distance to the camera, is the same
//! for all of them (the screen-space error of Hoppe 1997 and of MOM, at region granularity).
//! Regions nearer the camera still get more: their pixels per unit are larger.

use super::RegionMesh;
use crate::bounds::Obb;

/// Samples per octave of error in the tables.
const PER_OCTAVE: f32 = 4.0;
/// The most samples a table holds (errors spanning more octaves are sampled more coarsely).
const MAX_SAMPLES: usize = 96;
/// The most steps [`ErrorCurves::split`] takes to find the tolerance (it stops sooner once
/// the count is within a thousandth of the total; bisection alone would be within a
/// ten-thousandth of an octave over any range a table spans after these).
const STEPS: usize = 24;

/// Per region of a [`RegionMesh`], its triangle count against its geometric error (in the
/// mesh's units), sampled at errors a fixed ratio apart, and the size of its box; what
/// [`split`](Self::split) needs to share a model's triangles by error.
///
/// ```
/// use bevy_aslod::bounds::Obb;
/// use bevy_aslod::mesh::IndexedMesh;
/// use bevy_aslod::multires::BuildOptions;
/// use bevy_aslod::regions::{ErrorCurves, GridPlane, Partition, RegionMesh};
/// use glam::Vec3;
///
/// // A 17x17 grid, flat on its left half and bumpy on its right, cut into two regions.
/// let mut positions = Vec::new();
/// for z in 0..17 {
///     for x in 0..17 {
///         let bump = if x > 8 { ((x * 5 + z * 3) % 4) as f32 * 0.3 } else { 0.0 };
///         positions.push(Vec3::new(x as f32, bump, z as f32));
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
/// let regions = RegionMesh::build(&mesh, &Partition::grid(&mesh, GridPlane::XZ, 2, 1)?, &BuildOptions::default())?;
/// let obbs: Vec<Obb> = regions.regions().iter().map(|r| r.obb()).collect();
/// let curves = ErrorCurves::new(&regions, &obbs);
/// // Both halves equally large on screen, 200 triangles between them: the bumpy half gets
/// // most of them.
/// let mut counts = [0; 2];
/// curves.split(&[1000.0, 1000.0], 200, &mut counts);
/// assert!(counts[0] + counts[1] <= 200);
/// assert!(counts[1] > counts[0]);
/// # Ok::<(), bevy_aslod::regions::RegionError>(())
/// ```
#[derive(Clone, Debug)]
pub struct ErrorCurves {
    /// `log2` of the error of sample 0 (below every nonzero error of every level: each
    /// region is there at its finest level, after the collapses that cost nothing).
    log2_first: f32,
    /// Octaves between samples.
    step: f32,
    samples: usize,
    /// `counts[r * samples + k]`: triangles of region `r` at the coarsest level whose error
    /// is at most the error of sample `k`; non-increasing in `k`, its finest level at `k = 0`
    /// and its coarsest level at the last sample.
    counts: Vec<f32>,
    /// Per region, `log2` of its box's mean projected area (over all directions, in the
    /// mesh's units²).
    log2_mean_area: Vec<f32>,
}

impl ErrorCurves {
    /// The curves of every region of `regions`; `obbs` holds one box per region (the boxes
    /// whose projected areas [`split`](Self::split) is given). Regions without a box count
    /// as a unit cube.
    #[must_use]
    pub fn new(regions: &RegionMesh, obbs: &[Obb]) -> Self {
        // Every level's error in the mesh's units, per region: the tables keep it relative
        // to the region's own diagonal.
        let per_region: Vec<(f32, &crate::multires::ProgressiveMesh)> = regions
            .regions()
            .iter()
            .map(|r| {
                let pm = r.progressive_mesh();
                (diagonal_of_triangles(pm), pm)
            })
            .collect();
        let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
        for &(diagonal, pm) in &per_region {
            for level in 1..pm.level_count() {
                let e = pm.level_error(level) * diagonal;
                if e > 0.0 && e.is_finite() {
                    lo = lo.min(e);
                    hi = hi.max(e);
                }
            }
        }
        if lo > hi {
            // No level with an error: every region has one level (or all errors are zero).
            (lo, hi) = (1.0, 1.0);
        }
        let octaves = (hi.log2() - lo.log2()).max(0.0);
        let samples = ((octaves * PER_OCTAVE).ceil() as usize)
            .saturating_add(2)
            .min(MAX_SAMPLES);
        // Equal errors everywhere still get a step of a sample's worth, so that the
        // positions along a table keep their fractions.
        let step = (octaves / (samples - 2).max(1) as f32).max(1.0 / PER_OCTAVE);
        // Sample 0 lies one step below the smallest error, the last at (or above) the largest.
        let log2_first = lo.log2() - step;
        let mut counts = Vec::with_capacity(per_region.len() * samples);
        for &(diagonal, pm) in &per_region {
            let triangles = pm.level_triangle_counts();
            for k in 0..samples {
                let error = (log2_first + k as f32 * step).exp2();
                let level = if k + 1 == samples {
                    pm.level_count() - 1
                } else if diagonal > 0.0 {
                    pm.level_for_error(error / diagonal)
                } else {
                    0
                };
                counts.push(triangles[level.min(triangles.len() - 1)] as f32);
            }
        }
        let log2_mean_area = (0..per_region.len())
            .map(|r| {
                let area = obbs.get(r).map_or(1.5, Obb::mean_projected_area);
                area.max(f32::MIN_POSITIVE).log2()
            })
            .collect();
        Self {
            log2_first,
            step,
            samples,
            counts,
            log2_mean_area,
        }
    }

    /// How many regions the curves describe.
    #[inline]
    #[must_use]
    pub fn region_count(&self) -> usize {
        self.log2_mean_area.len()
    }

    /// Splits `total` triangles among the regions so that each shows about the same error
    /// in pixels, and writes each region's count into `out` (one per region; their sum is at
    /// most `total`, unless even the coarsest levels exceed it, when every region gets its
    /// coarsest).
    ///
    /// `areas` holds each region's projected area (pixels², or anything proportional to
    /// them, the same for every region): with the mean projected area of its box, it says
    /// how many pixels a unit of the mesh covers there. A region with an area of `0` (out of
    /// view), or one that is not finite, gets its coarsest level. Regions past the end of
    /// `areas` or `out` are left out.
    pub fn split(&self, areas: &[f32], total: u32, out: &mut [u32]) {
        self.split_from(areas, total, f32::NAN, &mut Vec::new(), out);
    }

    /// [`split`](Self::split), starting the search from `hint`, the tolerance an earlier
    /// split returned (`NaN`: none), with `scratch` for its per-region data. Returns the
    /// tolerance found (`log2` of pixels, in the units of `areas`; not finite when no
    /// region is in view). From one frame to the next the tolerance moves little, so a
    /// split from the last one takes a few evaluations instead of a dozen.
    pub fn split_from(
        &self,
        areas: &[f32],
        total: u32,
        hint: f32,
        scratch: &mut Vec<f32>,
        out: &mut [u32],
    ) -> f32 {
        let n = self.region_count().min(areas.len()).min(out.len());
        let last = self.samples - 1;
        let inverse = 1.0 / self.step;
        // Per region, the sample position at t = 0: a region's sample at tolerance 2^t is
        // `t / step - offset` (NaN: out of view).
        scratch.clear();
        scratch.extend((0..n).map(|r| {
            let a = areas[r];
            if a > 0.0 && a.is_finite() {
                (0.5 * (a.log2() - self.log2_mean_area[r]) + self.log2_first) * inverse
            } else {
                f32::NAN
            }
        }));
        let offsets = &scratch[..];
        let (mut lo, mut hi) = offsets
            .iter()
            .filter(|o| !o.is_nan())
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &o| {
                (lo.min(o), hi.max(o))
            });
        // Below `lo` every region in view is at full detail, above `hi` at its coarsest.
        (lo, hi) = (lo * self.step, (hi + last as f32) * self.step);
        let at = |t: f32, r: usize| -> f32 {
            let c = &self.counts[r * self.samples..(r + 1) * self.samples];
            let x = t * inverse - offsets[r];
            if x.is_nan() || x >= last as f32 {
                c[last]
            } else if x <= 0.0 {
                c[0]
            } else {
                let k = x as usize;
                c[k] + (c[k + 1] - c[k]) * (x - k as f32)
            }
        };
        // Summed as integers: a total over 2^24 triangles is exact too.
        let over = |t: f32| {
            let sum: u64 = (0..n).map(|r| at(t, r) as u64).sum();
            (sum as i64 - i64::from(total)) as f32
        };
        let total = total as f32;
        let t = if lo > hi {
            f32::INFINITY
        } else {
            match over(lo) {
                at_lo if at_lo <= 0.0 => lo,
                at_lo => tolerance((lo, at_lo), hi, hint, 1.0 + total / 1024.0, over),
            }
        };
        for (r, count) in out.iter_mut().enumerate().take(n) {
            *count = at(t, r) as u32;
        }
        t
    }
}

/// The smallest `t` in `lo..=hi` (about: within `slack` triangles) at which `over(t)`, the
/// triangles over the total, falling with `t`, is at most zero; `over(lo) = at_lo > 0`. From
/// `hint` when it lies inside, by steps that double until they bracket it, then by regula
/// falsi (Illinois): the sum is piecewise linear in `t`.
fn tolerance(
    (mut lo, at_lo): (f32, f32),
    mut hi: f32,
    hint: f32,
    slack: f32,
    over: impl Fn(f32) -> f32,
) -> f32 {
    let (mut over_lo, mut over_hi) = (at_lo, f32::NAN);
    if hint > lo && hint < hi {
        let at_hint = over(hint);
        let mut step = 0.125;
        if at_hint <= 0.0 {
            (hi, over_hi) = (hint, at_hint);
            while hi - step > lo {
                let t = hi - step;
                let o = over(t);
                if o > 0.0 {
                    (lo, over_lo) = (t, o);
                    break;
                }
                (hi, over_hi) = (t, o);
                step *= 2.0;
            }
        } else {
            (lo, over_lo) = (hint, at_hint);
            while lo + step < hi {
                let t = lo + step;
                let o = over(t);
                if o <= 0.0 {
                    (hi, over_hi) = (t, o);
                    break;
                }
                (lo, over_lo) = (t, o);
                step *= 2.0;
            }
        }
    }
    if over_hi.is_nan() {
        over_hi = over(hi);
    }
    let mut last_side = 0i8;
    for _ in 0..STEPS {
        if -over_hi <= slack {
            break;
        }
        let secant = lo + over_lo * (hi - lo) / (over_lo - over_hi);
        let t = if secant > lo && secant < hi {
            secant
        } else {
            0.5 * (lo + hi)
        };
        let o = over(t);
        if o <= 0.0 {
            (hi, over_hi) = (t, o);
            if last_side == -1 {
                over_lo *= 0.5;
            }
            last_side = -1;
        } else {
            (lo, over_lo) = (t, o);
            if last_side == 1 {
                over_hi *= 0.5;
            }
            last_side = 1;
        }
    }
    hi
}

/// The diagonal of the box around the vertices the full-detail triangles use: about the
/// length the region's error table is relative to (the builder's box also holds the ring of
/// neighbouring triangles around the region, about an edge wider on each side).
fn diagonal_of_triangles(pm: &crate::multires::ProgressiveMesh) -> f32 {
    let positions = &pm.vertices().positions;
    let (mut lo, mut hi) = (
        glam::Vec3::splat(f32::INFINITY),
        glam::Vec3::splat(f32::NEG_INFINITY),
    );
    for i in pm.full_indices() {
        if let Some(&p) = positions.get(i as usize) {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    let d = (hi - lo).length();
    if d.is_finite() { d } else { 0.0 }
}
