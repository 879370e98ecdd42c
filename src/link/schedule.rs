//! PUS ST[11] time-based scheduling on the wire: the telecommands TC[11,1], [11,2],
//! [11,3], [11,4], [11,5], [11,15], [11,17] ([`ScheduleCommand`], parse and emit) and
//! the layout of the summary report TM[11,13] ([`SummaryEntry`]). Subtype numbers come
//! from `spacepackets::ecss::scheduling::MessageSubtypeId` (`super::subtype`).
//!
//! Layouts (big-endian; times are CUC 4+2 on-board time, [`TmTime`]):
//! * TC[11,4] insert: N u8 (1..), then N times: release time (6 bytes), the embedded
//!   telecommand packet (its own CCSDS length field delimits it; at most
//!   [`MAX_SCHEDULED_TC_LEN`] bytes). At most [`MAX_INSERT_APP_DATA_LEN`] bytes in all.
//!   Each embedded packet is checked as a telecommand of this controller (every check
//!   of `tc::decode_telecommand`); a TC[11,x] or a table chunk TC[6,2] inside cannot be
//!   scheduled (embedded code 0x0510).
//! * TC[11,5] delete: N u8 (1..=[`SCHEDULE_CAPACITY`]), then N request IDs (4 bytes:
//!   the first four bytes of the embedded telecommand).
//! * TC[11,15] time-shift all: offset (6 bytes): seconds i32, fraction u16; the offset
//!   is `seconds + fraction / 65536` s (a 48-bit two's complement count of 1/65536 s).
//! * TC[11,1], [11,2], [11,3], [11,17]: no application data.
//! * TM[11,13]: N u8, then N times: release time (6 bytes), request ID (4 bytes), in
//!   release order.
//!
//! Checks here are of format only (acceptance, TM[1,2]); what the schedule holds (room,
//! release times not in the past, unique request IDs) is checked when the telecommand
//! executes (`controller::schedule`, TM[1,4]).

use super::command::{expect_len, Command};
use super::error::{sat_u16, LinkError};
use super::tc::{RequestId, TcPacket, REQUEST_ID_LEN};
use super::tm::TmTime;
use super::wire::{copy_prefix, Order, Reader, Writer};
use super::{
    service, subtype, CCSDS_PRIMARY_HEADER_LEN, DATA_LEN_FIELD_OFFSET, DATA_LEN_OFFSET,
    TM_TIMESTAMP_LEN,
};

/// Activities the on-board schedule holds.
pub const SCHEDULE_CAPACITY: usize = 16;
/// Largest embedded telecommand of an activity (bytes, whole packet): a schedule slot.
/// A move is 39 bytes. Table chunks (TC[6,2]) cannot be scheduled at any length.
pub const MAX_SCHEDULED_TC_LEN: usize = 64;
/// Largest application data of a TC[11,4] (bytes): three moves (136 bytes) with room for
/// longer embedded commands; bounded so that [`Command`] stays small (it is copied on
/// the link service's stack). More activities take several TC[11,4].
pub const MAX_INSERT_APP_DATA_LEN: usize = 160;
/// Bytes of the activity count N (TC[11,4], TC[11,5], TM[11,13]).
pub const ACTIVITY_COUNT_LEN: usize = 1;
/// Bytes of a release time or a time offset (CUC 4+2).
pub const RELEASE_TIME_LEN: usize = TM_TIMESTAMP_LEN;
/// Bytes of one TM[11,13] entry: release time, request ID.
pub const SUMMARY_ENTRY_LEN: usize = RELEASE_TIME_LEN + REQUEST_ID_LEN;
/// Largest TM[11,13] source data (bytes): a full schedule.
pub const MAX_SUMMARY_LEN: usize = ACTIVITY_COUNT_LEN + SCHEDULE_CAPACITY * SUMMARY_ENTRY_LEN;

/// A signed time offset of TC[11,15], in 1/65536 s (48-bit range on the wire).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ObtOffset {
    ticks: i64,
}

