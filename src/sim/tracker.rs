//! Simulated measuring instruments of a calibration campaign (host only).
//!
//! * [`true_motion`]: where the true mechanism goes for a set of strokes (FK with the
//!   true parameters): what any instrument observes.
//! * [`PoseTracker`]: the idealised instrument of the paper's simulation, Gaussian noise
//!   directly on the six pose components, as if the mirror's pose were measured in the
//!   base frame. The pose-based calibration path uses it.
//! * [`LaserTracker`]: what a laser tracker really measures, the centres of target balls
//!   (SMRs) in its own frame, with an anisotropic noise model: a range error along the line
//!   of sight and a transverse (angle-encoder) error that grows with distance
//!   ([`TrackerNoise`]). [`TrackerScene`] places the tracker, the balls on the moving
//!   platform and the fiducial nests on the base with their true (unknown to the ground)
//!   positions.
//!
//! Frames: B (base), M (moving platform) as in the kinematics; T, the tracker's own frame
//! (origin at the tracker head, z up), in which the instrument reports points. All
//! lengths in mm.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

use crate::kinematics::{fk, FkConfig, FkError, Geometry, Pose};
use crate::units::{ARCSEC_PER_RAD, MM_PER_M, MM_PER_UM};

/// Moves the true mechanism: the pose it reaches for `strokes_mm` (FK with the true
/// parameters, warm-started at `near`).
pub fn true_motion(
    truth: &Geometry<f64>,
    strokes_mm: &[f64; 6],
    near: &Pose<f64>,
) -> Result<Pose<f64>, FkError> {
    fk(truth, strokes_mm, near, &FkConfig::default()).map(|s| s.pose)
}

// ---------------------------------------------------------------------------------------
// The idealised pose tracker
// ---------------------------------------------------------------------------------------

/// The paper's simulation noise on the measured translation (um, per axis).
pub const PAPER_NOISE_UM: f64 = 0.1;
/// The paper's simulation noise on the measured rotation (arcsec, per axis).
pub const PAPER_NOISE_ARCSEC: f64 = 0.1;
/// A realistic pose noise on the translation (um, per axis), for the idealised path.
pub const REALISTIC_NOISE_UM: f64 = 5.0;
/// A realistic pose noise on the rotation (arcsec, per axis), for the idealised path.
pub const REALISTIC_NOISE_ARCSEC: f64 = 1.0;

/// The idealised tracker: independent Gaussian noise on each component of the pose,
/// measured directly in the base frame (no registration, no target balls).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseTracker {
    /// Standard deviation of the measured x, y, z (um).
    pub noise_um: f64,
    /// Standard deviation of the measured alpha, beta, gamma (arcsec).
    pub noise_arcsec: f64,
}

impl PoseTracker {
    /// The paper's simulation noise (0.1 um, 0.1 arcsec).
    pub const PAPER: PoseTracker = PoseTracker {
        noise_um: PAPER_NOISE_UM,
        noise_arcsec: PAPER_NOISE_ARCSEC,
    };
    /// A realistic pose noise (5 um, 1 arcsec).
    pub const REALISTIC: PoseTracker = PoseTracker {
        noise_um: REALISTIC_NOISE_UM,
        noise_arcsec: REALISTIC_NOISE_ARCSEC,
    };
    /// A noise-free tracker.
    pub const PERFECT: PoseTracker = PoseTracker {
        noise_um: 0.0,
        noise_arcsec: 0.0,
    };

    /// The measured pose of a true pose.
    pub fn measure(&self, truth: &Pose<f64>, rng: &mut Pcg64) -> Pose<f64> {
        let mut p = *truth;
        if let Ok(n) = Normal::new(0.0, self.noise_um * MM_PER_UM) {
            for t in p.translation_mm.iter_mut() {
                *t += n.sample(rng);
            }
        }
        if let Ok(n) = Normal::new(0.0, self.noise_arcsec / ARCSEC_PER_RAD) {
            for r in p.rotation_rad.iter_mut() {
                *r += n.sample(rng);
            }
        }
        p
    }
}

// ---------------------------------------------------------------------------------------
// The laser tracker
// ---------------------------------------------------------------------------------------

