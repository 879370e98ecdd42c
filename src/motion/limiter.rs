//! The output stage: the last check of every stroke command before it goes to the
//! drives, independent of the geometry and of the planner.
//!
//! Whatever computed a command (a trajectory through IK, a direct-stroke ramp), its
//! per-cycle change is bounded here, leg by leg, by the speed and acceleration limits in
//! force: a step of at most `v dt` and a change of step of at most `a dt^2`, each with
//! [`STEP_TOLERANCE_MM`] for the f32 rounding of strokes. A command beyond them is
//! clamped to them and reported ([`Limited::legs`]): the controller latches
//! [`crate::supervision::FaultFlags::OUTPUT_LIMITED`] and holds, since a step beyond the
//! limits means the geometry or the planner is wrong (a RAM upset of the geometry during
//! a move commanded 0.10 mm in one cycle, 500 times the speed limit, before the scrub
//! or the following error caught it).
//!
//! The limits live here in their own checked storage ([`CheckedLimits`]: each word and
//! its complement), set when the parameters are applied: an upset of the motion limits
//! the planner uses does not move them, and an upset of this copy is found at its next
//! use ([`Limited::limits_ok`]).
//!
//! Units: strokes in mm (the slider's travel along the base z axis); steps in mm per
//! control cycle ([`CYCLE_S`]).

use super::ramp::CYCLE_S;
use crate::kinematics::LEGS;

/// Tolerance on a step and on a change of step (mm): f32 strokes near 5 mm round to
/// 0.5 nm; a step is a difference of two, a change of step of three (the soak's own
/// bound on a healthy step is 2 nm).
pub const STEP_TOLERANCE_MM: f32 = 4e-6;

/// Which limits a command is held to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LimitKind {
    /// A coordinated move (and its stop ramp): parameters 0x0010, 0x0011.
    Coordinated,
    /// A direct-stroke move: parameters 0x0012, 0x0013.
    Direct,
}

/// Speed (mm/s) and acceleration (mm/s^2) limits of each kind of motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepLimits {
    /// Coordinated moves: speed, acceleration.
    pub coordinated: (f32, f32),
    /// Direct strokes: speed, acceleration.
    pub direct: (f32, f32),
}

/// [`StepLimits`] as per-cycle bounds, each word kept with its complement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CheckedLimits {
    /// Largest step and largest change of step (mm, f32 bits): coordinated, then direct.
    words: [u32; 4],
    complements: [u32; 4],
}

impl CheckedLimits {
    /// The per-cycle bounds of `l`.
    pub fn new(l: &StepLimits) -> Self {
        let dt = CYCLE_S;
        let words = [
            l.coordinated.0 * dt,
            l.coordinated.1 * dt * dt,
            l.direct.0 * dt,
            l.direct.1 * dt * dt,
        ]
        .map(f32::to_bits);
        Self {
            words,
            complements: words.map(|w| !w),
        }
    }

    /// The bounds of `kind` (largest step, largest change of step, mm), if the storage
    /// is intact.
    fn bounds(&self, kind: LimitKind) -> Option<(f32, f32)> {
        if self
            .words
            .iter()
            .zip(self.complements)
            .any(|(w, c)| *w != !c)
        {
            return None;
        }
        let [cs, ca, ds, da] = self.words.map(f32::from_bits);
        Some(match kind {
            LimitKind::Coordinated => (cs, ca),
            LimitKind::Direct => (ds, da),
        })
    }
}

/// What [`OutputLimiter::limit`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limited {
    /// The command to send.
    pub strokes_mm: [f32; LEGS],
    /// Legs whose step was clamped (bit i = leg i+1).
    pub legs: u8,
    /// The limits' storage was intact (if not, the command is the previous one).
    pub limits_ok: bool,
}

/// The output stage (module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputLimiter {
    limits: CheckedLimits,
    /// The last command it let through (mm) and its step (mm per cycle).
    prev_mm: [f32; LEGS],
    prev_step_mm: [f32; LEGS],
}

impl OutputLimiter {
    /// At rest at `held_mm`, with `limits`.
    pub fn new(limits: &StepLimits, held_mm: [f32; LEGS]) -> Self {
        Self {
            limits: CheckedLimits::new(limits),
            prev_mm: held_mm,
            prev_step_mm: [0.0; LEGS],
        }
    }

    /// New limits in force (the parameters were applied).
    pub fn set_limits(&mut self, limits: &StepLimits) {
        self.limits = CheckedLimits::new(limits);
    }

    /// At rest where the drives hold: the next motion starts from `held_mm` at zero
    /// speed.
    pub fn rest(&mut self, held_mm: [f32; LEGS]) {
        self.prev_mm = held_mm;
        self.prev_step_mm = [0.0; LEGS];
    }

    /// The command `strokes_mm` with each leg's step from the last command bounded by
    /// `kind`'s limits (`!(x <= bound)` also clamps a NaN: the leg keeps its command).
    pub fn limit(&mut self, kind: LimitKind, strokes_mm: [f32; LEGS]) -> Limited {
        let Some((max_step, max_change)) = self.limits.bounds(kind) else {
            return Limited {
                strokes_mm: self.prev_mm,
                legs: 0,
                limits_ok: false,
            };
        };
        let (max_step, max_change) = (max_step + STEP_TOLERANCE_MM, max_change + STEP_TOLERANCE_MM);
        let mut out = strokes_mm;
        let mut legs = 0u8;
        for (i, ((s, prev), prev_step)) in out
            .iter_mut()
            .zip(self.prev_mm.iter_mut())
            .zip(self.prev_step_mm.iter_mut())
            .enumerate()
        {
            let step = *s - *prev;
            // Within the speed bound, and within the acceleration bound of the last step.
            let lo = (*prev_step - max_change).max(-max_step);
            let hi = (*prev_step + max_change).min(max_step);
            let bounded = if step >= lo && step <= hi {
                step
            } else {
                legs |= 1 << i;
                if step < lo {
                    lo
                } else if step > hi {
                    hi
                } else {
                    0.0
                }
            };
            *s = *prev + bounded;
            *prev = *s;
            *prev_step = bounded;
        }
        Limited {
            strokes_mm: out,
            legs,
            limits_ok: true,
        }
    }

    /// Test hook (host): flips bit `bit` of word `word` of the limits' storage (0..=3
    /// the bounds, 4..=7 their complements), as a radiation upset would.
    #[cfg(feature = "host")]
    pub fn upset(&mut self, word: usize, bit: u32) {
        let m = 1u32.checked_shl(bit).unwrap_or(0);
        if let Some(w) = self.limits.words.get_mut(word) {
            *w ^= m;
        } else if let Some(c) = self.limits.complements.get_mut(word.wrapping_sub(4)) {
            *c ^= m;
        }
    }
}
