//! BiSS-C absolute linear encoders read through an `embedded_hal::spi::SpiDevice`.
//!
//! ## The protocol facts this driver relies on
//!
//! * **Lines.** The master's clock MA idles high; the encoder's data line SLO idles high
//!   when the encoder is ready. The master starts a request by clocking MA; the encoder
//!   answers by pulling SLO low on the second rising MA edge ("Ack"), then sends a
//!   Start bit (1), then the position MSB first, then the error bit, the warning bit and
//!   a 6-bit CRC; after the last bit it holds SLO low ("Timeout") until it is ready for
//!   the next request, then releases it high. (Renishaw data sheet L-9709-9005-03,
//!   *BiSS C-mode (unidirectional) for RESOLUTE encoders*, "Data format" and "A typical
//!   request cycle"; Beckhoff EL5042 documentation, "Basics of BiSS-C technology".)
//! * **CDS.** The Start bit "is always followed by a 0 bit" (Beckhoff EL5042, ibid.): the
//!   CDS bit, which a slave sets only to answer control (register) communication. This
//!   master never starts any (MA stays high during the timeout, i.e. CDM = 0), so a CDS
//!   of 1 is a framing error here. In each frame one CDS bit is transmitted, right after
//!   the Start bit (Baumer BiSS-C manual, "The BiSS-Frame").
//! * **Error and warning bits are active low.** Error "0 indicates that the internal
//!   check has failed and the position information should not be trusted" (also set on
//!   over-temperature); warning "0 indicates that the encoder scale (and/or reading
//!   window) should be cleaned ... not an indication of the trustworthiness of the
//!   position data" (Renishaw L-9709-9005-03-A, as quoted in Galil's `SY` command
//!   reference).
//! * **CRC.** Polynomial x^6 + x + 1 (0x43), start value 0, computed over the position,
//!   error and warning bits in transmission order (not over Ack, Start or CDS), sent MSB
//!   first and **inverted** (Lika/IKA/Baumer BiSS C-mode manuals: "Polynomial: X6+X1+1
//!   (binary: 1000011)", "(inverted output)", "starting value zero"; Beckhoff EP7041:
//!   "As a rule, the CRC checksum is transmitted inverted"; "ACK, Start and CDS bits are
//!   not included in the CRC calculation").
//! * **Daisy chain.** In the bus configuration MA reaches every slave at once and each
//!   slave's SLO feeds the next one's SLI, the first slave's SLO going to the master; the
//!   last slave's SLI is held low (iC-Haus, *BiSS Interface Protocol Description
//!   (C-Mode)* rev C5, "Brief description"; iC-MB4 data sheet, "BiSS C Frame"). All
//!   slaves latch their position on the same MA edge and their single-cycle data follow
//!   one another in one frame, first slave first, each with its own error/warning bits
//!   and CRC (TI motor-control SDK `bissc_enc_len`: "Each encoder transmits its position
//!   data sequentially in the BiSS-C frame").
//!
//! ## How it maps onto SPI
//!
//! SCK drives MA (through the line driver), MISO reads SL; MOSI is not used. The SPI
//! clock must idle high (CPOL = 1, BiSS's MA idle level); sampling on the falling edge
//! (CPHA = 0, SPI mode 2) reads each bit half a period after the slave changed it on
//! the rising edge. One `SpiDevice::read` of [`BissConfig::frame_bytes`] bytes is one
//! BiSS frame: the bits are taken MSB first. The first bits may still be high (before
//! the Ack) and the Ack lasts a number of bits that depends on the line delay and the
//! slave; both are absorbed by the window [`BissConfig::start_bit_first`] ..=
//! [`BissConfig::start_bit_last`] in which the Start bit must be found. After the last
//! CRC the remaining clocked bits must all be 0 (the timeout, or the chain's low SLI).
//! The master must leave at least the encoder's timeout between two reads (the 1 ms
//! control cycle does).
//!
//! ## Which failure is which ([`EncoderError`])
//!
//! | found | error |
//! |---|---|
//! | SPI error; SL never low before the window ends (no Ack); no Start bit by [`BissConfig::start_bit_last`] | `NoResponse` |
//! | Start bit before [`BissConfig::start_bit_first`]; CDS = 1; a 1 after the last CRC | `Corrupted` |
//! | CRC of a slave's data wrong | `Corrupted` (that leg) |
//! | CRC good, error bit active (0) | `SelfCheckFailed` (that leg) |
//! | CRC good, warning bit active (0) | reading valid; leg in [`EncoderWarnings::warning_legs`] |
//!
//! Framing failures of a daisy chain concern the whole frame: they carry
//! [`EVERY_LEG`]. With an exact window (`start_bit_first == start_bit_last`) every
//! single-bit error anywhere in the clocked bits is detected or harmless (it cannot
//! change a reading); with a wider window a bit error before the Start bit can shift the
//! frame and is then caught by the CRCs (and the trailing-zero check) only with high
//! probability. `host-tests/drivers.rs` shows both.

