//! Netduino Plus 2: STM32F405RG (Cortex-M4F, 168 MHz, 1 MiB flash, 128 KiB SRAM; its
//! 64 KiB CCM RAM is unused, QEMU 7.2 lacks it), also QEMU's `netduinoplus2` machine. Feature `board-netduinoplus2`; memory
//! map in `memory/netduinoplus2.x` (selected by build.rs).
//!
//! The same glue items as the mps2-an386 board, so every image builds for either:
//!
//! * [`device`]: what RTIC's `#[app(device = ...)]` needs, from the stm32f4 PAC (its
//!   `Interrupt` lines, `NVIC_PRIO_BITS`, its vector table and `device.x`), and the
//!   flight image's board-independent interrupt names ([`device::interrupt`]) mapped
//!   onto this board's lines (`memory/netduinoplus2.x` aliases the PAC's handler
//!   names to them);
//! * [`Board::take`]: the take-once hardware: the telecommand UART ([`Uart0`], USART1),
//!   the control timer ([`ControlTimer`], TIM3), the independent watchdog
//!   ([`Watchdog`]), the table flash ([`TableFlash`], sectors 8 to 11) and the
//!   mechanism ([`Sliders`]: the drivers of `crate::drivers` wired through
//!   `stm32f4xx-hal`, embedded-hal 1.0): six BiSS-C encoders in one daisy chain on
//!   SPI1, six step/direction drives (step pulses from [`StepEngine`] on TIM2), and the
//!   end-of-travel/reference inputs;
//! * re-exported from [`super::cortex_m`]: the reset record, the fault handlers
//!   (HardFault, MemManage, unexpected interrupts) that record their cause and reset,
//!   the MPU stack guard, stack painting/peak, instruction-count markers and the
//!   semihosting exit (test images).
//!
//! ## Harness (pin map)
//!
//! | signal | pins |
//! |---|---|
//! | USART1 TX / RX (telecommands, QEMU's first `-serial`) | PA9 / PA10 |
//! | BiSS MA (SPI1 SCK) / SL (SPI1 MISO) | PA5 / PA6 |
//! | STEP legs 1..6 | PC0, PC4, PC8, PB0, PB4, PB8 |
//! | DIR legs 1..6 | PC1, PC5, PC9, PB1, PB5, PB9 |
//! | ENABLE (active low) legs 1..6 | PC2, PC6, PC10, PB2, PB6, PB10 |
//! | FAULT (active low, pull-up) legs 1..6 | PC3, PC7, PC11, PB3, PB7, PB11 |
//! | lower end switch (NC, pull-up) legs 1..6 | PA0, PA1, PA2, PA3, PA4, PA8 |
//! | upper end switch (NC, pull-up) legs 1..6 | PA11, PA12, PA15, PB12, PB13, PB14 |
//! | reference sensor (active high) legs 1..6 | PB15, PC12, PC13, PC14, PC15, PD2 |
//!
//! ## Clocks
//!
//! 25 MHz crystal (HSE) -> PLL -> 168 MHz. The crystal is waited for a bounded time
//! ([`HSE_STARTUP_POLLS`]); if it does not start the board runs on the internal 16 MHz
//! oscillator ([`ClockSource::InternalFallback`]).
//!
//! ## QEMU 7.2 `netduinoplus2`
//!
//! QEMU models the core (its clock fixed at [`QEMU_SYSCLK_HZ`]), the USARTs, SPI, TIM2
//! to TIM5 (input clock fixed at [`QEMU_TIMER_CLOCK_HZ`], whatever the RCC says) and
//! the RAMs; the RCC, GPIO, IWDG and the flash interface are unimplemented devices
//! (writes ignored, reads 0). The board recognises it by its RCC reading all zero
//! (impossible on silicon, which runs on the HSI oscillator whose ready flag is set from
//! reset) and then ([`ClockSource::Emulated`]) paces the control timer from QEMU's
//! timer clock and does not start the step engine (there are no drives to step). What
//! follows there: the link works; the encoders answer nothing (no start bit: the
//! controller's encoder fault, safe state); the watchdog never bites; table writes fail
//! their read-back (the flash is ROM there) with a clear error.
//!
//! ## Known limitation on the real board
//!
//! The STM32F405's flash is one bank: while a sector erase (128 KiB, 1 to 2 s, RM0090)
//! runs, every instruction fetch from flash stalls, the control task too, and the
//! watchdog ([`WATCHDOG_TIMEOUT_MS`]) resets the board. Table commits on this board
//! need the erase started from RAM-resident code with the watchdog widened; not done.
#![allow(unsafe_code)] // Board glue: MMIO registers, linker symbols, painted RAM.

use core::cell::RefCell;
use core::ptr::{read_volatile, write_volatile};
use core::sync::atomic::{AtomicBool, AtomicU16, AtomicU32, Ordering};

use cortex_m::interrupt::{self as irq, Mutex};
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use heapless::spsc::{Consumer, Producer};
use stm32f4xx_hal::gpio::{AnyPin, Input, Output, PushPull};
use stm32f4xx_hal::pac::{self, interrupt};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Config as RccConfig, Enable, Rcc, Reset};

use crate::hw::ResetCause;
use stm32f4xx_hal::serial::{self as hal_serial, Serial};
use stm32f4xx_hal::spi::{Mode as SpiMode, Phase, Polarity, Spi};

