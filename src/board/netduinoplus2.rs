//! Netduino Plus 2: STM32F405RG (Cortex-M4F, 168 MHz, 1 MiB flash, 128 KiB SRAM), also
//! QEMU's `netduinoplus2` machine. Feature `board-netduinoplus2`; memory map in
//! `memory/netduinoplus2.x` (selected by build.rs).
//!
//! The same glue items as the mps2-an386 board, so every image builds for either:
//! semihosting exit and the panic handler, the telecommand UART ([`Uart`], USART1),
//! the parameter-table flash ([`TableFlash`], two 128 KiB sectors behind the table
//! store's offsets), 1 kHz cycle pacing ([`CycleTimer`], SysTick), stack-peak
//! measurement and the instruction-count markers. And what mps2 lacks, the mechanism
//! wired to the drivers of `crate::drivers` through `stm32f4xx-hal` (embedded-hal 1.0):
//! [`Board::take`] hands out the UART, the six BiSS-C encoders in one daisy chain on
//! SPI1, the six step/direction drives (step pulses from [`StepEngine`] on TIM2), and
//! the end-of-travel/reference inputs, as one [`Mechanism`].
//!
//! ## Harness (pin map)
//!
//! | signal | pins |
//! |---|---|
//! | USART1 TX / RX (telecommands, QEMU's first `-serial`) | PA9 / PA10 |
//! | BiSS MA (SPI1 SCK) / SL (SPI1 MISO) | PA5 / PA6 |
//! | STEP legs 1..6 | PC0, PC4, PC8, PB0, PB4, PB8 |
//! | DIR legs 1..6 | PC1, PC5, PC9, PB1, PB5, PB9 |
//! | ENABLE (active low) legs 1..6 | PC2, PC6, PC10, PB2, PB6, PB10 |
//! | FAULT (active low, pull-up) legs 1..6 | PC3, PC7, PC11, PB3, PB7, PB11 |
//! | lower end switch (NC, pull-up) legs 1..6 | PA0, PA1, PA2, PA3, PA4, PA8 |
//! | upper end switch (NC, pull-up) legs 1..6 | PA11, PA12, PA15, PB12, PB13, PB14 |
//! | reference sensor (active high) legs 1..6 | PB15, PC12, PC13, PC14, PC15, PD2 |
//!
//! ## Clocks
//!
//! 25 MHz crystal (HSE) -> PLL -> 168 MHz. The crystal is waited for a bounded time
//! ([`HSE_STARTUP_POLLS`]); if it does not start (a failed crystal, or QEMU, whose
//! STM32F405 has no RCC model) the board runs on the internal 16 MHz oscillator and
//! [`clock_source`] says so. QEMU's CPU runs at its own 168 MHz whatever the RCC says.
//!
//! ## Not modelled by QEMU 7.2
//!
//! GPIO, RCC and the flash interface are unimplemented devices there (writes ignored,
//! reads 0): the self-test image runs (it needs only the core, semihosting and defmt);
//! the drivers build and are tested on the host (`host-tests/drivers.rs`), not in QEMU;
//! table writes cannot succeed in QEMU (the "flash" is ROM).
#![allow(unsafe_code)] // Board glue: linker symbols, painted RAM, stolen peripherals.

use core::cell::Cell;
use core::ptr::read_volatile;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::interrupt::{self as irq, Mutex};
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use stm32f4xx_hal::flash::{FlashExt, LockedFlash};
use stm32f4xx_hal::gpio::{AnyPin, Input, Output, PushPull};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Clocks, Config as RccConfig, Rcc};
use stm32f4xx_hal::serial::{self as hal_serial, Serial};
use stm32f4xx_hal::spi::{Mode as SpiMode, Phase, Polarity, Spi};
use stm32f4xx_hal::timer::{CounterHz, Event as TimerEvent, Flag as TimerFlag};
use stm32f4xx_hal::{ClearFlags, Listen};

use crate::drivers::biss::{BissChain, BissConfig, BissConfigError, EncoderScale, MaLine};
use crate::drivers::stepper::{
    StepDirDrives, StepPulses, StepperConfig, StepperConfigError, StepperLeg, StepperPolarity,
};
use crate::drivers::switches::{LegSwitches, SwitchPolarity, TravelSwitchInputs};
use crate::drivers::Mechanism as DriverMechanism;
use crate::kinematics::LEGS;
use crate::motion::CYCLE_S;
use crate::table::{BANK_A_OFFSET, BANK_B_OFFSET, BANK_SIZE};

