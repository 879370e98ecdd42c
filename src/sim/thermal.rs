//! The plant's thermal side (issue 22): the temperatures of the mechanism's parts, the
//! true geometry they give it, and the temperature sensors that read them.
//!
//! # The temperature field
//! Per leg a rod and a slider column, the base plate (a uniform part plus a linear
//! gradient across it: each leg's lower-joint corner has its own temperature, and the
//! plate's centre, where a sensor sits) and the moving platform. Each part follows a
//! *drive* temperature with a first-order lag of its own time constant
//! ([`Profile::lag_s`], by [`Part`]): `dT/dt = (D(t) - T) / tau`, integrated exactly for
//! a drive held over each step. The drive is the on-orbit profile ([`Profile`]):
//! * a uniform swing about [`Profile::mean_c`] ([`Swing`]: a sinusoid over the orbit, or
//!   the steps of sun and eclipse);
//! * a gradient across the base plate, [`Profile::gradient_k`] between the two extreme
//!   lower-joint corners along its direction, the direction turning with
//!   [`Profile::gradient_period_s`] (the sun's direction over an orbit). The corners'
//!   drives take it at their lower joints' `a_xy`; each leg's column and rod stand on
//!   their corner and take the corner's drive (a column and a rod are conductively tied
//!   to their corner; the rods' upper ends to the platform are neglected); the platform
//!   and the plate's centre take the uniform drive alone.
//!
//! Defaults ([`Profile::ON_ORBIT`]) and their reasoning: a low orbit of 5,400 s (90 min;
//! 500 km is 94.6 min) with a +-5 K swing (the figure between sun and eclipse)
//! and a 2 K gradient turning once per orbit. Time constants `tau = rho c V / (h A)`
//! with an effective coupling `h` of about 6 W/(m^2 K) (radiation at 293 K with
//! emissivity 0.8, `4 eps sigma T^3` = 4.6 W/(m^2 K), plus conduction through the
//! mounts): a titanium rod of 6 mm diameter (`rho c` = 2.35 MJ/(m^3 K), `tau = rho c d /
//! 4h`) about 600 s; an aluminium column of 15 mm section (2.43 MJ/(m^3 K)) about
//! 1,500 s; the 10 mm aluminium base plate, heated from both faces (`rho c d / 2h`),
//! about 2,000 s, and more with its mounts' mass: 2,400 s; the platform with the
//! mirror's mass 1,800 s. [`Profile::REFERENCE`] holds every part at the reference
//! temperature: the plant's default, which leaves it exactly as it was without a
//! thermal side.
//!
//! Not modelled: the base plate's in-plane thermoelastic field under a gradient. A free
//! plate with a linear temperature `T0 + g.x` is stress-free, but its points move by
//! `alpha (T0 x + (g.x) x - |x|^2 g / 2)` about a fixed centre: the last term, which
//! the thermal model (and so this plant) leaves out, is the same for every corner (the
//! lower joints lie on one circle), a rigid shift of about 1 um for 2 K across the
//! plate that depends on how the plate is held.
//!
//! # The true geometry at temperature
//! Exactly the physics of [`crate::thermal`]'s module documentation, with the plant's
//! own [`Coefficients`] (which the controller does not know): with `e = alpha (T -
//! T_ref)` of each part of each leg, the base plate scales the lower joint's `a_xy` (its
//! corner's temperature), the column raises `a_z` by `e_column * column_length_mm`, the
//! rod's length is `L (1 + e_rod)` (`L = |b + p0 - a|` at the reference), the platform
//! scales `b` (all three coordinates). The reference temperature is
//! [`crate::thermal::ThermalModel::NONE`]'s, where the plant's true geometry holds.
//!
//! The rod length is implicit in [`GeometryParams`] (`|b + p0 - a|`), so a longer rod
//! is represented by moving the lower joint along base z to where `|b' + p0 - a''| =
//! L'`, and by shifting that leg's stroke origin by the same amount: the rod equation
//! `(p - a' - s e_z)^2 = L'^2` for the true stroke `s` is the same equation as `(p -
//! a'' - (s - c) e_z)^2 = L'^2` with `c = a''_z - a'_z` ([`Expanded`]). The kinematics
//! then evaluate the expanded mechanism exactly (host test
//! `thermal_plant::the_plant_at_temperature_solves_the_rod_equation`).
//!
//! # The sensors
//! [`TEMP_SENSORS`] PT1000 channels ([`crate::thermal::pt1000`]) through the 16-bit
//! ratiometric ADC ([`crate::thermal::adc`]); placement ([`SENSOR_OF`]): channel `i` =
//! 0..5 on the slider column of leg `i + 1` at its foot (it governs the leg's column, rod
//! and base corner in the thermal model), [`PLATFORM_SENSOR`] on the moving platform,
//! [`BASE_CENTRE_SENSOR`] at the base plate's centre (governs nothing in the nominal
//! model: the cross-check of the corners' mean, and the spare). Each reading is the
//! sensor's part's true temperature plus its calibration offset, through the curve and
//! the divider, plus Gaussian noise ([`SensorConfig::noise_counts`]), rounded to a
//! count. Calibration offsets ([`SensorConfig::drawn`]): uniform within the tolerance
//! of class 1/10 DIN (1/10 of IEC 60751 class B, `+-(0.03 + 0.0005 |t|)` K) at the
//! reference temperature, +-0.04 K. Failures ([`SensorFailure`]) are injected per
//! channel: open reads full scale, short reads 0, stuck repeats the count it had.

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