use super::memory_x;
use crate::drivers::biss::{BissChain, BissConfig, EncoderScale, MaLine};
use crate::drivers::stepper::{
    StepDirDrives, StepPulses, StepperConfig, StepperLeg, StepperPolarity,
};
use crate::drivers::switches::{LegSwitches, SwitchPolarity, TravelSwitchInputs};
use crate::drivers::Mechanism as DriverMechanism;
use crate::hw::ResetInfo;
use crate::kinematics::LEGS;
use crate::table::{BankLayout, FlashStatus};
use crate::timing::CYCLE_US;
use crate::units::US_PER_S;

// ---------------------------------------------------------------------------------
// Device description for RTIC.

/// What RTIC's `#[app(device = ...)]` needs: the PAC's interrupt lines and priority
/// bits, the flight image's interrupt names on this board, and the vector table.
pub mod device {
    pub use stm32f4xx_hal::pac::{Interrupt, NVIC_PRIO_BITS};

    /// The flight image's interrupts by role (RTIC's `binds =` and `rtic::pend` use
    /// these names), on this board's lines. The three software-pended ones are lines of
    /// peripherals this board never enables (CAN2).
    #[allow(missing_docs)]
    pub mod interrupt {
        use super::Interrupt;
        /// USART1 (receive, and the transmitter's TXE, see [`super::super::UartRx`]).
        pub const UART_RX: Interrupt = Interrupt::USART1;
        /// Software-pended by the link service and by `UART_RX`: one TX drain.
        pub const UART_TX: Interrupt = Interrupt::CAN2_TX;
        /// TIM3 update: the control rate.
        pub const CONTROL_TIMER: Interrupt = Interrupt::TIM3;
        /// Software-pended by the control task: the link service pass.
        pub const LINK_SERVICE: Interrupt = Interrupt::CAN2_RX0;
        /// Software-pended by the control task: one worker step.
        pub const WORKER: Interrupt = Interrupt::CAN2_RX1;
    }
}

// ---------------------------------------------------------------------------------
// Clocks.

/// The Netduino Plus 2's crystal (Hz).
pub const HSE_HZ: u32 = 25_000_000;
/// System clock from the PLL (Hz): the STM32F405's maximum.
pub const SYSCLK_HZ: u32 = 168_000_000;
/// Polls of HSERDY before giving up on the crystal (several ms at 16 MHz; crystals
/// start in about 2 ms).
pub const HSE_STARTUP_POLLS: u32 = 200_000;
/// QEMU's netduinoplus2: the core clock (`hw/arm/netduinoplus2.c`, fixed).
pub const QEMU_SYSCLK_HZ: u32 = 168_000_000;
/// QEMU's stm32f405 SoC: the input clock of TIM2..TIM5 (`clock-frequency`, fixed).
pub const QEMU_TIMER_CLOCK_HZ: u32 = 48_000_000;
/// Timer tick of the control and step timers (Hz): 1 us.
const TIMER_TICK_HZ: u32 = 1_000_000;

/// Where the system clock comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockSource {
    /// Crystal and PLL, [`SYSCLK_HZ`].
    CrystalPll,
    /// The crystal did not start: internal 16 MHz RC oscillator.
    InternalFallback,
    /// QEMU (the RCC reads all zero): its fixed clocks.
    Emulated,
}

/// The clock tree as configured, and the input clock of the APB1 timers (Hz).
struct ClockTree {
    rcc: Rcc,
    source: ClockSource,
    timer_clock_hz: u32,
}

/// Configures the clock tree (once, from [`Board::take`]).
fn configure_clocks(rcc: pac::RCC) -> ClockTree {
    if rcc.cr().read().bits() == 0 {
        // QEMU: nothing to configure, and nothing the HAL would compute would be true.
        return ClockTree {
            rcc: rcc.constrain(),
            source: ClockSource::Emulated,
            timer_clock_hz: QEMU_TIMER_CLOCK_HZ,
        };
    }
    rcc.cr().modify(|_, w| w.hseon().set_bit());
    let hse_ready = (0..HSE_STARTUP_POLLS).any(|_| rcc.cr().read().hserdy().bit_is_set());
    let (rcc, source) = if hse_ready {
        // One constant configuration: the HAL's checks of it fold away.
        (
            rcc.freeze(RccConfig::hse(HSE_HZ.Hz()).sysclk(SYSCLK_HZ.Hz())),
            ClockSource::CrystalPll,
        )
    } else {
        // The reset state: HSI, no prescalers, what the HAL's default clocks say.
        rcc.cr().modify(|_, w| w.hseon().clear_bit());
        (rcc.constrain(), ClockSource::InternalFallback)
    };
    let timer_clock_hz = rcc.clocks.timclk1().raw();
    ClockTree {
        rcc,
        source,
        timer_clock_hz,
    }
}

/// Where the clock came from (set by [`Board::take`]; `InternalFallback` before).
static CLOCK_SOURCE: Mutex<core::cell::Cell<ClockSource>> =
    Mutex::new(core::cell::Cell::new(ClockSource::InternalFallback));

/// Where the system clock comes from.
pub fn clock_source() -> ClockSource {
    irq::free(|cs| CLOCK_SOURCE.borrow(cs).get())
}

