//! The housekeeping report TM[3,25]: [`Housekeeping`] and its byte layout.
//!
//! # Layout (source data of TM[3,25], [`HK_REPORT_LEN`] = 234 bytes, big-endian)
//!
//! | offset | size | type    | field                                                        |
//! |-------:|-----:|---------|--------------------------------------------------------------|
//! |      0 |    1 | u8      | structure ID ([`HK_STRUCTURE_ID`] = 1)                       |
//! |      1 |    1 | u8      | controller state (the controller's enum code)                |
//! |      2 |    1 | u8      | boot source (0 nominal, 1 bank A, 2 bank B)                  |
//! |      3 |    1 | u8      | active table bank (0 none/nominal, 1 A, 2 B)                 |
//! |      4 |    1 | u8      | last FK iteration count                                      |
//! |      5 |    1 | u8      | FK valid (1: `pose_fk` is this cycle's FK; 0: FK failed)     |
//! |      6 |    4 | u32     | control cycle counter                                        |
//! |     10 |    4 | u32     | fault flags (latched)                                        |
//! |     14 |    4 | u32     | warning flags                                                |
//! |     18 |    4 | u32     | last refusal bits (`kinematics::Refusals::to_bits`)          |
//! |     22 |    4 | u32     | active table ID                                              |
//! |     26 |    4 | u32     | active table CRC-32                                          |
//! |     30 |   24 | 6 x i32 | pose from FK: x, y, z (nm), alpha, beta, gamma (uas)         |
//! |     54 |   24 | 6 x i32 | commanded pose (nm, uas)                                     |
//! |     78 |   24 | 6 x i32 | commanded strokes, legs 1..6 (nm)                            |
//! |    102 |   24 | 6 x i32 | encoder readings, legs 1..6 (nm; multiples of 100 nm = one 0.1 um count) |
//! |    126 |    2 | u16     | telecommands accepted (wrapping)                             |
//! |    128 |    2 | u16     | telecommands rejected (wrapping)                             |
//! |    130 |    2 | u16     | last failure code (0: none)                                  |
//! |    132 |    1 | u8      | moving legs mask (bit i = leg i+1)                           |
//! |    133 |    1 | u8      | legs named by the latched faults (bit i = leg i+1)           |
//! |    134 |    1 | u8      | bank of the pending (committed, not activated) table: 0 none, 1 A, 2 B |
//! |    135 |    4 | u32     | pending table ID (0 if none)                                 |
//! |    139 |    1 | u8      | table job running: 0 none, 1 commit, 2 selection, 3 reload   |
//! |    140 |    1 | u8      | selected table (what boots): 0 nominal, 1 A, 2 B, 255 no selection record |
//! |    141 |    2 | u16     | telemetry records dropped (queue full; wrapping)             |
//! |    143 |    2 | u16     | telecommand frames dropped (too long or bad COBS; wrapping)  |
//! |    145 |    2 | u16     | UART receive overruns and RX queue overflows (wrapping)      |
//! |    147 |    2 | u16     | control-cycle overruns (wrapping)                            |
//! |    149 |    1 | u8      | reset cause: 0 power-on, 1 watchdog, 2 software, 3 HardFault, 4 panic |
//! |    150 |    2 | u16     | boot count (wrapping)                                        |
//! |    152 |    1 | u8      | flash bank health: bit 0 bank A, bit 1 bank B record corrupt |
//! |    153 |   12 | 3 x i32 | pivot in M's coordinates, x, y, z (nm; ST[20] parameters 1..3) |
//! |    165 |   24 | 6 x i32 | pose from FK in the operator's frames (pivot, user frame; nm, uas) |
//! |    189 |   24 | 6 x i32 | commanded pose in the operator's frames (nm, uas)            |
//! |    213 |    4 | u32     | on-board parameters set (bit i = parameter index i)          |
//!
//! Time-based schedule and time reports (ST[11], ST[9]; [`ScheduleHk`]):
//!
//! | offset | size | type    | field                                                        |
//! |-------:|-----:|---------|--------------------------------------------------------------|
//! |    217 |    1 | u8      | activities in the schedule (0..16)                           |
//! |    218 |    1 | u8      | release enabled (1) or disabled (0)                          |
//! |    219 |    2 | u16     | activities released since boot (wrapping)                   |
//! |    221 |    2 | u16     | released activities that failed (wrapping)                   |
//! |    223 |    6 | CUC 4+2 | release time of the next activity (0 if none)                |
//! |    229 |    1 | u8      | time report rate: N of 2^N s, 255 off                        |
//!
//! End-of-travel switches and reference sensors:
//!
//! | offset | size | type    | field                                                        |
//! |-------:|-----:|---------|--------------------------------------------------------------|
//! |    230 |    1 | u8      | legs at the lower end-of-travel switch (bit i = leg i+1)     |
//! |    231 |    1 | u8      | legs at the upper end-of-travel switch (bit i = leg i+1)     |
//! |    232 |    1 | u8      | legs at the reference (home) sensor (bit i = leg i+1)        |
//! |    233 |    1 | u8      | legs with a switch input that cannot be read (bit i = leg i+1) |
//!
//! The four switch bytes are the last cycle's read (`hw::TravelSwitches`), unfiltered.

