//! Ground telecommand encoder (host): builds the framed TC byte sequences of the link
//! ICD (`docs/icd.md`) and the `m2ground tc ...` output (hex lines or a binary file).

use std::fmt::Write as _;
use std::path::Path;

use m2ctl::link::command::TABLE_CHUNK_MAX_LEN;
use m2ctl::link::schedule::ObtOffset;
use m2ctl::link::tc::{RequestId, APID_MASK, SEQ_COUNT_MASK};
use m2ctl::link::tm::{TmTime, TIME_FRACTIONS_PER_SECOND};
use m2ctl::link::{Command, TableChunk, WirePose, MAX_TC_FRAME_LEN};
use m2ctl::table::layout::{CRC32, PROVENANCE_TAG_LEN};
use m2ctl::table::{Provenance, Table, DEFAULT_SUPERVISION};
use m2ctl::units::{NM_PER_UM, UAS_PER_ARCSEC};

pub use m2ctl::station::sequencer::{frame, TcSequencer};

/// Provenance key whose value becomes the table's calibration ID and tag.
pub const CALIBRATION_ID_KEY: &str = "calibration_id";

/// The request ID of the telecommand this ground sends with sequence count `seq_count`
/// (APID [`m2ctl::link::M2_APID`], unsegmented): what TC[11,5] names.
pub fn request_id_of(seq_count: u16) -> RequestId {
    /// Packet ID bits of a TC with a secondary header (type and flag).
    const TC_WITH_SEC_HEADER: u16 = 0x1800;
    /// Sequence flags of an unsegmented packet.
    const UNSEGMENTED: u16 = 0xC000;
    RequestId {
        packet_id: TC_WITH_SEC_HEADER | (m2ctl::link::M2_APID & APID_MASK),
        sequence_control: UNSEGMENTED | (seq_count & SEQ_COUNT_MASK),
    }
}

pub use m2ctl::station::obt_from_seconds;

/// A time offset from seconds (nearest 1/65536 s); refused if not finite or beyond the
/// TC[11,15] range (+-2^31 s).
pub fn offset_from_seconds(s: f64) -> Result<ObtOffset, String> {
    let ticks = (s * TIME_FRACTIONS_PER_SECOND as f64).round();
    if !ticks.is_finite() || ticks.abs() >= 2f64.powi(47) {
        return Err(format!("{s} s: not a time offset (+-2^31 s)"));
    }
    ObtOffset::from_ticks(ticks as i64).ok_or_else(|| format!("{s} s: beyond the offset range"))
}

/// Largest frame any telecommand can have (bytes).
pub const MAX_FRAME_LEN: usize = MAX_TC_FRAME_LEN;

/// A wire pose from micrometres and arcseconds; refused if not finite or beyond the i32
/// range of nanometres / micro-arcseconds.
pub fn wire_pose(translation_um: [f64; 3], rotation_arcsec: [f64; 3]) -> Result<WirePose, String> {
    let conv = |v: f64, scale: f64, what: &str| -> Result<i32, String> {
        let r = (v * scale).round();
        if r.is_finite() && r >= f64::from(i32::MIN) && r <= f64::from(i32::MAX) {
            Ok(r as i32)
        } else {
            Err(format!("{what} = {v} is not finite or out of range"))
        }
    };
    let mut p = WirePose::default();
    for (k, (dst, v)) in p.translation_nm.iter_mut().zip(translation_um).enumerate() {
        *dst = conv(v, NM_PER_UM, ["x_um", "y_um", "z_um"][k])?;
    }
    for (k, (dst, v)) in p.rotation_uas.iter_mut().zip(rotation_arcsec).enumerate() {
        *dst = conv(
            v,
            UAS_PER_ARCSEC,
            ["rx_arcsec", "ry_arcsec", "rz_arcsec"][k],
        )?;
    }
    Ok(p)
}

