//! The upload buffer: the inactive RAM copy that TC[6,2] chunks fill, in any order, and
//! the checks a commit makes before anything reaches flash.
//!
//! Every byte has a "received" bit; a commit needs all of them, then the CRC-32 the
//! operator names must match the bytes, then the bytes must decode as a table. After a
//! successful commit the received bits are cleared (a second commit needs a new upload).
//! The bitmap is a fixed array of [`TABLE_LEN`] bits (`heapless` has no bit set; this is
//! the bounded structure).

use super::layout::{Table, TableError, CRC32, TABLE_CRC_OFFSET, TABLE_LEN};

/// Bytes of the received-bit map (one bit per table byte).
const BITMAP_LEN: usize = TABLE_LEN.div_ceil(8);

/// Why the upload buffer cannot be committed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UploadError {
    /// Bytes never loaded (count).
    Incomplete(u16),
    /// The CRC-32 named by the commit differs from the bytes' (the computed one).
    CrcMismatch(u32),
    /// The bytes do not decode as a table.
    Decode(TableError),
}

/// The upload buffer with its received bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UploadBuffer {
    bytes: [u8; TABLE_LEN],
    received: [u8; BITMAP_LEN],
}

impl Default for UploadBuffer {
    fn default() -> Self {
        Self::new()
    }
}

impl UploadBuffer {
    /// Empty: all bytes 0, none received.
    pub const fn new() -> Self {
        Self {
            bytes: [0; TABLE_LEN],
            received: [0; BITMAP_LEN],
        }
    }

    /// Loads `data` at table offset `offset_bytes`; bytes beyond the table are ignored
    /// (the link refuses such chunks before they get here).
    pub fn load(&mut self, offset_bytes: u16, data: &[u8]) {
        let off = usize::from(offset_bytes);
        for (i, b) in data.iter().enumerate() {
            let at = off + i;
            let Some(dst) = self.bytes.get_mut(at) else {
                break;
            };
            *dst = *b;
            if let Some(bits) = self.received.get_mut(at / 8) {
                *bits |= 1 << (at % 8);
            }
        }
    }

    /// Bytes not loaded yet.
    pub fn missing(&self) -> u16 {
        let received: u32 = self.received.iter().map(|b| b.count_ones()).sum();
        (TABLE_LEN as u32).saturating_sub(received) as u16
    }

    /// The buffer's bytes (a dump shows them whatever was loaded).
    pub fn bytes(&self) -> &[u8; TABLE_LEN] {
        &self.bytes
    }

    /// The table ID of the upload, for events naming a refused table: `None` unless
    /// every byte was loaded since the last commit that passed its first checks and the
    /// image decodes (bytes left from an earlier upload never name a table).
    pub fn table_id(&self) -> Option<u32> {
        if self.missing() > 0 {
            return None;
        }
        Table::decode(&self.bytes).ok().map(|t| t.table_id)
    }

    /// The commit checks, in order: every byte loaded, the CRC-32 `crc32` matches bytes
    /// `0..TABLE_CRC_OFFSET`, the bytes decode. Changes nothing.
    pub fn check(&self, crc32: u32) -> Result<Table, UploadError> {
        let missing = self.missing();
        if missing > 0 {
            return Err(UploadError::Incomplete(missing));
        }
        let computed = CRC32.checksum(self.bytes.get(..TABLE_CRC_OFFSET).unwrap_or(&[]));
        if computed != crc32 {
            return Err(UploadError::CrcMismatch(computed));
        }
        Table::decode(&self.bytes).map_err(UploadError::Decode)
    }

    /// Forgets which bytes were received (after a commit was started from them).
    pub fn clear_received(&mut self) {
        self.received = [0; BITMAP_LEN];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_commit_needs_every_byte_the_named_crc_and_a_decodable_image() {
        let t = Table::nominal();
        let bytes = t.to_bytes();
        let mut u = UploadBuffer::new();
        assert_eq!(u.missing(), TABLE_LEN as u16);
        u.load(0, &bytes[..500]);
        assert_eq!(
            u.check(t.crc32()),
            Err(UploadError::Incomplete(TABLE_LEN as u16 - 500))
        );
        u.load(500, &bytes[500..]);
        assert_eq!(
            u.check(t.crc32() ^ 1),
            Err(UploadError::CrcMismatch(t.crc32()))
        );
        assert_eq!(u.check(t.crc32()), Ok(t));
        u.clear_received();
        assert_eq!(u.missing(), TABLE_LEN as u16);
        // Bytes beyond the table are ignored, never written out of bounds.
        u.load(TABLE_LEN as u16 - 1, &[1, 2, 3]);
        assert_eq!(u.missing(), TABLE_LEN as u16 - 1);
    }
}
