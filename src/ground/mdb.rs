//! The mission database (host): one machine-readable description of the whole
//! telecommand/telemetry vocabulary of `docs/icd.md`, built from the flight code's own
//! constants, and the single source of the Yamcs XTCE (`m2ground mdb-json` ->
//! `yamcs/tools/gen_xtce.py` -> `m2.xml`, see `docs/ground-segment.md`).
//!
//! What it holds:
//! * every telecommand: PUS service/subtype, TC[8,1] function ID, arguments with their
//!   wire type, engineering unit, calibration (engineering value = raw x `scale`, e.g.
//!   0.001 um per nm) and valid range; a `build` function that turns raw argument values
//!   into the flight [`Command`], so the tests can encode every described telecommand
//!   through the description and compare it with the link's encoder;
//! * every telemetry packet with its fields (offset in the source data, wire type, unit,
//!   calibration, enumeration or named bit field), the housekeeping fields each with an
//!   accessor into [`Housekeeping`], so the tests read an emitted report back by the
//!   description;
//! * the enumerations (controller state, boot source, bank, memory ID, failure codes,
//!   event IDs) and the bit fields (fault/warning flags, refusal bits, leg masks);
//! * the events with their severities and the meaning of their auxiliary words;
//! * how service-1 reports verify each telecommand (acceptance, start, completion).
//!
//! Drift between this file and the flight code is a failing test
//! (`host-tests/mdb.rs`): a telecommand the parser knows but the description lacks, a
//! housekeeping field at another offset, an event, failure code or flag bit the code has
//! and the description does not.

use serde::Serialize;

use crate::controller::params::{ParamError, PARAMETERS};
use crate::controller::schedule::ScheduleError;
use crate::controller::{CommandError, State};
use crate::kinematics::{FkError, GeometryError, IkError, Refusals, LEGS};
use crate::link::command::{
    FunctionId, MemoryId, ParameterIds, ParameterValues, TableChunk, WirePose, FUNCTION_ID_LEN,
    TABLE_CHUNK_MAX_LEN,
};
use crate::link::hk::{HK_REPORT_LEN, HK_STRUCTURE_ID};
use crate::link::schedule::{
    ActivityBlock, ObtOffset, RequestIdList, ScheduleCommand, ACTIVITY_COUNT_LEN,
    MAX_SCHEDULED_TC_LEN, RELEASE_TIME_LEN, SCHEDULE_CAPACITY, SUMMARY_ENTRY_LEN,
};
use crate::link::tc::{RequestId, TcHeader, APID_MASK, MIN_TC_PACKET_LEN, SEQ_COUNT_MASK};
use crate::link::time::{TimeReportRate, MAX_TIME_REPORT_EXPONENT, TIME_REPORT_LEN};
use crate::link::tm::TmTime;
use crate::link::tm::MOVE_CHECK_REPORT_LEN;
use crate::link::tm::{event_id, EventSeverity, TIME_FRACTIONS_PER_SECOND};
use crate::link::{
    encode_telecommand, service, subtype, AckFlags, Command, Housekeeping, LinkError,
    CCSDS_PRIMARY_HEADER_LEN, M2_APID, MAX_TC_PACKET_LEN, PUS_C_VERSION, PUS_TC_SEC_HEADER_LEN,
    PUS_TM_SEC_HEADER_LEN_NO_TIME, TM_TIMESTAMP_LEN,
};
use crate::motion::{MotionError, StrokeMoveError};
use crate::supervision::FaultFlags;
use crate::table::{BootSource, StoreError, TableError, ValidationError, TABLE_LEN};
use crate::timing::{CYCLE_S_F64, HK_PERIOD_CYCLES};
use crate::units::{ARCSEC_PER_UAS, UM_PER_NM};

/// Engineering unit of translations and strokes.
pub const UNIT_UM: &str = "um";
/// Engineering unit of rotations.
pub const UNIT_ARCSEC: &str = "arcsec";
/// Offset of the TM source data in a TM packet (bytes): primary header + secondary
/// header with its CUC 4+2 timestamp.
pub const TM_SOURCE_DATA_OFFSET: usize =
    CCSDS_PRIMARY_HEADER_LEN + PUS_TM_SEC_HEADER_LEN_NO_TIME + TM_TIMESTAMP_LEN;
/// Offset of the TC application data in a TC packet (bytes).
pub const TC_APP_DATA_OFFSET: usize = CCSDS_PRIMARY_HEADER_LEN + PUS_TC_SEC_HEADER_LEN;
/// Bytes of the CUC coarse time (seconds since controller boot).
pub const CUC_COARSE_BYTES: usize = 4;
/// Bytes of the CUC fine time (1/65536 s).
pub const CUC_FINE_BYTES: usize = TM_TIMESTAMP_LEN - CUC_COARSE_BYTES;
/// Completion window of telecommands that finish within the cycle that accepts them (s).
pub const QUICK_COMPLETION_S: f64 = 10.0;
/// Completion window of moves (s): long enough for any move inside the workspace.
pub const MOVE_COMPLETION_S: f64 = 600.0;
/// Acceptance and start windows (s).
pub const ACK_WINDOW_S: f64 = 10.0;

/// How a field is encoded on the wire (big-endian).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum Wire {
    /// Unsigned 8 bits.
    U8,
    /// Unsigned 16 bits.
    U16,
    /// Unsigned 32 bits.
    U32,
    /// Two's complement 32 bits.
    I32,
    /// A u16 byte count followed by that many bytes.
    Bytes {
        /// Fewest bytes.
        min_len: usize,
        /// Most bytes.
        max_len: usize,
    },
    /// An embedded CCSDS packet (a telecommand of a TC[11,4] activity): the bytes alone,
    /// no prefix; the packet's own length field delimits it.
    Packet {
        /// Fewest bytes.
        min_len: usize,
        /// Most bytes.
        max_len: usize,
    },
}

impl Wire {
    /// Encoded size (bytes) of a fixed-size type; `None` for [`Wire::Bytes`].
    pub const fn fixed_len(self) -> Option<usize> {
        match self {
            Wire::U8 => Some(1),
            Wire::U16 => Some(2),
            Wire::U32 | Wire::I32 => Some(4),
            Wire::Bytes { .. } | Wire::Packet { .. } => None,
        }
    }

    /// Bytes of the length prefix of [`Wire::Bytes`].
    pub const LENGTH_PREFIX_LEN: usize = 2;

    /// Raw range of an integer type.
    pub fn raw_range(self) -> Option<(i64, i64)> {
        match self {
            Wire::U8 => Some((0, i64::from(u8::MAX))),
            Wire::U16 => Some((0, i64::from(u16::MAX))),
            Wire::U32 => Some((0, i64::from(u32::MAX))),
            Wire::I32 => Some((i64::from(i32::MIN), i64::from(i32::MAX))),
            Wire::Bytes { .. } | Wire::Packet { .. } => None,
        }
    }
}

/// What a field's value means.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Meaning {
    /// A number; engineering value = raw x `scale`, in `unit`.
    Number {
        /// Engineering unit (`None`: a count or an identifier).
        unit: Option<&'static str>,
        /// Engineering value per raw unit (1 when uncalibrated).
        scale: f64,
        /// Valid engineering range, inclusive (telecommand arguments).
        range: Option<(f64, f64)>,
    },
    /// One value of a named enumeration ([`Mdb::enums`]).
    Enum {
        /// Enumeration name.
        enumeration: &'static str,
    },
    /// A word of named flag bits ([`Mdb::bit_fields`]).
    Bits {
        /// Bit field name.
        bit_field: &'static str,
    },
    /// 0 = false, 1 = true.
    Boolean,
    /// A constant the encoder writes (not an operator argument).
    Fixed {
        /// The value.
        value: i64,
    },
    /// Opaque bytes (table chunks).
    Binary,
}

/// One field of a telecommand's application data or of a TM packet's source data.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Field {
    /// Name (lower snake case; unique within its packet).
    pub name: String,
    /// Offset from the start of the application/source data (bytes).
    pub offset: usize,
    /// Wire encoding.
    pub wire: Wire,
    /// Meaning.
    pub meaning: Meaning,
    /// What it is (frame and unit included).
    pub description: String,
}

/// A raw argument value of a telecommand.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ArgValue {
    /// An integer in the wire's raw units.
    Int(i64),
    /// Bytes of a [`Wire::Bytes`] argument.
    Bytes(Vec<u8>),
}

/// Builds the flight command from raw argument values (operator arguments only, in
/// description order); `Err` if a value is out of range.
pub type BuildFn = fn(&[ArgValue]) -> Result<Command, String>;

/// One telecommand.
#[derive(Clone, Debug, Serialize)]
pub struct Telecommand {
    /// Name (upper snake case).
    pub name: String,
    /// PUS service.
    pub service: u8,
    /// PUS subtype.
    pub subtype: u8,
    /// TC[8,1] function ID (the first two bytes of the application data).
    pub function_id: Option<u16>,
    /// Application-data fields after the function ID (offsets count from the start of
    /// the application data, function ID included).
    pub fields: Vec<Field>,
    /// What it does.
    pub description: String,
    /// Seconds within which the completion report must come.
    pub completion_timeout_s: f64,
    /// Raw arguments -> flight command.
    #[serde(skip)]
    pub build: BuildFn,
}

/// One TM packet type.
#[derive(Clone, Debug, Serialize)]
pub struct TmPacket {
    /// Name (lower snake case).
    pub name: String,
    /// PUS service.
    pub service: u8,
    /// PUS subtypes this layout covers.
    pub subtypes: Vec<u8>,
    /// Source-data fields.
    pub fields: Vec<Field>,
    /// Source-data length when fixed (bytes).
    pub fixed_len: Option<usize>,
    /// What it is.
    pub description: String,
    /// A repeated group after the fields (e.g. the activities of TM[11,13]).
    pub repeated: Option<Repeated>,
}

/// A group of fields repeated `count_field` times at the end of a TM packet.
#[derive(Clone, Debug, Serialize)]
pub struct Repeated {
    /// Name of the group (one array parameter in Yamcs).
    pub name: String,
    /// The field holding the number of repetitions.
    pub count_field: String,
    /// Offset of the first repetition in the source data (bytes).
    pub offset: usize,
    /// Bytes of one repetition.
    pub element_len: usize,
    /// Most repetitions.
    pub max_count: usize,
    /// The fields of one repetition (offsets from its start).
    pub fields: Vec<Field>,
}

/// A named enumeration.
#[derive(Clone, Debug, Serialize)]
pub struct Enumeration {
    /// Name.
    pub name: &'static str,
    /// `(value, label, meaning)`.
    pub values: Vec<(i64, String, String)>,
}

/// A word of named flag bits.
#[derive(Clone, Debug, Serialize)]
pub struct BitField {
    /// Name.
    pub name: &'static str,
    /// `(bit, name, meaning)`, bit 0 = least significant.
    pub bits: Vec<(u32, String, String)>,
}

