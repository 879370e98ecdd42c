//! The controller: the mechanism's state, its control cycle and its telecommands.
//!
//! # Who calls what, at which priority
//! The firmware runs three kinds of work (`main.rs`, RTIC); the host bench
//! (`sim::Bench`) calls the same functions in the same order, one control cycle at a
//! time:
//! 1. **Control task** (highest priority, 1 kHz timer): [`Controller::control_cycle`]
//!    reads the encoders, runs FK, supervision and the motion, commands the drives,
//!    and queues telemetry records. Bounded: it never waits for I/O, never decodes or
//!    encodes packets, never touches flash.
//! 2. **Link service** (below it): [`comms::LinkService`] deframes received bytes,
//!    hands each telecommand to [`Controller::handle_telecommand`] (at most
//!    [`comms::MAX_TC_PER_PASS`] per pass), encodes queued telemetry records into
//!    frames, and moves job requests and results between the controller and the
//!    background worker.
//! 3. **Background** (lowest priority): [`jobs::Worker`] validates tables, writes
//!    flash through the non-blocking store, scrubs the flash banks and checks the RAM
//!    image of the running table.
//!
//! # A control cycle, in order
//! 1. encoders ([`StrokeEncoders`]), their warnings ([`EncoderWarnings`]) and the
//!    end-of-travel switches ([`EndOfTravel`]), one read each; a change to a non-empty
//!    set of active switches is event [`event::END_OF_TRAVEL`];
//! 2. FK warm-started from the last pose;
//! 3. supervision ([`Supervisor`]): a new fault stops any motion at the acceleration
//!    limit (a corrupted running table holds at once), latches, and is reported;
//! 4. motion: the active trajectory's setpoint pose -> IK -> six strokes -> drives
//!    ([`SliderDrives`]), or a direct-stroke move; at rest the drives are polled. A
//!    leg whose end-of-travel switch is active (or unreadable) is never commanded
//!    further toward it, from the cycle the switch is seen to the end of that motion;
//! 5. periodic work: housekeeping every `hk_period` cycles (a parameter, default
//!    [`crate::timing::HK_PERIOD_CYCLES`]), a RAM-scrub snapshot every
//!    [`SCRUB_PERIOD_CYCLES`];
//! 6. the state event if the state changed.
//!
//! # Rules an operator can rely on (each has a test)
//! * a rejected telecommand changes nothing (acceptance or start failure, with a code);
//! * a move is all-or-nothing: refused with every workspace reason unless every leg can
//!   make the whole path; no move while a fault is latched, while moving or while a
//!   table job runs;
//! * every motion starts from the strokes the drives hold
//!   ([`SliderDrives::setpoints_mm`]), so its first setpoint is continuous with them;
//!   a direct-stroke move moves one leg from its own held setpoint and every other leg
//!   keeps exactly its setpoint;
//! * tables change between motions only; a commit never changes what boots; what the
//!   operator last selected (activate, switch bank, revert to nominal) is what boots;
//! * completion of a move is reported when the mirror has arrived (TM[1,7]) or, if a
//!   stop or a fault ended it, as a completion failure (TM[1,8]);
//! * an end-of-travel switch stops its leg in that direction in the cycle it is seen and
//!   latches [`FaultFlags::LIMIT_SWITCH`]; until it is cleared only direct strokes away
//!   from the switches seen are accepted, and the clear only once no switch is active.
//!
//! [`StrokeEncoders`]: crate::hw::StrokeEncoders
//! [`EncoderWarnings`]: crate::hw::EncoderWarnings
//! [`EndOfTravel`]: crate::hw::EndOfTravel
//! [`SliderDrives`]: crate::hw::SliderDrives
//! [`SliderDrives::setpoints_mm`]: crate::hw::SliderDrives::setpoints_mm

pub mod comms;
pub mod error;
pub mod jobs;
pub mod params;
pub mod schedule;
pub mod telemetry;
pub mod time;

mod commands;
pub mod motion;
mod verification;

use crate::hw::{counts_to_mm, DriveError, MechanismIo, TravelSwitches};
use crate::kinematics::{
    fk, FkConfig, FkError, FkSolution, Frames, Geometry, GeometryError, Pose, LEGS,
};
use crate::link::tm::EventSeverity;
use crate::link::{Housekeeping, WirePose};
use crate::motion::MotionLimits;
use crate::supervision::{CycleInputs, FaultFlags, Supervisor};
use crate::table::upload::UploadBuffer;
use crate::table::{BootReport, BootSource, CommitReport, Table};
use crate::timing::{cycle_to_us, SCRUB_PERIOD_CYCLES};

