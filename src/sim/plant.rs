//! Six sliders with finite speed, absolute encoders with quantisation and noise, and the
//! true geometry: the mechanism the controller drives in host tests.
//!
//! The sliders and the encoder quantisation are the `no_std` core in [`crate::plant`]
//! (the same code the QEMU board runs); this module adds what only a simulation has: the
//! true geometry, encoder noise and warnings, the end-of-travel switches and reference
//! sensors, missed steps and the other injected faults.
//!
//! Switches: per leg a lower and an upper end-of-travel switch at fixed strokes
//! ([`PlantConfig::lower_switch_mm`], [`PlantConfig::upper_switch_mm`], by default
//! [`DEFAULT_SWITCH_MARGIN_MM`] beyond the ±[`STROKE_LIMIT_MM`] stroke limits), active
//! while the **true** slider stroke is at or beyond them, and a reference sensor active
//! within [`REFERENCE_HALF_WIDTH_MM`] of home. They are read when the controller reads
//! them ([`EndOfTravel::read_switches`]), from where the sliders are then.
//!
//! Drive train: by default each true slider is exactly where its drive has moved it. A
//! realistic drive train (microsteps, backlash, lead error, stiction, settling) between
//! the drives and the sliders is opt-in ([`Plant::with_drive_train`],
//! [`super::drive_train`]); the encoders and switches then see the slider, the drives
//! report their own position.
//!
//! Temperatures: the parts' temperatures and the sensors reading them are
//! [`super::thermal`]'s; by default every part stays at the reference temperature and
//! the true geometry is exactly the one given ([`Plant::with_thermal`] sets a profile).
//! The true pose follows the expanded mechanism; the encoders and switches see the
//! sliders only, which temperatures do not move.
//!
//! The controller owns its hardware; the simulation's test bench must still advance the
//! plant's time and inject faults. [`SharedPlant`] is that: a cheap handle onto one
//! plant, one copy given to the controller as its drives and encoders, one kept by the
//! bench.

use std::cell::RefCell;
use std::rc::Rc;

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

use super::drive_train::{DriveTrain, DriveTrainConfig, DriveTrainError};
use super::thermal::{Expanded, ThermalConfig, ThermalConfigError, ThermalField};
use crate::hw::{
    DriveError, EncoderError, EncoderWarnings, EndOfTravel, SliderDrives, StrokeEncoders,
    TemperatureInputs, TravelSwitches,
};
use crate::kinematics::{
    fk, FkConfig, FkError, Geometry, GeometryError, GeometryParams, Pose, LEGS,
};
use crate::nominal::STROKE_LIMIT_MM;
use crate::plant::{nearest_count, Sliders};
use crate::thermal::TEMP_SENSORS;

/// Plant settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantConfig {
    /// Largest slider speed (mm/s) each drive moves with toward its setpoint.
    pub max_speed_mm_per_s: f64,
    /// Standard deviation of the encoder noise before quantisation (mm).
    pub encoder_noise_mm: f64,
    /// Seed of the encoder-noise generator.
    pub seed: u64,
    /// Stroke (mm) of each leg's lower end-of-travel switch: active while the true
    /// stroke is at or below it.
    pub lower_switch_mm: [f64; LEGS],
    /// Stroke (mm) of each leg's upper end-of-travel switch: active while the true
    /// stroke is at or above it.
    pub upper_switch_mm: [f64; LEGS],
}

/// Default slider speed (mm/s): a fine-pitch screw slider.
pub const DEFAULT_MAX_SPEED_MM_PER_S: f64 = 0.5;
/// Default encoder noise (mm): 0.02 um, a fifth of a count.
pub const DEFAULT_ENCODER_NOISE_MM: f64 = 2.0e-5;
/// Default distance (mm) of the end-of-travel switches beyond the flight stroke limits:
/// the controller never commands a slider there, a runaway trips them at once.
pub const DEFAULT_SWITCH_MARGIN_MM: f64 = 0.2;
/// Half-width (mm) of the stroke band about home in which the reference sensor is
/// active.
pub const REFERENCE_HALF_WIDTH_MM: f64 = 0.01;

