//! What the controller tells the ground: telemetry *records* in a bounded queue, and
//! the housekeeping sample.
//!
//! The controller never encodes or sends bytes itself: it queues small records
//! ([`TmRecord`], stamped with the control cycle) and the link service (`comms`, below
//! the control task's priority) encodes them into framed PUS packets for the UART.
//!
//! ## When the queue is full
//! The queue holds [`TM_QUEUE_LEN`] records in three classes ([`TmClass`]):
//! * **replies**, what a telecommand is owed: its verification reports and its direct
//!   answer (TM[17,2], TM[8,130], TM[20,2]). They are queued whenever a place is free,
//!   and a place is always free for them (below);
//! * **events**: queued only while more than [`REPLY_RESERVE`] places are free;
//! * **bulk** (housekeeping, dump chunks, time reports, schedule summaries): queued only
//!   while more than [`TM_RESERVED_SLOTS`] places are free.
//!
//! A housekeeping record carries its sample, taken when it is queued (the report's
//! content is the state of the cycle its time stamp names); the queue keeps at most
//! [`HK_SAMPLES`] samples waiting, and a housekeeping record beyond them is dropped too.
//!
//! A record that finds no room in its class is dropped and counted ([`TmQueue::dropped`],
//! housekeeping `tm_dropped`). Nothing already queued is ever dropped or reordered.
//!
//! **Why replies always find room.** The link service takes a telecommand (from the
//! uplink or the schedule) only while [`ADMISSION_FREE_SLOTS`] places are free
//! ([`TmQueue::admits_telecommand`]). One telecommand queues at most
//! [`MAX_REPLIES_PER_TC`] replies at once; the one long-running telecommand still owes
//! at most [`MAX_DEFERRED_REPLIES`] (a move's start and completion). Events and bulk
//! never take the last [`REPLY_RESERVE`] = the sum of the two, so the replies of an
//! admitted telecommand and the deferred ones of the pending one always fit. The
//! admission threshold also leaves room for the bulk answer of one telecommand (a dump's
//! [`MAX_BULK_PER_TC`] chunks) above the bulk reserve, so a telecommand taken is answered
//! whole; a telecommand that finds less room waits in the receive queue.

use heapless::Deque;

use crate::kinematics::{Pose, LEGS};
use crate::link::command::TABLE_CHUNK_MAX_LEN;
use crate::link::tc::RequestId;
use crate::link::time::TimeReportRate;
use crate::link::tm::{EventSeverity, Verification};
use crate::link::wire::{mm_to_nm_f32, pose_to_wire_f32};
use crate::link::{Housekeeping, MemoryId};

/// Records the queue holds.
pub const TM_QUEUE_LEN: usize = 64;
/// Free places kept from bulk records (housekeeping, dump chunks, time reports, schedule
/// summaries are refused at or below this).
pub const TM_RESERVED_SLOTS: usize = 16;
/// Replies one telecommand queues at once, at most: acceptance, start and completion
/// reports and one direct answer (TM[17,2], TM[8,130] or TM[20,2]).
pub const MAX_REPLIES_PER_TC: usize = 4;
/// Replies the one pending long-running telecommand can still owe: a move's start (sent
/// when its path is planned) and its completion.
pub const MAX_DEFERRED_REPLIES: usize = 2;
/// Free places events never take: the replies of one telecommand and of the pending one.
pub const REPLY_RESERVE: usize = MAX_REPLIES_PER_TC + MAX_DEFERRED_REPLIES;
/// Bulk records one telecommand queues, at most: a table dump's chunks.
pub const MAX_BULK_PER_TC: usize = crate::table::TABLE_LEN.div_ceil(TABLE_CHUNK_MAX_LEN);
/// Free places the link service needs to take a telecommand: room for everything one
/// telecommand and the pending one can queue (module documentation).
pub const ADMISSION_FREE_SLOTS: usize =
    TM_RESERVED_SLOTS + MAX_BULK_PER_TC + MAX_REPLIES_PER_TC + MAX_DEFERRED_REPLIES;
