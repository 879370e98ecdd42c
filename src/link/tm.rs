//! Telemetry: [`TmWriter`] emits whole framed PUS-C TM packets (verification, events,
//! housekeeping, ping reply, table dump, time report, schedule summary) into caller
//! buffers, counting packet sequence
//! and per-service message type counters; [`parse_tm`] is the checked inverse for the
//! ground and the tests.
//!
//! Every TM packet: CCSDS primary header (APID [`M2_APID`], type TM, secondary header
//! flag, unsegmented, sequence count incremented per emitted packet, wrapping at 2^14),
//! PUS-C TM secondary header (version 2, time reference status 0, service, subtype,
//! message type counter per service (u16, wrapping), destination ID 0, timestamp
//! [`TmTime`]), source data, CRC-16/CCITT-FALSE.

use crate::units::{US_PER_MS, US_PER_S};
use spacepackets::ecss::tm::{GenericPusTmSecondaryHeader, PusTmReader};
use spacepackets::CcsdsPacket;

use super::command::{MemoryId, TABLE_CHUNK_MAX_LEN};
use super::error::{sat_u16, LinkError};
use super::framing::{encode_frame, FrameError};
use super::hk::{Housekeeping, HK_REPORT_LEN};
use super::schedule::{
    write_summary, SummaryEntry, SummaryView, MAX_SUMMARY_LEN, SCHEDULE_CAPACITY,
};
use super::tc::{RequestId, CRC16, REQUEST_ID_LEN, SEQ_COUNT_MASK};
use super::time::{parse_time_report, write_time_report, TimeReportRate, TIME_REPORT_LEN};
use super::wire::{copy_prefix, Order, Reader, Writer};
use super::{
    service, subtype, CCSDS_PRIMARY_HEADER_LEN, CRC16_LEN, DATA_LEN_FIELD_OFFSET, DATA_LEN_OFFSET,
    M2_APID, MAX_TM_PACKET_LEN, PUS_C_VERSION, PUS_TM_SEC_HEADER_LEN_NO_TIME, TM_TIMESTAMP_LEN,
};

/// Largest source data of any TM packet the controller emits (bytes): the schedule
/// summary of a full schedule (161), the housekeeping report, a dump chunk,
/// the move check, a parameter report.
pub const MAX_TM_SOURCE_DATA_LEN: usize = {
    let mut m = MAX_SUMMARY_LEN;
    if MOVE_CHECK_REPORT_LEN > m {
        m = MOVE_CHECK_REPORT_LEN;
    }
    // TM[20,2] answering one TC[20,1]: count, then 6 bytes per ID.
    if 1 + PARAMETER_ENTRY_LEN * crate::link::command::MAX_PARAMETERS_PER_TC > m {
        m = 1 + PARAMETER_ENTRY_LEN * crate::link::command::MAX_PARAMETERS_PER_TC;
    }
    if HK_REPORT_LEN > m {
        m = HK_REPORT_LEN;
    }
    if DUMP_HEADER_LEN + TABLE_CHUNK_MAX_LEN > m {
        m = DUMP_HEADER_LEN + TABLE_CHUNK_MAX_LEN;
    }
    m
};
/// Bytes of the headers of a TM packet before its source data: primary header, PUS-C
/// TM secondary header, timestamp.
pub const TM_HEADER_LEN: usize =
    CCSDS_PRIMARY_HEADER_LEN + PUS_TM_SEC_HEADER_LEN_NO_TIME + TM_TIMESTAMP_LEN;
/// The packet ID of every TM packet: version 0, type TM (0), secondary header flag,
/// APID [`M2_APID`].
const TM_PACKET_ID: u16 = 0x0800 | (M2_APID & super::tc::APID_MASK);
/// Sequence flags "unsegmented" in the packet sequence control.
const SEQ_FLAGS_UNSEGMENTED: u16 = 0xc000;
/// Shift of the PUS version in the first secondary-header byte (time reference status
/// 0 below it).
const PUS_VERSION_SHIFT: u8 = 4;

/// Bytes of the TM[6,6] header before the data: memory ID u8, offset u16, length u16.
pub const DUMP_HEADER_LEN: usize = 5;
/// Bytes of a failure notice: code u16, data u32.
pub const FAILURE_NOTICE_LEN: usize = 6;
/// Bytes of an event report: event ID u16, two u32 auxiliary words.
pub const EVENT_REPORT_LEN: usize = 10;
/// Bytes of a TM[8,130] move-check report.
pub const MOVE_CHECK_REPORT_LEN: usize = REQUEST_ID_LEN + 2 + 4 + 4 + 1;
/// Bytes of one (ID, value) pair of TM[20,2].
pub const PARAMETER_ENTRY_LEN: usize = 6;

/// The answer of a move check, as TM[8,130] carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MoveCheckReport {
    /// The code the move would be refused with now (0: accepted).
    pub code: u16,
    /// Refusal bits of the target.
    pub target_refusals: u32,
    /// Refusal bits of the first refused point of the path (0: none).
    pub path_refusals: u32,
    /// Index of that point (0: none).
    pub path_sample: u8,
}

/// Saturating `usize` -> `u8`.
fn sat_u8(v: usize) -> u8 {
    u8::try_from(v).unwrap_or(u8::MAX)
}
/// Sub-second resolution of the timestamp: 2^16 fractions per second.
pub const TIME_FRACTIONS_PER_SECOND: u64 = 1 << 16;