use crate::units::PM_PER_MM;
use embedded_hal::spi::{ErrorType, Operation, SpiBus, SpiDevice};

use crate::hw::{EncoderError, EncoderWarnings, StrokeEncoders, ENCODER_MM_PER_COUNT, EVERY_LEG};
use crate::kinematics::LEGS;

/// Width of the BiSS-C single-cycle CRC (bits).
pub const CRC_BITS: u32 = 6;
/// Error and warning bits after the position (bits).
pub const STATUS_BITS: u32 = 2;
/// Start and CDS bits before the first slave's data (bits).
pub const HEADER_BITS: u32 = 2;
/// Widest position word accepted (bits). RESOLUTE linear encoders send 26, 32 or 36.
pub const MAX_POSITION_BITS: u8 = 48;
/// Largest frame buffer (bytes): six slaves of [`MAX_POSITION_BITS`] plus the Ack window.
pub const MAX_FRAME_BYTES: usize = 64;
/// Low bits that must follow the last CRC at least (the start of the timeout).
pub const MIN_TRAILING_BITS: u32 = 1;

/// The BiSS-C single-cycle-data CRC: x^6 + x + 1 (0x43; `poly` omits the x^6 term),
/// start value 0, MSB first, transmitted inverted (`xorout` 0x3F). Leading zero bits do
/// not change a CRC with start value 0, so a bit string is checked by right-aligning it
/// in whole bytes.
pub const BISS_CRC6: crc::Algorithm<u8> = crc::Algorithm {
    width: 6,
    poly: 0x03,
    init: 0x00,
    refin: false,
    refout: false,
    xorout: 0x3F,
    check: 0x2E,
    residue: 0x02,
};

const CRC6: crc::Crc<u8> = crc::Crc::<u8>::new(&BISS_CRC6);

/// Controller counts (of [`ENCODER_MM_PER_COUNT`]) in picometres: 100,000 pm = 0.1 um.
const PM_PER_COUNT: i64 = (ENCODER_MM_PER_COUNT * PM_PER_MM + 0.5) as i64;

/// Frame layout shared by every slave on a link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BissConfig {
    /// Position bits each slave sends (1..=[`MAX_POSITION_BITS`]).
    pub position_bits: u8,
    /// Earliest bit index (0-based, counted from the first clocked bit) at which the
    /// Start bit is accepted. A Start bit before it is a framing error.
    pub start_bit_first: u16,
    /// Latest bit index at which the Start bit is accepted; none by then is "no
    /// response" (timeout). The frame is clocked long enough for this case.
    pub start_bit_last: u16,
}

impl BissConfig {
    /// Bits of one slave's single-cycle data: position, error, warning, CRC.
    pub const fn slave_bits(&self) -> u32 {
        self.position_bits as u32 + STATUS_BITS + CRC_BITS
    }

