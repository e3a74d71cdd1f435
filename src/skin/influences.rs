//! Validated per-vertex skin influences: glTF `JOINTS_0`/`WEIGHTS_0`, cleaned and sorted.

use super::{MAX_INFLUENCES, SkinError};

/// Negative weights down to this are rounding noise and clamp to 0; below it they are errors.
const NEGATIVE_TOLERANCE: f32 = 1e-6;

/// A weight sum further than this from 1 counts as [`WeightReport::renormalised`].
const SUM_TOLERANCE: f32 = 1e-3;

/// Per-vertex influences after validation.
///
/// Invariants established by [`Influences::new`] (and by
/// [`shortest_path_weights`](super::shortest_path_weights)):
/// - each weight is in `[0, 1]` and the four sum to 1 up to rounding;
/// - slots are sorted by weight, largest first (ties by ascending joint index), so the first
///   slot is the dominant joint and the first zero weight ends the list;
/// - a joint appears in at most one slot;
/// - unused slots have weight 0 and joint 0.
///
/// The fields are public for reading; code that writes them must keep the invariants.
/// [`blend`](super::blend) never panics on data that breaks them, but places such vertices
/// arbitrarily.
#[derive(Clone, Debug, PartialEq)]
pub struct Influences {
    /// Joint indices, one `[u16; 4]` per vertex.
    pub joints: Vec<[u16; MAX_INFLUENCES]>,
    /// Weights, one `[f32; 4]` per vertex, parallel to [`joints`](Self::joints).
    pub weights: Vec<[f32; MAX_INFLUENCES]>,
}

/// What [`Influences::new`] had to fix. Nothing here is an error; a caller that imports assets
/// typically logs a warning when any count is non-zero.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WeightReport {
    /// Vertices whose weights did not sum to 1 (off by more than `1e-3`) and were divided by
    /// their sum.
    pub renormalised: usize,
    /// Vertices with more than two non-zero weights. ASLOD allows one or two bones per vertex;
    /// these still blend with all their influences but join the region of their two largest.
    pub more_than_two: usize,
    /// Zero-weight slots whose joint index was not 0 (possibly out of range) and was set to 0.
    pub unused_slots_cleared: usize,
    /// Vertices that named one joint in several slots; the slots were merged into one.
    pub duplicate_joints_merged: usize,
}

impl Influences {
    /// Validates and normalises glTF-style `JOINTS_0`/`WEIGHTS_0` for a skeleton of
    /// `joint_count` joints.
    ///
    /// Normalisation, per vertex, in this order (each step counted in the [`WeightReport`]):
    /// 1. a weight in `[-1e-6, 0)` is rounding noise and becomes 0;
    /// 2. a zero-weight slot gets joint 0, whatever index it had (`unused_slots_cleared` when
    ///    that index was not 0), so garbage in unused slots is harmless;
    /// 3. slots that name the same joint are merged by adding their weights
    ///    (`duplicate_joints_merged`);
    /// 4. the weights are divided by their sum (`renormalised` when the sum was off by more
    ///    than `1e-3`; a sum within that is still divided, so it is 1 up to rounding);
    /// 5. the slots are sorted by weight, largest first, ties by ascending joint.
    ///
    /// # Errors
    /// - [`SkinError::LengthMismatch`] when `weights` and `joints` differ in length;
    /// - [`SkinError::NoJoints`] when `joint_count` is 0;
    /// - [`SkinError::NonFiniteWeight`] for a NaN or infinite weight;
    /// - [`SkinError::NegativeWeight`] for a weight below `-1e-6`;
    /// - [`SkinError::JointOutOfRange`] for a joint index `>= joint_count` with a non-zero
    ///   weight;
    /// - [`SkinError::ZeroWeights`] for a vertex whose weights are all zero.
    ///
    /// The first defect found (lowest vertex, then lowest slot) is reported.
    ///
    /// # Example
    /// ```
    /// use bevy_aslod::skin::Influences;
    ///
    /// // One vertex, weights not normalised and listed smallest first.
    /// let (influences, report) = Influences::new(&[[0, 2, 0, 0]], &[[1.0, 3.0, 0.0, 0.0]], 3)?;
    /// assert_eq!(influences.joints[0], [2, 0, 0, 0]);
    /// assert_eq!(influences.weights[0], [0.75, 0.25, 0.0, 0.0]);
    /// assert_eq!(report.renormalised, 1);
    /// # Ok::<(), bevy_aslod::skin::SkinError>(())
    /// ```
    pub fn new(
        joints: &[[u16; MAX_INFLUENCES]],
        weights: &[[f32; MAX_INFLUENCES]],
        joint_count: usize,
    ) -> Result<(Self, WeightReport), SkinError> {
        if weights.len() != joints.len() {
            return Err(SkinError::LengthMismatch {
                what: "weights",
                expected: joints.len(),
                found: weights.len(),
            });
        }
        if joint_count == 0 {
            return Err(SkinError::NoJoints);
        }
        let mut report = WeightReport::default();
        let mut out = Self {
            joints: Vec::with_capacity(joints.len()),
            weights: Vec::with_capacity(joints.len()),
        };
        for (vertex, (&j, &w)) in joints.iter().zip(weights).enumerate() {
            let (j, w) = normalise_vertex(vertex, j, w, joint_count, &mut report)?;
            out.joints.push(j);
            out.weights.push(w);
        }
        Ok((out, report))
    }

