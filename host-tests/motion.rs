//! Motion: trajectories between poses and direct-stroke moves.
//!
//! The limit checks come in three layers:
//! * **exact profile** — the plan's integer phase lengths rebuilt in f64, poses in f64,
//!   strokes by f64 IK, every cycle: per-cycle slider speed (first difference) and
//!   acceleration (second difference) never exceed the limits;
//! * **f32 implementation** — the setpoints the controller receives differ from that
//!   exact profile by at most [`F32_POSE_TOL_MM`] per component;
//! * **what the drives see** — f32 setpoints through f32 IK: per-cycle speed within the
//!   limits, acceleration over a [`ACCEL_STENCIL_CYCLES`]-cycle stencil within the limits
//!   (a per-cycle second difference of f32 strokes carries ~1 nm of rounding, i.e.
//!   ~ 4 nm / (1 ms)^2 = 4 mm/s^2 of noise; the stencil divides that by 100).

// Index loops over legs and pose components read more clearly than zips here.
#![allow(clippy::needless_range_loop)]

use m2ctl::kinematics::fk::strokes_and_jacobian;
use m2ctl::kinematics::{
    ik, Geometry, GeometryParams, IkError, Pose, Refusals, StrokeLimits, LEGS,
};
use m2ctl::motion::{
    DirectStrokeLimits, MotionError, MotionLimits, Ramp, StrokeMove, StrokeMoveError, Trajectory,
    CYCLE_S,
};
use m2ctl::nominal::prototype_with_flight_limits;
use proptest::prelude::*;

const DT_S: f64 = CYCLE_S as f64;
/// Acceleration stencil for f32 strokes (cycles).
const ACCEL_STENCIL_CYCLES: usize = 10;
/// Largest difference between an f32 setpoint pose component and the exact profile's
/// (mm or rad): a few f32 ulps of 2 mm.
const F32_POSE_TOL_MM: f64 = 1.0e-6;

fn geom32() -> Geometry<f32> {
    Geometry::new(&prototype_with_flight_limits()).unwrap()
}

fn geom64() -> Geometry<f64> {
    Geometry::new(&prototype_with_flight_limits()).unwrap()
}

fn pose(mm: [f64; 3], arcsec: [f64; 3]) -> Pose<f32> {
    Pose::from_mm_arcsec(mm, arcsec)
}

fn limits(speed: [f32; LEGS], accel: [f32; LEGS]) -> MotionLimits {
    MotionLimits {
        max_speed_mm_per_s: speed,
        max_accel_mm_per_s2: accel,
    }
}

/// The exact (f64) path parameter of a ramp at cycle `k`, rebuilt from its integer phase
/// lengths (and its stop, if any).
fn exact_progress(r: &Ramp, k: u32) -> f64 {
    let na = f64::from(r.accel_cycles());
    let nc = f64::from(r.cruise_cycles());
    let n = 2.0 * na + nc;
    let base = |k: f64| -> (f64, f64) {
        if k >= n || na == 0.0 {
            return (1.0, 0.0);
        }
        let v = 1.0 / (na + nc);
        let a = v / na;
        if k < na {
            (0.5 * a * k * k, a * k)
        } else if k < na + nc {
            (v * (k - 0.5 * na), v)
        } else {
            (1.0 - 0.5 * a * (n - k) * (n - k), a * (n - k))
        }
    };
    if let Some(c) = r.stopped_at() {
        if k >= c {
            let (sc, vc) = base(f64::from(c));
            let d = f64::from(r.stop_decel_per_cycle2());
            let t = (f64::from(k - c)).min(if vc > 0.0 { vc / d } else { 0.0 });
            return sc + t * (vc - 0.5 * d * t);
        }
    }
    base(f64::from(k)).0
}

fn along64(start: &Pose<f32>, target: &Pose<f32>, s: f64) -> Pose<f64> {
    let a = start.cast::<f64>().to_array();
    let b = target.cast::<f64>().to_array();
    let mut p = [0.0; 6];
    for k in 0..6 {
        p[k] = a[k] + s * (b[k] - a[k]);
    }
    Pose::from_array(p)
}

