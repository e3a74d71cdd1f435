//! Splitting the polygon budget among regions; the method is on [`allocate`].
//!
//! After the public types and the driver, [`Allocator::allocate_with`], the file follows the
//! phases in the order they run (the list on [`allocate`]); the unit tests are in
//! `allocate/tests.rs`.

use super::BudgetError;
pub use crate::executor::{Executor, Sequential};

/// The α of [`AllocationParams::default`]: the paper's choice, with which the allocation
/// reproduces Funkhouser & Séquin's benefit heuristic (see [the α table](super#choosing-α)).
pub const DEFAULT_ALPHA: f32 = 3.0;

/// The budget `P` of [`AllocationParams::default`] and of the plugin's `PolygonBudget`: 100,000
/// triangles, a frame's worth for a mid-range GPU at 60 Hz with room for the rest of a scene.
pub const DEFAULT_BUDGET: u32 = 100_000;

/// The global settings of one allocation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AllocationParams {
    /// The total polygon budget `P`, in triangles, for everything in view. Must be positive.
    ///
    /// Default: [`DEFAULT_BUDGET`] (`100_000`).
    pub budget: u32,
    /// Triangles of conventional (non-LOD) meshes that count against the budget:
    /// `P' = budget − fixed_cost`, or `0` when the fixed cost is larger.
    ///
    /// Default: `0`.
    pub fixed_cost: u32,
    /// The attenuation exponent α: `pᵢ ∝ wᵢ^(1/α)`. `1` is proportional to the weight, larger
    /// values flatten towards an equal split, `f32::INFINITY` is the equal split. Must be
    /// positive.
    ///
    /// Default: [`DEFAULT_ALPHA`] (`3`).
    pub alpha: f32,
    /// Hysteresis ε in triangles: a region keeps its current count while its target stays
    /// within ε of it (the paper's runtime loop), which stops regions from flickering between
    /// neighbouring levels as the camera drifts.
    ///
    /// Default: `0` (always follow the target).
    pub hysteresis: u32,
}

impl Default for AllocationParams {
    fn default() -> Self {
        Self {
            budget: DEFAULT_BUDGET,
            fixed_cost: 0,
            alpha: DEFAULT_ALPHA,
            hysteresis: 0,
        }
    }
}

impl AllocationParams {
    /// The defaults with the given budget.
    #[inline]
    #[must_use]
    pub fn with_budget(budget: u32) -> Self {
        Self {
            budget,
            ..Self::default()
        }
    }

    /// The budget left for the LOD regions, `P' = budget − fixed_cost` (saturating at `0`).
    #[inline]
    #[must_use]
    pub fn available(&self) -> u32 {
        self.budget.saturating_sub(self.fixed_cost)
    }
}

/// One region's input to [`allocate`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RegionInput {
    /// `wᵢ = cᵢ · Aᵢ`: the user priority times the projected area in pixels². Finite and not
    /// negative; `0` means out of view (the region gets `min` and nothing more).
    pub weight: f32,
    /// The fewest triangles the region may have (its coarsest level).
    pub min: u32,
    /// The most triangles the region may have (its full detail). At least `min`.
    pub max: u32,
    /// The triangles the region has now; only used for hysteresis.
    pub current: u32,
}

impl RegionInput {
    /// A region of projected area `area` (pixels²) and user priority `priority`:
    /// `weight = priority · area`.
    ///
    /// The paper's `w = 2·A·c` differs by a constant factor, which the formula ignores.
    #[inline]
    #[must_use]
    pub fn from_area(area: f32, priority: f32, min: u32, max: u32, current: u32) -> Self {
        Self {
            weight: area * priority,
            min,
            max,
            current,
        }
    }
}

/// Regions per chunk of a pass that an [`Executor`] runs. Fixed, not derived from a thread
/// count, so that the sums (per chunk, then in chunk order) are the same on any executor.
const CHUNK: usize = 2048;

/// What [`allocate`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AllocationReport {
    /// `P'`: the budget left for the regions after the fixed cost.
    pub available: u64,
    /// `Σ pᵢ`, the triangles allocated. At most `available` unless `infeasible`.
    pub total: u64,
    /// `P' < Σ minᵢ`: every region got its `min`, and the total is over `available`.
    pub infeasible: bool,
    /// Every region with a weight fits at its `max` (with the others at their `min`): they all
    /// got it, and `available − total` triangles are left over.
    pub saturated: bool,
    /// Regions whose target was clamped up to their `min`, including the weightless ones and
    /// those with `min == max`.
    pub at_min: usize,
    /// Regions whose target was clamped down to their `max`.
    pub at_max: usize,
    /// Regions that kept their current count through hysteresis.
    pub kept: usize,
    /// Regions hysteresis would have kept but that moved so the total fits in `P'`.
    pub released: usize,
}

/// Reusable scratch space for [`allocate`]: keep one alive across frames and allocation does
/// not touch the heap once the buffers have grown to the region count.
#[derive(Clone, Debug, Default)]
pub struct Allocator {
    share: Vec<f64>,
    pending: Vec<Pending>,
    pending_next: Vec<Pending>,
    breakpoints: Vec<f64>,
    ranked: Vec<u128>,
    kept: Vec<(u32, u32)>,
    /// `kept` in release order (hysteresis), and the start of each cost's run in it.
    released: Vec<(u32, u32)>,
    runs: Vec<u32>,
    /// The last water level found, and how far it moved from the one before (relative): the
    /// next search guesses its bracket from them (see [`Allocator::water_level`]).
    last_level: Option<(f64, f64)>,
}

