//! The parameter table: layout round trip, validation, A/B store under power cuts and
//! bit flips, decoder robustness.
//!
//! `cargo test --features host --test table -- --nocapture` prints the counts.

use embedded_storage::nor_flash::NorFlash;
use m2ctl::kinematics::GeometryParams;
use m2ctl::nominal;
use m2ctl::table::layout::{stored_crc, CRC32, TABLE_CRC_OFFSET, TABLE_FORMAT_VERSION};
use m2ctl::table::mock_flash::{MockFlash, TearMode};
use m2ctl::table::store::{seq_newer, CommitHeader, HEADER_SLOT_LEN, RECORD_LEN};
use m2ctl::table::*;
use m2ctl::thermal::ThermalModel;
use m2ctl::units::ARCSEC_PER_RAD;
use proptest::prelude::*;

/// Mock flash: 4-byte words, 4 KiB sectors, room for two 64 KiB banks.
type Flash = MockFlash<4, 4096>;
const TEST_BANK_SIZE: u32 = 0x1_0000;
const TEST_LAYOUT: BankLayout = BankLayout::two_banks(0, TEST_BANK_SIZE);

fn flash() -> Flash {
    Flash::new(2 * TEST_BANK_SIZE as usize)
}

fn store(f: Flash) -> TableStore<Flash> {
    TableStore::new(f, TEST_LAYOUT).unwrap()
}

fn cfg() -> ValidationConfig {
    ValidationConfig::flight()
}

/// A "calibrated" table: nominal joints moved by a few tenths of a mm, its own ID.
fn calibrated(id: u32, shift_mm: f64) -> Table {
    let mut t = Table::nominal();
    t.table_id = id;
    t.provenance = Provenance {
        calibration_id: 1000 + id,
        tag: *b"CAL-2025-07-01 A",
    };
    for (i, leg) in t.legs.iter_mut().enumerate() {
        let s = shift_mm * (1.0 + i as f64 / 10.0);
        leg.a_mm[0] += s;
        leg.a_mm[2] -= 0.5 * s;
        leg.b_mm[1] -= s;
    }
    t.p0_mm[2] += 0.1;
    t.supervision.fault_debounce_cycles = 4 + id as u16;
    // A thermal model whose every field differs, so that a field out of place shows.
    t.thermal = ThermalModel {
        reference_c: 18.5 + id as f32,
        expansion_per_k: [8.6e-6, 23.1e-6, 22.9e-6, 23.6e-6],
        column_length_mm: 61.25,
        sensor_of: core::array::from_fn(|leg| core::array::from_fn(|p| ((leg + p) % 8) as u8)),
    };
    t
}

/// A thermal model out of range is refused by the validation with 0x041d and the
/// field; the table otherwise valid.
#[test]
fn a_thermal_model_out_of_range_is_refused_by_field() {
    type Spoil<'a> = &'a dyn Fn(&mut ThermalModel);
    let cases: [(Spoil, u16); 4] = [
        (&|m| m.reference_c = f32::NAN, 1),
        (&|m| m.expansion_per_k[2] = 1.0e-3, 2),
        (&|m| m.column_length_mm = -1.0, 3),
        (&|m| m.sensor_of[4][1] = 8, 4),
    ];
    for (spoil, field) in cases {
        let mut t = calibrated(9, 0.1);
        assert_eq!(validate(&t, &cfg()), Ok(()));
        spoil(&mut t.thermal);
        let e = validate(&t, &cfg()).unwrap_err();
        assert_eq!((e.code(), e.detail()), (0x041d, field));
        // It survives the encoding: the refusal is the table's, not the decoder's.
        assert_eq!(
            Table::decode(&t.to_bytes()).map(|d| d.to_bytes()),
            Ok(t.to_bytes())
        );
    }
}

#[test]
fn layout_round_trip() {
    assert_eq!(TABLE_LEN, 564);
    for t in [Table::nominal(), calibrated(7, 0.3), calibrated(8, -0.2)] {
        let mut buf = [0u8; TABLE_LEN];
        t.encode(&mut buf);
        assert_eq!(&buf[0..4], b"M2TB");
        assert_eq!(u16::from_le_bytes([buf[4], buf[5]]), TABLE_FORMAT_VERSION);
        assert_eq!(u16::from_le_bytes([buf[6], buf[7]]) as usize, TABLE_LEN);
        assert_eq!(
            u32::from_le_bytes(buf[8..12].try_into().unwrap()),
            t.table_id
        );
        // p0.z at 320 + 16, f64 LE.
        let p0z = f64::from_le_bytes(buf[336..344].try_into().unwrap());
        assert_eq!(p0z, t.p0_mm[2]);
        // Leg 1 a.x at 32.
        let a1x = f64::from_le_bytes(buf[32..40].try_into().unwrap());
        assert_eq!(a1x, t.legs[0].a_mm[0]);
        // Supervision fault debounce at 508.
        assert_eq!(
            u16::from_le_bytes([buf[508], buf[509]]),
            t.supervision.fault_debounce_cycles
        );
        assert_eq!(
            stored_crc(&buf).unwrap(),
            CRC32.checksum(&buf[..TABLE_CRC_OFFSET])
        );
        assert_eq!(t.crc32(), stored_crc(&buf).unwrap());
        let back = Table::decode(&buf).unwrap();
        assert_eq!(back, t);
        // Bit-exact f64 (including -0.0 and the like).
        assert_eq!(back.to_bytes(), buf);
    }
    // A NaN survives the round trip bit-exactly (validation, not decode, refuses it).
    let mut t = Table::nominal();
    t.legs[3].b_mm[2] = f64::NAN;
    let back = Table::decode(&t.to_bytes()).unwrap();
    assert!(back.legs[3].b_mm[2].is_nan());
    assert_eq!(back.to_bytes(), t.to_bytes());
}

