//! A/B storage of the table in NOR flash, power-cut safe, with the operator's selection.
//!
//! # Banks
//! Two banks of `bank_size` bytes ([`BankLayout`], chosen by the board next to its
//! linker script: on QEMU mps2-an386 the top 128 KiB of the 4 MiB code flash). Offsets
//! are **relative to the start of the flash device** the [`NorFlash`] implementation
//! drives. Each bank holds one table record at its start; each bank also carries one
//! selection slot at `selection_*_offset` (its own erase sector, never erased with the
//! record).
//!
//! # Table record (one per bank, at the bank start)
//!
//! | bank offset | size | content                                                        |
//! |------------:|-----:|----------------------------------------------------------------|
//! |           0 |   32 | commit header, **written last** (below)                         |
//! |          32 |  544 | encoded table ([`TABLE_LEN`] bytes), then `0xFF` padding        |
//!
//! Commit header (little-endian): `0` magic `"M2CR"`, `4` u16 record format (1), `6` u16
//! header length (24), `8` u32 sequence number, `12` u32 table length, `16` u32 CRC-32 of
//! the table (equal to its trailing CRC), `20` u32 CRC-32 of header bytes 0..20, `24..32`
//! `0xFF`. Every padding byte must read `0xFF`, so every bit of the record is checked.
//!
//! # Selection record (one slot in each bank, 160 bytes)
//!
//! What the operator selected to run (the compiled-in nominal table, or bank A's or B's
//! record, named by its sequence number and table CRC), and the operations parameters
//! set on board (ST[20]; an opaque payload here). Little-endian: `0` magic `"M2SL"`, `4`
//! u16 format (2), `6` u8 choice ([`BootSource::code`]: 0 nominal, 1 A, 2 B), `7` u8
//! reserved 0, `8` u32 selection sequence, `12` u32 record sequence of the chosen bank (0
//! for nominal), `16` u32 table CRC-32 of the chosen table (nominal: its CRC), `20`
//! [`PARAMETERS_LEN`] bytes of parameters, `148` u32 CRC-32 of bytes 0..148, `152..160`
//! `0xFF`. A new record (a new selection, or new parameters with the selection
//! unchanged) goes to the slot not holding the newest one (erase, write, read back), so
//! a power cut leaves the old or the new record, never neither.
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
//! [`NorFlash`] requires. Committing does not change what boots: only a selection does.
//!
//! # Non-blocking operation
//! Erasing and programming NOR flash takes milliseconds to seconds. Writes are steps of
//! a state machine ([`TableStore::start_commit`], [`TableStore::start_select`],
//! [`TableStore::poll`]): each poll issues at most one erase (one sector) or one program
//! (one [`RECORD_ALIGN`] chunk, read back at the next poll) and returns at once while the
//! device is busy ([`FlashStatus::busy`]). The blocking [`TableStore::commit`] and
//! [`TableStore::select`] run the same state machine to completion.
//!
//! # Boot
//! [`TableStore::boot`] follows the newest valid selection record: nominal, or the
//! named bank if its record is complete, CRC-valid, the one named (sequence and CRC) and
//! passes validation; otherwise it falls back to the nominal table (never to a table the
//! operator did not select). Without any valid selection record (flash written before
//! selections existed, or programmed on the ground) it takes the newest complete valid
//! bank, else the other, else nominal. The [`BootReport`] says which and why.

use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};

use super::layout::{stored_crc, Table, TableError, CRC32, TABLE_LEN};
use super::validate::{validate, ValidationConfig, ValidationError};

/// Magic of a commit header.
pub const COMMIT_MAGIC: [u8; 4] = *b"M2CR";
/// Record format version.
pub const RECORD_FORMAT_VERSION: u16 = 1;
/// Bytes of the commit header: the fields and their CRC-32.
pub const COMMIT_HEADER_LEN: usize = 24;
/// Bytes of the commit header covered by its CRC.
const COMMIT_HEADER_CRC_OFFSET: usize = COMMIT_HEADER_LEN - 4;
/// Alignment of the record's parts (bytes): every write and read is a multiple of it,
/// so flashes with `WRITE_SIZE`/`READ_SIZE` dividing 32 are supported.
pub const RECORD_ALIGN: usize = 32;
/// Header slot (bytes): the commit header padded to [`RECORD_ALIGN`].
pub const HEADER_SLOT_LEN: usize = round_up(COMMIT_HEADER_LEN, RECORD_ALIGN);
/// Body slot (bytes): the table padded to [`RECORD_ALIGN`].
pub const BODY_SLOT_LEN: usize = round_up(TABLE_LEN, RECORD_ALIGN);
/// Whole record (bytes).
pub const RECORD_LEN: usize = HEADER_SLOT_LEN + BODY_SLOT_LEN;
/// The erased value of NOR flash.
pub const ERASED: u8 = 0xFF;

