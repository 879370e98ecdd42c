//! The thermal module (issue 22): sensor conversion against the IEC 60751 curve, the
//! sensor supervision, the thermal model's validation, and the first-order stroke
//! offsets against the exact strokes of the expanded mechanism (an independent
//! evaluation: the square root of the rod equation in f64, not the crate's IK).

use m2ctl::kinematics::geometry::{Geometry, GeometryParams, LEGS};
use m2ctl::kinematics::pose::{Pose, RotationDelta};
use m2ctl::nominal;
use m2ctl::thermal::{
    adc, celsius_from_counts, pt1000, stroke_offsets_mm, Part, SensorFault, SensorMonitor,
    ThermalModel, ThermalModelError, MEAN_SAMPLES, PARTS, SENSOR_MAX_C, SENSOR_MIN_C,
    STUCK_SAMPLES, TEMP_SENSORS,
};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// IEC 60751's table for a PT100 (ohm at deg C), times 10 for the PT1000: the published
/// values, rounded to 1 mohm of the PT100.
const IEC_60751_PT100: [(f64, f64); 7] = [
    (-50.0, 80.306),
    (-20.0, 92.160),
    (0.0, 100.000),
    (20.0, 107.794),
    (25.0, 109.735),
    (50.0, 119.397),
    (100.0, 138.506),
];

#[test]
fn the_sensor_curve_is_iec_60751() {
    for (t, r100) in IEC_60751_PT100 {
        let r = pt1000::resistance_ohm(t);
        // The table's rounding (0.5 mohm of the PT100, 5 mohm of the PT1000).
        assert!(
            (r - 10.0 * r100).abs() <= 0.0051,
            "{t} C: {r} ohm, table {}",
            10.0 * r100
        );
    }
}

