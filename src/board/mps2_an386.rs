//! QEMU mps2-an386 (Cortex-M4F, FPU on).
//!
//! * process exit through semihosting (QEMU's exit code),
//! * UART0 (CMSDK APB UART at 0x4000_4000, QEMU's first `-serial`) behind
//!   `embedded-hal-nb`'s serial traits,
//! * the parameter-table flash region behind `embedded-storage`'s `NorFlash` (on QEMU
//!   the "flash" is SSRAM, so NOR semantics are enforced in software here),
//! * 1 kHz cycle pacing with SysTick,
//! * stack-peak measurement from cortex-m-rt's painted stack, instruction-count markers.
#![allow(unsafe_code)] // Board glue: MMIO registers, linker symbols, painted RAM.

use core::ptr::{read_volatile, write_volatile};

use embedded_hal_nb::serial::{self, ErrorKind};
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Value cortex-m-rt's `paint-stack` writes over the stack before `main`.
const STACK_PAINT: u32 = 0xCCCC_CCCC;

extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}

/// Bytes of stack used so far: scans the painted region from its low end upwards for the
/// first word that is no longer the paint value.
pub fn stack_peak_bytes() -> u32 {
    let lo = core::ptr::addr_of!(_stack_end) as usize;
    let hi = core::ptr::addr_of!(_stack_start) as usize;
    let mut p = lo;
    // SAFETY: [lo, hi) is the stack region of cortex-m-rt's linker script, plain RAM;
    // aligned volatile word reads inside it are sound.
    while p < hi && unsafe { read_volatile(p as *const u32) } == STACK_PAINT {
        p += 4;
    }
    (hi - p) as u32
}

/// Size of the stack region (bytes) between `_stack_end` and `_stack_start`.
pub fn stack_region_bytes() -> u32 {
    let lo = core::ptr::addr_of!(_stack_end) as usize;
    let hi = core::ptr::addr_of!(_stack_start) as usize;
    (hi - lo) as u32
}

/// Ends the QEMU run with an exit code (0 = pass).
pub fn exit(code: i32) -> ! {
    semihosting::process::exit(code)
}

/// Exit code of a panic: a defect, flight code must not panic.
pub const EXIT_PANIC: i32 = 101;

/// The panic handler of every firmware image of this board: log and end the run with
/// [`EXIT_PANIC`] (on a flight board: the watchdog/safe-mode path).
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    defmt::error!("PANIC");
    exit(EXIT_PANIC)
}

/// Marker for `qemu-insncount`: start of a measured section.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_start() {
    core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
}

/// Marker for `qemu-insncount`: end of a measured section (a different body from
/// `bench_start`, so the linker cannot merge the two).
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_end() {
    core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::Release);
    core::hint::black_box(0u32);
}

// ---------------------------------------------------------------------------------
// UART0: CMSDK APB UART.

/// Base address of UART0 on mps2-an386.
const UART0_BASE: usize = 0x4000_4000;
/// Data register offset (read: received byte, write: byte to send).
const UART_DATA: usize = 0x000;
/// State register offset.
const UART_STATE: usize = 0x004;
/// Control register offset.
const UART_CTRL: usize = 0x008;
/// Baud divider register offset.
const UART_BAUDDIV: usize = 0x010;
/// STATE bit: transmit buffer full.
const STATE_TX_FULL: u32 = 1 << 0;
/// STATE bit: receive buffer full.
const STATE_RX_FULL: u32 = 1 << 1;
/// CTRL bits: transmitter and receiver enable.
const CTRL_TX_RX_EN: u32 = 0b11;
/// Smallest baud divider the CMSDK UART accepts (QEMU ignores the rate itself).
const UART_BAUDDIV_MIN: u32 = 16;

/// The telecommand/telemetry UART (UART0).
pub struct Uart {
    base: usize,
}

impl Uart {
    /// Enables UART0's transmitter and receiver. Call once.
    pub fn uart0() -> Self {
        let u = Self { base: UART0_BASE };
        u.write_reg(UART_BAUDDIV, UART_BAUDDIV_MIN);
        u.write_reg(UART_CTRL, CTRL_TX_RX_EN);
        u
    }

    fn read_reg(&self, off: usize) -> u32 {
        // SAFETY: `base + off` is a CMSDK UART register of this board (MMIO, 32-bit).
        unsafe { read_volatile((self.base + off) as *const u32) }
    }

    fn write_reg(&self, off: usize, v: u32) {
        // SAFETY: as in `read_reg`.
        unsafe { write_volatile((self.base + off) as *mut u32, v) }
    }
}

impl serial::ErrorType for Uart {
    type Error = ErrorKind;
}

