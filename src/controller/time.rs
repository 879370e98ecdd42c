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

/// The first OBT multiple of the rate's period strictly after `cycle` (cycles). The
/// quotient in 32 bits (the cycle counter is a u32; a period beyond u32 has quotient
/// 0): no 64-bit division routine in the flight image.
fn next_multiple(rate: TimeReportRate, cycle: u32) -> Option<u64> {
    let period = u64::from(rate.period_s()?) * u64::from(CONTROL_RATE_HZ);
    let quotient = match u32::try_from(period) {
        Ok(p) => cycle.checked_div(p)?,
        Err(_) => 0,
    };
    u64::from(quotient).checked_add(1)?.checked_mul(period)
}

impl<M: MechanismIo> Controller<M> {
    /// TC[9,1]: the new rate applies from the next multiple of its period.
    pub(super) fn set_time_report_rate(&mut self, rate: TimeReportRate) -> Outcome {
        self.time_reports = TimeReports {
            rate,
            next_cycle: next_multiple(rate, self.cycle),
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
            self.time_reports.next_cycle = next_multiple(rate, self.cycle);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 32-bit quotient is the 64-bit one for every rate, at and around multiples
    /// and at the ends of the counter.
    #[test]
    fn next_multiple_in_32_bits_is_the_64_bit_one() {
        let reference = |rate: TimeReportRate, cycle: u32| {
            let period = u64::from(rate.period_s()?) * u64::from(CONTROL_RATE_HZ);
            u64::from(cycle)
                .checked_div(period)?
                .checked_add(1)?
                .checked_mul(period)
        };
        for exponent in 0..=31u8 {
            let rate = TimeReportRate::Every { exponent };
            let period = u64::from(rate.period_s().unwrap_or(1)) * u64::from(CONTROL_RATE_HZ);
            let mut cycles = vec![0, 1, 999, 1000, 1001, u32::MAX - 1, u32::MAX];
            for k in 1..4u64 {
                for d in [-1i64, 0, 1] {
                    if let Ok(c) = u32::try_from((k * period) as i64 + d) {
                        cycles.push(c);
                    }
                }
            }
            for c in cycles {
                assert_eq!(
                    next_multiple(rate, c),
                    reference(rate, c),
                    "2^{exponent} s, cycle {c}"
                );
            }
        }
        assert_eq!(next_multiple(TimeReportRate::Off, 5), None);
    }
}
