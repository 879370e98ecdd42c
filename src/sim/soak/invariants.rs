//! The invariants checked every control cycle (numbered as in the module documentation
//! of [`super`]): limits (1), speed and continuity (2), nothing moves while faulted (3),
//! a recovery move moves only its leg (4), no telemetry dropped (5), not toward an
//! active switch (7), the speed limit in force (8), an upset repaired in time (10), a
//! mirror put in position stays there while idle (14); and
//! the telemetry events the model follows (selections, detections, repairs, switch
//! trips).

use crate::controller::{event, State};
use crate::kinematics::LEGS;
use crate::link::tm::Verification;
use crate::link::Housekeeping;
use crate::link::RequestId;
use crate::motion::{CYCLE_S, DEFAULT_MAX_SPEED_MM_PER_S};
use crate::sim::InjectedFault;
use crate::station::Tm;
use crate::thermal::compensation::MAX_STEP_HIGHEST_MM;
use crate::units::UM_PER_MM;

use super::{Choices, Soak, TableRef};

/// Stroke tolerance beyond a soft limit (mm): the supervision's own tolerance.
const LIMIT_TOL_MM: f64 = 1e-3;
/// Rounding allowance on one setpoint step (mm): f32 strokes near 5 mm.
const STEP_ROUNDING_MM: f64 = 2e-6;
/// A slider "at rest" moves less than this per cycle (mm): 0.1 nm, above the f32
/// resolution of a held stroke (a hold rounds the setpoint to the f32 of the interface).
const STILL_MM: f64 = 1e-7;

/// Invariant 14's record of a mirror put in position (`Soak::check_placed`).
#[derive(Clone, Copy, Debug)]
pub(super) struct Placed {
    /// The held setpoint (mm, stroke at the thermal model's reference temperature).
    setpoint_mm: [f32; LEGS],
    /// The largest change of an applied offset in the last compensation step (mm).
    last_step_mm: f32,
    /// The largest in-position tolerance in force since (mm).
    tolerance_mm: f32,
}

/// Cycles within which a detected upset must be repaired (invariant 10): two scrub
/// periods (the reload may wait for a job that runs: a commit erases 0.3 s sectors) and
/// the slowest job.
pub const REPAIR_CYCLES: u64 = 6_000;

