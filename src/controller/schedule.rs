//! The on-board time-based schedule (PUS ST[11]): time-tagged telecommands released at
//! their on-board time.
//!
//! # What it holds
//! At most [`SCHEDULE_CAPACITY`] activities, each a release time (on-board time, OBT:
//! the CUC 4+2 time of the TM, [`Controller::obt`]) and the embedded telecommand packet
//! (at most [`MAX_SCHEDULED_TC_LEN`] bytes), kept in release order; activities with
//! equal release times keep their insertion order (TC order within one TC[11,4]).
//! Bounded (`heapless`), no heap.
//!
//! # Rules (each has a test in `ground/tests/schedule.rs`)
//! * **Insert** (TC[11,4]) is all-or-nothing: refused with a start failure, changing
//!   nothing, if the activities do not all fit (0x0B01), a release time is earlier than
//!   now (0x0B02) or beyond the on-board clock's range (0x0B06), or a request ID is
//!   already scheduled or repeated in the TC (0x0B03). Format errors of the TC and of
//!   its embedded telecommands are acceptance failures of the link (0x050C, 0x050D,
//!   0x050F).
//! * **Delete** (TC[11,5]) is all-or-nothing: refused (0x0B04) if a listed request ID
//!   is not scheduled or listed twice.
//! * **Time-shift** (TC[11,15]) moves every release time by the offset, all-or-nothing:
//!   refused (0x0B05) if any would be earlier than now or beyond the clock's range.
//! * **Release**: in every link pass, before the uplink's telecommands, the activities
//!   whose release time is not later than the pass's OBT are released in release order,
//!   at most [`super::comms::MAX_TC_PER_PASS`] per pass (the budget is shared with the
//!   uplink, so at most that many telecommands run per cycle). An activity is removed
//!   from the schedule before its telecommand runs (it cannot run twice), announced by
//!   event [`event::ACTIVITY_RELEASED`], and its packet goes through
//!   [`Controller::execute_released`], which executes it exactly as a received one: its own service-1
//!   reports under its own request ID and acknowledgement flags. If that telecommand
//!   fails (acceptance, start or, for a move or a table job, completion), the failure
//!   report is accompanied by event [`event::ACTIVITY_FAILED`] (request ID, subtype and
//!   code). Release latency: the activity runs in the first link pass whose OBT is at
//!   or after its release time, i.e. within one control cycle (1 ms) of it, plus one
//!   cycle per further [`super::comms::MAX_TC_PER_PASS`] activities due at once.
//! * **Disable** (TC[11,2]) stops the releases; activities stay. **Enable** (TC[11,1])
//!   resumes them; activities whose release time passed while release was disabled are
//!   not run late: enabling deletes them, each with event [`event::ACTIVITY_EXPIRED`].
//! * **Reset** (TC[11,3]) deletes every activity and leaves release **disabled**.
//! * **Not persisted**: the OBT restarts at 0 at every boot, so release times cannot
//!   outlive a reset; the controller boots with an empty schedule, release enabled,
//!   time reports off.

use heapless::Vec;

use super::error::CommandError;
use super::verification::Outcome;
use super::{event, Controller, TmRecord};
use crate::hw::MechanismIo;
use crate::link::hk::ScheduleHk;
use crate::link::schedule::{
    ActivityBlock, ObtOffset, RequestIdList, ScheduleCommand, SummaryEntry, TimeTagged,
    MAX_SCHEDULED_TC_LEN, SCHEDULE_CAPACITY,
};
use crate::link::tc::RequestId;
use crate::link::tm::{EventSeverity, TmTime, Verification};
use crate::timing::CONTROL_RATE_HZ;

