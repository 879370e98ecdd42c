//! UART0: CMSDK APB UART.

use core::sync::atomic::{AtomicU16, Ordering};

use heapless::spsc::{Consumer, Producer};

use super::{reg_read, reg_write, SYSCLK_HZ};

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
pub struct Uart0(pub(super) ());

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