/// One service-5 event.
#[derive(Clone, Debug, Serialize)]
pub struct Event {
    /// Event ID.
    pub id: u16,
    /// Label (upper snake case, the `event_id` constant's name).
    pub name: &'static str,
    /// Severities the controller sends it with (TM[5,x] subtype).
    pub severities: Vec<&'static str>,
    /// Meaning of aux0.
    pub aux0: &'static str,
    /// Meaning of aux1.
    pub aux1: &'static str,
    /// One-line text for the operator (`{aux0}`, `{aux1}` are replaced).
    pub message: &'static str,
}

/// One verification stage: TM[1,`success`] or TM[1,`success`+1].
#[derive(Clone, Debug, Serialize)]
pub struct VerificationStage {
    /// Yamcs stage name.
    pub name: &'static str,
    /// Subtype of the success report (failure = +1).
    pub success_subtype: u8,
}

/// Link-level constants the ground needs.
#[derive(Clone, Debug, Serialize)]
pub struct LinkInfo {
    /// APID of every TC and TM.
    pub apid: u16,
    /// PUS version.
    pub pus_version: u8,
    /// Default acknowledgement flags of a TC.
    pub default_ack_flags: u8,
    /// Largest TC packet (bytes).
    pub max_tc_packet_len: usize,
    /// Offset of the TM source data (bytes).
    pub tm_source_data_offset: usize,
    /// Offset of the TC application data (bytes).
    pub tc_app_data_offset: usize,
    /// Offset of the CUC timestamp in a TM packet (bytes).
    pub tm_time_offset: usize,
    /// CUC coarse bytes.
    pub cuc_coarse_bytes: usize,
    /// CUC fine bytes.
    pub cuc_fine_bytes: usize,
    /// CUC fractions per second.
    pub cuc_fractions_per_second: u64,
    /// Control cycle (s).
    pub control_cycle_s: f64,
    /// Periodic housekeeping (s).
    pub housekeeping_period_s: f64,
}

/// The whole mission database.
#[derive(Clone, Debug, Serialize)]
pub struct Mdb {
    /// Space system name.
    pub name: &'static str,
    /// Link constants.
    pub link: LinkInfo,
    /// Enumerations.
    pub enums: Vec<Enumeration>,
    /// Bit fields.
    pub bit_fields: Vec<BitField>,
    /// Telecommands.
    pub telecommands: Vec<Telecommand>,
    /// TM packets.
    pub telemetry: Vec<TmPacket>,
    /// Events.
    pub events: Vec<Event>,
    /// Service-1 stages, in order.
    pub verification: Vec<VerificationStage>,
}

// ---------------------------------------------------------------------------------
// Names from the code's own identifiers.

/// `MoveAbsolute` / `Truncated { got: 1 }` -> `MOVE_ABSOLUTE` / `TRUNCATED`.
pub fn upper_snake(debug: &str) -> String {
    let ident: String = debug
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric())
        .collect();
    let mut out = String::new();
    for (i, c) in ident.chars().enumerate() {
        if c.is_ascii_uppercase() && i > 0 {
            out.push('_');
        }
        out.push(c.to_ascii_uppercase());
    }
    out
}

/// The description's name of the telecommand that carries `command` (an exhaustive
/// match: a new [`Command`] variant does not compile until it is named here).
pub fn telecommand_name(command: &Command) -> String {
    match command {
        Command::Ping => "PING".into(),
        Command::HousekeepingOneShot => "HOUSEKEEPING_ONE_SHOT".into(),
        Command::LoadTableChunk(_) => "LOAD_TABLE_CHUNK".into(),
        Command::DumpTable(_) => "DUMP_TABLE".into(),
        Command::ReportParameters(_) => "REPORT_PARAMETER".into(),
        Command::SetParameters(_) => "SET_PARAMETER".into(),
        Command::Schedule(s) => match s {
            ScheduleCommand::EnableRelease => "SCHEDULE_ENABLE_RELEASE",
            ScheduleCommand::DisableRelease => "SCHEDULE_DISABLE_RELEASE",
            ScheduleCommand::Reset => "SCHEDULE_RESET",
            ScheduleCommand::Insert(_) => "SCHEDULE_INSERT_ACTIVITY",
            ScheduleCommand::Delete(_) => "SCHEDULE_DELETE_ACTIVITY",
            ScheduleCommand::TimeShiftAll(_) => "SCHEDULE_TIME_SHIFT_ALL",
            ScheduleCommand::SummaryReport => "SCHEDULE_SUMMARY_REPORT",
        }
        .into(),
        Command::SetTimeReportRate(_) => "SET_TIME_REPORT_RATE".into(),
        Command::MoveAbsolute(_)
        | Command::CheckMove(_)
        | Command::MoveRelative(_)
        | Command::Stop
        | Command::ClearFault
        | Command::DirectStroke { .. }
        | Command::CommitTable { .. }
        | Command::ActivateTable { .. }
        | Command::SwitchBank
        | Command::RevertToNominal => command
            .function_id()
            .map(|f| upper_snake(&format!("{f:?}")))
            .unwrap_or_default(),
    }
}

// ---------------------------------------------------------------------------------
// Field constructors.

fn field(name: &str, offset: usize, wire: Wire, meaning: Meaning, description: &str) -> Field {
    Field {
        name: name.into(),
        offset,
        wire,
        meaning,
        description: description.into(),
    }
}

fn count(name: &str, offset: usize, wire: Wire, description: &str) -> Field {
    field(
        name,
        offset,
        wire,
        Meaning::Number {
            unit: None,
            scale: 1.0,
            range: None,
        },
        description,
    )
}

fn calibrated(
    name: &str,
    offset: usize,
    wire: Wire,
    unit: &'static str,
    scale: f64,
    description: &str,
) -> Field {
    let range = wire
        .raw_range()
        .map(|(lo, hi)| (lo as f64 * scale, hi as f64 * scale));
    field(
        name,
        offset,
        wire,
        Meaning::Number {
            unit: Some(unit),
            scale,
            range,
        },
        description,
    )
}

/// Axis names of a pose, in wire order.
pub const POSE_AXES: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// The six fields of a wire pose at `offset`: translations in um (raw nm), rotations in
/// arcsec (raw micro-arcseconds).
fn pose_fields(prefix: &str, offset: usize, what: &str) -> Vec<Field> {
    POSE_AXES
        .iter()
        .enumerate()
        .map(|(k, axis)| {
            let (unit, scale, frame) = if k < 3 {
                (
                    UNIT_UM,
                    UM_PER_NM,
                    "translation of the moving-platform origin from p0 along base axis",
                )
            } else {
                (
                    UNIT_ARCSEC,
                    ARCSEC_PER_UAS,
                    "rotation R = Rz(gamma) Ry(beta) Rx(alpha), angle about axis",
                )
            };
            calibrated(
                &format!("{prefix}{axis}"),
                offset + 4 * k,
                Wire::I32,
                unit,
                scale,
                &format!("{what}: {frame} {axis} ({unit}; wire i32 in {})", {
                    if k < 3 {
                        "nm"
                    } else {
                        "micro-arcsec"
                    }
                }),
            )
        })
        .collect()
}

fn fixed(name: &str, offset: usize, wire: Wire, value: i64, description: &str) -> Field {
    field(name, offset, wire, Meaning::Fixed { value }, description)
}

// ---------------------------------------------------------------------------------
// Telecommands.

fn int_arg(args: &[ArgValue], i: usize) -> Result<i64, String> {
    match args.get(i) {
        Some(ArgValue::Int(v)) => Ok(*v),
        other => Err(format!("argument {i}: expected an integer, got {other:?}")),
    }
}

fn arg_i32(args: &[ArgValue], i: usize) -> Result<i32, String> {
    i32::try_from(int_arg(args, i)?).map_err(|e| format!("argument {i}: {e}"))
}

fn pose_arg(args: &[ArgValue]) -> Result<WirePose, String> {
    let mut v = [0i32; 6];
    for (k, dst) in v.iter_mut().enumerate() {
        *dst = arg_i32(args, k)?;
    }
    Ok(WirePose::from_array(v))
}

fn build_move_absolute(a: &[ArgValue]) -> Result<Command, String> {
    Ok(Command::MoveAbsolute(pose_arg(a)?))
}
fn build_check_move(a: &[ArgValue]) -> Result<Command, String> {
    Ok(Command::CheckMove(pose_arg(a)?))
}
fn build_report_parameter(a: &[ArgValue]) -> Result<Command, String> {
    let id = u16::try_from(int_arg(a, 0)?).map_err(|e| e.to_string())?;
    ParameterIds::new(&[id])
        .map(Command::ReportParameters)
        .map_err(|e| format!("{e:?}"))
}
fn build_set_parameter(a: &[ArgValue]) -> Result<Command, String> {
    let id = u16::try_from(int_arg(a, 0)?).map_err(|e| e.to_string())?;
    ParameterValues::new(&[(id, arg_i32(a, 1)?)])
        .map(Command::SetParameters)
        .map_err(|e| format!("{e:?}"))
}
fn build_move_relative(a: &[ArgValue]) -> Result<Command, String> {
    Ok(Command::MoveRelative(pose_arg(a)?))
}
fn build_direct_stroke(a: &[ArgValue]) -> Result<Command, String> {
    Ok(Command::DirectStroke {
        leg: u8::try_from(int_arg(a, 0)?).map_err(|e| e.to_string())?,
        delta_nm: arg_i32(a, 1)?,
    })
}
fn build_commit(a: &[ArgValue]) -> Result<Command, String> {
    Ok(Command::CommitTable {
        crc32: u32::try_from(int_arg(a, 0)?).map_err(|e| e.to_string())?,
    })
}
fn build_activate(a: &[ArgValue]) -> Result<Command, String> {
    Ok(Command::ActivateTable {
        table_id: u32::try_from(int_arg(a, 0)?).map_err(|e| e.to_string())?,
        crc32: u32::try_from(int_arg(a, 1)?).map_err(|e| e.to_string())?,
    })
}
fn build_load_chunk(a: &[ArgValue]) -> Result<Command, String> {
    let offset = u16::try_from(int_arg(a, 0)?).map_err(|e| e.to_string())?;
    let Some(ArgValue::Bytes(b)) = a.get(1) else {
        return Err("argument 1: expected bytes".into());
    };
    TableChunk::new(offset, b)
        .map(Command::LoadTableChunk)
        .map_err(|e| format!("{e:?}"))
}
fn build_dump(a: &[ArgValue]) -> Result<Command, String> {
    let code = u8::try_from(int_arg(a, 0)?).map_err(|e| e.to_string())?;
    MemoryId::from_code(code)
        .map(Command::DumpTable)
        .ok_or_else(|| format!("memory ID {code}: unknown"))
}