    /// Bytes to clock for a frame of `slaves` slaves: the latest Start bit, CDS, the
    /// slaves' data and at least [`MIN_TRAILING_BITS`] of timeout, rounded up to bytes.
    pub const fn frame_bytes(&self, slaves: usize) -> usize {
        let bits = self.start_bit_last as u32
            + HEADER_BITS
            + slaves as u32 * self.slave_bits()
            + MIN_TRAILING_BITS;
        bits.div_ceil(8) as usize
    }

    fn check(&self, slaves: usize) -> Result<(), BissConfigError> {
        if self.position_bits == 0 || self.position_bits > MAX_POSITION_BITS {
            return Err(BissConfigError::PositionBits);
        }
        if self.start_bit_first == 0 || self.start_bit_first > self.start_bit_last {
            // Index 0 cannot be a Start bit: at least one Ack bit comes first.
            return Err(BissConfigError::StartWindow);
        }
        if self.frame_bytes(slaves) > MAX_FRAME_BYTES {
            return Err(BissConfigError::FrameTooLong);
        }
        Ok(())
    }
}

/// How one leg's encoder reading becomes controller counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EncoderScale {
    /// Length of one encoder position step (picometres; RESOLUTE linear: 1,000 or 5,000
    /// or 50,000 pm).
    pub lsb_pm: u32,
    /// Raw position (encoder steps) at zero stroke (home), from calibration.
    pub zero_lsb: u64,
    /// The scale counts down as the stroke grows (mounted the other way round).
    pub reversed: bool,
}

impl EncoderScale {
    /// Controller counts of a raw position: `(raw - zero) * lsb_pm / 100,000 pm`, to the
    /// nearest count (ties away from zero), negated if reversed.
    pub fn counts(&self, raw: u64) -> i32 {
        // `check` bounded the full scale times the resolution below 2^31 counts
        // (< 2.2e14 pm), so the i64 products cannot overflow and the result fits i32;
        // the saturating steps only guard a raw value from outside the position word.
        let steps = (raw as i64).saturating_sub(self.zero_lsb as i64);
        let pm = steps.saturating_mul(i64::from(self.lsb_pm));
        let pm = if self.reversed {
            pm.saturating_neg()
        } else {
            pm
        };
        let c = round_div(pm, PM_PER_COUNT);
        i32::try_from(c).unwrap_or(if c < 0 { i32::MIN } else { i32::MAX })
    }

    fn check(&self, position_bits: u8) -> Result<(), BissConfigError> {
        if self.lsb_pm == 0 {
            return Err(BissConfigError::Resolution);
        }
        let full_scale = (1u128 << position_bits) - 1;
        if u128::from(self.zero_lsb) > full_scale {
            return Err(BissConfigError::ZeroOffset);
        }
        // Every reading must be representable in i32 counts.
        let max_pm = full_scale * u128::from(self.lsb_pm);
        if max_pm / PM_PER_COUNT as u128 >= i32::MAX as u128 {
            return Err(BissConfigError::Range);
        }
        Ok(())
    }
}

/// Rounds `a / b` (`b > 0`) to the nearest integer, ties away from zero (saturating at
/// the i64 extremes, which no caller reaches; 0 for `b <= 0`, which no caller passes:
/// checked, so the flight image keeps no division panic).
pub(crate) fn round_div(a: i64, b: i64) -> i64 {
    if b <= 0 {
        return 0;
    }
    let half = b / 2;
    let q = |n: i64| n.checked_div(b).unwrap_or(0);
    if a >= 0 {
        q(a.saturating_add(half))
    } else {
        -q(a.saturating_neg().saturating_add(half))
    }
}

/// A configuration that cannot work (refused at construction, nothing is read).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BissConfigError {
    /// `position_bits` is 0 or above [`MAX_POSITION_BITS`].
    PositionBits,
    /// The Start-bit window is empty or starts at bit 0.
    StartWindow,
    /// The frame would exceed [`MAX_FRAME_BYTES`].
    FrameTooLong,
    /// An encoder resolution of 0.
    Resolution,
    /// A zero offset beyond the position word.
    ZeroOffset,
    /// Some reading would not fit the controller's i32 counts.
    Range,
}