impl<C: Choices> Soak<C> {
    /// The per-cycle invariants (module documentation).
    pub(super) fn check_cycle(&mut self) {
        // The controller commands strokes at the thermal model's reference temperature
        // (`c_ref`, what its limits apply to); the drives receive them with the applied
        // compensation offset (`c`, what the speed and switch invariants bound).
        let c_ref = self.r.ctl.strokes_commanded_mm();
        let applied = self.r.ctl.compensation().applied_mm();
        let c: [f32; LEGS] = core::array::from_fn(|i| c_ref[i] + applied[i]);
        let state = self.r.ctl.state();
        let faulted = !self.r.ctl.faults().is_empty();
        let hk = self.r.ctl.housekeeping();
        // The running table as the operator uploaded it (the RAM copy may be upset).
        let limits = self
            .known
            .get(&hk.active_table_crc32)
            .map_or(self.r.ctl.active_table().stroke_limits, |t| t.stroke_limits);
        let truth = self.r.plant.with(|p| p.strokes_mm());
        let drives = self.r.plant.with(|p| p.drive_setpoints_mm());
        let skip = std::mem::take(&mut self.repaired);
        if let Some(n) = self.state_cycles.get_mut(usize::from(state.code())) {
            *n += 1;
        }
        // 1. Inside the limits: what is commanded and where the sliders are.
        for i in 0..LEGS {
            let (lo, hi) = (
                limits.min_mm[i] - LIMIT_TOL_MM,
                limits.max_mm[i] + LIMIT_TOL_MM,
            );
            let ci = f64::from(c_ref[i]);
            // Outside, a hold (the drive commanded to where it stood) or a command back
            // toward the limits is no command outward: a slip can carry a slider out
            // and a repair re-reference its drive there, which the controller then
            // holds until a recovery move brings it in (found by a 10-minute run:
            // 248,912 cycles of a hold at 5.029 mm counted). The repair's own cycle is
            // skipped, as by the other checks: the drive re-referenced there.
            let hold = (drives[i] - self.prev_positions[i]).abs() <= STILL_MM;
            let prev_ci = f64::from(self.prev_cmd[i]) - f64::from(self.prev_applied[i]);
            let toward_inside = (prev_ci > hi && ci <= prev_ci + STILL_MM)
                || (prev_ci < lo && ci >= prev_ci - STILL_MM);
            if !(lo..=hi).contains(&ci) && !hold && !toward_inside && !skip {
                self.violation(format!(
                    "leg {} commanded {ci} mm outside [{lo}, {hi}]",
                    i + 1
                ));
            }
            // The sliders: never taken outside, nor further outside, by the controller.
            // A slip (missed steps) can displace a slider at rest beyond a limit by
            // itself; the controller must then detect it (soft limit, following error)
            // and only bring it back, which the soak does not forbid. Found by the
            // 10-minute run: an 80 um slip at -4.93 mm put a slider 8 um beyond -5 mm,
            // detected 2 cycles later, and counted as a violation every cycle after.
            let t = truth[i] - f64::from(applied[i]);
            let outward = if t < lo {
                t < self.prev_truth[i] - STILL_MM
            } else {
                t > self.prev_truth[i] + STILL_MM
            };
            // A slip's travel reaches the slider through the drive train over the
            // following cycles (its settling), not in the cycle of the slip: until the
            // controller commands the leg again, the slider's own drift is the slip's
            // (found by a 10-minute run: a 44 um slip at 4.985 mm carried a slider out
            // over 17 cycles, each counted).
            if drives[i] != self.prev_drives[i] {
                self.slipped &= !(1 << i);
            }
            let drifting = self.slipped & (1 << i) != 0;
            let was_inside = (lo..=hi).contains(&self.prev_truth[i]);
            if !(lo..=hi).contains(&t) && (outward || was_inside) && !skip && !drifting {
                self.violation(format!("leg {} true stroke {t} mm outside", i + 1));
            }
        }
        // 2. Speed: no drive is commanded to a setpoint further than the speed limit
        //    times a cycle from its last one, unless to where it is (a hold), and the
        //    controller's commands are continuous: within a motion from cycle to cycle,
        //    and at its start from what the drives held.
        let step_limit = f64::from(DEFAULT_MAX_SPEED_MM_PER_S * CYCLE_S) + STEP_ROUNDING_MM;
        let moving = |s: State| matches!(s, State::Moving | State::Stopping | State::StrokeMoving);
        let positions = self.r.plant.with(|p| p.drive_positions_mm());
        for i in 0..LEGS {
            let d = (drives[i] - self.prev_drives[i]).abs();
            // A hold: the drive commanded to where it was (it cannot move by that).
            let hold = (drives[i] - self.prev_positions[i]).abs() <= STILL_MM;
            if d > step_limit && !hold && !skip {
                self.violation(format!(
                    "leg {} drive setpoint stepped {:.3} um in one cycle ({:?} -> {state:?})",
                    i + 1,
                    d * UM_PER_MM,
                    self.prev_state
                ));
            }
            // Continuous with the last command, or with what the drives held: a motion
            // that ended in a hold (faulted: the drives hold where they are, e.g. a
            // faulted drive that refused the commands) and a new one that started from
            // the held strokes in the same cycle.
            let from_drives = (f64::from(c[i]) - self.prev_drives[i]).abs();
            let d = if moving(self.prev_state) {
                (f64::from(c[i]) - f64::from(self.prev_cmd[i]))
                    .abs()
                    .min(from_drives)
            } else {
                from_drives
            };
            // Or a hold: commanded to where its drive is (a stop that came to rest with
            // a fault latched holds the drives where their sliders are; a jammed
            // slider's drive then steps back to it without moving anything, and a
            // recovery move may start from there in the same cycle).
            if moving(state) && d > step_limit && !hold {
                self.violation(format!(
                    "leg {} commanded step {:.3} um ({:?} -> {state:?})",
                    i + 1,
                    d * UM_PER_MM,
                    self.prev_state
                ));
            }
        }
        // 3. While faulted and at rest no slider moves (from the second cycle at rest:
        //    the drives take one cycle to reach the stop ramp's last setpoint).
        self.rest_cycles = if state == State::Faulted {
            self.rest_cycles.saturating_add(1)
        } else {
            0
        };
        //    The drives: a slider still settles on its drive train (a first-order tail
        //    after the last step), which the controller does not command.
        if self.rest_cycles > 2 && !skip {
            for i in 0..LEGS {
                if (positions[i] - self.prev_positions[i]).abs() > STILL_MM {
                    self.violation(format!(
                        "leg {} moved {:.6} um while faulted at rest",
                        i + 1,
                        (positions[i] - self.prev_positions[i]) * UM_PER_MM
                    ));
                }
            }
        }
        // 4. During a recovery move only its leg's drive setpoint changes; the others
        //    keep theirs (to the f32 rounding of a stroke). Checked from the second
        //    cycle of the same move: a move may come to rest (its leg's last setpoint)
        //    and the next start in one cycle, the last step then belonging to the move
        //    that ended (invariant 2 bounds it).
        if state == State::StrokeMoving
            && self.prev_state == State::StrokeMoving
            && hk.moving_legs == self.prev_moving_legs
            && !skip
        {
            // To the f32 rounding of a held stroke: a hold leaves a drive at its own
            // (f64) position, and the move commands it back as the f32 stroke plus the
            // f32 offset, one f32 step away (found by the 10-minute run: 0.47 pm at
            // 7 um, 3.7 pm at 52 um; a microstep is 312,500 pm).
            for i in (0..LEGS).filter(|i| hk.moving_legs & (1 << i) == 0) {
                if (drives[i] - self.prev_drives[i]).abs() > STEP_ROUNDING_MM {
                    self.violation(format!(
                        "leg {} drive setpoint {} -> {} during a recovery move of legs {:#08b}",
                        i + 1,
                        self.prev_drives[i],
                        drives[i],
                        hk.moving_legs
                    ));
                }
            }
        }
        // 5. Nothing dropped.
        if hk.tm_dropped != self.tm_dropped_seen {
            self.tm_dropped_seen = hk.tm_dropped;
            self.violation(format!("{} telemetry records dropped", hk.tm_dropped));
        }
        // 7. Not toward an active switch: a blocked leg's command does not move toward
        //    it (a hold, where the drive's setpoint is its slider's position, is no move).
        let sw = self.r.ctl.switches();
        let (neg, pos) = (sw.blocked_negative(), sw.blocked_positive());
        if moving(state) && (neg | pos) != 0 {
            self.blocked_motion_cycles += 1;
        }
        for i in 0..LEGS {
            let bit = 1u8 << i;
            let d = f64::from(c[i]) - f64::from(self.prev_cmd[i]);
            // A hold: the drive commanded to where it was (it cannot move by that).
            let hold = (drives[i] - self.prev_positions[i]).abs() <= STILL_MM;
            let toward = (pos & bit != 0 && d > 0.0) || (neg & bit != 0 && d < 0.0);
            if toward && !hold && !skip {
                self.violation(format!(
                    "leg {} commanded {:+.6} um toward an active end-of-travel switch ({sw:?}, {:?} -> {state:?})",
                    i + 1,
                    d * UM_PER_MM,
                    self.prev_state
                ));
            }
        }
        // 8. The speed limit in force (the output stage's, whatever is upset): each
        //    command's step within the coordinated or the direct limit of the motion.
        if moving(state) && moving(self.prev_state) && !skip {
            // A set in flight may be in force before its completion reaches the model.
            let dt = f64::from(CYCLE_S);
            let in_flight = |id: u16| {
                self.setting
                    .iter()
                    .flat_map(|(_, pairs)| pairs.iter())
                    .filter(|(p, _)| *p == id)
                    .map(|(_, v)| f64::from(*v) / crate::units::NM_PER_MM * dt)
                    .fold(0.0, f64::max)
            };
            let coordinated = self.step_limits_mm.0.max(in_flight(0x0010));
            let direct = self.step_limits_mm.1.max(in_flight(0x0012));
            let limit = match state {
                State::StrokeMoving => direct,
                State::Moving => coordinated,
                _ => coordinated.max(direct),
            } + f64::from(crate::motion::limiter::STEP_TOLERANCE_MM);
            for i in 0..LEGS {
                // As in 2: from the last command, or from what the drive held (a motion
                // that ended in a hold and the next that began there in one cycle); a
                // hold itself is no step.
                let d = (f64::from(c[i]) - f64::from(self.prev_cmd[i]))
                    .abs()
                    .min((f64::from(c[i]) - self.prev_drives[i]).abs());
                let hold = (drives[i] - self.prev_positions[i]).abs() <= STILL_MM;
                if d > limit && !hold {
                    self.violation(format!(
                        "leg {} commanded step {:.4} um over the {:.4} um limit in force ({:?} -> {state:?})",
                        i + 1,
                        d * UM_PER_MM,
                        limit * UM_PER_MM,
                        self.prev_state
                    ));
                }
            }
        }
        // 10. A detected upset is repaired within REPAIR_CYCLES (detections and repairs
        //     are read from the telemetry by `track_selections`).
        if let Some(t) = self.corrupt_since {
            if self.cycles.saturating_sub(t) > REPAIR_CYCLES {
                self.violation(format!(
                    "an upset detected at cycle {t} (fault 0x100) not repaired"
                ));
                self.corrupt_since = None;
            }
        }
        // 6. Track completed selections from the telemetry.
        self.track_selections();
        let step = self.check_thermal_and_hold(&applied, state, &hk);
        self.check_placed(&applied, state, faulted || skip, step);
        self.prev_cmd = c;
        self.prev_truth = core::array::from_fn(|i| truth[i] - f64::from(applied[i]));
        self.prev_drives = drives;
        self.prev_positions = positions;
        self.prev_state = state;
        self.prev_moving_legs = hk.moving_legs;
        self.prev_faulted = faulted;
    }

