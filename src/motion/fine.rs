//! Closed-loop fine positioning on the slider encoders, and the in-position rule.
//!
//! A coordinated move's path commands the **drives**; what ends at its setpoint must be
//! the **sliders**, which the encoders read. Between the two lie the drive train's
//! backlash, lead error, microsteps, friction and settling (issue 21; simulated in
//! `sim::drive_train`). After the path (and for a move whose target is already in
//! position, instead of it) the controller runs [`Fine`]:
//!
//! * **In position** = the sliders at rest for the in-position dwell (no reading moved
//!   more than twice the in-position tolerance from the window's first), and every
//!   slider's mean reading over that window within the tolerance of its setpoint (the
//!   path's last IK strokes), less half an encoder count (ST[20] parameters 0x0015 and
//!   0x0016). The mean, because single readings flicker between two counts with the
//!   encoder's noise; less half a count, because a reading is a whole count, so a
//!   mean within `tol - count/2` puts the true slider within `tol` of its setpoint.
//!   Only then is the move's completion success reported.
//! * **Corrections.** Whenever the sliders have been at rest for the dwell (they had it
//!   to settle; after a return, below, for two dwells) and some leg is not in position,
//!   every such leg's drive command is corrected, at most [`MAX_CORRECTIONS`] times per
//!   move, the drive never further than [`MAX_CORRECTION_MM`] from the setpoint and
//!   never beyond the stroke limits. A correction is a ramp within the coordinated-move
//!   speed and acceleration limits (the output stage checks it like any command).
//! * **Anti-backlash: final approach from one side.** Each leg's final approach is in
//!   the direction of its last commanded motion before the fine positioning (the path's
//!   direction at its end, a reversal counting once it exceeds [`TURN_MM`]): there the
//!   backlash gap is taken up, so a correction in that direction moves the slider by
//!   what the drive moves. The drive train leaves each slider short of its setpoint in
//!   that direction (half the gap and the friction lag), so almost every correction is
//!   one: **whole microsteps** ([`MICROSTEP_MM`]) from the one the drive stands on, as
//!   many as cannot carry the slider past the far edge of the band ([`GAIN`]), so the
//!   last one lands in it. The first such correction adds how far the command stood
//!   behind its furthest point in that direction (a reversal smaller than the turn left
//!   the gap there). A slider found beyond its setpoint (an overshoot) is not corrected
//!   back through the gap by its error (which would lose the unknown backlash): it is
//!   **retreated** past the setpoint by [`RETREAT_MM`] more, and the next correction
//!   **returns** it by as much, which takes the gap up on the approach side again with
//!   the drive the overshoot short of where it was. A leg still out at the
//!   [`LATE_CORRECTION`] is retreated and returned too (its gap may not be where the
//!   tracked direction says). Chosen by measurement (docs/decisions.md, "Fine
//!   positioning"): with the realistic drive train a correction opposite to the approach
//!   moved the slider by its error less the 3.2 um of backlash and break-away, so
//!   correcting by the error converged only after several corrections and a measured
//!   compensation would need the backlash of every leg kept and re-measured; the
//!   one-sided approach needs neither.
//! * **After a compensation step** (`controller`'s thermal compensation, no move): a
//!   leg the step moves against its approach side takes the step's side
//!   ([`Approach::step_offsets`]) and crosses its backlash gap toward it by the same
//!   corrections toward the approach, however many the timeout allows; a leg found
//!   beyond its setpoint crosses back the same way. No retreat: on a mirror held during
//!   an exposure a retreat is a 5 um excursion (docs/decisions.md, "Thermal
//!   compensation").
//! * **Timeout.** A move not in position [`TIMEOUT_CYCLES`] after its path ended ends
//!   with a completion failure 0x070F naming the legs out of tolerance.
//!
//! Strokes in mm along base z (0 at home), leg masks bit i = leg i+1.

use super::ramp::{Ramp, RampError};
use super::trajectory::LIMIT_USE_FRACTION;
use crate::hw::ENCODER_MM_PER_COUNT;
use crate::kinematics::LEGS;

/// Half an encoder count (mm): what the in-position rule takes off the tolerance.
const HALF_COUNT_MM: f32 = (0.5 * ENCODER_MM_PER_COUNT) as f32;

