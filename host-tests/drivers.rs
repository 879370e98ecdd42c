//! The hardware drivers (src/drivers) against embedded-hal-mock: expected SPI
//! transactions and pin states.
//!
//! * BiSS-C: frames built by a generator written here from the protocol description
//!   (bit by bit, its own shift-register CRC, not the decoder's), decoded by the chain
//!   and point-to-point drivers; every single-bit error of a frame is detected (or, before
//!   the Start bit, cannot change a reading); every failure maps to its `EncoderError`;
//!   the warning bit reaches `warning_legs`; `SelfCheckFailed` is a read failure of its
//!   leg in the supervisor.
//! * Stepper: the total of the pulses over long moves equals the commanded stroke to
//!   the microstep (where per-cycle rounding would drift); pin states for enable,
//!   direction and fault; refusal before alignment; rate limit; unsent pulses.
//! * Limit switches: a switch seen is in the read of that cycle, and with the stepper's
//!   inhibit no pulse towards it is issued in that cycle.

use std::cell::RefCell;
use std::rc::Rc;

use embedded_hal::digital::{ErrorType as PinErrorType, InputPin, OutputPin};
use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};
use embedded_hal_mock::eh1::digital::{
    Mock as PinMock, State as PinState, Transaction as PinTransaction,
};
use embedded_hal_mock::eh1::spi::{Mock as SpiMock, Transaction as SpiTransaction};
use embedded_hal_mock::eh1::MockError;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use m2ctl::drivers::biss::{
    BissChain, BissConfig, BissConfigError, BissPointToPoint, EncoderScale, MaLine, BISS_CRC6,
};
use m2ctl::drivers::stepper::{
    StepDirDrives, StepPulses, StepperConfig, StepperLeg, StepperPolarity,
};
use m2ctl::drivers::switches::{LegSwitches, SwitchPolarity, TravelSwitchInputs};
use m2ctl::drivers::Mechanism;
use m2ctl::hw::{
    DriveError, EncoderError, EncoderWarnings, EndOfTravel, IssuedStrokes, SliderDrives,
    StrokeEncoders, TravelSwitches, EVERY_LEG,
};
use m2ctl::kinematics::{FkSolution, Pose, LEGS};
use m2ctl::supervision::{CycleInputs, FaultFlags, SupervisionConfig, Supervisor};

// =====================================================================================
// BiSS-C frame generator (independent of the decoder).

/// Controller count in picometres (0.1 um), as the ICD defines the encoder count.
const PM_PER_COUNT: f64 = 100_000.0;

/// CRC-6, polynomial x^6 + x + 1, start 0, over `bits` MSB first: a plain shift
/// register, as drawn in the encoder manuals ("1st stage .. 6th stage").
fn crc6(bits: &[bool]) -> u8 {
    let mut reg = 0u8;
    for &b in bits {
        let feedback = ((reg >> 5) & 1 == 1) ^ b;
        reg = (reg << 1) & 0x3F;
        if feedback {
            reg ^= 0b00_0011; // the x^1 and x^0 taps
        }
    }
    reg
}

/// What one slave sends.
#[derive(Clone, Copy, Debug)]
struct Slave {
    position: u64,
    /// Error bit as sent (true = 1 = no error).
    n_e: bool,
    /// Warning bit as sent (true = 1 = no warning).
    n_w: bool,
}

impl Slave {
    fn ok(position: u64) -> Self {
        Self {
            position,
            n_e: true,
            n_w: true,
        }
    }
}

/// A frame as the master samples it: `idle` high bits, `ack` low bits, Start, CDS, each
/// slave's position/nE/nW/inverted CRC, then low bits up to `bytes` bytes.
fn frame_bits(
    idle: usize,
    ack: usize,
    cds: bool,
    pos_bits: usize,
    slaves: &[Slave],
    bytes: usize,
) -> Vec<bool> {
    let mut v = vec![true; idle];
    v.extend(std::iter::repeat_n(false, ack));
    v.push(true); // Start
    v.push(cds);
    for s in slaves {
        let mut data: Vec<bool> = (0..pos_bits)
            .rev()
            .map(|i| (s.position >> i) & 1 == 1)
            .collect();
        data.push(s.n_e);
        data.push(s.n_w);
        let crc = crc6(&data) ^ 0x3F; // transmitted inverted
        v.extend(&data);
        v.extend((0..6).rev().map(|i| (crc >> i) & 1 == 1));
    }
    assert!(v.len() < bytes * 8, "frame does not fit");
    v.resize(bytes * 8, false); // timeout: SL low
    v
}

fn to_bytes(bits: &[bool]) -> Vec<u8> {
    bits.chunks(8)
        .map(|c| c.iter().fold(0u8, |acc, &b| (acc << 1) | u8::from(b)))
        .collect()
}

/// RESOLUTE-like linear encoders: 26-bit position words.
const POS_BITS: u8 = 26;
/// Idle-high bits before the Ack, as SPI mode 2 samples them (second rising edge).
const IDLE_BITS: usize = 2;
/// Ack length of the simulated installation.
const ACK_BITS: usize = 3;
/// The Start bit's index in that installation.
const START_AT: u16 = (IDLE_BITS + ACK_BITS) as u16;

fn exact_cfg() -> BissConfig {
    BissConfig {
        position_bits: POS_BITS,
        start_bit_first: START_AT,
        start_bit_last: START_AT,
    }
}

/// Six scales: 1 nm, 5 nm and 50 nm resolutions, various zeros, two reversed.
fn scales() -> [EncoderScale; LEGS] {
    let lsb = [1_000, 5_000, 50_000, 1_000, 5_000, 1_000];
    let mut out = [EncoderScale {
        lsb_pm: 0,
        zero_lsb: 0,
        reversed: false,
    }; LEGS];
    for (i, s) in out.iter_mut().enumerate() {
        *s = EncoderScale {
            lsb_pm: lsb[i],
            zero_lsb: 1 << 24 | (i as u64 * 12_345),
            reversed: i % 3 == 2,
        };
    }
    out
}

