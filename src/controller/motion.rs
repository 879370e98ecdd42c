//! Motion sequencing: planning over cycles, stepping the path or the direct-stroke move,
//! stops, and the start/completion reports of the move telecommand.

use super::error::{suspect, CommandError};
use super::verification::{Accepted, Outcome, Token};
use super::TmRecord;
use super::{event, Controller, State};
use crate::hw::MechanismIo;
use crate::kinematics::{fk, ik, FkConfig, Frames, Geometry, Pose, LEGS};

use crate::link::tm::EventSeverity;
use crate::motion::fine::{in_position_legs, single_reading_tolerance_mm, Fine, FineStep};
use crate::motion::{
    DirectStrokeLimits, PlanStart, StrokeMove, Trajectory, TrajectoryPlanner, PATH_SAMPLE_INTERVALS,
};
use crate::motion::{LimitKind, MotionLimits, Ramp};
use crate::supervision::FaultFlags;

/// The motion in progress.
#[derive(Clone, Copy, Debug)]
pub(super) enum Motion {
    /// At rest: the drives hold.
    Hold,
    /// A move accepted and being planned (a few cycles); the drives hold meanwhile.
    Planning(TrajectoryPlanner),
    /// A coordinated move along a straight path in pose space.
    Path {
        traj: Trajectory,
        start_cycle: u32,
        stopping: bool,
    },
    /// One slider by a stroke (recovery).
    Stroke {
        mv: StrokeMove,
        start_cycle: u32,
        stopping: bool,
    },
    /// A coordinated move's fine positioning after its path (or instead of it, when the
    /// target is already in position): waiting for the sliders to be in position, or a
    /// correction (`ramp`, from `start_cycle`; [`Ramp::immediate`] while waiting).
    Fine {
        fine: Fine,
        ramp: Ramp,
        start_cycle: u32,
        stopping: bool,
    },
}

/// The answer of a move check (TM[8,130]).
pub use crate::link::tm::MoveCheckReport as MoveCheck;

/// A move check TC[8,1] 0x0006 as executed: the controller's state, working geometry,
/// frames, limits and held strokes at that moment, copied so that the check is
/// evaluated outside the controller's lock. Its evaluation (IK of the target, FK of the
/// held strokes, IK of every sample of the straight path: up to
/// `PATH_SAMPLE_INTERVALS + 1` IK and one FK, ~57,000 instructions on the M4F in
/// the flight profile, `m2cyclebench`) would otherwise hold the lock, and so delay the
/// control task, by more than a control cycle's budget.
#[derive(Clone, Copy, Debug)]
pub struct MoveCheckJob {
    /// The check's telecommand, accepted.
    token: Token<Accepted>,
    /// Target pose (operator frames: mm, rad).
    target: Pose<f32>,
    /// Why a move could not start now (0: it could).
    state_code: u16,
    geom: Geometry<f32>,
    frames: Frames<f32>,
    motion: MotionLimits,
    fk_cfg: FkConfig<f32>,
    /// Strokes the drives held (mm).
    held_mm: [f32; LEGS],
    /// The commanded pose (internal frames; FK warm start).
    pose_commanded: Pose<f32>,
}

impl MoveCheckJob {
    /// The check's telecommand (its start and completion follow the check's report).
    pub fn token(&self) -> Token<Accepted> {
        self.token
    }

