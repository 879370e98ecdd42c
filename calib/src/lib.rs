//! # m2calib: the calibration side of the M2 ground tools (host)
//!
//! Built on the flight crate `m2ctl` (its kinematics, table and simulated plant), never
//! the other way; `m2ground` builds on this crate.
//! * [`files`]: geometry, pose and stroke files; [`ikfk`]: the `ik`/`fk` commands.
//! * [`calib`]: the source paper's calibration (identification, statistics, bundle fit).
//! * [`tracker`]: laser-tracker campaigns, their files, robust fit and the study.
//! * [`plan`], [`campaign`], [`eval`], [`report`], [`calib_cmd`]: calibration poses,
//!   simulated campaigns, accuracy evaluation, plots and the `calibrate` command.
//! * [`thermal`]: the thermal calibration campaign in simulation (issue 22).
//!
//! Everything needs `std`: the crate is empty without the `host` feature, so the
//! workspace's one test command (`cargo test --features host`) selects it and a firmware
//! build of the workspace (`--target thumbv7em-none-eabihf`) passes over it.
#![cfg_attr(not(feature = "host"), no_std)]
#![cfg(feature = "host")]
// (The flight code's panic-free lints, denied in m2ctl's src/lib.rs, are not denied here:
// a ground tool may stop on a broken invariant.)

pub mod calib;
pub mod calib_cmd;
pub mod campaign;
pub mod eval;
pub mod files;
pub mod ikfk;
pub mod plan;
pub mod report;
pub mod thermal;
pub mod tracker;