/// Expected controller counts, computed independently in f64 (exact for these sizes).
fn expected_counts(s: &EncoderScale, raw: u64) -> i32 {
    let pm = (raw as f64 - s.zero_lsb as f64) * f64::from(s.lsb_pm);
    let pm = if s.reversed { -pm } else { pm };
    // Nearest count, ties away from zero.
    let c = pm / PM_PER_COUNT;
    (c.signum() * (c.abs() + 0.5).floor()) as i32
}

/// Raw positions within +-6 mm of each leg's zero.
fn random_slaves(rng: &mut Pcg64, sc: &[EncoderScale; LEGS]) -> [Slave; LEGS] {
    std::array::from_fn(|i| {
        let span = (6.0e9 / f64::from(sc[i].lsb_pm)) as i64; // 6 mm in encoder steps
        let raw = sc[i].zero_lsb as i64 + rng.random_range(-span..=span);
        Slave::ok(raw as u64)
    })
}

fn spi_reading(bytes: Vec<u8>) -> Vec<SpiTransaction<u8>> {
    vec![
        SpiTransaction::transaction_start(),
        SpiTransaction::read_vec(bytes),
        SpiTransaction::transaction_end(),
    ]
}

/// Reads one frame through a `BissChain` on a mock SPI that returns `bits`.
fn chain_read(cfg: BissConfig, bits: &[bool]) -> (Result<[i32; LEGS], EncoderError>, u8) {
    let mut spi = SpiMock::new(&spi_reading(to_bytes(bits)));
    let mut enc = BissChain::new(spi.clone(), cfg, scales()).unwrap();
    let r = enc.read_counts();
    let w = enc.warning_legs();
    spi.done();
    (r, w)
}

fn chain_frame(cfg: &BissConfig, slaves: &[Slave; LEGS]) -> Vec<bool> {
    frame_bits(
        IDLE_BITS,
        ACK_BITS,
        false,
        POS_BITS as usize,
        slaves,
        cfg.frame_bytes(LEGS),
    )
}

#[test]
fn crc6_of_the_generator_and_the_decoder_agree() {
    // The decoder uses the `crc` crate's table with BISS_CRC6; the generator a shift
    // register. Same definition, two implementations: they must agree on every input.
    let table = crc::Crc::<u8>::new(&BISS_CRC6);
    let mut rng = Pcg64::seed_from_u64(61);
    for _ in 0..2000 {
        let n = rng.random_range(1..=50);
        let v: u64 = rng.random::<u64>() & ((1u64 << n) - 1);
        let bits: Vec<bool> = (0..n).rev().map(|i| (v >> i) & 1 == 1).collect();
        assert_eq!(
            table.checksum(&v.to_be_bytes()),
            crc6(&bits) ^ 0x3F,
            "{n} bits {v:#x}"
        );
    }
    // The catalogue-style check value stated in BISS_CRC6 (CRC of ASCII "123456789").
    let ascii: Vec<bool> = b"123456789"
        .iter()
        .flat_map(|c| (0..8).rev().map(move |i| (c >> i) & 1 == 1))
        .collect();
    assert_eq!(crc6(&ascii) ^ 0x3F, BISS_CRC6.check);
    assert_eq!(table.checksum(b"123456789"), BISS_CRC6.check);
}

#[test]
fn chain_decodes_six_positions_in_one_transaction() {
    let cfg = BissConfig {
        position_bits: POS_BITS,
        start_bit_first: 1,
        start_bit_last: 12,
    };
    let sc = scales();
    let mut rng = Pcg64::seed_from_u64(7);
    for case in 0..300 {
        let slaves = random_slaves(&mut rng, &sc);
        // Any Ack length inside the window.
        let idle = rng.random_range(0..=2);
        let ack = rng.random_range(1..=(12 - idle));
        let bits = frame_bits(
            idle,
            ack,
            false,
            POS_BITS as usize,
            &slaves,
            cfg.frame_bytes(LEGS),
        );
        let (r, w) = chain_read(cfg, &bits);
        let want: [i32; LEGS] =
            std::array::from_fn(|i| expected_counts(&sc[i], slaves[i].position));
        assert_eq!(r, Ok(want), "case {case}");
        assert_eq!(w, 0);
    }
}

#[test]
fn every_single_bit_error_in_a_chain_frame_is_detected() {
    let cfg = exact_cfg();
    let sc = scales();
    let mut rng = Pcg64::seed_from_u64(11);
    let mut flips = 0usize;
    let mut harmless = 0usize;
    for _ in 0..20 {
        let slaves = random_slaves(&mut rng, &sc);
        let bits = chain_frame(&cfg, &slaves);
        let (good, _) = chain_read(cfg, &bits);
        let good = good.unwrap();
        let start = usize::from(START_AT);
        let slave_len = usize::from(POS_BITS) + 8;
        for k in 0..bits.len() {
            let mut b = bits.clone();
            b[k] = !b[k];
            let (r, _) = chain_read(cfg, &b);
            flips += 1;
            if k < start {
                // Before the Start bit: detected, or the frame is unchanged.
                match r {
                    Err(_) => {}
                    Ok(c) => {
                        assert_eq!(c, good, "flip {k} before the start changed a reading");
                        harmless += 1;
                    }
                }
                continue;
            }
            let want = if k == start {
                EncoderError::NoResponse { leg: EVERY_LEG } // Start lost: no start in the window
            } else if k == start + 1 {
                EncoderError::Corrupted { leg: EVERY_LEG } // CDS
            } else if k < start + 2 + LEGS * slave_len {
                EncoderError::Corrupted {
                    leg: ((k - start - 2) / slave_len) as u8,
                }
            } else {
                EncoderError::Corrupted { leg: EVERY_LEG } // a 1 in the timeout
            };
            assert_eq!(r, Err(want), "flip of bit {k}");
        }
    }
    println!(
        "chain: {flips} single-bit errors, all detected except {harmless} idle/Ack flips that leave the frame as it was"
    );
}

