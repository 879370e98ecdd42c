//! Watchdog: the independent watchdog (LSI, ~32 kHz), fed only by a completed control
//! cycle. It has no early-warning interrupt: its reset is recognised at the next boot
//! (a valid reset record without an announced cause).

use stm32f4xx_hal::pac;

use crate::hw::ResetCause;

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

/// The cause of a reset software did not announce, from RCC_CSR (RM0090 7.3.21): the
/// independent watchdog's flag, else an external reset (the NRST pin, a debugger;
/// QEMU's netduinoplus2 models neither the flags nor the watchdog, so there every
/// unannounced reset is external). Clears the flags for the next boot.
pub(super) fn unannounced_reset_cause(rcc: &pac::RCC) -> ResetCause {
    let watchdog = rcc.csr().read().wdgrstf().bit_is_set();
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    if watchdog {
        ResetCause::Watchdog
    } else {
        ResetCause::External
    }
}

/// The watchdog (owned by the control task: only a completed cycle feeds it).
pub struct Watchdog(pub(super) pac::IWDG);

impl Watchdog {
    /// Starts it (it cannot be stopped again but by a reset).
    pub fn start(&mut self) {
        let w = &self.0;
        // The key register's values (RM0090 21.4.1) by the PAC's names: unlock 0x5555
        // (access to PR and RLR), feed 0xAAAA (reload), start 0xCCCC.
        w.kr().write(|k| k.key().unlock());
        w.pr().write(|p| p.pr().set(IWDG_PR_DIV4));
        w.rlr().write(|r| r.rl().set(IWDG_RELOAD));
        w.kr().write(|k| k.key().feed());
        w.kr().write(|k| k.key().start());
    }

    /// Reloads the counter.
    pub fn feed(&mut self) {
        self.0.kr().write(|k| k.key().feed());
    }
}
