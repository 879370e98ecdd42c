//! The housekeeping report TM[3,25]: [`Housekeeping`] and its byte layout.
//!
//! # Layout
//!
//! The source data of TM[3,25] is [`HK_REPORT_LEN`] = 279 bytes, big-endian, laid out by
//! the named field ranges of [`field`] (smoltcp's `mod field`): the one description of
//! the report's bytes. [`Housekeeping::emit`] writes by them, [`Housekeeping::parse`]
//! reads by them, the mission database (`ground::mdb::housekeeping_rows`) takes each
//! field's offset from them, and docs/icd.md section 6's table is generated from the
//! mission database (`m2ground icd-tables`; `ground/tests/icd.rs` fails on drift). The
//! fields tile the report end to end (checked at compile time below).
//!
//! The four switch bytes are the last cycle's read (`hw::TravelSwitches`), unfiltered.
//! The temperatures are each sensor's last mean (`thermal::SensorBank`, a reading per
//! 100 ms, a mean of 16), in hundredths of a kelvin, 0 when the sensor has none (faulty,
//! or before its first mean); the three sensor masks say why (bit i = sensor i, the
//! channel of `thermal::ThermalModel::sensor_of`).

use super::command::WirePose;
use super::tm::TmTime;
use super::wire::{Field, Fields, Order, Writer};
use crate::kinematics::LEGS;
use crate::thermal::TEMP_SENSORS;

/// Structure ID of the one housekeeping report.
pub const HK_STRUCTURE_ID: u8 = 1;
/// Length of the TM[3,25] source data (bytes).
pub const HK_REPORT_LEN: usize = 279;
/// `selected_source` when no selection record exists.
pub const NO_SELECTION: u8 = 0xFF;

/// The housekeeping layout as named byte ranges, end to end from offset 0 (types
/// big-endian; poses are x, y, z in nm then alpha, beta, gamma in uas, each an i32; leg
/// arrays are legs 1..6; leg masks have bit i = leg i+1).
pub mod field {
    use crate::link::wire::{after, field, Field};