    /// Every reason a move to the target would be refused: the state (fault, motion,
    /// job), the target's workspace check, the straight path's first refused sample.
    #[inline(never)]
    pub fn evaluate(&self) -> MoveCheck {
        let now = self.state_code;
        let target_refusals =
            crate::kinematics::check(&self.geom, &self.frames.to_internal(&self.target)).to_bits();
        let Ok(start) = fk(
            &self.geom,
            &self.held_mm,
            &self.pose_commanded,
            &self.fk_cfg,
        ) else {
            return MoveCheck {
                code: if now != 0 {
                    now
                } else {
                    CommandError::NoPose.code()
                },
                target_refusals,
                path_refusals: 0,
                path_sample: 0,
            };
        };
        let start = self.frames.to_operator(&start.pose);
        let planned = TrajectoryPlanner::begin_in(
            &self.geom,
            &self.frames,
            &start,
            &self.target,
            &self.motion,
        )
        .and_then(|b| match b {
            PlanStart::Ready(_) => Ok(()),
            // All the path's samples at once: a bounded cost (PATH_SAMPLE_INTERVALS + 1
            // IK evaluations and one FK, measured in the cycle benchmark).
            PlanStart::Sampling(mut p) => p
                .advance(&self.geom, PATH_SAMPLE_INTERVALS + 1)
                .unwrap_or(Err(crate::motion::MotionError::TooLong))
                .map(|_| ()),
        });
        let (code, path_refusals, path_sample) = match planned {
            Ok(()) => (0, 0, 0),
            Err(e @ crate::motion::MotionError::PathRefused { sample, refusals }) => {
                (e.code(), refusals.to_bits(), sample)
            }
            Err(e) => (e.code(), 0, 0),
        };
        MoveCheck {
            code: if now != 0 { now } else { code },
            target_refusals,
            path_refusals,
            path_sample,
        }
    }
}

/// Faults that make a leg's encoder unfit to guide a direct-stroke move of that leg.
const ENCODER_FAULTS: [(FaultFlags, u32); 3] = [
    (FaultFlags::ENCODER_READ_FAILURE, suspect::READ_FAILURE),
    (FaultFlags::ENCODER_JUMP, suspect::JUMP),
    (FaultFlags::ENCODER_STUCK, suspect::STUCK),
];

impl<M: MechanismIo> Controller<M> {
    /// Turns the current motion into a stop ramp; at rest, holds every drive where it is.
    pub(super) fn begin_stop(&mut self) {
        let now = self.cycle;
        match &mut self.motion.now {
            // A fault latched at rest: the drives hold where their sliders are, as when
            // a stop comes to rest with a fault latched (a slider jammed short of its
            // setpoint must not complete its move when the jam frees). The next cycle's
            // supervision takes the held strokes as the reference.
            Motion::Hold => self.mech.hold(),
            Motion::Planning(_) => self.motion.plan_aborted = true,
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
            Motion::Fine {
                ramp,
                start_cycle,
                stopping,
                ..
            } => {
                if !*stopping {
                    ramp.stop(now.wrapping_sub(*start_cycle));
                    *stopping = true;
                }
            }
        }
    }

    /// Stops at once: every drive holds where it is, no ramp (the running geometry
    /// cannot be trusted to compute one). The move in progress, if any, ends with a
    /// completion failure.
    pub(super) fn hold_now(&mut self) {
        let was_moving = !matches!(self.motion.now, Motion::Hold);
        if let Motion::Planning(_) = self.motion.now {
            self.motion.plan_aborted = true;
            self.step_planning();
        }
        self.motion.now = Motion::Hold;
        self.hold_here();
        self.motion.moving_prev = false;
        if was_moving {
            self.end_pending_move(true);
        }
    }

    /// Reports the end of the pending move: completion success, or failure with the
    /// stop or the fault that ended it.
    fn end_pending_move(&mut self, stopped: bool) {
        if !matches!(self.ledger.pending, Some(p) if p.is_motion()) {
            return;
        }
        if stopped {
            let latched = self.supervisor.latched();
            let err = if latched.is_empty() {
                CommandError::Stopped
            } else {
                CommandError::AbortedByFault(latched)
            };
            self.complete_pending(Err(err));
        } else {
            self.complete_pending(Ok(()));
        }
    }

