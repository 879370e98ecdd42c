//! QEMU mps2-an386 (Cortex-M4F, FPU on, 25 MHz system clock).
//!
//! Everything here is a fact of this board, checked against QEMU's model of it
//! (`hw/arm/mps2.c`, `hw/char/cmsdk-apb-uart.c`, `hw/timer/cmsdk-apb-timer.c`,
//! `hw/watchdog/cmsdk-apb-watchdog.c`):
//!
//! * [`device`]: the device description RTIC needs (the board has no PAC): the
//!   interrupt lines with their numbers, `NVIC_PRIO_BITS`, the vector table for
//!   cortex-m-rt's `device` feature (`device.x` names the handlers);
//! * [`Board::take`]: the take-once hardware singletons: UART0, the control timer
//!   (TIMER0), the watchdog, the table flash and the emulated sliders;
//! * UART0 (CMSDK APB UART at 0x4000_4000, QEMU's first `-serial`): interrupt-driven,
//!   RX into a bounded queue (overrun bits and queue overflows counted), TX drained
//!   from a bounded queue by the TX interrupt;
//! * TIMER0 (CMSDK APB timer at 0x4000_0000, IRQ 8): the control rate, reload derived
//!   from [`CONTROL_RATE_HZ`] and [`SYSCLK_HZ`]; overrun detection;
//! * the CMSDK APB watchdog at 0x4000_8000 (its interrupt is the NMI; a second expiry
//!   resets the system): fed only by a completed control cycle;
//! * the watchdog's NMI, which records its cause in the reset record;
//! * the parameter-table flash region behind `embedded-storage`'s `NorFlash` and
//!   [`FlashStatus`] (on QEMU the "flash" is SSRAM: NOR semantics and erase/program
//!   times are modelled here);
//! * re-exported from [`super::cortex_m`]: the reset record in no-init RAM (reset cause,
//!   boot counter), the fault handlers (HardFault, MemManage, unexpected interrupts)
//!   that record their cause and reset, the MPU stack guard, stack painting/peak,
//!   instruction-count markers, semihosting exit (test images).
#![allow(unsafe_code)] // Board glue: MMIO registers, linker symbols, painted RAM.

use core::ptr::{read_volatile, write_volatile};
use core::sync::atomic::{AtomicBool, AtomicU16, AtomicU32, Ordering};

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use heapless::spsc::{Consumer, Producer};

use super::memory_x;
use super::qemu_sliders::QemuSliders;
use crate::hw::{ResetCause, ResetInfo};
use crate::table::{BankLayout, FlashStatus};
use crate::timing::CONTROL_RATE_HZ;

/// System clock of QEMU's mps2 boards (Hz): the core, SysTick, the APB timers, the
/// watchdog and the UART baud generator all run from it.
pub const SYSCLK_HZ: u32 = 25_000_000;

// ---------------------------------------------------------------------------------
// Device description for RTIC.

/// What RTIC's `#[app(device = ...)]` needs: the interrupt lines, their priority bits
/// and the vector table.
pub mod device {
    /// Priority bits of the Cortex-M4 NVIC in the AN386 image (8 levels).
    pub const NVIC_PRIO_BITS: u8 = 3;

    /// The 32 external interrupt lines of mps2-an386 (QEMU: `num-irq` 32), numbered as
    /// `hw/arm/mps2.c` wires them for the AN385/AN386 images. Lines named `IRQn` are
    /// connected to no device QEMU models (GPIO and others); the firmware uses two of
    /// them as software-pended task interrupts.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    #[repr(u16)]
    #[allow(missing_docs, clippy::upper_case_acronyms)]
    pub enum Interrupt {
        /// UART0 receive.
        UARTRX0 = 0,
        /// UART0 transmit.
        UARTTX0 = 1,
        UARTRX1 = 2,
        UARTTX1 = 3,
        UARTRX2 = 4,
        UARTTX2 = 5,
        IRQ6 = 6,
        IRQ7 = 7,
        /// CMSDK APB timer 0 (0x4000_0000): the control rate.
        TIMER0 = 8,
        TIMER1 = 9,
        DUALTIMER = 10,
        SPI = 11,
        /// Overrun of UART0, 1 or 2 (ORed).
        UARTOVF = 12,
        ETHERNET = 13,
        IRQ14 = 14,
        IRQ15 = 15,
        IRQ16 = 16,
        IRQ17 = 17,
        UARTRX3 = 18,
        UARTTX3 = 19,
        UARTRX4 = 20,
        UARTTX4 = 21,
        ADCSPI = 22,
        IRQ23 = 23,
        SHIELDSPI = 24,
        IRQ25 = 25,
        IRQ26 = 26,
        IRQ27 = 27,
        IRQ28 = 28,
        IRQ29 = 29,
        IRQ30 = 30,
        /// Not wired in QEMU: the link service's software-pended interrupt.
        IRQ31 = 31,
    }