    /// u8: the structure ID ([`super::HK_STRUCTURE_ID`]).
    pub const STRUCTURE_ID: Field = field(0, 1);
    /// u8: controller state (the controller's enum code).
    pub const STATE: Field = after(&STRUCTURE_ID, 1);
    /// u8: boot source (0 nominal, 1 bank A, 2 bank B).
    pub const BOOT_SOURCE: Field = after(&STATE, 1);
    /// u8: bank of the running table (0 none/nominal, 1 A, 2 B).
    pub const ACTIVE_BANK: Field = after(&BOOT_SOURCE, 1);
    /// u8: last FK Newton iteration count.
    pub const FK_ITERATIONS: Field = after(&ACTIVE_BANK, 1);
    /// u8: 1 when the FK pose is this cycle's FK, 0 when FK failed.
    pub const FK_VALID: Field = after(&FK_ITERATIONS, 1);
    /// u32: control cycle counter (the cycle the report was sampled in).
    pub const CYCLE_COUNTER: Field = after(&FK_VALID, 4);
    /// u32: latched fault flags.
    pub const FAULT_FLAGS: Field = after(&CYCLE_COUNTER, 4);
    /// u32: warning flags.
    pub const WARNING_FLAGS: Field = after(&FAULT_FLAGS, 4);
    /// u32: refusal bits of the last refused move (`kinematics::Refusals::to_bits`).
    pub const REFUSAL_BITS: Field = after(&WARNING_FLAGS, 4);
    /// u32: running table ID.
    pub const ACTIVE_TABLE_ID: Field = after(&REFUSAL_BITS, 4);
    /// u32: running table CRC-32.
    pub const ACTIVE_TABLE_CRC32: Field = after(&ACTIVE_TABLE_ID, 4);
    /// 6 x i32: pose from FK of the encoders (nm, uas).
    pub const POSE_FK: Field = after(&ACTIVE_TABLE_CRC32, POSE_LEN);
    /// 6 x i32: commanded pose (nm, uas).
    pub const POSE_COMMANDED: Field = after(&POSE_FK, POSE_LEN);
    /// 6 x i32: commanded strokes (nm).
    pub const STROKES_COMMANDED: Field = after(&POSE_COMMANDED, LEGS_I32_LEN);
    /// 6 x i32: encoder readings (nm; multiples of one 100 nm count).
    pub const ENCODERS: Field = after(&STROKES_COMMANDED, LEGS_I32_LEN);
    /// u16: telecommands accepted (wrapping).
    pub const TC_ACCEPTED: Field = after(&ENCODERS, 2);
    /// u16: telecommands rejected (wrapping).
    pub const TC_REJECTED: Field = after(&TC_ACCEPTED, 2);
    /// u16: last failure code (0: none).
    pub const LAST_FAILURE_CODE: Field = after(&TC_REJECTED, 2);
    /// u8: legs commanded to move (leg mask).
    pub const MOVING_LEGS: Field = after(&LAST_FAILURE_CODE, 1);
    /// u8: legs named by the latched faults (leg mask).
    pub const FAULT_LEGS: Field = after(&MOVING_LEGS, 1);
    /// u8: bank of the pending (committed, not activated) table: 0 none, 1 A, 2 B.
    pub const PENDING_BANK: Field = after(&FAULT_LEGS, 1);
    /// u32: pending table ID (0 if none).
    pub const PENDING_TABLE_ID: Field = after(&PENDING_BANK, 4);
    /// u8: table job running: 0 none, 1 commit, 2 selection, 3 reload.
    pub const JOB: Field = after(&PENDING_TABLE_ID, 1);
    /// u8: what boots: 0 nominal, 1 A, 2 B, [`super::NO_SELECTION`] without a record.
    pub const SELECTED_SOURCE: Field = after(&JOB, 1);
    /// u16: telemetry records dropped (queue full; wrapping).
    pub const TM_DROPPED: Field = after(&SELECTED_SOURCE, 2);
    /// u16: telecommand frames dropped (too long or bad COBS; wrapping).
    pub const TC_FRAMES_DROPPED: Field = after(&TM_DROPPED, 2);
    /// u16: UART receive overruns and RX queue overflows (wrapping).
    pub const UART_OVERRUNS: Field = after(&TC_FRAMES_DROPPED, 2);
    /// u16: control-cycle overruns (wrapping).
    pub const CYCLE_OVERRUNS: Field = after(&UART_OVERRUNS, 2);
    /// u8: reset cause (the reset causes' codes).
    pub const RESET_CAUSE: Field = after(&CYCLE_OVERRUNS, 1);
    /// u16: boot count (wrapping).
    pub const BOOT_COUNT: Field = after(&RESET_CAUSE, 2);
    /// u8: flash bank health: bit 0 bank A, bit 1 bank B record corrupt.
    pub const BANK_HEALTH: Field = after(&BOOT_COUNT, 1);
    /// 3 x i32: the pivot in M's coordinates, x, y, z (nm).
    pub const PIVOT: Field = after(&BANK_HEALTH, PIVOT_LEN);
    /// 6 x i32: pose from FK in the operator's frames (pivot, user frame; nm, uas).
    pub const POSE_FK_OPERATOR: Field = after(&PIVOT, POSE_LEN);
    /// 6 x i32: commanded pose in the operator's frames (nm, uas).
    pub const POSE_COMMANDED_OPERATOR: Field = after(&POSE_FK_OPERATOR, POSE_LEN);
    /// u32: on-board parameters set (bit i = parameter index i).
    pub const PARAMETERS_SET: Field = after(&POSE_COMMANDED_OPERATOR, 4);
    /// u8: activities in the time-based schedule (0..16).
    pub const SCHEDULE_ACTIVITIES: Field = after(&PARAMETERS_SET, 1);
    /// u8: release enabled (1) or disabled (0).
    pub const SCHEDULE_RELEASE_ENABLED: Field = after(&SCHEDULE_ACTIVITIES, 1);
    /// u16: activities released since boot (wrapping).
    pub const SCHEDULE_RELEASED: Field = after(&SCHEDULE_RELEASE_ENABLED, 2);
    /// u16: released activities that failed (wrapping).
    pub const SCHEDULE_FAILED: Field = after(&SCHEDULE_RELEASED, 2);
    /// CUC 4+2: release time of the next activity (0 if none).
    pub const SCHEDULE_NEXT_RELEASE: Field = after(&SCHEDULE_FAILED, CUC_LEN);
    /// u8: time report rate: N of 2^N s, 255 off.
    pub const TIME_REPORT_RATE: Field = after(&SCHEDULE_NEXT_RELEASE, 1);
    /// u8: legs at the lower end-of-travel switch (leg mask).
    pub const LIMIT_LOWER_LEGS: Field = after(&TIME_REPORT_RATE, 1);
    /// u8: legs at the upper end-of-travel switch (leg mask).
    pub const LIMIT_UPPER_LEGS: Field = after(&LIMIT_LOWER_LEGS, 1);
    /// u8: legs at the reference (home) sensor (leg mask).
    pub const REFERENCE_LEGS: Field = after(&LIMIT_UPPER_LEGS, 1);
    /// u8: legs with a switch input that cannot be read (leg mask).
    pub const SWITCH_UNREADABLE_LEGS: Field = after(&REFERENCE_LEGS, 1);
    /// u8: legs whose encoder reads within the in-position tolerance (plus half a count)
    /// of the setpoint of the last coordinated move, or of where the drives were told to
    /// hold (leg mask; `motion::fine`).
    pub const IN_POSITION_LEGS: Field = after(&SWITCH_UNREADABLE_LEGS, 1);
    /// 8 x u16: each temperature sensor's mean (0.01 K; 0: none, the sensor faulty or
    /// before its first mean), sensors 0..7.
    pub const TEMPERATURES_CENTI_K: Field = after(&IN_POSITION_LEGS, TEMPERATURES_LEN);
    /// u8: temperature sensors open (sensor mask: bit i = sensor i).
    pub const SENSORS_OPEN: Field = after(&TEMPERATURES_CENTI_K, 1);
    /// u8: temperature sensors shorted (sensor mask).
    pub const SENSORS_SHORT: Field = after(&SENSORS_OPEN, 1);
    /// u8: temperature sensors stuck (sensor mask).
    pub const SENSORS_STUCK: Field = after(&SENSORS_SHORT, 1);
    /// u8: thermal compensation and exposure hold ([`super::thermal_state`] bits).
    pub const THERMAL_STATE: Field = after(&SENSORS_STUCK, 1);
    /// 6 x i32: the thermal compensation's applied stroke offset of each leg (nm, along
    /// base z): the drives hold the reported strokes plus these.
    pub const THERMAL_OFFSETS: Field = after(&THERMAL_STATE, LEGS_I32_LEN);