/// Prescaler register value for a [`TIMER_TICK_HZ`] tick from `timer_clock_hz`.
fn tick_prescaler(timer_clock_hz: u32) -> u16 {
    u16::try_from((timer_clock_hz / TIMER_TICK_HZ).saturating_sub(1)).unwrap_or(u16::MAX)
}

// ---------------------------------------------------------------------------------
// Take-once hardware.

/// The board's hardware, handed out once ([`Board::take`]).
pub struct Board {
    /// Why the board reset, and the boot count (from the no-init reset record).
    pub reset: ResetInfo,
    /// The telecommand UART (split it into RX, TX and its error counter).
    pub uart0: Uart0,
    /// The control-rate timer.
    pub timer: ControlTimer,
    /// The watchdog (not running until started).
    pub watchdog: Watchdog,
    /// The parameter-table flash.
    pub flash: TableFlash,
    /// The mechanism: encoders, drives, switches.
    pub sliders: Sliders,
}

static BOARD_TAKEN: AtomicBool = AtomicBool::new(false);

impl Board {
    /// The hardware, the first time; `None` afterwards or if a part refused its
    /// configuration. Reads the reset record (cause, boot count) and re-arms it;
    /// configures the clocks, pins, UART, SPI and the step engine (its interrupt
    /// unmasked above every task; not started on QEMU).
    pub fn take() -> Option<Board> {
        if BOARD_TAKEN.swap(true, Ordering::SeqCst) {
            return None;
        }
        // SAFETY: the first and only take (BOARD_TAKEN); RTIC is built with
        // `peripherals = false`, so nothing else owns the device peripherals.
        let dp = unsafe { pac::Peripherals::steal() };
        let unannounced = unannounced_reset_cause(&dp.RCC);
        let clocks = configure_clocks(dp.RCC);
        irq::free(|cs| CLOCK_SOURCE.borrow(cs).set(clocks.source));
        let mut rcc = clocks.rcc;
        let gpioa = dp.GPIOA.split(&mut rcc);
        let gpiob = dp.GPIOB.split(&mut rcc);
        let gpioc = dp.GPIOC.split(&mut rcc);
        let gpiod = dp.GPIOD.split(&mut rcc);

        // Pins, clock, baud rate and frame; from here on the USART is driven by its
        // registers (the interrupt-driven halves of `Uart0::split`).
        Serial::<pac::USART1, u8>::new(
            dp.USART1,
            (gpioa.pa9, gpioa.pa10),
            hal_serial::Config::default().baudrate(UART_BAUD.bps()),
            &mut rcc,
        )
        .ok()?;

        let spi = Spi::new(
            dp.SPI1,
            (Some(gpioa.pa5), Some(gpioa.pa6), pac::SPI1::NoMosi),
            SpiMode {
                polarity: Polarity::IdleHigh,
                phase: Phase::CaptureOnFirstTransition,
            },
            BISS_CLOCK_HZ.Hz(),
            &mut rcc,
        );
        let scales = ENCODER_ZERO_LSB.map(|zero_lsb| EncoderScale {
            lsb_pm: ENCODER_LSB_PM,
            zero_lsb,
            reversed: false,
        });
        let encoders = BissChain::new(MaLine(spi), BISS, scales).ok()?;

        let step = [
            gpioc.pc0.into_push_pull_output().erase(),
            gpioc.pc4.into_push_pull_output().erase(),
            gpioc.pc8.into_push_pull_output().erase(),
            gpiob.pb0.into_push_pull_output().erase(),
            gpiob.pb4.into_push_pull_output().erase(),
            gpiob.pb8.into_push_pull_output().erase(),
        ];
        // One leg per line: its step channel, DIR, ENABLE, FAULT (the pin map above).
        let leg = |leg: usize, dir: OutPin, enable: OutPin, fault: InPin| StepperLeg {
            pulses: StepChannel { leg },
            dir,
            enable,
            fault,
        };
        let legs = [
            leg(
                0,
                gpioc.pc1.into_push_pull_output().erase(),
                gpioc.pc2.into_push_pull_output().erase(),
                gpioc.pc3.into_pull_up_input().erase(),
            ),
            leg(
                1,
                gpioc.pc5.into_push_pull_output().erase(),
                gpioc.pc6.into_push_pull_output().erase(),
                gpioc.pc7.into_pull_up_input().erase(),
            ),
            leg(
                2,
                gpioc.pc9.into_push_pull_output().erase(),
                gpioc.pc10.into_push_pull_output().erase(),
                gpioc.pc11.into_pull_up_input().erase(),
            ),
            leg(
                3,
                gpiob.pb1.into_push_pull_output().erase(),
                gpiob.pb2.into_push_pull_output().erase(),
                gpiob.pb3.into_pull_up_input().erase(),
            ),
            leg(
                4,
                gpiob.pb5.into_push_pull_output().erase(),
                gpiob.pb6.into_push_pull_output().erase(),
                gpiob.pb7.into_pull_up_input().erase(),
            ),
            leg(
                5,
                gpiob.pb9.into_push_pull_output().erase(),
                gpiob.pb10.into_push_pull_output().erase(),
                gpiob.pb11.into_pull_up_input().erase(),
            ),
        ];
        let drives = StepDirDrives::new(legs, STEPPERS).ok()?;

        // One leg per line: lower and upper end switch (pull-up), reference (pull-down).
        let sw = |lower: InPin, upper: InPin, reference: InPin| LegSwitches {
            lower,
            upper,
            reference,
        };
        let sw_legs = [
            sw(
                gpioa.pa0.into_pull_up_input().erase(),
                gpioa.pa11.into_pull_up_input().erase(),
                gpiob.pb15.into_pull_down_input().erase(),
            ),
            sw(
                gpioa.pa1.into_pull_up_input().erase(),
                gpioa.pa12.into_pull_up_input().erase(),
                gpioc.pc12.into_pull_down_input().erase(),
            ),
            sw(
                gpioa.pa2.into_pull_up_input().erase(),
                gpioa.pa15.into_pull_up_input().erase(),
                gpioc.pc13.into_pull_down_input().erase(),
            ),
            sw(
                gpioa.pa3.into_pull_up_input().erase(),
                gpiob.pb12.into_pull_up_input().erase(),
                gpioc.pc14.into_pull_down_input().erase(),
            ),
            sw(
                gpioa.pa4.into_pull_up_input().erase(),
                gpiob.pb13.into_pull_up_input().erase(),
                gpioc.pc15.into_pull_down_input().erase(),
            ),
            sw(
                gpioa.pa8.into_pull_up_input().erase(),
                gpiob.pb14.into_pull_up_input().erase(),
                gpiod.pd2.into_pull_down_input().erase(),
            ),
        ];
        let switches = TravelSwitchInputs::new(sw_legs, SWITCHES);

        pac::TIM3::enable(&mut rcc);
        pac::TIM3::reset(&mut rcc);
        pac::TIM2::enable(&mut rcc);
        pac::TIM2::reset(&mut rcc);
        StepEngine::install(dp.TIM2, step, clocks.source, clocks.timer_clock_hz);

        Some(Board {
            reset: reset_record::on_boot(unannounced),
            uart0: Uart0(()),
            timer: ControlTimer {
                tim: dp.TIM3,
                prescaler: tick_prescaler(clocks.timer_clock_hz),
            },
            watchdog: Watchdog(dp.IWDG),
            flash: TableFlash(dp.FLASH),
            sliders: DriverMechanism {
                encoders,
                drives,
                switches,
            },
        })
    }
}

