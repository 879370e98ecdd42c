//! # m2ground: the operations side of the M2 ground tools (host)
//!
//! Built on the flight crate `m2ctl` (its link layer and simulated bench) and on
//! `m2calib` (geometry files, calibration), never the other way.
//! * [`tc`]: the telecommand encoder (names and values to CCSDS/PUS packets).
//! * [`mdb`]: the mission database (XTCE for Yamcs), written from the flight code's
//!   layouts; [`icd`]: the ICD's generated tables.
//! * [`gateway`]: the Yamcs gateway (frames to packets, time correlation).
//! * [`mission`]: the mission demo (calibration campaign, upload, poses).
//! * the `m2ground` command line (ground/ground/src/bin/m2ground).
//!
//! Everything needs `std`: the crate is empty without the `host` feature, so the
//! workspace's one test command (`cargo test --features host`) selects it and a firmware
//! build of the workspace (`--target thumbv7em-none-eabihf`) passes over it.
#![cfg_attr(not(feature = "host"), no_std)]
#![cfg(feature = "host")]
// (The flight code's panic-free lints, denied in m2ctl's src/lib.rs, are not denied here:
// a ground tool may stop on a broken invariant.)

pub mod gateway;
pub mod icd;
pub mod mdb;
pub mod mission;
/// The ground station's link side, shared with the simulated bench (`m2ctl::station`).
pub use m2ctl::station;
pub mod tc;
