//! A triangle budget for a variable-resolution level: the screen-space tolerance that gives
//! the most detail within a count.

use super::{
    Criterion, LevelCut, RefineError, ScreenSpaceError, VariableCache, VariableMesh, View,
};

/// The largest tolerance the search tries, in pixels ([`ToleranceSearch::MAX_TOLERANCE_PX`]).
const MAX_TOLERANCE_PX: f32 = 1.0e5;

/// The smallest tolerance the search tries above `0`, in pixels.
const MIN_TOLERANCE_PX: f32 = 1.0e-3;

/// Finds, frame after frame, the screen-space tolerance τ whose level has the most triangles
/// within a budget, and leaves the cache at that level.
///
/// The count of the level for `criterion` *or* [`ScreenSpaceError`]`(τ)` never grows with τ
/// (the criteria are monotone), so the tolerance is found by bracketing and bisection. Each
/// trial is a [`VariableCache::update`] from the level before, whose cost grows with what
/// changes, and the search starts from the last frame's τ: along a smooth camera path the
/// count at that τ is usually still inside the window `[(1 − slack)·budget, budget]` and one
/// update is the whole search (Hoppe's frame-to-frame regulation), while a jump (a cut, a new
/// budget) brackets by multiplying or dividing τ by four and then bisects on a logarithmic
/// scale. The search ends within `max_updates` trials (one more to return to the best level
/// tried), always at a level within the budget: the one of
/// the smallest τ tried that fits, or, when no τ up to 10⁵ pixels fits (the eye inside the
/// bounds of the detail it sees, where no tolerance drops anything, or a budget below what
/// the other criteria keep), the level of 10⁵ pixels cut at the finest uniform level that
/// fits ([`LevelCut`], bisected like τ; [`BudgetFit::level_cut`]), or the coarsest level
/// when none does.
///
/// ```
/// use bevy_aslod::mesh::IndexedMesh;
/// use bevy_aslod::multires::{BuildOptions, ProgressiveMesh};
/// use bevy_aslod::refine::{Criteria, ToleranceSearch, VariableCache, VariableMesh, View};
/// use glam::Vec3;
///
/// let (mesh, _) = IndexedMesh::load("../shared/testdata/meshes/cow.obj")?;
/// let options = BuildOptions::default().with_view_dependent(true);
/// let cow = VariableMesh::new(ProgressiveMesh::build(&mesh, &options)?)?;
/// let (lo, hi) = mesh.bounds().unwrap();
/// let centre = (lo + hi) * 0.5;
/// let eye = centre + Vec3::new(0.0, 0.0, 2.0 * (hi - lo).length());
/// let view = View::perspective(eye, centre - eye, Vec3::Y, 0.6, 4.0 / 3.0, 0.01, 600.0)?;
///
/// let mut cache = VariableCache::new(&cow);
/// let mut search = ToleranceSearch::default();
/// let criteria = Criteria::default().with_frustum(true).with_back_facing(true);
/// let fit = search.fit(&mut cache, &cow, &criteria, &view, 1_000, 0.0)?;
/// assert!(fit.triangles <= 1_000 && fit.triangles == cache.triangle_count());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct ToleranceSearch {
    /// The most updates one [`fit`](Self::fit) may run. Default: `12`.
    pub max_updates: u32,
    /// The fraction of the budget a level may leave unused and still be kept without a
    /// search. Default: `0.03`.
    pub slack: f32,
    /// Bisection stops when the bracket's ends are within this ratio. Default: `1.02`.
    pub precision: f32,
    /// The last tolerance that fitted, where the next search starts (`None` at first).
    tolerance: Option<f32>,
}

impl Default for ToleranceSearch {
    fn default() -> Self {
        Self {
            max_updates: 12,
            slack: 0.03,
            precision: 1.02,
            tolerance: None,
        }
    }
}

with_setters!(ToleranceSearch {
    max_updates: u32 => with_max_updates,
    slack: f32 => with_slack,
    precision: f32 => with_precision,
});

