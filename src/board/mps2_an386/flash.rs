//! Table flash: the TABLE region of `memory.x` (top 128 KiB of the 4 MiB flash).
#![allow(unsafe_code)] // The table region: emulated flash read and written through raw pointers.

use core::ptr::{read_volatile, write_volatile};

use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

use super::timer::ticks;
use crate::board::memory_x;
pub use crate::board::table_flash::FlashError;
use crate::board::table_flash::{erase_aligned, TableRegion};
use crate::table::{BankLayout, FlashStatus};

/// Offsets are from the start of the 4 MiB flash, as `table::store` expects.
const FLASH_BASE: usize = 0x0000_0000;
/// Flash size (bytes).
const FLASH_SIZE: u32 = 0x40_0000;
/// Bank size (bytes): two banks fill the TABLE region.
const TABLE_BANK_SIZE: u32 = 0x1_0000;
/// First byte the table store may write or erase (start of the TABLE region).
const TABLE_REGION_START: u32 = 0x3E_0000;
/// The table banks of this board: A then B in the TABLE region.
pub const TABLE_LAYOUT: BankLayout = BankLayout::two_banks(TABLE_REGION_START, TABLE_BANK_SIZE);
// The layout is exactly memory.x's TABLE region, at the top of the flash.
const _: () = assert!(memory_x::TABLE_ORIGIN == TABLE_REGION_START);
const _: () = assert!(memory_x::TABLE_LENGTH == 2 * TABLE_BANK_SIZE);
const _: () = assert!(TABLE_REGION_START + 2 * TABLE_BANK_SIZE == FLASH_SIZE);
const _: () = assert!(TABLE_LAYOUT.bank_b_offset + TABLE_LAYOUT.bank_size == FLASH_SIZE);
/// Erase granularity emulated here (bytes).
const FLASH_ERASE_SIZE: u32 = 4096;
/// Erased byte value.
const FLASH_ERASED: u8 = 0xFF;
// SAFETY: [FLASH_BASE + TABLE_REGION_START, FLASH_BASE + FLASH_SIZE) is memory.x's
// TABLE region (the asserts above), reserved: nothing is linked there and no Rust object
// or reference covers it; on QEMU it is RAM, read and written only through TableFlash.
const REGION: TableRegion = unsafe { TableRegion::new(FLASH_BASE, TABLE_REGION_START, FLASH_SIZE) };
/// Modelled sector-erase time (control ticks): 0.3 s, a NOR sector.
pub const FLASH_ERASE_TICKS: u32 = 300;
/// Modelled program time of one write (control ticks).
pub const FLASH_PROGRAM_TICKS: u32 = 1;

/// The table region as NOR flash, busy for the modelled time after each erase or
/// program ([`FlashStatus`]).
pub struct TableFlash {
    pub(super) busy_until: Option<u32>,
}

impl TableFlash {
    /// QEMU's SSRAM comes up zeroed, a new NOR flash erased: a TABLE region that reads
    /// all zero (never written: no valid store state is all zero) is erased, so the
    /// store sees blank banks as on a new device. Any other content (written by an
    /// earlier boot: QEMU keeps RAM across a system reset) is kept.
    pub(super) fn erase_if_never_written(&mut self) {
        let start = FLASH_BASE + TABLE_REGION_START as usize;
        let end = FLASH_BASE + FLASH_SIZE as usize;
        // SAFETY: [start, end) is the TABLE region (word-aligned bounds), reserved in
        // memory.x (the asserts above): nothing is linked there and no Rust object or
        // reference covers it; on QEMU it is RAM, read as plain u32.
        let zero = (start..end)
            .step_by(4)
            .all(|a| unsafe { read_volatile(a as *const u32) } == 0);
        if zero {
            for a in (start..end).step_by(4) {
                // SAFETY: `a` steps through the same reserved TABLE region, aligned
                // words no code, data or reference uses (see the read above).
                unsafe { write_volatile(a as *mut u32, u32::from_ne_bytes([FLASH_ERASED; 4])) };
            }
        }
    }

    fn start_busy(&mut self, ticks_needed: u32) {
        self.busy_until = Some(ticks().wrapping_add(ticks_needed));
    }
}

impl FlashStatus for TableFlash {
    fn busy(&mut self) -> bool {
        match self.busy_until {
            // Serial comparison: busy while `now` is before the deadline.
            Some(t) if (ticks().wrapping_sub(t) as i32) < 0 => true,
            _ => {
                self.busy_until = None;
                false
            }
        }
    }
}

impl ErrorType for TableFlash {
    type Error = FlashError;
}

impl ReadNorFlash for TableFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        REGION.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        REGION.capacity()
    }
}

impl NorFlash for TableFlash {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = FLASH_ERASE_SIZE as usize;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if !erase_aligned(from, to, FLASH_ERASE_SIZE) {
            return Err(FlashError::NotAligned);
        }
        REGION.check(from, (to - from) as usize)?;
        for a in from..to {
            // SAFETY: `check` put [from, to) inside the TABLE region, reserved in
            // memory.x (no code, data or Rust object there); byte writes of emulated
            // flash (RAM).
            unsafe { write_volatile(REGION.address(a) as *mut u8, FLASH_ERASED) };
        }
        let sectors = (to - from) / FLASH_ERASE_SIZE;
        self.start_busy(FLASH_ERASE_TICKS.saturating_mul(sectors));
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        REGION.check(offset, bytes.len())?;
        let base = REGION.address(offset);
        for (i, b) in bytes.iter().enumerate() {
            let p = (base + i) as *mut u8;
            // SAFETY: `check` put [offset, offset + len) inside the TABLE region, reserved
            // in memory.x (no code, data or Rust object there); a byte read.
            let old = unsafe { read_volatile(p) };
            if b & !old != 0 {
                return Err(FlashError::NotErased);
            }
            // SAFETY: the byte just read, inside the checked TABLE region; emulated
            // flash (RAM) that nothing else uses.
            unsafe { write_volatile(p, old & b) };
        }
        self.start_busy(FLASH_PROGRAM_TICKS);
        Ok(())
    }
}
