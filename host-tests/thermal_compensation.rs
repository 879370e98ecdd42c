//! Thermal compensation's stepping (issue 22, `m2ctl::thermal::compensation`): the
//! bounded steps over long random sequences of targets, enables, sensor faults, moves
//! and holds; convergence and the dead band; the ramp to zero when disabled; freezing
//! on a sensor fault and recovering without a jump; the parameters' validation.
//! The properties are checked against the design's rules (docs/decisions.md, "Thermal
//! compensation (issue 22)"), each step against the state before it.

mod common;

use common::TestRng;
use m2ctl::kinematics::geometry::LEGS;
use m2ctl::thermal::compensation::{
    MAX_STEP_HIGHEST_MM, MAX_STEP_LOWEST_MM, MIN_STEP_LOWEST_MM, STEP_PERIOD_CYCLES,
};
use m2ctl::thermal::{Compensation, CompensationParamError, CompensationParams, StepOutcome};
use m2ctl::timing::CYCLE_US;
use m2ctl::units::{MM_PER_UM, US_PER_S};

/// Largest target offset the tests use (mm): 30 um, about 10 K of aluminium.
const TARGET_RANGE_MM: f64 = 0.03;

/// Uniform in [lo, hi].
fn uniform(rng: &mut TestRng, lo: f64, hi: f64) -> f64 {
    lo + (rng.sym() + 1.0) * 0.5 * (hi - lo)
}

/// True with probability `p`.
fn chance(rng: &mut TestRng, p: f64) -> bool {
    uniform(rng, 0.0, 1.0) < p
}

fn random_target(rng: &mut TestRng) -> [f32; LEGS] {
    core::array::from_fn(|_| (rng.sym() * TARGET_RANGE_MM) as f32)
}

/// Valid parameters, log-uniform over their ranges.
fn random_params(rng: &mut TestRng) -> CompensationParams {
    let log_between = |rng: &mut TestRng, lo: f32, hi: f32| {
        (uniform(rng, f64::from(lo).ln(), f64::from(hi).ln()).exp() as f32).clamp(lo, hi)
    };
    let max_step_mm = log_between(rng, MAX_STEP_LOWEST_MM, MAX_STEP_HIGHEST_MM);
    let min_step_mm = log_between(rng, MIN_STEP_LOWEST_MM, max_step_mm);
    let p = CompensationParams {
        max_step_mm,
        min_step_mm,
    };
    p.validate().unwrap();
    p
}

/// Largest |a - b| over the legs (f64).
fn max_diff_mm(a: &[f32; LEGS], b: &[f32; LEGS]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).abs())
        .fold(0.0, f64::max)
}

/// The rounding an f32 step may add to a change (mm): a few ulps of the largest value
/// involved (the offsets stay below 0.03 mm: ulp 1.9e-9 mm).
fn rounding_mm(a: &[f32; LEGS], b: &[f32; LEGS], c: &[f32; LEGS]) -> f64 {
    let big = a
        .iter()
        .chain(b)
        .chain(c)
        .map(|x| f64::from(x.abs()))
        .fold(0.0, f64::max);
    8.0 * f64::from(f32::EPSILON) * big
}

/// The most a leg may move in one step (mm): the maximum step and the rounding of an
/// f32 sum at the tests' largest offsets.
fn step_bound_mm(p: &CompensationParams) -> f64 {
    f64::from(p.max_step_mm) + 8.0 * f64::from(f32::EPSILON) * TARGET_RANGE_MM
}

#[test]
fn the_step_period_is_one_second() {
    assert_eq!(
        u64::from(STEP_PERIOD_CYCLES) * u64::from(CYCLE_US),
        u64::from(US_PER_S)
    );
}

