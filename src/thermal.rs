//! Thermal: the mechanism's temperature sensors and its thermal model (issue 22).
//!
//! On orbit the mechanism's parts change temperature by kelvins; each grows by its
//! expansion coefficient and the mirror moves by micrometres at constant strokes, which
//! the slider encoders cannot see. This module holds what the firmware needs to
//! compensate, hardware-independent (no HAL, no heap):
//!
//! * [`pt1000`]: the sensors, PT1000 resistance thermometers (IEC 60751) read through a
//!   16-bit ratiometric ADC ([`adc`]); [`celsius_from_counts`] turns a reading into a
//!   temperature or a [`SensorFault`] (open, short); [`SensorMonitor`] adds the stuck
//!   check and the mean over a window.
//! * [`ThermalModel`]: reference temperature, one linear expansion coefficient per part
//!   class ([`Part`]), the slider columns' effective length, and which sensor governs
//!   which part of which leg.
//! * [`stroke_offsets_mm`]: the change of each slider's stroke that keeps a pose where
//!   the reference-temperature geometry puts it, to first order in the expansions.
//! * [`compensation`]: how the applied offsets follow those, in bounded steps
//!   ([`Compensation`]), once a second by the controller at rest.
//!
//! # The model (frames as [`crate::kinematics::geometry`]: base B, moving M; mm)
//! Each part's dimensions scale by `1 + alpha * (T - T_ref)` (`alpha` in 1/K, `T` of its
//! governing sensor, deg C):
//! * **base plate**: the lower joints' horizontal position `a_xy` (about B's origin);
//! * **slider column**: the lower joint's height at zero stroke rises by
//!   `alpha * column_length_mm * dT` (the column is referenced at its foot);
//! * **rod**: the rod length `L`;
//! * **platform**: the upper joints `b` (all three coordinates, about M's origin).
//!
//! With the leg's state at the pose (IK: horizontal rod `h`, vertical rod `q`, `Rb`),
//! the stroke `s = b'_z - a_z - sqrt(L^2 - |h|^2)` changes, to first order, by
//!
//! ```text
//! ds = - e_column * column_length_mm            (the joint rose: less stroke)
//!      - e_rod * L^2 / q                        (a longer rod: less stroke)
//!      - e_base * (h . a_xy) / q                (the joint moved outward)
//!      + e_platform * ((Rb)_z + (h . (Rb)_xy) / q)
//! ```
//!
//! with `e_part = alpha_part * (T_part - T_ref)`. The neglected second order is
//! `|da|^2 / q`: below 2 nm for a 5 K swing of aluminium (`da` ~ 12 um at 100 mm, `q`
//! ~ 80 mm); host test `thermal::offsets_match_the_exact_strokes` compares these offsets
//! with the exact strokes of the expanded mechanism (the square root in f64).

use crate::kinematics::geometry::{Geometry, LEGS};
use crate::kinematics::linalg::{add3, mat_vec3};
use crate::kinematics::pose::{Pose, RotationDelta};

pub mod compensation;
pub use compensation::{Compensation, CompensationParamError, CompensationParams, StepOutcome};

/// Number of temperature sensors (ADC channels).
pub const TEMP_SENSORS: usize = 8;

/// The PT1000 resistance thermometer (IEC 60751, Callendar-Van Dusen).
pub mod pt1000 {
    /// Resistance at 0 deg C (ohm).
    pub const R0_OHM: f64 = 1000.0;
    /// Callendar-Van Dusen A (1/K).
    pub const A_PER_K: f64 = 3.9083e-3;
    /// Callendar-Van Dusen B (1/K^2).
    pub const B_PER_K2: f64 = -5.775e-7;
    /// Callendar-Van Dusen C (1/K^4), below 0 deg C only.
    pub const C_PER_K4: f64 = -4.183e-12;

    /// Resistance (ohm) at `t_c` (deg C): `R0 (1 + A t + B t^2 + C (t - 100) t^3)`, the
    /// C term below 0 deg C only. (The sensors' truth in the simulation; the firmware
    /// inverts it with [`super::celsius_from_counts`].)
    pub fn resistance_ohm(t_c: f64) -> f64 {
        let c = if t_c < 0.0 {
            C_PER_K4 * (t_c - 100.0) * t_c * t_c * t_c
        } else {
            0.0
        };
        R0_OHM * (1.0 + A_PER_K * t_c + B_PER_K2 * t_c * t_c + c)
    }
}