/// Value cortex-m-rt's `paint-stack` writes over the stack before `main`.
const STACK_PAINT: u32 = 0xCCCC_CCCC;

extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}

/// Bytes of stack used so far: scans the painted region from its low end upwards for the
/// first word that is no longer the paint value.
pub fn stack_peak_bytes() -> u32 {
    let lo = core::ptr::addr_of!(_stack_end) as usize;
    let hi = core::ptr::addr_of!(_stack_start) as usize;
    let mut p = lo;
    // SAFETY: [lo, hi) is the stack region of cortex-m-rt's linker script, plain RAM;
    // aligned volatile word reads inside it are sound.
    while p < hi && unsafe { read_volatile(p as *const u32) } == STACK_PAINT {
        p += 4;
    }
    (hi - p) as u32
}

/// Size of the stack region (bytes) between `_stack_end` and `_stack_start`.
pub fn stack_region_bytes() -> u32 {
    let lo = core::ptr::addr_of!(_stack_end) as usize;
    let hi = core::ptr::addr_of!(_stack_start) as usize;
    (hi - lo) as u32
}

/// Ends the run with an exit code (0 = pass) through semihosting (QEMU's exit code; on
/// the real board only with a debugger attached).
pub fn exit(code: i32) -> ! {
    semihosting::process::exit(code)
}

/// Exit code of a panic: a defect, flight code must not panic.
pub const EXIT_PANIC: i32 = 101;

/// The panic handler of every firmware image of this board: log and end the run with
/// [`EXIT_PANIC`] (on a flight board: the watchdog/safe-mode path of issue 9).
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    defmt::error!("PANIC");
    exit(EXIT_PANIC)
}

/// Marker for `qemu-insncount`: start of a measured section.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_start() {
    core::sync::atomic::compiler_fence(Ordering::SeqCst);
}

/// Marker for `qemu-insncount`: end of a measured section (a different body from
/// `bench_start`, so the linker cannot merge the two).
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_end() {
    core::sync::atomic::compiler_fence(Ordering::Release);
    core::hint::black_box(0u32);
}

/// A hardware part requested twice, or a configuration the board cannot use: a defect
/// of the image, not a run-time condition.
fn defect() -> ! {
    defmt::error!("board: part taken twice or misconfigured");
    exit(EXIT_PANIC)
}

// ---------------------------------------------------------------------------------
// Clocks.

/// The Netduino Plus 2's crystal (Hz).
pub const HSE_HZ: u32 = 25_000_000;
/// System clock from the PLL (Hz): the STM32F405's maximum.
pub const SYSCLK_HZ: u32 = 168_000_000;
/// Polls of HSERDY before giving up on the crystal (several ms at 16 MHz; crystals
/// start in about 2 ms).
pub const HSE_STARTUP_POLLS: u32 = 200_000;

/// Where the system clock comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum ClockSource {
    /// Crystal and PLL, [`SYSCLK_HZ`].
    CrystalPll,
    /// The crystal did not start: internal 16 MHz RC oscillator.
    InternalFallback,
}

static CLOCKS: Mutex<Cell<Option<(Clocks, ClockSource)>>> = Mutex::new(Cell::new(None));

/// Configures the clock tree once (later calls return the same) and returns it.
pub fn clocks() -> (Clocks, ClockSource) {
    irq::free(|cs| {
        if let Some(c) = CLOCKS.borrow(cs).get() {
            return c;
        }
        // SAFETY: the RCC is only configured here, once, inside a critical section; the
        // peripheral constructors below only enable/reset their own clock bits.
        let rcc = unsafe { pac::RCC::steal() };
        rcc.cr().modify(|_, w| w.hseon().set_bit());
        let hse_ready = (0..HSE_STARTUP_POLLS).any(|_| rcc.cr().read().hserdy().bit_is_set());
        let (cfg, source) = if hse_ready {
            (
                RccConfig::hse(HSE_HZ.Hz()).sysclk(SYSCLK_HZ.Hz()),
                ClockSource::CrystalPll,
            )
        } else {
            rcc.cr().modify(|_, w| w.hseon().clear_bit());
            (RccConfig::hsi(), ClockSource::InternalFallback)
        };
        let c = (rcc.freeze(cfg).clocks, source);
        CLOCKS.borrow(cs).set(Some(c));
        c
    })
}

/// Where the system clock came from ([`clocks`] is run if it has not been).
pub fn clock_source() -> ClockSource {
    clocks().1
}

