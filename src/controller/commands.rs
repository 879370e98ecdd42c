//! Telecommand dispatch: a decoded telecommand (the link decided its acceptance)
//! executed, with its start and completion reports.

use super::error::CommandError;
use super::jobs::{JobKind, JobRequest};
use super::telemetry::DumpChunk;
use super::verification::{Accepted, Outcome, PendingKind, PendingTc, Token};
use super::{event, Controller, TmRecord};
use crate::hw::MechanismIo;
use crate::link::command::TABLE_CHUNK_MAX_LEN;
use crate::link::tc::{Rejection, Telecommand};
use crate::link::tm::{EventSeverity, Verification};
use crate::link::{Command, MemoryId};
use crate::table::TABLE_LEN;
use crate::units::NM_PER_MM_F32;

impl<M: MechanismIo> Controller<M> {
    /// A telecommand the link refused (its decoder's code): counted and reported
    /// (TM[1,2] if the packet named a request); nothing else changes.
    pub fn refuse_telecommand(&mut self, rej: &Rejection) {
        self.settle_move_check();
        self.ledger.rejected = self.ledger.rejected.wrapping_add(1);
        match rej.request_id {
            Some(rid) => self.verify(rid, Verification::acceptance_failure(&rej.error)),
            None => self.ledger.last_failure_code = rej.error.code(),
        }
    }

    /// A telecommand the link decoded and accepted: acceptance reported (if asked),
    /// executed, its start and completion reported as they come. A refused telecommand
    /// changes nothing but the counters and the reports.
    pub fn execute_telecommand(&mut self, tc: &Telecommand) {
        self.settle_move_check();
        self.ledger.accepted = self.ledger.accepted.wrapping_add(1);
        let token = self.accept(tc.request_id, tc.ack);
        let result = self.execute(tc, token);
        self.report_outcome(tc, token, result);
        self.publish_state();
    }

    /// A move check a caller without a link service left uncollected: evaluated and
    /// reported now, before the next telecommand (none is lost, the order is kept).
    fn settle_move_check(&mut self) {
        if self.motion.check.is_some() {
            self.run_move_check();
        }
    }

    /// The reports an execution's outcome calls for now; a long-running telecommand
    /// becomes the pending one ([`PendingTc`]), reported as it goes on.
    fn report_outcome(
        &mut self,
        tc: &Telecommand,
        token: Token<Accepted>,
        result: Result<Outcome, CommandError>,
    ) {
        match result {
            Ok(Outcome::Done) => self.done(token),
            // Start and completion follow the check's report (`finish_move_check`).
            Ok(Outcome::CheckQueued) => {}
            // Start success or failure is reported when the plan is done. A newer
            // long-running TC cannot start while one is pending (busy), so no report is
            // lost here or below.
            Ok(Outcome::Planning) => {
                self.ledger.pending = Some(PendingTc::Accepted(token, PendingKind::Motion))
            }
            Ok(Outcome::Started) => {
                let started = self.start_success(token);
                self.ledger.pending = Some(PendingTc::Started(started, PendingKind::Motion));
            }
            Ok(Outcome::JobStarted) => {
                let started = self.start_success(token);
                self.ledger.pending = Some(PendingTc::Started(started, PendingKind::Job));
            }
            Err(e) => {
                self.refusal_event(&tc.command, &e);
                self.start_failure(token, &e);
            }
        }
    }

    /// The event that accompanies a refused move or table command.
    fn refusal_event(&mut self, command: &Command, e: &CommandError) {
        match command {
            Command::MoveAbsolute(_) | Command::MoveRelative(_) => {
                let refusal = match e {
                    CommandError::Motion(_) => e.data(),
                    _ => 0,
                };
                self.event(
                    EventSeverity::Low,
                    event::MOVE_REFUSED,
                    [refusal, u32::from(e.code())],
                );
            }
            Command::CommitTable { .. } => {
                let id = self.tables.upload.table_id().unwrap_or(0);
                self.table_rejected(e, id);
            }
            Command::ActivateTable { .. } | Command::SwitchBank | Command::RevertToNominal => {
                self.table_rejected(e, 0)
            }
            _ => {}
        }
    }