/// Most corrections per move.
pub const MAX_CORRECTIONS: u8 = 16;
/// The farthest the corrections of a move may take a leg's drive from its setpoint
/// (mm, 20 um): four times the following-error warning threshold, beyond what any drive
/// train leaves behind a path (a slider further off is a fault for the supervision, not
/// a task for the fine positioning). A jammed slider thus leaves its drive at most this
/// far beyond its setpoint, where the slider goes should the jam free.
pub const MAX_CORRECTION_MM: f32 = 0.02;
/// How far past its setpoint, against its final approach, an overshot slider is moved
/// back, and then returned (mm, 5 um, 64 microsteps): more than the realistic backlash
/// and break-away (3.2 um), so that the retreat moves the slider and the return takes
/// the gap up again.
pub const RETREAT_MM: f32 = 0.005;
/// Share of a leg's error (plus the in-position band) a correction toward its approach
/// side may move the drive: less than 1, so that a drive train that moves the slider
/// more than the drive (the microstep nonlinearity's slope, up to 18 % with the
/// realistic defaults) does not carry it past the far edge of the band, which would cost
/// a retreat and a new approach.
pub const GAIN: f32 = 0.85;
// A leg out of position is out by more than the band, at least half a count (the least
// tolerance is a count: `controller::params`), so a correction toward the approach side
// is at least one microstep.
const _: () = assert!(GAIN * 2.0 * HALF_COUNT_MM >= MICROSTEP_MM);
/// The drives' microstep (mm of stroke), from the drive constants of [`crate::nominal`]
/// (64 microsteps of a 200-step motor on a 1 mm lead: 0.078 um). The drives stand on
/// whole microsteps (the step/direction drivers round a setpoint to the nearest one), so
/// a correction toward the approach side is a whole number of microsteps from where the
/// drive stands: rounded the drive's way, a fraction of a microstep would move it by one
/// more or one less, as much as the in-position band.
pub const MICROSTEP_MM: f32 = (crate::nominal::DRIVE_LEAD_SCREW_PITCH_NM as f64
    * crate::nominal::DRIVE_GEAR_SCREW_REVS as f64
    / (crate::nominal::DRIVE_FULL_STEPS_PER_REV as f64
        * crate::nominal::DRIVE_MICROSTEPS_PER_STEP as f64
        * crate::nominal::DRIVE_GEAR_MOTOR_REVS as f64)
    / crate::units::NM_PER_MM) as f32;
/// The correction at which a leg still out of position toward its approach side is
/// retreated and returned ([`RETREAT_MM`]) as if it had overshot: its backlash gap may
/// not be taken up on the approach side (at power-on the gaps are anywhere; after a
/// missed step or a stroke in recovery the tracked direction may not be the gap's), and
/// corrections toward the approach would then creep through the gap a microstep or two
/// at a time. The return takes the gap up.
pub const LATE_CORRECTION: u8 = 8;
/// Cycles after the path's end by which a move must be in position (5 s): more than
/// [`MAX_CORRECTIONS`] dwells of the longest dwell (`controller::params`, 200 cycles);
/// at the default dwell (20 cycles) [`MAX_CORRECTIONS`] corrections with a retreat and
/// a return every other one (0.15 s each at the default acceleration limit) take
/// about 3 s.
pub const TIMEOUT_CYCLES: u32 = 5_000;

/// How far a leg's command must turn back from its furthest point before its last
/// direction counts as reversed (mm, 2 um; [`Approach::track`]): far above the f32
/// dither of a leg that hardly moves (nm), and more than half the realistic backlash
/// and the friction lag (1.6 um), so that a slider whose command turned back further is
/// short of its setpoint in the new direction by 0.4 um at least: its corrections then
/// take up the rest of the gap in one or two (closer to 1.6 um, a microstep at a time
/// through most of the gap). A smaller reversal leaves the approach as it was, the
/// command behind its furthest point by the reversal: the first correction toward the
/// approach takes that up first ([`Fine::correct`]).
pub const TURN_MM: f32 = 0.002;

/// The legs whose encoder (mm) reads within `tolerance_mm` of their setpoint (mm); none
/// without a reading. (Housekeeping's `in_position_legs` gives each single reading half
/// a count more: [`single_reading_tolerance_mm`].)
pub fn in_position_legs(
    target_mm: &[f32; LEGS],
    encoders_mm: Option<&[f32; LEGS]>,
    tolerance_mm: f32,
) -> u8 {
    let Some(enc) = encoders_mm else {
        return 0;
    };
    let mut legs = 0u8;
    for (i, (t, e)) in target_mm.iter().zip(enc.iter()).enumerate() {
        // `<=` is false for NaN: not in position.
        if (*t - *e).abs() <= tolerance_mm {
            legs |= 1 << i;
        }
    }
    legs
}

/// The tolerance a single reading is held to at rest (housekeeping `in_position_legs`,
/// a move's nothing-to-do check): the in-position tolerance plus half a count, since a
/// slider the rule put in position (its mean reading within the tolerance less half a
/// count) reads a count either side as the encoder's noise has it.
pub fn single_reading_tolerance_mm(tolerance_mm: f32) -> f32 {
    tolerance_mm + HALF_COUNT_MM
}

/// The drive command (mm) nearest to `mm` on a whole microstep ([`MICROSTEP_MM`], from
/// zero stroke, as the drives count them). Rounded by adding and taking off 1.5 2^23:
/// f32 has no fraction at that magnitude, so the sum is rounded to a whole number
/// (exact for any stroke: 2^22 microsteps are 328 mm; a tie goes to the even one, where
/// the drives round away from zero, a microstep apart at worst and only there).
fn on_microstep(mm: f32) -> f32 {
    const ROUND: f32 = 1.5 * (1u32 << 23) as f32;
    (mm / MICROSTEP_MM + ROUND - ROUND) * MICROSTEP_MM
}