    /// Advances a move being planned: on completion it becomes the path (start success
    /// reported), on refusal or abort the sliders keep holding (start failure reported).
    fn step_planning(&mut self) {
        if !matches!(self.motion.now, Motion::Planning(_)) {
            return;
        }
        let result = if self.motion.plan_aborted {
            let latched = self.supervisor.latched();
            Some(Err(if latched.is_empty() {
                CommandError::Stopped
            } else {
                CommandError::AbortedByFault(latched)
            }))
        } else if let Motion::Planning(planner) = &mut self.motion.now {
            // Advanced where it is (not copied out and back: the control task's stack).
            planner
                .advance(&self.tables.active.geom, super::PLAN_SAMPLES_PER_CYCLE)
                .map(|r| r.map_err(CommandError::Motion))
        } else {
            None
        };
        self.motion.plan_aborted = false;
        match result {
            None => {}
            Some(Ok(traj)) => {
                self.motion.refusal_bits = 0;
                // The path starts in this very cycle (the motion step follows).
                self.motion.now = Motion::Path {
                    traj,
                    start_cycle: self.cycle,
                    stopping: false,
                };
                self.start_pending(Ok(()));
            }
            Some(Err(e)) => {
                self.motion.now = Motion::Hold;
                if let CommandError::Motion(_) = e {
                    self.motion.refusal_bits = e.data();
                    self.event(
                        EventSeverity::Low,
                        event::MOVE_REFUSED,
                        [self.motion.refusal_bits, u32::from(e.code())],
                    );
                }
                self.start_pending(Err(e));
            }
        }
    }

    /// Step 4 of the cycle: the motion's setpoint to the drives, or a drive poll at rest.
    pub(super) fn step_motion(&mut self) {
        self.step_planning();
        let now = self.cycle;
        // Matched by reference: the trajectory (236 bytes) is not copied onto the control
        // task's stack.
        let (strokes, moving, done, stopping) = match &self.motion.now {
            Motion::Hold | Motion::Planning(_) => (self.motion.strokes_mm, false, false, false),
            Motion::Path {
                traj,
                start_cycle,
                stopping,
            } => {
                let stopping = *stopping;
                let sp = traj.setpoint(now.wrapping_sub(*start_cycle));
                match ik(&self.tables.active.geom, &sp.pose) {
                    Ok(s) => {
                        self.motion.pose = sp.pose;
                        (s, sp.moving, sp.done, stopping)
                    }
                    Err(_) => {
                        // Planned paths are checked along their length; should a
                        // setpoint still be refused, hold here and say so.
                        let refusals = crate::kinematics::check(&self.tables.active.geom, &sp.pose);
                        self.event(
                            EventSeverity::High,
                            event::SETPOINT_REFUSED,
                            [refusals.to_bits(), now],
                        );
                        (self.motion.strokes_mm, false, true, true)
                    }
                }
            }
            Motion::Stroke {
                mv,
                start_cycle,
                stopping,
            } => {
                let sp = mv.setpoint(now.wrapping_sub(*start_cycle));
                (sp.strokes_mm, sp.moving, sp.done, *stopping)
            }
            Motion::Fine {
                fine,
                ramp,
                start_cycle,
                stopping,
            } => {
                let smp = ramp.sample(now.wrapping_sub(*start_cycle));
                (
                    fine.setpoint(smp.progress),
                    smp.rate_per_cycle > 0.0,
                    smp.at_rest,
                    *stopping,
                )
            }
        };
        // Waiting for the sliders commands nothing, as at rest.
        let resting = match self.motion.now {
            Motion::Hold | Motion::Planning(_) => true,
            Motion::Fine { .. } => done,
            _ => false,
        };
        if resting {
            // Nothing is commanded at rest: poll the drives' health instead. The next
            // motion's end-of-travel clamp starts from its own first cycle's switches,
            // its output stage from where the drives hold, at rest.
            self.motion.last_drive = self.mech.status();
            self.travel.rest();
            self.motion.limiter.rest(self.motion.strokes_mm);
        } else {
            let kind = if matches!(self.motion.now, Motion::Stroke { .. }) {
                LimitKind::Direct
            } else {
                LimitKind::Coordinated
            };
            let limited = self.motion.limiter.limit(kind, strokes);
            // The end-of-travel clamp, on every command just before the drives.
            let strokes = self
                .travel
                .clamp(limited.strokes_mm, &self.motion.strokes_mm);
            self.motion.approach.track(&strokes);
            self.motion.strokes_mm = strokes;
            self.motion.last_drive = self.drive_mm(&strokes);
            if !limited.limits_ok {
                // The output stage's own limits are upset: no command is trusted; the
                // repair re-derives them.
                self.ram_upset();
                return;
            }
            if limited.legs != 0 {
                self.output_limited(limited.legs);
                return;
            }
        }
        self.motion.moving_prev = moving;
        if done {
            if matches!(self.motion.now, Motion::Fine { .. }) && !stopping {
                self.step_fine();
                return;
            }
            let was_stroke = matches!(self.motion.now, Motion::Stroke { .. });
            let path_arrived = matches!(self.motion.now, Motion::Path { .. }) && !stopping;
            self.motion.now = Motion::Hold;
            if !self.supervisor.latched().is_empty() {
                // Came to rest with a fault latched: the drives hold where their sliders
                // are, so a jammed slider that frees later does not lurch to the stop
                // ramp's last setpoint.
                self.hold_here();
            } else if was_stroke {
                // The commanded pose of the strokes now held.
                self.sync_to_drives();
            } else if path_arrived {
                // The path has arrived: its completion waits for the sliders.
                self.begin_fine(strokes, false);
                return;
            }
            self.end_pending_move(stopping);
        }
    }

