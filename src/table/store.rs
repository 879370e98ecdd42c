//! A/B storage of the table in NOR flash, power-cut safe.
//!
//! # Banks
//! Two banks of [`BANK_SIZE`] bytes at [`BANK_A_OFFSET`] and [`BANK_B_OFFSET`]. Offsets
//! are **relative to the start of the flash device** the [`NorFlash`] implementation
//! drives; the board maps them onto the region `memory.x` keeps out of the image (on QEMU
//! mps2-an386: the top 128 KiB of the 4 MiB code flash). A different board passes its own
//! [`BankLayout`].
//!
//! # Record (one per bank, at the bank start)
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
//! # Update order (power-cut safety)
//! A new table goes to the bank **not** holding the active table:
//! 1. erase the record's sectors of that bank (the header bytes come first, so a
//!    partial erase already invalidates the bank);
//! 2. write the table and its padding, read back and compare;
//! 3. write the commit header with sequence = newest sequence + 1, read back and compare.
//!
//! Until step 3 completes the bank has no valid header and boot takes the other bank
//! (the old table). A header is valid only if its own CRC matches, and a body only if
//! its CRC matches the header's copy, so a torn header or body can never be taken. After
//! step 3 both banks are valid and the higher sequence (serial-number arithmetic, so the
//! wrap at 2^32 is harmless) wins. Each word is written once after the erase, as
//! [`NorFlash`] requires.
//!
//! # Boot
//! [`TableStore::boot`] reads both banks, tries the newest complete, CRC-valid record
//! first, then the other, re-validating each against the [`ValidationConfig`]; if neither
//! passes it returns the compiled-in [`Table::nominal`]. The [`BootReport`] says which
//! and why, for telemetry.

use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};

use super::layout::{stored_crc, Table, TableError, CRC32, TABLE_LEN};
use super::validate::{validate, ValidationConfig, ValidationError};

/// Size of the flash the flight layout assumes (bytes; QEMU mps2-an386 code flash).
pub const FLASH_SIZE: u32 = 0x40_0000;
/// Size of one bank (bytes; a power of two, a multiple of the erase size).
pub const BANK_SIZE: u32 = 0x1_0000;
/// Bank A offset from the flash start: the second-highest [`BANK_SIZE`] block.
pub const BANK_A_OFFSET: u32 = FLASH_SIZE - 2 * BANK_SIZE;
/// Bank B offset from the flash start: the highest [`BANK_SIZE`] block.
pub const BANK_B_OFFSET: u32 = FLASH_SIZE - BANK_SIZE;

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

const _: () = assert!(RECORD_LEN as u32 <= BANK_SIZE && BANK_SIZE.is_power_of_two());

/// Where the two banks are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BankLayout {
    /// Bank A offset from the flash start (bytes).
    pub bank_a_offset: u32,
    /// Bank B offset from the flash start (bytes).
    pub bank_b_offset: u32,
    /// Size of each bank (bytes).
    pub bank_size: u32,
}

/// The flight layout: two 64 KiB banks at the top of the 4 MiB flash.
pub const FLIGHT_LAYOUT: BankLayout = BankLayout {
    bank_a_offset: BANK_A_OFFSET,
    bank_b_offset: BANK_B_OFFSET,
    bank_size: BANK_SIZE,
};

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
    /// Where the active table came from.
    pub source: BootSource,
    /// Sequence number of the active record (0 for the nominal table).
    pub sequence: u32,
    /// Bank A's state.
    pub bank_a: BankStatus,
    /// Bank B's state.
    pub bank_b: BankStatus,
    /// A newer complete record was refused and an older one (or nominal) used.
    pub fell_back: bool,
}

