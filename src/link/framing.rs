//! Framing of packets on a byte stream: COBS with `0x00` delimiters.
//!
//! A frame on the wire is `0x00, COBS(packet), 0x00`. COBS (Consistent Overhead Byte
//! Stuffing) removes every `0x00` from the packet at a cost of one byte per 254 (at most
//! 2 bytes for a 256-byte packet), so `0x00` marks frame boundaries unambiguously:
//! * a receiver resynchronises at the next `0x00` after garbage, a lost byte or an
//!   overflow, without searching for a sync word that could also occur in the data;
//! * the leading `0x00` flushes any partial frame left in the receiver (e.g. after a
//!   reset of the sender); empty frames (two adjacent delimiters) are ignored;
//! * integrity is the packet's own CRC-16 (every PUS-C TC and TM carries one), so the
//!   frame adds no checksum of its own, and the length is the packet's length field,
//!   checked against the frame length.
//!
//! The [`Deframer`] takes bytes one at a time or in slices into a fixed buffer and yields
//! complete packets; a frame longer than its buffer is dropped up to the next delimiter
//! and reported as [`FrameError::Overflow`].

use super::error::LinkError;

/// The frame delimiter.
pub const FRAME_DELIMITER: u8 = 0x00;
/// COBS adds one code byte per started block of this many data bytes.
const COBS_BLOCK_LEN: usize = 254;
/// Bytes of delimiters around each frame (leading and trailing).
const DELIMITERS_PER_FRAME: usize = 2;

/// Largest COBS encoding of a `packet_len`-byte packet (without delimiters).
pub const fn max_cobs_len(packet_len: usize) -> usize {
    packet_len + packet_len / COBS_BLOCK_LEN + 1
}

/// Largest frame (both delimiters included) for a `packet_len`-byte packet.
pub const fn max_frame_len(packet_len: usize) -> usize {
    max_cobs_len(packet_len) + DELIMITERS_PER_FRAME
}

/// Default deframer buffer: the COBS encoding of the largest telecommand.
pub const DEFRAMER_BUFFER_LEN: usize = max_cobs_len(super::MAX_TC_PACKET_LEN);

/// Why a frame could not be produced or received.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// [`encode_frame`]: the output buffer is too small for the framed packet.
    BufferTooSmall {
        /// Bytes the frame may need ([`max_frame_len`]).
        needed: u16,
    },
    /// [`Deframer`]: a frame exceeded the buffer and was dropped (up to the next `0x00`).
    Overflow,
    /// [`Deframer`]: the bytes between two delimiters are not a valid COBS encoding.
    BadCobs,
}

impl FrameError {
    /// The link error a received-frame failure maps to (for counting/telemetry; there is
    /// no request ID for it, so no verification report can name the telecommand).
    pub const fn link_error(&self) -> LinkError {
        match self {
            FrameError::Overflow | FrameError::BufferTooSmall { .. } => LinkError::Oversized,
            FrameError::BadCobs => LinkError::BadFraming,
        }
    }
}

/// Frames `packet` into `out` as `0x00, COBS(packet), 0x00`; returns the frame length.
pub fn encode_frame(packet: &[u8], out: &mut [u8]) -> Result<usize, FrameError> {
    let needed = max_frame_len(packet.len());
    let too_small = FrameError::BufferTooSmall {
        needed: super::error::sat_u16(needed),
    };
    let (first, rest) = out.split_first_mut().ok_or(too_small)?;
    *first = FRAME_DELIMITER;
    let n = cobs::try_encode(packet, rest).map_err(|_| too_small)?;
    let last = rest.get_mut(n).ok_or(too_small)?;
    *last = FRAME_DELIMITER;
    Ok(n + DELIMITERS_PER_FRAME)
}

