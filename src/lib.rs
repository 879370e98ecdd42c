//! # m2ctl: controller of a space telescope's secondary-mirror (M2) mechanism
//!
//! A 6-PSS Stewart platform (six vertical sliders, spherical joints, fixed-length rods)
//! positions the secondary mirror. This crate holds the flight software and, behind the
//! `host` feature, the simulated plant and the ground station's link side. The ground
//! tools are the workspace's other crates, built on this one (never the other way):
//! `calib/` (m2calib: geometry files, IK/FK commands, calibration, the paper study) and
//! `ground/` (m2ground: telecommand encoder, mission database, ICD, gateway, the CLI).
//!
//! Layers (hardware-independent unless noted):
//! * [`kinematics`]: geometry, IK, FK, workspace check, generic over `f32`/`f64`.
//! * [`nominal`]: the compiled-in nominal geometry of the prototype.
//! * [`selftest`]: the golden-vector self-test the firmware runs at boot.
//! * [`units`]: the unit conversion factors, each defined once.
//! * [`softfloat`], [`mem`]: the target's `f64` arithmetic and memory copy and fill,
//!   written for size.
//! * [`thermal`]: temperature sensors (PT1000 through an ADC) and the thermal model:
//!   the stroke offsets that keep a pose as the parts expand.
//! * [`drivers`]: BiSS-C encoders, step/direction drives, limit switches on
//!   embedded-hal 1.0 traits (no board imports).
//! * `sim` (host): the simulated plant (true geometry, sliders, encoders).
//! * `station` (host): the ground station's side of the link (framing, numbering).
#![cfg_attr(not(feature = "host"), no_std)]
// The flight code's panic-free rules, once for the whole library (Cargo.toml's [lints]
// says why here): the host-only folders `sim` and `station` allow them, and the few
// places that index provably in range say so where they do. `unsafe_code` (denied) and
// `missing_docs` come from Cargo.toml. Unit tests (`cfg(test)`) may unwrap.
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::unreachable,
        clippy::indexing_slicing
    )
)]

pub mod controller;
pub mod drivers;
pub mod hw;
pub mod kinematics;
pub mod link;
pub mod mem;
pub mod motion;
pub mod nominal;
pub mod pass;
#[cfg(any(feature = "host", feature = "firmware"))]
pub mod plant;
pub mod selftest;
pub mod softfloat;
pub mod supervision;
pub mod table;
pub mod thermal;
pub mod timing;
pub mod units;
pub mod worker;

#[cfg(feature = "firmware")]
pub mod board;
#[cfg(feature = "host")]
pub mod sim;
#[cfg(feature = "host")]
pub mod station;
