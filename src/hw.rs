//! The few things the controller needs from hardware. The board glue implements them on
//! the target, the simulated plant (`sim`, host) on x86; the controller code is the same.
//! The board's reset record reports in [`ResetCause`] and [`ResetInfo`], defined here so
//! that the board layer depends on this seam only, never on the controller (which
//! re-exports them).

use crate::kinematics::LEGS;

/// Encoder resolution: one count is 0.1 um of slider stroke (mm per count).
pub const ENCODER_MM_PER_COUNT: f64 = 1.0e-4;

/// The leg index a hardware error carries when it concerns every leg at once (a shared
/// bus or a daisy chain that failed as a whole). Any index `>= LEGS` means "every leg" to
/// the supervisor; this is the one the drivers use.
pub const EVERY_LEG: u8 = u8::MAX;

/// Why the encoders could not be read. `leg` is 0-based, or [`EVERY_LEG`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncoderError {
    /// No answer from the encoder of this leg (0-based): no acknowledge, no start bit
    /// in time (timeout), or the bus itself failed.
    NoResponse {
        /// 0-based leg index.
        leg: u8,
    },
    /// The encoder answered with a corrupted frame (parity/CRC, or a frame that breaks
    /// the protocol's structure).
    Corrupted {
        /// 0-based leg index.
        leg: u8,
    },
    /// The encoder answered with an intact frame (CRC good) whose error bit is set: its
    /// own checks say this position must not be trusted (on a Renishaw RESOLUTE: the
    /// internal position check failed, or the readhead is over temperature). The link
    /// works; the measurement does not.
    SelfCheckFailed {
        /// 0-based leg index.
        leg: u8,
    },
}

impl EncoderError {
    /// The 0-based leg (or [`EVERY_LEG`]) the error concerns.
    pub const fn leg(&self) -> u8 {
        match *self {
            EncoderError::NoResponse { leg }
            | EncoderError::Corrupted { leg }
            | EncoderError::SelfCheckFailed { leg } => leg,
        }
    }

    /// Stable code of the kind of failure, for events and telemetry: 1 no response,
    /// 2 corrupted, 3 the encoder's own error bit. Never renumbered.
    pub const fn code(&self) -> u8 {
        match self {
            EncoderError::NoResponse { .. } => 1,
            EncoderError::Corrupted { .. } => 2,
            EncoderError::SelfCheckFailed { .. } => 3,
        }
    }
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

/// Per-leg encoder warnings, for encoders that report one beside the position (BiSS-C's
/// warning bit). A warning does not invalidate the reading (that is
/// [`EncoderError::SelfCheckFailed`]); it asks for maintenance (RESOLUTE: the scale or
/// the readhead window should be cleaned).
pub trait EncoderWarnings {
    /// Legs (bit i = leg i+1) whose encoder flagged a warning in the most recent
    /// [`StrokeEncoders::read_counts`], counting only frames that arrived intact (CRC
    /// good); 0 before the first read. Read it after `read_counts`, every cycle.
    fn warning_legs(&self) -> u8;
}

/// What open-loop (step/direction) drives have issued: the stroke each slider was told
/// to reach, counted in the pulses actually sent. The encoders measure where it is; the
/// difference is missed steps (or compliance).
pub trait IssuedStrokes {
    /// Stroke (mm, along base z, 0 at home) each drive has been stepped to: the
    /// microsteps sent so far, converted through the lead-screw pitch, microstepping and
    /// gear ratio. Pulses still in flight at the call count as issued.
    fn issued_strokes_mm(&self) -> [f32; LEGS];
    /// Declares where the sliders are (mm, e.g. the encoder reading at boot or after
    /// recovery): the issued position becomes this, to the nearest microstep, and no
    /// pulse is sent. Until it has been called, the drives refuse to move (they do not
    /// know where they are).
    fn align_issued_mm(&mut self, measured_mm: &[f32; LEGS]);
}

/// The end-of-travel and reference inputs of every slider, as read in one cycle. Each
/// field is a leg mask (bit i = leg i+1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TravelSwitches {
    /// Lower end-of-travel switch active: the slider must not move to smaller strokes.
    pub lower: u8,
    /// Upper end-of-travel switch active: the slider must not move to larger strokes.
    pub upper: u8,
    /// Reference (home) sensor active. Information only (homing, checking the encoder
    /// zero); never a fault by itself.
    pub reference: u8,
    /// Some input of this leg could not be read. Treat as both ends active (fail safe).
    pub unreadable: u8,
}

impl TravelSwitches {
    /// Legs that must not move towards smaller strokes: lower switch active or unreadable.
    pub const fn blocked_negative(&self) -> u8 {
        self.lower | self.unreadable
    }

    /// Legs that must not move towards larger strokes: upper switch active or unreadable.
    pub const fn blocked_positive(&self) -> u8 {
        self.upper | self.unreadable
    }

    /// Legs with an end-of-travel condition (either end, both, or unreadable).
    pub const fn end_of_travel(&self) -> u8 {
        self.lower | self.upper | self.unreadable
    }