    /// Bytes of a wire pose (6 x i32).
    const POSE_LEN: usize = 24;
    /// Bytes of one i32 per leg.
    const LEGS_I32_LEN: usize = 4 * crate::kinematics::LEGS;
    /// Bytes of the pivot (3 x i32).
    const PIVOT_LEN: usize = 12;
    /// Bytes of a CUC 4+2 time.
    const CUC_LEN: usize = 6;
    /// Bytes of one u16 per temperature sensor.
    const TEMPERATURES_LEN: usize = 2 * crate::thermal::TEMP_SENSORS;
}

// The fields tile the report exactly.
const _: () = assert!(field::THERMAL_OFFSETS.end == HK_REPORT_LEN);

/// The bits of [`Housekeeping::thermal_state`].
pub mod thermal_state {
    /// The thermal compensation is enabled (parameter 0x0060).
    pub const ENABLED: u8 = 1 << 0;
    /// It is frozen at its last offset by a faulty sensor (event 0x0051).
    pub const FROZEN: u8 = 1 << 1;
    /// An exposure hold is in force (events 0x0052/0x0053).
    pub const EXPOSURE_HOLD: u8 = 1 << 2;
}

/// One housekeeping sample, filled by the controller.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Housekeeping {
    /// Controller state (the controller's `u8` enum code).
    pub state: u8,
    /// Boot source (`table::BootSource::code`: 0 nominal, 1 bank A, 2 bank B).
    pub boot_source: u8,
    /// Bank holding the active table (0 none/nominal, 1 A, 2 B).
    pub active_bank: u8,
    /// Newton iterations of the last FK.
    pub fk_iterations: u8,
    /// True when `pose_fk` comes from this cycle's successful FK.
    pub fk_valid: bool,
    /// Control cycle counter.
    pub cycle_counter: u32,
    /// Latched fault flags.
    pub fault_flags: u32,
    /// Warning flags.
    pub warning_flags: u32,
    /// Refusal bits of the last refused move (`kinematics::Refusals::to_bits`).
    pub refusal_bits: u32,
    /// Active table ID.
    pub active_table_id: u32,
    /// Active table CRC-32.
    pub active_table_crc32: u32,
    /// Pose from FK of the encoder readings (nm, uas).
    pub pose_fk: WirePose,
    /// Commanded pose (nm, uas).
    pub pose_commanded: WirePose,
    /// Commanded strokes, legs 1..6 (nm).
    pub strokes_commanded_nm: [i32; LEGS],
    /// Encoder readings, legs 1..6 (nm).
    pub encoders_nm: [i32; LEGS],
    /// Telecommands accepted (wrapping).
    pub tc_accepted: u16,
    /// Telecommands rejected (wrapping).
    pub tc_rejected: u16,
    /// Last failure code sent in a verification report (0: none).
    pub last_failure_code: u16,
    /// Legs currently commanded to move (bit i = leg i+1).
    pub moving_legs: u8,
    /// Legs named by the latched faults (bit i = leg i+1).
    pub fault_legs: u8,
    /// Bank of the pending table (0 none, 1 A, 2 B).
    pub pending_bank: u8,
    /// Pending table ID (0 if none).
    pub pending_table_id: u32,
    /// Table job running (0 none, 1 commit, 2 selection, 3 reload).
    pub job: u8,
    /// What boots (0 nominal, 1 A, 2 B; [`NO_SELECTION`] without a selection record).
    pub selected_source: u8,
    /// Telemetry records dropped (wrapping).
    pub tm_dropped: u16,
    /// Telecommand frames dropped by the deframer (wrapping).
    pub tc_frames_dropped: u16,
    /// UART receive overruns and RX queue overflows (wrapping).
    pub uart_overruns: u16,
    /// Control-cycle overruns (wrapping).
    pub cycle_overruns: u16,
    /// Reset cause (0 power-on, 1 watchdog, 2 software, 3 HardFault, 4 panic).
    pub reset_cause: u8,
    /// Boot count (wrapping).
    pub boot_count: u16,
    /// Flash bank health (bit 0 bank A, bit 1 bank B record corrupt).
    pub bank_health: u8,
    /// The pivot in M's coordinates (nm).
    pub pivot_nm: [i32; 3],
    /// Pose from FK in the operator's frames (nm, uas).
    pub pose_fk_operator: WirePose,
    /// Commanded pose in the operator's frames (nm, uas).
    pub pose_commanded_operator: WirePose,
    /// On-board parameters set (bit i = parameter index i).
    pub parameters_set: u32,
    /// Legs at their lower end-of-travel switch (bit i = leg i+1), last cycle's read.
    pub limit_lower_legs: u8,
    /// Legs at their upper end-of-travel switch (bit i = leg i+1).
    pub limit_upper_legs: u8,
    /// Legs at their reference (home) sensor (bit i = leg i+1).
    pub reference_legs: u8,
    /// Legs with a switch input that could not be read (bit i = leg i+1).
    pub switch_unreadable_legs: u8,
    /// Legs whose encoder reads within the in-position tolerance of the setpoint (bit i
    /// = leg i+1; [`field::IN_POSITION_LEGS`]).
    pub in_position_legs: u8,
    /// Each temperature sensor's mean (0.01 K; 0: none; [`field::TEMPERATURES_CENTI_K`]).
    pub temperatures_centi_k: [u16; TEMP_SENSORS],
    /// Temperature sensors open (bit i = sensor i).
    pub sensors_open: u8,
    /// Temperature sensors shorted (bit i = sensor i).
    pub sensors_short: u8,
    /// Temperature sensors stuck (bit i = sensor i).
    pub sensors_stuck: u8,
    /// Thermal compensation and exposure hold ([`thermal_state`] bits).
    pub thermal_state: u8,
    /// The thermal compensation's applied stroke offset of each leg (nm, along base z).
    pub thermal_offsets_nm: [i32; LEGS],
    /// The time-based schedule and the time reports (offsets 217..230).
    pub schedule: ScheduleHk,
}