// ---------------------------------------------------------------------------------
// UART: USART1 (PA9 TX, PA10 RX), QEMU's first `-serial`. One interrupt line for both
// directions: the receive task owns it (highest task priority); it hands the
// transmitter's TXE to the lower-priority software line UART_TX, as the mps2 board's
// separate TX interrupt would.

/// Telecommand/telemetry line rate (bit/s).
pub const UART_BAUD: u32 = 115_200;
/// Bytes one TX drain writes at most while the transmitter is free (QEMU's is always
/// free; on silicon one or two bytes go before TXE drops), then it pends itself again.
const TX_BYTES_PER_DRAIN: usize = 64;

fn usart1() -> &'static pac::usart1::RegisterBlock {
    // SAFETY: USART1's register block, used only by the UART halves below (one owner
    // per register: RX reads SR/DR, TX writes DR; CR1's TXEIE under a critical section).
    unsafe { &*pac::USART1::ptr() }
}

/// The telecommand UART, before it is split.
pub struct Uart0(());

/// Receive side (owned by the RX interrupt task).
pub struct UartRx(());
/// Transmit side (owned by the TX interrupt task).
pub struct UartTx(());
/// Receive errors (owned by the link service).
pub struct UartErrors(());

/// Receive overruns plus bytes dropped because the RX queue was full.
static UART_RX_ERRORS: AtomicU16 = AtomicU16::new(0);

impl Uart0 {
    /// Enables the receive interrupt (the NVIC lines are unmasked by RTIC) and splits
    /// the UART (baud rate, frame and pins were set by [`Board::take`]).
    pub fn split(self) -> (UartRx, UartTx, UartErrors) {
        usart1().cr1().modify(|_, w| w.rxneie().set_bit());
        (UartRx(()), UartTx(()), UartErrors(()))
    }
}

fn set_txeie(on: bool) {
    irq::free(|_| usart1().cr1().modify(|_, w| w.txeie().bit(on)));
}

impl UartRx {
    /// The USART1 interrupt: counts an overrun, moves the received byte into `queue`
    /// (counted and dropped if the queue is full); a TXE the transmitter asked for
    /// (TXEIE) is masked again and handed to the TX task.
    pub fn on_interrupt<const N: usize>(&mut self, queue: &mut Producer<'_, u8, N>) {
        let u = usart1();
        let sr = u.sr().read();
        let mut errors: u16 = 0;
        if sr.ore().bit_is_set() {
            errors += 1;
        }
        if sr.rxne().bit_is_set() || sr.ore().bit_is_set() {
            // Reading DR after SR clears RXNE and ORE.
            let byte = (u.dr().read().bits() & 0xFF) as u8;
            if sr.rxne().bit_is_set() && queue.enqueue(byte).is_err() {
                errors += 1;
            }
        }
        if errors > 0 {
            UART_RX_ERRORS.fetch_add(errors, Ordering::Relaxed);
        }
        if sr.txe().bit_is_set() && u.cr1().read().txeie().bit_is_set() {
            set_txeie(false);
            cortex_m::peripheral::NVIC::pend(device::interrupt::UART_TX);
        }
    }
}

