//! Table jobs: what the controller asks of the background worker, and the worker.
//!
//! The controller never touches flash and never validates a table in its control
//! cycle: a telecommand that needs it (commit, activate, switch bank, revert to nominal)
//! becomes a [`JobRequest`]; the [`Worker`], at the lowest priority, does the work in
//! steps ([`Worker::step`]: one validation, or one flash operation of the non-blocking
//! store, or one scrub check) and answers with a [`JobResult`], which the controller
//! applies between motions. The two talk only through these messages (on the target
//! two bounded single-producer queues), so the worker never blocks the control task.
//!
//! The worker also scrubs: every [`SCRUB_PERIOD_CYCLES`] the controller sends a
//! [`ScrubImage`] of its running table, derived geometry and supervision thresholds;
//! the worker re-derives them from the table, checks the table's CRC and compares bit
//! for bit. And every [`SCRUB_PERIOD_CYCLES`] the worker reads both flash banks and
//! reports a change of their health.
//!
//! ## Job semantics (what the operator sees)
//! * **Commit**: validate, then write the table into the bank not holding the running
//!   table; it becomes the *pending* table. What boots does not change: before the first
//!   commit on a flash without a selection record, the worker records the running
//!   table as the selection, so a commit can never make a table boot that the operator
//!   did not select.
//! * **Activate (pending)**: persist a selection naming the pending record (bank,
//!   sequence, CRC), then the controller runs it.
//! * **Switch bank**: the table of the bank not running (with the nominal table
//!   running: the bank with the newest record): read, validate, persist its selection,
//!   run it. A pending table in that bank is thereby activated.
//! * **Revert to nominal**: persist the nominal selection, run the nominal table; it
//!   stays selected across resets.
//! * **Reload**: re-read the running table from its bank and the parameters from their
//!   persisted record (after a RAM upset); CRC-checked, they are the validated table
//!   byte for byte and the persisted set. An upset found while another job runs is
//!   repaired as soon as that job ends (its result is applied first).
//! * Activate, switch bank and revert to nominal fail with 0x0437 before anything is
//!   persisted if the table's following-error thresholds and the overrides in force
//!   would leave the warning not below the fault threshold.

use super::{ActiveTable, Controller};
use crate::hw::MechanismIo;
use crate::kinematics::{Geometry, GeometryError};
use crate::link::tm::EventSeverity;
use crate::supervision::{FaultFlags, SupervisionConfig};
use crate::table::{
    validate, Bank, BootSource, CommitReport, FlashStatus, Selection, StoreError, Table,
    TableStore, ValidationConfig, WriteDone, WritePoll,
};
use crate::timing::SCRUB_PERIOD_CYCLES;
use embedded_storage::nor_flash::NorFlash;

/// The kinds of operator job (housekeeping `job` byte).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JobKind {
    /// Validate and write a table (1).
    Commit,
    /// Persist a selection and run it: activate, switch bank, revert (2).
    Select,
    /// Re-read the running table after a RAM upset (3).
    Reload,
    /// Persist on-board parameters (4).
    Parameters,
}

impl JobKind {
    /// Wire code (0 is "no job").
    pub const fn code(self) -> u8 {
        match self {
            JobKind::Commit => 1,
            JobKind::Select => 2,
            JobKind::Reload => 3,
            JobKind::Parameters => 4,
        }
    }
}

/// A snapshot of the controller's running configuration, for the RAM scrub.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScrubImage {
    /// The table generation the snapshot was taken of.
    pub generation: u32,
    /// The running table with its CRC and derived geometry.
    pub active: ActiveTable,
    /// The supervisor's thresholds.
    pub supervision: SupervisionConfig,
    /// The on-board parameters and their check word.
    pub params: super::params::InForce,
    /// What they and the table make of the settings.
    pub ops: super::Ops,
}