impl BootReport {
    /// Packed flags: bank A in bits 0..7, [`boot_flags::FELL_BACK`] in bit 7, bank B in
    /// bits 8..15.
    pub const fn flags(&self) -> u16 {
        let fb = if self.fell_back {
            boot_flags::FELL_BACK
        } else {
            0
        };
        self.bank_a.flag() | fb | (self.bank_b.flag() << BOOT_FLAGS_BANK_B_SHIFT)
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

/// Result of a successful [`TableStore::commit`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommitReport {
    /// The bank written (now active).
    pub bank: Bank,
    /// Its sequence number.
    pub sequence: u32,
    /// CRC-32 of the table.
    pub table_crc: u32,
}

/// The table store: a [`NorFlash`] and where the banks are, plus which bank is active.
#[derive(Debug)]
pub struct TableStore<F> {
    flash: F,
    layout: BankLayout,
    active: BootSource,
    active_sequence: u32,
}

impl<F: NorFlash> TableStore<F> {
    /// Checks the layout against the flash: bank size a power of two and a multiple of
    /// the erase size, offsets erase-aligned, banks disjoint and inside the flash, the
    /// record fits, write/read sizes divide [`RECORD_ALIGN`].
    pub fn new(flash: F, layout: BankLayout) -> Result<Self, (F, StoreError)> {
        if Self::layout_ok(&flash, &layout) {
            Ok(Self {
                flash,
                layout,
                active: BootSource::Nominal,
                active_sequence: 0,
            })
        } else {
            Err((flash, StoreError::BadLayout))
        }
    }

    fn layout_ok(flash: &F, l: &BankLayout) -> bool {
        let erase = F::ERASE_SIZE as u64;
        let size = u64::from(l.bank_size);
        let (a, b) = (u64::from(l.bank_a_offset), u64::from(l.bank_b_offset));
        let cap = flash.capacity() as u64;
        let sizes_ok = F::WRITE_SIZE > 0
            && F::READ_SIZE > 0
            && RECORD_ALIGN % F::WRITE_SIZE == 0
            && RECORD_ALIGN % F::READ_SIZE == 0
            && erase > 0;
        sizes_ok
            && l.bank_size.is_power_of_two()
            && size % erase == 0
            && size >= RECORD_LEN as u64
            && a % erase == 0
            && b % erase == 0
            && a + size <= cap
            && b + size <= cap
            && (a + size <= b || b + size <= a)
    }

    /// The layout in use.
    pub fn layout(&self) -> BankLayout {
        self.layout
    }

    /// Where the active table is.
    pub fn active(&self) -> BootSource {
        self.active
    }

    /// Sequence number of the active record (0 when nominal).
    pub fn active_sequence(&self) -> u32 {
        self.active_sequence
    }