pub use crate::worker::Worker;
pub use error::CommandError;
// The reset cause and boot count are the board's (the hardware seam, `hw`), reported here.
pub use crate::hw::{ResetCause, ResetInfo};
pub use jobs::{JobRequest, JobResult};
pub use params::Parameters;
pub use telemetry::{HkSample, Stamped, TmConsumer, TmProducer, TmQueue, TmRecord};

/// Event IDs of service 5 (the ICD's table; aux words in the link's `event_id` docs).
pub use crate::link::tm::event_id as event;

use motion::Motion;
use verification::PendingTc;

/// Path samples (IK evaluations) a move's planning may use per control cycle: the
/// ~17 samples of a plan are spread over a few cycles (9 at most) so that no cycle
/// carries them all. Two: with four the planning cycles of the flight image took up
/// to 23,327 instructions, over the 20,000 budget (`m2cyclebench`, move scenario).
pub const PLAN_SAMPLES_PER_CYCLE: usize = 2;
/// Consecutive control-cycle overruns after which motion stops and
/// [`FaultFlags::DEADLINE_MISSED`] latches ([`Controller::note_overrun`]).
pub const OVERRUN_HOLD_LIMIT: u16 = 3;

/// Controller state, as reported in housekeeping (`code()`). Derived from the motion
/// and the latched faults ([`Controller::state`]), never stored separately.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    /// Holding position, ready for commands.
    Idle,
    /// Following a trajectory (or planning one).
    Moving,
    /// Decelerating to rest after a stop or a fault.
    Stopping,
    /// A direct-stroke (recovery) move.
    StrokeMoving,
    /// At rest with a latched fault: moves refused until cleared.
    Faulted,
}

impl State {
    /// Wire code.
    pub const fn code(self) -> u8 {
        match self {
            State::Idle => 0,
            State::Moving => 1,
            State::Stopping => 2,
            State::StrokeMoving => 3,
            State::Faulted => 4,
        }
    }
}

/// What the on-board parameters and the running table make of the controller's
/// settings (derived, and checked by the RAM scrub).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ops {
    /// The pivot and user frame.
    pub frames: Frames<f32>,
    /// Coordinated-move limits.
    pub motion: MotionLimits,
    /// Direct-stroke speed (mm/s), acceleration (mm/s^2), largest delta (mm).
    pub direct: (f32, f32, f32),
    /// Housekeeping period (cycles).
    pub hk_period_cycles: u32,
}

impl Ops {
    /// The settings of `params` with `table` running.
    pub fn derive(params: &Parameters, table: &Table) -> Self {
        Self {
            frames: params.frames(table),
            motion: params.motion_limits(table),
            direct: params.direct_limits(table),
            hk_period_cycles: params.hk_period_cycles(table),
        }
    }
}

/// The running table and everything derived from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActiveTable {
    /// The table.
    pub table: Table,
    /// Its CRC-32.
    pub crc32: u32,
    /// The working geometry (f32) derived from it.
    pub geom: Geometry<f32>,
    /// Where it came from.
    pub source: BootSource,
}

impl ActiveTable {
    /// Derives the working geometry of `table`.
    pub fn new(table: Table, source: BootSource) -> Result<Self, GeometryError> {
        let geom = Geometry::new(&table.geometry_params())?;
        Ok(Self {
            crc32: table.crc32(),
            table,
            geom,
            source,
        })
    }
}

/// A committed table waiting for activation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PendingTable {
    /// Where it was written.
    pub report: CommitReport,
    /// Its table ID.
    pub table_id: u32,
}

