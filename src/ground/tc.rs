//! Ground telecommand encoder (host): builds the framed TC byte sequences of the link
//! ICD (`docs/icd.md`) and the `m2ground tc ...` output (hex lines or a binary file).

use std::fmt::Write as _;
use std::path::Path;

use crate::link::command::{TABLE_CHUNK_MAX_LEN, UAS_PER_ARCSEC};
use crate::link::schedule::{ActivityBlock, ObtOffset, RequestIdList, ScheduleCommand};
use crate::link::tc::{EncodeError, RequestId, TcHeader, APID_MASK, SEQ_COUNT_MASK};
use crate::link::time::TimeReportRate;
use crate::link::tm::{TmTime, TIME_FRACTIONS_PER_SECOND};
use crate::link::{
    encode_frame, encode_telecommand, AckFlags, Command, TableChunk, WirePose, MAX_TC_FRAME_LEN,
    MAX_TC_PACKET_LEN,
};
use crate::table::layout::{CRC32, PROVENANCE_TAG_LEN};
use crate::table::{Provenance, Table, DEFAULT_SUPERVISION};

/// Nanometres per micrometre.
pub const NM_PER_UM: f64 = 1.0e3;
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

/// The table of a geometry file (with `[limits]`), default supervision thresholds.
pub fn table_from_geometry_file(
    path: &Path,
    table_id: u32,
    calibration_id: Option<u32>,
) -> Result<Table, String> {
    let file = crate::ground::files::read_geometry(path)?;
    Table::from_geometry(
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
    })
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

/// What `m2ground tc` is asked to encode.
#[derive(Clone, Debug)]
pub enum TcRequest {
    /// TC[17,1].
    Ping,
    /// TC[3,27].
    Housekeeping,
    /// TC[8,1] move (absolute or relative).
    Move {
        /// Translation (um).
        translation_um: [f64; 3],
        /// Rotation (arcsec).
        rotation_arcsec: [f64; 3],
        /// Relative to the commanded pose.
        relative: bool,
    },
    /// TC[8,1] direct stroke (recovery).
    DirectStroke {
        /// Leg 1..6.
        leg: u8,
        /// Stroke increment (um).
        delta_um: f64,
    },
    /// TC[8,1] stop.
    Stop,
    /// TC[8,1] clear fault.
    ClearFault,
    /// TC[8,1] activate the pending table named by its ID and CRC-32.
    Activate {
        /// Table ID.
        table_id: u32,
        /// CRC-32.
        crc32: u32,
    },
    /// TC[8,1] switch bank.
    SwitchBank,
    /// TC[8,1] revert to nominal.
    RevertToNominal,
    /// TC[6,2] chunks + TC[8,1] commit of the table built from a geometry file.
    Upload {
        /// Geometry file with `[limits]`.
        geometry: std::path::PathBuf,
        /// Table ID.
        table_id: u32,
        /// Calibration ID override.
        calibration_id: Option<u32>,
        /// Append the activation of the committed table.
        activate: bool,
    },
    /// TC[6,5] dump of the active table (or of the upload buffer).
    Dump {
        /// Dump the upload buffer instead of the active table.
        upload_buffer: bool,
    },
    /// TC[11,4]: the telecommands of `what`, released at on-board time `release_s`.
    Schedule {
        /// Release time (on-board time, s since the controller's boot).
        release_s: f64,
        /// What to release.
        what: Box<TcRequest>,
    },
    /// TC[11,1] enable release.
    ScheduleEnable,
    /// TC[11,2] disable release.
    ScheduleDisable,
    /// TC[11,3] reset the schedule (empty, release disabled).
    ScheduleReset,
    /// TC[11,5] delete the activities sent with these sequence counts.
    ScheduleDelete {
        /// Sequence counts of the embedded telecommands.
        seq_counts: Vec<u16>,
    },
    /// TC[11,15] time-shift every activity.
    ScheduleShift {
        /// Offset (s, signed).
        by_s: f64,
    },
    /// TC[11,17] summary report.
    ScheduleReport,
    /// TC[9,1] time reports every 2^exponent s (`None`: off).
    TimeReportRate {
        /// N of 2^N s.
        exponent: Option<u8>,
    },
}

