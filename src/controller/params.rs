//! On-board parameters (PUS ST[20]): the operator's pivot and user frame, the motion
//! limits, the housekeeping period and overrides of the table's supervision thresholds.
//!
//! Every parameter is an `i32` on the wire in an integer unit (nm, nm/s, milli-arcsec,
//! control cycles), with a validated range ([`PARAMETERS`]). A parameter that was never
//! set has its default: a compiled-in one, or for the supervision thresholds the running
//! table's value (so a table activation changes them unless they are overridden here).
//!
//! Set (TC[20,3]) is all-or-nothing, at rest only; the new set is persisted with the
//! selection record (power-cut safe, two slots, `table::store`) by the background
//! worker and applied when it is written (the telecommand completes then). Report
//! (TC[20,1]) answers TM[20,2] with the effective values.
//!
//! ## Protection against upsets
//! The parameters in force are kept with a check word ([`InForce`]: the CRC-32 of their
//! persisted form), so that any flipped bit of a value, of the set mask or of the check
//! word itself is found: by the RAM scrub every second, and before the parameters are
//! used to build a new set, a report or a table's settings. The repair re-reads them
//! from their persisted record (the one the next boot reads), never from RAM, so an
//! upset value is neither adopted nor written back to flash.
//!
//! ## Warning below fault, whichever side changes
//! The following-error warning threshold in force must stay below the fault threshold
//! in force (each an override here, or the running table's). The combination is checked
//! whenever either side changes: a set is refused (0x0722); a table job (activate,
//! switch bank, revert to nominal) whose table would conflict with the overrides fails
//! with 0x0722 before anything is persisted ([`Parameters::following_conflict`]); and a
//! persisted set that conflicts with the table that boots (or is out of range) is not
//! applied as it stands ([`Parameters::from_persisted`]): the conflicting overrides are
//! left out, event 0x0041 names them, and the table's thresholds run.

use crate::kinematics::{Frames, LEGS};
use crate::motion::{
    MotionLimits, DEFAULT_DIRECT_ACCEL_MM_PER_S2, DEFAULT_DIRECT_MAX_DELTA_MM,
    DEFAULT_DIRECT_SPEED_MM_PER_S, DEFAULT_MAX_ACCEL_MM_PER_S2, DEFAULT_MAX_SPEED_MM_PER_S,
};
use crate::supervision::SupervisionConfig;
use crate::table::store::PARAMETERS_LEN;
use crate::table::Table;
use crate::thermal::compensation::{self, CompensationParams};
use crate::timing::HK_PERIOD_CYCLES;
use crate::units::{ARCSEC_PER_RAD, MAS_PER_ARCSEC, NM_PER_MM, NM_PER_MM_F32};

/// What a parameter's default is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Default {
    /// A compiled-in value (wire units).
    Fixed(i32),
    /// The running table's supervision threshold (converted to wire units).
    Table,
}

/// One on-board parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamDef {
    /// Parameter ID (ST[20]).
    pub id: u16,
    /// Name (mission database, ICD). Host builds only: the flight code never reads it
    /// (the names and units with their pointers were 616 bytes of the flight image).
    #[cfg(feature = "host")]
    pub name: &'static str,
    /// Unit of the wire value. Host builds only, as `name`.
    #[cfg(feature = "host")]
    pub unit: &'static str,
    /// Smallest accepted value.
    pub min: i32,
    /// Largest accepted value.
    pub max: i32,
    /// The value when not set.
    pub default: Default,
}

const fn p(
    id: u16,
    name: &'static str,
    unit: &'static str,
    min: i32,
    max: i32,
    d: Default,
) -> ParamDef {
    // The flight image keeps neither (see the fields).
    #[cfg(not(feature = "host"))]
    let _ = (name, unit);
    ParamDef {
        id,
        #[cfg(feature = "host")]
        name,
        #[cfg(feature = "host")]
        unit,
        min,
        max,
        default: d,
    }
}

