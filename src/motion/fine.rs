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
//!   to settle) and some leg is not in position, every such leg's drive command is
//!   corrected by its encoder error, at most [`MAX_CORRECTIONS`] times per move, each
//!   correction at most [`MAX_CORRECTION_MM`] per leg, the drive never further than that
//!   from the setpoint, and never beyond the stroke limits.
//!   A correction is a ramp within the coordinated-move speed and acceleration limits
//!   (the output stage checks it like any command).
//! * **Anti-backlash: final approach from one side.** Each leg's final approach is in
//!   the direction of its last commanded motion before the fine positioning (the path's
//!   direction at its end): there the backlash gap is already taken up, so a correction
//!   in that direction moves the slider by what the drive moves. The drive train leaves
//!   each slider short of its setpoint in that direction (half the gap and the friction
//!   lag), so almost every correction is one. A slider found beyond its setpoint (an
//!   overshoot) is not corrected back through the gap by its error (which would lose the
//!   unknown backlash): it is moved back past the setpoint by [`RETREAT_MM`] more, and
//!   approached again from the same side by the next corrections. Chosen by measurement
//!   (docs/decisions.md, "Fine positioning"): with the realistic drive train a
//!   correction opposite to the approach moved the slider by its error less the 3.2 um
//!   of backlash and break-away, so correcting by the error converged only after several
//!   corrections and a measured compensation would need the backlash of every leg kept
//!   and re-measured; the one-sided approach needs neither.
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
/// Largest correction of one leg (mm, 20 um), and the farthest the corrections of a move
/// may take a leg's drive from its setpoint in all: four times the following-error
/// warning threshold, beyond what any drive train leaves behind a path (a slider
/// further off is a fault for the supervision, not a task for the fine positioning). A
/// jammed slider thus leaves its drive at most this far beyond its setpoint, where the
/// slider goes should the jam free.
pub const MAX_CORRECTION_MM: f32 = 0.02;
/// How far past its setpoint, against its final approach, an overshot slider is moved
/// back (mm, 5 um): more than the realistic backlash and break-away (3.2 um), so one
/// retreat usually suffices; more retreats follow if not.
pub const RETREAT_MM: f32 = 0.005;
/// Share of a leg's error a correction toward its approach side moves the drive: less
/// than 1, so that a drive train that moves the slider more than the drive (the
/// microstep nonlinearity's slope, up to 18 % with the realistic defaults) does not
/// overshoot, which would cost a retreat and a new approach.
pub const GAIN: f32 = 0.85;
/// Corrections after which a leg still not in position is retreated and approached
/// again once (whatever its error's side): it may be in the backlash gap, where
/// corrections by its error creep (a reversal smaller than [`TURN_MM`] left the gap on
/// the old side).
pub const LATE_CORRECTIONS: u8 = 4;
/// Cycles after the path's end by which a move must be in position (5 s): more than
/// [`MAX_CORRECTIONS`] dwells of the longest dwell (`controller::params`, 200 cycles)
/// plus the corrections themselves (a 20 um correction takes about 0.3 s at the default
/// acceleration limit).
pub const TIMEOUT_CYCLES: u32 = 5_000;

/// How far a leg's command must turn back from its furthest point before its last
/// direction counts as reversed (mm, 1 um; [`Approach::track`]): far above the f32
/// dither of a leg that hardly moves (nm). (A smaller reversal may have left the
/// backlash gap on the old side; the corrections then creep through it, and a move of
/// about a micrometre may end in 0x070F: docs/decisions.md, "Fine positioning".)
pub const TURN_MM: f32 = 0.001;

/// Every leg (bits 0..5).
const ALL_LEGS: u8 = (1u8 << LEGS) - 1;

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
    /// The correction under way: strokes it starts from and its change (mm).
    from_mm: [f32; LEGS],
    delta_mm: [f32; LEGS],
    /// Legs retreated by the late rule ([`LATE_CORRECTIONS`]).
    retreated: u8,
}

impl Fine {
    /// Begins positioning the sliders on `target_mm` in cycle `now`, each leg
    /// approaching from the side of its last commanded motion (`approach`).
    pub fn begin(target_mm: [f32; LEGS], approach: &Approach, now: u32) -> Self {
        Self {
            target_mm,
            approach_up: approach.last_up,
            corrections: 0,
            since: 0,
            began: now,
            rest_ref_mm: target_mm,
            rest_sum_mm: [0.0; LEGS],
            from_mm: target_mm,
            delta_mm: [0.0; LEGS],
            retreated: 0,
        }
    }

