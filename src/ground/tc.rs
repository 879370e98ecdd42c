//! Ground telecommand encoder (host): builds the framed TC byte sequences of the link
//! ICD (`docs/icd.md`) and the `m2ground tc ...` output (hex lines or a binary file).

use std::fmt::Write as _;
use std::path::Path;

use crate::link::command::TABLE_CHUNK_MAX_LEN;
use crate::link::schedule::{ActivityBlock, ObtOffset, ScheduleCommand};
use crate::link::tc::{EncodeError, RequestId, TcHeader, APID_MASK, SEQ_COUNT_MASK};
use crate::link::tm::{TmTime, TIME_FRACTIONS_PER_SECOND};
use crate::link::{
    encode_frame, encode_telecommand, AckFlags, Command, TableChunk, WirePose, MAX_TC_FRAME_LEN,
    MAX_TC_PACKET_LEN,
};
use crate::table::layout::{CRC32, PROVENANCE_TAG_LEN};
use crate::table::{Provenance, Table, DEFAULT_SUPERVISION};
use crate::units::{NM_PER_UM, UAS_PER_ARCSEC};

/// Provenance key whose value becomes the table's calibration ID and tag.
pub const CALIBRATION_ID_KEY: &str = "calibration_id";

/// Numbers telecommands in sequence: every encoded TC takes the next sequence count
/// (14 bits, wrapping) and carries the source ID and acknowledgement flags given here.
#[derive(Clone, Copy, Debug)]
pub struct TcSequencer {
    /// Sequence count of the next TC.
    pub next_seq_count: u16,
    /// Source ID of every TC.
    pub source_id: u16,
    /// Acknowledgement flags of every TC.
    pub ack: AckFlags,
}

impl TcSequencer {
    /// Starting at `first_seq_count`, source ID 0, all acknowledgements.
    pub fn new(first_seq_count: u16) -> TcSequencer {
        TcSequencer {
            next_seq_count: first_seq_count,
            source_id: 0,
            ack: AckFlags::ALL,
        }
    }

    fn header(&mut self) -> TcHeader {
        let h = TcHeader {
            seq_count: self.next_seq_count,
            source_id: self.source_id,
            ack: self.ack,
        };
        self.next_seq_count = self.next_seq_count.wrapping_add(1) & crate::link::tc::SEQ_COUNT_MASK;
        h
    }

    /// The PUS packet (unframed) of the next TC.
    pub fn packet(&mut self, command: &Command) -> Result<Vec<u8>, String> {
        let mut buf = [0u8; MAX_TC_PACKET_LEN];
        let n = encode_telecommand(command, self.header(), &mut buf)
            .map_err(|EncodeError::BufferTooSmall| format!("{command:?}: packet too long"))?;
        Ok(buf[..n].to_vec())
    }

    /// The framed bytes (`0x00, COBS(packet), 0x00`) of the next TC.
    pub fn frame(&mut self, command: &Command) -> Result<Vec<u8>, String> {
        let packet = self.packet(command)?;
        Ok(frame(&packet))
    }

    /// Frames of a command sequence, one per command.
    pub fn frames(&mut self, commands: &[Command]) -> Result<Vec<Vec<u8>>, String> {
        commands.iter().map(|c| self.frame(c)).collect()
    }

    /// A TC[11,4] inserting `activities` (release time, telecommand): each embedded
    /// telecommand is numbered by this sequencer first (in order), then the insert
    /// itself. Returns the insert and the embedded request IDs (what a delete names).
    pub fn schedule_insert(
        &mut self,
        activities: &[(TmTime, Command)],
    ) -> Result<(Command, Vec<RequestId>), String> {
        let mut packets = Vec::new();
        for (release, command) in activities {
            if matches!(command, Command::Schedule(_)) {
                return Err("a schedule telecommand cannot be scheduled".into());
            }
            packets.push((*release, self.packet(command)?));
        }
        let ids = packets
            .iter()
            .map(|(_, p)| RequestId::from_packet(p).unwrap_or_default())
            .collect();
        let refs: Vec<(TmTime, &[u8])> = packets.iter().map(|(t, p)| (*t, p.as_slice())).collect();
        let block = ActivityBlock::new(&refs).map_err(|e| {
            format!(
                "the activities do not make a TC[11,4] (code {:#06x}, data {:#x}): at most {} \
                 bytes, embedded telecommands of at most {} bytes",
                e.code(),
                e.data(),
                crate::link::schedule::MAX_INSERT_APP_DATA_LEN,
                crate::link::schedule::MAX_SCHEDULED_TC_LEN
            )
        })?;
        Ok((Command::Schedule(ScheduleCommand::Insert(block)), ids))
    }
}

/// The request ID of the telecommand this ground sends with sequence count `seq_count`
/// (APID [`crate::link::M2_APID`], unsegmented): what TC[11,5] names.
pub fn request_id_of(seq_count: u16) -> RequestId {
    /// Packet ID bits of a TC with a secondary header (type and flag).
    const TC_WITH_SEC_HEADER: u16 = 0x1800;
    /// Sequence flags of an unsegmented packet.
    const UNSEGMENTED: u16 = 0xC000;
    RequestId {
        packet_id: TC_WITH_SEC_HEADER | (crate::link::M2_APID & APID_MASK),
        sequence_control: UNSEGMENTED | (seq_count & SEQ_COUNT_MASK),
    }
}