/// Largest ratio (measured / limit) over legs and cycles, of per-cycle speed and
/// per-cycle (or per-stencil) acceleration of a stroke series sampled every cycle.
fn peak_ratios(strokes: &[[f64; LEGS]], lim: &MotionLimits, stencil: usize) -> (f64, f64) {
    let mut speed = 0.0f64;
    let mut accel = 0.0f64;
    for i in 0..LEGS {
        let v = f64::from(lim.max_speed_mm_per_s[i]);
        let a = f64::from(lim.max_accel_mm_per_s2[i]);
        for w in strokes.windows(2) {
            speed = speed.max((w[1][i] - w[0][i]).abs() / DT_S / v);
        }
        let h = stencil;
        for k in h..strokes.len().saturating_sub(h) {
            let d2 = strokes[k + h][i] - 2.0 * strokes[k][i] + strokes[k - h][i];
            accel = accel.max(d2.abs() / (h as f64 * DT_S).powi(2) / a);
        }
    }
    (speed, accel)
}

struct Run {
    /// Exact profile strokes (f64 IK), cycles 0..=end+pad.
    exact: Vec<[f64; LEGS]>,
    /// f32 setpoints through f32 IK.
    f32_strokes: Vec<[f64; LEGS]>,
    /// Largest |f32 setpoint - exact pose| component.
    pose_dev: f64,
}

/// Samples a trajectory every cycle from 0 to its end plus `pad` cycles.
fn simulate(traj: &Trajectory, pad: u32) -> Run {
    let (g32, g64) = (geom32(), geom64());
    let (start, target) = (traj.start(), traj.target());
    let mut run = Run {
        exact: Vec::new(),
        f32_strokes: Vec::new(),
        pose_dev: 0.0,
    };
    for k in 0..=traj.end_cycle() + pad {
        let sp = traj.setpoint(k);
        let exact_pose = along64(&start, &target, exact_progress(traj.ramp(), k));
        let e = ik(&g64, &exact_pose).unwrap();
        run.exact.push(e);
        let s = ik(&g32, &sp.pose).unwrap();
        run.f32_strokes.push(s.map(f64::from));
        let (a, b) = (sp.pose.cast::<f64>().to_array(), exact_pose.to_array());
        for c in 0..6 {
            run.pose_dev = run.pose_dev.max((a[c] - b[c]).abs());
        }
    }
    run
}

/// Asserts the three layers of limit checks; returns (speed, accel) peak ratios of the
/// exact profile.
fn assert_limits(traj: &Trajectory, lim: &MotionLimits, what: &str) -> (f64, f64) {
    let run = simulate(traj, 3);
    let (v, a) = peak_ratios(&run.exact, lim, 1);
    assert!(
        v <= 1.0 && a <= 1.0,
        "{what}: exact profile speed {v:.4} accel {a:.4} of limit"
    );
    assert!(
        run.pose_dev <= F32_POSE_TOL_MM,
        "{what}: f32 setpoint deviates {:e}",
        run.pose_dev
    );
    let (v32, a32) = peak_ratios(&run.f32_strokes, lim, ACCEL_STENCIL_CYCLES);
    assert!(
        v32 <= 1.0 && a32 <= 1.0,
        "{what}: f32 speed {v32:.4} accel (stencil) {a32:.4} of limit"
    );
    (v, a)
}

/// Moves over the workspace: translations, rotations, corner to corner, from off-home.
fn moves() -> Vec<(Pose<f32>, Pose<f32>)> {
    vec![
        (Pose::home(), pose([1.0, 0.0, 0.0], [0.0; 3])),
        (Pose::home(), pose([0.0, 0.0, -2.0], [0.0; 3])),
        (Pose::home(), pose([0.0; 3], [0.0, 0.0, 600.0])),
        (Pose::home(), pose([0.0; 3], [600.0, -600.0, 0.0])),
        (
            pose([-2.0, -2.0, -2.0], [-600.0, -600.0, -600.0]),
            pose([2.0, 2.0, 2.0], [600.0, 600.0, 600.0]),
        ),
        (
            pose([2.0, -2.0, 2.0], [600.0, -600.0, 600.0]),
            pose([-2.0, 2.0, -2.0], [-600.0, 600.0, -600.0]),
        ),
        (
            pose([0.3, -0.1, 0.05], [12.0, -30.0, 5.0]),
            pose([0.3001, -0.1, 0.05], [12.0, -30.0, 5.0]),
        ),
        (
            pose([0.5, 0.5, 0.5], [100.0; 3]),
            pose([0.5, 0.5, 0.5], [101.0, 100.0, 100.0]),
        ),
    ]
}