    /// Legs whose two end switches are active at once, or unreadable: the switch
    /// hardware is at fault (a slider cannot be at both ends).
    pub const fn implausible(&self) -> u8 {
        (self.lower & self.upper) | self.unreadable
    }
}

/// End-of-travel switches and reference sensors of the six sliders.
pub trait EndOfTravel {
    /// Reads every input once (call once per cycle, right after the encoders). A switch
    /// seen active is in the result of this call: there is no filtering or latching here.
    fn read_switches(&mut self) -> TravelSwitches;
}

/// Everything the controller reads and commands of one mechanism: every control cycle
/// the encoders and their warnings, the drives, the end-of-travel switches; every
/// [`crate::timing::TEMPERATURE_PERIOD_CYCLES`] the temperature sensors. The controller
/// is generic over it; anything with the five parts has it (drivers on a board, the
/// simulated plant, a board's slider model).
pub trait MechanismIo:
    StrokeEncoders + SliderDrives + EndOfTravel + EncoderWarnings + TemperatureInputs + ExposureInput
{
}

impl<
        T: StrokeEncoders
            + SliderDrives
            + EndOfTravel
            + EncoderWarnings
            + TemperatureInputs
            + ExposureInput
            + ?Sized,
    > MechanismIo for T
{
}

/// The camera's "exposing" discrete input (issue 22's exposure hold): read once per
/// control cycle. Active holds every compensation step and every scheduled motion
/// and refuses operator moves, from its rising edge until it is released or
/// `controller` times it out.
pub trait ExposureInput {
    /// The input is active (the camera is exposing).
    fn exposing(&mut self) -> bool;
}

/// The mechanism's temperature sensors (issue 22): PT1000 resistance thermometers
/// ([`crate::thermal::pt1000`]) read through a 16-bit ratiometric ADC
/// ([`crate::thermal::adc`]). Part of [`MechanismIo`]: the controller reads every
/// channel once per [`crate::timing::TEMPERATURE_PERIOD_CYCLES`] and supervises each
/// ([`crate::thermal::SensorBank`]).
pub trait TemperatureInputs {
    /// Reads every channel once, in ADC counts (0 to
    /// [`crate::thermal::adc::FULL_SCALE_COUNTS`]; ratiometric, `counts = full scale * R
    /// / (R + REFERENCE_OHM)` for a sensor of resistance `R`). Channel `i` is sensor `i`
    /// of the thermal model (`crate::thermal::ThermalModel::sensor_of`, 0-based). An
    /// open sensor reads full scale, a shorted one 0; convert with
    /// [`crate::thermal::celsius_from_counts`] (deg C) and supervise with
    /// [`crate::thermal::SensorMonitor`].
    fn read_temperature_counts(&mut self) -> [u16; crate::thermal::TEMP_SENSORS];
}

/// Converts encoder counts to strokes (mm) in f32.
pub fn counts_to_mm(counts: &[i32; LEGS]) -> [f32; LEGS] {
    // f32 holds integers exactly up to 2^24 counts (1.6 m of stroke), far beyond the slider.
    let per = ENCODER_MM_PER_COUNT as f32;
    counts.map(|c| c as f32 * per)
}

/// Why the board reset the controller last (kept in no-init RAM by the board, reported
/// by the controller in the boot event and in housekeeping; `controller::ResetCause`
/// re-exports it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ResetCause {
    /// Power-on (no valid reset record found), or a host run.
    #[default]
    PowerOn,
    /// The watchdog expired (a control cycle did not complete in time).
    Watchdog,
    /// A commanded software reset.
    Software,
    /// A HardFault (including a stack overflow into the guard).
    HardFault,
    /// A panic (a defect: the flight image proves at link time it has none).
    Panic,
    /// A reset from outside that software did not announce: the reset pin, a debugger,
    /// QEMU's `system_reset` (how a board tells it from a watchdog reset: its
    /// `reset_record::on_boot` argument).
    External,
}

impl ResetCause {
    /// Wire code.
    pub const fn code(self) -> u8 {
        match self {
            ResetCause::PowerOn => 0,
            ResetCause::Watchdog => 1,
            ResetCause::Software => 2,
            ResetCause::HardFault => 3,
            ResetCause::Panic => 4,
            ResetCause::External => 5,
        }
    }

    /// From the wire code.
    pub const fn from_code(code: u8) -> Option<ResetCause> {
        Some(match code {
            0 => ResetCause::PowerOn,
            1 => ResetCause::Watchdog,
            2 => ResetCause::Software,
            3 => ResetCause::HardFault,
            4 => ResetCause::Panic,
            5 => ResetCause::External,
            _ => return None,
        })
    }
}

/// The reset cause and the boot counter, from the board.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ResetInfo {
    /// Why the last reset happened.
    pub cause: ResetCause,
    /// Boots since the no-init record was created (wrapping).
    pub boot_count: u16,
}
