//! The few things the controller needs from hardware. The board glue implements them on
//! the target, the simulated plant (`sim`, host) on x86; the controller code is the same.

use crate::kinematics::LEGS;

/// Encoder resolution: one count is 0.1 um of slider stroke (mm per count).
pub const ENCODER_MM_PER_COUNT: f64 = 1.0e-4;

/// Why the encoders could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncoderError {
    /// No answer from the encoder of this leg (0-based).
    NoResponse {
        /// 0-based leg index.
        leg: u8,
    },
    /// The encoder answered with a corrupted frame (parity/CRC).
    Corrupted {
        /// 0-based leg index.
        leg: u8,
    },
}

/// Why a slider command was not accepted by the drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveError {
    /// The drive of this leg (0-based) reports a fault.
    DriveFault {
        /// 0-based leg index.
        leg: u8,
    },
}

/// Absolute stroke encoders of the six sliders.
pub trait StrokeEncoders {
    /// Reads all six encoders at one instant, in counts of [`ENCODER_MM_PER_COUNT`]
    /// (stroke along base z, 0 at home).
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError>;
}

/// Position-commanded slider drives.
pub trait SliderDrives {
    /// Commands every slider to a stroke setpoint (mm, along base z, 0 at home). The
    /// drives follow within their own speed limits. A faulted drive refuses and holds.
    fn command_strokes_mm(&mut self, setpoint_mm: &[f32; LEGS]) -> Result<(), DriveError>;
    /// Holds every slider where its drive is now (setpoint := the drive's own position).
    fn hold(&mut self);
    /// The stroke each drive holds or is moving to now (mm, along base z): the drive's
    /// own count (steps issued for a stepper drive, the setpoint of a position-controlled
    /// one), independent of the encoders. After [`SliderDrives::hold`] it is where the
    /// drives stopped. The controller starts every motion from these, so a motion's
    /// first setpoint is continuous with what the drives hold whatever the encoders say.
    fn setpoints_mm(&mut self) -> [f32; LEGS];
    /// Health of the drives now (polled while no command is sent, i.e. at rest).
    fn status(&mut self) -> Result<(), DriveError>;
}

/// Converts encoder counts to strokes (mm) in f32.
pub fn counts_to_mm(counts: &[i32; LEGS]) -> [f32; LEGS] {
    // f32 holds integers exactly up to 2^24 counts (1.6 m of stroke), far beyond the slider.
    let per = ENCODER_MM_PER_COUNT as f32;
    counts.map(|c| c as f32 * per)
}