/// The provenance of a table from a geometry file's `[provenance]`: calibration ID =
/// CRC-32 of the `calibration_id` text (or `calibration_id_override`), tag = its first
/// 16 ASCII characters, space padded (`m2ground` without a calibration ID).
pub fn provenance(
    entries: &[(String, String)],
    calibration_id_override: Option<u32>,
) -> Provenance {
    let text = entries
        .iter()
        .find(|(k, _)| k == CALIBRATION_ID_KEY)
        .map(|(_, v)| v.as_str());
    let mut tag = [b' '; PROVENANCE_TAG_LEN];
    let src = text.unwrap_or("m2ground");
    for (d, c) in tag
        .iter_mut()
        .zip(src.bytes().filter(|b| b.is_ascii_graphic() || *b == b' '))
    {
        *d = c;
    }
    Provenance {
        calibration_id: calibration_id_override
            .unwrap_or_else(|| text.map_or(0, |t| CRC32.checksum(t.as_bytes()))),
        tag,
    }
}

/// The table of a geometry file (with `[limits]`), default supervision thresholds,
/// checked by the flight validation (`table::validate`, flight configuration): a table
/// the controller would refuse is never encoded.
pub fn table_from_geometry_file(
    path: &Path,
    table_id: u32,
    calibration_id: Option<u32>,
) -> Result<Table, String> {
    let file = m2calib::files::read_geometry(path)?;
    let table = Table::from_geometry(
        &file.params,
        table_id,
        provenance(&file.provenance, calibration_id),
        DEFAULT_SUPERVISION,
    )
    .map_err(|_| {
        format!(
            "{}: a table needs [limits] with stroke and workspace limits",
            path.display()
        )
    })?;
    // The controller would refuse it after the whole upload: refuse it here, before
    // anything is encoded.
    m2calib::files::validate_table_for_flight(&table)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(table)
}

/// The upload sequence of a table: TC[6,2] chunks of at most 128 bytes in offset order,
/// then TC[8,1] commit with the table's CRC-32.
pub fn upload_commands(table: &Table) -> Result<Vec<Command>, String> {
    let bytes = table.to_bytes();
    let mut cmds = Vec::new();
    for (i, chunk) in bytes.chunks(TABLE_CHUNK_MAX_LEN).enumerate() {
        let offset = u16::try_from(i * TABLE_CHUNK_MAX_LEN).map_err(|e| e.to_string())?;
        let c = TableChunk::new(offset, chunk).map_err(|e| format!("chunk {i}: {e:?}"))?;
        cmds.push(Command::LoadTableChunk(c));
    }
    cmds.push(Command::CommitTable {
        crc32: table.crc32(),
    });
    Ok(cmds)
}

/// TC[8,1] activate naming `table` (its ID and CRC-32).
pub fn activate_command(table: &Table) -> Command {
    Command::ActivateTable {
        table_id: table.table_id,
        crc32: table.crc32(),
    }
}

/// Lowercase hex, one frame per line.
pub fn hex_lines(frames: &[Vec<u8>]) -> String {
    let mut s = String::new();
    for f in frames {
        for b in f {
            let _ = write!(s, "{b:02x}");
        }
        s.push('\n');
    }
    s
}

/// Parses hex lines back into frames (blank lines and `#` comments skipped).
pub fn parse_hex_lines(text: &str) -> Result<Vec<Vec<u8>>, String> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if line.len() % 2 != 0 {
            return Err(format!("line {}: odd number of hex digits", n + 1));
        }
        let bytes = (0..line.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&line[i..i + 2], 16))
            .collect::<Result<Vec<u8>, _>>()
            .map_err(|e| format!("line {}: {e}", n + 1))?;
        out.push(bytes);
    }
    Ok(out)
}

/// Pose axes an operator may omit from a move or a move check (they are 0 then).
const OPTIONAL_POSE_AXES: [&str; 6] = crate::mdb::POSE_AXES;

