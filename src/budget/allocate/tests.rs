//! The allocator's unit tests.

use super::*;

fn region(weight: f32, min: u32, max: u32) -> RegionInput {
    RegionInput {
        weight,
        min,
        max,
        current: 0,
    }
}

/// Runs the chunks last first, each on its own scoped thread.
struct Backwards;

impl Executor for Backwards {
    fn for_each<T: Send>(&self, items: &mut [T], f: &(dyn Fn(&mut T) + Sync)) {
        std::thread::scope(|scope| {
            for item in items.iter_mut().rev() {
                scope.spawn(move || f(item));
            }
        });
    }
}

/// A xorshift sequence from `seed`, for the randomized tests.
fn xorshift(mut seed: u64) -> impl FnMut() -> u64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    }
}

#[test]
fn any_executor_gives_the_sequential_result() {
    // Several chunks, a partial last one, weightless and pinned regions among them.
    let mut next = xorshift(0x2545_F491_4F6C_DD1D);
    let regions: Vec<RegionInput> = (0..3 * CHUNK + 517)
        .map(|_| {
            let min = (next() % 40) as u32;
            let max = min + (next() % 400) as u32 * u32::from(!next().is_multiple_of(13));
            let weight = if next().is_multiple_of(7) {
                0.0
            } else {
                (next() % 1_000_000) as f32 * 0.37
            };
            RegionInput {
                weight,
                min,
                max,
                current: (next() % 420) as u32,
            }
        })
        .collect();
    for (budget, alpha, hysteresis) in [
        (1_000_000, 3.0, 0),
        (400_000, 1.0, 8),
        (150_000, 2.0, 0),
        (300_000, 0.7, 3),
        (u32::MAX, 3.0, 0),
        (10, 3.0, 0),
    ] {
        let params = AllocationParams {
            budget,
            alpha,
            hysteresis,
            fixed_cost: 0,
        };
        let (mut a, mut b) = (Vec::new(), Vec::new());
        let report_a = Allocator::new()
            .allocate(&params, &regions, &mut a)
            .unwrap();
        let report_b = Allocator::new()
            .allocate_with(&params, &regions, &mut b, &Backwards)
            .unwrap();
        assert_eq!((report_a, &a), (report_b, &b), "budget {budget}, α {alpha}");
        assert_eq!(a.len(), regions.len());
    }
    // The first invalid region in order is named, wherever the chunks finish.
    let mut bad = regions.clone();
    bad[2 * CHUNK + 5].min = bad[2 * CHUNK + 5].max + 1;
    bad[CHUNK + 9].weight = f32::NAN;
    let params = AllocationParams::with_budget(1_000);
    let err = Allocator::new()
        .allocate_with(&params, &bad, &mut Vec::new(), &Backwards)
        .unwrap_err();
    assert!(matches!(err, BudgetError::InvalidWeight { region, .. } if region == CHUNK + 9));
}

#[test]
fn the_last_level_steers_the_search_but_not_the_result() {
    // A view that drifts (the guessed bracket holds the new level), then jumps (it does
    // not), over several chunks: an allocator that remembers gives what a fresh one does.
    let base: Vec<RegionInput> = (0..2 * CHUNK + 300)
        .map(|i| {
            let min = (i % 7) as u32;
            let max = min + 20 + (i * 37 % 300) as u32;
            region(((i * 7919) % 1000) as f32 + 0.5 * (i % 3) as f32, min, max)
        })
        .collect();
    let mut remembering = Allocator::new();
    let mut hits = 0;
    for frame in 0..40 {
        let drift = 1.0 + 0.01 * (frame as f32 * 0.3).sin();
        let jump = if frame % 13 == 12 { 50.0 } else { 1.0 };
        let regions: Vec<RegionInput> = base
            .iter()
            .enumerate()
            .map(|(i, r)| RegionInput {
                weight: r.weight
                    * if i % 2 == 0 {
                        drift * jump
                    } else {
                        1.0 / drift
                    },
                ..*r
            })
            .collect();
        let params = AllocationParams::with_budget(150_000);
        let last = remembering.last_level;
        let (mut a, mut b) = (Vec::new(), Vec::new());
        let report_a = remembering.allocate(&params, &regions, &mut a).unwrap();
        let report_b = Allocator::new()
            .allocate(&params, &regions, &mut b)
            .unwrap();
        assert_eq!((report_a, &a), (report_b, &b), "frame {frame}");
        // Count the frames whose level fell inside the bracket guessed from the last one.
        if let (Some(last), Some((now, _))) = (last, remembering.last_level) {
            let (a, _, b) = guessed_bracket(last);
            hits += usize::from(a < now && now < b);
        }
    }
    assert!(hits >= 30, "the guess held in only {hits} of 39 frames");
}