/// The housekeeping block of the time-based schedule (ST[11]) and the time reports
/// (ST[9]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ScheduleHk {
    /// Activities in the schedule.
    pub activities: u8,
    /// Activities are released when their time comes.
    pub release_enabled: bool,
    /// Activities released since boot (wrapping).
    pub released: u16,
    /// Released activities whose telecommand failed (wrapping).
    pub failed: u16,
    /// Release time of the next activity (0 if none).
    pub next_release: TmTime,
    /// Time report rate (`link::time::TimeReportRate::code`: N of 2^N s, 255 off).
    pub time_report_rate: u8,
}

impl ScheduleHk {
    fn parse(f: &Fields<'_>) -> Option<ScheduleHk> {
        Some(ScheduleHk {
            activities: f.u8(field::SCHEDULE_ACTIVITIES)?,
            release_enabled: f.u8(field::SCHEDULE_RELEASE_ENABLED)? != 0,
            released: f.u16(field::SCHEDULE_RELEASED)?,
            failed: f.u16(field::SCHEDULE_FAILED)?,
            next_release: TmTime::from_bytes(
                f.bytes(field::SCHEDULE_NEXT_RELEASE)?.try_into().ok()?,
            ),
            time_report_rate: f.u8(field::TIME_REPORT_RATE)?,
        })
    }
}

