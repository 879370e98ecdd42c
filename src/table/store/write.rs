//! Writing a record: power-cut safe and non-blocking.
//!
//! # Update order (power-cut safety)
//! A new table goes to the bank **not** holding the running table ([`TableStore::target_bank`]):
//! 1. erase the record's sectors of that bank (the header bytes come first, so a
//!    partial erase already invalidates the bank);
//! 2. write the table and its padding, read back and compare;
//! 3. write the commit header with sequence = newest sequence + 1, read back and compare.
//!
//! Until step 3 completes the bank has no valid header. A header is valid only if its
//! own CRC matches, and a body only if its CRC matches the header's copy, so a torn
//! header or body can never be taken. Each word is written once after the erase, as
//! [`NorFlash`] requires. Committing does not change what boots: only a selection does
//! (written the same way into a selection slot, [`super::selection`]).
//!
//! # Non-blocking operation
//! Erasing and programming NOR flash takes milliseconds to seconds. Writes are steps of
//! a state machine ([`TableStore::start_commit`], [`TableStore::start_select`],
//! [`TableStore::poll`]): each poll issues at most one erase (one sector) or one program
//! (one [`RECORD_ALIGN`] chunk, read back at the next poll) and returns at once while the
//! device is busy ([`FlashStatus::busy`]). The blocking [`TableStore::commit`] and
//! [`TableStore::select`] run the same state machine to completion.

use embedded_storage::nor_flash::NorFlash;

use super::records::{seq_newer, CommitHeader, ERASED, PARAMETERS_LEN, RECORD_ALIGN, RECORD_LEN};
use super::selection::{Selection, Slot};
use super::{flash_err, Bank, StoreError, TableStore};
use crate::table::layout::{stored_crc, Table, TABLE_LEN};
use crate::table::validate::{validate, ValidationConfig};

/// Result of a successful commit: where the table went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommitReport {
    /// The bank written (now holding the pending table).
    pub bank: Bank,
    /// Its sequence number.
    pub sequence: u32,
    /// CRC-32 of the table.
    pub table_crc: u32,
}

/// Whether a flash device is still erasing or programming. A device whose
/// [`NorFlash::erase`]/[`NorFlash::write`] return when the operation is done answers
/// `false` always; one that starts the operation and returns (QEMU's modelled flash,
/// the host mock in timed mode, a real NOR controller) answers `true` until it is done,
/// and the store issues nothing meanwhile.
pub trait FlashStatus {
    /// The last erase or program has not finished yet.
    fn busy(&mut self) -> bool;
}

/// What a write in progress is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum WriteKind {
    /// A table record into `bank`.
    Commit(CommitReport),
    /// A selection record into `slot` with selection sequence `sequence`; `runs`: the
    /// selection becomes what runs (activate, switch bank, revert), or the record only
    /// carries new parameters and what runs does not change (after a boot that fell
    /// back, the selected bank is not what runs).
    Select {
        selection: Selection,
        parameters: [u8; PARAMETERS_LEN],
        slot: Slot,
        sequence: u32,
        runs: bool,
    },
}

/// The phase of a write in progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Erasing; the next sector starts at this offset.
    Erase(u32),
    /// Programming chunk `index` of the image next; `verify` = chunk `index - 1` was
    /// programmed and must be read back first.
    Program { index: usize, verify: bool },
}

/// A record being written: the image (body chunks first, header chunk last), where it
/// goes and how far it got.
#[derive(Clone, Copy, Debug)]
pub(super) struct Write {
    kind: WriteKind,
    /// Flash offset of the image's first byte (the header slot).
    base: u32,
    /// End of the erase range (exclusive).
    erase_end: u32,
    /// The image: header slot then body, exactly as it lands in flash.
    image: [u8; RECORD_LEN],
    /// Bytes of `image` in use.
    len: usize,
    phase: Phase,
}

impl Write {
    /// Writing the first `len` bytes of `image` at `base`, after erasing `erase_len`
    /// bytes from there.
    pub(super) fn new(
        kind: WriteKind,
        base: u32,
        erase_len: u32,
        image: [u8; RECORD_LEN],
        len: usize,
    ) -> Self {
        Self {
            kind,
            base,
            erase_end: base.saturating_add(erase_len),
            image,
            len,
            phase: Phase::Erase(base),
        }
    }