    /// Begins the fine positioning on the setpoint strokes `target_mm` (module
    /// [`crate::motion::fine`]); the move's completion waits for it.
    pub(super) fn begin_fine(&mut self, target_mm: [f32; LEGS], creep: bool) {
        self.motion.setpoint_mm = target_mm;
        self.motion.now = Motion::Fine {
            fine: Fine::begin(target_mm, &self.motion.approach, self.cycle, creep),
            ramp: Ramp::immediate(),
            start_cycle: self.cycle,
            stopping: false,
        };
    }

    /// A cycle of the fine positioning at rest: completion when in position, a
    /// correction when due, a completion failure at the timeout.
    #[inline(never)]
    fn step_fine(&mut self) {
        let (tol, dwell) = self.settings.ops.in_position;
        let now = self.cycle;
        let enc = self
            .estimate
            .encoders_valid
            .then_some(&self.estimate.encoders_mm);
        let Motion::Fine {
            fine,
            ramp,
            start_cycle,
            ..
        } = &mut self.motion.now
        else {
            return;
        };
        let end = match fine.at_rest(now, enc, tol, dwell) {
            FineStep::Wait => return,
            FineStep::InPosition => Ok(()),
            FineStep::TimedOut(legs) => Err(CommandError::NotInPosition(legs)),
            FineStep::Correct => {
                if let Some(stroke) = &self.tables.active.geom.stroke {
                    let lim = &self.settings.ops.motion;
                    if let Ok(r) = fine.correct(
                        &self.motion.strokes_mm,
                        tol,
                        &stroke.min_mm,
                        &stroke.max_mm,
                        lim.max_speed_mm_per_s[0],
                        lim.max_accel_mm_per_s2[0],
                    ) {
                        // From the next cycle (its sample 0 commands the held strokes).
                        *ramp = r;
                        *start_cycle = now.wrapping_add(1);
                    }
                }
                return;
            }
        };
        self.motion.now = Motion::Hold;
        if matches!(self.ledger.pending, Some(p) if p.is_motion()) {
            self.complete_pending(end);
        }
    }