const _: () = assert!(REPLY_RESERVE <= TM_RESERVED_SLOTS);
const _: () = assert!(ADMISSION_FREE_SLOTS <= TM_QUEUE_LEN);

/// Housekeeping samples the queue keeps waiting to be sent (a backed-up downlink's
/// periodic and one-shot reports beyond them are dropped and counted).
pub const HK_SAMPLES: usize = 4;

/// A housekeeping sample as the control cycle takes it: the report's other fields as
/// they go on the wire, and its poses, strokes and encoder readings still in working
/// units (mm, rad, `f32`). The link service converts those to nm and micro-arcseconds
/// when it encodes the report ([`HkSample::to_report`]): the conversion of the rotations
/// is exact in `f64`, software floating point on the Cortex-M4F (~5,000 instructions
/// for the four poses), and taken in the control cycle it put a move's cycle with a
/// housekeeping sample at 20,233 instructions. The result is the same: the same
/// conversion of the same values, only later.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HkSample {
    /// Every field but the six below, which are zero here.
    pub report: Housekeeping,
    /// Pose from FK (mm, rad).
    pub pose_fk: Pose<f32>,
    /// Commanded pose (mm, rad).
    pub pose_commanded: Pose<f32>,
    /// Commanded strokes (mm).
    pub strokes_commanded_mm: [f32; LEGS],
    /// Encoder readings (mm).
    pub encoders_mm: [f32; LEGS],
    /// Pose from FK in the operator's frames (mm, rad).
    pub pose_fk_operator: Pose<f32>,
    /// Commanded pose in the operator's frames (mm, rad).
    pub pose_commanded_operator: Pose<f32>,
}

impl HkSample {
    /// The report: the six fields in wire units (`link::wire::pose_to_wire_f32`,
    /// `mm_to_nm_f32`).
    pub fn to_report(&self) -> Housekeeping {
        let mut h = self.report;
        h.pose_fk = pose_to_wire_f32(&self.pose_fk);
        h.pose_commanded = pose_to_wire_f32(&self.pose_commanded);
        h.strokes_commanded_nm = self.strokes_commanded_mm.map(mm_to_nm_f32);
        h.encoders_nm = self.encoders_mm.map(mm_to_nm_f32);
        h.pose_fk_operator = pose_to_wire_f32(&self.pose_fk_operator);
        h.pose_commanded_operator = pose_to_wire_f32(&self.pose_commanded_operator);
        h
    }
}

/// Which records yield to which when the queue fills (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TmClass {
    /// What a telecommand is owed: never dropped.
    Reply,
    /// Events: keep [`REPLY_RESERVE`] places free.
    Event,
    /// Housekeeping, dump chunks, time reports, schedule summaries: keep
    /// [`TM_RESERVED_SLOTS`] places free.
    Bulk,
}

impl TmClass {
    /// Places that must stay free after a record of this class is queued.
    pub const fn reserve(self) -> usize {
        match self {
            TmClass::Reply => 0,
            TmClass::Event => REPLY_RESERVE,
            TmClass::Bulk => TM_RESERVED_SLOTS,
        }
    }
}

/// One telemetry packet to be: what the link service encodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TmRecord {
    /// TM[1,x] for a telecommand.
    Verification {
        /// The telecommand.
        request_id: RequestId,
        /// The report.
        report: Verification,
    },
    /// TM[5,x].
    Event {
        /// Severity (= subtype).
        severity: EventSeverity,
        /// Event ID.
        id: u16,
        /// Auxiliary words.
        aux: [u32; 2],
    },
    /// TM[3,25]: the housekeeping sample taken when the record was queued (kept by the
    /// queue beside the record, [`TmQueue::push_housekeeping`]).
    Housekeeping,
    /// TM[17,2].
    PingReply,
    /// TM[8,130]: the answer of a move check for a telecommand.
    MoveCheck {
        /// The telecommand.
        request_id: RequestId,
        /// The answer.
        check: super::motion::MoveCheck,
    },
    /// TM[20,2]: the effective values of the parameters in `mask` (bit i = index i),
    /// read when it is encoded.
    Parameters {
        /// The parameters to report.
        mask: u32,
    },
    /// TM[6,6]: the chunk of `memory` at `offset_bytes`, read when it is encoded.
    DumpChunk {
        /// Memory area.
        memory: MemoryId,
        /// Offset of the chunk (bytes).
        offset_bytes: u16,
    },
    /// TM[9,2]: a time report (its OBT is the record's cycle).
    TimeReport {
        /// The generation rate in force.
        rate: TimeReportRate,
    },
    /// TM[11,13]: the schedule summary, read when it is encoded.
    ScheduleSummary,
}