fn uint_arg<T: TryFrom<i64>>(args: &[ArgValue], i: usize) -> Result<T, String> {
    T::try_from(int_arg(args, i)?).map_err(|_| format!("argument {i}: out of range"))
}
fn schedule(c: ScheduleCommand) -> Result<Command, String> {
    Ok(Command::Schedule(c))
}
fn build_schedule_insert(a: &[ArgValue]) -> Result<Command, String> {
    let release = TmTime {
        seconds: uint_arg(a, 0)?,
        fraction: uint_arg(a, 1)?,
    };
    let Some(ArgValue::Bytes(packet)) = a.get(2) else {
        return Err("argument 2: expected the embedded telecommand's bytes".into());
    };
    let block =
        ActivityBlock::new(&[(release, packet.as_slice())]).map_err(|e| format!("{e:?}"))?;
    schedule(ScheduleCommand::Insert(block))
}
fn build_schedule_delete(a: &[ArgValue]) -> Result<Command, String> {
    let id = RequestId {
        packet_id: uint_arg(a, 0)?,
        sequence_control: uint_arg(a, 1)?,
    };
    let list = RequestIdList::new(&[id]).ok_or("one request ID")?;
    schedule(ScheduleCommand::Delete(list))
}
fn build_schedule_shift(a: &[ArgValue]) -> Result<Command, String> {
    let offset = ObtOffset::from_parts(arg_i32(a, 0)?, uint_arg(a, 1)?);
    schedule(ScheduleCommand::TimeShiftAll(offset))
}
fn build_time_report_rate(a: &[ArgValue]) -> Result<Command, String> {
    let code: u8 = uint_arg(a, 0)?;
    TimeReportRate::from_code(code)
        .map(Command::SetTimeReportRate)
        .ok_or_else(|| format!("time report rate {code}: unknown"))
}

/// The telecommands of the time-based schedule (ST[11]) and the time reports (ST[9]).
/// The Yamcs description inserts or deletes one activity per telecommand (N = 1);
/// the flight link accepts several (docs/icd.md).
fn schedule_telecommands() -> Vec<Telecommand> {
    let tc = |name: &str,
              sub: u8,
              fields: Vec<Field>,
              description: &str,
              build: BuildFn|
     -> Telecommand {
        Telecommand {
            name: name.into(),
            service: service::SCHEDULING,
            subtype: sub,
            function_id: None,
            fields,
            description: description.into(),
            completion_timeout_s: QUICK_COMPLETION_S,
            build,
        }
    };
    let n1 = |what: &str| {
        fixed(
            "count",
            0,
            Wire::U8,
            1,
            &format!("N: one {what} (the flight link takes 1..16)"),
        )
    };
    let mut insert = vec![n1("activity")];
    insert.extend(obt_fields(
        "release_",
        ACTIVITY_COUNT_LEN,
        "release time (on-board time)",
    ));
    insert.push(field(
        "telecommand",
        ACTIVITY_COUNT_LEN + RELEASE_TIME_LEN,
        Wire::Packet {
            min_len: MIN_TC_PACKET_LEN,
            max_len: MAX_SCHEDULED_TC_LEN,
        },
        Meaning::Binary,
        "the telecommand to release: a whole PUS-C TC packet of this controller \
         (e.g. `m2ground tc --unframed move ...`), not a TC[11,x]",
    ));
    let mut shift = vec![field(
        "shift_seconds",
        0,
        Wire::I32,
        Meaning::Number {
            unit: Some("s"),
            scale: 1.0,
            range: None,
        },
        "offset: whole seconds (signed; the offset is seconds + fraction)",
    )];
    shift.push(calibrated(
        "shift_fraction",
        4,
        Wire::U16,
        "s",
        S_PER_CUC_FRACTION,
        "offset: fraction of a second added to the seconds (s; wire u16 in 1/65536 s)",
    ));
    vec![
        tc(
            "SCHEDULE_ENABLE_RELEASE",
            subtype::SCHEDULE_ENABLE,
            Vec::new(),
            "Release activities when their time comes; those whose time passed while \
             release was disabled are deleted (event ACTIVITY_EXPIRED).",
            |_| schedule(ScheduleCommand::EnableRelease),
        ),
        tc(
            "SCHEDULE_DISABLE_RELEASE",
            subtype::SCHEDULE_DISABLE,
            Vec::new(),
            "Release nothing; activities stay in the schedule.",
            |_| schedule(ScheduleCommand::DisableRelease),
        ),
        tc(
            "SCHEDULE_RESET",
            subtype::SCHEDULE_RESET,
            Vec::new(),
            "Delete every activity; release is disabled afterwards.",
            |_| schedule(ScheduleCommand::Reset),
        ),
        tc(
            "SCHEDULE_INSERT_ACTIVITY",
            subtype::SCHEDULE_INSERT,
            insert,
            "Insert a time-tagged telecommand (refused if the schedule is full, the time \
             is past or the request ID is already scheduled).",
            build_schedule_insert,
        ),
        tc(
            "SCHEDULE_DELETE_ACTIVITY",
            subtype::SCHEDULE_DELETE,
            vec![
                n1("request ID"),
                count(
                    "activity_packet_id",
                    ACTIVITY_COUNT_LEN,
                    Wire::U16,
                    "request ID: packet ID of the embedded TC",
                ),
                count(
                    "activity_sequence_control",
                    ACTIVITY_COUNT_LEN + 2,
                    Wire::U16,
                    "request ID: sequence flags and count of the embedded TC",
                ),
            ],
            "Delete the activity with this request ID.",
            build_schedule_delete,
        ),
        tc(
            "SCHEDULE_TIME_SHIFT_ALL",
            subtype::SCHEDULE_TIME_SHIFT_ALL,
            shift,
            "Move every release time by the offset (refused if one would be in the past).",
            build_schedule_shift,
        ),
        tc(
            "SCHEDULE_SUMMARY_REPORT",
            subtype::SCHEDULE_SUMMARY_ALL,
            Vec::new(),
            "Report every activity (TM[11,13]).",
            |_| schedule(ScheduleCommand::SummaryReport),
        ),
        Telecommand {
            name: "SET_TIME_REPORT_RATE".into(),
            service: service::TIME,
            subtype: subtype::SET_TIME_REPORT_RATE,
            function_id: None,
            fields: vec![field(
                "rate",
                0,
                Wire::U8,
                Meaning::Enum {
                    enumeration: "time_report_rate",
                },
                "a TM[9,2] every 2^N s of on-board time, or off",
            )],
            description: "Set the time report (TM[9,2]) generation rate.".into(),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: build_time_report_rate,
        },
    ]
}

/// The TC[8,1] arguments and builder of a function (an exhaustive match: a new function
/// ID does not compile until it is described).
fn function_args(f: FunctionId) -> (Vec<Field>, BuildFn, &'static str, f64) {
    let at = FUNCTION_ID_LEN;
    let none = |b: BuildFn, d: &'static str| (Vec::new(), b, d, QUICK_COMPLETION_S);
    match f {
        FunctionId::MoveAbsolute => (
            pose_fields("", at, "target pose"),
            build_move_absolute,
            "Move to an absolute pose (all-or-nothing workspace and path check).",
            MOVE_COMPLETION_S,
        ),
        FunctionId::MoveRelative => (
            pose_fields("", at, "increment from the commanded pose"),
            build_move_relative,
            "Move by an increment added component-wise to the commanded pose.",
            MOVE_COMPLETION_S,
        ),
        FunctionId::CheckMove => (
            pose_fields("", at, "target pose (as MOVE_ABSOLUTE)"),
            build_check_move,
            "Check a move without moving: TM[8,130] gives the code MOVE_ABSOLUTE would get now and the refusal bits of the target and of the first refused path point.",
            QUICK_COMPLETION_S,
        ),
        FunctionId::Stop => none(|_| Ok(Command::Stop), "Stop any motion (ramp down)."),
        FunctionId::ClearFault => none(|_| Ok(Command::ClearFault), "Clear latched faults."),
        FunctionId::DirectStroke => (
            vec![
                field(
                    "leg",
                    at,
                    Wire::U8,
                    Meaning::Number {
                        unit: None,
                        scale: 1.0,
                        range: Some((1.0, LEGS as f64)),
                    },
                    "slider 1..6",
                ),
                calibrated(
                    "delta",
                    at + 1,
                    Wire::I32,
                    UNIT_UM,
                    UM_PER_NM,
                    "stroke increment along base z (um; wire i32 in nm)",
                ),
            ],
            build_direct_stroke,
            "Move one slider by a stroke increment (recovery).",
            MOVE_COMPLETION_S,
        ),
        FunctionId::CommitTable => (
            vec![count(
                "crc32",
                at,
                Wire::U32,
                "CRC-32/ISO-HDLC of table bytes 0..512 (= the table's last four bytes, LE)",
            )],
            build_commit,
            "Commit the uploaded table (checked, validated, written to the inactive bank).",
            QUICK_COMPLETION_S,
        ),
        FunctionId::ActivateTable => (
            vec![
                count(
                    "table_id",
                    at,
                    Wire::U32,
                    "expected table ID of the pending table",
                ),
                count(
                    "crc32",
                    at + 4,
                    Wire::U32,
                    "expected CRC-32 of the pending table",
                ),
            ],
            build_activate,
            "Activate the pending (committed) table named by its ID and CRC (at rest only).",
            QUICK_COMPLETION_S,
        ),
        FunctionId::SwitchBank => none(
            |_| Ok(Command::SwitchBank),
            "Switch to the other flash bank's table.",
        ),
        FunctionId::RevertToNominal => none(
            |_| Ok(Command::RevertToNominal),
            "Revert to the compiled-in nominal table.",
        ),
    }
}

