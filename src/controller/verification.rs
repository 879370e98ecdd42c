//! The service-1 verification policy: which report goes out when.
//!
//! * TM[1,1] acceptance success when the packet decodes and the TC asks for it; TM[1,2]
//!   acceptance failure always (link codes 0x05xx), if the packet names a request.
//! * TM[1,3] start success when execution begins and the TC asks for it; TM[1,4] start
//!   failure always, when the controller refuses to begin (state, arguments, workspace).
//! * TM[1,7] completion success when the TC asks for it; TM[1,8] completion failure
//!   always, when something that had started fails (a move ended by a stop or a fault,
//!   a commit refused by validation or by the flash).
//!
//! Immediate telecommands get start and completion in the same cycle. A move gets its
//! start when its path is planned (a few cycles) and its completion on arrival; a table
//! job (commit, activate, switch bank, revert) gets its start at once and its completion
//! when the background worker has finished. At most one such telecommand is pending at a
//! time: another one is refused while it runs (busy, 0x0702, or job busy, 0x070D).

use super::error::CommandError;
use super::{Controller, TmRecord};
use crate::hw::MechanismIo;
use crate::link::tc::{AckFlags, RequestId};
use crate::link::tm::Verification;

/// What executing a telecommand did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Outcome {
    /// Executed completely.
    Done,
    /// A move accepted and being planned: start is reported when the plan is done.
    Planning,
    /// A motion started; completion is reported when it ends.
    Started,
    /// A table job was handed to the background worker; completion follows its result.
    JobStarted,
    /// A move check was taken; its report, start and completion follow its evaluation
    /// ([`Controller::finish_move_check`]).
    CheckQueued,
}

/// What kind of long-running telecommand is pending.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum PendingKind {
    /// A move or direct-stroke move.
    Motion,
    /// A table job.
    Job,
}

/// A telecommand whose start or completion report is still to come.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct PendingTc {
    pub request_id: RequestId,
    pub ack: AckFlags,
    pub kind: PendingKind,
    /// Its start has been reported.
    pub started: bool,
}

impl PendingTc {
    pub fn is_motion(&self) -> bool {
        self.kind == PendingKind::Motion
    }
}

impl<M: MechanismIo> Controller<M> {
    /// Queues a verification report; a failure is also remembered for housekeeping.
    pub(super) fn verify(&mut self, request_id: RequestId, report: Verification) {
        if let Some((code, _)) = report.failure() {
            self.ledger.last_failure_code = code;
        }
        self.tm
            .push(self.cycle, TmRecord::Verification { request_id, report });
        // A released schedule activity's failure is also an event (ST[11]).
        self.note_scheduled_report(request_id, &report);
    }

    /// The start report of the pending telecommand: success (if asked for) or failure
    /// (which ends it).
    pub(super) fn start_pending(&mut self, result: Result<(), CommandError>) {
        let Some(mut p) = self.ledger.pending else {
            return;
        };
        match result {
            Ok(()) => {
                if p.ack.start() {
                    self.verify(p.request_id, Verification::StartSuccess);
                }
                p.started = true;
                self.ledger.pending = Some(p);
            }
            Err(e) => {
                self.ledger.pending = None;
                self.verify(
                    p.request_id,
                    Verification::StartFailure {
                        code: e.code(),
                        data: e.data(),
                    },
                );
            }
        }
    }

    /// The completion report of the pending telecommand (which ends it).
    pub(super) fn complete_pending(&mut self, result: Result<(), CommandError>) {
        let Some(p) = self.ledger.pending.take() else {
            return;
        };
        match result {
            Ok(()) => {
                if p.ack.completion() {
                    self.verify(p.request_id, Verification::CompletionSuccess);
                }
            }
            Err(e) => self.verify(
                p.request_id,
                Verification::CompletionFailure {
                    code: e.code(),
                    data: e.data(),
                },
            ),
        }
    }
}
