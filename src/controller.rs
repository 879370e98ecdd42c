//! The cyclic executive: one [`Controller::tick`] per control cycle ([`crate::motion::CYCLE_S`]).
//!
//! A tick, in order:
//! 1. read the six encoders ([`StrokeEncoders`]);
//! 2. forward kinematics of the readings, warm-started from the last pose;
//! 3. supervision ([`Supervisor`]): a new fault stops any motion at the acceleration
//!    limit, latches, and is reported (event TM[5,4] + housekeeping);
//! 4. motion: the active trajectory's setpoint pose -> IK -> six strokes -> drives
//!    ([`SliderDrives`]); a direct-stroke move commands strokes directly;
//! 5. at most one telecommand (the caller passes the frame it received this cycle):
//!    checked decode, service-1 verification reports, execution;
//! 6. housekeeping TM[3,25] every [`HK_PERIOD_CYCLES`].
//!
//! Rules an operator can rely on:
//! * a rejected telecommand changes nothing (acceptance or start failure, with a code);
//! * a move is all-or-nothing: refused with every workspace reason unless every leg can
//!   make the whole path; no move while a fault is latched or while moving (stop first);
//! * tables change between motions only (activate / switch bank / revert refused while
//!   moving); an uploaded table is checked (all bytes, CRC-32, decode, validation)
//!   before it is written to the inactive bank, and is used only after activation (or
//!   at the next boot, which takes the newest valid bank);
//! * completion of a move is reported when the mirror has arrived (TM[1,7]) or, if a
//!   stop or a fault ended it, as a completion failure (TM[1,8]).

use embedded_storage::nor_flash::NorFlash;

use crate::hw::{counts_to_mm, DriveError, SliderDrives, StrokeEncoders};
use crate::kinematics::{fk, ik, FkConfig, FkError, FkSolution, Geometry, Pose, LEGS};
use crate::link::command::{round_sat_i32, MemoryId, WirePose};
use crate::link::tc::{decode_telecommand, AckFlags, RequestId, Telecommand};
use crate::link::tm::{dump_chunks, EventSeverity, TmTime, TmWriter, Verification};
use crate::link::{Command, Housekeeping, MAX_TM_FRAME_LEN};
use crate::motion::{
    DirectStrokeLimits, MotionError, MotionLimits, PlanStart, StrokeMove, Trajectory,
    TrajectoryPlanner,
};
use crate::supervision::{CycleInputs, FaultFlags, SupervisionConfig, Supervisor};
use crate::table::{
    BootReport, BootSource, StoreError, Table, TableStore, ValidationConfig, TABLE_LEN,
};

/// Housekeeping period (cycles): 1 Hz at the 1 kHz control rate.
pub const HK_PERIOD_CYCLES: u32 = 1000;
/// Path samples (IK evaluations) a move's planning may use per control cycle: the
/// ~17 samples of a plan are spread over a few cycles so that no cycle carries them all.
pub const PLAN_SAMPLES_PER_CYCLE: usize = 4;
/// Milliseconds per control cycle, for the TM timestamps.
const MS_PER_CYCLE: u64 = (crate::motion::CYCLE_S * 1000.0) as u64;
/// Bytes of the upload-received bitmap (one bit per table byte).
const UPLOAD_BITMAP_LEN: usize = TABLE_LEN.div_ceil(8);
/// Nanometres per millimetre (telemetry).
const NM_PER_MM: f32 = 1.0e6;

/// Event IDs of service 5 (the ICD's table; aux words in the link's `event_id` docs).
pub use crate::link::tm::event_id as event;

/// Controller state, as reported in housekeeping (`code()`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    /// Holding position, ready for commands.
    Idle,
    /// Following a trajectory.
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

/// Why the controller refused or failed a telecommand (family 0x07xx; the
/// kinematics, motion and table codes pass through unchanged).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandError {
    /// A fault is latched (data: latched flags).
    Faulted(FaultFlags),
    /// A motion is in progress: stop first (data: state code).
    Busy(State),
    /// Clear refused: the fault condition persists (data: blocking flags).
    FaultPersists(FaultFlags),
    /// The current pose is unknown (FK failed): no path can be planned.
    NoPose,
    /// The move was refused (data: refusal bits or 0).
    Motion(MotionError),
    /// The direct-stroke move was refused.
    Stroke(u16),
    /// Commit before every table byte was uploaded (data: bytes still missing).
    UploadIncomplete(u16),
    /// Commit with a CRC-32 that does not match the uploaded bytes (data: computed CRC).
    CrcMismatch(u32),
    /// The uploaded bytes do not decode as a table (table error code).
    TableDecode(u16),
    /// Validation or flash storage failed (table/store error code).
    Store(StoreError),
    /// Activate with no committed table waiting.
    NoCandidate,
    /// Stopped before arrival by a stop telecommand.
    Stopped,
    /// Stopped before arrival by a fault (data: latched flags).
    AbortedByFault(FaultFlags),
}

