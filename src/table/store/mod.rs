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
//! # Parts
//! * [`records`]: the flash records as bytes, each layout once as named field ranges
//!   (the table record: commit header, written last, then the table; the selection
//!   record), their encoding, decoding and CRC-32.
//! * [`selection`]: what the operator selected to run, the two selection slots and
//!   which of them is newest.
//! * [`boot`]: which table boots, with the fallback to the compiled-in nominal table,
//!   and the [`BootReport`] saying which and why.
//! * [`write`]: the power-cut-safe, non-blocking write of a table record or a selection
//!   record (a state machine polled by the background task).
//! * Here: the [`TableStore`] itself, its [`BankLayout`], its errors and its reads of a
//!   bank's record.

use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};

use super::layout::Table;
use super::validate::ValidationError;

pub mod boot;
pub mod records;
pub mod selection;
pub mod write;

pub use boot::{
    boot_flags, BankStatus, BootReport, BootSource, BOOT_FLAGS_BANK_B_SHIFT,
    BOOT_FLAGS_SELECTION_SHIFT,
};
pub use records::{
    seq_newer, CommitHeader, BODY_SLOT_LEN, COMMIT_HEADER_LEN, COMMIT_MAGIC, ERASED,
    HEADER_SLOT_LEN, PARAMETERS_LEN, RECORD_ALIGN, RECORD_FORMAT_VERSION, RECORD_LEN,
    SELECTION_FORMAT_VERSION, SELECTION_LEN, SELECTION_MAGIC, SELECTION_SLOT_LEN,
};
pub use selection::Selection;
pub use write::{CommitReport, FlashStatus, WriteDone, WritePoll};

use records::{record_field, round_up};
use selection::Slot;
use write::Write;

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
        let at = self.record_offset(bank, record_field::HEADER.start);
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
        let at = self.record_offset(bank, record_field::BODY.start);
        self.flash
            .read(at, &mut body)
            .map_err(|_| BankStatus::ReadFailed)?;
        header.decode_body(&body)
    }

    /// Flash offset of byte `at` of `bank`'s record.
    fn record_offset(&self, bank: Bank, at: usize) -> u32 {
        self.bank_offset(bank) + at as u32
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
}
