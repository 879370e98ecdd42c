//! Calibration from laser-tracker points: registration, the bundle fit, uncertainty.

#![cfg(feature = "host")]

use m2calib::calib::bundle::{self, Bundle, BundleConfig, Priors};
use m2calib::calib::registration::{kabsch, pose_from_balls};
use m2calib::eval::{accuracy, random_poses};
use m2calib::plan::{plan_poses, PlanConfig};
use m2calib::tracker::campaign::{simulate, CampaignSeeds, TrackerSetup};
use m2ctl::kinematics::Pose;
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::tracker::{rotation_matrix, TrackerNoise, TrackerPlacement};
use m2ctl::units::UM_PER_MM;
use nalgebra::{Point3, Vector3};

#[test]
fn registration_recovers_a_noise_free_transform_to_rounding() {
    let placement = TrackerPlacement::default();
    let t = placement.base_to_tracker();
    let from = [
        [106.0, 106.0, -140.0],
        [-106.0, 106.0, -140.0],
        [-106.0, -106.0, -140.0],
        [106.0, -106.0, -131.0],
        [12.0, 3.0, 40.0],
    ];
    let to: Vec<[f64; 3]> = from
        .iter()
        .map(|p| {
            let y = t * Point3::from(*p);
            [y.x, y.y, y.z]
        })
        .collect();
    let got = kabsch(&from, &to, None).expect("kabsch");
    let dr = (got.rotation.to_rotation_matrix().matrix()
        - t.rotation.to_rotation_matrix().matrix())
    .abs()
    .max();
    let dt = (got.translation.vector - t.translation.vector).abs().max();
    eprintln!("rotation {dr:e}, translation {dt:e} mm");
    assert!(dr < 1e-15 * 10.0, "rotation off by {dr:e}");
    assert!(dt < 1e-12 * 2.0, "translation off by {dt:e} mm");
    // Pose from balls: noise free, exact to rounding.
    let balls = [
        [100.0, 0.0, 100.0],
        [0.0, 100.0, 100.0],
        [-100.0, 0.0, 100.0],
        [0.0, -100.0, 100.0],
    ];
    let pose = Pose::from_mm_arcsec([0.3, -0.7, 0.9], [40.0, -25.0, 55.0]);
    let r = rotation_matrix(&pose.rotation_rad);
    let p0 = PROTOTYPE.p0_mm;
    let in_b: Vec<[f64; 3]> = balls
        .iter()
        .map(|c| {
            let x = Vector3::from(p0) + Vector3::from(pose.translation_mm) + r * Vector3::from(*c);
            [x.x, x.y, x.z]
        })
        .collect();
    let back = pose_from_balls(&balls, &in_b, None, &p0).expect("pose");
    for k in 0..3 {
        assert!((back.translation_mm[k] - pose.translation_mm[k]).abs() < 1e-13);
        assert!((back.rotation_rad[k] - pose.rotation_rad[k]).abs() < 1e-15);
    }
    // Collinear points are refused.
    assert!(kabsch(
        &[[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        &[[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        None
    )
    .is_err());
}

fn small_campaign(
    noise: TrackerNoise,
    n_poses: usize,
) -> (TrackerSetup, m2calib::tracker::campaign::SimulatedCampaign) {
    let setup = TrackerSetup {
        noise,
        ..TrackerSetup::default()
    };
    let plan: Vec<Pose<f64>> = plan_poses(&PlanConfig::default())
        .into_iter()
        .take(n_poses)
        .collect();
    let c = simulate(&PROTOTYPE, 0.1, &setup, &plan, CampaignSeeds::from_one(3)).expect("campaign");
    (setup, c)
}

#[test]
fn bundle_jacobian_matches_finite_differences() {
    let (setup, c) = small_campaign(TrackerNoise::CLASS_15_6, 24);
    let data = c.data(&PROTOTYPE, &setup).expect("data");
    let priors = Priors {
        joint_sigma_mm: Some(0.1),
        ball_sigma_mm: Some(0.1),
    };
    let b = Bundle::new(&data, priors).expect("bundle");
    // A point away from the start: joints and balls off, registration corrected.
    let mut x = b.start();
    for (k, v) in x.iter_mut().enumerate() {
        *v += 1e-3 * ((k as f64 * 0.7).sin());
    }
    let j = b.jacobian(&x);
    // Steps (mm for lengths, rad for the registration angles): large enough that the
    // rounding of ~100 mm coordinates (1e-14 mm) stays far below the difference.
    let h = [1e-4, 1e-7];
    let reg = b.layout().registration();
    let mut worst = 0.0f64;
    for k in 0..b.n_params() {
        let step = if (reg..reg + 3).contains(&k) {
            h[1]
        } else {
            h[0]
        };
        let mut xp = x.clone();
        let mut xm = x.clone();
        xp[k] += step;
        xm[k] -= step;
        let rp = b.evaluate(&xp, None);
        let rm = b.evaluate(&xm, None);
        let col_scale = (0..b.n_rows())
            .map(|r| j[(r, k)].abs())
            .fold(0.0, f64::max)
            .max(1.0);
        for r in 0..b.n_rows() {
            let fd = (rp[r] - rm[r]) / (2.0 * step);
            let rel = (fd - j[(r, k)]).abs() / col_scale;
            worst = worst.max(rel);
        }
    }
    eprintln!("worst relative difference {worst:e}");
    assert!(worst < 1e-6, "{worst:e}");
}

#[test]
fn bundle_recovers_a_noise_free_campaign() {
    // Perfect tracker and perfect fiducial nests (the nests are the only reference of the
    // mechanism's rotation about z: with a 20 um drawing tolerance that alone is ~0.05 um
    // at 1 mm from home).
    let mut setup = TrackerSetup {
        noise: TrackerNoise::PERFECT,
        ..TrackerSetup::default()
    };
    setup.targets.fiducial_sigma_mm = 1e-9;
    let plan = plan_poses(&PlanConfig::default());
    let c = simulate(&PROTOTYPE, 0.1, &setup, &plan, CampaignSeeds::from_one(3)).expect("campaign");
    // A perfect tracker has a singular covariance: weight with a tiny isotropic one.
    let weighting = TrackerSetup {
        noise: TrackerNoise::isotropic(1e-3),
        ..setup.clone()
    };
    let data = c.data(&PROTOTYPE, &weighting).expect("data");
    let fit = bundle::fit(&data, &BundleConfig::unbounded()).expect("fit");
    let targets = random_poses(50, 1.0, 60.0, 99);
    let before = accuracy(&PROTOTYPE, &c.truth, &targets).expect("eval");
    let after = accuracy(&fit.params, &c.truth, &targets).expect("eval");
    eprintln!(
        "before {:?}\nafter {:?}\n{} evaluations, chi2 {:e}, {}",
        before.max_abs, after.max_abs, fit.evaluations, fit.chi2, fit.note
    );
    assert!(before.max_um() > 1.0);
    assert!(
        after.max_um() < 1e-6 && after.max_arcsec() < 1e-6,
        "{:?}",
        after.max_abs
    );
}

// ---- Tracker noise model ----

#[test]
fn simulated_tracker_noise_matches_its_anisotropic_model() {
    use rand::SeedableRng;
    let setup = TrackerSetup::default();
    let tracker =
        m2ctl::sim::tracker::LaserTracker::new(TrackerNoise::CLASS_15_6, &setup.placement);
    let x = [100.0, 0.0, -50.0];
    let y0 = Vector3::from(tracker.to_tracker(&x));
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    let n = 20_000;
    let mut cov = nalgebra::Matrix3::zeros();
    for _ in 0..n {
        let d = Vector3::from(tracker.measure(&x, &mut rng)) - y0;
        cov += d * d.transpose() / n as f64;
    }
    let model = TrackerNoise::CLASS_15_6.covariance_mm2(&[y0.x, y0.y, y0.z]);
    let u = y0 / y0.norm();
    let range_var = (u.transpose() * cov * u)[(0, 0)];
    let (sr, st) = TrackerNoise::CLASS_15_6.sigmas_mm(y0.norm());
    eprintln!(
        "range {:.2} um (model {:.2}), transverse model {:.2} um at {:.0} mm",
        range_var.sqrt() * UM_PER_MM,
        sr * UM_PER_MM,
        st * UM_PER_MM,
        y0.norm()
    );
    // Range error distinct from the transverse one, which grows with distance.
    assert!(st > 2.0 * sr, "anisotropic at 2.5 m");
    assert!((range_var.sqrt() / sr - 1.0).abs() < 0.03);
    assert!(((cov.trace() / model.trace()).sqrt() - 1.0).abs() < 0.03);
    assert!((cov - model).abs().max() < 0.05 * model.abs().max());
    let (_, st_far) = TrackerNoise::CLASS_15_6.sigmas_mm(2.0 * y0.norm());
    assert!(st_far > st * 1.4);
}

// ---- Files ----

fn campaign_files(n_poses: usize) -> (String, String, String) {
    use m2calib::tracker::files::{format_export, format_strokes, format_targets};
    let (setup, c) = small_campaign(TrackerNoise::CLASS_15_6, n_poses);
    (
        format_targets(&setup.targets, "test"),
        format_export(&c.points, "test"),
        format_strokes(&c.strokes, "test"),
    )
}

#[test]
fn tracker_files_round_trip() {
    use m2calib::tracker::files::{parse_export, parse_strokes, parse_targets};
    let (setup, c) = small_campaign(TrackerNoise::CLASS_15_6, 12);
    let (t, p, s) = campaign_files(12);
    assert_eq!(parse_targets(&t).unwrap(), setup.targets);
    let points = parse_export(&p).unwrap();
    assert_eq!(points.len(), c.points.len());
    for (a, b) in points.iter().zip(&c.points) {
        assert_eq!((a.pose, &a.name), (b.pose, &b.name));
        for k in 0..3 {
            assert!((a.y_mm[k] - b.y_mm[k]).abs() <= 5e-7, "printed to 1 nm");
        }
    }
    let strokes = parse_strokes(&s).unwrap();
    for (a, b) in strokes.iter().zip(&c.strokes) {
        assert_eq!(a.pose, b.pose);
        for k in 0..6 {
            assert!((a.strokes_mm[k] - b.strokes_mm[k]).abs() < 1e-14);
        }
    }
}

/// `text` with line `line` (1-based) replaced.
fn edit(text: &str, line: usize, new: &str) -> String {
    let mut l: Vec<String> = text.lines().map(str::to_string).collect();
    l[line - 1] = new.to_string();
    l.join("\n") + "\n"
}

/// 1-based number of the first line containing `pat`.
fn line_with(text: &str, pat: &str) -> usize {
    text.lines().position(|l| l.contains(pat)).unwrap() + 1
}

#[test]
fn malformed_tracker_files_are_refused_with_the_line() {
    use m2calib::tracker::bundle_data;
    use m2calib::tracker::files::{
        check_export, parse_export, parse_strokes, parse_targets, Which,
    };
    let (t, p, s) = campaign_files(12);
    let targets = parse_targets(&t).unwrap();
    let header = line_with(&p, "pose,point");
    let f1 = line_with(&p, "base,F1,");
    let b = line_with(&p, "3,B2,");
    let b_fields: Vec<&str> = p.lines().nth(b - 1).unwrap().split(',').collect();
    let with = |k: usize, v: &str| {
        let mut f = b_fields.clone();
        f[k] = v;
        edit(&p, b, &f.join(","))
    };
    // (file text, expected line, words)
    let point_cases: Vec<(String, usize, &str)> = vec![
        (
            edit(&p, header, "pose,point,x_mm,y_mm"),
            header,
            "missing column 'z_mm'",
        ),
        (
            edit(&p, header, "pose,point,x_mm,y_mm,z_mm,colour"),
            header,
            "unknown column",
        ),
        (
            edit(&p, header, "pose,point,x_mm,x_mm,z_mm"),
            header,
            "twice",
        ),
        (with(2, "12,3"), b, "fields"),
        (with(3, "abc"), b, "not a number"),
        (with(4, "NaN"), b, "finite"),
        (with(0, "0"), b, "pose number"),
        (with(0, "x"), b, "pose number"),
        (edit(&p, b, "3,B2,0.1,0.1,0.1"), b, "from the tracker"),
        (with(2, "1e9"), b, "from the tracker"),
        (
            edit(&p, b, p.lines().nth(b - 2).unwrap()),
            b,
            "already on line",
        ),
    ];
    for (i, (text, line, what)) in point_cases.iter().enumerate() {
        let e = parse_export(text).unwrap_err();
        assert!(e.line == *line && e.message.contains(what), "case {i}: {e}");
    }
    let strokes = parse_strokes(&s).unwrap();
    let check = |text: &str| {
        let pts = parse_export(text).unwrap();
        check_export(&targets, &pts, &strokes).unwrap_err()
    };
    // Cross-file checks: an unknown name, a ball in the base rows, a fiducial in a pose.
    for (text, line, what) in [
        (with(1, "B9"), b, "not in the target file"),
        (
            edit(&p, f1, &p.lines().nth(f1 - 1).unwrap().replace("F1", "B1")),
            f1,
            "is a ball",
        ),
        (with(1, "F2"), b, "is a fiducial"),
    ] {
        let (which, e) = check(&text);
        assert!(
            which == Which::Points && e.line == line && e.message.contains(what),
            "{e}"
        );
    }
    // A pose with two balls left.
    let pose3: Vec<usize> = p
        .lines()
        .enumerate()
        .filter(|(_, l)| l.starts_with("3,"))
        .map(|(i, _)| i)
        .collect();
    let two: String = p
        .lines()
        .enumerate()
        .filter(|(i, _)| !pose3[..2].contains(i))
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    let (_, e) = check(&two);
    assert!(e.message.contains("pose 3 has 2 balls"), "{e}");
    // Two fiducials only.
    let nofid: String = p
        .lines()
        .filter(|l| !l.starts_with("base,F3") && !l.starts_with("base,F4"))
        .map(|l| format!("{l}\n"))
        .collect();
    let (_, e) = check(&nofid);
    assert!(e.message.contains("2 fiducials"), "{e}");
    // Strokes: a missing pose, an extra pose, a duplicated pose, a bad number.
    let pts = parse_export(&p).unwrap();
    let missing: String = s
        .lines()
        .filter(|l| !l.starts_with("7,"))
        .map(|l| format!("{l}\n"))
        .collect();
    let (which, e) = check_export(&targets, &pts, &parse_strokes(&missing).unwrap()).unwrap_err();
    assert!(
        which == Which::Points && e.message.contains("pose 7 has no strokes"),
        "{e}"
    );
    let extra = format!("{s}99,0,0,0,0,0,0\n");
    let (which, e) = check_export(&targets, &pts, &parse_strokes(&extra).unwrap()).unwrap_err();
    assert!(
        which == Which::Strokes && e.line == extra.lines().count() && e.message.contains("pose 99"),
        "{e}"
    );
    let l4 = s.lines().position(|l| l.starts_with("4,")).unwrap() + 1;
    let dup = edit(&s, l4, s.lines().find(|l| l.starts_with("3,")).unwrap());
    let e = parse_strokes(&dup).unwrap_err();
    assert!(e.line == l4 && e.message.contains("pose 3 already"), "{e}");
    let e = parse_strokes(&edit(&s, l4, "4,0,0,inf,0,0,0")).unwrap_err();
    assert!(e.line == l4 && e.message.contains("finite"), "{e}");
    // A stroke beyond the slider range.
    let e = bundle_data(
        &targets,
        &pts,
        &parse_strokes(&edit(&s, l4, "4,0,0,7.5,0,0,0")).unwrap(),
        &PROTOTYPE,
        &TrackerNoise::CLASS_15_6,
    )
    .unwrap_err();
    assert!(
        e.which == Which::Strokes && e.error.line == l4 && e.error.message.contains("slider range"),
        "{e}"
    );
    // Target file: a duplicated name, collinear fiducials, too few balls, a bad sigma.
    let e = parse_targets(&t.replacen("name = \"B2\"", "name = \"B1\"", 1)).unwrap_err();
    assert!(
        e.message.contains("already defined") && e.line == line_with(&t, "name = \"B2\""),
        "{e}"
    );
    let e = parse_targets(&t.replace("ball_sigma_mm = 0.1", "ball_sigma_mm = -0.1")).unwrap_err();
    assert!(
        e.message.contains("positive") && e.line == line_with(&t, "ball_sigma_mm"),
        "{e}"
    );
    let mut few = targets.clone();
    few.balls.truncate(2);
    let e = parse_targets(&m2calib::tracker::files::format_targets(&few, "")).unwrap_err();
    assert!(e.message.contains("at least 3"), "{e}");
    let mut line = targets.clone();
    for (k, f) in line.fiducials.iter_mut().enumerate() {
        f.mm = [k as f64 * 50.0, 0.0, -140.0];
    }
    let e = parse_targets(&m2calib::tracker::files::format_targets(&line, "")).unwrap_err();
    assert!(e.message.contains("not all on one line"), "{e}");
}

#[test]
fn gross_errors_are_refused_before_the_fit_and_outliers_after() {
    use m2calib::calib::bundle::BundleError;
    use m2calib::tracker::bundle_data;
    use m2calib::tracker::files::{parse_export, parse_strokes, parse_targets, Which};
    let (t, p, s) = campaign_files(40);
    let targets = parse_targets(&t).unwrap();
    let strokes = parse_strokes(&s).unwrap();
    let noise = TrackerNoise::CLASS_15_6;
    let data = |text: &str| {
        bundle_data(
            &targets,
            &parse_export(text).unwrap(),
            &strokes,
            &PROTOTYPE,
            &noise,
        )
    };
    // Two balls' names swapped in pose 9.
    let (l1, l2) = (line_with(&p, "9,B1,"), line_with(&p, "9,B2,"));
    let swapped = edit(
        &edit(&p, l1, &p.lines().nth(l1 - 1).unwrap().replace("B1", "B2")),
        l2,
        &p.lines().nth(l2 - 1).unwrap().replace("B2", "B1"),
    );
    let e = data(&swapped).unwrap_err();
    assert!(
        e.which == Which::Points
            && [l1, l2].contains(&e.error.line)
            && e.error.message.contains("swapped"),
        "{e}"
    );
    // A fiducial moved by 5 mm.
    let lf = line_with(&p, "base,F3,");
    let f: Vec<String> = p
        .lines()
        .nth(lf - 1)
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let moved = edit(
        &p,
        lf,
        &format!(
            "{},{},{},{},{}",
            f[0],
            f[1],
            f[2].parse::<f64>().unwrap() + 5.0,
            f[3],
            f[4]
        ),
    );
    let e = data(&moved).unwrap_err();
    assert!(
        e.error.line == lf && e.error.message.contains("fiducial F3"),
        "{e}"
    );
    // One ball off by 0.3 mm: plausible before the fit, 20 sigma after it.
    let lb = line_with(&p, "17,B3,");
    let f: Vec<String> = p
        .lines()
        .nth(lb - 1)
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let off = edit(
        &p,
        lb,
        &format!(
            "{},{},{},{},{}",
            f[0],
            f[1],
            f[2],
            f[3].parse::<f64>().unwrap() + 0.3,
            f[4]
        ),
    );
    let d = data(&off).expect("plausible before the fit");
    match bundle::fit(&d, &BundleConfig::with_priors(0.1, 0.1)) {
        Err(BundleError::Outlier { line, sigmas, .. }) => {
            assert!(line == lb && sigmas > 10.0, "line {line}, {sigmas}")
        }
        other => panic!("expected an outlier: {:?}", other.map(|f| f.worst_point)),
    }
    // The unedited data fit, every point within a few sigma.
    let fit = bundle::fit(&data(&p).unwrap(), &BundleConfig::with_priors(0.1, 0.1)).expect("fit");
    assert!(
        fit.worst_point.0 < 5.0 && (fit.normalised_rms() - 1.0).abs() < 0.15,
        "{:?} {}",
        fit.worst_point,
        fit.normalised_rms()
    );
}

// ---- Uncertainty, observability, plan ----

/// Campaigns of the in-suite prediction check (docs/calibration.md's figures use 100 per scale:
/// `m2ground tracker-stats`).
const CHECK_CAMPAIGNS: u64 = 8;

#[test]
fn predicted_accuracy_matches_the_measured_held_out_error() {
    use m2calib::tracker::study::{prediction_check, rms3, run_method, Method, StudyConfig};
    let cfg = StudyConfig {
        campaigns: CHECK_CAMPAIGNS as usize,
        mc_draws: 50,
        targets: random_poses(60, 1.0, 60.0, 518002),
        ..StudyConfig::default()
    };
    let r = prediction_check(&cfg).expect("check");
    let sum = |f: &dyn Fn(&m2calib::tracker::study::PredictionPoint) -> f64| {
        r.points.iter().map(f).sum::<f64>()
    };
    for (what, range) in [("translation", 0..3), ("rotation", 3..6)] {
        let measured = sum(&|p| rms3(&p.measured_rms[range.clone()]).powi(2));
        let predicted = sum(&|p| rms3(&p.predicted_rms[range.clone()]).powi(2));
        let ratio = (measured / predicted).sqrt();
        eprintln!(
            "{what}: measured / predicted RMS over {} campaigns = {ratio:.3}",
            r.points.len()
        );
        assert!(ratio > 1.0 / 1.5 && ratio < 1.5, "{what}: {ratio}");
    }
    // The prior is what makes the fit better than not calibrating; without it the weak
    // directions take the tracker's noise (campaign 1).
    let c = cfg.campaign(1, &cfg.plan).expect("campaign");
    let before = run_method(&cfg, &c, Method::Before).unwrap().0.acc;
    let prior = run_method(&cfg, &c, Method::BundlePrior).unwrap().0.acc;
    let unbounded = run_method(&cfg, &c, Method::BundleUnbounded).unwrap().0.acc;
    eprintln!(
        "before {:.2}/{:.2}, prior {:.2}/{:.2}, unbounded {:.2}/{:.2}",
        before.max_um(),
        before.max_arcsec(),
        prior.max_um(),
        prior.max_arcsec(),
        unbounded.max_um(),
        unbounded.max_arcsec()
    );
    assert!(prior.max_um() < 0.5 * before.max_um() && prior.max_arcsec() < before.max_arcsec());
    assert!(unbounded.max_um() > prior.max_um() && unbounded.max_arcsec() > prior.max_arcsec());
}

#[test]
fn freeing_the_balls_and_registration_only_removes_information() {
    let (setup, c) = small_campaign(TrackerNoise::CLASS_15_6, 60);
    let data = c.data(&PROTOTYPE, &setup).expect("data");
    let fit = bundle::fit(&data, &BundleConfig::with_priors(0.1, 0.1)).expect("fit");
    let obs = bundle::observability(&data, &fit.x, 0.1, 6).expect("observability");
    // Weyl: the marginal information is below the full one in the Loewner order, so
    // every sorted singular value is.
    for (f, k) in obs.singular_free.iter().zip(&obs.singular_known) {
        assert!(*f <= *k * (1.0 + 1e-9) + 1e-12, "{f} > {k}");
    }
    for (kept, d) in &obs.hidden {
        assert!(*kept < 1.0 && d.singular_free <= d.singular_known * (1.0 + 1e-9));
    }
    // The weakest directions are the per-leg common shifts of a_i and b_i (their effect on
    // the strokes is only through R - I).
    let v = &obs.weakest[0].vector;
    let common: f64 = (0..6)
        .flat_map(|leg| (0..3).map(move |a| (leg, a)))
        .map(|(leg, a)| ((v[leg * 6 + a] + v[leg * 6 + 3 + a]) / 2f64.sqrt()).powi(2))
        .sum();
    assert!(common > 0.95, "{common}");
    assert!(obs.weakest[0].singular_free < 0.01);
}

#[test]
fn a_plan_of_40_corners_predicts_better_than_the_papers_120_poses() {
    use m2calib::calib::design::{self, Criterion};
    use m2calib::tracker::campaign::nominal_data;
    let setup = TrackerSetup::default();
    let priors = Priors {
        joint_sigma_mm: Some(0.1),
        ball_sigma_mm: Some(0.1),
    };
    let eval = random_poses(60, 1.0, 60.0, 4242);
    // The 64 corners of the +-1 mm, +-60" box as candidates (the full 729-pose grid is
    // the command's).
    let corners: Vec<Pose<f64>> = design::grid_candidates(1.0, 60.0)
        .into_iter()
        .filter(|p| p.translation_mm.iter().all(|v| v.abs() > 0.5))
        .filter(|p| p.rotation_arcsec().iter().all(|v| v.abs() > 30.0))
        .collect();
    assert_eq!(corners.len(), 64);
    let dp = design::problem(
        &nominal_data(&PROTOTYPE, &setup, &corners).unwrap(),
        priors,
        &eval,
    )
    .unwrap();
    let paper = plan_poses(&PlanConfig::default());
    let pp = design::problem(
        &nominal_data(&PROTOTYPE, &setup, &paper).unwrap(),
        priors,
        &eval,
    )
    .unwrap();
    let all: Vec<usize> = (0..paper.len()).collect();
    let paper_var = pp.mean_variance(&all).unwrap();
    for crit in [Criterion::D, Criterion::I] {
        let sel = dp.select(crit, 40);
        let mut uniq = sel.clone();
        uniq.sort();
        uniq.dedup();
        assert_eq!(uniq.len(), 40, "each candidate at most once");
        let var = dp.mean_variance(&sel).unwrap();
        // Greedy + exchange beats the first 40 candidates on its own criterion.
        let first: Vec<usize> = (0..40).collect();
        assert!(dp.value(crit, &sel).unwrap() >= dp.value(crit, &first).unwrap());
        eprintln!(
            "{}: 40 corners {var:.3} vs paper 120 {paper_var:.3} (um^2 + arcsec^2)",
            crit.name()
        );
        assert!(var < paper_var, "{}: {var} vs {paper_var}", crit.name());
    }
}

#[test]
fn calibrate_command_on_tracker_files_writes_a_validated_table() {
    use m2calib::tracker::commands::{
        run_point_calibrate, run_simulate, PointCalibrateArgs, SimulateArgs, SIMULATED_FILES,
    };
    use m2calib::tracker::study::TruthModel;
    let dir = std::env::temp_dir().join(format!("m2ctl-tracker-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let files = run_simulate(&SimulateArgs {
        nominal: PROTOTYPE,
        truth: TruthModel::Gaussian { sigma_mm: 0.1 },
        setup: TrackerSetup::default(),
        plan: plan_poses(&PlanConfig::default()),
        campaign: 2,
    })
    .unwrap();
    for (n, t) in SIMULATED_FILES.iter().zip(&files) {
        std::fs::write(dir.join(n), t).unwrap();
    }
    let nominal = dir.join("nominal.toml");
    std::fs::write(
        &nominal,
        std::fs::read_to_string(concat!(
            concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
            "/testdata/geometry.toml"
        ))
        .unwrap(),
    )
    .unwrap();
    let args = PointCalibrateArgs {
        points: dir.join("points.csv"),
        strokes: dir.join("strokes.csv"),
        targets: dir.join("targets.toml"),
        nominal,
        export: m2calib::tracker::exports::ExportOptions::default(),
        noise: TrackerNoise::CLASS_15_6,
        adjust: m2calib::calib::adjust::AdjustConfig::estimated(0.1),
        report: true,
        truth: Some(dir.join("truth.toml")),
        plot: None,
        residual_plot: Some(dir.join("residuals.svg")),
    };
    let (text, summary) = run_point_calibrate(&args).expect("calibrate");
    let back = m2calib::files::parse_geometry(&text).expect("parses");
    m2calib::files::validate_for_flight(&back.params).expect("flight validation");
    for what in [
        "registration",
        "ball centres",
        "observability",
        "predicted accuracy",
        "held-out accuracy",
        "global test",
        "outlier test",
        "variance factor",
        "joints' spread, posterior",
        "without it",
    ] {
        assert!(summary.contains(what), "{what}: {summary}");
    }
    // A malformed export is refused with its path and line.
    let p = files[1].replacen("base,F2,", "base,F2,x", 1);
    std::fs::write(dir.join("points.csv"), &p).unwrap();
    let e = run_point_calibrate(&args).unwrap_err();
    assert!(
        e.contains("points.csv: line") && e.contains("not a number"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