    // SAFETY: every variant is a valid IRQ number of this board (0..32).
    unsafe impl cortex_m::interrupt::InterruptNumber for Interrupt {
        fn number(self) -> u16 {
            self as u16
        }
    }

    /// The flight image's interrupts by role (RTIC's `binds =` and `rtic::pend` use
    /// these names; every board maps them onto its lines, and its vector table and
    /// `device.x` name the handlers so).
    #[allow(missing_docs)]
    pub mod interrupt {
        use super::Interrupt;
        /// UART0 receive (IRQ 0).
        pub const UART_RX: Interrupt = Interrupt::UARTRX0;
        /// UART0 transmit (IRQ 1; also pended by the link service).
        pub const UART_TX: Interrupt = Interrupt::UARTTX0;
        /// TIMER0 (IRQ 8): the control rate.
        pub const CONTROL_TIMER: Interrupt = Interrupt::TIMER0;
        /// IRQ 30, not wired in QEMU: software-pended link service pass.
        pub const LINK_SERVICE: Interrupt = Interrupt::IRQ30;
        /// IRQ 31, not wired in QEMU: software-pended worker step.
        pub const WORKER: Interrupt = Interrupt::IRQ31;
    }

    macro_rules! vectors {
        ($($name:ident),* $(,)?) => {
            extern "C" {
                $(fn $name();)*
            }
            /// The device part of the vector table (IRQ 0..31); `device.x` provides
            /// every handler as `DefaultHandler` unless the firmware binds it.
            #[link_section = ".vector_table.interrupts"]
            #[no_mangle]
            #[used]
            pub static __INTERRUPTS: [unsafe extern "C" fn(); 32] = [$($name),*];
        };
    }
    // Lines 0, 1, 8, 30 and 31 under the flight image's names (`interrupt`).
    #[rustfmt::skip]
    vectors!(
        UART_RX, UART_TX, UARTRX1, UARTTX1, UARTRX2, UARTTX2, IRQ6, IRQ7, CONTROL_TIMER, TIMER1,
        DUALTIMER, SPI, UARTOVF, ETHERNET, IRQ14, IRQ15, IRQ16, IRQ17, UARTRX3, UARTTX3, UARTRX4,
        UARTTX4, ADCSPI, IRQ23, SHIELDSPI, IRQ25, IRQ26, IRQ27, IRQ28, IRQ29, LINK_SERVICE,
        WORKER,
    );
}

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

fn reg_read(addr: usize) -> u32 {
    // SAFETY: only called with the addresses of this board's 32-bit MMIO registers.
    unsafe { read_volatile(addr as *const u32) }
}

fn reg_write(addr: usize, v: u32) {
    // SAFETY: as in `reg_read`.
    unsafe { write_volatile(addr as *mut u32, v) }
}

// ---------------------------------------------------------------------------------
// UART0: CMSDK APB UART.

/// Base address of UART0.
const UART0_BASE: usize = 0x4000_4000;
/// Data register (read: received byte, write: byte to send).
const UART_DATA: usize = UART0_BASE;
/// State register: TX full, RX full, TX overrun, RX overrun (the overruns W1C).
const UART_STATE: usize = UART0_BASE + 0x004;
/// Control register.
const UART_CTRL: usize = UART0_BASE + 0x008;
/// Interrupt status (W1C).
const UART_INTSTATUS: usize = UART0_BASE + 0x00C;
/// Baud divider.
const UART_BAUDDIV: usize = UART0_BASE + 0x010;
/// STATE: transmit buffer full.
const STATE_TX_FULL: u32 = 1 << 0;
/// STATE: receive buffer full.
const STATE_RX_FULL: u32 = 1 << 1;
/// STATE: a byte arrived while the receive buffer was full (the old one was lost).
const STATE_RX_OVERRUN: u32 = 1 << 3;
/// CTRL: transmitter, receiver, TX interrupt, RX interrupt enable.
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;
const CTRL_TX_INTEN: u32 = 1 << 2;
const CTRL_RX_INTEN: u32 = 1 << 3;
/// INTSTATUS: TX (a byte left the buffer), RX (a byte arrived).
const INT_TX: u32 = 1 << 0;
const INT_RX: u32 = 1 << 1;
/// The link's baud rate.
pub const UART_BAUD: u32 = 115_200;
/// Baud divider for [`UART_BAUD`] (QEMU forwards bytes as fast as the host takes them;
/// the divider matters on hardware).
const UART_BAUDDIV_VALUE: u32 = SYSCLK_HZ / UART_BAUD;
// The CMSDK UART needs a divider of at least 16.
const _: () = assert!(UART_BAUDDIV_VALUE >= 16);