/// The M2 mechanism controller.
pub struct Controller<M> {
    /// The six slider drives and encoders (drivers on the target, the simulated plant
    /// on the host); owned: nothing else commands them.
    mech: M,
    active: ActiveTable,
    /// The on-board parameters (ST[20]) with their check word, and what they make of
    /// the settings.
    params: params::InForce,
    ops: Ops,
    /// The running geometry is usable; `false` only after a defect (the compiled-in
    /// nominal table failed to derive): every motion is refused.
    geometry_ok: bool,
    /// Counts activations and reloads; scrub results name the generation they checked.
    generation: u32,
    boot: BootReport,
    reset: ResetInfo,
    pending_table: Option<PendingTable>,
    /// What the operator's last completed selection chose (`None`: none made since
    /// boot and no selection record found at boot).
    selection_source: Option<BootSource>,
    upload: UploadBuffer,
    supervisor: Supervisor,
    motion: Motion,
    /// The state last reported by event (the derived state is [`Controller::state`]).
    reported_state: State,
    /// The telecommand whose start or completion report is still to come.
    tc_pending: Option<PendingTc>,
    /// A move check executed but not yet evaluated (the link service evaluates it
    /// outside the controller's lock: [`motion::MoveCheckJob`]).
    move_check: Option<motion::MoveCheckJob>,
    jobs: jobs::JobLane,
    fk_cfg: FkConfig<f32>,
    /// Last good FK pose (warm start and telemetry).
    pose_fk: Pose<f32>,
    fk_valid: bool,
    fk_iterations: u8,
    /// The pose of the commanded/held strokes: the last path setpoint, or FK of the
    /// strokes the drives hold.
    pose_commanded: Pose<f32>,
    /// The strokes commanded to the drives in the last cycle, or (at rest) the strokes
    /// they hold.
    strokes_commanded_mm: [f32; LEGS],
    /// The output stage every command passes (`motion::limiter`).
    limiter: crate::motion::OutputLimiter,
    /// Last encoder reading and whether it is this cycle's.
    encoders_mm: [f32; LEGS],
    encoders_valid: bool,
    last_drive: Result<(), DriveError>,
    moving_prev: bool,
    warnings: FaultFlags,
    /// The end-of-travel switches and reference sensors as read in the last cycle.
    switches: TravelSwitches,
    /// Every switch seen active or unreadable while [`FaultFlags::LIMIT_SWITCH`] has
    /// been latched: the directions a direct stroke may not take until the clear.
    switches_since_latch: TravelSwitches,
    /// Legs the current motion may not move toward smaller / larger strokes: every
    /// switch seen since the motion began (a switch that releases mid-motion keeps its
    /// leg held, so the command never jumps back to the path).
    clamp_negative: u8,
    clamp_positive: u8,
    /// The set of active switches last reported by [`event::END_OF_TRAVEL`] (its aux0).
    end_of_travel_reported: u32,
    /// Control cycles run since boot: the motion time base and the telemetry clock.
    cycle: u32,
    /// Its end of the telemetry queue (the link service holds the other).
    tm: TmProducer,
    tc_accepted: u16,
    tc_rejected: u16,
    last_failure_code: u16,
    refusal_bits: u32,
    overruns: u16,
    consecutive_overruns: u16,
    /// Flash-bank health from the background scrub: bit 0 bank A, bit 1 bank B corrupt.
    bank_health: u8,
    boot_event_sent: bool,
    /// Persisted parameters not applied at boot (event 0x0041 after the boot events).
    params_ignored_at_boot: u32,
    /// A stop or a fault ended a move while it was being planned.
    plan_aborted: bool,
    // Time-based schedule (ST[11]) and time reports (ST[9]): not persisted, empty and
    // off at boot.
    schedule: schedule::Schedule,
    time_reports: time::TimeReports,
}

impl<M: MechanismIo> Controller<M> {
    /// Starts on the table boot selected (`table`, `boot`: [`crate::table::TableStore::boot`]),
    /// queuing its telemetry through `tm`; holds the sliders where their drives are and
    /// takes the first reading.
    pub fn new(mech: M, table: Table, boot: BootReport, tm: TmProducer) -> Self {
        let mut c = Self::unstarted(mech, table, boot, tm);
        c.start();
        c
    }

