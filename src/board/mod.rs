//! Board glue (feature `firmware`, target only): the only code that touches hardware
//! registers. One file per board; [`active`] names the one this image is built for.
//! Today: QEMU's mps2-an386 (Cortex-M4F). A second board is a new file here
//! implementing the same items (device description, take-once `Board`, UART, control
//! timer, watchdog, reset record, table flash, stack guard, markers).
//!
//! [`qemu_sliders`] is a board part, not a board: the slider/encoder model that an
//! emulated board has instead of slider drivers.

pub mod mps2_an386;
pub mod qemu_sliders;

pub use mps2_an386 as active;
