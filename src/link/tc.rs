//! Telecommands: checked decoding of a PUS-C TC packet into a [`Telecommand`] through one
//! checked view ([`TcPacket`]), and the encoder (`spacepackets`; ground tool, tests).
//!
//! Checks, in this order (the first failing one is reported):
//! 1. length: at least a primary header + TC secondary header + CRC
//!    ([`LinkError::Truncated`]), at most [`MAX_TC_PACKET_LEN`] ([`LinkError::Oversized`]);
//! 2. primary header: version 0, type TC, secondary-header flag set, unsegmented
//!    ([`LinkError::BadPrimaryHeader`]);
//! 3. packet length field against the frame ([`LinkError::Truncated`],
//!    [`LinkError::LengthMismatch`]);
//! 4. CRC-16/CCITT-FALSE over the whole packet ([`LinkError::BadCrc`]);
//! 5. APID == [`M2_APID`] ([`LinkError::WrongApid`]);
//! 6. PUS version 2 ([`LinkError::UnsupportedPusVersion`]);
//! 7. service, subtype, application data ([`Command::parse`]).

use arbitrary_int::{u11, u14};
use spacepackets::ecss::tc::{PusTcCreator, PusTcSecondaryHeader};
use spacepackets::ecss::{CreatorConfig, MessageTypeId};
use spacepackets::{PacketId, PacketSequenceControl, SequenceFlags, SpHeader};

use super::command::{Command, MAX_TC_APP_DATA_LEN};
use super::error::{sat_u16, LinkError};
use super::wire::{Order, Reader};
use super::{
    CCSDS_PRIMARY_HEADER_LEN, CRC16_LEN, DATA_LEN_OFFSET, M2_APID, MAX_TC_PACKET_LEN,
    PUS_C_VERSION, PUS_TC_SEC_HEADER_LEN,
};

/// Smallest telecommand: primary header, secondary header, CRC (bytes).
pub const MIN_TC_PACKET_LEN: usize = CCSDS_PRIMARY_HEADER_LEN + PUS_TC_SEC_HEADER_LEN + CRC16_LEN;
/// Mask of the 14-bit packet sequence count.
pub const SEQ_COUNT_MASK: u16 = 0x3fff;
/// Mask of the 11-bit APID.
pub const APID_MASK: u16 = 0x07ff;
/// Bytes of a request ID (PUS-C: the first four bytes of the TC).
pub const REQUEST_ID_LEN: usize = 4;

/// The PUS-C request ID of a telecommand: its packet ID (version, type, secondary header
/// flag, APID) and packet sequence control (sequence flags, count), i.e. the first four
/// bytes of the TC, big-endian. Verification reports name the TC by it (and the
/// time-based schedule its activities).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct RequestId {
    /// Bytes 0..2 of the TC.
    pub packet_id: u16,
    /// Bytes 2..4 of the TC.
    pub sequence_control: u16,
}

impl RequestId {
    /// From the first four bytes of a packet; `None` if shorter.
    pub fn from_packet(packet: &[u8]) -> Option<RequestId> {
        let b: [u8; REQUEST_ID_LEN] = packet.get(..REQUEST_ID_LEN)?.try_into().ok()?;
        Some(RequestId::from_bytes(b))
    }

    /// From its four wire bytes.
    pub const fn from_bytes(b: [u8; REQUEST_ID_LEN]) -> RequestId {
        RequestId {
            packet_id: u16::from_be_bytes([b[0], b[1]]),
            sequence_control: u16::from_be_bytes([b[2], b[3]]),
        }
    }

    /// Its four wire bytes.
    pub const fn to_bytes(self) -> [u8; REQUEST_ID_LEN] {
        let p = self.packet_id.to_be_bytes();
        let s = self.sequence_control.to_be_bytes();
        [p[0], p[1], s[0], s[1]]
    }

    /// APID of the telecommand.
    pub const fn apid(self) -> u16 {
        self.packet_id & APID_MASK
    }