impl CommandError {
    /// Failure code for the verification report.
    pub fn code(&self) -> u16 {
        match self {
            CommandError::Faulted(_) => 0x0701,
            CommandError::Busy(_) => 0x0702,
            CommandError::FaultPersists(_) => 0x0703,
            CommandError::NoPose => 0x0704,
            CommandError::Motion(e) => e.code(),
            CommandError::Stroke(code) => *code,
            CommandError::UploadIncomplete(_) => 0x0705,
            CommandError::CrcMismatch(_) => 0x0706,
            CommandError::TableDecode(code) => *code,
            CommandError::Store(e) => e.code(),
            CommandError::NoCandidate => 0x0707,
            CommandError::Stopped => 0x0708,
            CommandError::AbortedByFault(_) => 0x0709,
        }
    }

    /// Failure datum for the verification report.
    pub fn data(&self) -> u32 {
        match self {
            CommandError::Faulted(f)
            | CommandError::FaultPersists(f)
            | CommandError::AbortedByFault(f) => f.bits(),
            CommandError::Busy(s) => u32::from(s.code()),
            CommandError::Motion(e) => match e {
                MotionError::StartRefused(r) | MotionError::TargetRefused(r) => r.to_bits(),
                MotionError::PathRefused { refusals, .. } => refusals.to_bits(),
                _ => 0,
            },
            CommandError::UploadIncomplete(n) => u32::from(*n),
            CommandError::CrcMismatch(c) => *c,
            CommandError::Store(StoreError::Invalid(v)) => u32::from(v.code()),
            _ => 0,
        }
    }
}

/// The motion in progress.
#[derive(Clone, Copy, Debug)]
enum Motion {
    Hold,
    /// A move accepted and being planned (a few cycles); the sliders hold meanwhile.
    Planning(TrajectoryPlanner),
    Path {
        traj: Trajectory,
        start_cycle: u32,
        stopping: bool,
    },
    Stroke {
        mv: StrokeMove,
        start_cycle: u32,
        stopping: bool,
    },
}

/// A move telecommand waiting for its completion report.
#[derive(Clone, Copy, Debug)]
struct PendingCompletion {
    request_id: RequestId,
    ack: AckFlags,
}

/// The table in use, derived once per activation.
#[derive(Clone, Copy, Debug)]
struct ActiveTable {
    table: Table,
    geom: Geometry<f32>,
    crc32: u32,
    source: BootSource,
}

impl ActiveTable {
    fn new(table: Table, source: BootSource) -> Result<Self, StoreError> {
        let geom = Geometry::new(&table.geometry_params())
            .map_err(|e| StoreError::Invalid(crate::table::ValidationError::Geometry(e)))?;
        Ok(Self {
            crc32: table.crc32(),
            table,
            geom,
            source,
        })
    }
}

/// Settings of the controller that are not in the parameter table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerConfig {
    /// Slider speed/acceleration limits of coordinated moves.
    pub motion: MotionLimits,
    /// Speed/acceleration of direct-stroke (recovery) moves and their largest delta (mm).
    pub direct_speed_mm_per_s: f32,
    /// Acceleration of direct-stroke moves (mm/s^2).
    pub direct_accel_mm_per_s2: f32,
    /// Largest single direct-stroke move (mm).
    pub direct_max_delta_mm: f32,
    /// Table validation settings.
    pub validation: ValidationConfig,
}

/// Default direct-stroke speed (mm/s): slower than coordinated moves.
pub const DEFAULT_DIRECT_SPEED_MM_PER_S: f32 = 0.05;
/// Default direct-stroke acceleration (mm/s^2).
pub const DEFAULT_DIRECT_ACCEL_MM_PER_S2: f32 = 0.5;
/// Default largest direct-stroke move (mm).
pub const DEFAULT_DIRECT_MAX_DELTA_MM: f32 = 0.5;

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            motion: MotionLimits::default(),
            direct_speed_mm_per_s: DEFAULT_DIRECT_SPEED_MM_PER_S,
            direct_accel_mm_per_s2: DEFAULT_DIRECT_ACCEL_MM_PER_S2,
            direct_max_delta_mm: DEFAULT_DIRECT_MAX_DELTA_MM,
            validation: ValidationConfig::flight(),
        }
    }
}

/// Telemetry goes out through this: one call per framed TM packet.
pub trait TmSink {
    /// Sends one framed packet (COBS frame with delimiters).
    fn send(&mut self, frame: &[u8]);
}

impl<F: FnMut(&[u8])> TmSink for F {
    fn send(&mut self, frame: &[u8]) {
        self(frame)
    }
}

