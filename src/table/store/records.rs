//! The store's flash records as bytes: each layout once, as named field ranges (the
//! `*_field` modules, smoltcp's `mod field`, sequential-storage's item header), their
//! encoding, their decoding and their CRC-32 seal.
//!
//! All multi-byte fields are little-endian. Every byte of a slot is checked when it is
//! read: the fields, the CRC, and the padding (which must read [`ERASED`]), so a torn
//! write or a flipped bit is never taken for a record.
//!
//! * A bank holds one table record at its start ([`record_field`]): the commit header
//!   slot ([`commit_field`]), **written last**, then the body slot ([`body_field`]): the
//!   encoded table, then padding.
//! * Each bank also carries one selection slot ([`selection_field`]), in its own erase
//!   sector.

use crate::link::wire::{Field, Fields, FieldsMut, Order, Writer};
use crate::table::layout::{stored_crc, Table, TableError, CRC32, TABLE_LEN};

use super::boot::{BankStatus, BootSource};
use super::selection::Selection;

/// Magic of a commit header.
pub const COMMIT_MAGIC: [u8; 4] = *b"M2CR";
/// Record format version.
pub const RECORD_FORMAT_VERSION: u16 = 1;
/// Bytes of the commit header: the fields and their CRC-32.
pub const COMMIT_HEADER_LEN: usize = commit_field::CRC.end;
/// Alignment of the record's parts (bytes): every write and read is a multiple of it,
/// so flashes with `WRITE_SIZE`/`READ_SIZE` dividing 32 are supported.
pub const RECORD_ALIGN: usize = 32;
/// Header slot (bytes): the commit header padded to [`RECORD_ALIGN`].
pub const HEADER_SLOT_LEN: usize = round_up(COMMIT_HEADER_LEN, RECORD_ALIGN);
/// Body slot (bytes): the table padded to [`RECORD_ALIGN`].
pub const BODY_SLOT_LEN: usize = round_up(TABLE_LEN, RECORD_ALIGN);
/// Whole record (bytes).
pub const RECORD_LEN: usize = record_field::BODY.end;
/// The erased value of NOR flash.
pub const ERASED: u8 = 0xFF;

/// `v` rounded up to a multiple of `to`.
pub(super) const fn round_up(v: usize, to: usize) -> usize {
    v.div_ceil(to) * to
}

/// Magic of a selection record.
pub const SELECTION_MAGIC: [u8; 4] = *b"M2SL";
/// Selection record format version (2: with the operations parameters).
pub const SELECTION_FORMAT_VERSION: u16 = 2;
/// Bytes of the operations-parameter payload a selection record carries (opaque here:
/// the controller's on-board parameters, ST[20]).
pub const PARAMETERS_LEN: usize = 128;
/// Bytes of a selection record: the fields, the parameters and their CRC-32.
pub const SELECTION_LEN: usize = selection_field::CRC.end;
/// Selection slot (bytes): the record padded to [`RECORD_ALIGN`].
pub const SELECTION_SLOT_LEN: usize = round_up(SELECTION_LEN, RECORD_ALIGN);

/// The table record in a bank, from the bank start.
pub mod record_field {
    use super::{BODY_SLOT_LEN, HEADER_SLOT_LEN};
    use crate::link::wire::{after, field, Field};

    /// The commit header slot ([`super::commit_field`]), programmed last.
    pub const HEADER: Field = field(0, HEADER_SLOT_LEN);
    /// The body slot ([`super::body_field`]).
    pub const BODY: Field = after(&HEADER, BODY_SLOT_LEN);
}

/// The commit header slot, from its start.
pub mod commit_field {
    use super::HEADER_SLOT_LEN;
    use crate::link::wire::{after, field, Field};

    /// 4 bytes: [`super::COMMIT_MAGIC`].
    pub const MAGIC: Field = field(0, 4);
    /// u16: [`super::RECORD_FORMAT_VERSION`].
    pub const FORMAT: Field = after(&MAGIC, 2);
    /// u16: the header's length, [`super::COMMIT_HEADER_LEN`].
    pub const HEADER_LEN: Field = after(&FORMAT, 2);
    /// u32: record sequence number (newer = larger, serial arithmetic).
    pub const SEQUENCE: Field = after(&HEADER_LEN, 4);
    /// u32: the table's length, [`crate::table::TABLE_LEN`].
    pub const TABLE_LENGTH: Field = after(&SEQUENCE, 4);
    /// u32: CRC-32 of the table (equal to its trailing CRC).
    pub const TABLE_CRC: Field = after(&TABLE_LENGTH, 4);
    /// u32: CRC-32 of [`COVERED`].
    pub const CRC: Field = after(&TABLE_CRC, 4);
    /// The bytes [`CRC`] covers: every field before it.
    pub const COVERED: Field = field(0, CRC.start);
    /// [`super::ERASED`] up to the slot's end.
    pub const PADDING: Field = CRC.end..HEADER_SLOT_LEN;
}