/// UART0, before it is split.
pub struct Uart0(());

/// Receive side of UART0 (owned by the RX interrupt task).
pub struct UartRx(());
/// Transmit side of UART0 (owned by the TX interrupt task).
pub struct UartTx(());
/// Receive errors of UART0 (owned by the link service).
pub struct UartErrors(());

/// Receive overruns (STATE bit) plus bytes dropped because the RX queue was full.
static UART0_RX_ERRORS: AtomicU16 = AtomicU16::new(0);

impl Uart0 {
    /// Sets the baud rate, enables the transmitter, the receiver and both interrupts
    /// (the NVIC lines are unmasked by RTIC), and splits the UART.
    pub fn split(self) -> (UartRx, UartTx, UartErrors) {
        reg_write(UART_BAUDDIV, UART_BAUDDIV_VALUE);
        reg_write(
            UART_CTRL,
            CTRL_TX_EN | CTRL_RX_EN | CTRL_TX_INTEN | CTRL_RX_INTEN,
        );
        (UartRx(()), UartTx(()), UartErrors(()))
    }
}

impl UartRx {
    /// The RX interrupt: counts a receive overrun, then moves the received byte into
    /// `queue` (counted and dropped if the queue is full). The interrupt flag is
    /// cleared before the data register is read, so a byte arriving meanwhile raises
    /// the interrupt again.
    pub fn on_interrupt<const N: usize>(&mut self, queue: &mut Producer<'_, u8, N>) {
        let mut errors: u16 = 0;
        if reg_read(UART_STATE) & STATE_RX_OVERRUN != 0 {
            reg_write(UART_STATE, STATE_RX_OVERRUN);
            errors += 1;
        }
        reg_write(UART_INTSTATUS, INT_RX);
        if reg_read(UART_STATE) & STATE_RX_FULL != 0 {
            let byte = (reg_read(UART_DATA) & 0xFF) as u8;
            if queue.enqueue(byte).is_err() {
                errors += 1;
            }
        }
        if errors > 0 {
            UART0_RX_ERRORS.fetch_add(errors, Ordering::Relaxed);
        }
    }
}

impl UartTx {
    /// The TX interrupt (also pended by the link service after it queued a frame):
    /// sends the next queued byte if the transmit buffer is free.
    pub fn on_interrupt<const N: usize>(&mut self, queue: &mut Consumer<'_, u8, N>) {
        reg_write(UART_INTSTATUS, INT_TX);
        if reg_read(UART_STATE) & STATE_TX_FULL == 0 {
            if let Some(byte) = queue.dequeue() {
                reg_write(UART_DATA, u32::from(byte));
            }
        }
    }
}

impl UartErrors {
    /// Receive errors since the last call (overruns and RX queue overflows).
    pub fn take_new(&mut self) -> u16 {
        UART0_RX_ERRORS.swap(0, Ordering::Relaxed)
    }
}

// ---------------------------------------------------------------------------------
// Control timer: CMSDK APB timer 0.

const TIMER0_BASE: usize = 0x4000_0000;
const TIMER_CTRL: usize = TIMER0_BASE;
const TIMER_VALUE: usize = TIMER0_BASE + 0x004;
const TIMER_RELOAD: usize = TIMER0_BASE + 0x008;
const TIMER_INTSTATUS: usize = TIMER0_BASE + 0x00C;
/// CTRL: enable, interrupt enable.
const TIMER_CTRL_EN: u32 = 1 << 0;
const TIMER_CTRL_IRQEN: u32 = 1 << 3;
/// Timer reload: the counter runs from RELOAD down to 0 and holds 0 for one clock, so
/// the period is RELOAD + 1 clocks of [`SYSCLK_HZ`].
pub const TIMER_RELOAD_VALUE: u32 = SYSCLK_HZ / CONTROL_RATE_HZ - 1;
// The control period must be a whole number of clocks.
const _: () = assert!(SYSCLK_HZ % CONTROL_RATE_HZ == 0);

/// Control-rate ticks since the timer started (the time base of the flash model and
/// the worker's bank-check period).
static TICKS: AtomicU32 = AtomicU32::new(0);

