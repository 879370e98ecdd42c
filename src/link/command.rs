//! The decoded telecommand, the contract between the link and the controller, and the
//! byte layout of each telecommand's application data (parse and emit, big-endian).

use super::error::{sat_u16, LinkError};
use super::schedule::{ScheduleCommand, MAX_INSERT_APP_DATA_LEN};
use super::time::TimeReportRate;
use super::wire::{copy_prefix, Order, Reader, Writer};
use super::{service, subtype};
use crate::kinematics::{Pose, Real, LEGS};
use crate::table::TABLE_LEN;
use crate::units::{ARCSEC_PER_RAD, NM_PER_MM, UAS_PER_ARCSEC};

/// Largest table chunk in one TC[6,2] or TM[6,6] (bytes).
pub const TABLE_CHUNK_MAX_LEN: usize = 128;
/// Bytes of a pose on the wire: six i32.
pub const WIRE_POSE_LEN: usize = 24;
/// Bytes of a function ID (TC[8,1]).
pub const FUNCTION_ID_LEN: usize = 2;
/// Bytes of the TC[6,2] header before the data: memory ID u8, offset u16, length u16.
pub const MEMORY_LOAD_HEADER_LEN: usize = 5;
/// Largest application data of any telecommand (bytes): a TC[11,4] insert or a table
/// chunk, whichever is longer.
pub const MAX_TC_APP_DATA_LEN: usize = max_len(
    MEMORY_LOAD_HEADER_LEN + TABLE_CHUNK_MAX_LEN,
    MAX_INSERT_APP_DATA_LEN,
);

/// The larger of two lengths (for constants).
const fn max_len(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}
/// Bytes of a TC[20,3] count, and of one (ID u16, value i32) pair.
const PARAMETER_COUNT_LEN: usize = 1;
const PARAMETER_PAIR_LEN: usize = 6;
/// Bytes of one TC[20,1] parameter ID.
const PARAMETER_ID_LEN: usize = 2;
const _: () = assert!(
    PARAMETER_COUNT_LEN + PARAMETER_PAIR_LEN * MAX_PARAMETERS_PER_TC <= MAX_TC_APP_DATA_LEN
);

/// A pose on the wire: exact integers, big-endian i32 each, in the order
/// `x_nm, y_nm, z_nm, alpha_uas, beta_uas, gamma_uas` (in the operator's frames,
/// `kinematics::frames`: translation of the pivot from home along the user frame's axes
/// in nanometres, rotation `Q = Rz(gamma) Ry(beta) Rx(alpha)` in the user frame in
/// micro-arcseconds; with the default frames, M's origin from p0 along B's axes). Range: +-2.1 m, +-2147 arcsec.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WirePose {
    /// Translation x, y, z (nm).
    pub translation_nm: [i32; 3],
    /// Rotation alpha, beta, gamma (micro-arcseconds).
    pub rotation_uas: [i32; 3],
}

pub use super::wire::round_sat_i32;

impl WirePose {
    /// The pose in working units (mm, rad), converted once to `T`.
    pub fn to_pose<T: Real>(&self) -> Pose<T> {
        Pose::from_mm_arcsec(
            self.translation_nm.map(|v| f64::from(v) / NM_PER_MM),
            self.rotation_uas.map(|v| f64::from(v) / UAS_PER_ARCSEC),
        )
    }

    /// The nearest wire pose of a working pose (mm, rad); saturates at the i32 range,
    /// NaN gives 0 (telemetry never fails on a bad pose).
    pub fn from_pose<T: Real>(pose: &Pose<T>) -> WirePose {
        WirePose {
            translation_nm: pose
                .translation_mm
                .map(|v| round_sat_i32(v.to_f64() * NM_PER_MM)),
            rotation_uas: pose
                .rotation_rad
                .map(|v| round_sat_i32(v.to_f64() * ARCSEC_PER_RAD * UAS_PER_ARCSEC)),
        }
    }