/// A constrained RCC carrying the frozen clocks, for the HAL's peripheral constructors.
fn rcc() -> Rcc {
    let (c, _) = clocks();
    // SAFETY: see `clocks`; `constrain` writes nothing.
    let mut r = unsafe { pac::RCC::steal() }.constrain();
    r.clocks = c;
    r
}

// ---------------------------------------------------------------------------------
// UART: USART1 (PA9 TX, PA10 RX), QEMU's first `-serial`.

/// Telecommand/telemetry line rate (bit/s).
pub const UART_BAUD: u32 = 115_200;

/// The telecommand/telemetry UART (USART1), behind `embedded-hal-nb`'s serial traits.
pub struct Uart(Serial<pac::USART1, u8>);

impl Uart {
    /// The telecommand UART, for images written against the mps2 shape: takes the whole
    /// [`Board`] (the first call only; a second is a defect) and keeps the UART.
    pub fn uart0() -> Self {
        match Board::take() {
            Ok(b) => b.uart,
            Err(_) => defect(),
        }
    }
}

impl embedded_hal_nb::serial::ErrorType for Uart {
    type Error = hal_serial::Error;
}

impl embedded_hal_nb::serial::Read<u8> for Uart {
    fn read(&mut self) -> nb::Result<u8, Self::Error> {
        embedded_hal_nb::serial::Read::read(&mut self.0)
    }
}

impl embedded_hal_nb::serial::Write<u8> for Uart {
    fn write(&mut self, byte: u8) -> nb::Result<(), Self::Error> {
        embedded_hal_nb::serial::Write::write(&mut self.0, byte)
    }
    fn flush(&mut self) -> nb::Result<(), Self::Error> {
        embedded_hal_nb::serial::Write::flush(&mut self.0)
    }
}

// ---------------------------------------------------------------------------------
// Table flash: sectors 10 and 11 (128 KiB each, at 0x080C_0000 and 0x080E_0000),
// reserved as TABLE in memory/netduinoplus2.x. The table store addresses its banks at
// the flight layout's offsets (`BANK_A_OFFSET`, `BANK_B_OFFSET`, `BANK_SIZE` 64 KiB);
// this maps bank A onto the first 64 KiB of sector 10 and bank B onto sector 11.

/// Memory-mapped start of the STM32F405's flash.
const FLASH_BASE: u32 = 0x0800_0000;
/// Sector and address holding bank A.
const BANK_A_SECTOR: u8 = 10;
const BANK_A_ADDR: u32 = 0x080C_0000;
/// Sector and address holding bank B.
const BANK_B_SECTOR: u8 = 11;
const BANK_B_ADDR: u32 = 0x080E_0000;

/// Why a flash operation was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    /// Outside the two banks, or crossing a bank's end.
    OutOfBounds,
    /// An erase not covering whole banks.
    NotAligned,
    /// A write tried to set a bit that is 0 (NOR can only clear bits before an erase).
    NotErased,
    /// The flash interface reported an error (programming, protection, sequence).
    Device,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::NotErased | FlashError::Device => NorFlashErrorKind::Other,
        }
    }
}

/// The table banks as NOR flash at the table store's offsets.
pub struct TableFlash(());

impl TableFlash {
    /// The board's table flash. Only one instance should exist.
    pub fn take() -> Self {
        TableFlash(())
    }

    /// The bank (physical address, sector) holding `[offset, offset + len)`.
    fn map(offset: u32, len: usize) -> Result<(u32, u8), FlashError> {
        let len = u32::try_from(len).map_err(|_| FlashError::OutOfBounds)?;
        for (bank, addr, sector) in [
            (BANK_A_OFFSET, BANK_A_ADDR, BANK_A_SECTOR),
            (BANK_B_OFFSET, BANK_B_ADDR, BANK_B_SECTOR),
        ] {
            let inside = offset >= bank
                && offset
                    .checked_add(len)
                    .is_some_and(|end| end <= bank + BANK_SIZE);
            if inside {
                return Ok((addr + (offset - bank), sector));
            }
        }
        Err(FlashError::OutOfBounds)
    }

    fn hal_flash() -> LockedFlash {
        // SAFETY: the FLASH interface is used by this type only (one instance).
        LockedFlash::new(unsafe { pac::FLASH::steal() })
    }
}

impl ErrorType for TableFlash {
    type Error = FlashError;
}