    /// [`Controller::new`] in two steps, for a board that builds the controller in
    /// place (a static slot: `slot.write(Controller::unstarted(..)).start()`), so the
    /// ~6 KB struct is never copied on the stack. Until [`Controller::start`] the
    /// drives are not held and no reading was taken: call it before the first cycle.
    #[inline(always)]
    pub fn unstarted(mech: M, table: Table, boot: BootReport, tm: TmProducer) -> Self {
        let (active, geometry_ok) = match ActiveTable::new(table, boot.source) {
            Ok(a) => (a, true),
            // A booted table was validated, so this is a defect guard: fall back to the
            // nominal table; if even that fails, run without motion.
            Err(_) => match ActiveTable::new(Table::nominal(), BootSource::Nominal) {
                Ok(a) => (a, true),
                Err(_) => (nominal_placeholder(), false),
            },
        };
        let params = params::InForce::new(Parameters::none());
        let supervisor = Supervisor::new(params.params().supervision(&active.table));
        let ops = Ops::derive(params.params(), &active.table);
        Self {
            mech,
            active,
            params,
            ops,
            geometry_ok,
            generation: 0,
            boot,
            reset: ResetInfo::default(),
            pending_table: None,
            selection_source: boot.selection.map(|s| s.source),
            upload: UploadBuffer::new(),
            supervisor,
            motion: Motion::Hold,
            reported_state: State::Idle,
            tc_pending: None,
            move_check: None,
            jobs: jobs::JobLane::new(),
            fk_cfg: FkConfig::default(),
            pose_fk: Pose::home(),
            fk_valid: false,
            fk_iterations: 0,
            pose_commanded: Pose::home(),
            strokes_commanded_mm: [0.0; LEGS],
            limiter: crate::motion::OutputLimiter::new(
                &params.params().step_limits(&active.table),
                [0.0; LEGS],
            ),
            encoders_mm: [0.0; LEGS],
            encoders_valid: false,
            last_drive: Ok(()),
            moving_prev: false,
            warnings: FaultFlags::empty(),
            switches: TravelSwitches::default(),
            switches_since_latch: TravelSwitches::default(),
            clamp_negative: 0,
            clamp_positive: 0,
            end_of_travel_reported: 0,
            cycle: 0,
            tm,
            tc_accepted: 0,
            tc_rejected: 0,
            last_failure_code: 0,
            refusal_bits: 0,
            overruns: 0,
            consecutive_overruns: 0,
            bank_health: 0,
            boot_event_sent: false,
            params_ignored_at_boot: 0,
            plan_aborted: false,
            schedule: schedule::Schedule::new(),
            time_reports: time::TimeReports::new(),
        }
    }

    /// [`Controller::unstarted`] written into `slot` (the flight image's static slot).
    /// Not inlined, with the construction inlined into it: the optimiser then writes
    /// each field into the slot instead of building the whole struct on the stack and
    /// copying it (the boot stack of the flight image).
    #[inline(never)]
    pub fn unstarted_in(
        slot: &mut core::mem::MaybeUninit<Self>,
        mech: M,
        table: Table,
        boot: BootReport,
        tm: TmProducer,
    ) -> &mut Self {
        slot.write(Self::unstarted(mech, table, boot, tm))
    }

    /// Second step of [`Controller::unstarted`]: holds the sliders where their drives
    /// are and takes the first reading.
    pub fn start(&mut self) {
        self.hold_here();
        let first = self.mech.read_counts();
        self.switches = self.mech.read_switches();
        if let Ok(counts) = first {
            self.encoders_mm = counts_to_mm(&counts);
            self.encoders_valid = true;
            if let Ok(sol) = fk(
                &self.active.geom,
                &self.encoders_mm,
                &self.pose_fk,
                &self.fk_cfg,
            ) {
                self.pose_fk = sol.pose;
                self.fk_valid = true;
            }
        }
    }

    /// Restores the on-board parameters persisted with the selection record
    /// ([`crate::table::TableStore::parameters`]); call once after [`Controller::new`].
    /// What is not applied (out of range, or the following-error overrides that would
    /// conflict with the booted table: [`Parameters::from_persisted`]) is reported by
    /// event 0x0041 after the boot events.
    pub fn restore_parameters(&mut self, persisted: &[u8; crate::table::store::PARAMETERS_LEN]) {
        let table = self.active.table;
        self.restore_parameters_for(persisted, &table);
    }

    /// [`Controller::restore_parameters`] for `table` (the one about to run).
    fn restore_parameters_for(
        &mut self,
        persisted: &[u8; crate::table::store::PARAMETERS_LEN],
        table: &Table,
    ) {
        let (params, ignored) = Parameters::from_persisted(persisted, table);
        self.apply_parameters(params);
        if ignored != 0 {
            if self.boot_event_sent {
                self.report_parameters_ignored(ignored);
            } else {
                self.params_ignored_at_boot = ignored;
            }
        }
    }

    /// Event 0x0041: persisted parameters not applied.
    fn report_parameters_ignored(&mut self, ignored: u32) {
        self.event(EventSeverity::Low, event::PARAMETERS_IGNORED, [ignored, 0]);
    }