    /// One control cycle `now` at rest (no correction under way), with this cycle's
    /// encoder reading (mm; `None`: none), the in-position tolerance (mm) and dwell
    /// (cycles): in position, or a correction due, once the sliders have stayed within
    /// twice the tolerance of where they were for the dwell (module documentation; twice,
    /// so that a reading flickering between two counts is at rest).
    pub fn at_rest(
        &mut self,
        now: u32,
        encoders_mm: Option<&[f32; LEGS]>,
        tolerance_mm: f32,
        dwell_cycles: u16,
    ) -> FineStep {
        let dwell = dwell_cycles.max(1);
        if let Some(enc) = encoders_mm {
            let moved = enc
                .iter()
                .zip(self.rest_ref_mm.iter())
                .any(|(e, r)| !((*e - *r).abs() <= 2.0 * tolerance_mm));
            if moved || self.since == 0 {
                self.rest_ref_mm = *enc;
                self.rest_sum_mm = [0.0; LEGS];
                self.since = 0;
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
        let out = ALL_LEGS & !self.settled_in_position(tolerance_mm);
        let at_rest = encoders_mm.is_some() && self.since >= dwell;
        if at_rest && out == 0 {
            return FineStep::InPosition;
        }
        if now.wrapping_sub(self.began) >= TIMEOUT_CYCLES {
            return FineStep::TimedOut(out);
        }
        if at_rest && self.corrections < MAX_CORRECTIONS {
            return FineStep::Correct;
        }
        FineStep::Wait
    }

    /// The mean reading of each leg over the rest window (mm).
    fn mean_mm(&self) -> [f32; LEGS] {
        let n = f32::from(self.since.max(1));
        let mut mean = self.rest_ref_mm;
        for (m, s) in mean.iter_mut().zip(self.rest_sum_mm.iter()) {
            *m += *s / n;
        }
        mean
    }

    /// The legs whose mean reading over the rest window is within `tolerance_mm` less
    /// half a count of the setpoint.
    fn settled_in_position(&self, tolerance_mm: f32) -> u8 {
        in_position_legs(
            &self.target_mm,
            Some(&self.mean_mm()),
            tolerance_mm - HALF_COUNT_MM,
        )
    }

    /// Plans a correction of every leg not in position (its mean reading over the rest
    /// window not within `tolerance_mm` less half a count: module documentation) from the strokes the drives hold
    /// `held_mm`, within `[min_mm, max_mm]`, and its ramp within `speed_mm_per_s` and
    /// `accel_mm_per_s2`. Counts as a correction even when the limits leave nothing to
    /// move (the ramp is then immediate).
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
        self.from_mm = *held_mm;
        let mut largest = 0.0f32;
        for (i, (d, ((((t, e), h), lo), hi))) in self
            .delta_mm
            .iter_mut()
            .zip(
                self.target_mm
                    .iter()
                    .zip(mean.iter())
                    .zip(held_mm.iter())
                    .zip(min_mm.iter())
                    .zip(max_mm.iter()),
            )
            .enumerate()
        {
            let err = *t - *e;
            *d = 0.0;
            if !(err.abs() > band) {
                continue;
            }
            let bit = 1u8 << i;
            let up = self.approach_up & bit != 0;
            // Late, once per leg: as if overshot (it may be in the gap).
            let late = self.corrections > LATE_CORRECTIONS && self.retreated & bit == 0;
            if late {
                self.retreated |= bit;
            }
            // Toward the approach side: by the error. Against it (an overshoot): back
            // past the setpoint, to approach again.
            let step = if (err > 0.0) == up && !late {
                GAIN * err
            } else if up {
                err - RETREAT_MM
            } else {
                err + RETREAT_MM
            };
            // Constant bounds: `clamp` cannot panic. The run-time bounds below take `max`
            // then `min` (`clamp` panics on bounds out of order or NaN).
            let step = step.clamp(-MAX_CORRECTION_MM, MAX_CORRECTION_MM);
            *d = (*h + step)
                .max(*t - MAX_CORRECTION_MM)
                .min(*t + MAX_CORRECTION_MM)
                .max(*lo)
                .min(*hi)
                - *h;
            largest = largest.max(d.abs());
        }
        if !(largest > 0.0) {
            return Ok(Ramp::immediate());
        }
        Ramp::plan(
            LIMIT_USE_FRACTION * speed_mm_per_s / largest,
            LIMIT_USE_FRACTION * accel_mm_per_s2 / largest,
        )
    }

    /// The drive command of the correction under way at ramp progress `progress` (0..1).
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
        let mut f = Fine::begin([0.0; LEGS], &Approach::new([0.0; LEGS]), 100);
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
        f = Fine::begin([0.00005; LEGS], &Approach::new([0.0; LEGS]), 200);
        let (lo, hi) = ([0.0f32; LEGS], [0.0001f32; LEGS]);
        assert_eq!(f.at_rest(201, Some(&lo), TOL, 4), FineStep::Wait);
        assert_eq!(f.at_rest(202, Some(&hi), TOL, 4), FineStep::Wait);
        assert_eq!(f.at_rest(203, Some(&lo), TOL, 4), FineStep::Wait);
        assert_eq!(f.at_rest(204, Some(&hi), TOL, 4), FineStep::InPosition);
        // A mean one count off: within the tolerance, not within it less half a count
        // (the true slider could be 1.5 counts off): a correction.
        f = Fine::begin([0.0; LEGS], &Approach::new([0.0; LEGS]), 300);
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
        let mut f = Fine::begin([0.0; LEGS], &Approach::new([0.0; LEGS]), 0);
        let bad = [0.001f32; LEGS];
        let lim = [10.0f32; LEGS];
        let mut n = 0;
        for c in 1..TIMEOUT_CYCLES {
            if f.at_rest(c, Some(&bad), TOL, 1) == FineStep::Correct {
                n += 1;
                f.correct(&[0.0; LEGS], TOL, &lim.map(|v| -v), &lim, 0.2, 1.0)
                    .unwrap();
            }
        }
        assert_eq!(n, MAX_CORRECTIONS);
        assert_eq!(
            f.at_rest(TIMEOUT_CYCLES, Some(&bad), TOL, 1),
            FineStep::TimedOut(ALL_LEGS)
        );
    }

