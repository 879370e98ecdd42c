//! QEMU mps2-an386 (Cortex-M4F, FPU on, 25 MHz system clock).
//!
//! Everything here is a fact of this board, checked against QEMU's model of it
//! (`hw/arm/mps2.c`, `hw/char/cmsdk-apb-uart.c`, `hw/timer/cmsdk-apb-timer.c`,
//! `hw/watchdog/cmsdk-apb-watchdog.c`):
//!
//! This file holds the [`Board`] and its take-once [`Board::take`] (UART0, the control
//! timer, the watchdog, the table flash and the emulated sliders) and the register
//! access every part uses; one file per part, each re-exported here:
//!
//! * `device.rs`, [`device`]: the device description RTIC needs (the board has no PAC):
//!   the interrupt lines with their numbers, `NVIC_PRIO_BITS`, the vector table for
//!   cortex-m-rt's `device` feature (`device.x` names the handlers);
//! * `uart.rs`: UART0 (CMSDK APB UART at 0x4000_4000, QEMU's first `-serial`):
//!   interrupt-driven, RX into a bounded queue (overrun bits and queue overflows
//!   counted), TX drained from a bounded queue by the TX interrupt;
//! * `timer.rs`: TIMER0 (CMSDK APB timer at 0x4000_0000, IRQ 8): the control rate,
//!   reload derived from [`CONTROL_RATE_HZ`](crate::timing::CONTROL_RATE_HZ) and
//!   [`SYSCLK_HZ`]; overrun detection;
//! * `watchdog.rs`: the CMSDK APB watchdog at 0x4000_8000 (its interrupt is the NMI; a
//!   second expiry resets the system), fed only by a completed control cycle, and its
//!   NMI, which records the cause in the reset record;
//! * `flash.rs`: the parameter-table flash region behind `embedded-storage`'s
//!   `NorFlash` and [`FlashStatus`](crate::table::FlashStatus) (on QEMU the "flash" is
//!   SSRAM: NOR semantics and erase/program times are modelled here);
//! * `super::qemu_sliders`: the emulated sliders ([`Sliders`]), a board part of its own;
//! * re-exported from [`super::cortex_m`]: the reset record in no-init RAM (reset cause,
//!   boot counter), the fault handlers (HardFault, MemManage, unexpected interrupts)
//!   that record their cause and reset, the MPU stack guard, stack painting/peak,
//!   instruction-count markers, semihosting exit (test images).
#![allow(unsafe_code)] // Volatile access to the board's MMIO registers.

use core::ptr::{read_volatile, write_volatile};
use core::sync::atomic::{AtomicBool, Ordering};

use super::qemu_sliders::QemuSliders;
use crate::hw::{ResetCause, ResetInfo};

pub mod device;

mod flash;
mod timer;
mod uart;
mod watchdog;

pub use flash::{FlashError, TableFlash, FLASH_ERASE_TICKS, FLASH_PROGRAM_TICKS, TABLE_LAYOUT};
pub use timer::{ticks, ControlTimer, TIMER_RELOAD_VALUE};
pub use uart::{Uart0, UartErrors, UartRx, UartTx, UART_BAUD};
pub use watchdog::{Watchdog, WATCHDOG_TIMEOUT_CYCLES};

/// System clock of QEMU's mps2 boards (Hz): the core, SysTick, the APB timers, the
/// watchdog and the UART baud generator all run from it.
pub const SYSCLK_HZ: u32 = 25_000_000;

// ---------------------------------------------------------------------------------
// Take-once hardware.

/// What the controller drives on this board: the emulated sliders.
pub type Sliders = QemuSliders;

/// The board's hardware, handed out once ([`Board::take`]).
pub struct Board {
    /// Why the board reset, and the boot count (from the no-init reset record).
    pub reset: ResetInfo,
    /// UART0 (split it into RX, TX and its error counter).
    pub uart0: Uart0,
    /// The control-rate timer.
    pub timer: ControlTimer,
    /// The watchdog (not running until started).
    pub watchdog: Watchdog,
    /// The parameter-table flash.
    pub flash: TableFlash,
    /// The emulated sliders, drives and encoders.
    pub sliders: QemuSliders,
}

static BOARD_TAKEN: AtomicBool = AtomicBool::new(false);

impl Board {
    /// The hardware, the first time; `None` afterwards. Reads the reset record (cause,
    /// boot count) and re-arms it.
    pub fn take() -> Option<Board> {
        if BOARD_TAKEN.swap(true, Ordering::SeqCst) {
            return None;
        }
        let mut flash = TableFlash { busy_until: None };
        flash.erase_if_never_written();
        Some(Board {
            // The watchdog announces itself from its NMI: a reset nobody announced
            // came from outside (the reset button, a debugger, QEMU's system_reset).
            reset: reset_record::on_boot(ResetCause::External),
            uart0: Uart0(()),
            timer: ControlTimer(()),
            watchdog: Watchdog(()),
            flash,
            sliders: QemuSliders::new(),
        })
    }
}

/// Reads a register of this board's peripherals (`addr`: one of the register constants
/// of `uart.rs`, `timer.rs` and `watchdog.rs`, the only callers).
fn reg_read(addr: usize) -> u32 {
    // SAFETY: every caller passes one of its `const` register addresses: 32-bit
    // registers of the CMSDK APB UART0, TIMER0 and watchdog (word-aligned device memory
    // at 0x4000_0000..0x4000_9000, no Rust object there); QEMU models each access.
    unsafe { read_volatile(addr as *const u32) }
}

/// Writes a register of this board's peripherals (as [`reg_read`]).
fn reg_write(addr: usize, v: u32) {
    // SAFETY: as in `reg_read`: `addr` is one of the callers' register constants, a
    // 32-bit device register no Rust object aliases; the value is the register's to take.
    unsafe { write_volatile(addr as *mut u32, v) }
}

// ---------------------------------------------------------------------------------
// Reset record, fault handlers, stack guard and paint, test-image exit and markers: the
// Cortex-M core parts both boards share (`super::cortex_m`).

use super::cortex_m::reset_record;
pub use super::cortex_m::{
    bench_end, bench_start, enable_stack_guard, exit, record_and_reset, repaint_stack,
    stack_depth_bytes, stack_peak_bytes, stack_region_bytes, EXIT_FAIL, EXIT_PANIC, EXIT_PASS,
    STACK_BYTES, STACK_GUARD_BYTES,
};