/// The body slot, from its start.
pub mod body_field {
    use super::BODY_SLOT_LEN;
    use crate::link::wire::{field, Field};
    use crate::table::TABLE_LEN;

    /// The encoded table ([`crate::table::Table::encode`]).
    pub const TABLE: Field = field(0, TABLE_LEN);
    /// [`super::ERASED`] up to the slot's end.
    pub const PADDING: Field = TABLE.end..BODY_SLOT_LEN;
}

/// The selection slot, from its start.
pub mod selection_field {
    use super::{PARAMETERS_LEN, SELECTION_SLOT_LEN};
    use crate::link::wire::{after, field, Field};

    /// 4 bytes: [`super::SELECTION_MAGIC`].
    pub const MAGIC: Field = field(0, 4);
    /// u16: [`super::SELECTION_FORMAT_VERSION`].
    pub const FORMAT: Field = after(&MAGIC, 2);
    /// u8: the choice, [`super::BootSource::code`] (0 nominal, 1 A, 2 B).
    pub const CHOICE: Field = after(&FORMAT, 1);
    /// u8: reserved, 0.
    pub const RESERVED: Field = after(&CHOICE, 1);
    /// u32: selection sequence number (newer = larger, serial arithmetic).
    pub const SEQUENCE: Field = after(&RESERVED, 4);
    /// u32: record sequence number of the chosen bank's table (0 for nominal).
    pub const RECORD_SEQUENCE: Field = after(&SEQUENCE, 4);
    /// u32: CRC-32 of the chosen table (nominal: its CRC).
    pub const TABLE_CRC: Field = after(&RECORD_SEQUENCE, 4);
    /// [`super::PARAMETERS_LEN`] bytes: the operations parameters (opaque here).
    pub const PARAMETERS: Field = after(&TABLE_CRC, PARAMETERS_LEN);
    /// u32: CRC-32 of [`COVERED`].
    pub const CRC: Field = after(&PARAMETERS, 4);
    /// The bytes [`CRC`] covers: every field before it.
    pub const COVERED: Field = field(0, CRC.start);
    /// [`super::ERASED`] up to the slot's end.
    pub const PADDING: Field = CRC.end..SELECTION_SLOT_LEN;
}

// The slots are what the formats have always been (the ones in flight stay readable),
// and every slot is tiled by its fields.
const _: () = {
    assert!(COMMIT_HEADER_LEN == 24 && HEADER_SLOT_LEN == 32);
    assert!(SELECTION_LEN == 152 && SELECTION_SLOT_LEN == 160);
    assert!(commit_field::PADDING.end == HEADER_SLOT_LEN);
    assert!(body_field::PADDING.end == BODY_SLOT_LEN);
    assert!(selection_field::PADDING.end == SELECTION_SLOT_LEN);
    assert!(RECORD_LEN == HEADER_SLOT_LEN + BODY_SLOT_LEN);
};

/// All `bytes` read [`ERASED`].
pub(super) fn erased(bytes: &[u8]) -> bool {
    bytes.iter().all(|b| *b == ERASED)
}

/// Writes the CRC-32 of the `covered` bytes of `slot` into its `crc` field.
fn seal(slot: &mut [u8], covered: Field, crc: Field) -> Option<()> {
    let sum = CRC32.checksum(slot.get(covered)?);
    FieldsMut::new(slot, Order::Little).set_u32(crc, sum)
}

/// The `crc` field of `f` holds the CRC-32 of its `covered` bytes.
fn sealed(f: &Fields<'_>, covered: Field, crc: Field) -> Option<bool> {
    Some(CRC32.checksum(f.bytes(covered)?) == f.u32(crc)?)
}

