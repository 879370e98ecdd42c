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
//! 2. **Link service** (below it): [`comms::LinkService`] deframes and decodes received
//!    bytes, hands each decoded telecommand to [`Controller::execute_telecommand`] (at most
//!    [`comms::MAX_TC_PER_PASS`] per pass), encodes queued telemetry records into
//!    frames, and moves job requests and results between the controller and the
//!    background worker.
//! 3. **Background** (lowest priority): [`crate::worker::Worker`] validates tables, writes
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
//! 5. periodic work: the temperature sensors every [`TEMPERATURE_PERIOD_CYCLES`] (at
//!    [`TEMPERATURE_PHASE_CYCLES`] within it, apart from the whole seconds; one
//!    reading of every channel, supervised: [`crate::thermal::SensorBank`]),
//!    housekeeping every `hk_period` cycles (a parameter, default
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
mod parts;
mod verification;

use crate::hw::{counts_to_mm, MechanismIo, TravelSwitches};
use crate::kinematics::{fk, FkError, FkSolution, Frames, Geometry, GeometryError, Pose, LEGS};
use crate::link::tm::EventSeverity;
use crate::link::{Housekeeping, WirePose};
use crate::motion::MotionLimits;
use crate::supervision::{CycleInputs, FaultFlags, Supervisor};
use crate::table::upload::UploadBuffer;
use crate::table::{BootReport, BootSource, CommitReport, Table};
use crate::thermal::compensation::{Compensation, StepOutcome, STEP_PERIOD_CYCLES};
use crate::thermal::{SensorBank, SensorFault, TEMP_SENSORS};
use crate::timing::{
    cycle_to_us, COMPENSATION_PHASE_CYCLES, SCRUB_PERIOD_CYCLES, TEMPERATURE_PERIOD_CYCLES,
    TEMPERATURE_PHASE_CYCLES,
};

pub use crate::worker::Worker;
pub use error::CommandError;
// The reset cause and boot count are the board's (the hardware seam, `hw`), reported here.
pub use crate::hw::{ResetCause, ResetInfo};
pub use jobs::{JobRequest, JobResult};
pub use params::Parameters;
pub use telemetry::{HkSample, Stamped, TmConsumer, TmProducer, TmQueue, TmRecord};
pub use verification::{Accepted, Started, Token};

/// Event IDs of service 5 (the ICD's table; aux words in the link's `event_id` docs).
pub use crate::link::tm::event_id as event;

use motion::Motion;

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
    /// In-position tolerance (mm) and dwell (cycles): [`Parameters::in_position`].
    pub in_position: (f32, u16),
}

