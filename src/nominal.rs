//! The prototype's nominal geometry, compiled in: the table the controller falls back to
//! when no valid calibrated table is stored. Joint centres are those of
//! `testdata/geometry.toml` (the seed paper's Table 1, nominal column); a host test
//! checks that the two agree.

use crate::kinematics::{GeometryParams, LegParams, StrokeLimits, WorkspaceLimits, LEGS};

/// Flight workspace half-range in translation (mm per axis).
pub const WORKSPACE_TRANSLATION_MM: f64 = 2.0;
/// Flight workspace half-range in rotation (arcsec per axis).
pub const WORKSPACE_ROTATION_ARCSEC: f64 = 600.0;
/// Slider soft stroke limit, symmetric about home (mm). The workspace corners need up to
/// about 4 mm; 5 mm leaves margin without letting the mechanism reach its hard stops.
pub const STROKE_LIMIT_MM: f64 = 5.0;

/// The prototype's slider drives, one per leg: the lead of the lead screw (nm of slider
/// travel per screw revolution). With [`DRIVE_FULL_STEPS_PER_REV`],
/// [`DRIVE_MICROSTEPS_PER_STEP`] and the gear ([`DRIVE_GEAR_MOTOR_REVS`] motor turns per
/// [`DRIVE_GEAR_SCREW_REVS`] screw turns) it fixes the microstep: 1 mm / (200 * 64) =
/// 0.078 um of stroke (`motion::fine::MICROSTEP_MM`). The second board's step/direction drives
/// (`board::netduinoplus2::STEPPERS`) and the simulated drive train
/// (`sim::drive_train::DRIVE_STEPPERS`) both take these.
pub const DRIVE_LEAD_SCREW_PITCH_NM: u32 = 1_000_000;
/// Full steps per motor revolution (a 1.8 degree two-phase hybrid stepper).
pub const DRIVE_FULL_STEPS_PER_REV: u16 = 200;
/// Microsteps per full step set on the drive.
pub const DRIVE_MICROSTEPS_PER_STEP: u16 = 64;
/// Gear between motor and screw: this many motor revolutions ...
pub const DRIVE_GEAR_MOTOR_REVS: u16 = 1;
/// ... turn the lead screw this many revolutions (1:1, direct drive).
pub const DRIVE_GEAR_SCREW_REVS: u16 = 1;

const fn leg(a_mm: [f64; 3], b_mm: [f64; 3]) -> LegParams {
    LegParams { a_mm, b_mm }
}

/// Nominal joint centres and home position, no limits (as in `geometry.toml`).
pub const PROTOTYPE: GeometryParams = GeometryParams::new(PROTOTYPE_LEGS, PROTOTYPE_P0_MM);

/// [`PROTOTYPE`]'s legs. The flight code builds its geometries from this and
/// [`PROTOTYPE_P0_MM`] (not from the whole [`PROTOTYPE`], whose empty limits would be
/// 160 bytes of zeros in flash).
pub const PROTOTYPE_LEGS: [LegParams; LEGS] = [
    leg([67.8981, 61.7825, -134.1000], [103.3452, 35.5846, 85.7000]),
    leg([19.5562, 89.6928, -134.1000], [-20.8554, 107.2919, 85.7000]),
    leg([-87.4543, 27.9102, -134.1000], [-82.4898, 71.7073, 85.7000]),
    leg(
        [-87.4543, -27.9102, -134.1000],
        [-82.4898, -71.7073, 85.7000],
    ),
    leg(
        [19.5562, -89.6928, -134.1000],
        [-20.8554, -107.2919, 85.7000],
    ),
    leg(
        [67.8981, -61.7825, -134.1000],
        [103.3452, -35.5846, 85.7000],
    ),
];

/// [`PROTOTYPE`]'s home position of the pivot (mm, base frame).
pub const PROTOTYPE_P0_MM: [f64; 3] = [0.0, 0.0, -150.0];

/// The nominal geometry with the flight stroke and workspace limits.
pub const fn prototype_with_flight_limits() -> GeometryParams {
    GeometryParams {
        legs: PROTOTYPE_LEGS,
        p0_mm: PROTOTYPE_P0_MM,
        stroke_limits: Some(StrokeLimits {
            min_mm: [-STROKE_LIMIT_MM; LEGS],
            max_mm: [STROKE_LIMIT_MM; LEGS],
        }),
        workspace: Some(WorkspaceLimits {
            translation_mm: [WORKSPACE_TRANSLATION_MM; 3],
            rotation_rad: [WORKSPACE_ROTATION_ARCSEC / crate::units::ARCSEC_PER_RAD; 3],
        }),
    }
}