    /// Runs with `params`: derived settings and the supervision thresholds follow.
    fn apply_parameters(&mut self, params: Parameters) {
        self.params = params::InForce::new(params);
        self.ops = Ops::derive(&params, &self.active.table);
        self.limiter
            .set_limits(&params.step_limits(&self.active.table));
        self.supervisor
            .set_config(params.supervision(&self.active.table));
        self.generation = self.generation.wrapping_add(1);
        self.jobs.scrub_done();
    }

    /// The on-board parameters (as they are in RAM).
    pub fn parameters(&self) -> &Parameters {
        self.params.params()
    }

    /// Records the board's reset cause and boot counter (call once, before the first
    /// cycle: the boot event reports them).
    pub fn set_reset_info(&mut self, info: ResetInfo) {
        self.reset = info;
    }

    /// Holds every drive where it is, takes the held strokes as the commanded ones and
    /// their pose as the commanded pose.
    #[inline(never)]
    fn hold_here(&mut self) {
        self.mech.hold();
        self.sync_to_drives();
    }

    /// Takes the strokes the drives hold as the commanded strokes and derives their pose
    /// (FK, warm-started from the last commanded pose). The pose is kept if FK fails.
    fn sync_to_drives(&mut self) {
        let held = self.mech.setpoints_mm();
        self.strokes_commanded_mm = held;
        if let Ok(sol) = fk(&self.active.geom, &held, &self.pose_commanded, &self.fk_cfg) {
            self.pose_commanded = sol.pose;
        }
    }

    /// One control cycle (the module documentation lists its steps). Bounded: no I/O
    /// wait, no packet work, no flash.
    pub fn control_cycle(&mut self) {
        if !self.boot_event_sent {
            self.boot_event_sent = true;
            self.emit_boot_events();
        }
        // 1. Encoders, their warnings, the end-of-travel switches.
        let readings = self.mech.read_counts().map(|c| counts_to_mm(&c));
        let encoder_warning_legs = self.mech.warning_legs();
        self.switches = self.mech.read_switches();
        self.report_end_of_travel();
        // 2. Forward kinematics, warm-started.
        let fk_result: Option<Result<FkSolution<f32>, FkError>> = match &readings {
            Ok(s) => {
                self.encoders_mm = *s;
                self.encoders_valid = true;
                Some(fk(&self.active.geom, s, &self.pose_fk, &self.fk_cfg))
            }
            Err(_) => {
                self.encoders_valid = false;
                None
            }
        };
        match &fk_result {
            Some(Ok(sol)) => {
                self.pose_fk = sol.pose;
                self.fk_valid = true;
                self.fk_iterations = sol.iterations;
            }
            _ => self.fk_valid = false,
        }
        // 3. Supervision. At rest the reference is what the drives hold now (a drive
        //    re-referenced after missed steps holds a corrected setpoint).
        if matches!(self.motion, Motion::Hold) {
            let held = self.mech.setpoints_mm();
            if held != self.strokes_commanded_mm {
                self.strokes_commanded_mm = held;
                if let Ok(sol) = fk(&self.active.geom, &held, &self.pose_commanded, &self.fk_cfg) {
                    self.pose_commanded = sol.pose;
                }
            }
        }
        let verdict = self.supervisor.check(&CycleInputs {
            encoders: readings,
            commanded_prev_mm: self.strokes_commanded_mm,
            motion_commanded: self.moving_prev,
            fk: fk_result,
            drive: self.last_drive,
            switches: self.switches,
            encoder_warning_legs,
        });
        self.switches_since_latch = if verdict.latched.contains(FaultFlags::LIMIT_SWITCH) {
            or_switches(&self.switches_since_latch, &self.switches)
        } else {
            TravelSwitches::default()
        };
        if verdict.warnings != self.warnings {
            self.warnings = verdict.warnings;
            self.event(
                EventSeverity::Low,
                event::WARNING_CHANGED,
                [verdict.warnings.bits(), u32::from(verdict.warning_legs)],
            );
        }
        if !verdict.new_faults.is_empty() {
            self.event(
                EventSeverity::High,
                event::FAULT_LATCHED,
                [
                    verdict.latched.bits(),
                    verdict.new_faults.bits() | (u32::from(verdict.new_fault_legs) << 24),
                ],
            );
            self.begin_stop();
        }
        // 4. Motion.
        self.step_motion();
        // 5. Periodic work.
        if self.cycle % self.ops.hk_period_cycles.max(1) == 0 {
            self.queue_housekeeping();
        }
        if self.cycle % SCRUB_PERIOD_CYCLES == 0 && self.jobs.scrub_wanted() {
            self.queue_scrub();
        }
        // 6. State.
        self.publish_state();
        self.cycle = self.cycle.wrapping_add(1);
    }