#[test]
fn decode_errors() {
    let good = Table::nominal().to_bytes();
    assert_eq!(
        Table::decode(&good[..TABLE_LEN - 1]),
        Err(TableError::WrongLength {
            got: TABLE_LEN as u16 - 1
        })
    );
    assert_eq!(Table::decode(&[]), Err(TableError::WrongLength { got: 0 }));
    let mut long = [0u8; TABLE_LEN + 1];
    long[..TABLE_LEN].copy_from_slice(&good);
    assert!(matches!(
        Table::decode(&long),
        Err(TableError::WrongLength { .. })
    ));
    let mut b = good;
    b[0] = b'X';
    assert_eq!(Table::decode(&b), Err(TableError::BadMagic));
    // Format 1 (before the thermal model) is another format: refused by its version.
    let mut b = good;
    b[4] = 1;
    assert_eq!(
        Table::decode(&b),
        Err(TableError::UnsupportedVersion { version: 1 })
    );
    let mut b = good;
    b[6] = 0;
    assert!(matches!(
        Table::decode(&b),
        Err(TableError::BadLengthField { .. })
    ));
    let mut b = good;
    b[100] ^= 1;
    assert_eq!(Table::decode(&b), Err(TableError::BadCrc));
    // Reserved field non-zero with a correct CRC.
    let mut b = good;
    b[m2ctl::table::layout::field::RESERVED.start] = 1;
    let crc = CRC32.checksum(&b[..TABLE_CRC_OFFSET]);
    b[TABLE_CRC_OFFSET..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(Table::decode(&b), Err(TableError::ReservedNotZero));
}

#[test]
fn geometry_conversion_and_nominal() {
    let t = Table::nominal();
    assert_eq!(t.geometry_params(), nominal::prototype_with_flight_limits());
    let back = Table::from_geometry(
        &t.geometry_params(),
        t.table_id,
        t.provenance,
        t.supervision,
    )
    .unwrap();
    assert_eq!(back, t);
    assert_eq!(
        back.thermal,
        ThermalModel::NONE,
        "no thermal model from a geometry"
    );
    let no_limits: GeometryParams = nominal::PROTOTYPE;
    assert_eq!(
        Table::from_geometry(&no_limits, 1, t.provenance, DEFAULT_SUPERVISION),
        Err(TableError::MissingLimits)
    );
    assert_eq!(validate(&t, &cfg()), Ok(()));
    assert_eq!(validate(&calibrated(3, 0.3), &cfg()), Ok(()));
    assert_eq!(validate(&calibrated(3, -0.4), &cfg()), Ok(()));
}

#[test]
fn nan_rejected() {
    let mut t = calibrated(5, 0.2);
    t.legs[2].a_mm[1] = f64::NAN;
    let e = validate(&t, &cfg()).unwrap_err();
    assert_eq!(e, ValidationError::NonFinite { field: 2 * 6 + 1 });
    assert_eq!(e.code(), 0x0411);
    let mut t = calibrated(5, 0.2);
    t.supervision.following_error_fault_mm = f32::NAN;
    assert!(matches!(
        validate(&t, &cfg()),
        Err(ValidationError::NonFinite { .. })
    ));
    let mut t = calibrated(5, 0.2);
    t.workspace.rotation_rad[1] = f64::INFINITY;
    assert!(matches!(
        validate(&t, &cfg()),
        Err(ValidationError::NonFinite { .. })
    ));
    // Commit refuses it and writes nothing.
    let mut s = store(flash());
    let mut t = calibrated(5, 0.2);
    t.p0_mm[0] = f64::NAN;
    let before = s.flash_mut().stats();
    assert_eq!(
        s.commit(&t, &cfg()).map(|_| ()),
        Err(StoreError::Invalid(ValidationError::NonFinite {
            field: 36
        }))
    );
    assert_eq!(s.flash_mut().stats(), before);
    assert!(s.flash_mut().bytes().iter().all(|b| *b == 0xFF));
}

#[test]
fn unreachable_rejected() {
    // Stroke limits tighter than the corners need (they need about 4 mm).
    let mut t = calibrated(9, 0.1);
    t.stroke_limits.min_mm = [-3.0; 6];
    t.stroke_limits.max_mm = [3.0; 6];
    let e = validate(&t, &cfg()).unwrap_err();
    assert!(matches!(e, ValidationError::StrokeLimitExceeded { legs } if legs != 0));
    assert_eq!(e.code(), 0x0419);
    // One leg's upper limit tightened: that leg is named.
    let mut t = calibrated(9, 0.1);
    t.stroke_limits.max_mm[4] = 1.0;
    assert_eq!(
        validate(&t, &cfg()),
        Err(ValidationError::StrokeLimitExceeded { legs: 1 << 4 })
    );
    // Far from nominal / implausible rods.
    let mut t = calibrated(9, 0.1);
    t.legs[1].b_mm[2] += 1.5;
    assert_eq!(
        validate(&t, &cfg()),
        Err(ValidationError::CoordinateOffNominal { index: 6 + 5 })
    );
    // Rod length check: with a loose coordinate tolerance, the rod check trips.
    let mut loose = cfg();
    loose.max_coordinate_deviation_mm = 10.0;
    let mut t = calibrated(9, 0.1);
    t.legs[0].b_mm[2] += 5.0;
    assert_eq!(
        validate(&t, &loose),
        Err(ValidationError::RodLengthImplausible { leg: 0 })
    );
    // A wider workspace than the cap, or stroke limits beyond the cap.
    let mut t = calibrated(9, 0.1);
    t.workspace.rotation_rad[2] = 700.0 / ARCSEC_PER_RAD;
    assert_eq!(
        validate(&t, &cfg()),
        Err(ValidationError::WorkspaceBeyondCap { axis: 5 })
    );
    let mut t = calibrated(9, 0.1);
    t.stroke_limits.min_mm[3] = -6.0;
    assert_eq!(
        validate(&t, &cfg()),
        Err(ValidationError::StrokeLimitBeyondCap { leg: 3 })
    );
    // Supervision thresholds out of order.
    let mut t = calibrated(9, 0.1);
    t.supervision.following_error_warning_mm = 0.1;
    assert_eq!(
        validate(&t, &cfg()),
        Err(ValidationError::Supervision { field: 1 })
    );
    // Bad tag.
    let mut t = calibrated(9, 0.1);
    t.provenance.tag[3] = 0x80;
    assert_eq!(
        validate(&t, &cfg()),
        Err(ValidationError::ProvenanceNotAscii { index: 3 })
    );
    // Commit refuses the unreachable table.
    let mut t = calibrated(9, 0.1);
    t.stroke_limits.max_mm = [3.0; 6];
    let mut s = store(flash());
    assert!(matches!(
        s.commit(&t, &cfg()),
        Err(StoreError::Invalid(
            ValidationError::StrokeLimitExceeded { .. }
        ))
    ));
    // Also at boot: a stored (unvalidated) unreachable table is refused, nominal used.
    s.write_record(&t).unwrap();
    let mut s = store(s.into_inner());
    let (booted, report) = s.boot(&cfg());
    assert_eq!(booted, Table::nominal());
    assert_eq!(report.source, BootSource::Nominal);
    assert!(matches!(report.bank_a, BankStatus::Rejected(_)));
    assert!(report.fell_back);
    assert_eq!(report.rejection_code(), 0x0419);
}

#[test]
fn grid_density_and_margin() {
    // Every grid density gives the same verdict on the nominal table.
    for n in 2..=5u8 {
        let mut c = cfg();
        c.grid_points_per_axis = n;
        assert_eq!(validate(&Table::nominal(), &c), Ok(()), "n = {n}");
    }
    let mut c = cfg();
    c.grid_points_per_axis = 1;
    assert_eq!(
        validate(&Table::nominal(), &c),
        Err(ValidationError::BadConfig)
    );
    // Limits just above the largest corner stroke: refused (inside the margin), and
    // limits 0.05 mm above: accepted (the margin is about 0.03 mm).
    let g = m2ctl::kinematics::Geometry::<f64>::new(&nominal::PROTOTYPE).unwrap();
    let mut max_s = [f64::MIN; 6];
    let mut min_s = [f64::MAX; 6];
    for corner in 0..64u32 {
        let mut v = [0.0; 6];
        for (k, x) in v.iter_mut().enumerate() {
            let half = if k < 3 {
                nominal::WORKSPACE_TRANSLATION_MM
            } else {
                nominal::WORKSPACE_ROTATION_ARCSEC / ARCSEC_PER_RAD
            };
            *x = if corner >> k & 1 == 1 { half } else { -half };
        }
        let s = m2ctl::kinematics::ik(
            &m2ctl::kinematics::Geometry::<f64> {
                stroke: None,
                workspace: None,
                ..g
            },
            &m2ctl::kinematics::Pose::from_array(v),
        )
        .unwrap();
        for i in 0..6 {
            max_s[i] = max_s[i].max(s[i]);
            min_s[i] = min_s[i].min(s[i]);
        }
    }
    println!("corner strokes: min {min_s:?} max {max_s:?}");
    let mut t = Table::nominal();
    for i in 0..6 {
        t.stroke_limits.max_mm[i] = max_s[i] + 0.001;
        t.stroke_limits.min_mm[i] = min_s[i] - 0.001;
    }
    assert!(matches!(
        validate(&t, &cfg()),
        Err(ValidationError::StrokeLimitExceeded { .. })
    ));
    for i in 0..6 {
        t.stroke_limits.max_mm[i] = max_s[i] + 0.05;
        t.stroke_limits.min_mm[i] = min_s[i] - 0.05;
    }
    assert_eq!(validate(&t, &cfg()), Ok(()));
}

#[test]
fn error_codes_unique() {
    let codes = [
        TableError::WrongLength { got: 0 }.code(),
        TableError::BadMagic.code(),
        TableError::UnsupportedVersion { version: 0 }.code(),
        TableError::BadLengthField { length: 0 }.code(),
        TableError::BadCrc.code(),
        TableError::ReservedNotZero.code(),
        TableError::MissingLimits.code(),
        ValidationError::ProvenanceNotAscii { index: 0 }.code(),
        ValidationError::NonFinite { field: 0 }.code(),
        ValidationError::CoordinateOffNominal { index: 0 }.code(),
        ValidationError::RodLengthImplausible { leg: 0 }.code(),
        ValidationError::Geometry(m2ctl::kinematics::GeometryError::NonFinite).code(),
        ValidationError::StrokeLimitBeyondCap { leg: 0 }.code(),
        ValidationError::WorkspaceBeyondCap { axis: 0 }.code(),
        ValidationError::Supervision { field: 0 }.code(),
        ValidationError::Unreachable { legs: 0 }.code(),
        ValidationError::StrokeLimitExceeded { legs: 0 }.code(),
        ValidationError::FkFailed {
            corner: 0,
            fk_code: 0,
        }
        .code(),
        ValidationError::FkInaccurate { corner: 0 }.code(),
        ValidationError::BadConfig.code(),
        StoreError::BadLayout.code(),
        StoreError::Flash(embedded_storage::nor_flash::NorFlashErrorKind::Other).code(),
        StoreError::Invalid(ValidationError::BadConfig).code(),
        StoreError::VerifyFailed.code(),
        StoreError::NoRecord(BankStatus::Blank).code(),
    ];
    let mut sorted = codes.to_vec();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted.len(), codes.len());
    assert!(codes.iter().all(|c| c >> 8 == 0x04));
}