impl Housekeeping {
    /// Writes the TM[3,25] source data.
    pub fn emit(&self, out: &mut [u8; HK_REPORT_LEN]) {
        let mut w = Writer::new(out, Order::Big);
        // The buffer has exactly the layout's length: every field fits.
        let _ = self.write(&mut w);
    }

    /// Writes the TM[3,25] source data as the next [`HK_REPORT_LEN`] bytes of `w`, field
    /// by field of [`field`] in offset order. Each write names its field
    /// ([`Writer::at`]: on the host a field out of place makes the write fail); the
    /// flight build writes sequentially, 0.3-0.4 KB less code than a checked write by
    /// range (flight image text, measured: 63,184 so, 63,492 by a loop over (field,
    /// value) pairs, 63,576 by `FieldsMut`; 63,076 before the fields were named). Out
    /// of line: inlined into `TmSource::write`, it cost 52 bytes more.
    #[inline(never)]
    pub fn write(&self, w: &mut Writer<'_>) -> Option<()> {
        use field::*;
        let base = w.position();
        let at = |w: &mut Writer<'_>, f: Field| w.at(base, &f);
        at(w, STRUCTURE_ID)?;
        w.u8(HK_STRUCTURE_ID)?;
        for (f, v) in [
            (STATE, self.state),
            (BOOT_SOURCE, self.boot_source),
            (ACTIVE_BANK, self.active_bank),
            (FK_ITERATIONS, self.fk_iterations),
            (FK_VALID, u8::from(self.fk_valid)),
        ] {
            at(w, f)?;
            w.u8(v)?;
        }
        for (f, v) in [
            (CYCLE_COUNTER, self.cycle_counter),
            (FAULT_FLAGS, self.fault_flags),
            (WARNING_FLAGS, self.warning_flags),
            (REFUSAL_BITS, self.refusal_bits),
            (ACTIVE_TABLE_ID, self.active_table_id),
            (ACTIVE_TABLE_CRC32, self.active_table_crc32),
        ] {
            at(w, f)?;
            w.u32(v)?;
        }
        at(w, POSE_FK)?;
        w.pose(&self.pose_fk)?;
        at(w, POSE_COMMANDED)?;
        w.pose(&self.pose_commanded)?;
        at(w, STROKES_COMMANDED)?;
        w.i32s(&self.strokes_commanded_nm)?;
        at(w, ENCODERS)?;
        w.i32s(&self.encoders_nm)?;
        for (f, v) in [
            (TC_ACCEPTED, self.tc_accepted),
            (TC_REJECTED, self.tc_rejected),
            (LAST_FAILURE_CODE, self.last_failure_code),
        ] {
            at(w, f)?;
            w.u16(v)?;
        }
        for (f, v) in [
            (MOVING_LEGS, self.moving_legs),
            (FAULT_LEGS, self.fault_legs),
            (PENDING_BANK, self.pending_bank),
        ] {
            at(w, f)?;
            w.u8(v)?;
        }
        at(w, PENDING_TABLE_ID)?;
        w.u32(self.pending_table_id)?;
        at(w, JOB)?;
        w.u8(self.job)?;
        at(w, SELECTED_SOURCE)?;
        w.u8(self.selected_source)?;
        for (f, v) in [
            (TM_DROPPED, self.tm_dropped),
            (TC_FRAMES_DROPPED, self.tc_frames_dropped),
            (UART_OVERRUNS, self.uart_overruns),
            (CYCLE_OVERRUNS, self.cycle_overruns),
        ] {
            at(w, f)?;
            w.u16(v)?;
        }
        at(w, RESET_CAUSE)?;
        w.u8(self.reset_cause)?;
        at(w, BOOT_COUNT)?;
        w.u16(self.boot_count)?;
        at(w, BANK_HEALTH)?;
        w.u8(self.bank_health)?;
        at(w, PIVOT)?;
        for v in self.pivot_nm {
            w.i32(v)?;
        }
        at(w, POSE_FK_OPERATOR)?;
        w.pose(&self.pose_fk_operator)?;
        at(w, POSE_COMMANDED_OPERATOR)?;
        w.pose(&self.pose_commanded_operator)?;
        at(w, PARAMETERS_SET)?;
        w.u32(self.parameters_set)?;
        let s = &self.schedule;
        for (f, v) in [
            (SCHEDULE_ACTIVITIES, s.activities),
            (SCHEDULE_RELEASE_ENABLED, u8::from(s.release_enabled)),
        ] {
            at(w, f)?;
            w.u8(v)?;
        }
        for (f, v) in [(SCHEDULE_RELEASED, s.released), (SCHEDULE_FAILED, s.failed)] {
            at(w, f)?;
            w.u16(v)?;
        }
        at(w, SCHEDULE_NEXT_RELEASE)?;
        w.put(&s.next_release.to_bytes())?;
        for (f, v) in [
            (TIME_REPORT_RATE, s.time_report_rate),
            (LIMIT_LOWER_LEGS, self.limit_lower_legs),
            (LIMIT_UPPER_LEGS, self.limit_upper_legs),
            (REFERENCE_LEGS, self.reference_legs),
            (SWITCH_UNREADABLE_LEGS, self.switch_unreadable_legs),
            (IN_POSITION_LEGS, self.in_position_legs),
        ] {
            at(w, f)?;
            w.u8(v)?;
        }
        at(w, TEMPERATURES_CENTI_K)?;
        for v in self.temperatures_centi_k {
            w.u16(v)?;
        }
        for (f, v) in [
            (SENSORS_OPEN, self.sensors_open),
            (SENSORS_SHORT, self.sensors_short),
            (SENSORS_STUCK, self.sensors_stuck),
            (THERMAL_STATE, self.thermal_state),
        ] {
            at(w, f)?;
            w.u8(v)?;
        }
        at(w, THERMAL_OFFSETS)?;
        w.i32s(&self.thermal_offsets_nm)?;
        // The last field ends the report.
        w.at(base, &(HK_REPORT_LEN..HK_REPORT_LEN)).map(|_| ())
    }