/// The telecommand of the mission database named `name` (case-insensitive, `-` for
/// `_`: `move-absolute`), with its arguments as `name=value` in engineering units
/// (`x=1.5` um, `rx=-2` arcsec, `leg=3`, `parameter_id=PIVOT_Z` or `0x0003`,
/// `crc32=0x1234abcd`, `data=` hex bytes). Every argument is required except the pose
/// axes of a move (0 when omitted). An unknown or a repeated argument is refused with
/// its name, and so is a value the controller would refuse for its own range
/// ([`check_arguments`]). The mission database is the one vocabulary: its `build`
/// makes the flight [`Command`], which the link then encodes.
pub fn command_from_args(name: &str, args: &[String]) -> Result<Command, String> {
    let db = crate::mdb::mdb();
    let tc = named_telecommand(&db, name)?;
    let values = argument_values(&db, tc, args)?;
    checked_build(tc, &values)
}

/// The mission database's telecommand `name` (`move-absolute` or `MOVE_ABSOLUTE`).
fn named_telecommand<'a>(
    db: &'a crate::mdb::Mdb,
    name: &str,
) -> Result<&'a crate::mdb::Telecommand, String> {
    let wanted = name.to_ascii_uppercase().replace('-', "_");
    db.telecommand(&wanted)
        .ok_or_else(|| format!("{name}: no such telecommand (`m2ground tc list` shows them)"))
}

/// The raw argument values (description order) of `name=value` words.
fn argument_values(
    db: &crate::mdb::Mdb,
    tc: &crate::mdb::Telecommand,
    args: &[String],
) -> Result<Vec<crate::mdb::ArgValue>, String> {
    use crate::mdb::{ArgValue, Meaning, Wire};
    let mut given: Vec<(String, String)> = Vec::new();
    for a in args {
        let (k, v) = a
            .split_once('=')
            .ok_or_else(|| format!("{a}: arguments are name=value"))?;
        if given.iter().any(|(g, _)| g == k) {
            return Err(format!("{k}: given twice"));
        }
        if !tc.arguments().any(|f| f.name == k) {
            let names: Vec<&str> = tc.arguments().map(|f| f.name.as_str()).collect();
            return Err(format!(
                "{}: no argument {k} (arguments: {names:?})",
                tc.name
            ));
        }
        given.push((k.to_string(), v.to_string()));
    }
    let mut values = Vec::new();
    for f in tc.arguments() {
        let v = given
            .iter()
            .find(|(k, _)| *k == f.name)
            .map(|(_, v)| v.as_str());
        let is_pose_axis = tc.fields.len() == OPTIONAL_POSE_AXES.len()
            && OPTIONAL_POSE_AXES.contains(&f.name.as_str());
        let v = match (v, is_pose_axis) {
            (Some(v), _) => v,
            (None, true) => "0",
            (None, false) => return Err(format!("{}: missing argument {}", tc.name, f.name)),
        };
        let value = match (&f.meaning, f.wire) {
            (Meaning::Binary, _) => {
                ArgValue::Bytes(parse_hex_bytes(v).map_err(|e| format!("{}: {e}", f.name))?)
            }
            (Meaning::Enum { enumeration }, _) => {
                let e = db
                    .enums
                    .iter()
                    .find(|e| e.name == *enumeration)
                    .ok_or_else(|| format!("{enumeration}: no enumeration"))?;
                let by_label = e
                    .values
                    .iter()
                    .find(|(_, label, _)| label.eq_ignore_ascii_case(v))
                    .map(|(n, _, _)| *n);
                let known = by_label
                    .or_else(|| parse_integer(v).ok())
                    .filter(|n| e.values.iter().any(|(m, _, _)| m == n));
                let Some(n) = known else {
                    let labels: Vec<&str> = e.values.iter().map(|(_, l, _)| l.as_str()).collect();
                    return Err(format!("{} = {v}: not one of {labels:?}", f.name));
                };
                ArgValue::Int(n)
            }
            (Meaning::Number { .. }, Wire::U32) | (Meaning::Number { .. }, Wire::U16)
                if v.starts_with("0x") || v.starts_with("0X") =>
            {
                ArgValue::Int(parse_integer(v).map_err(|e| format!("{}: {e}", f.name))?)
            }
            _ => {
                let eng: f64 = v
                    .parse()
                    .map_err(|e| format!("{} = {v}: not a number ({e})", f.name))?;
                if let Some(e) = outside_range(f, eng) {
                    return Err(e);
                }
                ArgValue::Int(f.to_raw(eng)?)
            }
        };
        values.push(value);
    }
    Ok(values)
}

