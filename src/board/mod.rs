//! Board glue (feature `firmware`, target only): the only code that touches hardware
//! registers. One file per board; [`active`] names the one this image is built for.
//! Today: QEMU's mps2-an386 (Cortex-M4F). A second board is a new file here
//! implementing the same items (exit, UART, table flash, cycle pacing, markers).

pub mod mps2_an386;

pub use mps2_an386 as active;
