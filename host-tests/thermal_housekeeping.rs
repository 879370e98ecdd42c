//! The controller's temperature sensors (issue 22, first step): every channel read
//! once per `timing::TEMPERATURE_PERIOD_CYCLES` through the hardware seam
//! (`hw::TemperatureInputs`, part of `hw::MechanismIo`), supervised per sensor
//! (`thermal::SensorBank`), and reported in housekeeping (TM[3,25]: each sensor's mean
//! in 0.01 K, the open, shorted and stuck sensor masks): the means as the ground
//! receives them against the simulated plant's true part temperatures (within the
//! sensors' error), and open, short and stuck sensors as the supervision reports them.

use m2ctl::link::Housekeeping;
mod common;

use common::{all_ok, calibrated_table, install};
use m2ctl::controller::event;
use m2ctl::sim::thermal::{
    Coefficients, Profile, SensorFailure, Swing, CLASS_TENTH_DIN_K, CLASS_TENTH_DIN_PER_C,
    REFERENCE_C,
};
use m2ctl::sim::{Bench, Plant};
use m2ctl::thermal::{
    adc, pt1000, SensorFault, MEAN_SAMPLES, NO_TEMPERATURE, STUCK_SAMPLES, TEMP_SENSORS,
};
use m2ctl::timing::{CONTROL_RATE_HZ, TEMPERATURE_PERIOD_CYCLES, TEMPERATURE_PHASE_CYCLES};

/// The sensors' error bound on a mean (K): the calibration offset of a class 1/10 DIN
/// sensor (`SensorConfig::drawn`), plus the mean's noise (1 count / 4, 0.005 K), the
/// 0.01 K rounding of housekeeping and the conversion (1 mK), with margin.
fn sensor_error_k(t_c: f64) -> f64 {
    let _ = t_c;
    CLASS_TENTH_DIN_K + CLASS_TENTH_DIN_PER_C * REFERENCE_C.abs() + 0.02
}

/// A plant whose parts sit at 25 deg C mean with a 3 K gradient across the base (each
/// sensor at its own temperature), the parts following their drive at once.
fn warm_plant(seed: u64) -> Plant {
    common::thermal_plant(
        Profile {
            mean_c: 25.0,
            swing: Swing::Constant,
            gradient_k: 3.0,
            gradient_angle_rad: 0.3,
            gradient_period_s: None,
            lag_s: [0.0; 4],
        },
        seed,
    )
}

/// Control cycles until every sensor has a first mean: `MEAN_SAMPLES` readings, one per
/// `TEMPERATURE_PERIOD_CYCLES` (the first in cycle `TEMPERATURE_PHASE_CYCLES`), and one
/// period more.
const FIRST_MEAN_CYCLES: u32 = (MEAN_SAMPLES as u32 + 1) * TEMPERATURE_PERIOD_CYCLES;

/// The true temperature of the part each sensor sits on (deg C).
fn true_sensor_temperatures(b: &Bench) -> [f64; TEMP_SENSORS] {
    b.plant.with(|p| {
        let t = p.thermal().temperatures();
        core::array::from_fn(|ch| t.at_sensor(ch))
    })
}

#[test]
fn one_reading_per_100_ms() {
    assert_eq!(TEMPERATURE_PERIOD_CYCLES * 10, CONTROL_RATE_HZ);
}

#[test]
fn each_mean_agrees_with_the_part_it_sits_on() {
    let mut b = Bench::with_plant(warm_plant(7));
    // Before the first complete window (readings in cycles 50, 150, ..; the 16th in
    // cycle 1,550, 1.55 s after boot): no temperature, healthy.
    let hk = b.hk();
    assert_eq!(hk.temperatures_centi_k, [NO_TEMPERATURE; TEMP_SENSORS]);
    assert_eq!(faults(&hk), [0, 0, 0]);
    let first_mean_cycle =
        (u32::from(MEAN_SAMPLES) - 1) * TEMPERATURE_PERIOD_CYCLES + TEMPERATURE_PHASE_CYCLES;
    assert_eq!(first_mean_cycle, 1_550);
    b.run(first_mean_cycle - b.ctl.cycle());
    assert!(b.ctl.temperatures().celsius().iter().all(|t| t.is_none()));
    b.run(1);
    assert!(b.ctl.temperatures().celsius().iter().all(|t| t.is_some()));
    b.run(FIRST_MEAN_CYCLES);
    let truth = true_sensor_temperatures(&b);
    let means = b.ctl.temperatures().celsius();
    let hk = b.hk();
    // The sensors differ (the gradient), so a channel read as another's fails.
    let spread = truth.iter().cloned().fold(f64::MIN, f64::max)
        - truth.iter().cloned().fold(f64::MAX, f64::min);
    assert!(spread > 1.0, "{truth:?}");
    for ch in 0..TEMP_SENSORS {
        let m = f64::from(means[ch].unwrap());
        assert!(
            (m - truth[ch]).abs() < sensor_error_k(truth[ch]),
            "sensor {ch}: mean {m} deg C, part {} deg C",
            truth[ch]
        );
        // As the ground receives it: the same mean, to its 0.01 K.
        let t = celsius_of_hk(hk.temperatures_centi_k[ch]);
        assert!((t - m).abs() <= 0.005 + 1e-4, "sensor {ch}: {t} {m}");
        assert!(
            (t - truth[ch]).abs() < sensor_error_k(truth[ch]),
            "sensor {ch}"
        );
    }
    assert_eq!(faults(&hk), [0, 0, 0]);
    assert_eq!(b.ctl.temperatures().faulty(), 0);
}