#[test]
fn layouts() {
    // The simulated board's layout (the QEMU board's: the top 128 KiB of 4 MiB) fits a
    // 4 MiB flash with 4 KiB sectors.
    use m2ctl::sim::bench::{SIM_BANK_SIZE, SIM_LAYOUT};
    let big = MockFlash::<4, 4096>::new(4 * 1024 * 1024);
    let s = TableStore::new(big, SIM_LAYOUT).unwrap();
    assert_eq!(s.layout().bank_a_offset, 0x3E_0000);
    assert_eq!(s.layout().bank_b_offset, 0x3F_0000);
    assert_eq!(SIM_BANK_SIZE, 0x1_0000);
    assert_eq!(
        SIM_LAYOUT.bank_a_offset + SIM_BANK_SIZE,
        SIM_LAYOUT.bank_b_offset
    );
    // Refused: erase sector bigger than the bank, overlap, out of range, misaligned, a
    // selection slot inside a record's sectors.
    assert!(TableStore::new(MockFlash::<4, 0x2_0000>::new(0x40_0000), SIM_LAYOUT).is_err());
    let slot_in_record = BankLayout {
        selection_a_offset: 0,
        ..TEST_LAYOUT
    };
    assert!(TableStore::new(flash(), slot_in_record).is_err());
    let overlap = BankLayout {
        bank_b_offset: 0x8000,
        ..TEST_LAYOUT
    };
    assert!(TableStore::new(flash(), overlap).is_err());
    let out = BankLayout {
        bank_b_offset: 0x2_0000,
        ..TEST_LAYOUT
    };
    assert!(TableStore::new(flash(), out).is_err());
    let misaligned = BankLayout {
        bank_a_offset: 0x100,
        bank_b_offset: 0x1_0000,
        bank_size: 0x8000,
        ..TEST_LAYOUT
    };
    assert!(TableStore::new(flash(), misaligned).is_err());
    let not_pow2 = BankLayout {
        bank_a_offset: 0,
        bank_b_offset: 0x1_0000,
        bank_size: 0x3000,
        ..TEST_LAYOUT
    };
    assert!(TableStore::new(flash(), not_pow2).is_err());
    // Large write words (32 bytes) and 1-byte words both work.
    for_word_size::<1>();
    for_word_size::<32>();
}

