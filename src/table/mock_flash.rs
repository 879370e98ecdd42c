//! Host-only NOR flash model with power cuts, for the power-cut and bit-flip tests.
//!
//! NOR semantics: erase sets bytes to `0xFF`; a write can only clear bits: writing a 1
//! over a 0 is refused ([`MockFlashError::BitRaise`]), and so is writing a word twice
//! between erases ([`MockFlashError::DoubleWrite`], as the [`NorFlash`] contract says).
//!
//! Power cuts: every byte erased or written is one *step*. With
//! [`MockFlash::cut_power_after`]`(n)` the flash performs `n` more steps and then loses
//! power in the middle of the operation: the bytes before the cut are done, the rest of
//! that operation is untouched (an erase leaves a partially erased sector: bytes before
//! the cut erased, the rest old). With [`TearMode::TornByte`] the byte at the cut is also
//! half-done (a write clears only some of its bits, an erase sets only some). After a
//! cut every operation fails with [`MockFlashError::PowerLoss`] until
//! [`MockFlash::power_cycle`].
//!
//! Time: a real NOR device erases a sector in 0.5-2 s and programs a few hundred bytes
//! in about a millisecond, while the CPU goes on. With [`MockFlash::set_timing`] the mock
//! answers [`FlashStatus::busy`] for a number of calls after each erase or write (the
//! simulated bench calls the store once per control cycle, so that number is the
//! operation's duration in cycles); by default it is never busy.

use super::store::FlashStatus;
use embedded_storage::nor_flash::{
    check_erase, check_read, check_write, ErrorType, NorFlash, NorFlashError, NorFlashErrorKind,
    ReadNorFlash,
};

/// Bits a torn write still clears at the cut byte: only those also clear in this mask
/// survive as written (the rest keep their old value).
pub const TORN_WRITE_KEEP_MASK: u8 = 0xAA;
/// Bits a torn erase sets at the cut byte.
pub const TORN_ERASE_SET_MASK: u8 = 0x55;

/// What happens to the byte at which power is cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TearMode {
    /// The byte at the cut is untouched.
    Clean,
    /// The byte at the cut is half-programmed / half-erased.
    TornByte,
}

/// Errors of the mock flash.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MockFlashError {
    /// Alignment or bounds ([`NorFlashErrorKind`]).
    Kind(NorFlashErrorKind),
    /// Power was lost (during this operation or before).
    PowerLoss,
    /// A write would set a bit that is 0 (byte offset).
    BitRaise(u32),
    /// A word was written twice without an erase in between (byte offset of the word).
    DoubleWrite(u32),
}

impl NorFlashError for MockFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            MockFlashError::Kind(k) => *k,
            _ => NorFlashErrorKind::Other,
        }
    }
}

/// Counters of what the flash did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MockStats {
    /// Byte steps performed since creation (erase + write).
    pub steps: u64,
    /// Erase calls.
    pub erases: u64,
    /// Write calls.
    pub writes: u64,
}

/// In-memory NOR flash with `W`-byte write words and `E`-byte erase sectors.
#[derive(Clone, Debug)]
pub struct MockFlash<const W: usize = 4, const E: usize = 4096> {
    mem: Vec<u8>,
    /// Word written since its last erase.
    written: Vec<bool>,
    /// Steps left before the power cut; `None`: no cut armed.
    budget: Option<u64>,
    powered: bool,
    tear: TearMode,
    stats: MockStats,
    /// Busy answers after an erase / a write ([`MockFlash::set_timing`]).
    erase_busy_polls: u32,
    write_busy_polls: u32,
    /// Busy answers left for the operation in progress.
    busy_left: u32,
}

impl<const W: usize, const E: usize> MockFlash<W, E> {
    /// An erased flash of `capacity` bytes.
    pub fn new(capacity: usize) -> Self {
        Self {
            mem: vec![0xFF; capacity],
            written: vec![false; capacity.div_ceil(W.max(1))],
            budget: None,
            powered: true,
            tear: TearMode::Clean,
            stats: MockStats::default(),
            erase_busy_polls: 0,
            write_busy_polls: 0,
            busy_left: 0,
        }
    }

    /// Models operation times: after an erase [`FlashStatus::busy`] answers `true`
    /// `erase_polls` times, after a write `write_polls` times.
    pub fn set_timing(&mut self, erase_polls: u32, write_polls: u32) {
        self.erase_busy_polls = erase_polls;
        self.write_busy_polls = write_polls;
    }

