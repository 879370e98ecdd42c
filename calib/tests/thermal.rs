//! Thermal calibration in simulation (issue 22): the fit recovers the plant's true
//! coefficients within its stated uncertainty, and the campaign's observability.

#![cfg(feature = "host")]

use m2calib::campaign::perturbed;
use m2calib::thermal::{
    default_states, default_targets, fit, observability, params_of, simulate, ThermalCampaign,
    PARAMS, PARAM_NAMES,
};
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::thermal::{Coefficients, PartTemperatures, Profile, SensorConfig, ThermalConfig};
use m2ctl::sim::tracker::PoseTracker;
use m2ctl::sim::{Plant, PlantConfig};

/// A manufactured plant with its own coefficients (seed), and the campaign measured on
/// it with the ground's geometry the nominal one (0.1 mm off the truth).
fn campaign(
    seed: u64,
    tracker: PoseTracker,
) -> (Coefficients, Vec<m2calib::thermal::ThermalMeasurement>) {
    campaign_in(seed, tracker, default_states())
}

/// The campaign of `seed` fitted (column length held at the nominal one), and the
/// plant's true parameters in the fit's order.
fn fitted(seed: u64, tracker: PoseTracker) -> (m2calib::thermal::ThermalFit, [f64; PARAMS]) {
    let (coef, meas) = campaign(seed, tracker);
    let f = fit(
        &PROTOTYPE,
        &meas,
        &tracker,
        Coefficients::NOMINAL.column_length_mm,
    )
    .unwrap();
    (f, params_of(&coef))
}

fn campaign_in(
    seed: u64,
    tracker: PoseTracker,
    states: Vec<PartTemperatures>,
) -> (Coefficients, Vec<m2calib::thermal::ThermalMeasurement>) {
    let truth = perturbed(&PROTOTYPE, 0.1, seed);
    let coef = Coefficients::drawn(seed);
    let mut plant = Plant::new(&truth, PlantConfig::default())
        .unwrap()
        .with_thermal(ThermalConfig {
            profile: Profile::REFERENCE,
            truth: coef,
            sensors: SensorConfig::drawn(seed),
        })
        .unwrap();
    let c = ThermalCampaign {
        targets: default_targets(),
        states,
        tracker,
    };
    (
        coef,
        simulate(&mut plant, &PROTOTYPE, &c, seed + 100).unwrap(),
    )
}

#[test]
fn the_fit_recovers_the_true_coefficients_within_its_uncertainty() {
    let tracker = PoseTracker::PAPER;
    for seed in [1u64, 2, 3] {
        let (f, truth) = fitted(seed, tracker);
        for i in 0..PARAMS {
            let z = (f.estimate[i] - truth[i]) / f.sigma[i];
            eprintln!(
                "seed {seed} {}: fit {:.4e} +- {:.2e} ({:.2} %), truth {:.4e}, {z:+.2} sigma",
                PARAM_NAMES[i],
                f.estimate[i],
                f.sigma[i],
                100.0 * f.sigma[i] / truth[i].abs(),
                truth[i]
            );
            assert!(z.abs() <= 3.0, "{}: {z} sigma", PARAM_NAMES[i]);
            // The campaign determines each to a few percent: better than the materials'
            // spread (3 %) needs the paper-class instrument.
            assert!(f.sigma[i] < 0.05 * truth[i].abs(), "{}", PARAM_NAMES[i]);
        }
        assert!(
            (0.8..1.2).contains(&f.chi2_per_dof),
            "chi2/dof {}",
            f.chi2_per_dof
        );
        eprintln!("seed {seed} correlation {:.3?}", f.correlation);
    }
}

#[test]
fn the_column_coefficient_and_length_are_observable_only_as_their_product() {
    let tracker = PoseTracker::PAPER;
    let (_, meas) = campaign(4, tracker);
    let sv = observability(&PROTOTYPE, &meas, &tracker).unwrap();
    eprintln!("relative singular values {sv:.3?}");
    assert_eq!(sv.len(), 5);
    // Four observable directions, one null: alpha_column * column_length.
    assert!(sv[3] / sv[0] > 1e-3, "{sv:?}");
    assert!(sv[4] / sv[0] < 1e-6, "{sv:?}");
}

#[test]
fn the_base_interface_state_separates_the_rods_from_the_columns() {
    // Rods and columns both lift the mirror nearly uniformly: with soaks alone (every
    // base-side part at one temperature) their growths are all but collinear.
    let tracker = PoseTracker::PAPER;
    let column = Coefficients::NOMINAL.column_length_mm;
    let all = default_states();
    let without: Vec<PartTemperatures> = all
        .iter()
        .copied()
        .filter(|t| t.rod_c[0] == t.column_c[0])
        .collect();
    assert_eq!(without.len(), all.len() - 2);
    let corr = |states| {
        let (_, meas) = campaign_in(5, tracker, states);
        let f = fit(&PROTOTYPE, &meas, &tracker, column).unwrap();
        (f.correlation[0][3], f.sigma[0])
    };
    let (c_without, s_without) = corr(without);
    let (c_with, s_with) = corr(all);
    eprintln!("rod/column-growth correlation {c_without:.4} -> {c_with:.4}; rod sigma {s_without:.2e} -> {s_with:.2e}");
    assert!(c_without.abs() > 0.99, "{c_without}");
    assert!(c_with.abs() < 0.9, "{c_with}");
    assert!(s_with < 0.2 * s_without);
}

#[test]
#[ignore = "prints: the thermal fit's uncertainty with each instrument"]
fn thermal_fit_uncertainty_by_instrument() {
    for (name, tracker) in [
        ("paper (0.1 um, 0.1\")", PoseTracker::PAPER),
        ("realistic pose (5 um, 1\")", PoseTracker::REALISTIC),
    ] {
        let (f, truth) = fitted(1, tracker);
        let rel: Vec<String> = (0..PARAMS)
            .map(|i| {
                format!(
                    "{} {:.2} %",
                    PARAM_NAMES[i],
                    100.0 * f.sigma[i] / truth[i].abs()
                )
            })
            .collect();
        println!("{name}: 1-sigma {}", rel.join(", "));
        println!("  correlation {:.3?}", f.correlation);
    }
}