/// Splits `params.budget` among `regions` into `out` (one count per region, in order) with a
/// fresh [`Allocator`]; see [`Allocator::allocate`], which reuses its scratch space.
///
/// `pᵢ = P' · wᵢ^(1/α) / Σⱼ wⱼ^(1/α)` (ASLOD, section 3), clamped to `[minᵢ, maxᵢ]` with the
/// surplus handed on to the others until nothing moves, rounded to integers with `Σ pᵢ ≤ P'`,
/// then held by hysteresis. The same input always gives the same output.
///
/// # Errors and clamps
///
/// | input | result |
/// |---|---|
/// | `alpha` zero, negative or NaN | [`BudgetError::InvalidAlpha`] |
/// | `alpha = f32::INFINITY` | the equal split among regions with a weight |
/// | `budget = 0` | [`BudgetError::ZeroBudget`] |
/// | a weight NaN, infinite or negative | [`BudgetError::InvalidWeight`] naming the first |
/// | `min > max` | [`BudgetError::MinAboveMax`] naming the first |
/// | `fixed_cost ≥ budget` | `P' = 0`: every region at `min`, infeasible if any `min > 0` |
/// | `P' < Σ min` | every region at `min`, [`infeasible`](AllocationReport::infeasible) |
/// | weight `0` | `min`, exempt from hysteresis (out of view, so free to drop at once) |
/// | `current` outside `[min, max]` | not kept by hysteresis |
/// | a share `(wᵢ/w_max)^(1/α)` below 1e-200 (α ≪ 1) | treated as weight `0` |
///
/// On error `out` is left empty.
///
/// # Method
///
/// The phases, in the order [`Allocator::allocate`] runs them:
///
/// 1. **validate** the parameters and every region (the table above);
/// 2. **shares** `sᵢ = wᵢ^(1/α)` in `f64`, in the same pass for α ≥ 1 (within f64's range
///    for any f32 weight); for α < 1 normalised by the largest weight, `(wᵢ / w_max)^(1/α)`,
///    so that a huge exponent neither under- nor overflows;
/// 3. **water level**: the scale `λ` with `Σ clamp(λ·sᵢ, minᵢ, maxᵢ) = P'`, found by a
///    quartile search over the regions' breakpoints `minᵢ/sᵢ` and `maxᵢ/sᵢ` (`O(n)`, no sort;
///    a reused [`Allocator`] starts from a bracket around its last level, which after a small
///    change of view settles nearly every region in the first pass); where nothing is
///    clamped this is exactly `pᵢ = P'·sᵢ / Σ sⱼ`;
/// 4. **rounding**: floors, then one more triangle for the largest remainders (ties to the
///    larger weight, then the lower index) until the floors add up to `P'`, never past it;
/// 5. **hysteresis**: a region keeps its current count when the target moved by at most ε,
///    unless that pushes the total over `P'`; then the kept regions that cost the most go to
///    their targets first, until the total fits.
///
/// ```
/// use bevy_aslod::budget::{AllocationParams, RegionInput, allocate};
///
/// let params = AllocationParams { budget: 10_000, alpha: 1.0, ..Default::default() };
/// let region = |area| RegionInput::from_area(area, 1.0, 100, 100_000, 0);
/// let mut out = Vec::new();
/// let report = allocate(&params, &[region(300.0), region(100.0), region(0.0)], &mut out)?;
/// // α = 1: proportional to area once the out-of-view region has its minimum.
/// assert_eq!(out, vec![7425, 2475, 100]);
/// assert_eq!(report.total, 10_000);
/// # Ok::<(), bevy_aslod::budget::BudgetError>(())
/// ```
pub fn allocate(
    params: &AllocationParams,
    regions: &[RegionInput],
    out: &mut Vec<u32>,
) -> Result<AllocationReport, BudgetError> {
    Allocator::default().allocate(params, regions, out)
}

impl Allocator {
    /// An allocator with empty scratch space.
    #[inline]
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// [`allocate`], reusing this allocator's scratch space. The result does not depend on
    /// what the allocator computed before: its last water level only steers the next search,
    /// and the level found is summed again in a fixed order.
    ///
    /// # Errors
    ///
    /// As [`allocate`].
    pub fn allocate(
        &mut self,
        params: &AllocationParams,
        regions: &[RegionInput],
        out: &mut Vec<u32>,
    ) -> Result<AllocationReport, BudgetError> {
        self.allocate_with(params, regions, out, &Sequential)
    }

    /// [`allocate`](Self::allocate) with its passes over the regions (validation, shares,
    /// the water level's first round, rounding) run by `executor`, in chunks: the same
    /// result as [`Sequential`]'s, split across threads. The few small job lists are the only
    /// memory it takes per call.
    ///
    /// # Errors
    ///
    /// As [`allocate`].
    pub fn allocate_with(
        &mut self,
        params: &AllocationParams,
        regions: &[RegionInput],
        out: &mut Vec<u32>,
        executor: &impl Executor,
    ) -> Result<AllocationReport, BudgetError> {
        out.clear();
        // For α ≥ 1, `wᵢ^(1/α)` stays well inside f64's range for every f32 weight: the
        // shares need no normalising, and the validation pass computes them too. A smaller
        // α needs the largest weight first (a second pass).
        let fused = params.alpha >= 1.0;
        // Every share is written below; resizing only keeps the length.
        self.share.resize(regions.len(), 0.0);
        if self.pending.len() < regions.len() {
            self.pending.resize(regions.len(), Pending::default());
            self.pending_next.resize(regions.len(), Pending::default());
        }
        // With the shares in this pass and a level to guess from, the water level's first
        // round runs in it too: one pass over the regions fewer.
        let first = self.last_level.filter(|_| fused).map(FirstRound::around);
        let (totals, parts) = scan(
            params,
            regions,
            fused.then_some(&mut self.share[..]),
            first.map(|f| (f, &mut self.pending_next[..regions.len()])),
            executor,
        )?;
        let first = first.map(|f| (f, self.combine(&parts)));
        let available = u64::from(params.available());
        let mut report = AllocationReport {
            available,
            ..Default::default()
        };
        if available < totals.min_total {
            out.extend(regions.iter().map(|r| r.min));
            report.infeasible = true;
            report.total = totals.min_total;
            report.at_min = regions.len();
            return Ok(report);
        }

        if !fused {
            self.compute_shares(params.alpha, totals.max_weight, regions, executor);
        }
        match self.water_level(regions, available as f64, first, executor) {
            None => {
                // Everything with a weight fits at its maximum.
                report.saturated = true;
                for (r, &s) in regions.iter().zip(&self.share) {
                    if s > 0.0 {
                        out.push(r.max);
                        report.at_max += 1;
                    } else {
                        out.push(r.min);
                        report.at_min += 1;
                    }
                }
            }
            Some(lambda) => self.round(regions, lambda, available, out, &mut report, executor),
        }
        self.hysteresis(
            params.hysteresis,
            regions,
            available,
            out,
            &mut report,
            executor,
        );
        report.total = out.iter().map(|&p| u64::from(p)).sum();
        Ok(report)
    }
}