const fn nm(mm: f32) -> i32 {
    (mm * NM_PER_MM_F32) as i32
}

/// Pivot / user-frame range: +-1 m (nm), +-180 deg (mas).
const PIVOT_LIMIT_NM: i32 = 1_000_000_000;
const USER_ROTATION_LIMIT_MAS: i32 = 648_000_000;

/// Index of each parameter in [`PARAMETERS`].
pub mod index {
    /// Pivot x, y, z (in M, nm).
    pub const PIVOT: usize = 0;
    /// User frame alpha, beta, gamma (mas).
    pub const USER: usize = 3;
    /// Coordinated-move speed limit (nm/s).
    pub const MOVE_SPEED: usize = 6;
    /// Coordinated-move acceleration limit (nm/s^2).
    pub const MOVE_ACCEL: usize = 7;
    /// Direct-stroke speed limit (nm/s).
    pub const DIRECT_SPEED: usize = 8;
    /// Direct-stroke acceleration limit (nm/s^2).
    pub const DIRECT_ACCEL: usize = 9;
    /// Largest direct-stroke move (nm).
    pub const DIRECT_MAX_DELTA: usize = 10;
    /// Housekeeping period (cycles).
    pub const HK_PERIOD: usize = 11;
    /// Following warning threshold (nm).
    pub const FOLLOWING_WARNING: usize = 12;
    /// Following fault threshold (nm).
    pub const FOLLOWING_FAULT: usize = 13;
    /// Encoder jump threshold (nm per cycle).
    pub const JUMP: usize = 14;
    /// Stuck detection least progress (nm).
    pub const STUCK_PROGRESS: usize = 15;
    /// Stuck detection window (cycles).
    pub const STUCK_WINDOW: usize = 16;
    /// Warning debounce (cycles).
    pub const WARNING_DEBOUNCE: usize = 17;
    /// Fault debounce (cycles).
    pub const FAULT_DEBOUNCE: usize = 18;
    /// In-position tolerance of every slider encoder about its setpoint (nm).
    pub const IN_POSITION_TOLERANCE: usize = 19;
    /// In-position dwell (cycles).
    pub const IN_POSITION_DWELL: usize = 20;
    /// Thermal compensation enabled (1) or not (0).
    pub const THERMAL_ENABLE: usize = 21;
    /// Thermal compensation's largest step per leg (nm).
    pub const THERMAL_MAX_STEP: usize = 22;
    /// Thermal compensation's smallest step (nm): the dead band.
    pub const THERMAL_MIN_STEP: usize = 23;
}

/// Number of parameters.
pub const N_PARAMETERS: usize = 24;

/// Default in-position tolerance (nm): one encoder count (0.1 um), the accuracy issue
/// 21 asks of every slider.
pub const DEFAULT_IN_POSITION_TOLERANCE_NM: i32 = MIN_IN_POSITION_TOLERANCE_NM;
/// Smallest in-position tolerance (nm): one encoder count
/// ([`crate::hw::ENCODER_MM_PER_COUNT`]); a reading is a whole count, so a finer
/// tolerance could not be met by a slider between two counts.
pub const MIN_IN_POSITION_TOLERANCE_NM: i32 = (crate::hw::ENCODER_MM_PER_COUNT * NM_PER_MM) as i32;
/// Default in-position dwell (cycles, 20 ms): four settling time constants of the
/// realistic drive train (`sim::drive_train::DEFAULT_SETTLING_TIME_CONSTANT_S`, 5 ms:
/// 98 % settled), and the wait before each correction of the fine positioning.
pub const DEFAULT_IN_POSITION_DWELL_CYCLES: i32 = 20;
/// Largest in-position dwell (cycles): with `motion::fine::MAX_CORRECTIONS` waits of it
/// and the corrections themselves the fine positioning stays within its timeout
/// (`motion::fine::TIMEOUT_CYCLES`).
pub const MAX_IN_POSITION_DWELL_CYCLES: i32 = 200;