fn limit_sets() -> Vec<MotionLimits> {
    vec![
        MotionLimits::default(),
        limits([0.5; LEGS], [5.0; LEGS]),
        limits(
            [0.1, 0.2, 0.3, 0.4, 0.5, 0.05],
            [0.5, 1.0, 2.0, 0.3, 4.0, 1.5],
        ),
    ]
}

#[test]
fn slider_limits_hold_every_cycle_over_the_workspace() {
    let g = geom32();
    let mut worst = (0.0f64, 0.0f64);
    let mut cycles = 0u64;
    for lim in limit_sets() {
        for (i, (a, b)) in moves().iter().enumerate() {
            let t = Trajectory::plan(&g, a, b, &lim).unwrap();
            let (v, acc) = assert_limits(&t, &lim, &format!("move {i}"));
            worst = (worst.0.max(v), worst.1.max(acc));
            cycles += u64::from(t.end_cycle());
        }
    }
    println!(
        "{cycles} cycles simulated; peak slider speed {:.3} and acceleration {:.3} of their limits",
        worst.0, worst.1
    );
    // The plan is not needlessly slow: some slider reaches most of its speed limit.
    assert!(worst.0 > 0.8, "{worst:?}");
}

#[test]
fn sliders_start_at_cycle_0_and_arrive_together() {
    let g = geom32();
    let g64 = geom64();
    let lim = limits([0.5; LEGS], [5.0; LEGS]);
    let (a, b) = (Pose::home(), pose([0.5, -0.3, 0.2], [100.0, -50.0, 80.0]));
    let t = Trajectory::plan(&g, &a, &b, &lim).unwrap();
    let n = t.end_cycle();
    assert!(n > 10);
    let s = |k: u32| ik(&g64, &t.setpoint(k).pose.cast::<f64>()).unwrap();
    let (s0, s1, sn1, sn) = (s(0), s(1), s(n - 1), s(n));
    let s_target = ik(&g64, &b.cast::<f64>()).unwrap();
    for i in 0..LEGS {
        assert!(s1[i] != s0[i], "leg {} does not move at cycle 1", i + 1);
        assert!(
            sn1[i] != sn[i],
            "leg {} has arrived before cycle {n}",
            i + 1
        );
        assert_eq!(sn[i], s_target[i]);
        for k in n..n + 50 {
            assert_eq!(s(k)[i], s_target[i]);
        }
    }
    assert_eq!(t.setpoint(0).pose, a);
    assert!(!t.setpoint(0).moving && !t.setpoint(0).done);
    assert!(t.setpoint(1).moving && !t.setpoint(n - 1).done);
    assert!(t.setpoint(n).done && !t.setpoint(n).moving && t.is_done(n) && !t.is_done(n - 1));
    assert_eq!(t.setpoint(n).pose, b, "arrival is the exact target");
    // Together all the way: every slider is at the same fraction of its stroke change,
    // up to the path curvature (relative to the largest stroke change).
    let span = (0..LEGS).map(|i| (sn[i] - s0[i]).abs()).fold(0.0, f64::max);
    let mut spread = 0.0f64;
    for k in 0..=n {
        let sk = s(k);
        let f = exact_progress(t.ramp(), k);
        for i in 0..LEGS {
            spread = spread.max(((sk[i] - s0[i]) - f * (sn[i] - s0[i])).abs() / span);
        }
    }
    println!("largest deviation of a slider from the common progress: {spread:.2e} of the largest stroke change");
    assert!(spread < 2e-3, "{spread}");
}