    /// The six components in wire order.
    pub const fn to_array(&self) -> [i32; 6] {
        let t = self.translation_nm;
        let r = self.rotation_uas;
        [t[0], t[1], t[2], r[0], r[1], r[2]]
    }

    /// From six components in wire order.
    pub const fn from_array(v: [i32; 6]) -> WirePose {
        WirePose {
            translation_nm: [v[0], v[1], v[2]],
            rotation_uas: [v[3], v[4], v[5]],
        }
    }
}

/// Memory areas of service 6.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemoryId {
    /// The inactive table buffer in RAM that uploads fill (load and dump).
    UploadBuffer,
    /// The active parameter table (dump only).
    ActiveTable,
}

impl MemoryId {
    /// Wire value.
    pub const fn code(self) -> u8 {
        match self {
            MemoryId::UploadBuffer => 1,
            MemoryId::ActiveTable => 2,
        }
    }

    /// From the wire value.
    pub const fn from_code(code: u8) -> Option<MemoryId> {
        match code {
            1 => Some(MemoryId::UploadBuffer),
            2 => Some(MemoryId::ActiveTable),
            _ => None,
        }
    }
}

/// One chunk of a table upload: `len` bytes for offsets `offset..offset + len` of the
/// encoded table ([`TABLE_LEN`] bytes). Always `1 <= len <= TABLE_CHUNK_MAX_LEN` and
/// `offset + len <= TABLE_LEN` (checked when built or parsed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TableChunk {
    offset: u16,
    len: u8,
    data: [u8; TABLE_CHUNK_MAX_LEN],
}

impl TableChunk {
    /// A chunk of `bytes` at table offset `offset_bytes`; refused if empty, longer than
    /// [`TABLE_CHUNK_MAX_LEN`] or reaching past the table.
    pub fn new(offset_bytes: u16, bytes: &[u8]) -> Result<TableChunk, LinkError> {
        let refused = LinkError::ChunkOutOfRange {
            offset: offset_bytes,
            length: sat_u16(bytes.len()),
        };
        let end = usize::from(offset_bytes).saturating_add(bytes.len());
        if bytes.is_empty() || bytes.len() > TABLE_CHUNK_MAX_LEN || end > TABLE_LEN {
            return Err(refused);
        }
        let mut data = [0u8; TABLE_CHUNK_MAX_LEN];
        copy_prefix(&mut data, bytes).ok_or(refused)?;
        Ok(TableChunk {
            offset: offset_bytes,
            len: u8::try_from(bytes.len()).map_err(|_| refused)?,
            data,
        })
    }

    /// Offset of the chunk in the encoded table (bytes).
    pub const fn offset_bytes(&self) -> u16 {
        self.offset
    }

    /// The chunk's bytes.
    pub fn bytes(&self) -> &[u8] {
        self.data.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// The table offsets the chunk covers.
    pub fn range(&self) -> core::ops::Range<usize> {
        let start = usize::from(self.offset);
        start..start + usize::from(self.len)
    }
}

/// Most parameters named by one TC[20,1] or TC[20,3].
pub const MAX_PARAMETERS_PER_TC: usize = 16;

/// The parameter IDs of a TC[20,1]: a count u8 (1..=16), then that many IDs u16.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParameterIds {
    len: u8,
    ids: [u16; MAX_PARAMETERS_PER_TC],
}

impl ParameterIds {
    /// From a list (1..=16 IDs).
    pub fn new(ids: &[u16]) -> Result<Self, LinkError> {
        let mut out = Self {
            len: 0,
            ids: [0; MAX_PARAMETERS_PER_TC],
        };
        if ids.is_empty() || ids.len() > MAX_PARAMETERS_PER_TC {
            return Err(LinkError::InvalidArgument { index: 0 });
        }
        for (d, s) in out.ids.iter_mut().zip(ids) {
            *d = *s;
        }
        out.len = ids.len() as u8;
        Ok(out)
    }