/// The TM timestamp: CCSDS unsegmented time code (CUC) with implicit P-field, 4 bytes of
/// seconds and 2 bytes of 1/65536 s, big-endian, counted from controller boot (the
/// controller has no absolute time; the ground correlates). The same code is the
/// on-board time (OBT) of the schedule's release times (ST[11]) and of the time reports
/// (ST[9]). Ordered by time (seconds, then fraction).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TmTime {
    /// Whole seconds since boot.
    pub seconds: u32,
    /// Fraction of a second (units of 1/65536 s).
    pub fraction: u16,
}

impl TmTime {
    /// From milliseconds since boot (seconds wrap after 2^32 s).
    pub const fn from_millis(ms: u64) -> TmTime {
        TmTime::from_micros(ms * US_PER_MS as u64)
    }

    /// From microseconds since boot (seconds wrap after 2^32 s; the fraction is
    /// truncated to 1/65536 s).
    pub const fn from_micros(us: u64) -> TmTime {
        let us_per_s = US_PER_S as u64;
        TmTime {
            seconds: (us / us_per_s) as u32,
            fraction: ((us % us_per_s) * TIME_FRACTIONS_PER_SECOND / us_per_s) as u16,
        }
    }

    /// The six wire bytes.
    pub const fn to_bytes(self) -> [u8; TM_TIMESTAMP_LEN] {
        let s = self.seconds.to_be_bytes();
        let f = self.fraction.to_be_bytes();
        [s[0], s[1], s[2], s[3], f[0], f[1]]
    }

    /// From the six wire bytes.
    pub const fn from_bytes(b: [u8; TM_TIMESTAMP_LEN]) -> TmTime {
        TmTime {
            seconds: u32::from_be_bytes([b[0], b[1], b[2], b[3]]),
            fraction: u16::from_be_bytes([b[4], b[5]]),
        }
    }

    /// The time as one count of 1/65536 s (48 bits: seconds << 16 | fraction).
    pub const fn to_ticks(self) -> u64 {
        ((self.seconds as u64) << FRACTION_BITS) | self.fraction as u64
    }

    /// From a count of 1/65536 s; `None` beyond the 48 bits of the code.
    pub const fn from_ticks(ticks: u64) -> Option<TmTime> {
        if ticks > MAX_TIME_TICKS {
            return None;
        }
        Some(TmTime {
            seconds: (ticks >> FRACTION_BITS) as u32,
            fraction: (ticks & FRACTION_MASK) as u16,
        })
    }

    /// This time moved by `offset_ticks` (1/65536 s, signed); `None` if the result is
    /// before 0 or beyond the 48 bits of the code.
    pub const fn checked_offset(self, offset_ticks: i64) -> Option<TmTime> {
        match (self.to_ticks() as i64).checked_add(offset_ticks) {
            Some(t) if t >= 0 => TmTime::from_ticks(t as u64),
            _ => None,
        }
    }
}

/// Bits of the CUC fraction.
const FRACTION_BITS: u32 = 16;
/// Mask of the CUC fraction in a tick count.
const FRACTION_MASK: u64 = (1 << FRACTION_BITS) - 1;
/// Largest tick count of CUC 4+2 (2^48 - 1).
pub const MAX_TIME_TICKS: u64 = (1 << (8 * TM_TIMESTAMP_LEN)) - 1;

/// A service-1 verification report for one telecommand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verification {
    /// TM[1,1].
    AcceptanceSuccess,
    /// TM[1,2]: `code` is a [`LinkError::code`] (or a controller code), `data` its datum.
    AcceptanceFailure {
        /// Failure code.
        code: u16,
        /// Failure datum.
        data: u32,
    },
    /// TM[1,3].
    StartSuccess,
    /// TM[1,4]: the controller refused to start (e.g. faulted, moving).
    StartFailure {
        /// Failure code.
        code: u16,
        /// Failure datum (e.g. refusal bits).
        data: u32,
    },
    /// TM[1,7].
    CompletionSuccess,
    /// TM[1,8]: execution failed (kinematics/table/store error codes pass through).
    CompletionFailure {
        /// Failure code.
        code: u16,
        /// Failure datum.
        data: u32,
    },
}

impl Verification {
    /// The acceptance failure for a link error.
    pub const fn acceptance_failure(error: &LinkError) -> Verification {
        Verification::AcceptanceFailure {
            code: error.code(),
            data: error.data(),
        }
    }

    /// PUS subtype of the report.
    pub const fn subtype(&self) -> u8 {
        match self {
            Verification::AcceptanceSuccess => subtype::ACCEPTANCE_SUCCESS,
            Verification::AcceptanceFailure { .. } => subtype::ACCEPTANCE_FAILURE,
            Verification::StartSuccess => subtype::START_SUCCESS,
            Verification::StartFailure { .. } => subtype::START_FAILURE,
            Verification::CompletionSuccess => subtype::COMPLETION_SUCCESS,
            Verification::CompletionFailure { .. } => subtype::COMPLETION_FAILURE,
        }
    }

    /// The failure notice, if a failure.
    pub const fn failure(&self) -> Option<(u16, u32)> {
        match *self {
            Verification::AcceptanceFailure { code, data }
            | Verification::StartFailure { code, data }
            | Verification::CompletionFailure { code, data } => Some((code, data)),
            _ => None,
        }
    }

