//! Drivers for the mechanism's hardware, `no_std`, generic over embedded-hal 1.0 traits
//! and free of any board import: a board wires them to its HAL's SPI, GPIO and timers.
//!
//! * [`biss`]: BiSS-C absolute linear encoders on an `SpiDevice` (one daisy chain of
//!   six in one transaction, or six point-to-point links) -> [`hw::StrokeEncoders`],
//!   [`hw::EncoderWarnings`].
//! * [`stepper`]: step/direction drives (lead screw, microsteps, gear) with a
//!   drift-free microstep count and a [`stepper::StepPulses`] seam for the board's
//!   timer -> [`hw::SliderDrives`], [`hw::IssuedStrokes`].
//! * [`switches`]: lower/upper end-of-travel switches and a reference sensor per slider
//!   -> [`hw::EndOfTravel`].
//! * [`exposure`]: the camera's "exposing" line -> [`hw::ExposureInput`].
//! * [`Mechanism`]: the three together as the one `mech` object the controller takes.
//!   Its switch read also stops the drives at once in every blocked direction
//!   ([`DirectionInhibit`]): an end-of-travel switch stops its leg in the driver, within
//!   the cycle it is read, independently of what the controller commands next.
//!
//! Nothing here allocates or panics; every hardware failure becomes a [`hw`] error.
//!
//! [`hw`]: crate::hw
//! [`hw::StrokeEncoders`]: crate::hw::StrokeEncoders
//! [`hw::EncoderWarnings`]: crate::hw::EncoderWarnings
//! [`hw::SliderDrives`]: crate::hw::SliderDrives
//! [`hw::IssuedStrokes`]: crate::hw::IssuedStrokes
//! [`hw::EndOfTravel`]: crate::hw::EndOfTravel
//! [`hw::ExposureInput`]: crate::hw::ExposureInput

pub mod biss;
pub mod exposure;
pub mod stepper;
pub mod switches;

use crate::hw::{
    DriveError, EncoderError, EncoderWarnings, EndOfTravel, IssuedStrokes, SliderDrives,
    StrokeEncoders, TravelSwitches,
};
use crate::kinematics::LEGS;

/// Encoders, drives, switches and the camera's exposing line of one mechanism, behind
/// every [`crate::hw`] trait (each call goes to the part that owns it).
pub struct Mechanism<E, D, S, X = exposure::NoExposureLine> {
    /// The stroke encoders.
    pub encoders: E,
    /// The slider drives.
    pub drives: D,
    /// The end-of-travel switches and reference sensors.
    pub switches: S,
    /// The camera's "exposing" line ([`exposure::NoExposureLine`] where none is wired).
    pub exposure: X,
}

impl<E: StrokeEncoders, D, S, X> StrokeEncoders for Mechanism<E, D, S, X> {
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError> {
        self.encoders.read_counts()
    }
}

impl<E: EncoderWarnings, D, S, X> EncoderWarnings for Mechanism<E, D, S, X> {
    fn warning_legs(&self) -> u8 {
        self.encoders.warning_legs()
    }
}

impl<E, D: SliderDrives, S, X> SliderDrives for Mechanism<E, D, S, X> {
    fn command_strokes_mm(&mut self, setpoint_mm: &[f32; LEGS]) -> Result<(), DriveError> {
        self.drives.command_strokes_mm(setpoint_mm)
    }
    fn hold(&mut self) {
        self.drives.hold()
    }
    fn setpoints_mm(&mut self) -> [f32; LEGS] {
        self.drives.setpoints_mm()
    }
    fn status(&mut self) -> Result<(), DriveError> {
        self.drives.status()
    }
}

impl<E, D: IssuedStrokes, S, X> IssuedStrokes for Mechanism<E, D, S, X> {
    fn issued_strokes_mm(&self) -> [f32; LEGS] {
        self.drives.issued_strokes_mm()
    }
    fn align_issued_mm(&mut self, measured_mm: &[f32; LEGS]) {
        self.drives.align_issued_mm(measured_mm)
    }
}

/// Drives that can refuse motion in one direction per leg at once: the hardware-level
/// stop of the end-of-travel switches.
pub trait DirectionInhibit {
    /// Blocks motion toward smaller (`negative_legs`) and larger (`positive_legs`)
    /// strokes, per leg (bit i = leg i+1), until the next call; a motion already under
    /// way in a newly blocked direction stops now. Motion away stays possible.
    fn inhibit(&mut self, negative_legs: u8, positive_legs: u8);
}

impl<P, DIR, EN, FLT> DirectionInhibit for stepper::StepDirDrives<P, DIR, EN, FLT>
where
    P: stepper::StepPulses,
    DIR: embedded_hal::digital::OutputPin,
    EN: embedded_hal::digital::OutputPin,
    FLT: embedded_hal::digital::InputPin,
{
    fn inhibit(&mut self, negative_legs: u8, positive_legs: u8) {
        stepper::StepDirDrives::inhibit(self, negative_legs, positive_legs);
    }
}

/// Reads the switches and, before returning, applies them to the drives
/// ([`DirectionInhibit::inhibit`] with `blocked_negative`/`blocked_positive`).
impl<E, D: DirectionInhibit, S: EndOfTravel, X> EndOfTravel for Mechanism<E, D, S, X> {
    fn read_switches(&mut self) -> TravelSwitches {
        let s = self.switches.read_switches();
        self.drives
            .inhibit(s.blocked_negative(), s.blocked_positive());
        s
    }
}

/// The camera's "exposing" line, as wired ([`exposure`]).
impl<E, D, S, X: crate::hw::ExposureInput> crate::hw::ExposureInput for Mechanism<E, D, S, X> {
    fn exposing(&mut self) -> bool {
        self.exposure.exposing()
    }
}

/// The drivers' mechanism (the Netduino Plus 2's, a host rig's) has no ADC driver yet:
/// every channel reads the fixed [`crate::thermal::adc::COUNTS_NEAR_20_C`] (19.99 deg C).
/// The supervision takes a channel that repeats one count as stuck
/// (`thermal::STUCK_SAMPLES` readings, 6.4 s), so housekeeping reports these sensors
/// stuck: no temperature is claimed that was not measured.
impl<E, D, S, X> crate::hw::TemperatureInputs for Mechanism<E, D, S, X> {
    fn read_temperature_counts(&mut self) -> [u16; crate::thermal::TEMP_SENSORS] {
        [crate::thermal::adc::COUNTS_NEAR_20_C; crate::thermal::TEMP_SENSORS]
    }
}