/// Control-rate ticks counted so far.
pub fn ticks() -> u32 {
    TICKS.load(Ordering::Relaxed)
}

/// TIMER0 at the control rate (owned by the control task).
pub struct ControlTimer(());

impl ControlTimer {
    /// Starts the timer: an interrupt every control period.
    pub fn start(&mut self) {
        reg_write(TIMER_RELOAD, TIMER_RELOAD_VALUE);
        reg_write(TIMER_VALUE, TIMER_RELOAD_VALUE);
        reg_write(TIMER_CTRL, TIMER_CTRL_EN | TIMER_CTRL_IRQEN);
    }

    /// Acknowledges the tick (call first in the control task) and counts it.
    pub fn acknowledge(&mut self) {
        reg_write(TIMER_INTSTATUS, 1);
        TICKS.fetch_add(1, Ordering::Relaxed);
    }

    /// The next tick has already come: the running cycle overran its period.
    pub fn tick_pending(&self) -> bool {
        reg_read(TIMER_INTSTATUS) & 1 != 0
    }
}

// ---------------------------------------------------------------------------------
// Watchdog: CMSDK APB watchdog. First expiry: interrupt (wired to the NMI); second
// expiry with RESEN: system reset. Writes are ignored while it is locked.

const WDOG_BASE: usize = 0x4000_8000;
const WDOG_LOAD: usize = WDOG_BASE;
const WDOG_CONTROL: usize = WDOG_BASE + 0x008;
const WDOG_INTCLR: usize = WDOG_BASE + 0x00C;
const WDOG_LOCK: usize = WDOG_BASE + 0xC00;
/// CONTROL: interrupt (and counter) enable, reset enable.
const WDOG_INTEN: u32 = 1 << 0;
const WDOG_RESEN: u32 = 1 << 1;
/// LOCK: the value that unlocks writes (any other value locks).
const WDOG_UNLOCK: u32 = 0x1ACC_E551;
const WDOG_RELOCK: u32 = 0;
/// Control periods without a completed cycle before the watchdog's NMI (the reset
/// follows one more such interval).
pub const WATCHDOG_TIMEOUT_CYCLES: u32 = 100;
/// Watchdog load value (clocks of [`SYSCLK_HZ`]).
const WDOG_LOAD_VALUE: u32 = SYSCLK_HZ / CONTROL_RATE_HZ * WATCHDOG_TIMEOUT_CYCLES;

/// The watchdog (owned by the control task: only a completed cycle feeds it).
pub struct Watchdog(());

impl Watchdog {
    /// Starts it (interrupt and reset enabled) and locks it.
    pub fn start(&mut self) {
        reg_write(WDOG_LOCK, WDOG_UNLOCK);
        reg_write(WDOG_LOAD, WDOG_LOAD_VALUE);
        reg_write(WDOG_CONTROL, WDOG_INTEN | WDOG_RESEN);
        reg_write(WDOG_LOCK, WDOG_RELOCK);
    }

    /// Reloads the counter.
    pub fn feed(&mut self) {
        reg_write(WDOG_LOCK, WDOG_UNLOCK);
        reg_write(WDOG_INTCLR, 1);
        reg_write(WDOG_LOCK, WDOG_RELOCK);
    }
}

// ---------------------------------------------------------------------------------
// Reset record, fault handlers, stack guard and paint, test-image exit and markers: the
// Cortex-M core parts both boards share (`super::cortex_m`).

use super::cortex_m::reset_record;
pub use super::cortex_m::{
    bench_end, bench_start, enable_stack_guard, exit, record_and_reset, repaint_stack,
    stack_depth_bytes, stack_peak_bytes, stack_region_bytes, EXIT_PANIC, STACK_BYTES,
    STACK_GUARD_BYTES,
};

/// The watchdog's first expiry (no control cycle completed for
/// [`WATCHDOG_TIMEOUT_CYCLES`] periods): record the cause, then wait for the
/// watchdog's own reset one interval later.
#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    reset_record::announce(ResetCause::Watchdog);
    loop {
        cortex_m::asm::nop();
    }
}

// ---------------------------------------------------------------------------------
// Table flash: the TABLE region of `memory.x` (top 128 KiB of the 4 MiB flash).