    /// Chunks of the image in programming order: the body chunks (1..), then the header
    /// chunk (0) last.
    fn chunks(&self) -> usize {
        self.len.div_ceil(RECORD_ALIGN)
    }

    /// Image chunk programmed at step `index` (the header chunk last).
    fn chunk_at(&self, index: usize) -> Option<usize> {
        let n = self.chunks();
        if index + 1 < n {
            Some(index + 1)
        } else if index + 1 == n {
            Some(0)
        } else {
            None
        }
    }
}

/// What a finished write did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WriteDone {
    /// A table record was committed (now pending).
    Committed(CommitReport),
    /// A selection was persisted (now running).
    Selected(Selection),
}

/// Progress of [`TableStore::poll`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WritePoll {
    /// Nothing in progress.
    Idle,
    /// In progress: poll again.
    Pending,
    /// Finished with this outcome (reported once).
    Done(Result<WriteDone, StoreError>),
}

impl<F: NorFlash + FlashStatus> TableStore<F> {
    /// A write is in progress.
    pub fn writing(&self) -> bool {
        self.write.is_some()
    }

    /// The bank the next commit writes: never the running table's; with the nominal
    /// table running, the bank without a valid header, else the one with the older
    /// record (a pending table there is replaced).
    pub fn target_bank(&mut self) -> Bank {
        if let Some(bank) = self.running.bank() {
            return bank.other();
        }
        match (self.read_header(Bank::A), self.read_header(Bank::B)) {
            (Ok(ha), Ok(hb)) if seq_newer(ha.sequence, hb.sequence) => Bank::B,
            (Ok(_), Err(_)) => Bank::B,
            _ => Bank::A,
        }
    }

    /// Sequence number for the next record: one past the newest valid header.
    fn next_sequence(&mut self) -> u32 {
        let seqs = [self.read_header(Bank::A), self.read_header(Bank::B)];
        let mut newest: Option<u32> = None;
        for h in seqs.iter().flatten() {
            newest = match newest {
                Some(n) if !seq_newer(h.sequence, n) => Some(n),
                _ => Some(h.sequence),
            };
        }
        match newest {
            Some(n) => n.wrapping_add(1),
            None => self.running_sequence.wrapping_add(1),
        }
    }

    /// Starts writing `table` into [`TableStore::target_bank`] **without validating
    /// it** (the caller has; tests use it to store deliberately bad tables). Any pending
    /// table is forgotten (its bank may be the one overwritten).
    #[inline(never)] // its record image is not on the stack during a validation
    pub fn start_commit(&mut self, table: &Table) -> Result<CommitReport, StoreError> {
        if self.write.is_some() {
            return Err(StoreError::Busy);
        }
        let bank = self.target_bank();
        let sequence = self.next_sequence();
        let base = self.bank_offset(bank);
        let mut image = [ERASED; RECORD_LEN];
        let mut encoded = [0u8; TABLE_LEN];
        table.encode(&mut encoded);
        let table_crc = stored_crc(&encoded).unwrap_or(0);
        // The image has exactly the record's length: every field fits.
        let _ = CommitHeader {
            sequence,
            table_crc,
        }
        .encode_record(&encoded, &mut image);
        let report = CommitReport {
            bank,
            sequence,
            table_crc,
        };
        self.pending = None;
        self.write = Some(Write::new(
            WriteKind::Commit(report),
            base,
            Self::record_erase_len() as u32,
            image,
            RECORD_LEN,
        ));
        Ok(report)
    }

    /// Advances the write in progress by at most one flash operation (module
    /// documentation, "Non-blocking operation").
    pub fn poll(&mut self) -> WritePoll {
        let Some(mut w) = self.write else {
            return WritePoll::Idle;
        };
        if self.flash.busy() {
            return WritePoll::Pending;
        }
        match self.advance(&mut w) {
            Ok(false) => {
                self.write = Some(w);
                WritePoll::Pending
            }
            Ok(true) => {
                self.write = None;
                WritePoll::Done(Ok(self.finish(&w.kind)))
            }
            Err(e) => {
                self.write = None;
                WritePoll::Done(Err(e))
            }
        }
    }