/// One slave's decoded single-cycle data.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SlaveData {
    /// Raw position (encoder steps).
    pub position: u64,
    /// The error bit is active (received 0).
    pub error: bool,
    /// The warning bit is active (received 0).
    pub warning: bool,
    /// The received CRC matches the data. When false, nothing else here is meaningful.
    pub crc_ok: bool,
}

/// Why a frame as a whole could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// SL never went low before the window ended: no Ack (slave absent or not ready).
    NoAck,
    /// No Start bit by [`BissConfig::start_bit_last`] (timeout, or SL stuck low).
    NoStart,
    /// A Start bit before [`BissConfig::start_bit_first`].
    EarlyStart,
    /// The CDS bit after the Start bit is 1.
    ControlBit,
    /// A 1 after the last slave's CRC, where the timeout must hold SL low.
    TrailingHigh,
    /// The buffer is shorter than the configured frame (a caller error).
    Short,
}

impl FrameError {
    /// The [`EncoderError`] of this framing failure for `leg` ([`EVERY_LEG`] on a chain).
    pub fn to_encoder_error(self, leg: u8) -> EncoderError {
        match self {
            FrameError::NoAck | FrameError::NoStart | FrameError::Short => {
                EncoderError::NoResponse { leg }
            }
            FrameError::EarlyStart | FrameError::ControlBit | FrameError::TrailingHigh => {
                EncoderError::Corrupted { leg }
            }
        }
    }
}

/// Bit `i` (MSB first) of `frame`.
fn bit(frame: &[u8], i: u32) -> Option<bool> {
    let byte = frame.get((i / 8) as usize)?;
    Some(byte & (0x80 >> (i % 8)) != 0)
}

/// Bits `[from, from + n)` as an unsigned integer, MSB first (`n <= 64`).
fn bits_value(frame: &[u8], from: u32, n: u32) -> Option<u64> {
    let mut v = 0u64;
    for i in from..from.checked_add(n)? {
        v = (v << 1) | u64::from(bit(frame, i)?);
    }
    Some(v)
}

/// Decodes one BiSS-C frame of `out.len()` slaves (first slave first) from the bits
/// clocked in `frame` (MSB first). Per-slave problems (CRC, error, warning) are reported
/// in `out`; problems of the frame as a whole are the `Err`.
pub fn decode_frame(
    frame: &[u8],
    cfg: &BissConfig,
    out: &mut [SlaveData],
) -> Result<(), FrameError> {
    let total = (frame.len() as u32).saturating_mul(8);
    if frame.len() < cfg.frame_bytes(out.len()) {
        return Err(FrameError::Short);
    }
    let last = u32::from(cfg.start_bit_last);
    // Ack: the first low bit.
    let mut i = 0u32;
    while i <= last && bit(frame, i) == Some(true) {
        i += 1;
    }
    if i > last {
        return Err(FrameError::NoAck);
    }
    // Start: the first high bit after the Ack.
    while i <= last && bit(frame, i) == Some(false) {
        i += 1;
    }
    if i > last {
        return Err(FrameError::NoStart);
    }
    if i < u32::from(cfg.start_bit_first) {
        return Err(FrameError::EarlyStart);
    }
    if bit(frame, i + 1) != Some(false) {
        return Err(FrameError::ControlBit);
    }
    let pos_bits = u32::from(cfg.position_bits);
    let data_bits = pos_bits + STATUS_BITS;
    let mut at = i + HEADER_BITS;
    for s in out.iter_mut() {
        let data = bits_value(frame, at, data_bits).ok_or(FrameError::Short)?;
        let sent_crc = bits_value(frame, at + data_bits, CRC_BITS).ok_or(FrameError::Short)?;
        // The position is above the two status bits; nE then nW, both active low.
        *s = SlaveData {
            position: data >> STATUS_BITS,
            error: data & 0b10 == 0,
            warning: data & 0b01 == 0,
            crc_ok: u64::from(CRC6.checksum(&data.to_be_bytes())) == sent_crc,
        };
        at += data_bits + CRC_BITS;
    }
    while at < total {
        if bit(frame, at) != Some(false) {
            return Err(FrameError::TrailingHigh);
        }
        at += 1;
    }
    Ok(())
}

