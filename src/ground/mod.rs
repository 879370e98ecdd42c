//! Ground tools (host only): file formats, the `ik`/`fk` commands, calibration.

pub mod files;
pub mod ikfk;