impl Ops {
    /// The settings of `params` with `table` running.
    pub fn derive(params: &Parameters, table: &Table) -> Self {
        Self {
            frames: params.frames(table),
            motion: params.motion_limits(table),
            direct: params.direct_limits(table),
            hk_period_cycles: params.hk_period_cycles(table),
            in_position: params.in_position(table),
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
        let geom = crate::table::validate::working_geometry(&table)?;
        Ok(Self {
            crc32: table.crc32(),
            table,
            geom,
            source,
        })
    }

    /// The running table at boot: `table` (from `source`) with its working geometry,
    /// and whether motion may run. A booted table was validated, so a geometry that
    /// fails is a defect guard: the nominal table instead; if even that fails, the
    /// nominal table without a geometry and motion refused (`false`). Out of line, its
    /// frame is gone before the controller's fields are built (the boot stack).
    #[inline(never)]
    fn booted(table: Table, source: BootSource) -> (Self, bool) {
        use crate::table::validate::working_geometry;
        // One table, one geometry result and one struct written in place: built as
        // `ActiveTable::new` results, the three outcomes were each a whole copy.
        let (table, source, geom) = match working_geometry(&table) {
            Ok(g) => (table, source, Ok(g)),
            Err(_) => {
                let nominal = Table::nominal();
                (nominal, BootSource::Nominal, working_geometry(&nominal))
            }
        };
        let (geom, geometry_ok) = match geom {
            Ok(g) => (g, true),
            Err(_) => (no_geometry(), false),
        };
        (
            Self {
                crc32: table.crc32(),
                table,
                geom,
                source,
            },
            geometry_ok,
        )
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

/// The M2 mechanism controller: the mechanism it owns and the parts of its state
/// ([`parts`]), each plain data with the operations that concern it alone.
pub struct Controller<M> {
    /// The six slider drives and encoders (drivers on the target, the simulated plant
    /// on the host); owned: nothing else commands them.
    mech: M,
    /// What runs, what is pending, what the operator selected.
    tables: parts::Tables,
    /// The on-board parameters (ST[20]) and what they make of the settings.
    settings: parts::Settings,
    /// The fault supervision (latched faults, warnings, thresholds).
    supervisor: Supervisor,
    /// Encoders and forward kinematics.
    estimate: parts::FkEstimate,
    /// End-of-travel switches as the motion must respect them.
    travel: parts::EndOfTravel,
    /// The motion and what was last commanded.
    motion: parts::MotionPart,
    /// Control-cycle overruns.
    deadline: parts::DeadlineMonitor,
    /// The temperature sensors' supervision and means.
    temperatures: SensorBank,
    /// The thermal compensation's applied stroke offsets and state (module
    /// [`crate::thermal::compensation`]): subtracted from every encoder reading and
    /// added to every drive command at the seam ([`Controller::held_mm`],
    /// [`Controller::read_strokes_mm`], [`Controller::drive_mm`]).
    compensation: Compensation,
    /// The exposure hold (telecommand and discrete input).
    exposure: parts::ExposureHold,
    /// Telecommand counters and the telecommand still owed a report.
    ledger: parts::TcLedger,
    /// What was last reported by event.
    reporting: parts::Reporting,
    /// The background jobs' lane (requests, results, the scrub's due flag).
    jobs: jobs::JobLane,
    /// The board's reset cause and boot counter.
    reset: ResetInfo,
    /// Control cycles run since boot: the motion time base and the telemetry clock.
    cycle: u32,
    /// Its end of the telemetry queue (the link service holds the other).
    tm: TmProducer,
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
    pub fn unstarted(mech: M, table: Table, boot: BootReport, tm: TmProducer) -> Self {
        let booted = ActiveTable::booted(table, boot.source);
        Self::assembled(mech, &booted.0, booted.1, boot, tm)
    }

    /// [`Controller::unstarted`] on the running table `active` (`geometry_ok`: its
    /// geometry derived, [`ActiveTable::booted`]).
    #[inline(always)]
    fn assembled(
        mech: M,
        active: &ActiveTable,
        geometry_ok: bool,
        boot: BootReport,
        tm: TmProducer,
    ) -> Self {
        let params = params::InForce::new(Parameters::none());
        let supervisor = Supervisor::new(params.params().supervision(&active.table));
        let ops = Ops::derive(params.params(), &active.table);
        Self {
            mech,
            tables: parts::Tables {
                active: *active,
                geometry_ok,
                generation: 0,
                boot,
                pending: None,
                selection_source: boot.selection.map(|s| s.source),
                upload: UploadBuffer::new(),
                bank_health: 0,
            },
            settings: parts::Settings { params, ops },
            supervisor,
            estimate: parts::FkEstimate::new(),
            travel: parts::EndOfTravel::default(),
            motion: parts::MotionPart {
                now: Motion::Hold,
                pose: Pose::home(),
                strokes_mm: [0.0; LEGS],
                limiter: crate::motion::OutputLimiter::new(
                    &params.params().step_limits(&active.table),
                    [0.0; LEGS],
                ),
                last_drive: Ok(()),
                moving_prev: false,
                plan_aborted: false,
                refusal_bits: 0,
                check: None,
                setpoint_mm: [0.0; LEGS],
                approach: crate::motion::fine::Approach::new([0.0; LEGS]),
            },
            deadline: parts::DeadlineMonitor::default(),
            temperatures: SensorBank::default(),
            compensation: Compensation::default(),
            exposure: parts::ExposureHold::default(),
            ledger: parts::TcLedger::default(),
            reporting: parts::Reporting {
                state: State::Idle,
                warnings: FaultFlags::empty(),
                boot_event_sent: false,
                params_ignored_at_boot: 0,
                sensors_faulty: 0,
            },
            jobs: jobs::JobLane::new(),
            reset: ResetInfo::default(),
            cycle: 0,
            tm,
            schedule: schedule::Schedule::new(),
            time_reports: time::TimeReports::new(),
        }
    }

    /// [`Controller::unstarted`] written into `slot` (the flight image's static slot):
    /// the running table derived here ([`ActiveTable::booted`]), the rest by
    /// [`Controller::assembled_in`], not inlined, with the construction inlined into it:
    /// the optimiser then writes each field into the slot instead of building the whole
    /// struct on the stack and copying it (the boot stack of the flight image).
    #[inline(never)]
    pub fn unstarted_in(
        slot: &mut core::mem::MaybeUninit<Self>,
        mech: M,
        table: Table,
        boot: BootReport,
        tm: TmProducer,
    ) -> &mut Self {
        let booted = ActiveTable::booted(table, boot.source);
        Self::assembled_in(slot, mech, &booted.0, booted.1, boot, tm)
    }

    /// [`Controller::assembled`] written into `slot`. Not inlined: the running table is
    /// read where [`ActiveTable::booted`] left it, in the caller's frame, instead of
    /// being copied about this one's (the boot stack).
    #[inline(never)]
    fn assembled_in<'a>(
        slot: &'a mut core::mem::MaybeUninit<Self>,
        mech: M,
        active: &ActiveTable,
        geometry_ok: bool,
        boot: BootReport,
        tm: TmProducer,
    ) -> &'a mut Self {
        slot.write(Self::assembled(mech, active, geometry_ok, boot, tm))
    }

    /// Second step of [`Controller::unstarted`]: holds the sliders where their drives
    /// are and takes the first reading.
    pub fn start(&mut self) {
        self.hold_here();
        let first = self.read_strokes_mm();
        self.travel.switches = self.mech.read_switches();
        if let Ok(strokes) = first {
            self.estimate.encoders_mm = strokes;
            self.estimate.encoders_valid = true;
            if let Ok(sol) = fk(
                &self.tables.active.geom,
                &self.estimate.encoders_mm,
                &self.estimate.pose,
                &self.estimate.cfg,
            ) {
                self.estimate.pose = sol.pose;
                self.estimate.valid = true;
            }
        }
    }

    /// Restores the on-board parameters persisted with the selection record
    /// ([`crate::table::TableStore::parameters`]); call once after [`Controller::new`].
    /// What is not applied (out of range, or the following-error overrides that would
    /// conflict with the booted table: [`Parameters::from_persisted`]) is reported by
    /// event 0x0041 after the boot events.
    pub fn restore_parameters(&mut self, persisted: &[u8; crate::table::store::PARAMETERS_LEN]) {
        let table = self.tables.active.table;
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
            if self.reporting.boot_event_sent {
                self.report_parameters_ignored(ignored);
            } else {
                self.reporting.params_ignored_at_boot = ignored;
            }
        }
    }