/// Noise of one laser-tracker point measurement, as standard deviations (1 sigma) that
/// grow linearly with the range `d`: along the line of sight
/// `range_um + range_um_per_m * d` (the distance meter), across it, per transverse
/// component, `transverse_um + transverse_um_per_m * d` (the angle encoders: um per m of
/// range is urad). Errors of different points are independent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackerNoise {
    /// Range error at zero distance (um, 1 sigma).
    pub range_um: f64,
    /// Range error growth (um per m of range).
    pub range_um_per_m: f64,
    /// Transverse error at zero distance, per component (um, 1 sigma).
    pub transverse_um: f64,
    /// Transverse error growth (um per m = urad).
    pub transverse_um_per_m: f64,
}

/// Coverage factor of a maximum permissible error (MPE): the MPE is read as a 2 sigma
/// bound.
pub const MPE_COVERAGE_SIGMAS: f64 = 2.0;
/// The +-(15 um + 6 um/m) tracker class: MPE of a point coordinate, constant part (um).
pub const CLASS_MPE_UM: f64 = 15.0;
/// ... and its growth with distance (um per m).
pub const CLASS_MPE_UM_PER_M: f64 = 6.0;
/// MPE of that class's absolute distance meter (um), constant over the range.
pub const CLASS_ADM_MPE_UM: f64 = 10.0;
/// ... and the interferometer's growth with distance (um per m, MPE).
pub const CLASS_ADM_MPE_UM_PER_M: f64 = 0.4;
/// The independent simulation: an isotropic 15 um per coordinate (1 sigma).
pub const ISOTROPIC_15_UM: f64 = 15.0;
/// Point noise that gives the paper's ~0.1 arcsec per pose axis with four balls 100 mm
/// from the centre (isotropic, um, 1 sigma).
pub const PAPER_POINT_NOISE_UM: f64 = 0.07;

impl TrackerNoise {
    /// The +-(15 um + 6 um/m) class (e.g. a Leica AT960 in its data sheet): transverse
    /// sigma = MPE / 2 = 7.5 um + 3 um/m, range sigma = ADM MPE / 2 = 5 um + 0.2 um/m. At
    /// 2.5 m: 15 um across the line of sight, 5.5 um along it.
    pub const CLASS_15_6: TrackerNoise = TrackerNoise {
        range_um: CLASS_ADM_MPE_UM / MPE_COVERAGE_SIGMAS,
        range_um_per_m: CLASS_ADM_MPE_UM_PER_M / MPE_COVERAGE_SIGMAS,
        transverse_um: CLASS_MPE_UM / MPE_COVERAGE_SIGMAS,
        transverse_um_per_m: CLASS_MPE_UM_PER_M / MPE_COVERAGE_SIGMAS,
    };
    /// Isotropic, distance-independent noise of `sigma_um` per coordinate.
    pub const fn isotropic(sigma_um: f64) -> TrackerNoise {
        TrackerNoise {
            range_um: sigma_um,
            range_um_per_m: 0.0,
            transverse_um: sigma_um,
            transverse_um_per_m: 0.0,
        }
    }
    /// No noise.
    pub const PERFECT: TrackerNoise = TrackerNoise::isotropic(0.0);
    /// The paper's simulation: [`PAPER_POINT_NOISE_UM`] per coordinate, isotropic.
    pub const PAPER: TrackerNoise = TrackerNoise::isotropic(PAPER_POINT_NOISE_UM);

    /// Every sigma multiplied by `k` (0.1: a tracker ten times better).
    pub fn scaled(&self, k: f64) -> TrackerNoise {
        TrackerNoise {
            range_um: self.range_um * k,
            range_um_per_m: self.range_um_per_m * k,
            transverse_um: self.transverse_um * k,
            transverse_um_per_m: self.transverse_um_per_m * k,
        }
    }

    /// `(range, transverse)` sigmas (mm) at a range of `range_mm`.
    pub fn sigmas_mm(&self, range_mm: f64) -> (f64, f64) {
        let d_m = range_mm / MM_PER_M;
        (
            (self.range_um + self.range_um_per_m * d_m) * MM_PER_UM,
            (self.transverse_um + self.transverse_um_per_m * d_m) * MM_PER_UM,
        )
    }