    /// Sequence count of the telecommand.
    pub const fn seq_count(self) -> u16 {
        self.sequence_control & SEQ_COUNT_MASK
    }
}

/// PUS-C acknowledgement flags of a TC (which successful steps the sender wants reported
/// by service 1; failures are always reported).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AckFlags(pub u8);

impl AckFlags {
    /// All four steps.
    pub const ALL: AckFlags = AckFlags(0b1111);
    /// None (failures only).
    pub const NONE: AckFlags = AckFlags(0);
    /// Report successful acceptance (TM[1,1]).
    pub const fn acceptance(self) -> bool {
        self.0 & 0b1000 != 0
    }
    /// Report successful start (TM[1,3]).
    pub const fn start(self) -> bool {
        self.0 & 0b0100 != 0
    }
    /// Report progress (not used by the controller).
    pub const fn progress(self) -> bool {
        self.0 & 0b0010 != 0
    }
    /// Report successful completion (TM[1,7]).
    pub const fn completion(self) -> bool {
        self.0 & 0b0001 != 0
    }
}

/// A telecommand accepted by the link: who asked, what to report, what to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Telecommand {
    /// Request ID for the verification reports.
    pub request_id: RequestId,
    /// Acknowledgement flags.
    pub ack: AckFlags,
    /// Source ID of the secondary header (the ground application that sent it).
    pub source_id: u16,
    /// The command.
    pub command: Command,
}

/// A refused telecommand: report TM[1,2] with `error.code()` for `request_id` (if the
/// packet had at least four bytes to name it), change nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rejection {
    /// The first four bytes of the packet, if there were four.
    pub request_id: Option<RequestId>,
    /// Why.
    pub error: LinkError,
}

/// Checked decoding of one packet (the bytes of one frame). Never panics.
#[inline(never)]
pub fn decode_telecommand(packet: &[u8]) -> Result<Telecommand, Rejection> {
    let request_id = RequestId::from_packet(packet);
    decode_full(packet).map_err(|error| Rejection { request_id, error })
}

/// Primary header field positions (first two bytes = packet ID, next two = sequence
/// control), as masks over the 16-bit words.
const VERSION_MASK: u16 = 0xe000;
const TYPE_TC_BIT: u16 = 0x1000;
const SEC_HEADER_BIT: u16 = 0x0800;
const SEQ_FLAGS_MASK: u16 = 0xc000;
const SEQ_FLAGS_UNSEGMENTED: u16 = 0xc000;
/// Shift of the PUS version in the first secondary-header byte.
const PUS_VERSION_SHIFT: u8 = 4;
/// Mask of the ack flags in the first secondary-header byte.
const ACK_MASK: u8 = 0x0f;
/// The packet error control of CCSDS/PUS: CRC-16/CCITT-FALSE (= CRC-16/IBM-3740), of
/// every telecommand checked and every telemetry packet emitted.
pub const CRC16: NibbleCrc16 = NibbleCrc16::new(CRC16_ALGORITHM);
/// The algorithm of [`CRC16`] (CRC-16/CCITT-FALSE, catalogued as CRC-16/IBM-3740): its
/// parameters for the ICD and the ground's encoders.
pub const CRC16_ALGORITHM: &crc::Algorithm<u16> = &crc::CRC_16_IBM_3740;

/// A non-reflected 16-bit CRC of the `crc` crate's catalogue, computed four bits at a
/// time with a 16-entry table (32 bytes), as `table::layout::NibbleCrc32` does for the
/// table's CRC-32. The crate's byte-wise table is 512 bytes of the flight image's flash
/// (m2fw 66,072 -> 65,4xx bytes with the TM header written by `link::tm`, which
/// spacepackets' creator did with that table); this costs about five more instructions a
/// byte (a 256-byte packet: ~1,300). Equal to the crate on every input tested (host test
/// `link::nibble_crc16_equals_the_crc_crate`: 20,000 random inputs, the catalogue check
/// value).
#[derive(Clone, Copy, Debug)]
pub struct NibbleCrc16 {
    /// CRC of the four-bit value `i` in the register's top nibble (the polynomial
    /// applied four times).
    table: [u16; 16],
    /// Initial register.
    init: u16,
    /// Final XOR.
    xorout: u16,
}

