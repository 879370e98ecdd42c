//! Invariant 5: every telecommand gets its service-1 reports in a valid order, none
//! lost; finished telecommands are retired and counted.

use crate::link::tm::Verification;

use super::{Choices, Soak};

impl<C: Choices> Soak<C> {
    /// Checks the report order of every telecommand in flight; retires finished ones.
    /// `dying`: the controller is about to reboot (incomplete reports are fine then).
    pub fn check_reports(&mut self, dying: bool) {
        let mut keep = Vec::new();
        let in_flight = std::mem::take(&mut self.in_flight);
        for (rid, from) in in_flight {
            let reps = self.r.st.reports_since(from, rid);
            let finished = match report_order(&reps) {
                Ok(f) => f,
                Err(e) => {
                    self.violation(format!("TC {rid:?}: {e}: {reps:?}"));
                    continue;
                }
            };
            if finished {
                self.tcs_done += 1;
                let hold_code = crate::controller::CommandError::ExposureHold(0).code();
                if reps
                    .iter()
                    .any(|r| r.failure().is_some_and(|(c, _)| c == hold_code))
                {
                    self.hold_refusals += 1;
                }
                // A parameter set that completed is in force now (invariant 8's model),
                // and persisted (invariant 9 checks the flash).
                let set = self.setting.iter().position(|(r, _)| *r == rid);
                if let Some(k) = set.filter(|_| self.check_persisted_parameters()) {
                    self.setting.remove(k);
                    if reps.last() == Some(&Verification::CompletionSuccess) {
                        self.read_step_limits_from_model();
                    }
                }
                // A selection refused at start changed nothing; one that completed (or
                // failed after starting) is known from the events.
                self.selecting.retain(|(r, _)| *r != rid);
                if reps.last() == Some(&Verification::CompletionSuccess) {
                    self.completed += 1;
                }
            } else if !dying {
                keep.push((rid, from));
            }
        }
        self.in_flight = keep;
    }
}

/// A valid service-1 sequence (all acknowledgements requested): `[1,2]`, or `[1,1]` then
/// `[1,4]`, or `[1,1] [1,3]` then `[1,7]` or `[1,8]`; a prefix of one while in flight.
/// Returns whether it is complete.
fn report_order(reps: &[Verification]) -> Result<bool, &'static str> {
    use Verification::*;
    Ok(match reps {
        [] => false,
        [AcceptanceFailure { .. }] => true,
        [AcceptanceSuccess] => false,
        [AcceptanceSuccess, StartFailure { .. }] => true,
        [AcceptanceSuccess, StartSuccess] => false,
        [AcceptanceSuccess, StartSuccess, CompletionSuccess | CompletionFailure { .. }] => true,
        _ => return Err("reports out of order or duplicated"),
    })
}
