//! Netduino Plus 2: STM32F405RG (Cortex-M4F, 168 MHz, 1 MiB flash, 128 KiB SRAM; its
//! 64 KiB CCM RAM is unused, QEMU 7.2 lacks it), also QEMU's `netduinoplus2` machine.
//! Feature `board-netduinoplus2`; memory map in `memory/netduinoplus2.x` (selected by
//! build.rs).
//!
//! The same glue items as the mps2-an386 board, so every image builds for either; this
//! file holds the [`Board`], its take-once [`Board::take`] that wires the pins of the
//! harness (the pin map below), and one file per peripheral, each re-exported here:
//!
//! * `device.rs`, [`device`]: what RTIC's `#[app(device = ...)]` needs, from the
//!   stm32f4 PAC (its `Interrupt` lines, `NVIC_PRIO_BITS`, its vector table and
//!   `device.x`), and the flight image's board-independent interrupt names
//!   ([`device::interrupt`]) mapped onto this board's lines (`memory/netduinoplus2.x`
//!   aliases the PAC's handler names to them);
//! * `clocks.rs`: the clock tree (crystal and PLL, the internal fallback, QEMU's fixed
//!   clocks: [`ClockSource`]);
//! * `uart.rs`: the telecommand UART ([`Uart0`], USART1), interrupt-driven;
//! * `timer.rs`: the control timer ([`ControlTimer`], TIM3);
//! * `watchdog.rs`: the independent watchdog ([`Watchdog`]) and the cause of a reset
//!   software did not announce (RCC_CSR);
//! * `flash.rs`: the table flash ([`TableFlash`], sectors 8 to 11);
//! * `step_engine.rs`: the step pulses ([`StepEngine`] on TIM2, [`StepChannel`] per
//!   leg);
//! * `mechanism.rs`: the mechanism's configuration and types ([`Sliders`]: the drivers
//!   of `crate::drivers` wired through `stm32f4xx-hal`, embedded-hal 1.0): six BiSS-C
//!   encoders in one daisy chain on SPI1, six step/direction drives, and the
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
//! | camera "exposing" line (active high, pull-down: unconnected is not exposing) | PA7 |
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
#![allow(unsafe_code)] // The device peripherals, taken once.

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m::interrupt as irq;
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Enable, Reset};
use stm32f4xx_hal::serial::{self as hal_serial, Serial};
use stm32f4xx_hal::spi::{Mode as SpiMode, Phase, Polarity, Spi};

use crate::drivers::biss::{BissChain, EncoderScale, MaLine};
use crate::drivers::exposure::ExposureLine;
use crate::drivers::stepper::{StepDirDrives, StepperLeg};
use crate::drivers::switches::{LegSwitches, TravelSwitchInputs};
use crate::drivers::Mechanism as DriverMechanism;
use crate::hw::ResetInfo;

pub mod device;

mod clocks;
mod flash;
mod mechanism;
mod step_engine;
mod timer;
mod uart;
mod watchdog;

use clocks::{configure_clocks, tick_prescaler, CLOCK_SOURCE};
use mechanism::{InPin, OutPin};
use watchdog::unannounced_reset_cause;

pub use clocks::{
    clock_source, ClockSource, HSE_HZ, HSE_STARTUP_POLLS, QEMU_SYSCLK_HZ, QEMU_TIMER_CLOCK_HZ,
    SYSCLK_HZ,
};
pub use flash::{FlashError, TableFlash, TABLE_LAYOUT};
pub use mechanism::{
    Drives, Encoders, Sliders, Switches, BISS, BISS_CLOCK_HZ, ENCODER_LSB_PM, ENCODER_ZERO_LSB,
    STEPPERS, SWITCHES,
};
pub use step_engine::{StepChannel, StepEngine, StepError, MAX_PULSES_PER_CYCLE, STEP_TICK_HZ};
pub use timer::{ticks, ControlTimer};
pub use uart::{Uart0, UartErrors, UartRx, UartTx, UART_BAUD};
pub use watchdog::{Watchdog, WATCHDOG_TIMEOUT_MS};

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
        // SAFETY: `steal` must not make a second owner of the device peripherals. This is
        // the first and only take (BOARD_TAKEN above), and RTIC is built with
        // `peripherals = false`, so nothing else took them: `dp` is the only instance.
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
                exposure: ExposureLine::new(gpioa.pa7.into_pull_down_input().erase(), true),
            },
        })
    }
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
