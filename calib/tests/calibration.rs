//! Ground calibration: model, solvers, sampling plan, campaign, evaluation, files.
//!
//! Budgets are small (dev profile); the full-size runs are `m2ground table3`.

#![cfg(feature = "host")]

use m2calib::calib::cuckoo::Coordinates;
use m2calib::calib::{
    self, calibrate, cuckoo, parse_measurements, CalibConfig, Measurement, ParamBox, Problem,
    SolverKind, N_PARAMS,
};
use m2calib::campaign::{perturbed, simulate};
use m2calib::eval::{accuracy, random_poses};
use m2calib::plan::{plan_poses, PlanConfig};
use m2ctl::kinematics::GeometryParams;
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::tracker::PoseTracker;
use m2ctl::units::UM_PER_MM;

/// Manufacturing error sigma of the test campaigns (mm).
const SIGMA_MM: f64 = 0.1;
/// Seed of the true geometry.
const GEOMETRY_SEED: u64 = 7;
/// Seed of the tracker noise.
const NOISE_SEED: u64 = 11;
/// Held-out poses per evaluation.
const EVAL_POSES: usize = 50;

fn truth() -> GeometryParams {
    perturbed(&PROTOTYPE, SIGMA_MM, GEOMETRY_SEED)
}

fn campaign(tracker: &PoseTracker) -> Vec<Measurement> {
    simulate(
        &PROTOTYPE,
        &truth(),
        &plan_poses(&PlanConfig::default()),
        tracker,
        NOISE_SEED,
    )
    .expect("campaign")
}

#[test]
fn jacobian_matches_finite_differences() {
    let meas = campaign(&PoseTracker::PAPER);
    let problem = Problem::new(meas, PROTOTYPE.p0_mm);
    let v = calib::to_vec(&truth());
    let j = problem.jacobian(&v);
    let n = problem.n_residuals();
    let h_mm = 1e-6;
    for k in 0..N_PARAMS {
        let mut vp = v;
        let mut vm = v;
        vp[k] += h_mm;
        vm[k] -= h_mm;
        let rp = problem.residuals(&vp);
        let rm = problem.residuals(&vm);
        for r in 0..n {
            let fd = (rp[r] - rm[r]) / (2.0 * h_mm);
            let an = j[r * N_PARAMS + k];
            assert!(
                (fd - an).abs() < 1e-7,
                "row {r} col {k}: analytic {an} vs finite difference {fd}"
            );
        }
    }
}

#[test]
fn lm_recovers_noise_free_to_nanometres() {
    let meas = campaign(&PoseTracker::PERFECT);
    let cfg = CalibConfig::default();
    let r = calibrate(&PROTOTYPE, &meas, &cfg).expect("lm");
    let targets = random_poses(EVAL_POSES, 1.0, 60.0, 99);
    let before = accuracy(&PROTOTYPE, &truth(), &targets).expect("eval");
    let after = accuracy(&r.params, &truth(), &targets).expect("eval");
    eprintln!("{}", r.summary());
    eprintln!("before {:?}\nafter {:?}", before.max_abs, after.max_abs);
    assert!(
        before.max_um() > 1.0 && before.max_arcsec() > 1.0,
        "campaign must need calibration"
    );
    assert!(after.max_um() < 1e-4, "max {} um", after.max_um());
    assert!(
        after.max_arcsec() < 1e-3,
        "max {} arcsec",
        after.max_arcsec()
    );
}

/// Small cuckoo budget for the dev-profile tests.
fn small_cuckoo() -> cuckoo::CuckooConfig {
    cuckoo::CuckooConfig {
        nests: 8,
        max_generations: 4,
        nm_iterations: 10,
        ..cuckoo::CuckooConfig::default()
    }
}

