//! The background worker: the lowest-priority task that owns the table store (and so
//! the flash), validates tables, writes records through the non-blocking store and
//! checks the scrub snapshots, one bounded step at a time ([`Worker::step`]). It talks
//! to the controller only through the messages of `controller::jobs` ([`JobRequest`],
//! [`JobResult`]): on the target two bounded single-producer queues, so the worker
//! never blocks the control task.
//!
//! What each job does for the operator is described with the messages
//! (`controller::jobs`, "Job semantics").

use crate::controller::jobs::{
    derive_geometry, JobKind, JobRequest, JobResult, ScrubImage, BANK_A_CORRUPT, BANK_B_CORRUPT,
};
use crate::controller::Parameters;
use crate::table::{
    Bank, BootSource, CommitReport, FlashStatus, Selection, StoreError, Table, TableStore,
    ValidationConfig, ValidationState, WriteDone, WritePoll,
};
use crate::timing::SCRUB_PERIOD_CYCLES;
use embedded_storage::nor_flash::NorFlash;

/// An operator job in the worker.
#[derive(Clone, Copy, Debug)]
enum Op {
    /// Commit: first make sure a selection record exists, then validate, then write.
    /// `crc32`: the table's CRC when it was handed over (checked again before the
    /// write: validation takes many steps, and RAM can be upset between them).
    Commit {
        table: Table,
        crc32: u32,
        phase: CommitPhase,
    },
    /// Switch bank: the other bank's table read, being validated; then its selection.
    Switch {
        table: Table,
        selection: Selection,
        params: Parameters,
    },
    /// A selection being written; `table` runs when it is done.
    Select { table: Table },
    /// On-board parameters being written.
    Parameters(Parameters),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CommitPhase {
    /// Writing the running table's selection (no selection record existed).
    Anchor,
    /// Validate (one bounded step per worker step: `validation`), then start the
    /// write.
    Validate,
    /// The record is being written.
    Write,
}

/// The background worker: owns the table store (and so the flash).
#[derive(Debug)]
pub struct Worker<F> {
    store: TableStore<F>,
    validation: ValidationConfig,
    /// The validation in progress (commit, switch bank), a bounded step at a time.
    checking: ValidationState,
    op: Option<Op>,
    scrub: Option<ScrubImage>,
    /// The table of the pending record (what an activation will run).
    pending_table: Option<(CommitReport, Table)>,
    /// A job that failed before any flash work, reported at the next step.
    failed: Option<(JobKind, StoreError)>,
    /// A reload's table, reported at the next step.
    reloaded: Option<(Table, BootSource)>,
    last_bank_check: Option<u32>,
    corrupt: u8,
}

impl<F: NorFlash + FlashStatus> Worker<F> {
    /// The worker of `store` (after boot), validating against `validation`.
    pub fn new(store: TableStore<F>, validation: ValidationConfig) -> Self {
        Self {
            store,
            validation,
            checking: ValidationState::new(),
            op: None,
            scrub: None,
            pending_table: None,
            failed: None,
            reloaded: None,
            last_bank_check: None,
            corrupt: 0,
        }
    }

    /// The store (tests: the flash, power cuts).
    pub fn store_mut(&mut self) -> &mut TableStore<F> {
        &mut self.store
    }

    /// The boot selection ([`TableStore::boot`]) with the worker's validation settings.
    pub fn boot(&mut self) -> (Table, crate::table::BootReport) {
        self.store.boot(&self.validation)
    }

    /// Gives the store back.
    pub fn into_store(self) -> TableStore<F> {
        self.store
    }

    /// Nothing to do until the next request or bank check.
    pub fn is_idle(&self) -> bool {
        self.op.is_none()
            && self.scrub.is_none()
            && self.failed.is_none()
            && self.reloaded.is_none()
    }

    /// Takes (copies) a request and returns true; refused (false, nothing copied) while
    /// an operator job runs, or a scrub is still queued, for a request of that kind.
    /// By reference: the ~1.3 KB request is copied once, from its queue into the worker.
    #[inline(never)]
    pub fn submit(&mut self, request: &JobRequest) -> bool {
        match request {
            JobRequest::Scrub(img) => {
                if self.scrub.is_some() {
                    return false;
                }
                self.scrub = Some(*img);
                true
            }
            _ if self.op.is_some() => false,
            JobRequest::Commit(table) => {
                self.accept_commit(table);
                true
            }
            JobRequest::SaveParameters(params) => {
                self.accept_parameters(params);
                true
            }
            _ => {
                self.op = None;
                // Selections start at once; a refusal is a result, given at the next step.
                self.start_selection(request);
                true
            }
        }
    }

