//! What the two boards' table flashes share, written once: the refusal reasons
//! ([`FlashError`]), the bounds of the TABLE region, byte reads of the memory-mapped
//! flash, the erase alignment and the NOR rule (a program may only clear bits). How a
//! board erases and programs (RAM emulation with a modelled busy time on mps2-an386,
//! the flash interface's registers on the STM32) stays in the board's `flash.rs`.
#![allow(unsafe_code)] // Byte reads of the memory-mapped TABLE region.

use core::ptr::read_volatile;

use embedded_storage::nor_flash::{NorFlashError, NorFlashErrorKind};

/// Why a table-flash operation was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    /// Outside the table region.
    OutOfBounds,
    /// An erase not covering whole sectors (erase size).
    NotAligned,
    /// A write tried to set a bit that is 0 (NOR can only clear bits before an erase).
    NotErased,
    /// The flash interface reported an error (sequence, protection, alignment): only
    /// the board with a flash interface has it (mps2-an386 emulates its flash in RAM).
    #[cfg(feature = "board-netduinoplus2")]
    Device,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::NotErased => NorFlashErrorKind::Other,
            #[cfg(feature = "board-netduinoplus2")]
            FlashError::Device => NorFlashErrorKind::Other,
        }
    }
}

/// A board's TABLE region: offsets `start..size` of a flash mapped at `base` (offsets
/// are from the start of the flash, as `table::store` expects).
#[derive(Clone, Copy, Debug)]
pub struct TableRegion {
    /// Address of offset 0 (the flash's first byte).
    base: usize,
    /// First offset the table store may read, write or erase (bytes).
    start: u32,
    /// Size of the flash: one past the last offset of the region (bytes).
    size: u32,
}

impl TableRegion {
    /// The region `start..size` of a flash mapped at `base`.
    ///
    /// # Safety
    /// Addresses `base + start .. base + size` must be the TABLE region reserved in the
    /// board's memory map (`memory.x`): byte-readable memory where nothing is linked and
    /// no Rust object or reference lives, used only through this region's owner.
    pub const unsafe fn new(base: usize, start: u32, size: u32) -> Self {
        Self { base, start, size }
    }

    /// The flash's size (bytes): the store's capacity.
    pub const fn capacity(&self) -> usize {
        self.size as usize
    }

    /// The address of the byte at `offset` (inside the region after [`Self::check`]).
    pub const fn address(&self, offset: u32) -> usize {
        self.base + offset as usize
    }

    /// `len` bytes from `from` lie inside the region.
    pub fn check(&self, from: u32, len: usize) -> Result<(), FlashError> {
        let end = (from as usize)
            .checked_add(len)
            .ok_or(FlashError::OutOfBounds)?;
        if from < self.start || end > self.size as usize {
            return Err(FlashError::OutOfBounds);
        }
        Ok(())
    }

    /// The byte at `offset`, which [`Self::check`] put inside the region (private:
    /// both callers check first).
    fn byte(&self, offset: usize) -> u8 {
        // SAFETY: both callers pass offsets `check` put inside the region, which the
        // constructor's contract makes reserved, byte-readable memory (emulated flash
        // in RAM, or memory-mapped flash: during an erase the bus stalls, no fault)
        // that no Rust object or reference covers.
        unsafe { read_volatile((self.base + offset) as *const u8) }
    }

    /// Reads `bytes.len()` bytes from `offset`.
    pub fn read(&self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        self.check(offset, bytes.len())?;
        for (i, b) in bytes.iter_mut().enumerate() {
            *b = self.byte(offset as usize + i);
        }
        Ok(())
    }

    /// A program of `bytes` at `offset` is allowed: inside the region, and no byte
    /// sets a bit that is 0 now (the NOR rule). Checked whole before anything is
    /// written, so a refused program changes nothing.
    pub fn check_programmable(&self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        self.check(offset, bytes.len())?;
        for (i, b) in bytes.iter().enumerate() {
            if b & !self.byte(offset as usize + i) != 0 {
                return Err(FlashError::NotErased);
            }
        }
        Ok(())
    }
}

/// `from..to` is whole erase units of `erase_bytes` (an erase of anything else is
/// refused with [`FlashError::NotAligned`]).
pub const fn erase_aligned(from: u32, to: u32, erase_bytes: u32) -> bool {
    from <= to && from % erase_bytes == 0 && to % erase_bytes == 0
}