#[test]
fn a_root_on_a_breakpoint_does_not_depend_on_the_last_level() {
    // Few distinct weights and maxima, and budgets that put the level exactly on some
    // region's breakpoint max/s: the search can end with that breakpoint as either end
    // of its bracket, depending on the path (the guess), and the two pieces' sums round
    // differently. (Found by review with a differential test.)
    let mut rng = xorshift(0x1234_5678_9ABC_DEF1);
    let mut next = move |n: u64| rng() % n;
    let mut checked = 0;
    for _ in 0..3000 {
        let n = 1 + next(6000) as usize;
        let w = [0.3f32, 0.7, 1.1, 3.3, 0.1][next(5) as usize];
        let alpha = [1.0f32, 2.0, 3.0, 0.5, f32::INFINITY][next(5) as usize];
        let regions: Vec<RegionInput> = (0..n)
            .map(|_| {
                let weight = w * (1 + next(3)) as f32;
                let max = [7u32, 13, 29, 100_000][next(4) as usize];
                region(weight, next(2) as u32, max)
            })
            .collect();
        let share = |r: &RegionInput| {
            if alpha.is_infinite() {
                1.0
            } else {
                f64::from(r.weight).powf(1.0 / f64::from(alpha))
            }
        };
        let j = next(n as u64) as usize;
        let b = f64::from(regions[j].max) / share(&regions[j]);
        let g: f64 = regions
            .iter()
            .map(|r| (b * share(r)).clamp(f64::from(r.min), f64::from(r.max)))
            .sum();
        for budget in [g.round() as u32, g.floor() as u32, g.ceil() as u32 + 1] {
            if budget == 0 {
                continue;
            }
            let params = AllocationParams {
                budget,
                alpha,
                ..Default::default()
            };
            // Warmed with a nearby budget, so that the call below starts from a guess.
            let mut warmed = Allocator::new();
            let nearby = AllocationParams {
                budget: budget.saturating_add(budget / 50 + 1),
                ..params
            };
            warmed.allocate(&nearby, &regions, &mut Vec::new()).unwrap();
            let (mut a, mut b) = (Vec::new(), Vec::new());
            let report_a = warmed.allocate(&params, &regions, &mut a).unwrap();
            let report_b = allocate(&params, &regions, &mut b).unwrap();
            assert_eq!(
                (report_a, &a),
                (report_b, &b),
                "n {n}, α {alpha}, w {w}, budget {budget}"
            );
            checked += 1;
        }
    }
    assert!(checked > 1000);
}

#[test]
fn extreme_weights_split_cleanly_for_every_alpha() {
    // The largest and the smallest (subnormal) f32 weights side by side: shares
    // unnormalised for α ≥ 1, normalised below it; nothing overflows or turns NaN.
    let tiny = f32::from_bits(1);
    let regions = [
        region(f32::MAX, 0, 1_000),
        region(1.0, 0, 1_000),
        region(tiny, 0, 1_000),
        region(f32::MAX, 0, 1_000),
    ];
    for alpha in [0.25, 0.999, 1.0, 1.5, 3.0, 1e30, f32::INFINITY] {
        let params = AllocationParams {
            budget: 1_000,
            alpha,
            ..Default::default()
        };
        let mut out = Vec::new();
        let report = allocate(&params, &regions, &mut out).unwrap();
        assert_eq!(report.total, 1_000, "α {alpha}: {out:?}");
        assert!(out[0] >= out[1] && out[1] >= out[2], "α {alpha}: {out:?}");
        assert_eq!(out[0], out[3], "α {alpha}: {out:?}");
    }
}

#[test]
fn fast_cube_root_is_exact_to_two_ulp() {
    let mut worst = 0.0f64;
    for i in 0..200_000 {
        // 1 down to 1e-87: every ratio of two f32 weights.
        let x = (-(i as f64) * 1e-3).exp();
        let expected = x.cbrt();
        worst = worst.max((cbrt_normal(x) - expected).abs() / expected);
    }
    assert!(worst <= 4.5e-16, "worst relative error {worst:e}");
    assert_eq!(cbrt_normal(1.0), 1.0);
    assert_eq!(cbrt_normal(0.125), 0.5);
}