/// A housekeeping temperature (0.01 K) in deg C.
fn celsius_of_hk(centi_k: u16) -> f64 {
    f64::from(centi_k) / 100.0 - 273.15
}

/// The open, shorted and stuck sensor masks of a report.
fn faults(hk: &Housekeeping) -> [u8; 3] {
    [hk.sensors_open, hk.sensors_short, hk.sensors_stuck]
}

#[test]
fn open_short_and_stuck_sensors_are_reported_by_sensor() {
    let mut b = Bench::with_plant(warm_plant(11));
    b.run(FIRST_MEAN_CYCLES);
    b.plant.with(|p| {
        p.thermal_mut().inject(1, SensorFailure::Open);
        p.thermal_mut().inject(2, SensorFailure::Short);
        p.thermal_mut().inject(5, SensorFailure::Stuck);
    });
    // Open and short at the next reading.
    b.run(TEMPERATURE_PERIOD_CYCLES);
    let s = b.ctl.temperatures();
    assert_eq!(s.faulty(), 0b0000_0110);
    assert_eq!(s.with_fault(SensorFault::Open), 0b0000_0010);
    assert_eq!(s.with_fault(SensorFault::Short), 0b0000_0100);
    assert_eq!(s.celsius()[1], None);
    assert_eq!(s.celsius()[2], None);
    let hk = b.hk();
    assert_eq!(faults(&hk), [0b0000_0010, 0b0000_0100, 0]);
    assert_eq!(hk.temperatures_centi_k[1], NO_TEMPERATURE);
    assert_eq!(hk.temperatures_centi_k[2], NO_TEMPERATURE);
    // Stuck once the channel repeated its count STUCK_SAMPLES times.
    b.run(TEMPERATURE_PERIOD_CYCLES * u32::from(STUCK_SAMPLES));
    let s = *b.ctl.temperatures();
    assert_eq!(s.faulty(), 0b0010_0110);
    let hk = b.hk();
    assert_eq!(faults(&hk), [0b0000_0010, 0b0000_0100, 0b0010_0000]);
    assert_eq!(hk.temperatures_centi_k[5], NO_TEMPERATURE);
    // The healthy ones keep their means.
    let truth = true_sensor_temperatures(&b);
    for ch in [0, 3, 4, 6, 7] {
        let m = f64::from(s.celsius()[ch].unwrap());
        assert!((m - truth[ch]).abs() < sensor_error_k(truth[ch]), "{ch}");
        let t = celsius_of_hk(hk.temperatures_centi_k[ch]);
        assert!(
            (t - truth[ch]).abs() < sensor_error_k(truth[ch]),
            "{ch}: {t}"
        );
    }
    // Repaired: healthy again at the first reading that is (a stuck channel's once its
    // count changes: with one count of noise it may repeat a few readings), a mean
    // again after a window.
    b.plant.with(|p| p.thermal_mut().clear_failures());
    b.run(TEMPERATURE_PERIOD_CYCLES * 5);
    assert_eq!(faults(&b.hk()), [0, 0, 0]);
    b.run(FIRST_MEAN_CYCLES);
    let hk = b.hk();
    assert!(hk.temperatures_centi_k.iter().all(|t| *t != NO_TEMPERATURE));
}

#[test]
fn the_default_plant_reads_every_sensor_healthy_at_the_reference() {
    let mut b = Bench::new();
    // Long enough for the stuck check to have seen every channel.
    b.run(TEMPERATURE_PERIOD_CYCLES * (u32::from(STUCK_SAMPLES) + 10));
    let hk = b.hk();
    assert_eq!(faults(&hk), [0, 0, 0]);
    for (ch, t) in hk.temperatures_centi_k.iter().enumerate() {
        let t = celsius_of_hk(*t);
        assert!(
            (t - REFERENCE_C).abs() < sensor_error_k(REFERENCE_C),
            "sensor {ch}: {t} deg C"
        );
    }
}