impl UartTx {
    /// The TX task (pended by the link service after it queued a frame, and by the
    /// receive interrupt on TXE): writes queued bytes while the transmitter is free,
    /// then asks for TXE again if bytes remain.
    pub fn on_interrupt<const N: usize>(&mut self, queue: &mut Consumer<'_, u8, N>) {
        let u = usart1();
        for _ in 0..TX_BYTES_PER_DRAIN {
            if u.sr().read().txe().bit_is_clear() {
                // The transmitter is busy: its TXE interrupt brings the next drain.
                if queue.ready() {
                    set_txeie(true);
                }
                return;
            }
            let Some(byte) = queue.dequeue() else {
                return;
            };
            u.dr().write(|w| unsafe { w.bits(u16::from(byte)) });
        }
        // Budget spent with the transmitter still free (QEMU's always is): drain again
        // after the tasks above have had their turn.
        if queue.ready() {
            cortex_m::peripheral::NVIC::pend(device::interrupt::UART_TX);
        }
    }
}

impl UartErrors {
    /// Receive errors since the last call (overruns and RX queue overflows).
    pub fn take_new(&mut self) -> u16 {
        UART_RX_ERRORS.swap(0, Ordering::Relaxed)
    }
}

// ---------------------------------------------------------------------------------
// Control timer: TIM3 update at the control rate, 1 us ticks.

/// Control-rate ticks since the timer started (the worker's time base).
static TICKS: AtomicU32 = AtomicU32::new(0);

/// Control-rate ticks counted so far.
pub fn ticks() -> u32 {
    TICKS.load(Ordering::Relaxed)
}

/// TIM3 at the control rate (owned by the control task).
pub struct ControlTimer {
    tim: pac::TIM3,
    prescaler: u16,
}

/// Auto-reload value: one control period of 1 us ticks.
const CONTROL_TIMER_ARR: u32 = CYCLE_US - 1;
const _: () = assert!(US_PER_S == TIMER_TICK_HZ);

impl ControlTimer {
    /// Starts the timer: an update interrupt every control period.
    pub fn start(&mut self) {
        let t = &self.tim;
        t.psc().write(|w| w.psc().set(self.prescaler));
        t.arr().write(|w| unsafe { w.bits(CONTROL_TIMER_ARR) });
        // Load the prescaler now (update event), then clear the flag it sets.
        t.egr().write(|w| w.ug().set_bit());
        t.sr().write(|w| unsafe { w.bits(0) });
        t.dier().write(|w| w.uie().set_bit());
        t.cr1().write(|w| w.cen().set_bit());
    }

    /// Acknowledges the tick (call first in the control task) and counts it.
    pub fn acknowledge(&mut self) {
        self.tim.sr().write(|w| unsafe { w.bits(0) });
        TICKS.fetch_add(1, Ordering::Relaxed);
    }

    /// The next tick has already come: the running cycle overran its period.
    pub fn tick_pending(&self) -> bool {
        self.tim.sr().read().uif().bit_is_set()
    }
}

// ---------------------------------------------------------------------------------
// Watchdog: the independent watchdog (LSI, ~32 kHz), fed only by a completed control
// cycle. It has no early-warning interrupt: its reset is recognised at the next boot
// (a valid reset record without an announced cause).

/// Watchdog timeout (ms): ten control periods.
pub const WATCHDOG_TIMEOUT_MS: u32 = 10;
/// LSI frequency (Hz, nominal; 17 to 47 kHz over temperature, RM0090).
const LSI_HZ: u32 = 32_000;
/// Prescaler register value 0: LSI / 4.
const IWDG_PR_DIV4: u8 = 0;
const IWDG_DIV: u32 = 4;
/// Reload value for [`WATCHDOG_TIMEOUT_MS`].
const IWDG_RELOAD: u16 = (LSI_HZ / IWDG_DIV * WATCHDOG_TIMEOUT_MS / 1000) as u16;
const _: () = assert!(IWDG_RELOAD > 0 && IWDG_RELOAD <= 0x0FFF);
/// Key register values (RM0090 21.4.1).
const IWDG_KEY_ACCESS: u16 = 0x5555;
const IWDG_KEY_RELOAD: u16 = 0xAAAA;
const IWDG_KEY_START: u16 = 0xCCCC;

/// The cause of a reset software did not announce, from RCC_CSR (RM0090 7.3.21): the
/// independent watchdog's flag, else an external reset (the NRST pin, a debugger;
/// QEMU's netduinoplus2 models neither the flags nor the watchdog, so there every
/// unannounced reset is external). Clears the flags for the next boot.
fn unannounced_reset_cause(rcc: &pac::RCC) -> ResetCause {
    let watchdog = rcc.csr().read().wdgrstf().bit_is_set();
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    if watchdog {
        ResetCause::Watchdog
    } else {
        ResetCause::External
    }
}

/// The watchdog (owned by the control task: only a completed cycle feeds it).
pub struct Watchdog(pac::IWDG);

impl Watchdog {
    /// Starts it (it cannot be stopped again but by a reset).
    pub fn start(&mut self) {
        let w = &self.0;
        w.kr().write(|k| unsafe { k.key().bits(IWDG_KEY_ACCESS) });
        w.pr().write(|p| unsafe { p.pr().bits(IWDG_PR_DIV4) });
        w.rlr().write(|r| unsafe { r.rl().bits(IWDG_RELOAD) });
        w.kr().write(|k| unsafe { k.key().bits(IWDG_KEY_RELOAD) });
        w.kr().write(|k| unsafe { k.key().bits(IWDG_KEY_START) });
    }