#[test]
fn a_wide_start_window_still_catches_shifted_chain_frames() {
    // With a tolerant window a flipped Ack bit shifts the frame; six CRCs and the
    // trailing-zero check must catch it. (With one slave a shift can pass with a
    // probability of about 2^-6: use the exact window there.)
    let cfg = BissConfig {
        position_bits: POS_BITS,
        start_bit_first: 1,
        start_bit_last: 12,
    };
    let sc = scales();
    let mut rng = Pcg64::seed_from_u64(12);
    let mut wrong = 0;
    let mut caught = 0;
    for _ in 0..50 {
        let slaves = random_slaves(&mut rng, &sc);
        let bits = frame_bits(
            2,
            6,
            false,
            POS_BITS as usize,
            &slaves,
            cfg.frame_bytes(LEGS),
        );
        let (good, _) = chain_read(cfg, &bits);
        let good = good.unwrap();
        for k in 0..bits.len() {
            let mut b = bits.clone();
            b[k] = !b[k];
            match chain_read(cfg, &b).0 {
                Err(_) => caught += 1,
                Ok(c) if c == good => {}
                Ok(_) => wrong += 1,
            }
        }
    }
    println!("wide window: {caught} flips detected, {wrong} wrong readings");
    assert_eq!(wrong, 0);
}