impl ScrubImage {
    /// True when the image is self-consistent: the table's CRC is the recorded one, the
    /// parameters agree with their check word (any flipped bit of either is found), and
    /// the geometry, thresholds and settings are exactly what the table and the
    /// parameters derive.
    #[inline(never)]
    pub fn consistent(&self) -> bool {
        let a = &self.active;
        a.table.crc32() == a.crc32
            && geometry_matches(a)
            && self.params.checked().is_some_and(|p| {
                p.supervision(&a.table) == self.supervision
                    && super::Ops::derive(p, &a.table) == self.ops
            })
    }
}

/// The running table's derived geometry is exactly what its table derives (out of
/// line: the re-derived geometry is on the stack alone, not a whole `ActiveTable`).
#[inline(never)]
fn geometry_matches(a: &ActiveTable) -> bool {
    Geometry::new(&a.table.geometry_params()).is_ok_and(|g| g == a.geom)
}

/// What the controller asks of the worker. The messages carry whole tables by value
/// (no heap in flight code): they live in two bounded static queues, and a copy of
/// about a kilobyte per job or scrub is cheap next to the work it asks for.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JobRequest {
    /// Validate and write the table (pending afterwards).
    Commit(Table),
    /// Select the pending table committed as in this report (with the parameters in
    /// force, against which its thresholds are checked).
    ActivatePending(CommitReport, super::Parameters),
    /// Select the other bank's table (thresholds checked against the parameters).
    SwitchBank(super::Parameters),
    /// Select the nominal table (thresholds checked against the parameters).
    RevertToNominal(super::Parameters),
    /// Re-read the running table from its source.
    Reload,
    /// Persist these on-board parameters (with the selection record).
    SaveParameters(super::Parameters),
    /// Check this snapshot of the running configuration.
    Scrub(ScrubImage),
}

impl JobRequest {
    /// The operator-job kind (`None` for a scrub).
    pub const fn kind(&self) -> Option<JobKind> {
        match self {
            JobRequest::Commit(_) => Some(JobKind::Commit),
            JobRequest::ActivatePending(..)
            | JobRequest::SwitchBank(_)
            | JobRequest::RevertToNominal(_) => Some(JobKind::Select),
            JobRequest::Reload => Some(JobKind::Reload),
            JobRequest::SaveParameters(_) => Some(JobKind::Parameters),
            JobRequest::Scrub(_) => None,
        }
    }
}

/// What the worker derives from a table before the controller runs it, so that
/// neither is computed under the controller's lock ([`Controller::job_finished`] only
/// copies them): the f64 geometry derivation and the (bitwise) CRC are most of an
/// activation's cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DerivedGeometry {
    /// The working geometry ([`Geometry::new`] of the table's parameters).
    pub geom: Result<Geometry<f32>, GeometryError>,
    /// The CRC-32 of the table's encoding (what housekeeping and event 0x0010 report).
    pub crc32: u32,
}

/// Derives `table`'s working geometry and CRC (out of line: its f64 parameters and its
/// encoding are on the stack alone).
#[inline(never)]
pub fn derive_geometry(table: &Table) -> DerivedGeometry {
    DerivedGeometry {
        geom: Geometry::new(&table.geometry_params()),
        crc32: table.crc32(),
    }
}

/// What the worker answers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JobResult {
    /// The table was validated and written: it is pending.
    Committed {
        /// Where.
        report: CommitReport,
        /// Its table ID.
        table_id: u32,
    },
    /// A selection was persisted: run this table.
    Selected {
        /// The table.
        table: Table,
        /// Its working geometry, derived by the worker (not under the controller's
        /// lock: the f64 derivation is most of an activation's cost).
        geom: DerivedGeometry,
        /// What was selected.
        selection: Selection,
    },
    /// The on-board parameters were persisted: run with them.
    ParametersSaved(super::Parameters),
    /// The running table, re-read from its source, and the persisted parameters.
    Reloaded {
        /// The table.
        table: Table,
        /// Its working geometry, derived by the worker.
        geom: DerivedGeometry,
        /// Its source.
        source: BootSource,
        /// The parameters of the newest selection record, as persisted.
        params: [u8; crate::table::store::PARAMETERS_LEN],
    },
    /// An operator job failed; nothing in RAM changed (a failed commit leaves the
    /// target bank without a valid record, never the running one).
    Failed {
        /// Which job.
        kind: JobKind,
        /// Why.
        error: StoreError,
    },
    /// The RAM scrub of a generation: consistent or not.
    Scrubbed {
        /// The generation checked.
        generation: u32,
        /// The image was consistent.
        ok: bool,
    },
    /// The flash banks' health changed: bit 0 bank A, bit 1 bank B holds a header but
    /// its record no longer reads back CRC-valid.
    Banks {
        /// The health bits.
        corrupt: u8,
    },
}