fn telecommands() -> Vec<Telecommand> {
    let mut v = vec![
        Telecommand {
            name: "PING".into(),
            service: service::TEST,
            subtype: subtype::PING,
            function_id: None,
            fields: Vec::new(),
            description: "Are-you-alive: the controller answers TM[17,2].".into(),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: |_| Ok(Command::Ping),
        },
        Telecommand {
            name: "HOUSEKEEPING_ONE_SHOT".into(),
            service: service::HOUSEKEEPING,
            subtype: subtype::HK_ONE_SHOT,
            function_id: None,
            fields: Vec::new(),
            description: "Send one housekeeping report TM[3,25] now.".into(),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: |_| Ok(Command::HousekeepingOneShot),
        },
        Telecommand {
            name: "LOAD_TABLE_CHUNK".into(),
            service: service::MEMORY,
            subtype: subtype::MEMORY_LOAD,
            function_id: None,
            fields: vec![
                fixed(
                    "memory_id",
                    0,
                    Wire::U8,
                    i64::from(MemoryId::UploadBuffer.code()),
                    "memory ID: the upload buffer",
                ),
                field(
                    "offset",
                    1,
                    Wire::U16,
                    Meaning::Number {
                        unit: Some("byte"),
                        scale: 1.0,
                        range: Some((0.0, (TABLE_LEN - 1) as f64)),
                    },
                    "offset of the chunk in the table image (bytes)",
                ),
                field(
                    "data",
                    3,
                    Wire::Bytes {
                        min_len: 1,
                        max_len: TABLE_CHUNK_MAX_LEN,
                    },
                    Meaning::Binary,
                    "chunk bytes (u16 length, then the bytes)",
                ),
            ],
            description: "Load one table chunk into the upload buffer.".into(),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: build_load_chunk,
        },
        Telecommand {
            name: "DUMP_TABLE".into(),
            service: service::MEMORY,
            subtype: subtype::MEMORY_DUMP,
            function_id: None,
            fields: vec![field(
                "memory_id",
                0,
                Wire::U8,
                Meaning::Enum {
                    enumeration: "memory_id",
                },
                "memory area to dump as TM[6,6] chunks",
            )],
            description: "Dump a table as TM[6,6] chunks.".into(),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: build_dump,
        },
        Telecommand {
            name: "REPORT_PARAMETER".into(),
            service: service::PARAMETER,
            subtype: subtype::PARAMETER_REPORT_REQUEST,
            function_id: None,
            fields: vec![
                fixed("count", 0, Wire::U8, 1, "number of parameter IDs (this description: one)"),
                field(
                    "parameter_id",
                    1,
                    Wire::U16,
                    Meaning::Enum {
                        enumeration: "parameter_id",
                    },
                    "on-board parameter to report",
                ),
            ],
            description: "Report an on-board parameter's effective value as TM[20,2] (the link takes up to 16 IDs).".into(),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: build_report_parameter,
        },
        Telecommand {
            name: "SET_PARAMETER".into(),
            service: service::PARAMETER,
            subtype: subtype::PARAMETER_SET,
            function_id: None,
            fields: vec![
                fixed("count", 0, Wire::U8, 1, "number of (ID, value) pairs (this description: one)"),
                field(
                    "parameter_id",
                    1,
                    Wire::U16,
                    Meaning::Enum {
                        enumeration: "parameter_id",
                    },
                    "on-board parameter to set",
                ),
                count(
                    "value",
                    3,
                    Wire::I32,
                    "new value in the parameter's wire unit (parameter_id enumeration: unit and range)",
                ),
            ],
            description: "Set an on-board parameter (at rest only; persisted before it applies, completion then; the link takes up to 16 pairs, all-or-nothing).".into(),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: build_set_parameter,
        },
    ];
    for f in FunctionId::ALL {
        let (fields, build, description, completion_timeout_s) = function_args(f);
        v.push(Telecommand {
            name: upper_snake(&format!("{f:?}")),
            service: service::FUNCTION,
            subtype: subtype::PERFORM_FUNCTION,
            function_id: Some(f.code()),
            fields,
            description: description.into(),
            completion_timeout_s,
            build,
        });
    }
    v.extend(schedule_telecommands());
    v
}

// ---------------------------------------------------------------------------------
// Housekeeping.

/// Reads one housekeeping member as the raw integer of its wire field.
pub type HkGetter = fn(&Housekeeping) -> i64;

fn hk_pose(p: &WirePose, k: usize) -> i64 {
    p.to_array().get(k).copied().map_or(0, i64::from)
}

macro_rules! pose_getters {
    ($member:ident) => {
        [
            |h: &Housekeeping| hk_pose(&h.$member, 0),
            |h: &Housekeeping| hk_pose(&h.$member, 1),
            |h: &Housekeeping| hk_pose(&h.$member, 2),
            |h: &Housekeeping| hk_pose(&h.$member, 3),
            |h: &Housekeeping| hk_pose(&h.$member, 4),
            |h: &Housekeeping| hk_pose(&h.$member, 5),
        ]
    };
}

macro_rules! leg_getters {
    ($member:ident) => {
        [
            |h: &Housekeeping| i64::from(h.$member[0]),
            |h: &Housekeeping| i64::from(h.$member[1]),
            |h: &Housekeeping| i64::from(h.$member[2]),
            |h: &Housekeeping| i64::from(h.$member[3]),
            |h: &Housekeeping| i64::from(h.$member[4]),
            |h: &Housekeeping| i64::from(h.$member[5]),
        ]
    };
}

/// The housekeeping fields with their accessors into [`Housekeeping`] (the structure
/// ID has none: it is the constant [`HK_STRUCTURE_ID`]).
pub fn housekeeping_fields() -> Vec<(Field, Option<HkGetter>)> {
    let e = |name: &str, off, enumeration, d: &str| {
        field(name, off, Wire::U8, Meaning::Enum { enumeration }, d)
    };
    let b = |name: &str, off, wire, bit_field, d: &str| {
        field(name, off, wire, Meaning::Bits { bit_field }, d)
    };
    let mut v: Vec<(Field, Option<HkGetter>)> = vec![
        (
            fixed(
                "structure_id",
                0,
                Wire::U8,
                i64::from(HK_STRUCTURE_ID),
                "structure ID of the one housekeeping report",
            ),
            None,
        ),
        (
            e("state", 1, "controller_state", "controller state"),
            Some(|h| i64::from(h.state)),
        ),
        (
            e(
                "boot_source",
                2,
                "boot_source",
                "where the boot table came from",
            ),
            Some(|h| i64::from(h.boot_source)),
        ),
        (
            e("active_bank", 3, "bank", "flash bank of the active table"),
            Some(|h| i64::from(h.active_bank)),
        ),
        (
            count(
                "fk_iterations",
                4,
                Wire::U8,
                "Newton iterations of the last FK",
            ),
            Some(|h| i64::from(h.fk_iterations)),
        ),
        (
            field(
                "fk_valid",
                5,
                Wire::U8,
                Meaning::Boolean,
                "the FK pose is this cycle's (false: FK failed)",
            ),
            Some(|h| i64::from(h.fk_valid)),
        ),
        (
            count("cycle_counter", 6, Wire::U32, "control cycle counter"),
            Some(|h| i64::from(h.cycle_counter)),
        ),
        (
            b(
                "fault_flags",
                10,
                Wire::U32,
                "fault_flags",
                "latched fault flags",
            ),
            Some(|h| i64::from(h.fault_flags)),
        ),
        (
            b(
                "warning_flags",
                14,
                Wire::U32,
                "fault_flags",
                "warning flags",
            ),
            Some(|h| i64::from(h.warning_flags)),
        ),
        (
            b(
                "refusal_bits",
                18,
                Wire::U32,
                "refusal_bits",
                "refusal bits of the last refused move",
            ),
            Some(|h| i64::from(h.refusal_bits)),
        ),
        (
            count("active_table_id", 22, Wire::U32, "active table ID"),
            Some(|h| i64::from(h.active_table_id)),
        ),
        (
            count("active_table_crc32", 26, Wire::U32, "active table CRC-32"),
            Some(|h| i64::from(h.active_table_crc32)),
        ),
    ];
    let groups: [(&str, usize, &str, [HkGetter; 6]); 2] = [
        (
            "pose_fk_",
            30,
            "pose from FK of the encoders",
            pose_getters!(pose_fk),
        ),
        (
            "pose_cmd_",
            54,
            "commanded pose",
            pose_getters!(pose_commanded),
        ),
    ];
    for (prefix, off, what, getters) in groups {
        for (f, g) in pose_fields(prefix, off, what).into_iter().zip(getters) {
            v.push((f, Some(g)));
        }
    }
    let legs: [(&str, usize, &str, [HkGetter; 6]); 2] = [
        (
            "stroke_cmd_leg",
            78,
            "commanded stroke (um; wire i32 in nm)",
            leg_getters!(strokes_commanded_nm),
        ),
        (
            "encoder_leg",
            102,
            "encoder reading (um; wire i32 in nm, multiples of one 0.1 um count)",
            leg_getters!(encoders_nm),
        ),
    ];
    for (prefix, off, what, getters) in legs {
        for (i, g) in getters.into_iter().enumerate() {
            v.push((
                calibrated(
                    &format!("{prefix}{}", i + 1),
                    off + 4 * i,
                    Wire::I32,
                    UNIT_UM,
                    UM_PER_NM,
                    &format!("leg {}: {what}", i + 1),
                ),
                Some(g),
            ));
        }
    }
    v.extend([
        (
            count(
                "tc_accepted",
                126,
                Wire::U16,
                "telecommands accepted (wrapping)",
            ),
            Some((|h| i64::from(h.tc_accepted)) as HkGetter),
        ),
        (
            count(
                "tc_rejected",
                128,
                Wire::U16,
                "telecommands rejected (wrapping)",
            ),
            Some(|h| i64::from(h.tc_rejected)),
        ),
        (
            field(
                "last_failure_code",
                130,
                Wire::U16,
                Meaning::Enum {
                    enumeration: "failure_code",
                },
                "last failure code reported (0 none)",
            ),
            Some(|h| i64::from(h.last_failure_code)),
        ),
        (
            b(
                "moving_legs",
                132,
                Wire::U8,
                "leg_mask",
                "legs commanded to move",
            ),
            Some(|h| i64::from(h.moving_legs)),
        ),
        (
            b(
                "fault_legs",
                133,
                Wire::U8,
                "leg_mask",
                "legs named by the latched faults",
            ),
            Some(|h| i64::from(h.fault_legs)),
        ),
        (
            e(
                "pending_bank",
                134,
                "bank",
                "bank of the pending (committed, not activated) table",
            ),
            Some(|h| i64::from(h.pending_bank)),
        ),
        (
            count(
                "pending_table_id",
                135,
                Wire::U32,
                "pending table ID (0 if none)",
            ),
            Some(|h| i64::from(h.pending_table_id)),
        ),
        (
            count(
                "job",
                139,
                Wire::U8,
                "background job running: 0 none, 1 commit, 2 selection, 3 reload, 4 parameters",
            ),
            Some(|h| i64::from(h.job)),
        ),
        (
            count(
                "selected_source",
                140,
                Wire::U8,
                "selected table (what boots): 0 nominal, 1 A, 2 B, 255 no selection record",
            ),
            Some(|h| i64::from(h.selected_source)),
        ),
        (
            count(
                "tm_dropped",
                141,
                Wire::U16,
                "telemetry records dropped (wrapping)",
            ),
            Some(|h| i64::from(h.tm_dropped)),
        ),
        (
            count(
                "tc_frames_dropped",
                143,
                Wire::U16,
                "telecommand frames dropped: too long or bad COBS (wrapping)",
            ),
            Some(|h| i64::from(h.tc_frames_dropped)),
        ),
        (
            count(
                "uart_overruns",
                145,
                Wire::U16,
                "UART receive overruns and RX queue overflows (wrapping)",
            ),
            Some(|h| i64::from(h.uart_overruns)),
        ),
        (
            count(
                "cycle_overruns",
                147,
                Wire::U16,
                "control-cycle overruns (wrapping)",
            ),
            Some(|h| i64::from(h.cycle_overruns)),
        ),
        (
            count(
                "reset_cause",
                149,
                Wire::U8,
                "reset cause: 0 power-on, 1 watchdog, 2 software, 3 HardFault, 4 panic, 5 external",
            ),
            Some(|h| i64::from(h.reset_cause)),
        ),
        (
            count("boot_count", 150, Wire::U16, "boot count (wrapping)"),
            Some(|h| i64::from(h.boot_count)),
        ),
        (
            count(
                "bank_health",
                152,
                Wire::U8,
                "flash bank health: bit 0 bank A, bit 1 bank B corrupt",
            ),
            Some(|h| i64::from(h.bank_health)),
        ),
    ]);
    let pivot: [HkGetter; 3] = [
        |h| i64::from(h.pivot_nm[0]),
        |h| i64::from(h.pivot_nm[1]),
        |h| i64::from(h.pivot_nm[2]),
    ];
    for (k, g) in pivot.into_iter().enumerate() {
        let axis = POSE_AXES.get(k).copied().unwrap_or("");
        v.push((
            calibrated(
                &format!("pivot_{axis}"),
                153 + 4 * k,
                Wire::I32,
                UNIT_UM,
                UM_PER_NM,
                &format!("pivot in M's coordinates, {axis} (um; wire i32 in nm; ST[20] parameter)"),
            ),
            Some(g),
        ));
    }
    let operator: [(&str, usize, &str, [HkGetter; 6]); 2] = [
        (
            "pose_fk_op_",
            165,
            "pose from FK in the operator's frames (about the pivot, in the user frame)",
            pose_getters!(pose_fk_operator),
        ),
        (
            "pose_cmd_op_",
            189,
            "commanded pose in the operator's frames (about the pivot, in the user frame)",
            pose_getters!(pose_commanded_operator),
        ),
    ];
    for (prefix, off, what, getters) in operator {
        for (f, g) in pose_fields(prefix, off, what).into_iter().zip(getters) {
            v.push((f, Some(g)));
        }
    }
    v.push((
        count(
            "parameters_set",
            213,
            Wire::U32,
            "on-board parameters set by TC[20,3] (bit i = parameter index i; clear: default)",
        ),
        Some(|h| i64::from(h.parameters_set)),
    ));
    // Time-based schedule (ST[11]) and time reports (ST[9]): offsets 217..230.
    let next = obt_fields(
        "schedule_next_release_",
        223,
        "release time of the next activity (0 if none)",
    );
    let mut next = next.into_iter();
    v.extend([
        (
            count(
                "schedule_activities",
                217,
                Wire::U8,
                "activities in the time-based schedule",
            ),
            Some((|h| i64::from(h.schedule.activities)) as HkGetter),
        ),
        (
            field(
                "schedule_release_enabled",
                218,
                Wire::U8,
                Meaning::Boolean,
                "activities are released when their time comes",
            ),
            Some(|h| i64::from(h.schedule.release_enabled)),
        ),
        (
            count(
                "schedule_released",
                219,
                Wire::U16,
                "activities released since boot (wrapping)",
            ),
            Some(|h| i64::from(h.schedule.released)),
        ),
        (
            count(
                "schedule_failed",
                221,
                Wire::U16,
                "released activities whose telecommand failed (wrapping)",
            ),
            Some(|h| i64::from(h.schedule.failed)),
        ),
    ]);
    if let (Some(sec), Some(frac)) = (next.next(), next.next()) {
        v.push((sec, Some(|h| i64::from(h.schedule.next_release.seconds))));
        v.push((frac, Some(|h| i64::from(h.schedule.next_release.fraction))));
    }
    v.push((
        field(
            "time_report_rate",
            229,
            Wire::U8,
            Meaning::Enum {
                enumeration: "time_report_rate",
            },
            "time report (TM[9,2]) rate in force",
        ),
        Some(|h| i64::from(h.schedule.time_report_rate)),
    ));
    let switches: [(&str, usize, &str, HkGetter); 4] = [
        (
            "limit_lower_legs",
            230,
            "legs at their lower end-of-travel switch (last cycle's read)",
            |h| i64::from(h.limit_lower_legs),
        ),
        (
            "limit_upper_legs",
            231,
            "legs at their upper end-of-travel switch (last cycle's read)",
            |h| i64::from(h.limit_upper_legs),
        ),
        (
            "reference_legs",
            232,
            "legs at their reference (home) sensor",
            |h| i64::from(h.reference_legs),
        ),
        (
            "switch_unreadable_legs",
            233,
            "legs with a switch input that cannot be read (both directions blocked)",
            |h| i64::from(h.switch_unreadable_legs),
        ),
    ];
    for (name, off, what, g) in switches {
        v.push((b(name, off, Wire::U8, "leg_mask", what), Some(g)));
    }
    v
}

