//! Control timer: CMSDK APB timer 0.

use core::sync::atomic::{AtomicU32, Ordering};

use super::{reg_read, reg_write, SYSCLK_HZ};
use crate::timing::CONTROL_RATE_HZ;

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
pub struct ControlTimer(pub(super) ());

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
