//! The link service: between the UART byte queues and the controller, below the
//! control task's priority.
//!
//! One [`LinkService::pass`] (run after every control cycle):
//! 1. **receive**: first the time-based schedule's due activities (ST[11]): each is
//!    released through [`Controller::release_next_due`] (and a due time report ST[9]
//!    queued, [`Controller::link_pass_start`]); then it takes bytes from the RX queue
//!    through the deframer; each complete
//!    frame is one telecommand for [`Controller::handle_telecommand`]; at most
//!    [`MAX_TC_PER_PASS`] telecommands per pass (the rest of the bytes wait in the
//!    queue for the next pass). A frame too long for the deframer (longer than the
//!    largest telecommand's frame) or not valid COBS is dropped and counted
//!    (`tc_frames_dropped`): it carries no request ID to report on. A frame that
//!    decodes into a packet longer than [`crate::link::MAX_TC_PACKET_LEN`] still
//!    reaches the controller, which refuses it with TM[1,2] 0x0503.
//! 2. **transmit**: encodes queued telemetry records into framed PUS packets while the
//!    TX queue has room for the whole frame (frames are never split or truncated; a
//!    record waits in the telemetry queue until its frame fits).
//!
//! The controller is reached through [`Exclusive`]: on the target an RTIC resource
//! lock, held only for one telecommand or one record at a time; on the host a plain
//! `&mut`. Encoding happens outside the lock, and so does a move check's evaluation
//! (TC[8,1] 0x0006: the whole path's IK and FK): the telecommand leaves a copy of what
//! the check reads ([`MoveCheckJob`]), the link service evaluates it unlocked and
//! reports it under the lock.

use super::motion::MoveCheckJob;
use super::telemetry::{Stamped, TmRecord};
use super::{Controller, JobRequest, JobResult};
use crate::hw::MechanismIo;
use crate::link::framing::{max_cobs_len, Deframer};
use crate::link::tm::{TmSource, TmWriter};
use crate::link::{Housekeeping, MAX_TC_PACKET_LEN, MAX_TM_FRAME_LEN};

/// Telecommands handled per pass (per control cycle): a table upload's five chunks and
/// its commit arrive within two cycles; the budget per telecommand is measured by the
/// cycle benchmark.
pub const MAX_TC_PER_PASS: usize = 4;
/// Deframer buffer (bytes): one byte more than the COBS encoding of the largest
/// telecommand, so an oversized packet (up to 255 + 2 bytes) still reaches the decoder
/// and gets its TM[1,2] 0x0503; longer frames are dropped and counted.
pub const RX_FRAME_BUFFER_LEN: usize = max_cobs_len(MAX_TC_PACKET_LEN + 1);

/// Exclusive access to a `T` for a short section.
pub trait Exclusive<T> {
    /// Runs `f` with `&mut T`.
    fn lock<R>(&mut self, f: impl FnOnce(&mut T) -> R) -> R;
}

impl<T> Exclusive<T> for &mut T {
    fn lock<R>(&mut self, f: impl FnOnce(&mut T) -> R) -> R {
        f(self)
    }
}

/// Received bytes (the UART RX queue).
pub trait RxBytes {
    /// The next received byte, if any.
    fn pop(&mut self) -> Option<u8>;
}

/// Bytes to send (the UART TX queue).
pub trait TxBytes {
    /// Bytes that can be queued now.
    fn free(&self) -> usize;
    /// Queues a whole frame (called only when it fits).
    fn push(&mut self, frame: &[u8]);
}

/// The background worker as the link service sees it (two bounded queues on the
/// target, the worker itself on the host).
pub trait JobPort {
    /// Hands a request over (copies it) and returns true; false if there is no room
    /// (the request stays with the controller). By reference: a request is ~1.3 KB.
    fn send(&mut self, request: &JobRequest) -> bool;
    /// The next result, if any.
    fn recv(&mut self) -> Option<JobResult>;
}

/// Counters of the link that the controller does not see.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkCounters {
    /// Frames the deframer dropped (too long, bad COBS).
    pub frames_dropped: u16,
    /// UART receive overruns and RX queue overflows (reported by the board).
    pub uart_overruns: u16,
}