/// Every parameter, in index order (module [`index`]).
pub const PARAMETERS: [ParamDef; N_PARAMETERS] = [
    p(
        0x0001,
        "pivot_x",
        "nm",
        -PIVOT_LIMIT_NM,
        PIVOT_LIMIT_NM,
        Default::Fixed(0),
    ),
    p(
        0x0002,
        "pivot_y",
        "nm",
        -PIVOT_LIMIT_NM,
        PIVOT_LIMIT_NM,
        Default::Fixed(0),
    ),
    p(
        0x0003,
        "pivot_z",
        "nm",
        -PIVOT_LIMIT_NM,
        PIVOT_LIMIT_NM,
        Default::Fixed(0),
    ),
    p(
        0x0004,
        "user_alpha",
        "mas",
        -USER_ROTATION_LIMIT_MAS,
        USER_ROTATION_LIMIT_MAS,
        Default::Fixed(0),
    ),
    p(
        0x0005,
        "user_beta",
        "mas",
        -USER_ROTATION_LIMIT_MAS,
        USER_ROTATION_LIMIT_MAS,
        Default::Fixed(0),
    ),
    p(
        0x0006,
        "user_gamma",
        "mas",
        -USER_ROTATION_LIMIT_MAS,
        USER_ROTATION_LIMIT_MAS,
        Default::Fixed(0),
    ),
    p(
        0x0010,
        "move_speed",
        "nm/s",
        1_000,
        500_000,
        Default::Fixed(nm(DEFAULT_MAX_SPEED_MM_PER_S)),
    ),
    p(
        0x0011,
        "move_accel",
        "nm/s^2",
        1_000,
        5_000_000,
        Default::Fixed(nm(DEFAULT_MAX_ACCEL_MM_PER_S2)),
    ),
    p(
        0x0012,
        "direct_speed",
        "nm/s",
        1_000,
        100_000,
        Default::Fixed(nm(DEFAULT_DIRECT_SPEED_MM_PER_S)),
    ),
    p(
        0x0013,
        "direct_accel",
        "nm/s^2",
        1_000,
        5_000_000,
        Default::Fixed(nm(DEFAULT_DIRECT_ACCEL_MM_PER_S2)),
    ),
    p(
        0x0014,
        "direct_max_delta",
        "nm",
        1_000,
        1_000_000,
        Default::Fixed(nm(DEFAULT_DIRECT_MAX_DELTA_MM)),
    ),
    p(
        0x0020,
        "hk_period",
        "cycles",
        100,
        60_000,
        Default::Fixed(HK_PERIOD_CYCLES as i32),
    ),
    p(
        0x0030,
        "following_warning",
        "nm",
        100,
        1_000_000,
        Default::Table,
    ),
    p(
        0x0031,
        "following_fault",
        "nm",
        100,
        1_000_000,
        Default::Table,
    ),
    p(
        0x0032,
        "encoder_jump",
        "nm/cycle",
        10_000,
        1_000_000,
        Default::Table,
    ),
    p(0x0033, "stuck_progress", "nm", 100, 100_000, Default::Table),
    p(0x0034, "stuck_window", "cycles", 10, 10_000, Default::Table),
    p(
        0x0035,
        "warning_debounce",
        "cycles",
        1,
        1_000,
        Default::Table,
    ),
    p(0x0036, "fault_debounce", "cycles", 1, 1_000, Default::Table),
    p(
        0x0015,
        "in_position_tolerance",
        "nm",
        MIN_IN_POSITION_TOLERANCE_NM,
        100_000,
        Default::Fixed(DEFAULT_IN_POSITION_TOLERANCE_NM),
    ),
    p(
        0x0016,
        "in_position_dwell",
        "cycles",
        1,
        MAX_IN_POSITION_DWELL_CYCLES,
        Default::Fixed(DEFAULT_IN_POSITION_DWELL_CYCLES),
    ),
    // Off by default: the mirror holds what the operator commanded until the operator
    // enables the compensation (which then moves it only by bounded steps).
    p(0x0060, "thermal_compensation", "", 0, 1, Default::Fixed(0)),
    p(
        0x0061,
        "thermal_max_step",
        "nm",
        nm(compensation::MAX_STEP_LOWEST_MM),
        nm(compensation::MAX_STEP_HIGHEST_MM),
        Default::Fixed(nm(compensation::DEFAULT_MAX_STEP_MM)),
    ),
    // Its highest accepted value is the maximum step in force (checked by `with`).
    p(
        0x0062,
        "thermal_min_step",
        "nm",
        nm(compensation::MIN_STEP_LOWEST_MM),
        nm(compensation::MAX_STEP_HIGHEST_MM),
        Default::Fixed(nm(compensation::DEFAULT_MIN_STEP_MM)),
    ),
];