    /// Invariants 12 and 13 (module documentation): the compensation's steps bounded,
    /// and nothing released, stepped or started during an exposure hold (in force before
    /// and after the cycle: a hold that began or ended within it is not checked).
    /// Returns the largest change of an applied offset in the cycle (mm).
    fn check_thermal_and_hold(
        &mut self,
        applied: &[f32; LEGS],
        state: State,
        hk: &Housekeeping,
    ) -> f32 {
        let step = (0..LEGS)
            .map(|i| (applied[i] - self.prev_applied[i]).abs())
            .fold(0.0f32, f32::max);
        if step > 0.0 {
            self.thermal_steps += 1;
        }
        if step > MAX_STEP_HIGHEST_MM * (1.0 + 1e-5) {
            self.violation(format!(
                "the compensation offset stepped {:.4} um in one cycle",
                f64::from(step) * UM_PER_MM
            ));
        }
        let hold = self.r.ctl.exposure_hold_active();
        if hold && self.prev_hold {
            self.hold_cycles += 1;
            if step > 0.0 {
                self.violation("a compensation step during an exposure hold".into());
            }
            if hk.schedule.released != self.prev_released {
                self.violation("an activity released during an exposure hold".into());
            }
            let rest = |s: State| matches!(s, State::Idle | State::Faulted);
            let motion = |s: State| matches!(s, State::Moving | State::StrokeMoving);
            if rest(self.prev_state) && motion(state) {
                self.violation(format!(
                    "a motion started during an exposure hold ({:?} -> {state:?})",
                    self.prev_state
                ));
            }
        }
        self.prev_applied = *applied;
        self.prev_hold = hold;
        self.prev_released = hk.schedule.released;
        step
    }

