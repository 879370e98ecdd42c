//! A ground station's side of the link (host): numbers telecommands ([`TcSequencer`])
//! and turns the controller's telemetry byte stream into owned records. Used by the
//! simulated bench (`sim`), the ground tools (`ground`) and the tests; it depends on the
//! flight code's link layer only, so `sim` and `ground` both build on it and neither
//! imports the other for it (ground -> sim -> station -> core, one way).

// Host only (feature `host`), as `ground` and `sim`: a station may stop on a broken
// invariant, so the flight code's panic-free rules (src/lib.rs) do not apply here.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::indexing_slicing
)]

pub mod sequencer;

use crate::link::framing::Deframer;
use crate::link::schedule::SummaryEntry;
use crate::link::time::TimeReportRate;
use crate::link::tm::{parse_tm, EventSeverity, TmReport, TmTime, Verification};
use crate::link::{Command, Housekeeping, MemoryId, RequestId};
pub use sequencer::{frame, TcSequencer};

/// The packet header fields of one received TM packet (the counters the ICD promises:
/// sequence count 0 after boot, +1 per packet; message type counter per service).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TmHeader {
    /// Packet sequence count (14 bits).
    pub seq_count: u16,
    /// Service.
    pub service: u8,
    /// Subtype.
    pub subtype: u8,
    /// Message type counter (per service).
    pub msg_counter: u16,
}

/// One telemetry packet, owned.
#[derive(Clone, Debug, PartialEq)]
// The housekeeping report is the one large variant; a parsed report is a transient
// value (no heap on the target, and the station's log keeps one per packet).
#[allow(clippy::large_enum_variant)]
pub enum Tm {
    /// TM[1,x].
    Verify(RequestId, Verification),
    /// TM[3,25].
    Hk(Housekeeping),
    /// TM[5,x]: severity, event ID, aux words.
    Event(EventSeverity, u16, [u32; 2]),
    /// TM[6,6]: memory, offset (bytes), data.
    Dump(MemoryId, u16, Vec<u8>),
    /// TM[17,2].
    Ping,
    /// TM[8,130]: the move check's answer to a telecommand.
    MoveCheck(RequestId, crate::link::tm::MoveCheckReport),
    /// TM[20,2]: (parameter ID, value) pairs.
    Parameters(Vec<(u16, i32)>),
    /// TM[9,2]: the rate in force, the on-board time of the report.
    TimeReport(TimeReportRate, TmTime),
    /// TM[11,13]: the scheduled activities, in release order.
    ScheduleSummary(Vec<SummaryEntry>),
}

/// Sends telecommands, collects telemetry.
#[derive(Debug)]
pub struct Station {
    seq: TcSequencer,
    /// Sized for the largest TM frame (the default deframer is the telecommands').
    deframer: Deframer<{ crate::link::framing::max_cobs_len(crate::link::MAX_TM_PACKET_LEN) }>,
    /// Every TM packet received, in order.
    pub log: Vec<Tm>,
    /// The packet time (on-board time) of each entry of `log`.
    pub log_times: Vec<TmTime>,
    /// The packet header of each entry of `log`.
    pub log_headers: Vec<TmHeader>,
    /// Frames that did not deframe or parse (a healthy link keeps this at 0).
    pub bad_frames: usize,
    /// Telecommands encoded so far.
    pub tc_sent: usize,
}

impl Default for Station {
    fn default() -> Self {
        Self::new()
    }
}

impl Station {
    /// Sequence count 0, all acknowledgements requested.
    pub fn new() -> Self {
        Station {
            seq: TcSequencer::new(0),
            deframer: Deframer::new(),
            log: Vec::new(),
            log_times: Vec::new(),
            log_headers: Vec::new(),
            bad_frames: 0,
            tc_sent: 0,
        }
    }

    /// The next telecommand as a PUS packet (unframed) and its request ID.
    pub fn packet(&mut self, cmd: &Command) -> Result<(Vec<u8>, RequestId), String> {
        let pkt = self.seq.packet(cmd)?;
        let rid = RequestId::from_packet(&pkt).ok_or("packet shorter than a request ID")?;
        self.tc_sent += 1;
        Ok((pkt, rid))
    }

    /// The next telecommand framed for the byte stream, and its request ID.
    pub fn frame(&mut self, cmd: &Command) -> Result<(Vec<u8>, RequestId), String> {
        let (pkt, rid) = self.packet(cmd)?;
        Ok((frame(&pkt), rid))
    }