use crate::kinematics::{GeometryError, GeometryParams, LEGS};
use crate::thermal::{adc, pt1000, Part, ThermalModel, PARTS, TEMP_SENSORS};

/// The temperature (deg C) at which the plant's true geometry holds: the thermal
/// model's reference ([`ThermalModel::NONE`]).
pub const REFERENCE_C: f64 = ThermalModel::NONE.reference_c as f64;

/// Linear expansion coefficient of titanium (Ti-6Al-4V, 1/K), the rods' material.
pub const TITANIUM_EXPANSION_PER_K: f64 = 8.6e-6;
/// Linear expansion coefficient of aluminium (6061, 1/K), the columns' and the
/// plates' material.
pub const ALUMINIUM_EXPANSION_PER_K: f64 = 23.1e-6;
/// The slider columns' nominal effective length (mm): from the column's foot on the
/// base plate to the lower joint at zero stroke.
pub const NOMINAL_COLUMN_LENGTH_MM: f64 = 60.0;

/// Relative standard deviation of a true expansion coefficient about its material's
/// handbook value: alloy, temper and lot make a few percent (3 %).
pub const EXPANSION_SPREAD_REL: f64 = 0.03;
/// Standard deviation of the true effective column length (mm): where the column is
/// effectively referenced (bolts, interface) is known to a few millimetres.
pub const COLUMN_LENGTH_SPREAD_MM: f64 = 3.0;
/// Drawn deviations are truncated at this many standard deviations.
pub const SPREAD_TRUNCATION_SIGMAS: f64 = 3.0;

/// Channel of the sensor on the moving platform (0-based).
pub const PLATFORM_SENSOR: usize = 6;
/// Channel of the sensor at the base plate's centre (0-based).
pub const BASE_CENTRE_SENSOR: usize = 7;
/// Which sensor governs each part of each leg, `[leg][Part]` (the thermal model's
/// `sensor_of`): leg `i`'s column sensor `i` for its rod, column and base corner, the
/// platform's sensor for the platform.
pub const SENSOR_OF: [[u8; PARTS]; LEGS] = {
    let mut s = [[0u8; PARTS]; LEGS];
    let mut i = 0;
    while i < LEGS {
        s[i] = [i as u8, i as u8, i as u8, PLATFORM_SENSOR as u8];
        i += 1;
    }
    s
};

