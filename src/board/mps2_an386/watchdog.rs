//! Watchdog: CMSDK APB watchdog. First expiry: interrupt (wired to the NMI); second
//! expiry with RESEN: system reset. Writes are ignored while it is locked.
#![allow(unsafe_code)] // The NMI handler (`cortex-m-rt` requires it `unsafe fn`).

use super::{reg_write, SYSCLK_HZ};
use crate::board::cortex_m::reset_record;
use crate::hw::ResetCause;
use crate::timing::CONTROL_RATE_HZ;

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
pub struct Watchdog(pub(super) ());

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

/// The watchdog's first expiry (no control cycle completed for
/// [`WATCHDOG_TIMEOUT_CYCLES`] periods): record the cause, then wait for the
/// watchdog's own reset one interval later.
// SAFETY: cortex-m-rt requires `unsafe fn` for the NMI because it preempts every
// critical section. This handler touches no data a critical section guards: it writes
// the reset record (volatile words of its own) and spins until the watchdog resets.
#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    reset_record::announce(ResetCause::Watchdog);
    loop {
        cortex_m::asm::nop();
    }
}