    /// Reloads the counter.
    pub fn feed(&mut self) {
        self.0
            .kr()
            .write(|k| unsafe { k.key().bits(IWDG_KEY_RELOAD) });
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

// ---------------------------------------------------------------------------------
// Table flash: sectors 8 to 11 (128 KiB each, 0x0808_0000..0x0810_0000), the TABLE
// region of memory/netduinoplus2.x. Four sectors because the store erases four ranges
// separately (two records, two selection slots): bank A = sectors 8 (record) and 9
// (selection slot), bank B = sectors 10 and 11. Offsets are from the flash start.
// Driven by its registers (RM0090 3.6): an erase or program is started and
// [`FlashStatus::busy`] reads BSY.

/// Memory-mapped start of the flash.
const FLASH_BASE: usize = 0x0800_0000;
/// Flash size (bytes).
const FLASH_SIZE: u32 = 0x10_0000;
/// Sector size in the TABLE region (bytes).
const TABLE_SECTOR_BYTES: u32 = 0x2_0000;
/// First sector of the TABLE region, and its offset.
const TABLE_FIRST_SECTOR: u32 = 8;
const TABLE_REGION_START: u32 = 0x8_0000;
/// The 128 KiB sectors 5..=11 start at `(n - SECTOR_NUMBER_OFFSET) * 128 KiB` (sectors
/// 0..=4 fill the first 128 KiB).
const SECTOR_NUMBER_OFFSET: u32 = 4;
/// Bank size (bytes): a record sector and a selection sector.
const TABLE_BANK_SIZE: u32 = 2 * TABLE_SECTOR_BYTES;
/// The table banks of this board.
pub const TABLE_LAYOUT: BankLayout = BankLayout::two_banks(TABLE_REGION_START, TABLE_BANK_SIZE);
const _: () = assert!(memory_x::TABLE_ORIGIN as usize == FLASH_BASE + TABLE_REGION_START as usize);
const _: () = assert!(memory_x::TABLE_LENGTH == 2 * TABLE_BANK_SIZE);
const _: () = assert!(TABLE_REGION_START + 2 * TABLE_BANK_SIZE == FLASH_SIZE);
const _: () =
    assert!(TABLE_REGION_START == (TABLE_FIRST_SECTOR - SECTOR_NUMBER_OFFSET) * TABLE_SECTOR_BYTES);
/// Erased byte value.
const FLASH_ERASED: u8 = 0xFF;
/// Unlock keys (RM0090 3.5.1).
const FLASH_KEY1: u32 = 0x4567_0123;
const FLASH_KEY2: u32 = 0xCDEF_89AB;
/// SR error flags: programming sequence, parallelism, alignment, write protection,
/// operation (RM0090 3.9.4); write 1 to clear.
const FLASH_SR_ERRORS: u32 = (1 << 7) | (1 << 6) | (1 << 5) | (1 << 4) | (1 << 1);

/// Why a flash operation was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    /// Outside the table region.
    OutOfBounds,
    /// An erase not covering whole sectors.
    NotAligned,
    /// A write tried to set a bit that is 0 (NOR can only clear bits before an erase).
    NotErased,
    /// The flash interface reported an error (sequence, protection, alignment).
    Device,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::NotErased | FlashError::Device => NorFlashErrorKind::Other,
        }
    }
}

/// The TABLE region as NOR flash.
pub struct TableFlash(pac::FLASH);

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

    fn bsy(&self) -> bool {
        self.0.sr().read().bsy().bit_is_set()
    }

    /// Waits for the operation under way, unlocks, and reports (and clears) the error
    /// flags of the last operation.
    fn ready(&mut self) -> Result<(), FlashError> {
        while self.bsy() {}
        let f = &self.0;
        if f.cr().read().lock().bit_is_set() {
            f.keyr().write(|w| unsafe { w.key().bits(FLASH_KEY1) });
            f.keyr().write(|w| unsafe { w.key().bits(FLASH_KEY2) });
        }
        let errors = f.sr().read().bits() & FLASH_SR_ERRORS;
        if errors != 0 {
            f.sr().write(|w| unsafe { w.bits(errors) });
            return Err(FlashError::Device);
        }
        Ok(())
    }
}