#[test]
fn surplus_flows_to_the_others() {
    // Region 0 wants 900 of 1000 but may only have 100; the rest splits 1:1.
    let params = AllocationParams {
        budget: 1000,
        alpha: 1.0,
        ..Default::default()
    };
    let mut out = Vec::new();
    let report = allocate(
        &params,
        &[
            region(9.0, 0, 100),
            region(1.0, 0, 1000),
            region(1.0, 0, 1000),
        ],
        &mut out,
    )
    .unwrap();
    assert_eq!(out, vec![100, 450, 450]);
    assert_eq!(report.at_max, 1);
    assert_eq!(report.total, 1000);
}

#[test]
fn rounding_uses_largest_remainders() {
    let params = AllocationParams {
        budget: 10,
        alpha: 1.0,
        ..Default::default()
    };
    let mut out = Vec::new();
    allocate(
        &params,
        &[region(1.0, 0, 99), region(1.0, 0, 99), region(1.0, 0, 99)],
        &mut out,
    )
    .unwrap();
    assert_eq!(out, vec![4, 3, 3]); // ties go to the lower index
}

/// Hysteresis releases the kept regions in the documented order (cost descending, then
/// index) through either path: the counting sort for ε ≤ 4096 and the sort above.
#[test]
fn hysteresis_release_order_is_the_same_on_both_paths() {
    let mut rng = xorshift(0x2545_f491_4f6c_dd1d);
    let mut next = move |n: u64| rng() % n;
    let mut released = 0;
    for epsilon in [1u32, 3, 8, 100, 4096, 4097, 9000] {
        for _ in 0..20 {
            // Some of them over several chunks (the keep pass runs per chunk).
            let n = if next(4) == 0 {
                CHUNK + next(3 * CHUNK as u64) as usize
            } else {
                50 + next(400) as usize
            };
            let mut regions: Vec<RegionInput> = (0..n)
                .map(|_| region((1 + next(1000)) as f32, next(5) as u32, 20_000))
                .collect();
            let params = AllocationParams {
                budget: 100 * n as u32,
                alpha: 1.0,
                hysteresis: epsilon,
                ..Default::default()
            };
            let mut targets = Vec::new();
            let no_hysteresis = AllocationParams {
                hysteresis: 0,
                ..params
            };
            allocate(&no_hysteresis, &regions, &mut targets).unwrap();
            for (r, &t) in regions.iter_mut().zip(&targets) {
                // Mostly above the target, so keeping them overruns the budget.
                let d = next(u64::from(epsilon) + 1) as u32;
                r.current = if next(4) == 0 {
                    t.saturating_sub(d)
                } else {
                    t + d
                };
            }
            // The rule, written out.
            let mut expected = targets.clone();
            let mut kept = Vec::new();
            for (i, (r, p)) in regions.iter().zip(expected.iter_mut()).enumerate() {
                let in_bounds = (r.min..=r.max).contains(&r.current);
                if in_bounds && r.current != *p && r.current.abs_diff(*p) <= epsilon {
                    kept.push((i64::from(r.current) - i64::from(*p), i, *p));
                    *p = r.current;
                }
            }
            let mut total: u64 = expected.iter().map(|&p| u64::from(p)).sum();
            kept.sort_by_key(|&(cost, i, _)| (std::cmp::Reverse(cost), i));
            for (cost, i, target) in kept {
                if total <= u64::from(params.available()) || cost <= 0 {
                    break;
                }
                total -= cost as u64;
                expected[i] = target;
                released += 1;
            }
            let mut out = Vec::new();
            allocate(&params, &regions, &mut out).unwrap();
            assert_eq!(out, expected, "ε = {epsilon}");
        }
    }
    assert!(released > 100, "the cases release kept regions: {released}");
}

#[test]
fn hysteresis_releases_the_most_expensive_first() {
    let params = AllocationParams {
        budget: 300,
        alpha: 1.0,
        hysteresis: 10,
        ..Default::default()
    };
    let regions = [
        RegionInput {
            weight: 1.0,
            min: 0,
            max: 500,
            current: 105,
        },
        RegionInput {
            weight: 1.0,
            min: 0,
            max: 500,
            current: 108,
        },
        RegionInput {
            weight: 1.0,
            min: 0,
            max: 500,
            current: 95,
        },
    ];
    let mut out = Vec::new();
    let report = allocate(&params, &regions, &mut out).unwrap();
    // Targets 100 each; keeping all would be 308; releasing region 1 (8 over) gives 300.
    assert_eq!(out, vec![105, 100, 95]);
    assert_eq!((report.kept, report.released, report.total), (2, 1, 300));
}