const fn round_up(v: usize, to: usize) -> usize {
    v.div_ceil(to) * to
}

/// Magic of a selection record.
pub const SELECTION_MAGIC: [u8; 4] = *b"M2SL";
/// Selection record format version (2: with the operations parameters).
pub const SELECTION_FORMAT_VERSION: u16 = 2;
/// Bytes of the operations-parameter payload a selection record carries (opaque here:
/// the controller's on-board parameters, ST[20]).
pub const PARAMETERS_LEN: usize = 128;
/// Offset of the parameter payload in the selection record.
const PARAMETERS_OFFSET: usize = 20;
/// Bytes of a selection record: the fields, the parameters and their CRC-32.
pub const SELECTION_LEN: usize = PARAMETERS_OFFSET + PARAMETERS_LEN + 4;
/// Bytes of the selection record covered by its CRC.
const SELECTION_CRC_OFFSET: usize = SELECTION_LEN - 4;
/// Selection slot (bytes): the record padded to [`RECORD_ALIGN`].
pub const SELECTION_SLOT_LEN: usize = round_up(SELECTION_LEN, RECORD_ALIGN);

/// Where the two banks and the two selection slots are (a board fact: the board
/// chooses it next to its linker script).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BankLayout {
    /// Bank A offset from the flash start (bytes).
    pub bank_a_offset: u32,
    /// Bank B offset from the flash start (bytes).
    pub bank_b_offset: u32,
    /// Size of each bank (bytes).
    pub bank_size: u32,
    /// Offset of the selection slot of bank A's side from the flash start (bytes): its
    /// own erase sector, outside both records' sectors.
    pub selection_a_offset: u32,
    /// Offset of the second selection slot (bytes).
    pub selection_b_offset: u32,
}

impl BankLayout {
    /// Two banks of `bank_size` bytes from `base`, A then B, with each selection slot
    /// half-way into its bank (the record takes the first sectors).
    pub const fn two_banks(base: u32, bank_size: u32) -> Self {
        Self {
            bank_a_offset: base,
            bank_b_offset: base + bank_size,
            bank_size,
            selection_a_offset: base + bank_size / 2,
            selection_b_offset: base + bank_size + bank_size / 2,
        }
    }
}

/// One of the two banks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bank {
    /// Bank A.
    A,
    /// Bank B.
    B,
}

impl Bank {
    /// The other bank.
    pub const fn other(self) -> Bank {
        match self {
            Bank::A => Bank::B,
            Bank::B => Bank::A,
        }
    }
}

/// Where the active table came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BootSource {
    /// Bank A's record.
    BankA,
    /// Bank B's record.
    BankB,
    /// The compiled-in nominal table (no bank holds a valid table, or reverted).
    Nominal,
}

impl BootSource {
    /// Stable numeric code for telemetry (0 nominal, 1 bank A, 2 bank B).
    pub const fn code(&self) -> u8 {
        match self {
            BootSource::Nominal => 0,
            BootSource::BankA => 1,
            BootSource::BankB => 2,
        }
    }

    /// The bank, if any.
    pub const fn bank(&self) -> Option<Bank> {
        match self {
            BootSource::BankA => Some(Bank::A),
            BootSource::BankB => Some(Bank::B),
            BootSource::Nominal => None,
        }
    }
}

impl From<Bank> for BootSource {
    fn from(b: Bank) -> Self {
        match b {
            Bank::A => BootSource::BankA,
            Bank::B => BootSource::BankB,
        }
    }
}

/// What boot found in one bank.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BankStatus {
    /// Header slot fully erased: never written, or erased by an interrupted update.
    Blank,
    /// The flash read failed.
    ReadFailed,
    /// Header not erased but not a valid commit header (torn write, bit flip).
    HeaderCorrupt,
    /// Valid header, but the body does not decode or does not match the header's CRC.
    BodyCorrupt(TableError),
    /// Complete and CRC-valid, but refused by validation.
    Rejected(ValidationError),
    /// Complete and CRC-valid, not selected (older); not re-validated.
    Standby {
        /// Its sequence number.
        sequence: u32,
    },
    /// Selected: complete, CRC-valid, validated.
    Active {
        /// Its sequence number.
        sequence: u32,
    },
}

