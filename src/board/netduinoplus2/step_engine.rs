//! Step pulses: one TIM2 update interrupt drives the six STEP pins.
#![allow(unsafe_code)] // TIM2's status register (whole-register write), the NVIC.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::interrupt::{self as irq, Mutex};
use stm32f4xx_hal::pac::{self, interrupt};

use super::clocks::{tick_prescaler, ClockSource, TIMER_TICK_HZ};
use super::mechanism::OutPin;
use crate::drivers::stepper::StepPulses;
use crate::kinematics::LEGS;
use crate::timing::CYCLE_US;
use crate::units::US_PER_S;

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
    pub(super) leg: usize,
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
    pub(super) fn install(
        tim: pac::TIM2,
        step: [OutPin; LEGS],
        source: ClockSource,
        timer_clock_hz: u32,
    ) {
        tim.psc()
            .write(|w| w.psc().set(tick_prescaler(timer_clock_hz)));
        tim.arr()
            .write(|w| w.arr().set(TIMER_TICK_HZ / STEP_TICK_HZ - 1));
        tim.egr().write(|w| w.ug().set_bit());
        // SAFETY: the PAC cannot check a whole-register value. TIM2_SR's flags are rc_w0
        // (write 0 clears, 1 leaves them; RM0090 18.4.5) and its other bits are reserved
        // at 0: writing 0 clears every flag and changes nothing else.
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
            // SAFETY: `steal` makes a second NVIC handle, used for TIM2's lines only: RTIC
            // sets the priorities of its own interrupts, never TIM2's (no task binds it),
            // and an IPR write is one byte, so the two never write the same field.
            // Priority 0 and unmasking are sound because TIM2's handler shares no RTIC
            // resource (BASEPRI does not mask it): it touches only the engine, installed
            // above and behind its critical-section mutex, and the atomics.
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
        // SAFETY: as in `install`: writing 0 to TIM2_SR clears its flags (rc_w0),
        // nothing else.
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