#[test]
fn path_is_the_straight_line_in_pose_space() {
    let g = geom32();
    for (a, b) in moves() {
        let t = Trajectory::plan(&g, &a, &b, &MotionLimits::default()).unwrap();
        let (a64, b64) = (a.cast::<f64>().to_array(), b.cast::<f64>().to_array());
        let d: Vec<f64> = (0..6).map(|k| b64[k] - a64[k]).collect();
        let dn = d.iter().map(|x| x * x).sum::<f64>().sqrt();
        let mut prev_s = -1.0f64;
        for k in (0..=t.end_cycle() + 1).step_by(7) {
            let p = t.setpoint(k).pose.cast::<f64>().to_array();
            // Distance of (p - a) from the line through 0 along d, per component.
            let w: Vec<f64> = (0..6).map(|c| p[c] - a64[c]).collect();
            let s = w.iter().zip(d.iter()).map(|(x, y)| x * y).sum::<f64>() / (dn * dn);
            for c in 0..6 {
                let off = (w[c] - s * d[c]).abs();
                // f32 rounding of the components (|value| <= 2 mm: ulp 2.4e-7 mm).
                assert!(off <= 5e-7, "cycle {k} component {c}: {off:e} off the line");
            }
            assert!(s >= prev_s - 1e-6 && (-1e-7..=1.0 + 1e-7).contains(&s));
            prev_s = s;
        }
    }
}

#[test]
fn stop_decelerates_within_the_limits_to_rest_on_the_path() {
    let g = geom32();
    let lim = limits(
        [0.1, 0.2, 0.3, 0.4, 0.5, 0.05],
        [0.5, 1.0, 2.0, 0.3, 4.0, 1.5],
    );
    let (a, b) = (
        pose([-1.0, 0.5, 0.0], [-200.0, 0.0, 100.0]),
        pose([1.5, -0.5, 1.0], [300.0, 100.0, -200.0]),
    );
    let planned = Trajectory::plan(&g, &a, &b, &lim).unwrap();
    let n = planned.end_cycle();
    let na = planned.ramp().accel_cycles();
    let d = f64::from(planned.ramp().stop_decel_per_cycle2());
    for c in [
        0,
        1,
        na / 2,
        na,
        (n - na) / 2 + na / 2,
        n - na,
        n - na / 2,
        n - 1,
        n,
        n + 5,
    ] {
        let mut t = planned;
        let before = t.setpoint(c);
        t.stop(c);
        t.stop(c + 3); // a second stop request changes nothing
        assert_eq!(
            t.setpoint(c).pose,
            before.pose,
            "stop at {c} changed the setpoint of {c}"
        );
        assert_eq!(t.setpoint(c).moving, before.moving);
        for k in 0..c.min(n) {
            assert_eq!(t.setpoint(k), planned.setpoint(k));
        }
        let (v, acc) = assert_limits(&t, &lim, &format!("stop at {c}"));
        let end = t.end_cycle();
        // At rest: within ceil(rate / D) cycles of the stop, done, pose constant.
        let rate = if c < n {
            planned.ramp().sample(c).rate_per_cycle as f64
        } else {
            0.0
        };
        assert!(
            f64::from(end.saturating_sub(c)) <= (rate / d).ceil() + 1.0,
            "stop at {c} ends at {end}"
        );
        assert!(end <= n);
        let rest = t.setpoint(end);
        assert!(rest.done && !rest.moving);
        for k in end..end + 20 {
            assert_eq!(t.setpoint(k).pose, rest.pose);
        }
        if c > 0 && c < n {
            assert!(t.setpoint(end - 1).moving);
        }
        // The rest pose is on the path, between the stop point and the target.
        let s_rest = exact_progress(t.ramp(), end);
        let s_stop = exact_progress(planned.ramp(), c);
        assert!(s_rest >= s_stop && s_rest <= 1.0, "{s_stop} {s_rest}");
        println!("stop at {c:>5}/{n}: rest at {end:>5}, s {s_stop:.4} -> {s_rest:.4}, peaks {v:.3} {acc:.3}");
    }
}