/// `a` is newer than `b` in serial-number arithmetic (RFC 1982 style, 32 bit).
pub const fn seq_newer(a: u32, b: u32) -> bool {
    let d = a.wrapping_sub(b);
    d != 0 && d < (1 << 31)
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
        // The slot has exactly the layout's length: every field fits.
        let _ = self.write(&mut out);
        out
    }

    /// Writes the fields of [`commit_field`] in their order (each named: on the host
    /// one out of place fails the write), then the CRC.
    fn write(&self, slot: &mut [u8; HEADER_SLOT_LEN]) -> Option<()> {
        use commit_field::*;
        let mut w = Writer::new(slot, Order::Little);
        w.at(0, &MAGIC)?;
        w.put(&COMMIT_MAGIC)?;
        w.at(0, &FORMAT)?;
        w.u16(RECORD_FORMAT_VERSION)?;
        w.at(0, &HEADER_LEN)?;
        w.u16(COMMIT_HEADER_LEN as u16)?;
        w.at(0, &SEQUENCE)?;
        w.u32(self.sequence)?;
        w.at(0, &TABLE_LENGTH)?;
        w.u32(TABLE_LEN as u32)?;
        w.at(0, &TABLE_CRC)?;
        w.u32(self.table_crc)?;
        w.at(0, &CRC)?;
        seal(slot, COVERED, CRC)
    }

    /// Parses a header slot: `Err(Blank)` if fully erased, `Err(HeaderCorrupt)` unless
    /// magic, version, lengths, CRC and padding are all right.
    pub fn decode(slot: &[u8; HEADER_SLOT_LEN]) -> Result<CommitHeader, BankStatus> {
        if erased(slot) {
            return Err(BankStatus::Blank);
        }
        Self::parse(&Fields::new(slot, Order::Little)).ok_or(BankStatus::HeaderCorrupt)
    }

    fn parse(f: &Fields<'_>) -> Option<CommitHeader> {
        use commit_field::*;
        let valid = sealed(f, COVERED, CRC)?
            && f.bytes(MAGIC)? == COMMIT_MAGIC
            && f.u16(FORMAT)? == RECORD_FORMAT_VERSION
            && f.u16(HEADER_LEN)? == COMMIT_HEADER_LEN as u16
            && f.u32(TABLE_LENGTH)? == TABLE_LEN as u32
            && erased(f.bytes(PADDING)?);
        if !valid {
            return None;
        }
        Some(CommitHeader {
            sequence: f.u32(SEQUENCE)?,
            table_crc: f.u32(TABLE_CRC)?,
        })
    }

    /// The record of this header and a body slot: the table decodes, its CRC is this
    /// header's copy, and the padding is erased. (Returning the whole record lets the
    /// caller's return slot hold the table: one table on the stack, not two.)
    pub fn decode_body(
        self,
        body: &[u8; BODY_SLOT_LEN],
    ) -> Result<(CommitHeader, Table), BankStatus> {
        use body_field::*;
        let f = Fields::new(body, Order::Little);
        // Both fields are inside the slot (checked at compile time above).
        let table = f.bytes(TABLE).unwrap_or_default();
        let padding = f.bytes(PADDING).unwrap_or_default();
        let decoded = Table::decode(table).map_err(BankStatus::BodyCorrupt)?;
        if stored_crc(table) != Some(self.table_crc) {
            return Err(BankStatus::BodyCorrupt(TableError::BadCrc));
        }
        if !erased(padding) {
            return Err(BankStatus::BodyCorrupt(TableError::ReservedNotZero));
        }
        Ok((self, decoded))
    }

    /// Writes the record this header commits into `image` ([`record_field`]): the
    /// header slot, then the body slot with the encoded `table`; the padding is left as
    /// `image` holds it (the caller fills it with [`ERASED`]).
    pub(super) fn encode_record(
        &self,
        table: &[u8; TABLE_LEN],
        image: &mut [u8; RECORD_LEN],
    ) -> Option<()> {
        let mut w = Writer::new(image, Order::Little);
        w.at(0, &record_field::HEADER)?;
        w.put(&self.encode())?;
        w.at(0, &record_field::BODY)?;
        let body = record_field::BODY.start;
        w.at(body, &body_field::TABLE)?;
        w.put(table)
    }
}

impl Selection {
    /// Encodes a selection slot with selection sequence `sequence`, carrying the
    /// operations parameters `parameters`.
    pub fn encode(
        &self,
        sequence: u32,
        parameters: &[u8; PARAMETERS_LEN],
    ) -> [u8; SELECTION_SLOT_LEN] {
        let mut out = [ERASED; SELECTION_SLOT_LEN];
        // The slot has exactly the layout's length: every field fits.
        let _ = self.write(sequence, parameters, &mut out);
        out
    }

    /// Writes the fields of [`selection_field`] in their order (each named: on the
    /// host one out of place fails the write), then the CRC.
    fn write(
        &self,
        sequence: u32,
        parameters: &[u8; PARAMETERS_LEN],
        slot: &mut [u8; SELECTION_SLOT_LEN],
    ) -> Option<()> {
        use selection_field::*;
        let mut w = Writer::new(slot, Order::Little);
        w.at(0, &MAGIC)?;
        w.put(&SELECTION_MAGIC)?;
        w.at(0, &FORMAT)?;
        w.u16(SELECTION_FORMAT_VERSION)?;
        w.at(0, &CHOICE)?;
        w.u8(self.source.code())?;
        w.at(0, &RESERVED)?;
        w.u8(0)?;
        w.at(0, &SEQUENCE)?;
        w.u32(sequence)?;
        w.at(0, &RECORD_SEQUENCE)?;
        w.u32(self.record_sequence)?;
        w.at(0, &TABLE_CRC)?;
        w.u32(self.table_crc)?;
        w.at(0, &PARAMETERS)?;
        w.put(parameters)?;
        w.at(0, &CRC)?;
        seal(slot, COVERED, CRC)
    }

