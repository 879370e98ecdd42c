//! Why a frame or a telecommand is refused: [`LinkError`], stable codes `0x05xx`.

/// Why bytes from the link are not an acceptable telecommand. Each variant has a stable
/// code ([`LinkError::code`]) and a 32-bit failure datum ([`LinkError::data`]) that go
/// into the TM[1,2] acceptance-failure report. A rejected telecommand changes nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkError {
    /// The frame is shorter than the packet needs: shorter than a primary header plus a
    /// PUS-C TC secondary header plus CRC, or shorter than the packet length field says.
    Truncated {
        /// Bytes received.
        got: u16,
        /// Bytes the header demands (saturated at `u16::MAX`).
        needed: u16,
    },
    /// The frame is longer than the packet length field says (trailing bytes).
    LengthMismatch {
        /// Bytes received.
        got: u16,
        /// Packet length from the header.
        declared: u16,
    },
    /// The frame or packet exceeds [`super::MAX_TC_PACKET_LEN`] (also a deframer overflow).
    Oversized,
    /// The COBS frame does not decode.
    BadFraming,
    /// The CRC-16/CCITT-FALSE of the packet does not match.
    BadCrc {
        /// CRC-16 found in the packet.
        found: u16,
    },
    /// Not addressed to the controller's APID.
    WrongApid {
        /// APID found.
        apid: u16,
    },
    /// Primary header is not a version-0, unsegmented telecommand with a secondary header.
    BadPrimaryHeader,
    /// The PUS version in the secondary header is not PUS-C (2).
    UnsupportedPusVersion {
        /// Version found.
        version: u8,
    },
    /// No such service on this controller.
    UnknownService {
        /// Service found.
        service: u8,
    },
    /// No such subtype in a known service.
    UnknownSubtype {
        /// Service found.
        service: u8,
        /// Subtype found.
        subtype: u8,
    },
    /// No such function ID in TC[8,1].
    UnknownFunction {
        /// Function ID found.
        function_id: u16,
    },
    /// The application data length is wrong for this telecommand.
    AppDataLength {
        /// Bytes of application data received.
        got: u16,
        /// Bytes this telecommand needs (or the largest allowed).
        expected: u16,
    },
    /// An argument is out of its range (leg number, memory ID, ...).
    InvalidArgument {
        /// Zero-based index of the offending argument in the application data layout.
        index: u8,
    },
    /// A table chunk lies (partly) outside the table, or is empty or too long.
    ChunkOutOfRange {
        /// Offset of the chunk (bytes).
        offset: u16,
        /// Length of the chunk (bytes).
        length: u16,
    },
    /// A telecommand that cannot be scheduled: a TC[11,x] or a table chunk TC[6,2]
    /// inside a TC[11,4] (reported only as the embedded code of [`LinkError::EmbeddedTc`]).
    NotSchedulable {
        /// Service of the embedded telecommand.
        service: u8,
        /// Its subtype.
        subtype: u8,
    },
    /// A telecommand embedded in a TC[11,4] activity is refused (ST[11]): `code` is the
    /// link code the same packet would get on its own (0x0503 also when it is longer
    /// than a schedule slot, 0x0510 for a telecommand that cannot be scheduled).
    EmbeddedTc {
        /// Zero-based index of the activity in the TC[11,4].
        index: u8,
        /// The embedded packet's own refusal code (0x05xx).
        code: u16,
    },
}

/// Saturating `usize` -> `u16` for error reports.
pub(crate) fn sat_u16(v: usize) -> u16 {
    u16::try_from(v).unwrap_or(u16::MAX)
}

impl LinkError {
    /// Stable numeric code for telemetry (family `0x05xx`).
    pub const fn code(&self) -> u16 {
        match self {
            LinkError::Truncated { .. } => 0x0501,
            LinkError::LengthMismatch { .. } => 0x0502,
            LinkError::Oversized => 0x0503,
            LinkError::BadFraming => 0x0504,
            LinkError::BadCrc { .. } => 0x0505,
            LinkError::WrongApid { .. } => 0x0506,
            LinkError::BadPrimaryHeader => 0x0507,
            LinkError::UnsupportedPusVersion { .. } => 0x0508,
            LinkError::UnknownService { .. } => 0x0509,
            LinkError::UnknownSubtype { .. } => 0x050a,
            LinkError::UnknownFunction { .. } => 0x050b,
            LinkError::AppDataLength { .. } => 0x050c,
            LinkError::InvalidArgument { .. } => 0x050d,
            LinkError::ChunkOutOfRange { .. } => 0x050e,
            LinkError::EmbeddedTc { .. } => 0x050f,
            LinkError::NotSchedulable { .. } => 0x0510,
        }
    }

    /// The failure datum of the verification report (layout per variant in the ICD):
    /// two u16 packed as `high << 16 | low`, or one value, or 0.
    pub const fn data(&self) -> u32 {
        match *self {
            LinkError::Truncated { got, needed } => pack(got, needed),
            LinkError::LengthMismatch { got, declared } => pack(got, declared),
            LinkError::Oversized | LinkError::BadFraming | LinkError::BadPrimaryHeader => 0,
            LinkError::BadCrc { found } => found as u32,
            LinkError::WrongApid { apid } => apid as u32,
            LinkError::UnsupportedPusVersion { version } => version as u32,
            LinkError::UnknownService { service } => service as u32,
            LinkError::UnknownSubtype { service, subtype } => pack(service as u16, subtype as u16),
            LinkError::UnknownFunction { function_id } => function_id as u32,
            LinkError::AppDataLength { got, expected } => pack(got, expected),
            LinkError::InvalidArgument { index } => index as u32,
            LinkError::ChunkOutOfRange { offset, length } => pack(offset, length),
            LinkError::EmbeddedTc { index, code } => pack(index as u16, code),
            LinkError::NotSchedulable { service, subtype } => pack(service as u16, subtype as u16),
        }
    }
}

/// Two u16 in one u32: `high << 16 | low`.
const fn pack(high: u16, low: u16) -> u32 {
    ((high as u32) << 16) | low as u32
}