#[test]
fn cuckoo_is_deterministic_per_seed() {
    let meas = campaign(&PoseTracker::PAPER);
    for solver in [SolverKind::Smcs, SolverKind::Improved] {
        let cfg = |seed| CalibConfig {
            solver,
            seed,
            cuckoo: small_cuckoo(),
            ..CalibConfig::default()
        };
        let a = calibrate(&PROTOTYPE, &meas, &cfg(5)).expect("run a");
        let b = calibrate(&PROTOTYPE, &meas, &cfg(5)).expect("run b");
        let c = calibrate(&PROTOTYPE, &meas, &cfg(6)).expect("run c");
        assert_eq!(a.vec_mm, b.vec_mm, "{solver}: same seed, same result");
        assert_eq!(a.evaluations, b.evaluations);
        assert_ne!(
            a.vec_mm, c.vec_mm,
            "{solver}: another seed explores differently"
        );
        // The search makes progress from its random start.
        assert!(a.rms_after_mm < a.rms_before_mm * 10.0);
    }
}

#[test]
fn improved_stays_in_omega_and_beats_random_start() {
    let meas = campaign(&PoseTracker::PAPER);
    let problem = Problem::new(meas.clone(), PROTOTYPE.p0_mm);
    let nominal = calib::to_vec(&PROTOTYPE);
    for (half_width_mm, coordinates) in [0.05, 0.5]
        .into_iter()
        .flat_map(|h| [(h, Coordinates::Original), (h, Coordinates::Whitened)])
    {
        let omega = ParamBox::around(&nominal, half_width_mm);
        let cfg = cuckoo::CuckooConfig {
            coordinates,
            ..small_cuckoo()
        };
        for seed in 0..3 {
            let r = cuckoo::solve(
                &problem,
                &omega,
                &cfg,
                cuckoo::Variant::Improved,
                seed,
                false,
            )
            .expect("improved");
            assert!(
                omega.contains(&r.best),
                "{coordinates:?} seed {seed}: best left Omega"
            );
            // Monotone best (elitism).
            for w in r.history_rms_mm.windows(2) {
                assert!(w[1] <= w[0], "best got worse: {w:?}");
            }
        }
    }
}

/// Whitened search coordinates (our preconditioning) reach LM's fit and the noise floor
/// on a budget where the paper's original coordinates do not; both stay in Omega.
#[test]
fn whitened_coordinates_reach_the_lm_fit() {
    let meas = campaign(&PoseTracker::PAPER);
    let lm = calibrate(&PROTOTYPE, &meas, &CalibConfig::default()).expect("lm");
    let run = |coordinates| {
        let cfg = CalibConfig {
            solver: SolverKind::Improved,
            cuckoo: cuckoo::CuckooConfig {
                coordinates,
                ..test_budget_cuckoo()
            },
            ..CalibConfig::default()
        };
        calibrate(&PROTOTYPE, &meas, &cfg).expect("improved")
    };
    let whitened = run(Coordinates::Whitened);
    let original = run(Coordinates::Original);
    eprintln!(
        "fit RMS um: lm {:.4}, whitened {:.4}, original {:.4}",
        lm.rms_after_mm * UM_PER_MM,
        whitened.rms_after_mm * UM_PER_MM,
        original.rms_after_mm * UM_PER_MM
    );
    assert!(whitened.inside_omega && original.inside_omega);
    assert!(whitened.rms_after_mm < original.rms_after_mm);
    assert!(
        whitened.rms_after_mm <= lm.rms_after_mm * WHITENED_FIT_TOLERANCE,
        "whitened {} um vs LM {} um",
        whitened.rms_after_mm * UM_PER_MM,
        lm.rms_after_mm * UM_PER_MM
    );
    // And it is at the noise floor on held-out poses, like LM.
    let targets = random_poses(EVAL_POSES, 1.0, 60.0, 4);
    let acc = accuracy(&whitened.params, &truth(), &targets).expect("eval");
    assert!(acc.max_um() <= 0.2, "{} um", acc.max_um());
    assert!(acc.max_arcsec() <= 0.2, "{} arcsec", acc.max_arcsec());
}