/// Long random sequences: every step moves no leg by more than the maximum step, moves
/// nothing during a move, a hold or a freeze, keeps the direction of the difference,
/// reports the freeze once per fault, and steps exactly when the rule says it must.
#[test]
fn random_sequences_keep_every_step_bounded_and_held_when_they_must() {
    let mut counts = [0usize; 6];
    let mut freezes = 0;
    for seed in 1..=12u64 {
        let mut rng = TestRng(0x9E37_79B9_7F4A_7C15 ^ seed.wrapping_mul(0x2545_F491_4F6C_DD1D));
        let params = random_params(&mut rng);
        let mut c = Compensation::default();
        let mut target = random_target(&mut rng);
        let (mut moving, mut hold, mut faulty, mut no_target) = (false, false, false, false);
        // The test's own record of the fault edge: faulted while enabled since the last
        // good reading or enable.
        let mut reported = false;
        for n in 0..20_000 {
            // The inputs: episodes of moves, holds, faults; target jumps and drifts.
            if chance(&mut rng, 0.02) {
                moving = !moving;
            }
            if chance(&mut rng, 0.01) {
                hold = !hold;
            }
            if chance(&mut rng, 0.01) {
                faulty = !faulty;
            }
            if chance(&mut rng, 0.005) {
                no_target = !no_target;
            }
            if chance(&mut rng, 0.003) {
                c.set_enabled(!c.is_enabled());
                if !c.is_enabled() {
                    reported = false;
                }
            }
            if chance(&mut rng, 0.01) {
                target = random_target(&mut rng);
            } else {
                for t in &mut target {
                    *t += (rng.sym() * 0.3 * f64::from(params.max_step_mm)) as f32;
                    *t = t.clamp(-TARGET_RANGE_MM as f32, TARGET_RANGE_MM as f32);
                }
            }
            let mut offered = if no_target { None } else { Some(target) };
            if chance(&mut rng, 0.002) {
                offered = Some([f32::NAN; LEGS]);
            }
            // Now and then out-of-range parameters: nothing at all changes.
            if chance(&mut rng, 0.01) {
                let bad = CompensationParams {
                    max_step_mm: params.max_step_mm,
                    min_step_mm: params.max_step_mm * 1.5,
                };
                let before = c;
                let out = c.step(!moving, offered, !faulty, hold, &bad);
                assert_eq!(out, StepOutcome::InvalidParams);
                assert_eq!(
                    c, before,
                    "seed {seed} step {n}: invalid parameters changed the state"
                );
                continue;
            }

            let before = c;
            let a0 = c.applied_mm();
            let out = c.step(!moving, offered, !faulty, hold, &params);
            let a1 = c.applied_mm();
            counts[out as usize] += 1;
            let ctx = format!("seed {seed} step {n}: {out:?} {before:?} -> {c:?}");
            let changed = a0 != a1;
            assert_eq!(changed, out == StepOutcome::Stepped, "{ctx}");

            // Bounded: no leg by more than the maximum step.
            let goal = if before.is_enabled() {
                offered.unwrap_or([0.0; LEGS])
            } else {
                [0.0; LEGS]
            };
            let tol = rounding_mm(&a0, &a1, &goal);
            let delta = max_diff_mm(&a0, &a1);
            assert!(
                delta <= f64::from(params.max_step_mm) + tol,
                "{ctx}: a leg moved {delta} mm"
            );
            // Held: no change during a move or a hold.
            if moving || hold {
                assert!(!changed, "{ctx}: changed while moving or on hold");
            }
            // Frozen (enabled and a used sensor faulty, or no usable target): no change,
            // and the warning exactly on the fault's first period.
            let fault = faulty || offered.is_none_or(|t| t.iter().any(|x| !x.is_finite()));
            if before.is_enabled() {
                assert_eq!(c.is_frozen(), fault, "{ctx}");
                if fault {
                    assert!(!changed, "{ctx}: changed while frozen");
                    let expect = if reported {
                        StepOutcome::StillFrozen
                    } else {
                        StepOutcome::Frozen
                    };
                    assert_eq!(out, expect, "{ctx}");
                    freezes += usize::from(!reported);
                    reported = true;
                    continue;
                }
                reported = false;
            } else {
                assert!(!c.is_frozen(), "{ctx}");
                // Disabled: every leg only toward zero, never across it.
                for (x0, x1) in a0.iter().zip(&a1) {
                    assert!(x1.abs() <= x0.abs() && x0 * x1 >= 0.0, "{ctx}");
                }
            }
            if moving || hold {
                assert_eq!(out, StepOutcome::Held, "{ctx}");
                continue;
            }
            // At rest: a step exactly when some leg is at least the dead band away (any
            // distance when disabled); the step is the whole difference or the maximum
            // step on the worst leg, every leg scaled alike.
            let worst = max_diff_mm(&a0, &goal);
            let dead = if before.is_enabled() {
                f64::from(params.min_step_mm)
            } else {
                0.0
            };
            let must = worst > 0.0 && worst >= dead;
            // (Within rounding of the dead band either is right.)
            if (worst - dead).abs() > tol {
                assert_eq!(changed, must, "{ctx}: worst {worst} mm");
            }
            if must {
                let scale = (f64::from(params.max_step_mm) / worst).min(1.0);
                for ((x0, x1), g) in a0.iter().zip(&a1).zip(&goal) {
                    let want = f64::from(*x0) + (f64::from(*g) - f64::from(*x0)) * scale;
                    assert!(
                        (f64::from(*x1) - want).abs() <= tol,
                        "{ctx}: leg at {x1}, the scaled step gives {want}"
                    );
                }
                if scale == 1.0 {
                    assert_eq!(a1, goal, "{ctx}: the last step lands on the goal");
                }
            }
        }
    }
    // Every branch was exercised, by many periods.
    for (i, n) in counts.iter().enumerate().take(5) {
        assert!(*n > 100, "outcome {i} seen {n} times: {counts:?}");
    }
    assert!(freezes > 100, "{freezes} freezes");
}