    /// The legs whose encoder reads within the in-position tolerance (plus half a count:
    /// [`single_reading_tolerance_mm`]) of the setpoint of the last coordinated move
    /// (or of where the drives were told to hold): housekeeping `in_position_legs`. At
    /// rest this is the creep rule: a slider that creeps out is reported here, not
    /// moved (the controller moves on telecommands only); the next move, even to the
    /// same target, corrects it.
    pub fn in_position_legs(&self) -> u8 {
        let target = self.motion.setpoint_mm;
        self.in_position_mask(&target)
    }

    /// The strokes the encoders must read to be in position (mm): the setpoint of the
    /// last coordinated move, or where the drives were told to hold.
    pub fn in_position_setpoint_mm(&self) -> [f32; LEGS] {
        self.motion.setpoint_mm
    }

    /// Every leg's encoder reads within the in-position tolerance of `target_mm`.
    fn in_position_of(&self, target_mm: &[f32; LEGS]) -> bool {
        self.in_position_mask(target_mm) == crate::supervision::ALL_LEGS
    }

    fn in_position_mask(&self, target_mm: &[f32; LEGS]) -> u8 {
        let enc = self
            .estimate
            .encoders_valid
            .then_some(&self.estimate.encoders_mm);
        let tol = single_reading_tolerance_mm(self.settings.ops.in_position.0);
        in_position_legs(target_mm, enc, tol)
    }

    /// The output stage clamped a step of `legs`: latch [`FaultFlags::OUTPUT_LIMITED`]
    /// (event 0x0002 naming the legs) and hold at once where the clamped command left
    /// the drives (the geometry or the planner is wrong: no ramp computed by them can be
    /// trusted).
    #[inline(never)]
    fn output_limited(&mut self, legs: u8) {
        let flag = FaultFlags::OUTPUT_LIMITED;
        self.supervisor.raise_external_on(flag, legs);
        self.event(
            EventSeverity::High,
            event::FAULT_LATCHED,
            [
                self.supervisor.latched().bits(),
                flag.bits() | (u32::from(legs) << event::FAULT_LEGS_SHIFT),
            ],
        );
        self.hold_now();
    }

    fn require_geometry(&self) -> Result<(), CommandError> {
        if self.tables.geometry_ok {
            Ok(())
        } else {
            Err(CommandError::NoGeometry)
        }
    }

    /// At rest (holding, faulted or not) and no table job running.
    pub(super) fn require_idle(&self) -> Result<(), CommandError> {
        match self.state() {
            State::Idle | State::Faulted => {}
            s => return Err(CommandError::Busy(s)),
        }
        match self.jobs.running_code() {
            0 => Ok(()),
            job => Err(CommandError::JobBusy(job)),
        }
    }

    fn require_can_move(&self) -> Result<(), CommandError> {
        self.require_geometry()?;
        let latched = self.supervisor.latched();
        if !latched.is_empty() {
            return Err(CommandError::Faulted(latched));
        }
        self.require_idle()?;
        self.require_no_exposure_hold()
    }

    /// No exposure hold in force (operator moves are refused during one: 0x0710, data
    /// its seconds left, rounded up).
    fn require_no_exposure_hold(&self) -> Result<(), CommandError> {
        if self.exposure.active() {
            return Err(CommandError::ExposureHold(
                self.exposure
                    .left_cycles()
                    .div_ceil(crate::timing::CONTROL_RATE_HZ),
            ));
        }
        Ok(())
    }

    /// The pose the drives hold now, in the operator's frames: the start of any move
    /// (FK of the held strokes, warm-started from the commanded pose).
    fn held_pose(&mut self) -> Result<Pose<f32>, CommandError> {
        let held = self.held_mm();
        self.motion.strokes_mm = held;
        let sol = fk(
            &self.tables.active.geom,
            &held,
            &self.motion.pose,
            &self.estimate.cfg,
        )
        .map_err(|_| CommandError::NoPose)?;
        self.motion.pose = sol.pose;
        Ok(self.settings.ops.frames.to_operator(&sol.pose))
    }

