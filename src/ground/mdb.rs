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

use crate::controller::jobs::JobKind;
use crate::controller::params::{ParamError, PARAMETERS};
use crate::controller::schedule::ScheduleError;
use crate::controller::{CommandError, State};
use crate::kinematics::{FkError, GeometryError, IkError, Refusals, LEGS};
use crate::link::command::{
    FunctionId, MemoryId, ParameterIds, ParameterValues, TableChunk, WirePose, FUNCTION_ID_LEN,
    MAX_PARAMETERS_PER_TC, TABLE_CHUNK_MAX_LEN,
};
use crate::link::hk::{field as hk_field, HK_REPORT_LEN, HK_STRUCTURE_ID, NO_SELECTION};
use crate::link::schedule::{
    ActivityBlock, ObtOffset, RequestIdList, ScheduleCommand, ACTIVITY_COUNT_LEN,
    MAX_INSERT_APP_DATA_LEN, MAX_SCHEDULED_TC_LEN, RELEASE_TIME_LEN, SCHEDULE_CAPACITY,
    SUMMARY_ENTRY_LEN,
};
use crate::link::tc::{
    RequestId, TcHeader, APID_MASK, MIN_TC_PACKET_LEN, REQUEST_ID_LEN, SEQ_COUNT_MASK,
};
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
use crate::table::{BootSource, StoreError, Table, TableError, ValidationError, TABLE_LEN};
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
    /// Its short name in docs/icd.md (section 3: the telecommand list, or the TC[8,1]
    /// function table).
    pub title: String,
    /// Its application data as the flight link takes it (docs/icd.md section 3; after
    /// the function ID for a TC[8,1] function). The description's `fields` may restrict
    /// it (one parameter per TC[20,x], one activity per TC[11,4]).
    pub app_data_layout: String,
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
    /// Its rows in docs/icd.md's telemetry list (section 4): which subtypes, what they
    /// mean, their source data (together they cover `subtypes` once each).
    pub kinds: Vec<TmKind>,
}

/// One row of docs/icd.md's telemetry list: one or more subtypes of a TM packet layout.
#[derive(Clone, Debug, Serialize)]
pub struct TmKind {
    /// PUS subtypes of the row.
    pub subtypes: Vec<u8>,
    /// What they are.
    pub title: String,
    /// Their source data, as docs/icd.md shows it.
    pub data_layout: String,
}

fn tm_kind(subtypes: &[u8], title: &str, data_layout: &str) -> TmKind {
    TmKind {
        subtypes: subtypes.to_vec(),
        title: title.into(),
        data_layout: data_layout.into(),
    }
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
    /// What it reports.
    pub description: String,
    /// Severities the controller sends it with (TM[5,x] subtype), each with when.
    pub severities: Vec<SeverityUse>,
    /// Meaning of aux0.
    pub aux0: String,
    /// Meaning of aux1.
    pub aux1: String,
    /// One-line text for the operator (`{aux0}`, `{aux1}` are replaced).
    pub message: &'static str,
}

/// One severity an event is sent with.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct SeverityUse {
    /// [`severity_name`].
    pub severity: &'static str,
    /// TM[5,x] subtype.
    pub subtype: u8,
    /// When (empty: whenever the event is not sent with another severity).
    pub when: &'static str,
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
    /// Failure codes with where they are reported and what their data holds (the
    /// `failure_code` enumeration's values).
    pub failure_codes: Vec<FailureCode>,
    /// The parameter table image's layout (what TC[6,2] loads, TM[6,6] dumps).
    pub table_image: Vec<TableImageRow>,
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

/// `f` with its valid range narrowed to `lo..=hi` (engineering units): the controller's
/// own, where it is narrower than the wire's.
fn ranged(mut f: Field, lo: f64, hi: f64) -> Field {
    if let Meaning::Number { range, .. } = &mut f.meaning {
        *range = Some((lo, hi));
    }
    f
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
    // Packet ID of this controller's telecommands (TC, secondary header, APID) and the
    // sequence flags of an unsegmented packet: the only request IDs a schedule holds.
    const TC_PACKET_ID: u16 = (1 << 12) | (1 << 11) | (M2_APID & APID_MASK);
    const TC_UNSEGMENTED: u16 = 0b11 << 14;
    let tc = |name: &str,
              sub: u8,
              fields: Vec<Field>,
              description: &str,
              (title, app_data_layout): (&str, String),
              build: BuildFn|
     -> Telecommand {
        Telecommand {
            name: name.into(),
            service: service::SCHEDULING,
            subtype: sub,
            function_id: None,
            fields,
            description: description.into(),
            title: title.into(),
            app_data_layout,
            completion_timeout_s: QUICK_COMPLETION_S,
            build,
        }
    };
    let none = || "none".to_string();
    let n1 = |what: &str| {
        fixed(
            "count",
            0,
            Wire::U8,
            1,
            &format!("N: one {what} (the flight link takes 1..{SCHEDULE_CAPACITY})"),
        )
    };
    let mut insert = vec![n1("activity")];
    // Release times beyond the clock are refused on board (0x0B06): the seconds here,
    // the fraction of the last second where the ground tool encodes (`m2ground tc`).
    insert.extend(obt_fields(
        "release_",
        ACTIVITY_COUNT_LEN,
        "release time (on-board time)",
    ));
    if let Some(f) = insert.iter_mut().find(|f| f.name == "release_seconds") {
        *f = ranged(
            f.clone(),
            0.0,
            f64::from(crate::controller::schedule::MAX_OBT.seconds),
        );
    }
    insert.push(field(
        "telecommand",
        ACTIVITY_COUNT_LEN + RELEASE_TIME_LEN,
        Wire::Packet {
            min_len: MIN_TC_PACKET_LEN,
            max_len: MAX_SCHEDULED_TC_LEN,
        },
        Meaning::Binary,
        "the telecommand to release: a whole PUS-C TC packet of this controller \
         (e.g. `m2ground tc --unframed move-absolute x=3`), not a TC[11,x]",
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
            title: "set the time report rate".into(),
            app_data_layout: format!(
                "rate u8: N = 0..{MAX_TIME_REPORT_EXPONENT} (a TM[{},{}] every 2^N s), {} off \
                 (section 10)",
                service::TIME,
                subtype::TIME_REPORT,
                TimeReportRate::Off.code()
            ),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: build_time_report_rate,
        },
        tc(
            "SCHEDULE_ENABLE_RELEASE",
            subtype::SCHEDULE_ENABLE,
            Vec::new(),
            "Release activities when their time comes; those whose time passed while \
             release was disabled are deleted (event ACTIVITY_EXPIRED).",
            ("enable the release of time-tagged activities", none()),
            |_| schedule(ScheduleCommand::EnableRelease),
        ),
        tc(
            "SCHEDULE_DISABLE_RELEASE",
            subtype::SCHEDULE_DISABLE,
            Vec::new(),
            "Release nothing; activities stay in the schedule.",
            ("disable the release", none()),
            |_| schedule(ScheduleCommand::DisableRelease),
        ),
        tc(
            "SCHEDULE_RESET",
            subtype::SCHEDULE_RESET,
            Vec::new(),
            "Delete every activity; release is disabled afterwards.",
            ("reset the schedule (delete all; release disabled)", none()),
            |_| schedule(ScheduleCommand::Reset),
        ),
        tc(
            "SCHEDULE_INSERT_ACTIVITY",
            subtype::SCHEDULE_INSERT,
            insert,
            "Insert a time-tagged telecommand (refused if the schedule is full, the time \
             is past or the request ID is already scheduled).",
            (
                "insert time-tagged activities",
                format!(
                    "N u8 (1..), N × (release time CUC {CUC_COARSE_BYTES}+{CUC_FINE_BYTES}, a \
                     whole TC packet); at most {MAX_INSERT_APP_DATA_LEN} bytes (section 10)"
                ),
            ),
            build_schedule_insert,
        ),
        tc(
            "SCHEDULE_DELETE_ACTIVITY",
            subtype::SCHEDULE_DELETE,
            vec![
                n1("request ID"),
                // Only this controller's unsegmented TCs can be scheduled: their packet ID
                // and sequence flags (another ID is never scheduled: 0x0B04).
                ranged(
                    count(
                        "activity_packet_id",
                        ACTIVITY_COUNT_LEN,
                        Wire::U16,
                        "request ID: packet ID of the embedded TC",
                    ),
                    f64::from(TC_PACKET_ID),
                    f64::from(TC_PACKET_ID),
                ),
                ranged(
                    count(
                        "activity_sequence_control",
                        ACTIVITY_COUNT_LEN + 2,
                        Wire::U16,
                        "request ID: sequence flags and count of the embedded TC",
                    ),
                    f64::from(TC_UNSEGMENTED),
                    f64::from(TC_UNSEGMENTED | SEQ_COUNT_MASK),
                ),
            ],
            "Delete the activity with this request ID.",
            (
                "delete activities by request ID",
                format!("N u8 (1..{SCHEDULE_CAPACITY}), N × request ID ({REQUEST_ID_LEN} bytes)"),
            ),
            build_schedule_delete,
        ),
        tc(
            "SCHEDULE_TIME_SHIFT_ALL",
            subtype::SCHEDULE_TIME_SHIFT_ALL,
            shift,
            "Move every release time by the offset (refused if one would be in the past).",
            (
                "time-shift all activities",
                "offset: seconds i32, fraction u16 (section 10)".into(),
            ),
            build_schedule_shift,
        ),
        tc(
            "SCHEDULE_SUMMARY_REPORT",
            subtype::SCHEDULE_SUMMARY_ALL,
            Vec::new(),
            "Report every activity (TM[11,13]).",
            (
                "summary report of all activities",
                format!(
                    "none → TM[{},{}]",
                    service::SCHEDULING,
                    subtype::SCHEDULE_SUMMARY_REPORT
                ),
            ),
            |_| schedule(ScheduleCommand::SummaryReport),
        ),
    ]
}

/// The largest direct-stroke delta any DIRECT_MAX_DELTA admits (nm).
fn max_direct_delta_nm() -> i32 {
    PARAMETERS
        .get(crate::controller::params::index::DIRECT_MAX_DELTA)
        .map_or(0, |p| p.max)
}

/// What the description says of one TC[8,1] function.
struct FunctionDesc {
    fields: Vec<Field>,
    build: BuildFn,
    description: &'static str,
    title: String,
    app_data_layout: String,
    completion_timeout_s: f64,
}

/// The TC[8,1] row of docs/icd.md's telecommand list (section 3): its title and
/// application data; each function's own are in [`Telecommand::title`] and
/// [`Telecommand::app_data_layout`].
pub const PERFORM_FUNCTION: (&str, &str) = (
    "perform function",
    "function ID u16, then the function's arguments (table below)",
);