fn for_word_size<const W: usize>() {
    let f = MockFlash::<W, 4096>::new(2 * TEST_BANK_SIZE as usize);
    let mut s = TableStore::new(f, TEST_LAYOUT).unwrap();
    s.commit(&calibrated(1, 0.1), &cfg()).unwrap();
    s.commit(&calibrated(2, 0.2), &cfg()).unwrap();
    let mut s = TableStore::new(s.into_inner(), TEST_LAYOUT).unwrap();
    let (t, r) = s.boot(&cfg());
    assert_eq!(t, calibrated(2, 0.2));
    assert_eq!(r.source, BootSource::BankB);
}

#[test]
fn blank_boots_nominal_and_commits_alternate() {
    let mut s = store(flash());
    let (t, r) = s.boot(&cfg());
    assert_eq!(t, Table::nominal());
    assert_eq!(r.source, BootSource::Nominal);
    assert_eq!((r.bank_a, r.bank_b), (BankStatus::Blank, BankStatus::Blank));
    assert!(!r.fell_back);
    let mut banks = vec![];
    for id in 1..=5 {
        let c = s.commit(&calibrated(id, 0.05 * id as f64), &cfg()).unwrap();
        assert_eq!(c.sequence, id);
        banks.push(c.bank);
        let mut s2 = store(s.flash_mut().clone());
        let (t, r) = s2.boot(&cfg());
        assert_eq!(t, calibrated(id, 0.05 * id as f64));
        assert_eq!(r.source, BootSource::from(c.bank));
        assert_eq!(r.sequence, id);
    }
    assert_eq!(banks, [Bank::A, Bank::B, Bank::A, Bank::B, Bank::A]);
    // After boot the store keeps writing to the bank not holding the running table.
    let mut s = store(s.into_inner());
    let (_, r) = s.boot(&cfg());
    assert_eq!(r.source, BootSource::BankA);
    assert_eq!(r.bank_b, BankStatus::Standby { sequence: 4 });
    assert_eq!(r.selection, None);
    assert_eq!(s.target_bank(), Bank::B);
    // Select the older table (B, seq 4): from now on the selection decides what boots.
    let (hb, tb) = s.read_bank(Bank::B).unwrap();
    s.select(&Selection::bank(Bank::B, hb.sequence, hb.table_crc))
        .unwrap();
    assert_eq!(s.running(), BootSource::BankB);
    let (t, r) = store(s.into_inner()).boot(&cfg());
    assert_eq!(t, calibrated(4, 0.2));
    assert_eq!(t, tb);
    assert_eq!(r.source, BootSource::BankB);
    assert_eq!(r.selection.map(|s| s.source), Some(BootSource::BankB));
    // A commit never changes what boots once a selection exists.
    let mut s = store(flash());
    s.select(&Selection::nominal()).unwrap();
    s.commit(&calibrated(1, 0.1), &cfg()).unwrap(); // A seq 1
    let (t, r) = store(s.flash_mut().clone()).boot(&cfg());
    assert_eq!((t, r.source), (Table::nominal(), BootSource::Nominal));
    // Nominal running: the next commit goes to the bank without a record.
    assert_eq!(s.target_bank(), Bank::B);
    s.commit(&calibrated(2, 0.1), &cfg()).unwrap(); // B seq 2
                                                    // ... then to the bank with the older record (replacing it).
    assert_eq!(s.target_bank(), Bank::A);
    let c = s.commit(&calibrated(3, 0.1), &cfg()).unwrap();
    assert_eq!((c.bank, c.sequence), (Bank::A, 3));
    assert_eq!(s.pending(), Some(c));
}