    /// Starts a coordinated move to `target` (absolute pose in the operator's frames:
    /// the pivot's displacement along the user frame's axes, the rotation in it).
    pub(super) fn start_move(&mut self, target: Pose<f32>) -> Result<Outcome, CommandError> {
        self.require_can_move()?;
        // Plan from the pose of the strokes the drives hold, so the first setpoint is
        // continuous with them. The ends are checked now (a refused target is refused at
        // once with every reason); the path samples are evaluated over the next cycles.
        let start = self.held_pose()?;
        // Nothing to do: every slider already reads within the in-position tolerance of
        // the target's strokes. No path: the fine positioning completes the move after
        // the dwell, without motion.
        if let Ok(target_mm) = ik(
            &self.tables.active.geom,
            &self.settings.ops.frames.to_internal(&target),
        ) {
            if self.in_position_of(&target_mm) {
                self.motion.refusal_bits = 0;
                self.begin_fine(target_mm, false);
                return Ok(Outcome::Started);
            }
        }
        let begun = TrajectoryPlanner::begin_in(
            &self.tables.active.geom,
            &self.settings.ops.frames,
            &start,
            &target,
            &self.settings.ops.motion,
        )
        .map_err(|e| {
            self.motion.refusal_bits = CommandError::Motion(e).data();
            CommandError::Motion(e)
        })?;
        self.motion.refusal_bits = 0;
        self.motion.plan_aborted = false;
        match begun {
            PlanStart::Ready(traj) => {
                // Telecommands are handled between control cycles: `self.cycle` is
                // already the index of the next one, where the path begins.
                self.motion.now = Motion::Path {
                    traj,
                    start_cycle: self.cycle,
                    stopping: false,
                };
                Ok(Outcome::Started)
            }
            PlanStart::Sampling(planner) => {
                self.motion.now = Motion::Planning(planner);
                Ok(Outcome::Planning)
            }
        }
    }

    /// Takes a move check TC[8,1] 0x0006 of `target` (operator frames): everything its
    /// evaluation reads is copied into a [`MoveCheckJob`], evaluated by the link service
    /// outside the controller's lock ([`Controller::take_move_check`]). (A check a
    /// direct caller left uncollected was evaluated when this telecommand arrived:
    /// [`Controller::execute_telecommand`].)
    #[inline(never)]
    pub(super) fn queue_move_check(&mut self, token: Token<Accepted>, target: Pose<f32>) {
        self.motion.check = Some(MoveCheckJob {
            token,
            target,
            state_code: self.require_can_move().err().map_or(0, |e| e.code()),
            geom: self.tables.active.geom,
            frames: self.settings.ops.frames,
            motion: self.settings.ops.motion,
            fk_cfg: self.estimate.cfg,
            held_mm: self.held_mm(),
            pose_commanded: self.motion.pose,
        });
    }

    /// Moves the move check waiting for evaluation (if any) into `slot` (the link
    /// service's; copied once, not via the stack). Returns whether there was one.
    pub fn take_move_check(&mut self, slot: &mut Option<MoveCheckJob>) -> bool {
        match &self.motion.check {
            Some(job) => {
                *slot = Some(*job);
                self.motion.check = None;
                true
            }
            None => false,
        }
    }

    /// Reports an evaluated move check: TM[8,130], then start and completion success as
    /// its telecommand asked.
    pub fn finish_move_check(&mut self, token: Token<Accepted>, check: MoveCheck) {
        let request_id = token.request_id();
        self.tm
            .push(self.cycle, TmRecord::MoveCheck { request_id, check });
        self.done(token);
    }

    /// Evaluates and reports the waiting move check here (a caller without a link
    /// service; the link service evaluates outside the lock instead).
    #[inline(never)]
    pub fn run_move_check(&mut self) {
        let mut slot = None;
        self.take_move_check(&mut slot);
        if let Some(job) = &slot {
            let check = job.evaluate();
            self.finish_move_check(job.token, check);
        }
    }