#[allow(clippy::indexing_slicing)] // Table indices are nibbles: below 16, the table's size.
impl NibbleCrc16 {
    /// The CRC of `alg`, which must be a non-reflected 16-bit algorithm (checked when
    /// the constant is evaluated: compilation fails otherwise).
    pub const fn new(alg: &crc::Algorithm<u16>) -> Self {
        assert!(alg.width == 16 && !alg.refin && !alg.refout);
        let mut table = [0u16; 16];
        let mut i = 0;
        while i < 16 {
            let mut c = (i as u16) << 12;
            let mut bit = 0;
            while bit < 4 {
                c = if c & 0x8000 != 0 {
                    (c << 1) ^ alg.poly
                } else {
                    c << 1
                };
                bit += 1;
            }
            table[i] = c;
            i += 1;
        }
        Self {
            table,
            init: alg.init,
            xorout: alg.xorout,
        }
    }

    /// The CRC of `bytes`.
    pub fn checksum(&self, bytes: &[u8]) -> u16 {
        let mut c = self.init;
        for b in bytes {
            c ^= u16::from(*b) << 8;
            c = (c << 4) ^ self.table[usize::from(c >> 12)];
            c = (c << 4) ^ self.table[usize::from(c >> 12)];
        }
        c ^ self.xorout
    }
}

/// A checked view of a PUS-C telecommand packet (smoltcp style): [`TcPacket::new_checked`]
/// runs checks 1..6 of the module documentation; afterwards no accessor can fail or panic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TcPacket<'a> {
    bytes: &'a [u8],
    packet_id: u16,
    sequence_control: u16,
    version_ack: u8,
    service: u8,
    subtype: u8,
    source_id: u16,
}

impl<'a> TcPacket<'a> {
    /// Checks length, primary header, length field, CRC-16, APID and PUS version.
    pub fn new_checked(packet: &'a [u8]) -> Result<Self, LinkError> {
        let got = sat_u16(packet.len());
        if packet.len() > MAX_TC_PACKET_LEN {
            return Err(LinkError::Oversized);
        }
        let truncated = LinkError::Truncated {
            got,
            needed: sat_u16(MIN_TC_PACKET_LEN),
        };
        if packet.len() < MIN_TC_PACKET_LEN {
            return Err(truncated);
        }
        let mut r = Reader::new(packet, Order::Big);
        let (Some(packet_id), Some(sequence_control), Some(data_len)) = (r.u16(), r.u16(), r.u16())
        else {
            return Err(truncated);
        };
        if packet_id & VERSION_MASK != 0
            || packet_id & TYPE_TC_BIT == 0
            || packet_id & SEC_HEADER_BIT == 0
            || sequence_control & SEQ_FLAGS_MASK != SEQ_FLAGS_UNSEGMENTED
        {
            return Err(LinkError::BadPrimaryHeader);
        }
        let declared = usize::from(data_len) + DATA_LEN_OFFSET;
        if declared > MAX_TC_PACKET_LEN {
            return Err(LinkError::Oversized);
        }
        if packet.len() < declared || declared < MIN_TC_PACKET_LEN {
            return Err(LinkError::Truncated {
                got,
                needed: sat_u16(declared.max(MIN_TC_PACKET_LEN)),
            });
        }
        if packet.len() > declared {
            return Err(LinkError::LengthMismatch {
                got,
                declared: sat_u16(declared),
            });
        }
        let (body, crc) = packet.split_at(packet.len() - CRC16_LEN);
        let found = Reader::new(crc, Order::Big).u16().ok_or(truncated)?;
        if CRC16.checksum(body) != found {
            return Err(LinkError::BadCrc { found });
        }
        let apid = packet_id & APID_MASK;
        if apid != M2_APID {
            return Err(LinkError::WrongApid { apid });
        }
        let (Some(version_ack), Some(service), Some(subtype), Some(source_id)) =
            (r.u8(), r.u8(), r.u8(), r.u16())
        else {
            return Err(truncated);
        };
        let version = version_ack >> PUS_VERSION_SHIFT;
        if version != PUS_C_VERSION {
            return Err(LinkError::UnsupportedPusVersion { version });
        }
        Ok(Self {
            bytes: packet,
            packet_id,
            sequence_control,
            version_ack,
            service,
            subtype,
            source_id,
        })
    }