// ---------------------------------------------------------------------------------
// Telemetry packets.

fn telemetry() -> Vec<TmPacket> {
    let rid = |off| {
        vec![
            count(
                "tc_packet_id",
                off,
                Wire::U16,
                "request ID: packet ID of the TC (version, type, sec. header, APID)",
            ),
            count(
                "tc_sequence_control",
                off + 2,
                Wire::U16,
                "request ID: sequence flags and count of the TC",
            ),
        ]
    };
    let mut failure = rid(0);
    failure.extend([
        field(
            "failure_code",
            4,
            Wire::U16,
            Meaning::Enum {
                enumeration: "failure_code",
            },
            "failure code",
        ),
        count(
            "failure_data",
            6,
            Wire::U32,
            "failure datum (per code: refusal bits, flags, a/b = a << 16 | b)",
        ),
    ]);
    vec![
        TmPacket {
            name: "verification_success".into(),
            service: service::VERIFICATION,
            subtypes: vec![
                subtype::ACCEPTANCE_SUCCESS,
                subtype::START_SUCCESS,
                subtype::COMPLETION_SUCCESS,
            ],
            fields: rid(0),
            fixed_len: Some(4),
            description: "TM[1,1] acceptance, [1,3] start, [1,7] completion success".into(),
            repeated: None,
        },
        TmPacket {
            name: "verification_failure".into(),
            service: service::VERIFICATION,
            subtypes: vec![
                subtype::ACCEPTANCE_FAILURE,
                subtype::START_FAILURE,
                subtype::COMPLETION_FAILURE,
            ],
            fields: failure,
            fixed_len: Some(10),
            description: "TM[1,2] acceptance, [1,4] start, [1,8] completion failure".into(),
            repeated: None,
        },
        TmPacket {
            name: "housekeeping".into(),
            service: service::HOUSEKEEPING,
            subtypes: vec![subtype::HK_REPORT],
            fields: housekeeping_fields().into_iter().map(|(f, _)| f).collect(),
            fixed_len: Some(HK_REPORT_LEN),
            description: "TM[3,25] housekeeping report".into(),
            repeated: None,
        },
        TmPacket {
            name: "event".into(),
            service: service::EVENT,
            subtypes: vec![
                subtype::EVENT_INFO,
                subtype::EVENT_LOW,
                subtype::EVENT_MEDIUM,
                subtype::EVENT_HIGH,
            ],
            fields: vec![
                field(
                    "event_id",
                    0,
                    Wire::U16,
                    Meaning::Enum {
                        enumeration: "event_id",
                    },
                    "event ID",
                ),
                count("event_aux0", 2, Wire::U32, "auxiliary word 0 (per event)"),
                count("event_aux1", 6, Wire::U32, "auxiliary word 1 (per event)"),
            ],
            fixed_len: Some(crate::link::tm::EVENT_REPORT_LEN),
            description: "TM[5,1] info, [5,2] low, [5,3] medium, [5,4] high severity event".into(),
            repeated: None,
        },
        TmPacket {
            name: "table_dump".into(),
            service: service::MEMORY,
            subtypes: vec![subtype::MEMORY_DUMP_REPORT],
            fields: vec![
                field(
                    "dump_memory_id",
                    0,
                    Wire::U8,
                    Meaning::Enum {
                        enumeration: "memory_id",
                    },
                    "memory area",
                ),
                count("dump_offset", 1, Wire::U16, "offset of the chunk (bytes)"),
                field(
                    "dump_data",
                    3,
                    Wire::Bytes {
                        min_len: 1,
                        max_len: TABLE_CHUNK_MAX_LEN,
                    },
                    Meaning::Binary,
                    "chunk bytes (u16 length, then the bytes)",
                ),
            ],
            fixed_len: None,
            description: "TM[6,6] table dump chunk".into(),
            repeated: None,
        },
        TmPacket {
            name: "move_check".into(),
            service: service::FUNCTION,
            subtypes: vec![subtype::MOVE_CHECK_REPORT],
            fields: {
                let mut f = rid(0);
                for r in &mut f {
                    r.name = format!("check_{}", r.name);
                }
                f.extend([
                    field(
                        "check_code",
                        4,
                        Wire::U16,
                        Meaning::Enum {
                            enumeration: "failure_code",
                        },
                        "the code MOVE_ABSOLUTE would be refused with now (0: it would be accepted)",
                    ),
                    field(
                        "check_target_refusals",
                        6,
                        Wire::U32,
                        Meaning::Bits {
                            bit_field: "refusal_bits",
                        },
                        "refusal bits of the target pose",
                    ),
                    field(
                        "check_path_refusals",
                        10,
                        Wire::U32,
                        Meaning::Bits {
                            bit_field: "refusal_bits",
                        },
                        "refusal bits of the first refused path point (0: none)",
                    ),
                    count(
                        "check_path_sample",
                        14,
                        Wire::U8,
                        "index of that path point (0: none)",
                    ),
                ]);
                f
            },
            fixed_len: Some(MOVE_CHECK_REPORT_LEN),
            description: "TM[8,130] move check report (answer to CHECK_MOVE)".into(),
            repeated: None,
        },
        TmPacket {
            name: "parameter_report".into(),
            service: service::PARAMETER,
            subtypes: vec![subtype::PARAMETER_REPORT],
            fields: vec![count(
                "report_count",
                0,
                Wire::U8,
                "number of (ID, value) pairs",
            )],
            fixed_len: None,
            description: "TM[20,2] parameter report: count, then (ID u16, value i32) pairs".into(),
            repeated: Some(Repeated {
                name: "report_parameters".into(),
                count_field: "report_count".into(),
                offset: 1,
                element_len: crate::link::tm::PARAMETER_ENTRY_LEN,
                max_count: crate::link::command::MAX_PARAMETERS_PER_TC,
                fields: vec![
                    count(
                        "report_parameter_id",
                        0,
                        Wire::U16,
                        "parameter ID (the parameter_id enumeration's values)",
                    ),
                    count(
                        "report_value",
                        2,
                        Wire::I32,
                        "the parameter's effective value (its wire unit)",
                    ),
                ],
            }),
        },
        TmPacket {
            name: "ping_reply".into(),
            service: service::TEST,
            subtypes: vec![subtype::PING_REPLY],
            fields: Vec::new(),
            fixed_len: Some(0),
            description: "TM[17,2] are-you-alive reply".into(),
            repeated: None,
        },
        TmPacket {
            name: "cuc_time_report".into(),
            service: service::TIME,
            subtypes: vec![subtype::TIME_REPORT],
            fields: {
                let mut f = vec![field(
                    "cuc_report_rate",
                    0,
                    Wire::U8,
                    Meaning::Enum {
                        enumeration: "time_report_rate",
                    },
                    "time report rate in force",
                )];
                f.extend(obt_fields(
                    "cuc_report_obt_",
                    1,
                    "on-board time of the report",
                ));
                f
            },
            fixed_len: Some(TIME_REPORT_LEN),
            description: "TM[9,2] CUC time report (on-board time since boot)".into(),
            repeated: None,
        },
        TmPacket {
            name: "schedule_summary".into(),
            service: service::SCHEDULING,
            subtypes: vec![subtype::SCHEDULE_SUMMARY_REPORT],
            fields: vec![count(
                "summary_count",
                0,
                Wire::U8,
                "activities in the schedule (N)",
            )],
            fixed_len: None,
            description: "TM[11,13] time-based schedule summary: release time and request ID \
                          of every activity, in release order"
                .into(),
            repeated: Some(Repeated {
                name: "summary_activities".into(),
                count_field: "summary_count".into(),
                offset: ACTIVITY_COUNT_LEN,
                element_len: SUMMARY_ENTRY_LEN,
                max_count: SCHEDULE_CAPACITY,
                fields: {
                    let mut f = obt_fields("activity_release_", 0, "release time");
                    f.extend([
                        count(
                            "activity_tc_packet_id",
                            RELEASE_TIME_LEN,
                            Wire::U16,
                            "request ID: packet ID of the embedded TC",
                        ),
                        count(
                            "activity_tc_sequence_control",
                            RELEASE_TIME_LEN + 2,
                            Wire::U16,
                            "request ID: sequence flags and count of the embedded TC",
                        ),
                    ]);
                    f
                },
            }),
        },
    ]
}

