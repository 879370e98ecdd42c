//! The six sliders of an emulated board: QEMU models no slider, drive or encoder, so
//! the board stands one in behind the same hardware traits the flight code uses
//! ([`StrokeEncoders`], [`SliderDrives`]), built on the `no_std` plant core
//! ([`crate::plant::Sliders`], in `f32`).
//!
//! A board part, not flight code: it is what the QEMU board has instead of drivers.
//! Time: the model moves its sliders by one control period each time the encoders are
//! read (the controller reads them once per control cycle), at most
//! [`MODEL_SLIDER_SPEED_MM_PER_S`] times the period; the encoders report the nearest
//! count of [`crate::hw::ENCODER_MM_PER_COUNT`]. Its drives never fault.
//!
//! Temperatures: QEMU models no ADC behind the PT1000s either; every channel reads a
//! sensor at 20 deg C (the nominal thermal model's reference) with one count of noise,
//! alternately [`COUNTS_NEAR_20_C`] and one count more (a mean of 20.000 deg C to 1 mK,
//! and a live channel to the stuck check, as a real sensor's noise makes it).

use crate::hw::{DriveError, EncoderError, SliderDrives, StrokeEncoders};
use crate::kinematics::LEGS;
use crate::plant::{nearest_count_f32, Sliders};
use crate::thermal::adc::COUNTS_NEAR_20_C;
use crate::thermal::TEMP_SENSORS;
use crate::timing::CYCLE_S;

/// Speed of the model's sliders (mm/s): faster than the flight motion limits, so the
/// model follows the setpoints like a good position-controlled drive.
pub const MODEL_SLIDER_SPEED_MM_PER_S: f32 = 1.0;

/// The emulated sliders, drives and encoders (one instance, owned by the controller).
#[derive(Debug)]
pub struct QemuSliders {
    sliders: Sliders<f32>,
    max_step_mm: f32,
    /// The temperature channels' one count of noise: this read's.
    temperature_dither: u16,
}

impl QemuSliders {
    /// The sliders at home, at rest. Called once by the board's take-once constructor.
    pub(super) fn new() -> Self {
        Self {
            sliders: Sliders::default(),
            max_step_mm: MODEL_SLIDER_SPEED_MM_PER_S * CYCLE_S,
            temperature_dither: 0,
        }
    }
}

impl StrokeEncoders for QemuSliders {
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError> {
        self.sliders.step(self.max_step_mm, |_| false);
        Ok(self.sliders.positions_mm().map(nearest_count_f32))
    }
}

impl SliderDrives for QemuSliders {
    fn command_strokes_mm(&mut self, setpoint_mm: &[f32; LEGS]) -> Result<(), DriveError> {
        self.sliders.command(setpoint_mm);
        Ok(())
    }

    fn hold(&mut self) {
        self.sliders.hold();
    }

    fn setpoints_mm(&mut self) -> [f32; LEGS] {
        self.sliders.setpoints_f32()
    }

    fn status(&mut self) -> Result<(), DriveError> {
        Ok(())
    }
}

// An emulated board has no end-of-travel switches and no encoder warnings: the model's
// own (none active, none reported).
impl crate::hw::EndOfTravel for QemuSliders {
    fn read_switches(&mut self) -> crate::hw::TravelSwitches {
        self.sliders.read_switches()
    }
}

impl crate::hw::EncoderWarnings for QemuSliders {
    fn warning_legs(&self) -> u8 {
        self.sliders.warning_legs()
    }
}

const _: () = assert!(COUNTS_NEAR_20_C % 2 == 0);

/// The QEMU machine has no discrete input wired to the camera: never exposing (the
/// exposure hold is the telecommand's).
impl crate::hw::ExposureInput for QemuSliders {
    fn exposing(&mut self) -> bool {
        false
    }
}

impl crate::hw::TemperatureInputs for QemuSliders {
    fn read_temperature_counts(&mut self) -> [u16; TEMP_SENSORS] {
        self.temperature_dither ^= 1;
        // COUNTS_NEAR_20_C is even: `|` adds the count.
        [COUNTS_NEAR_20_C | self.temperature_dither; TEMP_SENSORS]
    }
}