impl Default for PlantConfig {
    fn default() -> Self {
        Self {
            max_speed_mm_per_s: DEFAULT_MAX_SPEED_MM_PER_S,
            encoder_noise_mm: DEFAULT_ENCODER_NOISE_MM,
            seed: 0,
            lower_switch_mm: [-(STROKE_LIMIT_MM + DEFAULT_SWITCH_MARGIN_MM); LEGS],
            upper_switch_mm: [STROKE_LIMIT_MM + DEFAULT_SWITCH_MARGIN_MM; LEGS],
        }
    }
}

/// Which end-of-travel switch of a slider.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SwitchEnd {
    /// The lower switch (smallest strokes).
    Lower,
    /// The upper switch (largest strokes).
    Upper,
}

/// A fault the plant can be made to show, from the moment it is injected
/// ([`Plant::inject`]) until [`Plant::clear_faults`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InjectedFault {
    /// The encoder of `leg` (0-based) keeps reporting the value it had at injection.
    EncoderStuck {
        /// 0-based leg.
        leg: u8,
    },
    /// The encoder of `leg` reads `jump_mm` off from the injection on (a slipped scale
    /// or a counting glitch): an impossible step between two cycles.
    EncoderJump {
        /// 0-based leg.
        leg: u8,
        /// Offset added to the reading (mm).
        jump_mm: f64,
    },
    /// The encoder of `leg` does not answer.
    EncoderNoResponse {
        /// 0-based leg.
        leg: u8,
    },
    /// The encoder of `leg` answers with corrupted frames.
    EncoderCorrupted {
        /// 0-based leg.
        leg: u8,
    },
    /// The drive of `leg` loses `lost_mm` of travel at once (missed steps): the slider
    /// is that much short of where the drive believes it is, from then on.
    MissedSteps {
        /// 0-based leg.
        leg: u8,
        /// Travel lost (mm, along base z).
        lost_mm: f64,
    },
    /// The slider of `leg` is jammed: it no longer moves.
    StuckSlider {
        /// 0-based leg.
        leg: u8,
    },
    /// The encoder of `leg` gets extra Gaussian noise of `sigma_mm`.
    NoiseBurst {
        /// 0-based leg.
        leg: u8,
        /// Standard deviation of the extra noise (mm).
        sigma_mm: f64,
    },
    /// The drive of `leg` reports a fault and refuses commands.
    DriveFault {
        /// 0-based leg.
        leg: u8,
    },
    /// The `end` switch of `leg` sits at stroke `at_mm` instead of where the
    /// configuration puts it (misadjusted: moved inside the stroke range, a normal move
    /// trips it).
    SwitchMisadjusted {
        /// 0-based leg.
        leg: u8,
        /// Which switch.
        end: SwitchEnd,
        /// Where it trips now (mm, along base z).
        at_mm: f64,
    },
    /// The `end` switch of `leg` reads active wherever the slider is (a welded contact,
    /// or a broken wire of a normally-closed switch).
    SwitchStuckActive {
        /// 0-based leg.
        leg: u8,
        /// Which switch.
        end: SwitchEnd,
    },
    /// The switch inputs of `leg` cannot be read.
    SwitchUnreadable {
        /// 0-based leg.
        leg: u8,
    },
    /// The encoder of `leg` sets its warning bit (the position stays valid).
    EncoderWarning {
        /// 0-based leg.
        leg: u8,
    },
}

impl InjectedFault {
    fn leg(&self) -> usize {
        usize::from(match *self {
            InjectedFault::EncoderStuck { leg }
            | InjectedFault::EncoderJump { leg, .. }
            | InjectedFault::EncoderNoResponse { leg }
            | InjectedFault::EncoderCorrupted { leg }
            | InjectedFault::MissedSteps { leg, .. }
            | InjectedFault::StuckSlider { leg }
            | InjectedFault::NoiseBurst { leg, .. }
            | InjectedFault::DriveFault { leg }
            | InjectedFault::SwitchMisadjusted { leg, .. }
            | InjectedFault::SwitchStuckActive { leg, .. }
            | InjectedFault::SwitchUnreadable { leg }
            | InjectedFault::EncoderWarning { leg } => leg,
        })
    }
}

