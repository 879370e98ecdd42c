//! What the controller tells the ground: telemetry *records* in a bounded queue, and
//! the housekeeping sample.
//!
//! The controller never encodes or sends bytes itself: it queues small records
//! ([`TmRecord`], stamped with the control cycle) and the link service (`comms`, below
//! the control task's priority) encodes them into framed PUS packets for the UART.
//!
//! ## When the queue is full
//! The queue holds [`TM_QUEUE_LEN`] records. Housekeeping reports and table-dump chunks
//! are queued only while at least [`TM_RESERVED_SLOTS`] slots are free, so that
//! verification reports and events always find room first; when even those find the
//! queue full, the new record is dropped. Every dropped record is counted
//! ([`TmQueue::dropped`], housekeeping `tm_dropped`). Nothing already queued is ever
//! dropped or reordered.

use heapless::Deque;

use crate::link::tc::RequestId;
use crate::link::time::TimeReportRate;
use crate::link::tm::{EventSeverity, Verification};
use crate::link::MemoryId;

/// Records the queue holds.
pub const TM_QUEUE_LEN: usize = 64;
/// Free slots kept for verification reports and events (housekeeping and dump chunks
/// are refused below this).
pub const TM_RESERVED_SLOTS: usize = 16;

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
    /// TM[3,25]: the housekeeping sample taken when it is encoded.
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
    /// Housekeeping, dump chunks, time reports and schedule summaries yield to
    /// verification reports and events.
    pub const fn is_bulk(&self) -> bool {
        matches!(
            self,
            TmRecord::Housekeeping
                | TmRecord::DumpChunk { .. }
                | TmRecord::TimeReport { .. }
                | TmRecord::ScheduleSummary
        )
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
    dropped: u16,
}

impl TmQueue {
    /// Empty.
    pub const fn new() -> Self {
        Self {
            queue: Deque::new(),
            dropped: 0,
        }
    }

    /// Queues `record` made in `cycle`, or drops and counts it (policy above). Returns
    /// whether it was queued.
    pub fn push(&mut self, cycle: u32, record: TmRecord) -> bool {
        let free = TM_QUEUE_LEN - self.queue.len();
        let room = if record.is_bulk() {
            free > TM_RESERVED_SLOTS
        } else {
            free > 0
        };
        if room && self.queue.push_back(Stamped { cycle, record }).is_ok() {
            true
        } else {
            self.dropped = self.dropped.wrapping_add(1);
            false
        }
    }

    /// The oldest record, still queued.
    pub fn peek(&self) -> Option<&Stamped> {
        self.queue.front()
    }

    /// Takes the oldest record.
    pub fn pop(&mut self) -> Option<Stamped> {
        self.queue.pop_front()
    }

    /// Records queued.
    pub fn len(&self) -> usize {
        self.queue.len()
    }

    /// Nothing queued.
    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
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

    #[test]
    fn bulk_records_leave_the_reserve_to_reports_and_events() {
        let mut q = TmQueue::new();
        let mut bulk = 0;
        while q.push(0, TmRecord::Housekeeping) {
            bulk += 1;
        }
        assert_eq!(bulk, TM_QUEUE_LEN - TM_RESERVED_SLOTS);
        assert_eq!(q.dropped(), 1);
        for _ in 0..TM_RESERVED_SLOTS {
            assert!(q.push(1, event()));
        }
        assert!(!q.push(2, event()), "full");
        assert_eq!(q.dropped(), 2);
        // Nothing queued is reordered: the oldest comes out first.
        assert_eq!(q.pop().map(|s| s.record), Some(TmRecord::Housekeeping));
        assert_eq!(q.len(), TM_QUEUE_LEN - 1);
    }
}
