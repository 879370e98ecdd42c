//! # m2calib: the calibration side of the M2 ground tools (host)
//!
//! Built on the flight crate `m2ctl` (its kinematics, table and simulated plant), never
//! the other way; `m2ground` builds on this crate.
//! * [`files`]: geometry, pose and stroke files; [`ikfk`]: the `ik`/`fk` commands.
//! * [`calib`]: the source paper's calibration (identification, statistics, bundle fit).
//! * [`tracker`]: laser-tracker campaigns, their files, robust fit and the study.
//! * [`plan`], [`campaign`], [`eval`], [`report`], [`calib_cmd`]: calibration poses,
//!   simulated campaigns, accuracy evaluation, plots and the `calibrate` command.
//!
//! Everything needs `std`: the crate is empty without the `host` feature, so the
//! workspace's one test command (`cargo test --features host`) selects it and a firmware
//! build of the workspace (`--target thumbv7em-none-eabihf`) passes over it.
#![cfg_attr(not(feature = "host"), no_std)]
// A ground tool may stop on a broken invariant: the flight code's panic-free rules
// (m2ctl's src/lib.rs) do not apply here.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::indexing_slicing
)]

#[cfg(feature = "host")]
pub mod calib;
#[cfg(feature = "host")]
pub mod calib_cmd;
#[cfg(feature = "host")]
pub mod campaign;
#[cfg(feature = "host")]
pub mod eval;
#[cfg(feature = "host")]
pub mod files;
#[cfg(feature = "host")]
pub mod ikfk;
#[cfg(feature = "host")]
pub mod plan;
#[cfg(feature = "host")]
pub mod report;
#[cfg(feature = "host")]
pub mod tracker;
