//! What the controller tells the ground: telemetry *records*, complete when queued,
//! through a lock-free single-producer single-consumer queue to the link service.
//!
//! The controller never encodes or sends bytes itself: it queues records ([`TmRecord`],
//! stamped with the control cycle, every value in them taken when they are made: the
//! housekeeping sample, a dump's bytes, a parameter report's values, a schedule
//! summary) through its [`TmProducer`]; the link service (`comms`, below the control
//! task's priority) takes them from its [`TmConsumer`] and encodes them into framed PUS
//! packets, without locking the controller and without reaching back into it. The
//! controller is the one producer: the control task, and the telecommands it executes
//! under its lock in the link task, queue through it.
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
//! content is the state of the cycle its time stamp names).
//!
//! A record that finds no room in its class is dropped and counted ([`TmProducer::dropped`],
//! housekeeping `tm_dropped`). Nothing already queued is ever dropped or reordered.
//!
//! **Why replies always find room.** The link service takes a telecommand (from the
//! uplink or the schedule) only while [`ADMISSION_FREE_SLOTS`] places are free
//! ([`TmConsumer::admits_telecommand`]). One telecommand queues at most
//! [`MAX_REPLIES_PER_TC`] replies at once; the one long-running telecommand still owes
//! at most [`MAX_DEFERRED_REPLIES`] (a move's start and completion). Events and bulk
//! never take the last [`REPLY_RESERVE`] = the sum of the two, so the replies of an
//! admitted telecommand and the deferred ones of the pending one always fit. The
//! admission threshold also leaves room for the bulk answer of one telecommand (a dump's
//! [`MAX_BULK_PER_TC`] chunks) above the bulk reserve, so a telecommand taken is answered
//! whole; a telecommand that finds less room waits in the receive queue.

use heapless::spsc::{Consumer, Producer, Queue};

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

/// One telemetry packet to be, complete: what the link service encodes.
#[derive(Clone, Debug, PartialEq)]
// The housekeeping sample is the large variant; records live in the static queue only.
#[allow(clippy::large_enum_variant)]
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
    /// TM[3,25]: the housekeeping sample of the cycle the record was made in.
    Housekeeping(HkSample),
    /// TM[17,2].
    PingReply,
    /// TM[8,130]: the answer of a move check for a telecommand.
    MoveCheck {
        /// The telecommand.
        request_id: RequestId,
        /// The answer.
        check: super::motion::MoveCheck,
    },
    /// TM[20,2]: (ID, effective value) of the parameters named, in index order.
    Parameters(ParameterValues),
    /// TM[6,6]: one chunk of a memory area, its bytes as they were when queued.
    DumpChunk(DumpChunk),
    /// TM[9,2]: a time report (its OBT is the record's cycle).
    TimeReport {
        /// The generation rate in force.
        rate: TimeReportRate,
    },
    /// TM[11,13]: the schedule's activities when the record was made.
    ScheduleSummary(super::schedule::ScheduleSummary),
}

/// The values of a TM[20,2] report.
pub type ParameterValues = heapless::Vec<(u16, i32), { super::params::N_PARAMETERS }>;

/// One TM[6,6] chunk: the memory area, the offset and the bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DumpChunk {
    /// Memory area.
    pub memory: MemoryId,
    /// Offset of the chunk (bytes).
    pub offset_bytes: u16,
    len: u8,
    bytes: [u8; TABLE_CHUNK_MAX_LEN],
}

impl DumpChunk {
    /// The chunk of `memory` at `offset_bytes` of `image` (`None` outside it).
    pub fn of(memory: MemoryId, image: &[u8], offset_bytes: u16) -> Option<DumpChunk> {
        let start = usize::from(offset_bytes);
        let end = start.saturating_add(TABLE_CHUNK_MAX_LEN).min(image.len());
        let src = image.get(start..end)?;
        let mut bytes = [0u8; TABLE_CHUNK_MAX_LEN];
        crate::link::wire::copy_prefix(&mut bytes, src)?;
        Some(DumpChunk {
            memory,
            offset_bytes,
            len: u8::try_from(src.len()).ok()?,
            bytes,
        })
    }

    /// The chunk's bytes.
    pub fn bytes(&self) -> &[u8] {
        self.bytes.get(..usize::from(self.len)).unwrap_or(&[])
    }
}

impl TmRecord {
    /// The record's class in the queue's policy (module documentation).
    pub const fn class(&self) -> TmClass {
        match self {
            TmRecord::Verification { .. }
            | TmRecord::PingReply
            | TmRecord::MoveCheck { .. }
            | TmRecord::Parameters(_) => TmClass::Reply,
            TmRecord::Event { .. } => TmClass::Event,
            TmRecord::Housekeeping(_)
            | TmRecord::DumpChunk(_)
            | TmRecord::TimeReport { .. }
            | TmRecord::ScheduleSummary(_) => TmClass::Bulk,
        }
    }

    /// Housekeeping, dump chunks, time reports and schedule summaries yield to replies
    /// and events.
    pub const fn is_bulk(&self) -> bool {
        matches!(self.class(), TmClass::Bulk)
    }
}

/// A record and the control cycle it was made in (its telemetry time).
#[derive(Clone, Debug, PartialEq)]
pub struct Stamped {
    /// Control cycle of the record.
    pub cycle: u32,
    /// The record.
    pub record: TmRecord,
}

/// Slots of the queue's storage: `heapless::spsc::Queue<_, N>` holds `N - 1` records.
pub const TM_QUEUE_SLOTS: usize = TM_QUEUE_LEN + 1;

/// The queue's storage (a `static` on the target: the firmware splits it once at init).
pub type TmQueue = Queue<Stamped, TM_QUEUE_SLOTS>;

