//! The telecommand/telemetry link: CCSDS space packets with PUS-C secondary headers,
//! framed with COBS on a byte stream (UART).
//!
//! Hardware independent, `no_std`, no heap, never panics: every parser is a checked
//! parse (smoltcp style) that returns `Ok` or a typed error for any byte string, and
//! every emitter writes into a caller buffer and reports a too-small buffer as an error.
//!
//! Layers, bottom up:
//! * [`framing`]: COBS frames with `0x00` delimiters on the byte stream ([`Deframer`],
//!   [`encode_frame`]).
//! * [`tc`]: a frame's bytes -> checked PUS-C telecommand -> [`Telecommand`] (request ID,
//!   acknowledgement flags, [`Command`]) or a [`Rejection`] carrying a [`LinkError`] whose
//!   stable code goes into the service-1 acceptance-failure report. Also the encoder
//!   (used by the ground tool and the tests).
//! * [`command`]: the decoded command, the contract with the controller, and its
//!   application-data layout (parse and emit).
//! * [`tm`]: telemetry emitters ([`TmWriter`]: verification, events, housekeeping, ping
//!   reply, table dump) writing a whole framed TM packet, with sequence and message
//!   counting; and a checked TM parser for the ground and the tests.
//! * [`hk`]: the housekeeping report ([`Housekeeping`]) and its byte layout.
//! * [`schedule`], [`time`]: the layouts of the time-based schedule's telecommands and
//!   summary report (PUS ST[11]) and of the time reports (ST[9]).
//!
//! The interface control document `docs/icd.md` describes every packet byte by byte.
//! Every multi-byte field on the wire is big-endian (network order), as CCSDS and PUS.
//!
//! Failure codes of this module: family `0x05xx` ([`LinkError::code`]).

pub mod command;
pub mod error;
pub mod framing;
pub mod hk;
pub mod schedule;
pub mod tc;
pub mod time;
pub mod tm;
pub mod wire;

pub use command::{
    Command, FunctionId, MemoryId, ParameterIds, ParameterValues, TableChunk, WirePose,
};
pub use error::LinkError;
pub use framing::{encode_frame, Deframer, FrameError};
pub use hk::Housekeeping;
pub use tc::{decode_telecommand, encode_telecommand, AckFlags, Rejection, RequestId, Telecommand};
pub use tm::{EventSeverity, TmReport, TmTime, TmWriter, Verification};

/// The controller's application process identifier (11 bits). Every telecommand must
/// carry it; every telemetry packet carries it.
pub const M2_APID: u16 = 0x0B2;

/// Largest telecommand packet accepted (bytes, whole CCSDS packet incl. CRC-16).
pub const MAX_TC_PACKET_LEN: usize = 256;
/// Largest telemetry packet emitted (bytes, whole CCSDS packet incl. CRC-16): the
/// housekeeping report's (19 header bytes, 279 of source data, CRC-16).
pub const MAX_TM_PACKET_LEN: usize = 300;
/// Largest framed telecommand (bytes): delimiter, COBS-encoded packet, delimiter.
pub const MAX_TC_FRAME_LEN: usize = framing::max_frame_len(MAX_TC_PACKET_LEN);
// Every TM packet's source data fits the packet buffer (`TmWriter::emit` refuses, at run
// time, what does not).
const _: () =
    assert!(tm::TM_HEADER_LEN + tm::MAX_TM_SOURCE_DATA_LEN + CRC16_LEN <= MAX_TM_PACKET_LEN);
/// Largest framed telemetry packet (bytes): a buffer this long always fits any emitter.
pub const MAX_TM_FRAME_LEN: usize = framing::max_frame_len(MAX_TM_PACKET_LEN);

/// Length of the CCSDS primary header (bytes).
pub const CCSDS_PRIMARY_HEADER_LEN: usize = 6;
/// Offset of the packet data length field in the CCSDS primary header (bytes).
pub const DATA_LEN_FIELD_OFFSET: usize = 4;
/// The data length field holds the packet length minus the primary header minus one:
/// packet length = field + this (bytes).
pub const DATA_LEN_OFFSET: usize = CCSDS_PRIMARY_HEADER_LEN + 1;
/// Length of the PUS-C telecommand secondary header (bytes): version/ack, service,
/// subtype, source ID (u16).
pub const PUS_TC_SEC_HEADER_LEN: usize = 5;
/// Length of the packet error control field (CRC-16/CCITT-FALSE, bytes).
pub const CRC16_LEN: usize = 2;
/// Length of the telemetry timestamp (bytes): CUC 4+2, see [`TmTime`].
pub const TM_TIMESTAMP_LEN: usize = 6;
/// Length of the PUS-C telemetry secondary header without the timestamp (bytes).
pub const PUS_TM_SEC_HEADER_LEN_NO_TIME: usize = 7;
/// PUS version number of PUS-C (ECSS-E-ST-70-41C).
pub const PUS_C_VERSION: u8 = 2;