    /// A TC[11,4] inserting `activities` (release time, telecommand), each embedded
    /// telecommand numbered by this station first; and their request IDs.
    pub fn schedule_insert(
        &mut self,
        activities: &[(TmTime, Command)],
    ) -> Result<(Command, Vec<RequestId>), String> {
        let out = self.seq.schedule_insert(activities)?;
        self.tc_sent += activities.len();
        Ok(out)
    }

    /// Feeds received bytes (any split) through the deframer and parses whole frames.
    pub fn receive(&mut self, bytes: &[u8]) {
        for &b in bytes {
            let Some(frame) = self.deframer.push_byte(b) else {
                continue;
            };
            let tm = frame.ok().and_then(|f| parse_tm(f).ok()).map(|tm| {
                let report = match tm.report {
                    TmReport::Verification { request_id, report } => Tm::Verify(request_id, report),
                    TmReport::Housekeeping(h) => Tm::Hk(h),
                    TmReport::Event {
                        severity,
                        event_id,
                        aux,
                    } => Tm::Event(severity, event_id, aux),
                    TmReport::DumpChunk {
                        memory,
                        offset_bytes,
                        bytes,
                    } => Tm::Dump(memory, offset_bytes, bytes.to_vec()),
                    TmReport::PingReply => Tm::Ping,
                    TmReport::MoveCheck { request_id, check } => Tm::MoveCheck(request_id, check),
                    TmReport::Parameters { entries } => Tm::Parameters(
                        entries
                            .chunks_exact(crate::link::tm::PARAMETER_ENTRY_LEN)
                            .map(|c| {
                                (
                                    u16::from_be_bytes([c[0], c[1]]),
                                    i32::from_be_bytes([c[2], c[3], c[4], c[5]]),
                                )
                            })
                            .collect(),
                    ),
                    TmReport::TimeReport { rate, obt } => Tm::TimeReport(rate, obt),
                    TmReport::ScheduleSummary(view) => {
                        Tm::ScheduleSummary(view.entries().collect())
                    }
                };
                let header = TmHeader {
                    seq_count: tm.seq_count,
                    service: tm.service,
                    subtype: tm.subtype,
                    msg_counter: tm.msg_counter,
                };
                (report, tm.time, header)
            });
            match tm {
                Some((t, time, header)) => {
                    self.log.push(t);
                    self.log_times.push(time);
                    self.log_headers.push(header);
                }
                None => self.bad_frames += 1,
            }
        }
    }

    /// Verification reports for one request, in order.
    pub fn reports(&self, rid: RequestId) -> Vec<Verification> {
        self.reports_since(0, rid)
    }

    /// Verification reports for one request among the packets from `log[from..]`.
    pub fn reports_since(&self, from: usize, rid: RequestId) -> Vec<Verification> {
        self.log
            .get(from..)
            .unwrap_or(&[])
            .iter()
            .filter_map(|t| match t {
                Tm::Verify(r, v) if *r == rid => Some(*v),
                _ => None,
            })
            .collect()
    }

    /// The telecommand's reports are complete: a completion (success or failure) or an
    /// acceptance or start failure has arrived.
    pub fn finished(&self, rid: RequestId) -> bool {
        self.finished_since(0, rid)
    }

    /// As [`Station::finished`], among the packets from `log[from..]` (the log's length
    /// when the telecommand was sent): a long run's callers each cycle then read what
    /// came since, not the whole log (and no earlier request with the same, wrapped,
    /// sequence count).
    pub fn finished_since(&self, from: usize, rid: RequestId) -> bool {
        self.reports_since(from, rid).iter().any(|v| {
            matches!(
                v,
                Verification::CompletionSuccess
                    | Verification::CompletionFailure { .. }
                    | Verification::AcceptanceFailure { .. }
                    | Verification::StartFailure { .. }
            )
        })
    }

    /// The newest housekeeping report received. Only where the station and the
    /// controller run in lockstep (the simulated bench): over a real link the
    /// controller runs on while the station is not reading, so "newest" is whatever the
    /// read happened to reach; select by request ID and time stamp there
    /// ([`Station::hk_answer`], [`Station::hk_after`]).
    pub fn last_hk(&self) -> Option<Housekeeping> {
        self.log.iter().rev().find_map(|t| match t {
            Tm::Hk(h) => Some(*h),
            _ => None,
        })
    }

    /// The newest schedule summary report received (lockstep only, as
    /// [`Station::last_hk`]; over a real link: [`Station::answer`]).
    pub fn last_summary(&self) -> Option<&[SummaryEntry]> {
        self.log.iter().rev().find_map(|t| match t {
            Tm::ScheduleSummary(s) => Some(s.as_slice()),
            _ => None,
        })
    }