/// The M2 mechanism controller.
pub struct Controller<M, F> {
    /// The six slider drives and encoders (board glue on the target, the simulated
    /// plant on the host).
    mech: M,
    store: TableStore<F>,
    cfg: ControllerConfig,
    active: ActiveTable,
    boot: BootReport,
    /// Committed (validated, stored) table waiting for activation.
    candidate: Option<ActiveTable>,
    upload: [u8; TABLE_LEN],
    upload_seen: [u8; UPLOAD_BITMAP_LEN],
    supervisor: Supervisor,
    motion: Motion,
    state: State,
    pending: Option<PendingCompletion>,
    fk_cfg: FkConfig<f32>,
    /// Last good FK pose (warm start and telemetry).
    pose_fk: Pose<f32>,
    fk_valid: bool,
    fk_iterations: u8,
    pose_commanded: Pose<f32>,
    strokes_commanded_mm: [f32; LEGS],
    encoders_mm: [f32; LEGS],
    last_drive: Result<(), DriveError>,
    moving_prev: bool,
    warnings: FaultFlags,
    cycle: u32,
    tm: TmWriter,
    tc_accepted: u16,
    tc_rejected: u16,
    last_failure_code: u16,
    refusal_bits: u32,
    boot_event_sent: bool,
    /// A stop or a fault ended a move while it was being planned.
    plan_aborted: bool,
}

impl<M: SliderDrives + StrokeEncoders, F: NorFlash> Controller<M, F> {
    /// Boots: selects the table (newest valid bank, else the other, else nominal), holds
    /// the sliders where they are, and takes the first encoder reading as the pose.
    pub fn new(mech: M, store: TableStore<F>, cfg: ControllerConfig) -> Self {
        let mut store = store;
        let (table, boot) = store.boot(&cfg.validation);
        let active = match ActiveTable::new(table, boot.source) {
            Ok(a) => a,
            // A booted table was validated, so this is a defect guard: fall back.
            Err(_) => {
                store.set_nominal_active();
                nominal_active()
            }
        };
        let supervisor = Supervisor::new(SupervisionConfig::from_table(&active.table));
        let mut c = Self {
            mech,
            store,
            cfg,
            active,
            boot,
            candidate: None,
            upload: [0; TABLE_LEN],
            upload_seen: [0; UPLOAD_BITMAP_LEN],
            supervisor,
            motion: Motion::Hold,
            state: State::Idle,
            pending: None,
            fk_cfg: FkConfig::default(),
            pose_fk: Pose::home(),
            fk_valid: false,
            fk_iterations: 0,
            pose_commanded: Pose::home(),
            strokes_commanded_mm: [0.0; LEGS],
            encoders_mm: [0.0; LEGS],
            last_drive: Ok(()),
            moving_prev: false,
            warnings: FaultFlags::empty(),
            cycle: 0,
            tm: TmWriter::new(),
            tc_accepted: 0,
            tc_rejected: 0,
            last_failure_code: 0,
            refusal_bits: 0,
            boot_event_sent: false,
            plan_aborted: false,
        };
        c.hold_here();
        c
    }

    /// Holds the sliders at their current readings and takes the pose from them.
    fn hold_here(&mut self) {
        self.mech.hold();
        if let Ok(counts) = self.mech.read_counts() {
            self.encoders_mm = counts_to_mm(&counts);
            self.strokes_commanded_mm = self.encoders_mm;
            if let Ok(sol) = fk(
                &self.active.geom,
                &self.encoders_mm,
                &self.pose_fk,
                &self.fk_cfg,
            ) {
                self.pose_fk = sol.pose;
                self.pose_commanded = sol.pose;
                self.fk_valid = true;
            }
        }
    }

    fn time(&self) -> TmTime {
        TmTime::from_millis(u64::from(self.cycle) * MS_PER_CYCLE)
    }

    fn verify(&mut self, out: &mut impl TmSink, rid: RequestId, report: Verification) {
        if let Some((code, _)) = report.failure() {
            self.last_failure_code = code;
        }
        let mut buf = [0u8; MAX_TM_FRAME_LEN];
        if let Ok(n) = self
            .tm
            .emit_verification(self.time(), rid, report, &mut buf)
        {
            if let Some(frame) = buf.get(..n) {
                out.send(frame);
            }
        }
    }

    fn event(&mut self, out: &mut impl TmSink, sev: EventSeverity, id: u16, aux: [u32; 2]) {
        let mut buf = [0u8; MAX_TM_FRAME_LEN];
        if let Ok(n) = self.tm.emit_event(self.time(), sev, id, aux, &mut buf) {
            if let Some(frame) = buf.get(..n) {
                out.send(frame);
            }
        }
    }

    fn set_state(&mut self, out: &mut impl TmSink, new: State) {
        if new != self.state {
            let old = self.state;
            self.state = new;
            self.event(
                out,
                EventSeverity::Info,
                event::STATE_CHANGED,
                [u32::from(old.code()), u32::from(new.code())],
            );
        }
    }

