//! A minimal, `no_std` stand-in for the mechanism: six sliders that follow their
//! setpoints at a bounded speed, and encoders that report the nearest 0.1 um count. The
//! firmware image uses it on QEMU (which has no sliders) behind the same
//! [`crate::hw`] traits the real drives and encoders implement; the host tests use the
//! richer `sim::Plant` (true geometry, noise, fault injection).

use crate::hw::{DriveError, EncoderError, SliderDrives, StrokeEncoders, ENCODER_MM_PER_COUNT};
use crate::kinematics::LEGS;

/// Sliders and encoders, advanced one control cycle at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliderModel {
    /// Slider positions (mm, stroke along base z).
    stroke_mm: [f32; LEGS],
    /// Drive setpoints (mm).
    setpoint_mm: [f32; LEGS],
    /// Largest slider travel per cycle (mm).
    max_step_mm: f32,
}

impl SliderModel {
    /// Sliders at home that move at most `max_speed_mm_per_s * cycle_s` per cycle.
    pub fn new(max_speed_mm_per_s: f32, cycle_s: f32) -> Self {
        Self {
            stroke_mm: [0.0; LEGS],
            setpoint_mm: [0.0; LEGS],
            max_step_mm: (max_speed_mm_per_s * cycle_s).abs(),
        }
    }

    /// Advances one cycle.
    pub fn step(&mut self) {
        let m = self.max_step_mm;
        for (s, sp) in self.stroke_mm.iter_mut().zip(self.setpoint_mm.iter()) {
            let d = *sp - *s;
            *s += if d > m {
                m
            } else if d < -m {
                -m
            } else {
                d
            };
        }
    }

    /// Slider positions (mm).
    pub fn strokes_mm(&self) -> [f32; LEGS] {
        self.stroke_mm
    }
}

/// Rounds to the nearest integer count without libm (|x| < 2^31 assumed).
fn round_to_count(x: f32) -> i32 {
    if x >= 0.0 {
        (x + 0.5) as i32
    } else {
        (x - 0.5) as i32
    }
}

impl StrokeEncoders for SliderModel {
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError> {
        let per = ENCODER_MM_PER_COUNT as f32;
        Ok(self.stroke_mm.map(|s| round_to_count(s / per)))
    }
}

impl SliderDrives for SliderModel {
    fn command_strokes_mm(&mut self, setpoint_mm: &[f32; LEGS]) -> Result<(), DriveError> {
        self.setpoint_mm = *setpoint_mm;
        Ok(())
    }

    fn hold(&mut self) {
        self.setpoint_mm = self.stroke_mm;
    }

    fn status(&mut self) -> Result<(), DriveError> {
        Ok(())
    }
}