/// Boot flag bits, per bank (bank A in bits 0..8, bank B in bits 8..16 by shifting with
/// [`BOOT_FLAGS_BANK_B_SHIFT`]).
pub mod boot_flags {
    /// Header slot erased.
    pub const BLANK: u16 = 1 << 0;
    /// Flash read error.
    pub const READ_FAILED: u16 = 1 << 1;
    /// Header corrupt.
    pub const HEADER_CORRUPT: u16 = 1 << 2;
    /// Body corrupt.
    pub const BODY_CORRUPT: u16 = 1 << 3;
    /// Refused by validation.
    pub const REJECTED: u16 = 1 << 4;
    /// Valid, older, not used.
    pub const STANDBY: u16 = 1 << 5;
    /// Selected.
    pub const ACTIVE: u16 = 1 << 6;
    /// Bank-independent: a newer record was skipped (the boot fell back).
    pub const FELL_BACK: u16 = 1 << 7;
}
/// Shift of bank B's flags in [`BootReport::flags`].
pub const BOOT_FLAGS_BANK_B_SHIFT: u32 = 8;
/// Shift of the selection bits in [`BootReport::flags_word`].
pub const BOOT_FLAGS_SELECTION_SHIFT: u32 = 16;

impl BankStatus {
    /// This status as [`boot_flags`] bits (unshifted).
    pub const fn flag(&self) -> u16 {
        match self {
            BankStatus::Blank => boot_flags::BLANK,
            BankStatus::ReadFailed => boot_flags::READ_FAILED,
            BankStatus::HeaderCorrupt => boot_flags::HEADER_CORRUPT,
            BankStatus::BodyCorrupt(_) => boot_flags::BODY_CORRUPT,
            BankStatus::Rejected(_) => boot_flags::REJECTED,
            BankStatus::Standby { .. } => boot_flags::STANDBY,
            BankStatus::Active { .. } => boot_flags::ACTIVE,
        }
    }
}

/// What boot chose and why (for housekeeping/events).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BootReport {
    /// The newest valid selection record (`None`: no valid selection record found).
    pub selection: Option<Selection>,
    /// Where the active table came from.
    pub source: BootSource,
    /// Sequence number of the active record (0 for the nominal table).
    pub sequence: u32,
    /// Bank A's state.
    pub bank_a: BankStatus,
    /// Bank B's state.
    pub bank_b: BankStatus,
    /// The selected table could not be booted (or, without a selection, a newer
    /// complete record was refused) and an older one or nominal was used.
    pub fell_back: bool,
}

impl BootReport {
    /// Packed flags: bank A in bits 0..7, [`boot_flags::FELL_BACK`] in bit 7, bank B in
    /// bits 8..15 (see [`BootReport::flags_word`] for the selection bits).
    pub const fn flags(&self) -> u16 {
        let fb = if self.fell_back {
            boot_flags::FELL_BACK
        } else {
            0
        };
        self.bank_a.flag() | fb | (self.bank_b.flag() << BOOT_FLAGS_BANK_B_SHIFT)
    }

    /// The boot flags with the selection in bits 16..23: bit 16 a valid selection
    /// record was found, bits 17..18 its choice ([`BootSource::code`]).
    pub const fn flags_word(&self) -> u32 {
        let sel = match self.selection {
            Some(s) => (1 | ((s.source.code() as u32) << 1)) << BOOT_FLAGS_SELECTION_SHIFT,
            None => 0,
        };
        self.flags() as u32 | sel
    }

    /// Validation code of the first rejected bank (0 if none), for telemetry.
    pub const fn rejection_code(&self) -> u16 {
        match (self.bank_a, self.bank_b) {
            (BankStatus::Rejected(e), _) | (_, BankStatus::Rejected(e)) => e.code(),
            _ => 0,
        }
    }
}

/// Why a store operation failed. Stable numeric codes (family 0x04xx, from 0x0430).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreError {
    /// The bank layout does not fit the flash (size, alignment, overlap).
    BadLayout,
    /// The flash driver failed.
    Flash(NorFlashErrorKind),
    /// The table was refused by validation; nothing was written.
    Invalid(ValidationError),
    /// Read-back after writing differs from what was written.
    VerifyFailed,
    /// The bank holds no complete, CRC-valid record.
    NoRecord(BankStatus),
    /// A write is already in progress (one at a time).
    Busy,
    /// The bank's record is not the one expected (sequence or CRC differ).
    NotExpected,
    /// The table's following-error thresholds, with the on-board overrides in force
    /// (parameters 0x0030, 0x0031), would leave the warning not below the fault
    /// threshold: the table is not selected, nothing was written.
    ThresholdConflict,
}

impl StoreError {
    /// Stable numeric code for telemetry.
    pub const fn code(&self) -> u16 {
        match self {
            StoreError::BadLayout => 0x0430,
            StoreError::Flash(_) => 0x0431,
            StoreError::Invalid(_) => 0x0432,
            StoreError::VerifyFailed => 0x0433,
            StoreError::NoRecord(_) => 0x0434,
            StoreError::Busy => 0x0435,
            StoreError::NotExpected => 0x0436,
            StoreError::ThresholdConflict => 0x0437,
        }
    }