    /// One control cycle. `tc_packet` is the telecommand packet received this cycle (the
    /// bytes of one deframed frame), if any; telemetry goes to `out`.
    pub fn tick(&mut self, tc_packet: Option<&[u8]>, out: &mut impl TmSink) {
        if !self.boot_event_sent {
            self.boot_event_sent = true;
            let sev = if self.boot.fell_back {
                EventSeverity::Low
            } else {
                EventSeverity::Info
            };
            self.event(
                out,
                sev,
                event::BOOT,
                [
                    u32::from(self.boot.flags()),
                    u32::from(self.boot.source.code()),
                ],
            );
        }
        // 1. Encoders.
        let readings = self.mech.read_counts().map(|c| counts_to_mm(&c));
        // 2. Forward kinematics, warm-started.
        let fk_result: Option<Result<FkSolution<f32>, FkError>> = match &readings {
            Ok(s) => {
                self.encoders_mm = *s;
                Some(fk(&self.active.geom, s, &self.pose_fk, &self.fk_cfg))
            }
            Err(_) => None,
        };
        match &fk_result {
            Some(Ok(sol)) => {
                self.pose_fk = sol.pose;
                self.fk_valid = true;
                self.fk_iterations = sol.iterations;
            }
            _ => self.fk_valid = false,
        }
        // 3. Supervision. Faulted and at rest, the drives are not commanded; the
        //    following reference is then the measured stroke, so that a fault can be
        //    cleared once the mechanism is at rest and consistent again (e.g. after a
        //    drive was re-referenced following missed steps).
        if let (State::Faulted, Motion::Hold, Ok(s)) = (self.state, &self.motion, &readings) {
            self.strokes_commanded_mm = *s;
        }
        let verdict = self.supervisor.check(&CycleInputs {
            encoders: readings,
            commanded_prev_mm: self.strokes_commanded_mm,
            motion_commanded: self.moving_prev,
            fk: fk_result,
            drive: self.last_drive,
        });
        if verdict.warnings != self.warnings {
            self.warnings = verdict.warnings;
            self.event(
                out,
                EventSeverity::Low,
                event::WARNING_CHANGED,
                [verdict.warnings.bits(), 0],
            );
        }
        if !verdict.new_faults.is_empty() {
            self.event(
                out,
                EventSeverity::High,
                event::FAULT_LATCHED,
                [verdict.latched.bits(), verdict.new_faults.bits()],
            );
            self.begin_stop();
        }
        // 4. Motion.
        self.step_motion(out);
        // 5. One telecommand.
        if let Some(packet) = tc_packet {
            self.handle_packet(packet, out);
        }
        // 6. Housekeeping.
        if self.cycle % HK_PERIOD_CYCLES == 0 {
            self.send_housekeeping(out);
        }
        self.cycle = self.cycle.wrapping_add(1);
    }

    /// Turns the current motion into a stop ramp (no-op when holding).
    fn begin_stop(&mut self) {
        let now = self.cycle;
        match &mut self.motion {
            Motion::Hold => {}
            Motion::Planning(_) => self.plan_aborted = true,
            Motion::Path {
                traj,
                start_cycle,
                stopping,
            } => {
                if !*stopping {
                    traj.stop(now.wrapping_sub(*start_cycle));
                    *stopping = true;
                }
            }
            Motion::Stroke {
                mv,
                start_cycle,
                stopping,
            } => {
                if !*stopping {
                    mv.stop(now.wrapping_sub(*start_cycle));
                    *stopping = true;
                }
            }
        }
    }

    /// Advances a move being planned: on completion it becomes the path (start success
    /// reported), on refusal or abort the sliders keep holding (start failure reported).
    fn step_planning(&mut self, out: &mut impl TmSink) {
        let Motion::Planning(mut planner) = self.motion else {
            return;
        };
        let result = if self.plan_aborted {
            let latched = self.supervisor.latched();
            Some(Err(if latched.is_empty() {
                CommandError::Stopped
            } else {
                CommandError::AbortedByFault(latched)
            }))
        } else {
            planner
                .advance(&self.active.geom, PLAN_SAMPLES_PER_CYCLE)
                .map(|r| r.map_err(CommandError::Motion))
        };
        self.plan_aborted = false;
        match result {
            None => self.motion = Motion::Planning(planner),
            Some(Ok(traj)) => {
                self.refusal_bits = 0;
                // The path starts in this very cycle (the motion step follows).
                self.motion = Motion::Path {
                    traj,
                    start_cycle: self.cycle,
                    stopping: false,
                };
                if let Some(p) = self.pending {
                    if p.ack.start() {
                        self.verify(out, p.request_id, Verification::StartSuccess);
                    }
                }
            }
            Some(Err(e)) => {
                self.motion = Motion::Hold;
                if let CommandError::Motion(_) = e {
                    self.refusal_bits = e.data();
                    self.event(
                        out,
                        EventSeverity::Low,
                        event::MOVE_REFUSED,
                        [self.refusal_bits, u32::from(e.code())],
                    );
                }
                if let Some(p) = self.pending.take() {
                    self.verify(
                        out,
                        p.request_id,
                        Verification::StartFailure {
                            code: e.code(),
                            data: e.data(),
                        },
                    );
                }
            }
        }
    }