    #[inline(never)]
    fn accept_commit(&mut self, table: &Table) {
        let phase = if self.store.selection().is_none() {
            CommitPhase::Anchor
        } else {
            CommitPhase::Validate
        };
        self.checking = ValidationState::new();
        self.op = Some(Op::Commit {
            table: *table,
            crc32: table.crc32(),
            phase,
        });
    }

    #[inline(never)]
    fn accept_parameters(&mut self, params: &Parameters) {
        match self.store.start_parameters(&params.encode()) {
            Ok(()) => self.op = Some(Op::Parameters(*params)),
            Err(e) => self.fail_later(JobKind::Parameters, e),
        }
    }

    /// Holds a failure to report at the next step.
    fn fail_later(&mut self, kind: JobKind, error: StoreError) {
        self.failed = Some((kind, error));
    }

    /// Starts a selection (activate, switch bank, revert, reload). Each kind out of
    /// line: their table reads are alternatives, never on the stack together.
    fn start_selection(&mut self, request: &JobRequest) {
        match request {
            JobRequest::ActivatePending(report, params) => self.select_pending(report, params),
            JobRequest::SwitchBank(params) => self.select_other_bank(params),
            JobRequest::RevertToNominal(params) => self.begin_select(
                JobKind::Select,
                Selection::nominal(),
                &Table::nominal(),
                params,
            ),
            JobRequest::Reload => self.reload(),
            _ => self.fail_later(JobKind::Select, StoreError::NotExpected),
        }
    }

    #[inline(never)]
    fn select_pending(&mut self, report: &CommitReport, params: &Parameters) {
        match self.pending_table {
            Some((r, t)) if r == *report && self.store.pending() == Some(*report) => self
                .begin_select(
                    JobKind::Select,
                    Selection::bank(r.bank, r.sequence, r.table_crc),
                    &t,
                    params,
                ),
            _ => self.fail_later(JobKind::Select, StoreError::NotExpected),
        }
    }

    /// Switch bank: the table of the bank not running (with nominal running, the bank
    /// with the newest record), read and validated, then its selection persisted.
    #[inline(never)]
    fn select_other_bank(&mut self, params: &Parameters) {
        let kind = JobKind::Select;
        let bank = match self.other_bank() {
            Ok(b) => b,
            Err(e) => return self.fail_later(kind, e),
        };
        match self.store.read_bank(bank) {
            Err(s) => self.fail_later(kind, StoreError::NoRecord(s)),
            // Validated over the next steps (`switch_validate`), then selected.
            Ok((h, t)) => {
                self.checking = ValidationState::new();
                self.op = Some(Op::Switch {
                    table: t,
                    selection: Selection::bank(bank, h.sequence, h.table_crc),
                    params: *params,
                });
            }
        }
    }

    /// One validation step of the table switch bank read; its selection once valid.
    #[inline(never)]
    fn switch_validate(&mut self) -> Option<JobResult> {
        let Some(Op::Switch { table, .. }) = &self.op else {
            return None;
        };
        match self.checking.step(table, &self.validation)? {
            Err(v) => self.op_failed(JobKind::Select, StoreError::Invalid(v)),
            Ok(()) => {
                let Some(Op::Switch {
                    table,
                    selection,
                    params,
                }) = self.op.take()
                else {
                    return None;
                };
                self.begin_select(JobKind::Select, selection, &table, &params);
                None
            }
        }
    }

    #[inline(never)]
    fn reload(&mut self) {
        let sel = self.store.running_selection();
        match self.store.read_selected(&sel) {
            Ok(table) => self.reloaded = Some((table, sel.source)),
            Err(e) => self.fail_later(JobKind::Reload, e),
        }
    }

    /// Persists `sel`; `table` runs when that is done. Refused (0x0437) if `table`'s
    /// following-error thresholds conflict with the overrides in `params`.
    #[inline(never)]
    fn begin_select(&mut self, kind: JobKind, sel: Selection, table: &Table, params: &Parameters) {
        if params.following_conflict(table) {
            return self.fail_later(kind, StoreError::ThresholdConflict);
        }
        match self.store.start_select(&sel) {
            Ok(()) => self.op = Some(Op::Select { table: *table }),
            Err(e) => self.fail_later(kind, e),
        }
    }

