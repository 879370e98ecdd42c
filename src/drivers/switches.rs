//! End-of-travel switches and a reference sensor per slider, on `InputPin`s
//! ([`EndOfTravel`]).
//!
//! Every input is read once per [`EndOfTravel::read_switches`] call, with no filtering
//! and no latching: a switch active at the read is in that read's result, and the
//! controller decides what it means (latching, recovery). An input that cannot be read
//! is reported in [`TravelSwitches::unreadable`], which
//! [`TravelSwitches::blocked_negative`]/[`TravelSwitches::blocked_positive`] treat as
//! both ends active (fail safe).
//!
//! Wiring: end-of-travel switches are best wired normally closed to an input with a
//! pull-up, so a broken wire reads like a tripped switch; that is `end_active_high =
//! true` here (open contact = high = active).

use embedded_hal::digital::InputPin;

use crate::hw::{EndOfTravel, TravelSwitches};
use crate::kinematics::LEGS;

/// The three inputs of one slider.
pub struct LegSwitches<P> {
    /// Lower end-of-travel switch (smallest strokes).
    pub lower: P,
    /// Upper end-of-travel switch (largest strokes).
    pub upper: P,
    /// Reference (home) sensor.
    pub reference: P,
}

/// Active levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SwitchPolarity {
    /// The end-of-travel inputs are high when the switch is active (normally-closed
    /// switch to ground with a pull-up: open = high).
    pub end_active_high: bool,
    /// The reference input is high when the sensor is active.
    pub reference_active_high: bool,
}

/// The switch inputs of the six sliders.
pub struct TravelSwitchInputs<P> {
    legs: [LegSwitches<P>; LEGS],
    polarity: SwitchPolarity,
}

impl<P: InputPin> TravelSwitchInputs<P> {
    /// The six sliders' inputs with their active levels.
    pub fn new(legs: [LegSwitches<P>; LEGS], polarity: SwitchPolarity) -> Self {
        Self { legs, polarity }
    }
}

/// Reads one input: `Some(active)`, or `None` if it cannot be read.
fn active<P: InputPin>(pin: &mut P, active_high: bool) -> Option<bool> {
    pin.is_high().ok().map(|high| high == active_high)
}

impl<P: InputPin> EndOfTravel for TravelSwitchInputs<P> {
    fn read_switches(&mut self) -> TravelSwitches {
        let mut s = TravelSwitches::default();
        let p = self.polarity;
        for (i, leg) in self.legs.iter_mut().enumerate() {
            let bit = 1u8 << i;
            match active(&mut leg.lower, p.end_active_high) {
                Some(true) => s.lower |= bit,
                Some(false) => {}
                None => s.unreadable |= bit,
            }
            match active(&mut leg.upper, p.end_active_high) {
                Some(true) => s.upper |= bit,
                Some(false) => {}
                None => s.unreadable |= bit,
            }
            match active(&mut leg.reference, p.reference_active_high) {
                Some(true) => s.reference |= bit,
                Some(false) => {}
                None => s.unreadable |= bit,
            }
        }
        s
    }
}
