//! A simulated calibration campaign with the realistic laser tracker: the true
//! mechanism (nominal + manufacturing errors), the true ball and fiducial positions
//! (nominal / drawing + mounting errors), a tracker 2-3 m away with its anisotropic
//! noise; every plan pose commanded with the nominal parameters, the balls measured, the
//! strokes read (exact: the encoders' 0.1 um is far below the tracker's noise). The
//! output is what the calibration team gets: a point export and a stroke file.

use rand::SeedableRng;
use rand_pcg::Pcg64;

use super::files::{PointPose, PointRecord, StrokeRecord, TargetFile};
use super::{bundle_data, TrackerDataError};
use crate::calib::bundle::BundleData;
use m2ctl::kinematics::{ik, Geometry, GeometryParams, Pose};
use m2ctl::sim::manufacturing::perturbed;
use m2ctl::sim::tracker::{
    scatter_points, true_motion, LaserTracker, TrackerNoise, TrackerPlacement, TrackerScene,
    ISOTROPIC_15_UM,
};

/// Named tracker noise presets of the command line.
pub const NOISE_PRESETS: [&str; 4] = ["class15+6", "iso15", "paper", "perfect"];

/// The noise of a preset name (see [`NOISE_PRESETS`]): `class15+6` the +-(15 um + 6
/// um/m) class ([`TrackerNoise::CLASS_15_6`]), `iso15` an isotropic 15 um (the issue's
/// independent simulation), `paper` the 0.07 um that gives the paper's ~0.1 arcsec per
/// pose, `perfect` none.
pub fn noise_preset(name: &str) -> Option<TrackerNoise> {
    match name {
        "class15+6" => Some(TrackerNoise::CLASS_15_6),
        "iso15" => Some(TrackerNoise::isotropic(ISOTROPIC_15_UM)),
        "paper" => Some(TrackerNoise::PAPER),
        "perfect" => Some(TrackerNoise::PERFECT),
        _ => None,
    }
}

/// What the campaign is made of, besides the mechanism.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackerSetup {
    /// Target balls and fiducials (nominal, with tolerances).
    pub targets: TargetFile,
    /// The tracker's noise (the simulation draws with it; the ground weights with it).
    pub noise: TrackerNoise,
    /// Where the tracker stands.
    pub placement: TrackerPlacement,
}

impl Default for TrackerSetup {
    fn default() -> Self {
        Self {
            targets: TargetFile::default(),
            noise: TrackerNoise::CLASS_15_6,
            placement: TrackerPlacement::default(),
        }
    }
}

/// Seeds of one simulated campaign.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CampaignSeeds {
    /// True joint geometry.
    pub geometry: u64,
    /// True ball and fiducial positions.
    pub scene: u64,
    /// Tracker noise.
    pub noise: u64,
}

impl CampaignSeeds {
    /// Seeds derived from one number (campaign `k` of a study).
    pub fn from_one(k: u64) -> Self {
        Self {
            geometry: k,
            scene: k.wrapping_mul(0x9e37_79b9).wrapping_add(17),
            noise: k.wrapping_mul(0x85eb_ca6b).wrapping_add(29),
        }
    }
}

/// Offset between the seeds of the ball and of the fiducial scatter.
const FIDUCIAL_SEED_OFFSET: u64 = 0x0f1d;

/// The true scene: the tracker at `setup.placement`, balls and fiducials scattered about
/// their nominal / drawing centres by the target file's tolerances.
pub fn scene(setup: &TrackerSetup, seed: u64) -> TrackerScene {
    TrackerScene {
        tracker: LaserTracker::new(setup.noise, &setup.placement),
        balls_m: scatter_points(&setup.targets.balls, setup.targets.ball_sigma_mm, seed),
        fiducials_b: scatter_points(
            &setup.targets.fiducials,
            setup.targets.fiducial_sigma_mm,
            seed.wrapping_add(FIDUCIAL_SEED_OFFSET),
        ),
    }
}

/// A simulated campaign: what the ground gets, and the truth behind it.
#[derive(Clone, Debug, PartialEq)]
pub struct SimulatedCampaign {
    /// True joint geometry.
    pub truth: GeometryParams,
    /// True scene (tracker, balls, fiducials).
    pub scene: TrackerScene,
    /// The point export (fiducials first, then pose 1, 2, ...).
    pub points: Vec<PointRecord>,
    /// The strokes of each pose.
    pub strokes: Vec<StrokeRecord>,
    /// True pose reached at each plan pose.
    pub true_poses: Vec<Pose<f64>>,
}