    /// The bank switch-bank selects: the bank not running (with nominal running, the
    /// bank with the newest record that reads back complete and valid: a corrupt bank
    /// is skipped).
    #[inline(never)]
    fn other_bank(&mut self) -> Result<Bank, StoreError> {
        Ok(match self.store.running().bank() {
            Some(b) => b.other(),
            // Each bank's header only is kept (its table is dropped before the next
            // read): two tables side by side were 1,152 bytes of the worker's deepest
            // frame chain (`scripts/stack-depth.py`, WORKER).
            None => match (
                self.store.read_bank(Bank::A).map(|(h, _)| h),
                self.store.read_bank(Bank::B).map(|(h, _)| h),
            ) {
                (Ok(ha), Ok(hb)) if crate::table::store::seq_newer(hb.sequence, ha.sequence) => {
                    Bank::B
                }
                (Ok(_), _) => Bank::A,
                (Err(_), Ok(_)) => Bank::B,
                (Err(s), Err(_)) => return Err(StoreError::NoRecord(s)),
            },
        })
    }

    /// One unit of work; returns a result when something finished. `now_cycle` is the
    /// controller's cycle counter (for the bank-check period).
    #[inline(never)]
    pub fn step(&mut self, now_cycle: u32) -> Option<JobResult> {
        if let Some((kind, error)) = self.failed.take() {
            return Some(JobResult::Failed { kind, error });
        }
        if self.reloaded.is_some() {
            return self.take_reloaded();
        }
        // Checked where it is (a ~1 KB image: not moved to the stack).
        if let Some(img) = &self.scrub {
            let result = JobResult::Scrubbed {
                generation: img.generation,
                ok: img.consistent(),
            };
            self.scrub = None;
            return Some(result);
        }
        if self.op.is_some() {
            return self.step_op();
        }
        let due = self
            .last_bank_check
            .is_none_or(|t| now_cycle.wrapping_sub(t) >= SCRUB_PERIOD_CYCLES);
        if due {
            self.last_bank_check = Some(now_cycle);
            let corrupt = self.check_banks();
            if corrupt != self.corrupt {
                self.corrupt = corrupt;
                return Some(JobResult::Banks { corrupt });
            }
        }
        None
    }

    /// The reload's result (out of line: the table is copied once, into the result).
    #[inline(never)]
    fn take_reloaded(&mut self) -> Option<JobResult> {
        let params = self.store.reread_parameters();
        let (table, source) = self.reloaded.as_ref()?;
        let result = JobResult::Reloaded {
            table: *table,
            geom: derive_geometry(table),
            source: *source,
            params,
        };
        self.reloaded = None;
        Some(result)
    }

    /// Reads both banks: a bank with a header whose record does not read back valid is
    /// corrupt (a blank bank is not).
    #[inline(never)]
    fn check_banks(&mut self) -> u8 {
        let mut corrupt = 0;
        for (bank, bit) in [(Bank::A, BANK_A_CORRUPT), (Bank::B, BANK_B_CORRUPT)] {
            match self.store.read_bank(bank) {
                Ok(_) | Err(crate::table::BankStatus::Blank) => {}
                Err(_) => corrupt |= bit,
            }
        }
        corrupt
    }

    /// One step of the running operator job (each phase out of line: their frames are
    /// alternatives, never on the stack together; the job's table is used where it
    /// lies in `self.op`, not copied out).
    #[inline(never)]
    fn step_op(&mut self) -> Option<JobResult> {
        match self.op {
            Some(Op::Commit {
                phase: CommitPhase::Anchor,
                ..
            }) => self.commit_anchor(),
            Some(Op::Commit {
                phase: CommitPhase::Validate,
                ..
            }) => self.commit_validate(),
            Some(Op::Commit {
                phase: CommitPhase::Write,
                ..
            }) => self.commit_write(),
            Some(Op::Parameters(_)) => self.parameters_poll(),
            Some(Op::Switch { .. }) => self.switch_validate(),
            Some(Op::Select { .. }) => self.select_poll(),
            None => None,
        }
    }