    /// Queues the scrub snapshot of the running configuration for the worker. Not
    /// inlined: the ~1.3 KB snapshot is not on the stack with the cycle's motion step.
    #[inline(never)]
    fn queue_scrub(&mut self) {
        self.jobs.request_scrub(&jobs::ScrubImage {
            generation: self.generation,
            active: self.active,
            supervision: *self.supervisor.config(),
            params: self.params,
            ops: self.ops,
        });
    }

    /// The board saw this control cycle overrun its period (the timer fired again before
    /// the cycle ended). Counted; [`OVERRUN_HOLD_LIMIT`] consecutive overruns stop any
    /// motion and raise [`event::DEADLINE_MISSED`]. A cycle that met its deadline is
    /// reported with [`Controller::note_deadline_met`].
    pub fn note_overrun(&mut self) {
        self.overruns = self.overruns.wrapping_add(1);
        self.consecutive_overruns = self.consecutive_overruns.saturating_add(1);
        if self.consecutive_overruns == OVERRUN_HOLD_LIMIT {
            self.supervisor
                .raise_external(FaultFlags::DEADLINE_MISSED, true);
            self.event(
                EventSeverity::High,
                event::DEADLINE_MISSED,
                [
                    u32::from(self.consecutive_overruns),
                    u32::from(self.overruns),
                ],
            );
            self.begin_stop();
        }
    }

    /// The last control cycle finished within its period (a latched deadline fault
    /// becomes clearable).
    pub fn note_deadline_met(&mut self) {
        if self.consecutive_overruns > 0 {
            self.consecutive_overruns = 0;
            self.supervisor
                .set_external_condition(FaultFlags::DEADLINE_MISSED, false);
        }
    }

    /// Event [`event::END_OF_TRAVEL`] when the set of active end-of-travel switches (or
    /// unreadable inputs) changes to a non-empty one.
    fn report_end_of_travel(&mut self) {
        let word = end_of_travel_word(&self.switches);
        if word != self.end_of_travel_reported {
            self.end_of_travel_reported = word;
            if word != 0 {
                self.event(
                    EventSeverity::High,
                    event::END_OF_TRAVEL,
                    [word, self.cycle],
                );
            }
        }
    }

    /// Legs a direct stroke may not move toward smaller (`.0`) and larger (`.1`) strokes:
    /// the switches of the last read, and while [`FaultFlags::LIMIT_SWITCH`] is latched
    /// every switch seen since it latched.
    pub(super) fn end_of_travel_blocked(&self) -> (u8, u8) {
        let mut s = self.switches;
        if self.supervisor.latched().contains(FaultFlags::LIMIT_SWITCH) {
            s = or_switches(&s, &self.switches_since_latch);
        }
        (s.blocked_negative(), s.blocked_positive())
    }

    fn emit_boot_events(&mut self) {
        let sev = if self.boot.fell_back || !self.geometry_ok {
            EventSeverity::Low
        } else {
            EventSeverity::Info
        };
        self.event(
            sev,
            event::BOOT,
            [
                u32::from(self.boot.source.code()),
                self.active.table.table_id,
            ],
        );
        self.event(
            EventSeverity::Info,
            event::BOOT_DETAIL,
            [
                self.boot.flags_word(),
                u32::from(self.reset.cause.code()) | (u32::from(self.reset.boot_count) << 16),
            ],
        );
        if self.params_ignored_at_boot != 0 {
            self.report_parameters_ignored(self.params_ignored_at_boot);
        }
    }

    /// The state as derived from the motion and the latched faults.
    pub fn state(&self) -> State {
        match &self.motion {
            Motion::Hold => {
                if self.supervisor.latched().is_empty() {
                    State::Idle
                } else {
                    State::Faulted
                }
            }
            Motion::Planning(_) => State::Moving,
            Motion::Path { stopping: true, .. } | Motion::Stroke { stopping: true, .. } => {
                State::Stopping
            }
            Motion::Path { .. } => State::Moving,
            Motion::Stroke { .. } => State::StrokeMoving,
        }
    }