/// Steps `c` at rest toward `target` until it settles (at most `limit` periods).
fn run_to(c: &mut Compensation, target: [f32; LEGS], p: &CompensationParams, limit: usize) {
    for _ in 0..limit {
        if c.step(true, Some(target), true, false, p) != StepOutcome::Stepped {
            return;
        }
    }
}

/// A constant target is reached (within the dead band) in ceil(distance / max step) + 1
/// periods, every leg's offset on the straight line between start and target; then the
/// stepping stops until the target moves by the minimum step.
#[test]
fn a_constant_target_is_reached_in_bounded_steps_then_stepping_stops() {
    let mut rng = TestRng(0x5EED_C0DE);
    for case in 0..300 {
        let p = if case == 0 {
            CompensationParams::DEFAULT
        } else {
            random_params(&mut rng)
        };
        let mut c = Compensation::default();
        c.set_enabled(true);
        // From zero or from a previous target's offset.
        if case % 2 == 1 {
            run_to(&mut c, random_target(&mut rng), &p, 100_000);
        }
        let start = c.applied_mm();
        let target = random_target(&mut rng);
        let distance = max_diff_mm(&start, &target);
        let bound = (distance / f64::from(p.max_step_mm)).ceil() as usize + 1;
        let mut n = 0;
        while max_diff_mm(&c.applied_mm(), &target) >= f64::from(p.min_step_mm) {
            assert!(n < bound, "case {case}: not there after {n} steps ({p:?})");
            assert_eq!(
                c.step(true, Some(target), true, false, &p),
                StepOutcome::Stepped
            );
            n += 1;
            // On the line from start to target: every leg the same fraction of the way
            // as the leg with the longest way (to the rounding of the steps so far).
            let a = c.applied_mm();
            let worst = (0..LEGS)
                .max_by(|&i, &j| {
                    let w = |k: usize| (f64::from(target[k]) - f64::from(start[k])).abs();
                    w(i).total_cmp(&w(j))
                })
                .unwrap();
            let way = |k: usize| f64::from(target[k]) - f64::from(start[k]);
            let frac = (f64::from(a[worst]) - f64::from(start[worst])) / way(worst);
            for i in 0..LEGS {
                let on_line = f64::from(start[i]) + frac * way(i);
                assert!(
                    (f64::from(a[i]) - on_line).abs()
                        <= n as f64 * rounding_mm(&a, &start, &target),
                    "case {case} step {n}: leg {i} at {} mm, the line at {on_line} mm",
                    a[i]
                );
            }
        }
        // Not in fewer steps than the bound allows (distance / max step).
        assert!(
            n as f64 >= (distance / f64::from(p.max_step_mm)).floor() - 1.0 || n == 0,
            "case {case}: {n} steps for {distance} mm"
        );
        let settled = c.applied_mm();
        for _ in 0..20 {
            assert_eq!(
                c.step(true, Some(target), true, false, &p),
                StepOutcome::Settled
            );
            assert_eq!(c.applied_mm(), settled);
        }
        // The dead band: 0.9 of the minimum step away on one leg, no step; 1.1, a step,
        // straight onto the new target (below the maximum step).
        let leg = case % LEGS;
        let mut near = settled;
        near[leg] += 0.9 * p.min_step_mm;
        assert_eq!(
            c.step(true, Some(near), true, false, &p),
            StepOutcome::Settled
        );
        let mut far = settled;
        far[leg] += (1.1 * p.min_step_mm).min(0.99 * p.max_step_mm);
        if max_diff_mm(&settled, &far) >= f64::from(p.min_step_mm) {
            assert_eq!(
                c.step(true, Some(far), true, false, &p),
                StepOutcome::Stepped
            );
            assert_eq!(c.applied_mm(), far);
        }
    }
}