impl FlashStatus for TableFlash {
    fn busy(&mut self) -> bool {
        self.bsy()
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
            // SAFETY: bounds checked above: inside the TABLE region, memory-mapped flash.
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
    const ERASE_SIZE: usize = TABLE_SECTOR_BYTES as usize;
    /// Starts the erase of each sector in `[from, to)` (waiting for the previous one):
    /// returns while the last one runs ([`FlashStatus::busy`]).
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if from > to || from % TABLE_SECTOR_BYTES != 0 || to % TABLE_SECTOR_BYTES != 0 {
            return Err(FlashError::NotAligned);
        }
        Self::check(from, (to - from) as usize)?;
        for index in (from / TABLE_SECTOR_BYTES)..(to / TABLE_SECTOR_BYTES) {
            let sector = index + SECTOR_NUMBER_OFFSET;
            self.ready()?;
            // x32 parallelism (2.7 to 3.6 V supply), sector erase, sector number, start.
            self.0.cr().write(|w| unsafe {
                w.psize().bits(0b10);
                w.ser().set_bit();
                w.snb().bits(sector as u8);
                w.strt().set_bit()
            });
        }
        Ok(())
    }
    /// Programs byte by byte (x8), waiting for each; bits can only be cleared.
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        Self::check(offset, bytes.len())?;
        let base = FLASH_BASE + offset as usize;
        for (i, b) in bytes.iter().enumerate() {
            // SAFETY: bounds checked above.
            let old = unsafe { read_volatile((base + i) as *const u8) };
            if b & !old != 0 {
                return Err(FlashError::NotErased);
            }
        }
        self.ready()?;
        self.0.cr().write(|w| unsafe {
            w.psize().bits(0b00);
            w.pg().set_bit()
        });
        let mut result = Ok(());
        for (i, b) in bytes.iter().enumerate() {
            if *b == FLASH_ERASED {
                continue;
            }
            // SAFETY: inside the TABLE region (checked), PG set: a program operation.
            unsafe { write_volatile((base + i) as *mut u8, *b) };
            while self.bsy() {}
            if self.0.sr().read().bits() & FLASH_SR_ERRORS != 0 {
                result = Err(FlashError::Device);
                break;
            }
        }
        self.0.cr().write(|w| w.pg().clear_bit());
        result
    }
}

// ---------------------------------------------------------------------------------
// Step pulses: one TIM2 update interrupt drives the six STEP pins.

/// Step engine tick (Hz): a pulse is high for one tick and low for at least one.
pub const STEP_TICK_HZ: u32 = 100_000;
/// Ticks per control cycle.
const TICKS_PER_CYCLE: u32 = STEP_TICK_HZ / (US_PER_S / CYCLE_US);
const _: () = assert!(STEP_TICK_HZ % (US_PER_S / CYCLE_US) == 0);
/// Most pulses per leg and cycle: two ticks each, after one direction set-up tick.
pub const MAX_PULSES_PER_CYCLE: u32 = (TICKS_PER_CYCLE - 1) / 2;

/// Pulses requested and not yet sent, per leg (control task -> interrupt).
static PENDING: [AtomicU32; LEGS] = [const { AtomicU32::new(0) }; LEGS];
/// Length of each leg's current train (for spreading it over the cycle).
static TRAIN: [AtomicU32; LEGS] = [const { AtomicU32::new(0) }; LEGS];
/// Incremented by every start: the interrupt waits one tick after a new train (the
/// direction pin's set-up time, 10 us, far above a drive's few hundred ns).
static GENERATION: [AtomicU32; LEGS] = [const { AtomicU32::new(0) }; LEGS];

/// One leg's step-pulse generator ([`StepPulses`]): a handle on the [`StepEngine`].
pub struct StepChannel {
    leg: usize,
}

/// Why a train was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepError {
    /// More pulses than fit in one cycle ([`MAX_PULSES_PER_CYCLE`]).
    TooMany,
}

impl StepPulses for StepChannel {
    type Error = StepError;
    fn start(&mut self, count: u32) -> Result<(), StepError> {
        if count > MAX_PULSES_PER_CYCLE {
            return Err(StepError::TooMany);
        }
        let (Some(g), Some(t), Some(p)) = (
            GENERATION.get(self.leg),
            TRAIN.get(self.leg),
            PENDING.get(self.leg),
        ) else {
            return Err(StepError::TooMany);
        };
        // Generation first, pending last: the interrupt never sends a pulse of the new
        // train in the tick it first sees it.
        g.fetch_add(1, Ordering::AcqRel);
        t.store(count, Ordering::Release);
        p.store(count, Ordering::Release);
        Ok(())
    }
    fn stop(&mut self) -> u32 {
        PENDING
            .get(self.leg)
            .map_or(0, |p| p.swap(0, Ordering::AcqRel))
    }
}

/// The interrupt side of the step pulses: owns TIM2 and the six STEP pins. Installed
/// by [`Board::take`] in [`STEP_ENGINE`]; TIM2's interrupt runs [`StepEngine::on_tick`]
/// at the highest priority, above every RTIC task (it shares nothing with them but
/// the atomics above), and outside RTIC.
pub struct StepEngine {
    tim: pac::TIM2,
    step: [OutPin; LEGS],
    high: [bool; LEGS],
    seen: [u32; LEGS],
    acc: [u32; LEGS],
}

/// The step engine, owned by TIM2's interrupt once installed.
static STEP_ENGINE: Mutex<RefCell<Option<StepEngine>>> = Mutex::new(RefCell::new(None));

/// TIM2's interrupt: one step-engine tick.
#[interrupt]
fn TIM2() {
    irq::free(|cs| {
        if let Ok(mut e) = STEP_ENGINE.borrow(cs).try_borrow_mut() {
            if let Some(e) = e.as_mut() {
                e.on_tick();
            }
        }
    });
}

/// NVIC priority of the step timer: 0, the highest (RTIC's tasks use 1..=4, mapped
/// to lower urgencies; BASEPRI never masks priority 0).
const STEP_TIMER_NVIC_PRIORITY: u8 = 0;