#[test]
fn refused_targets_return_every_reason_and_no_trajectory() {
    let g = geom32();
    let lim = MotionLimits::default();
    let home = Pose::home();
    // Outside the workspace in x and in gamma.
    let r = Trajectory::plan(&g, &home, &pose([2.5, 0.0, 0.0], [0.0, 0.0, 700.0]), &lim);
    let Err(MotionError::TargetRefused(refusals)) = r else {
        panic!("{r:?}")
    };
    assert_eq!(refusals.axes_outside, 0b10_0001);
    assert_eq!(
        refusals.first_error(),
        Some(IkError::OutsideWorkspace { axes: 0b10_0001 })
    );
    assert_eq!(r.unwrap_err().code(), 0x0604);
    // Non-finite.
    let mut nan = home;
    nan.translation_mm[1] = f32::NAN;
    assert_eq!(
        Trajectory::plan(&g, &home, &nan, &lim),
        Err(MotionError::NonFinite)
    );
    assert_eq!(
        Trajectory::plan(&g, &nan, &home, &lim),
        Err(MotionError::NonFinite)
    );
    // Start refused.
    let r = Trajectory::plan(&g, &pose([0.0, -3.0, 0.0], [0.0; 3]), &home, &lim);
    assert!(
        matches!(
            r,
            Err(MotionError::StartRefused(Refusals {
                axes_outside: 0b10,
                ..
            }))
        ),
        "{r:?}"
    );
    // Bad limits.
    let mut bad = lim;
    bad.max_accel_mm_per_s2[4] = 0.0;
    assert_eq!(
        Trajectory::plan(&g, &home, &pose([0.1, 0.0, 0.0], [0.0; 3]), &bad),
        Err(MotionError::BadLimits { leg: 4 })
    );
    bad = lim;
    bad.max_speed_mm_per_s[0] = f32::NAN;
    assert_eq!(
        Trajectory::plan(&g, &home, &home, &bad),
        Err(MotionError::BadLimits { leg: 0 })
    );
}

#[test]
fn a_path_leaving_the_workspace_between_accepted_ends_is_refused() {
    // Along a horizontal direction orthogonal to leg 1's stroke gradient, leg 1's stroke is
    // convex in the path parameter: the ends need more stroke than the middle. A lower
    // stroke limit of leg 1 between the two refuses the middle of the path only.
    let mut params: GeometryParams = prototype_with_flight_limits();
    params.workspace = None;
    let g64 = Geometry::<f64>::new(&params).unwrap();
    let (_, jac) = strokes_and_jacobian(&g64, &Pose::home()).unwrap();
    let (jx, jy) = (jac[0][0], jac[0][1]);
    let norm = (jx * jx + jy * jy).sqrt();
    let u = [-jy / norm * 2.0, jx / norm * 2.0];
    let z = -0.01;
    let end = |sgn: f64| Pose::<f64>::from_array([sgn * u[0], sgn * u[1], z, 0.0, 0.0, 0.0]);
    let s_end = ik(&g64, &end(1.0)).unwrap()[0];
    let s_mid = ik(&g64, &Pose::from_array([0.0, 0.0, z, 0.0, 0.0, 0.0])).unwrap()[0];
    assert!(s_end > s_mid + 0.01, "{s_end} {s_mid}");
    let mut lim = params.stroke_limits.unwrap();
    lim.min_mm[0] = 0.5 * (s_mid + s_end).min(0.0);
    assert!(lim.min_mm[0] > s_mid && lim.min_mm[0] < s_end);
    params.stroke_limits = Some(StrokeLimits { ..lim });
    let g = Geometry::<f32>::new(&params).unwrap();
    let (a, b) = (end(-1.0).cast::<f32>(), end(1.0).cast::<f32>());
    let r = Trajectory::plan(&g, &a, &b, &MotionLimits::default());
    let Err(MotionError::PathRefused { sample, refusals }) = r else {
        panic!("{r:?}")
    };
    assert!(sample > 0 && (sample as usize) < m2ctl::motion::trajectory::PATH_SAMPLE_INTERVALS);
    assert_eq!(refusals.legs_below_min, 0b1);
    // Where the points lie (ICD section 3, "Check move"): point k (1..15) is the pose
    // start + (k/16)(target - start), component by component; the refused one reported
    // is the first such point whose leg 1 is below its limit (independent f64 IK).
    let n = m2ctl::motion::trajectory::PATH_SAMPLE_INTERVALS;
    assert_eq!(n, 16);
    let point = |k: usize| {
        let s = k as f64 / n as f64;
        let (pa, pb) = (end(-1.0).to_array(), end(1.0).to_array());
        Pose::<f64>::from_array(std::array::from_fn(|i| pa[i] + s * (pb[i] - pa[i])))
    };
    let first_below = (1..n)
        .find(|&k| ik(&g64, &point(k)).unwrap()[0] < f64::from(lim.min_mm[0] as f32))
        .unwrap();
    assert_eq!(usize::from(sample), first_below);
    // Either end alone is fine.
    assert!(Trajectory::plan(&g, &a, &a, &MotionLimits::default()).is_ok());
}