    /// The IDs.
    pub fn ids(&self) -> &[u16] {
        self.ids.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// Parsed in place: `parameter_count` has checked the count (1..=16) and the length,
    /// so the list is built directly (no second copy through [`ParameterIds::new`]).
    fn parse(app_data: &[u8]) -> Result<Self, LinkError> {
        let (mut r, n) = parameter_count(app_data, PARAMETER_ID_LEN)?;
        let mut out = Self {
            len: n as u8,
            ids: [0; MAX_PARAMETERS_PER_TC],
        };
        for id in out.ids.iter_mut().take(n) {
            *id = r.u16().ok_or(LinkError::InvalidArgument { index: 1 })?;
        }
        Ok(out)
    }
}

/// The (ID, value) pairs of a TC[20,3]: a count u8 (1..=16), then that many (ID u16,
/// value i32).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParameterValues {
    len: u8,
    entries: [(u16, i32); MAX_PARAMETERS_PER_TC],
}

impl ParameterValues {
    /// From a list (1..=16 pairs).
    pub fn new(entries: &[(u16, i32)]) -> Result<Self, LinkError> {
        let mut out = Self {
            len: 0,
            entries: [(0, 0); MAX_PARAMETERS_PER_TC],
        };
        if entries.is_empty() || entries.len() > MAX_PARAMETERS_PER_TC {
            return Err(LinkError::InvalidArgument { index: 0 });
        }
        for (d, s) in out.entries.iter_mut().zip(entries) {
            *d = *s;
        }
        out.len = entries.len() as u8;
        Ok(out)
    }

    /// The pairs.
    pub fn entries(&self) -> &[(u16, i32)] {
        self.entries.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// Parsed in place, as [`ParameterIds`]'s list.
    fn parse(app_data: &[u8]) -> Result<Self, LinkError> {
        let (mut r, n) = parameter_count(app_data, PARAMETER_PAIR_LEN)?;
        let mut out = Self {
            len: n as u8,
            entries: [(0, 0); MAX_PARAMETERS_PER_TC],
        };
        for e in out.entries.iter_mut().take(n) {
            let (Some(id), Some(v)) = (r.u16(), r.i32()) else {
                return Err(LinkError::InvalidArgument { index: 1 });
            };
            *e = (id, v);
        }
        Ok(out)
    }
}

/// The count u8 (1..=16) that opens a TC[20,1] or TC[20,3], checked against the
/// application data length for `entry_len` bytes an entry: the reader past the count and
/// the count.
fn parameter_count(app_data: &[u8], entry_len: usize) -> Result<(Reader<'_>, usize), LinkError> {
    let mut r = Reader::new(app_data, Order::Big);
    let n = usize::from(r.u8().ok_or(LinkError::AppDataLength {
        got: sat_u16(app_data.len()),
        expected: 1,
    })?);
    if n == 0 || n > MAX_PARAMETERS_PER_TC {
        return Err(LinkError::InvalidArgument { index: 0 });
    }
    expect_len(app_data, PARAMETER_COUNT_LEN + entry_len * n)?;
    Ok((r, n))
}

/// Function IDs of TC[8,1] (u16, big-endian, first two bytes of the application data).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u16)]
pub enum FunctionId {
    /// Move to an absolute pose. Args: [`WirePose`].
    MoveAbsolute = 0x0001,
    /// Move by a pose increment relative to the commanded pose. Args: [`WirePose`].
    MoveRelative = 0x0002,
    /// Stop any motion (ramp down). No args.
    Stop = 0x0003,
    /// Clear latched faults. No args.
    ClearFault = 0x0004,
    /// Move one slider by a stroke increment (recovery). Args: leg u8 (1..6), delta i32 nm.
    DirectStroke = 0x0005,
    /// Check a move without moving: every refusal reason for the target and the straight
    /// path, answered by TM[8,130]. Args: [`WirePose`] (absolute, operator frames).
    CheckMove = 0x0006,
    /// Commit the uploaded table. Args: CRC-32 u32 of the whole encoded table.
    CommitTable = 0x0010,
    /// Activate the pending (committed, validated) table. Args: the expected table ID
    /// u32 and CRC-32 u32; refused unless they are the pending table's.
    ActivateTable = 0x0011,
    /// Switch to the table of the other flash bank (validated first). No args.
    SwitchBank = 0x0012,
    /// Revert to the compiled-in nominal table. No args.
    RevertToNominal = 0x0013,
    /// The camera is exposing: hold every compensation step and every scheduled motion,
    /// refuse operator moves, for this long. Args: timeout u16 (s,
    /// 0..=[`MAX_EXPOSURE_HOLD_S`]; 0 ends the hold the telecommand set).
    ExposureHold = 0x0007,
}

/// Longest exposure hold (s): one hour, longer than any exposure, so that a hold the
/// camera never ends still times out.
pub const MAX_EXPOSURE_HOLD_S: u16 = 3_600;

impl FunctionId {
    /// Every function ID.
    pub const ALL: [FunctionId; 11] = [
        FunctionId::MoveAbsolute,
        FunctionId::MoveRelative,
        FunctionId::Stop,
        FunctionId::ClearFault,
        FunctionId::DirectStroke,
        FunctionId::CheckMove,
        FunctionId::ExposureHold,
        FunctionId::CommitTable,
        FunctionId::ActivateTable,
        FunctionId::SwitchBank,
        FunctionId::RevertToNominal,
    ];