impl TcRequest {
    /// The command sequence.
    pub fn commands(&self) -> Result<Vec<Command>, String> {
        use crate::link::MemoryId;
        Ok(match self {
            TcRequest::Ping => vec![Command::Ping],
            TcRequest::Housekeeping => vec![Command::HousekeepingOneShot],
            TcRequest::Move {
                translation_um,
                rotation_arcsec,
                relative,
            } => {
                let p = wire_pose(*translation_um, *rotation_arcsec)?;
                vec![if *relative {
                    Command::MoveRelative(p)
                } else {
                    Command::MoveAbsolute(p)
                }]
            }
            TcRequest::DirectStroke { leg, delta_um } => {
                if !(1..=6).contains(leg) {
                    return Err(format!("leg {leg}: must be 1..6"));
                }
                let d = wire_pose([*delta_um, 0.0, 0.0], [0.0; 3])?;
                vec![Command::DirectStroke {
                    leg: *leg,
                    delta_nm: d.translation_nm[0],
                }]
            }
            TcRequest::Stop => vec![Command::Stop],
            TcRequest::ClearFault => vec![Command::ClearFault],
            TcRequest::Activate { table_id, crc32 } => vec![Command::ActivateTable {
                table_id: *table_id,
                crc32: *crc32,
            }],
            TcRequest::SwitchBank => vec![Command::SwitchBank],
            TcRequest::RevertToNominal => vec![Command::RevertToNominal],
            TcRequest::Upload {
                geometry,
                table_id,
                calibration_id,
                activate,
            } => {
                let table = table_from_geometry_file(geometry, *table_id, *calibration_id)?;
                let mut cmds = upload_commands(&table)?;
                if *activate {
                    cmds.push(activate_command(&table));
                }
                cmds
            }
            TcRequest::Dump { upload_buffer } => vec![Command::DumpTable(if *upload_buffer {
                MemoryId::UploadBuffer
            } else {
                MemoryId::ActiveTable
            })],
            TcRequest::Schedule { .. } => {
                return Err(
                    "a schedule insert is built by TcRequest::packets (it numbers \
                            the embedded telecommands); it cannot be scheduled itself"
                        .into(),
                )
            }
            TcRequest::ScheduleEnable => vec![Command::Schedule(ScheduleCommand::EnableRelease)],
            TcRequest::ScheduleDisable => {
                vec![Command::Schedule(ScheduleCommand::DisableRelease)]
            }
            TcRequest::ScheduleReset => vec![Command::Schedule(ScheduleCommand::Reset)],
            TcRequest::ScheduleDelete { seq_counts } => {
                let ids: Vec<RequestId> = seq_counts.iter().map(|s| request_id_of(*s)).collect();
                let list = RequestIdList::new(&ids).ok_or_else(|| {
                    format!(
                        "{} request IDs: a delete names 1..={}",
                        ids.len(),
                        crate::link::schedule::SCHEDULE_CAPACITY
                    )
                })?;
                vec![Command::Schedule(ScheduleCommand::Delete(list))]
            }
            TcRequest::ScheduleShift { by_s } => vec![Command::Schedule(
                ScheduleCommand::TimeShiftAll(offset_from_seconds(*by_s)?),
            )],
            TcRequest::ScheduleReport => vec![Command::Schedule(ScheduleCommand::SummaryReport)],
            TcRequest::TimeReportRate { exponent } => {
                let rate = match exponent {
                    None => TimeReportRate::Off,
                    Some(n) => TimeReportRate::from_code(*n)
                        .filter(|r| *r != TimeReportRate::Off)
                        .ok_or_else(|| {
                            format!(
                                "exponent {n}: 0..={}",
                                crate::link::time::MAX_TIME_REPORT_EXPONENT
                            )
                        })?,
                };
                vec![Command::SetTimeReportRate(rate)]
            }
        })
    }

    /// The PUS packets (unframed) of the request, numbered by `sequencer`; a schedule
    /// insert numbers its embedded telecommands first, then itself.
    pub fn packets(&self, sequencer: &mut TcSequencer) -> Result<Vec<Vec<u8>>, String> {
        let commands = match self {
            TcRequest::Schedule { release_s, what } => {
                let release = obt_from_seconds(*release_s)?;
                let activities: Vec<(TmTime, Command)> =
                    what.commands()?.into_iter().map(|c| (release, c)).collect();
                vec![sequencer.schedule_insert(&activities)?.0]
            }
            other => other.commands()?,
        };
        commands.iter().map(|c| sequencer.packet(c)).collect()
    }
}

/// Output of `m2ground tc`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TcOutput {
    /// One frame per line, lowercase hex.
    HexLines,
    /// The frames back to back, raw bytes (ready for the UART).
    Binary,
}

/// Runs `m2ground tc`: the bytes to write (hex text or binary).
pub fn run_tc(
    request: &TcRequest,
    sequencer: &mut TcSequencer,
    output: TcOutput,
    unframed: bool,
) -> Result<Vec<u8>, String> {
    let frames: Vec<Vec<u8>> = request
        .packets(sequencer)?
        .into_iter()
        .map(|p| if unframed { p } else { frame(&p) })
        .collect();
    Ok(match output {
        TcOutput::HexLines => hex_lines(&frames).into_bytes(),
        TcOutput::Binary => frames.concat(),
    })
}