impl ReadNorFlash for TableFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let (addr, _) = Self::map(offset, bytes.len())?;
        for (i, b) in bytes.iter_mut().enumerate() {
            // SAFETY: inside a table bank (checked by `map`), memory-mapped flash.
            *b = unsafe { read_volatile((addr as usize + i) as *const u8) };
        }
        Ok(())
    }
    fn capacity(&self) -> usize {
        // The offsets the table store uses run to the end of bank B.
        (BANK_B_OFFSET.max(BANK_A_OFFSET) + BANK_SIZE) as usize
    }
}

impl NorFlash for TableFlash {
    const WRITE_SIZE: usize = 1;
    /// One bank: erasing it erases the whole sector behind it.
    const ERASE_SIZE: usize = BANK_SIZE as usize;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if from > to || (to - from) % BANK_SIZE != 0 {
            return Err(FlashError::NotAligned);
        }
        let mut flash = Self::hal_flash();
        let mut unlocked = flash.unlocked();
        let mut at = from;
        while at < to {
            let (addr, sector) = Self::map(at, BANK_SIZE as usize)?;
            if addr != BANK_A_ADDR && addr != BANK_B_ADDR {
                return Err(FlashError::NotAligned);
            }
            unlocked.erase(sector).map_err(|_| FlashError::Device)?;
            at += BANK_SIZE;
        }
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let (addr, _) = Self::map(offset, bytes.len())?;
        for (i, b) in bytes.iter().enumerate() {
            // SAFETY: as in `read`.
            let old = unsafe { read_volatile((addr as usize + i) as *const u8) };
            if b & !old != 0 {
                return Err(FlashError::NotErased);
            }
        }
        let mut flash = Self::hal_flash();
        let mut unlocked = flash.unlocked();
        unlocked
            .program((addr - FLASH_BASE) as usize, bytes.iter())
            .map_err(|_| FlashError::Device)
    }
}

// ---------------------------------------------------------------------------------
// Cycle pacing: SysTick at the control rate, from the actual core clock.

/// Paces the control loop at the control rate (`motion::CYCLE_S`).
pub struct CycleTimer {
    syst: cortex_m::peripheral::SYST,
}

impl CycleTimer {
    /// Starts SysTick (core clock, one control cycle per wrap, no interrupt); configures
    /// the clocks first if nothing has.
    pub fn start(mut syst: cortex_m::peripheral::SYST) -> Self {
        use cortex_m::peripheral::syst::SystClkSource;
        let hz = clocks().0.sysclk().raw();
        let reload = (hz as f32 * CYCLE_S + 0.5) as u32;
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(reload.saturating_sub(1));
        syst.clear_current();
        syst.enable_counter();
        Self { syst }
    }

    /// Waits for the next cycle boundary. Returns `true` if the previous cycle overran
    /// (more than one period elapsed since the last call).
    pub fn wait(&mut self) -> bool {
        let overran = self.syst.has_wrapped();
        while !self.syst.has_wrapped() {}
        overran
    }
}

// ---------------------------------------------------------------------------------
// Step pulses: one TIM2 update interrupt drives the six STEP pins.

/// Step engine tick (Hz): a pulse is high for one tick and low for at least one.
pub const STEP_TICK_HZ: u32 = 100_000;
/// Ticks per control cycle.
const TICKS_PER_CYCLE: u32 = (STEP_TICK_HZ as f32 * CYCLE_S + 0.5) as u32;
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
    leg: usize,
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

/// The interrupt side of the step pulses: owns TIM2 and the six STEP pins. The
/// executive binds TIM2's interrupt to [`StepEngine::on_tick`] at a priority above the
/// control task (nothing here runs until it does).
pub struct StepEngine {
    tim: CounterHz<pac::TIM2>,
    step: [AnyPin<Output<PushPull>>; LEGS],
    high: [bool; LEGS],
    seen: [u32; LEGS],
    acc: [u32; LEGS],
}