    /// Marks the nominal table active (e.g. "revert to nominal"); flash is unchanged,
    /// so the next commit goes to the bank with the older record.
    pub fn set_nominal_active(&mut self) {
        self.active = BootSource::Nominal;
        self.active_sequence = 0;
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

    /// Selects the table to run with: the newest complete, CRC-valid, validated record,
    /// else the other bank's, else [`Table::nominal`]. Never fails.
    pub fn boot(&mut self, cfg: &ValidationConfig) -> (Table, BootReport) {
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
        let order = match (seq_of(&a), seq_of(&b)) {
            (Some(sa), Some(sb)) if seq_newer(sb, sa) => [Bank::B, Bank::A],
            (None, Some(_)) => [Bank::B, Bank::A],
            _ => [Bank::A, Bank::B],
        };
        let mut status_a = a.as_ref().err().copied().unwrap_or(BankStatus::Blank);
        let mut status_b = b.as_ref().err().copied().unwrap_or(BankStatus::Blank);
        let mut chosen: Option<(Bank, u32, Table)> = None;
        for bank in order {
            let (rec, status) = match bank {
                Bank::A => (&a, &mut status_a),
                Bank::B => (&b, &mut status_b),
            };
            let Ok((h, t)) = rec else {
                continue;
            };
            if chosen.is_some() {
                *status = BankStatus::Standby {
                    sequence: h.sequence,
                };
                continue;
            }
            match validate(t, cfg) {
                Ok(()) => {
                    *status = BankStatus::Active {
                        sequence: h.sequence,
                    };
                    chosen = Some((bank, h.sequence, *t));
                }
                Err(e) => *status = BankStatus::Rejected(e),
            }
        }
        let (source, sequence, table) = match chosen {
            Some((bank, seq, t)) => (BootSource::from(bank), seq, t),
            None => (BootSource::Nominal, 0, Table::nominal()),
        };
        // The newest valid commit header was not the one booted: its body was corrupt or
        // its table was refused.
        let fell_back = newest_header.is_some() && newest_header != source.bank();
        self.active = source;
        self.active_sequence = sequence;
        (
            table,
            BootReport {
                source,
                sequence,
                bank_a: status_a,
                bank_b: status_b,
                fell_back,
            },
        )
    }

    /// The bank the next commit writes: the one not holding the active table; when the
    /// nominal table is active, the bank without a valid header or with the older one.
    pub fn inactive_bank(&mut self) -> Bank {
        if let Some(bank) = self.active.bank() {
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
            None => self.active_sequence.wrapping_add(1),
        }
    }

    fn write_verified(&mut self, at: u32, data: &[u8]) -> Result<(), StoreError> {
        self.flash.write(at, data).map_err(flash_err)?;
        let mut back = [0u8; RECORD_ALIGN];
        for (k, chunk) in data.chunks(RECORD_ALIGN).enumerate() {
            let off = at + (k * RECORD_ALIGN) as u32;
            let dst = back
                .get_mut(..chunk.len())
                .ok_or(StoreError::VerifyFailed)?;
            self.flash.read(off, dst).map_err(flash_err)?;
            if dst != chunk {
                return Err(StoreError::VerifyFailed);
            }
        }
        Ok(())
    }

    /// Validates `table` and writes it, with a new sequence number, into the inactive
    /// bank (erase, body, header last; each read back). On success that bank is active.
    /// On any error the previously active record is untouched.
    pub fn commit(
        &mut self,
        table: &Table,
        cfg: &ValidationConfig,
    ) -> Result<CommitReport, StoreError> {
        validate(table, cfg).map_err(StoreError::Invalid)?;
        self.write_record(table)
    }

    /// Writes `table` into the inactive bank **without validating it** (the caller has;
    /// tests use it to store deliberately bad tables).
    pub fn write_record(&mut self, table: &Table) -> Result<CommitReport, StoreError> {
        let bank = self.inactive_bank();
        let sequence = self.next_sequence();
        let base = self.bank_offset(bank);
        let erase_len = round_up(RECORD_LEN, F::ERASE_SIZE.max(1)) as u32;
        self.flash
            .erase(base, base + erase_len)
            .map_err(flash_err)?;
        let mut body = [ERASED; BODY_SLOT_LEN];
        let mut encoded = [0u8; TABLE_LEN];
        table.encode(&mut encoded);
        for (dst, src) in body.iter_mut().zip(encoded.iter()) {
            *dst = *src;
        }
        let table_crc = stored_crc(&encoded).unwrap_or(0);
        self.write_verified(base + HEADER_SLOT_LEN as u32, &body)?;
        let header = CommitHeader {
            sequence,
            table_crc,
        }
        .encode();
        self.write_verified(base, &header)?;
        self.active = BootSource::from(bank);
        self.active_sequence = sequence;
        Ok(CommitReport {
            bank,
            sequence,
            table_crc,
        })
    }

    /// Re-commits the inactive bank's own (older) table as the newest record, i.e.
    /// "switch bank". The table is validated first; a power cut leaves the active bank.
    pub fn promote_inactive(&mut self, cfg: &ValidationConfig) -> Result<CommitReport, StoreError> {
        let bank = self.inactive_bank();
        let (_, table) = self.read_bank(bank).map_err(StoreError::NoRecord)?;
        self.commit(&table, cfg)
    }
}