/// Writes a record by hand with a chosen sequence number.
fn put_record(f: &mut Flash, bank_offset: u32, t: &Table, sequence: u32) {
    f.erase(bank_offset, bank_offset + 4096).unwrap();
    let mut body = [0xFFu8; RECORD_LEN - HEADER_SLOT_LEN];
    body[..TABLE_LEN].copy_from_slice(&t.to_bytes());
    f.write(bank_offset + HEADER_SLOT_LEN as u32, &body)
        .unwrap();
    let h = CommitHeader {
        sequence,
        table_crc: t.crc32(),
    };
    f.write(bank_offset, &h.encode()).unwrap();
}

#[test]
fn stale_sequence_not_preferred() {
    let old = calibrated(1, 0.1);
    let new = calibrated(2, 0.2);
    for (seq_a, seq_b, newest_is_a) in [
        (1u32, 2u32, false),
        (7, 3, true),
        (u32::MAX, 0, false), // wrap: 0 follows 0xFFFF_FFFF
        (0, u32::MAX, true),
        (0x8000_0000, 0x7FFF_FFFF, true),
    ] {
        let mut f = flash();
        let (ta, tb) = if newest_is_a { (new, old) } else { (old, new) };
        put_record(&mut f, 0, &ta, seq_a);
        put_record(&mut f, TEST_BANK_SIZE, &tb, seq_b);
        let mut s = store(f);
        let (t, r) = s.boot(&cfg());
        assert_eq!(t, new, "seq a {seq_a:#x} b {seq_b:#x}");
        let (want_src, want_seq) = if newest_is_a {
            (BootSource::BankA, seq_a)
        } else {
            (BootSource::BankB, seq_b)
        };
        assert_eq!((r.source, r.sequence), (want_src, want_seq));
        assert!(!r.fell_back);
        // The next commit continues after the newest and goes to the older bank.
        let c = s.commit(&calibrated(3, 0.0), &cfg()).unwrap();
        assert_eq!(c.sequence, want_seq.wrapping_add(1));
        assert_eq!(
            BootSource::from(c.bank),
            if newest_is_a {
                BootSource::BankB
            } else {
                BootSource::BankA
            }
        );
    }
    assert!(seq_newer(0, u32::MAX));
    assert!(!seq_newer(5, 5));
}

/// One power-cut campaign: `setup` commits (if any) land before the cut test; then the
/// update to `new` is cut at every byte step. Returns the number of cut points.
fn cut_campaign(prior: &[Table], new: Table, tear: TearMode) -> u64 {
    let mut base = store(flash());
    for t in prior {
        base.commit(t, &cfg()).unwrap();
    }
    let old = prior.last().copied().unwrap_or(Table::nominal());
    let f0 = base.into_inner();
    // Without a selection record the newest record boots (the legacy rule).
    let old_src = store(f0.clone()).boot(&cfg()).1.source;
    // Uncut update: count its steps.
    let mut s = store(f0.clone());
    s.boot(&cfg());
    let steps0 = s.flash_mut().stats().steps;
    let c = s.commit(&new, &cfg()).unwrap();
    let total = s.flash_mut().stats().steps - steps0;
    let new_src = BootSource::from(c.bank);
    assert_ne!(new_src, old_src);
    let mut seen_new = false;
    let mut first_new = None;
    for n in 0..total {
        let mut s = store(f0.clone());
        s.boot(&cfg());
        s.flash_mut().cut_power_after(n, tear);
        let r = s.commit(&new, &cfg());
        assert!(r.is_err(), "cut {n} of {total} did not interrupt");
        assert!(!s.flash_mut().is_powered());
        s.flash_mut().power_cycle();
        let mut s = store(s.into_inner());
        let (t, rep) = s.boot(&cfg());
        if t == new {
            assert_eq!(rep.source, new_src);
            if !seen_new {
                first_new = Some(n);
            }
            seen_new = true;
        } else {
            assert_eq!(t, old, "cut {n}: neither old nor new");
            assert_eq!(rep.source, old_src, "cut {n}");
            // Once the new table was bootable, a later cut cannot lose it.
            assert!(
                !seen_new,
                "cut {n}: new table lost after step {first_new:?}"
            );
        }
        assert!(!rep.fell_back, "cut {n}: {rep:?}");
        // After the cut the system can still commit the new table.
        if n % 257 == 0 {
            let c2 = s.commit(&new, &cfg()).unwrap();
            let (t2, _) = store(s.into_inner()).boot(&cfg());
            assert_eq!(t2, new, "recommit after cut {n} ({c2:?})");
        }
    }
    // The uncut update boots the new table.
    let (t, _) = store(s.into_inner()).boot(&cfg());
    assert_eq!(t, new);
    println!(
        "power cut {tear:?}: {} prior, {total} cut points, new table bootable from cut {first_new:?}",
        prior.len()
    );
    total
}