/// The seconds of on-board time of `t`.
fn obt_seconds(t: TmTime) -> f64 {
    f64::from(t.seconds) + f64::from(t.fraction) / TIME_FRACTIONS_PER_SECOND as f64
}

/// Checks raw argument values (description order) against the controller's ranges,
/// refusing the first value outside with the argument's name and its range:
/// * every number within the description's range (mission database, the same in
///   Yamcs; else its wire type's), whatever notation it was given in, every enumerated
///   value one of its enumeration, every byte string's length;
/// * what one argument's range owes to another, which a per-argument range cannot
///   state: TC[20,3]'s value within the range of its parameter
///   ([`m2ctl::controller::params::PARAMETERS`], refused on board with 0x0721), a
///   TC[11,4] release time within the on-board clock
///   ([`m2ctl::controller::schedule::MAX_OBT`], 0x0B06), a table chunk inside the
///   table image (0x050E), a scheduled telecommand one of this controller that may be
///   scheduled (0x050F).
///
/// What depends on the controller's state (a pose inside the workspace of the table and
/// frames in force, a time not yet past, a request ID scheduled) cannot be checked here:
/// `check-move` asks the controller.
pub fn check_arguments(
    tc: &crate::mdb::Telecommand,
    values: &[crate::mdb::ArgValue],
) -> Result<(), String> {
    use crate::mdb::{ArgValue, Meaning, Wire};
    use m2ctl::controller::params::PARAMETERS;
    use m2ctl::controller::schedule::MAX_OBT;
    use m2ctl::table::TABLE_LEN;
    let fields: Vec<&crate::mdb::Field> = tc.arguments().collect();
    if fields.len() != values.len() {
        return Err(format!(
            "{}: {} arguments, {} given",
            tc.name,
            fields.len(),
            values.len()
        ));
    }
    // The value given for the field called `name`.
    let value = |name: &str| {
        fields
            .iter()
            .zip(values)
            .find(|(f, _)| f.name == name)
            .map(|(_, v)| v)
    };
    let int = |name: &str| match value(name)? {
        ArgValue::Int(i) => Some(*i),
        ArgValue::Bytes(_) => None,
    };
    let bytes = |name: &str| match value(name)? {
        ArgValue::Bytes(b) => Some(b.as_slice()),
        ArgValue::Int(_) => None,
    };
    for (f, v) in fields.iter().zip(values) {
        match (v, f.wire) {
            (ArgValue::Bytes(b), Wire::Bytes { min_len, max_len })
            | (ArgValue::Bytes(b), Wire::Packet { min_len, max_len }) => {
                if !(min_len..=max_len).contains(&b.len()) {
                    return Err(format!(
                        "{}: {} bytes, outside {min_len}..={max_len}",
                        f.name,
                        b.len()
                    ));
                }
            }
            (ArgValue::Int(raw), w) => {
                let (lo, hi) = w
                    .raw_range()
                    .ok_or_else(|| format!("{}: expected bytes", f.name))?;
                if !(lo..=hi).contains(raw) {
                    return Err(format!("{} = {raw}: outside {lo}..={hi}", f.name));
                }
                match f.meaning {
                    Meaning::Number { scale, .. } => {
                        if let Some(e) = outside_range(f, *raw as f64 * scale) {
                            return Err(e);
                        }
                    }
                    Meaning::Enum { enumeration } => {
                        let db = crate::mdb::mdb();
                        let e = db.enums.iter().find(|e| e.name == enumeration);
                        if !e.is_some_and(|e| e.values.iter().any(|(n, _, _)| n == raw)) {
                            return Err(format!("{} = {raw}: not a {enumeration}", f.name));
                        }
                    }
                    _ => {}
                }
            }
            (ArgValue::Bytes(_), _) => return Err(format!("{}: expected a number", f.name)),
        }
    }
    match tc.name.as_str() {
        "SET_PARAMETER" => {
            let (Some(id), Some(value)) = (int("parameter_id"), int("value")) else {
                return Err("SET_PARAMETER: parameter_id and value".into());
            };
            let p = PARAMETERS
                .iter()
                .find(|p| i64::from(p.id) == id)
                .ok_or_else(|| format!("parameter_id = {id:#06x}: no such parameter"))?;
            if !(i64::from(p.min)..=i64::from(p.max)).contains(&value) {
                return Err(format!(
                    "value = {value}: outside {}..={} {} (the range of {}, parameter {:#06x})",
                    p.min,
                    p.max,
                    p.unit,
                    p.name.to_ascii_uppercase(),
                    p.id
                ));
            }
        }
        "SCHEDULE_INSERT_ACTIVITY" => {
            let (Some(seconds), Some(fraction), Some(packet)) = (
                int("release_seconds"),
                int("release_fraction"),
                bytes("telecommand"),
            ) else {
                return Err("SCHEDULE_INSERT_ACTIVITY: release time and telecommand".into());
            };
            let release = TmTime {
                seconds: u32::try_from(seconds).map_err(|e| e.to_string())?,
                fraction: u16::try_from(fraction).map_err(|e| e.to_string())?,
            };
            if release > MAX_OBT {
                return Err(format!(
                    "release time = {} s: outside 0..={:.3} s (the on-board clock's range: \
                     release_seconds {} and release_fraction at most {:.6} s)",
                    obt_seconds(release),
                    obt_seconds(MAX_OBT),
                    MAX_OBT.seconds,
                    f64::from(MAX_OBT.fraction) / TIME_FRACTIONS_PER_SECOND as f64
                ));
            }
            check_schedulable(packet, "telecommand")?;
        }
        "LOAD_TABLE_CHUNK" => {
            let (Some(offset), Some(data)) = (int("offset"), bytes("data")) else {
                return Err("LOAD_TABLE_CHUNK: offset and data".into());
            };
            let end = usize::try_from(offset).unwrap_or(usize::MAX) + data.len();
            if end > TABLE_LEN {
                return Err(format!(
                    "data: {} bytes at offset {offset} end at {end}, outside the table \
                     (offset + length <= {TABLE_LEN})",
                    data.len()
                ));
            }
        }
        _ => {}
    }
    Ok(())
}