/// Why a schedule telecommand was refused (start failure TM[1,4]; codes 0x0Bxx, after
/// the service number 11).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScheduleError {
    /// 0x0B01: the activities of the insert do not all fit (data: free places).
    Full {
        /// Free places in the schedule.
        free: u8,
    },
    /// 0x0B02: a release time is earlier than now (data: activity index in the TC).
    ReleaseTimeInPast {
        /// Zero-based index of the activity in the TC[11,4].
        index: u8,
    },
    /// 0x0B03: a request ID is already scheduled or repeated in the TC (data: activity
    /// index in the TC).
    DuplicateRequestId {
        /// Zero-based index of the activity in the TC[11,4].
        index: u8,
    },
    /// 0x0B04: delete of a request ID that is not scheduled, or listed twice (data:
    /// index in the TC).
    NotScheduled {
        /// Zero-based index of the request ID in the TC[11,5].
        index: u8,
    },
    /// 0x0B05: the time shift would move an activity before now or beyond the clock's
    /// range (data: its request ID).
    ShiftOutOfRange {
        /// The first such activity.
        request_id: RequestId,
    },
    /// 0x0B06: a release time beyond the on-board clock's range (the cycle counter
    /// wraps after 2^32 cycles, 49.7 days) (data: activity index in the TC).
    ReleaseTimeBeyondClock {
        /// Zero-based index of the activity in the TC[11,4].
        index: u8,
    },
}

impl ScheduleError {
    /// Failure code.
    pub const fn code(&self) -> u16 {
        match self {
            ScheduleError::Full { .. } => 0x0B01,
            ScheduleError::ReleaseTimeInPast { .. } => 0x0B02,
            ScheduleError::DuplicateRequestId { .. } => 0x0B03,
            ScheduleError::NotScheduled { .. } => 0x0B04,
            ScheduleError::ShiftOutOfRange { .. } => 0x0B05,
            ScheduleError::ReleaseTimeBeyondClock { .. } => 0x0B06,
        }
    }

    /// Failure datum.
    pub const fn data(&self) -> u32 {
        match *self {
            ScheduleError::Full { free } => free as u32,
            ScheduleError::ReleaseTimeInPast { index }
            | ScheduleError::DuplicateRequestId { index }
            | ScheduleError::NotScheduled { index }
            | ScheduleError::ReleaseTimeBeyondClock { index } => index as u32,
            ScheduleError::ShiftOutOfRange { request_id } => request_id_word(request_id),
        }
    }
}

/// A request ID as one u32 (packet ID << 16 | sequence control): event and failure data.
pub const fn request_id_word(id: RequestId) -> u32 {
    ((id.packet_id as u32) << 16) | id.sequence_control as u32
}

/// The on-board time of control cycle `cycle` (the TM time stamp of its records):
/// `TmTime::from_micros(cycle_to_us(cycle))`, in 32-bit arithmetic (a cycle is a whole
/// number of microseconds and the rate divides a second, so it is exactly whole
/// seconds plus `(cycle % rate) / rate` of a second, floored to 1/65536 s; no 64-bit
/// division routine in the flight image).
pub const fn obt_of_cycle(cycle: u32) -> TmTime {
    let rate = CONTROL_RATE_HZ;
    TmTime {
        seconds: cycle / rate,
        // < rate * 2^16 <= 2^32 for any rate up to 65,536 Hz (asserted below).
        fraction: ((cycle % rate) * FRACTIONS_PER_SECOND / rate) as u16,
    }
}

/// 1/65536 s units of [`TmTime::fraction`], as u32.
const FRACTIONS_PER_SECOND: u32 = crate::link::tm::TIME_FRACTIONS_PER_SECOND as u32;
const _: () =
    assert!((CONTROL_RATE_HZ as u64) * crate::link::tm::TIME_FRACTIONS_PER_SECOND <= 1 << 32);

/// The latest on-board time the clock reaches before its cycle counter wraps.
pub const MAX_OBT: TmTime = obt_of_cycle(u32::MAX);

/// One scheduled telecommand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Activity {
    /// Release time (OBT).
    pub release: TmTime,
    /// Request ID of the embedded telecommand.
    pub request_id: RequestId,
    len: u8,
    packet: [u8; MAX_SCHEDULED_TC_LEN],
}

impl Activity {
    fn new(a: &TimeTagged<'_>) -> Activity {
        // The block's packets fit a slot (checked when it was parsed); a longer one
        // would be cut short and then refused by the decoder at release, never run.
        let mut packet = [0u8; MAX_SCHEDULED_TC_LEN];
        let mut len = 0u8;
        for (d, s) in packet.iter_mut().zip(a.packet) {
            *d = *s;
            len = len.saturating_add(1);
        }
        Activity {
            release: a.release,
            request_id: a.request_id(),
            len,
            packet,
        }
    }