/// An on-board time from seconds (nearest 1/65536 s); refused if negative, not finite
/// or beyond CUC 4+2.
pub fn obt_from_seconds(s: f64) -> Result<TmTime, String> {
    let ticks = (s * TIME_FRACTIONS_PER_SECOND as f64).round();
    if !(ticks.is_finite() && ticks >= 0.0 && ticks < 2f64.powi(48)) {
        return Err(format!("{s} s: not an on-board time (0 .. 2^32 s)"));
    }
    TmTime::from_ticks(ticks as u64).ok_or_else(|| format!("{s} s: beyond CUC 4+2"))
}

/// A time offset from seconds (nearest 1/65536 s); refused if not finite or beyond the
/// TC[11,15] range (+-2^31 s).
pub fn offset_from_seconds(s: f64) -> Result<ObtOffset, String> {
    let ticks = (s * TIME_FRACTIONS_PER_SECOND as f64).round();
    if !ticks.is_finite() || ticks.abs() >= 2f64.powi(47) {
        return Err(format!("{s} s: not a time offset (+-2^31 s)"));
    }
    ObtOffset::from_ticks(ticks as i64).ok_or_else(|| format!("{s} s: beyond the offset range"))
}

/// COBS frame of a packet.
pub fn frame(packet: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; crate::link::framing::max_frame_len(packet.len())];
    let n = encode_frame(packet, &mut out).unwrap_or(0);
    out.truncate(n);
    out
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
    let file = crate::ground::files::read_geometry(path)?;
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
    crate::ground::files::validate_table_for_flight(&table)
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
const OPTIONAL_POSE_AXES: [&str; 6] = crate::ground::mdb::POSE_AXES;

/// The telecommand of the mission database named `name` (case-insensitive, `-` for
/// `_`: `move-absolute`), with its arguments as `name=value` in engineering units
/// (`x=1.5` um, `rx=-2` arcsec, `leg=3`, `parameter_id=PIVOT_Z` or `0x0003`,
/// `crc32=0x1234abcd`, `data=` hex bytes). Every argument is required except the pose
/// axes of a move (0 when omitted). A value outside the description's range, an unknown
/// or a repeated argument is refused with its name. The mission database is the one
/// vocabulary: its `build` makes the flight [`Command`], which the link then encodes.
pub fn command_from_args(name: &str, args: &[String]) -> Result<Command, String> {
    use crate::ground::mdb::{mdb, ArgValue, Meaning, Wire};
    let db = mdb();
    let wanted = name.to_ascii_uppercase().replace('-', "_");
    let tc = db
        .telecommand(&wanted)
        .ok_or_else(|| format!("{name}: no such telecommand (`m2ground tc list` shows them)"))?;
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
                ArgValue::Int(f.to_raw(eng)?)
            }
        };
        values.push(value);
    }
    (tc.build)(&values).map_err(|e| format!("{}: {e}", tc.name))
}

/// A decimal or `0x` hexadecimal integer.
fn parse_integer(s: &str) -> Result<i64, String> {
    match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(h) => i64::from_str_radix(h, 16).map_err(|e| format!("{s}: {e}")),
        None => s.parse().map_err(|e| format!("{s}: {e}")),
    }
}

/// `m2ground tc schedule at=SECONDS NAME [arg=value ...]`: a TC[11,4] inserting the
/// named telecommand (as [`command_from_args`]) with release time `at` (on-board time,
/// s since the controller's boot, to 1/65536 s). The embedded telecommand is numbered
/// by `sequencer` first, then the insert; returns the insert and the embedded request
/// ID (what a delete names).
pub fn schedule_from_args(
    args: &[String],
    sequencer: &mut TcSequencer,
) -> Result<(Command, RequestId), String> {
    let (at, rest) = args
        .split_first()
        .ok_or("schedule: at=SECONDS, then the telecommand")?;
    let release_s: f64 = at
        .strip_prefix("at=")
        .ok_or_else(|| format!("{at}: schedule takes at=SECONDS first"))?
        .parse()
        .map_err(|e| format!("{at}: {e}"))?;
    let (name, targs) = rest.split_first().ok_or("schedule: which telecommand?")?;
    let command = command_from_args(name, targs)?;
    let release = obt_from_seconds(release_s)?;
    let (insert, ids) = sequencer.schedule_insert(&[(release, command)])?;
    Ok((insert, ids.first().copied().unwrap_or_default()))
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
/// and range (`m2ground tc list`).
pub fn telecommand_list() -> String {
    use crate::ground::mdb::{mdb, Meaning};
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
            .map(|f| match &f.meaning {
                Meaning::Number {
                    unit,
                    range: Some((lo, hi)),
                    ..
                } => format!(
                    "{}=<{}..{}{}>",
                    f.name,
                    lo,
                    hi,
                    unit.map_or(String::new(), |u| format!(" {u}"))
                ),
                Meaning::Enum { enumeration } => format!("{}=<{}>", f.name, labels(enumeration)),
                _ => format!("{}=<{}>", f.name, f.name),
            })
            .collect();
        out.push_str(&format!(
            "{:<24} {}\n    {}\n",
            tc.name.to_ascii_lowercase().replace('_', "-"),
            args.join(" "),
            tc.description
        ));
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