/// Fractions of a second of the CUC code.
const TICKS_PER_SECOND: i64 = 1 << 16;

impl ObtOffset {
    /// From its wire parts: `seconds + fraction / 65536` s.
    pub const fn from_parts(seconds: i32, fraction: u16) -> ObtOffset {
        ObtOffset {
            ticks: seconds as i64 * TICKS_PER_SECOND + fraction as i64,
        }
    }

    /// Its wire parts (seconds = the floor, fraction = the rest).
    pub const fn to_parts(self) -> (i32, u16) {
        (
            self.ticks.div_euclid(TICKS_PER_SECOND) as i32,
            self.ticks.rem_euclid(TICKS_PER_SECOND) as u16,
        )
    }

    /// The offset in 1/65536 s.
    pub const fn ticks(self) -> i64 {
        self.ticks
    }

    /// From a count of 1/65536 s; `None` beyond the wire's range (i32 seconds).
    pub const fn from_ticks(ticks: i64) -> Option<ObtOffset> {
        let min = i32::MIN as i64 * TICKS_PER_SECOND;
        let max = i32::MAX as i64 * TICKS_PER_SECOND + (TICKS_PER_SECOND - 1);
        if ticks < min || ticks > max {
            None
        } else {
            Some(ObtOffset { ticks })
        }
    }
}

/// The validated application data of a TC[11,4]: N activities, each a release time and
/// an embedded telecommand packet (module documentation). Built only by
/// [`ActivityBlock::parse`] or [`ActivityBlock::new`], so its content always passed
/// the checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ActivityBlock {
    len: u8,
    bytes: [u8; MAX_INSERT_APP_DATA_LEN],
}

/// One activity of a TC[11,4]: when, and what.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimeTagged<'a> {
    /// Release time (on-board time).
    pub release: TmTime,
    /// The embedded telecommand packet (checked).
    pub packet: &'a [u8],
}

impl TimeTagged<'_> {
    /// The request ID of the embedded telecommand (its first four bytes).
    pub fn request_id(&self) -> RequestId {
        RequestId::from_packet(self.packet).unwrap_or_default()
    }
}

/// Length of the packet at the start of `rest` from its CCSDS length field, checked
/// against the bytes there and the schedule slot (the embedded packet's own link code
/// on failure).
fn embedded_len(rest: &[u8]) -> Result<usize, LinkError> {
    let truncated = LinkError::Truncated {
        got: sat_u16(rest.len()),
        needed: sat_u16(CCSDS_PRIMARY_HEADER_LEN),
    };
    let data_len = rest
        .get(DATA_LEN_FIELD_OFFSET..)
        .and_then(|b| Reader::new(b, Order::Big).u16())
        .ok_or(truncated)?;
    let declared = usize::from(data_len) + DATA_LEN_OFFSET;
    if declared > MAX_SCHEDULED_TC_LEN {
        return Err(LinkError::Oversized);
    }
    if declared > rest.len() {
        return Err(LinkError::Truncated {
            got: sat_u16(rest.len()),
            needed: sat_u16(declared),
        });
    }
    Ok(declared)
}

/// Every check of a received telecommand on an embedded packet, then whether it may be
/// scheduled: not ST[11] itself, not a table chunk TC[6,2] (an upload is interactive:
/// its chunks, commit and CRC belong together, and a chunk released later could land
/// in another upload).
fn check_embedded(packet: &[u8]) -> Result<(), LinkError> {
    let tc = TcPacket::new_checked(packet)?;
    let command = Command::parse_plain(tc.service(), tc.subtype(), tc.app_data());
    if tc.service() == service::SCHEDULING || matches!(command, Ok(Command::LoadTableChunk(_))) {
        return Err(LinkError::NotSchedulable {
            service: tc.service(),
            subtype: tc.subtype(),
        });
    }
    command.map(|_| ())
}

