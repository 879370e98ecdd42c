//! Calibration from laser-tracker points: registration, the bundle fit, uncertainty.

use m2ctl::ground::calib::bundle::{self, Bundle, BundleConfig, Priors};
use m2ctl::ground::calib::registration::{kabsch, pose_from_balls};
use m2ctl::ground::eval::{accuracy, random_poses};
use m2ctl::ground::plan::{plan_poses, PlanConfig};
use m2ctl::ground::tracker::campaign::{simulate, CampaignSeeds, TrackerSetup};
use m2ctl::kinematics::Pose;
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::tracker::{rotation_matrix, TrackerNoise, TrackerPlacement};
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
) -> (
    TrackerSetup,
    m2ctl::ground::tracker::campaign::SimulatedCampaign,
) {
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