    /// Event 0x0041: persisted parameters not applied.
    fn report_parameters_ignored(&mut self, ignored: u32) {
        self.event(EventSeverity::Low, event::PARAMETERS_IGNORED, [ignored, 0]);
    }

    /// Runs with `params`: derived settings and the supervision thresholds follow.
    fn apply_parameters(&mut self, params: Parameters) {
        self.settings.params = params::InForce::new(params);
        self.settings.ops = Ops::derive(&params, &self.tables.active.table);
        self.motion
            .limiter
            .set_limits(&params.step_limits(&self.tables.active.table));
        self.supervisor
            .set_config(params.supervision(&self.tables.active.table));
        self.tables.generation = self.tables.generation.wrapping_add(1);
        self.jobs.scrub_done();
    }

    /// The thermal compensation: its applied stroke offsets (mm, per leg along base z)
    /// and state.
    pub fn compensation(&self) -> &Compensation {
        &self.compensation
    }

    /// An exposure hold is in force (telecommand or discrete input).
    pub fn exposure_hold_active(&self) -> bool {
        self.exposure.active()
    }

    /// The on-board parameters (as they are in RAM).
    pub fn parameters(&self) -> &Parameters {
        self.settings.params.params()
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
        // A fine positioning under way at rest (a compensation step's: the controller
        // is idle, so a clear or an activation may come) ends here. Its ramp would go on
        // from its own last command, not from where the drives now hold: the soak saw
        // drive setpoints jump 0.2 to 16.9 um in a cycle.
        if matches!(self.motion.now, Motion::Fine { .. }) {
            self.motion.now = Motion::Hold;
            self.motion.moving_prev = false;
        }
        self.mech.hold();
        self.sync_to_drives();
    }

    /// Takes the strokes the drives hold as the commanded strokes and derives their pose
    /// (FK, warm-started from the last commanded pose). The pose is kept if FK fails.
    fn sync_to_drives(&mut self) {
        let held = self.held_mm();
        self.motion.strokes_mm = held;
        // At rest where the drives hold: in position means there.
        self.motion.setpoint_mm = held;
        if let Ok(sol) = fk(
            &self.tables.active.geom,
            &held,
            &self.motion.pose,
            &self.estimate.cfg,
        ) {
            self.motion.pose = sol.pose;
        }
    }