    /// Wire value.
    pub const fn code(self) -> u16 {
        self as u16
    }

    /// From the wire value.
    pub fn from_code(code: u16) -> Option<FunctionId> {
        FunctionId::ALL.iter().copied().find(|f| f.code() == code)
    }

    /// Bytes of arguments after the function ID.
    pub const fn args_len(self) -> usize {
        match self {
            FunctionId::MoveAbsolute | FunctionId::MoveRelative | FunctionId::CheckMove => {
                WIRE_POSE_LEN
            }
            FunctionId::DirectStroke => 1 + 4,
            FunctionId::CommitTable => 4,
            FunctionId::ActivateTable => 4 + 4,
            FunctionId::ExposureHold => 2,
            FunctionId::Stop
            | FunctionId::ClearFault
            | FunctionId::SwitchBank
            | FunctionId::RevertToNominal => 0,
        }
    }
}

/// A telecommand the controller executes (decoded and checked for format and ranges; the
/// controller judges it against its state, e.g. the workspace check of a move).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// TC[17,1]: answer with TM[17,2].
    Ping,
    /// TC[3,27]: send one housekeeping report TM[3,25] now.
    HousekeepingOneShot,
    /// TC[8,1] fn 0x0001: move to this absolute pose (all-or-nothing workspace check).
    MoveAbsolute(WirePose),
    /// TC[8,1] fn 0x0002: move by this increment from the commanded pose.
    MoveRelative(WirePose),
    /// TC[8,1] fn 0x0003: stop any motion.
    Stop,
    /// TC[8,1] fn 0x0004: clear latched faults.
    ClearFault,
    /// TC[8,1] fn 0x0005: move one slider by a stroke increment (recovery).
    DirectStroke {
        /// Leg number, 1..=6.
        leg: u8,
        /// Stroke increment (nm, along base z).
        delta_nm: i32,
    },
    /// TC[8,1] fn 0x0010: commit the upload buffer; the controller checks the CRC-32 over
    /// the whole encoded table, decodes, validates and stores it in the inactive bank.
    CommitTable {
        /// Expected CRC-32 (ISO-HDLC) of the first `TABLE_LEN - 4` bytes, which is also
        /// the value in the table's last four bytes.
        crc32: u32,
    },
    /// TC[8,1] fn 0x0011: activate the pending table (between motions only), which
    /// must be the one named.
    ActivateTable {
        /// Expected table ID of the pending table.
        table_id: u32,
        /// Expected CRC-32 of the pending table.
        crc32: u32,
    },
    /// TC[8,1] fn 0x0012: switch to the other bank's table.
    SwitchBank,
    /// TC[8,1] fn 0x0013: revert to the compiled-in nominal table.
    RevertToNominal,
    /// TC[8,1] fn 0x0006: check a move to this pose without moving (TM[8,130]).
    CheckMove(WirePose),
    /// TC[8,1] fn 0x0007: the exposure hold for `timeout_s` seconds (0 ends it).
    ExposureHold {
        /// The hold's timeout (s), 0..=[`MAX_EXPOSURE_HOLD_S`].
        timeout_s: u16,
    },
    /// TC[20,1]: report these parameters (TM[20,2]).
    ReportParameters(ParameterIds),
    /// TC[20,3]: set these parameters (all or none; at rest only).
    SetParameters(ParameterValues),
    /// TC[6,2]: one chunk into the upload buffer.
    LoadTableChunk(TableChunk),
    /// TC[6,5]: dump a memory area as TM[6,6] chunks.
    DumpTable(MemoryId),
    /// TC[11,x]: the time-based schedule (insert, delete, time-shift, enable, disable,
    /// reset, summary report; `link::schedule`).
    Schedule(ScheduleCommand),
    /// TC[9,1]: set the time report (TM[9,2]) generation rate (`link::time`).
    SetTimeReportRate(TimeReportRate),
}

