//! The simulated mechanism's core, `no_std`: six sliders that follow their drive
//! setpoints at a bounded speed, and absolute encoders that report the nearest count.
//!
//! It is not flight logic and no flight module uses it. Two places do:
//! * the QEMU board (`board::mps2_an386`), which has no sliders, in `f32`;
//! * the host simulation (`sim::Plant`), in `f64`, which adds the true geometry,
//!   encoder noise, missed steps and the other injected faults.
//!
//! Strokes are in mm along base z, 0 at home; counts are [`ENCODER_MM_PER_COUNT`].
//!
//! The core has no end-of-travel switches, reference sensors or encoder warnings: its
//! [`EndOfTravel`] reads every input inactive and readable, its [`EncoderWarnings`]
//! none. That is what a board model built on it (QEMU's, which emulates no GPIO behind
//! the sliders) reports by delegating to it; the host simulation has its own.

use crate::hw::{EncoderWarnings, EndOfTravel, TravelSwitches, ENCODER_MM_PER_COUNT};
use crate::kinematics::{Real, LEGS};

/// Six position-commanded sliders: each drive moves its slider toward its setpoint by at
/// most `max_step_mm` per [`Sliders::step`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sliders<T> {
    /// Drive positions (mm): where each drive has moved its slider.
    position_mm: [T; LEGS],
    /// Drive setpoints (mm): where each drive is going.
    setpoint_mm: [T; LEGS],
}

impl<T: Real> Default for Sliders<T> {
    fn default() -> Self {
        Self::at([T::ZERO; LEGS])
    }
}

impl<T: Real> Sliders<T> {
    /// Sliders at rest at these strokes (mm).
    pub fn at(strokes_mm: [T; LEGS]) -> Self {
        Self {
            position_mm: strokes_mm,
            setpoint_mm: strokes_mm,
        }
    }

    /// Moves every slider toward its setpoint by at most `max_step_mm`, except those for
    /// which `blocked(leg)` (a jammed slider).
    pub fn step(&mut self, max_step_mm: T, blocked: impl Fn(usize) -> bool) {
        let m = max_step_mm.abs();
        for (leg, (p, sp)) in self
            .position_mm
            .iter_mut()
            .zip(self.setpoint_mm.iter())
            .enumerate()
        {
            if blocked(leg) {
                continue;
            }
            let d = *sp - *p;
            *p += if d > m {
                m
            } else if d < -m {
                -m
            } else {
                d
            };
        }
    }

    /// New setpoints (mm).
    pub fn command(&mut self, setpoint_mm: &[f32; LEGS]) {
        for (sp, c) in self.setpoint_mm.iter_mut().zip(setpoint_mm.iter()) {
            *sp = T::from_f64(f64::from(*c));
        }
    }

    /// Stops every drive where it is: setpoint := position, in the drive's own
    /// resolution (the `f32` of its command interface), so that commanding back what it
    /// reports holding changes nothing.
    pub fn hold(&mut self) {
        self.setpoint_mm = self
            .position_mm
            .map(|p| T::from_f64(f64::from(p.to_f64() as f32)));
    }

    /// Drive positions (mm).
    pub fn positions_mm(&self) -> [T; LEGS] {
        self.position_mm
    }

    /// Drive setpoints (mm).
    pub fn setpoints_mm(&self) -> [T; LEGS] {
        self.setpoint_mm
    }

    /// Drive setpoints in `f32` (mm), as the controller's drive interface reports them.
    pub fn setpoints_f32(&self) -> [f32; LEGS] {
        self.setpoint_mm.map(|v| v.to_f64() as f32)
    }

    /// Shifts a drive's position and setpoint by `delta_mm` (re-referencing after missed
    /// steps: the slider does not move, the drive's count does); the setpoint stays in
    /// the drive's resolution. No-op for a bad leg.
    pub fn shift(&mut self, leg: usize, delta_mm: T) {
        if let (Some(p), Some(sp)) = (self.position_mm.get_mut(leg), self.setpoint_mm.get_mut(leg))
        {
            *p += delta_mm;
            *sp = T::from_f64(f64::from((*sp + delta_mm).to_f64() as f32));
        }
    }

    /// Every slider has reached its setpoint, except those for which `blocked(leg)`.
    pub fn settled(&self, blocked: impl Fn(usize) -> bool) -> bool {
        self.position_mm
            .iter()
            .zip(self.setpoint_mm.iter())
            .enumerate()
            .all(|(leg, (p, sp))| p == sp || blocked(leg))
    }
}

/// No switches: every input inactive and readable.
impl<T> EndOfTravel for Sliders<T> {
    fn read_switches(&mut self) -> TravelSwitches {
        TravelSwitches::default()
    }
}

/// No encoder warnings.
impl<T> EncoderWarnings for Sliders<T> {
    fn warning_legs(&self) -> u8 {
        0
    }
}

/// The encoder count nearest to a stroke (mm), rounding half away from zero; saturates
/// at the `i32` range, NaN gives 0.
pub fn nearest_count<T: Real>(stroke_mm: T) -> i32 {
    let c = (stroke_mm / T::from_f64(ENCODER_MM_PER_COUNT)).to_f64();
    let r = if c >= 0.0 { c + 0.5 } else { c - 0.5 };
    // `as` saturates and maps NaN to 0.
    r as i32
}

/// [`nearest_count`] for `f32` strokes without f64 arithmetic (the emulated board's
/// encoders, read every control cycle: there the f64 form was soft-float calls). Equal
/// to `nearest_count::<f32>` for every stroke (host test
/// `plant::nearest_count_f32_equals_the_f64_rounding`).
pub fn nearest_count_f32(stroke_mm: f32) -> i32 {
    // The same quotient as `nearest_count::<f32>` (computed in f32 there too).
    let c = stroke_mm / f32::from_f64(ENCODER_MM_PER_COUNT);
    // Toward zero, saturating, NaN to 0.
    let t = c as i32;
    // Exact: below 2^23 by Sterbenz' lemma (t within a factor 2 of c, or 0); beyond,
    // c is an integer and this is 0 (or, past the i32 range, of c's sign).
    let frac = c - t as f32;
    if frac >= 0.5 {
        t.saturating_add(1)
    } else if frac <= -0.5 {
        t.saturating_sub(1)
    } else {
        t
    }
}