    /// The embedded telecommand packet.
    pub fn packet(&self) -> &[u8] {
        self.packet.get(..usize::from(self.len)).unwrap_or(&[])
    }
}

/// The schedule's state (module documentation).
#[derive(Clone, Debug)]
pub struct Schedule {
    /// In **reverse** release order (the next activity is the last element, taken with
    /// `pop`, which has no index and so no out-of-bounds panic path); among equal
    /// release times the one inserted first is nearest the end.
    activities: Vec<Activity, SCHEDULE_CAPACITY>,
    release_enabled: bool,
    released: u16,
    failed: u16,
    /// The released telecommand being executed now.
    executing: Option<RequestId>,
    /// A released long-running telecommand (move, table job) whose final report is
    /// still to come.
    watched: Option<RequestId>,
}

impl Default for Schedule {
    fn default() -> Self {
        Self::new()
    }
}

impl Schedule {
    /// Empty, release enabled (the state at boot).
    pub const fn new() -> Self {
        Self {
            activities: Vec::new(),
            release_enabled: true,
            released: 0,
            failed: 0,
            executing: None,
            watched: None,
        }
    }

    /// Activities scheduled.
    pub fn len(&self) -> usize {
        self.activities.len()
    }

    /// No activity scheduled.
    pub fn is_empty(&self) -> bool {
        self.activities.is_empty()
    }

    /// Release is enabled.
    pub fn release_enabled(&self) -> bool {
        self.release_enabled
    }

    fn position(&self, id: RequestId) -> Option<usize> {
        self.activities.iter().position(|a| a.request_id == id)
    }

    /// TC[11,4]: all activities of `block` or none (module documentation).
    pub fn insert(&mut self, block: &ActivityBlock, now: TmTime) -> Result<(), ScheduleError> {
        let free = SCHEDULE_CAPACITY.saturating_sub(self.activities.len());
        if block.count() > free {
            return Err(ScheduleError::Full {
                free: u8::try_from(free).unwrap_or(u8::MAX),
            });
        }
        for (i, a) in block.activities().enumerate() {
            let index = u8::try_from(i).unwrap_or(u8::MAX);
            if a.release < now {
                return Err(ScheduleError::ReleaseTimeInPast { index });
            }
            if a.release > MAX_OBT {
                return Err(ScheduleError::ReleaseTimeBeyondClock { index });
            }
            let id = a.request_id();
            let repeated = block.activities().take(i).any(|b| b.request_id() == id);
            if repeated || self.position(id).is_some() {
                return Err(ScheduleError::DuplicateRequestId { index });
            }
        }
        for a in block.activities() {
            // Before every activity released at or before it (reverse release order;
            // equal release times: the earlier insert stays nearer the end).
            let at = self
                .activities
                .iter()
                .position(|b| b.release <= a.release)
                .unwrap_or(self.activities.len());
            // Room was checked above: the push cannot fail. Then moved down to `at` by
            // neighbour exchanges (`Vec::insert` shifts with a general `memmove`, 1.6 KB
            // of flash for this one call; at most SCHEDULE_CAPACITY exchanges here).
            if self.activities.push(Activity::new(&a)).is_ok() {
                let mut i = self.activities.len();
                while i > at + 1 {
                    if let Some([.., below, last]) = self.activities.get_mut(..i) {
                        core::mem::swap(below, last);
                    }
                    i -= 1;
                }
            }
        }
        Ok(())
    }

    /// TC[11,5]: deletes every listed activity or none.
    pub fn delete(&mut self, ids: &RequestIdList) -> Result<(), ScheduleError> {
        let list = ids.as_slice();
        for (i, id) in list.iter().enumerate() {
            let repeated = list.iter().take(i).any(|b| b == id);
            if repeated || self.position(*id).is_none() {
                return Err(ScheduleError::NotScheduled {
                    index: u8::try_from(i).unwrap_or(u8::MAX),
                });
            }
        }
        self.activities.retain(|a| !list.contains(&a.request_id));
        Ok(())
    }

