//! Control timer: TIM3 update at the control rate, 1 us ticks.
#![allow(unsafe_code)] // TIM3's status register (whole-register write).

use core::sync::atomic::{AtomicU32, Ordering};

use stm32f4xx_hal::pac;

use super::clocks::TIMER_TICK_HZ;
use crate::timing::CYCLE_US;
use crate::units::US_PER_S;

/// Control-rate ticks since the timer started (the worker's time base).
static TICKS: AtomicU32 = AtomicU32::new(0);

/// Control-rate ticks counted so far.
pub fn ticks() -> u32 {
    TICKS.load(Ordering::Relaxed)
}

/// TIM3 at the control rate (owned by the control task).
pub struct ControlTimer {
    pub(super) tim: pac::TIM3,
    pub(super) prescaler: u16,
}

/// Auto-reload value: one control period of 1 us ticks.
const CONTROL_TIMER_ARR: u16 = (CYCLE_US - 1) as u16;
const _: () = assert!(CYCLE_US - 1 <= u16::MAX as u32);
const _: () = assert!(US_PER_S == TIMER_TICK_HZ);

impl ControlTimer {
    /// Starts the timer: an update interrupt every control period.
    pub fn start(&mut self) {
        let t = &self.tim;
        t.psc().write(|w| w.psc().set(self.prescaler));
        t.arr().write(|w| w.arr().set(CONTROL_TIMER_ARR));
        // Load the prescaler now (update event), then clear the flag it sets.
        t.egr().write(|w| w.ug().set_bit());
        // SAFETY: the PAC cannot check a whole-register value. TIM3_SR's flags are rc_w0
        // (write 0 clears, 1 leaves them; RM0090 18.4.5) and its other bits are reserved
        // at 0: writing 0 clears every flag and changes nothing else.
        t.sr().write(|w| unsafe { w.bits(0) });
        t.dier().write(|w| w.uie().set_bit());
        t.cr1().write(|w| w.cen().set_bit());
    }

    /// Acknowledges the tick (call first in the control task) and counts it.
    pub fn acknowledge(&mut self) {
        // SAFETY: as in `start`: writing 0 to TIM3_SR clears its flags (rc_w0), nothing
        // else.
        self.tim.sr().write(|w| unsafe { w.bits(0) });
        TICKS.fetch_add(1, Ordering::Relaxed);
    }

    /// The next tick has already come: the running cycle overran its period.
    pub fn tick_pending(&self) -> bool {
        self.tim.sr().read().uif().bit_is_set()
    }
}