#[test]
fn zero_length_move_is_an_immediate_arrival() {
    let g = geom32();
    let p = pose([0.2, 0.1, -0.3], [10.0, 20.0, 30.0]);
    let t = Trajectory::plan(&g, &p, &p, &MotionLimits::default()).unwrap();
    assert_eq!(t.end_cycle(), 0);
    for k in [0, 1, 1000] {
        let sp = t.setpoint(k);
        assert!(sp.done && !sp.moving);
        assert_eq!(sp.pose, p);
    }
    let mut t2 = t;
    t2.stop(0);
    assert_eq!(t2, t);
}

#[test]
fn long_slow_move_stays_exact_in_f32() {
    // 1.6 mm of leg travel at 2 um/s: ~15 minutes, ~900,000 cycles, s increments of 1e-6.
    let g = geom32();
    let lim = limits([0.002; LEGS], [0.01; LEGS]);
    let (a, b) = (
        pose([-0.4, 0.3, 0.2], [50.0, 0.0, 0.0]),
        pose([0.4, 0.1, -0.2], [-50.0, 20.0, 0.0]),
    );
    let t = Trajectory::plan(&g, &a, &b, &lim).unwrap();
    let n = t.end_cycle();
    assert!(n > 500_000, "{n}");
    let mut dev = 0.0f64;
    let mut prev = -1.0f64;
    for k in 0..=n + 1 {
        let sp = t.setpoint(k);
        let exact = along64(&a, &b, exact_progress(t.ramp(), k)).to_array();
        let p = sp.pose.cast::<f64>().to_array();
        for c in 0..6 {
            dev = dev.max((p[c] - exact[c]).abs());
        }
        let s = f64::from(t.ramp().sample(k).progress);
        assert!(s >= prev, "progress decreased at {k}");
        prev = s;
    }
    println!("{n} cycles: largest f32 setpoint deviation from the exact profile {dev:.2e} mm/rad");
    assert!(dev <= F32_POSE_TOL_MM, "{dev:e}");
    assert_eq!(t.setpoint(n).pose, b);
}

// ---- Direct stroke ----------------------------------------------------------------------

fn direct_limits() -> DirectStrokeLimits {
    DirectStrokeLimits {
        max_speed_mm_per_s: 0.05,
        max_accel_mm_per_s2: 0.2,
        max_delta_mm: 1.0,
        stroke_min_mm: [-5.0; LEGS],
        stroke_max_mm: [5.0; LEGS],
    }
}

fn exact_stroke_series(m: &StrokeMove, start: f32, pad: u32) -> Vec<[f64; LEGS]> {
    (0..=m.end_cycle() + pad)
        .map(|k| {
            let mut s = [0.0; LEGS];
            s[m.leg() as usize] =
                f64::from(start) + exact_progress(m.ramp(), k) * f64::from(m.delta_mm());
            s
        })
        .collect()
}

#[test]
fn direct_stroke_moves_one_slider_within_its_own_limits() {
    let lim = direct_limits();
    let mlim = limits(
        [lim.max_speed_mm_per_s; LEGS],
        [lim.max_accel_mm_per_s2; LEGS],
    );
    let current = [0.1, -0.2, 0.3, -0.4, 0.5, -0.6];
    for (leg, delta) in [(0u8, 0.3f32), (3, -1.0), (5, 0.0005), (2, 0.01)] {
        for stop_at in [None, Some(40u32)] {
            let mut m = StrokeMove::plan(&current, leg, delta, &lim).unwrap();
            if let Some(c) = stop_at {
                m.stop(c);
            }
            let n = m.end_cycle();
            let (v, a) = peak_ratios(&exact_stroke_series(&m, current[leg as usize], 3), &mlim, 1);
            assert!(v <= 1.0 && a <= 1.0, "leg {leg} delta {delta}: {v} {a}");
            let f32s: Vec<[f64; LEGS]> = (0..=n + 3)
                .map(|k| m.setpoint(k).strokes_mm.map(f64::from))
                .collect();
            let (v32, a32) = peak_ratios(&f32s, &mlim, ACCEL_STENCIL_CYCLES);
            assert!(
                v32 <= 1.0 && a32 <= 1.0,
                "leg {leg} delta {delta}: f32 {v32} {a32}"
            );
            for k in 0..=n + 3 {
                let sp = m.setpoint(k);
                for i in 0..LEGS {
                    if i != leg as usize {
                        assert_eq!(sp.strokes_mm[i], current[i], "leg {i} moved");
                    }
                }
            }
            let fin = m.setpoint(n);
            assert!(fin.done && !fin.moving);
            if stop_at.is_none() {
                assert_eq!(fin.strokes_mm[leg as usize], current[leg as usize] + delta);
                println!(
                    "direct leg {} by {delta} mm: {n} cycles, peaks {v:.3} {a:.3}",
                    leg + 1
                );
            } else {
                let moved = (fin.strokes_mm[leg as usize] - current[leg as usize]) / delta;
                assert!((0.0..=1.0).contains(&moved));
            }
        }
    }
}

