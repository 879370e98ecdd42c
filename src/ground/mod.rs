//! Ground tools (host only): file formats, the `ik`/`fk` commands, calibration.

// Host only (feature `host`): a ground tool or a simulation may stop on a broken
// invariant, so the flight code's panic-free rules (src/lib.rs) do not apply here.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::indexing_slicing
)]

pub mod calib;
pub mod calib_cmd;
pub mod campaign;
pub mod eval;
pub mod files;
pub mod gateway;
pub mod icd;
pub mod ikfk;
pub mod mdb;
pub mod mission;
pub mod plan;
pub mod report;
/// The ground station's link side, shared with the simulated bench (`crate::station`).
pub use crate::station;
pub mod tc;
pub mod tracker;