/// The ADC the sensors are read through: a ratiometric divider, the PT1000 in series
/// with a reference resistor across the ADC's reference voltage, so the reading is
/// `FULL_SCALE_COUNTS * R / (R + REFERENCE_OHM)` whatever the reference voltage.
pub mod adc {
    /// Full scale of the 16-bit ADC (counts).
    pub const FULL_SCALE_COUNTS: u16 = u16::MAX;
    /// The divider's reference resistor (ohm): equal to the PT1000 at 0 deg C, so a
    /// count is about 0.017 K around room temperature (58 counts per kelvin).
    pub const REFERENCE_OHM: f64 = 1000.0;

    /// The count just below a sensor at 20 deg C (the nominal thermal model's reference;
    /// ideally 33,996.48 counts, so 19.992 deg C): the fixed reading of a board whose
    /// temperature inputs are not wired (`crate::hw::TemperatureInputs`).
    pub const COUNTS_NEAR_20_C: u16 = 33_996;

    /// The ideal (unrounded) reading of a sensor of resistance `r_ohm`.
    pub fn counts_of_resistance(r_ohm: f64) -> f64 {
        f64::from(FULL_SCALE_COUNTS) * r_ohm / (r_ohm + REFERENCE_OHM)
    }
}

/// Lowest temperature a sensor may read (deg C); below it the sensor is taken as
/// shorted (a short reads 0 counts).
pub const SENSOR_MIN_C: f32 = -60.0;
/// Highest temperature a sensor may read (deg C); above it the sensor is taken as open
/// (an open sensor reads full scale).
pub const SENSOR_MAX_C: f32 = 100.0;

/// Why a temperature sensor cannot be used. Stable codes (housekeeping, events).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorFault {
    /// Reading below [`SENSOR_MIN_C`]: a short circuit (or a broken reference).
    Short,
    /// Reading above [`SENSOR_MAX_C`]: an open circuit.
    Open,
    /// The same count for [`STUCK_SAMPLES`] readings in a row: the ADC channel or its
    /// multiplexer is stuck (a live sensor's noise changes its last count).
    Stuck,
}

impl SensorFault {
    /// Stable code (0 is healthy; housekeeping reports each fault as a sensor mask).
    pub const fn code(self) -> u8 {
        match self {
            SensorFault::Short => 1,
            SensorFault::Open => 2,
            SensorFault::Stuck => 3,
        }
    }

    /// From the stable code (`None` for 0, healthy, and unknown codes).
    pub const fn from_code(code: u8) -> Option<SensorFault> {
        match code {
            1 => Some(SensorFault::Short),
            2 => Some(SensorFault::Open),
            3 => Some(SensorFault::Stuck),
            _ => None,
        }
    }
}

/// Temperature (deg C) of a reading, or why it is not one (open, short). The inverse of
/// [`pt1000::resistance_ohm`] through [`adc::counts_of_resistance`]: the quadratic's
/// root above 0 deg C, then (below 0 deg C) one Newton step with the C term. Agrees
/// with the IEC 60751 table to 1 mK over the sensor range (host test
/// `thermal::conversion_matches_the_iec_60751_table`).
pub fn celsius_from_counts(counts: u16) -> Result<f32, SensorFault> {
    let fs = f32::from(adc::FULL_SCALE_COUNTS);
    let c = f32::from(counts);
    if counts == adc::FULL_SCALE_COUNTS {
        return Err(SensorFault::Open);
    }
    let ratio = (adc::REFERENCE_OHM / pt1000::R0_OHM) as f32 * c / (fs - c);
    let a = pt1000::A_PER_K as f32;
    let b = pt1000::B_PER_K2 as f32;
    // B t^2 + A t + (1 - R/R0) = 0, the root near A t = R/R0 - 1, written without the
    // cancellation of -A + sqrt(...): t = 2 (R/R0 - 1) / (A + sqrt(A^2 + 4 B (R/R0 - 1))).
    let x = ratio - 1.0;
    let disc = a * a + 4.0 * b * x;
    if !(disc > 0.0) {
        return Err(SensorFault::Open);
    }
    let mut t = 2.0 * x / (a + <f32 as crate::kinematics::Real>::sqrt(disc));
    if t < 0.0 {
        // f(t) = A t + B t^2 + C (t - 100) t^3 - x; one Newton step from the quadratic's
        // root (the C term is below 2e-4 of R0 over the range).
        let cc = pt1000::C_PER_K4 as f32;
        let t2 = t * t;
        let f = a * t + b * t2 + cc * (t - 100.0) * t2 * t - x;
        let df = a + 2.0 * b * t + cc * (4.0 * t2 * t - 300.0 * t2);
        t -= f / df;
    }
    if t < SENSOR_MIN_C {
        Err(SensorFault::Short)
    } else if t > SENSOR_MAX_C || t.is_nan() {
        Err(SensorFault::Open)
    } else {
        Ok(t)
    }
}