    fn step_motion(&mut self, out: &mut impl TmSink) {
        self.step_planning(out);
        let now = self.cycle;
        let (strokes, moving, done, stopping) = match self.motion {
            Motion::Hold | Motion::Planning(_) => (self.strokes_commanded_mm, false, false, false),
            Motion::Path {
                traj,
                start_cycle,
                stopping,
            } => {
                let sp = traj.setpoint(now.wrapping_sub(start_cycle));
                match ik(&self.active.geom, &sp.pose) {
                    Ok(s) => {
                        self.pose_commanded = sp.pose;
                        (s, sp.moving, sp.done, stopping)
                    }
                    Err(_) => {
                        // Planned paths are checked along their length; should a
                        // setpoint still be refused, hold here and say so.
                        let refusals = crate::kinematics::check(&self.active.geom, &sp.pose);
                        self.event(
                            out,
                            EventSeverity::High,
                            event::SETPOINT_REFUSED,
                            [refusals.to_bits(), now],
                        );
                        (self.strokes_commanded_mm, false, true, true)
                    }
                }
            }
            Motion::Stroke {
                mv,
                start_cycle,
                stopping,
            } => {
                let sp = mv.setpoint(now.wrapping_sub(start_cycle));
                (sp.strokes_mm, sp.moving, sp.done, stopping)
            }
        };
        if matches!(self.motion, Motion::Hold | Motion::Planning(_)) {
            // Nothing is commanded at rest: poll the drives' health instead.
            self.last_drive = self.mech.status();
        } else {
            self.strokes_commanded_mm = strokes;
            self.last_drive = self.mech.command_strokes_mm(&strokes);
        }
        self.moving_prev = moving;
        let faulted = !self.supervisor.latched().is_empty();
        if done {
            // After a direct-stroke move the commanded pose is the measured one; after a
            // path it is the last setpoint (target, or where the stop ramp ended).
            if matches!(self.motion, Motion::Stroke { .. }) && self.fk_valid {
                self.pose_commanded = self.pose_fk;
            }
            self.motion = Motion::Hold;
            if let Some(p) = self.pending.take() {
                if !stopping {
                    if p.ack.completion() {
                        self.verify(out, p.request_id, Verification::CompletionSuccess);
                    }
                } else {
                    let err = if faulted {
                        CommandError::AbortedByFault(self.supervisor.latched())
                    } else {
                        CommandError::Stopped
                    };
                    self.verify(
                        out,
                        p.request_id,
                        Verification::CompletionFailure {
                            code: err.code(),
                            data: err.data(),
                        },
                    );
                }
            }
        }
        let next = match (&self.motion, faulted) {
            (Motion::Hold, true) => State::Faulted,
            (Motion::Hold, false) => State::Idle,
            (Motion::Path { stopping: true, .. }, _)
            | (Motion::Stroke { stopping: true, .. }, _) => State::Stopping,
            (Motion::Path { .. }, _) | (Motion::Planning(_), _) => State::Moving,
            (Motion::Stroke { .. }, _) => State::StrokeMoving,
        };
        self.set_state(out, next);
    }

    fn handle_packet(&mut self, packet: &[u8], out: &mut impl TmSink) {
        let tc = match decode_telecommand(packet) {
            Ok(tc) => tc,
            Err(rej) => {
                self.tc_rejected = self.tc_rejected.wrapping_add(1);
                if let Some(rid) = rej.request_id {
                    self.verify(out, rid, Verification::acceptance_failure(&rej.error));
                } else {
                    self.last_failure_code = rej.error.code();
                }
                return;
            }
        };
        self.tc_accepted = self.tc_accepted.wrapping_add(1);
        if tc.ack.acceptance() {
            self.verify(out, tc.request_id, Verification::AcceptanceSuccess);
        }
        match self.execute(&tc, out) {
            Ok(Outcome::Done) => {
                if tc.ack.start() {
                    self.verify(out, tc.request_id, Verification::StartSuccess);
                }
                if tc.ack.completion() {
                    self.verify(out, tc.request_id, Verification::CompletionSuccess);
                }
            }
            Ok(Outcome::Planning) => {
                // Start success or failure is reported when the plan is done.
                self.pending = Some(PendingCompletion {
                    request_id: tc.request_id,
                    ack: tc.ack,
                });
            }
            Ok(Outcome::Started) => {
                if tc.ack.start() {
                    self.verify(out, tc.request_id, Verification::StartSuccess);
                }
                // A newer move cannot start while one is pending (Busy), so no report
                // is lost here.
                self.pending = Some(PendingCompletion {
                    request_id: tc.request_id,
                    ack: tc.ack,
                });
            }
            Err(e) => {
                match tc.command {
                    Command::MoveAbsolute(_) | Command::MoveRelative(_) => {
                        let refusal = match e {
                            CommandError::Motion(_) => e.data(),
                            _ => 0,
                        };
                        self.event(
                            out,
                            EventSeverity::Low,
                            event::MOVE_REFUSED,
                            [refusal, u32::from(e.code())],
                        );
                    }
                    Command::CommitTable { .. }
                    | Command::ActivateTable
                    | Command::SwitchBank
                    | Command::RevertToNominal => {
                        // The refused table's ID where there is one: the uploaded table
                        // of a commit (if it decodes); 0 otherwise.
                        let id = match tc.command {
                            Command::CommitTable { .. } => {
                                Table::decode(&self.upload).map(|t| t.table_id).unwrap_or(0)
                            }
                            _ => 0,
                        };
                        self.event(
                            out,
                            EventSeverity::Medium,
                            event::TABLE_REJECTED,
                            [u32::from(e.code()), id],
                        );
                    }
                    _ => {}
                }
                self.verify(
                    out,
                    tc.request_id,
                    Verification::StartFailure {
                        code: e.code(),
                        data: e.data(),
                    },
                );
            }
        }
    }

