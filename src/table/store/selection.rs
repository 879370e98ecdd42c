//! What the operator selected to run, and where the selection is kept.
//!
//! A [`Selection`] names the compiled-in nominal table, or bank A's or B's record by
//! its sequence number and table CRC; the selection record ([`super::records`],
//! `selection_field`) carries it with the operations parameters set on board (ST[20];
//! an opaque payload here). A new record (a new selection, or new parameters with the
//! selection unchanged) goes to the slot not holding the newest one (erase, write, read
//! back: [`super::write`]), so a power cut leaves the old or the new record, never
//! neither. The newest valid record is what boots ([`super::boot`]).

use embedded_storage::nor_flash::NorFlash;

use super::boot::BootSource;
use super::records::{seq_newer, ERASED, PARAMETERS_LEN, RECORD_LEN, SELECTION_SLOT_LEN};
use super::write::{FlashStatus, Write, WriteKind};
use super::{Bank, StoreError, TableStore};
use crate::link::wire::copy_prefix;
use crate::table::layout::Table;

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
}

/// One of the two selection slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Slot {
    A,
    B,
}

impl<F: NorFlash + FlashStatus> TableStore<F> {
    /// The newest valid selection record, if any.
    pub fn selection(&self) -> Option<Selection> {
        self.selection.map(|(s, _, _)| s)
    }

    fn slot_offset(&self, slot: Slot) -> u32 {
        match slot {
            Slot::A => self.layout.selection_a_offset,
            Slot::B => self.layout.selection_b_offset,
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
    pub(super) fn load_selection(&mut self) -> Option<Selection> {
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
        // The selection slot fits the image (the image is a table record's size).
        let _ = copy_prefix(&mut image, &selection.encode(sequence, parameters));
        self.write = Some(Write::new(
            WriteKind::Select {
                selection: *selection,
                parameters: *parameters,
                slot,
                sequence,
                runs,
            },
            base,
            F::ERASE_SIZE as u32,
            image,
            SELECTION_SLOT_LEN,
        ));
        Ok(())
    }
}