#[test]
fn the_fixed_reading_of_a_board_without_sensors_is_20_c() {
    // The count just below the ideal reading at 20 deg C, and even (the QEMU board's
    // dither adds one count with `|`).
    let ideal = adc::counts_of_resistance(pt1000::resistance_ohm(20.0));
    assert_eq!(f64::from(adc::COUNTS_NEAR_20_C), ideal.floor());
    assert_eq!(adc::COUNTS_NEAR_20_C % 2, 0);
    let lo = m2ctl::thermal::celsius_from_counts(adc::COUNTS_NEAR_20_C).unwrap();
    let hi = m2ctl::thermal::celsius_from_counts(adc::COUNTS_NEAR_20_C + 1).unwrap();
    assert!((f64::from(lo + hi) / 2.0 - 20.0).abs() < 0.001, "{lo} {hi}");
}

#[test]
fn a_board_without_an_adc_driver_reports_its_sensors_stuck() {
    use m2ctl::hw::TemperatureInputs;
    use m2ctl::thermal::SensorBank;
    // The drivers' mechanism (the Netduino Plus 2's): the fixed reading, every channel.
    let mut mech = m2ctl::drivers::Mechanism {
        encoders: (),
        drives: (),
        switches: (),
        exposure: m2ctl::drivers::exposure::NoExposureLine,
    };
    let mut bank = SensorBank::default();
    for k in 1..=STUCK_SAMPLES {
        let c = mech.read_temperature_counts();
        assert_eq!(c, [adc::COUNTS_NEAR_20_C; TEMP_SENSORS]);
        bank.update(&c);
        let stuck = bank.with_fault(SensorFault::Stuck);
        assert_eq!(
            stuck,
            if k < STUCK_SAMPLES { 0 } else { 0xFF },
            "reading {k}"
        );
    }
}

#[test]
fn a_used_sensor_that_fails_raises_one_low_event() {
    let mut b = Bench::with_plant(warm_plant(13));
    let mut t = calibrated_table(0x2201);
    t.thermal = Coefficients::NOMINAL.model();
    assert!(all_ok(&install(&mut b, &t, true)));
    assert_eq!(b.ctl.active_table().thermal, t.thermal);
    // Sensors 0..5 (legs) and 6 (platform) are used; 7 (base centre) is not.
    assert_eq!(t.thermal.sensors_used(), 0b0111_1111);
    b.run(FIRST_MEAN_CYCLES);
    let events = |b: &Bench| b.st.events(event::SENSOR_FAULT);
    assert!(events(&b).is_empty());
    // An unused sensor fails: housekeeping says so, no event.
    b.plant
        .with(|p| p.thermal_mut().inject(7, SensorFailure::Open));
    b.run(TEMPERATURE_PERIOD_CYCLES * 10);
    assert_eq!(b.hk().sensors_open, 0b1000_0000);
    assert!(events(&b).is_empty());
    // A used one: one event, not repeated while it stays faulty.
    b.plant
        .with(|p| p.thermal_mut().inject(2, SensorFailure::Short));
    b.run(TEMPERATURE_PERIOD_CYCLES * 10);
    assert_eq!(
        events(&b),
        vec![[0b0000_0100, 0b1000_0000 | 0b0000_0100 << 8]]
    );
    // A second used sensor stuck: one more event, naming it.
    b.plant
        .with(|p| p.thermal_mut().inject(6, SensorFailure::Stuck));
    b.run(TEMPERATURE_PERIOD_CYCLES * (u32::from(STUCK_SAMPLES) + 10));
    let ev = events(&b);
    assert_eq!(ev.len(), 2, "{ev:?}");
    assert_eq!(
        ev[1],
        [
            0b0100_0000,
            0b1000_0000 | 0b0000_0100 << 8 | 0b0100_0000 << 16
        ]
    );
    let hk = b.hk();
    assert_eq!(faults(&hk), [0b1000_0000, 0b0000_0100, 0b0100_0000]);
    // Repaired and failed again: a new event.
    b.plant.with(|p| p.thermal_mut().clear_failures());
    b.run(TEMPERATURE_PERIOD_CYCLES * 10);
    assert_eq!(faults(&b.hk()), [0, 0, 0]);
    b.plant
        .with(|p| p.thermal_mut().inject(2, SensorFailure::Open));
    b.run(TEMPERATURE_PERIOD_CYCLES * 2);
    let ev = events(&b);
    assert_eq!(ev.len(), 3, "{ev:?}");
    assert_eq!(ev[2], [0b0000_0100, 0b0000_0100]);
}