    /// The relative-move target: the held pose plus `delta` component by component, in
    /// the operator's frames (translations added along the user frame's axes, Euler
    /// angles added).
    #[inline(never)]
    pub(super) fn relative_target(&mut self, delta: Pose<f32>) -> Result<Pose<f32>, CommandError> {
        self.require_can_move()?;
        let mut target = self.held_pose()?;
        for (t, v) in target.translation_mm.iter_mut().zip(delta.translation_mm) {
            *t += v;
        }
        for (t, v) in target.rotation_rad.iter_mut().zip(delta.rotation_rad) {
            *t += v;
        }
        Ok(target)
    }

    /// Why leg `idx`'s own encoder is unfit to guide a direct-stroke move of it
    /// ([`suspect`] bits, 0 if fit).
    fn encoder_suspect(&self, idx: usize, held_mm: f32) -> u32 {
        let mut why = 0;
        let leg_bit = 1u8.checked_shl(idx as u32).unwrap_or(0);
        for (flag, bit) in ENCODER_FAULTS {
            if self.supervisor.latched_legs(flag) & leg_bit != 0 {
                why |= bit;
            }
        }
        if !self.estimate.encoders_valid {
            why |= suspect::NO_READING;
        } else if let Some(m) = self.estimate.encoders_mm.get(idx) {
            let threshold = self.supervisor.config().following_fault_mm;
            if !((m - held_mm).abs() <= threshold) {
                why |= suspect::DISAGREES;
            }
        }
        why
    }

    /// Starts a direct-stroke (recovery) move of `leg` (1..=6) by `delta_mm`: that leg
    /// from its held setpoint, every other leg keeping exactly its setpoint.
    #[inline(never)]
    pub(super) fn start_direct_stroke(
        &mut self,
        leg: u8,
        delta_mm: f32,
    ) -> Result<Outcome, CommandError> {
        // Recovery works while faulted (that is what it is for), not while moving, nor
        // during an exposure hold.
        self.require_geometry()?;
        self.require_idle()?;
        self.require_no_exposure_hold()?;
        let Some(stroke) = self.tables.active.geom.stroke else {
            return Err(CommandError::NoGeometry);
        };
        let idx = leg.wrapping_sub(1);
        let held = self.held_mm();
        let Some(own) = held.get(usize::from(idx)).copied() else {
            return Err(CommandError::Stroke(crate::motion::StrokeMoveError::BadLeg));
        };
        let why = self.encoder_suspect(usize::from(idx), own);
        if why != 0 {
            return Err(CommandError::EncoderSuspect(why));
        }
        // Only away from an end-of-travel switch: not toward one active now or seen
        // since the limit-switch fault latched (an unreadable input blocks both ways).
        let (blocked_negative, blocked_positive) = self.end_of_travel_blocked();
        let leg_bit = 1u8.checked_shl(u32::from(idx)).unwrap_or(0);
        let toward = if delta_mm > 0.0 {
            blocked_positive
        } else if delta_mm < 0.0 {
            blocked_negative
        } else {
            0
        };
        if toward & leg_bit != 0 {
            return Err(CommandError::TowardEndOfTravel(toward));
        }
        let (speed, accel, delta) = self.settings.ops.direct;
        let limits = DirectStrokeLimits {
            max_speed_mm_per_s: speed,
            max_accel_mm_per_s2: accel,
            max_delta_mm: delta,
            stroke_min_mm: stroke.min_mm,
            stroke_max_mm: stroke.max_mm,
        };
        let mv = StrokeMove::plan(&held, idx, delta_mm, &limits).map_err(CommandError::Stroke)?;
        self.motion.strokes_mm = held;
        // The move begins in the next control cycle, whose index `self.cycle` already is.
        self.motion.now = Motion::Stroke {
            mv,
            start_cycle: self.cycle,
            stopping: false,
        };
        Ok(Outcome::Started)
    }
}