/// Bank-health bit of bank A ([`JobResult::Banks`]).
pub const BANK_A_CORRUPT: u8 = 1 << 0;
/// Bank-health bit of bank B.
pub const BANK_B_CORRUPT: u8 = 1 << 1;

/// The controller's side: at most one operator job and one scrub outstanding.
#[derive(Clone, Copy, Debug)]
pub(super) struct JobLane {
    outbox: Option<JobRequest>,
    /// Always a [`JobRequest::Scrub`]: kept as the request so that it is handed to the
    /// worker by reference, never rebuilt on the stack.
    scrub: Option<JobRequest>,
    running: Option<JobKind>,
    scrub_outstanding: bool,
    /// The parameters the running TC[20,3] names (bit i = parameter index i): event
    /// 0x0040's aux0 when they are persisted.
    pub parameters_named: u32,
    /// A RAM upset was found while a job ran: reload when it ends.
    reload_wanted: bool,
}

impl JobLane {
    pub const fn new() -> Self {
        Self {
            outbox: None,
            scrub: None,
            running: None,
            scrub_outstanding: false,
            parameters_named: 0,
            reload_wanted: false,
        }
    }

    /// Queues an operator job; refused with the running job's kind while one runs.
    pub fn submit(&mut self, request: JobRequest) -> Result<(), JobKind> {
        if let Some(k) = self.running {
            return Err(k);
        }
        self.running = request.kind();
        self.outbox = Some(request);
        Ok(())
    }

    /// [`JobLane::submit`] of a commit of `table`, copied once, straight into the
    /// outbox (not via a ~1.3 KB request on the stack).
    #[inline(never)]
    pub fn submit_commit(&mut self, table: &Table) -> Result<(), JobKind> {
        if let Some(k) = self.running {
            return Err(k);
        }
        self.running = Some(JobKind::Commit);
        self.outbox = Some(JobRequest::Commit(*table));
        Ok(())
    }

    /// The outstanding scrub (if any) was of an older generation: forget it.
    pub fn scrub_done(&mut self) {
        self.scrub_outstanding = false;
    }

    /// True when a scrub snapshot may be queued (none outstanding).
    pub fn scrub_wanted(&self) -> bool {
        !self.scrub_outstanding
    }

    /// Queues a scrub snapshot (after [`JobLane::scrub_wanted`]).
    pub fn request_scrub(&mut self, image: &ScrubImage) {
        self.scrub = Some(JobRequest::Scrub(*image));
        self.scrub_outstanding = true;
    }

    /// The running operator job's code (0: none).
    pub fn running_code(&self) -> u8 {
        self.running.map_or(0, JobKind::code)
    }
}

impl<M: MechanismIo> Controller<M> {
    /// Offers the next request for the worker (an operator job first, then a scrub
    /// snapshot) to `send`, by reference: it copies the request where it goes and
    /// returns true, and the request leaves the controller; or it returns false (no
    /// room), and the request stays for the next offer. Returns whether one was taken.
    /// (A request is ~1.3 KB: handing it on by reference keeps it off the stack.)
    pub fn offer_job_request(&mut self, send: impl FnOnce(&JobRequest) -> bool) -> bool {
        let slot = if self.jobs.outbox.is_some() {
            &mut self.jobs.outbox
        } else {
            &mut self.jobs.scrub
        };
        match slot {
            Some(r) if send(r) => {
                *slot = None;
                true
            }
            _ => false,
        }
    }