/// Noise of a reading (ADC counts, standard deviation before rounding): about a count.
pub const DEFAULT_NOISE_COUNTS: f64 = 1.0;
/// Class 1/10 DIN tolerance, constant part (K).
pub const CLASS_TENTH_DIN_K: f64 = 0.03;
/// Class 1/10 DIN tolerance, part proportional to |t| (K per deg C).
pub const CLASS_TENTH_DIN_PER_C: f64 = 0.0005;

/// A mechanism's thermal coefficients: the plant's truth, or what a model assumes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    /// Linear expansion coefficient of each part class, by [`Part`] (1/K).
    pub expansion_per_k: [f64; PARTS],
    /// Effective slider-column length (mm).
    pub column_length_mm: f64,
}

impl Coefficients {
    /// The nominal materials: titanium rods, aluminium columns and plates, the nominal
    /// column length.
    pub const NOMINAL: Coefficients = Coefficients {
        expansion_per_k: [
            TITANIUM_EXPANSION_PER_K,
            ALUMINIUM_EXPANSION_PER_K,
            ALUMINIUM_EXPANSION_PER_K,
            ALUMINIUM_EXPANSION_PER_K,
        ],
        column_length_mm: NOMINAL_COLUMN_LENGTH_MM,
    };

    /// A true mechanism's coefficients: the nominal ones with each coefficient off by
    /// [`EXPANSION_SPREAD_REL`] and the column length by [`COLUMN_LENGTH_SPREAD_MM`]
    /// (Gaussian, truncated at [`SPREAD_TRUNCATION_SIGMAS`]). Deterministic per seed.
    pub fn drawn(seed: u64) -> Coefficients {
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut draw = || {
            let n: f64 = rand_distr::StandardNormal.sample(&mut rng);
            n.clamp(-SPREAD_TRUNCATION_SIGMAS, SPREAD_TRUNCATION_SIGMAS)
        };
        let mut c = Coefficients::NOMINAL;
        for a in c.expansion_per_k.iter_mut() {
            *a *= 1.0 + EXPANSION_SPREAD_REL * draw();
        }
        c.column_length_mm += COLUMN_LENGTH_SPREAD_MM * draw();
        c
    }

    /// The firmware's thermal model with these coefficients, the reference temperature
    /// [`REFERENCE_C`] and the sensor placement [`SENSOR_OF`] (f32, as the table holds
    /// it).
    pub fn model(&self) -> ThermalModel {
        ThermalModel {
            reference_c: REFERENCE_C as f32,
            expansion_per_k: self.expansion_per_k.map(|a| a as f32),
            column_length_mm: self.column_length_mm as f32,
            sensor_of: SENSOR_OF,
        }
    }
}

/// The uniform swing of the drive temperature about [`Profile::mean_c`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Swing {
    /// No swing.
    Constant,
    /// `amplitude_k * sin(2 pi t / period_s)`.
    Sine {
        /// Amplitude (K).
        amplitude_k: f64,
        /// Period (s): an orbit.
        period_s: f64,
    },
    /// Sun and eclipse: `+amplitude_k` for `period_s - eclipse_s` from the start of
    /// each orbit, then `-amplitude_k` for `eclipse_s`.
    Eclipse {
        /// Half the step between sun and eclipse (K).
        amplitude_k: f64,
        /// Period (s): an orbit.
        period_s: f64,
        /// Time in eclipse per orbit (s).
        eclipse_s: f64,
    },
}

impl Swing {
    /// The swing at `t_s` (K).
    pub fn at(&self, t_s: f64) -> f64 {
        match *self {
            Swing::Constant => 0.0,
            Swing::Sine {
                amplitude_k,
                period_s,
            } => amplitude_k * (core::f64::consts::TAU * t_s / period_s).sin(),
            Swing::Eclipse {
                amplitude_k,
                period_s,
                eclipse_s,
            } => {
                if t_s.rem_euclid(period_s) < period_s - eclipse_s {
                    amplitude_k
                } else {
                    -amplitude_k
                }
            }
        }
    }
}