impl serial::Read<u8> for Uart {
    fn read(&mut self) -> nb::Result<u8, Self::Error> {
        if self.read_reg(UART_STATE) & STATE_RX_FULL != 0 {
            Ok((self.read_reg(UART_DATA) & 0xFF) as u8)
        } else {
            Err(nb::Error::WouldBlock)
        }
    }
}

impl serial::Write<u8> for Uart {
    fn write(&mut self, byte: u8) -> nb::Result<(), Self::Error> {
        if self.read_reg(UART_STATE) & STATE_TX_FULL != 0 {
            Err(nb::Error::WouldBlock)
        } else {
            self.write_reg(UART_DATA, u32::from(byte));
            Ok(())
        }
    }

    fn flush(&mut self) -> nb::Result<(), Self::Error> {
        if self.read_reg(UART_STATE) & STATE_TX_FULL != 0 {
            Err(nb::Error::WouldBlock)
        } else {
            Ok(())
        }
    }
}

// ---------------------------------------------------------------------------------
// Table flash: the region memory.x reserves (TABLE, top 128 KiB of the 4 MiB flash).

/// Offsets are from the start of the 4 MiB flash, as `table::store` expects.
const FLASH_BASE: usize = 0x0000_0000;
/// Flash size (bytes).
const FLASH_SIZE: u32 = 0x40_0000;
/// First byte the table store may write or erase (start of the TABLE region).
const TABLE_REGION_START: u32 = 0x3E_0000;
/// Erase granularity emulated here (bytes).
const FLASH_ERASE_SIZE: usize = 4096;
/// Erased byte value.
const FLASH_ERASED: u8 = 0xFF;

/// Why a flash operation was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    /// Outside the table region or not aligned.
    OutOfBounds,
    /// Not aligned to the erase or write size.
    NotAligned,
    /// A write tried to set a bit that is 0 (NOR can only clear bits before an erase).
    NotErased,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::NotErased => NorFlashErrorKind::Other,
        }
    }
}

/// The table region as NOR flash.
pub struct TableFlash(());

impl TableFlash {
    /// The board's table flash. Only one instance should exist.
    pub fn take() -> Self {
        TableFlash(())
    }

    fn check(from: u32, len: usize) -> Result<(), FlashError> {
        let end = (from as usize)
            .checked_add(len)
            .ok_or(FlashError::OutOfBounds)?;
        if from < TABLE_REGION_START || end > FLASH_SIZE as usize {
            return Err(FlashError::OutOfBounds);
        }
        Ok(())
    }
}

impl ErrorType for TableFlash {
    type Error = FlashError;
}

impl ReadNorFlash for TableFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        Self::check(offset, bytes.len())?;
        for (i, b) in bytes.iter_mut().enumerate() {
            // SAFETY: bounds checked above: inside the reserved TABLE region.
            *b = unsafe { read_volatile((FLASH_BASE + offset as usize + i) as *const u8) };
        }
        Ok(())
    }
    fn capacity(&self) -> usize {
        FLASH_SIZE as usize
    }
}

impl NorFlash for TableFlash {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = FLASH_ERASE_SIZE;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if from > to || from as usize % FLASH_ERASE_SIZE != 0 || to as usize % FLASH_ERASE_SIZE != 0
        {
            return Err(FlashError::NotAligned);
        }
        Self::check(from, (to - from) as usize)?;
        for a in from..to {
            // SAFETY: bounds checked above.
            unsafe { write_volatile((FLASH_BASE + a as usize) as *mut u8, FLASH_ERASED) };
        }
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        Self::check(offset, bytes.len())?;
        for (i, b) in bytes.iter().enumerate() {
            let p = (FLASH_BASE + offset as usize + i) as *mut u8;
            // SAFETY: bounds checked above.
            let old = unsafe { read_volatile(p) };
            if b & !old != 0 {
                return Err(FlashError::NotErased);
            }
            // SAFETY: as above.
            unsafe { write_volatile(p, old & b) };
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------
// Cycle pacing: SysTick at the control rate.

/// SysTick reload for 1 ms at the 25 MHz core clock QEMU models for mps2 boards.
const SYSTICK_RELOAD_1MS: u32 = 25_000 - 1;

/// Paces the control loop at 1 kHz.
pub struct CycleTimer {
    syst: cortex_m::peripheral::SYST,
}

impl CycleTimer {
    /// Starts SysTick (core clock source, 1 ms period, no interrupt).
    pub fn start(mut syst: cortex_m::peripheral::SYST) -> Self {
        use cortex_m::peripheral::syst::SystClkSource;
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(SYSTICK_RELOAD_1MS);
        syst.clear_current();
        syst.enable_counter();
        Self { syst }
    }

    /// Waits for the next cycle boundary. Returns `true` if the previous cycle overran
    /// (more than one period elapsed since the last call).
    pub fn wait(&mut self) -> bool {
        let overran = self.syst.has_wrapped();
        while !self.syst.has_wrapped() {}
        overran
    }
}
