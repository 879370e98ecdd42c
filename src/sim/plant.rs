//! Six sliders with finite speed, absolute encoders with quantisation and noise, and the
//! true geometry: the mechanism the controller drives in host tests.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

use crate::hw::{DriveError, EncoderError, SliderDrives, StrokeEncoders, ENCODER_MM_PER_COUNT};
use crate::kinematics::{
    fk, FkConfig, FkError, Geometry, GeometryError, GeometryParams, Pose, LEGS,
};

/// Plant settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantConfig {
    /// Largest slider speed (mm/s) each drive moves with toward its setpoint.
    pub max_speed_mm_per_s: f64,
    /// Standard deviation of the encoder noise before quantisation (mm).
    pub encoder_noise_mm: f64,
    /// Seed of the encoder-noise generator.
    pub seed: u64,
}

/// Default slider speed (mm/s): a fine-pitch screw slider.
pub const DEFAULT_MAX_SPEED_MM_PER_S: f64 = 0.5;
/// Default encoder noise (mm): 0.02 um, a fifth of a count.
pub const DEFAULT_ENCODER_NOISE_MM: f64 = 2.0e-5;

impl Default for PlantConfig {
    fn default() -> Self {
        Self {
            max_speed_mm_per_s: DEFAULT_MAX_SPEED_MM_PER_S,
            encoder_noise_mm: DEFAULT_ENCODER_NOISE_MM,
            seed: 0,
        }
    }
}

/// The true mechanism.
#[derive(Clone, Debug)]
pub struct Plant {
    truth: Geometry<f64>,
    cfg: PlantConfig,
    /// True slider positions (mm, stroke along base z).
    stroke_mm: [f64; LEGS],
    /// Drive setpoints (mm).
    setpoint_mm: [f64; LEGS],
    rng: Pcg64,
    noise: Option<Normal<f64>>,
    /// Simulated time (s).
    time_s: f64,
    /// Last true pose, the warm start of the next [`Plant::true_pose`].
    last_pose: Pose<f64>,
}

impl Plant {
    /// A plant at home (all strokes 0) with the given true geometry.
    pub fn new(true_geometry: &GeometryParams, cfg: PlantConfig) -> Result<Self, GeometryError> {
        // The true mechanism has no soft limits of its own; the controller applies them.
        let mut g = *true_geometry;
        g.stroke_limits = None;
        g.workspace = None;
        Ok(Self {
            truth: Geometry::new(&g)?,
            cfg,
            stroke_mm: [0.0; LEGS],
            setpoint_mm: [0.0; LEGS],
            rng: Pcg64::seed_from_u64(cfg.seed),
            noise: Normal::new(0.0, cfg.encoder_noise_mm)
                .ok()
                .filter(|_| cfg.encoder_noise_mm > 0.0),
            time_s: 0.0,
            last_pose: Pose::home(),
        })
    }

    /// Advances time by `dt_s`: every slider moves toward its setpoint at most
    /// `max_speed * dt`.
    pub fn step(&mut self, dt_s: f64) {
        let max_step = self.cfg.max_speed_mm_per_s * dt_s.max(0.0);
        for (s, sp) in self.stroke_mm.iter_mut().zip(self.setpoint_mm.iter()) {
            let d = (*sp - *s).clamp(-max_step, max_step);
            *s += d;
        }
        self.time_s += dt_s.max(0.0);
    }

    /// True slider positions (mm).
    pub fn strokes_mm(&self) -> [f64; LEGS] {
        self.stroke_mm
    }

    /// Simulated time (s).
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Whether every slider has reached its setpoint.
    pub fn settled(&self) -> bool {
        self.stroke_mm == self.setpoint_mm
    }

    /// The mirror's true pose: FK of the true geometry at the true strokes (f64).
    pub fn true_pose(&mut self) -> Result<Pose<f64>, FkError> {
        let cfg = FkConfig::<f64> {
            max_iterations: 20,
            ..FkConfig::default()
        };
        let sol = fk(&self.truth, &self.stroke_mm, &self.last_pose, &cfg)?;
        self.last_pose = sol.pose;
        Ok(sol.pose)
    }

    /// The true geometry.
    pub fn truth(&self) -> &Geometry<f64> {
        &self.truth
    }
}

impl StrokeEncoders for Plant {
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError> {
        let mut out = [0i32; LEGS];
        for (o, s) in out.iter_mut().zip(self.stroke_mm.iter()) {
            let noise = match &self.noise {
                Some(n) => n.sample(&mut self.rng),
                None => 0.0,
            };
            // Quantisation: the encoder reports the nearest count.
            *o = ((s + noise) / ENCODER_MM_PER_COUNT).round() as i32;
        }
        Ok(out)
    }
}

impl SliderDrives for Plant {
    fn command_strokes_mm(&mut self, setpoint_mm: &[f32; LEGS]) -> Result<(), DriveError> {
        for (sp, c) in self.setpoint_mm.iter_mut().zip(setpoint_mm.iter()) {
            *sp = f64::from(*c);
        }
        Ok(())
    }

    fn hold(&mut self) {
        self.setpoint_mm = self.stroke_mm;
    }
}