/// Orbit period of the defaults (s): 90 min.
pub const ORBIT_S: f64 = 5_400.0;
/// Eclipse time per orbit of a low orbit (s): 35 min.
pub const ECLIPSE_S: f64 = 2_100.0;

/// The on-orbit temperature profile (module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Profile {
    /// Mean drive temperature (deg C).
    pub mean_c: f64,
    /// Uniform swing about the mean.
    pub swing: Swing,
    /// Temperature difference (K) between the two extreme lower-joint corners along the
    /// gradient's direction (the joint circle's diameter): "K across the base plate".
    pub gradient_k: f64,
    /// Direction of the gradient at time 0 (rad from base x toward base y).
    pub gradient_angle_rad: f64,
    /// Period (s) with which the gradient's direction turns (positive about base z);
    /// `None`: fixed.
    pub gradient_period_s: Option<f64>,
    /// Thermal time constant of each part class, by [`Part`] (s; 0: the part follows
    /// its drive at once).
    pub lag_s: [f64; PARTS],
}

impl Profile {
    /// Every part at [`REFERENCE_C`], always: the plant's default.
    pub const REFERENCE: Profile = Profile {
        mean_c: REFERENCE_C,
        swing: Swing::Constant,
        gradient_k: 0.0,
        gradient_angle_rad: 0.0,
        gradient_period_s: None,
        lag_s: [0.0; PARTS],
    };

    /// The realistic defaults (module documentation): +-5 K over a 90-min orbit, a 2 K
    /// gradient turning once per orbit, the parts' time constants (rod 600 s, column
    /// 1,500 s, base plate 2,400 s, platform 1,800 s).
    pub const ON_ORBIT: Profile = Profile {
        mean_c: REFERENCE_C,
        swing: Swing::Sine {
            amplitude_k: 5.0,
            period_s: ORBIT_S,
        },
        gradient_k: 2.0,
        gradient_angle_rad: 0.0,
        gradient_period_s: Some(ORBIT_S),
        lag_s: [600.0, 1_500.0, 2_400.0, 1_800.0],
    };

    /// Issue 22's evidence profile: a +-5 K sinusoidal swing over `period_s` (s) and a
    /// 2 K gradient across the base at 0.7 rad from base x, fixed, every part following
    /// its drive at once (no lags).
    pub const fn swing_with_gradient(period_s: f64) -> Profile {
        Profile {
            swing: Swing::Sine {
                amplitude_k: 5.0,
                period_s,
            },
            gradient_k: 2.0,
            gradient_angle_rad: 0.7,
            ..Profile::REFERENCE
        }
    }

    /// The uniform drive at `t_s` (deg C).
    fn uniform_c(&self, t_s: f64) -> f64 {
        self.mean_c + self.swing.at(t_s)
    }

    /// The gradient's direction at `t_s` (unit vector in base xy).
    fn gradient_direction(&self, t_s: f64) -> [f64; 2] {
        let turn = match self.gradient_period_s {
            Some(p) => core::f64::consts::TAU * t_s / p,
            None => 0.0,
        };
        let (s, c) = (self.gradient_angle_rad + turn).sin_cos();
        [c, s]
    }
}

/// The sensors' settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorConfig {
    /// Standard deviation of the noise of a reading (ADC counts, before rounding).
    pub noise_counts: f64,
    /// Each sensor's calibration offset (K): it reads its part this much too warm.
    pub offset_k: [f64; TEMP_SENSORS],
    /// Seed of the noise.
    pub seed: u64,
}

