//! Time reports (PUS ST[9]): TM[9,2] at the rate TC[9,1] sets.
//!
//! The on-board time (OBT) is the control cycle counter as CUC 4+2
//! ([`Controller::obt`]); it is never set by telecommand. A time report gives the
//! ground a correlation sample whose OBT is known exactly: with the rate 2^N s, one
//! report is queued in the first link pass at or after every OBT multiple of 2^N s (the
//! pass after the control cycle that reaches it), and its OBT field is the time stamp
//! of that pass (the same as the packet's time). Off at boot; not persisted.

use super::verification::Outcome;
use super::{Controller, TmRecord};
use crate::hw::MechanismIo;
use crate::link::time::TimeReportRate;
use crate::timing::CONTROL_RATE_HZ;

/// The time-report state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TimeReports {
    rate: TimeReportRate,
    /// Control cycle (counted without wrap) at or after which the next report is due.
    next_cycle: Option<u64>,
}

impl TimeReports {
    /// Off (the state at boot).
    pub const fn new() -> Self {
        Self {
            rate: TimeReportRate::Off,
            next_cycle: None,
        }
    }

    /// The rate in force.
    pub const fn rate(&self) -> TimeReportRate {
        self.rate
    }
}

/// The first OBT multiple of the rate's period strictly after `cycle` (cycles).
fn next_multiple(rate: TimeReportRate, cycle: u64) -> Option<u64> {
    let period = u64::from(rate.period_s()?) * u64::from(CONTROL_RATE_HZ);
    cycle
        .checked_div(period)?
        .checked_add(1)?
        .checked_mul(period)
}

impl<M: MechanismIo> Controller<M> {
    /// TC[9,1]: the new rate applies from the next multiple of its period.
    pub(super) fn set_time_report_rate(&mut self, rate: TimeReportRate) -> Outcome {
        self.time_reports = TimeReports {
            rate,
            next_cycle: next_multiple(rate, u64::from(self.cycle)),
        };
        Outcome::Done
    }

    /// Queues a time report if one is due (called at the start of every link pass).
    pub(super) fn time_report_due(&mut self) {
        let now = u64::from(self.cycle);
        let Some(next) = self.time_reports.next_cycle else {
            return;
        };
        if now >= next {
            let rate = self.time_reports.rate;
            self.tm.push(self.cycle, TmRecord::TimeReport { rate });
            self.time_reports.next_cycle = next_multiple(rate, now);
        }
    }
}