/// Why a parameter set or report was refused (family 0x07xx, from 0x0720).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamError {
    /// 0x0720: no parameter with this ID (data: the ID).
    UnknownId(u16),
    /// 0x0723: the telecommand names this ID more than once (data: the ID).
    Repeated(u16),
    /// 0x0721: a value outside its range (data: the ID).
    OutOfRange(u16),
    /// 0x0722: the following warning threshold would not be below the fault threshold
    /// (data: 0).
    WarningNotBelowFault,
    /// 0x0724: the thermal compensation's dead band (0x0062) would be above its largest
    /// step (0x0061), the effective values after the set (data: 0).
    DeadBandAboveStep,
}

impl ParamError {
    /// Stable code.
    pub const fn code(&self) -> u16 {
        match self {
            ParamError::UnknownId(_) => 0x0720,
            ParamError::OutOfRange(_) => 0x0721,
            ParamError::WarningNotBelowFault => 0x0722,
            ParamError::Repeated(_) => 0x0723,
            ParamError::DeadBandAboveStep => 0x0724,
        }
    }

    /// Failure datum.
    pub const fn data(&self) -> u32 {
        match self {
            ParamError::UnknownId(id) | ParamError::OutOfRange(id) | ParamError::Repeated(id) => {
                *id as u32
            }
            ParamError::WarningNotBelowFault | ParamError::DeadBandAboveStep => 0,
        }
    }
}

/// The index of parameter `id`.
pub fn index_of(id: u16) -> Option<usize> {
    PARAMETERS.iter().position(|d| d.id == id)
}

/// The parameters a TC[20,1] or TC[20,3] names (bit i = parameter index i), checked in
/// the telecommand's order: an unknown ID is 0x0720, an ID named twice 0x0723.
pub fn named_mask(ids: impl Iterator<Item = u16>) -> Result<u32, ParamError> {
    let mut mask = 0u32;
    for id in ids {
        let bit = 1u32 << index_of(id).ok_or(ParamError::UnknownId(id))?;
        if mask & bit != 0 {
            return Err(ParamError::Repeated(id));
        }
        mask |= bit;
    }
    Ok(mask)
}

/// The parameters set on board (a bit and a value per parameter).
#[derive(Clone, Copy, Debug, PartialEq, Eq, core::default::Default)]
pub struct Parameters {
    /// Bit i: parameter i is set.
    set: u32,
    values: [i32; N_PARAMETERS],
}

/// The parameters in force and their check word (module documentation, "Protection
/// against upsets").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InForce {
    params: Parameters,
    /// CRC-32 (ISO-HDLC) of `params.encode()`.
    check: u32,
}

impl InForce {
    /// `params` with their check word.
    pub fn new(params: Parameters) -> Self {
        Self {
            check: params.check_word(),
            params,
        }
    }

    /// The parameters as they are in RAM (for telemetry; unchecked).
    pub const fn params(&self) -> &Parameters {
        &self.params
    }

    /// The parameters if they still agree with their check word.
    pub fn checked(&self) -> Option<&Parameters> {
        (self.params.check_word() == self.check).then_some(&self.params)
    }