    /// Reports a state change (event 0x0001) if the derived state differs from the one
    /// last reported.
    fn publish_state(&mut self) {
        let now = self.state();
        if now != self.reported_state {
            let old = self.reported_state;
            self.reported_state = now;
            self.event(
                EventSeverity::Info,
                event::STATE_CHANGED,
                [u32::from(old.code()), u32::from(now.code())],
            );
        }
    }

    fn event(&mut self, severity: EventSeverity, id: u16, aux: [u32; 2]) {
        self.tm
            .push(self.cycle, TmRecord::Event { severity, id, aux });
    }

    /// Queues a housekeeping report with the sample of now (stamped with this cycle,
    /// whose number it carries).
    fn queue_housekeeping(&mut self) {
        let sample = self.hk_sample();
        self.tm.push(self.cycle, TmRecord::Housekeeping(sample));
    }

    /// The housekeeping report of now (the link service adds its own counters).
    pub fn housekeeping(&self) -> Housekeeping {
        self.hk_sample().to_report()
    }

    /// The housekeeping sample of now, its poses and strokes in working units (the link
    /// service converts them, [`HkSample::to_report`], and adds its own counters).
    pub fn hk_sample(&self) -> HkSample {
        let moving_legs = match &self.motion {
            Motion::Hold | Motion::Planning(_) => 0,
            Motion::Path { .. } => crate::supervision::ALL_LEGS,
            Motion::Stroke { mv, .. } => 1u8.checked_shl(u32::from(mv.leg())).unwrap_or(0),
        };
        let latched = self.supervisor.latched();
        let report = Housekeeping {
            state: self.state().code(),
            boot_source: self.boot.source.code(),
            active_bank: self.active.source.code(),
            fk_iterations: self.fk_iterations,
            fk_valid: self.fk_valid,
            cycle_counter: self.cycle,
            fault_flags: latched.bits(),
            warning_flags: self.warnings.bits(),
            refusal_bits: self.refusal_bits,
            active_table_id: self.active.table.table_id,
            active_table_crc32: self.active.crc32,
            pose_fk: WirePose::default(),
            pose_commanded: WirePose::default(),
            strokes_commanded_nm: [0; LEGS],
            encoders_nm: [0; LEGS],
            tc_accepted: self.tc_accepted,
            tc_rejected: self.tc_rejected,
            last_failure_code: self.last_failure_code,
            moving_legs,
            fault_legs: self.supervisor.latched_legs(latched),
            pending_bank: self
                .pending_table
                .map_or(0, |p| BootSource::from(p.report.bank).code()),
            pending_table_id: self.pending_table.map_or(0, |p| p.table_id),
            job: self.jobs.running_code(),
            selected_source: self
                .selection_source
                .map_or(crate::link::hk::NO_SELECTION, |s| s.code()),
            tm_dropped: self.tm.dropped(),
            tc_frames_dropped: 0,
            uart_overruns: 0,
            cycle_overruns: self.overruns,
            reset_cause: self.reset.cause.code(),
            boot_count: self.reset.boot_count,
            bank_health: self.bank_health,
            pivot_nm: self.pivot_nm(),
            pose_fk_operator: WirePose::default(),
            pose_commanded_operator: WirePose::default(),
            parameters_set: self.params.params().set_mask(),
            schedule: self.schedule_hk(),
            limit_lower_legs: self.switches.lower,
            limit_upper_legs: self.switches.upper,
            reference_legs: self.switches.reference,
            switch_unreadable_legs: self.switches.unreadable,
        };
        HkSample {
            report,
            pose_fk: self.pose_fk,
            pose_commanded: self.pose_commanded,
            strokes_commanded_mm: self.strokes_commanded_mm,
            encoders_mm: self.encoders_mm,
            pose_fk_operator: self.ops.frames.to_operator(&self.pose_fk),
            pose_commanded_operator: self.ops.frames.to_operator(&self.pose_commanded),
        }
    }

    /// The pivot (M's coordinates, nm), as set.
    fn pivot_nm(&self) -> [i32; 3] {
        let k = params::index::PIVOT;
        [0, 1, 2].map(|i| self.params.params().value(k + i, &self.active.table))
    }

    /// The running geometry's check word ([`Geometry::check_word`]; the cycle
    /// benchmark measures it).
    pub fn geometry_check_word(&self) -> u32 {
        self.active.geom.check_word()
    }

    /// Control cycles since boot.
    pub fn cycle(&self) -> u32 {
        self.cycle
    }

    /// Microseconds since boot of the current cycle (the telemetry clock).
    pub fn time_us(&self) -> u64 {
        cycle_to_us(u64::from(self.cycle))
    }