#[test]
fn every_failure_maps_to_its_encoder_error() {
    let cfg = exact_cfg();
    let sc = scales();
    let mut rng = Pcg64::seed_from_u64(3);
    let slaves = random_slaves(&mut rng, &sc);
    let n = cfg.frame_bytes(LEGS);
    let pos = POS_BITS as usize;

    // Line high throughout: no Ack.
    let (r, _) = chain_read(cfg, &vec![true; n * 8]);
    assert_eq!(r, Err(EncoderError::NoResponse { leg: EVERY_LEG }));
    // Line low throughout (busy, or stuck): no Start bit.
    let (r, _) = chain_read(cfg, &vec![false; n * 8]);
    assert_eq!(r, Err(EncoderError::NoResponse { leg: EVERY_LEG }));
    // Start bit one bit late (a slow slave): timeout.
    let late = frame_bits(IDLE_BITS, ACK_BITS + 1, false, pos, &slaves, n);
    assert_eq!(
        chain_read(cfg, &late).0,
        Err(EncoderError::NoResponse { leg: EVERY_LEG })
    );
    // Start bit one bit early: framing error.
    let early = frame_bits(IDLE_BITS, ACK_BITS - 1, false, pos, &slaves, n);
    assert_eq!(
        chain_read(cfg, &early).0,
        Err(EncoderError::Corrupted { leg: EVERY_LEG })
    );
    // CDS = 1.
    let cds = frame_bits(IDLE_BITS, ACK_BITS, true, pos, &slaves, n);
    assert_eq!(
        chain_read(cfg, &cds).0,
        Err(EncoderError::Corrupted { leg: EVERY_LEG })
    );
    // A seventh slave in the chain (its data where the timeout must be low).
    let mut seven = slaves.to_vec();
    seven.push(Slave::ok(0x3FF_FFFF));
    let seven = frame_bits(IDLE_BITS, ACK_BITS, false, pos, &seven, n + 5);
    assert_eq!(
        chain_read(cfg, &seven[..n * 8]).0,
        Err(EncoderError::Corrupted { leg: EVERY_LEG })
    );
    // Error bit of leg 2 (CRC good): the encoder's own check failed.
    let mut s = slaves;
    s[2].n_e = false;
    assert_eq!(
        chain_read(cfg, &chain_frame(&cfg, &s)).0,
        Err(EncoderError::SelfCheckFailed { leg: 2 })
    );
    // Warning bit of legs 1 and 4: the reading stands, the warning is reported.
    let mut s = slaves;
    s[1].n_w = false;
    s[4].n_w = false;
    let (r, w) = chain_read(cfg, &chain_frame(&cfg, &s));
    assert_eq!(
        r.map(|c| c[4]),
        Ok(expected_counts(&sc[4], slaves[4].position))
    );
    assert_eq!(w, 0b01_0010);
    // Error and warning together: the error wins, the warning is still reported.
    let mut s = slaves;
    s[3].n_e = false;
    s[3].n_w = false;
    let (r, w) = chain_read(cfg, &chain_frame(&cfg, &s));
    assert_eq!(r, Err(EncoderError::SelfCheckFailed { leg: 3 }));
    assert_eq!(w, 1 << 3);
    // A warning in a frame whose CRC fails is not believed.
    let mut s = slaves;
    s[5].n_w = false;
    let mut bits = chain_frame(&cfg, &s);
    let crc_bit_of_leg5 = usize::from(START_AT) + 2 + 5 * (pos + 8) + pos + 2;
    bits[crc_bit_of_leg5] = !bits[crc_bit_of_leg5];
    let (r, w) = chain_read(cfg, &bits);
    assert_eq!(r, Err(EncoderError::Corrupted { leg: 5 }));
    assert_eq!(w, 0);
    // The SPI bus itself fails.
    struct Broken;
    impl ErrorType for Broken {
        type Error = ErrorKind;
    }
    impl SpiDevice for Broken {
        fn transaction(&mut self, _: &mut [Operation<'_, u8>]) -> Result<(), ErrorKind> {
            Err(ErrorKind::ModeFault)
        }
    }
    let mut enc = BissChain::new(Broken, cfg, sc).unwrap();
    assert_eq!(
        enc.read_counts(),
        Err(EncoderError::NoResponse { leg: EVERY_LEG })
    );
    // Stable codes.
    assert_eq!(
        [
            EncoderError::NoResponse { leg: 0 }.code(),
            EncoderError::Corrupted { leg: 0 }.code(),
            EncoderError::SelfCheckFailed { leg: 0 }.code()
        ],
        [1, 2, 3]
    );
}

#[test]
fn point_to_point_reads_all_six_and_names_the_failing_leg() {
    let cfg = exact_cfg();
    let sc = scales();
    let mut rng = Pcg64::seed_from_u64(5);
    let slaves = random_slaves(&mut rng, &sc);
    let n = cfg.frame_bytes(1);
    let frames: Vec<Vec<bool>> = slaves
        .iter()
        .map(|s| frame_bits(IDLE_BITS, ACK_BITS, false, POS_BITS as usize, &[*s], n))
        .collect();
    let run = |frames: &[Vec<bool>]| {
        let mut mocks: Vec<SpiMock<u8>> = frames
            .iter()
            .map(|f| SpiMock::new(&spi_reading(to_bytes(f))))
            .collect();
        let spis: [SpiMock<u8>; LEGS] = std::array::from_fn(|i| mocks[i].clone());
        let mut enc = BissPointToPoint::new(spis, cfg, sc).unwrap();
        let r = enc.read_counts();
        let w = enc.warning_legs();
        // Every encoder was read, whatever failed.
        for m in mocks.iter_mut() {
            m.done();
        }
        (r, w)
    };
    let want: [i32; LEGS] = std::array::from_fn(|i| expected_counts(&sc[i], slaves[i].position));
    assert_eq!(run(&frames), (Ok(want), 0));

    let mut f = frames.clone();
    f[4] = vec![true; n * 8]; // leg 5 silent
    assert_eq!(run(&f).0, Err(EncoderError::NoResponse { leg: 4 }));
    let mut f = frames.clone();
    f[1][usize::from(START_AT) + 5] ^= true; // leg 2 corrupted
    f[4] = vec![true; n * 8]; // and leg 5 silent: the first in leg order is reported
    assert_eq!(run(&f).0, Err(EncoderError::Corrupted { leg: 1 }));
    let mut f = frames.clone();
    f[0] = frame_bits(
        IDLE_BITS,
        ACK_BITS,
        true,
        POS_BITS as usize,
        &[slaves[0]],
        n,
    ); // CDS
    assert_eq!(run(&f).0, Err(EncoderError::Corrupted { leg: 0 }));
    let mut s = slaves;
    s[3].n_w = false;
    let mut f = frames.clone();
    f[3] = frame_bits(IDLE_BITS, ACK_BITS, false, POS_BITS as usize, &[s[3]], n);
    assert_eq!(run(&f), (Ok(want), 1 << 3));

    // Every single-bit error of a point-to-point frame (exact window) is detected or harmless.
    let bits = &frames[2];
    for k in 0..bits.len() {
        let mut f = frames.clone();
        f[2][k] ^= true;
        match run(&f).0 {
            Err(e) => assert_eq!(e.leg(), 2, "flip {k}"),
            Ok(c) => {
                assert!(
                    k < usize::from(START_AT),
                    "flip {k} after the start not detected"
                );
                assert_eq!(c, want);
            }
        }
    }
}

#[test]
fn scales_convert_to_controller_counts() {
    // 1 nm encoder, zero at 1000 steps: 100 steps = 1 count; 150 = 1.5 -> 2 (away from 0).
    let s = EncoderScale {
        lsb_pm: 1_000,
        zero_lsb: 1_000,
        reversed: false,
    };
    assert_eq!(
        [
            s.counts(1_000),
            s.counts(1_100),
            s.counts(1_150),
            s.counts(850),
            s.counts(1_149)
        ],
        [0, 1, 2, -2, 1]
    );
    // 50 nm, reversed: +1 step = -0.5 count -> -1.
    let r = EncoderScale {
        lsb_pm: 50_000,
        zero_lsb: 10,
        reversed: true,
    };
    assert_eq!([r.counts(11), r.counts(12), r.counts(8)], [-1, -1, 1]);
    // Refused configurations change nothing and read nothing.
    let bad = |cfg: BissConfig, sc: [EncoderScale; LEGS]| {
        let spi = SpiMock::<u8>::new(&[]);
        let r = BissChain::new(spi.clone(), cfg, sc).err();
        spi.clone().done();
        r
    };
    let mut c = exact_cfg();
    c.position_bits = 0;
    assert_eq!(bad(c, scales()), Some(BissConfigError::PositionBits));
    c.position_bits = 49;
    assert_eq!(bad(c, scales()), Some(BissConfigError::PositionBits));
    let mut c = exact_cfg();
    c.start_bit_first = c.start_bit_last + 1;
    assert_eq!(bad(c, scales()), Some(BissConfigError::StartWindow));
    let mut c = exact_cfg();
    c.position_bits = 48;
    c.start_bit_last = 200;
    assert_eq!(bad(c, scales()), Some(BissConfigError::FrameTooLong));
    let mut sc = scales();
    sc[1].lsb_pm = 0;
    assert_eq!(bad(exact_cfg(), sc), Some(BissConfigError::Resolution));
    let mut sc = scales();
    sc[1].zero_lsb = 1 << 26;
    assert_eq!(bad(exact_cfg(), sc), Some(BissConfigError::ZeroOffset));
    let mut c = exact_cfg();
    c.position_bits = 40; // 2^40 nm = 1.1 km: beyond i32 counts
    assert_eq!(bad(c, scales()), Some(BissConfigError::Range));
}

#[test]
fn self_check_failure_is_a_read_failure_of_its_leg() {
    let mut sup = Supervisor::new(SupervisionConfig::default());
    let home = [0.0f32; LEGS];
    let inputs = |enc| CycleInputs {
        encoders: enc,
        commanded_prev_mm: home,
        motion_commanded: false,
        fk: Some(Ok(FkSolution {
            pose: Pose::home(),
            iterations: 1,
            residual_mm: 0.0,
        })),
        drive: Ok(()),
        switches: TravelSwitches::default(),
        encoder_warning_legs: 0,
    };
    assert!(sup.check(&inputs(Ok(home))).new_faults.is_empty());
    let v = sup.check(&inputs(Err(EncoderError::SelfCheckFailed { leg: 2 })));
    assert_eq!(v.new_faults, FaultFlags::ENCODER_READ_FAILURE);
    assert_eq!(v.new_fault_legs, 1 << 2);
    // A whole-chain failure blames every leg.
    let mut sup = Supervisor::new(SupervisionConfig::default());
    let v = sup.check(&inputs(Err(EncoderError::Corrupted { leg: EVERY_LEG })));
    assert_eq!(v.new_fault_legs, 0b11_1111);
}

#[test]
fn ma_line_is_a_spi_device_without_chip_select() {
    let mut bus = SpiMock::new(&[
        SpiTransaction::read_vec(vec![0xA5, 0x5A]),
        SpiTransaction::flush(),
    ]);
    let mut dev = MaLine(bus.clone());
    let mut buf = [0u8; 2];
    dev.read(&mut buf).unwrap();
    assert_eq!(buf, [0xA5, 0x5A]);
    assert!(dev.transaction(&mut [Operation::DelayNs(10)]).is_err());
    bus.done();
}

// =====================================================================================
// Stepper drives.

/// A step-pulse generator that records every train and can leave pulses unsent.
#[derive(Clone, Default)]
struct RecPulses(Rc<RefCell<RecState>>);

#[derive(Default)]
struct RecState {
    trains: Vec<u32>,
    /// Pulses of the current train not sent when `stop` is called.
    unsent_at_stop: u32,
    running: u32,
    stops: u32,
}

impl StepPulses for RecPulses {
    type Error = ();
    fn start(&mut self, count: u32) -> Result<(), ()> {
        let mut s = self.0.borrow_mut();
        assert!(count > 0);
        s.trains.push(count);
        s.running = count;
        Ok(())
    }
    fn stop(&mut self) -> u32 {
        let mut s = self.0.borrow_mut();
        s.stops += 1;
        let unsent = s.unsent_at_stop.min(s.running);
        s.running = 0;
        s.unsent_at_stop = 0;
        // `trains` holds the pulses actually sent.
        if let Some(t) = s.trains.last_mut() {
            *t -= unsent;
        }
        unsent
    }
}

/// An output that records its level history (the drift test's direction pin).
#[derive(Clone, Default)]
struct RecPin(Rc<RefCell<Vec<bool>>>);

impl PinErrorType for RecPin {
    type Error = core::convert::Infallible;
}
impl OutputPin for RecPin {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.0.borrow_mut().push(false);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.0.borrow_mut().push(true);
        Ok(())
    }
}
/// A healthy fault input (active low: reads high).
#[derive(Clone, Default)]
struct Healthy;
impl PinErrorType for Healthy {
    type Error = core::convert::Infallible;
}
impl InputPin for Healthy {
    fn is_high(&mut self) -> Result<bool, Self::Error> {
        Ok(true)
    }
    fn is_low(&mut self) -> Result<bool, Self::Error> {
        Ok(false)
    }
}

