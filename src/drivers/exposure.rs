//! The camera's "exposing" discrete input on an embedded-hal `InputPin` ->
//! [`hw::ExposureInput`] (issue 22's exposure hold).
//!
//! [`hw::ExposureInput`]: crate::hw::ExposureInput

use embedded_hal::digital::InputPin;

use crate::hw::ExposureInput;

/// The exposing line: a pin and its active level. A read error is "not exposing": the
/// hold protects an exposure, not the mechanism, and an unreadable line must not hold
/// the compensation and the schedule for up to an hour (the telecommand still holds).
pub struct ExposureLine<P> {
    pin: P,
    active_high: bool,
}

impl<P: InputPin> ExposureLine<P> {
    /// The line on `pin`, exposing when the pin reads `active_high`.
    pub fn new(pin: P, active_high: bool) -> Self {
        Self { pin, active_high }
    }
}

impl<P: InputPin> ExposureInput for ExposureLine<P> {
    fn exposing(&mut self) -> bool {
        self.pin
            .is_high()
            .is_ok_and(|high| high == self.active_high)
    }
}

/// No exposing line wired (a rig without a camera): never exposing; the exposure hold
/// is the telecommand's.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoExposureLine;

impl ExposureInput for NoExposureLine {
    fn exposing(&mut self) -> bool {
        false
    }
}