    /// From a subtype and failure notice (ground side).
    pub const fn from_parts(subtype: u8, code: u16, data: u32) -> Option<Verification> {
        Some(match subtype {
            subtype::ACCEPTANCE_SUCCESS => Verification::AcceptanceSuccess,
            subtype::ACCEPTANCE_FAILURE => Verification::AcceptanceFailure { code, data },
            subtype::START_SUCCESS => Verification::StartSuccess,
            subtype::START_FAILURE => Verification::StartFailure { code, data },
            subtype::COMPLETION_SUCCESS => Verification::CompletionSuccess,
            subtype::COMPLETION_FAILURE => Verification::CompletionFailure { code, data },
            _ => return None,
        })
    }
}

/// Severity of a service-5 event (= its TM subtype).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventSeverity {
    /// TM[5,1] informative (state changes, table activated).
    Info,
    /// TM[5,2] low-severity anomaly (warnings).
    Low,
    /// TM[5,3] medium-severity anomaly (refused commands, table rejected).
    Medium,
    /// TM[5,4] high-severity anomaly (faults latched).
    High,
}

impl EventSeverity {
    /// PUS subtype.
    pub const fn subtype(self) -> u8 {
        match self {
            EventSeverity::Info => subtype::EVENT_INFO,
            EventSeverity::Low => subtype::EVENT_LOW,
            EventSeverity::Medium => subtype::EVENT_MEDIUM,
            EventSeverity::High => subtype::EVENT_HIGH,
        }
    }

    /// From the PUS subtype.
    pub const fn from_subtype(subtype: u8) -> Option<EventSeverity> {
        match subtype {
            subtype::EVENT_INFO => Some(EventSeverity::Info),
            subtype::EVENT_LOW => Some(EventSeverity::Low),
            subtype::EVENT_MEDIUM => Some(EventSeverity::Medium),
            subtype::EVENT_HIGH => Some(EventSeverity::High),
            _ => None,
        }
    }
}

/// Event IDs of service 5 (u16). Auxiliary words per event in the ICD.
pub mod event_id {
    /// Controller state changed. aux0: old state, aux1: new state.
    pub const STATE_CHANGED: u16 = 0x0001;
    /// A fault latched. aux0: all latched fault flags, aux1: the newly latched ones
    /// (bits 0..23) and the legs they name (bits 24..29, bit i = leg i+1).
    pub const FAULT_LATCHED: u16 = 0x0002;
    /// Faults cleared. aux0: flags cleared, aux1: 0.
    pub const FAULTS_CLEARED: u16 = 0x0003;
    /// Warning flags changed. aux0: warning flags, aux1: legs of the warnings.
    pub const WARNING_CHANGED: u16 = 0x0004;
    /// A move was refused. aux0: refusal bits, aux1: failure code.
    pub const MOVE_REFUSED: u16 = 0x0005;
    /// A setpoint on a planned path failed IK (a defect guard: the motion holds).
    /// aux0: refusal bits, aux1: control cycle.
    pub const SETPOINT_REFUSED: u16 = 0x0006;
    /// The set of active end-of-travel switches changed to a non-empty one (the leg is
    /// stopped in that direction; fault `LIMIT_SWITCH` latches). aux0: legs at the lower
    /// switch (bits 0..5), at the upper switch (bits 8..13), with an unreadable switch
    /// input (bits 16..21), bit i = leg i+1; aux1: control cycle.
    pub const END_OF_TRAVEL: u16 = 0x0007;
    /// A table was activated. aux0: table ID, aux1: CRC-32.
    pub const TABLE_ACTIVATED: u16 = 0x0010;
    /// A table was rejected (commit/activation). aux0: failure code, aux1: table ID.
    pub const TABLE_REJECTED: u16 = 0x0011;
    /// A table was committed to flash. aux0: table ID, aux1: bank (1 A, 2 B).
    pub const TABLE_COMMITTED: u16 = 0x0012;
    /// A table was re-read from its source after a RAM upset. aux0: table ID, aux1:
    /// source (0 nominal, 1 A, 2 B).
    pub const TABLE_RELOADED: u16 = 0x0013;
    /// The flash banks' health changed. aux0: bit 0 bank A, bit 1 bank B corrupt; aux1: 0.
    pub const BANK_HEALTH: u16 = 0x0014;
    /// Boot finished. aux0: boot source (0 nominal, 1 A, 2 B), aux1: active table ID.
    pub const BOOT: u16 = 0x0020;
    /// Boot details. aux0: boot flags (bank A bits 0..7, fell back bit 7, bank B bits
    /// 8..15, selection bits 16..18); aux1: reset cause (bits 0..7), boot count (bits
    /// 16..31).
    pub const BOOT_DETAIL: u16 = 0x0021;
    /// On-board parameters changed (persisted and applied). aux0: the parameters the
    /// TC[20,3] set, aux1: every parameter set now (bit i = parameter index i).
    pub const PARAMETERS_CHANGED: u16 = 0x0040;
    /// Persisted on-board parameters not applied (at boot, or when the repair of an
    /// upset re-read them): out of range, or following-error overrides that would leave
    /// the warning not below the running table's fault threshold. aux0: the parameters
    /// not applied (bit i = parameter index i), aux1: 0.
    pub const PARAMETERS_IGNORED: u16 = 0x0041;
    /// Control cycles overran their period several times in a row: motion stopped.
    /// aux0: consecutive overruns, aux1: overruns since boot.
    pub const DEADLINE_MISSED: u16 = 0x0030;
    /// A temperature sensor the running table's thermal model uses became faulty (open,
    /// shorted or stuck; once per failure: again only after it was healthy). aux0: the
    /// sensors that became faulty (bit i = sensor i); aux1: every sensor's fault now,
    /// open (bits 0..7), shorted (bits 8..15), stuck (bits 16..23).
    pub const SENSOR_FAULT: u16 = 0x0050;
    /// The thermal compensation froze at its last applied offset: it is enabled and a
    /// sensor the running table's thermal model uses is faulty (once per freeze: again
    /// only after a recovery, or a disable and an enable). Warning: the mirror keeps the
    /// frozen offset, no longer following the temperatures. aux0: the faulty sensors
    /// the model uses (bit i = sensor i); aux1: 0.
    pub const THERMAL_FROZEN: u16 = 0x0051;
    /// An exposure hold began: no compensation step, no scheduled motion, no operator
    /// move until it ends. aux0: what began it (0 the telecommand, 1 the discrete
    /// input); aux1: its timeout (s).
    pub const EXPOSURE_HOLD_STARTED: u16 = 0x0052;
    /// The exposure hold ended. aux0: why (0 a telecommand with timeout 0, 1 the timeout
    /// passed, 2 the discrete input was released); aux1: 0.
    pub const EXPOSURE_HOLD_ENDED: u16 = 0x0053;
    // Time-based schedule (ST[11]).
    /// A scheduled activity was released: its telecommand runs now. aux0: request ID
    /// (packet ID << 16 | sequence control), aux1: release time (OBT seconds).
    pub const ACTIVITY_RELEASED: u16 = 0x00B0;
    /// A released activity's telecommand failed (its TM[1,2]/[1,4]/[1,8] carries the
    /// details). aux0: request ID, aux1: report subtype << 16 | failure code.
    pub const ACTIVITY_FAILED: u16 = 0x00B1;
    /// An activity whose release time passed while release was disabled was deleted
    /// when release was enabled (never run). aux0: request ID, aux1: release time (OBT
    /// seconds).
    pub const ACTIVITY_EXPIRED: u16 = 0x00B2;