    /// Test hook (host): flips bit `bit` of the RAM word `word` (0: the set mask, 1..=N
    /// the values, N + 1: the check word; N = [`N_PARAMETERS`]), as a radiation upset would.
    #[cfg(feature = "host")]
    pub fn upset(&mut self, word: usize, bit: u32) {
        let m = 1u32.checked_shl(bit).unwrap_or(0);
        match word {
            0 => self.params.set ^= m,
            w if w <= N_PARAMETERS => {
                if let Some(v) = self.params.values.get_mut(w - 1) {
                    *v ^= m as i32;
                }
            }
            _ => self.check ^= m,
        }
    }
}

/// Byte offsets in the persisted payload.
const PAYLOAD_SET_MASK: usize = 0;
const PAYLOAD_VALUES: usize = 4;
const _: () = assert!(PAYLOAD_VALUES + 4 * N_PARAMETERS <= PARAMETERS_LEN);

impl Parameters {
    /// None set.
    pub const fn none() -> Self {
        Self {
            set: 0,
            values: [0; N_PARAMETERS],
        }
    }

    /// The set-bit mask (housekeeping).
    pub const fn set_mask(&self) -> u32 {
        self.set
    }

    /// CRC-32 of the persisted form: [`InForce`]'s check word.
    pub fn check_word(&self) -> u32 {
        crate::table::layout::CRC32.checksum(&self.encode())
    }

    /// What runs from a persisted set with `table` (at boot, and when the repair of an
    /// upset re-reads them): [`Parameters::decode`], then the following-error overrides
    /// left out if they would leave the warning not below the fault threshold (module
    /// documentation). Also returns the set bits not applied (event 0x0041's aux0).
    pub fn from_persisted(bytes: &[u8; PARAMETERS_LEN], table: &Table) -> (Self, u32) {
        let mut p = Self::decode(bytes);
        if p.following_conflict(table) {
            p.set &= !((1 << index::FOLLOWING_WARNING) | (1 << index::FOLLOWING_FAULT));
        }
        let stored = u32::from_le_bytes(
            bytes
                .get(PAYLOAD_SET_MASK..PAYLOAD_SET_MASK + 4)
                .and_then(|b| b.try_into().ok())
                .unwrap_or([0; 4]),
        );
        let known = (1u32 << N_PARAMETERS) - 1;
        (p, stored & known & !p.set)
    }

    /// The following warning threshold in force would not be below the fault threshold
    /// in force with `table` running.
    pub fn following_conflict(&self, table: &Table) -> bool {
        self.value(index::FOLLOWING_WARNING, table) >= self.value(index::FOLLOWING_FAULT, table)
    }

    /// The persisted form (little-endian: set mask, then each value).
    pub fn encode(&self) -> [u8; PARAMETERS_LEN] {
        let mut out = [0u8; PARAMETERS_LEN];
        for (d, s) in out
            .iter_mut()
            .skip(PAYLOAD_SET_MASK)
            .zip(self.set.to_le_bytes())
        {
            *d = s;
        }
        for (k, v) in self.values.iter().enumerate() {
            for (d, s) in out
                .iter_mut()
                .skip(PAYLOAD_VALUES + 4 * k)
                .zip(v.to_le_bytes())
            {
                *d = s;
            }
        }
        out
    }

    /// From the persisted form; values out of range (or bits of unknown parameters)
    /// are dropped, so what runs is always in range.
    pub fn decode(bytes: &[u8; PARAMETERS_LEN]) -> Self {
        let word = |at: usize| -> u32 {
            bytes
                .get(at..at + 4)
                .and_then(|b| b.try_into().ok())
                .map_or(0, u32::from_le_bytes)
        };
        let mut p = Self::none();
        let mask = word(PAYLOAD_SET_MASK);
        for (k, def) in PARAMETERS.iter().enumerate() {
            let v = word(PAYLOAD_VALUES + 4 * k) as i32;
            if mask & (1 << k) != 0 && (def.min..=def.max).contains(&v) {
                p.set |= 1 << k;
                if let Some(dst) = p.values.get_mut(k) {
                    *dst = v;
                }
            }
        }
        p
    }