/// Tolerance of the whitened search's fit RMS against LM's in
/// `whitened_coordinates_reach_the_lm_fit` (ratio).
const WHITENED_FIT_TOLERANCE: f64 = 1.02;

/// Budget of `whitened_coordinates_reach_the_lm_fit`: a fraction of the default, enough
/// for the whitened search to converge.
fn test_budget_cuckoo() -> cuckoo::CuckooConfig {
    cuckoo::CuckooConfig {
        nests: 15,
        max_generations: 60,
        nm_iterations: 100,
        ..cuckoo::CuckooConfig::default()
    }
}

/// Minimal deterministic generator for the property tests (xorshift64*).
struct XorShift(u64);

impl XorShift {
    fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn clamp_never_leaves_omega() {
    let nominal = calib::to_vec(&PROTOTYPE);
    let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
    for case in 0..2000 {
        let half = 1e-3 + rng.next_f64();
        let omega = ParamBox::around(&nominal, half);
        let mut v = nominal;
        for x in v.iter_mut() {
            // Far outside, inside, and the occasional NaN / infinity.
            let r = rng.next_f64();
            *x += (rng.next_f64() - 0.5) * 20.0 * half;
            if r < 0.02 {
                *x = f64::NAN;
            } else if r < 0.04 {
                *x = f64::INFINITY;
            } else if r < 0.06 {
                *x = f64::NEG_INFINITY;
            }
        }
        omega.clamp(&mut v);
        assert!(omega.contains(&v), "case {case}: {v:?}");
        // Idempotent, and inside points are untouched.
        let w = v;
        omega.clamp(&mut v);
        assert_eq!(v, w);
    }
}

#[test]
fn clamped_nelder_mead_evaluates_only_points_in_omega() {
    let meas = campaign(&PoseTracker::PAPER);
    let problem = Problem::new(meas, PROTOTYPE.p0_mm);
    let nominal = calib::to_vec(&PROTOTYPE);
    let omega = ParamBox::around(&nominal, 0.01);
    let mut rng = XorShift(42);
    for _ in 0..5 {
        let mut x0 = nominal;
        for x in x0.iter_mut() {
            *x += (rng.next_f64() - 0.5) * 0.02;
        }
        // Large steps push reflections and expansions far outside the box.
        let step = [0.05; N_PARAMS];
        let mut outside = 0usize;
        let mut f = |v: &calib::ParamVec| {
            if !omega.contains(v) {
                outside += 1;
            }
            problem.objective(v)
        };
        let (best, _) = cuckoo::nelder_mead(&mut f, &x0, &step, 60, Some(&omega));
        assert_eq!(outside, 0, "clamped NM evaluated points outside Omega");
        assert!(omega.contains(&best));
    }
    // Without the clamp (SMCS) the same steps do leave the box: the test is meaningful.
    let mut outside = 0usize;
    let mut f = |v: &calib::ParamVec| {
        if !omega.contains(v) {
            outside += 1;
        }
        problem.objective(v)
    };
    let _ = cuckoo::nelder_mead(&mut f, &nominal, &[0.05; N_PARAMS], 20, None);
    assert!(outside > 0);
}

#[test]
fn bounded_lm_beats_unbounded_with_realistic_noise() {
    let meas = campaign(&PoseTracker::REALISTIC);
    let targets = random_poses(EVAL_POSES, 1.0, 60.0, 3);
    let run = |solver| {
        let r = calibrate(
            &PROTOTYPE,
            &meas,
            &CalibConfig {
                solver,
                ..CalibConfig::default()
            },
        )
        .expect("lm");
        (accuracy(&r.params, &truth(), &targets).expect("eval"), r)
    };
    let (bounded, rb) = run(SolverKind::Lm);
    let (unbounded, _) = run(SolverKind::LmUnbounded);
    assert!(rb.inside_omega);
    assert!(rb.condition() > 1e3, "weakly observable directions exist");
    assert!(
        bounded.max_um() < unbounded.max_um(),
        "bounded {} um vs unbounded {} um",
        bounded.max_um(),
        unbounded.max_um()
    );
}

#[test]
fn lm_reaches_noise_floor_with_paper_noise() {
    let meas = campaign(&PoseTracker::PAPER);
    let r = calibrate(&PROTOTYPE, &meas, &CalibConfig::default()).expect("lm");
    let targets = random_poses(EVAL_POSES, 1.0, 60.0, 4);
    let acc = accuracy(&r.params, &truth(), &targets).expect("eval");
    assert!(acc.max_um() <= 0.2, "{} um", acc.max_um());
    assert!(acc.max_arcsec() <= 0.2, "{} arcsec", acc.max_arcsec());
}

#[test]
fn plan_has_the_papers_poses() {
    let poses = plan_poses(&PlanConfig::default());
    assert_eq!(poses.len(), 15 * 8);
    let mut seen = std::collections::HashSet::new();
    for p in &poses {
        let r = p.rotation_arcsec();
        for a in r {
            assert!((a.abs() - 30.0).abs() < 1e-9);
        }
        let t = p.translation_mm;
        let key = format!("{:?}{:?}", t, r.map(|v| v.signum()));
        assert!(seen.insert(key), "duplicate pose");
        let on_axis = t.iter().filter(|v| v.abs() == 1.0).count() == 1
            && t.iter().filter(|v| **v == 0.0).count() == 2;
        let corner = t.iter().all(|v| v.abs() == 0.5);
        let centre = t.iter().all(|v| *v == 0.0);
        assert!(on_axis || corner || centre, "{t:?}");
    }
}

fn csv_of(meas: &[Measurement]) -> String {
    calib::format_measurements(meas, "test campaign")
}

#[test]
fn measurement_file_round_trips() {
    let meas = campaign(&PoseTracker::PAPER);
    let back = parse_measurements(&csv_of(&meas)).expect("parse");
    assert_eq!(back.len(), meas.len());
    for (a, b) in back.iter().zip(meas.iter()) {
        for k in 0..6 {
            assert!((a.strokes_mm[k] - b.strokes_mm[k]).abs() < 1e-14);
        }
        for k in 0..3 {
            assert!((a.pose.translation_mm[k] - b.pose.translation_mm[k]).abs() < 1e-14);
            assert!((a.pose.rotation_rad[k] - b.pose.rotation_rad[k]).abs() < 1e-15);
        }
    }
}

#[test]
fn bad_measurement_files_are_rejected_with_line_numbers() {
    let good = csv_of(&campaign(&PoseTracker::PAPER));
    let lines: Vec<&str> = good.lines().collect();
    // Line 1 is the comment, line 2 the header, data from line 3.
    let edit = |line_no: usize, new: &str| {
        let mut l: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
        l[line_no - 1] = new.to_string();
        l.join("\n")
    };
    let data5 = lines[4];
    let mut fields: Vec<&str> = data5.split(',').collect();
    // Malformed row: a field missing.
    let short = fields[..11].join(",");
    let e = parse_measurements(&edit(5, &short)).unwrap_err();
    assert_eq!(e.line, 5, "{e}");
    // Not a number.
    fields[3] = "abc";
    let e = parse_measurements(&edit(5, &fields.join(","))).unwrap_err();
    assert_eq!(e.line, 5, "{e}");
    // NaN.
    fields[3] = "NaN";
    let e = parse_measurements(&edit(5, &fields.join(","))).unwrap_err();
    assert_eq!(e.line, 5, "{e}");
    assert!(e.message.contains("finite"), "{e}");
    // Duplicated header column.
    let dup = lines[1].replacen("s2_mm", "s1_mm", 1);
    let e = parse_measurements(&edit(2, &dup)).unwrap_err();
    assert_eq!(e.line, 2, "{e}");
    // A second header line in the data.
    let e = parse_measurements(&edit(7, lines[1])).unwrap_err();
    assert_eq!(e.line, 7, "{e}");
    // Duplicated measurement row.
    let e = parse_measurements(&edit(9, lines[3])).unwrap_err();
    assert_eq!(e.line, 9, "{e}");
    assert!(e.message.contains("line 4"), "{e}");
    // Fewer rows than parameters.
    let few: String = lines[..2 + N_PARAMS - 1].join("\n");
    let e = parse_measurements(&few).unwrap_err();
    assert!(e.message.contains("at least 36"), "{e}");
    let enough: String = lines[..2 + N_PARAMS].join("\n");
    assert_eq!(
        parse_measurements(&enough).expect("36 rows").len(),
        N_PARAMS
    );
    // Empty file.
    assert!(parse_measurements("").is_err());
    // And calibrate() itself refuses too few measurements.
    let meas = campaign(&PoseTracker::PAPER);
    assert!(calibrate(&PROTOTYPE, &meas[..N_PARAMS - 1], &CalibConfig::default()).is_err());
}

#[test]
fn levy_and_adaptive_step_constants() {
    // Mantegna's sigma_u for beta = 1.5 (Yang & Deb's value 0.6966).
    assert!((cuckoo::mantegna_sigma(1.5) - 0.696_574_4).abs() < 1e-6);
    assert!((cuckoo::gamma(5.0) - 24.0).abs() < 1e-12);
    let cfg = cuckoo::CuckooConfig::default();
    let t_max = cfg.max_generations;
    let mut prev = (f64::INFINITY, f64::INFINITY);
    for t in 0..=t_max {
        let (lambda, s_min) = cuckoo::adaptive_coefficients(&cfg, t, t_max);
        assert!(lambda <= prev.0 && s_min <= prev.1, "steps must shrink");
        assert!(lambda > 0.0 && s_min >= 0.0);
        prev = (lambda, s_min);
    }
    assert_eq!(cuckoo::adaptive_coefficients(&cfg, 0, t_max).0, 1.0);
    assert_eq!(cuckoo::adaptive_coefficients(&cfg, t_max, t_max).1, 0.0);
}

#[test]
fn calibrate_command_writes_a_geometry_file_that_round_trips() {
    use m2calib::calib_cmd::{run_calibrate, CalibrateArgs};
    let dir = std::env::temp_dir().join(format!("m2ctl-calib-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let data = dir.join("meas.csv");
    let nominal = dir.join("nominal.toml");
    std::fs::write(&data, csv_of(&campaign(&PoseTracker::PAPER))).expect("write");
    std::fs::write(
        &nominal,
        std::fs::read_to_string(concat!(
            concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
            "/testdata/geometry.toml"
        ))
        .expect("testdata"),
    )
    .expect("write");
    let args = CalibrateArgs {
        data: data.clone(),
        nominal,
        cfg: CalibConfig::default(),
        report: true,
        truth: None,
        plot: Some(dir.join("errors.svg")),
    };
    let (text, summary) = run_calibrate(&args).expect("calibrate");
    let back = m2calib::files::parse_geometry(&text).expect("output parses");
    let direct = calibrate(
        &PROTOTYPE,
        &parse_measurements(&std::fs::read_to_string(&data).expect("read")).expect("csv"),
        &CalibConfig::default(),
    )
    .expect("lm");
    assert_eq!(back.params, direct.params, "full f64 precision");
    assert!(back
        .provenance
        .iter()
        .any(|(k, v)| k == "solver" && v == "lm"));
    assert!(summary.contains("condition"), "{summary}");
    assert!(
        std::fs::metadata(dir.join("errors.svg"))
            .expect("plot")
            .len()
            > 1000
    );
    // A bad file is refused with its path and line.
    std::fs::write(&data, "x_mm\n1\n").expect("write");
    let e = run_calibrate(&args).unwrap_err();
    assert!(e.contains("meas.csv"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