/// The true mechanism.
#[derive(Clone, Debug)]
pub struct Plant {
    truth: Geometry<f64>,
    /// The true geometry's parameters at the reference temperature (what expands).
    truth_params: GeometryParams,
    /// The parts' temperatures and the temperature sensors.
    thermal: ThermalField,
    cfg: PlantConfig,
    /// The drives: position = where each drive believes its slider is (mm).
    sliders: Sliders<f64>,
    rng: Pcg64,
    noise: Option<Normal<f64>>,
    /// Simulated time (s).
    time_s: f64,
    /// Last true pose, the warm start of the next [`Plant::true_pose`].
    last_pose: Pose<f64>,
    /// Active injected faults, with the reading frozen at injection for stuck encoders.
    faults: Vec<(InjectedFault, i32)>,
    /// Travel lost per slider by missed steps (mm): true stroke = drive position - loss.
    loss_mm: [f64; LEGS],
    /// Legs whose encoder warned in the last [`StrokeEncoders::read_counts`].
    warning_legs: u8,
    /// The camera's "exposing" discrete input ([`Plant::set_exposing`]).
    exposing: bool,
    /// Between the drives and the sliders (ideal unless [`Plant::with_drive_train`]).
    train: DriveTrain,
}

impl Plant {
    /// A plant at home (all strokes 0) with the given true geometry.
    pub fn new(true_geometry: &GeometryParams, cfg: PlantConfig) -> Result<Self, GeometryError> {
        // The true mechanism has no soft limits of its own; the controller applies them.
        let mut g = *true_geometry;
        g.stroke_limits = None;
        g.workspace = None;
        let thermal = ThermalField::new(ThermalConfig::at_reference(cfg.seed), &g)
            .unwrap_or_else(|e| unreachable!("the reference thermal field is valid: {e:?}"));
        Ok(Self {
            truth: Geometry::new(&g)?,
            truth_params: g,
            thermal,
            cfg,
            sliders: Sliders::default(),
            rng: Pcg64::seed_from_u64(cfg.seed),
            noise: Normal::new(0.0, cfg.encoder_noise_mm)
                .ok()
                .filter(|_| cfg.encoder_noise_mm > 0.0),
            time_s: 0.0,
            last_pose: Pose::home(),
            faults: Vec::new(),
            loss_mm: [0.0; LEGS],
            warning_legs: 0,
            exposing: false,
            train: ideal_train(&[0.0; LEGS]),
        })
    }

    /// This plant with `cfg` between its drives and its sliders, at rest where the drives
    /// are now (backlash gaps centred, [`DriveTrain::new`]). Refuses parameters
    /// [`DriveTrainConfig::check`] refuses (the plant is then dropped: build another).
    pub fn with_drive_train(mut self, cfg: DriveTrainConfig) -> Result<Self, DriveTrainError> {
        self.train = DriveTrain::new(cfg, &self.motor_mm())?;
        Ok(self)
    }

    /// This plant with the thermal side `cfg` ([`super::thermal`]) from now on (its
    /// profile's time 0 is now). Refused if [`ThermalConfig::check`] refuses it or if
    /// the mechanism expanded at the profile's start is not a mechanism (the plant is
    /// then dropped: build another).
    pub fn with_thermal(mut self, cfg: ThermalConfig) -> Result<Self, ThermalConfigError> {
        let field = ThermalField::new(cfg, &self.truth_params)?;
        if let Some(Err(_)) = field.expanded(&self.truth_params) {
            return Err(ThermalConfigError::Geometry);
        }
        self.thermal = field;
        Ok(self)
    }

    /// The thermal side: the parts' temperatures, the sensors.
    pub fn thermal(&self) -> &ThermalField {
        &self.thermal
    }

    /// Sets the camera's "exposing" discrete input (`hw::ExposureInput`).
    pub fn set_exposing(&mut self, exposing: bool) {
        self.exposing = exposing;
    }

    /// The camera's "exposing" discrete input as set.
    pub fn is_exposing(&self) -> bool {
        self.exposing
    }

    /// The thermal side, to set temperatures or inject sensor failures.
    pub fn thermal_mut(&mut self) -> &mut ThermalField {
        &mut self.thermal
    }

    /// The true mechanism expanded at the parts' temperatures now ([`Expanded`]), `None`
    /// while nothing has expanded ([`Plant::truth`] holds as it is); an error if the
    /// temperatures make it no mechanism.
    pub fn expanded_truth(&self) -> Option<Result<Expanded, GeometryError>> {
        self.thermal.expanded(&self.truth_params)
    }

