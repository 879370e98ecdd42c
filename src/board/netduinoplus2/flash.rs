//! Table flash: sectors 8 to 11 (128 KiB each, 0x0808_0000..0x0810_0000), the TABLE
//! region of memory/netduinoplus2.x. Four sectors because the store erases four ranges
//! separately (two records, two selection slots): bank A = sectors 8 (record) and 9
//! (selection slot), bank B = sectors 10 and 11. Offsets are from the flash start.
//! Driven by its registers (RM0090 3.6): an erase or program is started and
//! [`FlashStatus::busy`] reads BSY.
#![allow(unsafe_code)] // Flash interface registers, memory-mapped flash.

use core::ptr::write_volatile;

use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use stm32f4xx_hal::pac;

use crate::board::memory_x;
pub use crate::board::table_flash::FlashError;
use crate::board::table_flash::{erase_aligned, TableRegion};
use crate::table::{BankLayout, FlashStatus};

/// Memory-mapped start of the flash.
const FLASH_BASE: usize = 0x0800_0000;
/// Flash size (bytes).
const FLASH_SIZE: u32 = 0x10_0000;
/// Sector size in the TABLE region (bytes).
const TABLE_SECTOR_BYTES: u32 = 0x2_0000;
/// First sector of the TABLE region, and its offset.
const TABLE_FIRST_SECTOR: u32 = 8;
const TABLE_REGION_START: u32 = 0x8_0000;
/// The 128 KiB sectors 5..=11 start at `(n - SECTOR_NUMBER_OFFSET) * 128 KiB` (sectors
/// 0..=4 fill the first 128 KiB).
const SECTOR_NUMBER_OFFSET: u32 = 4;
/// Bank size (bytes): a record sector and a selection sector.
const TABLE_BANK_SIZE: u32 = 2 * TABLE_SECTOR_BYTES;
/// The table banks of this board.
pub const TABLE_LAYOUT: BankLayout = BankLayout::two_banks(TABLE_REGION_START, TABLE_BANK_SIZE);
const _: () = assert!(memory_x::TABLE_ORIGIN as usize == FLASH_BASE + TABLE_REGION_START as usize);
const _: () = assert!(memory_x::TABLE_LENGTH == 2 * TABLE_BANK_SIZE);
const _: () = assert!(TABLE_REGION_START + 2 * TABLE_BANK_SIZE == FLASH_SIZE);
const _: () =
    assert!(TABLE_REGION_START == (TABLE_FIRST_SECTOR - SECTOR_NUMBER_OFFSET) * TABLE_SECTOR_BYTES);
// SAFETY: [FLASH_BASE + TABLE_REGION_START, FLASH_BASE + FLASH_SIZE) is the TABLE
// region of memory/netduinoplus2.x (the asserts above): sectors 8 to 11 of the
// memory-mapped flash, reserved (no code, data or Rust object there), byte-readable,
// used only through TableFlash.
const REGION: TableRegion = unsafe { TableRegion::new(FLASH_BASE, TABLE_REGION_START, FLASH_SIZE) };
/// Erased byte value.
const FLASH_ERASED: u8 = 0xFF;
/// Unlock keys (RM0090 3.5.1).
const FLASH_KEY1: u32 = 0x4567_0123;
const FLASH_KEY2: u32 = 0xCDEF_89AB;
/// SR error flags: programming sequence, parallelism, alignment, write protection,
/// operation (RM0090 3.9.4); write 1 to clear.
const FLASH_SR_ERRORS: u32 = (1 << 7) | (1 << 6) | (1 << 5) | (1 << 4) | (1 << 1);

/// The TABLE region as NOR flash.
pub struct TableFlash(pub(super) pac::FLASH);

impl TableFlash {
    fn bsy(&self) -> bool {
        self.0.sr().read().bsy().bit_is_set()
    }

    /// Waits for the operation under way, unlocks, and reports (and clears) the error
    /// flags of the last operation.
    fn ready(&mut self) -> Result<(), FlashError> {
        while self.bsy() {}
        let f = &self.0;
        if f.cr().read().lock().bit_is_set() {
            f.keyr().write(|w| w.key().set(FLASH_KEY1));
            f.keyr().write(|w| w.key().set(FLASH_KEY2));
        }
        let errors = f.sr().read().bits() & FLASH_SR_ERRORS;
        if errors != 0 {
            // SAFETY: the PAC cannot check a whole-register value. SR's error flags are
            // write-1-to-clear (RM0090 3.9.4) and `errors` holds only those (masked with
            // FLASH_SR_ERRORS): the write clears exactly them; EOP's 0 and the read-only
            // and reserved bits' 0 change nothing.
            f.sr().write(|w| unsafe { w.bits(errors) });
            return Err(FlashError::Device);
        }
        Ok(())
    }
}

impl FlashStatus for TableFlash {
    fn busy(&mut self) -> bool {
        self.bsy()
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
    const ERASE_SIZE: usize = TABLE_SECTOR_BYTES as usize;
    /// Starts the erase of each sector in `[from, to)` (waiting for the previous one):
    /// returns while the last one runs ([`FlashStatus::busy`]).
    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if !erase_aligned(from, to, TABLE_SECTOR_BYTES) {
            return Err(FlashError::NotAligned);
        }
        REGION.check(from, (to - from) as usize)?;
        for index in (from / TABLE_SECTOR_BYTES)..(to / TABLE_SECTOR_BYTES) {
            let sector = index + SECTOR_NUMBER_OFFSET;
            self.ready()?;
            // x32 parallelism (2.7 to 3.6 V supply), sector erase, sector number, start.
            self.0.cr().write(|w| {
                w.psize().set(0b10);
                w.ser().set_bit();
                // SAFETY: SNB takes a sector number 0..=11 (RM0090 3.9.7; the PAC's
                // writer is unchecked because the SVD gives no range): `check` above
                // keeps [from, to) inside the TABLE region, so `sector` is 8..=11.
                unsafe { w.snb().bits(sector as u8) };
                w.strt().set_bit()
            });
        }
        Ok(())
    }
    /// Programs byte by byte (x8), waiting for each; bits can only be cleared.
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        REGION.check_programmable(offset, bytes)?;
        let base = REGION.address(offset);
        self.ready()?;
        self.0.cr().write(|w| {
            w.psize().set(0b00);
            w.pg().set_bit()
        });
        let mut result = Ok(());
        for (i, b) in bytes.iter().enumerate() {
            if *b == FLASH_ERASED {
                continue;
            }
            // SAFETY: a byte inside the checked TABLE region (reserved, no Rust object
            // there), written with PG set and PSIZE x8: the flash interface's program
            // operation (RM0090 3.6.3), one byte, awaited below.
            unsafe { write_volatile((base + i) as *mut u8, *b) };
            while self.bsy() {}
            if self.0.sr().read().bits() & FLASH_SR_ERRORS != 0 {
                result = Err(FlashError::Device);
                break;
            }
        }
        self.0.cr().write(|w| w.pg().clear_bit());
        result
    }
}