    fn set_commit_phase(&mut self, next: CommitPhase) {
        if let Some(Op::Commit { phase, .. }) = &mut self.op {
            *phase = next;
        }
    }

    #[inline(never)]
    fn commit_anchor(&mut self) -> Option<JobResult> {
        if !self.store.writing() {
            let sel = self.store.running_selection();
            if let Err(e) = self.store.start_select(&sel) {
                return self.op_failed(JobKind::Commit, e);
            }
        }
        match self.store.poll() {
            WritePoll::Pending => None,
            WritePoll::Done(Err(e)) => self.op_failed(JobKind::Commit, e),
            WritePoll::Done(Ok(_)) | WritePoll::Idle => {
                self.set_commit_phase(CommitPhase::Validate);
                None
            }
        }
    }

    #[inline(never)]
    fn commit_validate(&mut self) -> Option<JobResult> {
        let Some(Op::Commit { table, crc32, .. }) = &self.op else {
            return None;
        };
        if let Err(v) = self.checking.step(table, &self.validation)? {
            return self.op_failed(JobKind::Commit, StoreError::Invalid(v));
        }
        // What was validated over many steps is what was handed over: an upset of the
        // copy here meanwhile is refused, never written.
        if table.crc32() != *crc32 {
            return self.op_failed(JobKind::Commit, StoreError::NotExpected);
        }
        self.pending_table = None;
        let Some(Op::Commit { table, .. }) = &self.op else {
            return None;
        };
        match self.store.start_commit(table) {
            Ok(_) => {
                self.set_commit_phase(CommitPhase::Write);
                None
            }
            Err(e) => self.op_failed(JobKind::Commit, e),
        }
    }

    #[inline(never)]
    fn commit_write(&mut self) -> Option<JobResult> {
        match self.store.poll() {
            WritePoll::Pending => None,
            WritePoll::Done(Ok(WriteDone::Committed(report))) => {
                let Some(Op::Commit { table, .. }) = &self.op else {
                    return None;
                };
                let table_id = table.table_id;
                self.pending_table = Some((report, *table));
                self.op = None;
                Some(JobResult::Committed { report, table_id })
            }
            WritePoll::Done(Err(e)) => self.op_failed(JobKind::Commit, e),
            WritePoll::Done(Ok(WriteDone::Selected(_))) | WritePoll::Idle => {
                self.op_failed(JobKind::Commit, StoreError::Busy)
            }
        }
    }

    #[inline(never)]
    fn parameters_poll(&mut self) -> Option<JobResult> {
        match self.store.poll() {
            WritePoll::Pending => None,
            WritePoll::Done(Ok(WriteDone::Selected(_))) => {
                let Some(Op::Parameters(params)) = self.op.take() else {
                    return None;
                };
                Some(JobResult::ParametersSaved(params))
            }
            WritePoll::Done(Err(e)) => self.op_failed(JobKind::Parameters, e),
            WritePoll::Done(Ok(WriteDone::Committed(_))) | WritePoll::Idle => {
                self.op_failed(JobKind::Parameters, StoreError::Busy)
            }
        }
    }

    #[inline(never)]
    fn select_poll(&mut self) -> Option<JobResult> {
        match self.store.poll() {
            WritePoll::Pending => None,
            WritePoll::Done(Ok(WriteDone::Selected(selection))) => {
                if selection.source.bank().is_some()
                    && self
                        .pending_table
                        .is_some_and(|(r, _)| Some(r.bank) == selection.source.bank())
                {
                    self.pending_table = None;
                }
                let Some(Op::Select { table }) = &self.op else {
                    return None;
                };
                let result = JobResult::Selected {
                    table: *table,
                    geom: derive_geometry(table),
                    selection,
                };
                self.op = None;
                Some(result)
            }
            WritePoll::Done(Err(e)) => self.op_failed(JobKind::Select, e),
            WritePoll::Done(Ok(WriteDone::Committed(_))) | WritePoll::Idle => {
                self.op_failed(JobKind::Select, StoreError::Busy)
            }
        }
    }

    /// The operation in progress ends with `error`. Not inlined: nine failure paths
    /// end here (100 bytes of flash less).
    #[inline(never)]
    fn op_failed(&mut self, kind: JobKind, error: StoreError) -> Option<JobResult> {
        self.op = None;
        if kind == JobKind::Commit {
            self.pending_table = None;
        }
        Some(JobResult::Failed { kind, error })
    }
}