/// Disabling ramps every leg to exactly zero by bounded steps (below the dead band too),
/// not during a move or a hold, and without the sensors; enabling again steps back.
#[test]
fn disabling_ramps_to_exactly_zero() {
    let mut rng = TestRng(0xD15A_B1ED);
    for case in 0..100 {
        let p = random_params(&mut rng);
        let mut c = Compensation::default();
        c.set_enabled(true);
        let target = if case == 0 {
            // Below the dead band everywhere but one leg: the ramp still ends at zero.
            let mut t = [0.3 * p.min_step_mm; LEGS];
            t[0] = 1.5 * p.min_step_mm;
            t
        } else {
            random_target(&mut rng)
        };
        run_to(&mut c, target, &p, 100_000);
        let start = c.applied_mm();
        assert!(max_diff_mm(&start, &[0.0; LEGS]) > 0.0);
        c.set_enabled(false);
        // Not while moving or on hold.
        for (at_rest, hold) in [(false, false), (true, true), (false, true)] {
            assert_eq!(
                c.step(at_rest, Some(target), true, hold, &p),
                StepOutcome::Held
            );
            assert_eq!(c.applied_mm(), start);
        }
        let bound =
            (max_diff_mm(&start, &[0.0; LEGS]) / f64::from(p.max_step_mm)).ceil() as usize + 1;
        let mut n = 0;
        while c.applied_mm() != [0.0; LEGS] {
            assert!(n < bound, "case {case}: not at zero after {n} steps");
            let before = c.applied_mm();
            // The sensors do not matter when disabled.
            let out = c.step(true, None, n % 2 == 0, false, &p);
            assert_eq!(out, StepOutcome::Stepped);
            assert!(max_diff_mm(&before, &c.applied_mm()) <= step_bound_mm(&p));
            n += 1;
        }
        assert_eq!(
            c.step(true, Some(target), true, false, &p),
            StepOutcome::Settled
        );
        assert_eq!(c.applied_mm(), [0.0; LEGS]);
        // Enabled again: back toward the target from zero, one bounded step.
        c.set_enabled(true);
        assert_eq!(
            c.step(true, Some(target), true, false, &p),
            StepOutcome::Stepped
        );
        assert!(max_diff_mm(&[0.0; LEGS], &c.applied_mm()) <= step_bound_mm(&p));
    }
}

/// A used sensor's fault freezes the offset at its last value with one warning; the
/// recovery resumes from there by one bounded step toward the new target (no jump); a
/// new fault warns again; disabling ends the freeze, an enable with the fault still
/// there warns again.
#[test]
fn a_sensor_fault_freezes_and_the_recovery_does_not_jump() {
    let p = CompensationParams::DEFAULT;
    let max = f64::from(p.max_step_mm);
    let slack = step_bound_mm(&p) - max;
    let mut c = Compensation::default();
    c.set_enabled(true);
    let a = [0.010, -0.008, 0.004, 0.0, -0.012, 0.006f32];
    for _ in 0..5 {
        assert_eq!(c.step(true, Some(a), true, false, &p), StepOutcome::Stepped);
    }
    let frozen = c.applied_mm();
    assert!(max_diff_mm(&frozen, &[0.0; LEGS]) > 4.0 * max * 0.99);
    // The fault: sensors bad (the target still offered), then no target, a NaN target,
    // during moves and holds: one warning, no change.
    assert_eq!(c.step(true, Some(a), false, false, &p), StepOutcome::Frozen);
    assert!(c.is_frozen());
    let b = [-0.020, 0.015, 0.0, 0.009, 0.011, -0.003f32];
    for (i, (at_rest, target, ok, hold)) in [
        (true, Some(b), false, false),
        (true, None, true, false),
        (true, Some([f32::NAN; LEGS]), true, false),
        (false, None, false, false),
        (true, Some(b), false, true),
        (true, None, false, false),
    ]
    .into_iter()
    .enumerate()
    {
        assert_eq!(
            c.step(at_rest, target, ok, hold, &p),
            StepOutcome::StillFrozen,
            "{i}"
        );
        assert_eq!(c.applied_mm(), frozen, "{i}");
    }
    // Recovery toward a far target: one bounded step from the frozen value.
    assert_eq!(c.step(true, Some(b), true, false, &p), StepOutcome::Stepped);
    assert!(!c.is_frozen());
    let d = max_diff_mm(&frozen, &c.applied_mm());
    assert!(d <= max + slack && d >= max - slack, "{d}");
    // Recovery during a move: the freeze ends, nothing moves until rest.
    assert_eq!(c.step(true, None, true, false, &p), StepOutcome::Frozen);
    let frozen = c.applied_mm();
    assert_eq!(c.step(false, Some(b), true, false, &p), StepOutcome::Held);
    assert!(!c.is_frozen());
    assert_eq!(c.applied_mm(), frozen);
    // A new fault warns again.
    assert_eq!(c.step(true, Some(b), false, false, &p), StepOutcome::Frozen);
    assert_eq!(
        c.step(true, Some(b), false, false, &p),
        StepOutcome::StillFrozen
    );
    // Disabled: the freeze ends, the offset ramps toward zero by bounded steps.
    c.set_enabled(false);
    assert!(!c.is_frozen());
    let before = c.applied_mm();
    assert_eq!(c.step(true, None, false, false, &p), StepOutcome::Stepped);
    assert!(max_diff_mm(&before, &c.applied_mm()) <= max + slack);
    // Enabled with the fault still there: frozen again, reported again.
    c.set_enabled(true);
    let held = c.applied_mm();
    assert_eq!(c.step(true, Some(b), false, false, &p), StepOutcome::Frozen);
    assert_eq!(c.applied_mm(), held);
}

