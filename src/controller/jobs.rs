//! Table jobs: what the controller asks of the background worker (`crate::worker`),
//! the answers, and the controller's side of both.
//!
//! The controller never touches flash and never validates a table in its control
//! cycle: a telecommand that needs it (commit, activate, switch bank, revert to nominal)
//! becomes a [`JobRequest`]; the [`Worker`](crate::worker::Worker), at the lowest priority, does the work in
//! steps ([`Worker::step`](crate::worker::Worker::step): one validation, or one flash operation of the non-blocking
//! store, or one scrub check) and answers with a [`JobResult`], which the controller
//! applies between motions. The two talk only through these messages (on the target
//! two bounded single-producer queues), so the worker never blocks the control task.
//!
//! The worker also scrubs: every [`SCRUB_PERIOD_CYCLES`](crate::timing::SCRUB_PERIOD_CYCLES) the controller sends a
//! [`ScrubImage`] of its running table, derived geometry and supervision thresholds;
//! the worker re-derives them from the table, checks the table's CRC and compares bit
//! for bit. And every [`SCRUB_PERIOD_CYCLES`](crate::timing::SCRUB_PERIOD_CYCLES) the worker reads both flash banks and
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
use crate::table::validate::working_geometry;
use crate::table::{BootSource, CommitReport, Selection, StoreError, Table};

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
    working_geometry(&a.table).is_ok_and(|g| g == a.geom)
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
        geom: working_geometry(table),
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
    /// Out of line: inlined into the link service's job exchange, its match was copied
    /// per result kind.
    #[inline(never)]
    pub fn job_finished(&mut self, result: &JobResult) {
        match *result {
            JobResult::Committed { report, table_id } => {
                self.jobs.running = None;
                self.tables.pending = Some(super::PendingTable { report, table_id });
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
                        if let (Some(p), Some(bank)) =
                            (self.tables.pending, selection.source.bank())
                        {
                            if p.report.bank == bank {
                                self.tables.pending = None;
                            }
                        }
                        self.tables.selection_source = Some(selection.source);
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
                    let id = self.tables.upload.table_id().unwrap_or(0);
                    self.table_rejected(&e, id);
                } else {
                    self.table_rejected(&e, 0);
                }
                self.complete_pending(Err(e));
            }
            JobResult::Scrubbed { generation, ok } => {
                self.jobs.scrub_outstanding = false;
                if generation == self.tables.generation && !ok {
                    self.ram_upset();
                }
            }
            JobResult::Banks { corrupt } => {
                self.tables.bank_health = corrupt;
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
        self.tables.active.table = *table;
        self.tables.active.crc32 = geom.crc32;
        self.tables.active.geom = *g;
        self.tables.active.source = source;
        self.tables.geometry_ok = true;
        self.tables.generation = self.tables.generation.wrapping_add(1);
        self.jobs.scrub_outstanding = false;
        // Derived from the parameters only if they are intact; else the repair
        // re-derives everything from flash (the drives hold meanwhile).
        let params = *self.settings.params.params();
        if self.settings.params.checked().is_none() {
            self.ram_upset();
        }
        self.settings.ops = super::Ops::derive(&params, &self.tables.active.table);
        self.supervisor
            .set_config(params.supervision(&self.tables.active.table));
        // The same strokes are a (slightly) different pose under the new geometry:
        // hold and re-derive the commanded pose.
        self.hold_here();
        self.event(
            EventSeverity::Info,
            super::event::TABLE_ACTIVATED,
            [self.tables.active.table.table_id, self.tables.active.crc32],
        );
        Ok(())
    }
}