    fn require_idle(&self) -> Result<(), CommandError> {
        match self.state {
            State::Idle | State::Faulted => Ok(()),
            s => Err(CommandError::Busy(s)),
        }
    }

    fn require_can_move(&self) -> Result<(), CommandError> {
        let latched = self.supervisor.latched();
        if !latched.is_empty() {
            return Err(CommandError::Faulted(latched));
        }
        self.require_idle()
    }

    fn execute(
        &mut self,
        tc: &Telecommand,
        out: &mut impl TmSink,
    ) -> Result<Outcome, CommandError> {
        match tc.command {
            Command::Ping => {
                let mut buf = [0u8; MAX_TM_FRAME_LEN];
                if let Ok(n) = self.tm.emit_ping_reply(self.time(), &mut buf) {
                    if let Some(f) = buf.get(..n) {
                        out.send(f);
                    }
                }
                Ok(Outcome::Done)
            }
            Command::HousekeepingOneShot => {
                self.send_housekeeping(out);
                Ok(Outcome::Done)
            }
            Command::MoveAbsolute(target) => self.start_move(target.to_pose()),
            Command::MoveRelative(delta) => {
                let d: Pose<f32> = delta.to_pose();
                let mut target = self.pose_commanded;
                for (t, v) in target.translation_mm.iter_mut().zip(d.translation_mm) {
                    *t += v;
                }
                for (t, v) in target.rotation_rad.iter_mut().zip(d.rotation_rad) {
                    *t += v;
                }
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
                        out,
                        EventSeverity::Info,
                        event::FAULTS_CLEARED,
                        [latched.bits(), 0],
                    );
                }
                // Resume from where the mechanism is.
                self.hold_here();
                self.set_state(out, State::Idle);
                Ok(Outcome::Done)
            }
            Command::DirectStroke { leg, delta_nm } => {
                // Recovery works while faulted (that is what it is for), not while moving.
                self.require_idle()?;
                let limits = self.direct_limits();
                let delta_mm = delta_nm as f32 / NM_PER_MM;
                let idx = leg.wrapping_sub(1);
                let mv = StrokeMove::plan(&self.encoders_mm, idx, delta_mm, &limits)
                    .map_err(|e| CommandError::Stroke(e.code()))?;
                self.strokes_commanded_mm = self.encoders_mm;
                self.motion = Motion::Stroke {
                    mv,
                    start_cycle: self.cycle.wrapping_add(1),
                    stopping: false,
                };
                self.set_state(out, State::StrokeMoving);
                Ok(Outcome::Started)
            }
            Command::LoadTableChunk(chunk) => {
                let off = usize::from(chunk.offset_bytes());
                for (i, b) in chunk.bytes().iter().enumerate() {
                    let at = off + i;
                    if let Some(dst) = self.upload.get_mut(at) {
                        *dst = *b;
                    }
                    if let Some(bits) = self.upload_seen.get_mut(at / 8) {
                        *bits |= 1 << (at % 8);
                    }
                }
                Ok(Outcome::Done)
            }
            Command::CommitTable { crc32 } => self.commit_upload(crc32, out),
            Command::ActivateTable => {
                self.require_idle()?;
                let cand = self.candidate.take().ok_or(CommandError::NoCandidate)?;
                self.activate(cand, out);
                Ok(Outcome::Done)
            }
            Command::SwitchBank => {
                self.require_idle()?;
                let report = self
                    .store
                    .promote_inactive(&self.cfg.validation)
                    .map_err(CommandError::Store)?;
                let (_, table) = self
                    .store
                    .read_bank(report.bank)
                    .map_err(|s| CommandError::Store(StoreError::NoRecord(s)))?;
                let act = ActiveTable::new(table, BootSource::from(report.bank))
                    .map_err(CommandError::Store)?;
                self.candidate = None;
                self.activate(act, out);
                Ok(Outcome::Done)
            }
            Command::RevertToNominal => {
                self.require_idle()?;
                self.store.set_nominal_active();
                self.activate(nominal_active(), out);
                Ok(Outcome::Done)
            }
            Command::DumpTable(memory) => {
                let bytes = match memory {
                    MemoryId::ActiveTable => self.active.table.to_bytes(),
                    MemoryId::UploadBuffer => self.upload,
                };
                let time = self.time();
                for (off, chunk) in dump_chunks(&bytes) {
                    let mut buf = [0u8; MAX_TM_FRAME_LEN];
                    if let Ok(n) = self
                        .tm
                        .emit_table_dump_chunk(time, memory, off, chunk, &mut buf)
                    {
                        if let Some(f) = buf.get(..n) {
                            out.send(f);
                        }
                    }
                }
                Ok(Outcome::Done)
            }
        }
    }

    fn direct_limits(&self) -> DirectStrokeLimits {
        let (min_mm, max_mm) = match self.active.geom.stroke {
            Some(s) => (s.min_mm, s.max_mm),
            None => ([f32::NEG_INFINITY; LEGS], [f32::INFINITY; LEGS]),
        };
        DirectStrokeLimits {
            max_speed_mm_per_s: self.cfg.direct_speed_mm_per_s,
            max_accel_mm_per_s2: self.cfg.direct_accel_mm_per_s2,
            max_delta_mm: self.cfg.direct_max_delta_mm,
            stroke_min_mm: min_mm,
            stroke_max_mm: max_mm,
        }
    }

    fn start_move(&mut self, target: Pose<f32>) -> Result<Outcome, CommandError> {
        self.require_can_move()?;
        // Plan from the commanded pose (where the drives are being held); the FK pose
        // differs from it by the encoder resolution only. The ends are checked now (a
        // refused target is refused at once with every reason); the path samples are
        // evaluated over the next cycles.
        let start = self.pose_commanded;
        let begun = TrajectoryPlanner::begin(&self.active.geom, &start, &target, &self.cfg.motion)
            .map_err(|e| {
                self.refusal_bits = CommandError::Motion(e).data();
                CommandError::Motion(e)
            })?;
        self.refusal_bits = 0;
        self.plan_aborted = false;
        self.state = State::Moving;
        match begun {
            PlanStart::Ready(traj) => {
                self.motion = Motion::Path {
                    traj,
                    start_cycle: self.cycle.wrapping_add(1),
                    stopping: false,
                };
                Ok(Outcome::Started)
            }
            PlanStart::Sampling(planner) => {
                self.motion = Motion::Planning(planner);
                Ok(Outcome::Planning)
            }
        }
    }

    fn commit_upload(
        &mut self,
        crc32: u32,
        out: &mut impl TmSink,
    ) -> Result<Outcome, CommandError> {
        let missing: u32 = (0..TABLE_LEN)
            .filter(|at| {
                self.upload_seen
                    .get(at / 8)
                    .is_none_or(|bits| bits & (1 << (at % 8)) == 0)
            })
            .count() as u32;
        if missing > 0 {
            return Err(CommandError::UploadIncomplete(
                missing.min(u32::from(u16::MAX)) as u16,
            ));
        }
        let computed = crate::table::layout::CRC32.checksum(
            self.upload
                .get(..crate::table::layout::TABLE_CRC_OFFSET)
                .unwrap_or(&[]),
        );
        if computed != crc32 {
            return Err(CommandError::CrcMismatch(computed));
        }
        let table = Table::decode(&self.upload).map_err(|e| CommandError::TableDecode(e.code()))?;
        let report = self
            .store
            .commit(&table, &self.cfg.validation)
            .map_err(CommandError::Store)?;
        let act =
            ActiveTable::new(table, BootSource::from(report.bank)).map_err(CommandError::Store)?;
        self.candidate = Some(act);
        self.upload_seen = [0; UPLOAD_BITMAP_LEN];
        self.event(
            out,
            EventSeverity::Info,
            event::TABLE_COMMITTED,
            [
                table.table_id,
                u32::from(BootSource::from(report.bank).code()),
            ],
        );
        Ok(Outcome::Done)
    }

    fn activate(&mut self, act: ActiveTable, out: &mut impl TmSink) {
        self.active = act;
        self.supervisor
            .set_config(SupervisionConfig::from_table(&act.table));
        // The same strokes are a (slightly) different pose under the new geometry:
        // re-derive it, hold, and command from there.
        self.hold_here();
        self.event(
            out,
            EventSeverity::Info,
            event::TABLE_ACTIVATED,
            [act.table.table_id, act.crc32],
        );
    }

    fn send_housekeeping(&mut self, out: &mut impl TmSink) {
        let hk = self.housekeeping();
        let mut buf = [0u8; MAX_TM_FRAME_LEN];
        if let Ok(n) = self.tm.emit_housekeeping(self.time(), &hk, &mut buf) {
            if let Some(f) = buf.get(..n) {
                out.send(f);
            }
        }
    }

    /// The housekeeping sample of now.
    pub fn housekeeping(&self) -> Housekeeping {
        let to_nm = |v: &[f32; LEGS]| v.map(|s| round_nm(s * NM_PER_MM));
        let moving_legs = match &self.motion {
            Motion::Hold | Motion::Planning(_) => 0,
            Motion::Path { .. } => 0b11_1111,
            Motion::Stroke { mv, .. } => 1u8.checked_shl(u32::from(mv.leg())).unwrap_or(0),
        };
        Housekeeping {
            state: self.state.code(),
            boot_source: self.boot.source.code(),
            active_bank: self.active.source.code(),
            fk_iterations: self.fk_iterations,
            fk_valid: self.fk_valid,
            cycle_counter: self.cycle,
            fault_flags: self.supervisor.latched().bits(),
            warning_flags: self.warnings.bits(),
            refusal_bits: self.refusal_bits,
            active_table_id: self.active.table.table_id,
            active_table_crc32: self.active.crc32,
            pose_fk: wire_pose_f32(&self.pose_fk),
            pose_commanded: wire_pose_f32(&self.pose_commanded),
            strokes_commanded_nm: to_nm(&self.strokes_commanded_mm),
            encoders_nm: to_nm(&self.encoders_mm),
            tc_accepted: self.tc_accepted,
            tc_rejected: self.tc_rejected,
            last_failure_code: self.last_failure_code,
            moving_legs,
        }
    }

    /// Current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// Control cycles since boot.
    pub fn cycle(&self) -> u32 {
        self.cycle
    }

    /// The boot report (table source, bank status).
    pub fn boot_report(&self) -> &BootReport {
        &self.boot
    }

    /// The active table.
    pub fn active_table(&self) -> &Table {
        &self.active.table
    }

    /// Latched faults.
    pub fn faults(&self) -> FaultFlags {
        self.supervisor.latched()
    }

    /// The mechanism (e.g. the simulated plant in host tests, to advance its time).
    pub fn mechanism_mut(&mut self) -> &mut M {
        &mut self.mech
    }

    /// The parameter-table store (e.g. the mock flash in host tests).
    pub fn store_mut(&mut self) -> &mut TableStore<F> {
        &mut self.store
    }
}