const POLARITY: StepperPolarity = StepperPolarity {
    dir_high_is_positive: true,
    enable_active_high: false,
    fault_active_high: false,
};

/// 1 mm lead screw, 200 steps, 16 microsteps, 3:1 gear: 9,600 microsteps per mm.
fn stepper_cfg() -> StepperConfig {
    StepperConfig {
        lead_screw_pitch_nm: 1_000_000,
        full_steps_per_rev: 200,
        microsteps_per_step: 16,
        gear_motor_revs: 3,
        gear_screw_revs: 1,
        max_microsteps_per_cycle: 100,
        travel_limit_nm: 8_000_000,
        polarity: POLARITY,
    }
}

type RecDrives = StepDirDrives<RecPulses, RecPin, RecPin, Healthy>;

fn rec_drives(cfg: StepperConfig) -> (RecDrives, Vec<RecPulses>, Vec<RecPin>) {
    let pulses: Vec<RecPulses> = (0..LEGS).map(|_| RecPulses::default()).collect();
    let dirs: Vec<RecPin> = (0..LEGS).map(|_| RecPin::default()).collect();
    let legs = std::array::from_fn(|i| StepperLeg {
        pulses: pulses[i].clone(),
        dir: dirs[i].clone(),
        enable: RecPin::default(),
        fault: Healthy,
    });
    let d = StepDirDrives::new(legs, cfg).map_err(|(e, _)| e).unwrap();
    (d, pulses, dirs)
}

/// Net microsteps of one leg from its recorded trains and direction pin history (each
/// train follows one direction write; `dir_high_is_positive`).
fn net_microsteps(p: &RecPulses, d: &RecPin) -> i64 {
    let trains = &p.0.borrow().trains;
    let dirs = &d.0.borrow();
    // The first direction write is `new`'s; then one before each train.
    assert_eq!(dirs.len(), trains.len() + 1);
    trains
        .iter()
        .zip(dirs.iter().skip(1))
        .map(|(&n, &high)| if high { i64::from(n) } else { -i64::from(n) })
        .sum()
}

/// The exact microstep nearest to the f32 stroke `mm` for `cfg`: the f32 scaled by
/// 2^64 is an exact integer (24 significant bits), so the rational arithmetic is exact.
fn nearest_microstep(cfg: &StepperConfig, mm: f32) -> i64 {
    let x = (f64::from(mm) * 2f64.powi(64)) as i128;
    let num = x
        * 1_000_000
        * i128::from(cfg.full_steps_per_rev)
        * i128::from(cfg.microsteps_per_step)
        * i128::from(cfg.gear_motor_revs);
    let den = (i128::from(cfg.lead_screw_pitch_nm) * i128::from(cfg.gear_screw_revs)) << 64;
    // Nearest, ties away from zero.
    let q = (2 * num.abs() + den) / (2 * den);
    (q * num.signum()) as i64
}