/// Seconds per CUC fraction (engineering unit of a CUC fine field).
pub const S_PER_CUC_FRACTION: f64 = 1.0 / TIME_FRACTIONS_PER_SECOND as f64;

/// The two fields of a CUC 4+2 on-board time at `offset`: seconds (u32) and the
/// fraction (u16, calibrated to seconds).
fn obt_fields(prefix: &str, offset: usize, what: &str) -> Vec<Field> {
    vec![
        field(
            &format!("{prefix}seconds"),
            offset,
            Wire::U32,
            Meaning::Number {
                unit: Some("s"),
                scale: 1.0,
                range: None,
            },
            &format!("{what}: whole seconds of on-board time since boot (CUC coarse)"),
        ),
        calibrated(
            &format!("{prefix}fraction"),
            offset + CUC_COARSE_BYTES,
            Wire::U16,
            "s",
            S_PER_CUC_FRACTION,
            &format!("{what}: fraction of a second (s; wire u16 in 1/65536 s, CUC fine)"),
        ),
    ]
}

// ---------------------------------------------------------------------------------
// Enumerations and bit fields.

fn controller_states() -> Vec<(i64, String, String)> {
    // Exhaustive: a new state does not compile until it is listed.
    let all = [
        State::Idle,
        State::Moving,
        State::Stopping,
        State::StrokeMoving,
        State::Faulted,
    ];
    all.iter()
        .map(|s| {
            let meaning = match s {
                State::Idle => "holding position, ready",
                State::Moving => "following a trajectory",
                State::Stopping => "decelerating after a stop or a fault",
                State::StrokeMoving => "direct-stroke (recovery) move",
                State::Faulted => "at rest with a latched fault",
            };
            (
                i64::from(s.code()),
                upper_snake(&format!("{s:?}")),
                meaning.into(),
            )
        })
        .collect()
}

fn boot_sources() -> Vec<(i64, String, String)> {
    [BootSource::Nominal, BootSource::BankA, BootSource::BankB]
        .iter()
        .map(|b| {
            let meaning = match b {
                BootSource::Nominal => "the compiled-in nominal table",
                BootSource::BankA => "flash bank A",
                BootSource::BankB => "flash bank B",
            };
            (
                i64::from(b.code()),
                upper_snake(&format!("{b:?}")),
                meaning.into(),
            )
        })
        .collect()
}

fn banks() -> Vec<(i64, String, String)> {
    boot_sources()
        .into_iter()
        .map(|(v, l, m)| {
            if v == i64::from(BootSource::Nominal.code()) {
                (v, "NONE".into(), "no bank (nominal table)".into())
            } else {
                (v, l, m)
            }
        })
        .collect()
}

fn memory_ids() -> Vec<(i64, String, String)> {
    [MemoryId::UploadBuffer, MemoryId::ActiveTable]
        .iter()
        .map(|m| {
            let meaning = match m {
                MemoryId::UploadBuffer => "the upload buffer (RAM)",
                MemoryId::ActiveTable => "the active parameter table",
            };
            (
                i64::from(m.code()),
                upper_snake(&format!("{m:?}")),
                meaning.into(),
            )
        })
        .collect()
}

fn time_report_rates() -> Vec<(i64, String, String)> {
    let mut v: Vec<(i64, String, String)> = (0..=MAX_TIME_REPORT_EXPONENT)
        .map(|n| {
            (
                i64::from(n),
                format!("EVERY_{}_S", 1u32 << n),
                format!("a TM[9,2] every 2^{n} = {} s", 1u32 << n),
            )
        })
        .collect();
    v.push((
        i64::from(TimeReportRate::Off.code()),
        "OFF".into(),
        "no time reports (the state at boot)".into(),
    ));
    v
}

/// One instance of every failure the controller reports, by family, with the family
/// prefix of its label. The labels are the variants' names.
pub fn failure_samples() -> Vec<(&'static str, u16, String)> {
    let mut v: Vec<(&'static str, u16, String)> = Vec::new();
    let mut push = |family: &'static str, code: u16, debug: String| {
        v.push((family, code, debug));
    };
    for e in [
        LinkError::Truncated { got: 0, needed: 0 },
        LinkError::LengthMismatch {
            got: 0,
            declared: 0,
        },
        LinkError::Oversized,
        LinkError::BadFraming,
        LinkError::BadCrc { found: 0 },
        LinkError::WrongApid { apid: 0 },
        LinkError::BadPrimaryHeader,
        LinkError::UnsupportedPusVersion { version: 0 },
        LinkError::UnknownService { service: 0 },
        LinkError::UnknownSubtype {
            service: 0,
            subtype: 0,
        },
        LinkError::UnknownFunction { function_id: 0 },
        LinkError::AppDataLength {
            got: 0,
            expected: 0,
        },
        LinkError::InvalidArgument { index: 0 },
        LinkError::ChunkOutOfRange {
            offset: 0,
            length: 0,
        },
        LinkError::EmbeddedTc { index: 0, code: 0 },
        LinkError::NotSchedulable {
            service: 0,
            subtype: 0,
        },
    ] {
        push("LINK", e.code(), format!("{e:?}"));
    }
    for e in [
        GeometryError::NonFinite,
        GeometryError::UpperNotAboveLower { leg: 0 },
        GeometryError::BadStrokeLimits { leg: 0 },
        GeometryError::BadWorkspaceLimits,
    ] {
        push("GEOMETRY", e.code(), format!("{e:?}"));
    }
    for e in [
        IkError::NonFinite,
        IkError::OutsideWorkspace { axes: 0 },
        IkError::Unreachable { legs: 0 },
        IkError::StrokeLimit { legs: 0 },
    ] {
        push("IK", e.code(), format!("{e:?}"));
    }
    for e in [
        FkError::NonFinite,
        FkError::Unreachable {
            legs: 0,
            iterations: 0,
        },
        FkError::SingularJacobian { iterations: 0 },
        FkError::NotConverged { iterations: 0 },
        FkError::ResidualTooLarge { iterations: 0 },
    ] {
        push("FK", e.code(), format!("{e:?}"));
    }
    for e in [
        TableError::WrongLength { got: 0 },
        TableError::BadMagic,
        TableError::UnsupportedVersion { version: 0 },
        TableError::BadLengthField { length: 0 },
        TableError::BadCrc,
        TableError::ReservedNotZero,
        TableError::MissingLimits,
    ] {
        push("TABLE", e.code(), format!("{e:?}"));
    }
    for e in [
        ValidationError::ProvenanceNotAscii { index: 0 },
        ValidationError::NonFinite { field: 0 },
        ValidationError::CoordinateOffNominal { index: 0 },
        ValidationError::RodLengthImplausible { leg: 0 },
        ValidationError::Geometry(GeometryError::NonFinite),
        ValidationError::StrokeLimitBeyondCap { leg: 0 },
        ValidationError::WorkspaceBeyondCap { axis: 0 },
        ValidationError::Supervision { field: 0 },
        ValidationError::Unreachable { legs: 0 },
        ValidationError::StrokeLimitExceeded { legs: 0 },
        ValidationError::FkFailed {
            corner: 0,
            fk_code: 0,
        },
        ValidationError::FkInaccurate { corner: 0 },
        ValidationError::BadConfig,
    ] {
        push("VALIDATION", e.code(), format!("{e:?}"));
    }
    for e in [
        StoreError::BadLayout,
        StoreError::Flash(embedded_storage::nor_flash::NorFlashErrorKind::Other),
        StoreError::Invalid(ValidationError::BadConfig),
        StoreError::VerifyFailed,
        StoreError::NoRecord(crate::table::BankStatus::Blank),
        StoreError::Busy,
        StoreError::NotExpected,
        StoreError::ThresholdConflict,
    ] {
        push("STORE", e.code(), format!("{e:?}"));
    }
    for e in [
        MotionError::NonFinite,
        MotionError::BadLimits { leg: 0 },
        MotionError::StartRefused(Refusals::default()),
        MotionError::TargetRefused(Refusals::default()),
        MotionError::PathRefused {
            sample: 0,
            refusals: Refusals::default(),
        },
        MotionError::TooLong,
    ] {
        push("MOTION", e.code(), format!("{e:?}"));
    }
    for e in [
        StrokeMoveError::BadLeg,
        StrokeMoveError::NonFinite,
        StrokeMoveError::BadLimits,
        StrokeMoveError::DeltaTooLarge,
        StrokeMoveError::OutsideStrokeRange,
        StrokeMoveError::TooLong,
    ] {
        push("STROKE", e.code(), format!("{e:?}"));
    }
    // The controller's own codes; its pass-through variants (Motion, Stroke, TableDecode,
    // Store) carry the codes listed above.
    for e in [
        CommandError::Faulted(FaultFlags::empty()),
        CommandError::Busy(State::Moving),
        CommandError::FaultPersists(FaultFlags::empty()),
        CommandError::NoPose,
        CommandError::UploadIncomplete(0),
        CommandError::CrcMismatch(0),
        CommandError::NoPending,
        CommandError::Stopped,
        CommandError::AbortedByFault(FaultFlags::empty()),
        CommandError::PendingMismatch { pending_id: 0 },
        CommandError::EncoderSuspect(0),
        CommandError::NoGeometry,
        CommandError::JobBusy(0),
        CommandError::TowardEndOfTravel(0),
    ] {
        push("CONTROLLER", e.code(), format!("{e:?}"));
    }
    for e in [
        ParamError::UnknownId(0),
        ParamError::OutOfRange(0),
        ParamError::WarningNotBelowFault,
        ParamError::Repeated(0),
    ] {
        push("CONTROLLER", e.code(), format!("{e:?}"));
    }
    // The schedule's codes (CommandError::Schedule passes them through).
    for e in [
        ScheduleError::Full { free: 0 },
        ScheduleError::ReleaseTimeInPast { index: 0 },
        ScheduleError::DuplicateRequestId { index: 0 },
        ScheduleError::NotScheduled { index: 0 },
        ScheduleError::ShiftOutOfRange {
            request_id: RequestId::default(),
        },
        ScheduleError::ReleaseTimeBeyondClock { index: 0 },
    ] {
        push("SCHEDULE", e.code(), format!("{e:?}"));
    }
    v
}