    /// The request ID (first four bytes).
    pub fn request_id(&self) -> RequestId {
        RequestId {
            packet_id: self.packet_id,
            sequence_control: self.sequence_control,
        }
    }

    /// The acknowledgement flags.
    pub fn ack(&self) -> AckFlags {
        AckFlags(self.version_ack & ACK_MASK)
    }

    /// Service type.
    pub fn service(&self) -> u8 {
        self.service
    }

    /// Message subtype.
    pub fn subtype(&self) -> u8 {
        self.subtype
    }

    /// Source ID.
    pub fn source_id(&self) -> u16 {
        self.source_id
    }

    /// The application data (between the secondary header and the CRC).
    pub fn app_data(&self) -> &'a [u8] {
        let start = CCSDS_PRIMARY_HEADER_LEN + PUS_TC_SEC_HEADER_LEN;
        let end = self.bytes.len().saturating_sub(CRC16_LEN);
        self.bytes.get(start..end).unwrap_or(&[])
    }
}

fn decode_full(packet: &[u8]) -> Result<Telecommand, LinkError> {
    let tc = TcPacket::new_checked(packet)?;
    let command = Command::parse(tc.service(), tc.subtype(), tc.app_data())?;
    Ok(Telecommand {
        request_id: tc.request_id(),
        ack: tc.ack(),
        source_id: tc.source_id(),
        command,
    })
}

/// Header fields the sender chooses for a telecommand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TcHeader {
    /// Packet sequence count (14 bits; higher bits are ignored).
    pub seq_count: u16,
    /// Source ID of the secondary header.
    pub source_id: u16,
    /// Acknowledgement flags.
    pub ack: AckFlags,
}

impl TcHeader {
    /// Sequence count `seq_count`, source ID 0, all acknowledgements.
    pub const fn new(seq_count: u16) -> TcHeader {
        TcHeader {
            seq_count,
            source_id: 0,
            ack: AckFlags::ALL,
        }
    }
}

/// Why a telecommand could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncodeError {
    /// The output buffer is too small.
    BufferTooSmall,
}

/// Encodes `command` as a PUS-C TC (APID [`M2_APID`], unsegmented, with CRC-16) into
/// `out`; returns the packet length. Unframed: see [`super::encode_frame`].
pub fn encode_telecommand(
    command: &Command,
    header: TcHeader,
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    let mut app_data = [0u8; MAX_TC_APP_DATA_LEN];
    let n = command
        .emit_app_data(&mut app_data)
        .ok_or(EncodeError::BufferTooSmall)?;
    let app = app_data.get(..n).ok_or(EncodeError::BufferTooSmall)?;
    let (service, subtype) = command.message_type();
    let sp = SpHeader::new(
        PacketId::new_for_tc(true, u11::new(M2_APID & APID_MASK)),
        PacketSequenceControl::new(
            SequenceFlags::Unsegmented,
            u14::new(header.seq_count & SEQ_COUNT_MASK),
        ),
        0,
    );
    let sec = PusTcSecondaryHeader::new(
        MessageTypeId::new(service, subtype),
        spacepackets::ecss::tc::AckFlags::new_with_raw_value(arbitrary_int::u4::new(
            header.ack.0 & ACK_MASK,
        )),
        header.source_id,
    );
    let tc = PusTcCreator::new(sp, sec, app, CreatorConfig::default());
    tc.write_to_slice(out)
        .map_err(|_| EncodeError::BufferTooSmall)
}