impl TmRecord {
    /// The record's class in the queue's policy (module documentation).
    pub const fn class(&self) -> TmClass {
        match self {
            TmRecord::Verification { .. }
            | TmRecord::PingReply
            | TmRecord::MoveCheck { .. }
            | TmRecord::Parameters { .. } => TmClass::Reply,
            TmRecord::Event { .. } => TmClass::Event,
            TmRecord::Housekeeping
            | TmRecord::DumpChunk { .. }
            | TmRecord::TimeReport { .. }
            | TmRecord::ScheduleSummary => TmClass::Bulk,
        }
    }

    /// Housekeeping, dump chunks, time reports and schedule summaries yield to replies
    /// and events.
    pub const fn is_bulk(&self) -> bool {
        matches!(self.class(), TmClass::Bulk)
    }
}

/// A record and the control cycle it was made in (its telemetry time).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stamped {
    /// Control cycle of the record.
    pub cycle: u32,
    /// The record.
    pub record: TmRecord,
}

/// The bounded telemetry queue (module documentation for its policy).
#[derive(Clone, Debug, Default)]
pub struct TmQueue {
    queue: Deque<Stamped, TM_QUEUE_LEN>,
    /// The samples of the queued housekeeping records, in queue order.
    hk: Deque<HkSample, HK_SAMPLES>,
    dropped: u16,
}

impl TmQueue {
    /// Empty.
    pub const fn new() -> Self {
        Self {
            queue: Deque::new(),
            hk: Deque::new(),
            dropped: 0,
        }
    }

    /// Queues `record` made in `cycle`, or drops and counts it (policy above). Returns
    /// whether it was queued. A housekeeping record goes through
    /// [`TmQueue::push_housekeeping`] (this drops it).
    pub fn push(&mut self, cycle: u32, record: TmRecord) -> bool {
        let room =
            self.free() > record.class().reserve() && !matches!(record, TmRecord::Housekeeping);
        if room && self.queue.push_back(Stamped { cycle, record }).is_ok() {
            true
        } else {
            self.count_drop();
            false
        }
    }

    fn count_drop(&mut self) {
        self.dropped = self.dropped.wrapping_add(1);
    }

    /// Queues a housekeeping report made in `cycle` with its sample, or drops and
    /// counts it when the bulk reserve or the [`HK_SAMPLES`] are used up. Returns
    /// whether it was queued.
    pub fn push_housekeeping(&mut self, cycle: u32, sample: &HkSample) -> bool {
        let record = TmRecord::Housekeeping;
        if self.free() > record.class().reserve() && !self.hk.is_full() {
            let queued = self.hk.push_back(*sample).is_ok()
                && self.queue.push_back(Stamped { cycle, record }).is_ok();
            if queued {
                return true;
            }
        }
        self.count_drop();
        false
    }

    /// The oldest record, still queued.
    pub fn peek(&self) -> Option<&Stamped> {
        self.queue.front()
    }

    /// The sample of the oldest housekeeping record.
    pub fn peek_housekeeping(&self) -> Option<&HkSample> {
        self.hk.front()
    }

    /// Takes the oldest record (and its sample).
    pub fn pop(&mut self) -> Option<Stamped> {
        let s = self.queue.pop_front()?;
        if matches!(s.record, TmRecord::Housekeeping) {
            self.hk.pop_front();
        }
        Some(s)
    }

    /// Records queued.
    pub fn len(&self) -> usize {
        self.queue.len()
    }

    /// Nothing queued.
    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    /// Free places.
    pub fn free(&self) -> usize {
        TM_QUEUE_LEN - self.queue.len()
    }