    /// TC[11,15]: every release time moved by `offset`, or none. A refusal names the
    /// first activity in release order that would leave the range.
    pub fn time_shift(&mut self, offset: ObtOffset, now: TmTime) -> Result<(), ScheduleError> {
        // `activities` is in reverse release order.
        for a in self.activities.iter().rev() {
            match a.release.checked_offset(offset.ticks()) {
                Some(t) if t >= now && t <= MAX_OBT => {}
                _ => {
                    return Err(ScheduleError::ShiftOutOfRange {
                        request_id: a.request_id,
                    })
                }
            }
        }
        for a in self.activities.iter_mut() {
            // Checked above; the same offset keeps the order.
            a.release = a
                .release
                .checked_offset(offset.ticks())
                .unwrap_or(a.release);
        }
        Ok(())
    }

    /// TC[11,3]: empty, release disabled.
    pub fn reset(&mut self) {
        self.activities.clear();
        self.release_enabled = false;
    }

    /// Takes the first activity if release is enabled and its time has come.
    pub fn take_due(&mut self, now: TmTime) -> Option<Activity> {
        if !self.release_enabled {
            return None;
        }
        self.take_first_if(|a| a.release <= now)
    }

    /// Takes the first activity if its release time is earlier than `now`.
    fn take_overdue(&mut self, now: TmTime) -> Option<Activity> {
        self.take_first_if(|a| a.release < now)
    }

    fn take_first_if(&mut self, f: impl Fn(&Activity) -> bool) -> Option<Activity> {
        if self.activities.last().is_some_and(f) {
            self.activities.pop()
        } else {
            None
        }
    }

    /// The activities in release order (the TM[11,13] entries).
    pub fn entries(&self) -> impl Iterator<Item = SummaryEntry> + '_ {
        self.activities.iter().rev().map(|a| SummaryEntry {
            release: a.release,
            request_id: a.request_id,
        })
    }

    /// Release time of the next activity.
    pub fn next_release(&self) -> Option<TmTime> {
        self.activities.last().map(|a| a.release)
    }
}

/// The schedule's entries, copied out for the summary report.
pub type ScheduleSummary = Vec<SummaryEntry, SCHEDULE_CAPACITY>;

impl<M: MechanismIo> Controller<M> {
    /// The on-board time now: the time stamp of the records made now, and the clock of
    /// the schedule's release times.
    pub fn obt(&self) -> TmTime {
        obt_of_cycle(self.cycle)
    }

    /// A TC[11,x] (module documentation).
    #[inline(never)]
    pub(super) fn execute_schedule(
        &mut self,
        command: &ScheduleCommand,
    ) -> Result<Outcome, CommandError> {
        let now = self.obt();
        let refused = CommandError::Schedule;
        match command {
            ScheduleCommand::EnableRelease => {
                let was_disabled = !self.schedule.release_enabled;
                self.schedule.release_enabled = true;
                if was_disabled {
                    self.expire_overdue(now);
                }
            }
            ScheduleCommand::DisableRelease => self.schedule.release_enabled = false,
            ScheduleCommand::Reset => self.schedule.reset(),
            ScheduleCommand::Insert(block) => self.schedule.insert(block, now).map_err(refused)?,
            ScheduleCommand::Delete(ids) => self.schedule.delete(ids).map_err(refused)?,
            ScheduleCommand::TimeShiftAll(offset) => {
                self.schedule.time_shift(*offset, now).map_err(refused)?
            }
            ScheduleCommand::SummaryReport => {
                let summary = self.schedule_summary();
                self.tm.push(self.cycle, TmRecord::ScheduleSummary(summary));
            }
        }
        Ok(Outcome::Done)
    }

    /// Deletes the activities whose release time passed while release was disabled,
    /// each with event 0x00B2.
    fn expire_overdue(&mut self, now: TmTime) {
        while let Some(a) = self.schedule.take_overdue(now) {
            self.event(
                EventSeverity::Low,
                event::ACTIVITY_EXPIRED,
                [request_id_word(a.request_id), a.release.seconds],
            );
        }
    }

    /// The start of a link pass: a time report if one is due, and the end of the watch
    /// on a released long-running telecommand that completed without a report.
    pub fn link_pass_start(&mut self) {
        self.time_report_due();
        let pending = self.ledger.pending.map(|p| p.request_id());
        if self.schedule.watched.is_some() && self.schedule.watched != pending {
            self.schedule.watched = None;
        }
    }