    /// Failure datum for telemetry: the validation error's own code and detail for
    /// [`StoreError::Invalid`] (`code << 16 | detail`), the bank status flag for
    /// [`StoreError::NoRecord`], 0 otherwise.
    pub const fn data(&self) -> u32 {
        match self {
            StoreError::Invalid(v) => ((v.code() as u32) << 16) | v.detail() as u32,
            StoreError::NoRecord(s) => s.flag() as u32,
            _ => 0,
        }
    }
}

fn flash_err<E: NorFlashError>(e: E) -> StoreError {
    StoreError::Flash(e.kind())
}

/// A parsed, CRC-valid commit header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommitHeader {
    /// Sequence number (newer = larger, serial arithmetic).
    pub sequence: u32,
    /// CRC-32 of the table it commits.
    pub table_crc: u32,
}

impl CommitHeader {
    /// Encodes the header slot (header + `0xFF` padding).
    pub fn encode(&self) -> [u8; HEADER_SLOT_LEN] {
        let mut out = [ERASED; HEADER_SLOT_LEN];
        let mut h = [0u8; COMMIT_HEADER_LEN];
        let fields: [&[u8]; 5] = [
            &COMMIT_MAGIC,
            &RECORD_FORMAT_VERSION.to_le_bytes(),
            &(COMMIT_HEADER_LEN as u16).to_le_bytes(),
            &self.sequence.to_le_bytes(),
            &(TABLE_LEN as u32).to_le_bytes(),
        ];
        let table_crc = self.table_crc.to_le_bytes();
        let mut bytes = fields.iter().flat_map(|f| f.iter()).chain(table_crc.iter());
        for dst in h.iter_mut().take(COMMIT_HEADER_CRC_OFFSET) {
            *dst = bytes.next().copied().unwrap_or(ERASED);
        }
        let crc = h
            .get(..COMMIT_HEADER_CRC_OFFSET)
            .map_or(0, |b| CRC32.checksum(b));
        for (dst, src) in h
            .iter_mut()
            .skip(COMMIT_HEADER_CRC_OFFSET)
            .zip(crc.to_le_bytes())
        {
            *dst = src;
        }
        for (dst, src) in out.iter_mut().zip(h.iter()) {
            *dst = *src;
        }
        out
    }

    /// Parses a header slot: `Err(Blank)` if fully erased, `Err(HeaderCorrupt)` unless
    /// magic, version, lengths, CRC and padding are all right.
    pub fn decode(slot: &[u8; HEADER_SLOT_LEN]) -> Result<CommitHeader, BankStatus> {
        if slot.iter().all(|b| *b == ERASED) {
            return Err(BankStatus::Blank);
        }
        let corrupt = BankStatus::HeaderCorrupt;
        let word = |at: usize| -> Result<u32, BankStatus> {
            let b: [u8; 4] = slot
                .get(at..at + 4)
                .and_then(|s| s.try_into().ok())
                .ok_or(corrupt)?;
            Ok(u32::from_le_bytes(b))
        };
        let covered = slot.get(..COMMIT_HEADER_CRC_OFFSET).ok_or(corrupt)?;
        if CRC32.checksum(covered) != word(COMMIT_HEADER_CRC_OFFSET)? {
            return Err(corrupt);
        }
        let padding_ok = slot
            .get(COMMIT_HEADER_LEN..)
            .is_some_and(|p| p.iter().all(|b| *b == ERASED));
        let expected_format = u32::from(RECORD_FORMAT_VERSION) | ((COMMIT_HEADER_LEN as u32) << 16);
        if slot.get(..4) != Some(&COMMIT_MAGIC[..])
            || word(4)? != expected_format
            || word(12)? != TABLE_LEN as u32
            || !padding_ok
        {
            return Err(corrupt);
        }
        Ok(CommitHeader {
            sequence: word(8)?,
            table_crc: word(16)?,
        })
    }
}

/// `a` is newer than `b` in serial-number arithmetic (RFC 1982 style, 32 bit).
pub const fn seq_newer(a: u32, b: u32) -> bool {
    let d = a.wrapping_sub(b);
    d != 0 && d < (1 << 31)
}

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

/// What the operator selected to run (the content of a selection record).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Selection {
    /// The table source: nominal, or a bank.
    pub source: BootSource,
    /// Record sequence number of the chosen bank's table (0 for nominal).
    pub record_sequence: u32,
    /// CRC-32 of the chosen table.
    pub table_crc: u32,
}

impl Selection {
    /// The compiled-in nominal table.
    pub fn nominal() -> Self {
        Self {
            source: BootSource::Nominal,
            record_sequence: 0,
            table_crc: Table::nominal().crc32(),
        }
    }