/// Exact application-data length check.
pub(super) fn expect_len(app_data: &[u8], expected: usize) -> Result<(), LinkError> {
    if app_data.len() == expected {
        Ok(())
    } else {
        Err(LinkError::AppDataLength {
            got: sat_u16(app_data.len()),
            expected: sat_u16(expected),
        })
    }
}

impl Command {
    /// PUS service and subtype of the telecommand carrying this command.
    pub const fn message_type(&self) -> (u8, u8) {
        match self {
            Command::Ping => (service::TEST, subtype::PING),
            Command::HousekeepingOneShot => (service::HOUSEKEEPING, subtype::HK_ONE_SHOT),
            Command::LoadTableChunk(_) => (service::MEMORY, subtype::MEMORY_LOAD),
            Command::DumpTable(_) => (service::MEMORY, subtype::MEMORY_DUMP),
            Command::ReportParameters(_) => (service::PARAMETER, subtype::PARAMETER_REPORT_REQUEST),
            Command::SetParameters(_) => (service::PARAMETER, subtype::PARAMETER_SET),
            Command::Schedule(s) => (service::SCHEDULING, s.subtype()),
            Command::SetTimeReportRate(_) => (service::TIME, subtype::SET_TIME_REPORT_RATE),
            _ => (service::FUNCTION, subtype::PERFORM_FUNCTION),
        }
    }

    /// The function ID of a TC[8,1] command.
    pub const fn function_id(&self) -> Option<FunctionId> {
        match self {
            Command::MoveAbsolute(_) => Some(FunctionId::MoveAbsolute),
            Command::MoveRelative(_) => Some(FunctionId::MoveRelative),
            Command::Stop => Some(FunctionId::Stop),
            Command::ClearFault => Some(FunctionId::ClearFault),
            Command::DirectStroke { .. } => Some(FunctionId::DirectStroke),
            Command::CheckMove(_) => Some(FunctionId::CheckMove),
            Command::CommitTable { .. } => Some(FunctionId::CommitTable),
            Command::ActivateTable { .. } => Some(FunctionId::ActivateTable),
            Command::SwitchBank => Some(FunctionId::SwitchBank),
            Command::RevertToNominal => Some(FunctionId::RevertToNominal),
            Command::ExposureHold { .. } => Some(FunctionId::ExposureHold),
            Command::Ping
            | Command::HousekeepingOneShot
            | Command::LoadTableChunk(_)
            | Command::DumpTable(_)
            | Command::ReportParameters(_)
            | Command::SetParameters(_) => None,
            Command::Schedule(_) | Command::SetTimeReportRate(_) => None,
        }
    }