    /// Applies the worker's answer (between motions: no motion starts while a job runs).
    pub fn job_finished(&mut self, result: &JobResult) {
        match *result {
            JobResult::Committed { report, table_id } => {
                self.jobs.running = None;
                self.pending_table = Some(super::PendingTable { report, table_id });
                self.event(
                    EventSeverity::Info,
                    super::event::TABLE_COMMITTED,
                    [table_id, u32::from(BootSource::from(report.bank).code())],
                );
                self.complete_pending(Ok(()));
            }
            JobResult::Selected {
                ref table,
                ref geom,
                selection,
            } => {
                self.jobs.running = None;
                match self.run_table(table, geom, selection.source) {
                    Ok(()) => {
                        if let (Some(p), Some(bank)) = (self.pending_table, selection.source.bank())
                        {
                            if p.report.bank == bank {
                                self.pending_table = None;
                            }
                        }
                        self.selection_source = Some(selection.source);
                        self.complete_pending(Ok(()));
                    }
                    Err(e) => {
                        self.table_rejected(&e, table.table_id);
                        self.complete_pending(Err(e));
                    }
                }
            }
            JobResult::ParametersSaved(params) => {
                self.jobs.running = None;
                self.apply_parameters(params);
                self.event(
                    EventSeverity::Info,
                    super::event::PARAMETERS_CHANGED,
                    [self.jobs.parameters_named, params.set_mask()],
                );
                self.complete_pending(Ok(()));
            }
            JobResult::Reloaded {
                ref table,
                ref geom,
                source,
                ref params,
            } => {
                self.jobs.running = None;
                self.restore_parameters_for(params, table);
                if self.run_table(table, geom, source).is_ok() {
                    self.supervisor
                        .set_external_condition(FaultFlags::TABLE_CORRUPT, false);
                    self.event(
                        EventSeverity::Medium,
                        super::event::TABLE_RELOADED,
                        [table.table_id, u32::from(source.code())],
                    );
                }
            }
            JobResult::Failed { kind, error } => {
                self.jobs.running = None;
                let e = super::CommandError::Store(error);
                if kind == JobKind::Commit {
                    let id = self.upload.table_id().unwrap_or(0);
                    self.table_rejected(&e, id);
                } else {
                    self.table_rejected(&e, 0);
                }
                self.complete_pending(Err(e));
            }
            JobResult::Scrubbed { generation, ok } => {
                self.jobs.scrub_outstanding = false;
                if generation == self.generation && !ok {
                    self.ram_upset();
                }
            }
            JobResult::Banks { corrupt } => {
                self.bank_health = corrupt;
                self.event(
                    if corrupt == 0 {
                        EventSeverity::Info
                    } else {
                        EventSeverity::Medium
                    },
                    super::event::BANK_HEALTH,
                    [u32::from(corrupt), 0],
                );
            }
        }
        // An upset found while a job ran is repaired now that it has ended.
        if self.jobs.reload_wanted && self.jobs.running.is_none() {
            self.queue_reload();
        }
        self.publish_state();
    }

    /// Queues the reload of the running table and the persisted parameters.
    fn queue_reload(&mut self) {
        self.jobs.reload_wanted = false;
        self.jobs.running = Some(JobKind::Reload);
        self.jobs.outbox = Some(JobRequest::Reload);
    }

    /// The RAM image of the running table or of the parameters is corrupt: latch the
    /// fault, hold at once (no ramp computed with a corrupt geometry), and reload both
    /// from flash (now, or when the job that runs ends).
    pub(super) fn ram_upset(&mut self) {
        self.supervisor
            .raise_external(FaultFlags::TABLE_CORRUPT, true);
        self.event(
            EventSeverity::High,
            super::event::FAULT_LATCHED,
            [
                self.supervisor.latched().bits(),
                FaultFlags::TABLE_CORRUPT.bits(),
            ],
        );
        self.hold_now();
        if self.jobs.running.is_none() {
            self.queue_reload();
        } else {
            self.jobs.reload_wanted = true;
        }
    }