    /// Arms a power cut after `steps` more byte steps (0: the next step is cut).
    pub fn cut_power_after(&mut self, steps: u64, tear: TearMode) {
        self.budget = Some(steps);
        self.tear = tear;
    }

    /// Disarms any pending cut.
    pub fn disarm(&mut self) {
        self.budget = None;
    }

    /// Restores power (and disarms any pending cut): the flash content stays as the cut
    /// left it.
    pub fn power_cycle(&mut self) {
        self.powered = true;
        self.budget = None;
    }

    /// Power was cut and not yet restored.
    pub fn is_powered(&self) -> bool {
        self.powered
    }

    /// Counters.
    pub fn stats(&self) -> MockStats {
        self.stats
    }

    /// The raw content.
    pub fn bytes(&self) -> &[u8] {
        &self.mem
    }

    /// Flips one bit (radiation upset), bypassing NOR rules. `false` if out of range.
    pub fn flip_bit(&mut self, offset: usize, bit: u8) -> bool {
        match self.mem.get_mut(offset) {
            Some(b) => {
                *b ^= 1u8 << (bit & 7);
                true
            }
            None => false,
        }
    }

    /// Takes one step; `false` if power is cut at this step.
    fn step(&mut self) -> bool {
        if let Some(left) = self.budget {
            if left == 0 {
                self.powered = false;
                self.budget = None;
                return false;
            }
            self.budget = Some(left - 1);
        }
        self.stats.steps += 1;
        true
    }

    fn check_power(&self) -> Result<(), MockFlashError> {
        if self.powered {
            Ok(())
        } else {
            Err(MockFlashError::PowerLoss)
        }
    }
}

impl<const W: usize, const E: usize> ErrorType for MockFlash<W, E> {
    type Error = MockFlashError;
}

impl<const W: usize, const E: usize> ReadNorFlash for MockFlash<W, E> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.check_power()?;
        check_read(self, offset, bytes.len()).map_err(MockFlashError::Kind)?;
        let start = offset as usize;
        let src = self
            .mem
            .get(start..start + bytes.len())
            .ok_or(MockFlashError::Kind(NorFlashErrorKind::OutOfBounds))?;
        bytes.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl<const W: usize, const E: usize> NorFlash for MockFlash<W, E> {
    const WRITE_SIZE: usize = W;
    const ERASE_SIZE: usize = E;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.check_power()?;
        check_erase(self, from, to).map_err(MockFlashError::Kind)?;
        self.stats.erases += 1;
        self.busy_left = self.erase_busy_polls;
        for i in from as usize..to as usize {
            if !self.step() {
                if self.tear == TearMode::TornByte {
                    if let Some(b) = self.mem.get_mut(i) {
                        *b |= TORN_ERASE_SET_MASK;
                    }
                }
                return Err(MockFlashError::PowerLoss);
            }
            if let Some(b) = self.mem.get_mut(i) {
                *b = 0xFF;
            }
            if i % W == 0 {
                if let Some(w) = self.written.get_mut(i / W) {
                    *w = false;
                }
            }
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.check_power()?;
        check_write(self, offset, bytes.len()).map_err(MockFlashError::Kind)?;
        let start = offset as usize;
        // Contract checks first, on the whole operation.
        for (k, new) in bytes.iter().enumerate() {
            let i = start + k;
            let old = self.mem.get(i).copied().unwrap_or(0);
            if old & new != *new {
                return Err(MockFlashError::BitRaise(i as u32));
            }
            if i % W == 0 && self.written.get(i / W).copied().unwrap_or(false) {
                return Err(MockFlashError::DoubleWrite(i as u32));
            }
        }
        self.stats.writes += 1;
        self.busy_left = self.write_busy_polls;
        for (k, new) in bytes.iter().enumerate() {
            let i = start + k;
            if i % W == 0 {
                if let Some(w) = self.written.get_mut(i / W) {
                    *w = true;
                }
            }
            if !self.step() {
                if self.tear == TearMode::TornByte {
                    if let Some(b) = self.mem.get_mut(i) {
                        *b &= new | TORN_WRITE_KEEP_MASK;
                    }
                }
                return Err(MockFlashError::PowerLoss);
            }
            if let Some(b) = self.mem.get_mut(i) {
                *b &= new;
            }
        }
        Ok(())
    }
}

impl<const W: usize, const E: usize> FlashStatus for MockFlash<W, E> {
    fn busy(&mut self) -> bool {
        if self.busy_left > 0 {
            self.busy_left -= 1;
            true
        } else {
            false
        }
    }
}
