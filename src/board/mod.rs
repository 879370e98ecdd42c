//! Board glue (feature `firmware`, target only): the only code that touches hardware
//! registers. One folder per board, its `mod.rs` the `Board` and its take-once `take()`,
//! one file per peripheral beside it; [`active`] names the board this image is built
//! for, chosen by cargo feature:
//!
//! * default: QEMU's mps2-an386 (Cortex-M4F), [`mps2_an386`];
//! * `board-netduinoplus2`: the STM32F405 Netduino Plus 2 (also QEMU `netduinoplus2`),
//!   `netduinoplus2`, which also wires the drivers of `crate::drivers` to the HAL.
//!
//! Every board implements the same items (device description with the flight image's
//! interrupt names, `device::interrupt`; take-once `Board` and its `Sliders`; UART,
//! control timer, watchdog, reset record, fault handlers, table flash, stack guard,
//! markers), so every image builds for either. Exactly one board is compiled (each
//! defines the vector table and the fault handlers; the images define the panic
//! handler).
//!
//! `cortex_m` holds what every board shares because it is the core's, not the board's
//! (reset record, fault handlers, stack guard and paint, test-image markers); each
//! board re-exports it. `table_flash` holds what the boards' table flashes share
//! (bounds, reads, erase alignment, the NOR rule, the refusal reasons).
//!
//! `qemu_sliders` is a board part, not a board: the slider/encoder model that the
//! emulated mps2-an386 board has instead of slider drivers (compiled with it only).
//!
//! The board layer depends on the hardware seam (`crate::hw`: the traits it implements,
//! the reset cause it reports) and on the drivers, never on the controller. It is where
//! `unsafe` lives: each file that needs it allows it with its reason, and every
//! `unsafe` carries a `// SAFETY:` note (host test `unsafe_audit`).

pub mod cortex_m;
#[cfg(not(feature = "board-netduinoplus2"))]
pub mod qemu_sliders;
pub mod table_flash;

/// The board's memory map (`memory.x`), as build.rs reads it.
mod memory_x {
    include!(concat!(env!("OUT_DIR"), "/memory_x.rs"));
}

#[cfg(not(feature = "board-netduinoplus2"))]
pub mod mps2_an386;
#[cfg(not(feature = "board-netduinoplus2"))]
pub use mps2_an386 as active;

#[cfg(feature = "board-netduinoplus2")]
pub mod netduinoplus2;
#[cfg(feature = "board-netduinoplus2")]
pub use netduinoplus2 as active;