/// What a telecommand did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    /// A move accepted and being planned: start is reported when the plan is done.
    Planning,
    /// Executed completely.
    Done,
    /// Started; completion is reported when the motion ends.
    Started,
}

fn nominal_active() -> ActiveTable {
    let table = Table::nominal();
    let geom = match Geometry::new(&table.geometry_params()) {
        Ok(g) => g,
        // The compiled-in nominal geometry is valid (checked by host tests); this arm
        // only exists because the constructor is fallible.
        Err(_) => Geometry {
            legs: [crate::kinematics::geometry::Leg::default(); LEGS],
            p0_mm: [0.0; 3],
            stroke: None,
            workspace: None,
        },
    };
    ActiveTable {
        crc32: table.crc32(),
        table,
        geom,
        source: BootSource::Nominal,
    }
}

/// Below this magnitude every f32 multiple of 0.5 is exact, so rounding in f32 is
/// exact too (2^22).
const F32_EXACT_HALF_LIMIT: f32 = 4_194_304.0;

/// A telemetry pose (nm, uas) of an f32 pose. Translations (|x| <= 4 mm in nm fits
/// [`F32_EXACT_HALF_LIMIT`]) are scaled and rounded in f32: the product carries at most
/// ~0.25 nm of rounding, so the reported nm can differ from exact rounding by 1 nm on a
/// half-way value. Rotations need more than f32's 24 bits in micro-arcseconds and take
/// the exact f64 path. This keeps the 1 Hz housekeeping cycle inside the cycle budget
/// (f64 is software floating point on the Cortex-M4F).
fn wire_pose_f32(pose: &Pose<f32>) -> WirePose {
    let translation_nm = pose.translation_mm.map(|v| {
        let p = v * NM_PER_MM;
        if p.abs() < F32_EXACT_HALF_LIMIT {
            round_nm(p)
        } else {
            round_sat_i32(f64::from(v) * f64::from(NM_PER_MM))
        }
    });
    WirePose {
        translation_nm,
        rotation_uas: pose
            .rotation_rad
            .map(|v| round_sat_i32(f64::from(v) * UAS_PER_RAD)),
    }
}

/// Micro-arcseconds per radian.
const UAS_PER_RAD: f64 = crate::kinematics::ARCSEC_PER_RAD * 1.0e6;

/// Rounds to the nearest nanometre, saturating at the i32 range (telemetry only).
fn round_nm(v: f32) -> i32 {
    let r = if v >= 0.0 { v + 0.5 } else { v - 0.5 };
    if r.is_nan() {
        0
    } else {
        r as i32
    }
}
