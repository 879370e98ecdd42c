//! The controller's temperature sensors (issue 22, first step): every channel read
//! once per `timing::TEMPERATURE_PERIOD_CYCLES` through the hardware seam
//! (`hw::TemperatureInputs`, part of `hw::MechanismIo`), supervised per sensor
//! (`thermal::SensorBank`), each sensor's mean against the simulated plant's true part
//! temperatures (within the sensors' error), and open, short and stuck sensors as the
//! supervision reports them.

use m2ctl::kinematics::LEGS;
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::thermal::{
    Coefficients, Profile, SensorConfig, SensorFailure, Swing, ThermalConfig, CLASS_TENTH_DIN_K,
    CLASS_TENTH_DIN_PER_C, REFERENCE_C,
};
use m2ctl::sim::{Bench, Plant, PlantConfig};
use m2ctl::thermal::{
    adc, pt1000, SensorFault, MEAN_SAMPLES, NO_TEMPERATURE, STUCK_SAMPLES, TEMP_SENSORS,
};
use m2ctl::timing::{CONTROL_RATE_HZ, TEMPERATURE_PERIOD_CYCLES};

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
    let cfg = ThermalConfig {
        profile: Profile {
            mean_c: 25.0,
            swing: Swing::Constant,
            gradient_k: 3.0,
            gradient_angle_rad: 0.3,
            gradient_period_s: None,
            lag_s: [0.0; 4],
        },
        truth: Coefficients::NOMINAL,
        sensors: SensorConfig::drawn(seed),
    };
    Plant::new(
        &PROTOTYPE,
        PlantConfig {
            seed,
            ..PlantConfig::default()
        },
    )
    .unwrap()
    .with_thermal(cfg)
    .unwrap()
}

/// Control cycles until every sensor has a first mean: `MEAN_SAMPLES` readings, one per
/// `TEMPERATURE_PERIOD_CYCLES` (the first in cycle 0), and one period more.
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
    // Before the first complete window: no temperature, healthy.
    b.run(TEMPERATURE_PERIOD_CYCLES * (MEAN_SAMPLES as u32 - 2));
    assert!(b.ctl.temperatures().celsius().iter().all(|t| t.is_none()));
    assert_eq!(b.ctl.temperatures().health_word(), 0);
    b.run(FIRST_MEAN_CYCLES);
    let truth = true_sensor_temperatures(&b);
    let means = b.ctl.temperatures().celsius();
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
    }
    assert_eq!(b.ctl.temperatures().health_word(), 0);
    assert_eq!(b.ctl.temperatures().faulty(), 0);
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
    assert_eq!(
        s.health_word(),
        u16::from(SensorFault::Open.code()) << 2 | u16::from(SensorFault::Short.code()) << 4
    );
    assert_eq!(s.celsius()[1], None);
    assert_eq!(s.celsius()[2], None);
    assert_eq!(s.centi_celsius()[1], NO_TEMPERATURE);
    // Stuck once the channel repeated its count STUCK_SAMPLES times.
    b.run(TEMPERATURE_PERIOD_CYCLES * u32::from(STUCK_SAMPLES));
    let s = b.ctl.temperatures();
    assert_eq!(s.faulty(), 0b0010_0110);
    assert_eq!(
        (s.health_word() >> 10) & 3,
        u16::from(SensorFault::Stuck.code())
    );
    assert_eq!(s.centi_celsius()[5], NO_TEMPERATURE);
    // The healthy ones keep their means.
    let truth = true_sensor_temperatures(&b);
    for ch in [0, 3, 4, 6, 7] {
        let m = f64::from(s.celsius()[ch].unwrap());
        assert!((m - truth[ch]).abs() < sensor_error_k(truth[ch]), "{ch}");
        let cc = f64::from(s.centi_celsius()[ch]) / 100.0;
        assert!((cc - m).abs() <= 0.005 + 1e-6, "{ch}: {cc} {m}");
    }
    // Repaired: healthy again at the first reading that is (a stuck channel's once its
    // count changes: with one count of noise it may repeat a few readings), a mean
    // again after a window.
    b.plant.with(|p| p.thermal_mut().clear_failures());
    b.run(TEMPERATURE_PERIOD_CYCLES * 5);
    assert_eq!(b.ctl.temperatures().health_word(), 0);
    b.run(FIRST_MEAN_CYCLES);
    assert!(b.ctl.temperatures().celsius().iter().all(|t| t.is_some()));
}

#[test]
fn the_default_plant_reads_every_sensor_healthy_at_the_reference() {
    let mut b = Bench::new();
    // Long enough for the stuck check to have seen every channel.
    b.run(TEMPERATURE_PERIOD_CYCLES * (u32::from(STUCK_SAMPLES) + 10));
    let s = b.ctl.temperatures();
    assert_eq!(s.health_word(), 0);
    for (ch, t) in s.celsius().iter().enumerate() {
        let t = f64::from(t.unwrap());
        assert!(
            (t - REFERENCE_C).abs() < sensor_error_k(REFERENCE_C),
            "sensor {ch}: {t} deg C"
        );
    }
    let _ = LEGS;
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