    /// One flash operation of `w`; `Ok(true)` when the write is complete and verified.
    fn advance(&mut self, w: &mut Write) -> Result<bool, StoreError> {
        match w.phase {
            Phase::Erase(at) => {
                let sector = F::ERASE_SIZE.max(1) as u32;
                if at < w.erase_end {
                    let end = at.saturating_add(sector).min(w.erase_end);
                    self.flash.erase(at, end).map_err(flash_err)?;
                    w.phase = Phase::Erase(end);
                } else {
                    w.phase = Phase::Program {
                        index: 0,
                        verify: false,
                    };
                }
                Ok(false)
            }
            Phase::Program { index, verify } => {
                if verify {
                    let chunk = w.chunk_at(index.wrapping_sub(1));
                    if let Some(c) = chunk {
                        self.verify_chunk(w, c)?;
                    }
                }
                match w.chunk_at(index) {
                    Some(c) => {
                        let at = c * RECORD_ALIGN;
                        let end = (at + RECORD_ALIGN).min(w.len);
                        let data = w.image.get(at..end).ok_or(StoreError::VerifyFailed)?;
                        self.flash
                            .write(w.base + at as u32, data)
                            .map_err(flash_err)?;
                        w.phase = Phase::Program {
                            index: index + 1,
                            verify: true,
                        };
                        Ok(false)
                    }
                    None => Ok(true),
                }
            }
        }
    }

    fn verify_chunk(&mut self, w: &Write, chunk: usize) -> Result<(), StoreError> {
        let at = chunk * RECORD_ALIGN;
        let end = (at + RECORD_ALIGN).min(w.len);
        let want = w.image.get(at..end).ok_or(StoreError::VerifyFailed)?;
        let mut back = [0u8; RECORD_ALIGN];
        let dst = back.get_mut(..want.len()).ok_or(StoreError::VerifyFailed)?;
        self.flash
            .read(w.base + at as u32, dst)
            .map_err(flash_err)?;
        if dst != want {
            return Err(StoreError::VerifyFailed);
        }
        Ok(())
    }

    fn finish(&mut self, kind: &WriteKind) -> WriteDone {
        match *kind {
            WriteKind::Commit(report) => {
                self.pending = Some(report);
                WriteDone::Committed(report)
            }
            WriteKind::Select {
                selection,
                parameters,
                slot,
                sequence,
                runs,
            } => {
                self.selection = Some((selection, slot, sequence));
                self.parameters = parameters;
                if runs {
                    self.running = selection.source;
                    self.running_sequence = selection.record_sequence;
                    if let (Some(p), Some(bank)) = (self.pending, selection.source.bank()) {
                        if p.bank == bank {
                            self.pending = None;
                        }
                    }
                }
                WriteDone::Selected(selection)
            }
        }
    }

    /// Runs the write in progress to completion (blocking: tests, boot-time tools).
    fn complete(&mut self) -> Result<WriteDone, StoreError> {
        loop {
            match self.poll() {
                WritePoll::Pending => {}
                WritePoll::Done(r) => return r,
                WritePoll::Idle => return Err(StoreError::Busy),
            }
        }
    }

    /// Validates `table` and writes it into [`TableStore::target_bank`], blocking. On
    /// success it is the pending table (what boots does not change); on any error the
    /// running table's record is untouched.
    pub fn commit(
        &mut self,
        table: &Table,
        cfg: &ValidationConfig,
    ) -> Result<CommitReport, StoreError> {
        validate(table, cfg).map_err(StoreError::Invalid)?;
        self.write_record(table)
    }

    /// Writes `table` into the target bank **without validating it**, blocking.
    pub fn write_record(&mut self, table: &Table) -> Result<CommitReport, StoreError> {
        let report = self.start_commit(table)?;
        match self.complete()? {
            WriteDone::Committed(r) => Ok(r),
            WriteDone::Selected(_) => Ok(report),
        }
    }

    /// Persists `selection`, blocking. On success it is what boots and runs.
    pub fn select(&mut self, selection: &Selection) -> Result<(), StoreError> {
        self.start_select(selection)?;
        self.complete().map(|_| ())
    }
}