/// What one [`ToleranceSearch::fit`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct BudgetFit {
    /// Triangles of the level it left.
    pub triangles: usize,
    /// The tolerance of that level, in pixels (`f32::INFINITY` for the coarsest-level
    /// fallback).
    pub tolerance_px: f32,
    /// Updates run.
    pub updates: u32,
    /// Criterion evaluations over all updates.
    pub evaluated: usize,
    /// Collapses performed or undone over all updates.
    pub changed: usize,
    /// Whether the level is within the budget (false only when even the coarsest level
    /// holds more triangles than the budget).
    pub within: bool,
    /// When no tolerance fitted: the uniform level `L` that cuts the level of
    /// [`ToleranceSearch::MAX_TOLERANCE_PX`] (every collapse before `L` is performed too).
    pub level_cut: Option<usize>,
}

/// `criterion` or a screen-space tolerance, or every collapse.
struct WithTolerance<'a, K: ?Sized> {
    criterion: &'a K,
    tolerance: Option<ScreenSpaceError>,
    all: LevelCut,
}

impl<K: Criterion + ?Sized> Criterion for WithTolerance<'_, K> {
    #[inline]
    fn coarsen(&self, node: &super::Node, view: &View) -> bool {
        self.all.coarsen(node, view)
            || self.tolerance.is_some_and(|t| t.coarsen(node, view))
            || self.criterion.coarsen(node, view)
    }

    fn validate(&self) -> Result<(), RefineError> {
        self.criterion.validate()
    }
}

impl ToleranceSearch {
    /// The largest tolerance a search tries, in pixels.
    pub const MAX_TOLERANCE_PX: f32 = MAX_TOLERANCE_PX;

    /// The tolerance the last [`fit`](Self::fit) ended at, in pixels (`None` before the
    /// first and after a level-cut fallback).
    #[inline]
    #[must_use]
    pub fn tolerance(&self) -> Option<f32> {
        self.tolerance
    }