/// Readings in a row with the very same count after which a sensor is stuck: with the
/// ADC's noise (about a count) a live channel repeats a count a few times at most; 64
/// readings (6.4 s at one reading per 100 ms) in a row is a stuck channel.
pub const STUCK_SAMPLES: u16 = 64;

/// Readings averaged into one temperature (the sensors' noise is about a count,
/// 0.017 K; the mean of 16 is below 5 mK).
pub const MEAN_SAMPLES: u16 = 16;

/// One sensor's supervision: the stuck check and the running mean. Its default (nothing
/// read yet) is all zero bytes, so a controller built in place zeroes it instead of
/// writing it field by field (the boot stack: `Controller::unstarted_in`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SensorMonitor {
    /// The last count read.
    last_counts: u16,
    /// Readings in a row with the count `last_counts` (the first one included).
    run: u16,
    /// Sum of the temperatures of the current window (deg C).
    sum_c: f32,
    /// Readings in the current window.
    n: u16,
    /// The last complete window's mean (deg C), valid when `has_mean`.
    mean_c: f32,
    /// A window has completed since the last fault (or since the start).
    has_mean: bool,
    /// The sensor's fault, [`SensorFault::code`], 0 when healthy (a fault ends only with
    /// a reading that is healthy again; the window restarts then).
    fault_code: u8,
}

impl SensorMonitor {
    /// Takes one reading.
    pub fn update(&mut self, counts: u16) {
        if counts == self.last_counts {
            self.run = self.run.saturating_add(1);
        } else {
            self.run = 1;
            self.last_counts = counts;
        }
        // Open and short first: a failed sensor repeats its count (full scale, 0), and
        // must keep reading as what it is, not become "stuck".
        let reading = match celsius_from_counts(counts) {
            Ok(_) if self.run >= STUCK_SAMPLES => Err(SensorFault::Stuck),
            r => r,
        };
        match reading {
            Err(f) => {
                self.fault_code = f.code();
                self.sum_c = 0.0;
                self.n = 0;
                self.has_mean = false;
            }
            Ok(t) => {
                self.fault_code = 0;
                self.sum_c += t;
                self.n += 1;
                if self.n >= MEAN_SAMPLES {
                    self.mean_c = self.sum_c / f32::from(self.n);
                    self.has_mean = true;
                    self.sum_c = 0.0;
                    self.n = 0;
                }
            }
        }
    }

    /// The sensor's temperature (deg C): the last window's mean, `None` while faulty or
    /// before a first window is complete.
    pub fn celsius(&self) -> Option<f32> {
        if self.fault_code == 0 && self.has_mean {
            Some(self.mean_c)
        } else {
            None
        }
    }

    /// The sensor's fault, if any.
    pub fn fault(&self) -> Option<SensorFault> {
        SensorFault::from_code(self.fault_code)
    }

    /// The sensor's fault code ([`SensorFault::code`]; 0 when healthy).
    pub fn fault_code(&self) -> u8 {
        self.fault_code
    }
}

/// A temperature in housekeeping ([`SensorBank::centi_kelvin`]) when the sensor has
/// none: faulty, or before its first complete mean ([`MEAN_SAMPLES`] readings). 0 K is
/// no temperature a sensor can read.
pub const NO_TEMPERATURE: u16 = 0;

/// 0 deg C in hundredths of a kelvin.
pub const ZERO_CELSIUS_CENTI_K: f32 = 27_315.0;

/// Every sensor's supervision ([`SensorMonitor`]), as the controller keeps it: one
/// reading of every channel per [`crate::timing::TEMPERATURE_PERIOD_CYCLES`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SensorBank {
    monitors: [SensorMonitor; TEMP_SENSORS],
}