/// Every byte step of three updates (blank -> A, A -> B, B -> A over the older record).
fn power_cut_at_every_step(tear: TearMode) {
    let t1 = calibrated(1, 0.1);
    let t2 = calibrated(2, -0.2);
    let t3 = calibrated(3, 0.3);
    let total = cut_campaign(&[], t1, tear)
        + cut_campaign(&[t1], t2, tear)
        + cut_campaign(&[t1, t2], t3, tear);
    println!("power cut {tear:?}: {total} cut points in total, every one booted old or new");
    assert!(total > 3 * 4096);
}

#[test]
fn power_cut_at_every_step_clean() {
    power_cut_at_every_step(TearMode::Clean);
}

#[test]
fn power_cut_at_every_step_torn_byte() {
    power_cut_at_every_step(TearMode::TornByte);
}

#[test]
fn every_single_bit_flip_detected() {
    let t1 = calibrated(1, 0.1);
    let t2 = calibrated(2, -0.2);
    // Decoder: every bit of an encoded table.
    let enc = t2.to_bytes();
    let mut decode_flips = 0;
    for byte in 0..TABLE_LEN {
        for bit in 0..8 {
            let mut b = enc;
            b[byte] ^= 1 << bit;
            assert!(Table::decode(&b).is_err(), "byte {byte} bit {bit}");
            decode_flips += 1;
        }
    }
    // Store: every bit of each bank's record.
    let mut s = store(flash());
    s.commit(&t1, &cfg()).unwrap(); // A, seq 1
    s.commit(&t2, &cfg()).unwrap(); // B, seq 2
    let f0 = s.into_inner();
    let mut store_flips = 0;
    for (bank_off, survivor, survivor_src) in [
        (TEST_BANK_SIZE as usize, t1, BootSource::BankA),
        (0usize, t2, BootSource::BankB),
    ] {
        for byte in 0..RECORD_LEN {
            for bit in 0..8 {
                let mut f = f0.clone();
                assert!(f.flip_bit(bank_off + byte, bit));
                let (t, r) = store(f).boot(&cfg());
                assert_eq!(t, survivor, "bank at {bank_off:#x} byte {byte} bit {bit}");
                assert_eq!(r.source, survivor_src);
                let flipped = if bank_off == 0 { r.bank_a } else { r.bank_b };
                assert!(
                    matches!(
                        flipped,
                        BankStatus::Blank | BankStatus::HeaderCorrupt | BankStatus::BodyCorrupt(_)
                    ),
                    "byte {byte} bit {bit}: {flipped:?}"
                );
                // Losing the newest record is reported when its header still says it
                // was the newest (a corrupt header is reported as such in the flags).
                let newest_body_lost =
                    bank_off != 0 && matches!(flipped, BankStatus::BodyCorrupt(_));
                assert_eq!(r.fell_back, newest_body_lost);
                let flag = if bank_off == 0 {
                    r.flags()
                } else {
                    r.flags() >> 8
                };
                assert_ne!(flag & 0x0f, 0, "flags {:#06x}", r.flags());
                store_flips += 1;
            }
        }
    }
    println!(
        "bit flips: {decode_flips} in the encoded table (decode), {store_flips} in the two stored records (boot), all detected"
    );
    assert_eq!(decode_flips, TABLE_LEN * 8);
    assert_eq!(store_flips, 2 * RECORD_LEN * 8);
}

const DECODE_CASES: u32 = 4096;
const STRUCTURED_CASES: u32 = 512;
const BOOT_CASES: u32 = 128;