    /// The table of `bank` committed with `sequence` and `table_crc`.
    pub const fn bank(bank: Bank, sequence: u32, table_crc: u32) -> Self {
        Self {
            source: match bank {
                Bank::A => BootSource::BankA,
                Bank::B => BootSource::BankB,
            },
            record_sequence: sequence,
            table_crc,
        }
    }

    /// Encodes a selection slot with selection sequence `sequence`, carrying the
    /// operations parameters `parameters`.
    pub fn encode(
        &self,
        sequence: u32,
        parameters: &[u8; PARAMETERS_LEN],
    ) -> [u8; SELECTION_SLOT_LEN] {
        let mut out = [ERASED; SELECTION_SLOT_LEN];
        let mut w = [0u8; SELECTION_LEN];
        let fields = SELECTION_MAGIC
            .iter()
            .copied()
            .chain(SELECTION_FORMAT_VERSION.to_le_bytes())
            .chain([self.source.code(), 0])
            .chain(sequence.to_le_bytes())
            .chain(self.record_sequence.to_le_bytes())
            .chain(self.table_crc.to_le_bytes())
            .chain(parameters.iter().copied());
        for (d, s) in w.iter_mut().zip(fields) {
            *d = s;
        }
        let crc = w
            .get(..SELECTION_CRC_OFFSET)
            .map_or(0, |b| CRC32.checksum(b));
        for (d, s) in w
            .iter_mut()
            .skip(SELECTION_CRC_OFFSET)
            .zip(crc.to_le_bytes())
        {
            *d = s;
        }
        for (d, s) in out.iter_mut().zip(w.iter()) {
            *d = *s;
        }
        out
    }

    /// Parses a selection slot: the selection, its sequence and its parameters, or
    /// `None` unless magic, format, choice, reserved byte, CRC and padding are all right.
    pub fn decode(
        slot: &[u8; SELECTION_SLOT_LEN],
    ) -> Option<(Selection, u32, [u8; PARAMETERS_LEN])> {
        let word = |at: usize| -> Option<u32> {
            let b: [u8; 4] = slot.get(at..at + 4)?.try_into().ok()?;
            Some(u32::from_le_bytes(b))
        };
        let covered = slot.get(..SELECTION_CRC_OFFSET)?;
        if CRC32.checksum(covered) != word(SELECTION_CRC_OFFSET)? {
            return None;
        }
        let padding_ok = slot
            .get(SELECTION_LEN..)
            .is_some_and(|p| p.iter().all(|b| *b == ERASED));
        let version = u16::from_le_bytes([*slot.get(4)?, *slot.get(5)?]);
        let source = match *slot.get(6)? {
            0 => BootSource::Nominal,
            1 => BootSource::BankA,
            2 => BootSource::BankB,
            _ => return None,
        };
        if slot.get(..4) != Some(&SELECTION_MAGIC[..])
            || version != SELECTION_FORMAT_VERSION
            || *slot.get(7)? != 0
            || !padding_ok
        {
            return None;
        }
        let parameters: [u8; PARAMETERS_LEN] = slot
            .get(PARAMETERS_OFFSET..PARAMETERS_OFFSET + PARAMETERS_LEN)?
            .try_into()
            .ok()?;
        Some((
            Selection {
                source,
                record_sequence: word(12)?,
                table_crc: word(16)?,
            },
            word(8)?,
            parameters,
        ))
    }
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

/// One of the two selection slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Slot {
    A,
    B,
}

/// What a write in progress is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum WriteKind {
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
struct Write {
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

/// The table store: a [`NorFlash`] and where the banks are, which table runs, which is
/// pending, and the write in progress.
#[derive(Debug)]
pub struct TableStore<F> {
    flash: F,
    layout: BankLayout,
    /// Where the running table came from.
    running: BootSource,
    /// Record sequence of the running table (0 when nominal).
    running_sequence: u32,
    /// A committed table not selected yet: its bank and commit report.
    pending: Option<CommitReport>,
    /// The newest valid selection record and its slot and sequence.
    selection: Option<(Selection, Slot, u32)>,
    /// The operations parameters of the newest valid selection record (all zero: none
    /// set).
    parameters: [u8; PARAMETERS_LEN],
    write: Option<Write>,
}

impl<F: NorFlash + FlashStatus> TableStore<F> {
    /// Checks the layout against the flash: bank size a power of two and a multiple of
    /// the erase size, offsets erase-aligned, banks and selection sectors disjoint and
    /// inside the flash, the record fits, write/read sizes divide [`RECORD_ALIGN`].
    pub fn new(flash: F, layout: BankLayout) -> Result<Self, (F, StoreError)> {
        if Self::layout_ok(&flash, &layout) {
            Ok(Self {
                flash,
                layout,
                running: BootSource::Nominal,
                running_sequence: 0,
                pending: None,
                selection: None,
                parameters: [0; PARAMETERS_LEN],
                write: None,
            })
        } else {
            Err((flash, StoreError::BadLayout))
        }
    }