    /// Lowest bit of the legs in an event word that packs fault flags and their legs
    /// (FAULT_LATCHED's aux1: flags in the bits below, bit i above = leg i+1).
    pub const FAULT_LEGS_SHIFT: u32 = 24;
    /// Lowest bit of the report subtype in ACTIVITY_FAILED's aux1 (failure code below).
    pub const ACTIVITY_SUBTYPE_SHIFT: u32 = 16;
    /// Lowest bit of the shorted sensors in SENSOR_FAULT's aux1 (open below).
    pub const SENSOR_SHORT_SHIFT: u32 = 8;
    /// Lowest bit of the stuck sensors in SENSOR_FAULT's aux1.
    pub const SENSOR_STUCK_SHIFT: u32 = 16;
}

/// Why telemetry could not be emitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmitError {
    /// The output buffer cannot hold the framed packet ([`super::MAX_TM_FRAME_LEN`] always can).
    BufferTooSmall,
    /// A dump chunk is empty, too long or lies outside the table.
    BadChunk,
}

impl From<FrameError> for EmitError {
    fn from(_: FrameError) -> Self {
        EmitError::BufferTooSmall
    }
}

/// Message-type counters are kept per service; index in [`TmWriter`].
const COUNTED_SERVICES: [u8; 9] = [
    service::VERIFICATION,
    service::HOUSEKEEPING,
    service::EVENT,
    service::MEMORY,
    service::FUNCTION,
    service::TEST,
    service::PARAMETER,
    service::TIME,
    service::SCHEDULING,
];

/// The numbers the next TM packet takes: its sequence count and, per service, its
/// message type counter ([`TmWriter::checkpoint`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TmCounters {
    /// Sequence count of the next packet (14 bits).
    seq_count: u16,
    /// Message type counter of the next packet, per service of [`COUNTED_SERVICES`].
    msg_counters: [u16; COUNTED_SERVICES.len()],
}

/// Emits framed TM packets and counts them. One per link.
///
/// A number is consumed only by a packet that is sent: a caller that emits a frame and
/// then finds no room for it restores the [`TmWriter::checkpoint`] it took before, so the
/// frame emitted again later carries the same numbers.
#[derive(Clone, Debug, Default)]
pub struct TmWriter {
    counters: TmCounters,
}

impl TmWriter {
    /// Counters at zero.
    pub const fn new() -> TmWriter {
        TmWriter {
            counters: TmCounters {
                seq_count: 0,
                msg_counters: [0; COUNTED_SERVICES.len()],
            },
        }
    }

    /// Sequence count the next packet will carry.
    pub const fn next_seq_count(&self) -> u16 {
        self.counters.seq_count
    }

    /// The counters now, to be restored if the next emitted frame is not sent.
    pub const fn checkpoint(&self) -> TmCounters {
        self.counters
    }

    /// Takes back every number consumed since `checkpoint`: the frames emitted since were
    /// not sent.
    pub fn restore(&mut self, checkpoint: TmCounters) {
        self.counters = checkpoint;
    }

    /// Builds, frames and counts the packet of `source`; counters move only on success.
    /// Returns the frame length. The one path of every TM packet the controller sends:
    /// the source data is written in place after the headers ([`TmSource::write`]), the
    /// headers and CRC by [`TmWriter::finish`].
    pub fn emit(
        &mut self,
        time: TmTime,
        source: &TmSource<'_>,
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        let mut packet = [0u8; MAX_TM_PACKET_LEN];
        let area = packet
            .get_mut(TM_HEADER_LEN..TM_HEADER_LEN + MAX_TM_SOURCE_DATA_LEN)
            .ok_or(EmitError::BufferTooSmall)?;
        let mut w = Writer::new(area, Order::Big);
        source.write(time, &mut w).ok_or(source.refusal())?;
        let len = w.position();
        self.finish(time, source.message(), &mut packet, len, out)
    }

