//! The laser tracker at work in a mission (the demo's hook): the simulated instrument on
//! one side, the ground's use of it on the other.
//!
//! 1. [`TrackerSession::survey_home`]: the base fiducials (registration by Kabsch) and
//!    the balls at home (zero strokes: the home pose by definition) give the ground its
//!    first ball centres, enough to measure poses before any calibration.
//! 2. [`TrackerSession::measure_pose`]: the balls of a pose, fitted to the known centres.
//! 3. [`TrackerSession::record`]: a calibration pose's balls and its encoder strokes
//!    (from housekeeping) into the point export and the stroke file.
//! 4. [`TrackerSession::calibrate`]: the export written as text, read back by the same
//!    parsers as `m2ground calibrate --points`, the bundle fit; from then on poses are
//!    measured with the fitted ball centres and registration.

use nalgebra::{Isometry3, Point3};
use rand::SeedableRng;
use rand_pcg::Pcg64;

use super::campaign::{scene, TrackerSetup};
use super::files::{
    format_export, format_strokes, format_targets, parse_export, parse_strokes, parse_targets,
    PointPose, PointRecord, StrokeRecord,
};
use crate::calib::bundle::{self, BundleConfig, BundleFit};
use crate::calib::registration::{kabsch, pose_from_balls};
use m2ctl::kinematics::{GeometryParams, Pose, LEGS};
use m2ctl::sim::tracker::TrackerScene;

/// Offset between the mission seed and the seed of the tracker's noise.
const NOISE_SEED_OFFSET: u64 = 0x7a46_e75a;

/// How the ground turns measured balls into a pose.
#[derive(Clone, Debug, PartialEq)]
struct Knowledge {
    /// Ball centres in frame M (mm), in target-file order.
    balls_m: Vec<[f64; 3]>,
    /// Base -> tracker transform.
    registration: Isometry3<f64>,
}

/// A tracker campaign in progress.
#[derive(Clone, Debug)]
pub struct TrackerSession {
    setup: TrackerSetup,
    scene: TrackerScene,
    p0_mm: [f64; 3],
    rng: Pcg64,
    points: Vec<PointRecord>,
    strokes: Vec<StrokeRecord>,
    knowledge: Option<Knowledge>,
    fit: Option<BundleFit>,
}

impl TrackerSession {
    /// A session: the true scene (balls and fiducials scattered about their nominal
    /// positions, the tracker placed) drawn from `seed`, home position `p0_mm`.
    pub fn new(setup: &TrackerSetup, p0_mm: &[f64; 3], seed: u64) -> Self {
        Self {
            setup: setup.clone(),
            scene: scene(setup, seed),
            p0_mm: *p0_mm,
            rng: Pcg64::seed_from_u64(seed ^ NOISE_SEED_OFFSET),
            points: Vec::new(),
            strokes: Vec::new(),
            knowledge: None,
            fit: None,
        }
    }

    /// Measures the fiducials (kept for the export) and the balls at the true home pose
    /// `true_home` (the mechanism at zero strokes): registration from the fiducials'
    /// drawing positions, ball centres `c = T^-1 y - p0`.
    pub fn survey_home(&mut self, true_home: &Pose<f64>) -> Result<(), String> {
        let fid = self.scene.measure_fiducials(&mut self.rng);
        let mut from = Vec::new();
        let mut to = Vec::new();
        for (name, y) in &fid {
            let def = self
                .setup
                .targets
                .fiducials
                .iter()
                .find(|f| f.name == *name)
                .ok_or_else(|| format!("fiducial {name} not in the target file"))?;
            from.push(def.mm);
            to.push(*y);
            self.points.push(PointRecord {
                line: 0,
                pose: PointPose::Base,
                name: name.clone(),
                y_mm: *y,
                sigma_mm: None,
            });
        }
        let registration =
            kabsch(&from, &to, None).map_err(|e| format!("fiducial registration: {e}"))?;
        let inv = registration.inverse();
        let balls = self
            .scene
            .measure_balls(&self.p0_mm, true_home, &mut self.rng);
        let mut balls_m = Vec::new();
        for b in &self.setup.targets.balls {
            let (_, y) = balls
                .iter()
                .find(|(n, _)| *n == b.name)
                .ok_or_else(|| format!("ball {} not measured", b.name))?;
            let x = inv * Point3::from(*y);
            balls_m.push([
                x.x - self.p0_mm[0],
                x.y - self.p0_mm[1],
                x.z - self.p0_mm[2],
            ]);
        }
        self.knowledge = Some(Knowledge {
            balls_m,
            registration,
        });
        Ok(())
    }

    /// Measures the balls at the true pose `truth` and returns the pose the ground
    /// derives from them (home survey before calibration, the fit after).
    pub fn measure_pose(&mut self, truth: &Pose<f64>) -> Result<Pose<f64>, String> {
        let k = self.knowledge.as_ref().ok_or("no home survey yet")?;
        let inv = k.registration.inverse();
        let measured = self.scene.measure_balls(&self.p0_mm, truth, &mut self.rng);
        let mut m = Vec::new();
        let mut b = Vec::new();
        for (name, y) in &measured {
            if let Some(i) = self
                .setup
                .targets
                .balls
                .iter()
                .position(|t| t.name == *name)
            {
                let x = inv * Point3::from(*y);
                m.push(k.balls_m[i]);
                b.push([x.x, x.y, x.z]);
            }
        }
        pose_from_balls(&m, &b, None, &self.p0_mm).map_err(|e| format!("pose from the balls: {e}"))
    }