impl StepEngine {
    /// One tick: ends pulses that are high, then starts the pulses due (each leg's train
    /// spread evenly over [`MAX_PULSES_PER_CYCLE`] opportunities).
    pub fn on_tick(&mut self) {
        self.tim.clear_flags(TimerFlag::Update);
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

// ---------------------------------------------------------------------------------
// The mechanism.

/// BiSS clock (Hz) requested from SPI1 (84 MHz APB2 / 32 = 2.6 MHz).
pub const BISS_CLOCK_HZ: u32 = 2_625_000;
/// The encoders' frame: 32-bit position words (RESOLUTE linear, 1 nm), Start bit
/// accepted from bit 2 (two samples before the Ack, SPI mode 2) to bit 10.
pub const BISS: BissConfig = BissConfig {
    position_bits: 32,
    start_bit_first: 2,
    start_bit_last: 10,
};
/// Encoder step (pm): 1 nm.
pub const ENCODER_LSB_PM: u32 = 1_000;
/// Raw encoder position at zero stroke, per leg. Installation values (mid-scale until
/// the mechanism's are measured); the parameter table has no field for them yet.
pub const ENCODER_ZERO_LSB: [u64; LEGS] = [1 << 31; LEGS];
/// The drives: 1 mm lead screw, 200-step motors, 16 microsteps, direct drive
/// (3,200 microsteps per mm), at most [`MAX_PULSES_PER_CYCLE`] per cycle (15 mm/s),
/// clamped beyond 6 mm; DRV8825-style pins (ENABLE and FAULT active low).
pub const STEPPERS: StepperConfig = StepperConfig {
    lead_screw_pitch_nm: 1_000_000,
    full_steps_per_rev: 200,
    microsteps_per_step: 16,
    gear_motor_revs: 1,
    gear_screw_revs: 1,
    max_microsteps_per_cycle: MAX_PULSES_PER_CYCLE,
    travel_limit_nm: 6_000_000,
    polarity: StepperPolarity {
        dir_high_is_positive: true,
        enable_active_high: false,
        fault_active_high: false,
    },
};
/// Normally-closed end switches to ground with pull-ups (open = high = active);
/// reference sensors active high.
pub const SWITCHES: SwitchPolarity = SwitchPolarity {
    end_active_high: true,
    reference_active_high: true,
};

/// The BiSS daisy chain on SPI1.
pub type Encoders = BissChain<MaLine<Spi<pac::SPI1>>>;
/// The six step/direction drives.
pub type Drives =
    StepDirDrives<StepChannel, AnyPin<Output<PushPull>>, AnyPin<Output<PushPull>>, AnyPin<Input>>;
/// The eighteen switch inputs.
pub type Switches = TravelSwitchInputs<AnyPin<Input>>;
/// Encoders, drives and switches behind the `hw` traits.
pub type Mechanism = DriverMechanism<Encoders, Drives, Switches>;

/// Why the board could not be taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardError {
    /// Already taken (the peripherals are take-once).
    Taken,
    /// The UART configuration was refused.
    Uart,
    /// The encoder configuration was refused.
    Encoders(BissConfigError),
    /// The drive configuration was refused.
    Drives(StepperConfigError),
    /// The step timer could not be started.
    StepTimer,
}

/// Every part of the board, handed out once.
pub struct Board {
    /// Telecommand/telemetry UART.
    pub uart: Uart,
    /// Encoders, drives, switches.
    pub mechanism: Mechanism,
    /// The step-pulse interrupt's state ([`StepEngine::on_tick`]).
    pub step_engine: StepEngine,
    /// The parameter-table flash.
    pub table_flash: TableFlash,
    /// Where the clock came from.
    pub clock_source: ClockSource,
}

impl Board {
    /// Takes the device peripherals (once), configures the clocks, pins, UART, SPI and
    /// the step timer, and returns every part.
    pub fn take() -> Result<Board, BoardError> {
        let dp = pac::Peripherals::take().ok_or(BoardError::Taken)?;
        let (_, clock_source) = clocks();
        let mut rcc = rcc();
        let gpioa = dp.GPIOA.split(&mut rcc);
        let gpiob = dp.GPIOB.split(&mut rcc);
        let gpioc = dp.GPIOC.split(&mut rcc);
        let gpiod = dp.GPIOD.split(&mut rcc);

        let serial = Serial::new(
            dp.USART1,
            (gpioa.pa9, gpioa.pa10),
            hal_serial::Config::default().baudrate(UART_BAUD.bps()),
            &mut rcc,
        )
        .map_err(|_| BoardError::Uart)?;

        let spi = Spi::new(
            dp.SPI1,
            (Some(gpioa.pa5), Some(gpioa.pa6), pac::SPI1::NoMosi),
            SpiMode {
                polarity: Polarity::IdleHigh,
                phase: Phase::CaptureOnFirstTransition,
            },
            BISS_CLOCK_HZ.Hz(),
            &mut rcc,
        );
        let scales = ENCODER_ZERO_LSB.map(|zero_lsb| EncoderScale {
            lsb_pm: ENCODER_LSB_PM,
            zero_lsb,
            reversed: false,
        });
        let encoders = BissChain::new(MaLine(spi), BISS, scales).map_err(BoardError::Encoders)?;

        let step = [
            gpioc.pc0.into_push_pull_output().erase(),
            gpioc.pc4.into_push_pull_output().erase(),
            gpioc.pc8.into_push_pull_output().erase(),
            gpiob.pb0.into_push_pull_output().erase(),
            gpiob.pb4.into_push_pull_output().erase(),
            gpiob.pb8.into_push_pull_output().erase(),
        ];
        let dir = [
            gpioc.pc1.into_push_pull_output().erase(),
            gpioc.pc5.into_push_pull_output().erase(),
            gpioc.pc9.into_push_pull_output().erase(),
            gpiob.pb1.into_push_pull_output().erase(),
            gpiob.pb5.into_push_pull_output().erase(),
            gpiob.pb9.into_push_pull_output().erase(),
        ];
        let enable = [
            gpioc.pc2.into_push_pull_output().erase(),
            gpioc.pc6.into_push_pull_output().erase(),
            gpioc.pc10.into_push_pull_output().erase(),
            gpiob.pb2.into_push_pull_output().erase(),
            gpiob.pb6.into_push_pull_output().erase(),
            gpiob.pb10.into_push_pull_output().erase(),
        ];
        let fault = [
            gpioc.pc3.into_pull_up_input().erase(),
            gpioc.pc7.into_pull_up_input().erase(),
            gpioc.pc11.into_pull_up_input().erase(),
            gpiob.pb3.into_pull_up_input().erase(),
            gpiob.pb7.into_pull_up_input().erase(),
            gpiob.pb11.into_pull_up_input().erase(),
        ];
        let mut legs_iter = dir.into_iter().zip(enable).zip(fault).enumerate();
        let legs: [StepperLeg<_, _, _, _>; LEGS] = core::array::from_fn(|_| {
            let Some((leg, ((dir, enable), fault))) = legs_iter.next() else {
                defect() // six of each above
            };
            StepperLeg {
                pulses: StepChannel { leg },
                dir,
                enable,
                fault,
            }
        });
        let drives = StepDirDrives::new(legs, STEPPERS).map_err(|(e, _)| BoardError::Drives(e))?;

        let lower = [
            gpioa.pa0.into_pull_up_input().erase(),
            gpioa.pa1.into_pull_up_input().erase(),
            gpioa.pa2.into_pull_up_input().erase(),
            gpioa.pa3.into_pull_up_input().erase(),
            gpioa.pa4.into_pull_up_input().erase(),
            gpioa.pa8.into_pull_up_input().erase(),
        ];
        let upper = [
            gpioa.pa11.into_pull_up_input().erase(),
            gpioa.pa12.into_pull_up_input().erase(),
            gpioa.pa15.into_pull_up_input().erase(),
            gpiob.pb12.into_pull_up_input().erase(),
            gpiob.pb13.into_pull_up_input().erase(),
            gpiob.pb14.into_pull_up_input().erase(),
        ];
        let reference = [
            gpiob.pb15.into_pull_down_input().erase(),
            gpioc.pc12.into_pull_down_input().erase(),
            gpioc.pc13.into_pull_down_input().erase(),
            gpioc.pc14.into_pull_down_input().erase(),
            gpioc.pc15.into_pull_down_input().erase(),
            gpiod.pd2.into_pull_down_input().erase(),
        ];
        let mut sw_iter = lower.into_iter().zip(upper).zip(reference);
        let sw_legs: [LegSwitches<_>; LEGS] = core::array::from_fn(|_| {
            let Some(((lower, upper), reference)) = sw_iter.next() else {
                defect()
            };
            LegSwitches {
                lower,
                upper,
                reference,
            }
        });
        let switches = TravelSwitchInputs::new(sw_legs, SWITCHES);

        let mut tim = dp.TIM2.counter_hz(&mut rcc);
        tim.start(STEP_TICK_HZ.Hz())
            .map_err(|_| BoardError::StepTimer)?;
        tim.listen(TimerEvent::Update);
        let step_engine = StepEngine {
            tim,
            step,
            high: [false; LEGS],
            seen: [0; LEGS],
            acc: [0; LEGS],
        };

        Ok(Board {
            uart: Uart(serial),
            mechanism: DriverMechanism {
                encoders,
                drives,
                switches,
            },
            step_engine,
            table_flash: TableFlash::take(),
            clock_source,
        })
    }
}