/// What the fine positioning does after a cycle at rest ([`Fine::at_rest`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FineStep {
    /// Keep waiting (settling, or the dwell running).
    Wait,
    /// Every leg has been in position for the dwell: the move is complete.
    InPosition,
    /// Correct now ([`Fine::correct`]).
    Correct,
    /// The timeout passed: these legs are not in position.
    TimedOut(u8),
}

/// Which way each leg's command last moved (kept between moves; [`Approach::track`]):
/// the side a fine positioning approaches from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Approach {
    /// Legs whose last commanded motion was toward larger strokes.
    pub last_up: u8,
    /// Each leg's furthest command in its last direction (mm).
    turn_mm: [f32; LEGS],
}

impl Approach {
    /// No motion yet: every leg counts as last moved down, from `held_mm`.
    pub const fn new(held_mm: [f32; LEGS]) -> Self {
        Self {
            last_up: 0,
            turn_mm: held_mm,
        }
    }

    /// A compensation step: the applied offset (mm, added to every command) changed
    /// while the drives stood still, so the strokes they hold moved in the new offset's
    /// frame from `before_mm` to `after_mm` (mm) and each slider must move by the
    /// difference `before_mm - after_mm`. The furthest commands move into the new
    /// frame; a leg whose move is against its last direction takes the move's
    /// direction from where it holds: its fine positioning crosses the backlash gap
    /// toward the new side ([`Fine::begin`]'s `creep`) instead of retreating past the
    /// setpoint and returning, which moves the slider by micrometres.
    pub fn step_offsets(&mut self, before_mm: &[f32; LEGS], after_mm: &[f32; LEGS]) {
        let mut bit = 1u8;
        for ((t, b), a) in self.turn_mm.iter_mut().zip(before_mm).zip(after_mm) {
            let up = *b > *a;
            if up != (self.last_up & bit != 0) && *b != *a {
                self.last_up ^= bit;
                *t = *a;
            } else {
                *t += *a - *b;
            }
            bit <<= 1;
        }
    }

    /// Notes the direction of each leg's commanded motion, from its command `next_mm`:
    /// it reverses once the command has turned back [`TURN_MM`] from its furthest point
    /// in the last direction (a play of that width: a leg that hardly moves, or dithers
    /// by f32 rounding, keeps its direction).
    pub fn track(&mut self, next_mm: &[f32; LEGS]) {
        for (i, (t, n)) in self.turn_mm.iter_mut().zip(next_mm.iter()).enumerate() {
            let bit = 1u8 << i;
            let up = self.last_up & bit != 0;
            if (up && *n > *t) || (!up && *n < *t) {
                *t = *n;
            } else if (*n - *t).abs() > TURN_MM {
                self.last_up ^= bit;
                *t = *n;
            }
        }
    }
}

/// Bit of [`Fine`]'s `returning` (beside the legs' bits 0..5): the sliders must stay at
/// rest for a second dwell before the next decision, set by a return ([`RETREAT_MM`]),
/// after which a slider settles from micrometres away.
const LONG_SETTLE: u8 = 0x80;
/// Bit of [`Fine`]'s `returning`: a compensation step's fine positioning
/// ([`Fine::begin`]'s `creep`): no late retreat, and corrections until the timeout.
const CREEP: u8 = 0x40;

/// The fine positioning of one move (module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fine {
    /// The setpoint strokes the encoders must read (mm).
    target_mm: [f32; LEGS],
    /// The final approach: legs approaching from below (toward larger strokes).
    approach_up: u8,
    /// Corrections made.
    corrections: u8,
    /// Readings in the current rest window: cycles the sliders have stayed within
    /// twice the tolerance of `rest_ref_mm` (since the path or the last correction).
    since: u16,
    /// Cycle the fine positioning began.
    began: u32,
    /// The first reading of the current rest window (mm).
    rest_ref_mm: [f32; LEGS],
    /// Sum of the window's readings less `rest_ref_mm` (mm): their mean is the reading
    /// the rule and a correction use (averaging the encoder's noise and flicker).
    rest_sum_mm: [f32; LEGS],
    /// The correction under way: strokes it starts from and its change (mm). Before the
    /// first correction: each leg's furthest command in its approach direction
    /// ([`Approach`]), where the backlash gap was last taken up.
    from_mm: [f32; LEGS],
    delta_mm: [f32; LEGS],
    /// Legs the last correction retreated: the next one returns them ([`RETREAT_MM`]);
    /// and [`LONG_SETTLE`] and [`CREEP`].
    returning: u8,
}