proptest! {
    #![proptest_config(ProptestConfig { cases: DECODE_CASES, failure_persistence: None, ..ProptestConfig::default() })]
    /// Arbitrary bytes of any length: decode never panics, and only exact-length input
    /// with magic, version, length and CRC right can decode.
    #[test]
    fn decode_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..1100)) {
        if let Ok(t) = Table::decode(&bytes) {
            prop_assert_eq!(bytes.len(), TABLE_LEN);
            prop_assert_eq!(&t.to_bytes()[..], &bytes[..]);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: STRUCTURED_CASES, failure_persistence: None, ..ProptestConfig::default() })]
    /// Valid header and CRC around arbitrary content: decodes, validation never panics
    /// and only passes tables whose every number is finite.
    #[test]
    fn decode_and_validate_structured(body in proptest::collection::vec(any::<u8>(), TABLE_CRC_OFFSET - 8)) {
        let mut b = Table::nominal().to_bytes();
        b[8..TABLE_CRC_OFFSET].copy_from_slice(&body);
        b[510] = 0;
        b[511] = 0;
        let crc = CRC32.checksum(&b[..TABLE_CRC_OFFSET]);
        b[TABLE_CRC_OFFSET..].copy_from_slice(&crc.to_le_bytes());
        let t = Table::decode(&b).unwrap();
        let _ = validate(&t, &cfg());
    }

    /// Nominal table with random perturbations near the tolerance: validation never
    /// panics; accepted tables pass every flight check again.
    #[test]
    fn validate_perturbed(d in proptest::collection::vec(-1.2f64..1.2, 39), lim in 3.0f64..5.0) {
        let mut t = Table::nominal();
        for (i, leg) in t.legs.iter_mut().enumerate() {
            for k in 0..3 {
                leg.a_mm[k] += d[i * 6 + k];
                leg.b_mm[k] += d[i * 6 + 3 + k];
            }
        }
        for k in 0..3 {
            t.p0_mm[k] += d[36 + k];
        }
        t.stroke_limits.max_mm = [lim; 6];
        let _ = validate(&t, &cfg());
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: BOOT_CASES, failure_persistence: None, ..ProptestConfig::default() })]
    /// Arbitrary flash content in both banks (garbage, or a real record with random
    /// byte damage): boot never panics and returns a table that validates.
    #[test]
    fn boot_from_garbage(
        seed_a in proptest::collection::vec(any::<u8>(), RECORD_LEN),
        damage in proptest::collection::vec((0usize..RECORD_LEN, any::<u8>()), 0..4),
        seq in any::<u32>(),
    ) {
        let mut f = flash();
        f.write(0, &seed_a).unwrap();
        put_record(&mut f, TEST_BANK_SIZE, &calibrated(4, 0.2), seq);
        for (at, v) in damage {
            let cur = f.bytes()[TEST_BANK_SIZE as usize + at];
            for bit in 0..8 {
                if (cur ^ v) >> bit & 1 == 1 {
                    f.flip_bit(TEST_BANK_SIZE as usize + at, bit);
                }
            }
        }
        let (t, r) = store(f).boot(&cfg());
        prop_assert_eq!(validate(&t, &cfg()), Ok(()));
        prop_assert!(r.source != BootSource::BankA || t == Table::decode(&seed_a[HEADER_SLOT_LEN..HEADER_SLOT_LEN + TABLE_LEN]).unwrap());
    }
}

#[test]
fn proptest_case_counts() {
    println!(
        "proptest cases: decode {DECODE_CASES}, structured decode+validate {STRUCTURED_CASES} x 2, boot {BOOT_CASES}"
    );
}

#[test]
fn mock_flash_nor_semantics() {
    use m2ctl::table::mock_flash::MockFlashError;
    use m2ctl::table::mock_flash::{TORN_ERASE_SET_MASK, TORN_WRITE_KEEP_MASK};
    let mut f = flash();
    // Writing over erased flash works; writing the same word again is refused even if
    // it only clears bits; a 1 over a 0 is refused.
    f.write(0, &[0xF0, 0x0F, 0xFF, 0x00]).unwrap();
    assert_eq!(f.write(0, &[0x00; 4]), Err(MockFlashError::DoubleWrite(0)));
    assert_eq!(f.write(0, &[0xFF; 4]), Err(MockFlashError::BitRaise(0)));
    assert_eq!(&f.bytes()[..4], &[0xF0, 0x0F, 0xFF, 0x00]);
    // Alignment and bounds.
    assert!(f.write(2, &[0; 4]).is_err());
    assert!(f.erase(0, 100).is_err());
    assert!(f.write(2 * TEST_BANK_SIZE, &[0; 4]).is_err());
    // Erase restores 0xFF and allows writing again.
    f.erase(0, 4096).unwrap();
    assert!(f.bytes()[..4096].iter().all(|b| *b == 0xFF));
    f.write(0, &[0x12, 0x34, 0x56, 0x78]).unwrap();
    // A clean cut inside a write: bytes before the cut written, the rest untouched, and
    // nothing works until power is restored.
    f.cut_power_after(2, TearMode::Clean);
    assert_eq!(f.write(4, &[0x00; 4]), Err(MockFlashError::PowerLoss));
    assert_eq!(&f.bytes()[4..8], &[0x00, 0x00, 0xFF, 0xFF]);
    let mut buf = [0u8; 4];
    assert_eq!(
        embedded_storage::nor_flash::ReadNorFlash::read(&mut f, 0, &mut buf),
        Err(MockFlashError::PowerLoss)
    );
    f.power_cycle();
    embedded_storage::nor_flash::ReadNorFlash::read(&mut f, 0, &mut buf).unwrap();
    assert_eq!(buf, [0x12, 0x34, 0x56, 0x78]);
    // A torn cut: the byte at the cut is half-programmed.
    f.cut_power_after(1, TearMode::TornByte);
    assert!(f.write(8, &[0x00; 4]).is_err());
    assert_eq!(&f.bytes()[8..12], &[0x00, TORN_WRITE_KEEP_MASK, 0xFF, 0xFF]);
    f.power_cycle();
    // A cut inside an erase: the bytes before the cut erased, the rest old.
    f.cut_power_after(2, TearMode::Clean);
    assert!(f.erase(0, 4096).is_err());
    assert_eq!(&f.bytes()[..4], &[0xFF, 0xFF, 0x56, 0x78]);
    f.power_cycle();
    f.cut_power_after(2, TearMode::TornByte);
    assert!(f.erase(0, 4096).is_err());
    assert_eq!(
        &f.bytes()[..4],
        &[0xFF, 0xFF, 0x56 | TORN_ERASE_SET_MASK, 0x78]
    );
}