/// The refusal of an engineering value outside a number field's range (the described
/// one, else its wire type's), with the field's name, range and unit (identifiers also
/// in hex); `None` inside.
fn outside_range(f: &crate::mdb::Field, eng: f64) -> Option<String> {
    use crate::mdb::{Meaning, Wire};
    let Meaning::Number { unit, range, scale } = f.meaning else {
        return None;
    };
    let (lo, hi) = range.or_else(|| {
        f.wire
            .raw_range()
            .map(|(lo, hi)| (lo as f64 * scale, hi as f64 * scale))
    })?;
    if (lo..=hi).contains(&eng) {
        return None;
    }
    let identifier = unit.is_none() && matches!(f.wire, Wire::U16 | Wire::U32);
    let show = |v: f64| {
        if identifier && v >= 0.0 {
            format!("{v} ({:#x})", v as u64)
        } else {
            format!("{v}")
        }
    };
    Some(format!(
        "{} = {}: outside {}..={}{}",
        f.name,
        show(eng),
        show(lo),
        show(hi),
        unit.map_or(String::new(), |u| format!(" {u}"))
    ))
}

/// Refuses, naming `what`, a packet the controller would not schedule: not a
/// telecommand of this controller (its own link code), or a TC[11,x] or a table chunk
/// TC[6,2] (0x0510).
fn check_schedulable(packet: &[u8], what: &str) -> Result<(), String> {
    let tc = m2ctl::link::decode_telecommand(packet).map_err(|r| {
        format!(
            "{what}: not a telecommand of this controller (link code {:#06x}, data {:#x})",
            r.error.code(),
            r.error.data()
        )
    })?;
    if matches!(
        tc.command,
        Command::Schedule(_) | Command::LoadTableChunk(_)
    ) {
        return Err(format!(
            "{what}: {} cannot be scheduled (a TC[11,x] or a table chunk TC[6,2]; code 0x0510)",
            crate::mdb::telecommand_name(&tc.command)
        ));
    }
    Ok(())
}