/// The TC[8,1] arguments, builder and texts of a function (an exhaustive match: a new
/// function ID does not compile until it is described).
fn function_args(f: FunctionId) -> FunctionDesc {
    let at = FUNCTION_ID_LEN;
    let d = |fields: Vec<Field>,
             build: BuildFn,
             description: &'static str,
             (title, layout): (&str, &str),
             completion_timeout_s: f64| FunctionDesc {
        fields,
        build,
        description,
        title: title.into(),
        app_data_layout: layout.into(),
        completion_timeout_s,
    };
    let none = |b: BuildFn, d: &'static str, title: &str| FunctionDesc {
        fields: Vec::new(),
        build: b,
        description: d,
        title: title.into(),
        app_data_layout: "—".into(),
        completion_timeout_s: QUICK_COMPLETION_S,
    };
    match f {
        FunctionId::MoveAbsolute => d(
            pose_fields("", at, "target pose"),
            build_move_absolute,
            "Move to an absolute pose (all-or-nothing workspace and path check).",
            ("move absolute", "pose (below)"),
            MOVE_COMPLETION_S,
        ),
        FunctionId::MoveRelative => d(
            pose_fields("", at, "increment from the commanded pose"),
            build_move_relative,
            "Move by an increment added component-wise to the commanded pose.",
            ("move relative", "pose increment (below)"),
            MOVE_COMPLETION_S,
        ),
        FunctionId::CheckMove => FunctionDesc {
            title: format!(
                "check a move without moving → TM[{},{}]",
                service::FUNCTION,
                subtype::MOVE_CHECK_REPORT
            ),
            ..d(
                pose_fields("", at, "target pose (as MOVE_ABSOLUTE)"),
                build_check_move,
                "Check a move without moving: TM[8,130] gives the code MOVE_ABSOLUTE would get now and the refusal bits of the target and of the first refused path point.",
                ("", "target pose (below), as move absolute"),
                QUICK_COMPLETION_S,
            )
        },
        FunctionId::Stop => none(
            |_| Ok(Command::Stop),
            "Stop any motion (ramp down).",
            "stop (ramp down)",
        ),
        FunctionId::ClearFault => none(
            |_| Ok(Command::ClearFault),
            "Clear latched faults.",
            "clear latched faults",
        ),
        FunctionId::DirectStroke => FunctionDesc {
            app_data_layout: format!(
                "leg u8 (1..{LEGS}); delta i32 (nm, slider stroke along base z)"
            ),
            ..d(
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
                    // No DIRECT_MAX_DELTA admits more (refused on board: 0x0614).
                    ranged(
                        calibrated(
                            "delta",
                            at + 1,
                            Wire::I32,
                            UNIT_UM,
                            UM_PER_NM,
                            "stroke increment along base z (um; wire i32 in nm)",
                        ),
                        -f64::from(max_direct_delta_nm()) * UM_PER_NM,
                        f64::from(max_direct_delta_nm()) * UM_PER_NM,
                    ),
                ],
                build_direct_stroke,
                "Move one slider by a stroke increment (recovery).",
                ("direct stroke move (recovery)", ""),
                MOVE_COMPLETION_S,
            )
        },
        FunctionId::CommitTable => d(
            vec![count(
                "crc32",
                at,
                Wire::U32,
                "CRC-32/ISO-HDLC of table bytes 0..512 (= the table's last four bytes, LE)",
            )],
            build_commit,
            "Commit the uploaded table (checked, validated, written to the inactive bank).",
            (
                "commit the uploaded table",
                "CRC-32 u32 of the table (section 5)",
            ),
            QUICK_COMPLETION_S,
        ),
        FunctionId::ActivateTable => d(
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
            (
                "activate the pending table",
                "expected table ID u32; expected CRC-32 u32",
            ),
            QUICK_COMPLETION_S,
        ),
        FunctionId::SwitchBank => none(
            |_| Ok(Command::SwitchBank),
            "Switch to the other flash bank's table.",
            "switch to the other bank's table",
        ),
        FunctionId::RevertToNominal => none(
            |_| Ok(Command::RevertToNominal),
            "Revert to the compiled-in nominal table.",
            "revert to the compiled-in nominal table",
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
            title: "are-you-alive".into(),
            app_data_layout: format!("none → TM[{},{}]", service::TEST, subtype::PING_REPLY),
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
            title: "one-shot housekeeping report".into(),
            app_data_layout: format!(
                "none → TM[{},{}]",
                service::HOUSEKEEPING,
                subtype::HK_REPORT
            ),
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
            title: "load one table chunk into the upload buffer".into(),
            app_data_layout: format!(
                "memory ID u8 = {}; offset u16 (bytes); length u16 (1..{TABLE_CHUNK_MAX_LEN}); \
                 `length` bytes",
                MemoryId::UploadBuffer.code()
            ),
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
            title: format!(
                "dump a table as TM[{},{}] chunks",
                service::MEMORY,
                subtype::MEMORY_DUMP_REPORT
            ),
            app_data_layout: format!(
                "memory ID u8: {} = running table, {} = upload buffer",
                MemoryId::ActiveTable.code(),
                MemoryId::UploadBuffer.code()
            ),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: build_dump,
        },
    ];
    // docs/icd.md's order: the TC[8,1] functions after the memory services.
    for f in FunctionId::ALL {
        let d = function_args(f);
        v.push(Telecommand {
            name: upper_snake(&format!("{f:?}")),
            service: service::FUNCTION,
            subtype: subtype::PERFORM_FUNCTION,
            function_id: Some(f.code()),
            fields: d.fields,
            description: d.description.into(),
            title: d.title,
            app_data_layout: d.app_data_layout,
            completion_timeout_s: d.completion_timeout_s,
            build: d.build,
        });
    }
    v.extend([
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
            title: format!(
                "report on-board parameters → TM[{},{}]",
                service::PARAMETER,
                subtype::PARAMETER_REPORT
            ),
            app_data_layout: format!(
                "count u8 (1..{MAX_PARAMETERS_PER_TC}); that many parameter IDs u16 (section 5a)"
            ),
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
            title: "set on-board parameters (all or nothing, at rest only)".into(),
            app_data_layout: format!(
                "count u8 (1..{MAX_PARAMETERS_PER_TC}); that many (parameter ID u16, value i32)"
            ),
            completion_timeout_s: QUICK_COMPLETION_S,
            build: build_set_parameter,
        },
    ]);
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

/// One row of the housekeeping layout as docs/icd.md shows it (section 6): one field, or
/// a group of consecutive fields of one item (a pose, the six legs, a CUC time).
#[derive(Clone, Debug)]
pub struct HkRow {
    /// What the row holds: for one field, that field's description.
    pub description: String,
    /// Its fields with their accessors into [`Housekeeping`] (the structure ID has none:
    /// it is the constant [`HK_STRUCTURE_ID`]).
    pub fields: Vec<(Field, Option<HkGetter>)>,
}

impl HkRow {
    fn single(f: Field, get: Option<HkGetter>) -> HkRow {
        HkRow {
            description: f.description.clone(),
            fields: vec![(f, get)],
        }
    }

    fn group(description: String, fields: Vec<(Field, Option<HkGetter>)>) -> HkRow {
        HkRow {
            description,
            fields,
        }
    }
}

/// `0 nominal, 1 A, 2 B` with the codes of [`BootSource`] (`bank`: "bank A" for "A").
fn source_codes(nominal: &str, bank: &str) -> String {
    format!(
        "{} {nominal}, {} {bank}A, {} {bank}B",
        BootSource::Nominal.code(),
        BootSource::BankA.code(),
        BootSource::BankB.code()
    )
}