#[test]
fn direct_stroke_refusals() {
    let lim = direct_limits();
    let cur = [0.0; LEGS];
    assert_eq!(
        StrokeMove::plan(&cur, 6, 0.1, &lim),
        Err(StrokeMoveError::BadLeg)
    );
    assert_eq!(
        StrokeMove::plan(&cur, 0, 1.01, &lim),
        Err(StrokeMoveError::DeltaTooLarge)
    );
    assert_eq!(
        StrokeMove::plan(&cur, 0, f32::NAN, &lim),
        Err(StrokeMoveError::NonFinite)
    );
    let mut nan = cur;
    nan[3] = f32::INFINITY;
    assert_eq!(
        StrokeMove::plan(&nan, 0, 0.1, &lim),
        Err(StrokeMoveError::NonFinite)
    );
    let mut bad = lim;
    bad.max_speed_mm_per_s = 0.0;
    assert_eq!(
        StrokeMove::plan(&cur, 0, 0.1, &bad),
        Err(StrokeMoveError::BadLimits)
    );
    // Beyond the range: refused from inside, allowed back from outside.
    let mut near = cur;
    near[2] = 4.5;
    assert_eq!(
        StrokeMove::plan(&near, 2, 0.6, &lim),
        Err(StrokeMoveError::OutsideStrokeRange)
    );
    let mut out = cur;
    out[2] = 5.3;
    assert_eq!(
        StrokeMove::plan(&out, 2, 0.1, &lim),
        Err(StrokeMoveError::OutsideStrokeRange)
    );
    assert!(
        StrokeMove::plan(&out, 2, -0.1, &lim).is_ok(),
        "partial recovery toward the range"
    );
    assert!(StrokeMove::plan(&out, 2, -0.8, &lim).is_ok());
    assert_eq!(StrokeMoveError::OutsideStrokeRange.code(), 0x0615);
    let m = StrokeMove::plan(&cur, 1, 0.0, &lim).unwrap();
    assert!(m.setpoint(0).done);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Random moves over the workspace with random per-slider limits: the exact profile
    /// respects every limit at every cycle, and the f32 setpoints follow it.
    #[test]
    fn random_moves_respect_random_limits(
        a in prop::array::uniform6(-1.0f64..1.0),
        b in prop::array::uniform6(-1.0f64..1.0),
        v in prop::array::uniform6(0.1f32..1.0),
        acc in prop::array::uniform6(0.5f32..5.0),
        stop_frac in prop::option::of(0.0f64..1.0),
    ) {
        let ws = |x: [f64; 6]| pose([2.0 * x[0], 2.0 * x[1], 2.0 * x[2]],
            [600.0 * x[3], 600.0 * x[4], 600.0 * x[5]]);
        let lim = limits(v, acc);
        let mut t = Trajectory::plan(&geom32(), &ws(a), &ws(b), &lim).unwrap();
        if let Some(f) = stop_frac {
            t.stop((f * f64::from(t.end_cycle())) as u32);
        }
        assert_limits(&t, &lim, "random");
    }
}