    /// Invariant 14: a mirror put in position stays there while the controller is idle.
    /// From a completion invariant 11 found in position, while the controller stays idle
    /// with no fault latched, no plant fault injected and its setpoint unchanged, no true
    /// slider stands further from its setpoint and applied offset than the last
    /// compensation step (not followed yet), twice the in-position tolerance (where the
    /// last fine positioning left it, and a count of reading) and the encoder noise's
    /// sigma (the rule holds the mean reading). Upsets, table activations, parameter sets
    /// and exposure holds do not end the watch: none of them may move an idle mirror by
    /// more. `disturbed`: a fault latched or the soak itself moved a drive (a repair, a
    /// slip) this cycle.
    fn check_placed(&mut self, applied: &[f32; LEGS], state: State, disturbed: bool, step: f32) {
        let Some(mut placed) = self.placed else {
            return;
        };
        let plant_fault = self.r.plant.with(|p| p.faults().next().is_some());
        if state != State::Idle
            || disturbed
            || plant_fault
            || self.r.ctl.in_position_setpoint_mm() != placed.setpoint_mm
        {
            self.placed = None;
            return;
        }
        if step > 0.0 {
            placed.last_step_mm = step;
            self.placed_steps += 1;
        }
        let table = *self.r.ctl.active_table();
        placed.tolerance_mm = placed
            .tolerance_mm
            .max(self.r.ctl.parameters().in_position(&table).0);
        self.placed = Some(placed);
        self.placed_cycles += 1;
        let bound = f64::from(placed.last_step_mm)
            + 2.0 * f64::from(placed.tolerance_mm)
            + crate::sim::plant::DEFAULT_ENCODER_NOISE_MM;
        let truth = self.r.plant.with(|p| p.strokes_mm());
        for i in 0..LEGS {
            let off = truth[i] - f64::from(placed.setpoint_mm[i] + applied[i]);
            let beyond_step = off.abs() - f64::from(placed.last_step_mm);
            self.placed_worst_mm = self.placed_worst_mm.max(beyond_step);
            if off.abs() > bound {
                self.violation(format!(
                    "idle, leg {} is {:.4} um from its setpoint and offset (bound {:.4} um)",
                    i + 1,
                    off * UM_PER_MM,
                    bound * UM_PER_MM
                ));
                self.placed = None;
                return;
            }
        }
    }