    /// Moves `cache` to the level of `criterion` or [`ScreenSpaceError`]`(τ)` with the
    /// smallest `τ ≥ floor_px` whose count is at most `budget` (see the type's docs).
    ///
    /// # Errors
    /// [`RefineError::InvalidTolerance`] when `floor_px` is NaN, infinite or negative;
    /// [`RefineError::InvalidCriterion`] when `max_updates` is `0`, `slack` is not in
    /// `[0, 1)` or `precision` is not above `1`; and any error of
    /// [`VariableCache::update`].
    pub fn fit<K: Criterion + ?Sized>(
        &mut self,
        cache: &mut VariableCache,
        mesh: &VariableMesh,
        criterion: &K,
        view: &View,
        budget: usize,
        floor_px: f32,
    ) -> Result<BudgetFit, RefineError> {
        ScreenSpaceError::new(floor_px)?;
        // A floor above the largest tolerance is the largest tolerance.
        let floor_px = floor_px.min(MAX_TOLERANCE_PX);
        if self.max_updates == 0 {
            return Err(RefineError::InvalidCriterion(
                "a tolerance search needs at least one update",
            ));
        }
        if !(0.0..1.0).contains(&self.slack) {
            return Err(RefineError::InvalidCriterion(
                "the search's slack must be in [0, 1)",
            ));
        }
        if !(self.precision > 1.0 && self.precision.is_finite()) {
            return Err(RefineError::InvalidCriterion(
                "the search's precision must be a finite ratio above 1",
            ));
        }
        criterion.validate()?;
        let mut fit = BudgetFit::default();
        // A trial at a tolerance, or at the largest one cut at a uniform level.
        let run =
            |cache: &mut VariableCache, tolerance: Result<f32, usize>, fit: &mut BudgetFit| {
                let (t, cut) = match tolerance {
                    Ok(t) => (t, 0),
                    Err(level) => (MAX_TOLERANCE_PX, level),
                };
                let c = WithTolerance {
                    criterion,
                    tolerance: ScreenSpaceError::new(t).ok(),
                    all: LevelCut(cut),
                };
                let stats = cache.update(mesh, &c, view)?;
                fit.updates += 1;
                fit.evaluated += stats.evaluated;
                fit.changed += stats.changed;
                Ok::<usize, RefineError>(stats.triangles)
            };
        let floor = floor_px;
        let fits = |n: usize| n <= budget;
        // The smallest tolerance known to fit, and the largest known not to.
        let mut good: Option<(f32, usize)> = None;
        let mut bad: Option<f32> = None;
        let start = self
            .tolerance
            .filter(|t| t.is_finite())
            .unwrap_or(1.0)
            .max(floor);
        let n = run(cache, Ok(start), &mut fit)?;
        let lower = ((1.0 - self.slack) * budget as f32) as usize;
        if fits(n) && (n >= lower || start <= floor) {
            return Ok(self.finish(fit, start, n, budget));
        }
        if fits(n) {
            good = Some((start, n));
        } else {
            bad = Some(start);
        }
        // Bracket: divide by four while it fits (down to the floor), multiply by four while it
        // does not (from one pixel to the largest tolerance in nine trials).
        while fit.updates < self.max_updates {
            let t = match (good, bad) {
                (Some((g, _)), None) => {
                    let t = if g <= MIN_TOLERANCE_PX {
                        floor
                    } else {
                        (g * 0.25).max(floor)
                    };
                    if t >= g {
                        break;
                    }
                    t
                }
                (None, Some(b)) => {
                    if b >= MAX_TOLERANCE_PX {
                        break;
                    }
                    // From (near) zero, one pixel next: ×4 from there reaches the largest
                    // tolerance in nine trials.
                    if b < 0.25 {
                        1.0
                    } else {
                        (b * 4.0).min(MAX_TOLERANCE_PX)
                    }
                }
                _ => break,
            };
            let n = run(cache, Ok(t), &mut fit)?;
            if fits(n) {
                good = Some((t, n));
                if n >= lower || t <= floor {
                    bad = None;
                    break;
                }
            } else {
                bad = Some(t);
            }
        }
        // Bisect on a logarithmic scale between the ends.
        while let (Some((g, gn)), Some(b)) = (good, bad) {
            if fit.updates >= self.max_updates || g <= b * self.precision || gn >= lower {
                break;
            }
            let t = if b <= 0.0 {
                (g * MIN_TOLERANCE_PX).sqrt()
            } else {
                (g * b).sqrt()
            };
            let n = run(cache, Ok(t), &mut fit)?;
            if fits(n) {
                good = Some((t, n));
            } else {
                bad = Some(t);
            }
        }
        match good {
            Some((t, n)) => {
                // Every trial that fits becomes `good`: unless the last one did not fit, the
                // cache holds `good`'s level already.
                let n = if fits(cache.triangle_count()) {
                    n
                } else {
                    run(cache, Ok(t), &mut fit)?
                };
                Ok(self.finish(fit, t, n, budget))
            }
            None => {
                // The finest uniform cut that fits: between no cut (known or assumed not to
                // fit) and the first uniform level within the budget (fits).
                let counts = mesh.mesh().level_triangle_counts();
                let coarsest = counts.len().saturating_sub(1);
                let mut hi = counts.iter().position(|&n| n <= budget).unwrap_or(coarsest);
                let mut lo = 0;
                let mut last = None;
                while fit.updates < self.max_updates && hi - lo > (hi / 64).max(1) {
                    let mid = lo + (hi - lo) / 2;
                    let n = run(cache, Err(mid), &mut fit)?;
                    last = Some(mid);
                    if fits(n) {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                let n = if last == Some(hi) {
                    cache.triangle_count()
                } else {
                    run(cache, Err(hi), &mut fit)?
                };
                fit.level_cut = Some(hi);
                let fit = self.finish(fit, f32::INFINITY, n, budget);
                self.tolerance = None;
                Ok(fit)
            }
        }
    }

    fn finish(&mut self, mut fit: BudgetFit, tolerance: f32, n: usize, budget: usize) -> BudgetFit {
        self.tolerance = Some(tolerance);
        fit.triangles = n;
        fit.tolerance_px = tolerance;
        fit.within = n <= budget;
        fit
    }
}