/// The exact temperature (deg C) of a reading, by bisection on the f64 curve.
fn exact_celsius(counts: u16) -> f64 {
    let (mut lo, mut hi) = (-200.0f64, 400.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if adc::counts_of_resistance(pt1000::resistance_ohm(mid)) < f64::from(counts) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn conversion_matches_the_iec_60751_curve_to_a_millikelvin() {
    // Every count over the sensor range, and the counts of the table's points.
    let lo = adc::counts_of_resistance(pt1000::resistance_ohm(f64::from(SENSOR_MIN_C))).ceil();
    let hi = adc::counts_of_resistance(pt1000::resistance_ohm(f64::from(SENSOR_MAX_C))).floor();
    let mut worst = 0.0f64;
    for c in (lo as u16)..=(hi as u16) {
        let t = celsius_from_counts(c).unwrap();
        worst = worst.max((f64::from(t) - exact_celsius(c)).abs());
    }
    assert!(worst <= 1.0e-3, "worst conversion error {worst} K");
    // A count is about 17 mK at room temperature: the ADC resolves the 0.05 K that a
    // 0.3 um compensation needs.
    let c20 = adc::counts_of_resistance(pt1000::resistance_ohm(20.0)).round() as u16;
    let k_per_count = exact_celsius(c20 + 1) - exact_celsius(c20);
    assert!(
        (0.015..0.02).contains(&k_per_count),
        "{k_per_count} K per count"
    );
}

#[test]
fn open_and_short_sensors_are_faults() {
    assert_eq!(
        celsius_from_counts(adc::FULL_SCALE_COUNTS),
        Err(SensorFault::Open)
    );
    assert_eq!(celsius_from_counts(0), Err(SensorFault::Short));
    let just_below =
        adc::counts_of_resistance(pt1000::resistance_ohm(f64::from(SENSOR_MIN_C) - 0.1)) as u16;
    let just_above =
        adc::counts_of_resistance(pt1000::resistance_ohm(f64::from(SENSOR_MAX_C) + 0.1)).ceil()
            as u16;
    assert_eq!(celsius_from_counts(just_below), Err(SensorFault::Short));
    assert_eq!(celsius_from_counts(just_above), Err(SensorFault::Open));
    // Codes are stable and distinct, 0 is healthy.
    let codes = [SensorFault::Short, SensorFault::Open, SensorFault::Stuck].map(SensorFault::code);
    assert_eq!(codes, [1, 2, 3]);
}

#[test]
fn the_monitor_averages_flags_stuck_and_recovers() {
    let c20 = adc::counts_of_resistance(pt1000::resistance_ohm(20.0)).round() as u16;
    let mut m = SensorMonitor::default();
    // Alternating two counts: live, and the mean is their temperatures' mean.
    for i in 0..MEAN_SAMPLES {
        assert_eq!(m.celsius(), None, "no temperature before a full window");
        m.update(c20 + (i % 2));
    }
    let mean = m.celsius().unwrap();
    let expect = 0.5 * (exact_celsius(c20) + exact_celsius(c20 + 1));
    assert!(
        (f64::from(mean) - expect).abs() < 1.0e-3,
        "{mean} vs {expect}"
    );
    // The very same count: stuck after STUCK_SAMPLES repeats, not before.
    for _ in 0..STUCK_SAMPLES - 1 {
        m.update(c20 + 7);
    }
    assert_eq!(m.fault(), None);
    m.update(c20 + 7);
    assert_eq!(m.fault(), Some(SensorFault::Stuck));
    assert_eq!(m.celsius(), None);
    // A changing count ends the fault; a temperature again after a full window.
    for i in 0..MEAN_SAMPLES {
        m.update(c20 + (i % 2));
    }
    assert_eq!(m.fault(), None);
    assert!(m.celsius().is_some());
    // Open: a fault at once, and still open (not stuck) however long it stays so.
    for _ in 0..2 * STUCK_SAMPLES {
        m.update(adc::FULL_SCALE_COUNTS);
        assert_eq!(m.fault(), Some(SensorFault::Open));
        assert_eq!(m.celsius(), None);
    }
    for _ in 0..2 * STUCK_SAMPLES {
        m.update(0);
        assert_eq!(m.fault(), Some(SensorFault::Short));
    }
}

/// Realistic coefficients: titanium rods, aluminium columns and plates, 60 mm columns;
/// sensors 0..5 on the columns (and their rods and base corners), 6 on the platform.
fn model() -> ThermalModel {
    let mut sensor_of = [[0u8; PARTS]; LEGS];
    for (i, s) in sensor_of.iter_mut().enumerate() {
        *s = [i as u8, i as u8, i as u8, 6];
    }
    ThermalModel {
        reference_c: 20.0,
        expansion_per_k: [8.6e-6, 23.1e-6, 23.1e-6, 23.1e-6],
        column_length_mm: 60.0,
        sensor_of,
    }
}

#[test]
fn the_model_is_validated_field_by_field() {
    assert_eq!(model().validate(), Ok(()));
    assert_eq!(ThermalModel::NONE.validate(), Ok(()));
    let bad = |f: &dyn Fn(&mut ThermalModel)| {
        let mut m = model();
        f(&mut m);
        m.validate()
    };
    assert_eq!(
        bad(&|m| m.reference_c = f32::NAN),
        Err(ThermalModelError::Reference)
    );
    assert_eq!(
        bad(&|m| m.reference_c = 150.0),
        Err(ThermalModelError::Reference)
    );
    assert_eq!(
        bad(&|m| m.expansion_per_k[1] = -1e-6),
        Err(ThermalModelError::Expansion)
    );
    assert_eq!(
        bad(&|m| m.expansion_per_k[3] = 2e-4),
        Err(ThermalModelError::Expansion)
    );
    assert_eq!(
        bad(&|m| m.column_length_mm = f32::INFINITY),
        Err(ThermalModelError::ColumnLength)
    );
    assert_eq!(
        bad(&|m| m.sensor_of[5][2] = TEMP_SENSORS as u8),
        Err(ThermalModelError::Sensor)
    );
    assert_eq!(model().sensors_used(), 0b0111_1111);
    assert_eq!(ThermalModel::NONE.sensors_used(), 0);
}

/// The exact stroke of each leg of the mechanism `g` expanded by `e[leg][part]`, at
/// `pose` (translation from p0 in mm, rotation as the crate's pose): the rod equation
/// with the square root, in f64.
fn exact_strokes(
    g: &GeometryParams,
    pose: &Pose<f64>,
    e: &[[f64; PARTS]; LEGS],
    col_mm: f64,
) -> [f64; LEGS] {
    let w = RotationDelta::<f64>::new(&pose.rotation_rad).w;
    let t = pose.translation_mm;
    let mut s = [0.0; LEGS];
    for (i, leg) in g.legs.iter().enumerate() {
        let [e_rod, e_col, e_base, e_plat] = e[i];
        let a0 = leg.a_mm;
        let b0 = leg.b_mm;
        let l0 = ((b0[0] + g.p0_mm[0] - a0[0]).powi(2)
            + (b0[1] + g.p0_mm[1] - a0[1]).powi(2)
            + (b0[2] + g.p0_mm[2] - a0[2]).powi(2))
        .sqrt();
        let a = [
            a0[0] * (1.0 + e_base),
            a0[1] * (1.0 + e_base),
            a0[2] + e_col * col_mm,
        ];
        let b = b0.map(|x| x * (1.0 + e_plat));
        let l = l0 * (1.0 + e_rod);
        // R b = b + (R - I) b.
        let rb: Vec<f64> = (0..3)
            .map(|r| b[r] + (0..3).map(|c| w[(r, c)] * b[c]).sum::<f64>())
            .collect();
        let p: Vec<f64> = (0..3).map(|k| rb[k] + g.p0_mm[k] + t[k]).collect();
        s[i] = p[2] - a[2] - (l * l - (p[0] - a[0]).powi(2) - (p[1] - a[1]).powi(2)).sqrt();
    }
    s
}

#[test]
fn offsets_match_the_exact_strokes_to_two_nanometres() {
    let params = nominal::PROTOTYPE;
    let geom = Geometry::<f32>::new(&params).unwrap();
    let m = model();
    let mut rng = Pcg64::seed_from_u64(22);
    let mut worst_nm = 0.0f64;
    let mut largest_um = 0.0f64;
    for _ in 0..500 {
        let arcsec = std::f64::consts::PI / (180.0 * 3600.0);
        let pose = Pose::<f64> {
            translation_mm: [(); 3].map(|_| rng.random_range(-1.0..1.0)),
            rotation_rad: [(); 3].map(|_| rng.random_range(-60.0..60.0) * arcsec),
        };
        // A uniform swing up to 5 K plus a gradient up to 2 K across the sensors.
        let swing = rng.random_range(-5.0..5.0);
        let temps: [f32; TEMP_SENSORS] =
            [(); TEMP_SENSORS].map(|_| (20.0 + swing + rng.random_range(-1.0..1.0)) as f32);
        let offsets = stroke_offsets_mm(&m, &geom, &pose.cast::<f32>(), &temps).unwrap();
        let mut e = [[0.0f64; PARTS]; LEGS];
        for (leg, el) in e.iter_mut().enumerate() {
            for (p, x) in el.iter_mut().enumerate() {
                let s = usize::from(m.sensor_of[leg][p]);
                *x = f64::from(m.expansion_per_k[p])
                    * (f64::from(temps[s]) - f64::from(m.reference_c));
            }
        }
        let hot = exact_strokes(&params, &pose, &e, f64::from(m.column_length_mm));
        let cold = exact_strokes(&params, &pose, &[[0.0; PARTS]; LEGS], 0.0);
        for i in 0..LEGS {
            let exact = hot[i] - cold[i];
            worst_nm = worst_nm.max((f64::from(offsets[i]) - exact).abs() * 1e6);
            largest_um = largest_um.max(exact.abs() * 1e3);
        }
    }
    assert!(
        worst_nm <= 2.0,
        "first-order offsets {worst_nm} nm from the exact strokes"
    );
    // The compensation is worth doing: micrometres of stroke over the swing.
    assert!(largest_um > 3.0, "largest offset {largest_um} um");
    eprintln!("offsets vs exact: worst {worst_nm:.3} nm; largest offset {largest_um:.2} um");
}

#[test]
fn each_part_moves_the_strokes_in_its_direction() {
    // +1 K on one part class alone, at home: a longer rod, a higher column joint need
    // less stroke; the signs and sizes follow the formula's terms.
    let geom = Geometry::<f32>::new(&nominal::PROTOTYPE).unwrap();
    let temps = [21.0f32; TEMP_SENSORS];
    for part in [Part::Rod, Part::Column, Part::Base, Part::Platform] {
        let mut m = model();
        for (p, a) in m.expansion_per_k.iter_mut().enumerate() {
            if p != part as usize {
                *a = 0.0;
            }
        }
        let ds = stroke_offsets_mm(&m, &geom, &Pose::home(), &temps).unwrap();
        match part {
            Part::Column => ds
                .iter()
                .for_each(|d| assert!((d + 23.1e-6 * 60.0).abs() < 1e-9)),
            Part::Rod => ds
                .iter()
                .for_each(|d| assert!(*d < -0.5e-3 && *d > -1.0e-3, "{d}")),
            _ => ds
                .iter()
                .for_each(|d| assert!(d.abs() > 1e-4, "{part:?} {d}")),
        }
    }
    // No coefficient, no offset, whatever the temperatures.
    let ds = stroke_offsets_mm(
        &ThermalModel::NONE,
        &geom,
        &Pose::home(),
        &[-40.0; TEMP_SENSORS],
    )
    .unwrap();
    assert_eq!(ds, [0.0; LEGS]);
}