    #[test]
    fn a_correction_approaches_from_one_side_is_bounded_and_stays_within_the_stroke() {
        let mut a = Approach::new([0.0; LEGS]);
        // Legs 1, 3, 5 last moved up, 2, 4, 6 down.
        a.track(&[1.0, -1.0, 1.0, -1.0, 1.0, -1.0]);
        let mut f = Fine::begin([1.0; LEGS], &a, 0);
        let held = [1.0f32; LEGS];
        // Leg 1 short (below, approach up): corrected by its error. Leg 2 short (above,
        // approach down): by its error. Leg 3 overshot (above, approach up): back past
        // by the retreat. Leg 4 overshot (below, approach down). Leg 5 far off: bounded.
        // Leg 6 in tolerance: untouched.
        let enc = [0.998, 1.002, 1.002, 0.998, 0.9, 1.00004];
        // The reading a correction uses is the mean over the rest window.
        let mut noisy = enc;
        noisy[0] += 0.0001;
        assert_eq!(f.at_rest(1, Some(&noisy), TOL, 2), FineStep::Wait);
        noisy[0] -= 0.0002;
        assert_eq!(f.at_rest(2, Some(&noisy), TOL, 2), FineStep::Correct);
        let hi = [1.0 + 0.01; LEGS];
        let ramp = f.correct(&held, TOL, &[-5.0; LEGS], &hi, 0.2, 1.0).unwrap();
        let end = f.setpoint(1.0);
        let d: Vec<f32> = end.iter().zip(held).map(|(e, h)| e - h).collect();
        let close = |a: f32, b: f32| (a - b).abs() < 1e-6;
        assert!(close(d[0], GAIN * 0.002), "{d:?}");
        assert!(close(d[1], -GAIN * 0.002), "{d:?}");
        assert!(close(d[2], -0.002 - RETREAT_MM), "{d:?}");
        assert!(close(d[3], 0.002 + RETREAT_MM), "{d:?}");
        assert!(
            close(d[4], 0.01),
            "the stroke limit, inside the bound: {d:?}"
        );
        assert_eq!(d[5], 0.0);
        assert_eq!(f.setpoint(0.0), held);
        assert!(ramp.end_cycle() > 2);
        // The bound itself.
        let mut a = Approach::new([0.0; LEGS]);
        a.track(&[1.0; LEGS]);
        let mut g = Fine::begin([0.0; LEGS], &a, 0);
        assert_eq!(g.at_rest(1, Some(&[-1.0; LEGS]), TOL, 1), FineStep::Correct);
        g.correct(&[0.0; LEGS], TOL, &[-5.0; LEGS], &[5.0; LEGS], 0.2, 1.0)
            .unwrap();
        assert!(g.setpoint(1.0).iter().all(|v| close(*v, MAX_CORRECTION_MM)));
    }
}