    /// Packet time of the first report `which` for request `rid`.
    pub fn report_time(&self, rid: RequestId, which: Verification) -> Option<TmTime> {
        self.log
            .iter()
            .zip(&self.log_times)
            .find_map(|(t, time)| match t {
                Tm::Verify(r, v) if *r == rid && *v == which => Some(*time),
                _ => None,
            })
    }

    /// Index in `log` of the first report `which` for request `rid`.
    pub fn report_index(&self, rid: RequestId, which: Verification) -> Option<usize> {
        self.log
            .iter()
            .position(|t| matches!(t, Tm::Verify(r, v) if *r == rid && *v == which))
    }

    /// What the execution of telecommand `rid` made, with its packet times: the packets
    /// after its acceptance report and before its next report (start, or a start or
    /// completion failure), stamped in the acceptance's control cycle. The controller
    /// queues a telecommand's records together, in this order, while it executes it
    /// (one lock: ping reply, one-shot housekeeping, parameter report, dump chunks,
    /// schedule summary, a refusal's event), and nothing queued is reordered (ICD,
    /// section 1); so this is the telecommand's own answer, whatever else (periodic
    /// housekeeping, other telecommands' reports) arrived before or after it. Not a
    /// move check's TM[8,130]: that follows the check's evaluation, outside the lock,
    /// possibly a cycle later (it names its request ID). `None` until both reports
    /// have arrived (acceptance requested, ack flags 0xF).
    pub fn answer(&self, rid: RequestId) -> Option<Vec<(TmTime, &Tm)>> {
        Some(
            self.answer_indices(rid)?
                .into_iter()
                .filter_map(|i| Some((*self.log_times.get(i)?, self.log.get(i)?)))
                .collect(),
        )
    }

    /// Indices in `log` of [`Station::answer`]'s packets.
    pub fn answer_indices(&self, rid: RequestId) -> Option<Vec<usize>> {
        let acc = self.report_index(rid, Verification::AcceptanceSuccess)?;
        let at = *self.log_times.get(acc)?;
        let next = acc
            + 1
            + self.log.get(acc + 1..)?.iter().position(
                |t| matches!(t, Tm::Verify(r, v) if *r == rid && *v != Verification::AcceptanceSuccess),
            )?;
        Some(
            (acc + 1..next)
                .filter(|i| self.log_times.get(*i) == Some(&at))
                .collect(),
        )
    }

    /// The housekeeping report a one-shot request (TC[3,27]) `rid` made
    /// ([`Station::answer`]); `None` if it has not arrived (or was dropped).
    pub fn hk_answer(&self, rid: RequestId) -> Option<Housekeeping> {
        self.answer(rid)?.iter().find_map(|(_, t)| match t {
            Tm::Hk(h) => Some(*h),
            _ => None,
        })
    }

    /// The housekeeping reports made after the packet `log[i]`, with their packet
    /// times, in the order made: those after it in the log with a later time stamp,
    /// up to the next boot event (the on-board time restarts at 0 at every boot).
    pub fn hk_after(&self, i: usize) -> impl Iterator<Item = (TmTime, &Housekeeping)> + '_ {
        let after = self.log_times.get(i).copied();
        self.log
            .iter()
            .zip(&self.log_times)
            .skip(i.saturating_add(1))
            .take_while(
                |(t, _)| !matches!(t, Tm::Event(_, id, _) if *id == crate::controller::event::BOOT),
            )
            .filter_map(move |(t, time)| match t {
                Tm::Hk(h) if after.is_some_and(|a| *time > a) => Some((*time, h)),
                _ => None,
            })
    }

    /// Auxiliary words of the events with this ID, in order.
    pub fn events(&self, id: u16) -> Vec<[u32; 2]> {
        self.log
            .iter()
            .filter_map(|t| match t {
                Tm::Event(_, e, aux) if *e == id => Some(*aux),
                _ => None,
            })
            .collect()
    }
}

/// An on-board time from seconds (nearest 1/65536 s); refused if negative, not finite
/// or beyond CUC 4+2.
pub fn obt_from_seconds(s: f64) -> Result<TmTime, String> {
    let ticks = (s * crate::link::tm::TIME_FRACTIONS_PER_SECOND as f64).round();
    if !(ticks.is_finite() && ticks >= 0.0 && ticks < 2f64.powi(48)) {
        return Err(format!("{s} s: not an on-board time (0 .. 2^32 s)"));
    }
    TmTime::from_ticks(ticks as u64).ok_or_else(|| format!("{s} s: beyond CUC 4+2"))
}