/// The housekeeping report's rows, in offset order (the fields tile
/// [`HK_REPORT_LEN`] bytes: `host-tests/mdb.rs` reads an emitted report back by them).
pub fn housekeeping_rows() -> Vec<HkRow> {
    let one = |f: Field, get: HkGetter| HkRow::single(f, Some(get));
    let e = |name: &str, off, enumeration, d: &str| {
        field(name, off, Wire::U8, Meaning::Enum { enumeration }, d)
    };
    let b = |name: &str, off, wire, bit_field, d: &str| {
        field(name, off, wire, Meaning::Bits { bit_field }, d)
    };
    let leg_bits = "bit i = leg i+1";
    let mut v: Vec<HkRow> = vec![
        HkRow::single(
            fixed(
                "structure_id",
                hk_field::STRUCTURE_ID.start,
                Wire::U8,
                i64::from(HK_STRUCTURE_ID),
                &format!("structure ID = {HK_STRUCTURE_ID}"),
            ),
            None,
        ),
        one(
            e(
                "state",
                hk_field::STATE.start,
                "controller_state",
                "controller state",
            ),
            |h| i64::from(h.state),
        ),
        one(
            e(
                "boot_source",
                hk_field::BOOT_SOURCE.start,
                "boot_source",
                &format!("boot source: {}", source_codes("nominal", "bank ")),
            ),
            |h| i64::from(h.boot_source),
        ),
        one(
            e(
                "active_bank",
                hk_field::ACTIVE_BANK.start,
                "bank",
                &format!(
                    "source of the running table: {}",
                    source_codes("nominal", "")
                ),
            ),
            |h| i64::from(h.active_bank),
        ),
        one(
            count(
                "fk_iterations",
                hk_field::FK_ITERATIONS.start,
                Wire::U8,
                "last FK Newton iteration count",
            ),
            |h| i64::from(h.fk_iterations),
        ),
        one(
            field(
                "fk_valid",
                hk_field::FK_VALID.start,
                Wire::U8,
                Meaning::Boolean,
                "FK valid (1: the FK pose is this cycle's; 0: FK failed or no reading)",
            ),
            |h| i64::from(h.fk_valid),
        ),
        one(
            count(
                "cycle_counter",
                hk_field::CYCLE_COUNTER.start,
                Wire::U32,
                "control cycle counter: the cycle the report was sampled in, the one its time \
                 stamp names",
            ),
            |h| i64::from(h.cycle_counter),
        ),
        one(
            b(
                "fault_flags",
                hk_field::FAULT_FLAGS.start,
                Wire::U32,
                "fault_flags",
                "fault flags (latched)",
            ),
            |h| i64::from(h.fault_flags),
        ),
        one(
            b(
                "warning_flags",
                hk_field::WARNING_FLAGS.start,
                Wire::U32,
                "fault_flags",
                "warning flags",
            ),
            |h| i64::from(h.warning_flags),
        ),
        one(
            b(
                "refusal_bits",
                hk_field::REFUSAL_BITS.start,
                Wire::U32,
                "refusal_bits",
                "refusal bits of the last refused move",
            ),
            |h| i64::from(h.refusal_bits),
        ),
        one(
            count(
                "active_table_id",
                hk_field::ACTIVE_TABLE_ID.start,
                Wire::U32,
                "running table ID",
            ),
            |h| i64::from(h.active_table_id),
        ),
        one(
            count(
                "active_table_crc32",
                hk_field::ACTIVE_TABLE_CRC32.start,
                Wire::U32,
                "running table CRC-32",
            ),
            |h| i64::from(h.active_table_crc32),
        ),
    ];
    let poses: [(&str, usize, &str, String, [HkGetter; 6]); 2] = [
        (
            "pose_fk_",
            hk_field::POSE_FK.start,
            "pose from FK of the encoders",
            "pose from FK of the encoders (nm, µas; order as the TC pose)".into(),
            pose_getters!(pose_fk),
        ),
        (
            "pose_cmd_",
            hk_field::POSE_COMMANDED.start,
            "commanded pose",
            "commanded pose: the path setpoint, or the pose of the held strokes (nm, µas)".into(),
            pose_getters!(pose_commanded),
        ),
    ];
    for (prefix, off, what, row, getters) in poses {
        let fields = pose_fields(prefix, off, what)
            .into_iter()
            .zip(getters)
            .map(|(f, g)| (f, Some(g)))
            .collect();
        v.push(HkRow::group(row, fields));
    }
    let legs: [(&str, usize, &str, String, [HkGetter; 6]); 2] = [
        (
            "stroke_cmd_leg",
            hk_field::STROKES_COMMANDED.start,
            "commanded stroke (um; wire i32 in nm)",
            format!("commanded (or held) strokes, legs 1..{LEGS} (nm)"),
            leg_getters!(strokes_commanded_nm),
        ),
        (
            "encoder_leg",
            hk_field::ENCODERS.start,
            "encoder reading (um; wire i32 in nm, multiples of one 0.1 um count)",
            format!(
                "encoder readings, legs 1..{LEGS} (nm; the encoders count 0.1 µm, so multiples \
                 of 100)"
            ),
            leg_getters!(encoders_nm),
        ),
    ];
    for (prefix, off, what, row, getters) in legs {
        let fields = getters
            .into_iter()
            .enumerate()
            .map(|(i, g)| {
                (
                    calibrated(
                        &format!("{prefix}{}", i + 1),
                        off + 4 * i,
                        Wire::I32,
                        UNIT_UM,
                        UM_PER_NM,
                        &format!("leg {}: {what}", i + 1),
                    ),
                    Some(g),
                )
            })
            .collect();
        v.push(HkRow::group(row, fields));
    }
    let jobs = [
        JobKind::Commit,
        JobKind::Select,
        JobKind::Reload,
        JobKind::Parameters,
    ]
    .map(|j| {
        // Exhaustive: a new job does not compile until it is named here.
        let name = match j {
            JobKind::Commit => "commit",
            JobKind::Select => "selection",
            JobKind::Reload => "reload",
            JobKind::Parameters => "parameters",
        };
        format!("{} {name}", j.code())
    });
    v.extend([
        one(
            count(
                "tc_accepted",
                hk_field::TC_ACCEPTED.start,
                Wire::U16,
                "telecommands accepted (wrapping)",
            ),
            |h| i64::from(h.tc_accepted),
        ),
        one(
            count(
                "tc_rejected",
                hk_field::TC_REJECTED.start,
                Wire::U16,
                "telecommands rejected (wrapping)",
            ),
            |h| i64::from(h.tc_rejected),
        ),
        one(
            field(
                "last_failure_code",
                hk_field::LAST_FAILURE_CODE.start,
                Wire::U16,
                Meaning::Enum {
                    enumeration: "failure_code",
                },
                "last failure code reported (0 none)",
            ),
            |h| i64::from(h.last_failure_code),
        ),
        one(
            b(
                "moving_legs",
                hk_field::MOVING_LEGS.start,
                Wire::U8,
                "leg_mask",
                &format!("legs commanded to move ({leg_bits})"),
            ),
            |h| i64::from(h.moving_legs),
        ),
        one(
            b(
                "fault_legs",
                hk_field::FAULT_LEGS.start,
                Wire::U8,
                "leg_mask",
                &format!("legs named by the latched faults ({leg_bits})"),
            ),
            |h| i64::from(h.fault_legs),
        ),
        one(
            e(
                "pending_bank",
                hk_field::PENDING_BANK.start,
                "bank",
                &format!(
                    "bank of the pending (committed, not activated) table: {}",
                    source_codes("none", "")
                ),
            ),
            |h| i64::from(h.pending_bank),
        ),
        one(
            count(
                "pending_table_id",
                hk_field::PENDING_TABLE_ID.start,
                Wire::U32,
                "pending table ID (0 if none)",
            ),
            |h| i64::from(h.pending_table_id),
        ),
        one(
            count(
                "job",
                hk_field::JOB.start,
                Wire::U8,
                &format!("background job running: 0 none, {}", jobs.join(", ")),
            ),
            |h| i64::from(h.job),
        ),
        one(
            count(
                "selected_source",
                hk_field::SELECTED_SOURCE.start,
                Wire::U8,
                &format!(
                    "selected table (what boots): {}, {NO_SELECTION} no selection record",
                    source_codes("nominal", "")
                ),
            ),
            |h| i64::from(h.selected_source),
        ),
        one(
            count(
                "tm_dropped",
                hk_field::TM_DROPPED.start,
                Wire::U16,
                "telemetry records dropped (queue full; wrapping)",
            ),
            |h| i64::from(h.tm_dropped),
        ),
        one(
            count(
                "tc_frames_dropped",
                hk_field::TC_FRAMES_DROPPED.start,
                Wire::U16,
                "telecommand frames dropped (too long or bad COBS; wrapping)",
            ),
            |h| i64::from(h.tc_frames_dropped),
        ),
        one(
            count(
                "uart_overruns",
                hk_field::UART_OVERRUNS.start,
                Wire::U16,
                "UART receive overruns and receive-queue overflows (wrapping)",
            ),
            |h| i64::from(h.uart_overruns),
        ),
        one(
            count(
                "cycle_overruns",
                hk_field::CYCLE_OVERRUNS.start,
                Wire::U16,
                "control-cycle overruns (wrapping)",
            ),
            |h| i64::from(h.cycle_overruns),
        ),
        one(
            count(
                "reset_cause",
                hk_field::RESET_CAUSE.start,
                Wire::U8,
                &format!(
                    "reset cause (as in event 0x{:04X}): {}",
                    event_id::BOOT_DETAIL,
                    reset_causes()
                        .iter()
                        .map(|(code, name, _)| format!("{code} {name}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ),
            |h| i64::from(h.reset_cause),
        ),
        one(
            count(
                "boot_count",
                hk_field::BOOT_COUNT.start,
                Wire::U16,
                "boot count (wrapping)",
            ),
            |h| i64::from(h.boot_count),
        ),
        one(
            count(
                "bank_health",
                hk_field::BANK_HEALTH.start,
                Wire::U8,
                "flash bank health: bit 0 bank A, bit 1 bank B record corrupt",
            ),
            |h| i64::from(h.bank_health),
        ),
    ]);
    let pivot: [HkGetter; 3] = [
        |h| i64::from(h.pivot_nm[0]),
        |h| i64::from(h.pivot_nm[1]),
        |h| i64::from(h.pivot_nm[2]),
    ];
    let pivot_ids = PARAMETERS
        .get(crate::controller::params::index::PIVOT..crate::controller::params::index::PIVOT + 3)
        .unwrap_or(&[])
        .iter()
        .map(|d| d.id)
        .collect::<Vec<_>>();
    let pivot_fields = pivot
        .into_iter()
        .enumerate()
        .map(|(k, g)| {
            let axis = POSE_AXES.get(k).copied().unwrap_or("");
            (
                calibrated(
                    &format!("pivot_{axis}"),
                    hk_field::PIVOT.start + 4 * k,
                    Wire::I32,
                    UNIT_UM,
                    UM_PER_NM,
                    &format!(
                        "pivot in M's coordinates, {axis} (um; wire i32 in nm; ST[20] parameter)"
                    ),
                ),
                Some(g),
            )
        })
        .collect();
    v.push(HkRow::group(
        format!(
            "the pivot in M's coordinates, x, y, z (nm; parameters {}..{})",
            pivot_ids.first().copied().unwrap_or(0),
            pivot_ids.last().copied().unwrap_or(0)
        ),
        pivot_fields,
    ));
    let operator: [(&str, usize, &str, &str, [HkGetter; 6]); 2] = [
        (
            "pose_fk_op_",
            hk_field::POSE_FK_OPERATOR.start,
            "pose from FK in the operator's frames (about the pivot, in the user frame)",
            "pose from FK in the operator's frames (pivot, user frame; nm, µas)",
            pose_getters!(pose_fk_operator),
        ),
        (
            "pose_cmd_op_",
            hk_field::POSE_COMMANDED_OPERATOR.start,
            "commanded pose in the operator's frames (about the pivot, in the user frame)",
            "commanded pose in the operator's frames (nm, µas)",
            pose_getters!(pose_commanded_operator),
        ),
    ];
    for (prefix, off, what, row, getters) in operator {
        let fields = pose_fields(prefix, off, what)
            .into_iter()
            .zip(getters)
            .map(|(f, g)| (f, Some(g)))
            .collect();
        v.push(HkRow::group(row.into(), fields));
    }
    v.push(one(
        count(
            "parameters_set",
            hk_field::PARAMETERS_SET.start,
            Wire::U32,
            "on-board parameters set by TC[20,3] (bit i = parameter index i, rows of section \
             5a in order; clear: default)",
        ),
        |h| i64::from(h.parameters_set),
    ));
    // Time-based schedule (ST[11]) and time reports (ST[9]): offsets 217..230.
    v.extend([
        one(
            count(
                "schedule_activities",
                hk_field::SCHEDULE_ACTIVITIES.start,
                Wire::U8,
                &format!("time-tagged activities in the schedule (0..{SCHEDULE_CAPACITY})"),
            ),
            |h| i64::from(h.schedule.activities),
        ),
        one(
            field(
                "schedule_release_enabled",
                hk_field::SCHEDULE_RELEASE_ENABLED.start,
                Wire::U8,
                Meaning::Boolean,
                "release of activities: 1 enabled, 0 disabled",
            ),
            |h| i64::from(h.schedule.release_enabled),
        ),
        one(
            count(
                "schedule_released",
                hk_field::SCHEDULE_RELEASED.start,
                Wire::U16,
                "activities released since boot (wrapping)",
            ),
            |h| i64::from(h.schedule.released),
        ),
        one(
            count(
                "schedule_failed",
                hk_field::SCHEDULE_FAILED.start,
                Wire::U16,
                "released activities whose telecommand failed (wrapping)",
            ),
            |h| i64::from(h.schedule.failed),
        ),
    ]);
    let next_what = "release time of the next activity (0 if none)";
    let next: [HkGetter; 2] = [
        |h| i64::from(h.schedule.next_release.seconds),
        |h| i64::from(h.schedule.next_release.fraction),
    ];
    v.push(HkRow::group(
        next_what.into(),
        obt_fields(
            "schedule_next_release_",
            hk_field::SCHEDULE_NEXT_RELEASE.start,
            next_what,
        )
        .into_iter()
        .zip(next)
        .map(|(f, g)| (f, Some(g)))
        .collect(),
    ));
    v.push(one(
        field(
            "time_report_rate",
            hk_field::TIME_REPORT_RATE.start,
            Wire::U8,
            Meaning::Enum {
                enumeration: "time_report_rate",
            },
            &format!(
                "time report rate (TC[{},{}]): N of 2^N s, {} off",
                service::TIME,
                subtype::SET_TIME_REPORT_RATE,
                TimeReportRate::Off.code()
            ),
        ),
        |h| i64::from(h.schedule.time_report_rate),
    ));
    let switches: [(&str, usize, String, HkGetter); 4] = [
        (
            "limit_lower_legs",
            hk_field::LIMIT_LOWER_LEGS.start,
            format!("legs at their lower end-of-travel switch ({leg_bits}; the last cycle's read)"),
            |h| i64::from(h.limit_lower_legs),
        ),
        (
            "limit_upper_legs",
            hk_field::LIMIT_UPPER_LEGS.start,
            format!("legs at their upper end-of-travel switch ({leg_bits})"),
            |h| i64::from(h.limit_upper_legs),
        ),
        (
            "reference_legs",
            hk_field::REFERENCE_LEGS.start,
            format!("legs at their reference (home) sensor ({leg_bits}; information only)"),
            |h| i64::from(h.reference_legs),
        ),
        (
            "switch_unreadable_legs",
            hk_field::SWITCH_UNREADABLE_LEGS.start,
            format!(
                "legs with a switch input that cannot be read ({leg_bits}; treated as both \
                 ends active)"
            ),
            |h| i64::from(h.switch_unreadable_legs),
        ),
    ];
    for (name, off, what, g) in switches {
        v.push(one(b(name, off, Wire::U8, "leg_mask", &what), g));
    }
    v
}

/// The housekeeping fields with their accessors into [`Housekeeping`]: the fields of
/// [`housekeeping_rows`], in order.
pub fn housekeeping_fields() -> Vec<(Field, Option<HkGetter>)> {
    housekeeping_rows()
        .into_iter()
        .flat_map(|r| r.fields)
        .collect()
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
            kinds: vec![
                tm_kind(&[subtype::ACCEPTANCE_SUCCESS], "acceptance success", "request ID (4)"),
                tm_kind(&[subtype::START_SUCCESS], "start success", "request ID"),
                tm_kind(&[subtype::COMPLETION_SUCCESS], "completion success", "request ID"),
            ],
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
            kinds: vec![
                tm_kind(
                    &[subtype::ACCEPTANCE_FAILURE],
                    "acceptance failure",
                    "request ID (4); failure code u16; failure data u32",
                ),
                tm_kind(
                    &[subtype::START_FAILURE],
                    "start failure",
                    "request ID; code u16; data u32",
                ),
                tm_kind(
                    &[subtype::COMPLETION_FAILURE],
                    "completion failure",
                    "request ID; code u16; data u32",
                ),
            ],
        },
        TmPacket {
            name: "housekeeping".into(),
            service: service::HOUSEKEEPING,
            subtypes: vec![subtype::HK_REPORT],
            fields: housekeeping_fields().into_iter().map(|(f, _)| f).collect(),
            fixed_len: Some(HK_REPORT_LEN),
            description: "TM[3,25] housekeeping report".into(),
            repeated: None,
            kinds: vec![tm_kind(
                &[subtype::HK_REPORT],
                "housekeeping report",
                &format!("{HK_REPORT_LEN} bytes, section 6"),
            )],
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
            kinds: {
                let all = [
                    EventSeverity::Info,
                    EventSeverity::Low,
                    EventSeverity::Medium,
                    EventSeverity::High,
                ];
                let names: Vec<String> = all
                    .iter()
                    .map(|s| {
                        format!("{} {}", s.subtype(), severity_name(*s).to_ascii_lowercase())
                    })
                    .collect();
                vec![tm_kind(
                    &all.map(EventSeverity::subtype),
                    &format!("event: {} severity", names.join(", ")),
                    "event ID u16; aux0 u32; aux1 u32",
                )]
            },
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
            kinds: vec![tm_kind(
                &[subtype::MEMORY_DUMP_REPORT],
                "table dump chunk",
                &format!(
                    "memory ID u8; offset u16; length u16 (1..{TABLE_CHUNK_MAX_LEN}); `length` bytes"
                ),
            )],
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
            kinds: vec![tm_kind(
                &[subtype::MOVE_CHECK_REPORT],
                &format!(
                    "move check report (answer to function 0x{:04X})",
                    FunctionId::CheckMove.code()
                ),
                "request ID (4); code u16; target refusal bits u32; path refusal bits u32; \
                 path point u8",
            )],
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
            kinds: vec![tm_kind(
                &[subtype::PARAMETER_REPORT],
                &format!(
                    "parameter report (answer to TC[{},{}])",
                    service::PARAMETER,
                    subtype::PARAMETER_REPORT_REQUEST
                ),
                "count u8; that many (parameter ID u16, value i32), in parameter-index order",
            )],
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
            kinds: vec![tm_kind(
                &[subtype::TIME_REPORT],
                "time report",
                &format!(
                    "rate u8 (as TC[{},{}]); OBT CUC {CUC_COARSE_BYTES}+{CUC_FINE_BYTES} \
                     ({TM_TIMESTAMP_LEN} bytes) (section 10)",
                    service::TIME,
                    subtype::SET_TIME_REPORT_RATE
                ),
            )],
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
            kinds: vec![tm_kind(
                &[subtype::SCHEDULE_SUMMARY_REPORT],
                "schedule summary",
                &format!(
                    "N u8; N × (release time CUC {CUC_COARSE_BYTES}+{CUC_FINE_BYTES}, request ID \
                     {REQUEST_ID_LEN} bytes), in release order"
                ),
            )],
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
        // docs/icd.md's order: the ping reply last.
        TmPacket {
            name: "ping_reply".into(),
            service: service::TEST,
            subtypes: vec![subtype::PING_REPLY],
            fields: Vec::new(),
            fixed_len: Some(0),
            description: "TM[17,2] are-you-alive reply".into(),
            repeated: None,
            kinds: vec![tm_kind(&[subtype::PING_REPLY], "are-you-alive reply", "none")],
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

/// The controller states: code, label, name and what it means (docs/icd.md section 6).
pub fn controller_state_doc() -> Vec<(u8, String, &'static str, &'static str)> {
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
            let (name, meaning) = match s {
                State::Idle => ("idle", "holding position, ready"),
                State::Moving => ("moving", "planning or following a path"),
                State::Stopping => ("stopping", "decelerating after a stop or a fault"),
                State::StrokeMoving => ("direct-stroke move", "recovery"),
                State::Faulted => (
                    "faulted",
                    "at rest, moves refused until a clear fault TC succeeds",
                ),
            };
            (s.code(), upper_snake(&format!("{s:?}")), name, meaning)
        })
        .collect()
}

fn controller_states() -> Vec<(i64, String, String)> {
    controller_state_doc()
        .into_iter()
        .map(|(code, label, name, meaning)| (i64::from(code), label, format!("{name} ({meaning})")))
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

/// Where a failure code reaches the ground (docs/icd.md section 7, column "report").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind", content = "code")]
pub enum ReportedIn {
    /// TM[1,2]: the decoder refuses the packet.
    AcceptanceFailure,
    /// TM[1,4]: the controller refuses to begin.
    StartFailure,
    /// TM[1,8]: something that had started failed.
    CompletionFailure,
    /// TM[1,8], or TM[1,4] when it happens while a move is being planned.
    CompletionOrStartFailure,
    /// No report (there is no request ID to report on): counted in housekeeping.
    CountedOnly,
    /// Never itself: the report carries the code it wraps.
    AsWrappedCode,
    /// Only inside the failure data of the code given.
    InsideDataOf(u16),
    /// Never on the wire (a family enumerated for completeness).
    NotReported,
}

/// One failure code: docs/icd.md's row (section 7) and the mission database's
/// enumeration value (label and meaning).
#[derive(Clone, Debug, Serialize)]
pub struct FailureCode {
    /// The code (a `code()` of the flight error types).
    pub code: u16,
    /// Family prefix of the label.
    pub family: &'static str,
    /// Enumeration label: family and variant name (`MOTION_TARGET_REFUSED`).
    pub label: String,
    /// Origin column of docs/icd.md.
    pub origin: &'static str,
    /// What it means.
    pub meaning: String,
    /// Which report carries it.
    pub report: ReportedIn,
    /// What its failure data (u32) holds; "a/b" is `a << 16 | b`.
    pub data: String,
}

/// `1,234,567`.
pub fn thousands(v: i64) -> String {
    let digits = v.unsigned_abs().to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    if v < 0 {
        format!("-{out}")
    } else {
        out
    }
}

/// `0x050A`: a code or an ID as docs/icd.md writes it.
pub fn hex4(v: u16) -> String {
    format!("0x{v:04X}")
}

/// `2` or `2/2/3`: one number if all are equal (after rounding to 1e-9).
fn uniform(values: &[f64]) -> String {
    let r: Vec<f64> = values.iter().map(|v| (v * 1e9).round() / 1e9).collect();
    if r.windows(2).all(|w| w[0] == w[1]) {
        format!("{}", r.first().copied().unwrap_or(0.0))
    } else {
        r.iter()
            .map(|v| format!("{v}"))
            .collect::<Vec<_>>()
            .join("/")
    }
}

/// Every failure code the controller has, by family (one instance of each variant of
/// the flight error types), with what docs/icd.md says of it. A variant missing here
/// fails `host-tests/mdb.rs` (every `=> 0x0NNN` arm of a `code()` must be listed).
pub fn failure_codes() -> Vec<FailureCode> {
    use ReportedIn::{
        AcceptanceFailure as Acc, AsWrappedCode, CompletionFailure as Compl,
        CompletionOrStartFailure, CountedOnly, InsideDataOf, NotReported, StartFailure as Start,
    };
    let mut v: Vec<FailureCode> = Vec::new();
    let mut push = |family: &'static str,
                    origin: &'static str,
                    code: u16,
                    debug: String,
                    (report, meaning, data): (ReportedIn, String, String)| {
        v.push(FailureCode {
            code,
            family,
            label: format!("{family}_{}", upper_snake(&debug)),
            origin,
            meaning,
            report,
            data,
        });
    };
    let d = |r: ReportedIn, meaning: &str, data: &str| (r, meaning.to_string(), data.to_string());
    let validation = crate::table::ValidationConfig::flight();
    let ws = &validation.max_workspace;
    let ws_arcsec: Vec<f64> = ws
        .rotation_rad
        .iter()
        .map(|r| r * crate::units::ARCSEC_PER_RAD)
        .collect();
    let max_obt_ms = u64::from(u32::MAX) * u64::from(crate::timing::CYCLE_US) / 1000;
    use crate::table::validate::field_index as fi;
    let range = |a: u16, b: u16| format!("{a}..{}", b - 1);

    for (e, doc) in [
        (
            LinkError::Truncated { got: 0, needed: 0 },
            d(
                Acc,
                &format!(
                    "truncated: shorter than {MIN_TC_PACKET_LEN} bytes or than the length field"
                ),
                "received/needed",
            ),
        ),
        (
            LinkError::LengthMismatch {
                got: 0,
                declared: 0,
            },
            d(
                Acc,
                "wrong length: bytes after the packet's declared end",
                "received/declared",
            ),
        ),
        (
            LinkError::Oversized,
            d(
                Acc,
                &format!("oversized: packet or declared length > {MAX_TC_PACKET_LEN}"),
                "0",
            ),
        ),
        (
            LinkError::BadFraming,
            d(CountedOnly, "bad COBS framing", "0"),
        ),
        (
            LinkError::BadCrc { found: 0 },
            d(Acc, "CRC-16 mismatch", "CRC found"),
        ),
        (
            LinkError::WrongApid { apid: 0 },
            d(Acc, "wrong APID", "APID found"),
        ),
        (
            LinkError::BadPrimaryHeader,
            d(
                Acc,
                "not an unsegmented version-0 TC with secondary header",
                "0",
            ),
        ),
        (
            LinkError::UnsupportedPusVersion { version: 0 },
            d(Acc, &format!("PUS version not {PUS_C_VERSION}"), "version"),
        ),
        (
            LinkError::UnknownService { service: 0 },
            d(Acc, "unknown service", "service"),
        ),
        (
            LinkError::UnknownSubtype {
                service: 0,
                subtype: 0,
            },
            d(Acc, "unknown subtype", "service/subtype"),
        ),
        (
            LinkError::UnknownFunction { function_id: 0 },
            d(Acc, "unknown function ID", "function ID"),
        ),
        (
            LinkError::AppDataLength {
                got: 0,
                expected: 0,
            },
            d(Acc, "application data length wrong", "received/expected"),
        ),
        (
            LinkError::InvalidArgument { index: 0 },
            d(
                Acc,
                "argument out of range (leg, memory ID, a count of parameters or activities, the \
                 time report rate)",
                "argument index (0-based; TC[8,1]'s function ID not counted)",
            ),
        ),
        (
            LinkError::ChunkOutOfRange {
                offset: 0,
                length: 0,
            },
            d(
                Acc,
                &format!("table chunk empty, > {TABLE_CHUNK_MAX_LEN} bytes or beyond the table"),
                "offset/length",
            ),
        ),
        (
            LinkError::EmbeddedTc { index: 0, code: 0 },
            d(
                Acc,
                &format!(
                    "a TC[{s},{}]'s embedded telecommand is refused (the code it would get \
                     alone; {} also when longer than {MAX_SCHEDULED_TC_LEN} bytes, {} when it \
                     cannot be scheduled)",
                    subtype::SCHEDULE_INSERT,
                    hex4(LinkError::Oversized.code()),
                    hex4(
                        LinkError::NotSchedulable {
                            service: 0,
                            subtype: 0
                        }
                        .code()
                    ),
                    s = service::SCHEDULING,
                ),
                "activity index/code",
            ),
        ),
        (
            LinkError::NotSchedulable {
                service: 0,
                subtype: 0,
            },
            d(
                InsideDataOf(LinkError::EmbeddedTc { index: 0, code: 0 }.code()),
                &format!(
                    "a telecommand that cannot be scheduled: TC[{},x] or a table chunk TC[{},{}]",
                    service::SCHEDULING,
                    service::MEMORY,
                    subtype::MEMORY_LOAD
                ),
                "service/subtype",
            ),
        ),
    ] {
        push("LINK", "link", e.code(), format!("{e:?}"), doc);
    }
    let in_geometry = InsideDataOf(ValidationError::Geometry(GeometryError::NonFinite).code());
    let geometry = [
        (GeometryError::NonFinite, "non-finite"),
        (
            GeometryError::UpperNotAboveLower { leg: 0 },
            "upper joint not above the lower",
        ),
        (
            GeometryError::BadStrokeLimits { leg: 0 },
            "bad stroke limits",
        ),
        (GeometryError::BadWorkspaceLimits, "bad workspace"),
    ];
    for (e, meaning) in geometry {
        push(
            "GEOMETRY",
            "geometry",
            e.code(),
            format!("{e:?}"),
            d(in_geometry, meaning, "—"),
        );
    }
    for (e, meaning) in [
        (IkError::NonFinite, "non-finite pose"),
        (
            IkError::OutsideWorkspace { axes: 0 },
            "pose outside the workspace",
        ),
        (IkError::Unreachable { legs: 0 }, "a leg cannot reach"),
        (
            IkError::StrokeLimit { legs: 0 },
            "a stroke beyond its limit",
        ),
    ] {
        push(
            "IK",
            "IK",
            e.code(),
            format!("{e:?}"),
            d(NotReported, meaning, "—"),
        );
    }
    let in_fk = InsideDataOf(
        ValidationError::FkFailed {
            corner: 0,
            fk_code: 0,
        }
        .code(),
    );
    for (e, meaning) in [
        (FkError::NonFinite, "non-finite"),
        (
            FkError::Unreachable {
                legs: 0,
                iterations: 0,
            },
            "a leg cannot reach on the way",
        ),
        (
            FkError::SingularJacobian { iterations: 0 },
            "singular Jacobian",
        ),
        (FkError::NotConverged { iterations: 0 }, "not converged"),
        (
            FkError::ResidualTooLarge { iterations: 0 },
            "residual too large",
        ),
    ] {
        push(
            "FK",
            "FK",
            e.code(),
            format!("{e:?}"),
            d(in_fk, meaning, "—"),
        );
    }
    for (e, meaning) in [
        (TableError::WrongLength { got: 0 }, "wrong length"),
        (TableError::BadMagic, "bad magic"),
        (
            TableError::UnsupportedVersion { version: 0 },
            "unsupported format version",
        ),
        (
            TableError::BadLengthField { length: 0 },
            "length field wrong",
        ),
        (TableError::BadCrc, "CRC-32 wrong"),
        (TableError::ReservedNotZero, "reserved field not 0"),
        (TableError::MissingLimits, "limits missing"),
    ] {
        push(
            "TABLE",
            "table image",
            e.code(),
            format!("{e:?}"),
            d(Start, meaning, "0"),
        );
    }
    let geometry_codes = geometry.map(|(e, _)| e.code());
    for (e, doc) in [
        (
            ValidationError::ProvenanceNotAscii { index: 0 },
            d(Compl, "provenance tag not printable ASCII", "byte index"),
        ),
        (
            ValidationError::NonFinite { field: 0 },
            d(
                Compl,
                "a number is NaN or infinite",
                &format!(
                    "field: {} joints, {} p0, {} stroke min, {} stroke max, {} workspace \
                     translation, {} workspace rotation, {} the f32 thresholds",
                    range(0, fi::P0),
                    range(fi::P0, fi::STROKE_MIN),
                    range(fi::STROKE_MIN, fi::STROKE_MAX),
                    range(fi::STROKE_MAX, fi::WORKSPACE_TRANSLATION),
                    range(fi::WORKSPACE_TRANSLATION, fi::WORKSPACE_ROTATION),
                    range(fi::WORKSPACE_ROTATION, fi::SUPERVISION),
                    range(fi::SUPERVISION, fi::SUPERVISION + 4),
                ),
            ),
        ),
        (
            ValidationError::CoordinateOffNominal { index: 0 },
            d(
                Compl,
                &format!(
                    "a joint coordinate or p0 component more than {} mm off nominal",
                    uniform(&[validation.max_coordinate_deviation_mm])
                ),
                &format!(
                    "coordinate index ({} joints, {} p0)",
                    range(0, fi::P0),
                    range(fi::P0, fi::STROKE_MIN)
                ),
            ),
        ),
        (
            ValidationError::RodLengthImplausible { leg: 0 },
            d(
                Compl,
                &format!(
                    "a rod length more than {} mm off nominal",
                    uniform(&[validation.max_rod_deviation_mm])
                ),
                "leg (0-based)",
            ),
        ),
        (
            ValidationError::Geometry(GeometryError::NonFinite),
            d(
                Compl,
                "geometry unusable (rods, limits)",
                &format!(
                    "geometry code {}..{} ({})",
                    hex4(geometry_codes.iter().copied().min().unwrap_or(0)),
                    hex4(geometry_codes.iter().copied().max().unwrap_or(0)),
                    geometry.map(|(_, m)| m).join(", ")
                ),
            ),
        ),
        (
            ValidationError::StrokeLimitBeyondCap { leg: 0 },
            d(
                Compl,
                &format!(
                    "a stroke limit beyond ±{} mm",
                    uniform(&[validation.max_abs_stroke_limit_mm])
                ),
                "leg (0-based)",
            ),
        ),
        (
            ValidationError::WorkspaceBeyondCap { axis: 0 },
            d(
                Compl,
                &format!(
                    "a workspace half-range beyond ±{} mm / ±{}\"",
                    uniform(&ws.translation_mm),
                    uniform(&ws_arcsec)
                ),
                "axis 0..5",
            ),
        ),
        (
            ValidationError::Supervision { field: 0 },
            d(
                Compl,
                "a supervision threshold not positive, or warning >= fault",
                "field 0..6 in layout order: the first not positive; 1 (the fault threshold) \
                 when warning >= fault",
            ),
        ),
        (
            ValidationError::Unreachable { legs: 0 },
            d(Compl, "part of the workspace unreachable", "leg mask"),
        ),
        (
            ValidationError::StrokeLimitExceeded { legs: 0 },
            d(
                Compl,
                "part of the workspace beyond a stroke limit",
                "leg mask",
            ),
        ),
        (
            ValidationError::FkFailed {
                corner: 0,
                fk_code: 0,
            },
            d(
                Compl,
                "FK from home fails at a workspace corner",
                "FK code low byte << 8 / corner",
            ),
        ),
        (
            ValidationError::FkInaccurate { corner: 0 },
            d(Compl, "FK at a corner does not return the corner", "corner"),
        ),
        (
            ValidationError::BadConfig,
            d(Compl, "validation configuration out of range (defect)", "0"),
        ),
    ] {
        push("VALIDATION", "validation", e.code(), format!("{e:?}"), doc);
    }
    for (e, doc) in [
        (
            StoreError::BadLayout,
            d(Compl, "bank layout does not fit the flash (defect)", "0"),
        ),
        (
            StoreError::Flash(embedded_storage::nor_flash::NorFlashErrorKind::Other),
            d(Compl, "the flash driver failed (e.g. power loss)", "0"),
        ),
        (
            StoreError::Invalid(ValidationError::BadConfig),
            d(
                AsWrappedCode,
                "refused by validation (nested; reported as its 0x041x code)",
                "—",
            ),
        ),
        (
            StoreError::VerifyFailed,
            d(Compl, "read-back after a write differs", "0"),
        ),
        (
            StoreError::NoRecord(crate::table::BankStatus::Blank),
            d(
                Compl,
                "the bank holds no complete, CRC-valid record (switch bank)",
                "the bank's status flag (boot flags above)",
            ),
        ),
        (
            StoreError::Busy,
            d(Compl, "a write is already in progress (defect guard)", "0"),
        ),
        (
            StoreError::NotExpected,
            d(
                Compl,
                "the record is not the one expected (activate of a vanished pending table)",
                "0",
            ),
        ),
        (
            StoreError::ThresholdConflict,
            d(
                Compl,
                "activate, switch bank or revert: the table's following-error thresholds with \
                 the overrides in force (parameters 0x0030/0x0031) would leave the warning not \
                 below the fault threshold; nothing persisted",
                "0",
            ),
        ),
    ] {
        push("STORE", "store", e.code(), format!("{e:?}"), doc);
    }
    for (e, doc) in [
        (
            MotionError::NonFinite,
            d(Start, "move: non-finite pose", "0"),
        ),
        (
            MotionError::BadLimits { leg: 0 },
            d(Start, "move: motion limits invalid", "0"),
        ),
        (
            MotionError::StartRefused(Refusals::default()),
            d(
                Start,
                "move: the start pose (of the held strokes) is refused by the workspace check",
                "refusal bits",
            ),
        ),
        (
            MotionError::TargetRefused(Refusals::default()),
            d(
                Start,
                "move: the target is refused by the workspace check",
                "refusal bits",
            ),
        ),
        (
            MotionError::PathRefused {
                sample: 0,
                refusals: Refusals::default(),
            },
            d(
                Start,
                "move: the straight path leaves the workspace/stroke range between its ends",
                "refusal bits",
            ),
        ),
        (
            MotionError::TooLong,
            d(
                Start,
                &format!(
                    "move too long (more than 2^{} cycles)",
                    crate::motion::MAX_MOVE_CYCLES.trailing_zeros()
                ),
                "0",
            ),
        ),
    ] {
        push("MOTION", "motion", e.code(), format!("{e:?}"), doc);
    }
    let max_delta_id = PARAMETERS
        .get(crate::controller::params::index::DIRECT_MAX_DELTA)
        .map_or(0, |p| p.id);
    for (e, doc) in [
        (
            StrokeMoveError::BadLeg,
            d(Start, "direct stroke: bad leg", "0"),
        ),
        (
            StrokeMoveError::NonFinite,
            d(Start, "direct stroke: non-finite stroke or delta", "0"),
        ),
        (
            StrokeMoveError::BadLimits,
            d(Start, "direct stroke: limits invalid", "0"),
        ),
        (
            StrokeMoveError::DeltaTooLarge,
            d(
                Start,
                &format!(
                    "direct stroke: the delta exceeds the largest direct-stroke delta \
                     (parameter {})",
                    hex4(max_delta_id)
                ),
                "0",
            ),
        ),
        (
            StrokeMoveError::OutsideStrokeRange,
            d(
                Start,
                "direct stroke: destination outside the stroke limits and no closer",
                "0",
            ),
        ),
        (
            StrokeMoveError::TooLong,
            d(Start, "direct stroke: too long", "0"),
        ),
    ] {
        push("STROKE", "motion", e.code(), format!("{e:?}"), doc);
    }
    // The controller's own codes; its pass-through variants (Motion, Stroke, TableDecode,
    // Store) carry the codes listed above.
    let job_offset = housekeeping_fields()
        .iter()
        .find(|(f, _)| f.name == "job")
        .map_or(0, |(f, _)| f.offset);
    for (e, doc) in [
        (
            CommandError::Faulted(FaultFlags::empty()),
            d(
                Start,
                "a fault is latched: clear it first",
                "latched fault flags",
            ),
        ),
        (
            CommandError::Busy(State::Moving),
            d(
                Start,
                "busy: a motion is in progress (stop first; tables change between motions only)",
                "state code",
            ),
        ),
        (
            CommandError::FaultPersists(FaultFlags::empty()),
            d(
                Start,
                "clear refused: the fault condition persists",
                "blocking fault flags",
            ),
        ),
        (
            CommandError::NoPose,
            d(
                Start,
                "the pose of the held strokes is unknown (FK failed)",
                "0",
            ),
        ),
        (
            CommandError::UploadIncomplete(0),
            d(
                Start,
                "commit: table bytes missing from the upload buffer",
                "bytes missing",
            ),
        ),
        (
            CommandError::CrcMismatch(0),
            d(
                Start,
                "commit: CRC-32 does not match the uploaded bytes",
                "CRC computed",
            ),
        ),
        (
            CommandError::NoPending,
            d(Start, "activate: no table pending", "0"),
        ),
        (
            CommandError::Stopped,
            d(
                CompletionOrStartFailure,
                "move ended early by a stop telecommand",
                "0",
            ),
        ),
        (
            CommandError::AbortedByFault(FaultFlags::empty()),
            d(
                CompletionOrStartFailure,
                "move ended early by a fault",
                "latched fault flags",
            ),
        ),
        (
            CommandError::PendingMismatch { pending_id: 0 },
            d(
                Start,
                "activate: the named table is not the pending one",
                "pending table ID",
            ),
        ),
        (
            CommandError::EncoderSuspect(0),
            d(
                Start,
                "direct stroke: the leg's own encoder is suspect",
                "reasons (section 3)",
            ),
        ),
        (
            CommandError::NoGeometry,
            d(
                Start,
                "no usable geometry (defect guard): all motion refused",
                "0",
            ),
        ),
        (
            CommandError::JobBusy(0),
            d(
                Start,
                "a table job is running",
                &format!("job (`job`, offset {job_offset})"),
            ),
        ),
        (
            CommandError::TowardEndOfTravel(0),
            d(
                Start,
                "direct stroke toward an end-of-travel switch that is active or was seen since \
                 the fault latched",
                "legs blocked in the move's direction (bit i = leg i+1)",
            ),
        ),
    ] {
        push("CONTROLLER", "controller", e.code(), format!("{e:?}"), doc);
    }
    for (e, doc) in [
        (
            ParamError::UnknownId(0),
            d(Start, "unknown parameter ID", "the ID"),
        ),
        (
            ParamError::OutOfRange(0),
            d(Start, "value outside the parameter's range", "the ID"),
        ),
        (
            ParamError::WarningNotBelowFault,
            d(
                Start,
                "following warning threshold not below the fault threshold",
                "0",
            ),
        ),
        (
            ParamError::Repeated(0),
            d(
                Start,
                "a TC[20,1] or TC[20,3] names a parameter ID twice",
                "the ID",
            ),
        ),
    ] {
        push("CONTROLLER", "parameters", e.code(), format!("{e:?}"), doc);
    }
    // The schedule's codes (CommandError::Schedule passes them through).
    for (e, doc) in [
        (
            ScheduleError::Full { free: 0 },
            d(
                Start,
                &format!("insert: the activities do not all fit ({SCHEDULE_CAPACITY} places)"),
                "free places",
            ),
        ),
        (
            ScheduleError::ReleaseTimeInPast { index: 0 },
            d(
                Start,
                "insert: a release time is earlier than now",
                "activity index",
            ),
        ),
        (
            ScheduleError::DuplicateRequestId { index: 0 },
            d(
                Start,
                "insert: a request ID is already scheduled or repeated in the TC",
                "activity index",
            ),
        ),
        (
            ScheduleError::NotScheduled { index: 0 },
            d(
                Start,
                "delete: a request ID is not scheduled, or listed twice",
                "index in the TC",
            ),
        ),
        (
            ScheduleError::ShiftOutOfRange {
                request_id: RequestId::default(),
            },
            d(
                Start,
                "time shift: an activity would be earlier than now or beyond the clock's range",
                "the request ID of the first such activity in release order",
            ),
        ),
        (
            ScheduleError::ReleaseTimeBeyondClock { index: 0 },
            d(
                Start,
                &format!(
                    "insert: a release time beyond the clock's range ({}.{:03} s)",
                    thousands(i64::try_from(max_obt_ms / 1000).unwrap_or(i64::MAX)),
                    max_obt_ms % 1000
                ),
                "activity index",
            ),
        ),
    ] {
        push("SCHEDULE", "schedule", e.code(), format!("{e:?}"), doc);
    }
    v
}

/// The values of the `failure_code` enumeration: 0 (none), then every code of
/// [`failure_codes`] with its label and meaning.
fn failure_code_values() -> Vec<(i64, String, String)> {
    let mut v = vec![(0, "NONE".to_string(), "no failure".to_string())];
    v.extend(
        failure_codes()
            .into_iter()
            .map(|c| (i64::from(c.code), c.label, c.meaning)),
    );
    v
}

/// What an on-board parameter is, by its name in [`PARAMETERS`] (the flight image
/// carries no such text); `None` for a parameter not described here, which fails
/// `host-tests/mdb.rs`.
pub fn parameter_description(name: &str) -> Option<String> {
    Some(match name {
        "pivot_x" => "pivot x (in M's coordinates)".into(),
        "pivot_y" => "pivot y".into(),
        "pivot_z" => "pivot z".into(),
        "user_alpha" => {
            "user frame alpha (rotation of the user frame from the base, Rz Ry Rx)".into()
        }
        "user_beta" => "user frame beta".into(),
        "user_gamma" => "user frame gamma".into(),
        "move_speed" => "coordinated-move speed limit per slider".into(),
        "move_accel" => "coordinated-move acceleration limit per slider".into(),
        "direct_speed" => "direct-stroke speed".into(),
        "direct_accel" => "direct-stroke acceleration".into(),
        "direct_max_delta" => "largest direct-stroke delta".into(),
        "hk_period" => format!(
            "housekeeping period (in control cycles of {} ms)",
            crate::timing::CYCLE_US / 1000
        ),
        "following_warning" => "following-error warning threshold".into(),
        "following_fault" => "following-error fault threshold".into(),
        "encoder_jump" => "encoder jump threshold".into(),
        "stuck_progress" => "stuck detection: least progress".into(),
        "stuck_window" => "stuck detection: window".into(),
        "warning_debounce" => "warning debounce".into(),
        "fault_debounce" => "fault debounce".into(),
        _ => return None,
    })
}

/// A parameter's default as docs/icd.md writes it.
pub fn parameter_default(d: &crate::controller::params::ParamDef) -> String {
    match d.default {
        crate::controller::params::Default::Fixed(v) => thousands(i64::from(v)),
        crate::controller::params::Default::Table => "the running table's".into(),
    }
}

/// The on-board parameters (ST[20]) with their unit, range and default.
fn parameter_ids() -> Vec<(i64, String, String)> {
    PARAMETERS
        .iter()
        .map(|d| {
            (
                i64::from(d.id),
                d.name.to_ascii_uppercase(),
                format!(
                    "{} ({}; {}..={}; default {})",
                    parameter_description(d.name).unwrap_or_else(|| d.name.to_string()),
                    d.unit,
                    d.min,
                    d.max,
                    parameter_default(d)
                ),
            )
        })
        .collect()
}

/// The reset causes: code, name, note (docs/icd.md section 4 and housekeeping).
pub fn reset_causes() -> Vec<(u8, &'static str, &'static str)> {
    use crate::controller::ResetCause;
    [
        ResetCause::PowerOn,
        ResetCause::Watchdog,
        ResetCause::Software,
        ResetCause::HardFault,
        ResetCause::Panic,
        ResetCause::External,
    ]
    .iter()
    .map(|c| {
        // Exhaustive: a new cause does not compile until it is named here.
        let (name, note) = match c {
            ResetCause::PowerOn => ("power-on", ""),
            ResetCause::Watchdog => ("watchdog", ""),
            ResetCause::Software => ("software", ""),
            ResetCause::HardFault => ("HardFault", "including a stack overflow into the guard"),
            ResetCause::Panic => ("panic", ""),
            ResetCause::External => (
                "external",
                "a reset software did not announce: the reset pin, a debugger, QEMU's system_reset",
            ),
        };
        (c.code(), name, note)
    })
    .collect()
}

/// The events (IDs from [`event_id`], severities as the controller sends them).
pub fn events() -> Vec<Event> {
    use EventSeverity::{High, Info, Low, Medium};
    let sev = |s: &[(EventSeverity, &'static str)]| {
        s.iter()
            .map(|(s, when)| SeverityUse {
                severity: severity_name(*s),
                subtype: s.subtype(),
                when,
            })
            .collect()
    };
    let ev = |id: u16,
              name: &'static str,
              description: &str,
              severities: Vec<SeverityUse>,
              (aux0, aux1): (&str, &str),
              message: &'static str| Event {
        id,
        name,
        description: description.into(),
        severities,
        aux0: aux0.into(),
        aux1: aux1.into(),
        message,
    };
    let sources = format!("source ({})", source_codes("nominal", ""));
    let request_id_word = "request ID of the released TC (packet ID << 16, sequence control)";
    vec![
        ev(
            event_id::STATE_CHANGED,
            "STATE_CHANGED",
            "controller state changed",
            sev(&[(Info, "")]),
            ("old state", "new state"),
            "controller state {aux0} -> {aux1}",
        ),
        ev(
            event_id::FAULT_LATCHED,
            "FAULT_LATCHED",
            "fault latched",
            sev(&[(High, "")]),
            (
                "all latched fault flags",
                "newly latched flags (bits 0..23), legs they name (bits 24..29)",
            ),
            "fault latched: flags {aux0}, new {aux1}",
        ),
        ev(
            event_id::FAULTS_CLEARED,
            "FAULTS_CLEARED",
            "faults cleared",
            sev(&[(Info, "")]),
            ("flags cleared", "0"),
            "faults cleared: flags {aux0}",
        ),
        ev(
            event_id::WARNING_CHANGED,
            "WARNING_CHANGED",
            "warning flags changed",
            sev(&[(Low, "")]),
            ("warning flags", "legs of the warnings"),
            "warning flags now {aux0}",
        ),
        ev(
            event_id::MOVE_REFUSED,
            "MOVE_REFUSED",
            "move refused",
            sev(&[(Low, "")]),
            ("refusal bits", "failure code"),
            "move refused: refusal bits {aux0}, failure code {aux1}",
        ),
        ev(
            event_id::SETPOINT_REFUSED,
            "SETPOINT_REFUSED",
            "a setpoint on a planned path failed IK (defect guard; the motion holds)",
            sev(&[(High, "")]),
            ("refusal bits", "control cycle"),
            "setpoint on a planned path failed IK (motion holds): refusal bits {aux0}, cycle {aux1}",
        ),
        ev(
            event_id::END_OF_TRAVEL,
            "END_OF_TRAVEL",
            "end of travel: the set of active end-of-travel switches changed to a non-empty one",
            sev(&[(High, "")]),
            (
                "legs at the lower switch (bits 0..5), at the upper switch (bits 8..13), with an \
                 unreadable input (bits 16..21)",
                "control cycle",
            ),
            "end of travel: switches {aux0} at cycle {aux1} (legs stopped toward them)",
        ),
        ev(
            event_id::TABLE_ACTIVATED,
            "TABLE_ACTIVATED",
            "table activated (now running)",
            sev(&[(Info, "")]),
            ("table ID", "CRC-32"),
            "table {aux0} activated, CRC-32 {aux1}",
        ),
        ev(
            event_id::TABLE_REJECTED,
            "TABLE_REJECTED",
            "table command refused or failed (commit, activate, switch bank, revert)",
            sev(&[(Medium, "")]),
            (
                "failure code",
                "for a commit: the uploaded table's ID when every byte was loaded since the last \
                 commit and the image decodes (magic, version, length, CRC-32, reserved), else 0 \
                 (so 0 with 0x0705); 0 for the others",
            ),
            "table rejected: failure code {aux0}, table {aux1}",
        ),
        ev(
            event_id::TABLE_COMMITTED,
            "TABLE_COMMITTED",
            "table committed to flash (now pending)",
            sev(&[(Info, "")]),
            (
                "table ID",
                &format!(
                    "bank ({} A, {} B)",
                    BootSource::BankA.code(),
                    BootSource::BankB.code()
                ),
            ),
            "table {aux0} committed to bank {aux1}",
        ),
        ev(
            event_id::TABLE_RELOADED,
            "TABLE_RELOADED",
            "running table reloaded from its source after a RAM upset",
            sev(&[(Medium, "")]),
            ("table ID", &sources),
            "table {aux0} reloaded from {aux1} after a RAM upset",
        ),
        ev(
            event_id::BANK_HEALTH,
            "BANK_HEALTH",
            "flash bank health changed",
            sev(&[(Info, "when healthy"), (Medium, "when corrupt")]),
            ("bit 0 bank A, bit 1 bank B corrupt", "0"),
            "flash bank health {aux0}",
        ),
        ev(
            event_id::BOOT,
            "BOOT",
            "boot finished",
            sev(&[(Info, ""), (Low, "if the boot fell back")]),
            (
                &format!("boot {sources}"),
                "running table ID",
            ),
            "boot finished: source {aux0}, table {aux1}",
        ),
        ev(
            event_id::BOOT_DETAIL,
            "BOOT_DETAIL",
            "boot detail",
            sev(&[(Info, "")]),
            (
                "boot flags (below)",
                "reset cause (bits 0..7), boot count (bits 16..31)",
            ),
            "boot detail: flags {aux0}, reset cause and count {aux1}",
        ),
        ev(
            event_id::DEADLINE_MISSED,
            "DEADLINE_MISSED",
            &format!(
                "control cycles overran {} times in a row: motion stopped",
                crate::controller::OVERRUN_HOLD_LIMIT
            ),
            sev(&[(High, "")]),
            ("consecutive overruns", "overruns since boot"),
            "control cycles overran {aux0} times in a row (total {aux1}): motion stopped",
        ),
        ev(
            event_id::PARAMETERS_CHANGED,
            "PARAMETERS_CHANGED",
            "on-board parameters changed (persisted and applied)",
            sev(&[(Info, "")]),
            (
                "the parameters this TC[20,3] set (bit i = parameter index i)",
                "every parameter set now (the set mask: `parameters_set`, offset 213)",
            ),
            "on-board parameters changed: {aux0} set (all set: {aux1})",
        ),
        ev(
            event_id::PARAMETERS_IGNORED,
            "PARAMETERS_IGNORED",
            "persisted on-board parameters not applied (at boot, or when the repair of an upset \
             re-reads them): out of range, or following-error overrides that would leave the \
             warning not below the running table's fault threshold",
            sev(&[(Low, "")]),
            ("the parameters not applied (bit i = parameter index i)", "0"),
            "persisted parameters {aux0} not applied: the defaults or the table's thresholds run",
        ),
        ev(
            event_id::ACTIVITY_RELEASED,
            "ACTIVITY_RELEASED",
            "time-tagged activity released: its telecommand runs now",
            sev(&[(Info, "")]),
            (request_id_word, "release time (OBT, whole seconds)"),
            "scheduled activity {aux0} released (release time {aux1} s)",
        ),
        ev(
            event_id::ACTIVITY_FAILED,
            "ACTIVITY_FAILED",
            &format!(
                "a released activity's telecommand failed (its TM[{v},{}]/[{v},{}]/[{v},{}] has \
                 the details)",
                subtype::ACCEPTANCE_FAILURE,
                subtype::START_FAILURE,
                subtype::COMPLETION_FAILURE,
                v = service::VERIFICATION
            ),
            sev(&[(Medium, "")]),
            (
                "request ID of the released TC",
                "report subtype << 16, failure code",
            ),
            "released activity {aux0} failed: subtype and code {aux1}",
        ),
        ev(
            event_id::ACTIVITY_EXPIRED,
            "ACTIVITY_EXPIRED",
            "activity deleted unrun: its release time passed while release was disabled",
            sev(&[(Low, "")]),
            ("request ID of the TC", "release time (OBT, whole seconds)"),
            "activity {aux0} deleted unrun: release time {aux1} s passed while release was disabled",
        ),
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

/// One fault or warning flag: bit, label, its name in docs/icd.md (section 6) and what
/// it means (the mission database's bit description).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FlagDoc {
    /// Bit position (from [`FaultFlags`]).
    pub bit: u32,
    /// Label (the `FaultFlags` constant's name).
    pub label: &'static str,
    /// Its name in docs/icd.md.
    pub name: String,
    /// What it means.
    pub meaning: &'static str,
    /// A warning (not latched), not a fault.
    pub warning: bool,
}

/// The fault and warning flags, bits from [`FaultFlags`].
pub fn fault_flags_doc() -> Vec<FlagDoc> {
    let flags: [(FaultFlags, &str, String, &str); 14] = [
        (
            FaultFlags::FOLLOWING_ERROR,
            "FOLLOWING_ERROR",
            "following error".into(),
            "fault: |measured - commanded stroke| above the fault threshold",
        ),
        (
            FaultFlags::ENCODER_STUCK,
            "ENCODER_STUCK",
            "encoder stuck".into(),
            "fault: encoder makes no progress while its slider moves",
        ),
        (
            FaultFlags::ENCODER_JUMP,
            "ENCODER_JUMP",
            "encoder jump".into(),
            "fault: encoder changed more than physically possible in one cycle",
        ),
        (
            FaultFlags::ENCODER_READ_FAILURE,
            "ENCODER_READ_FAILURE",
            "encoder read failure".into(),
            "fault: encoder did not answer, corrupted or non-finite",
        ),
        (
            FaultFlags::SOFT_LIMIT,
            "SOFT_LIMIT",
            "slider beyond soft limit".into(),
            "fault: measured stroke beyond the soft limit",
        ),
        (
            FaultFlags::FK_NOT_CONVERGED,
            "FK_NOT_CONVERGED",
            "FK not converged".into(),
            "fault: FK of the measured strokes failed",
        ),
        (
            FaultFlags::POSE_OUTSIDE_WORKSPACE,
            "POSE_OUTSIDE_WORKSPACE",
            "pose outside workspace".into(),
            "fault: measured pose outside the workspace",
        ),
        (
            FaultFlags::DRIVE_FAULT,
            "DRIVE_FAULT",
            "drive fault".into(),
            "fault: a drive reported a fault",
        ),
        (
            FaultFlags::TABLE_CORRUPT,
            "TABLE_CORRUPT",
            "running table, parameters or settings corrupt in RAM (scrub, checks)".into(),
            "fault: the running table, geometry, thresholds or parameters in RAM failed the \
             scrub or their check",
        ),
        (
            FaultFlags::DEADLINE_MISSED,
            "DEADLINE_MISSED",
            format!(
                "deadline missed ({} consecutive control-cycle overruns)",
                crate::controller::OVERRUN_HOLD_LIMIT
            ),
            "fault: control cycles overran their period 3 times in a row",
        ),
        (
            FaultFlags::LIMIT_SWITCH,
            "LIMIT_SWITCH",
            "end of travel (an end-of-travel switch active or a switch input unreadable)".into(),
            "fault: an end-of-travel switch active, or a switch input unreadable",
        ),
        (
            FaultFlags::OUTPUT_LIMITED,
            "OUTPUT_LIMITED",
            "output limited (a stroke step beyond the speed or acceleration limit was clamped: \
             geometry or planner wrong; the drives held at once)"
                .into(),
            "fault: the output stage clamped a stroke step beyond the speed or acceleration \
             limit",
        ),
        (
            FaultFlags::FOLLOWING_WARNING,
            "FOLLOWING_WARNING",
            "following error above the warning threshold".into(),
            "warning: following error above the warning threshold",
        ),
        (
            FaultFlags::ENCODER_WARNING,
            "ENCODER_WARNING",
            format!(
                "encoder warning (the encoder's own warning bit: position valid, maintenance \
                 asked for; legs in event {}, not latched, motion goes on)",
                hex4(event_id::WARNING_CHANGED)
            ),
            "warning: an encoder reports its warning bit (maintenance: e.g. a dirty scale)",
        ),
    ];
    flags
        .into_iter()
        .map(|(f, label, name, meaning)| FlagDoc {
            bit: bit_of(f.bits()),
            label,
            name,
            meaning,
            warning: FaultFlags::ALL_WARNINGS.contains(f),
        })
        .collect()
}

/// The fault and warning flags as (bit, label, meaning), bits from [`FaultFlags`].
pub fn fault_flag_bits() -> Vec<(u32, String, String)> {
    fault_flags_doc()
        .into_iter()
        .map(|f| (f.bit, f.label.to_string(), f.meaning.to_string()))
        .collect()
}

/// The status flags of one flash bank in the boot flags (event BOOT_DETAIL aux0), from
/// [`crate::table::BankStatus::flag`]: (bit, what).
pub fn bank_status_flags() -> Vec<(u32, &'static str)> {
    use crate::table::BankStatus;
    let all = [
        BankStatus::Blank,
        BankStatus::ReadFailed,
        BankStatus::HeaderCorrupt,
        BankStatus::BodyCorrupt(TableError::BadCrc),
        BankStatus::Rejected(ValidationError::BadConfig),
        BankStatus::Standby { sequence: 0 },
        BankStatus::Active { sequence: 0 },
    ];
    all.iter()
        .map(|b| {
            // Exhaustive: a new status does not compile until it is named here.
            let what = match b {
                BankStatus::Blank => "blank",
                BankStatus::ReadFailed => "read failed",
                BankStatus::HeaderCorrupt => "header corrupt",
                BankStatus::BodyCorrupt(_) => "body corrupt",
                BankStatus::Rejected(_) => "refused by validation",
                BankStatus::Standby { .. } => "valid standby",
                BankStatus::Active { .. } => "selected and running",
            };
            (bit_of(u32::from(b.flag())), what)
        })
        .collect()
}

// ---------------------------------------------------------------------------------
// The parameter table image (TC[6,2] chunks, TM[6,6] dumps).

/// One row of the table image's layout (docs/icd.md section 5; little-endian).
#[derive(Clone, Debug, Serialize)]
pub struct TableImageRow {
    /// Offset in the image (bytes).
    pub offset: usize,
    /// Size (bytes).
    pub size: usize,
    /// Type as docs/icd.md writes it (`u16`, `36 × f64`, `ASCII`, `bytes`).
    pub ty: String,
    /// What it holds.
    pub field: String,
    /// Unit (empty: none).
    pub unit: &'static str,
    /// What validation accepts (with the refusal codes).
    pub validation: String,
    /// The row's bytes in an image of this table (checked against [`Table::to_bytes`] by
    /// `host-tests/icd.rs`).
    #[serde(skip)]
    pub bytes_of: fn(&Table) -> Vec<u8>,
}

fn f64s_le(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The table image's rows, in offset order (they tile [`TABLE_LEN`] bytes).
pub fn table_image() -> Vec<TableImageRow> {
    use crate::table::layout::{
        JOINT_COORDS, PROVENANCE_TAG_LEN, TABLE_CRC_LEN, TABLE_CRC_OFFSET, TABLE_FORMAT_VERSION,
        TABLE_MAGIC,
    };
    #[derive(Clone, Copy)]
    enum Ty {
        Bytes,
        Ascii,
        U16,
        U32,
        F32,
        F64,
    }
    let validation = crate::table::ValidationConfig::flight();
    let ws = &validation.max_workspace;
    let ws_arcsec: Vec<f64> = ws
        .rotation_rad
        .iter()
        .map(|r| r * crate::units::ARCSEC_PER_RAD)
        .collect();
    let code = |e: ValidationError| hex4(e.code());
    let non_finite = code(ValidationError::NonFinite { field: 0 });
    let dev = uniform(&[validation.max_coordinate_deviation_mm]);
    let cap = uniform(&[validation.max_abs_stroke_limit_mm]);
    let stroke_cap = code(ValidationError::StrokeLimitBeyondCap { leg: 0 });
    let ws_cap = code(ValidationError::WorkspaceBeyondCap { axis: 0 });
    let legs = format!("legs 1..{LEGS}");
    type Row = (
        Ty,
        usize,
        String,
        &'static str,
        String,
        fn(&Table) -> Vec<u8>,
    );
    let rows: Vec<Row> = vec![
        (
            Ty::Bytes,
            TABLE_MAGIC.len(),
            format!("magic `\"{}\"`", String::from_utf8_lossy(&TABLE_MAGIC)),
            "",
            "exact".into(),
            |_| TABLE_MAGIC.to_vec(),
        ),
        (
            Ty::U16,
            1,
            "format version".into(),
            "",
            format!("{TABLE_FORMAT_VERSION}"),
            |_| TABLE_FORMAT_VERSION.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            1,
            "total length, CRC included".into(),
            "bytes",
            format!("{TABLE_LEN}"),
            |_| u16::try_from(TABLE_LEN).unwrap_or(0).to_le_bytes().to_vec(),
        ),
        (
            Ty::U32,
            1,
            "table ID (reported in HK)".into(),
            "",
            "any".into(),
            |t| t.table_id.to_le_bytes().to_vec(),
        ),
        (Ty::U32, 1, "calibration ID".into(), "", "any".into(), |t| {
            t.provenance.calibration_id.to_le_bytes().to_vec()
        }),
        (
            Ty::Ascii,
            PROVENANCE_TAG_LEN,
            "provenance tag, NUL/space padded".into(),
            "",
            format!(
                "printable ASCII or NUL ({})",
                code(ValidationError::ProvenanceNotAscii { index: 0 })
            ),
            |t| t.provenance.tag.to_vec(),
        ),
        (
            Ty::F64,
            JOINT_COORDS,
            format!(
                "joint centres, leg-major: leg i (1..{LEGS}) at this offset + {} (i - 1): `a.x \
                 a.y a.z` (frame B, zero stroke), then `b.x b.y b.z` (frame M)",
                JOINT_COORDS / LEGS * core::mem::size_of::<f64>()
            ),
            "mm",
            format!(
                "finite ({non_finite}); within {dev} mm of nominal ({}); rod length within {} mm \
                 of nominal ({}); upper joint >= {} mm above the lower at home ({})",
                code(ValidationError::CoordinateOffNominal { index: 0 }),
                uniform(&[validation.max_rod_deviation_mm]),
                code(ValidationError::RodLengthImplausible { leg: 0 }),
                uniform(&[crate::kinematics::geometry::MIN_ROD_VERTICAL_MM]),
                code(ValidationError::Geometry(GeometryError::NonFinite)),
            ),
            |t| {
                t.legs
                    .iter()
                    .flat_map(|l| f64s_le(&l.a_mm).into_iter().chain(f64s_le(&l.b_mm)))
                    .collect()
            },
        ),
        (
            Ty::F64,
            3,
            "p0: home position of M's origin in B".into(),
            "mm",
            format!("finite, within {dev} mm of nominal"),
            |t| f64s_le(&t.p0_mm),
        ),
        (
            Ty::F64,
            LEGS,
            format!("slider stroke lower limits, {legs}"),
            "mm",
            format!("finite; >= -{cap} mm ({stroke_cap}); contains 0"),
            |t| f64s_le(&t.stroke_limits.min_mm),
        ),
        (
            Ty::F64,
            LEGS,
            format!("slider stroke upper limits, {legs}"),
            "mm",
            format!("finite; <= {cap} mm ({stroke_cap}); contains 0"),
            |t| f64s_le(&t.stroke_limits.max_mm),
        ),
        (
            Ty::F64,
            3,
            "workspace half-range x, y, z (base axes)".into(),
            "mm",
            format!(
                "finite, >= 0, <= {} mm ({ws_cap})",
                uniform(&ws.translation_mm)
            ),
            |t| f64s_le(&t.workspace.translation_mm),
        ),
        (
            Ty::F64,
            3,
            "workspace half-range alpha, beta, gamma".into(),
            "rad",
            format!("finite, >= 0, <= {} arcsec ({ws_cap})", uniform(&ws_arcsec)),
            |t| f64s_le(&t.workspace.rotation_rad),
        ),
        (
            Ty::F32,
            1,
            "following-error warning threshold".into(),
            "mm",
            format!(
                "> 0, < fault threshold ({})",
                code(ValidationError::Supervision { field: 0 })
            ),
            |t| {
                t.supervision
                    .following_error_warning_mm
                    .to_le_bytes()
                    .to_vec()
            },
        ),
        (
            Ty::F32,
            1,
            "following-error fault threshold".into(),
            "mm",
            "> 0".into(),
            |t| {
                t.supervision
                    .following_error_fault_mm
                    .to_le_bytes()
                    .to_vec()
            },
        ),
        (
            Ty::F32,
            1,
            "encoder jump threshold".into(),
            "mm per control cycle",
            "> 0".into(),
            |t| {
                t.supervision
                    .encoder_jump_mm_per_cycle
                    .to_le_bytes()
                    .to_vec()
            },
        ),
        (
            Ty::F32,
            1,
            "stuck detection: least progress counted as motion".into(),
            "mm",
            "> 0".into(),
            |t| t.supervision.stuck_min_progress_mm.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            1,
            "stuck detection window".into(),
            "control cycles",
            "> 0".into(),
            |t| t.supervision.stuck_detection_cycles.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            1,
            "warning debounce".into(),
            "control cycles",
            "> 0".into(),
            |t| t.supervision.warning_debounce_cycles.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            1,
            "fault debounce".into(),
            "control cycles",
            "> 0".into(),
            |t| t.supervision.fault_debounce_cycles.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            1,
            "reserved".into(),
            "",
            format!("0 ({})", hex4(TableError::ReservedNotZero.code())),
            |_| 0u16.to_le_bytes().to_vec(),
        ),
        (
            Ty::U32,
            TABLE_CRC_LEN / 4,
            format!("CRC-32/ISO-HDLC (zlib) of bytes 0..{TABLE_CRC_OFFSET}"),
            "",
            format!("must match ({})", hex4(TableError::BadCrc.code())),
            |t| t.crc32().to_le_bytes().to_vec(),
        ),
    ];
    let mut offset = 0;
    rows.into_iter()
        .map(|(ty, n, field, unit, validation, bytes_of)| {
            let (elem, name) = match ty {
                Ty::Bytes => (1, "bytes"),
                Ty::Ascii => (1, "ASCII"),
                Ty::U16 => (2, "u16"),
                Ty::U32 | Ty::F32 => (4, if matches!(ty, Ty::U32) { "u32" } else { "f32" }),
                Ty::F64 => (8, "f64"),
            };
            let ty = match ty {
                Ty::Bytes | Ty::Ascii => name.to_string(),
                _ if n == 1 => name.to_string(),
                _ => format!("{n} × {name}"),
            };
            let row = TableImageRow {
                offset,
                size: elem * n,
                ty,
                field,
                unit,
                validation,
                bytes_of,
            };
            offset += row.size;
            row
        })
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
                values: failure_code_values(),
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
        failure_codes: failure_codes(),
        table_image: table_image(),
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