/// Streaming receiver of COBS frames into a fixed buffer of `N` bytes (the encoded frame
/// without delimiters must fit; [`DEFRAMER_BUFFER_LEN`] fits every valid telecommand).
///
/// Feed it with [`Deframer::push_byte`] or [`Deframer::push`]; a completed frame is
/// decoded in place and returned as a borrowed packet, valid until the next call.
#[derive(Clone, Debug)]
pub struct Deframer<const N: usize = DEFRAMER_BUFFER_LEN> {
    buf: [u8; N],
    /// Encoded bytes collected since the last delimiter.
    len: usize,
    /// The current frame overflowed: drop bytes until the next delimiter.
    dropping: bool,
    /// Frames delivered (wrapping).
    frames_ok: u32,
    /// Frames dropped: overflow or bad COBS (wrapping).
    frames_bad: u32,
}

impl<const N: usize> Default for Deframer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Deframer<N> {
    /// An empty deframer.
    pub const fn new() -> Self {
        Deframer {
            buf: [0; N],
            len: 0,
            dropping: false,
            frames_ok: 0,
            frames_bad: 0,
        }
    }

    /// Drops any partial frame.
    pub fn reset(&mut self) {
        self.len = 0;
        self.dropping = false;
    }

    /// Frames delivered since creation (wrapping counter).
    pub const fn frames_ok(&self) -> u32 {
        self.frames_ok
    }

    /// Frames dropped since creation: overflow or bad COBS (wrapping counter).
    pub const fn frames_bad(&self) -> u32 {
        self.frames_bad
    }

    /// Takes one byte. Returns `None` while a frame is incomplete (or on an empty frame),
    /// `Some(Ok(packet))` when a delimiter completes a valid frame, `Some(Err(..))` when
    /// it completes an overflowed or undecodable one. Never panics, for any input.
    pub fn push_byte(&mut self, byte: u8) -> Option<Result<&[u8], FrameError>> {
        if byte != FRAME_DELIMITER {
            if self.dropping {
                return None;
            }
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.dropping = true,
            }
            return None;
        }
        // Delimiter: the frame collected so far is complete.
        let len = self.len;
        let dropped = self.dropping;
        self.reset();
        if dropped {
            self.frames_bad = self.frames_bad.wrapping_add(1);
            return Some(Err(FrameError::Overflow));
        }
        if len == 0 {
            return None;
        }
        let Some(encoded) = self.buf.get_mut(..len) else {
            return Some(Err(FrameError::Overflow));
        };
        match cobs_decode_in_place(encoded) {
            Some(n) if n > 0 => {
                self.frames_ok = self.frames_ok.wrapping_add(1);
                self.buf.get(..n).map(Ok)
            }
            _ => {
                self.frames_bad = self.frames_bad.wrapping_add(1);
                Some(Err(FrameError::BadCobs))
            }
        }
    }

    /// Takes bytes from `input` up to and including the delimiter that completes a frame
    /// (or an error). Returns the number of bytes consumed and the outcome; call again
    /// with the rest of the input until it is consumed.
    pub fn push(&mut self, input: &[u8]) -> (usize, Option<Result<&[u8], FrameError>>) {
        let mut consumed = 0;
        for &byte in input {
            consumed += 1;
            if byte == FRAME_DELIMITER {
                return (consumed, self.push_byte(byte));
            }
            // A non-delimiter byte never completes a frame.
            let _ = self.push_byte(byte);
        }
        (consumed, None)
    }
}