impl ActivityBlock {
    /// Checked parse of a TC[11,4]'s application data (module documentation).
    pub fn parse(app_data: &[u8]) -> Result<ActivityBlock, LinkError> {
        let got = sat_u16(app_data.len());
        if app_data.len() > MAX_INSERT_APP_DATA_LEN {
            return Err(LinkError::AppDataLength {
                got,
                expected: sat_u16(MAX_INSERT_APP_DATA_LEN),
            });
        }
        let mut r = Reader::new(app_data, Order::Big);
        let n = r.u8().ok_or(LinkError::AppDataLength {
            got,
            expected: sat_u16(ACTIVITY_COUNT_LEN),
        })?;
        if n == 0 {
            return Err(LinkError::InvalidArgument { index: 0 });
        }
        for index in 0..n {
            let short = LinkError::AppDataLength {
                got,
                expected: sat_u16(r.position() + RELEASE_TIME_LEN),
            };
            r.take::<RELEASE_TIME_LEN>().ok_or(short)?;
            let embedded = |code: u16| LinkError::EmbeddedTc { index, code };
            let len = embedded_len(r.remaining()).map_err(|e| embedded(e.code()))?;
            let packet = r.bytes(len).ok_or(embedded(LinkError::Oversized.code()))?;
            check_embedded(packet).map_err(|e| embedded(e.code()))?;
        }
        if !r.remaining().is_empty() {
            return Err(LinkError::AppDataLength {
                got,
                expected: sat_u16(r.position()),
            });
        }
        let mut bytes = [0u8; MAX_INSERT_APP_DATA_LEN];
        copy_prefix(&mut bytes, app_data).ok_or(LinkError::Oversized)?;
        Ok(ActivityBlock {
            len: u8::try_from(app_data.len()).map_err(|_| LinkError::Oversized)?,
            bytes,
        })
    }

    /// The block of these activities (ground side), checked as [`ActivityBlock::parse`]
    /// checks it.
    pub fn new(activities: &[(TmTime, &[u8])]) -> Result<ActivityBlock, LinkError> {
        let mut buf = [0u8; MAX_INSERT_APP_DATA_LEN];
        let too_long = LinkError::AppDataLength {
            got: sat_u16(
                activities
                    .iter()
                    .map(|(_, p)| RELEASE_TIME_LEN + p.len())
                    .sum::<usize>()
                    + ACTIVITY_COUNT_LEN,
            ),
            expected: sat_u16(MAX_INSERT_APP_DATA_LEN),
        };
        let mut w = Writer::new(&mut buf, Order::Big);
        let n = u8::try_from(activities.len()).map_err(|_| too_long)?;
        w.u8(n).ok_or(too_long)?;
        for (release, packet) in activities {
            w.put(&release.to_bytes()).ok_or(too_long)?;
            w.put(packet).ok_or(too_long)?;
        }
        let len = w.position();
        ActivityBlock::parse(buf.get(..len).ok_or(too_long)?)
    }

    /// The application data.
    pub fn bytes(&self) -> &[u8] {
        self.bytes.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// Number of activities (N).
    pub fn count(&self) -> usize {
        usize::from(self.bytes.first().copied().unwrap_or(0))
    }

    /// The activities in TC order.
    pub fn activities(&self) -> impl Iterator<Item = TimeTagged<'_>> {
        let mut r = Reader::new(self.bytes(), Order::Big);
        let n = r.u8().unwrap_or(0);
        // The block was checked when built: every read succeeds; a short one ends the
        // walk (never a panic).
        (0..n).map_while(move |_| {
            let release = TmTime::from_bytes(r.take()?);
            let len = embedded_len(r.remaining()).ok()?;
            Some(TimeTagged {
                release,
                packet: r.bytes(len)?,
            })
        })
    }
}

/// The request IDs of a TC[11,5] (1..=[`SCHEDULE_CAPACITY`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RequestIdList {
    len: u8,
    ids: [RequestId; SCHEDULE_CAPACITY],
}