/// Offsets are from the start of the 4 MiB flash, as `table::store` expects.
const FLASH_BASE: usize = 0x0000_0000;
/// Flash size (bytes).
const FLASH_SIZE: u32 = 0x40_0000;
/// Bank size (bytes): two banks fill the TABLE region.
const TABLE_BANK_SIZE: u32 = 0x1_0000;
/// First byte the table store may write or erase (start of the TABLE region).
const TABLE_REGION_START: u32 = 0x3E_0000;
/// The table banks of this board: A then B in the TABLE region.
pub const TABLE_LAYOUT: BankLayout = BankLayout::two_banks(TABLE_REGION_START, TABLE_BANK_SIZE);
// The layout is exactly memory.x's TABLE region, at the top of the flash.
const _: () = assert!(memory_x::TABLE_ORIGIN == TABLE_REGION_START);
const _: () = assert!(memory_x::TABLE_LENGTH == 2 * TABLE_BANK_SIZE);
const _: () = assert!(TABLE_REGION_START + 2 * TABLE_BANK_SIZE == FLASH_SIZE);
const _: () = assert!(TABLE_LAYOUT.bank_b_offset + TABLE_LAYOUT.bank_size == FLASH_SIZE);
/// Erase granularity emulated here (bytes).
const FLASH_ERASE_SIZE: usize = 4096;
/// Erased byte value.
const FLASH_ERASED: u8 = 0xFF;
/// Modelled sector-erase time (control ticks): 0.3 s, a NOR sector.
pub const FLASH_ERASE_TICKS: u32 = 300;
/// Modelled program time of one write (control ticks).
pub const FLASH_PROGRAM_TICKS: u32 = 1;

/// Why a flash operation was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    /// Outside the table region.
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

/// The table region as NOR flash, busy for the modelled time after each erase or
/// program ([`FlashStatus`]).
pub struct TableFlash {
    busy_until: Option<u32>,
}

impl TableFlash {
    fn check(from: u32, len: usize) -> Result<(), FlashError> {
        let end = (from as usize)
            .checked_add(len)
            .ok_or(FlashError::OutOfBounds)?;
        if from < TABLE_REGION_START || end > FLASH_SIZE as usize {
            return Err(FlashError::OutOfBounds);
        }
        Ok(())
    }

    /// QEMU's SSRAM comes up zeroed, a new NOR flash erased: a TABLE region that reads
    /// all zero (never written: no valid store state is all zero) is erased, so the
    /// store sees blank banks as on a new device. Any other content (written by an
    /// earlier boot: QEMU keeps RAM across a system reset) is kept.
    fn erase_if_never_written(&mut self) {
        let start = FLASH_BASE + TABLE_REGION_START as usize;
        let end = FLASH_BASE + FLASH_SIZE as usize;
        // SAFETY: the TABLE region, plain (emulated) memory, word aligned.
        let zero = (start..end)
            .step_by(4)
            .all(|a| unsafe { read_volatile(a as *const u32) } == 0);
        if zero {
            for a in (start..end).step_by(4) {
                // SAFETY: as above.
                unsafe { write_volatile(a as *mut u32, u32::from_ne_bytes([FLASH_ERASED; 4])) };
            }
        }
    }

    fn start_busy(&mut self, ticks_needed: u32) {
        self.busy_until = Some(ticks().wrapping_add(ticks_needed));
    }
}

impl FlashStatus for TableFlash {
    fn busy(&mut self) -> bool {
        match self.busy_until {
            // Serial comparison: busy while `now` is before the deadline.
            Some(t) if (ticks().wrapping_sub(t) as i32) < 0 => true,
            _ => {
                self.busy_until = None;
                false
            }
        }
    }
}

impl ErrorType for TableFlash {
    type Error = FlashError;
}

impl ReadNorFlash for TableFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        Self::check(offset, bytes.len())?;
        let base = FLASH_BASE + offset as usize;
        for (i, b) in bytes.iter_mut().enumerate() {
            // SAFETY: bounds checked above: inside the reserved TABLE region.
            *b = unsafe { read_volatile((base + i) as *const u8) };
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
        let sectors = (to - from) / FLASH_ERASE_SIZE as u32;
        self.start_busy(FLASH_ERASE_TICKS.saturating_mul(sectors));
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        Self::check(offset, bytes.len())?;
        let base = FLASH_BASE + offset as usize;
        for (i, b) in bytes.iter().enumerate() {
            let p = (base + i) as *mut u8;
            // SAFETY: bounds checked above.
            let old = unsafe { read_volatile(p) };
            if b & !old != 0 {
                return Err(FlashError::NotErased);
            }
            // SAFETY: as above.
            unsafe { write_volatile(p, old & b) };
        }
        self.start_busy(FLASH_PROGRAM_TICKS);
        Ok(())
    }
}