    /// Checked parse of the application data of telecommand `[service, subtype]`.
    pub fn parse(service: u8, subtype: u8, app_data: &[u8]) -> Result<Command, LinkError> {
        if service == service::SCHEDULING {
            // The embedded telecommands of a TC[11,4] are parsed by `parse_plain`: no
            // path leads back here (no recursion, no TC[11,x] inside a TC[11,x]).
            return ScheduleCommand::parse(subtype, app_data).map(Command::Schedule);
        }
        Command::parse_plain(service, subtype, app_data)
    }

    /// [`Command::parse`] of every service but 11 (time-based scheduling).
    pub(super) fn parse_plain(
        service: u8,
        subtype: u8,
        app_data: &[u8],
    ) -> Result<Command, LinkError> {
        let unknown_subtype = LinkError::UnknownSubtype { service, subtype };
        match service {
            service::TEST => {
                if subtype != subtype::PING {
                    return Err(unknown_subtype);
                }
                expect_len(app_data, 0)?;
                Ok(Command::Ping)
            }
            service::HOUSEKEEPING => {
                if subtype != subtype::HK_ONE_SHOT {
                    return Err(unknown_subtype);
                }
                expect_len(app_data, 0)?;
                Ok(Command::HousekeepingOneShot)
            }
            service::MEMORY => match subtype {
                subtype::MEMORY_LOAD => parse_memory_load(app_data),
                subtype::MEMORY_DUMP => {
                    expect_len(app_data, 1)?;
                    let code = app_data.first().copied().unwrap_or(0);
                    MemoryId::from_code(code)
                        .map(Command::DumpTable)
                        .ok_or(LinkError::InvalidArgument { index: 0 })
                }
                _ => Err(unknown_subtype),
            },
            service::FUNCTION => {
                if subtype != subtype::PERFORM_FUNCTION {
                    return Err(unknown_subtype);
                }
                parse_function(app_data)
            }
            service::PARAMETER => match subtype {
                subtype::PARAMETER_REPORT_REQUEST => {
                    ParameterIds::parse(app_data).map(Command::ReportParameters)
                }
                subtype::PARAMETER_SET => {
                    ParameterValues::parse(app_data).map(Command::SetParameters)
                }
                _ => Err(unknown_subtype),
            },
            service::TIME => {
                if subtype != subtype::SET_TIME_REPORT_RATE {
                    return Err(unknown_subtype);
                }
                TimeReportRate::parse(app_data).map(Command::SetTimeReportRate)
            }
            _ => Err(LinkError::UnknownService { service }),
        }
    }

    /// Writes the application data into `out`; returns its length, or `None` if `out` is
    /// shorter than [`MAX_TC_APP_DATA_LEN`] needs for this command.
    pub fn emit_app_data(&self, out: &mut [u8]) -> Option<usize> {
        let mut w = Writer::new(out, Order::Big);
        match self {
            Command::Ping | Command::HousekeepingOneShot => {}
            Command::LoadTableChunk(chunk) => {
                w.u8(MemoryId::UploadBuffer.code())?;
                w.u16(chunk.offset_bytes())?;
                w.u16(sat_u16(chunk.bytes().len()))?;
                w.put(chunk.bytes())?;
            }
            Command::DumpTable(memory) => w.u8(memory.code())?,
            Command::ReportParameters(ids) => {
                w.u8(ids.len)?;
                for id in ids.ids() {
                    w.u16(*id)?;
                }
            }
            Command::SetParameters(values) => {
                w.u8(values.len)?;
                for (id, v) in values.entries() {
                    w.u16(*id)?;
                    w.i32(*v)?;
                }
            }
            Command::Schedule(s) => s.emit(&mut w)?,
            Command::SetTimeReportRate(rate) => rate.emit(&mut w)?,
            _ => {
                let f = self.function_id()?;
                w.u16(f.code())?;
                match self {
                    Command::MoveAbsolute(p) | Command::MoveRelative(p) | Command::CheckMove(p) => {
                        w.pose(p)?
                    }
                    Command::DirectStroke { leg, delta_nm } => {
                        w.u8(*leg)?;
                        w.i32(*delta_nm)?;
                    }
                    Command::CommitTable { crc32 } => w.u32(*crc32)?,
                    Command::ExposureHold { timeout_s } => w.u16(*timeout_s)?,
                    Command::ActivateTable { table_id, crc32 } => {
                        w.u32(*table_id)?;
                        w.u32(*crc32)?;
                    }
                    _ => {}
                }
            }
        }
        Some(w.position())
    }
}