/// The link service (module documentation).
#[derive(Clone, Debug)]
pub struct LinkService {
    deframer: Deframer<RX_FRAME_BUFFER_LEN>,
    tm: TmWriter,
    counters: LinkCounters,
    /// The move check being evaluated ([`LinkService::run_move_check`]; here, not on
    /// the stack).
    move_check: Option<MoveCheckJob>,
}

impl Default for LinkService {
    fn default() -> Self {
        Self::new()
    }
}

/// What one record needs from the controller to be encoded.
enum Content {
    Plain(TmRecord),
    Hk(super::telemetry::HkSample),
    Params(heapless::Vec<(u16, i32), { super::params::N_PARAMETERS }>),
    Dump(crate::link::MemoryId, u16, super::commands::DumpChunk),
    Summary(super::schedule::ScheduleSummary),
    Nothing,
}

impl LinkService {
    /// A fresh link (TM counters at 0).
    pub const fn new() -> Self {
        Self {
            deframer: Deframer::new(),
            tm: TmWriter::new(),
            counters: LinkCounters {
                frames_dropped: 0,
                uart_overruns: 0,
            },
            move_check: None,
        }
    }

    /// Adds UART overruns the board counted.
    pub fn add_uart_overruns(&mut self, n: u16) {
        self.counters.uart_overruns = self.counters.uart_overruns.wrapping_add(n);
    }

    /// The link's own counters.
    pub fn counters(&self) -> LinkCounters {
        self.counters
    }

    /// One pass: receive, then transmit (module documentation).
    pub fn pass<M, C>(&mut self, ctl: &mut C, rx: &mut impl RxBytes, tx: &mut impl TxBytes)
    where
        M: MechanismIo,
        C: Exclusive<Controller<M>>,
    {
        self.receive(ctl, rx);
        self.transmit(ctl, tx);
    }

    /// Step 1: at most [`MAX_TC_PER_PASS`] telecommands: the schedule's due activities
    /// first, then from the RX bytes.
    #[inline(never)]
    pub fn receive<M, C>(&mut self, ctl: &mut C, rx: &mut impl RxBytes)
    where
        M: MechanismIo,
        C: Exclusive<Controller<M>>,
    {
        ctl.lock(|c| c.link_pass_start());
        let mut handled = 0;
        // Time-tagged activities due now (ST[11]) share the pass's budget, first. A
        // telecommand is taken only while the telemetry queue has room for all it can
        // report (`telemetry`, "Why replies always find room"); else it waits.
        while handled < MAX_TC_PER_PASS
            && ctl.lock(|c| c.tm_queue().admits_telecommand() && c.release_next_due())
        {
            self.run_move_check(ctl);
            handled += 1;
        }
        let mut admitted = false;
        while handled < MAX_TC_PER_PASS {
            if !admitted {
                admitted = ctl.lock(|c| c.tm_queue().admits_telecommand());
                if !admitted {
                    break;
                }
            }
            let Some(byte) = rx.pop() else { break };
            match self.deframer.push_byte(byte) {
                None => {}
                Some(Ok(packet)) => {
                    ctl.lock(|c| c.handle_telecommand(packet));
                    self.run_move_check(ctl);
                    handled += 1;
                    admitted = false;
                }
                Some(Err(_)) => {
                    self.counters.frames_dropped = self.counters.frames_dropped.wrapping_add(1);
                }
            }
        }
    }

    /// Evaluates the move check the last telecommand queued (if any) outside the
    /// controller's lock: locked only to take its copy and to report it, so the control
    /// task never waits for the path's IK and FK (module documentation).
    #[inline(never)]
    fn run_move_check<M, C>(&mut self, ctl: &mut C)
    where
        M: MechanismIo,
        C: Exclusive<Controller<M>>,
    {
        let slot = &mut self.move_check;
        ctl.lock(|c| c.take_move_check(slot));
        if let Some(job) = &self.move_check {
            let check = job.evaluate();
            let (request_id, ack) = (job.request_id(), job.ack());
            ctl.lock(|c| c.finish_move_check(request_id, ack, check));
        }
        self.move_check = None;
    }

