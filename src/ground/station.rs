//! A ground station's side of the link (host): numbers telecommands with the ground
//! encoder ([`super::tc::TcSequencer`]) and turns the controller's telemetry byte stream
//! into owned records. Used by the mission demo and the tests.

use super::tc::TcSequencer;
use crate::link::framing::Deframer;
use crate::link::schedule::SummaryEntry;
use crate::link::time::TimeReportRate;
use crate::link::tm::{parse_tm, EventSeverity, TmReport, TmTime, Verification};
use crate::link::{Command, Housekeeping, MemoryId, RequestId};

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

/// The numbers a TM packet carries besides its content.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TmNumbers {
    /// Packet sequence count (14 bits).
    pub seq_count: u16,
    /// PUS service.
    pub service: u8,
    /// Message type counter of its service.
    pub msg_counter: u16,
}

/// Sends telecommands, collects telemetry.
#[derive(Debug)]
pub struct Station {
    seq: TcSequencer,
    deframer: Deframer,
    /// Every TM packet received, in order.
    pub log: Vec<Tm>,
    /// The packet time (on-board time) of each entry of `log`.
    pub log_times: Vec<TmTime>,
    /// The numbers of each entry of `log`: its sequence count, service and message type
    /// counter (the ground checks them for gaps).
    pub log_numbers: Vec<TmNumbers>,
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
            log_numbers: Vec::new(),
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
        Ok((super::tc::frame(&pkt), rid))
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
                let numbers = TmNumbers {
                    seq_count: tm.seq_count,
                    service: tm.service,
                    msg_counter: tm.msg_counter,
                };
                (report, tm.time, numbers)
            });
            match tm {
                Some((t, time, numbers)) => {
                    self.log.push(t);
                    self.log_times.push(time);
                    self.log_numbers.push(numbers);
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
        self.reports(rid).iter().any(|v| {
            matches!(
                v,
                Verification::CompletionSuccess
                    | Verification::CompletionFailure { .. }
                    | Verification::AcceptanceFailure { .. }
                    | Verification::StartFailure { .. }
            )
        })
    }

    /// The newest housekeeping report.
    pub fn last_hk(&self) -> Option<Housekeeping> {
        self.log.iter().rev().find_map(|t| match t {
            Tm::Hk(h) => Some(*h),
            _ => None,
        })
    }

    /// The newest schedule summary report.
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