    /// Number of vertices.
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.joints.len().min(self.weights.len())
    }

    /// True when there are no vertices.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The dominant (largest-weight) joint of vertex `v`, or `None` when `v` is out of range.
    #[inline]
    #[must_use]
    pub fn dominant(&self, v: usize) -> Option<u16> {
        self.joints.get(v).map(|j| j[0])
    }
}

/// Steps 1-5 of [`Influences::new`] for one vertex.
fn normalise_vertex(
    vertex: usize,
    mut j: [u16; MAX_INFLUENCES],
    mut w: [f32; MAX_INFLUENCES],
    joint_count: usize,
    report: &mut WeightReport,
) -> Result<([u16; MAX_INFLUENCES], [f32; MAX_INFLUENCES]), SkinError> {
    for slot in 0..MAX_INFLUENCES {
        let weight = w[slot];
        if !weight.is_finite() {
            return Err(SkinError::NonFiniteWeight { vertex, slot });
        }
        if weight < -NEGATIVE_TOLERANCE {
            return Err(SkinError::NegativeWeight { vertex, weight });
        }
        if weight <= 0.0 {
            w[slot] = 0.0;
            if j[slot] != 0 {
                j[slot] = 0;
                report.unused_slots_cleared += 1;
            }
        } else if usize::from(j[slot]) >= joint_count {
            return Err(SkinError::JointOutOfRange {
                vertex,
                joint: j[slot],
                joint_count,
            });
        }
    }

    let mut merged = false;
    for k in 1..MAX_INFLUENCES {
        if w[k] == 0.0 {
            continue;
        }
        if let Some(m) = (0..k).find(|&m| w[m] > 0.0 && j[m] == j[k]) {
            w[m] += w[k];
            w[k] = 0.0;
            j[k] = 0;
            merged = true;
        }
    }
    report.duplicate_joints_merged += usize::from(merged);

    let mut sum: f32 = w.iter().sum();
    if sum == 0.0 {
        return Err(SkinError::ZeroWeights { vertex });
    }
    if !sum.is_finite() {
        // Four finite weights near f32::MAX overflow the sum; scale by the largest first.
        let max = w.iter().copied().fold(0.0, f32::max);
        w.iter_mut().for_each(|x| *x /= max);
        sum = w.iter().sum();
    }
    if (sum - 1.0).abs() > SUM_TOLERANCE {
        report.renormalised += 1;
    }
    if sum != 1.0 {
        w.iter_mut().for_each(|x| *x = (*x / sum).min(1.0));
    }

    // Insertion sort of four slots: weight descending, then joint ascending.
    let before = |a: usize, b: usize, j: &[u16; 4], w: &[f32; 4]| {
        w[a] > w[b] || (w[a] == w[b] && j[a] < j[b])
    };
    for k in 1..MAX_INFLUENCES {
        let mut m = k;
        while m > 0 && before(m, m - 1, &j, &w) {
            j.swap(m, m - 1);
            w.swap(m, m - 1);
            m -= 1;
        }
    }
    // Zero slots have joint 0 and sort after every non-zero slot, so the tie rule keeps them
    // last; subnormal weights divided by a large sum can still round to 0 here.
    for k in 0..MAX_INFLUENCES {
        if w[k] == 0.0 {
            j[k] = 0;
        }
    }
    if w[2] > 0.0 {
        report.more_than_two += 1;
    }
    Ok((j, w))
}
