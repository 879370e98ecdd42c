//! The link service: between the UART byte queues and the controller, below the
//! control task's priority. It owns the bytes and the packets; the controller never
//! sees either.
//!
//! One [`LinkService::pass`] (run after every control cycle; the period's order is
//! `crate::pass`):
//! 1. **receive**: first the time-based schedule's due activities (ST[11]): each is
//!    taken from the controller ([`Controller::take_due_activity`]), decoded here and
//!    executed as a received telecommand; then bytes from the RX queue through the
//!    deframer: each complete frame is decoded here (`link::tc::decode_telecommand`)
//!    and the controller gets the decoded [`Telecommand`]
//!    ([`Controller::execute_telecommand`]) or the refusal
//!    ([`Controller::refuse_telecommand`]): acceptance is decided here. At most
//!    [`MAX_TC_PER_PASS`] telecommands per pass, each only while the telemetry queue
//!    has room for all it can report (the rest wait in the RX queue). A frame too long
//!    for the deframer (longer than the largest telecommand's frame) or not valid COBS
//!    is dropped and counted (`tc_frames_dropped`): it carries no request ID to report
//!    on. A frame that decodes into a packet longer than
//!    [`crate::link::MAX_TC_PACKET_LEN`] is refused with TM[1,2] 0x0503.
//! 2. **jobs**: job requests from the controller to the background worker, results
//!    back ([`LinkService::exchange_jobs`]).
//! 3. **transmit**: takes the complete telemetry records from its end of the telemetry
//!    queue ([`TmConsumer`], lock-free) and encodes them into framed PUS packets while
//!    the TX queue has room for the whole frame (frames are never split or truncated;
//!    a record waits in the queue until its frame fits).
//!
//! The controller is reached through [`Exclusive`]: on the target an RTIC resource
//! lock, held for one telecommand or one job message at a time; on the host a plain
//! `&mut`. Decoding and encoding happen outside the lock, and so does a move check's
//! evaluation (TC[8,1] 0x0006: the whole path's IK and FK): the telecommand leaves a
//! copy of what the check reads ([`MoveCheckJob`]), the link service evaluates it
//! unlocked and reports it under the lock.

use super::motion::MoveCheckJob;
use super::telemetry::{Stamped, TmConsumer, TmRecord};
use super::{Controller, JobRequest, JobResult};
use crate::hw::MechanismIo;
use crate::link::framing::{max_cobs_len, Deframer};
use crate::link::tc::{decode_telecommand, Telecommand};
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
pub struct LinkService {
    deframer: Deframer<RX_FRAME_BUFFER_LEN>,
    tm: TmWriter,
    /// Its end of the telemetry queue.
    queue: TmConsumer,
    counters: LinkCounters,
    /// The move check being evaluated ([`LinkService::run_move_check`]; here, not on
    /// the stack).
    move_check: Option<MoveCheckJob>,
}