    /// A completed activation is a TABLE_ACTIVATED event: that table is now the one to
    /// boot.
    fn track_selections(&mut self) {
        let new = self.r.st.log.len();
        for k in self.log_seen..new {
            if let Tm::Event(_, event::END_OF_TRAVEL, _) = self.r.st.log[k] {
                self.switch_trips += 1;
            }
            // Each detection (event 0x0002 naming 0x100 among the new faults) waits for
            // a repair (event 0x0013); the fault may stay latched until cleared.
            if let Tm::Event(_, event::FAULT_LATCHED, [_, new]) = self.r.st.log[k] {
                if new & crate::supervision::FaultFlags::TABLE_CORRUPT.bits() != 0
                    && self.corrupt_since.is_none()
                {
                    self.corrupt_since = Some(self.cycles);
                }
            }
            if let Tm::Event(_, event::TABLE_RELOADED, _) = self.r.st.log[k] {
                self.repairs += 1;
                self.corrupt_since = None;
            }
            // A boot reloads table and parameters from flash: that repairs an upset too.
            // (A detection sent just before a power cut is read after the cut, so the
            // reboot's own reset of the tracking is too early to see it: the 10-minute
            // run flagged one such upset, detected at cycle 167,917,652 and cut 2
            // cycles later, as never repaired.)
            if let Tm::Event(_, event::BOOT, _) = self.r.st.log[k] {
                self.corrupt_since = None;
            }
            if let Tm::Event(_, event::TABLE_ACTIVATED, [id, crc]) = self.r.st.log[k] {
                let t = TableRef { id, crc };
                if !self.known.contains_key(&crc) {
                    self.violation(format!("activated an unknown table {t:?}"));
                }
                self.selected = t;
            }
        }
        self.log_seen = new;
    }

    /// Invariant 11, in the cycle the station receives a coordinated move's completion
    /// success: every true slider within the in-position tolerance in force (and the
    /// encoder noise's sigma: the rule holds the mean reading) of the controller's
    /// setpoint, unless an encoder is made to lie, the controller is no longer idle (a
    /// fault since the completion holds the drives where they are: a new setpoint) or a
    /// compensation step has moved the setpoint's offset since.
    pub(super) fn check_moves_completed(&mut self) {
        if self.moves.is_empty() {
            return;
        }
        let moves = std::mem::take(&mut self.moves);
        for (rid, from) in moves {
            if !self.r.st.finished_since(from, rid) {
                self.moves.push((rid, from));
            } else if self.r.st.reports_since(from, rid).last()
                == Some(&Verification::CompletionSuccess)
            {
                self.check_in_position(rid);
            }
        }
    }

    fn check_in_position(&mut self, rid: RequestId) {
        let misleading = self.r.plant.with(|p| {
            p.faults().any(|f| {
                matches!(
                    f,
                    InjectedFault::EncoderStuck { .. }
                        | InjectedFault::EncoderJump { .. }
                        | InjectedFault::NoiseBurst { .. }
                )
            })
        });
        // Nor once a compensation step's fine positioning has begun since the completion
        // (idle, legs moving): the sliders follow the new offset (found by a 150 s run:
        // legs "2.4 um from their setpoint" a cycle after a 2.3 um step was applied).
        if misleading
            || self.r.ctl.state() != State::Idle
            || self.r.ctl.housekeeping().moving_legs != 0
        {
            return;
        }
        self.moves_in_position += 1;
        let table = *self.r.ctl.active_table();
        let (tol_mm, _) = self.r.ctl.parameters().in_position(&table);
        let set = self.r.ctl.in_position_setpoint_mm();
        let applied = self.r.ctl.compensation().applied_mm();
        let truth = self.r.plant.with(|p| p.strokes_mm());
        let mut in_position = true;
        for i in 0..LEGS {
            let e = truth[i] - f64::from(applied[i]) - f64::from(set[i]);
            if !(e.abs() <= f64::from(tol_mm) + crate::sim::plant::DEFAULT_ENCODER_NOISE_MM) {
                in_position = false;
                self.violation(format!(
                    "move {rid:?} completed with leg {} {:.4} um from its setpoint",
                    i + 1,
                    e * UM_PER_MM
                ));
            }
        }
        // Invariant 14 watches it from here.
        if in_position {
            self.placed = Some(Placed {
                setpoint_mm: set,
                last_step_mm: 0.0,
                tolerance_mm: tol_mm,
            });
            self.placements += 1;
        }
    }
}