    /// Builds, frames and counts one packet of service and subtype `message` with this
    /// source data (at most [`MAX_TM_SOURCE_DATA_LEN`] bytes); counters move only on
    /// success. Returns the frame length. (Any packet: the ground's and the tests'.)
    pub fn emit_packet(
        &mut self,
        time: TmTime,
        message: (u8, u8),
        source_data: &[u8],
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        let mut packet = [0u8; MAX_TM_PACKET_LEN];
        let area = packet
            .get_mut(TM_HEADER_LEN..TM_HEADER_LEN + MAX_TM_SOURCE_DATA_LEN)
            .ok_or(EmitError::BufferTooSmall)?;
        copy_prefix(area, source_data).ok_or(EmitError::BufferTooSmall)?;
        self.finish(time, message, &mut packet, source_data.len(), out)
    }

    /// Writes the headers before the `source_len` bytes of source data in `packet` and
    /// the CRC after them, frames the packet into `out` and counts it.
    ///
    /// The headers are written here (the layout of the module documentation), not by
    /// spacepackets' `PusTmCreator`, and the CRC-16 is [`CRC16`] (a 32-byte table), not
    /// the `crc` crate's 512-byte table the creator used. Equal to the crate's packets
    /// bit for bit (host test `link::tm_packets_equal_spacepackets_creator`, which keeps
    /// the crate as the reference).
    fn finish(
        &mut self,
        time: TmTime,
        message: (u8, u8),
        packet: &mut [u8; MAX_TM_PACKET_LEN],
        source_len: usize,
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        let (svc, sub) = message;
        let too_small = EmitError::BufferTooSmall;
        let slot = COUNTED_SERVICES.iter().position(|s| *s == svc);
        let msg_counter = slot
            .and_then(|i| self.counters.msg_counters.get(i).copied())
            .unwrap_or(0);
        let crc_at = TM_HEADER_LEN + source_len;
        let len = crc_at + CRC16_LEN;
        let data_len = u16::try_from(len - DATA_LEN_OFFSET).map_err(|_| too_small)?;
        let [id0, id1] = TM_PACKET_ID.to_be_bytes();
        let [sc0, sc1] =
            (SEQ_FLAGS_UNSEGMENTED | (self.counters.seq_count & SEQ_COUNT_MASK)).to_be_bytes();
        let [dl0, dl1] = data_len.to_be_bytes();
        let [mc0, mc1] = msg_counter.to_be_bytes();
        let [t0, t1, t2, t3, t4, t5] = time.to_bytes();
        let header: [u8; TM_HEADER_LEN] = [
            id0,
            id1,
            sc0,
            sc1,
            dl0,
            dl1,
            PUS_C_VERSION << PUS_VERSION_SHIFT,
            svc,
            sub,
            mc0,
            mc1,
            0,
            0,
            t0,
            t1,
            t2,
            t3,
            t4,
            t5,
        ];
        copy_prefix(packet, &header).ok_or(too_small)?;
        let crc = CRC16.checksum(packet.get(..crc_at).ok_or(too_small)?);
        let tail = packet.get_mut(crc_at..len).ok_or(too_small)?;
        copy_prefix(tail, &crc.to_be_bytes()).ok_or(too_small)?;
        let framed = encode_frame(packet.get(..len).ok_or(too_small)?, out)?;
        self.counters.seq_count = self.counters.seq_count.wrapping_add(1) & SEQ_COUNT_MASK;
        if let Some(c) = slot.and_then(|i| self.counters.msg_counters.get_mut(i)) {
            *c = c.wrapping_add(1);
        }
        Ok(framed)
    }

    /// TM[1,x] verification report for `request_id`: source data = request ID (4 bytes),
    /// then for failures code u16 and data u32. Returns the frame length.
    pub fn emit_verification(
        &mut self,
        time: TmTime,
        request_id: RequestId,
        report: Verification,
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        self.emit(time, &TmSource::Verification { request_id, report }, out)
    }

    /// TM[5,x] event report: event ID u16, aux words u32 x2. Returns the frame length.
    pub fn emit_event(
        &mut self,
        time: TmTime,
        severity: EventSeverity,
        event_id: u16,
        aux: [u32; 2],
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        let source = TmSource::Event {
            severity,
            event_id,
            aux,
        };
        self.emit(time, &source, out)
    }

    /// TM[3,25] housekeeping report. Returns the frame length.
    pub fn emit_housekeeping(
        &mut self,
        time: TmTime,
        hk: &Housekeeping,
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        self.emit(time, &TmSource::Housekeeping(hk), out)
    }

    /// TM[9,2] time report: the rate in force and the OBT the report was made at (the
    /// same as its packet time). Returns the frame length.
    pub fn emit_time_report(
        &mut self,
        time: TmTime,
        rate: TimeReportRate,
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        self.emit(time, &TmSource::TimeReport(rate), out)
    }

    /// TM[11,13] schedule summary: N u8, then release time and request ID of each
    /// activity. Returns the frame length.
    pub fn emit_schedule_summary(
        &mut self,
        time: TmTime,
        entries: &[SummaryEntry],
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        self.emit(time, &TmSource::ScheduleSummary(entries), out)
    }

    /// TM[17,2] ping reply (no source data). Returns the frame length.
    pub fn emit_ping_reply(&mut self, time: TmTime, out: &mut [u8]) -> Result<usize, EmitError> {
        self.emit(time, &TmSource::PingReply, out)
    }