impl SensorConfig {
    /// [`DEFAULT_NOISE_COUNTS`], offsets uniform within the class 1/10 DIN tolerance at
    /// [`REFERENCE_C`]; deterministic per seed.
    pub fn drawn(seed: u64) -> SensorConfig {
        let mut rng = Pcg64::seed_from_u64(seed ^ OFFSET_SEED_SALT);
        let tol = CLASS_TENTH_DIN_K + CLASS_TENTH_DIN_PER_C * REFERENCE_C.abs();
        SensorConfig {
            noise_counts: DEFAULT_NOISE_COUNTS,
            offset_k: [(); TEMP_SENSORS].map(|_| rng.random_range(-tol..=tol)),
            seed,
        }
    }

    /// Perfect sensors: no noise, no offset (readings still rounded to a count). A
    /// steady temperature then repeats its count: the supervision's stuck check
    /// (`thermal::STUCK_SAMPLES`) takes such a channel as stuck.
    pub const IDEAL: SensorConfig = SensorConfig {
        noise_counts: 0.0,
        offset_k: [0.0; TEMP_SENSORS],
        seed: 0,
    };
}

/// Decorrelates the offsets' generator from the noise's (same seed).
const OFFSET_SEED_SALT: u64 = 0x7E3A_11C0_FFEE_0022;

/// The plant's thermal side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalConfig {
    /// The temperature profile.
    pub profile: Profile,
    /// The mechanism's true coefficients.
    pub truth: Coefficients,
    /// The sensors.
    pub sensors: SensorConfig,
}

impl ThermalConfig {
    /// Every part at the reference temperature, the nominal coefficients, sensors drawn
    /// from `seed`: the plant's default.
    pub fn at_reference(seed: u64) -> ThermalConfig {
        ThermalConfig {
            profile: Profile::REFERENCE,
            truth: Coefficients::NOMINAL,
            sensors: SensorConfig::drawn(seed),
        }
    }

    /// Checks every setting.
    pub fn check(&self) -> Result<(), ThermalConfigError> {
        let p = &self.profile;
        let finite = |v: f64| v.is_finite();
        if !finite(p.mean_c) || !finite(p.gradient_k) || !finite(p.gradient_angle_rad) {
            return Err(ThermalConfigError::Profile);
        }
        match p.swing {
            Swing::Constant => {}
            Swing::Sine {
                amplitude_k,
                period_s,
            } => {
                if !(finite(amplitude_k) && period_s > 0.0 && finite(period_s)) {
                    return Err(ThermalConfigError::Profile);
                }
            }
            Swing::Eclipse {
                amplitude_k,
                period_s,
                eclipse_s,
            } => {
                let ok = finite(amplitude_k)
                    && period_s > 0.0
                    && finite(period_s)
                    && (0.0..=period_s).contains(&eclipse_s);
                if !ok {
                    return Err(ThermalConfigError::Profile);
                }
            }
        }
        if let Some(per) = p.gradient_period_s {
            if !(per > 0.0 && finite(per)) {
                return Err(ThermalConfigError::Profile);
            }
        }
        if !p.lag_s.iter().all(|t| *t >= 0.0 && finite(*t)) {
            return Err(ThermalConfigError::Lag);
        }
        let c = &self.truth;
        let ok = c.expansion_per_k.iter().all(|a| finite(*a))
            && c.column_length_mm >= 0.0
            && finite(c.column_length_mm);
        if !ok {
            return Err(ThermalConfigError::Coefficients);
        }
        let s = &self.sensors;
        let ok = s.noise_counts >= 0.0
            && finite(s.noise_counts)
            && s.offset_k.iter().all(|o| finite(*o));
        if !ok {
            return Err(ThermalConfigError::Sensors);
        }
        Ok(())
    }
}

/// Why a thermal configuration is refused. Stable codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ThermalConfigError {
    /// A profile value not finite, a period not positive, an eclipse longer than the
    /// orbit.
    Profile,
    /// A time constant negative or not finite.
    Lag,
    /// A coefficient or the column length not finite (or the length negative).
    Coefficients,
    /// Sensor noise negative or not finite, an offset not finite.
    Sensors,
    /// The expanded mechanism is not a mechanism ([`GeometryError`]).
    Geometry,
}