    /// Parses a selection slot: the selection, its sequence and its parameters, or
    /// `None` unless magic, format, choice, reserved byte, CRC and padding are all right.
    pub fn decode(
        slot: &[u8; SELECTION_SLOT_LEN],
    ) -> Option<(Selection, u32, [u8; PARAMETERS_LEN])> {
        use selection_field::*;
        let f = Fields::new(slot, Order::Little);
        let source = match f.u8(CHOICE)? {
            0 => BootSource::Nominal,
            1 => BootSource::BankA,
            2 => BootSource::BankB,
            _ => return None,
        };
        let valid = sealed(&f, COVERED, CRC)?
            && f.bytes(MAGIC)? == SELECTION_MAGIC
            && f.u16(FORMAT)? == SELECTION_FORMAT_VERSION
            && f.u8(RESERVED)? == 0
            && erased(f.bytes(PADDING)?);
        if !valid {
            return None;
        }
        Some((
            Selection {
                source,
                record_sequence: f.u32(RECORD_SEQUENCE)?,
                table_crc: f.u32(TABLE_CRC)?,
            },
            f.u32(SEQUENCE)?,
            f.bytes(PARAMETERS)?.try_into().ok()?,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::table::store::Bank;

    /// The little-endian u32 of four bytes.
    fn le_u32(b: &[u8]) -> u32 {
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }

    /// The documented byte positions, written out independently of the field modules.
    #[test]
    fn records_land_at_their_documented_offsets() {
        let h = CommitHeader {
            sequence: 0x0403_0201,
            table_crc: 0xDDCC_BBAA,
        };
        let slot = h.encode();
        assert_eq!(&slot[0..4], b"M2CR");
        assert_eq!(&slot[4..8], &[1, 0, 24, 0]);
        assert_eq!(&slot[8..12], &[1, 2, 3, 4]);
        assert_eq!(le_u32(&slot[12..16]) as usize, TABLE_LEN);
        assert_eq!(&slot[16..20], &[0xAA, 0xBB, 0xCC, 0xDD]);
        let crc = CRC32.checksum(&slot[..20]);
        assert_eq!(le_u32(&slot[20..24]), crc);
        assert!(slot[24..].iter().all(|b| *b == 0xFF));
        assert_eq!(CommitHeader::decode(&slot), Ok(h));

        let sel = Selection::bank(Bank::B, 7, 0x1122_3344);
        let params: [u8; PARAMETERS_LEN] = core::array::from_fn(|i| i as u8);
        let slot = sel.encode(9, &params);
        assert_eq!(&slot[0..4], b"M2SL");
        assert_eq!(&slot[4..8], &[2, 0, 2, 0]);
        assert_eq!(&slot[8..12], &[9, 0, 0, 0]);
        assert_eq!(&slot[12..16], &[7, 0, 0, 0]);
        assert_eq!(&slot[16..20], &[0x44, 0x33, 0x22, 0x11]);
        assert_eq!(&slot[20..148], &params[..]);
        let crc = CRC32.checksum(&slot[..148]);
        assert_eq!(le_u32(&slot[148..152]), crc);
        assert!(slot[152..].iter().all(|b| *b == 0xFF));
        assert_eq!(Selection::decode(&slot), Some((sel, 9, params)));
    }

    #[test]
    fn the_record_image_is_header_slot_then_table_then_padding() {
        let table = Table::nominal().to_bytes();
        let table_crc = stored_crc(&table);
        assert!(table_crc.is_some());
        let h = CommitHeader {
            sequence: 3,
            table_crc: table_crc.unwrap_or_default(),
        };
        let mut image = [ERASED; RECORD_LEN];
        assert_eq!(h.encode_record(&table, &mut image), Some(()));
        assert_eq!(&image[..HEADER_SLOT_LEN], &h.encode()[..]);
        assert_eq!(&image[32..32 + TABLE_LEN], &table[..]);
        assert!(image[32 + TABLE_LEN..].iter().all(|b| *b == 0xFF));
        assert_eq!(image.len() - HEADER_SLOT_LEN, BODY_SLOT_LEN);
        let body: [u8; BODY_SLOT_LEN] = core::array::from_fn(|i| image[HEADER_SLOT_LEN + i]);
        assert_eq!(h.decode_body(&body), Ok((h, Table::nominal())));
    }
}