/// PUS service numbers used by the controller.
pub mod service {
    /// Request verification (TM only).
    pub const VERIFICATION: u8 = 1;
    /// Housekeeping.
    pub const HOUSEKEEPING: u8 = 3;
    /// Event reporting (TM only).
    pub const EVENT: u8 = 5;
    /// Memory management: parameter-table upload and dump.
    pub const MEMORY: u8 = 6;
    /// Function management: moves, stop, table activation...
    pub const FUNCTION: u8 = 8;
    /// Test: connection (ping).
    pub const TEST: u8 = 17;
    /// On-board parameter management.
    pub const PARAMETER: u8 = 20;
    /// Time management: time reports (ST[9]).
    pub const TIME: u8 = spacepackets::ecss::PusServiceId::TimeManagement as u8;
    /// Time-based scheduling: time-tagged telecommands (ST[11]).
    pub const SCHEDULING: u8 = spacepackets::ecss::PusServiceId::Scheduling as u8;
}

/// PUS message subtypes used by the controller, per service.
pub mod subtype {
    /// TM[1,1] successful acceptance verification.
    pub const ACCEPTANCE_SUCCESS: u8 = 1;
    /// TM[1,2] failed acceptance verification.
    pub const ACCEPTANCE_FAILURE: u8 = 2;
    /// TM[1,3] successful start of execution.
    pub const START_SUCCESS: u8 = 3;
    /// TM[1,4] failed start of execution.
    pub const START_FAILURE: u8 = 4;
    /// TM[1,7] successful completion of execution.
    pub const COMPLETION_SUCCESS: u8 = 7;
    /// TM[1,8] failed completion of execution.
    pub const COMPLETION_FAILURE: u8 = 8;
    /// TM[3,25] housekeeping parameter report.
    pub const HK_REPORT: u8 = 25;
    /// TC[3,27] generate a one-shot housekeeping report.
    pub const HK_ONE_SHOT: u8 = 27;
    /// TM[5,1] informative event report.
    pub const EVENT_INFO: u8 = 1;
    /// TM[5,2] low-severity anomaly report.
    pub const EVENT_LOW: u8 = 2;
    /// TM[5,3] medium-severity anomaly report.
    pub const EVENT_MEDIUM: u8 = 3;
    /// TM[5,4] high-severity anomaly report.
    pub const EVENT_HIGH: u8 = 4;
    /// TC[6,2] load raw memory data (one table chunk).
    pub const MEMORY_LOAD: u8 = 2;
    /// TC[6,5] dump raw memory data (a whole table, as TM[6,6] chunks).
    pub const MEMORY_DUMP: u8 = 5;
    /// TM[6,6] dumped raw memory data report (one chunk).
    pub const MEMORY_DUMP_REPORT: u8 = 6;
    /// TC[8,1] perform a function.
    pub const PERFORM_FUNCTION: u8 = 1;
    /// TC[17,1] are-you-alive connection test.
    pub const PING: u8 = 1;
    /// TM[17,2] are-you-alive connection test report.
    pub const PING_REPLY: u8 = 2;
    /// TM[8,130] move-check report (mission-specific subtype).
    pub const MOVE_CHECK_REPORT: u8 = 130;
    /// TC[20,1] report parameter values.
    pub const PARAMETER_REPORT_REQUEST: u8 = 1;
    /// TM[20,2] parameter value report.
    pub const PARAMETER_REPORT: u8 = 2;
    /// TC[20,3] set parameter values.
    pub const PARAMETER_SET: u8 = 3;

    // Services 9 and 11 (time management, time-based scheduling): the ST[11] numbers
    // come from `spacepackets::ecss::scheduling::MessageSubtypeId`.
    use spacepackets::ecss::scheduling::MessageSubtypeId as Sched;
    /// TC[9,1] set the time report generation rate.
    pub const SET_TIME_REPORT_RATE: u8 = 1;
    /// TM[9,2] CUC time report.
    pub const TIME_REPORT: u8 = 2;
    /// TC[11,1] enable the release of time-based activities.
    pub const SCHEDULE_ENABLE: u8 = Sched::TcEnableScheduling as u8;
    /// TC[11,2] disable the release of time-based activities.
    pub const SCHEDULE_DISABLE: u8 = Sched::TcDisableScheduling as u8;
    /// TC[11,3] reset the time-based schedule (delete all, release disabled).
    pub const SCHEDULE_RESET: u8 = Sched::TcResetScheduling as u8;
    /// TC[11,4] insert activities into the time-based schedule.
    pub const SCHEDULE_INSERT: u8 = Sched::TcInsertActivity as u8;
    /// TC[11,5] delete activities by request ID.
    pub const SCHEDULE_DELETE: u8 = Sched::TcDeleteActivityByRequestId as u8;
    /// TC[11,15] time-shift all activities.
    pub const SCHEDULE_TIME_SHIFT_ALL: u8 = Sched::TcTimeShiftAll as u8;
    /// TC[11,17] summary-report all activities.
    pub const SCHEDULE_SUMMARY_ALL: u8 = Sched::TcSummaryReportAll as u8;
    /// TM[11,13] time-based schedule summary report.
    pub const SCHEDULE_SUMMARY_REPORT: u8 = Sched::TmSummaryReport as u8;
}