    fn record_erase_len() -> u64 {
        round_up(RECORD_LEN, F::ERASE_SIZE.max(1)) as u64
    }

    fn layout_ok(flash: &F, l: &BankLayout) -> bool {
        let erase = F::ERASE_SIZE as u64;
        let size = u64::from(l.bank_size);
        let (a, b) = (u64::from(l.bank_a_offset), u64::from(l.bank_b_offset));
        let (sa, sb) = (
            u64::from(l.selection_a_offset),
            u64::from(l.selection_b_offset),
        );
        let cap = flash.capacity() as u64;
        let sizes_ok = F::WRITE_SIZE > 0
            && F::READ_SIZE > 0
            && RECORD_ALIGN % F::WRITE_SIZE == 0
            && RECORD_ALIGN % F::READ_SIZE == 0
            && erase > 0;
        if !sizes_ok {
            return false;
        }
        let rec = Self::record_erase_len();
        // Erase ranges: two records, two selection sectors; pairwise disjoint.
        let ranges = [
            (a, a + rec),
            (b, b + rec),
            (sa, sa + erase),
            (sb, sb + erase),
        ];
        let disjoint = ranges
            .iter()
            .enumerate()
            .all(|(i, r)| ranges.iter().skip(i + 1).all(|q| r.1 <= q.0 || q.1 <= r.0));
        l.bank_size.is_power_of_two()
            && size % erase == 0
            && size >= RECORD_LEN as u64
            && a % erase == 0
            && b % erase == 0
            && sa % erase == 0
            && sb % erase == 0
            && a + size <= cap
            && b + size <= cap
            && sa + erase <= cap
            && sb + erase <= cap
            && (a + size <= b || b + size <= a)
            && disjoint
    }

    /// The layout in use.
    pub fn layout(&self) -> BankLayout {
        self.layout
    }

    /// Where the running table came from.
    pub fn running(&self) -> BootSource {
        self.running
    }

    /// Record sequence number of the running table (0 when nominal).
    pub fn running_sequence(&self) -> u32 {
        self.running_sequence
    }

    /// The committed table waiting to be selected, if any.
    pub fn pending(&self) -> Option<CommitReport> {
        self.pending
    }

    /// The newest valid selection record, if any.
    pub fn selection(&self) -> Option<Selection> {
        self.selection.map(|(s, _, _)| s)
    }

    /// A write is in progress.
    pub fn writing(&self) -> bool {
        self.write.is_some()
    }

    /// The flash (tests: power cuts, bit flips).
    pub fn flash_mut(&mut self) -> &mut F {
        &mut self.flash
    }

    /// Gives the flash back.
    pub fn into_inner(self) -> F {
        self.flash
    }

    fn bank_offset(&self, bank: Bank) -> u32 {
        match bank {
            Bank::A => self.layout.bank_a_offset,
            Bank::B => self.layout.bank_b_offset,
        }
    }

    fn slot_offset(&self, slot: Slot) -> u32 {
        match slot {
            Slot::A => self.layout.selection_a_offset,
            Slot::B => self.layout.selection_b_offset,
        }
    }

    /// Reads a bank's commit header.
    pub fn read_header(&mut self, bank: Bank) -> Result<CommitHeader, BankStatus> {
        let mut slot = [0u8; HEADER_SLOT_LEN];
        let at = self.bank_offset(bank);
        self.flash
            .read(at, &mut slot)
            .map_err(|_| BankStatus::ReadFailed)?;
        CommitHeader::decode(&slot)
    }

    /// Reads a bank's record: header and table, both CRC-checked, padding checked.
    /// Not validated.
    pub fn read_bank(&mut self, bank: Bank) -> Result<(CommitHeader, Table), BankStatus> {
        let header = self.read_header(bank)?;
        let mut body = [0u8; BODY_SLOT_LEN];
        let at = self.bank_offset(bank) + HEADER_SLOT_LEN as u32;
        self.flash
            .read(at, &mut body)
            .map_err(|_| BankStatus::ReadFailed)?;
        let (table_bytes, padding) = body.split_at(TABLE_LEN.min(body.len()));
        let table = Table::decode(table_bytes).map_err(BankStatus::BodyCorrupt)?;
        if stored_crc(table_bytes) != Some(header.table_crc) {
            return Err(BankStatus::BodyCorrupt(TableError::BadCrc));
        }
        if !padding.iter().all(|b| *b == ERASED) {
            return Err(BankStatus::BodyCorrupt(TableError::ReservedNotZero));
        }
        Ok((header, table))
    }