impl Fine {
    /// Begins positioning the sliders on `target_mm` in cycle `now`, each leg
    /// approaching from the side of its last commanded motion (`approach`). `creep`:
    /// after a compensation step ([`Approach::step_offsets`]), a leg whose approach
    /// side changed crosses its backlash gap by corrections toward it, each no larger
    /// than its error allows, however many the timeout leaves room for: no late
    /// retreat ([`LATE_CORRECTION`]), and no limit of [`MAX_CORRECTIONS`].
    pub fn begin(target_mm: [f32; LEGS], approach: &Approach, now: u32, creep: bool) -> Self {
        Self {
            target_mm,
            approach_up: approach.last_up,
            corrections: 0,
            since: 0,
            began: now,
            rest_ref_mm: [0.0; LEGS],
            rest_sum_mm: [0.0; LEGS],
            from_mm: approach.turn_mm,
            delta_mm: [0.0; LEGS],
            returning: if creep { CREEP } else { 0 },
        }
    }

    /// One control cycle `now` at rest (no correction under way), with this cycle's
    /// encoder reading (mm; `None`: none), the in-position tolerance (mm) and dwell
    /// (cycles; 0 acts as 1): in position, or a correction due, once the sliders have
    /// stayed within twice the tolerance of where they were for the dwell (module
    /// documentation; twice, so that a reading flickering between two counts is at
    /// rest).
    pub fn at_rest(
        &mut self,
        now: u32,
        encoders_mm: Option<&[f32; LEGS]>,
        tolerance_mm: f32,
        dwell_cycles: u16,
    ) -> FineStep {
        if let Some(enc) = encoders_mm {
            let moved = enc
                .iter()
                .zip(self.rest_ref_mm.iter())
                .any(|(e, r)| !((*e - *r).abs() <= 2.0 * tolerance_mm));
            if moved {
                self.since = 0;
            }
            if self.since == 0 {
                self.rest_ref_mm = *enc;
                self.rest_sum_mm = [0.0; LEGS];
            }
            for ((s, e), r) in self
                .rest_sum_mm
                .iter_mut()
                .zip(enc.iter())
                .zip(self.rest_ref_mm.iter())
            {
                *s += *e - *r;
            }
            self.since = self.since.saturating_add(1);
        }
        let out = self.out_of(tolerance_mm - HALF_COUNT_MM);
        let at_rest = encoders_mm.is_some() && self.since >= dwell_cycles;
        if at_rest && self.returning & LONG_SETTLE != 0 {
            self.returning &= !LONG_SETTLE;
            self.since = 0;
            return FineStep::Wait;
        }
        if at_rest && out == 0 {
            return FineStep::InPosition;
        }
        if now.wrapping_sub(self.began) >= TIMEOUT_CYCLES {
            return FineStep::TimedOut(out);
        }
        if at_rest && (self.corrections < MAX_CORRECTIONS || self.returning & CREEP != 0) {
            return FineStep::Correct;
        }
        FineStep::Wait
    }

    /// The mean reading of each leg over the rest window (mm; NaN before its first
    /// reading: no leg in position).
    fn mean_mm(&self) -> [f32; LEGS] {
        let n = f32::from(self.since);
        let mut mean = self.rest_ref_mm;
        for (m, s) in mean.iter_mut().zip(self.rest_sum_mm.iter()) {
            *m += *s / n;
        }
        mean
    }

    /// The legs whose mean reading over the rest window is not within `band_mm` of the
    /// setpoint.
    fn out_of(&self, band_mm: f32) -> u8 {
        !in_position_legs(&self.target_mm, Some(&self.mean_mm()), band_mm)
            & crate::supervision::ALL_LEGS
    }