impl SensorBank {
    /// Takes one reading of every channel (channel `i` is sensor `i`).
    pub fn update(&mut self, counts: &[u16; TEMP_SENSORS]) {
        for (m, c) in self.monitors.iter_mut().zip(counts.iter()) {
            m.update(*c);
        }
    }

    /// Each sensor's mean (deg C; [`SensorMonitor::celsius`]).
    pub fn celsius(&self) -> [Option<f32>; TEMP_SENSORS] {
        self.monitors.map(|m| m.celsius())
    }

    /// Sensor `i`'s mean (deg C; [`SensorMonitor::celsius`]); `None` for no such sensor.
    pub fn sensor_celsius(&self, i: usize) -> Option<f32> {
        self.monitors.get(i).and_then(SensorMonitor::celsius)
    }

    /// Each sensor's mean in hundredths of a kelvin (0.01 K; `T / K * 100`), rounded to
    /// the nearest, or [`NO_TEMPERATURE`]: an unsigned 16-bit word holds every
    /// temperature from 0 to 655.35 K, the sensors' range (-60 to +100 deg C) as 21,315
    /// to 37,315.
    pub fn centi_kelvin(&self) -> [u16; TEMP_SENSORS] {
        self.monitors.map(|m| match m.celsius() {
            // Positive over the sensors' range: `as` truncates, so + 0.5 rounds (and
            // saturates; NaN, which a mean never is, would give NO_TEMPERATURE).
            Some(t) => (t * 100.0 + ZERO_CELSIUS_CENTI_K + 0.5) as u16,
            None => NO_TEMPERATURE,
        })
    }

    /// Sensors with fault `fault` now (bit i = sensor i).
    pub fn with_fault(&self, fault: SensorFault) -> u8 {
        let mut mask = 0u8;
        for (i, m) in self.monitors.iter().enumerate() {
            if m.fault_code() == fault.code() {
                mask |= 1u8.wrapping_shl(i as u32);
            }
        }
        mask
    }

    /// Sensors with any fault now (bit i = sensor i).
    pub fn faulty(&self) -> u8 {
        self.with_fault(SensorFault::Short)
            | self.with_fault(SensorFault::Open)
            | self.with_fault(SensorFault::Stuck)
    }
}

/// The part classes of the thermal model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Part {
    /// The rods (their length).
    Rod = 0,
    /// The slider columns (the lower joint's height at zero stroke).
    Column = 1,
    /// The base plate (the lower joints' horizontal positions).
    Base = 2,
    /// The moving platform (the upper joints).
    Platform = 3,
}

/// Number of part classes ([`Part`]).
pub const PARTS: usize = 4;

/// Largest accepted expansion coefficient (1/K): above any structural metal's
/// (aluminium 23e-6, steel 12e-6, titanium 8.6e-6, Invar 1.2e-6).
pub const MAX_EXPANSION_PER_K: f32 = 1.0e-4;
/// Largest accepted slider-column length (mm).
pub const MAX_COLUMN_LENGTH_MM: f32 = 1000.0;

/// The calibrated table's thermal model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalModel {
    /// The temperature at which the table's geometry holds (deg C).
    pub reference_c: f32,
    /// Linear expansion coefficient of each part class, by [`Part`] (1/K); 0 leaves the
    /// part uncompensated.
    pub expansion_per_k: [f32; PARTS],
    /// Effective length of a slider column, from its foot to the lower joint at zero
    /// stroke, along base z (mm).
    pub column_length_mm: f32,
    /// Which sensor (0-based) governs each part of each leg, `[leg][Part]`.
    pub sensor_of: [[u8; PARTS]; LEGS],
}

/// Why a thermal model is refused: the detail of the table validation's error 0x041d.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ThermalModelError {
    /// Reference temperature outside the sensors' range, or not finite.
    Reference,
    /// An expansion coefficient negative, above [`MAX_EXPANSION_PER_K`] or not finite.
    Expansion,
    /// Column length negative, above [`MAX_COLUMN_LENGTH_MM`] or not finite.
    ColumnLength,
    /// A sensor index beyond [`TEMP_SENSORS`].
    Sensor,
}

impl ThermalModelError {
    /// Stable code (the detail word of the table validation's 0x041d).
    pub const fn code(self) -> u8 {
        match self {
            ThermalModelError::Reference => 1,
            ThermalModelError::Expansion => 2,
            ThermalModelError::ColumnLength => 3,
            ThermalModelError::Sensor => 4,
        }
    }
}