/// COBS-decodes one frame (without its delimiter) in place: the `cobs` crate's byte
/// state machine ([`cobs::DecoderState`]) written out for this one use (its `feed`
/// was inlined twice, 256 bytes of flash; its slice decoder indexes with bounds checks
/// the compiler cannot remove, panic paths in the flight image). The decoded byte `k`
/// is written at index `k`, never ahead of the encoded byte being read. `None` if the
/// bytes are not one valid COBS frame; the same answer and bytes as the state machine
/// for every input (`tests::decoder_equals_the_cobs_state_machine`).
fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    // The state machine's states: Idle (`!started`), and in a run `left` bytes before
    // its end, the run's code byte 0xFF (`chain`: no zero follows the run) or not.
    let mut started = false;
    let mut chain = false;
    let mut left = 0u8;
    let mut out = 0usize;
    for i in 0..buf.len() {
        let byte = *buf.get(i)?;
        if byte == FRAME_DELIMITER {
            // Idle: ignored; in a frame: its end, early (or complete, and the rest is
            // another frame): not one valid frame either way.
            if started {
                return None;
            }
            continue;
        }
        if !started || left == 0 {
            // A code byte: the end of a run that stands for a zero (unless a chain),
            // and the length of the next run.
            if started && !chain {
                *buf.get_mut(out)? = 0;
                out += 1;
            }
            started = true;
            chain = byte == 0xFF;
            left = byte - 1;
        } else {
            *buf.get_mut(out)? = byte;
            out += 1;
            left -= 1;
        }
    }
    // The delimiter completes the frame only at the end of a run.
    (started && left == 0).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The decoder this module used before: the `cobs` crate's state machine.
    fn reference(buf: &mut [u8]) -> Option<usize> {
        let mut state = cobs::DecoderState::Idle;
        let mut out = 0usize;
        for i in 0..buf.len() {
            match state.feed(buf[i]) {
                Ok(cobs::DecodeResult::DataContinue(b)) => {
                    buf[out] = b;
                    out += 1;
                }
                Ok(cobs::DecodeResult::NoData | cobs::DecodeResult::DataStart) => {}
                Ok(cobs::DecodeResult::DataComplete) | Err(_) => return None,
            }
        }
        match state.feed(FRAME_DELIMITER) {
            Ok(cobs::DecodeResult::DataComplete) => Some(out),
            _ => None,
        }
    }

    fn same(input: &[u8]) {
        let (mut a, mut b) = (input.to_vec(), input.to_vec());
        let (ra, rb) = (cobs_decode_in_place(&mut a), reference(&mut b));
        assert_eq!(ra, rb, "result of {input:02x?}");
        if let Some(n) = ra {
            assert_eq!(a[..n], b[..n], "bytes of {input:02x?}");
        }
    }

    #[test]
    fn decoder_equals_the_cobs_state_machine() {
        // Every input of up to 4 bytes over the bytes that matter (zero, short and
        // long codes, the chain code), then valid frames of random packets (0xFF
        // chains included), each also cut short and with a byte changed.
        const ALPHABET: [u8; 7] = [0x00, 0x01, 0x02, 0x03, 0x04, 0xfe, 0xff];
        let mut input = Vec::new();
        for len in 0..=4u32 {
            for mut k in 0..ALPHABET.len().pow(len) {
                input.clear();
                for _ in 0..len {
                    input.push(ALPHABET[k % ALPHABET.len()]);
                    k /= ALPHABET.len();
                }
                same(&input);
            }
        }
        let mut seed = 0x2545_f491_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        for _ in 0..20_000 {
            let len = (next() % 600) as usize;
            let zeros = next() % 4;
            let packet: Vec<u8> = (0..len)
                .map(|_| {
                    let v = next();
                    if v % 16 < zeros {
                        0
                    } else {
                        (v >> 8) as u8
                    }
                })
                .collect();
            let mut enc = vec![0u8; max_cobs_len(len)];
            let n = cobs::encode(&packet, &mut enc);
            enc.truncate(n);
            same(&enc);
            let mut copy = enc.clone();
            assert_eq!(cobs_decode_in_place(&mut copy), Some(len));
            assert_eq!(copy[..len], packet[..]);
            if n > 0 {
                let cut = (next() as usize) % n;
                same(&enc[..cut]);
                let at = (next() as usize) % n;
                enc[at] = next() as u8;
                same(&enc);
            }
        }
    }
}
