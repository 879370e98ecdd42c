//! Which table boots.
//!
//! [`TableStore::boot`] follows the newest valid selection record: nominal, or the
//! named bank if its record is complete, CRC-valid, the one named (sequence and CRC) and
//! passes validation; otherwise it falls back to the nominal table (never to a table the
//! operator did not select). Without any valid selection record (flash written before
//! selections existed, or programmed on the ground) it takes the newest complete valid
//! bank, else the other, else nominal. The [`BootReport`] says which and why.

use embedded_storage::nor_flash::NorFlash;

use super::records::{seq_newer, CommitHeader};
use super::selection::Selection;
use super::write::FlashStatus;
use super::{Bank, TableStore};
use crate::table::layout::{Table, TableError};
use crate::table::validate::{validate, ValidationConfig, ValidationError};

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
    /// Stable numeric code for telemetry (0 nominal, 1 bank A, 2 bank B). Not inlined:
    /// five callers (12 bytes of flash less).
    #[inline(never)]
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

impl<F: NorFlash + FlashStatus> TableStore<F> {
    /// Selects the table to run with (this module's documentation). Never fails.
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
}
