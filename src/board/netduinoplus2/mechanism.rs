//! The mechanism: the encoders' frame and scale, the drives, the switches' polarity, and
//! the types of what [`Board::take`](super::Board::take) wires from them on the harness
//! (the pin map in `mod.rs`).

use stm32f4xx_hal::gpio::{AnyPin, Input, Output, PushPull};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::spi::Spi;

use super::step_engine::{StepChannel, MAX_PULSES_PER_CYCLE};
use crate::drivers::biss::{BissChain, BissConfig, MaLine};
use crate::drivers::exposure::ExposureLine;
use crate::drivers::stepper::{StepDirDrives, StepperConfig, StepperPolarity};
use crate::drivers::switches::{SwitchPolarity, TravelSwitchInputs};
use crate::drivers::Mechanism as DriverMechanism;
use crate::kinematics::LEGS;
use crate::nominal;

/// BiSS clock (Hz) requested from SPI1 (84 MHz APB2 / 32 = 2.6 MHz).
pub const BISS_CLOCK_HZ: u32 = 2_625_000;
/// The encoders' frame: 32-bit position words (RESOLUTE linear, 1 nm), Start bit
/// accepted from bit 2 (two samples before the Ack, SPI mode 2) to bit 10.
pub const BISS: BissConfig = BissConfig {
    position_bits: 32,
    start_bit_first: 2,
    start_bit_last: 10,
};
/// Encoder step (pm): 1 nm.
pub const ENCODER_LSB_PM: u32 = 1_000;
/// Raw encoder position at zero stroke, per leg. Installation values (mid-scale until
/// the mechanism's are measured); the parameter table has no field for them yet.
pub const ENCODER_ZERO_LSB: [u64; LEGS] = [1 << 31; LEGS];
/// The drives: the prototype's mechanics ([`crate::nominal`]: 1 mm lead screw, 200-step
/// motors, 16 microsteps, direct drive, 3,200 microsteps per mm), at most
/// [`MAX_PULSES_PER_CYCLE`] per cycle (15 mm/s), clamped beyond 6 mm; DRV8825-style pins
/// (ENABLE and FAULT active low).
pub const STEPPERS: StepperConfig = StepperConfig {
    lead_screw_pitch_nm: nominal::DRIVE_LEAD_SCREW_PITCH_NM,
    full_steps_per_rev: nominal::DRIVE_FULL_STEPS_PER_REV,
    microsteps_per_step: nominal::DRIVE_MICROSTEPS_PER_STEP,
    gear_motor_revs: nominal::DRIVE_GEAR_MOTOR_REVS,
    gear_screw_revs: nominal::DRIVE_GEAR_SCREW_REVS,
    max_microsteps_per_cycle: MAX_PULSES_PER_CYCLE,
    travel_limit_nm: 6_000_000,
    polarity: StepperPolarity {
        dir_high_is_positive: true,
        enable_active_high: false,
        fault_active_high: false,
    },
};
/// Normally-closed end switches to ground with pull-ups (open = high = active);
/// reference sensors active high.
pub const SWITCHES: SwitchPolarity = SwitchPolarity {
    end_active_high: true,
    reference_active_high: true,
};

/// The BiSS daisy chain on SPI1.
pub type Encoders = BissChain<MaLine<Spi<pac::SPI1>>>;
/// The six step/direction drives.
pub type Drives =
    StepDirDrives<StepChannel, AnyPin<Output<PushPull>>, AnyPin<Output<PushPull>>, AnyPin<Input>>;
/// The eighteen switch inputs.
pub type Switches = TravelSwitchInputs<AnyPin<Input>>;
/// The camera's "exposing" line (PA7).
pub type Exposure = ExposureLine<AnyPin<Input>>;
/// Encoders, drives, switches and the exposing line behind the `hw` traits: what the
/// controller drives on this board. Its temperature inputs are the drivers' mechanism's
/// fixed reading (`hw`: no ADC driver yet; housekeeping reports the sensors stuck).
pub type Sliders = DriverMechanism<Encoders, Drives, Switches, Exposure>;
/// An output pin of the harness.
pub(super) type OutPin = AnyPin<Output<PushPull>>;
/// An input pin of the harness.
pub(super) type InPin = AnyPin<Input>;