#[test]
fn long_moves_total_the_commanded_stroke_to_the_microstep() {
    let mut rng = Pcg64::seed_from_u64(2024);
    let mut worst_naive_drift = 0i64;
    for case in 0..40 {
        let mut cfg = stepper_cfg();
        // Awkward ratios: pitch 0.5..2 mm in odd nm, 1..256 microsteps, gears like 7:3.
        cfg.lead_screw_pitch_nm = rng.random_range(500_000..2_000_000) | 1;
        cfg.microsteps_per_step = [1, 2, 8, 16, 32, 64, 128][rng.random_range(0..7)];
        cfg.gear_motor_revs = rng.random_range(1..=13);
        cfg.gear_screw_revs = rng.random_range(1..=7);
        cfg.max_microsteps_per_cycle = 1_000_000;
        let (mut drives, pulses, dirs) = rec_drives(cfg);
        drives.align_issued_mm(&[0.0; LEGS]);
        // Per leg: a long smooth move from 0 to a target (10,000 cycles, sine profile),
        // then back part of the way; setpoints in f32 as the controller sends them.
        let targets: [f64; LEGS] = std::array::from_fn(|_| rng.random_range(-5.0..5.0));
        let back: [f64; LEGS] = std::array::from_fn(|i| targets[i] * rng.random_range(0.1..0.9));
        let cycles = 10_000;
        let mut naive = [0i64; LEGS];
        let mut prev_sp = [0.0f64; LEGS];
        let per_mm = cfg.microsteps_per_mm();
        let mut last = [0.0f32; LEGS];
        for c in 1..=2 * cycles {
            let sp: [f32; LEGS] = std::array::from_fn(|i| {
                let (from, to, t) = if c <= cycles {
                    (0.0, targets[i], c as f64 / cycles as f64)
                } else {
                    (targets[i], back[i], (c - cycles) as f64 / cycles as f64)
                };
                let s = 0.5 - 0.5 * (std::f64::consts::PI * t).cos();
                (from + (to - from) * s) as f32
            });
            drives.command_strokes_mm(&sp).unwrap();
            for i in 0..LEGS {
                // What rounding each cycle's increment would have issued.
                naive[i] += ((f64::from(sp[i]) - prev_sp[i]) * per_mm).round() as i64;
                prev_sp[i] = f64::from(sp[i]);
            }
            last = sp;
        }
        for i in 0..LEGS {
            let want = nearest_microstep(&cfg, last[i]);
            let got = net_microsteps(&pulses[i], &dirs[i]);
            assert_eq!(got, want, "case {case} leg {i}");
            assert_eq!(drives.issued_microsteps()[i], want);
            worst_naive_drift = worst_naive_drift.max((naive[i] - want).abs());
            // The issued stroke is the commanded one within half a microstep.
            let issued = f64::from(drives.issued_strokes_mm()[i]);
            assert!(
                (issued - f64::from(last[i])).abs() <= 0.5 / per_mm + 1e-6,
                "case {case} leg {i}: issued {issued} commanded {}",
                last[i]
            );
        }
    }
    println!("drift of per-cycle rounding over the same moves: up to {worst_naive_drift} microsteps; this driver: 0");
    assert!(
        worst_naive_drift > 10,
        "the profile should defeat per-cycle rounding"
    );
}

/// Mock pins of one leg with their expectations; `done` checks them all.
struct MockLeg {
    dir: PinMock,
    enable: PinMock,
    fault: PinMock,
}

fn mock_drives(
    legs: Vec<(
        Vec<PinTransaction>,
        Vec<PinTransaction>,
        Vec<PinTransaction>,
    )>,
) -> (
    StepDirDrives<RecPulses, PinMock, PinMock, PinMock>,
    Vec<RecPulses>,
    Vec<MockLeg>,
) {
    let pulses: Vec<RecPulses> = (0..LEGS).map(|_| RecPulses::default()).collect();
    let mocks: Vec<MockLeg> = legs
        .iter()
        .map(|(d, e, f)| MockLeg {
            dir: PinMock::new(d),
            enable: PinMock::new(e),
            fault: PinMock::new(f),
        })
        .collect();
    let arr = std::array::from_fn(|i| StepperLeg {
        pulses: pulses[i].clone(),
        dir: mocks[i].dir.clone(),
        enable: mocks[i].enable.clone(),
        fault: mocks[i].fault.clone(),
    });
    let d = StepDirDrives::new(arr, stepper_cfg())
        .map_err(|(e, _)| e)
        .unwrap();
    (d, pulses, mocks)
}

fn done(mocks: &mut [MockLeg]) {
    for m in mocks {
        m.dir.done();
        m.enable.done();
        m.fault.done();
    }
}

use PinState::{High, Low};

#[test]
fn pins_enable_direction_fault() {
    // Per leg: DIR positive (high) and ENABLE active (low) at construction; then per
    // command a fault read (high = healthy, active low), and DIR before each train.
    let um = 1.0e-3f32;
    let healthy = PinTransaction::get(High);
    let legs = (0..LEGS)
        .map(|i| {
            let dir = match i {
                0 => vec![
                    PinTransaction::set(High),
                    PinTransaction::set(High),
                    PinTransaction::set(Low),
                ],
                1 => vec![PinTransaction::set(High), PinTransaction::set(Low)],
                _ => vec![PinTransaction::set(High)],
            };
            let enable = vec![PinTransaction::set(Low), PinTransaction::set(High)];
            let mut fault = vec![healthy.clone(); 3];
            // Cycle 4: leg 3 reports a fault (low), leg 5 cannot be read.
            if i == 3 {
                fault.push(PinTransaction::get(Low));
            } else if i == 5 {
                fault.push(
                    PinTransaction::get(High).with_error(MockError::Io(std::io::ErrorKind::Other)),
                );
            } else {
                fault.push(healthy.clone());
            }
            fault.push(healthy.clone()); // status() after
            (dir, enable, fault)
        })
        .collect();
    let (mut drives, pulses, mut mocks) = mock_drives(legs);
    // 1: before alignment, motion is refused and no pin moves but the fault reads.
    assert_eq!(
        drives.command_strokes_mm(&[um; LEGS]),
        Err(DriveError::DriveFault { leg: EVERY_LEG })
    );
    drives.align_issued_mm(&[0.0; LEGS]);
    // 2: leg 0 up 1 um (9.6 -> 10 microsteps), leg 1 down 2 um (-19.2 -> -19).
    let mut sp = [0.0f32; LEGS];
    sp[0] = um;
    sp[1] = -2.0 * um;
    drives.command_strokes_mm(&sp).unwrap();
    assert_eq!(pulses[0].0.borrow().trains, vec![10]);
    assert_eq!(pulses[1].0.borrow().trains, vec![19]);
    // 3: leg 0 back down to 0: DIR low, 10 pulses.
    sp[0] = 0.0;
    drives.command_strokes_mm(&sp).unwrap();
    assert_eq!(pulses[0].0.borrow().trains, vec![10, 10]);
    assert_eq!(drives.issued_microsteps()[..2], [0, -19]);
    // 4: a fault on leg 3: refused for all, first faulted leg reported, nothing issued.
    sp[2] = 5.0 * um;
    assert_eq!(
        drives.command_strokes_mm(&sp),
        Err(DriveError::DriveFault { leg: 3 })
    );
    assert!(pulses[2].0.borrow().trains.is_empty());
    assert_eq!(drives.status(), Ok(()));
    // Safe mode: de-energised, and motion refused until aligned again.
    drives.disable().unwrap();
    done(&mut mocks);
}