    /// TM[8,130] move-check report: request ID (4), code u16 (0: the move would be
    /// accepted), target refusal bits u32, path refusal bits u32, refused path sample u8.
    pub fn emit_move_check(
        &mut self,
        time: TmTime,
        request_id: RequestId,
        check: &MoveCheckReport,
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        let source = TmSource::MoveCheck {
            request_id,
            check: *check,
        };
        self.emit(time, &source, out)
    }

    /// TM[20,2] parameter report: count u8, then (ID u16, value i32) per parameter.
    pub fn emit_parameter_report(
        &mut self,
        time: TmTime,
        values: &[(u16, i32)],
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        self.emit(time, &TmSource::Parameters(values), out)
    }

    /// TM[6,6] one dump chunk: memory ID u8, offset u16, length u16, bytes (1..=128).
    /// Returns the frame length. Use [`dump_chunks`] to split a table.
    pub fn emit_table_dump_chunk(
        &mut self,
        time: TmTime,
        memory: MemoryId,
        offset_bytes: u16,
        bytes: &[u8],
        out: &mut [u8],
    ) -> Result<usize, EmitError> {
        let source = TmSource::DumpChunk {
            memory,
            offset_bytes,
            bytes,
        };
        self.emit(time, &source, out)
    }
}

/// What one TM packet reports: its service and subtype and the content of its source
/// data ([`TmWriter::emit`]). Each packet's layout is written once, in
/// [`TmSource::write`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TmSource<'a> {
    /// TM[1,x]: request ID (4 bytes), then for failures code u16 and data u32.
    Verification {
        /// The telecommand.
        request_id: RequestId,
        /// The report.
        report: Verification,
    },
    /// TM[5,x]: event ID u16, aux words u32 x2.
    Event {
        /// Severity (= subtype).
        severity: EventSeverity,
        /// Event ID.
        event_id: u16,
        /// Auxiliary words.
        aux: [u32; 2],
    },
    /// TM[3,25]: the housekeeping report ([`Housekeeping::write`]).
    Housekeeping(&'a Housekeeping),
    /// TM[9,2]: the rate in force and the OBT of the report (the packet time).
    TimeReport(TimeReportRate),
    /// TM[11,13]: N u8, then release time and request ID of each activity (at most
    /// [`SCHEDULE_CAPACITY`]).
    ScheduleSummary(&'a [SummaryEntry]),
    /// TM[17,2]: no source data.
    PingReply,
    /// TM[8,130]: request ID (4), code u16, target refusal bits u32, path refusal bits
    /// u32, refused path sample u8.
    MoveCheck {
        /// The telecommand.
        request_id: RequestId,
        /// The answer.
        check: MoveCheckReport,
    },
    /// TM[20,2]: count u8, then (ID u16, value i32) per parameter.
    Parameters(&'a [(u16, i32)]),
    /// TM[6,6]: memory ID u8, offset u16, length u16, bytes (1..=128).
    DumpChunk {
        /// Memory area.
        memory: MemoryId,
        /// Offset of the chunk (bytes).
        offset_bytes: u16,
        /// The chunk.
        bytes: &'a [u8],
    },
}

impl TmSource<'_> {
    /// PUS service and subtype. Out of line: inlined into the emit path, 16 bytes of
    /// flash more.
    #[inline(never)]
    pub const fn message(&self) -> (u8, u8) {
        match self {
            TmSource::Verification { report, .. } => (service::VERIFICATION, report.subtype()),
            TmSource::Event { severity, .. } => (service::EVENT, severity.subtype()),
            TmSource::Housekeeping(_) => (service::HOUSEKEEPING, subtype::HK_REPORT),
            TmSource::TimeReport(_) => (service::TIME, subtype::TIME_REPORT),
            TmSource::ScheduleSummary(_) => (service::SCHEDULING, subtype::SCHEDULE_SUMMARY_REPORT),
            TmSource::PingReply => (service::TEST, subtype::PING_REPLY),
            TmSource::MoveCheck { .. } => (service::FUNCTION, subtype::MOVE_CHECK_REPORT),
            TmSource::Parameters(_) => (service::PARAMETER, subtype::PARAMETER_REPORT),
            TmSource::DumpChunk { .. } => (service::MEMORY, subtype::MEMORY_DUMP_REPORT),
        }
    }

    /// Why the source data could not be written: a dump chunk that is empty or too long
    /// is a bad chunk, anything else a too-small buffer.
    const fn refusal(&self) -> EmitError {
        match self {
            TmSource::DumpChunk { .. } => EmitError::BadChunk,
            _ => EmitError::BufferTooSmall,
        }
    }

    /// Writes the source data of a packet made at `time`; `None` if it does not fit (or
    /// a dump chunk is empty or longer than [`TABLE_CHUNK_MAX_LEN`], or a summary has
    /// more than [`SCHEDULE_CAPACITY`] entries). Out of line: inlined into the one
    /// emit path (`comms::encode`), its variants were copied per record kind.
    #[inline(never)]
    pub fn write(&self, time: TmTime, w: &mut Writer<'_>) -> Option<()> {
        match *self {
            TmSource::Verification { request_id, report } => {
                w.put(&request_id.to_bytes())?;
                if let Some((code, datum)) = report.failure() {
                    w.u16(code)?;
                    w.u32(datum)?;
                }
            }
            TmSource::Event {
                event_id,
                aux: [aux0, aux1],
                ..
            } => {
                w.u16(event_id)?;
                w.u32(aux0)?;
                w.u32(aux1)?;
            }
            TmSource::Housekeeping(hk) => hk.write(w)?,
            TmSource::TimeReport(rate) => write_time_report(w, rate, time)?,
            TmSource::ScheduleSummary(entries) => {
                if entries.len() > SCHEDULE_CAPACITY {
                    return None;
                }
                write_summary(w, entries)?
            }
            TmSource::PingReply => {}
            TmSource::MoveCheck { request_id, check } => {
                w.put(&request_id.to_bytes())?;
                w.u16(check.code)?;
                w.u32(check.target_refusals)?;
                w.u32(check.path_refusals)?;
                w.u8(check.path_sample)?;
            }
            TmSource::Parameters(values) => {
                w.u8(sat_u8(values.len()))?;
                for (id, v) in values {
                    w.u16(*id)?;
                    w.i32(*v)?;
                }
            }
            TmSource::DumpChunk {
                memory,
                offset_bytes,
                bytes,
            } => {
                if bytes.is_empty() || bytes.len() > TABLE_CHUNK_MAX_LEN {
                    return None;
                }
                w.u8(memory.code())?;
                w.u16(offset_bytes)?;
                w.u16(sat_u16(bytes.len()))?;
                w.put(bytes)?;
            }
        }
        Some(())
    }
}

/// Splits a table image into dump/upload chunks of at most [`TABLE_CHUNK_MAX_LEN`] bytes:
/// `(offset_bytes, bytes)` in increasing offset order.
pub fn dump_chunks(table: &[u8]) -> impl Iterator<Item = (u16, &[u8])> {
    table
        .chunks(TABLE_CHUNK_MAX_LEN)
        .enumerate()
        .map(|(i, c)| (sat_u16(i.saturating_mul(TABLE_CHUNK_MAX_LEN)), c))
}

/// A decoded TM packet (ground side and tests).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TmPacket<'a> {
    /// APID.
    pub apid: u16,
    /// Packet sequence count.
    pub seq_count: u16,
    /// Message type counter.
    pub msg_counter: u16,
    /// Timestamp.
    pub time: TmTime,
    /// Service.
    pub service: u8,
    /// Subtype.
    pub subtype: u8,
    /// The report.
    pub report: TmReport<'a>,
}