    /// Plans a correction of every leg not in position (its mean reading over the rest
    /// window not within `tolerance_mm` less half a count: module documentation) from
    /// the strokes the drives hold `held_mm`, within `[min_mm, max_mm]`, and its ramp
    /// within `speed_mm_per_s` and `accel_mm_per_s2`. Counts as a correction even when
    /// the limits leave nothing to move (the ramp then holds the strokes for a cycle or
    /// two).
    pub fn correct(
        &mut self,
        held_mm: &[f32; LEGS],
        tolerance_mm: f32,
        min_mm: &[f32; LEGS],
        max_mm: &[f32; LEGS],
        speed_mm_per_s: f32,
        accel_mm_per_s2: f32,
    ) -> Result<Ramp, RampError> {
        self.corrections = self.corrections.saturating_add(1);
        let mean = self.mean_mm();
        let band = tolerance_mm - HALF_COUNT_MM;
        self.since = 0;
        let mut largest = 0.0f32;
        for (i, (d, (((((t, e), h), lo), hi), f))) in self
            .delta_mm
            .iter_mut()
            .zip(
                self.target_mm
                    .iter()
                    .zip(mean.iter())
                    .zip(held_mm.iter())
                    .zip(min_mm.iter())
                    .zip(max_mm.iter())
                    .zip(self.from_mm.iter_mut()),
            )
            .enumerate()
        {
            let err = *t - *e;
            let bit = 1u8 << i;
            // +1 toward the approach side.
            let toward = if self.approach_up & bit != 0 {
                1.0f32
            } else {
                -1.0
            };
            // Before the first correction `from_mm` holds the legs' furthest commands
            // in their approach direction ([`Fine::begin`]): the gap a reversal smaller
            // than [`TURN_MM`] left, which the first correction toward the approach
            // takes up first. Not when creeping: where that gap is smaller than the
            // reversal (a preloaded nut, a stiff train) taking it up at once carries the
            // slider past the setpoint by the difference; the creep crosses whatever
            // gap there is.
            let behind = if self.corrections == 1 && self.returning & CREEP == 0 {
                *f - *h
            } else {
                0.0
            };
            *f = *h;
            // The drive's new command, from the microstep it stands on (the drive rounds
            // the command's fraction of a microstep as it rounded the held one's).
            let step = if self.returning & bit != 0 {
                // The return after a retreat: the gap taken up on the approach side
                // again, the drive the overshoot (in whole microsteps, at least one as
                // the overshoot is more than half of one) short of where it stood before
                // the retreat.
                self.returning = (self.returning & !bit) | LONG_SETTLE;
                toward * RETREAT_MM
            } else if !(err.abs() > band) {
                *d = 0.0;
                continue;
            } else if (err * toward > 0.0 && self.corrections != LATE_CORRECTION)
                || self.returning & CREEP != 0
            {
                // Toward the setpoint: whole microsteps, as many as cannot carry the
                // slider past the band's far edge (at least one: [`GAIN`]), plus the gap
                // left behind. (Creeping, a leg beyond its setpoint crosses its gap back
                // the same way, as after a compensation step against its approach,
                // instead of retreating.)
                let steps = (GAIN * (err.abs() + band) / MICROSTEP_MM) as i32;
                behind + err.signum() * MICROSTEP_MM * steps as f32
            } else {
                // An overshoot (or a leg still out at the late correction): back past the
                // setpoint; the next correction returns.
                self.returning |= bit;
                err - toward * RETREAT_MM
            };
            // `max` then `min`, not `clamp` (which panics on bounds out of order or NaN).
            *d = (on_microstep(*h) + step)
                .max(*t - MAX_CORRECTION_MM)
                .min(*t + MAX_CORRECTION_MM)
                .max(*lo)
                .min(*hi)
                - *h;
            largest = largest.max(d.abs());
        }
        // Nothing to move (every leg at a limit): the rates are infinite, a ramp of a
        // cycle or two that commands the held strokes.
        let share = LIMIT_USE_FRACTION / largest;
        Ramp::plan(share * speed_mm_per_s, share * accel_mm_per_s2)
    }

    /// The drive command of the correction under way at ramp progress `progress` (0..1)
    /// (before the first correction there is none, and the controller commands nothing).
    pub fn setpoint(&self, progress: f32) -> [f32; LEGS] {
        let mut out = self.from_mm;
        for (o, d) in out.iter_mut().zip(self.delta_mm.iter()) {
            *o += progress * *d;
        }
        out
    }