    /// Checked parse of the TM[3,25] source data (exact length, structure ID 1).
    pub fn parse(bytes: &[u8]) -> Option<Housekeeping> {
        if bytes.len() != HK_REPORT_LEN {
            return None;
        }
        let f = Fields::new(bytes, Order::Big);
        if f.u8(field::STRUCTURE_ID)? != HK_STRUCTURE_ID {
            return None;
        }
        let mut pivot = f.reader(field::PIVOT)?;
        let mut temps = f.reader(field::TEMPERATURES_CENTI_K)?;
        let mut temperatures_centi_k = [0u16; TEMP_SENSORS];
        for t in temperatures_centi_k.iter_mut() {
            *t = temps.u16()?;
        }
        Some(Housekeeping {
            state: f.u8(field::STATE)?,
            boot_source: f.u8(field::BOOT_SOURCE)?,
            active_bank: f.u8(field::ACTIVE_BANK)?,
            fk_iterations: f.u8(field::FK_ITERATIONS)?,
            fk_valid: f.u8(field::FK_VALID)? != 0,
            cycle_counter: f.u32(field::CYCLE_COUNTER)?,
            fault_flags: f.u32(field::FAULT_FLAGS)?,
            warning_flags: f.u32(field::WARNING_FLAGS)?,
            refusal_bits: f.u32(field::REFUSAL_BITS)?,
            active_table_id: f.u32(field::ACTIVE_TABLE_ID)?,
            active_table_crc32: f.u32(field::ACTIVE_TABLE_CRC32)?,
            pose_fk: f.reader(field::POSE_FK)?.pose()?,
            pose_commanded: f.reader(field::POSE_COMMANDED)?.pose()?,
            strokes_commanded_nm: f.reader(field::STROKES_COMMANDED)?.i32s()?,
            encoders_nm: f.reader(field::ENCODERS)?.i32s()?,
            tc_accepted: f.u16(field::TC_ACCEPTED)?,
            tc_rejected: f.u16(field::TC_REJECTED)?,
            last_failure_code: f.u16(field::LAST_FAILURE_CODE)?,
            moving_legs: f.u8(field::MOVING_LEGS)?,
            fault_legs: f.u8(field::FAULT_LEGS)?,
            pending_bank: f.u8(field::PENDING_BANK)?,
            pending_table_id: f.u32(field::PENDING_TABLE_ID)?,
            job: f.u8(field::JOB)?,
            selected_source: f.u8(field::SELECTED_SOURCE)?,
            tm_dropped: f.u16(field::TM_DROPPED)?,
            tc_frames_dropped: f.u16(field::TC_FRAMES_DROPPED)?,
            uart_overruns: f.u16(field::UART_OVERRUNS)?,
            cycle_overruns: f.u16(field::CYCLE_OVERRUNS)?,
            reset_cause: f.u8(field::RESET_CAUSE)?,
            boot_count: f.u16(field::BOOT_COUNT)?,
            bank_health: f.u8(field::BANK_HEALTH)?,
            pivot_nm: [pivot.i32()?, pivot.i32()?, pivot.i32()?],
            pose_fk_operator: f.reader(field::POSE_FK_OPERATOR)?.pose()?,
            pose_commanded_operator: f.reader(field::POSE_COMMANDED_OPERATOR)?.pose()?,
            parameters_set: f.u32(field::PARAMETERS_SET)?,
            schedule: ScheduleHk::parse(&f)?,
            limit_lower_legs: f.u8(field::LIMIT_LOWER_LEGS)?,
            limit_upper_legs: f.u8(field::LIMIT_UPPER_LEGS)?,
            reference_legs: f.u8(field::REFERENCE_LEGS)?,
            switch_unreadable_legs: f.u8(field::SWITCH_UNREADABLE_LEGS)?,
            in_position_legs: f.u8(field::IN_POSITION_LEGS)?,
            temperatures_centi_k,
            sensors_open: f.u8(field::SENSORS_OPEN)?,
            sensors_short: f.u8(field::SENSORS_SHORT)?,
            sensors_stuck: f.u8(field::SENSORS_STUCK)?,
            thermal_state: f.u8(field::THERMAL_STATE)?,
            thermal_offsets_nm: f.reader(field::THERMAL_OFFSETS)?.i32s()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A report whose every field holds a different value (no two bytes alike where the
    /// width allows), so a field written at another's place cannot round-trip.
    fn distinct() -> Housekeeping {
        let pose = |k: i32| WirePose::from_array([k, k + 1, k + 2, k + 3, k + 4, k + 5]);
        Housekeeping {
            state: 1,
            boot_source: 2,
            active_bank: 3,
            fk_iterations: 4,
            fk_valid: true,
            cycle_counter: 0x0607_0809,
            fault_flags: 0x0A0B_0C0D,
            warning_flags: 0x0E0F_1011,
            refusal_bits: 0x1213_1415,
            active_table_id: 0x1617_1819,
            active_table_crc32: 0x1A1B_1C1D,
            pose_fk: pose(100),
            pose_commanded: pose(200),
            strokes_commanded_nm: [300, 301, 302, 303, 304, 305],
            encoders_nm: [400, 401, 402, 403, 404, 405],
            tc_accepted: 0x2021,
            tc_rejected: 0x2223,
            last_failure_code: 0x2425,
            moving_legs: 0x26,
            fault_legs: 0x27,
            pending_bank: 0x28,
            pending_table_id: 0x292A_2B2C,
            job: 0x2D,
            selected_source: 0x2E,
            tm_dropped: 0x2F30,
            tc_frames_dropped: 0x3132,
            uart_overruns: 0x3334,
            cycle_overruns: 0x3536,
            reset_cause: 0x37,
            boot_count: 0x3839,
            bank_health: 0x3A,
            pivot_nm: [500, 501, 502],
            pose_fk_operator: pose(600),
            pose_commanded_operator: pose(700),
            parameters_set: 0x3B3C_3D3E,
            limit_lower_legs: 0x3F,
            limit_upper_legs: 0x40,
            reference_legs: 0x41,
            switch_unreadable_legs: 0x42,
            in_position_legs: 0xA5,
            temperatures_centi_k: [
                0x5051, 0x5253, 0x5455, 0x5657, 0x5859, 0x5A5B, 0x5C5D, 0x5E5F,
            ],
            sensors_open: 0x60,
            sensors_short: 0x61,
            sensors_stuck: 0x62,
            thermal_state: 0x63,
            thermal_offsets_nm: [
                0x6465_6667,
                -0x6869_6A6B,
                0x6C6D_6E6F,
                0x7071_7273,
                0x7475_7677,
                -1,
            ],
            schedule: ScheduleHk {
                activities: 0x43,
                release_enabled: true,
                released: 0x4445,
                failed: 0x4647,
                next_release: TmTime {
                    seconds: 0x4849_4A4B,
                    fraction: 0x4C4D,
                },
                time_report_rate: 0x4E,
            },
        }
    }

    #[test]
    fn every_field_is_written_and_read_at_its_named_range() {
        let hk = distinct();
        let mut out = [0u8; HK_REPORT_LEN];
        // Written inside a larger packet too: the layout is relative to where it starts.
        let mut packet = [0u8; HK_REPORT_LEN + 3];
        let mut w = Writer::new(&mut packet, Order::Big);
        assert_eq!(w.put(&[9, 9, 9]), Some(()));
        assert_eq!(hk.write(&mut w), Some(()));
        assert_eq!(w.position(), HK_REPORT_LEN + 3);
        hk.emit(&mut out);
        assert_eq!(&packet[3..], &out[..]);
        assert_eq!(Housekeeping::parse(&out), Some(hk));
        // Spot checks against the ICD's offsets (docs/icd.md section 6), read by hand.
        assert_eq!(out[0], HK_STRUCTURE_ID);
        assert_eq!(&out[6..10], &[6, 7, 8, 9]);
        assert_eq!(&out[130..132], &[0x24, 0x25]);
        assert_eq!(&out[221..223], &[0x46, 0x47]);
        assert_eq!(out[233], 0x42);
        assert_eq!(&out[235..237], &[0x50, 0x51]);
        assert_eq!(&out[249..251], &[0x5E, 0x5F]);
        assert_eq!(&out[251..254], &[0x60, 0x61, 0x62]);
        // Too short a buffer: refused (the TM encoder then drops the whole packet).
        let mut short = [0u8; HK_REPORT_LEN - 1];
        assert_eq!(hk.write(&mut Writer::new(&mut short, Order::Big)), None);
        assert_eq!(Housekeeping::parse(&out[1..]), None);
    }
}
