//! Board glue: the only code that touches hardware. One file per board; the firmware
//! entry selects one. Today: QEMU's mps2-an386 (Cortex-M4F).

pub mod mps2_an386;

pub use mps2_an386 as active;