    /// Event 0x0011: a table command refused or failed.
    pub(super) fn table_rejected(&mut self, e: &CommandError, table_id: u32) {
        self.event(
            EventSeverity::Medium,
            event::TABLE_REJECTED,
            [u32::from(e.code()), table_id],
        );
    }

    /// Not inlined (nor are its table and parameter arms): the decoded telecommand in
    /// the caller's frame and an arm's locals (a table, a job request) are each on the
    /// stack once, never merged with the move planner's frame.
    #[inline(never)]
    fn execute(
        &mut self,
        tc: &Telecommand,
        token: Token<Accepted>,
    ) -> Result<Outcome, CommandError> {
        match tc.command {
            Command::Ping => {
                self.tm.push(self.cycle, TmRecord::PingReply);
                Ok(Outcome::Done)
            }
            Command::HousekeepingOneShot => {
                self.queue_housekeeping();
                Ok(Outcome::Done)
            }
            Command::MoveAbsolute(target) => self.start_move(target.to_pose()),
            Command::CheckMove(target) => {
                self.queue_move_check(token, target.to_pose());
                Ok(Outcome::CheckQueued)
            }
            Command::ReportParameters(ids) => {
                let mask = super::params::named_mask(ids.ids().iter().copied())
                    .map_err(CommandError::Parameter)?;
                self.intact_parameters()?;
                let values = self.parameter_values(mask);
                self.tm.push(self.cycle, TmRecord::Parameters(values));
                Ok(Outcome::Done)
            }
            Command::SetParameters(ref values) => self.set_parameters(values.entries()),
            Command::MoveRelative(delta) => {
                let target = self.relative_target(delta.to_pose())?;
                self.start_move(target)
            }
            Command::Stop => {
                // A pending move's completion failure is reported when it comes to rest.
                self.begin_stop();
                Ok(Outcome::Done)
            }
            Command::ClearFault => {
                self.require_idle()?;
                let latched = self.supervisor.latched();
                self.supervisor
                    .clear()
                    .map_err(CommandError::FaultPersists)?;
                if !latched.is_empty() {
                    self.event(
                        EventSeverity::Info,
                        event::FAULTS_CLEARED,
                        [latched.bits(), 0],
                    );
                }
                // Resume from where the drives hold.
                self.hold_here();
                Ok(Outcome::Done)
            }
            Command::ExposureHold { timeout_s } => {
                self.set_exposure_hold(timeout_s);
                Ok(Outcome::Done)
            }
            Command::DirectStroke { leg, delta_nm } => {
                self.start_direct_stroke(leg, delta_nm as f32 / NM_PER_MM_F32)
            }
            Command::LoadTableChunk(chunk) => {
                self.tables.upload.load(chunk.offset_bytes(), chunk.bytes());
                Ok(Outcome::Done)
            }
            Command::CommitTable { crc32 } => self.commit_uploaded(crc32),
            Command::ActivateTable { table_id, crc32 } => {
                self.require_idle()?;
                let p = self.tables.pending.ok_or(CommandError::NoPending)?;
                if p.table_id != table_id || p.report.table_crc != crc32 {
                    return Err(CommandError::PendingMismatch {
                        pending_id: p.table_id,
                    });
                }
                let params = self.intact_parameters()?;
                self.start_job(JobRequest::ActivatePending(p.report, params))
            }
            Command::SwitchBank | Command::RevertToNominal => {
                self.require_idle()?;
                let params = self.intact_parameters()?;
                self.start_job(if matches!(tc.command, Command::SwitchBank) {
                    JobRequest::SwitchBank(params)
                } else {
                    JobRequest::RevertToNominal(params)
                })
            }
            // Time-based schedule (ST[11]) and time reports (ST[9]).
            Command::Schedule(ref op) => self.execute_schedule(op),
            Command::SetTimeReportRate(rate) => Ok(self.set_time_report_rate(rate)),
            Command::DumpTable(memory) => {
                self.queue_dump(memory);
                Ok(Outcome::Done)
            }
        }
    }