impl ThermalConfigError {
    /// Stable code.
    pub const fn code(self) -> u8 {
        match self {
            ThermalConfigError::Profile => 1,
            ThermalConfigError::Lag => 2,
            ThermalConfigError::Coefficients => 3,
            ThermalConfigError::Sensors => 4,
            ThermalConfigError::Geometry => 5,
        }
    }
}

/// A temperature sensor's injected failure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorFailure {
    /// Open circuit: reads full scale.
    Open,
    /// Short circuit: reads 0.
    Short,
    /// The channel repeats the count it had at injection.
    Stuck,
}

/// The true temperature of every part (deg C).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartTemperatures {
    /// Each leg's rod.
    pub rod_c: [f64; LEGS],
    /// Each leg's slider column.
    pub column_c: [f64; LEGS],
    /// The base plate at each leg's lower-joint corner.
    pub base_corner_c: [f64; LEGS],
    /// The base plate's centre.
    pub base_centre_c: f64,
    /// The moving platform.
    pub platform_c: f64,
}

impl PartTemperatures {
    /// Every part at `t_c`.
    pub fn uniform(t_c: f64) -> PartTemperatures {
        PartTemperatures {
            rod_c: [t_c; LEGS],
            column_c: [t_c; LEGS],
            base_corner_c: [t_c; LEGS],
            base_centre_c: t_c,
            platform_c: t_c,
        }
    }

    /// The temperature of `part` of `leg` (0-based, below `LEGS`; the platform is one
    /// part for every leg).
    pub fn of(&self, leg: usize, part: Part) -> f64 {
        match part {
            Part::Rod => self.rod_c[leg],
            Part::Column => self.column_c[leg],
            Part::Base => self.base_corner_c[leg],
            Part::Platform => self.platform_c,
        }
    }

    /// The temperature of the part sensor `channel` (0-based, below [`TEMP_SENSORS`])
    /// sits on ([`SENSOR_OF`]): the columns, the platform, the base plate's centre.
    pub fn at_sensor(&self, channel: usize) -> f64 {
        match channel {
            PLATFORM_SENSOR => self.platform_c,
            BASE_CENTRE_SENSOR => self.base_centre_c,
            leg => self.column_c[leg],
        }
    }
}

/// Every part class, in [`Part`] order.
pub const PART_CLASSES: [Part; PARTS] = [Part::Rod, Part::Column, Part::Base, Part::Platform];

/// The expanded mechanism in the kinematics' terms (module documentation): the true
/// stroke `s` of leg `i` is `s_geometry + stroke_origin_mm[i]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Expanded {
    /// The geometry whose rod equation is the expanded mechanism's (lower joints moved
    /// along base z so that `|b + p0 - a|` is the expanded rod).
    pub params: GeometryParams,
    /// Per leg, `a''_z - a'_z` (mm): true stroke = the geometry's stroke + this.
    pub stroke_origin_mm: [f64; LEGS],
}