    /// The drive train.
    pub fn drive_train(&self) -> &DriveTrain {
        &self.train
    }

    /// Where the motors have turned the screws (mm of travel): the drive positions less
    /// any travel lost to missed steps.
    fn motor_mm(&self) -> [f64; LEGS] {
        let mut s = self.sliders.positions_mm();
        for (v, l) in s.iter_mut().zip(self.loss_mm.iter()) {
            *v -= l;
        }
        s
    }

    /// The drive train follows the motors, settling for `dt_s`.
    fn follow(&mut self, dt_s: f64) {
        let m = self.motor_mm();
        self.train.update(&m, dt_s);
    }

    /// Injects a fault now (the test chooses the time by the cycle it calls this in).
    pub fn inject(&mut self, fault: InjectedFault) {
        let leg = fault.leg();
        let frozen = self
            .strokes_mm()
            .get(leg)
            .map(|s| nearest_count(*s))
            .unwrap_or(0);
        if let InjectedFault::MissedSteps { lost_mm, .. } = fault {
            if let Some(l) = self.loss_mm.get_mut(leg) {
                *l += lost_mm;
            }
            self.follow(0.0);
        }
        self.faults.push((fault, frozen));
    }

    /// Places the sliders (drive positions and setpoints) at these strokes (mm), e.g.
    /// where they were found at power-on. A drive train starts over at rest there
    /// ([`DriveTrain::new`]; its configuration was checked when it was set).
    pub fn set_strokes_mm(&mut self, strokes_mm: &[f64; LEGS]) {
        self.sliders = Sliders::at(*strokes_mm);
        let m = self.motor_mm();
        self.train = DriveTrain::new(*self.train.config(), &m).unwrap_or_else(|_| ideal_train(&m));
    }

    /// Removes every injected fault (a repaired mechanism). Drives that missed steps
    /// are re-referenced to where their sliders really are (the slider does not move;
    /// the drive's position and setpoint are corrected by the lost travel).
    pub fn clear_faults(&mut self) {
        self.faults.clear();
        for (leg, l) in self.loss_mm.iter_mut().enumerate() {
            self.sliders.shift(leg, -*l);
            *l = 0.0;
        }
        self.follow(0.0);
    }

    /// The injected faults still active.
    pub fn faults(&self) -> impl Iterator<Item = &InjectedFault> {
        self.faults.iter().map(|(f, _)| f)
    }

    fn has(&self, leg: usize, pred: impl Fn(&InjectedFault) -> bool) -> bool {
        self.faults.iter().any(|(f, _)| f.leg() == leg && pred(f))
    }

    fn jammed(&self, leg: usize) -> bool {
        self.has(leg, |f| matches!(f, InjectedFault::StuckSlider { .. }))
    }

    /// Advances time by `dt_s`: every drive moves toward its setpoint at most
    /// `max_speed * dt`, the drive train follows.
    pub fn step(&mut self, dt_s: f64) {
        let max_step = self.cfg.max_speed_mm_per_s * dt_s.max(0.0);
        let jammed: [bool; LEGS] = core::array::from_fn(|leg| self.jammed(leg));
        self.sliders
            .step(max_step, |leg| jammed.get(leg).copied().unwrap_or(false));
        self.follow(dt_s.max(0.0));
        self.thermal.advance(dt_s.max(0.0));
        self.time_s += dt_s.max(0.0);
    }

    /// True slider positions (mm): the drive positions less any travel lost, through
    /// the drive train (with the ideal one: exactly that).
    pub fn strokes_mm(&self) -> [f64; LEGS] {
        self.train.sliders_mm()
    }

    /// The drives' setpoints (mm): what each drive holds or is moving to.
    pub fn drive_setpoints_mm(&self) -> [f64; LEGS] {
        self.sliders.setpoints_mm()
    }

    /// The drives' positions (mm): where each drive believes its slider is (the true
    /// stroke plus any travel lost to missed steps).
    pub fn drive_positions_mm(&self) -> [f64; LEGS] {
        self.sliders.positions_mm()
    }