/// The parameters' ranges (0.05..5 um maximum step, 0.005 um..maximum minimum step):
/// out-of-range and non-finite values are refused with their codes, and a step with
/// them changes nothing where valid ones would step.
#[test]
fn out_of_range_parameters_are_refused_and_change_nothing() {
    let um = |x: f64| (x * MM_PER_UM) as f32;
    // The documented defaults and bounds.
    let d = CompensationParams::DEFAULT;
    assert_eq!((d.max_step_mm, d.min_step_mm), (um(0.5), um(0.05)));
    assert_eq!(CompensationParams::default(), d);
    assert_eq!(
        (MAX_STEP_LOWEST_MM, MAX_STEP_HIGHEST_MM),
        (um(0.05), um(5.0))
    );
    assert_eq!(MIN_STEP_LOWEST_MM, um(0.005));
    assert_eq!(d.validate(), Ok(()));
    for (max, min) in [
        (um(0.05), um(0.005)),
        (um(5.0), um(5.0)),
        (um(0.05), um(0.05)),
        (um(1.0), um(0.005)),
    ] {
        let p = CompensationParams {
            max_step_mm: max,
            min_step_mm: min,
        };
        assert_eq!(p.validate(), Ok(()), "{p:?}");
    }
    let next_down = |x: f32| f32::from_bits(x.to_bits() - 1);
    let next_up = |x: f32| f32::from_bits(x.to_bits() + 1);
    let bad = [
        (
            next_down(um(0.05)),
            um(0.01),
            CompensationParamError::MaxStep,
        ),
        (next_up(um(5.0)), um(0.05), CompensationParamError::MaxStep),
        (0.0, 0.0, CompensationParamError::MaxStep),
        (-um(0.5), um(0.05), CompensationParamError::MaxStep),
        (f32::NAN, um(0.05), CompensationParamError::MaxStep),
        (f32::INFINITY, um(0.05), CompensationParamError::MaxStep),
        (
            um(0.5),
            next_down(um(0.005)),
            CompensationParamError::MinStep,
        ),
        (um(0.5), next_up(um(0.5)), CompensationParamError::MinStep),
        (um(0.5), 0.0, CompensationParamError::MinStep),
        (um(0.5), -um(0.05), CompensationParamError::MinStep),
        (um(0.5), f32::NAN, CompensationParamError::MinStep),
    ];
    for (max, min, err) in bad {
        let p = CompensationParams {
            max_step_mm: max,
            min_step_mm: min,
        };
        assert_eq!(p.validate(), Err(err), "{p:?}");
        // A state that would step (and a hold flag that would be recorded) with valid
        // parameters changes nothing with these.
        for enabled in [true, false] {
            let mut c = Compensation::default();
            c.set_enabled(true);
            run_to(&mut c, [0.001; LEGS], &d, 1);
            c.set_enabled(enabled);
            let before = c;
            let mut valid = c;
            assert_eq!(
                valid.step(true, Some([-0.002; LEGS]), true, false, &d),
                StepOutcome::Stepped
            );
            assert_eq!(
                c.step(true, Some([-0.002; LEGS]), true, false, &p),
                StepOutcome::InvalidParams
            );
            assert_eq!(c, before);
            assert_eq!(
                c.step(true, None, false, true, &p),
                StepOutcome::InvalidParams
            );
            assert_eq!(c, before);
        }
    }
    // The stable codes.
    assert_eq!(CompensationParamError::MaxStep.code(), 1);
    assert_eq!(CompensationParamError::MinStep.code(), 2);
}