fn failure_codes() -> Vec<(i64, String, String)> {
    let mut v = vec![(0, "NONE".to_string(), "no failure".to_string())];
    v.extend(failure_samples().into_iter().map(|(family, code, debug)| {
        (
            i64::from(code),
            format!("{family}_{}", upper_snake(&debug)),
            format!(
                "{} ({family})",
                debug.split([' ', '(']).next().unwrap_or("")
            ),
        )
    }));
    v
}

/// The on-board parameters (ST[20]) with their unit, range and default.
fn parameter_ids() -> Vec<(i64, String, String)> {
    PARAMETERS
        .iter()
        .map(|d| {
            let default = match d.default {
                crate::controller::params::Default::Fixed(v) => format!("{v}"),
                crate::controller::params::Default::Table => "the running table's".into(),
            };
            (
                i64::from(d.id),
                d.name.to_ascii_uppercase(),
                format!(
                    "{} ({}; {}..={}; default {default})",
                    d.name, d.unit, d.min, d.max
                ),
            )
        })
        .collect()
}

/// The events (IDs from [`event_id`], severities as the controller sends them).
pub fn events() -> Vec<Event> {
    let info = EventSeverity::Info;
    let sev = |s: &[EventSeverity]| s.iter().map(|s| severity_name(*s)).collect();
    vec![
        Event {
            id: event_id::STATE_CHANGED,
            name: "STATE_CHANGED",
            severities: sev(&[info]),
            aux0: "old state (controller_state)",
            aux1: "new state (controller_state)",
            message: "controller state {aux0} -> {aux1}",
        },
        Event {
            id: event_id::FAULT_LATCHED,
            name: "FAULT_LATCHED",
            severities: sev(&[EventSeverity::High]),
            aux0: "all latched fault flags (fault_flags)",
            aux1: "newly latched flags (bits 0..23) and the legs they name (bits 24..29)",
            message: "fault latched: flags {aux0}, new {aux1}",
        },
        Event {
            id: event_id::FAULTS_CLEARED,
            name: "FAULTS_CLEARED",
            severities: sev(&[info]),
            aux0: "flags cleared (fault_flags)",
            aux1: "0",
            message: "faults cleared: flags {aux0}",
        },
        Event {
            id: event_id::WARNING_CHANGED,
            name: "WARNING_CHANGED",
            severities: sev(&[EventSeverity::Low]),
            aux0: "warning flags (fault_flags)",
            aux1: "legs of the warnings (leg mask)",
            message: "warning flags now {aux0}",
        },
        Event {
            id: event_id::MOVE_REFUSED,
            name: "MOVE_REFUSED",
            severities: sev(&[EventSeverity::Low]),
            aux0: "refusal bits (refusal_bits)",
            aux1: "failure code (failure_code)",
            message: "move refused: refusal bits {aux0}, failure code {aux1}",
        },
        Event {
            id: event_id::SETPOINT_REFUSED,
            name: "SETPOINT_REFUSED",
            severities: sev(&[EventSeverity::High]),
            aux0: "refusal bits (refusal_bits)",
            aux1: "control cycle",
            message: "setpoint on a planned path failed IK (motion holds): refusal bits {aux0}, cycle {aux1}",
        },
        Event {
            id: event_id::END_OF_TRAVEL,
            name: "END_OF_TRAVEL",
            severities: sev(&[EventSeverity::High]),
            aux0: "legs at the lower switch (bits 0..5), at the upper switch (bits 8..13), with an unreadable input (bits 16..21)",
            aux1: "control cycle",
            message: "end of travel: switches {aux0} at cycle {aux1} (legs stopped toward them)",
        },
        Event {
            id: event_id::TABLE_ACTIVATED,
            name: "TABLE_ACTIVATED",
            severities: sev(&[info]),
            aux0: "table ID",
            aux1: "CRC-32",
            message: "table {aux0} activated, CRC-32 {aux1}",
        },
        Event {
            id: event_id::TABLE_REJECTED,
            name: "TABLE_REJECTED",
            severities: sev(&[EventSeverity::Medium]),
            aux0: "failure code (failure_code)",
            aux1: "ID of the uploaded table for a commit (if it decodes), else 0",
            message: "table rejected: failure code {aux0}, table {aux1}",
        },
        Event {
            id: event_id::TABLE_COMMITTED,
            name: "TABLE_COMMITTED",
            severities: sev(&[info]),
            aux0: "table ID",
            aux1: "bank (boot_source: 1 A, 2 B)",
            message: "table {aux0} committed to bank {aux1}",
        },
        Event {
            id: event_id::TABLE_RELOADED,
            name: "TABLE_RELOADED",
            severities: sev(&[EventSeverity::Medium]),
            aux0: "table ID",
            aux1: "source (boot_source)",
            message: "table {aux0} reloaded from {aux1} after a RAM upset",
        },
        Event {
            id: event_id::BANK_HEALTH,
            name: "BANK_HEALTH",
            severities: sev(&[info, EventSeverity::Medium]),
            aux0: "bit 0 bank A, bit 1 bank B corrupt",
            aux1: "0",
            message: "flash bank health {aux0}",
        },
        Event {
            id: event_id::BOOT,
            name: "BOOT",
            severities: sev(&[info, EventSeverity::Low]),
            aux0: "boot source (boot_source)",
            aux1: "running table ID",
            message: "boot finished: source {aux0}, table {aux1}",
        },
        Event {
            id: event_id::BOOT_DETAIL,
            name: "BOOT_DETAIL",
            severities: sev(&[info]),
            aux0: "boot flags (bank A bits 0..7, fell back bit 7, bank B bits 8..15, selection bits 16..18)",
            aux1: "reset cause (bits 0..7), boot count (bits 16..31)",
            message: "boot detail: flags {aux0}, reset cause and count {aux1}",
        },
        Event {
            id: event_id::DEADLINE_MISSED,
            name: "DEADLINE_MISSED",
            severities: sev(&[EventSeverity::High]),
            aux0: "consecutive overruns",
            aux1: "overruns since boot",
            message: "control cycles overran {aux0} times in a row (total {aux1}): motion stopped",
        },
        Event {
            id: event_id::PARAMETERS_CHANGED,
            name: "PARAMETERS_CHANGED",
            severities: sev(&[info]),
            aux0: "the parameters this telecommand set (bit i = parameter index i)",
            aux1: "every parameter set now (bit i = parameter index i; HK offset 213)",
            message: "on-board parameters changed: {aux0} set (all set: {aux1})",
        },
        Event {
            id: event_id::PARAMETERS_IGNORED,
            name: "PARAMETERS_IGNORED",
            severities: sev(&[EventSeverity::Low]),
            aux0: "persisted parameters not applied (bit i = parameter index i): out of range, or following-error overrides conflicting with the running table",
            aux1: "0",
            message: "persisted parameters {aux0} not applied: the defaults or the table's thresholds run",
        },
        Event {
            id: event_id::ACTIVITY_RELEASED,
            name: "ACTIVITY_RELEASED",
            severities: sev(&[info]),
            aux0: "request ID of the released TC (packet ID << 16 | sequence control)",
            aux1: "release time (on-board time, s)",
            message: "scheduled activity {aux0} released (release time {aux1} s)",
        },
        Event {
            id: event_id::ACTIVITY_FAILED,
            name: "ACTIVITY_FAILED",
            severities: sev(&[EventSeverity::Medium]),
            aux0: "request ID of the released TC (packet ID << 16 | sequence control)",
            aux1: "report subtype (bits 16..23) and failure code (bits 0..15)",
            message: "released activity {aux0} failed: subtype and code {aux1}",
        },
        Event {
            id: event_id::ACTIVITY_EXPIRED,
            name: "ACTIVITY_EXPIRED",
            severities: sev(&[EventSeverity::Low]),
            aux0: "request ID of the deleted TC (packet ID << 16 | sequence control)",
            aux1: "its release time (on-board time, s)",
            message: "activity {aux0} deleted unrun: release time {aux1} s passed while release was disabled",
        },
    ]
}

/// Label of a severity (Yamcs: INFO, WATCH, DISTRESS, CRITICAL for subtypes 1..4).
pub fn severity_name(s: EventSeverity) -> &'static str {
    match s {
        EventSeverity::Info => "INFO",
        EventSeverity::Low => "LOW",
        EventSeverity::Medium => "MEDIUM",
        EventSeverity::High => "HIGH",
    }
}

/// Bit position of a one-bit word.
fn bit_of(word: u32) -> u32 {
    word.trailing_zeros()
}

/// The fault and warning flags, bits from [`FaultFlags`].
pub fn fault_flag_bits() -> Vec<(u32, String, String)> {
    let flags = [
        (
            FaultFlags::FOLLOWING_ERROR,
            "FOLLOWING_ERROR",
            "fault: |measured - commanded stroke| above the fault threshold",
        ),
        (
            FaultFlags::ENCODER_STUCK,
            "ENCODER_STUCK",
            "fault: encoder makes no progress while its slider moves",
        ),
        (
            FaultFlags::ENCODER_JUMP,
            "ENCODER_JUMP",
            "fault: encoder changed more than physically possible in one cycle",
        ),
        (
            FaultFlags::ENCODER_READ_FAILURE,
            "ENCODER_READ_FAILURE",
            "fault: encoder did not answer, corrupted or non-finite",
        ),
        (
            FaultFlags::SOFT_LIMIT,
            "SOFT_LIMIT",
            "fault: measured stroke beyond the soft limit",
        ),
        (
            FaultFlags::FK_NOT_CONVERGED,
            "FK_NOT_CONVERGED",
            "fault: FK of the measured strokes failed",
        ),
        (
            FaultFlags::POSE_OUTSIDE_WORKSPACE,
            "POSE_OUTSIDE_WORKSPACE",
            "fault: measured pose outside the workspace",
        ),
        (
            FaultFlags::DRIVE_FAULT,
            "DRIVE_FAULT",
            "fault: a drive reported a fault",
        ),
        (
            FaultFlags::TABLE_CORRUPT,
            "TABLE_CORRUPT",
            "fault: the running table, geometry, thresholds or parameters in RAM failed the scrub or their check",
        ),
        (
            FaultFlags::DEADLINE_MISSED,
            "DEADLINE_MISSED",
            "fault: control cycles overran their period 3 times in a row",
        ),
        (
            FaultFlags::LIMIT_SWITCH,
            "LIMIT_SWITCH",
            "fault: an end-of-travel switch active, or a switch input unreadable",
        ),
        (
            FaultFlags::OUTPUT_LIMITED,
            "OUTPUT_LIMITED",
            "fault: the output stage clamped a stroke step beyond the speed or acceleration limit (geometry or planner wrong); the drives held at once",
        ),
        (
            FaultFlags::FOLLOWING_WARNING,
            "FOLLOWING_WARNING",
            "warning: following error above the warning threshold",
        ),
        (
            FaultFlags::ENCODER_WARNING,
            "ENCODER_WARNING",
            "warning: an encoder reports its warning bit (maintenance: e.g. a dirty scale)",
        ),
    ];
    flags
        .iter()
        .map(|(f, n, m)| (bit_of(f.bits()), (*n).to_string(), (*m).to_string()))
        .collect()
}

