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

use core::marker::PhantomData;

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

/// Typestate of a [`Token`]: the telecommand was accepted (its acceptance reported if
/// asked); its start is still to be reported.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Accepted;

/// Typestate of a [`Token`]: the telecommand started (its start reported if asked); its
/// completion is still to be reported.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Started;

/// A telecommand's verification token (sat-rs' model): the request and what its
/// acknowledgement flags ask, in the stage `S` its reports have reached. Made only by
/// [`Controller::accept`]; a start report needs a `Token<Accepted>` and gives a
/// `Token<Started>`, a completion report needs a `Token<Started>`, so no report can be
/// sent out of order, and the rule "success only if the flags ask for it, failure
/// always" is written once, here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Token<S> {
    request_id: RequestId,
    ack: AckFlags,
    _stage: PhantomData<S>,
}

impl<S> Token<S> {
    /// The request the token verifies.
    pub fn request_id(&self) -> RequestId {
        self.request_id
    }

    fn into_stage<T>(self) -> Token<T> {
        Token {
            request_id: self.request_id,
            ack: self.ack,
            _stage: PhantomData,
        }
    }
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
pub(super) enum PendingTc {
    /// Accepted, not started (a move being planned).
    Accepted(Token<Accepted>, PendingKind),
    /// Started, not complete.
    Started(Token<Started>, PendingKind),
}

impl PendingTc {
    /// The pending telecommand is a motion.
    pub fn is_motion(&self) -> bool {
        let (Self::Accepted(_, kind) | Self::Started(_, kind)) = self;
        *kind == PendingKind::Motion
    }

    /// Its request.
    pub fn request_id(&self) -> RequestId {
        match self {
            Self::Accepted(t, _) => t.request_id(),
            Self::Started(t, _) => t.request_id(),
        }
    }
}

impl<M: MechanismIo> Controller<M> {
    /// Queues a verification report; a failure is also remembered for housekeeping.
    pub(super) fn verify(&mut self, request_id: RequestId, report: Verification) {
        if let Some((code, _)) = report.failure() {
            self.ledger.last_failure_code = code;
        }
        self.push_verification(request_id, report);
        // A released schedule activity's failure is also an event (ST[11]).
        self.note_scheduled_report(request_id, &report);
    }

    /// Queues the TM[1,x] record. Out of line: the record (a [`TmRecord`], ~390 bytes)
    /// is built in this frame, which is gone when [`Controller::verify`] goes on to the
    /// event that may follow (whose frame holds a record of its own). Inlined, both
    /// records were on the stack at once, on the deepest path of the control task and
    /// of the link service (flight image, `scripts/stack-depth.py`: `verify` 424 bytes
    /// above `event` 400).
    #[inline(never)]
    fn push_verification(&mut self, request_id: RequestId, report: Verification) {
        self.tm
            .push(self.cycle, TmRecord::Verification { request_id, report });
    }

    /// Acceptance of a decoded telecommand: TM[1,1] if its flags ask.
    pub(super) fn accept(&mut self, request_id: RequestId, ack: AckFlags) -> Token<Accepted> {
        if ack.acceptance() {
            self.verify(request_id, Verification::AcceptanceSuccess);
        }
        Token {
            request_id,
            ack,
            _stage: PhantomData,
        }
    }

    /// Start success: TM[1,3] if the flags ask.
    pub(super) fn start_success(&mut self, t: Token<Accepted>) -> Token<Started> {
        if t.ack.start() {
            self.verify(t.request_id, Verification::StartSuccess);
        }
        t.into_stage()
    }

    /// Start failure: TM[1,4], always.
    pub(super) fn start_failure(&mut self, t: Token<Accepted>, e: &CommandError) {
        self.verify(
            t.request_id,
            Verification::StartFailure {
                code: e.code(),
                data: e.data(),
            },
        );
    }

    /// Completion success: TM[1,7] if the flags ask.
    pub(super) fn completion_success(&mut self, t: Token<Started>) {
        if t.ack.completion() {
            self.verify(t.request_id, Verification::CompletionSuccess);
        }
    }

    /// Completion failure: TM[1,8], always.
    pub(super) fn completion_failure(&mut self, t: Token<Started>, e: &CommandError) {
        self.verify(
            t.request_id,
            Verification::CompletionFailure {
                code: e.code(),
                data: e.data(),
            },
        );
    }

    /// Start and completion of a telecommand executed at once.
    pub(super) fn done(&mut self, t: Token<Accepted>) {
        let started = self.start_success(t);
        self.completion_success(started);
    }

    /// The start report of the pending telecommand, if it has not started: success
    /// (it stays pending, started) or failure (which ends it).
    pub(super) fn start_pending(&mut self, result: Result<(), CommandError>) {
        let Some(PendingTc::Accepted(t, kind)) = self.ledger.pending else {
            return;
        };
        match result {
            Ok(()) => {
                let started = self.start_success(t);
                self.ledger.pending = Some(PendingTc::Started(started, kind));
            }
            Err(e) => {
                self.ledger.pending = None;
                self.start_failure(t, &e);
            }
        }
    }

    /// The last report of the pending telecommand (which ends it): its completion, or,
    /// if it had not started, its start failure (a success ends it as started and
    /// complete).
    pub(super) fn complete_pending(&mut self, result: Result<(), CommandError>) {
        let Some(p) = self.ledger.pending.take() else {
            return;
        };
        let t = match p {
            PendingTc::Started(t, _) => t,
            PendingTc::Accepted(t, _) => match &result {
                Ok(()) => self.start_success(t),
                Err(e) => return self.start_failure(t, e),
            },
        };
        match result {
            Ok(()) => self.completion_success(t),
            Err(e) => self.completion_failure(t, &e),
        }
    }
}