// ---------------------------------------------------------------------------------------------
// Phase 1: validation (for α ≥ 1 also the shares and the water level's guessed first round)
// ---------------------------------------------------------------------------------------------

/// What [`scan`] adds up over the regions.
#[derive(Clone, Copy, Debug, Default)]
struct Totals {
    /// `Σ minᵢ`.
    min_total: u64,
    /// The largest weight (`0` when there is none).
    max_weight: f32,
}

/// The checks listed on [`allocate`] (the first invalid region in order is the one named),
/// and the totals the allocation starts from; with `shares`, the shares for α ≥ 1 too, and
/// with `first` also the water level's first round over them (its open regions into the
/// given buffer, by chunks, and each chunk's part, which [`Allocator::combine`] packs; the
/// parts are empty without `first`).
fn scan(
    params: &AllocationParams,
    regions: &[RegionInput],
    shares: Option<&mut [f64]>,
    first: Option<(FirstRound, &mut [Pending])>,
    executor: &impl Executor,
) -> Result<(Totals, Vec<Gathered>), BudgetError> {
    if params.alpha.is_nan() || params.alpha <= 0.0 {
        return Err(BudgetError::InvalidAlpha(params.alpha));
    }
    if params.budget == 0 {
        return Err(BudgetError::ZeroBudget);
    }
    // Without `shares` (or `first`), every chunk gets an empty slice to fill: nothing.
    let mut shares = shares.map(|s| s.chunks_mut(CHUNK));
    let (round, open) = first.unzip();
    let mut open = open.map(|o| o.chunks_mut(CHUNK));
    let mut jobs: Vec<_> = regions
        .chunks(CHUNK)
        .enumerate()
        .map(|(c, regions)| {
            let shares = shares.as_mut().and_then(Iterator::next).unwrap_or_default();
            let open = open.as_mut().and_then(Iterator::next).unwrap_or_default();
            let result = Ok((Totals::default(), Gathered::default()));
            (c * CHUNK, regions, shares, open, result)
        })
        .collect();
    let alpha = params.alpha;
    executor.for_each(&mut jobs, &|(start, regions, shares, open, result)| {
        *result = validate(*start, regions).map(|()| {
            let totals = Totals {
                min_total: regions.iter().map(|r| u64::from(r.min)).sum(),
                max_weight: regions.iter().fold(0.0f32, |m, r| m.max(r.weight)),
            };
            fill_shares(shares, regions, 1.0, alpha);
            let gathered = round.map_or_else(Gathered::default, |round| {
                gather(regions, shares, open, round)
            });
            (totals, gathered)
        });
    });
    let mut all = Totals::default();
    let mut parts = Vec::with_capacity(jobs.len());
    for (_, _, _, _, result) in jobs {
        let (totals, gathered) = result?;
        all.min_total += totals.min_total;
        all.max_weight = all.max_weight.max(totals.max_weight);
        parts.push(gathered);
    }
    Ok((all, parts))
}