    /// Runs `table` from `source` at rest with `geom`, its geometry as the worker
    /// derived it: swap, hold, report (event 0x0010). Nothing changes if its geometry
    /// did not derive. The table is copied once, into the running slot.
    #[inline(never)]
    fn run_table(
        &mut self,
        table: &Table,
        geom: &DerivedGeometry,
        source: BootSource,
    ) -> Result<(), super::CommandError> {
        let g = geom
            .geom
            .as_ref()
            .map_err(|_| super::CommandError::Store(StoreError::NotExpected))?;
        self.active.table = *table;
        self.active.crc32 = geom.crc32;
        self.active.geom = *g;
        self.active.source = source;
        self.geometry_ok = true;
        self.generation = self.generation.wrapping_add(1);
        self.jobs.scrub_outstanding = false;
        // Derived from the parameters only if they are intact; else the repair
        // re-derives everything from flash (the drives hold meanwhile).
        let params = *self.params.params();
        if self.params.checked().is_none() {
            self.ram_upset();
        }
        self.ops = super::Ops::derive(&params, &self.active.table);
        self.supervisor
            .set_config(params.supervision(&self.active.table));
        // The same strokes are a (slightly) different pose under the new geometry:
        // hold and re-derive the commanded pose.
        self.hold_here();
        self.event(
            EventSeverity::Info,
            super::event::TABLE_ACTIVATED,
            [self.active.table.table_id, self.active.crc32],
        );
        Ok(())
    }
}

/// An operator job in the worker.
#[derive(Clone, Copy, Debug)]
enum Op {
    /// Commit: first make sure a selection record exists, then validate, then write.
    Commit { table: Table, phase: CommitPhase },
    /// A selection being written; `table` runs when it is done.
    Select { table: Table },
    /// On-board parameters being written.
    Parameters(super::Parameters),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CommitPhase {
    /// Writing the running table's selection (no selection record existed).
    Anchor,
    /// Validate (one step), then start the write.
    Validate,
    /// The record is being written.
    Write,
}

/// The background worker: owns the table store (and so the flash).
#[derive(Debug)]
pub struct Worker<F> {
    store: TableStore<F>,
    validation: ValidationConfig,
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
        self.op = Some(Op::Commit {
            table: *table,
            phase,
        });
    }

    #[inline(never)]
    fn accept_parameters(&mut self, params: &super::Parameters) {
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
    fn select_pending(&mut self, report: &CommitReport, params: &super::Parameters) {
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
    fn select_other_bank(&mut self, params: &super::Parameters) {
        let kind = JobKind::Select;
        let bank = match self.other_bank() {
            Ok(b) => b,
            Err(e) => return self.fail_later(kind, e),
        };
        match self.store.read_bank(bank) {
            Err(s) => self.fail_later(kind, StoreError::NoRecord(s)),
            Ok((h, t)) => match validate(&t, &self.validation) {
                Err(v) => self.fail_later(kind, StoreError::Invalid(v)),
                Ok(()) => self.begin_select(
                    kind,
                    Selection::bank(bank, h.sequence, h.table_crc),
                    &t,
                    params,
                ),
            },
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
    fn begin_select(
        &mut self,
        kind: JobKind,
        sel: Selection,
        table: &Table,
        params: &super::Parameters,
    ) {
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
            None => match (self.store.read_bank(Bank::A), self.store.read_bank(Bank::B)) {
                (Ok((ha, _)), Ok((hb, _)))
                    if crate::table::store::seq_newer(hb.sequence, ha.sequence) =>
                {
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
        let Some(Op::Commit { table, .. }) = &self.op else {
            return None;
        };
        if let Err(v) = validate(table, &self.validation) {
            return self.op_failed(JobKind::Commit, StoreError::Invalid(v));
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

    fn op_failed(&mut self, kind: JobKind, error: StoreError) -> Option<JobResult> {
        self.op = None;
        if kind == JobKind::Commit {
            self.pending_table = None;
        }
        Some(JobResult::Failed { kind, error })
    }
}