    /// Covariance (mm^2) of a point measured at `y_mm` in the tracker frame (the tracker
    /// at the origin): `s_r^2 u u^T + s_t^2 (I - u u^T)`, `u` the line of sight.
    pub fn covariance_mm2(&self, y_mm: &[f64; 3]) -> Matrix3<f64> {
        let y = Vector3::from(*y_mm);
        let d = y.norm();
        let (sr, st) = self.sigmas_mm(d);
        if d.is_nan() || d <= 0.0 {
            return Matrix3::identity() * sr.max(st).powi(2);
        }
        let u = y / d;
        let uu = u * u.transpose();
        uu * (sr * sr) + (Matrix3::identity() - uu) * (st * st)
    }

    /// Short description for reports.
    pub fn describe(&self) -> String {
        format!(
            "range {} um + {} um/m, transverse {} um + {} um/m (1 sigma)",
            self.range_um, self.range_um_per_m, self.transverse_um, self.transverse_um_per_m
        )
    }
}

/// Two unit vectors completing `u` (unit) to a right-handed orthonormal basis.
pub fn transverse_basis(u: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if u.z.abs() < 0.9 {
        Vector3::z()
    } else {
        Vector3::x()
    };
    let e1 = u.cross(&helper).normalize();
    let e2 = u.cross(&e1);
    (e1, e2)
}

/// A laser tracker standing somewhere near the mechanism.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaserTracker {
    /// Its noise model.
    pub noise: TrackerNoise,
    /// The true transform from base-frame to tracker-frame coordinates (`y = T x`).
    pub base_to_tracker: Isometry3<f64>,
}

/// Where the tracker stands (all relative to the base frame B).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackerPlacement {
    /// Horizontal distance from B's origin (mm).
    pub distance_mm: f64,
    /// Azimuth of the tracker seen from B's origin, from B's x axis (rad).
    pub azimuth_rad: f64,
    /// Height of the tracker head above B's origin (mm).
    pub height_mm: f64,
    /// Heading of the tracker frame's x axis about B's z (rad): arbitrary, the
    /// instrument's zero.
    pub heading_rad: f64,
    /// Levelling error: tilt of the tracker's z about its x axis (rad).
    pub tilt_rad: f64,
}

/// Default tracker distance (mm): the 2.5 m.
pub const DEFAULT_TRACKER_DISTANCE_MM: f64 = 2500.0;
/// Default tracker azimuth (deg).
pub const DEFAULT_TRACKER_AZIMUTH_DEG: f64 = 30.0;
/// Default tracker head height above B's origin (mm): looking slightly down.
pub const DEFAULT_TRACKER_HEIGHT_MM: f64 = 300.0;
/// Default heading of the tracker's frame (deg): any value; not a round one.
pub const DEFAULT_TRACKER_HEADING_DEG: f64 = 123.4;
/// Default levelling error (arcsec).
pub const DEFAULT_TRACKER_TILT_ARCSEC: f64 = 5.0;

impl Default for TrackerPlacement {
    fn default() -> Self {
        Self {
            distance_mm: DEFAULT_TRACKER_DISTANCE_MM,
            azimuth_rad: DEFAULT_TRACKER_AZIMUTH_DEG.to_radians(),
            height_mm: DEFAULT_TRACKER_HEIGHT_MM,
            heading_rad: DEFAULT_TRACKER_HEADING_DEG.to_radians(),
            tilt_rad: DEFAULT_TRACKER_TILT_ARCSEC / ARCSEC_PER_RAD,
        }
    }
}

impl TrackerPlacement {
    /// The base-to-tracker transform: the tracker head at
    /// `(d cos az, d sin az, h)` in B, its axes `Rz(heading) Rx(tilt)` in B.
    pub fn base_to_tracker(&self) -> Isometry3<f64> {
        let centre = Vector3::new(
            self.distance_mm * self.azimuth_rad.cos(),
            self.distance_mm * self.azimuth_rad.sin(),
            self.height_mm,
        );
        let axes = Rotation3::from_axis_angle(&Vector3::z_axis(), self.heading_rad)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), self.tilt_rad);
        let inv = axes.inverse();
        Isometry3::from_parts(
            Translation3::from(-(inv * centre)),
            UnitQuaternion::from_rotation_matrix(&inv),
        )
    }
}

impl LaserTracker {
    /// A tracker with `noise` placed at `placement`.
    pub fn new(noise: TrackerNoise, placement: &TrackerPlacement) -> Self {
        Self {
            noise,
            base_to_tracker: placement.base_to_tracker(),
        }
    }

    /// The noise-free tracker-frame coordinates of a point given in B (mm).
    pub fn to_tracker(&self, x_b_mm: &[f64; 3]) -> [f64; 3] {
        let y = self.base_to_tracker * Point3::from(*x_b_mm);
        [y.x, y.y, y.z]
    }