/// The mechanism `truth` (at the reference temperature) with its parts expanded by
/// `e[leg][Part]` (dimensionless, `alpha (T - T_ref)`) and columns of `column_length_mm`.
pub fn expanded(
    truth: &GeometryParams,
    e: &[[f64; PARTS]; LEGS],
    column_length_mm: f64,
) -> Result<Expanded, GeometryError> {
    let mut params = *truth;
    let mut origin = [0.0; LEGS];
    let p0 = truth.p0_mm;
    for ((leg, e), o) in params.legs.iter_mut().zip(e.iter()).zip(origin.iter_mut()) {
        let [e_rod, e_col, e_base, e_plat] = *e;
        let (a, b) = (leg.a_mm, leg.b_mm);
        let d0 = [0, 1, 2].map(|k| b[k] + p0[k] - a[k]);
        let rod = (d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2]).sqrt() * (1.0 + e_rod);
        let a_x = a[0] * (1.0 + e_base);
        let a_y = a[1] * (1.0 + e_base);
        let a_z = a[2] + e_col * column_length_mm;
        let b = b.map(|v| v * (1.0 + e_plat));
        let (h_x, h_y) = (b[0] + p0[0] - a_x, b[1] + p0[1] - a_y);
        let radicand = rod * rod - h_x * h_x - h_y * h_y;
        if !(radicand > 0.0) {
            return Err(GeometryError::NonFinite);
        }
        let a_zz = b[2] + p0[2] - radicand.sqrt();
        *o = a_zz - a_z;
        leg.a_mm = [a_x, a_y, a_zz];
        leg.b_mm = b;
    }
    params.validate()?;
    Ok(Expanded {
        params,
        stroke_origin_mm: origin,
    })
}

/// The temperature field, its true geometry and its sensors (module documentation).
#[derive(Clone, Debug)]
pub struct ThermalField {
    cfg: ThermalConfig,
    /// Each leg's lower joint `a_xy` (mm), where the gradient is evaluated.
    corners_mm: [[f64; 2]; LEGS],
    /// 1 / the joint circle's diameter (1/mm): turns "K across the plate" into K/mm.
    per_diameter: f64,
    time_s: f64,
    temps: PartTemperatures,
    rng: Pcg64,
    noise: Option<Normal<f64>>,
    failures: [Option<SensorFailure>; TEMP_SENSORS],
    /// Each channel's last count (what a stuck channel repeats).
    last_counts: [u16; TEMP_SENSORS],
}

impl ThermalField {
    /// The field of `cfg` on the mechanism `truth`, at time 0: every part at its drive
    /// (the profile's start, no transient).
    pub fn new(cfg: ThermalConfig, truth: &GeometryParams) -> Result<Self, ThermalConfigError> {
        cfg.check()?;
        let corners_mm = truth.legs.map(|l| [l.a_mm[0], l.a_mm[1]]);
        let radius = corners_mm
            .iter()
            .map(|c| c[0].hypot(c[1]))
            .fold(0.0f64, f64::max);
        let per_diameter = if radius > 0.0 { 0.5 / radius } else { 0.0 };
        let mut f = ThermalField {
            cfg,
            corners_mm,
            per_diameter,
            time_s: 0.0,
            temps: PartTemperatures::uniform(REFERENCE_C),
            rng: Pcg64::seed_from_u64(cfg.sensors.seed),
            noise: Normal::new(0.0, cfg.sensors.noise_counts)
                .ok()
                .filter(|_| cfg.sensors.noise_counts > 0.0),
            failures: [None; TEMP_SENSORS],
            last_counts: [0; TEMP_SENSORS],
        };
        f.temps = f.drive(0.0);
        f.last_counts = core::array::from_fn(|ch| f.ideal_counts(ch).round() as u16);
        Ok(f)
    }

    /// The configuration.
    pub fn config(&self) -> &ThermalConfig {
        &self.cfg
    }

    /// The drive temperatures at `t_s`.
    fn drive(&self, t_s: f64) -> PartTemperatures {
        let p = &self.cfg.profile;
        let u = p.uniform_c(t_s);
        let [gx, gy] = p.gradient_direction(t_s);
        let g = p.gradient_k * self.per_diameter;
        let corner = self.corners_mm.map(|[x, y]| u + g * (gx * x + gy * y));
        PartTemperatures {
            rod_c: corner,
            column_c: corner,
            base_corner_c: corner,
            base_centre_c: u,
            platform_c: u,
        }
    }