    /// Records a calibration pose: its balls at the true pose `truth` into the export and
    /// the encoder strokes read there. Returns the pose number.
    pub fn record(&mut self, truth: &Pose<f64>, strokes_mm: [f64; LEGS]) -> u32 {
        let pose = self.strokes.len() as u32 + 1;
        let measured = self.scene.measure_balls(&self.p0_mm, truth, &mut self.rng);
        for (name, y_mm) in measured {
            self.points.push(PointRecord {
                line: 0,
                pose: PointPose::Pose(pose),
                name,
                y_mm,
                sigma_mm: None,
            });
        }
        self.strokes.push(StrokeRecord {
            line: 0,
            pose,
            strokes_mm,
        });
        pose
    }

    /// Calibration poses recorded.
    pub fn poses(&self) -> usize {
        self.strokes.len()
    }

    /// The three files of the campaign as text: (targets.toml, points.csv, strokes.csv).
    pub fn export(&self) -> [String; 3] {
        [
            format_targets(
                &self.setup.targets,
                "Target balls and fiducials of the mission",
            ),
            format_export(
                &self.points,
                "Mission calibration campaign: tracker point export, tracker frame (mm)",
            ),
            format_strokes(
                &self.strokes,
                "Mission calibration campaign: encoder strokes from housekeeping (mm)",
            ),
        ]
    }

    /// Writes the export, reads it back with the file parsers and runs the bundle fit;
    /// poses are measured with its ball centres and registration from then on.
    pub fn calibrate(
        &mut self,
        nominal: &GeometryParams,
        cfg: &BundleConfig,
    ) -> Result<&BundleFit, String> {
        let [t, p, s] = self.export();
        let targets = parse_targets(&t).map_err(|e| format!("targets: {e}"))?;
        let points = parse_export(&p).map_err(|e| format!("point export: {e}"))?;
        let strokes = parse_strokes(&s).map_err(|e| format!("strokes: {e}"))?;
        let data = super::bundle_data(&targets, &points, &strokes, nominal, &self.setup.noise)
            .map_err(|e| format!("tracker data: {e}"))?;
        let fit = bundle::fit(&data, cfg).map_err(|e| format!("bundle fit: {e}"))?;
        self.knowledge = Some(Knowledge {
            balls_m: fit.balls_m.clone(),
            registration: fit.registration,
        });
        Ok(self.fit.insert(fit))
    }

    /// The fit, once [`TrackerSession::calibrate`] ran.
    pub fn fit(&self) -> Option<&BundleFit> {
        self.fit.as_ref()
    }

    /// 1-sigma noise of one pose measurement at home with the current knowledge
    /// (um x3, arcsec x3).
    pub fn pose_noise_sigma(&self) -> Option<[f64; 6]> {
        let k = self.knowledge.as_ref()?;
        let noise = self.setup.noise;
        bundle::pose_measurement_sigma(
            &k.balls_m,
            &k.registration,
            &self.p0_mm,
            &Pose::home(),
            &|y| noise.covariance_mm2(y),
        )
    }

    /// What the tracker can tell after calibration: the fit's predicted accuracy of the
    /// calibrated table at `targets` (its covariance propagated) against the noise of one
    /// tracker pose measurement, so that a tracker-measured error can be read.
    pub fn verification_note(&self, targets: &[Pose<f64>]) -> String {
        let (Some(f), Some(n)) = (&self.fit, self.pose_noise_sigma()) else {
            return "not calibrated".into();
        };
        let rms3 = super::study::rms3;
        match bundle::predict_accuracy(&f.params, &f.joint_covariance(), targets, bundle::DEFAULT_MC_DRAWS, 1) {
            Ok(p) => format!(
                "predicted accuracy of the calibrated table at these targets (fit covariance): RMS {:.3} um / {:.3} arcsec, expected max {:.3} um / {:.3} arcsec; one tracker pose measurement: 1 sigma {:.3} um / {:.3} arcsec (RMS of the axes), so errors measured below ~3 sigma of that are the tracker's own",
                rms3(&p.rms_sigma[..3]),
                rms3(&p.rms_sigma[3..]),
                p.expected_max_combined[0],
                p.expected_max_combined[1],
                rms3(&n[..3]),
                rms3(&n[3..])
            ),
            Err(e) => format!("no prediction: {e}"),
        }
    }

    /// One line on the fit for the mission's narrative.
    pub fn summary(&self) -> String {
        match &self.fit {
            None => "not calibrated".into(),
            Some(f) => format!(
                "bundle fit of {} joints, {} ball centres and the registration from {} poses x {} balls + {} fiducials: normalised residual RMS {:.3} -> {:.3}, ball residual {:.3} um RMS, {} evaluations, {:.0} ms",
                crate::calib::N_PARAMS,
                f.balls_m.len(),
                self.strokes.len(),
                f.balls_m.len(),
                self.setup.targets.fiducials.len(),
                f.start_rms,
                f.normalised_rms(),
                f.ball_residual_rms_um,
                f.evaluations,
                f.elapsed.as_secs_f64() * 1e3
            ),
        }
    }
}