#[test]
fn rate_limit_unsent_pulses_and_non_finite_setpoints() {
    let (mut drives, pulses, dirs) = rec_drives(stepper_cfg());
    drives.align_issued_mm(&[0.0; LEGS]);
    // 0.1 mm at once = 960 microsteps: 100 per cycle, 10 cycles, never beyond.
    let mut sp = [0.0f32; LEGS];
    sp[0] = 0.1;
    for _ in 0..12 {
        drives.command_strokes_mm(&sp).unwrap();
    }
    assert_eq!(
        pulses[0].0.borrow().trains,
        vec![100; 9].into_iter().chain([60]).collect::<Vec<_>>()
    );
    // The generator could not send 30 of a train: they are taken back and re-issued.
    sp[0] = 0.11; // +96
    drives.command_strokes_mm(&sp).unwrap();
    pulses[0].0.borrow_mut().unsent_at_stop = 30;
    drives.command_strokes_mm(&sp).unwrap();
    assert_eq!(pulses[0].0.borrow().trains.last(), Some(&30));
    assert_eq!(net_microsteps(&pulses[0], &dirs[0]), 1056);
    assert_eq!(drives.issued_microsteps()[0], 1056);
    // NaN: the leg holds where it is; the others still move.
    sp[0] = f32::NAN;
    sp[1] = 0.001;
    let before = pulses[0].0.borrow().trains.len();
    drives.command_strokes_mm(&sp).unwrap();
    assert_eq!(pulses[0].0.borrow().trains.len(), before);
    assert_eq!(drives.issued_microsteps()[..2], [1056, 10]);
    // Beyond the travel limit: clamped to 8 mm (76,800 microsteps), approached at the rate.
    let mut d2 = rec_drives(stepper_cfg()).0;
    d2.align_issued_mm(&[7.9999; LEGS]);
    d2.command_strokes_mm(&[1.0e9; LEGS]).unwrap();
    assert_eq!(d2.issued_microsteps(), [76_800; LEGS]);
    // Alignment is to the nearest microstep and sends nothing.
    let (mut d3, p3, _) = rec_drives(stepper_cfg());
    d3.align_issued_mm(&[0.000_052; LEGS]); // 0.4992 microstep -> 0
    assert_eq!(d3.issued_microsteps(), [0; LEGS]);
    assert!(p3.iter().all(|p| p.0.borrow().trains.is_empty()));
    // A non-finite reading leaves the drives unaligned: motion refused.
    let mut m = [0.0f32; LEGS];
    m[4] = f32::INFINITY;
    d3.align_issued_mm(&m);
    assert_eq!(
        d3.command_strokes_mm(&[0.001; LEGS]),
        Err(DriveError::DriveFault { leg: EVERY_LEG })
    );
}

#[test]
fn bad_stepper_configuration_is_refused_before_any_pin_moves() {
    let mut cfg = stepper_cfg();
    cfg.microsteps_per_step = 0;
    let legs = std::array::from_fn(|_| StepperLeg {
        pulses: RecPulses::default(),
        dir: PinMock::new(&[]),
        enable: PinMock::new(&[]),
        fault: PinMock::new(&[]),
    });
    let Err((e, mut legs)) = StepDirDrives::new(legs, cfg) else {
        panic!("accepted")
    };
    assert_eq!(e, m2ctl::drivers::stepper::StepperConfigError::Zero);
    for l in legs.iter_mut() {
        l.dir.done();
        l.enable.done();
        l.fault.done();
    }
    let mut cfg = stepper_cfg();
    cfg.travel_limit_nm = u32::MAX;
    cfg.microsteps_per_step = u16::MAX;
    cfg.gear_motor_revs = u16::MAX;
    cfg.full_steps_per_rev = u16::MAX;
    cfg.lead_screw_pitch_nm = 1;
    let legs = std::array::from_fn(|_| StepperLeg {
        pulses: RecPulses::default(),
        dir: RecPin::default(),
        enable: RecPin::default(),
        fault: Healthy,
    });
    assert!(matches!(
        StepDirDrives::new(legs, cfg),
        Err((m2ctl::drivers::stepper::StepperConfigError::Range, _))
    ));
}

// =====================================================================================
// Limit switches.

fn switch_pins(seq: &[[bool; 3]], leg: usize, fail_at: Option<usize>) -> [Vec<PinTransaction>; 3] {
    // Normally closed switches with pull-ups: active = high. Reference active high too.
    std::array::from_fn(|k| {
        seq.iter()
            .enumerate()
            .map(|(c, s)| {
                let t = PinTransaction::get(if s[k] { High } else { Low });
                if fail_at == Some(c) && k == 0 && leg == 1 {
                    t.with_error(MockError::Io(std::io::ErrorKind::Other))
                } else {
                    t
                }
            })
            .collect()
    })
}

