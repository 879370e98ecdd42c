//! What RTIC's `#[app(device = ...)]` needs: the PAC's interrupt lines and priority
//! bits, the flight image's interrupt names on this board, and the vector table.

pub use stm32f4xx_hal::pac::{Interrupt, NVIC_PRIO_BITS};

/// The flight image's interrupts by role (RTIC's `binds =` and `rtic::pend` use
/// these names), on this board's lines. The three software-pended ones are lines of
/// peripherals this board never enables (CAN2).
#[allow(missing_docs)]
pub mod interrupt {
    use super::Interrupt;
    /// USART1 (receive, and the transmitter's TXE, see [`UartRx`](super::super::UartRx)).
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