    /// Step 2: encode queued records while their frames fit in the TX queue.
    #[inline(never)]
    pub fn transmit<M, C>(&mut self, ctl: &mut C, tx: &mut impl TxBytes)
    where
        M: MechanismIo,
        C: Exclusive<Controller<M>>,
    {
        loop {
            let counters = self.counters;
            let peeked = ctl.lock(|c| {
                let stamped = *c.tm_queue().peek()?;
                let content = match stamped.record {
                    TmRecord::Housekeeping => {
                        let mut hk = *c.tm_queue().peek_housekeeping()?;
                        hk.report.tc_frames_dropped = counters.frames_dropped;
                        hk.report.uart_overruns = counters.uart_overruns;
                        Content::Hk(hk)
                    }
                    TmRecord::DumpChunk {
                        memory,
                        offset_bytes,
                    } => match c.dump_chunk(memory, offset_bytes) {
                        Some(chunk) => Content::Dump(memory, offset_bytes, chunk),
                        None => Content::Nothing,
                    },
                    TmRecord::Parameters { mask } => Content::Params(c.parameter_values(mask)),
                    TmRecord::ScheduleSummary => Content::Summary(c.schedule_summary()),
                    other => Content::Plain(other),
                };
                Some((stamped, content))
            });
            let Some((stamped, content)) = peeked else {
                return;
            };
            let mut frame = [0u8; MAX_TM_FRAME_LEN];
            // A number is consumed only by a packet that is sent: a frame that does not
            // fit gives its sequence count and message counter back.
            let numbers = self.tm.checkpoint();
            let len = self.encode(&stamped, &content, &mut frame);
            match (len, frame.get(..len.unwrap_or(0))) {
                (Some(n), Some(f)) if n > 0 => {
                    if tx.free() < n {
                        self.tm.restore(numbers);
                        return;
                    }
                    tx.push(f);
                }
                // Not encodable (a defect guard): drop it rather than block the queue.
                _ => {}
            }
            ctl.lock(|c| c.tm_queue().pop());
        }
    }

    /// The framed packet of one record: its source data described once
    /// ([`TmSource`]), written by the one emit path.
    #[inline(never)]
    fn encode(&mut self, stamped: &Stamped, content: &Content, out: &mut [u8]) -> Option<usize> {
        let time = super::schedule::obt_of_cycle(stamped.cycle);
        let hk: Housekeeping;
        let source = match content {
            Content::Plain(TmRecord::Verification { request_id, report }) => {
                TmSource::Verification {
                    request_id: *request_id,
                    report: *report,
                }
            }
            Content::Plain(TmRecord::Event { severity, id, aux }) => TmSource::Event {
                severity: *severity,
                event_id: *id,
                aux: *aux,
            },
            Content::Plain(TmRecord::PingReply) => TmSource::PingReply,
            Content::Plain(TmRecord::MoveCheck { request_id, check }) => TmSource::MoveCheck {
                request_id: *request_id,
                check: *check,
            },
            Content::Params(values) => TmSource::Parameters(values),
            Content::Plain(TmRecord::TimeReport { rate }) => TmSource::TimeReport(*rate),
            Content::Summary(entries) => TmSource::ScheduleSummary(entries),
            Content::Hk(sample) => {
                // Converted here, below the control task (`HkSample`).
                hk = sample.to_report();
                TmSource::Housekeeping(&hk)
            }
            Content::Dump(memory, offset, chunk) => TmSource::DumpChunk {
                memory: *memory,
                offset_bytes: *offset,
                bytes: chunk.bytes(),
            },
            Content::Plain(
                TmRecord::Housekeeping
                | TmRecord::DumpChunk { .. }
                | TmRecord::Parameters { .. }
                | TmRecord::ScheduleSummary,
            )
            | Content::Nothing => return None,
        };
        self.tm.emit(time, &source, out).ok()
    }

    /// Moves job requests from the controller to the worker and results back.
    #[inline(never)]
    pub fn exchange_jobs<M, C>(&mut self, ctl: &mut C, port: &mut impl JobPort)
    where
        M: MechanismIo,
        C: Exclusive<Controller<M>>,
    {
        while let Some(result) = port.recv() {
            ctl.lock(|c| c.job_finished(&result));
        }
        // A request the port has no room for stays with the controller until the next pass.
        while ctl.lock(|c| c.offer_job_request(|r| port.send(r))) {}
    }
}