use super::command::WirePose;
use super::tm::TmTime;
use super::wire::{Order, Reader, Writer};
use crate::kinematics::LEGS;

/// Structure ID of the one housekeeping report.
pub const HK_STRUCTURE_ID: u8 = 1;
/// Length of the TM[3,25] source data (bytes).
pub const HK_REPORT_LEN: usize = 234;
/// `selected_source` when no selection record exists.
pub const NO_SELECTION: u8 = 0xFF;

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
    fn write(&self, w: &mut Writer<'_>) -> Option<()> {
        w.put(&[self.activities, u8::from(self.release_enabled)])?;
        w.u16(self.released)?;
        w.u16(self.failed)?;
        w.put(&self.next_release.to_bytes())?;
        w.u8(self.time_report_rate)
    }

    fn read(r: &mut Reader<'_>) -> Option<ScheduleHk> {
        Some(ScheduleHk {
            activities: r.u8()?,
            release_enabled: r.u8()? != 0,
            released: r.u16()?,
            failed: r.u16()?,
            next_release: TmTime::from_bytes(r.take()?),
            time_report_rate: r.u8()?,
        })
    }
}

impl Housekeeping {
    /// Writes the TM[3,25] source data.
    pub fn emit(&self, out: &mut [u8; HK_REPORT_LEN]) {
        let mut w = Writer::new(out, Order::Big);
        // The buffer has exactly the layout's length: every put fits.
        let _ = self.write(&mut w);
    }

    /// Writes the TM[3,25] source data (the layout of the module documentation).
    pub fn write(&self, w: &mut Writer<'_>) -> Option<()> {
        w.put(&[
            HK_STRUCTURE_ID,
            self.state,
            self.boot_source,
            self.active_bank,
            self.fk_iterations,
            u8::from(self.fk_valid),
        ])?;
        for v in [
            self.cycle_counter,
            self.fault_flags,
            self.warning_flags,
            self.refusal_bits,
            self.active_table_id,
            self.active_table_crc32,
        ] {
            w.u32(v)?;
        }
        w.pose(&self.pose_fk)?;
        w.pose(&self.pose_commanded)?;
        w.i32s(&self.strokes_commanded_nm)?;
        w.i32s(&self.encoders_nm)?;
        for v in [self.tc_accepted, self.tc_rejected, self.last_failure_code] {
            w.u16(v)?;
        }
        w.put(&[self.moving_legs, self.fault_legs, self.pending_bank])?;
        w.u32(self.pending_table_id)?;
        w.put(&[self.job, self.selected_source])?;
        for v in [
            self.tm_dropped,
            self.tc_frames_dropped,
            self.uart_overruns,
            self.cycle_overruns,
        ] {
            w.u16(v)?;
        }
        w.u8(self.reset_cause)?;
        w.u16(self.boot_count)?;
        w.u8(self.bank_health)?;
        for v in self.pivot_nm {
            w.i32(v)?;
        }
        w.pose(&self.pose_fk_operator)?;
        w.pose(&self.pose_commanded_operator)?;
        w.u32(self.parameters_set)?;
        self.schedule.write(w)?;
        w.put(&[
            self.limit_lower_legs,
            self.limit_upper_legs,
            self.reference_legs,
            self.switch_unreadable_legs,
        ])
    }

    /// Checked parse of the TM[3,25] source data (exact length, structure ID 1).
    pub fn parse(bytes: &[u8]) -> Option<Housekeeping> {
        if bytes.len() != HK_REPORT_LEN {
            return None;
        }
        let mut r = Reader::new(bytes, Order::Big);
        if r.u8()? != HK_STRUCTURE_ID {
            return None;
        }
        Some(Housekeeping {
            state: r.u8()?,
            boot_source: r.u8()?,
            active_bank: r.u8()?,
            fk_iterations: r.u8()?,
            fk_valid: r.u8()? != 0,
            cycle_counter: r.u32()?,
            fault_flags: r.u32()?,
            warning_flags: r.u32()?,
            refusal_bits: r.u32()?,
            active_table_id: r.u32()?,
            active_table_crc32: r.u32()?,
            pose_fk: r.pose()?,
            pose_commanded: r.pose()?,
            strokes_commanded_nm: r.i32s()?,
            encoders_nm: r.i32s()?,
            tc_accepted: r.u16()?,
            tc_rejected: r.u16()?,
            last_failure_code: r.u16()?,
            moving_legs: r.u8()?,
            fault_legs: r.u8()?,
            pending_bank: r.u8()?,
            pending_table_id: r.u32()?,
            job: r.u8()?,
            selected_source: r.u8()?,
            tm_dropped: r.u16()?,
            tc_frames_dropped: r.u16()?,
            uart_overruns: r.u16()?,
            cycle_overruns: r.u16()?,
            reset_cause: r.u8()?,
            boot_count: r.u16()?,
            bank_health: r.u8()?,
            pivot_nm: [r.i32()?, r.i32()?, r.i32()?],
            pose_fk_operator: r.pose()?,
            pose_commanded_operator: r.pose()?,
            parameters_set: r.u32()?,
            schedule: ScheduleHk::read(&mut r)?,
            limit_lower_legs: r.u8()?,
            limit_upper_legs: r.u8()?,
            reference_legs: r.u8()?,
            switch_unreadable_legs: r.u8()?,
        })
    }
}