    /// The strokes the drives hold (mm, each slider along base z) at the thermal model's
    /// reference temperature: the drives' setpoints less the applied compensation
    /// offset. Every "where the drives hold" of the controller is this.
    pub(crate) fn held_mm(&mut self) -> [f32; LEGS] {
        let held = self.mech.setpoints_mm();
        less_offset(held, &self.compensation)
    }

    /// The encoder readings (mm, each slider along base z) at the reference
    /// temperature: the readings less the applied compensation offset.
    fn read_strokes_mm(&mut self) -> Result<[f32; LEGS], crate::hw::EncoderError> {
        let counts = self.mech.read_counts()?;
        Ok(less_offset(counts_to_mm(&counts), &self.compensation))
    }

    /// Commands the drives to `strokes_mm` (mm at the reference temperature): each
    /// with the applied compensation offset added.
    pub(crate) fn drive_mm(
        &mut self,
        strokes_mm: &[f32; LEGS],
    ) -> Result<(), crate::hw::DriveError> {
        let applied = self.compensation.applied_mm();
        let mut s = *strokes_mm;
        for (v, a) in s.iter_mut().zip(applied.iter()) {
            *v += a;
        }
        self.mech.command_strokes_mm(&s)
    }

    /// One control cycle (the module documentation lists its steps). Bounded: no I/O
    /// wait, no packet work, no flash.
    pub fn control_cycle(&mut self) {
        if !self.reporting.boot_event_sent {
            self.reporting.boot_event_sent = true;
            self.emit_boot_events();
        }
        // 1. Encoders, their warnings, the end-of-travel switches.
        let readings = self.read_strokes_mm();
        let encoder_warning_legs = self.mech.warning_legs();
        self.travel.switches = self.mech.read_switches();
        self.report_end_of_travel();
        // 2. Forward kinematics, warm-started.
        let fk_result: Option<Result<FkSolution<f32>, FkError>> = match &readings {
            Ok(s) => {
                self.estimate.encoders_mm = *s;
                self.estimate.encoders_valid = true;
                Some(fk(
                    &self.tables.active.geom,
                    s,
                    &self.estimate.pose,
                    &self.estimate.cfg,
                ))
            }
            Err(_) => {
                self.estimate.encoders_valid = false;
                None
            }
        };
        match &fk_result {
            Some(Ok(sol)) => {
                self.estimate.pose = sol.pose;
                self.estimate.valid = true;
                self.estimate.iterations = sol.iterations;
            }
            _ => self.estimate.valid = false,
        }
        // 3. Supervision. At rest the reference is what the drives hold now (a drive
        //    re-referenced after missed steps holds a corrected setpoint).
        if matches!(self.motion.now, Motion::Hold) {
            let held = self.held_mm();
            if held != self.motion.strokes_mm {
                self.motion.strokes_mm = held;
                if let Ok(sol) = fk(
                    &self.tables.active.geom,
                    &held,
                    &self.motion.pose,
                    &self.estimate.cfg,
                ) {
                    self.motion.pose = sol.pose;
                }
            }
        }
        let verdict = self.supervisor.check(&CycleInputs {
            encoders: readings,
            commanded_prev_mm: self.motion.strokes_mm,
            motion_commanded: self.motion.moving_prev,
            fk: fk_result,
            drive: self.motion.last_drive,
            switches: self.travel.switches,
            encoder_warning_legs,
        });
        self.travel.since_latch = if verdict.latched.contains(FaultFlags::LIMIT_SWITCH) {
            parts::or_switches(&self.travel.since_latch, &self.travel.switches)
        } else {
            TravelSwitches::default()
        };
        if verdict.warnings != self.reporting.warnings {
            self.reporting.warnings = verdict.warnings;
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
                    verdict.new_faults.bits()
                        | (u32::from(verdict.new_fault_legs) << event::FAULT_LEGS_SHIFT),
                ],
            );
            self.begin_stop();
        }
        // 4. Motion (after the exposure input: a hold it begins holds this cycle).
        self.step_exposure_hold();
        self.step_motion();
        // 5. Periodic work.
        if self.cycle % TEMPERATURE_PERIOD_CYCLES == TEMPERATURE_PHASE_CYCLES {
            self.read_temperatures();
        }
        if self.cycle % STEP_PERIOD_CYCLES == COMPENSATION_PHASE_CYCLES {
            self.step_compensation();
        }
        if self.cycle % self.settings.ops.hk_period_cycles.max(1) == 0 {
            self.queue_housekeeping();
        }
        if self.cycle % SCRUB_PERIOD_CYCLES == 0 && self.jobs.scrub_wanted() {
            self.queue_scrub();
        }
        // 6. State.
        self.publish_state();
        self.cycle = self.cycle.wrapping_add(1);
    }

    /// Housekeeping's thermal state bits (`link::hk::thermal_state`).
    fn thermal_state(&self) -> u8 {
        use crate::link::hk::thermal_state::{ENABLED, EXPOSURE_HOLD, FROZEN};
        let c = &self.compensation;
        (if c.is_enabled() { ENABLED } else { 0 })
            | (if c.is_frozen() { FROZEN } else { 0 })
            | (if self.exposure.active() {
                EXPOSURE_HOLD
            } else {
                0
            })
    }

    /// One period of the thermal compensation ([`Compensation::step`]): the target is
    /// the running table's thermal model at the commanded pose and the sensors' means.
    /// At rest means holding with no fault latched. A step leaves the drives where they
    /// are and runs a fine positioning onto the held setpoint in the new offset's frame
    /// (its corrections ramp at the speed limit and take up the backlash); a freeze is
    /// event
    /// [`event::THERMAL_FROZEN`]. Skipped while a sensor the model uses, healthy, has
    /// no mean yet (the first [`crate::thermal::MEAN_SAMPLES`] readings after the boot
    /// or a recovery), so the start is not taken for a loss. Not inlined: the cycle's
    /// frame does not grow by the model.
    #[inline(never)]
    fn step_compensation(&mut self) {
        let model = &self.tables.active.table.thermal;
        let used = model.sensors_used();
        let faulty = self.temperatures.faulty() & used;
        let mut temps_c = [f32::NAN; TEMP_SENSORS];
        for (i, t) in temps_c.iter_mut().enumerate() {
            match self.temperatures.sensor_celsius(i) {
                Some(v) => *t = v,
                None if (used & !faulty) & 1u8.wrapping_shl(i as u32) != 0 => return,
                None => {}
            }
        }
        let at_rest =
            matches!(self.motion.now, Motion::Hold) && self.supervisor.latched().is_empty();
        let target = crate::thermal::stroke_offsets_mm(
            model,
            &self.tables.active.geom,
            &self.motion.pose,
            &temps_c,
        );
        let (enabled, params) = self
            .settings
            .params
            .params()
            .thermal(&self.tables.active.table);
        self.compensation.set_enabled(enabled);
        match self.compensation.step(
            at_rest,
            target,
            faulty == 0,
            self.exposure.active(),
            &params,
        ) {
            StepOutcome::Stepped => {
                // Nothing jumps: the drives stay where they are, which in the new
                // offset's frame is off the setpoint by the step, and the fine
                // positioning ramps them back onto it at the speed limit.
                let setpoint = self.motion.setpoint_mm;
                // (At rest the commanded strokes are the held ones, in the old frame.)
                let held = self.held_mm();
                self.motion
                    .approach
                    .step_offsets(&self.motion.strokes_mm, &held);
                self.motion.strokes_mm = held;
                self.begin_fine(setpoint, true);
            }
            StepOutcome::Frozen => self.event(
                EventSeverity::Low,
                event::THERMAL_FROZEN,
                [u32::from(faulty), 0],
            ),
            _ => {}
        }
    }

    /// One cycle of the exposure hold: the discrete input read, the timeouts counted,
    /// and events 0x0052/0x0053 when the hold begins or ends.
    fn step_exposure_hold(&mut self) {
        let input = self.mech.exposing();
        let was = self.exposure.active();
        if let Some(why) = self.exposure.cycle(input) {
            self.event(
                EventSeverity::Info,
                event::EXPOSURE_HOLD_ENDED,
                [why as u32, 0],
            );
        } else if !was && self.exposure.active() {
            self.exposure_hold_started(1, parts::EXPOSURE_INPUT_TIMEOUT_CYCLES);
        }
    }

    /// Event 0x0052: a hold began (`source`: 0 telecommand, 1 input) for `cycles`.
    fn exposure_hold_started(&mut self, source: u32, cycles: u32) {
        self.event(
            EventSeverity::Info,
            event::EXPOSURE_HOLD_STARTED,
            [source, cycles / crate::timing::CONTROL_RATE_HZ],
        );
    }

    /// TC[8,1] 0x0007: holds for `timeout_s` seconds from now (again: from now), or
    /// with 0 ends the telecommand's hold (the input's goes on while it is active).
    fn set_exposure_hold(&mut self, timeout_s: u16) {
        let was = self.exposure.active();
        let cycles = u32::from(timeout_s) * crate::timing::CONTROL_RATE_HZ;
        self.exposure.tc_left = cycles;
        match (was, self.exposure.active()) {
            (false, true) => self.exposure_hold_started(0, cycles),
            (true, false) => self.event(
                EventSeverity::Info,
                event::EXPOSURE_HOLD_ENDED,
                [parts::HoldEnd::Telecommand as u32, 0],
            ),
            _ => {}
        }
    }

    /// Reads every temperature channel once and supervises it. Not inlined: the cycle's
    /// frame does not grow by the reading.
    #[inline(never)]
    fn read_temperatures(&mut self) {
        let counts = self.mech.read_temperature_counts();
        self.temperatures.update(&counts);
        // Event 0x0050 when a sensor the thermal model uses becomes faulty.
        let t = &self.temperatures;
        let faulty = t.faulty() & self.tables.active.table.thermal.sensors_used();
        let new = faulty & !self.reporting.sensors_faulty;
        self.reporting.sensors_faulty = faulty;
        if new != 0 {
            let every = u32::from(t.with_fault(SensorFault::Open))
                | u32::from(t.with_fault(SensorFault::Short)) << event::SENSOR_SHORT_SHIFT
                | u32::from(t.with_fault(SensorFault::Stuck)) << event::SENSOR_STUCK_SHIFT;
            self.event(
                EventSeverity::Low,
                event::SENSOR_FAULT,
                [u32::from(new), every],
            );
        }
    }

    /// Queues the scrub snapshot of the running configuration for the worker. Not
    /// inlined: the ~1.3 KB snapshot is not on the stack with the cycle's motion step.
    #[inline(never)]
    fn queue_scrub(&mut self) {
        self.jobs.request_scrub(&jobs::ScrubImage {
            generation: self.tables.generation,
            active: self.tables.active,
            supervision: *self.supervisor.config(),
            params: self.settings.params,
            ops: self.settings.ops,
        });
    }

    /// The board saw this control cycle overrun its period (the timer fired again before
    /// the cycle ended). Counted; [`OVERRUN_HOLD_LIMIT`] consecutive overruns stop any
    /// motion and raise [`event::DEADLINE_MISSED`]. A cycle that met its deadline is
    /// reported with [`Controller::note_deadline_met`].
    pub fn note_overrun(&mut self) {
        if self.deadline.overrun(OVERRUN_HOLD_LIMIT) {
            self.supervisor
                .raise_external(FaultFlags::DEADLINE_MISSED, true);
            self.event(
                EventSeverity::High,
                event::DEADLINE_MISSED,
                [
                    u32::from(self.deadline.consecutive),
                    u32::from(self.deadline.overruns),
                ],
            );
            self.begin_stop();
        }
    }

    /// The last control cycle finished within its period (a latched deadline fault
    /// becomes clearable).
    pub fn note_deadline_met(&mut self) {
        if self.deadline.met() {
            self.supervisor
                .set_external_condition(FaultFlags::DEADLINE_MISSED, false);
        }
    }

    /// Event [`event::END_OF_TRAVEL`] when the set of active end-of-travel switches (or
    /// unreadable inputs) changes to a non-empty one.
    fn report_end_of_travel(&mut self) {
        if let Some(word) = self.travel.changed_report() {
            self.event(
                EventSeverity::High,
                event::END_OF_TRAVEL,
                [word, self.cycle],
            );
        }
    }

    /// Legs a direct stroke may not move toward smaller (`.0`) and larger (`.1`) strokes:
    /// the switches of the last read, and while [`FaultFlags::LIMIT_SWITCH`] is latched
    /// every switch seen since it latched.
    pub(super) fn end_of_travel_blocked(&self) -> (u8, u8) {
        let mut s = self.travel.switches;
        if self.supervisor.latched().contains(FaultFlags::LIMIT_SWITCH) {
            s = parts::or_switches(&s, &self.travel.since_latch);
        }
        (s.blocked_negative(), s.blocked_positive())
    }

    fn emit_boot_events(&mut self) {
        let sev = if self.tables.boot.fell_back || !self.tables.geometry_ok {
            EventSeverity::Low
        } else {
            EventSeverity::Info
        };
        self.event(
            sev,
            event::BOOT,
            [
                u32::from(self.tables.boot.source.code()),
                self.tables.active.table.table_id,
            ],
        );
        self.event(
            EventSeverity::Info,
            event::BOOT_DETAIL,
            [
                self.tables.boot.flags_word(),
                u32::from(self.reset.cause.code()) | (u32::from(self.reset.boot_count) << 16),
            ],
        );
        if self.reporting.params_ignored_at_boot != 0 {
            self.report_parameters_ignored(self.reporting.params_ignored_at_boot);
        }
    }

    /// The state as derived from the motion and the latched faults.
    pub fn state(&self) -> State {
        match &self.motion.now {
            Motion::Hold => {
                if self.supervisor.latched().is_empty() {
                    State::Idle
                } else {
                    State::Faulted
                }
            }
            Motion::Planning(_) => State::Moving,
            // The fine positioning of a thermal compensation step (no move owns it) is
            // holding position: a move or a recovery may take over from it at once.
            Motion::Fine {
                stopping: false, ..
            } if !self.ledger.pending.is_some_and(|p| p.is_motion()) => {
                if self.supervisor.latched().is_empty() {
                    State::Idle
                } else {
                    State::Faulted
                }
            }
            Motion::Path { stopping: true, .. }
            | Motion::Stroke { stopping: true, .. }
            | Motion::Fine { stopping: true, .. } => State::Stopping,
            Motion::Path { .. } | Motion::Fine { .. } => State::Moving,
            Motion::Stroke { .. } => State::StrokeMoving,
        }
    }

    /// Reports a state change (event 0x0001) if the derived state differs from the one
    /// last reported.
    fn publish_state(&mut self) {
        let now = self.state();
        if now != self.reporting.state {
            let old = self.reporting.state;
            self.reporting.state = now;
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
        let moving_legs = match &self.motion.now {
            Motion::Hold | Motion::Planning(_) => 0,
            Motion::Path { .. } | Motion::Fine { .. } => crate::supervision::ALL_LEGS,
            Motion::Stroke { mv, .. } => 1u8.checked_shl(u32::from(mv.leg())).unwrap_or(0),
        };
        let latched = self.supervisor.latched();
        let report = Housekeeping {
            state: self.state().code(),
            boot_source: self.tables.boot.source.code(),
            active_bank: self.tables.active.source.code(),
            fk_iterations: self.estimate.iterations,
            fk_valid: self.estimate.valid,
            cycle_counter: self.cycle,
            fault_flags: latched.bits(),
            warning_flags: self.reporting.warnings.bits(),
            refusal_bits: self.motion.refusal_bits,
            active_table_id: self.tables.active.table.table_id,
            active_table_crc32: self.tables.active.crc32,
            pose_fk: WirePose::default(),
            pose_commanded: WirePose::default(),
            strokes_commanded_nm: [0; LEGS],
            encoders_nm: [0; LEGS],
            tc_accepted: self.ledger.accepted,
            tc_rejected: self.ledger.rejected,
            last_failure_code: self.ledger.last_failure_code,
            moving_legs,
            fault_legs: self.supervisor.latched_legs(latched),
            pending_bank: self
                .tables
                .pending
                .map_or(0, |p| BootSource::from(p.report.bank).code()),
            pending_table_id: self.tables.pending.map_or(0, |p| p.table_id),
            job: self.jobs.running_code(),
            selected_source: self
                .tables
                .selection_source
                .map_or(crate::link::hk::NO_SELECTION, |s| s.code()),
            tm_dropped: self.tm.dropped(),
            tc_frames_dropped: 0,
            uart_overruns: 0,
            cycle_overruns: self.deadline.overruns,
            reset_cause: self.reset.cause.code(),
            boot_count: self.reset.boot_count,
            bank_health: self.tables.bank_health,
            pivot_nm: self.pivot_nm(),
            pose_fk_operator: WirePose::default(),
            pose_commanded_operator: WirePose::default(),
            parameters_set: self.settings.params.params().set_mask(),
            schedule: self.schedule_hk(),
            limit_lower_legs: self.travel.switches.lower,
            limit_upper_legs: self.travel.switches.upper,
            reference_legs: self.travel.switches.reference,
            switch_unreadable_legs: self.travel.switches.unreadable,
            in_position_legs: self.in_position_legs(),
            temperatures_centi_k: self.temperatures.centi_kelvin(),
            sensors_open: self.temperatures.with_fault(SensorFault::Open),
            sensors_short: self.temperatures.with_fault(SensorFault::Short),
            sensors_stuck: self.temperatures.with_fault(SensorFault::Stuck),
            thermal_state: self.thermal_state(),
            thermal_offsets_nm: self
                .compensation
                .applied_mm()
                .map(crate::link::wire::mm_to_nm_f32),
        };
        HkSample {
            report,
            pose_fk: self.estimate.pose,
            pose_commanded: self.motion.pose,
            strokes_commanded_mm: self.motion.strokes_mm,
            encoders_mm: self.estimate.encoders_mm,
            pose_fk_operator: self.settings.ops.frames.to_operator(&self.estimate.pose),
            pose_commanded_operator: self.settings.ops.frames.to_operator(&self.motion.pose),
        }
    }

    /// The pivot (M's coordinates, nm), as set.
    fn pivot_nm(&self) -> [i32; 3] {
        let k = params::index::PIVOT;
        [0, 1, 2].map(|i| {
            self.settings
                .params
                .params()
                .value(k + i, &self.tables.active.table)
        })
    }

    /// The running geometry's check word ([`Geometry::check_word`]; the cycle
    /// benchmark measures it).
    pub fn geometry_check_word(&self) -> u32 {
        self.tables.active.geom.check_word()
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
        &self.tables.boot
    }

    /// The running table.
    pub fn active_table(&self) -> &Table {
        &self.tables.active.table
    }

    /// The committed table waiting for activation.
    pub fn pending_table(&self) -> Option<PendingTable> {
        self.tables.pending
    }

    /// Latched faults.
    pub fn faults(&self) -> FaultFlags {
        self.supervisor.latched()
    }

    /// The strokes commanded to (or held by) the drives (mm).
    pub fn strokes_commanded_mm(&self) -> [f32; LEGS] {
        self.motion.strokes_mm
    }

    /// The temperature sensors' supervision: each sensor's mean and health.
    pub fn temperatures(&self) -> &SensorBank {
        &self.temperatures
    }

    /// The end-of-travel switches and reference sensors as read in the last cycle.
    pub fn switches(&self) -> TravelSwitches {
        self.travel.switches
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
        self.settings.params.upset(word, bit);
    }

    /// Test hook (host): flips bit `bit` of word `word` of the output stage's limits
    /// ([`crate::motion::OutputLimiter::upset`]).
    #[cfg(feature = "host")]
    pub fn upset_output_limits(&mut self, word: usize, bit: u32) {
        self.motion.limiter.upset(word, bit);
    }

    /// Test hook (host): flips bits of the derived settings (frames, limits), as a
    /// radiation upset would.
    #[cfg(feature = "host")]
    pub fn upset_ops(&mut self, f: impl FnOnce(&mut Ops)) {
        f(&mut self.settings.ops);
    }

    /// Test hook (host): flips RAM bits of the running table, its derived geometry or
    /// the supervision thresholds, as a radiation upset would; the scrub must find it.
    #[cfg(feature = "host")]
    pub fn upset(
        &mut self,
        f: impl FnOnce(&mut ActiveTable, &mut crate::supervision::SupervisionConfig),
    ) {
        let mut cfg = *self.supervisor.config();
        f(&mut self.tables.active, &mut cfg);
        self.supervisor.set_config(cfg);
    }
}

/// `strokes_mm` (mm per leg) less the compensation's applied offset: from the drives'
/// and the encoders' frame to the reference temperature's. One out-of-line copy for the
/// readings and the held strokes.
#[inline(never)]
fn less_offset(mut strokes_mm: [f32; LEGS], c: &Compensation) -> [f32; LEGS] {
    for (v, a) in strokes_mm.iter_mut().zip(c.applied_mm().iter()) {
        *v -= a;
    }
    strokes_mm
}

/// The geometry of no table (all zero, mm in the base frame), only for the defect path
/// where even the compiled-in nominal table fails to derive: every motion is refused
/// then.
fn no_geometry() -> Geometry<f32> {
    Geometry {
        legs: [crate::kinematics::geometry::Leg::default(); LEGS],
        p0_mm: [0.0; 3],
        stroke: None,
        workspace: None,
    }
}