/// Turns decoded slave data into counts; the first failing leg (in leg order) is the
/// error. Returns the warning mask of the intact frames beside.
fn to_counts(
    data: &[SlaveData; LEGS],
    scales: &[EncoderScale; LEGS],
) -> (Result<[i32; LEGS], EncoderError>, u8) {
    let mut counts = [0i32; LEGS];
    let mut first_err = None;
    let mut warnings = 0u8;
    for (leg, ((c, d), scale)) in counts.iter_mut().zip(data).zip(scales).enumerate() {
        let leg = leg as u8;
        if !d.crc_ok {
            first_err.get_or_insert(EncoderError::Corrupted { leg });
            continue;
        }
        if d.warning {
            warnings |= 1 << leg;
        }
        if d.error {
            first_err.get_or_insert(EncoderError::SelfCheckFailed { leg });
            continue;
        }
        *c = scale.counts(d.position);
    }
    (first_err.map_or(Ok(counts), Err), warnings)
}

fn check_scales(cfg: &BissConfig, scales: &[EncoderScale; LEGS]) -> Result<(), BissConfigError> {
    for s in scales {
        s.check(cfg.position_bits)?;
    }
    Ok(())
}

/// Six BiSS-C encoders in one daisy chain on one SPI device: one transaction latches
/// all six positions on the same clock edge (slave 1 of the chain, the one whose SLO
/// goes to the master, is leg 1).
pub struct BissChain<SPI> {
    spi: SPI,
    cfg: BissConfig,
    scales: [EncoderScale; LEGS],
    frame_len: usize,
    buf: [u8; MAX_FRAME_BYTES],
    warnings: u8,
}

impl<SPI: SpiDevice> BissChain<SPI> {
    /// A chain with the given frame layout and per-leg scales; refuses a configuration
    /// that cannot work.
    pub fn new(
        spi: SPI,
        cfg: BissConfig,
        scales: [EncoderScale; LEGS],
    ) -> Result<Self, BissConfigError> {
        cfg.check(LEGS)?;
        check_scales(&cfg, &scales)?;
        Ok(Self {
            spi,
            cfg,
            scales,
            frame_len: cfg.frame_bytes(LEGS),
            buf: [0; MAX_FRAME_BYTES],
            warnings: 0,
        })
    }

    /// Bytes clocked per read.
    pub fn frame_len(&self) -> usize {
        self.frame_len
    }

    /// Gives the SPI device back.
    pub fn release(self) -> SPI {
        self.spi
    }
}

impl<SPI: SpiDevice> StrokeEncoders for BissChain<SPI> {
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError> {
        self.warnings = 0;
        let frame = self
            .buf
            .get_mut(..self.frame_len)
            .ok_or(EncoderError::NoResponse { leg: EVERY_LEG })?;
        self.spi
            .read(frame)
            .map_err(|_| EncoderError::NoResponse { leg: EVERY_LEG })?;
        let mut data = [SlaveData::default(); LEGS];
        decode_frame(frame, &self.cfg, &mut data).map_err(|e| e.to_encoder_error(EVERY_LEG))?;
        let (result, warnings) = to_counts(&data, &self.scales);
        self.warnings = warnings;
        result
    }
}

impl<SPI> EncoderWarnings for BissChain<SPI> {
    fn warning_legs(&self) -> u8 {
        self.warnings
    }
}

/// Six point-to-point BiSS-C encoders, one SPI device each, read one after the other in
/// every call (all six, whatever fails, so every encoder is polled at the same rate).
/// The six positions are latched one frame time apart (about `frame_len * 8` clock
/// periods each), not at one instant: prefer [`BissChain`] where the wiring allows.
pub struct BissPointToPoint<SPI> {
    spis: [SPI; LEGS],
    cfg: BissConfig,
    scales: [EncoderScale; LEGS],
    frame_len: usize,
    warnings: u8,
}