/// [`check_arguments`], then the description's `build`.
fn checked_build(
    tc: &crate::mdb::Telecommand,
    values: &[crate::mdb::ArgValue],
) -> Result<Command, String> {
    check_arguments(tc, values)?;
    (tc.build)(values).map_err(|e| format!("{}: {e}", tc.name))
}

/// A decimal or `0x` hexadecimal integer.
fn parse_integer(s: &str) -> Result<i64, String> {
    match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(h) => i64::from_str_radix(h, 16).map_err(|e| format!("{s}: {e}")),
        None => s.parse().map_err(|e| format!("{s}: {e}")),
    }
}

/// A TC[11,4] release time from seconds of on-board time (nearest 1/65536 s); refused,
/// with the range, outside 0 ..= the clock's last time
/// ([`m2ctl::controller::schedule::MAX_OBT`], 4,294,967.295 s), which the controller
/// refuses (0x0B06).
pub fn release_time_from_seconds(s: f64) -> Result<TmTime, String> {
    use m2ctl::controller::schedule::MAX_OBT;
    let refused = || {
        format!(
            "at = {s}: not an on-board time of the clock, outside 0..={:.3} s",
            obt_seconds(MAX_OBT)
        )
    };
    let t = obt_from_seconds(s).map_err(|_| refused())?;
    if t > MAX_OBT {
        return Err(refused());
    }
    Ok(t)
}

/// `m2ground tc schedule at=SECONDS NAME [arg=value ...]`: the mission database's
/// SCHEDULE_INSERT_ACTIVITY (TC[11,4]) whose `telecommand` argument is the named
/// telecommand (as [`command_from_args`]), released at `at` (on-board time, s since the
/// controller's boot, to 1/65536 s; the release time's range is checked). The embedded
/// telecommand is numbered by `sequencer` first, then the insert; returns the insert and
/// the embedded request ID (what a delete names).
pub fn schedule_from_args(
    args: &[String],
    sequencer: &mut TcSequencer,
) -> Result<(Command, RequestId), String> {
    use crate::mdb::ArgValue;
    let (at, rest) = args
        .split_first()
        .ok_or("schedule: at=SECONDS, then the telecommand")?;
    let release_s: f64 = at
        .strip_prefix("at=")
        .ok_or_else(|| format!("{at}: schedule takes at=SECONDS first"))?
        .parse()
        .map_err(|e| format!("{at}: {e}"))?;
    let release = release_time_from_seconds(release_s)?;
    let (name, targs) = rest.split_first().ok_or("schedule: which telecommand?")?;
    let command = command_from_args(name, targs)?;
    if matches!(command, Command::Schedule(_) | Command::LoadTableChunk(_)) {
        return Err(format!(
            "{name}: cannot be scheduled (a TC[11,x] or a table chunk TC[6,2]; code 0x0510)"
        ));
    }
    let packet = sequencer.packet(&command)?;
    let id = RequestId::from_packet(&packet).unwrap_or_default();
    let db = crate::mdb::mdb();
    let insert = named_telecommand(&db, "SCHEDULE_INSERT_ACTIVITY")?;
    let values = [
        ArgValue::Int(i64::from(release.seconds)),
        ArgValue::Int(i64::from(release.fraction)),
        ArgValue::Bytes(packet),
    ];
    Ok((checked_build(insert, &values)?, id))
}

/// Hex digits, two per byte, no separators.
fn parse_hex_bytes(s: &str) -> Result<Vec<u8>, String> {
    if s.len() % 2 != 0 {
        return Err(format!("{s}: an odd number of hex digits"));
    }
    (0..s.len())
        .step_by(2)
        .map(|i| {
            s.get(i..i + 2)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("{s}: not hex"))
        })
        .collect()
}