    /// The effective value of parameter `k` with `table` running.
    pub fn value(&self, k: usize, table: &Table) -> i32 {
        if self.set & (1 << k) != 0 {
            return self.values.get(k).copied().unwrap_or(0);
        }
        match PARAMETERS.get(k).map(|d| d.default) {
            Some(Default::Fixed(v)) => v,
            Some(Default::Table) => table_value(k, table),
            None => 0,
        }
    }

    /// [`Parameters::value`] of a length parameter (nm) in mm (f32, rounded from the f64
    /// quotient). Out of line: each of its ~15 flight uses was an inlined copy.
    #[inline(never)]
    fn value_mm(&self, k: usize, table: &Table) -> f32 {
        (f64::from(self.value(k, table)) / NM_PER_MM) as f32
    }

    /// These parameters with `updates` (ID, value) applied: all-or-nothing.
    pub fn with(&self, updates: &[(u16, i32)], table: &Table) -> Result<Self, ParamError> {
        let mut p = *self;
        let mut named = 0u32;
        for (id, v) in updates {
            let k = index_of(*id).ok_or(ParamError::UnknownId(*id))?;
            let def = PARAMETERS.get(k).ok_or(ParamError::UnknownId(*id))?;
            if named & (1 << k) != 0 {
                return Err(ParamError::Repeated(*id));
            }
            named |= 1 << k;
            if !(def.min..=def.max).contains(v) {
                return Err(ParamError::OutOfRange(*id));
            }
            p.set |= 1 << k;
            if let Some(dst) = p.values.get_mut(k) {
                *dst = *v;
            }
        }
        if p.following_conflict(table) {
            return Err(ParamError::WarningNotBelowFault);
        }
        // The dead band's range ends at the largest step in force (each alone is in its
        // range here, so only this combination can fail).
        if p.thermal(table).1.validate().is_err() {
            return Err(ParamError::DeadBandAboveStep);
        }
        Ok(p)
    }

    /// The pivot and user frame (f32 working units).
    pub fn frames(&self, table: &Table) -> Frames<f32> {
        let v = |k: usize| self.value(k, table);
        let mm = |k: usize| self.value_mm(k, table);
        let rad = |k: usize| (f64::from(v(k)) / MAS_PER_ARCSEC / ARCSEC_PER_RAD) as f32;
        Frames::new(
            [mm(index::PIVOT), mm(index::PIVOT + 1), mm(index::PIVOT + 2)],
            [rad(index::USER), rad(index::USER + 1), rad(index::USER + 2)],
        )
    }

    /// Coordinated-move limits (every slider the same).
    pub fn motion_limits(&self, table: &Table) -> MotionLimits {
        let mm = |k: usize| self.value_mm(k, table);
        MotionLimits {
            max_speed_mm_per_s: [mm(index::MOVE_SPEED); LEGS],
            max_accel_mm_per_s2: [mm(index::MOVE_ACCEL); LEGS],
        }
    }

    /// Direct-stroke speed, acceleration, largest delta (mm/s, mm/s^2, mm).
    pub fn direct_limits(&self, table: &Table) -> (f32, f32, f32) {
        let mm = |k: usize| self.value_mm(k, table);
        (
            mm(index::DIRECT_SPEED),
            mm(index::DIRECT_ACCEL),
            mm(index::DIRECT_MAX_DELTA),
        )
    }

    /// The output stage's limits (`motion::limiter`): coordinated and direct-stroke
    /// speed and acceleration (mm/s, mm/s^2).
    pub fn step_limits(&self, table: &Table) -> crate::motion::StepLimits {
        let mm = |k: usize| self.value_mm(k, table);
        crate::motion::StepLimits {
            coordinated: (mm(index::MOVE_SPEED), mm(index::MOVE_ACCEL)),
            direct: (mm(index::DIRECT_SPEED), mm(index::DIRECT_ACCEL)),
        }
    }