/// The content of a TM packet.
// The housekeeping variant is the whole report (235 bytes): a parse result is matched
// where it is made and never stored in bulk, and a `no_std` link has no heap to box it.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TmReport<'a> {
    /// TM[1,x].
    Verification {
        /// The telecommand it reports on.
        request_id: RequestId,
        /// The report.
        report: Verification,
    },
    /// TM[3,25].
    Housekeeping(Housekeeping),
    /// TM[5,x].
    Event {
        /// Severity.
        severity: EventSeverity,
        /// Event ID.
        event_id: u16,
        /// Auxiliary words.
        aux: [u32; 2],
    },
    /// TM[6,6].
    DumpChunk {
        /// Memory area.
        memory: MemoryId,
        /// Offset (bytes).
        offset_bytes: u16,
        /// Data.
        bytes: &'a [u8],
    },
    /// TM[17,2].
    PingReply,
    /// TM[8,130].
    MoveCheck {
        /// The telecommand.
        request_id: RequestId,
        /// The answer.
        check: MoveCheckReport,
    },
    /// TM[20,2]: the (ID u16, value i32) pairs, big-endian, as received.
    Parameters {
        /// The pairs' bytes (a multiple of 6).
        entries: &'a [u8],
    },
    /// TM[9,2].
    TimeReport {
        /// The generation rate in force.
        rate: TimeReportRate,
        /// The on-board time the report was made at.
        obt: TmTime,
    },
    /// TM[11,13].
    ScheduleSummary(SummaryView<'a>),
}

fn be_u16(b: &[u8], at: usize) -> Option<u16> {
    Reader::new(b.get(at..)?, Order::Big).u16()
}
fn be_u32(b: &[u8], at: usize) -> Option<u32> {
    Reader::new(b.get(at..)?, Order::Big).u32()
}