/// The telecommands of the mission database, one per line with their arguments, unit
/// and range (`m2ground tc list`); TC[20,3]'s value with the range of each parameter,
/// TC[11,4] with the `schedule` form that fills it.
pub fn telecommand_list() -> String {
    use crate::mdb::{mdb, Meaning, Wire};
    use m2ctl::controller::params::PARAMETERS;
    let db = mdb();
    let labels = |name: &str| -> String {
        db.enums
            .iter()
            .find(|e| e.name == name)
            .map(|e| {
                e.values
                    .iter()
                    .map(|(_, l, _)| l.as_str())
                    .collect::<Vec<_>>()
                    .join("|")
            })
            .unwrap_or_default()
    };
    let mut out = String::new();
    for tc in &db.telecommands {
        let args: Vec<String> = tc
            .arguments()
            .map(|f| match (&f.meaning, f.wire) {
                (Meaning::Number { .. }, _) if tc.name == "SET_PARAMETER" => {
                    format!("{}=<the range of parameter_id, below>", f.name)
                }
                (Meaning::Number { unit, range, scale }, w) => {
                    let (lo, hi) = range
                        .or_else(|| {
                            w.raw_range()
                                .map(|(lo, hi)| (lo as f64 * scale, hi as f64 * scale))
                        })
                        .unwrap_or_default();
                    format!(
                        "{}=<{}..{}{}>",
                        f.name,
                        lo,
                        hi,
                        unit.map_or(String::new(), |u| format!(" {u}"))
                    )
                }
                (Meaning::Enum { enumeration }, _) => {
                    format!("{}=<{}>", f.name, labels(enumeration))
                }
                (Meaning::Binary, Wire::Bytes { min_len, max_len })
                | (Meaning::Binary, Wire::Packet { min_len, max_len }) => {
                    format!("{}=<hex, {min_len}..{max_len} bytes>", f.name)
                }
                _ => format!("{}=<{}>", f.name, f.name),
            })
            .collect();
        out.push_str(&format!(
            "{:<24} {}\n    {}\n",
            tc.name.to_ascii_lowercase().replace('_', "-"),
            args.join(" "),
            tc.description
        ));
        if tc.name == "SET_PARAMETER" {
            for p in &PARAMETERS {
                out.push_str(&format!(
                    "    value of {:<17} ({:#06x}): {}..{} {}\n",
                    p.name.to_ascii_uppercase(),
                    p.id,
                    p.min,
                    p.max,
                    p.unit
                ));
            }
        }
        if tc.name == "SCHEDULE_INSERT_ACTIVITY" {
            out.push_str(&format!(
                "    or: schedule at=<0..{:.3} s> NAME [arg=value ...] (the named telecommand, \
                 numbered first)\n",
                obt_seconds(m2ctl::controller::schedule::MAX_OBT)
            ));
        }
    }
    out
}

/// The table upload procedure: TC[6,2] chunks of the table built from a geometry file
/// (validated first), TC[8,1] commit, and the activation if asked.
pub fn upload_procedure(
    geometry: &std::path::Path,
    table_id: u32,
    calibration_id: Option<u32>,
    activate: bool,
) -> Result<Vec<Command>, String> {
    let table = table_from_geometry_file(geometry, table_id, calibration_id)?;
    let mut cmds = upload_commands(&table)?;
    if activate {
        cmds.push(activate_command(&table));
    }
    Ok(cmds)
}

/// Output of `m2ground tc`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TcOutput {
    /// One frame per line, lowercase hex.
    HexLines,
    /// The frames back to back, raw bytes (ready for the UART).
    Binary,
}

/// Runs `m2ground tc`: the bytes to write (hex text or binary) for `cmds`.
pub fn run_tc(
    cmds: &[Command],
    sequencer: &mut TcSequencer,
    output: TcOutput,
    unframed: bool,
) -> Result<Vec<u8>, String> {
    let frames = cmds
        .iter()
        .map(|c| {
            if unframed {
                sequencer.packet(c)
            } else {
                sequencer.frame(c)
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(match output {
        TcOutput::HexLines => hex_lines(&frames).into_bytes(),
        TcOutput::Binary => frames.concat(),
    })
}