#[test]
fn power_cut_during_a_selection() {
    // A holds t1 (seq 1), B holds t2 (seq 2). Selecting A writes a selection record;
    // a cut at every step boots t2 (no valid selection yet: the newest record, B) or
    // t1 (the selection, A). Then, with that selection in place, selecting B again
    // (the other slot) boots t1 or t2 at every cut: never neither, never a mixture.
    let t1 = calibrated(1, 0.1);
    let t2 = calibrated(2, -0.2);
    let mut base = store(flash());
    base.commit(&t1, &cfg()).unwrap();
    base.commit(&t2, &cfg()).unwrap();
    let sel_a = {
        let (h, _) = base.read_bank(Bank::A).unwrap();
        Selection::bank(Bank::A, h.sequence, h.table_crc)
    };
    let sel_b = {
        let (h, _) = base.read_bank(Bank::B).unwrap();
        Selection::bank(Bank::B, h.sequence, h.table_crc)
    };
    let mut total_all = 0;
    for (from, to, before, after) in [(None, sel_a, t2, t1), (Some(sel_a), sel_b, t1, t2)] {
        let mut b0 = store(base.flash_mut().clone());
        b0.boot(&cfg());
        if let Some(f) = from {
            b0.select(&f).unwrap();
        }
        let f0 = b0.into_inner();
        let mut s = store(f0.clone());
        s.boot(&cfg());
        let steps0 = s.flash_mut().stats().steps;
        s.select(&to).unwrap();
        let total = s.flash_mut().stats().steps - steps0;
        total_all += total;
        let mut switched_from = None;
        for n in 0..total {
            let mut s = store(f0.clone());
            s.boot(&cfg());
            s.flash_mut().cut_power_after(n, TearMode::TornByte);
            assert!(s.select(&to).is_err());
            s.flash_mut().power_cycle();
            let (t, r) = store(s.into_inner()).boot(&cfg());
            if t == after {
                switched_from.get_or_insert(n);
                assert_eq!(r.source, to.source, "cut {n}");
            } else {
                assert_eq!(t, before, "cut {n}: neither table");
                assert!(switched_from.is_none(), "cut {n}: selection lost");
            }
            assert!(!r.fell_back, "cut {n}: {r:?}");
        }
        println!(
            "power cut during a selection {:?} -> {:?}: {total} cut points, switched from cut {switched_from:?}",
            from.map(|s| s.source),
            to.source
        );
    }
    assert!(total_all > 2 * 4096);
}

#[test]
fn a_selected_bank_that_no_longer_holds_the_selected_record_boots_nominal() {
    // Select A's t1; then overwrite A with another table behind the selection's back
    // (as a bit flip or a foreign tool would): the selection names sequence 1, A now
    // holds sequence 3. Boot falls back to nominal and says so.
    let mut s = store(flash());
    let c1 = s.commit(&calibrated(1, 0.1), &cfg()).unwrap();
    s.select(&Selection::bank(c1.bank, c1.sequence, c1.table_crc))
        .unwrap();
    let (_, r) = store(s.flash_mut().clone()).boot(&cfg());
    assert_eq!((r.source, r.fell_back), (BootSource::BankA, false));
    s.commit(&calibrated(2, 0.1), &cfg()).unwrap(); // B (A runs)
    let mut f = s.into_inner();
    put_record(&mut f, 0, &calibrated(3, 0.1), 3);
    let (t, r) = store(f).boot(&cfg());
    assert_eq!(t, Table::nominal());
    assert_eq!(r.source, BootSource::Nominal);
    assert!(r.fell_back);
    assert_eq!(r.bank_a, BankStatus::Standby { sequence: 3 });
}

/// The four-bit-table CRC-32 of the table and flash records is the `crc` crate's
/// CRC-32/ISO-HDLC: the catalogue's check value, and equal results on random inputs of
/// every length up to two tables (the negative control: a different algorithm differs).
#[test]
fn nibble_crc32_equals_the_crc_crate() {
    let reference = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    assert_eq!(CRC32.checksum(b"123456789"), crc::CRC_32_ISO_HDLC.check);
    assert_eq!(CRC32.checksum(&[]), reference.checksum(&[]));
    let other = m2ctl::table::layout::NibbleCrc32::new(&crc::CRC_32_JAMCRC);
    assert_ne!(other.checksum(b"123456789"), CRC32.checksum(b"123456789"));
    proptest!(ProptestConfig::with_cases(2000), |(bytes in proptest::collection::vec(any::<u8>(), 0..1100))| {
        prop_assert_eq!(CRC32.checksum(&bytes), reference.checksum(&bytes));
    });
}

/// ICD section 5, the order of the 36 joint values: leg-major, leg i (1..6) at byte
/// 32 + 48 (i - 1): `a.x a.y a.z` (frame B, zero stroke) then `b.x b.y b.z` (frame M),
/// each an f64 little-endian.
#[test]
fn the_joint_values_are_leg_major_a_then_b() {
    let mut t = Table::nominal();
    for (i, leg) in t.legs.iter_mut().enumerate() {
        for k in 0..3 {
            leg.a_mm[k] = 100.0 * (i as f64 + 1.0) + k as f64;
            leg.b_mm[k] = 100.0 * (i as f64 + 1.0) + 10.0 + k as f64;
        }
    }
    let bytes = t.to_bytes();
    let f64_at = |o: usize| f64::from_le_bytes(bytes[o..o + 8].try_into().unwrap());
    for leg in 1..=6usize {
        let base = 32 + 48 * (leg - 1);
        for k in 0..3 {
            assert_eq!(
                f64_at(base + 8 * k),
                100.0 * leg as f64 + k as f64,
                "leg {leg} a[{k}]"
            );
            assert_eq!(
                f64_at(base + 24 + 8 * k),
                100.0 * leg as f64 + 10.0 + k as f64,
                "leg {leg} b[{k}]"
            );
        }
    }
    assert_eq!(32 + 48 * 6, 320, "p0 follows at 320");
}