/// Checked parse of one TM packet (unframed) from the controller. Never panics.
pub fn parse_tm(packet: &[u8]) -> Result<TmPacket<'_>, LinkError> {
    // spacepackets 0.19's reader slices past the end of a packet whose length field is
    // shorter than its headers: check the lengths before handing it over.
    let min_len =
        CCSDS_PRIMARY_HEADER_LEN + PUS_TM_SEC_HEADER_LEN_NO_TIME + TM_TIMESTAMP_LEN + CRC16_LEN;
    let got = sat_u16(packet.len());
    let data_len = be_u16(packet, DATA_LEN_FIELD_OFFSET).ok_or(LinkError::Truncated {
        got,
        needed: sat_u16(min_len),
    })?;
    let declared = usize::from(data_len) + CCSDS_PRIMARY_HEADER_LEN + 1;
    if packet.len() < min_len || declared < min_len || packet.len() < declared {
        return Err(LinkError::Truncated {
            got,
            needed: sat_u16(declared.max(min_len)),
        });
    }
    if packet.len() > declared {
        return Err(LinkError::LengthMismatch {
            got,
            declared: sat_u16(declared),
        });
    }
    let tm = PusTmReader::new(packet, TM_TIMESTAMP_LEN).map_err(|e| match e {
        spacepackets::ecss::PusError::ChecksumFailure(found) => LinkError::BadCrc { found },
        _ => LinkError::Truncated {
            got: sat_u16(packet.len()),
            needed: 0,
        },
    })?;
    if tm.packet_len() != packet.len() {
        return Err(LinkError::LengthMismatch {
            got: sat_u16(packet.len()),
            declared: sat_u16(tm.packet_len()),
        });
    }
    if !tm.is_tm() {
        return Err(LinkError::BadPrimaryHeader);
    }
    let apid = tm.apid().value();
    let (svc, sub) = (tm.service_type_id(), tm.message_subtype_id());
    let d = tm.source_data();
    let wrong_len = |expected: usize| LinkError::AppDataLength {
        got: sat_u16(d.len()),
        expected: sat_u16(expected),
    };
    let stamp: [u8; TM_TIMESTAMP_LEN] = tm
        .timestamp()
        .try_into()
        .map_err(|_| LinkError::BadPrimaryHeader)?;
    let report = match svc {
        service::VERIFICATION => {
            let failure = matches!(
                sub,
                subtype::ACCEPTANCE_FAILURE | subtype::START_FAILURE | subtype::COMPLETION_FAILURE
            );
            let expected = REQUEST_ID_LEN + if failure { FAILURE_NOTICE_LEN } else { 0 };
            if d.len() != expected {
                return Err(wrong_len(expected));
            }
            let rid = RequestId::from_packet(d).ok_or(wrong_len(expected))?;
            let code = be_u16(d, REQUEST_ID_LEN).unwrap_or(0);
            let data = be_u32(d, REQUEST_ID_LEN + 2).unwrap_or(0);
            TmReport::Verification {
                request_id: rid,
                report: Verification::from_parts(sub, code, data).ok_or(
                    LinkError::UnknownSubtype {
                        service: svc,
                        subtype: sub,
                    },
                )?,
            }
        }
        service::HOUSEKEEPING if sub == subtype::HK_REPORT => {
            TmReport::Housekeeping(Housekeeping::parse(d).ok_or(wrong_len(HK_REPORT_LEN))?)
        }
        service::EVENT => {
            if d.len() != EVENT_REPORT_LEN {
                return Err(wrong_len(EVENT_REPORT_LEN));
            }
            TmReport::Event {
                severity: EventSeverity::from_subtype(sub).ok_or(LinkError::UnknownSubtype {
                    service: svc,
                    subtype: sub,
                })?,
                event_id: be_u16(d, 0).unwrap_or(0),
                aux: [be_u32(d, 2).unwrap_or(0), be_u32(d, 6).unwrap_or(0)],
            }
        }
        service::MEMORY if sub == subtype::MEMORY_DUMP_REPORT => {
            let memory = d
                .first()
                .copied()
                .and_then(MemoryId::from_code)
                .ok_or(LinkError::InvalidArgument { index: 0 })?;
            let offset = be_u16(d, 1).ok_or(wrong_len(DUMP_HEADER_LEN))?;
            let len = be_u16(d, 3).ok_or(wrong_len(DUMP_HEADER_LEN))?;
            let bytes = d.get(DUMP_HEADER_LEN..).unwrap_or(&[]);
            if bytes.len() != usize::from(len) {
                return Err(wrong_len(DUMP_HEADER_LEN + usize::from(len)));
            }
            TmReport::DumpChunk {
                memory,
                offset_bytes: offset,
                bytes,
            }
        }
        service::TEST if sub == subtype::PING_REPLY => {
            if !d.is_empty() {
                return Err(wrong_len(0));
            }
            TmReport::PingReply
        }
        service::FUNCTION if sub == subtype::MOVE_CHECK_REPORT => {
            if d.len() != MOVE_CHECK_REPORT_LEN {
                return Err(wrong_len(MOVE_CHECK_REPORT_LEN));
            }
            let mut r = Reader::new(d, Order::Big);
            let rid = r.take::<REQUEST_ID_LEN>().map(RequestId::from_bytes);
            match (rid, r.u16(), r.u32(), r.u32(), r.u8()) {
                (Some(request_id), Some(code), Some(t), Some(p), Some(k)) => TmReport::MoveCheck {
                    request_id,
                    check: MoveCheckReport {
                        code,
                        target_refusals: t,
                        path_refusals: p,
                        path_sample: k,
                    },
                },
                _ => return Err(wrong_len(MOVE_CHECK_REPORT_LEN)),
            }
        }
        service::PARAMETER if sub == subtype::PARAMETER_REPORT => {
            let n = usize::from(d.first().copied().unwrap_or(0));
            let expected = 1 + PARAMETER_ENTRY_LEN * n;
            if d.len() != expected {
                return Err(wrong_len(expected));
            }
            TmReport::Parameters {
                entries: d.get(1..).unwrap_or(&[]),
            }
        }
        service::TIME if sub == subtype::TIME_REPORT => {
            let (rate, obt) = parse_time_report(d).ok_or(wrong_len(TIME_REPORT_LEN))?;
            TmReport::TimeReport { rate, obt }
        }
        service::SCHEDULING if sub == subtype::SCHEDULE_SUMMARY_REPORT => {
            TmReport::ScheduleSummary(SummaryView::new(d).ok_or(wrong_len(MAX_SUMMARY_LEN))?)
        }
        service::HOUSEKEEPING
        | service::MEMORY
        | service::TEST
        | service::FUNCTION
        | service::PARAMETER
        | service::TIME
        | service::SCHEDULING => {
            return Err(LinkError::UnknownSubtype {
                service: svc,
                subtype: sub,
            })
        }
        _ => return Err(LinkError::UnknownService { service: svc }),
    };
    Ok(TmPacket {
        apid,
        seq_count: tm.seq_count().value(),
        msg_counter: tm.msg_type_counter(),
        time: TmTime::from_bytes(stamp),
        service: svc,
        subtype: sub,
        report,
    })
}
