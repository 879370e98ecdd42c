//! Telecommands: argument readers, the `build` functions, and every telecommand with
//! its fields (TC[8,1] functions, parameter, table, schedule and time services).

use super::fields::{
    calibrated, count, field, fixed, obt_fields, pose_fields, ranged, S_PER_CUC_FRACTION,
};
use super::names::upper_snake;
use super::{
    ArgValue, BuildFn, Constraint, Field, Meaning, Telecommand, Wire, CUC_COARSE_BYTES,
    CUC_FINE_BYTES, MOVE_COMPLETION_S, QUICK_COMPLETION_S, UNIT_UM,
};
use m2ctl::controller::params::PARAMETERS;
use m2ctl::controller::State;
use m2ctl::kinematics::LEGS;
use m2ctl::link::command::{
    FunctionId, MemoryId, ParameterIds, ParameterValues, TableChunk, WirePose, FUNCTION_ID_LEN,
    MAX_EXPOSURE_HOLD_S, MAX_PARAMETERS_PER_TC, TABLE_CHUNK_MAX_LEN,
};
use m2ctl::link::schedule::{
    ActivityBlock, ObtOffset, RequestIdList, ScheduleCommand, ACTIVITY_COUNT_LEN,
    MAX_INSERT_APP_DATA_LEN, MAX_SCHEDULED_TC_LEN, RELEASE_TIME_LEN, SCHEDULE_CAPACITY,
};
use m2ctl::link::tc::{RequestId, APID_MASK, MIN_TC_PACKET_LEN, REQUEST_ID_LEN, SEQ_COUNT_MASK};
use m2ctl::link::time::{TimeReportRate, MAX_TIME_REPORT_EXPONENT};
use m2ctl::link::tm::TmTime;
use m2ctl::link::{service, subtype, Command, M2_APID};
use m2ctl::table::TABLE_LEN;
use m2ctl::units::UM_PER_NM;

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
fn build_exposure_hold(a: &[ArgValue]) -> Result<Command, String> {
    let timeout_s: u16 = uint_arg(a, 0)?;
    if timeout_s > MAX_EXPOSURE_HOLD_S {
        return Err(format!("argument 0: above {MAX_EXPOSURE_HOLD_S} s"));
    }
    Ok(Command::ExposureHold { timeout_s })
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
            critical: None,
            constraint: None,
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
            f64::from(m2ctl::controller::schedule::MAX_OBT.seconds),
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
            critical: None,
            constraint: None,
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
        .get(m2ctl::controller::params::index::DIRECT_MAX_DELTA)
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
        FunctionId::ExposureHold => d(
            vec![field(
                "timeout",
                at,
                Wire::U16,
                Meaning::Number {
                    unit: Some("s"),
                    scale: 1.0,
                    range: Some((0.0, f64::from(MAX_EXPOSURE_HOLD_S))),
                },
                "the hold's timeout from now (s); 0 ends the hold",
            )],
            build_exposure_hold,
            "The camera is exposing: no thermal compensation step, no scheduled activity released and no operator move (0x0710) until the hold ends (timeout 0) or times out.",
            (
                "exposure hold",
                "timeout u16 (s, 0..3,600; 0 ends the hold)",
            ),
            QUICK_COMPLETION_S,
        ),
    }
}

pub(super) fn telecommands() -> Vec<Telecommand> {
    let mut v = vec![
        Telecommand {
            critical: None,
            constraint: None,
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
            critical: None,
            constraint: None,
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
            critical: None,
            constraint: None,
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
            critical: None,
            constraint: None,
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
            critical: None,
            constraint: None,
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
            critical: None,
            constraint: None,
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
            critical: None,
            constraint: None,
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
    for tc in &mut v {
        tc.critical = critical_reason(&tc.name);
        tc.constraint = constraint(&tc.name);
    }
    v
}

/// How long Yamcs holds a constrained telecommand for its state before failing it (s):
/// longer than a typical move (a 1 mm move takes about 6 s, its fine positioning at
/// most 5 s more) and a table job, short enough that an operator is told soon.
const CONSTRAINT_TIMEOUT_S: f64 = 15.0;

/// The state a telecommand is sent in (`None`: any). The controller refuses the same
/// telecommands in the other states (0x0702 busy, 0x070D a table job runs, 0x0701 a
/// fault latched); `ground/tests/mdb.rs` checks each one against the controller on the
/// simulated bench. Yamcs sees the state one housekeeping report late at worst, so the
/// controller's own refusal stays the rule; the constraint spares the operator a
/// refusal (and holds a command sent during a move until the move ends).
fn constraint(name: &str) -> Option<Constraint> {
    let label = |s: State| upper_snake(&format!("{s:?}"));
    let (states, why) = match name {
        "MOVE_ABSOLUTE" | "MOVE_RELATIVE" => (
            vec![label(State::Idle)],
            "refused while moving (0x0702), a table job runs (0x070D) or a fault is latched (0x0701)",
        ),
        "CLEAR_FAULT" | "DIRECT_STROKE" | "COMMIT_TABLE" | "ACTIVATE_TABLE" | "SWITCH_BANK"
        | "REVERT_TO_NOMINAL" | "SET_PARAMETER" => (
            vec![label(State::Idle), label(State::Faulted)],
            "refused while moving (0x0702) or while a table job runs (0x070D)",
        ),
        _ => return None,
    };
    Some(Constraint {
        states,
        no_job: true,
        timeout_s: CONSTRAINT_TIMEOUT_S,
        why,
    })
}

/// Why a telecommand is critical (Yamcs asks the operator to confirm it), `None` for a
/// normal one: what it changes cannot be undone by the next command, or it bypasses
/// the controller's workspace checks. `ground/tests/mdb.rs` checks this against every
/// flight [`Command`] the telecommand builds.
fn critical_reason(name: &str) -> Option<&'static str> {
    Some(match name {
        "ACTIVATE_TABLE" => "replaces the running geometry and limits",
        "SWITCH_BANK" => "changes the table the next boot runs",
        "REVERT_TO_NOMINAL" => "drops the calibrated table for the compiled-in one",
        "DIRECT_STROKE" => "moves one leg outside the pose checks (recovery)",
        "SCHEDULE_RESET" => "deletes every time-tagged activity",
        "COMMIT_TABLE" => "writes the flash bank the next activation or boot uses",
        _ => return None,
    })
}