    /// The first activity's release time has come (it is released in the next link pass
    /// unless release is disabled or an exposure hold is in force).
    pub fn scheduled_due(&self) -> bool {
        let now = self.obt();
        self.schedule
            .activities
            .first()
            .is_some_and(|a| a.release <= now)
    }

    /// Releases the first activity if its time has come and no exposure hold is in
    /// force (module documentation): it
    /// leaves the schedule (it can never run twice) and event 0x00B0 announces it; the
    /// link service decodes its packet and hands it to
    /// [`Controller::execute_released`].
    pub fn take_due_activity(&mut self) -> Option<Activity> {
        // An exposure hold holds every release: the activities wait, in time order,
        // and are released once it ends.
        if self.exposure.active() {
            return None;
        }
        let now = self.obt();
        let a = self.schedule.take_due(now)?;
        self.schedule.released = self.schedule.released.wrapping_add(1);
        self.event(
            EventSeverity::Info,
            event::ACTIVITY_RELEASED,
            [request_id_word(a.request_id), a.release.seconds],
        );
        Some(a)
    }

    /// A released activity's telecommand, as the link decoded it: executed (or
    /// refused) exactly as a received one, its failures watched for event 0x00B1.
    pub fn execute_released(
        &mut self,
        a: &Activity,
        decoded: &Result<crate::link::tc::Telecommand, crate::link::tc::Rejection>,
    ) {
        self.schedule.executing = Some(a.request_id);
        match decoded {
            Ok(tc) => self.execute_telecommand(tc),
            Err(rejection) => self.refuse_telecommand(rejection),
        }
        self.schedule.executing = None;
        if self.ledger.pending.map(|p| p.request_id()) == Some(a.request_id) {
            self.schedule.watched = Some(a.request_id);
        }
    }

    /// Every service-1 report passes here: a failure of a released activity's
    /// telecommand is also event 0x00B1 (request ID; report subtype << 16 | code).
    pub(super) fn note_scheduled_report(&mut self, request_id: RequestId, report: &Verification) {
        let watched = self.schedule.watched == Some(request_id);
        if !watched && self.schedule.executing != Some(request_id) {
            return;
        }
        let failure = report.failure();
        if watched && (failure.is_some() || *report == Verification::CompletionSuccess) {
            self.schedule.watched = None;
        }
        if let Some((code, _)) = failure {
            self.schedule.failed = self.schedule.failed.wrapping_add(1);
            self.event(
                EventSeverity::Medium,
                event::ACTIVITY_FAILED,
                [
                    request_id_word(request_id),
                    (u32::from(report.subtype()) << event::ACTIVITY_SUBTYPE_SHIFT)
                        | u32::from(code),
                ],
            );
        }
    }

    /// The schedule's entries, in release order (TM[11,13]).
    pub fn schedule_summary(&self) -> ScheduleSummary {
        // Not `collect()`: heapless' `FromIterator` has an `expect` (a panic path) for
        // an iterator longer than the capacity; the entries never exceed it.
        let mut summary = ScheduleSummary::new();
        for entry in self.schedule.entries() {
            let _ = summary.push(entry);
        }
        summary
    }

    /// The housekeeping block of the schedule and the time reports.
    pub(super) fn schedule_hk(&self) -> ScheduleHk {
        ScheduleHk {
            activities: u8::try_from(self.schedule.len()).unwrap_or(u8::MAX),
            release_enabled: self.schedule.release_enabled,
            released: self.schedule.released,
            failed: self.schedule.failed,
            next_release: self.schedule.next_release().unwrap_or_default(),
            time_report_rate: self.time_reports.rate().code(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::timing::cycle_to_us;

    /// The 32-bit OBT is the microsecond one, cycle for cycle: every cycle of the first
    /// 2,000 s, then a stride through the whole counter, and its last cycles.
    #[test]
    fn obt_of_cycle_in_32_bits_is_the_microsecond_time() {
        let reference = |c: u32| TmTime::from_micros(cycle_to_us(u64::from(c)));
        let cycles = (0..2_000_000u32)
            .chain((0..u32::MAX).step_by(65_537))
            .chain(u32::MAX - 2_000..=u32::MAX);
        for c in cycles {
            assert_eq!(obt_of_cycle(c), reference(c), "cycle {c}");
        }
    }
}