/// Measures the fiducials and the balls at each of `true_poses` (pose numbers 1..).
pub fn measure(
    scene: &TrackerScene,
    p0_mm: &[f64; 3],
    true_poses: &[Pose<f64>],
    rng: &mut Pcg64,
) -> Vec<PointRecord> {
    let record = |pose: PointPose, (name, y_mm): (String, [f64; 3])| PointRecord {
        line: 0,
        pose,
        name,
        y_mm,
        sigma_mm: None,
    };
    let mut points: Vec<PointRecord> = scene
        .measure_fiducials(rng)
        .into_iter()
        .map(|m| record(PointPose::Base, m))
        .collect();
    for (k, p) in true_poses.iter().enumerate() {
        let pose = PointPose::Pose(k as u32 + 1);
        points.extend(
            scene
                .measure_balls(p0_mm, p, rng)
                .into_iter()
                .map(|m| record(pose, m)),
        );
    }
    points
}

/// Simulates a campaign: true geometry `nominal + N(0, joint_sigma_mm)` (seed
/// `seeds.geometry`), the scene (seed `seeds.scene`), each plan pose commanded with
/// `IK(pose, nominal)`, the true pose reached, the balls measured (seed `seeds.noise`).
pub fn simulate(
    nominal: &GeometryParams,
    joint_sigma_mm: f64,
    setup: &TrackerSetup,
    plan: &[Pose<f64>],
    seeds: CampaignSeeds,
) -> Result<SimulatedCampaign, String> {
    let truth = perturbed(nominal, joint_sigma_mm, seeds.geometry);
    simulate_with_truth(nominal, &truth, setup, plan, seeds)
}

/// The stroke record of pose `k` (0-based) of a plan, numbered `k + 1`: the strokes the
/// `nominal` geometry commands for `pose` (mm); an error names it as `what` `k + 1`.
fn nominal_strokes(
    nominal: &Geometry<f64>,
    k: usize,
    pose: &Pose<f64>,
    what: &str,
) -> Result<StrokeRecord, String> {
    let s = ik(nominal, pose)
        .map_err(|e| format!("{what} {}: {}", k + 1, crate::ikfk::describe_ik_error(&e)))?;
    Ok(StrokeRecord {
        line: 0,
        pose: k as u32 + 1,
        strokes_mm: s,
    })
}

/// [`simulate`] with a given true geometry.
pub fn simulate_with_truth(
    nominal: &GeometryParams,
    truth: &GeometryParams,
    setup: &TrackerSetup,
    plan: &[Pose<f64>],
    seeds: CampaignSeeds,
) -> Result<SimulatedCampaign, String> {
    let describe = |e| crate::files::describe_geometry_error(&e);
    let nom = Geometry::<f64>::new(nominal).map_err(describe)?;
    let tru = Geometry::<f64>::new(truth).map_err(describe)?;
    let scene = scene(setup, seeds.scene);
    let mut strokes = Vec::with_capacity(plan.len());
    let mut true_poses = Vec::with_capacity(plan.len());
    for (k, target) in plan.iter().enumerate() {
        let rec = nominal_strokes(&nom, k, target, "plan pose")?;
        let reached = true_motion(&tru, &rec.strokes_mm, target).map_err(|e| {
            format!(
                "plan pose {}: true mechanism: {}",
                k + 1,
                crate::ikfk::describe_fk_error(&e)
            )
        })?;
        strokes.push(rec);
        true_poses.push(reached);
    }
    let mut rng = Pcg64::seed_from_u64(seeds.noise);
    let points = measure(&scene, &nominal.p0_mm, &true_poses, &mut rng);
    Ok(SimulatedCampaign {
        truth: *truth,
        scene,
        points,
        strokes,
        true_poses,
    })
}

impl SimulatedCampaign {
    /// The bundle's observations, weighted with `setup`'s noise model.
    pub fn data(
        &self,
        nominal: &GeometryParams,
        setup: &TrackerSetup,
    ) -> Result<BundleData, TrackerDataError> {
        bundle_data(
            &setup.targets,
            &self.points,
            &self.strokes,
            nominal,
            &setup.noise,
        )
    }
}

/// Noise-free predicted measurements of `poses` on the nominal mechanism with the nominal
/// balls and fiducials, weighted with `setup`'s noise model: the information a plan
/// would collect (see [`crate::calib::design`]).
pub fn nominal_data(
    nominal: &GeometryParams,
    setup: &TrackerSetup,
    poses: &[Pose<f64>],
) -> Result<BundleData, String> {
    let nom =
        Geometry::<f64>::new(nominal).map_err(|e| crate::files::describe_geometry_error(&e))?;
    let scene = TrackerScene {
        tracker: LaserTracker::new(TrackerNoise::PERFECT, &setup.placement),
        balls_m: setup.targets.balls.clone(),
        fiducials_b: setup.targets.fiducials.clone(),
    };
    let mut strokes = Vec::with_capacity(poses.len());
    for (k, p) in poses.iter().enumerate() {
        strokes.push(nominal_strokes(&nom, k, p, "candidate pose")?);
    }
    let mut rng = Pcg64::seed_from_u64(0);
    let points = measure(&scene, &nominal.p0_mm, poses, &mut rng);
    bundle_data(&setup.targets, &points, &strokes, nominal, &setup.noise).map_err(|e| e.to_string())
}