    /// Reads the table selected by `sel` if it is still there, exactly (its bank's
    /// record complete, CRC-valid, with the named sequence and CRC). Not validated.
    pub fn read_selected(&mut self, sel: &Selection) -> Result<Table, StoreError> {
        match sel.source.bank() {
            None => Ok(Table::nominal()),
            Some(bank) => {
                let (h, t) = self.read_bank(bank).map_err(StoreError::NoRecord)?;
                if h.sequence == sel.record_sequence && h.table_crc == sel.table_crc {
                    Ok(t)
                } else {
                    Err(StoreError::NotExpected)
                }
            }
        }
    }

    /// The parameters of the newest valid selection record in flash now, read without
    /// changing what the store knows (tests, the soak: what a boot would restore).
    pub fn persisted_parameters(&mut self) -> [u8; PARAMETERS_LEN] {
        match (self.read_slot(Slot::A), self.read_slot(Slot::B)) {
            (Some((_, qa, pa)), Some((_, qb, pb))) => {
                if seq_newer(qb, qa) {
                    pb
                } else {
                    pa
                }
            }
            (Some((_, _, p)), None) | (None, Some((_, _, p))) => p,
            (None, None) => [0; PARAMETERS_LEN],
        }
    }

    /// Re-reads both selection slots from flash and returns the parameters of the newest
    /// valid one (the repair of a RAM upset: what the next boot would read, not the RAM
    /// copy).
    pub fn reread_parameters(&mut self) -> [u8; PARAMETERS_LEN] {
        self.load_selection();
        self.parameters
    }

    /// The operations parameters persisted with the newest selection record (all zero
    /// when none were ever stored).
    pub fn parameters(&self) -> [u8; PARAMETERS_LEN] {
        self.parameters
    }

    fn read_slot(&mut self, slot: Slot) -> Option<(Selection, u32, [u8; PARAMETERS_LEN])> {
        let mut buf = [0u8; SELECTION_SLOT_LEN];
        let at = self.slot_offset(slot);
        self.flash.read(at, &mut buf).ok()?;
        Selection::decode(&buf)
    }

    /// Reads both selection slots; remembers and returns the newest valid one.
    fn load_selection(&mut self) -> Option<Selection> {
        let a = self.read_slot(Slot::A);
        let b = self.read_slot(Slot::B);
        let newest = match (a, b) {
            (Some((sa, qa, pa)), Some((sb, qb, pb))) => {
                if seq_newer(qb, qa) {
                    Some((sb, Slot::B, qb, pb))
                } else {
                    Some((sa, Slot::A, qa, pa))
                }
            }
            (Some((sa, qa, pa)), None) => Some((sa, Slot::A, qa, pa)),
            (None, Some((sb, qb, pb))) => Some((sb, Slot::B, qb, pb)),
            (None, None) => None,
        };
        self.selection = newest.map(|(s, slot, q, _)| (s, slot, q));
        self.parameters = newest.map_or([0; PARAMETERS_LEN], |(_, _, _, p)| p);
        self.selection()
    }