/// The controller's end of the telemetry queue (module documentation for its policy).
pub struct TmProducer {
    queue: Producer<'static, Stamped, TM_QUEUE_SLOTS>,
    dropped: u16,
}

impl TmProducer {
    /// The producer half of a split [`TmQueue`].
    pub const fn new(queue: Producer<'static, Stamped, TM_QUEUE_SLOTS>) -> Self {
        Self { queue, dropped: 0 }
    }

    /// Queues `record` made in `cycle`, or drops and counts it (policy above). Returns
    /// whether it was queued.
    pub fn push(&mut self, cycle: u32, record: TmRecord) -> bool {
        let room = self.free() > record.class().reserve();
        if room && self.queue.enqueue(Stamped { cycle, record }).is_ok() {
            true
        } else {
            self.dropped = self.dropped.wrapping_add(1);
            false
        }
    }

    /// Free places.
    pub fn free(&self) -> usize {
        TM_QUEUE_LEN.saturating_sub(self.queue.len())
    }

    /// Records dropped since boot (wrapping).
    pub fn dropped(&self) -> u16 {
        self.dropped
    }
}

/// The link service's end of the telemetry queue.
pub struct TmConsumer {
    queue: Consumer<'static, Stamped, TM_QUEUE_SLOTS>,
}

impl TmConsumer {
    /// The consumer half of a split [`TmQueue`].
    pub const fn new(queue: Consumer<'static, Stamped, TM_QUEUE_SLOTS>) -> Self {
        Self { queue }
    }

    /// The oldest record, still queued.
    pub fn peek(&self) -> Option<&Stamped> {
        self.queue.peek()
    }

    /// Takes the oldest record.
    pub fn pop(&mut self) -> Option<Stamped> {
        self.queue.dequeue()
    }

    /// Records queued.
    pub fn len(&self) -> usize {
        self.queue.len()
    }

    /// Nothing queued.
    pub fn is_empty(&self) -> bool {
        self.queue.len() == 0
    }

    /// Whether the link service may take a telecommand now: everything it and the
    /// pending one can queue fits ([`ADMISSION_FREE_SLOTS`]).
    pub fn admits_telecommand(&self) -> bool {
        TM_QUEUE_LEN.saturating_sub(self.queue.len()) >= ADMISSION_FREE_SLOTS
    }
}

/// A queue for one host bench or test: its storage leaked once (`'static`, as the
/// firmware's is); the halves outlive a simulated reboot by being handed on.
#[cfg(feature = "host")]
pub fn host_queue() -> (TmProducer, TmConsumer) {
    let q: &'static mut TmQueue = Box::leak(Box::new(TmQueue::new()));
    let (p, c) = q.split();
    (TmProducer::new(p), TmConsumer::new(c))
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

    fn chunk() -> TmRecord {
        let c = DumpChunk::of(MemoryId::ActiveTable, &[7; 10], 0);
        assert!(c.is_some(), "ten bytes make a chunk");
        c.map_or_else(event, TmRecord::DumpChunk)
    }

    #[test]
    fn each_class_leaves_its_reserve_and_replies_take_the_last_places() {
        let (mut p, mut c) = host_queue();
        let mut bulk = 0;
        while p.push(0, chunk()) {
            bulk += 1;
        }
        assert_eq!(bulk, TM_QUEUE_LEN - TM_RESERVED_SLOTS);
        assert_eq!(p.dropped(), 1);
        let mut events = 0;
        while p.push(1, event()) {
            events += 1;
        }
        assert_eq!(events, TM_RESERVED_SLOTS - REPLY_RESERVE);
        assert_eq!(p.dropped(), 2);
        assert!(!c.admits_telecommand());
        for _ in 0..REPLY_RESERVE {
            assert!(p.push(2, report()));
        }
        assert!(!p.push(3, report()), "full");
        assert_eq!(p.dropped(), 3);
        // Nothing queued is reordered: the oldest comes out first.
        assert!(matches!(
            c.pop().map(|s| s.record),
            Some(TmRecord::DumpChunk(_))
        ));
        assert_eq!(c.len(), TM_QUEUE_LEN - 1);
    }

    #[test]
    fn a_telecommand_is_admitted_only_with_room_for_all_it_can_queue() {
        let (mut p, c) = host_queue();
        while p.free() > ADMISSION_FREE_SLOTS {
            assert!(p.push(0, event()));
        }
        assert!(c.admits_telecommand());
        // What an admitted dump queues, with the pending move's two deferred replies.
        assert!(p.push(1, report()));
        for _ in 0..MAX_BULK_PER_TC {
            assert!(p.push(1, chunk()), "a dump's chunks fit");
        }
        for _ in 0..MAX_REPLIES_PER_TC - 1 + MAX_DEFERRED_REPLIES {
            assert!(p.push(1, report()));
        }
        assert_eq!(p.dropped(), 0);
        assert!(!c.admits_telecommand());
    }

    #[test]
    fn a_dump_chunk_holds_the_bytes_it_was_made_of() {
        let image: Vec<u8> = (0..=255u8).cycle().take(516).collect();
        let last = DumpChunk::of(MemoryId::UploadBuffer, &image, 512);
        assert_eq!(last.as_ref().map(DumpChunk::bytes), Some(&image[512..]));
        let first = DumpChunk::of(MemoryId::UploadBuffer, &image, 0);
        assert_eq!(
            first.as_ref().map(DumpChunk::bytes),
            Some(&image[..TABLE_CHUNK_MAX_LEN])
        );
        assert!(DumpChunk::of(MemoryId::UploadBuffer, &image, 517).is_none());
    }
}
