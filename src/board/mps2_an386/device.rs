//! What RTIC's `#[app(device = ...)]` needs: the interrupt lines, their priority bits
//! and the vector table.
#![allow(unsafe_code)] // The vector table (`no_mangle`) and the IRQ-number trait.

/// Priority bits of the Cortex-M4 NVIC in the AN386 image (8 levels).
pub const NVIC_PRIO_BITS: u8 = 3;

/// The 32 external interrupt lines of mps2-an386 (QEMU: `num-irq` 32), numbered as
/// `hw/arm/mps2.c` wires them for the AN385/AN386 images. Lines named `IRQn` are
/// connected to no device QEMU models (GPIO and others); the firmware uses two of
/// them as software-pended task interrupts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u16)]
#[allow(missing_docs, clippy::upper_case_acronyms)]
pub enum Interrupt {
    /// UART0 receive.
    UARTRX0 = 0,
    /// UART0 transmit.
    UARTTX0 = 1,
    UARTRX1 = 2,
    UARTTX1 = 3,
    UARTRX2 = 4,
    UARTTX2 = 5,
    IRQ6 = 6,
    IRQ7 = 7,
    /// CMSDK APB timer 0 (0x4000_0000): the control rate.
    TIMER0 = 8,
    TIMER1 = 9,
    DUALTIMER = 10,
    SPI = 11,
    /// Overrun of UART0, 1 or 2 (ORed).
    UARTOVF = 12,
    ETHERNET = 13,
    IRQ14 = 14,
    IRQ15 = 15,
    IRQ16 = 16,
    IRQ17 = 17,
    UARTRX3 = 18,
    UARTTX3 = 19,
    UARTRX4 = 20,
    UARTTX4 = 21,
    ADCSPI = 22,
    IRQ23 = 23,
    SHIELDSPI = 24,
    IRQ25 = 25,
    IRQ26 = 26,
    IRQ27 = 27,
    IRQ28 = 28,
    IRQ29 = 29,
    IRQ30 = 30,
    /// Not wired in QEMU: the link service's software-pended interrupt.
    IRQ31 = 31,
}

// SAFETY: the trait asks for valid interrupt numbers: every variant is one of the 32
// external lines of this board (0..=31, QEMU's `num-irq` 32), its discriminant the line.
unsafe impl cortex_m::interrupt::InterruptNumber for Interrupt {
    fn number(self) -> u16 {
        self as u16
    }
}

/// The flight image's interrupts by role (RTIC's `binds =` and `rtic::pend` use
/// these names; every board maps them onto its lines, and its vector table and
/// `device.x` name the handlers so).
#[allow(missing_docs)]
pub mod interrupt {
    use super::Interrupt;
    /// UART0 receive (IRQ 0).
    pub const UART_RX: Interrupt = Interrupt::UARTRX0;
    /// UART0 transmit (IRQ 1; also pended by the link service).
    pub const UART_TX: Interrupt = Interrupt::UARTTX0;
    /// TIMER0 (IRQ 8): the control rate.
    pub const CONTROL_TIMER: Interrupt = Interrupt::TIMER0;
    /// IRQ 30, not wired in QEMU: software-pended link service pass.
    pub const LINK_SERVICE: Interrupt = Interrupt::IRQ30;
    /// IRQ 31, not wired in QEMU: software-pended worker step.
    pub const WORKER: Interrupt = Interrupt::IRQ31;
}

macro_rules! vectors {
    ($($name:ident),* $(,)?) => {
        extern "C" {
            $(fn $name();)*
        }
        /// The device part of the vector table (IRQ 0..31); `device.x` provides
        /// every handler as `DefaultHandler` unless the firmware binds it.
        // SAFETY: entries of type `unsafe extern "C" fn()` because only the hardware
        // calls them, as exception entries: each is a handler `device.x` or the firmware
        // defines with that signature, in IRQ order, in the section cortex-m-rt's link.x
        // places right after the core exceptions.
        #[link_section = ".vector_table.interrupts"]
        #[no_mangle]
        #[used]
        pub static __INTERRUPTS: [unsafe extern "C" fn(); 32] = [$($name),*];
    };
}
// Lines 0, 1, 8, 30 and 31 under the flight image's names (`interrupt`).
#[rustfmt::skip]
vectors!(
    UART_RX, UART_TX, UARTRX1, UARTTX1, UARTRX2, UARTTX2, IRQ6, IRQ7, CONTROL_TIMER, TIMER1,
    DUALTIMER, SPI, UARTOVF, ETHERNET, IRQ14, IRQ15, IRQ16, IRQ17, UARTRX3, UARTTX3, UARTRX4,
    UARTTX4, ADCSPI, IRQ23, SHIELDSPI, IRQ25, IRQ26, IRQ27, IRQ28, IRQ29, LINK_SERVICE,
    WORKER,
);