/// Every region's weight and bounds; `start` is the index of `regions[0]`.
fn validate(start: usize, regions: &[RegionInput]) -> Result<(), BudgetError> {
    for (i, r) in regions.iter().enumerate() {
        if !(r.weight.is_finite() && r.weight >= 0.0) {
            return Err(BudgetError::InvalidWeight {
                region: start + i,
                weight: r.weight,
            });
        }
        if r.min > r.max {
            return Err(BudgetError::MinAboveMax {
                region: start + i,
                min: r.min,
                max: r.max,
            });
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Phase 2: shares (for α < 1; for α ≥ 1 the validation pass computes them)
// ---------------------------------------------------------------------------------------------

impl Allocator {
    /// `sᵢ = (wᵢ / w_max)^(1/α)` (for α < 1), `0` for weightless regions and for regions
    /// whose bounds leave nothing to decide.
    fn compute_shares(
        &mut self,
        alpha: f32,
        max_weight: f32,
        regions: &[RegionInput],
        executor: &impl Executor,
    ) {
        if max_weight <= 0.0 {
            self.share.fill(0.0);
            return;
        }
        let scale = 1.0 / f64::from(max_weight);
        let mut jobs: Vec<_> = regions
            .chunks(CHUNK)
            .zip(self.share.chunks_mut(CHUNK))
            .collect();
        executor.for_each(&mut jobs, &|(regions, shares)| {
            fill_shares(shares, regions, scale, alpha);
        });
    }
}

/// `shares[i] = (wᵢ · scale)^(1/α)` for regions with a weight and room between their bounds,
/// else 0.
fn fill_shares(shares: &mut [f64], regions: &[RegionInput], scale: f64, alpha: f32) {
    let alpha = f64::from(alpha);
    if alpha == 1.0 {
        fill_shares_with(shares, regions, scale, |x| x);
    } else if alpha == 2.0 {
        fill_shares_with(shares, regions, scale, f64::sqrt);
    } else if alpha == 3.0 {
        fill_shares_with(shares, regions, scale, cbrt_normal);
    } else if alpha.is_infinite() {
        fill_shares_with(shares, regions, scale, |_| 1.0);
    } else {
        // log2 then exp2 (glibc's are fast and exact to an ulp); underflow gives 0.
        let exponent = 1.0 / alpha;
        fill_shares_with(shares, regions, scale, |x| (x.log2() * exponent).exp2());
    }
}

/// `shares[i] = f(wᵢ · scale)` for regions with a weight and room between their bounds, else 0.
///
/// A share below [`MIN_SHARE`] counts as 0 too: its region's ideal count is below a triangle
/// for any budget, and `1 / s` must stay finite for the breakpoints (only α < 1 reaches it).
#[inline]
fn fill_shares_with(
    shares: &mut [f64],
    regions: &[RegionInput],
    scale: f64,
    f: impl Fn(f64) -> f64,
) {
    for (share, r) in shares.iter_mut().zip(regions) {
        *share = if r.weight > 0.0 && r.max > r.min {
            let s = f(f64::from(r.weight) * scale);
            if s >= MIN_SHARE { s } else { 0.0 }
        } else {
            0.0
        };
    }
}

/// The smallest share (relative to the largest, which is 1) that takes part in the split;
/// below it only an α far under 1 with weights many orders apart can go.
const MIN_SHARE: f64 = 1e-200;

/// The cube root of a positive normal `x`: a bit-level first guess (about 3 % off), then three
/// Halley steps, each of which triples the correct digits; within 2 ulp, and about five times
/// faster than `f64::cbrt` (α = 3 is the default, so this is the common path).
#[inline]
fn cbrt_normal(x: f64) -> f64 {
    let mut y = f64::from_bits(x.to_bits() / 3 + 0x2A9F_7893_782D_A1CE);
    for _ in 0..3 {
        let y3 = y * y * y;
        y *= (y3 + 2.0 * x) / (2.0 * y3 + x);
    }
    y
}

// ---------------------------------------------------------------------------------------------
// Phase 3: water level
// ---------------------------------------------------------------------------------------------

/// A region the water-level search has not settled yet: its breakpoints `min/s` and `max/s`,
/// its share `s` and its bounds, packed so the search streams through memory.
#[derive(Clone, Copy, Debug, Default)]
struct Pending {
    lower: f64,
    upper: f64,
    share: f64,
    min: f64,
    max: f64,
}

impl Allocator {
    /// The scale `λ` with `Σ clamp(λ·sᵢ, minᵢ, maxᵢ) = target`, or `None` when even every
    /// region at its maximum stays within `target`.
    ///
    /// `g(λ) = Σ clamp(λ·sᵢ, minᵢ, maxᵢ)` is continuous, piecewise linear and non-decreasing,
    /// with kinks at the breakpoints `minᵢ/sᵢ` and `maxᵢ/sᵢ`. The search keeps a bracket
    /// `[lo, hi]` around the root. Each round evaluates `g` at three pivots, the quartiles of
    /// a sample of the breakpoints still inside the bracket, in one pass that also settles
    /// every region whose state (at min, linear, at max) the bracket decides, and keeps the
    /// others. The bracket then shrinks to one of four pieces, so the open regions drop about
    /// fourfold per round: `O(n)` in all, and no sort. A round that shrinks too little (an
    /// unlucky sample) makes the next one use the exact median, which bounds the worst case.
    /// The first round's pivots come from the last call's level when there is one (a bracket
    /// of twice the level's last move either side, at least 1/64 and at most 1/8 of it):
    /// if the root lies inside, that pass already settles every region without a
    /// breakpoint in the bracket; if not, the three pivots still narrow the bracket, and a
    /// second pass settles every region against that one (a miss costs about one pass more
    /// than no guess). For α ≥ 1 the guessed round runs in the validation pass. In the plugin
    /// bench the guess holds in 110 of 116 frames, and then about 3 % of the regions with a
    /// share stay open after the first round instead of all of them.
    /// Once no breakpoint is left inside the bracket, `g`'s offset and slope there are
    /// summed over all regions in chunk order, so the level is the same whichever way the
    /// search went.
    ///
    /// The loops write their output slot unconditionally and advance by a 0/1 flag, and add
    /// flag-weighted terms instead of branching: which way a region goes is a coin toss the
    /// branch predictor cannot learn.
    fn water_level(
        &mut self,
        regions: &[RegionInput],
        target: f64,
        first: Option<(FirstRound, Gathered)>,
        executor: &impl Executor,
    ) -> Option<f64> {
        // Round one runs during the pass that gathers the open regions (the validation pass,
        // when it computed the shares). With a level from the last call, its pivots are that
        // level and a bracket around it, which the pass also settles regions against: after a
        // small change of view the root lies inside, and only the few regions with a
        // breakpoint in the bracket stay open. Without one, the pivots come from the
        // breakpoints of an evenly strided sample and every region with a share stays open.
        let (round, pass) = match first {
            Some(done) => done,
            None => {
                let round = match self.last_level {
                    Some(last) => FirstRound::around(last),
                    None => FirstRound {
                        pivots: self.sampled_pivots(regions, 0.0, f64::INFINITY),
                        bracket: (f64::NEG_INFINITY, f64::INFINITY),
                    },
                };
                (round, self.gather_all(regions, round, executor))
            }
        };
        if pass.fixed + pass.max_total <= target {
            return None;
        }
        let (mut lo, mut hi) = (0.0f64, f64::INFINITY);
        let FirstRound { pivots, bracket } = round;
        pivots.narrow(&mut lo, &mut hi, |k| pass.fixed + pass.sums[k] <= target);
        // What the pass settled holds if the root lies inside its bracket: then only the
        // regions it left open go on. If not (a missed guess), a second pass settles every
        // region against the bracket the three pivots gave, with pivots sampled inside it.
        let pass = if bracket.0 <= lo && hi <= bracket.1 {
            pass
        } else {
            let round = FirstRound {
                pivots: self.sampled_pivots(regions, lo, hi),
                bracket: (lo, hi),
            };
            let pass = self.gather_all(regions, round, executor);
            round
                .pivots
                .narrow(&mut lo, &mut hi, |k| pass.fixed + pass.sums[k] <= target);
            pass
        };
        std::mem::swap(&mut self.pending, &mut self.pending_next);
        let (mut len, mut fixed, mut slope) = (
            pass.open,
            pass.fixed + pass.at_min + pass.at_max,
            pass.linear,
        );

        let mut exact_median = false;
        let mut poor_rounds = 0;
        loop {
            let pivots = self.sample_pivots(len, lo, hi, exact_median);
            if pivots.count == 0 {
                break;
            }
            let [p0, p1, p2] = pivots.padded();
            let (pending, next) = (&self.pending[..len], &mut self.pending_next[..len]);
            let (mut at_min, mut at_max, mut linear_share) = (0.0, 0.0, 0.0);
            let mut sums = [0.0f64; 3];
            let mut kept = 0;
            for e in pending {
                let below = e.upper <= lo;
                let above = e.lower >= hi;
                let linear = (e.lower <= lo) & (e.upper >= hi);
                let open = !(below | above | linear);
                at_max += e.max * flag(below);
                at_min += e.min * flag(above);
                linear_share += e.share * flag(linear);
                let weight = flag(open);
                sums[0] += weight * (p0 * e.share).clamp(e.min, e.max);
                sums[1] += weight * (p1 * e.share).clamp(e.min, e.max);
                sums[2] += weight * (p2 * e.share).clamp(e.min, e.max);
                next[kept] = *e;
                kept += usize::from(open);
            }
            std::mem::swap(&mut self.pending, &mut self.pending_next);
            // Two rounds in a row that shrink too little (unlucky samples) make the next one
            // use the exact median; one alone is common after a missed guess, whose bracket
            // still holds most breakpoints.
            poor_rounds = if kept * 8 > len * 7 {
                poor_rounds + 1
            } else {
                0
            };
            exact_median = poor_rounds >= 2;
            len = kept;
            fixed += at_min + at_max;
            slope += linear_share;
            pivots.narrow(&mut lo, &mut hi, |k| {
                fixed + slope * [p0, p1, p2][k] + sums[k] <= target
            });
        }
        // No breakpoint is left inside the bracket: g is linear on it. Its offset and slope
        // are summed again over every region in a fixed order (chunks, then chunk order), so
        // the level does not depend on the path the search took, nor on the last level.
        let mut jobs: Vec<_> = regions
            .chunks(CHUNK)
            .zip(self.share.chunks(CHUNK))
            .map(|(regions, shares)| (regions, shares, (0.0, 0.0)))
            .collect();
        executor.for_each(&mut jobs, &|(regions, shares, line)| {
            *line = linear_piece(regions, shares, lo, hi);
        });
        let (fixed, slope) = jobs
            .iter()
            .fold((0.0, 0.0), |(f, s), job| (f + job.2.0, s + job.2.1));
        let level = if slope > 0.0 {
            ((target - fixed) / slope).max(0.0)
        } else {
            lo
        };
        // A root on a breakpoint ends the search with that breakpoint as the bracket's lower
        // end or its upper end, depending on the path; the two pieces' sums round
        // differently, and the level would move by an ulp with the path. A level within
        // 1e-9 (relative) of an end is that end: the same on every path. (The sums' rounding
        // is far below that for any region count that fits in memory, and moving a level by
        // 1e-9 moves a target of a million triangles by a thousandth of one.)
        let snap = |end: f64| end.is_finite() && (level - end).abs() <= 1e-9 * end;
        let level = if snap(hi) {
            hi
        } else if snap(lo) {
            lo
        } else {
            level
        };
        let moved = self
            .last_level
            .map_or(1.0, |(last, _)| (level / last - 1.0).abs());
        self.last_level = (level.is_finite() && level > 0.0).then_some((level, moved));
        Some(level)
    }

    /// Pivots for a first round: quartiles of the breakpoints inside `(lo, hi)` of an evenly
    /// strided sample of the regions.
    fn sampled_pivots(&mut self, regions: &[RegionInput], lo: f64, hi: f64) -> Pivots {
        let n = regions.len();
        self.breakpoints.clear();
        let stride = (n / 64).max(1);
        for i in (stride / 2..n).step_by(stride) {
            let s = self.share[i];
            if s > 0.0 {
                self.breakpoints.push(f64::from(regions[i].min) / s);
                self.breakpoints.push(f64::from(regions[i].max) / s);
            }
        }
        Pivots::quartiles(&mut self.breakpoints, lo, hi)
    }

    /// A first round over every region, by chunks on `executor`: `g` at the round's pivots,
    /// and the regions with a share that its bracket does not settle at the front of
    /// `pending_next`.
    fn gather_all(
        &mut self,
        regions: &[RegionInput],
        round: FirstRound,
        executor: &impl Executor,
    ) -> Gathered {
        let n = regions.len();
        let mut jobs: Vec<_> = regions
            .chunks(CHUNK)
            .zip(self.share.chunks(CHUNK))
            .zip(self.pending_next[..n].chunks_mut(CHUNK))
            .map(|((regions, shares), open)| (regions, shares, open, Gathered::default()))
            .collect();
        executor.for_each(&mut jobs, &|(regions, shares, open, gathered)| {
            *gathered = gather(regions, shares, open, round);
        });
        let parts: Vec<Gathered> = jobs.into_iter().map(|job| job.3).collect();
        self.combine(&parts)
    }

    /// The chunks' parts of a first round as one, in chunk order, their open regions packed
    /// at the front of `pending_next`.
    fn combine(&mut self, parts: &[Gathered]) -> Gathered {
        let mut all = Gathered {
            open: pack_chunks(&mut self.pending_next, parts.iter().map(|p| p.open)),
            ..Gathered::default()
        };
        for part in parts {
            all.fixed += part.fixed;
            all.max_total += part.max_total;
            all.at_min += part.at_min;
            all.at_max += part.at_max;
            all.linear += part.linear;
            for (sum, part) in all.sums.iter_mut().zip(part.sums) {
                *sum += part;
            }
        }
        all
    }

    /// Pivots for the next round from the open regions' breakpoints strictly inside
    /// `(lo, hi)`: quartiles of an evenly strided sample, or the exact median of all of them.
    /// No pivots means no breakpoint is left inside.
    fn sample_pivots(&mut self, len: usize, lo: f64, hi: f64, exact_median: bool) -> Pivots {
        let pending = &self.pending[..len];
        let inside = |b: f64| lo < b && b < hi;
        self.breakpoints.clear();
        if !exact_median {
            let stride = (len / 64).max(1);
            for e in pending.iter().skip(stride / 2).step_by(stride) {
                self.breakpoints
                    .extend([e.lower, e.upper].into_iter().filter(|&b| inside(b)));
            }
            if !self.breakpoints.is_empty() {
                return Pivots::quartiles(&mut self.breakpoints, lo, hi);
            }
        }
        for e in pending {
            self.breakpoints
                .extend([e.lower, e.upper].into_iter().filter(|&b| inside(b)));
        }
        if self.breakpoints.is_empty() {
            return Pivots::default();
        }
        let mid = self.breakpoints.len() / 2;
        let median = *self
            .breakpoints
            .select_nth_unstable_by(mid, f64::total_cmp)
            .1;
        Pivots {
            values: [median; 3],
            count: 1,
        }
    }
}

/// The water level's first round: its pivots, and the bracket it settles regions against.
#[derive(Clone, Copy, Debug)]
struct FirstRound {
    pivots: Pivots,
    bracket: (f64, f64),
}

impl FirstRound {
    /// The round guessed from the last level and its last move ([`guessed_bracket`]): that
    /// level and the bracket's ends as pivots.
    fn around(last: (f64, f64)) -> Self {
        let (a, level, b) = guessed_bracket(last);
        Self {
            pivots: Pivots {
                values: [a, level, b],
                count: 3,
            },
            bracket: (a, b),
        }
    }
}

/// The first round's bracket and middle pivot, from the last level and how far it moved
/// (relative): twice that move either side, at least 1/64 and at most 1/8 of the level.
fn guessed_bracket((level, moved): (f64, f64)) -> (f64, f64, f64) {
    let half = (2.0 * moved).clamp(1.0 / 64.0, 0.125);
    (level * (1.0 - half), level, level * (1.0 + half))
}

/// What the water level's first round learns from one chunk of regions.
#[derive(Clone, Copy, Debug, Default)]
struct Gathered {
    /// Regions with a share that the bracket does not settle, written to the front of the
    /// chunk's `open`.
    open: usize,
    /// `Σ min` of the regions without a share.
    fixed: f64,
    /// `Σ max` of the regions with a share.
    max_total: f64,
    /// `Σ clamp(p·s, min, max)` over the regions with a share, at each pivot `p`.
    sums: [f64; 3],
    /// Over the regions with a share that the bracket settles: `Σ min` of those at their
    /// minimum, `Σ max` of those at their maximum, `Σ s` of the linear ones.
    at_min: f64,
    at_max: f64,
    linear: f64,
}

/// The water level's first pass over one chunk: the chunk's part of `g` at the round's
/// pivots, what its bracket `(lo, hi)` settles (nothing for `(-∞, ∞)`), and the regions with
/// a share that it does not settle into `open` (at the front, in order).
///
/// The loop writes its output slot unconditionally and advances by a 0/1 flag, and adds
/// flag-weighted terms instead of branching (see [`Allocator::water_level`]).
fn gather(
    regions: &[RegionInput],
    shares: &[f64],
    open_out: &mut [Pending],
    round: FirstRound,
) -> Gathered {
    let [p0, p1, p2] = round.pivots.padded();
    let (lo, hi) = round.bracket;
    let mut g = Gathered::default();
    for (r, &s) in regions.iter().zip(shares) {
        let (min, max) = (f64::from(r.min), f64::from(r.max));
        let active = s > 0.0;
        let inverse = 1.0 / s; // ∞ when inactive, and then unused
        let e = Pending {
            lower: min * inverse,
            upper: max * inverse,
            share: s,
            min,
            max,
        };
        let below = active & (e.upper <= lo);
        let above = active & (e.lower >= hi);
        let linear = active & (e.lower <= lo) & (e.upper >= hi);
        let open = active & !(below | above | linear);
        open_out[g.open] = e;
        g.open += usize::from(open);
        g.fixed += min * flag(!active);
        g.max_total += max * flag(active);
        g.at_max += max * flag(below);
        g.at_min += min * flag(above);
        g.linear += s * flag(linear);
        // An inactive region has s = 0, so these add min · 0.
        let weight = flag(active);
        g.sums[0] += weight * (p0 * s).clamp(min, max);
        g.sums[1] += weight * (p1 * s).clamp(min, max);
        g.sums[2] += weight * (p2 * s).clamp(min, max);
    }
    g
}

/// Up to three distinct values inside the bracket at which a round evaluates `g`, ascending.
#[derive(Clone, Copy, Debug, Default)]
struct Pivots {
    values: [f64; 3],
    count: usize,
}

impl Pivots {
    /// The quartiles of `values` that lie strictly inside `(lo, hi)` (of an evenly strided
    /// subset when there are many). Reorders `values`.
    fn quartiles(values: &mut Vec<f64>, lo: f64, hi: f64) -> Self {
        values.retain(|&b| lo < b && b < hi);
        const SAMPLE: usize = 255;
        if values.len() > SAMPLE {
            let stride = values.len() / SAMPLE;
            for k in 0..SAMPLE {
                values[k] = values[k * stride];
            }
            values.truncate(SAMPLE);
        }
        values.sort_unstable_by(f64::total_cmp);
        let mut pivots = Self::default();
        let n = values.len();
        if n == 0 {
            return pivots;
        }
        for q in [n / 4, n / 2, (3 * n) / 4] {
            let p = values[q];
            if pivots.count == 0 || p > pivots.values[pivots.count - 1] {
                pivots.values[pivots.count] = p;
                pivots.count += 1;
            }
        }
        pivots
    }

    /// All three slots, the unused ones repeating the last pivot (or 0 when there is none).
    fn padded(&self) -> [f64; 3] {
        let last = if self.count == 0 {
            0.0
        } else {
            self.values[self.count - 1]
        };
        std::array::from_fn(|k| if k < self.count { self.values[k] } else { last })
    }

    /// Moves `lo` up to every pivot where `g ≤ target` and `hi` down to the first where it is
    /// above; `at_or_below(k)` says which for pivot `k`.
    fn narrow(&self, lo: &mut f64, hi: &mut f64, at_or_below: impl Fn(usize) -> bool) {
        for k in 0..self.count {
            if at_or_below(k) {
                *lo = self.values[k];
            } else {
                *hi = self.values[k];
                break;
            }
        }
    }
}

/// `g` on a bracket `[lo, hi]` with no breakpoint inside, over one chunk: the offset (the
/// regions at their minimum or maximum there, and those without a share) and the slope (the
/// shares of the linear ones). The breakpoints are computed as in [`gather`].
fn linear_piece(regions: &[RegionInput], shares: &[f64], lo: f64, hi: f64) -> (f64, f64) {
    let (mut fixed, mut slope) = (0.0, 0.0);
    for (r, &s) in regions.iter().zip(shares) {
        let (min, max) = (f64::from(r.min), f64::from(r.max));
        let active = s > 0.0;
        let inverse = 1.0 / s;
        let below = active & (max * inverse <= lo);
        let above = active & !below & (min * inverse >= hi);
        let linear = active & !(below | above);
        fixed += max * flag(below) + min * flag(above | !active);
        slope += s * flag(linear);
    }
    (fixed, slope)
}

// ---------------------------------------------------------------------------------------------
// Phase 4: rounding
// ---------------------------------------------------------------------------------------------

impl Allocator {
    /// Floors of the targets, then +1 for the largest remainders until the total reaches
    /// `available` (never past it).
    fn round(
        &mut self,
        regions: &[RegionInput],
        lambda: f64,
        available: u64,
        out: &mut Vec<u32>,
        report: &mut AllocationReport,
        executor: &impl Executor,
    ) {
        let n = regions.len();
        if self.ranked.len() < n {
            self.ranked.resize(n, 0);
        }
        out.resize(n, 0);
        let mut jobs: Vec<_> = regions
            .chunks(CHUNK)
            .zip(self.share.chunks(CHUNK))
            .zip(out.chunks_mut(CHUNK))
            .zip(self.ranked[..n].chunks_mut(CHUNK))
            .enumerate()
            .map(|(c, (((regions, shares), out), ranked))| {
                (c * CHUNK, regions, shares, out, ranked, Floors::default())
            })
            .collect();
        executor.for_each(&mut jobs, &|(
            start,
            regions,
            shares,
            out,
            ranked,
            floors,
        )| {
            *floors = floor_targets(*start, regions, shares, lambda, out, ranked);
        });
        let floors: Vec<Floors> = jobs.into_iter().map(|job| job.5).collect();
        let ranked = pack_chunks(&mut self.ranked, floors.iter().map(|f| f.ranked));
        let mut total = 0u64;
        for f in &floors {
            total += f.total;
            report.at_min += f.at_min;
            report.at_max += f.at_max;
        }
        let ranked = &mut self.ranked[..ranked];
        if total < available {
            // Largest remainder first, then the larger weight (so a larger region never gets
            // less than a smaller one, even when α = ∞ makes their targets equal), then the
            // lower index: a total order, so the selection is deterministic.
            let extra = ((available - total) as usize).min(ranked.len());
            let first = ranked.len() - extra;
            if extra > 0 && first > 0 {
                ranked.select_nth_unstable(first);
            }
            for &key in &ranked[first..] {
                out[rank_index(key)] += 1;
            }
        } else if total > available {
            // Only from floating-point error: take back from the smallest remainders.
            self.ranked.clear();
            for (i, (r, &s)) in regions.iter().zip(&self.share).enumerate() {
                if s > 0.0 && out[i] > r.min {
                    let t = (lambda * s).clamp(f64::from(r.min), f64::from(r.max));
                    self.ranked
                        .push(rank_key(t - f64::from(out[i]), r.weight, i));
                }
            }
            self.ranked.sort_unstable();
            let excess = (total - available) as usize;
            for &key in self.ranked.iter().take(excess) {
                out[rank_index(key)] -= 1;
            }
        }
    }
}

/// What rounding one chunk down gave.
#[derive(Clone, Copy, Debug, Default)]
struct Floors {
    /// `Σ ⌊pᵢ⌋`.
    total: u64,
    /// Regions at (or clamped up to) their `min`.
    at_min: usize,
    /// Regions with a share clamped down to their `max`.
    at_max: usize,
    /// Regions that may take one more triangle, ranked at the front of the chunk's `ranked`.
    ranked: usize,
}

/// One chunk's targets `clamp(λ·sᵢ, minᵢ, maxᵢ)` rounded down into `out`, and the rank keys
/// of the regions that can take one more triangle into `ranked` (at the front). `start` is the
/// chunk's first region.
///
/// Branch-free again. A weightless region has λ·0 = 0 ≤ min, so it lands on its min with no
/// remainder, and it is never ranked for an extra triangle.
fn floor_targets(
    start: usize,
    regions: &[RegionInput],
    shares: &[f64],
    lambda: f64,
    out: &mut [u32],
    ranked: &mut [u128],
) -> Floors {
    let mut f = Floors::default();
    for (i, ((r, &s), slot)) in regions.iter().zip(shares).zip(out).enumerate() {
        let (min, max) = (f64::from(r.min), f64::from(r.max));
        let want = lambda * s;
        let t = want.clamp(min, max);
        let p = t as u32; // t ≥ 0, so truncation is the floor; in [min, max]
        *slot = p;
        f.total += u64::from(p);
        f.at_min += usize::from(want <= min);
        f.at_max += usize::from((want >= max) & (s > 0.0));
        ranked[f.ranked] = rank_key(t - f64::from(p), r.weight, start + i);
        f.ranked += usize::from((s > 0.0) & (p < r.max));
    }
    f
}

/// The rounding order as one integer, larger first: remainder, then weight, then lower index.
/// Both floats are non-negative, where the bit pattern orders like the value.
#[inline]
fn rank_key(remainder: f64, weight: f32, index: usize) -> u128 {
    (u128::from(remainder.to_bits()) << 64)
        | (u128::from(weight.to_bits()) << 32)
        | u128::from(!(index as u32))
}

#[inline]
fn rank_index(key: u128) -> usize {
    !(key as u32) as usize
}

// ---------------------------------------------------------------------------------------------
// Phase 5: hysteresis
// ---------------------------------------------------------------------------------------------

impl Allocator {
    /// Keeps `current` where the target moved by at most `epsilon`, then releases the kept
    /// regions that cost the most until the total fits in `available`.
    fn hysteresis(
        &mut self,
        epsilon: u32,
        regions: &[RegionInput],
        available: u64,
        out: &mut [u32],
        report: &mut AllocationReport,
        executor: &impl Executor,
    ) {
        if epsilon == 0 {
            return;
        }
        // Which regions keep their count, by chunks. Only those kept above their target can
        // give triangles back: each chunk lists them (target, index) at the front of its part
        // of `kept`, and the lists are packed in order. Every slot is written before it is
        // read, so the buffer is only ever grown.
        let n = regions.len();
        if self.kept.len() < n {
            self.kept.resize(n, (0, 0));
        }
        let mut jobs: Vec<_> = regions
            .chunks(CHUNK)
            .zip(out.chunks_mut(CHUNK))
            .zip(self.kept.chunks_mut(CHUNK))
            .enumerate()
            .map(|(c, ((regions, out), above))| (c * CHUNK, regions, out, above, [0; 3]))
            .collect();
        executor.for_each(&mut jobs, &|(
            start,
            regions,
            out,
            above,
            [listed, kept, total],
        )| {
            for (i, (r, p)) in regions.iter().zip(out.iter_mut()).enumerate() {
                let keep = (r.weight > 0.0)
                    & (r.current != *p)
                    & (r.current.abs_diff(*p) <= epsilon)
                    & (r.min <= r.current)
                    & (r.current <= r.max);
                above[*listed as usize] = (*p, (*start + i) as u32);
                *listed += u64::from(keep & (r.current > *p));
                *kept += u64::from(keep);
                *p = if keep { r.current } else { *p };
                *total += u64::from(*p);
            }
        });
        let parts: Vec<[u64; 3]> = jobs.into_iter().map(|job| job.4).collect();
        let listed = pack_chunks(&mut self.kept, parts.iter().map(|p| p[0] as usize));
        report.kept += parts.iter().map(|p| p[1] as usize).sum::<usize>();
        let mut total: u64 = parts.iter().map(|p| p[2]).sum();
        if total <= available {
            return;
        }
        // Most expensive first (current − target, descending), lower index among equals, at
        // a cost of 1 to ε: for a small ε a counting sort by cost, stable (`kept` is in index
        // order), else a sort.
        let kept = &mut self.kept[..listed];
        let cost = |&(target, i): &(u32, u32)| out[i as usize] - target;
        let order: &[(u32, u32)] = if epsilon <= 4096 {
            let top = epsilon as usize;
            self.runs.clear();
            self.runs.resize(top + 1, 0);
            for k in kept.iter() {
                self.runs[top - cost(k) as usize + 1] += 1;
            }
            for c in 1..self.runs.len() {
                self.runs[c] += self.runs[c - 1];
            }
            self.released.clear();
            self.released.resize(kept.len(), (0, 0));
            for k in kept.iter() {
                let slot = &mut self.runs[top - cost(k) as usize];
                self.released[*slot as usize] = *k;
                *slot += 1;
            }
            &self.released
        } else {
            kept.sort_unstable_by_key(|k| (std::cmp::Reverse(cost(k)), k.1));
            kept
        };
        for &(target, i) in order {
            if total <= available {
                break;
            }
            let p = &mut out[i as usize];
            total -= u64::from(*p - target);
            *p = target;
            report.kept -= 1;
            report.released += 1;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Shared by the phases
// ---------------------------------------------------------------------------------------------

/// Moves the first `lens[c]` items of every chunk `c` of `buffer` (chunks of [`CHUNK`])
/// together at its front, in order, and returns how many there are.
fn pack_chunks<T: Copy>(buffer: &mut [T], lens: impl IntoIterator<Item = usize>) -> usize {
    let mut packed = 0;
    for (c, len) in lens.into_iter().enumerate() {
        let start = c * CHUNK;
        buffer.copy_within(start..start + len, packed);
        packed += len;
    }
    packed
}

/// `1.0` or `0.0`: multiplying by it keeps the compiler from turning the choice back into a
/// branch, which would mispredict about half the time here.
#[inline]
fn flag(condition: bool) -> f64 {
    f64::from(u8::from(condition))
}

#[cfg(test)]
mod tests;
