//! Ground tools (host only): file formats, the `ik`/`fk` commands, calibration.

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
pub mod station;
pub mod tc;
pub mod tracker;