impl LinkService {
    /// A fresh link (TM counters at 0) taking telemetry from `queue`.
    pub const fn new(queue: TmConsumer) -> Self {
        Self {
            deframer: Deframer::new(),
            tm: TmWriter::new(),
            queue,
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

    /// The telemetry records waiting to be sent.
    pub fn queue(&mut self) -> &mut TmConsumer {
        &mut self.queue
    }

    /// Gives its end of the telemetry queue back (a simulated reboot hands it to the
    /// next link, after dropping what it held: records queued at a reset are lost).
    pub fn into_queue(mut self) -> TmConsumer {
        while self.queue.pop().is_some() {}
        self.queue
    }

    /// One pass: receive, jobs, transmit (module documentation).
    pub fn pass<M, C>(
        &mut self,
        ctl: &mut C,
        rx: &mut impl RxBytes,
        port: &mut impl JobPort,
        tx: &mut impl TxBytes,
    ) where
        M: MechanismIo,
        C: Exclusive<Controller<M>>,
    {
        self.receive(ctl, rx);
        self.exchange_jobs(ctl, port);
        self.transmit(tx);
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
        while handled < MAX_TC_PER_PASS && self.queue.admits_telecommand() {
            let Some(activity) = ctl.lock(|c| c.take_due_activity()) else {
                break;
            };
            let decoded = decode_telecommand(activity.packet());
            ctl.lock(|c| c.execute_released(&activity, &decoded));
            self.run_move_check(ctl);
            handled += 1;
        }
        while handled < MAX_TC_PER_PASS && self.queue.admits_telecommand() {
            let Some(decoded) = self.next_packet(rx) else {
                break;
            };
            // One lock for either outcome (one copy of the lock's entry and exit).
            ctl.lock(|c| match &decoded {
                Ok(tc) => c.execute_telecommand(tc),
                Err(rejection) => c.refuse_telecommand(rejection),
            });
            self.run_move_check(ctl);
            handled += 1;
        }
    }

    /// The next complete frame of `rx` decoded (`None`: no complete frame in the bytes
    /// received so far). Frames that do not deframe are dropped and counted here.
    fn next_packet(
        &mut self,
        rx: &mut impl RxBytes,
    ) -> Option<Result<Telecommand, crate::link::tc::Rejection>> {
        loop {
            let byte = rx.pop()?;
            match self.deframer.push_byte(byte) {
                None => {}
                Some(Ok(packet)) => return Some(decode_telecommand(packet)),
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
        if !ctl.lock(|c| c.take_move_check(slot)) {
            return;
        }
        if let Some(job) = &self.move_check {
            let check = job.evaluate();
            let token = job.token();
            ctl.lock(|c| c.finish_move_check(token, check));
        }
        self.move_check = None;
    }

    /// Step 3: encode queued records while their frames fit in the TX queue (lock-free:
    /// the records are complete, module documentation).
    #[inline(never)]
    pub fn transmit(&mut self, tx: &mut impl TxBytes) {
        while let Some(stamped) = self.queue.peek() {
            let mut frame = [0u8; MAX_TM_FRAME_LEN];
            // A number is consumed only by a packet that is sent: a frame that does not
            // fit gives its sequence count and message counter back.
            let numbers = self.tm.checkpoint();
            let len = encode(&mut self.tm, self.counters, stamped, &mut frame);
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
            self.queue.pop();
        }
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

/// One telecommand packet decoded and handed to `ctl` as the link service does it
/// (executed, or refused with its decoder's code): for callers without a link
/// service (tests, the cycle benchmark).
pub fn deliver<M: MechanismIo>(ctl: &mut Controller<M>, packet: &[u8]) {
    match decode_telecommand(packet) {
        Ok(tc) => ctl.execute_telecommand(&tc),
        Err(rejection) => ctl.refuse_telecommand(&rejection),
    }
}

/// The framed packet of one record: its source data described once ([`TmSource`]),
/// written by the one emit path; housekeeping gets the link's own counters here.
#[inline(never)]
fn encode(
    tm: &mut TmWriter,
    counters: LinkCounters,
    stamped: &Stamped,
    out: &mut [u8],
) -> Option<usize> {
    let time = super::schedule::obt_of_cycle(stamped.cycle);
    let hk: Housekeeping;
    let source = match &stamped.record {
        TmRecord::Verification { request_id, report } => TmSource::Verification {
            request_id: *request_id,
            report: *report,
        },
        TmRecord::Event { severity, id, aux } => TmSource::Event {
            severity: *severity,
            event_id: *id,
            aux: *aux,
        },
        TmRecord::PingReply => TmSource::PingReply,
        TmRecord::MoveCheck { request_id, check } => TmSource::MoveCheck {
            request_id: *request_id,
            check: *check,
        },
        TmRecord::Parameters(values) => TmSource::Parameters(values),
        TmRecord::TimeReport { rate } => TmSource::TimeReport(*rate),
        TmRecord::ScheduleSummary(entries) => TmSource::ScheduleSummary(entries),
        TmRecord::Housekeeping(sample) => {
            // Converted here, below the control task (`HkSample`).
            let mut report = sample.to_report();
            report.tc_frames_dropped = counters.frames_dropped;
            report.uart_overruns = counters.uart_overruns;
            hk = report;
            TmSource::Housekeeping(&hk)
        }
        TmRecord::DumpChunk(chunk) => TmSource::DumpChunk {
            memory: chunk.memory,
            offset_bytes: chunk.offset_bytes,
            bytes: chunk.bytes(),
        },
    };
    tm.emit(time, &source, out).ok()
}
