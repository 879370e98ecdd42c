//! UART: USART1 (PA9 TX, PA10 RX), QEMU's first `-serial`. One interrupt line for both
//! directions: the receive task owns it (highest task priority); it hands the
//! transmitter's TXE to the lower-priority software line UART_TX, as the mps2 board's
//! separate TX interrupt would.
#![allow(unsafe_code)] // USART1's register block, shared by the UART halves.

use core::sync::atomic::{AtomicU16, Ordering};

use cortex_m::interrupt as irq;
use heapless::spsc::{Consumer, Producer};
use stm32f4xx_hal::pac;

use super::device;

/// Telecommand/telemetry line rate (bit/s).
pub const UART_BAUD: u32 = 115_200;
/// Bytes one TX drain writes at most while the transmitter is free (QEMU's is always
/// free; on silicon one or two bytes go before TXE drops), then it pends itself again.
const TX_BYTES_PER_DRAIN: usize = 64;

fn usart1() -> &'static pac::usart1::RegisterBlock {
    // SAFETY: `ptr()` is USART1's register block, device memory valid for the whole run;
    // its registers are cells (svd2rust), so shared references to them are sound.
    // `Board::take` configured USART1 through the HAL and kept no handle of it, so only
    // the UART halves below use it, one owner per register: RX reads SR and DR, TX
    // writes DR, CR1's TXEIE is changed under a critical section (`set_txeie`).
    unsafe { &*pac::USART1::ptr() }
}

/// The telecommand UART, before it is split.
pub struct Uart0(pub(super) ());

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
            u.dr().write(|w| w.dr().set(u16::from(byte)));
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