    /// The boot report (table source, bank status, selection).
    pub fn boot_report(&self) -> &BootReport {
        &self.boot
    }

    /// The running table.
    pub fn active_table(&self) -> &Table {
        &self.active.table
    }

    /// The committed table waiting for activation.
    pub fn pending_table(&self) -> Option<PendingTable> {
        self.pending_table
    }

    /// Latched faults.
    pub fn faults(&self) -> FaultFlags {
        self.supervisor.latched()
    }

    /// The strokes commanded to (or held by) the drives (mm).
    pub fn strokes_commanded_mm(&self) -> [f32; LEGS] {
        self.strokes_commanded_mm
    }

    /// The end-of-travel switches and reference sensors as read in the last cycle.
    pub fn switches(&self) -> TravelSwitches {
        self.switches
    }

    /// The mechanism (drives, encoders, switches) the controller owns.
    pub fn mechanism(&self) -> &M {
        &self.mech
    }

    /// Gives its end of the telemetry queue back (a simulated reboot hands it to the
    /// next controller).
    pub fn into_tm_producer(self) -> TmProducer {
        self.tm
    }

    /// Test hook (host): flips a bit of the parameters in force or of their check word
    /// ([`params::InForce::upset`]), as a radiation upset would.
    #[cfg(feature = "host")]
    pub fn upset_parameters(&mut self, word: usize, bit: u32) {
        self.params.upset(word, bit);
    }

    /// Test hook (host): flips bit `bit` of word `word` of the output stage's limits
    /// ([`crate::motion::OutputLimiter::upset`]).
    #[cfg(feature = "host")]
    pub fn upset_output_limits(&mut self, word: usize, bit: u32) {
        self.limiter.upset(word, bit);
    }

    /// Test hook (host): flips bits of the derived settings (frames, limits), as a
    /// radiation upset would.
    #[cfg(feature = "host")]
    pub fn upset_ops(&mut self, f: impl FnOnce(&mut Ops)) {
        f(&mut self.ops);
    }

    /// Test hook (host): flips RAM bits of the running table, its derived geometry or
    /// the supervision thresholds, as a radiation upset would; the scrub must find it.
    #[cfg(feature = "host")]
    pub fn upset(
        &mut self,
        f: impl FnOnce(&mut ActiveTable, &mut crate::supervision::SupervisionConfig),
    ) {
        let mut cfg = *self.supervisor.config();
        f(&mut self.active, &mut cfg);
        self.supervisor.set_config(cfg);
    }
}

/// Bit of the lowest leg in the lower-switch byte of [`event::END_OF_TRAVEL`]'s aux0.
const EOT_LOWER_SHIFT: u32 = 0;
/// Bit of the lowest leg in the upper-switch byte.
const EOT_UPPER_SHIFT: u32 = 8;
/// Bit of the lowest leg in the unreadable-input byte.
const EOT_UNREADABLE_SHIFT: u32 = 16;

/// aux0 of [`event::END_OF_TRAVEL`]: legs at the lower switch (bits 0..5), at the upper
/// switch (bits 8..13), with an unreadable input (bits 16..21); 0: none.
fn end_of_travel_word(s: &TravelSwitches) -> u32 {
    let legs = crate::supervision::ALL_LEGS;
    (u32::from(s.lower & legs) << EOT_LOWER_SHIFT)
        | (u32::from(s.upper & legs) << EOT_UPPER_SHIFT)
        | (u32::from(s.unreadable & legs) << EOT_UNREADABLE_SHIFT)
}

/// Every input active (or unreadable) in either reading.
fn or_switches(a: &TravelSwitches, b: &TravelSwitches) -> TravelSwitches {
    TravelSwitches {
        lower: a.lower | b.lower,
        upper: a.upper | b.upper,
        reference: a.reference | b.reference,
        unreadable: a.unreadable | b.unreadable,
    }
}

/// A table with no usable geometry, only for the defect path where even the
/// compiled-in nominal table fails to derive: every motion is refused then.
fn nominal_placeholder() -> ActiveTable {
    let table = Table::nominal();
    ActiveTable {
        crc32: table.crc32(),
        table,
        geom: Geometry {
            legs: [crate::kinematics::geometry::Leg::default(); LEGS],
            p0_mm: [0.0; 3],
            stroke: None,
            workspace: None,
        },
        source: BootSource::Nominal,
    }
}