    /// Simulated time (s).
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Whether every drive has reached its setpoint (a jammed slider counts as
    /// settled: it will not move) and every slider has settled on its drive train.
    pub fn settled(&self) -> bool {
        self.sliders.settled(|leg| self.jammed(leg)) && self.train.at_rest()
    }

    /// The mirror's true pose: FK of the true geometry at the true strokes (f64), the
    /// geometry expanded at the parts' temperatures ([`Plant::expanded_truth`]; an
    /// expansion that is no mechanism reads as [`FkError::NonFinite`]).
    pub fn true_pose(&mut self) -> Result<Pose<f64>, FkError> {
        let cfg = FkConfig::<f64> {
            max_iterations: 20,
            ..FkConfig::default()
        };
        let sol = match self.expanded_truth() {
            None => fk(&self.truth, &self.strokes_mm(), &self.last_pose, &cfg)?,
            Some(x) => {
                let x = x.map_err(|_| FkError::NonFinite)?;
                let geom = Geometry::new(&x.params).map_err(|_| FkError::NonFinite)?;
                let mut s = self.strokes_mm();
                for (s, c) in s.iter_mut().zip(x.stroke_origin_mm.iter()) {
                    *s -= c;
                }
                fk(&geom, &s, &self.last_pose, &cfg)?
            }
        };
        self.last_pose = sol.pose;
        Ok(sol.pose)
    }

    /// The true geometry at the reference temperature.
    pub fn truth(&self) -> &Geometry<f64> {
        &self.truth
    }

    /// Shares this plant: see [`SharedPlant`].
    pub fn shared(self) -> SharedPlant {
        SharedPlant(Rc::new(RefCell::new(self)))
    }
}

impl StrokeEncoders for Plant {
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError> {
        // Warnings come with intact frames only.
        self.warning_legs = (0..LEGS)
            .filter(|&leg| {
                self.has(leg, |f| matches!(f, InjectedFault::EncoderWarning { .. }))
                    && !self.has(leg, |f| {
                        matches!(
                            f,
                            InjectedFault::EncoderNoResponse { .. }
                                | InjectedFault::EncoderCorrupted { .. }
                        )
                    })
            })
            .fold(0u8, |m, leg| m | 1 << leg);
        let mut out = [0i32; LEGS];
        let strokes = self.strokes_mm();
        for (leg, (o, s)) in out.iter_mut().zip(strokes.iter()).enumerate() {
            let mut noise = match &self.noise {
                Some(n) => n.sample(&mut self.rng),
                None => 0.0,
            };
            let mut offset = 0.0;
            let mut frozen = None;
            for (f, frozen_counts) in &self.faults {
                if f.leg() != leg {
                    continue;
                }
                match *f {
                    InjectedFault::EncoderNoResponse { .. } => {
                        return Err(EncoderError::NoResponse { leg: leg as u8 })
                    }
                    InjectedFault::EncoderCorrupted { .. } => {
                        return Err(EncoderError::Corrupted { leg: leg as u8 })
                    }
                    InjectedFault::EncoderStuck { .. } => frozen = Some(*frozen_counts),
                    InjectedFault::EncoderJump { jump_mm, .. } => offset += jump_mm,
                    InjectedFault::NoiseBurst { sigma_mm, .. } => {
                        if let Ok(n) = Normal::new(0.0, sigma_mm.abs()) {
                            noise += n.sample(&mut self.rng);
                        }
                    }
                    _ => {}
                }
            }
            // Quantisation: the encoder reports the nearest count.
            *o = frozen.unwrap_or(nearest_count(s + offset + noise));
        }
        Ok(out)
    }
}

impl crate::hw::ExposureInput for Plant {
    fn exposing(&mut self) -> bool {
        self.exposing
    }
}

impl crate::hw::ExposureInput for SharedPlant {
    fn exposing(&mut self) -> bool {
        self.0.borrow_mut().exposing()
    }
}

impl TemperatureInputs for Plant {
    fn read_temperature_counts(&mut self) -> [u16; TEMP_SENSORS] {
        self.thermal.read_counts()
    }
}

impl EncoderWarnings for Plant {
    fn warning_legs(&self) -> u8 {
        self.warning_legs
    }
}

impl EndOfTravel for Plant {
    fn read_switches(&mut self) -> TravelSwitches {
        let mut s = TravelSwitches::default();
        let strokes = self.strokes_mm();
        for (leg, x) in strokes.iter().enumerate() {
            let bit = 1u8 << leg;
            let mut lower_mm = self.cfg.lower_switch_mm.get(leg).copied().unwrap_or(0.0);
            let mut upper_mm = self.cfg.upper_switch_mm.get(leg).copied().unwrap_or(0.0);
            let (mut lower_stuck, mut upper_stuck, mut unreadable) = (false, false, false);
            for (f, _) in self.faults.iter().filter(|(f, _)| f.leg() == leg) {
                match *f {
                    InjectedFault::SwitchMisadjusted { end, at_mm, .. } => match end {
                        SwitchEnd::Lower => lower_mm = at_mm,
                        SwitchEnd::Upper => upper_mm = at_mm,
                    },
                    InjectedFault::SwitchStuckActive { end, .. } => match end {
                        SwitchEnd::Lower => lower_stuck = true,
                        SwitchEnd::Upper => upper_stuck = true,
                    },
                    InjectedFault::SwitchUnreadable { .. } => unreadable = true,
                    _ => {}
                }
            }
            if unreadable {
                s.unreadable |= bit;
                continue;
            }
            if lower_stuck || *x <= lower_mm {
                s.lower |= bit;
            }
            if upper_stuck || *x >= upper_mm {
                s.upper |= bit;
            }
            if x.abs() <= REFERENCE_HALF_WIDTH_MM {
                s.reference |= bit;
            }
        }
        s
    }
}

impl SliderDrives for Plant {
    fn command_strokes_mm(&mut self, setpoint_mm: &[f32; LEGS]) -> Result<(), DriveError> {
        // A faulted drive holds and refuses.
        self.status()?;
        self.sliders.command(setpoint_mm);
        Ok(())
    }

