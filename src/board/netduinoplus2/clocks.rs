//! Clocks: 25 MHz crystal (HSE) -> PLL -> 168 MHz. The crystal is waited for a bounded
//! time ([`HSE_STARTUP_POLLS`]); if it does not start the board runs on the internal
//! 16 MHz oscillator ([`ClockSource::InternalFallback`]). On QEMU (the RCC reads all
//! zero) nothing is configured ([`ClockSource::Emulated`]).

use cortex_m::interrupt::{self as irq, Mutex};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Config as RccConfig, Rcc};

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
pub(super) const TIMER_TICK_HZ: u32 = 1_000_000;

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
pub(super) struct ClockTree {
    pub(super) rcc: Rcc,
    pub(super) source: ClockSource,
    pub(super) timer_clock_hz: u32,
}

/// Configures the clock tree (once, from [`Board::take`]).
pub(super) fn configure_clocks(rcc: pac::RCC) -> ClockTree {
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
pub(super) static CLOCK_SOURCE: Mutex<core::cell::Cell<ClockSource>> =
    Mutex::new(core::cell::Cell::new(ClockSource::InternalFallback));

/// Where the system clock comes from.
pub fn clock_source() -> ClockSource {
    irq::free(|cs| CLOCK_SOURCE.borrow(cs).get())
}

/// Prescaler register value for a [`TIMER_TICK_HZ`] tick from `timer_clock_hz`.
pub(super) fn tick_prescaler(timer_clock_hz: u32) -> u16 {
    u16::try_from((timer_clock_hz / TIMER_TICK_HZ).saturating_sub(1)).unwrap_or(u16::MAX)
}