#[test]
fn a_switch_seen_is_in_the_read_of_that_cycle() {
    // Cycle by cycle, per leg [lower, upper, reference].
    let mut rng = Pcg64::seed_from_u64(9);
    let cycles = 50;
    let states: Vec<[[bool; 3]; LEGS]> = (0..cycles)
        .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| rng.random_bool(0.2))))
        .collect();
    let fail_cycle = 17;
    let mut mocks: Vec<[PinMock; 3]> = (0..LEGS)
        .map(|leg| {
            let seq: Vec<[bool; 3]> = states.iter().map(|s| s[leg]).collect();
            switch_pins(&seq, leg, Some(fail_cycle)).map(|t| PinMock::new(&t))
        })
        .collect();
    let legs = std::array::from_fn(|i| LegSwitches {
        lower: mocks[i][0].clone(),
        upper: mocks[i][1].clone(),
        reference: mocks[i][2].clone(),
    });
    let mut sw = TravelSwitchInputs::new(
        legs,
        SwitchPolarity {
            end_active_high: true,
            reference_active_high: true,
        },
    );
    for (c, s) in states.iter().enumerate() {
        let r = sw.read_switches();
        let mask = |k: usize| (0..LEGS).filter(|&i| s[i][k]).fold(0u8, |m, i| m | 1 << i);
        if c == fail_cycle {
            // Leg 2's lower input cannot be read: reported, and both directions blocked.
            assert_eq!(r.unreadable, 1 << 1);
            assert_eq!(r.lower, mask(0) & !(1 << 1));
            assert!(r.blocked_negative() & r.blocked_positive() & (1 << 1) != 0);
        } else {
            assert_eq!(
                r,
                TravelSwitches {
                    lower: mask(0),
                    upper: mask(1),
                    reference: mask(2),
                    unreadable: 0
                },
                "cycle {c}"
            );
        }
    }
    for m in mocks.iter_mut() {
        for p in m.iter_mut() {
            p.done();
        }
    }
}

#[test]
fn a_switch_stops_its_leg_in_that_direction_in_the_cycle_it_is_seen() {
    // Encoders are not part of this test: a mechanism of drives and switches only.
    struct NoEncoders;
    let (drives, pulses, _) = rec_drives(stepper_cfg());
    let lower: Vec<Rc<RefCell<bool>>> = (0..LEGS).map(|_| Rc::new(RefCell::new(false))).collect();
    #[derive(Clone)]
    struct Flag(Rc<RefCell<bool>>);
    impl PinErrorType for Flag {
        type Error = core::convert::Infallible;
    }
    impl InputPin for Flag {
        fn is_high(&mut self) -> Result<bool, Self::Error> {
            Ok(*self.0.borrow())
        }
        fn is_low(&mut self) -> Result<bool, Self::Error> {
            Ok(!*self.0.borrow())
        }
    }
    let off = Rc::new(RefCell::new(false));
    let legs = std::array::from_fn(|i| LegSwitches {
        lower: Flag(lower[i].clone()),
        upper: Flag(off.clone()),
        reference: Flag(off.clone()),
    });
    let switches = TravelSwitchInputs::new(
        legs,
        SwitchPolarity {
            end_active_high: true,
            reference_active_high: true,
        },
    );
    let mut mech = Mechanism {
        encoders: NoEncoders,
        drives,
        switches,
        exposure: m2ctl::drivers::exposure::NoExposureLine,
    };
    mech.align_issued_mm(&[0.0; LEGS]);
    // Leg 3 moves down 5 microsteps per cycle; its lower switch trips at cycle 7.
    let per_cycle_mm = 5.0 / 9600.0;
    for c in 1..=12u32 {
        if c == 7 {
            *lower[2].borrow_mut() = true;
        }
        // The cycle: read the switches, apply them to the drives, command.
        let sw = mech.read_switches();
        mech.drives
            .inhibit(sw.blocked_negative(), sw.blocked_positive());
        let mut sp = [0.0f32; LEGS];
        sp[2] = -(c as f32) * per_cycle_mm as f32;
        mech.command_strokes_mm(&sp).unwrap();
        let n = pulses[2].0.borrow().trains.len();
        if c < 7 {
            assert_eq!(n, c as usize, "cycle {c}");
        } else {
            assert_eq!(n, 6, "cycle {c}: a pulse towards the tripped switch");
        }
    }
    assert_eq!(mech.drives.issued_microsteps()[2], -30);
    // Away from the switch is allowed at once.
    let mut sp = [0.0f32; LEGS];
    sp[2] = -25.0 / 9600.0;
    mech.command_strokes_mm(&sp).unwrap();
    assert_eq!(mech.drives.issued_microsteps()[2], -25);
    // A train running towards a switch that trips is cut short at the inhibit.
    sp[2] = -35.0 / 9600.0;
    *lower[2].borrow_mut() = false;
    let sw = mech.read_switches();
    mech.drives
        .inhibit(sw.blocked_negative(), sw.blocked_positive());
    mech.command_strokes_mm(&sp).unwrap(); // -10 microsteps started
    pulses[2].0.borrow_mut().unsent_at_stop = 4; // 6 sent when the switch trips
    *lower[2].borrow_mut() = true;
    let sw = mech.read_switches();
    mech.drives
        .inhibit(sw.blocked_negative(), sw.blocked_positive());
    assert_eq!(mech.drives.issued_microsteps()[2], -31);
}

/// The camera's exposing line (issue 22): its active level is "exposing", the other
/// level and an unreadable pin are not (the telecommand's hold still works), and the
/// mechanism answers `hw::ExposureInput` through it.
#[test]
fn the_exposing_line_reads_its_active_level_and_an_error_as_not_exposing() {
    use m2ctl::drivers::exposure::ExposureLine;
    use m2ctl::hw::ExposureInput;
    let reads = [
        PinTransaction::get(High),
        PinTransaction::get(Low),
        PinTransaction::get(High).with_error(MockError::Io(std::io::ErrorKind::Other)),
        PinTransaction::get(Low),
    ];
    let mut pin = PinMock::new(&reads);
    {
        let mut mech = Mechanism {
            encoders: (),
            drives: (),
            switches: (),
            exposure: ExposureLine::new(pin.clone(), true),
        };
        assert!(mech.exposing());
        assert!(!mech.exposing());
        assert!(!mech.exposing());
    }
    // Active low.
    let mut low = ExposureLine::new(pin.clone(), false);
    assert!(low.exposing());
    pin.done();
}