/// The refusal bits, positions from [`Refusals::to_bits`].
pub fn refusal_bits() -> Vec<(u32, String, String)> {
    let mut v = vec![(
        bit_of(
            Refusals {
                non_finite: true,
                ..Refusals::default()
            }
            .to_bits(),
        ),
        "NON_FINITE".to_string(),
        "a pose component is NaN or infinite".to_string(),
    )];
    for leg in 0..LEGS {
        let m = 1u8 << leg;
        let one = |r: Refusals| bit_of(r.to_bits());
        v.push((
            one(Refusals {
                legs_above_max: m,
                ..Refusals::default()
            }),
            format!("LEG{}_ABOVE_MAX", leg + 1),
            format!("leg {} above the upper stroke limit", leg + 1),
        ));
        v.push((
            one(Refusals {
                legs_unreachable: m,
                ..Refusals::default()
            }),
            format!("LEG{}_UNREACHABLE", leg + 1),
            format!("leg {} cannot reach", leg + 1),
        ));
        v.push((
            one(Refusals {
                legs_below_min: m,
                ..Refusals::default()
            }),
            format!("LEG{}_BELOW_MIN", leg + 1),
            format!("leg {} below the lower stroke limit", leg + 1),
        ));
    }
    for (axis, name) in POSE_AXES.iter().enumerate() {
        v.push((
            bit_of(
                Refusals {
                    axes_outside: 1 << axis,
                    ..Refusals::default()
                }
                .to_bits(),
            ),
            format!("{}_OUTSIDE_WORKSPACE", name.to_ascii_uppercase()),
            format!("axis {name} beyond the workspace half-range"),
        ));
    }
    v.sort_by_key(|b| b.0);
    v
}

fn leg_mask_bits() -> Vec<(u32, String, String)> {
    (0..LEGS as u32)
        .map(|i| {
            (
                i,
                format!("LEG{}", i + 1),
                format!("leg {} (bit i = leg i+1)", i + 1),
            )
        })
        .collect()
}

/// The mission database.
pub fn mdb() -> Mdb {
    let event_ids = events()
        .iter()
        .map(|e| (i64::from(e.id), e.name.to_string(), e.message.to_string()))
        .collect();
    Mdb {
        name: "M2",
        link: LinkInfo {
            apid: M2_APID,
            pus_version: PUS_C_VERSION,
            default_ack_flags: AckFlags::ALL.0,
            max_tc_packet_len: MAX_TC_PACKET_LEN,
            tm_source_data_offset: TM_SOURCE_DATA_OFFSET,
            tc_app_data_offset: TC_APP_DATA_OFFSET,
            tm_time_offset: CCSDS_PRIMARY_HEADER_LEN + PUS_TM_SEC_HEADER_LEN_NO_TIME,
            cuc_coarse_bytes: CUC_COARSE_BYTES,
            cuc_fine_bytes: CUC_FINE_BYTES,
            cuc_fractions_per_second: TIME_FRACTIONS_PER_SECOND,
            control_cycle_s: CYCLE_S_F64,
            housekeeping_period_s: f64::from(HK_PERIOD_CYCLES) * CYCLE_S_F64,
        },
        enums: vec![
            Enumeration {
                name: "controller_state",
                values: controller_states(),
            },
            Enumeration {
                name: "boot_source",
                values: boot_sources(),
            },
            Enumeration {
                name: "bank",
                values: banks(),
            },
            Enumeration {
                name: "memory_id",
                values: memory_ids(),
            },
            Enumeration {
                name: "failure_code",
                values: failure_codes(),
            },
            Enumeration {
                name: "event_id",
                values: event_ids,
            },
            Enumeration {
                name: "parameter_id",
                values: parameter_ids(),
            },
            Enumeration {
                name: "time_report_rate",
                values: time_report_rates(),
            },
        ],
        bit_fields: vec![
            BitField {
                name: "fault_flags",
                bits: fault_flag_bits(),
            },
            BitField {
                name: "refusal_bits",
                bits: refusal_bits(),
            },
            BitField {
                name: "leg_mask",
                bits: leg_mask_bits(),
            },
        ],
        telecommands: telecommands(),
        telemetry: telemetry(),
        events: events(),
        verification: vec![
            VerificationStage {
                name: "Acceptance",
                success_subtype: subtype::ACCEPTANCE_SUCCESS,
            },
            VerificationStage {
                name: "Start",
                success_subtype: subtype::START_SUCCESS,
            },
            VerificationStage {
                name: "Completion",
                success_subtype: subtype::COMPLETION_SUCCESS,
            },
        ],
    }
}

// ---------------------------------------------------------------------------------
// Encoding and decoding by the description (what Yamcs does with the XTCE).

impl Field {
    /// Raw integer of this field in `data` (offsets relative to `data`); `None` if out of
    /// bounds or a byte field.
    pub fn read_raw(&self, data: &[u8]) -> Option<i64> {
        let n = self.wire.fixed_len()?;
        let b = data.get(self.offset..self.offset.checked_add(n)?)?;
        let u = b.iter().fold(0u64, |acc, x| (acc << 8) | u64::from(*x));
        Some(match self.wire {
            Wire::I32 => i64::from(u32::try_from(u).ok()? as i32),
            _ => i64::try_from(u).ok()?,
        })
    }

    /// Engineering value of a raw number (raw x scale), for numbers.
    pub fn to_eng(&self, raw: i64) -> f64 {
        match self.meaning {
            Meaning::Number { scale, .. } => raw as f64 * scale,
            _ => raw as f64,
        }
    }

    /// Raw value of an engineering value (nearest, half away from zero), range-checked.
    pub fn to_raw(&self, eng: f64) -> Result<i64, String> {
        let (scale, range) = match self.meaning {
            Meaning::Number { scale, range, .. } => (scale, range),
            _ => (1.0, None),
        };
        if let Some((lo, hi)) = range {
            if !(lo..=hi).contains(&eng) {
                return Err(format!("{} = {eng}: outside {lo}..={hi}", self.name));
            }
        }
        let raw = (eng / scale).round();
        let (lo, hi) = self.wire.raw_range().ok_or("not a number field")?;
        if !raw.is_finite() || raw < lo as f64 || raw > hi as f64 {
            return Err(format!("{} = {eng}: beyond the wire range", self.name));
        }
        Ok(raw as i64)
    }

    /// Is this an operator argument (not a constant)?
    pub fn is_argument(&self) -> bool {
        !matches!(self.meaning, Meaning::Fixed { .. })
    }
}

impl Telecommand {
    /// Operator arguments, in order.
    pub fn arguments(&self) -> impl Iterator<Item = &Field> {
        self.fields.iter().filter(|f| f.is_argument())
    }

    /// Application data encoded by the description from raw argument values.
    pub fn encode_app_data(&self, args: &[ArgValue]) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        if let Some(f) = self.function_id {
            out.extend(f.to_be_bytes());
        }
        let mut next = args.iter();
        for f in &self.fields {
            if out.len() != f.offset {
                return Err(format!(
                    "{}.{}: offset {} != {}",
                    self.name,
                    f.name,
                    f.offset,
                    out.len()
                ));
            }
            let value = match f.meaning {
                Meaning::Fixed { value } => ArgValue::Int(value),
                _ => next
                    .next()
                    .cloned()
                    .ok_or_else(|| format!("{}: missing argument {}", self.name, f.name))?,
            };
            match (f.wire, value) {
                (Wire::Packet { min_len, max_len }, ArgValue::Bytes(b)) => {
                    if !(min_len..=max_len).contains(&b.len()) {
                        return Err(format!("{}: {} bytes", f.name, b.len()));
                    }
                    out.extend(b);
                }
                (Wire::Bytes { min_len, max_len }, ArgValue::Bytes(b)) => {
                    if !(min_len..=max_len).contains(&b.len()) {
                        return Err(format!("{}: {} bytes", f.name, b.len()));
                    }
                    let n = u16::try_from(b.len()).map_err(|e| e.to_string())?;
                    out.extend(n.to_be_bytes());
                    out.extend(b);
                }
                (w, ArgValue::Int(v)) => {
                    let (lo, hi) = w.raw_range().ok_or("bytes field given an integer")?;
                    if !(lo..=hi).contains(&v) {
                        return Err(format!("{} = {v}: beyond the wire range", f.name));
                    }
                    let n = w.fixed_len().unwrap_or(0);
                    let be = v.to_be_bytes();
                    out.extend(be.get(be.len() - n..).unwrap_or(&[]));
                }
                (_, v) => return Err(format!("{}: wrong value kind {v:?}", f.name)),
            }
        }
        if next.next().is_some() {
            return Err(format!("{}: too many arguments", self.name));
        }
        Ok(out)
    }

    /// The whole TC packet encoded by the description (what Yamcs' XTCE encoder and PUS
    /// post-processor produce): primary header, PUS-C secondary header, application
    /// data, CRC-16/CCITT-FALSE.
    pub fn encode_packet(&self, args: &[ArgValue], header: TcHeader) -> Result<Vec<u8>, String> {
        let app = self.encode_app_data(args)?;
        let mut p = Vec::with_capacity(TC_APP_DATA_OFFSET + app.len() + 2);
        // Packet ID: version 0, type TC (bit 12), secondary header (bit 11), APID.
        let packet_id: u16 = (1 << 12) | (1 << 11) | (M2_APID & APID_MASK);
        let seq: u16 = (0b11 << 14) | (header.seq_count & SEQ_COUNT_MASK);
        let total = TC_APP_DATA_OFFSET + app.len() + 2;
        let data_len =
            u16::try_from(total - CCSDS_PRIMARY_HEADER_LEN - 1).map_err(|e| e.to_string())?;
        p.extend(packet_id.to_be_bytes());
        p.extend(seq.to_be_bytes());
        p.extend(data_len.to_be_bytes());
        p.push((PUS_C_VERSION << 4) | (header.ack.0 & 0x0f));
        p.push(self.service);
        p.push(self.subtype);
        p.extend(header.source_id.to_be_bytes());
        p.extend(app);
        let crc = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740).checksum(&p);
        p.extend(crc.to_be_bytes());
        Ok(p)
    }

    /// The same telecommand encoded by the flight link's encoder (for comparison).
    pub fn encode_by_link(&self, args: &[ArgValue], header: TcHeader) -> Result<Vec<u8>, String> {
        let cmd = (self.build)(args)?;
        let mut buf = [0u8; MAX_TC_PACKET_LEN];
        let n = encode_telecommand(&cmd, header, &mut buf).map_err(|e| format!("{e:?}"))?;
        Ok(buf.get(..n).unwrap_or(&[]).to_vec())
    }
}

impl Mdb {
    /// The telecommand of this name.
    pub fn telecommand(&self, name: &str) -> Option<&Telecommand> {
        self.telecommands.iter().find(|t| t.name == name)
    }

    /// The TM packet of this name.
    pub fn tm_packet(&self, name: &str) -> Option<&TmPacket> {
        self.telemetry.iter().find(|t| t.name == name)
    }

    /// Pretty JSON (the input of `yamcs/tools/gen_xtce.py`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}