    /// The in-position rule: tolerance of every slider encoder about its setpoint (mm)
    /// and dwell (cycles).
    pub fn in_position(&self, table: &Table) -> (f32, u16) {
        let tol = self.value_mm(index::IN_POSITION_TOLERANCE, table);
        let dwell = u16::try_from(self.value(index::IN_POSITION_DWELL, table)).unwrap_or(1);
        (tol, dwell)
    }

    /// Thermal compensation enabled, and its steps (mm), with `table` running (their
    /// defaults are compiled in: no table changes them).
    pub fn thermal(&self, table: &Table) -> (bool, CompensationParams) {
        let mm = |k: usize| self.value_mm(k, table);
        (
            self.value(index::THERMAL_ENABLE, table) != 0,
            CompensationParams {
                max_step_mm: mm(index::THERMAL_MAX_STEP),
                min_step_mm: mm(index::THERMAL_MIN_STEP),
            },
        )
    }

    /// Housekeeping period (cycles).
    pub fn hk_period_cycles(&self, table: &Table) -> u32 {
        self.value(index::HK_PERIOD, table).unsigned_abs().max(1)
    }

    /// The supervision configuration: the table's exactly, with the overrides set here.
    pub fn supervision(&self, table: &Table) -> SupervisionConfig {
        let mut c = SupervisionConfig::from_table(table);
        let set = |k: usize| self.set & (1 << k) != 0;
        let raw = |k: usize| self.values.get(k).copied().unwrap_or(0);
        // Read only where set, where `value` is the stored (raw) value: the same quotient.
        let mm = |k: usize| self.value_mm(k, table);
        let cycles = |k: usize| u16::try_from(raw(k)).unwrap_or(u16::MAX);
        if set(index::FOLLOWING_WARNING) {
            c.following_warning_mm = mm(index::FOLLOWING_WARNING);
        }
        if set(index::FOLLOWING_FAULT) {
            c.following_fault_mm = mm(index::FOLLOWING_FAULT);
        }
        if set(index::JUMP) {
            c.jump_mm_per_cycle = mm(index::JUMP);
        }
        if set(index::STUCK_PROGRESS) {
            c.stuck_min_progress_mm = mm(index::STUCK_PROGRESS);
        }
        if set(index::STUCK_WINDOW) {
            c.stuck_window_cycles = cycles(index::STUCK_WINDOW);
        }
        if set(index::WARNING_DEBOUNCE) {
            c.debounce.following_warning = cycles(index::WARNING_DEBOUNCE);
        }
        if set(index::FAULT_DEBOUNCE) {
            let fault = cycles(index::FAULT_DEBOUNCE);
            c.debounce.following_fault = fault;
            c.debounce.soft_limit = fault;
            c.debounce.fk = fault;
            c.debounce.workspace = fault;
        }
        c
    }
}

/// The table's value of supervision parameter `k`, in wire units.
fn table_value(k: usize, table: &Table) -> i32 {
    let s = &table.supervision;
    let nm = |mm: f32| crate::link::wire::mm_to_nm_f32(mm);
    match k {
        index::FOLLOWING_WARNING => nm(s.following_error_warning_mm),
        index::FOLLOWING_FAULT => nm(s.following_error_fault_mm),
        index::JUMP => nm(s.encoder_jump_mm_per_cycle),
        index::STUCK_PROGRESS => nm(s.stuck_min_progress_mm),
        index::STUCK_WINDOW => i32::from(s.stuck_detection_cycles),
        index::WARNING_DEBOUNCE => i32::from(s.warning_debounce_cycles),
        index::FAULT_DEBOUNCE => i32::from(s.fault_debounce_cycles),
        _ => 0,
    }
}