/// TC[6,2]: memory ID u8 (1), offset u16, length u16, `length` bytes.
fn parse_memory_load(app_data: &[u8]) -> Result<Command, LinkError> {
    let short = LinkError::AppDataLength {
        got: sat_u16(app_data.len()),
        expected: sat_u16(MEMORY_LOAD_HEADER_LEN),
    };
    let mut r = Reader::new(app_data, Order::Big);
    let (Some(memory), Some(offset), Some(length)) = (r.u8(), r.u16(), r.u16()) else {
        return Err(short);
    };
    expect_len(
        app_data,
        MEMORY_LOAD_HEADER_LEN.saturating_add(usize::from(length)),
    )?;
    if MemoryId::from_code(memory) != Some(MemoryId::UploadBuffer) {
        return Err(LinkError::InvalidArgument { index: 0 });
    }
    let data = app_data.get(MEMORY_LOAD_HEADER_LEN..).ok_or(short)?;
    TableChunk::new(offset, data).map(Command::LoadTableChunk)
}

/// TC[8,1]: function ID u16, then the function's arguments.
fn parse_function(app_data: &[u8]) -> Result<Command, LinkError> {
    let id = Reader::new(app_data, Order::Big)
        .u16()
        .ok_or(LinkError::AppDataLength {
            got: sat_u16(app_data.len()),
            expected: sat_u16(FUNCTION_ID_LEN),
        })?;
    let f = FunctionId::from_code(id).ok_or(LinkError::UnknownFunction { function_id: id })?;
    expect_len(app_data, FUNCTION_ID_LEN + f.args_len())?;
    let args = app_data.get(FUNCTION_ID_LEN..).unwrap_or(&[]);
    // The length is exact (checked above): the reads below cannot run short; a short
    // read would still be a refusal, never a panic.
    let mut r = Reader::new(args, Order::Big);
    let arg = |v: Option<u32>, index: u8| v.ok_or(LinkError::InvalidArgument { index });
    let pose = |r: &mut Reader<'_>| r.pose().ok_or(LinkError::InvalidArgument { index: 0 });
    Ok(match f {
        FunctionId::MoveAbsolute => Command::MoveAbsolute(pose(&mut r)?),
        FunctionId::MoveRelative => Command::MoveRelative(pose(&mut r)?),
        FunctionId::CheckMove => Command::CheckMove(pose(&mut r)?),
        FunctionId::Stop => Command::Stop,
        FunctionId::ClearFault => Command::ClearFault,
        FunctionId::DirectStroke => {
            let leg = r.u8().unwrap_or(0);
            if leg == 0 || usize::from(leg) > LEGS {
                return Err(LinkError::InvalidArgument { index: 0 });
            }
            Command::DirectStroke {
                leg,
                delta_nm: r.i32().ok_or(LinkError::InvalidArgument { index: 1 })?,
            }
        }
        FunctionId::CommitTable => Command::CommitTable {
            crc32: arg(r.u32(), 0)?,
        },
        FunctionId::ActivateTable => Command::ActivateTable {
            table_id: arg(r.u32(), 0)?,
            crc32: arg(r.u32(), 1)?,
        },
        FunctionId::SwitchBank => Command::SwitchBank,
        FunctionId::RevertToNominal => Command::RevertToNominal,
        FunctionId::ExposureHold => match r.u16() {
            Some(timeout_s) if timeout_s <= MAX_EXPOSURE_HOLD_S => {
                Command::ExposureHold { timeout_s }
            }
            _ => return Err(LinkError::InvalidArgument { index: 0 }),
        },
    })
}