impl<SPI: SpiDevice> BissPointToPoint<SPI> {
    /// Six links with one frame layout and per-leg scales.
    pub fn new(
        spis: [SPI; LEGS],
        cfg: BissConfig,
        scales: [EncoderScale; LEGS],
    ) -> Result<Self, BissConfigError> {
        cfg.check(1)?;
        check_scales(&cfg, &scales)?;
        Ok(Self {
            spis,
            cfg,
            scales,
            frame_len: cfg.frame_bytes(1),
            warnings: 0,
        })
    }

    /// Bytes clocked per encoder and read.
    pub fn frame_len(&self) -> usize {
        self.frame_len
    }
}

impl<SPI: SpiDevice> StrokeEncoders for BissPointToPoint<SPI> {
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError> {
        let mut data = [SlaveData::default(); LEGS];
        let mut frame_err: Option<EncoderError> = None;
        for (leg, (spi, d)) in self.spis.iter_mut().zip(data.iter_mut()).enumerate() {
            let leg = leg as u8;
            let mut buf = [0u8; MAX_FRAME_BYTES];
            let Some(frame) = buf.get_mut(..self.frame_len) else {
                frame_err.get_or_insert(EncoderError::NoResponse { leg });
                continue;
            };
            let mut one = [SlaveData::default()];
            let r = match spi.read(frame) {
                Err(_) => Err(EncoderError::NoResponse { leg }),
                Ok(()) => {
                    decode_frame(frame, &self.cfg, &mut one).map_err(|e| e.to_encoder_error(leg))
                }
            };
            match r {
                Ok(()) => {
                    let [decoded] = one;
                    *d = decoded;
                }
                Err(e) => {
                    frame_err.get_or_insert(e);
                    // Not decoded: treated as corrupt below, but `frame_err` (earlier or
                    // this leg's own) is what is reported for it.
                    d.crc_ok = false;
                }
            }
        }
        let (result, warnings) = to_counts(&data, &self.scales);
        self.warnings = warnings;
        // The first failure in leg order, whichever kind.
        match (frame_err, result) {
            (Some(fe), Err(ce)) => Err(if ce.leg() < fe.leg() { ce } else { fe }),
            (Some(fe), Ok(_)) => Err(fe),
            (None, r) => r,
        }
    }
}

impl<SPI> EncoderWarnings for BissPointToPoint<SPI> {
    fn warning_legs(&self) -> u8 {
        self.warnings
    }
}

/// A BiSS link on a bare [`SpiBus`]: BiSS has no chip select (the first MA edge starts
/// a frame), so a transaction is the bus operations followed by a flush. Delay
/// operations are refused ([`MaLineError::DelayUnsupported`]); the encoder drivers
/// never use them.
pub struct MaLine<B>(pub B);

/// Error of [`MaLine`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaLineError<E> {
    /// The bus failed.
    Bus(E),
    /// A transaction asked for a delay, which a bare bus cannot time.
    DelayUnsupported,
}

impl<E: embedded_hal::spi::Error> embedded_hal::spi::Error for MaLineError<E> {
    fn kind(&self) -> embedded_hal::spi::ErrorKind {
        match self {
            MaLineError::Bus(e) => e.kind(),
            MaLineError::DelayUnsupported => embedded_hal::spi::ErrorKind::Other,
        }
    }
}

impl<B: SpiBus> ErrorType for MaLine<B> {
    type Error = MaLineError<B::Error>;
}

impl<B: SpiBus> SpiDevice for MaLine<B> {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
        for op in operations.iter_mut() {
            match op {
                Operation::Read(buf) => self.0.read(buf),
                Operation::Write(buf) => self.0.write(buf),
                Operation::Transfer(read, write) => self.0.transfer(read, write),
                Operation::TransferInPlace(buf) => self.0.transfer_in_place(buf),
                Operation::DelayNs(_) => return Err(MaLineError::DelayUnsupported),
            }
            .map_err(MaLineError::Bus)?;
        }
        self.0.flush().map_err(MaLineError::Bus)
    }
}