    /// Whether the link service may take a telecommand now: everything it and the
    /// pending one can queue fits ([`ADMISSION_FREE_SLOTS`]).
    pub fn admits_telecommand(&self) -> bool {
        self.free() >= ADMISSION_FREE_SLOTS
    }

    /// Records dropped since boot (wrapping).
    pub fn dropped(&self) -> u16 {
        self.dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn event() -> TmRecord {
        TmRecord::Event {
            severity: EventSeverity::Info,
            id: 1,
            aux: [0, 0],
        }
    }

    fn report() -> TmRecord {
        TmRecord::Verification {
            request_id: RequestId::from_bytes([0x18, 0xb2, 0xc0, 0x01]),
            report: Verification::AcceptanceSuccess,
        }
    }

    #[test]
    fn each_class_leaves_its_reserve_and_replies_take_the_last_places() {
        let mut q = TmQueue::new();
        let mut bulk = 0;
        while q.push(
            0,
            TmRecord::DumpChunk {
                memory: MemoryId::ActiveTable,
                offset_bytes: 0,
            },
        ) {
            bulk += 1;
        }
        assert_eq!(bulk, TM_QUEUE_LEN - TM_RESERVED_SLOTS);
        assert_eq!(q.dropped(), 1);
        let mut events = 0;
        while q.push(1, event()) {
            events += 1;
        }
        assert_eq!(events, TM_RESERVED_SLOTS - REPLY_RESERVE);
        assert_eq!(q.dropped(), 2);
        assert!(!q.admits_telecommand());
        for _ in 0..REPLY_RESERVE {
            assert!(q.push(2, report()));
        }
        assert!(!q.push(3, report()), "full");
        assert_eq!(q.dropped(), 3);
        // Nothing queued is reordered: the oldest comes out first.
        assert!(matches!(
            q.pop().map(|s| s.record),
            Some(TmRecord::DumpChunk { .. })
        ));
        assert_eq!(q.len(), TM_QUEUE_LEN - 1);
    }

    #[test]
    fn a_telecommand_is_admitted_only_with_room_for_all_it_can_queue() {
        let mut q = TmQueue::new();
        while q.free() > ADMISSION_FREE_SLOTS {
            assert!(q.push(0, event()));
        }
        assert!(q.admits_telecommand());
        // What an admitted dump queues, with the pending move's two deferred replies.
        assert!(q.push(1, report()));
        for _ in 0..MAX_BULK_PER_TC {
            assert!(
                q.push(
                    1,
                    TmRecord::DumpChunk {
                        memory: MemoryId::ActiveTable,
                        offset_bytes: 0
                    }
                ),
                "a dump's chunks fit"
            );
        }
        for _ in 0..MAX_REPLIES_PER_TC - 1 + MAX_DEFERRED_REPLIES {
            assert!(q.push(1, report()));
        }
        assert_eq!(q.dropped(), 0);
        assert!(!q.admits_telecommand());
    }

    #[test]
    fn housekeeping_samples_leave_with_their_records() {
        let sample = |cycle: u32| HkSample {
            report: Housekeeping {
                cycle_counter: cycle,
                ..Housekeeping::default()
            },
            ..HkSample::default()
        };
        let mut q = TmQueue::new();
        for c in 0..HK_SAMPLES as u32 {
            assert!(q.push_housekeeping(c, &sample(c)));
            assert!(q.push(c, event()));
        }
        assert!(!q.push_housekeeping(99, &sample(99)));
        assert_eq!(q.dropped(), 1);
        assert!(!q.push(0, TmRecord::Housekeeping), "only with a sample");
        for c in 0..HK_SAMPLES as u32 {
            assert_eq!(q.peek().map(|s| s.cycle), Some(c));
            assert_eq!(
                q.peek_housekeeping().map(|h| h.report.cycle_counter),
                Some(c)
            );
            assert!(matches!(
                q.pop().map(|s| s.record),
                Some(TmRecord::Housekeeping)
            ));
            assert!(matches!(
                q.pop().map(|s| s.record),
                Some(TmRecord::Event { .. })
            ));
        }
        assert!(q.peek_housekeeping().is_none());
    }
}