    /// Advances time by `dt_s`: each part relaxes toward its drive at the end of the
    /// step with its time constant.
    pub fn advance(&mut self, dt_s: f64) {
        let dt = dt_s.max(0.0);
        if dt == 0.0 {
            return;
        }
        self.time_s += dt;
        let d = self.drive(self.time_s);
        let k = self.cfg.profile.lag_s.map(|tau| {
            if tau > 0.0 {
                1.0 - (-dt / tau).exp()
            } else {
                1.0
            }
        });
        let relax = |t: &mut f64, d: f64, k: f64| *t += (d - *t) * k;
        let [k_rod, k_col, k_base, k_plat] = k;
        for leg in 0..LEGS {
            relax(&mut self.temps.rod_c[leg], d.rod_c[leg], k_rod);
            relax(&mut self.temps.column_c[leg], d.column_c[leg], k_col);
            relax(
                &mut self.temps.base_corner_c[leg],
                d.base_corner_c[leg],
                k_base,
            );
        }
        relax(&mut self.temps.base_centre_c, d.base_centre_c, k_base);
        relax(&mut self.temps.platform_c, d.platform_c, k_plat);
    }

    /// Time since the field started (s).
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The parts' true temperatures now.
    pub fn temperatures(&self) -> &PartTemperatures {
        &self.temps
    }

    /// Sets the parts' temperatures (they then relax toward the profile's drive).
    pub fn set_temperatures(&mut self, t: PartTemperatures) {
        self.temps = t;
    }

    /// `alpha (T - T_ref)` of each part of each leg, with the true coefficients.
    pub fn expansions(&self) -> [[f64; PARTS]; LEGS] {
        core::array::from_fn(|leg| {
            core::array::from_fn(|p| {
                self.cfg.truth.expansion_per_k[p]
                    * (self.temps.of(leg, PART_CLASSES[p]) - REFERENCE_C)
            })
        })
    }

    /// The expanded true mechanism now; `None` while nothing has expanded (every part
    /// at the reference temperature, or every coefficient 0: the true geometry holds
    /// as it is, bit for bit).
    pub fn expanded(&self, truth: &GeometryParams) -> Option<Result<Expanded, GeometryError>> {
        let e = self.expansions();
        if e.iter().flatten().all(|x| *x == 0.0) {
            return None;
        }
        Some(expanded(truth, &e, self.cfg.truth.column_length_mm))
    }

    /// The unrounded, noiseless reading of `channel` (counts).
    fn ideal_counts(&self, channel: usize) -> f64 {
        let t = self.temps.at_sensor(channel) + self.cfg.sensors.offset_k[channel];
        adc::counts_of_resistance(pt1000::resistance_ohm(t))
    }

    /// Reads every channel once (counts; see [`crate::hw::TemperatureInputs`]).
    pub fn read_counts(&mut self) -> [u16; TEMP_SENSORS] {
        let full = f64::from(adc::FULL_SCALE_COUNTS);
        let mut out = [0u16; TEMP_SENSORS];
        for (ch, o) in out.iter_mut().enumerate() {
            let noise = match &self.noise {
                Some(n) => n.sample(&mut self.rng),
                None => 0.0,
            };
            *o = match self.failures[ch] {
                Some(SensorFailure::Open) => adc::FULL_SCALE_COUNTS,
                Some(SensorFailure::Short) => 0,
                Some(SensorFailure::Stuck) => self.last_counts[ch],
                None => (self.ideal_counts(ch) + noise).round().clamp(0.0, full) as u16,
            };
            self.last_counts[ch] = *o;
        }
        out
    }

    /// Injects a failure into sensor `channel` (0-based) from now on; a stuck channel
    /// repeats its last count. Ignored for a channel beyond [`TEMP_SENSORS`].
    pub fn inject(&mut self, channel: usize, failure: SensorFailure) {
        if let Some(f) = self.failures.get_mut(channel) {
            *f = Some(failure);
        }
    }

    /// Repairs every sensor.
    pub fn clear_failures(&mut self) {
        self.failures = [None; TEMP_SENSORS];
    }
}