#[test]
fn stepwise_planning_gives_the_same_trajectory_as_one_call() {
    use m2ctl::motion::{PlanStart, TrajectoryPlanner};
    let geom = Geometry::<f32>::new(&m2ctl::nominal::prototype_with_flight_limits()).unwrap();
    let limits = MotionLimits::default();
    let ends = [
        (
            [0.0, 0.0, 0.0],
            [0.0; 3],
            [1.9, -1.9, 1.9],
            [590.0, -590.0, 590.0],
        ),
        (
            [0.5, 0.2, -0.3],
            [10.0, 0.0, -20.0],
            [-1.0, 0.7, 0.3],
            [-40.0, 300.0, 0.0],
        ),
    ];
    for (ts, rs, tt, rt) in ends {
        let start = Pose::<f32>::from_mm_arcsec(ts, rs);
        let target = Pose::<f32>::from_mm_arcsec(tt, rt);
        let one = Trajectory::plan(&geom, &start, &target, &limits).unwrap();
        for per_call in [1usize, 2, 3, 4, 7, 100] {
            let PlanStart::Sampling(mut p) =
                TrajectoryPlanner::begin(&geom, &start, &target, &limits).unwrap()
            else {
                panic!("expected sampling")
            };
            let mut calls = 1;
            let stepwise = loop {
                if let Some(r) = p.advance(&geom, per_call) {
                    break r.unwrap();
                }
                calls += 1;
            };
            assert_eq!(stepwise, one, "{per_call} samples per call");
            assert_eq!(
                calls,
                m2ctl::motion::trajectory::PATH_SAMPLE_INTERVALS.div_ceil(per_call)
            );
        }
    }
}

/// Why `micromath` is not in the flight image (docs/decisions.md, "Packages"), measured. Outside
/// the kinematics (where its error is excluded by the 1 nm budget) the only non-rational
/// function of the flight code is the motion planner's square root, evaluated once per
/// plan (17 times in a trajectory plan of ~12,000 instructions, once in a ramp), never
/// per cycle: nothing to gain in time. Telemetry scaling is a multiplication and a
/// rounding (no function micromath offers), and the supervision has no statistics
/// (thresholds on differences). And it would cost: in [`Ramp::plan`] the acceleration
/// phase lasts `ceil(sqrt(1 / a_max))` cycles; micromath's square root (one bit
/// manipulation) over-estimates by up to 6 %, so moves would accelerate longer than the
/// limit requires. This sweep over the per-cycle accelerations the planner sees (1e-10
/// .. 1 per cycle^2) measures both against f64: ours (`Real::sqrt`, the planner's)
/// keeps the triangular ramp's acceleration at its limit to f32 rounding (1.7e-7);
/// micromath's error and the phases it would lengthen are printed. If micromath became
/// accurate to 1 % this test fails and the decision is to be revisited.
#[test]
fn micromath_sqrt_measured_where_the_motion_planner_would_use_it() {
    use m2ctl::kinematics::Real;
    use micromath::F32Ext;
    let overshoot = |n: f64, t_true: f64| ((t_true / n.max(1.0)).powi(2) - 1.0).max(0.0);
    let (mut ours_err, mut mm_err) = (0.0f64, 0.0f64);
    let (mut ours_over, mut longer, mut longest) = (0.0f64, 0u32, 1.0f64);
    let steps = 200_000;
    for k in 0..=steps {
        // Per-cycle acceleration, log-uniform over ten decades.
        let a = 10f64.powf(-10.0 * f64::from(k) / f64::from(steps));
        let inv = (1.0 / a) as f32;
        let t_true = f64::from(inv).sqrt();
        let ours = f64::from(Real::sqrt(inv));
        let mm = f64::from(F32Ext::sqrt(inv));
        ours_err = ours_err.max((ours - t_true).abs() / t_true);
        mm_err = mm_err.max((mm - t_true).abs() / t_true);
        ours_over = ours_over.max(overshoot(ours.ceil(), t_true));
        if mm.ceil() > ours.ceil() {
            longer += 1;
            longest = longest.max(mm.ceil() / ours.ceil());
        }
    }
    println!(
        "sqrt relative error vs f64: ours {ours_err:.1e}, micromath {mm_err:.1e}; ramp \
         acceleration above its limit with ours {ours_over:.1e}; micromath would lengthen \
         the acceleration phase in {longer} of {} cases, by up to {:.1} %",
        steps + 1,
        100.0 * (longest - 1.0)
    );
    assert!(ours_err <= f64::from(f32::EPSILON), "our sqrt {ours_err:e}");
    assert!(ours_over <= 1e-6, "ours overshoots {ours_over:e}");
    assert!(
        mm_err > 0.01,
        "micromath's sqrt is now within 1 % ({mm_err:e}): revisit"
    );
    assert!(longer > 0);
}
