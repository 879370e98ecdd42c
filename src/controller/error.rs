//! Why the controller refused or failed a telecommand: [`CommandError`], family `0x07xx`
//! (the kinematics, motion, table and store codes pass through unchanged). Each variant
//! has a stable code and a 32-bit failure datum for the service-1 report.

use super::schedule::ScheduleError;
use super::State;
use crate::motion::{MotionError, StrokeMoveError};
use crate::supervision::FaultFlags;
use crate::table::upload::UploadError;
use crate::table::{StoreError, TableError};

/// Why the controller refused or failed a telecommand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandError {
    /// 0x0701: a fault is latched (data: latched flags).
    Faulted(FaultFlags),
    /// 0x0702: a motion is in progress: stop first (data: state code).
    Busy(State),
    /// 0x0703: clear refused: the fault condition persists (data: blocking flags).
    FaultPersists(FaultFlags),
    /// 0x0704: the pose of the held strokes is unknown (FK failed): no path can start.
    NoPose,
    /// A move refused by the planner (`MotionError` codes 0x060x; data: refusal bits).
    Motion(MotionError),
    /// A direct-stroke move refused by its planner (`StrokeMoveError` codes 0x061x).
    Stroke(StrokeMoveError),
    /// 0x0705: commit before every table byte was uploaded (data: bytes missing).
    UploadIncomplete(u16),
    /// 0x0706: commit with a CRC-32 that does not match the uploaded bytes (data: the
    /// computed CRC).
    CrcMismatch(u32),
    /// The uploaded bytes do not decode as a table (`TableError` codes 0x040x).
    TableDecode(TableError),
    /// Validation or flash storage failed (validation codes 0x041x with their detail,
    /// store codes 0x043x).
    Store(StoreError),
    /// 0x0707: activate with no committed table pending.
    NoPending,
    /// 0x0708: the move was ended early by a stop telecommand.
    Stopped,
    /// 0x0709: the move was ended early by a fault (data: latched flags).
    AbortedByFault(FaultFlags),
    /// 0x070A: activate named a table that is not the pending one (data: the pending
    /// table's ID).
    PendingMismatch {
        /// ID of the pending table.
        pending_id: u32,
    },
    /// 0x070B: a direct-stroke move of a leg whose own encoder is suspect (data: the
    /// reasons, [`suspect`] bits).
    EncoderSuspect(u32),
    /// 0x070C: the running geometry is unusable (a defect guard): all motion refused.
    NoGeometry,
    /// 0x070D: a table job (commit, selection, reload) is in progress (data: job code).
    JobBusy(u8),
    /// An on-board parameter refused (0x0720..0x0724).
    Parameter(super::params::ParamError),
    /// A time-based schedule telecommand refused (`ScheduleError` codes 0x0B0x).
    Schedule(ScheduleError),
    /// 0x070E: a direct-stroke move toward an end-of-travel switch that is active, or
    /// was seen since the limit-switch fault latched (data: the legs blocked in the
    /// move's direction, bit i = leg i+1).
    TowardEndOfTravel(u8),
    /// 0x070F: the move's sliders were not in position (every encoder within the
    /// in-position tolerance of its setpoint for the dwell) within the fine
    /// positioning's timeout (`motion::fine::TIMEOUT_CYCLES`) after the path (data: the
    /// legs out of tolerance, bit i = leg i+1).
    NotInPosition(u8),
    /// 0x0710: an operator move (absolute, relative, direct stroke) during an exposure
    /// hold (data: the hold's seconds left, rounded up).
    ExposureHold(u32),
}

/// Reasons a leg's encoder is suspect for a direct-stroke move (0x070B's data bits).
pub mod suspect {
    /// No reading of the leg this cycle (read failure or corrupted frame).
    pub const NO_READING: u32 = 1 << 0;
    /// A read-failure fault is latched on the leg.
    pub const READ_FAILURE: u32 = 1 << 1;
    /// An encoder-jump fault is latched on the leg.
    pub const JUMP: u32 = 1 << 2;
    /// An encoder-stuck fault is latched on the leg.
    pub const STUCK: u32 = 1 << 3;
    /// The reading disagrees with the drive's held setpoint by more than the
    /// following-error fault threshold.
    pub const DISAGREES: u32 = 1 << 4;
}

impl CommandError {
    /// Failure code for the verification report.
    pub const fn code(&self) -> u16 {
        match self {
            CommandError::Faulted(_) => 0x0701,
            CommandError::Busy(_) => 0x0702,
            CommandError::FaultPersists(_) => 0x0703,
            CommandError::NoPose => 0x0704,
            CommandError::Motion(e) => e.code(),
            CommandError::Stroke(e) => e.code(),
            CommandError::UploadIncomplete(_) => 0x0705,
            CommandError::CrcMismatch(_) => 0x0706,
            CommandError::TableDecode(e) => e.code(),
            CommandError::Store(StoreError::Invalid(v)) => v.code(),
            CommandError::Store(e) => e.code(),
            CommandError::NoPending => 0x0707,
            CommandError::Stopped => 0x0708,
            CommandError::AbortedByFault(_) => 0x0709,
            CommandError::PendingMismatch { .. } => 0x070A,
            CommandError::EncoderSuspect(_) => 0x070B,
            CommandError::NoGeometry => 0x070C,
            CommandError::JobBusy(_) => 0x070D,
            CommandError::TowardEndOfTravel(_) => 0x070E,
            CommandError::NotInPosition(_) => 0x070F,
            CommandError::ExposureHold(_) => 0x0710,
            CommandError::Parameter(e) => e.code(),
            CommandError::Schedule(e) => e.code(),
        }
    }

    /// Failure datum for the verification report.
    pub fn data(&self) -> u32 {
        match self {
            CommandError::Faulted(f)
            | CommandError::FaultPersists(f)
            | CommandError::AbortedByFault(f) => f.bits(),
            CommandError::Busy(s) => s.code() as u32,
            CommandError::Motion(e) => match e {
                MotionError::StartRefused(r) | MotionError::TargetRefused(r) => r.to_bits(),
                MotionError::PathRefused { refusals, .. } => refusals.to_bits(),
                _ => 0,
            },
            CommandError::UploadIncomplete(n) => *n as u32,
            CommandError::CrcMismatch(c) => *c,
            CommandError::Store(StoreError::Invalid(v)) => v.detail() as u32,
            CommandError::Store(e) => e.data(),
            CommandError::PendingMismatch { pending_id } => *pending_id,
            CommandError::EncoderSuspect(bits) => *bits,
            CommandError::JobBusy(job) => *job as u32,
            CommandError::TowardEndOfTravel(legs) | CommandError::NotInPosition(legs) => {
                u32::from(*legs)
            }
            CommandError::Parameter(e) => e.data(),
            CommandError::Schedule(e) => e.data(),
            CommandError::ExposureHold(left_s) => *left_s,
            _ => 0,
        }
    }
}

impl From<UploadError> for CommandError {
    fn from(e: UploadError) -> Self {
        match e {
            UploadError::Incomplete(n) => CommandError::UploadIncomplete(n),
            UploadError::CrcMismatch(c) => CommandError::CrcMismatch(c),
            UploadError::Decode(t) => CommandError::TableDecode(t),
        }
    }
}