impl RequestIdList {
    /// A list of these IDs; `None` if empty or longer than the schedule.
    pub fn new(ids: &[RequestId]) -> Option<RequestIdList> {
        if ids.is_empty() || ids.len() > SCHEDULE_CAPACITY {
            return None;
        }
        let mut out = [RequestId::default(); SCHEDULE_CAPACITY];
        copy_prefix(&mut out, ids)?;
        Some(RequestIdList {
            len: u8::try_from(ids.len()).ok()?,
            ids: out,
        })
    }

    /// The IDs, in TC order.
    pub fn as_slice(&self) -> &[RequestId] {
        self.ids.get(..usize::from(self.len)).unwrap_or(&[])
    }

    fn parse(app_data: &[u8]) -> Result<RequestIdList, LinkError> {
        let got = sat_u16(app_data.len());
        let mut r = Reader::new(app_data, Order::Big);
        let n = r.u8().ok_or(LinkError::AppDataLength {
            got,
            expected: sat_u16(ACTIVITY_COUNT_LEN),
        })?;
        if n == 0 || usize::from(n) > SCHEDULE_CAPACITY {
            return Err(LinkError::InvalidArgument { index: 0 });
        }
        expect_len(
            app_data,
            ACTIVITY_COUNT_LEN + usize::from(n) * REQUEST_ID_LEN,
        )?;
        let mut ids = [RequestId::default(); SCHEDULE_CAPACITY];
        for id in ids.iter_mut().take(usize::from(n)) {
            *id = RequestId::from_bytes(r.take().ok_or(LinkError::InvalidArgument { index: 1 })?);
        }
        Ok(RequestIdList { len: n, ids })
    }
}

/// A TC[11,x] (module documentation for the layouts).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScheduleCommand {
    /// TC[11,1]: release activities when their time comes.
    EnableRelease,
    /// TC[11,2]: release nothing (activities stay in the schedule).
    DisableRelease,
    /// TC[11,3]: delete every activity; release disabled afterwards.
    Reset,
    /// TC[11,4]: insert these activities (all or none).
    Insert(ActivityBlock),
    /// TC[11,5]: delete the activities with these request IDs (all or none).
    Delete(RequestIdList),
    /// TC[11,15]: move every release time by this offset (all or none).
    TimeShiftAll(ObtOffset),
    /// TC[11,17]: report every activity in a TM[11,13].
    SummaryReport,
}

impl ScheduleCommand {
    /// PUS subtype.
    pub const fn subtype(&self) -> u8 {
        match self {
            ScheduleCommand::EnableRelease => subtype::SCHEDULE_ENABLE,
            ScheduleCommand::DisableRelease => subtype::SCHEDULE_DISABLE,
            ScheduleCommand::Reset => subtype::SCHEDULE_RESET,
            ScheduleCommand::Insert(_) => subtype::SCHEDULE_INSERT,
            ScheduleCommand::Delete(_) => subtype::SCHEDULE_DELETE,
            ScheduleCommand::TimeShiftAll(_) => subtype::SCHEDULE_TIME_SHIFT_ALL,
            ScheduleCommand::SummaryReport => subtype::SCHEDULE_SUMMARY_ALL,
        }
    }