/// `lo <= x <= hi` (false for NaN).
fn within(x: f32, lo: f32, hi: f32) -> bool {
    x >= lo && x <= hi
}

impl ThermalModel {
    /// No compensation: every coefficient 0 (the nominal table's model).
    pub const NONE: ThermalModel = ThermalModel {
        reference_c: 20.0,
        expansion_per_k: [0.0; PARTS],
        column_length_mm: 0.0,
        sensor_of: [[0; PARTS]; LEGS],
    };

    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), ThermalModelError> {
        if !within(self.reference_c, SENSOR_MIN_C, SENSOR_MAX_C) {
            return Err(ThermalModelError::Reference);
        }
        if !self
            .expansion_per_k
            .iter()
            .all(|a| within(*a, 0.0, MAX_EXPANSION_PER_K))
        {
            return Err(ThermalModelError::Expansion);
        }
        if !within(self.column_length_mm, 0.0, MAX_COLUMN_LENGTH_MM) {
            return Err(ThermalModelError::ColumnLength);
        }
        if self
            .sensor_of
            .iter()
            .flatten()
            .any(|s| usize::from(*s) >= TEMP_SENSORS)
        {
            return Err(ThermalModelError::Sensor);
        }
        Ok(())
    }

    /// The sensors the model reads (bit i = sensor i): those governing a part whose
    /// coefficient is not 0.
    pub fn sensors_used(&self) -> u8 {
        let mut used = 0u8;
        for leg in &self.sensor_of {
            for (s, a) in leg.iter().zip(self.expansion_per_k.iter()) {
                if *a != 0.0 {
                    used |= 1u8.wrapping_shl(u32::from(*s));
                }
            }
        }
        used
    }
}

/// Change of each slider's stroke (mm, along base z) that keeps `pose` (internal
/// frames: mm, rad, as the IK takes it) where the reference-temperature geometry puts
/// it, with the parts at `temps_c` (deg C, by sensor); the module's formula. `None`
/// when a leg cannot reach the pose or a governing sensor's index is out of range.
pub fn stroke_offsets_mm(
    model: &ThermalModel,
    geom: &Geometry<f32>,
    pose: &Pose<f32>,
    temps_c: &[f32; TEMP_SENSORS],
) -> Option<[f32; LEGS]> {
    let rot = RotationDelta::new(&pose.rotation_rad);
    let mut out = [0.0f32; LEGS];
    for ((ds, leg), sensors) in out
        .iter_mut()
        .zip(geom.legs.iter())
        .zip(model.sensor_of.iter())
    {
        // The leg at the pose (as `kinematics::ik::leg_state`, without the stroke and
        // its fast square root: one plain root a second is cheaper in flash than a third
        // inlined copy of the IK's): the upper joint relative to M's origin `rb`, the
        // rod's horizontal components `h` and its vertical one `q` (`|d0|` is the rod).
        let b = [leg.b_mm.x, leg.b_mm.y, leg.b_mm.z];
        let wb = mat_vec3(&rot.w, &b);
        let rb = add3(&b, &wb);
        let t = &pose.translation_mm;
        let h_x = leg.d0_mm.x + wb[0] + t[0];
        let h_y = leg.d0_mm.y + wb[1] + t[1];
        let l = leg.rod_mm;
        let q2 = l * l - h_x * h_x - h_y * h_y;
        if !(q2 > 0.0) {
            return None;
        }
        let q = <f32 as crate::kinematics::Real>::sqrt(q2);
        let mut e = [0.0f32; PARTS];
        for ((e, s), a) in e
            .iter_mut()
            .zip(sensors.iter())
            .zip(model.expansion_per_k.iter())
        {
            *e = *a * (*temps_c.get(usize::from(*s))? - model.reference_c);
        }
        let a = &leg.a_mm;
        // In `Part` order.
        let [e_rod, e_column, e_base, e_platform] = e;
        let [rb_x, rb_y, rb_z] = rb;
        *ds = -e_column * model.column_length_mm
            - e_rod * l * l / q
            - e_base * (h_x * a.x + h_y * a.y) / q
            + e_platform * (rb_z + (h_x * rb_x + h_y * rb_y) / q);
    }
    Some(out)
}