impl StepEngine {
    /// Sets TIM2 to [`STEP_TICK_HZ`], hands the engine to its interrupt and unmasks it
    /// (on QEMU the timer is left stopped: no drives to step, and a 100 kHz interrupt
    /// would only load the emulator).
    fn install(tim: pac::TIM2, step: [OutPin; LEGS], source: ClockSource, timer_clock_hz: u32) {
        tim.psc()
            .write(|w| w.psc().set(tick_prescaler(timer_clock_hz)));
        tim.arr()
            .write(|w| unsafe { w.bits(TIMER_TICK_HZ / STEP_TICK_HZ - 1) });
        tim.egr().write(|w| w.ug().set_bit());
        tim.sr().write(|w| unsafe { w.bits(0) });
        tim.dier().write(|w| w.uie().set_bit());
        let run = source != ClockSource::Emulated;
        if run {
            tim.cr1().write(|w| w.cen().set_bit());
        }
        let engine = StepEngine {
            tim,
            step,
            high: [false; LEGS],
            seen: [0; LEGS],
            acc: [0; LEGS],
        };
        irq::free(|cs| {
            if let Ok(mut slot) = STEP_ENGINE.borrow(cs).try_borrow_mut() {
                *slot = Some(engine);
            }
        });
        if run {
            // SAFETY: the engine is installed; its handler touches only the engine and
            // the atomics, so unmasking it breaks no RTIC critical section.
            unsafe {
                let mut nvic = cortex_m::Peripherals::steal().NVIC;
                nvic.set_priority(pac::Interrupt::TIM2, STEP_TIMER_NVIC_PRIORITY);
                cortex_m::peripheral::NVIC::unmask(pac::Interrupt::TIM2);
            }
        }
    }

    /// One tick: ends pulses that are high, then starts the pulses due (each leg's train
    /// spread evenly over [`MAX_PULSES_PER_CYCLE`] opportunities).
    pub fn on_tick(&mut self) {
        self.tim.sr().write(|w| unsafe { w.bits(0) });
        for (i, pin) in self.step.iter_mut().enumerate() {
            let (Some(high), Some(seen), Some(acc)) = (
                self.high.get_mut(i),
                self.seen.get_mut(i),
                self.acc.get_mut(i),
            ) else {
                continue;
            };
            if *high {
                pin.set_low();
                *high = false;
                continue;
            }
            let (Some(g), Some(t), Some(p)) = (GENERATION.get(i), TRAIN.get(i), PENDING.get(i))
            else {
                continue;
            };
            let generation = g.load(Ordering::Acquire);
            if generation != *seen {
                *seen = generation;
                *acc = 0;
                continue; // direction set-up tick
            }
            *acc += t.load(Ordering::Acquire);
            if *acc < MAX_PULSES_PER_CYCLE {
                continue;
            }
            *acc -= MAX_PULSES_PER_CYCLE;
            if p.fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| n.checked_sub(1))
                .is_ok()
            {
                pin.set_high();
                *high = true;
            }
        }
    }
}

// ---------------------------------------------------------------------------------
// The mechanism.

/// BiSS clock (Hz) requested from SPI1 (84 MHz APB2 / 32 = 2.6 MHz).
pub const BISS_CLOCK_HZ: u32 = 2_625_000;
/// The encoders' frame: 32-bit position words (RESOLUTE linear, 1 nm), Start bit
/// accepted from bit 2 (two samples before the Ack, SPI mode 2) to bit 10.
pub const BISS: BissConfig = BissConfig {
    position_bits: 32,
    start_bit_first: 2,
    start_bit_last: 10,
};
/// Encoder step (pm): 1 nm.
pub const ENCODER_LSB_PM: u32 = 1_000;
/// Raw encoder position at zero stroke, per leg. Installation values (mid-scale until
/// the mechanism's are measured); the parameter table has no field for them yet.
pub const ENCODER_ZERO_LSB: [u64; LEGS] = [1 << 31; LEGS];
/// The drives: 1 mm lead screw, 200-step motors, 16 microsteps, direct drive
/// (3,200 microsteps per mm), at most [`MAX_PULSES_PER_CYCLE`] per cycle (15 mm/s),
/// clamped beyond 6 mm; DRV8825-style pins (ENABLE and FAULT active low).
pub const STEPPERS: StepperConfig = StepperConfig {
    lead_screw_pitch_nm: 1_000_000,
    full_steps_per_rev: 200,
    microsteps_per_step: 16,
    gear_motor_revs: 1,
    gear_screw_revs: 1,
    max_microsteps_per_cycle: MAX_PULSES_PER_CYCLE,
    travel_limit_nm: 6_000_000,
    polarity: StepperPolarity {
        dir_high_is_positive: true,
        enable_active_high: false,
        fault_active_high: false,
    },
};
/// Normally-closed end switches to ground with pull-ups (open = high = active);
/// reference sensors active high.
pub const SWITCHES: SwitchPolarity = SwitchPolarity {
    end_active_high: true,
    reference_active_high: true,
};

/// The BiSS daisy chain on SPI1.
pub type Encoders = BissChain<MaLine<Spi<pac::SPI1>>>;
/// The six step/direction drives.
pub type Drives =
    StepDirDrives<StepChannel, AnyPin<Output<PushPull>>, AnyPin<Output<PushPull>>, AnyPin<Input>>;
/// The eighteen switch inputs.
pub type Switches = TravelSwitchInputs<AnyPin<Input>>;
/// Encoders, drives and switches behind the `hw` traits: what the controller drives on
/// this board.
pub type Sliders = DriverMechanism<Encoders, Drives, Switches>;
/// An output pin of the harness.
type OutPin = AnyPin<Output<PushPull>>;
/// An input pin of the harness.
type InPin = AnyPin<Input>;