    fn hold(&mut self) {
        self.sliders.hold();
    }

    fn setpoints_mm(&mut self) -> [f32; LEGS] {
        self.sliders.setpoints_f32()
    }

    fn status(&mut self) -> Result<(), DriveError> {
        match self
            .faults
            .iter()
            .find(|(f, _)| matches!(f, InjectedFault::DriveFault { .. }))
        {
            Some((f, _)) => Err(DriveError::DriveFault { leg: f.leg() as u8 }),
            None => Ok(()),
        }
    }
}

/// The ideal drive train at rest at `drive_mm` (its configuration cannot be refused).
fn ideal_train(drive_mm: &[f64; LEGS]) -> DriveTrain {
    DriveTrain::new(DriveTrainConfig::ideal(), drive_mm)
        .unwrap_or_else(|e| unreachable!("the ideal drive train is valid: {e:?}"))
}

/// A shared handle onto one [`Plant`]: the controller gets one as its hardware, the
/// test bench keeps one to advance time, inject faults and look at the truth. Single
/// threaded, like the control cycle it stands in for.
#[derive(Clone, Debug)]
pub struct SharedPlant(Rc<RefCell<Plant>>);

impl SharedPlant {
    /// Runs `f` on the plant.
    pub fn with<R>(&self, f: impl FnOnce(&mut Plant) -> R) -> R {
        f(&mut self.0.borrow_mut())
    }
}

impl StrokeEncoders for SharedPlant {
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError> {
        self.0.borrow_mut().read_counts()
    }
}

impl TemperatureInputs for SharedPlant {
    fn read_temperature_counts(&mut self) -> [u16; TEMP_SENSORS] {
        self.0.borrow_mut().read_temperature_counts()
    }
}

impl EncoderWarnings for SharedPlant {
    fn warning_legs(&self) -> u8 {
        self.0.borrow().warning_legs()
    }
}

impl EndOfTravel for SharedPlant {
    fn read_switches(&mut self) -> TravelSwitches {
        self.0.borrow_mut().read_switches()
    }
}

impl SliderDrives for SharedPlant {
    fn command_strokes_mm(&mut self, setpoint_mm: &[f32; LEGS]) -> Result<(), DriveError> {
        self.0.borrow_mut().command_strokes_mm(setpoint_mm)
    }
    fn hold(&mut self) {
        self.0.borrow_mut().hold()
    }
    fn setpoints_mm(&mut self) -> [f32; LEGS] {
        self.0.borrow_mut().setpoints_mm()
    }
    fn status(&mut self) -> Result<(), DriveError> {
        self.0.borrow_mut().status()
    }
}