    /// Selects the table to run with (module documentation, "Boot"). Never fails.
    pub fn boot(&mut self, cfg: &ValidationConfig) -> (Table, BootReport) {
        self.write = None;
        self.pending = None;
        let selection = self.load_selection();
        let newest_header = match (self.read_header(Bank::A), self.read_header(Bank::B)) {
            (Ok(ha), Ok(hb)) if seq_newer(hb.sequence, ha.sequence) => Some(Bank::B),
            (Ok(_), _) => Some(Bank::A),
            (Err(_), Ok(_)) => Some(Bank::B),
            (Err(_), Err(_)) => None,
        };
        let a = self.read_bank(Bank::A);
        let b = self.read_bank(Bank::B);
        let seq_of = |r: &Result<(CommitHeader, Table), BankStatus>| match r {
            Ok((h, _)) => Some(h.sequence),
            Err(_) => None,
        };
        // Which banks may run, in preference order.
        let candidates: [Option<Bank>; 2] = match selection {
            Some(sel) => [sel.source.bank(), None],
            None => match (seq_of(&a), seq_of(&b)) {
                (Some(sa), Some(sb)) if seq_newer(sb, sa) => [Some(Bank::B), Some(Bank::A)],
                (None, Some(_)) => [Some(Bank::B), Some(Bank::A)],
                _ => [Some(Bank::A), Some(Bank::B)],
            },
        };
        let mut status_a = a.as_ref().err().copied().unwrap_or(BankStatus::Blank);
        let mut status_b = b.as_ref().err().copied().unwrap_or(BankStatus::Blank);
        let mut chosen: Option<(Bank, u32, Table)> = None;
        for bank in candidates.into_iter().flatten() {
            let (rec, status) = match bank {
                Bank::A => (&a, &mut status_a),
                Bank::B => (&b, &mut status_b),
            };
            let Ok((h, t)) = rec else {
                continue;
            };
            if let Some(sel) = selection {
                if h.sequence != sel.record_sequence || h.table_crc != sel.table_crc {
                    *status = BankStatus::Standby {
                        sequence: h.sequence,
                    };
                    continue;
                }
            }
            match validate(t, cfg) {
                Ok(()) => {
                    *status = BankStatus::Active {
                        sequence: h.sequence,
                    };
                    chosen = Some((bank, h.sequence, *t));
                    break;
                }
                Err(e) => *status = BankStatus::Rejected(e),
            }
        }
        // Every other complete record is standby.
        for (rec, status) in [(&a, &mut status_a), (&b, &mut status_b)] {
            if let (Ok((h, _)), BankStatus::Blank) = (rec, *status) {
                *status = BankStatus::Standby {
                    sequence: h.sequence,
                };
            }
        }
        let (source, sequence, table) = match chosen {
            Some((bank, seq, t)) => (BootSource::from(bank), seq, t),
            None => (BootSource::Nominal, 0, Table::nominal()),
        };
        let fell_back = match selection {
            // The selected bank could not be booted.
            Some(sel) => sel.source != source,
            // The newest valid commit header was not the one booted.
            None => newest_header.is_some() && newest_header != source.bank(),
        };
        self.running = source;
        self.running_sequence = sequence;
        (
            table,
            BootReport {
                selection,
                source,
                sequence,
                bank_a: status_a,
                bank_b: status_b,
                fell_back,
            },
        )
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
        let header = CommitHeader {
            sequence,
            table_crc,
        }
        .encode();
        for (d, s) in image.iter_mut().zip(header.iter().chain(encoded.iter())) {
            *d = *s;
        }
        let report = CommitReport {
            bank,
            sequence,
            table_crc,
        };
        self.pending = None;
        self.write = Some(Write {
            kind: WriteKind::Commit(report),
            base,
            erase_end: base.saturating_add(Self::record_erase_len() as u32),
            image,
            len: RECORD_LEN,
            phase: Phase::Erase(base),
        });
        Ok(report)
    }

    /// Starts persisting `selection` (with the current parameters) into the slot not
    /// holding the newest selection.
    pub fn start_select(&mut self, selection: &Selection) -> Result<(), StoreError> {
        let parameters = self.parameters;
        self.start_record(selection, &parameters, true)
    }

    /// Starts persisting new operations `parameters` with the current selection (with
    /// none yet: the selection of the running table, so what boots does not change).
    /// What runs does not change either: after a boot that fell back to nominal, the
    /// selection record still names the bank that could not boot.
    pub fn start_parameters(
        &mut self,
        parameters: &[u8; PARAMETERS_LEN],
    ) -> Result<(), StoreError> {
        let selection = match self.selection() {
            Some(s) => s,
            None => self.running_selection(),
        };
        self.start_record(&selection, parameters, false)
    }

    /// The selection describing the running table.
    pub fn running_selection(&mut self) -> Selection {
        match self.running.bank() {
            None => Selection::nominal(),
            Some(bank) => match self.read_header(bank) {
                Ok(h) => Selection::bank(bank, h.sequence, h.table_crc),
                Err(_) => Selection::bank(bank, self.running_sequence, 0),
            },
        }
    }

    fn start_record(
        &mut self,
        selection: &Selection,
        parameters: &[u8; PARAMETERS_LEN],
        runs: bool,
    ) -> Result<(), StoreError> {
        if self.write.is_some() {
            return Err(StoreError::Busy);
        }
        let (slot, sequence) = match self.selection {
            Some((_, Slot::A, q)) => (Slot::B, q.wrapping_add(1)),
            Some((_, Slot::B, q)) => (Slot::A, q.wrapping_add(1)),
            None => (Slot::A, 1),
        };
        let base = self.slot_offset(slot);
        let mut image = [ERASED; RECORD_LEN];
        for (d, s) in image
            .iter_mut()
            .zip(selection.encode(sequence, parameters).iter())
        {
            *d = *s;
        }
        self.write = Some(Write {
            kind: WriteKind::Select {
                selection: *selection,
                parameters: *parameters,
                slot,
                sequence,
                runs,
            },
            base,
            erase_end: base.saturating_add(F::ERASE_SIZE as u32),
            image,
            len: SELECTION_SLOT_LEN,
            phase: Phase::Erase(base),
        });
        Ok(())
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