    /// TC[8,1] set parameters: applied between motions only, after they are persisted.
    #[inline(never)]
    fn set_parameters(&mut self, entries: &[(u16, i32)]) -> Result<Outcome, CommandError> {
        self.require_idle()?;
        let new = self
            .intact_parameters()?
            .with(entries, &self.tables.active.table)
            .map_err(CommandError::Parameter)?;
        let named = super::params::named_mask(entries.iter().map(|(id, _)| *id))
            .map_err(CommandError::Parameter)?;
        let outcome = self.start_job(JobRequest::SaveParameters(new))?;
        self.jobs.parameters_named = named;
        Ok(outcome)
    }

    /// Commit of the uploaded table. Commits happen at rest only (a flash erase can
    /// stall a single-bank device for seconds); moves wait until the job is done.
    #[inline(never)]
    fn commit_uploaded(&mut self, crc32: u32) -> Result<Outcome, CommandError> {
        self.require_idle()?;
        let table = self.tables.upload.check(crc32)?;
        self.jobs
            .submit_commit(&table)
            .map_err(|kind: JobKind| CommandError::JobBusy(kind.code()))?;
        self.tables.upload.clear_received();
        self.tables.pending = None;
        Ok(Outcome::JobStarted)
    }

    /// The parameters in force, checked against their check word: a flipped bit is a
    /// RAM upset (fault 0x100 latched, the repair queued) and the telecommand is refused
    /// with 0x0701, so an upset value is never built on, reported or persisted.
    fn intact_parameters(&mut self) -> Result<super::Parameters, CommandError> {
        match self.settings.params.checked() {
            Some(p) => Ok(*p),
            None => {
                self.ram_upset();
                Err(CommandError::Faulted(self.supervisor.latched()))
            }
        }
    }

    fn start_job(&mut self, request: JobRequest) -> Result<Outcome, CommandError> {
        self.jobs
            .submit(request)
            .map_err(|kind: JobKind| CommandError::JobBusy(kind.code()))?;
        Ok(Outcome::JobStarted)
    }

    /// The effective values (ID, value) of the parameters in `mask`, in index order
    /// (TM[20,2]).
    pub fn parameter_values(&self, mask: u32) -> super::telemetry::ParameterValues {
        let mut out = heapless::Vec::new();
        for (k, def) in super::params::PARAMETERS.iter().enumerate() {
            if mask & (1 << k) != 0 {
                let _ = out.push((
                    def.id,
                    self.settings
                        .params
                        .params()
                        .value(k, &self.tables.active.table),
                ));
            }
        }
        out
    }

    /// TC[6,5]: the image of `memory` as it is now, queued as chunks of at most
    /// [`TABLE_CHUNK_MAX_LEN`] bytes in offset order. Out of line: the 516-byte image
    /// is on the stack here only.
    #[inline(never)]
    fn queue_dump(&mut self, memory: MemoryId) {
        let image = match memory {
            MemoryId::ActiveTable => self.tables.active.table.to_bytes(),
            MemoryId::UploadBuffer => *self.tables.upload.bytes(),
        };
        for offset in (0..TABLE_LEN).step_by(TABLE_CHUNK_MAX_LEN) {
            let chunk = u16::try_from(offset)
                .ok()
                .and_then(|o| DumpChunk::of(memory, &image, o));
            if let Some(chunk) = chunk {
                self.tm.push(self.cycle, TmRecord::DumpChunk(chunk));
            }
        }
    }
}