    /// Corrections made in the fine positioning in progress (or the last one).
    pub fn corrections(&self) -> u8 {
        self.corrections
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::supervision::ALL_LEGS;

    const TOL: f32 = 1e-4;

    #[test]
    fn in_position_needs_every_leg_and_a_reading() {
        let t = [0.0f32; LEGS];
        let mut e = [0.00005f32; LEGS];
        assert_eq!(in_position_legs(&t, Some(&e), TOL), ALL_LEGS);
        e[2] = 0.0002;
        e[4] = f32::NAN;
        assert_eq!(in_position_legs(&t, Some(&e), TOL), ALL_LEGS & !0b10100);
        assert_eq!(in_position_legs(&t, None, TOL), 0);
    }

    #[test]
    fn completion_waits_for_the_sliders_at_rest_for_the_dwell_on_their_mean_reading() {
        let mut f = Fine::begin([0.0; LEGS], &Approach::new([0.0; LEGS]), 100, false);
        let ok = [0.0f32; LEGS];
        let mut moved = ok;
        moved[1] = 0.001;
        assert_eq!(f.at_rest(101, Some(&ok), TOL, 3), FineStep::Wait);
        assert_eq!(f.at_rest(102, Some(&ok), TOL, 3), FineStep::Wait);
        // Leg 2 moves: the rest window starts over.
        assert_eq!(f.at_rest(103, Some(&moved), TOL, 3), FineStep::Wait);
        assert_eq!(f.at_rest(104, Some(&ok), TOL, 3), FineStep::Wait);
        assert_eq!(f.at_rest(105, None, TOL, 3), FineStep::Wait, "no reading");
        assert_eq!(f.at_rest(106, Some(&ok), TOL, 3), FineStep::Wait);
        assert_eq!(f.at_rest(107, Some(&ok), TOL, 3), FineStep::InPosition);
        // A reading flickering between the counts either side of the setpoint: at rest,
        // in position on the mean (each single reading is one count off).
        f = Fine::begin([0.00005; LEGS], &Approach::new([0.0; LEGS]), 200, false);
        let (lo, hi) = ([0.0f32; LEGS], [0.0001f32; LEGS]);
        assert_eq!(f.at_rest(201, Some(&lo), TOL, 4), FineStep::Wait);
        assert_eq!(f.at_rest(202, Some(&hi), TOL, 4), FineStep::Wait);
        assert_eq!(f.at_rest(203, Some(&lo), TOL, 4), FineStep::Wait);
        assert_eq!(f.at_rest(204, Some(&hi), TOL, 4), FineStep::InPosition);
        // A mean one count off: within the tolerance, not within it less half a count
        // (the true slider could be 1.5 counts off): a correction.
        f = Fine::begin([0.0; LEGS], &Approach::new([0.0; LEGS]), 300, false);
        for c in 301..303 {
            assert_eq!(f.at_rest(c, Some(&hi), TOL, 3), FineStep::Wait);
        }
        assert_eq!(f.at_rest(303, Some(&hi), TOL, 3), FineStep::Correct);
    }

    #[test]
    fn the_direction_reverses_only_past_the_turn() {
        let mut f = Approach::new([0.0; LEGS]);
        let dither = 0.9 * TURN_MM;
        f.track(&[1.0; LEGS]);
        assert_eq!(f.last_up, ALL_LEGS);
        f.track(&[1.0 - dither; LEGS]);
        assert_eq!(f.last_up, ALL_LEGS, "within the turn");
        f.track(&[1.0 + dither; LEGS]);
        f.track(&[1.0 + dither - 1.1 * TURN_MM; LEGS]);
        assert_eq!(f.last_up, 0, "turned back past it from the furthest point");
    }

    #[test]
    fn corrections_are_bounded_in_number_and_time() {
        let mut f = Fine::begin([0.0; LEGS], &Approach::new([0.0; LEGS]), 0, false);
        let bad = [0.001f32; LEGS];
        let lim = [10.0f32; LEGS];
        let mut n = 0;
        for c in 1..TIMEOUT_CYCLES {
            if f.at_rest(c, Some(&bad), TOL, 1) == FineStep::Correct {
                n += 1;
                assert!(f
                    .correct(&[0.0; LEGS], TOL, &lim.map(|v| -v), &lim, 0.2, 1.0)
                    .is_ok());
            }
        }
        assert_eq!(n, MAX_CORRECTIONS);
        assert_eq!(
            f.at_rest(TIMEOUT_CYCLES, Some(&bad), TOL, 1),
            FineStep::TimedOut(ALL_LEGS)
        );
    }

    /// An approach whose legs 1, 3, 5 last moved up, 2, 4, 6 down (by 10 um, more than
    /// the turn), all ending at `at_mm`: nothing left behind.
    fn alternate(at_mm: f32) -> Approach {
        let mut a = Approach::new([at_mm; LEGS]);
        let d = 0.01;
        a.track(&[
            at_mm - d,
            at_mm + d,
            at_mm - d,
            at_mm + d,
            at_mm - d,
            at_mm + d,
        ]);
        a.track(&[at_mm; LEGS]);
        assert_eq!(a.last_up, 0b01_0101);
        a
    }

    #[test]
    fn the_microstep_is_the_drives() {
        // 1 mm lead, 200 full steps, 64 microsteps, direct drive: 1/12,800 mm.
        assert!((f64::from(MICROSTEP_MM) * 12_800.0 - 1.0).abs() < 1e-7);
        assert_eq!(on_microstep(3.4 * MICROSTEP_MM), 3.0 * MICROSTEP_MM);
        assert_eq!(on_microstep(-3.6 * MICROSTEP_MM), -4.0 * MICROSTEP_MM);
    }

    #[test]
    fn a_correction_approaches_from_one_side_is_bounded_and_stays_within_the_stroke() {
        // The drives stand 0.3 microsteps off a whole one (as after a path, which ended
        // there).
        let held = [1.0f32 + 0.3 * MICROSTEP_MM; LEGS];
        let mut f = Fine::begin([1.0; LEGS], &alternate(held[0]), 0, false);
        // Leg 1 short (below, approach up): corrected toward the approach. Leg 2 short
        // (above, approach down): likewise. Leg 3 overshot (above, approach up): back
        // past by the retreat. Leg 4 overshot (below, approach down). Leg 5 far off:
        // bounded. Leg 6 in tolerance: untouched.
        let enc = [0.998, 1.002, 1.002, 0.998, 0.9, 1.00004];
        // The reading a correction uses is the mean over the rest window.
        let mut noisy = enc;
        noisy[0] += 0.0001;
        assert_eq!(f.at_rest(1, Some(&noisy), TOL, 2), FineStep::Wait);
        noisy[0] -= 0.0002;
        assert_eq!(f.at_rest(2, Some(&noisy), TOL, 2), FineStep::Correct);
        let hi = [1.0 + 0.01; LEGS];
        let ramp = f.correct(&held, TOL, &[-5.0; LEGS], &hi, 0.2, 1.0);
        assert!(ramp.is_ok(), "{ramp:?}");
        let end = f.setpoint(1.0);
        // In microsteps from the one the drive stands on (1 mm = 12,800).
        let steps: Vec<f32> = end.iter().map(|e| (e - 1.0) / MICROSTEP_MM).collect();
        let close = |a: f32, b: f32| (a - b).abs() < 1e-2;
        // 2 um short, band 0.05 um: floor(0.85 (2 + 0.05) / 0.078125) = 22 microsteps,
        // at most 0.85 of the error and the band: the slider cannot pass the band.
        assert!(close(steps[0], 22.0), "{steps:?}");
        assert!(close(steps[1], -22.0), "{steps:?}");
        // Overshot 2 um: 2 um (25.6 microsteps, rounded by the drive) and 5 um back.
        assert!(close(steps[2], -25.6 - 64.0), "{steps:?}");
        assert!(close(steps[3], 25.6 + 64.0), "{steps:?}");
        // The stroke limit, inside the 20 um bound.
        assert!((end[4] - 1.01).abs() < 1e-6, "{end:?}");
        assert_eq!(end[5], held[5]);
        assert_eq!(f.setpoint(0.0), held);
        assert!(ramp.is_ok_and(|r| r.end_cycle() > 2));
        // The next correction returns the retreated legs by the retreat from the
        // microstep they stand on: the gap taken up on the approach side again, the drive
        // the overshoot in whole microsteps (25.6 -> 26) short of where it was.
        let held = end;
        let enc = [1.0, 1.0, 0.995, 1.005, 1.0, 1.0];
        assert_eq!(f.at_rest(3, Some(&enc), TOL, 2), FineStep::Wait);
        assert_eq!(f.at_rest(4, Some(&enc), TOL, 2), FineStep::Correct);
        assert!(f.correct(&held, TOL, &[-5.0; LEGS], &hi, 0.2, 1.0).is_ok());
        let end = f.setpoint(1.0);
        let steps: Vec<f32> = end.iter().map(|e| (e - 1.0) / MICROSTEP_MM).collect();
        assert!(close(steps[2], -26.0), "{steps:?}");
        assert!(close(steps[3], 26.0), "{steps:?}");
        // After a return the sliders settle for a second dwell before the next decision.
        let enc = [1.0, 1.0, 0.998, 1.002, 1.0, 1.0];
        for c in 5..8 {
            assert_eq!(f.at_rest(c, Some(&enc), TOL, 2), FineStep::Wait, "{c}");
        }
        assert_eq!(f.at_rest(8, Some(&enc), TOL, 2), FineStep::Correct);
        // The bound itself.
        let mut g = Fine::begin([0.0; LEGS], &alternate(0.0), 0, false);
        assert_eq!(g.at_rest(1, Some(&[-1.0; LEGS]), TOL, 1), FineStep::Correct);
        assert!(g
            .correct(&[0.0; LEGS], TOL, &[-5.0; LEGS], &[5.0; LEGS], 0.2, 1.0)
            .is_ok());
        assert!(g
            .setpoint(1.0)
            .iter()
            .all(|v| (v.abs() - MAX_CORRECTION_MM).abs() < 1e-6));
    }

    #[test]
    fn a_compensation_step_turns_the_approach_of_the_legs_it_moves_against_it() {
        // Legs 1, 3, 5 last moved up, 2, 4, 6 down, all to 1 mm. The offset grows by
        // 0.3 um on legs 1, 2, 3 and shrinks by as much on legs 4, 5, 6 (each slider
        // must move by its change); in the new frame the drives hold 1 mm less it.
        let mut a = alternate(1.0);
        let change = [0.0003f32, 0.0003, 0.0003, -0.0003, -0.0003, -0.0003];
        let held: [f32; LEGS] = core::array::from_fn(|i| 1.0 - change[i]);
        a.step_offsets(&[1.0; LEGS], &held);
        // Up on 1, 2, 3; down on 4, 5, 6.
        assert_eq!(a.last_up, 0b00_0111);
        // Legs 1, 3, 4 and 6 kept their approach (their furthest command, where they
        // stood, moved into the new frame with the drives); 2 and 5 turned, from where
        // they hold.
        for (t, h) in a.turn_mm.iter().zip(held.iter()) {
            assert!((t - h).abs() < 1e-7, "{:?}", a.turn_mm);
        }
        // No change, no turn.
        let mut b = alternate(1.0);
        b.step_offsets(&[1.0; LEGS], &[1.0; LEGS]);
        assert_eq!(b, alternate(1.0));
    }

    /// A leg with `backlash_mm` of lost motion: its slider follows its drive `drive_mm`
    /// only when the drive pushes on one side of the gap (mm).
    fn follow(slider_mm: f32, drive_mm: f32, backlash_mm: f32) -> f32 {
        slider_mm
            .max(drive_mm - 0.5 * backlash_mm)
            .min(drive_mm + 0.5 * backlash_mm)
    }

    /// A compensation step's fine positioning (`creep`) on legs whose approach turned:
    /// the drives cross the backlash gap by corrections no larger than the error allows
    /// (more of them than [`MAX_CORRECTIONS`], past [`LATE_CORRECTION`]), the sliders
    /// never pass the band's far edge and never retreat; a leg beyond its setpoint
    /// turns its approach and crosses back the same way. Without `creep` the same
    /// fine positioning retreats past the setpoint at the late correction.
    #[test]
    fn a_creeping_fine_positioning_crosses_the_gap_without_passing_the_band() {
        const GAP_MM: f32 = 0.003;
        let band = TOL - HALF_COUNT_MM;
        let lim = [5.0f32; LEGS];
        let run = |creep: bool| {
            // Every leg last moved up, the drive half the gap above its slider. Legs
            // 1..5: the slider 0.1 um above the setpoint 1 mm before a compensation
            // step of -0.1 um turns their approach down. Leg 6: no step, its slider as
            // far above: an overshoot of its approach.
            let mut sliders = [1.0001f32; LEGS];
            let mut drives = sliders.map(|s| s + 0.5 * GAP_MM);
            let mut a = Approach::new([0.9; LEGS]);
            a.track(&drives);
            assert_eq!(a.last_up, ALL_LEGS);
            if creep {
                let change = [-0.0001, -0.0001, -0.0001, -0.0001, -0.0001, 0.0];
                let after: [f32; LEGS] = core::array::from_fn(|i| drives[i] - change[i]);
                a.step_offsets(&drives, &after);
                assert_eq!(a.last_up, 0b10_0000);
            }
            let mut f = Fine::begin([1.0; LEGS], &a, 0, creep);
            // (end, corrections, lowest slider, a drive moved up)
            let (mut lowest, mut up) = (f32::INFINITY, false);
            for c in 1..TIMEOUT_CYCLES {
                match f.at_rest(c, Some(&sliders), TOL, 1) {
                    FineStep::Correct => {
                        let r = f.correct(&drives, TOL, &lim.map(|v| -v), &lim, 0.2, 1.0);
                        assert!(r.is_ok());
                        let next = f.setpoint(1.0);
                        up |= next.iter().zip(drives.iter()).any(|(n, d)| *n > *d + 1e-7);
                        drives = next;
                        for (s, d) in sliders.iter_mut().zip(drives.iter()) {
                            *s = follow(*s, *d, GAP_MM);
                            lowest = lowest.min(*s);
                        }
                    }
                    FineStep::Wait => {}
                    end => return (end, f.corrections(), lowest, up),
                }
            }
            (FineStep::Wait, f.corrections(), lowest, up)
        };
        let (end, n, lowest, up) = run(true);
        assert_eq!(end, FineStep::InPosition);
        assert!(n > MAX_CORRECTIONS, "{n} corrections");
        assert!(!up, "a drive retreated");
        assert!(
            lowest >= 1.0 - band - 1e-7,
            "a slider passed the band: {lowest}"
        );
        // The same without `creep` (and without the step's turn): leg 6 retreats past
        // the setpoint by micrometres, legs 1..5 retreat and return.
        let (_, _, lowest, up) = run(false);
        assert!(up && lowest < 1.0 - 0.001, "{lowest}");
    }

    #[test]
    fn the_first_correction_takes_up_the_gap_a_small_reversal_left() {
        // Every leg moved up to 1.0015 mm, then back 1.5 um (less than the turn) to its
        // setpoint 1 mm: still approaching from below, the command 1.5 um behind where
        // the gap was taken up.
        let mut a = Approach::new([0.9; LEGS]);
        a.track(&[1.0015; LEGS]);
        a.track(&[1.0; LEGS]);
        assert_eq!(a.last_up, ALL_LEGS);
        let mut f = Fine::begin([1.0; LEGS], &a, 0, false);
        // The slider did not move back (in the gap): 1 um short of the setpoint.
        let short = [0.999; LEGS];
        assert_eq!(f.at_rest(1, Some(&short), TOL, 1), FineStep::Correct);
        assert!(f
            .correct(&[1.0; LEGS], TOL, &[-5.0; LEGS], &[5.0; LEGS], 0.2, 1.0)
            .is_ok());
        // 1.5 um of gap, and floor(0.85 (1 + 0.05) / 0.078125) = 11 microsteps.
        let d = f.setpoint(1.0)[0] - 1.0;
        assert!((d - (0.0015 + 11.0 * MICROSTEP_MM)).abs() < 1e-6, "{d}");
        // The next correction from there: the error alone, from the microstep the drive
        // stands on (the 1.5 um are 19.2 microsteps: it stands 0.2 below the command).
        assert_eq!(f.at_rest(2, Some(&short), TOL, 1), FineStep::Correct);
        let held = f.setpoint(1.0);
        assert!(f
            .correct(&held, TOL, &[-5.0; LEGS], &[5.0; LEGS], 0.2, 1.0)
            .is_ok());
        let d = f.setpoint(1.0)[0] - held[0];
        assert!((d - 10.8 * MICROSTEP_MM).abs() < 1e-6, "{d}");
    }
}