    /// Checked parse of a TC[11,`subtype`]'s application data. Out of line: inlined
    /// into the telecommand decoder, its results were copied per subtype.
    #[inline(never)]
    pub fn parse(subtype: u8, app_data: &[u8]) -> Result<ScheduleCommand, LinkError> {
        let none = |c: ScheduleCommand| expect_len(app_data, 0).map(|_| c);
        match subtype {
            subtype::SCHEDULE_ENABLE => none(ScheduleCommand::EnableRelease),
            subtype::SCHEDULE_DISABLE => none(ScheduleCommand::DisableRelease),
            subtype::SCHEDULE_RESET => none(ScheduleCommand::Reset),
            subtype::SCHEDULE_SUMMARY_ALL => none(ScheduleCommand::SummaryReport),
            subtype::SCHEDULE_INSERT => ActivityBlock::parse(app_data).map(ScheduleCommand::Insert),
            subtype::SCHEDULE_DELETE => RequestIdList::parse(app_data).map(ScheduleCommand::Delete),
            subtype::SCHEDULE_TIME_SHIFT_ALL => {
                expect_len(app_data, RELEASE_TIME_LEN)?;
                let mut r = Reader::new(app_data, Order::Big);
                let (Some(seconds), Some(fraction)) = (r.i32(), r.u16()) else {
                    return Err(LinkError::InvalidArgument { index: 0 });
                };
                Ok(ScheduleCommand::TimeShiftAll(ObtOffset::from_parts(
                    seconds, fraction,
                )))
            }
            _ => Err(LinkError::UnknownSubtype {
                service: service::SCHEDULING,
                subtype,
            }),
        }
    }

    /// Writes the application data.
    pub fn emit(&self, w: &mut Writer<'_>) -> Option<()> {
        match self {
            ScheduleCommand::EnableRelease
            | ScheduleCommand::DisableRelease
            | ScheduleCommand::Reset
            | ScheduleCommand::SummaryReport => Some(()),
            ScheduleCommand::Insert(block) => w.put(block.bytes()),
            ScheduleCommand::Delete(list) => {
                w.u8(u8::try_from(list.as_slice().len()).ok()?)?;
                for id in list.as_slice() {
                    w.put(&id.to_bytes())?;
                }
                Some(())
            }
            ScheduleCommand::TimeShiftAll(offset) => {
                let (seconds, fraction) = offset.to_parts();
                w.i32(seconds)?;
                w.u16(fraction)
            }
        }
    }
}

/// One activity in a TM[11,13].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SummaryEntry {
    /// Release time (on-board time).
    pub release: TmTime,
    /// Request ID of the embedded telecommand.
    pub request_id: RequestId,
}

/// Writes a TM[11,13]'s source data into `out`; returns its length, `None` if `out` is
/// too short or there are more than 255 entries.
pub fn emit_summary(entries: &[SummaryEntry], out: &mut [u8]) -> Option<usize> {
    let mut w = Writer::new(out, Order::Big);
    write_summary(&mut w, entries)?;
    Some(w.position())
}

/// Writes the TM[11,13] source data of `entries` (N u8, then release time and request
/// ID of each); `None` if it does not fit or there are more than 255 entries.
pub fn write_summary(w: &mut Writer<'_>, entries: &[SummaryEntry]) -> Option<()> {
    w.u8(u8::try_from(entries.len()).ok()?)?;
    for e in entries {
        w.put(&e.release.to_bytes())?;
        w.put(&e.request_id.to_bytes())?;
    }
    Some(())
}

/// A checked view of a TM[11,13]'s source data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SummaryView<'a> {
    bytes: &'a [u8],
}

impl<'a> SummaryView<'a> {
    /// Checks the length against N; `None` if they disagree.
    pub fn new(d: &'a [u8]) -> Option<SummaryView<'a>> {
        let n = usize::from(*d.first()?);
        (d.len() == ACTIVITY_COUNT_LEN + n * SUMMARY_ENTRY_LEN).then_some(SummaryView { bytes: d })
    }

    /// Number of activities.
    pub fn count(&self) -> usize {
        usize::from(self.bytes.first().copied().unwrap_or(0))
    }

    /// The entries, in report order.
    pub fn entries(&self) -> impl Iterator<Item = SummaryEntry> + 'a {
        let body = self.bytes.get(ACTIVITY_COUNT_LEN..).unwrap_or(&[]);
        body.chunks_exact(SUMMARY_ENTRY_LEN).map_while(|c| {
            let mut r = Reader::new(c, Order::Big);
            Some(SummaryEntry {
                release: TmTime::from_bytes(r.take()?),
                request_id: RequestId::from_bytes(r.take()?),
            })
        })
    }
}
