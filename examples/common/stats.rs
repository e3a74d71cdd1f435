//! Statistics of frame-time series the examples report: medians, the coefficient of
//! variation, run-to-run noise, correlation, and the machine's idle and stolen CPU time.

/// The median and the 95th percentile (nearest rank) of `values` as JSON (`median_ms`,
/// `p95_ms`), or null when empty.
pub fn median_p95(values: &[f64]) -> serde_json::Value {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return serde_json::Value::Null;
    }
    serde_json::json!({
        "median_ms": median(&v),
        "p95_ms": v[((0.95 * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1],
    })
}

/// The median of `values` (NaN when empty).
pub fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => (v[n / 2 - 1] + v[n / 2]) * 0.5,
    }
}

/// Mean and coefficient of variation (population standard deviation over the mean).
pub fn mean_cv(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    (
        mean,
        if mean > 0.0 {
            variance.sqrt() / mean
        } else {
            f64::NAN
        },
    )
}

/// Pearson's correlation of two equally long series (NaN when either is constant).
pub fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len()) as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx).powi(2);
        syy += (b - my).powi(2);
    }
    sxy / (sxx * syy).sqrt()
}

/// Each frame's median time over the runs (each run a list of frame times in ms).
pub fn per_frame_medians(runs: &[Vec<f64>], frames: usize) -> Vec<f64> {
    (0..frames)
        .map(|f| median(&runs.iter().map(|run| run[f]).collect::<Vec<_>>()))
        .collect()
}

/// One series' frame times over its runs (each `frames` long):
/// - `median_ms`, `p95_ms` (nearest rank), `mean_ms` and `cv` of the per-frame medians: the
///   systematic part, what the scripted frames themselves cost;
/// - `cv_all_frames`: the CV of every frame of every run, noise included;
/// - `run_to_run_ms`: the median absolute difference between two runs of the same frame (every
///   pair of runs; null with one run), and `frame_to_frame_ms`, between neighbouring frames of
///   a run: the noise;
/// - `cv_noise` and `cv_systematic`: how much of `cv` the noise explains and what is left,
///   estimated (null with one run): noise of standard deviation σ (from `run_to_run_ms`,
///   which is 0.954σ for normal noise) moves a median of R runs by about σ/√R for R ≤ 2 and
///   σ·√(π/2R) above, and the two variances add;
/// - `in_view_correlation`: Pearson's correlation of the per-frame medians with the
///   full-detail triangles in view.
///
/// The aerobic class adds `cpu_idle` and `cpu_steal` from [`CpuTimes`].
pub fn series_stats(runs: &[Vec<f64>], frames: usize, in_view: &[f64]) -> serde_json::Value {
    if runs.is_empty() || frames == 0 {
        return serde_json::Value::Null;
    }
    let medians = per_frame_medians(runs, frames);
    let mut sorted = medians.clone();
    sorted.sort_by(f64::total_cmp);
    let p95 = sorted[((0.95 * frames as f64).ceil() as usize).clamp(1, frames) - 1];
    let (mean, cv) = mean_cv(&medians);
    let every: Vec<f64> = runs
        .iter()
        .flat_map(|r| r[..frames].iter().copied())
        .collect();
    let mut pairs = Vec::new();
    for f in 0..frames {
        for (i, a) in runs.iter().enumerate() {
            for b in &runs[i + 1..] {
                pairs.push((a[f] - b[f]).abs());
            }
        }
    }
    let run_to_run = median(&pairs);
    let r = runs.len() as f64;
    let spread = if runs.len() <= 2 {
        1.0 / r.sqrt()
    } else {
        (std::f64::consts::PI / (2.0 * r)).sqrt()
    };
    let cv_noise = spread * run_to_run / 0.954 / mean;
    let steps: Vec<f64> = runs
        .iter()
        .flat_map(|r| r[..frames].windows(2).map(|w| (w[1] - w[0]).abs()))
        .collect();
    serde_json::json!({
        "runs": runs.len(),
        "median_ms": median(&medians),
        "p95_ms": p95,
        "mean_ms": mean,
        "cv": cv,
        "cv_all_frames": mean_cv(&every).1,
        "cv_noise": cv_noise,
        // NaN (null) with one run, like the noise.
        "cv_systematic": if cv_noise.is_nan() {
            f64::NAN
        } else {
            (cv * cv - cv_noise * cv_noise).max(0.0).sqrt()
        },
        "run_to_run_ms": run_to_run,
        "frame_to_frame_ms": median(&steps),
        "in_view_correlation": correlation(&medians, in_view),
    })
}

/// The whole machine's CPU time in clock ticks, from the first line of Linux's `/proc/stat`:
/// all of it, idle, and stolen by the hypervisor (a virtual machine's host running something
/// else). Zero where there is no `/proc/stat`.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuTimes {
    total: u64,
    idle: u64,
    steal: u64,
}

impl CpuTimes {
    pub fn now() -> Self {
        let Ok(stat) = std::fs::read_to_string("/proc/stat") else {
            return Self::default();
        };
        // cpu user nice system idle iowait irq softirq steal guest guest_nice
        let ticks: Vec<u64> = stat
            .lines()
            .next()
            .unwrap_or("")
            .split_whitespace()
            .skip(1)
            .filter_map(|t| t.parse().ok())
            .collect();
        let at = |i: usize| ticks.get(i).copied().unwrap_or(0);
        Self {
            // guest time is counted in user time already.
            total: ticks.iter().take(8).sum(),
            idle: at(3) + at(4),
            steal: at(7),
        }
    }

    pub fn since(self, start: Self) -> Self {
        Self {
            total: self.total.saturating_sub(start.total),
            idle: self.idle.saturating_sub(start.idle),
            steal: self.steal.saturating_sub(start.steal),
        }
    }

    pub fn add(&mut self, other: Self) {
        self.total += other.total;
        self.idle += other.idle;
        self.steal += other.steal;
    }

    /// Idle and stolen shares of the time (NaN without `/proc/stat`).
    pub fn shares(self) -> (f64, f64) {
        let total = self.total as f64;
        (self.idle as f64 / total, self.steal as f64 / total)
    }
}