    /// Measures a point given in B: its tracker-frame coordinates (mm) with a range error
    /// along the line of sight and two transverse errors (see [`TrackerNoise`]).
    pub fn measure(&self, x_b_mm: &[f64; 3], rng: &mut Pcg64) -> [f64; 3] {
        let y = Vector3::from(self.to_tracker(x_b_mm));
        let d = y.norm();
        let (sr, st) = self.noise.sigmas_mm(d);
        let std_normal = |rng: &mut Pcg64| Normal::new(0.0, 1.0).map_or(0.0, |n| n.sample(rng));
        let (nr, n1, n2) = (std_normal(rng), std_normal(rng), std_normal(rng));
        if d.is_nan() || d <= 0.0 {
            return [y.x, y.y, y.z];
        }
        let u = y / d;
        let (e1, e2) = transverse_basis(&u);
        let m = y + u * (sr * nr) + e1 * (st * n1) + e2 * (st * n2);
        [m.x, m.y, m.z]
    }
}

/// A named point with its coordinates (mm) in the frame its context names.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedPoint {
    /// Name as in the tracker export (`B1`, `F3`, ...).
    pub name: String,
    /// Coordinates (mm).
    pub mm: [f64; 3],
}

/// The truth of a tracker campaign: the tracker, the true ball centres on the moving
/// platform (frame M) and the true fiducial nest centres on the base (frame B). The
/// ground knows only nominal / drawing values of the latter two.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackerScene {
    /// The instrument.
    pub tracker: LaserTracker,
    /// True ball centres (frame M, mm).
    pub balls_m: Vec<NamedPoint>,
    /// True fiducial centres (frame B, mm).
    pub fiducials_b: Vec<NamedPoint>,
}

/// Standard deviation of a point's true position about its nominal one, truncated at 3
/// sigma, drawn from `seed`: the scene's manufacturing/mounting errors.
pub fn scatter_points(nominal: &[NamedPoint], sigma_mm: f64, seed: u64) -> Vec<NamedPoint> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let limit = crate::sim::manufacturing::TRUNCATION_SIGMAS * sigma_mm.abs();
    let normal = Normal::new(0.0, sigma_mm.abs()).ok();
    nominal
        .iter()
        .map(|p| NamedPoint {
            name: p.name.clone(),
            mm: p.mm.map(|v| {
                v + normal
                    .as_ref()
                    .map_or(0.0, |n| n.sample(&mut rng).clamp(-limit, limit))
            }),
        })
        .collect()
}

impl TrackerScene {
    /// Base-frame position of every ball at `pose` (mm): `p0 + t + R c`.
    pub fn balls_in_base(&self, p0_mm: &[f64; 3], pose: &Pose<f64>) -> Vec<[f64; 3]> {
        let r = rotation_matrix(&pose.rotation_rad);
        self.balls_m
            .iter()
            .map(|b| {
                let c = r * Vector3::from(b.mm);
                [0, 1, 2].map(|k| p0_mm[k] + pose.translation_mm[k] + c[k])
            })
            .collect()
    }

    /// Measures every ball at `pose`: `(name, tracker-frame mm)`.
    pub fn measure_balls(
        &self,
        p0_mm: &[f64; 3],
        pose: &Pose<f64>,
        rng: &mut Pcg64,
    ) -> Vec<(String, [f64; 3])> {
        self.balls_in_base(p0_mm, pose)
            .iter()
            .zip(self.balls_m.iter())
            .map(|(x, b)| (b.name.clone(), self.tracker.measure(x, rng)))
            .collect()
    }

    /// Measures every fiducial: `(name, tracker-frame mm)`.
    pub fn measure_fiducials(&self, rng: &mut Pcg64) -> Vec<(String, [f64; 3])> {
        self.fiducials_b
            .iter()
            .map(|f| (f.name.clone(), self.tracker.measure(&f.mm, rng)))
            .collect()
    }
}

/// `R = Rz(gamma) Ry(beta) Rx(alpha)` of a pose's angles (rad), as a matrix.
pub fn rotation_matrix(rotation_rad: &[f64; 3]) -> Matrix3<f64> {
    let [a, b, g] = *rotation_rad;
    *Rotation3::from_euler_angles(a, b, g).matrix()
}
