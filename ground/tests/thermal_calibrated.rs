//! Issue 22 end to end: a mechanism whose materials are not the nominal ones. The ground's
//! thermal campaign (`m2calib::thermal`: poses measured by the tracker at several
//! temperatures) fits its coefficients; the table carrying them is uploaded, committed and
//! activated by the ground's own telecommands (`m2ground::tc`); the controller, enabled by
//! TC[20,3], holds the pose through a +-5 K swing with a 2 K gradient within the goal,
//! measured every cycle on the plant's own true pose. The same table with the materials'
//! nominal coefficients is shown for comparison.

#![cfg(feature = "host")]

use m2calib::thermal::{default_states, default_targets, fit, simulate, ThermalCampaign};
use m2ctl::controller::params::{index, PARAMETERS};
use m2ctl::kinematics::Pose;
use m2ctl::link::tm::Verification;
use m2ctl::link::{Command, ParameterValues};
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::thermal::{Coefficients, Profile, SensorConfig, ThermalConfig};
use m2ctl::sim::tracker::PoseTracker;
use m2ctl::sim::{Bench, Plant, PlantConfig};
use m2ctl::table::Table;
use m2ctl::thermal::{ThermalModel, MEAN_SAMPLES};
use m2ctl::timing::{CONTROL_RATE_HZ, TEMPERATURE_PERIOD_CYCLES};
use m2ground::tc::{activate_command, upload_commands};

/// Issue 22's goal with compensation: held pose error (translation norm, um) ...
const GOAL_UM: f64 = 0.3;
/// ... and rotation norm (arcsec).
const GOAL_ARCSEC: f64 = 0.5;
/// The swing's orbit (s): a low orbit's 90 minutes (`sim::thermal::ORBIT_S`).
const ORBIT_S: f64 = m2ctl::sim::thermal::ORBIT_S;
/// How long the comparisons (off, nominal coefficients) run (s): through the swing's
/// first peak (a quarter orbit), where both are at their worst.
const TO_FIRST_PEAK_S: f64 = 0.25 * ORBIT_S + 60.0;
/// Cycles for a table job (upload chunk, commit, activation) to report.
const JOB_CYCLES: u32 = 20_000;

/// The swing: +-5 K over the orbit and a 2 K gradient across the base, the parts
/// following at once (their lags: README, "Thermal drift").
const SWING: Profile = Profile::swing_with_gradient(ORBIT_S);

/// The mechanism of `seed` (the prototype's geometry, its own materials) with its parts
/// at `profile`.
fn plant(seed: u64, profile: Profile) -> Plant {
    let plant = Plant::new(
        &PROTOTYPE,
        PlantConfig {
            seed,
            ..PlantConfig::default()
        },
    );
    assert!(plant.is_ok());
    let Ok(plant) = plant else { unreachable!() };
    let plant = plant.with_thermal(ThermalConfig {
        profile,
        truth: Coefficients::drawn(seed),
        sensors: SensorConfig::drawn(seed),
    });
    assert!(plant.is_ok());
    let Ok(plant) = plant else { unreachable!() };
    plant
}

/// The ground's thermal campaign on the mechanism of `seed` (home, the translation and
/// rotation corners, the default states, the paper's tracker): the fitted model.
fn fitted_model(seed: u64) -> ThermalModel {
    let tracker = PoseTracker::PAPER;
    let campaign = ThermalCampaign {
        targets: default_targets(),
        states: default_states(),
        tracker,
    };
    let mut p = plant(seed, Profile::REFERENCE);
    let meas = simulate(&mut p, &PROTOTYPE, &campaign, seed + 100);
    assert!(meas.is_ok(), "{meas:?}");
    let Ok(meas) = meas else { unreachable!() };
    let f = fit(
        &PROTOTYPE,
        &meas,
        &tracker,
        Coefficients::NOMINAL.column_length_mm,
    );
    assert!(f.is_ok(), "{f:?}");
    let Ok(f) = f else { unreachable!() };
    f.coefficients().model()
}

/// Sends `cmd` and waits for its completion success.
fn ok(b: &mut Bench, cmd: &Command) {
    let reps = b.command(cmd, JOB_CYCLES);
    assert!(
        reps.contains(&Verification::CompletionSuccess),
        "{cmd:?}: {reps:?}"
    );
}

/// A bench on the mechanism of `seed` at `profile`, running the nominal table with
/// `model`, installed by the ground's telecommands, the sensors' first means taken.
fn bench(seed: u64, profile: Profile, model: ThermalModel) -> Bench {
    let mut b = Bench::with_plant(plant(seed, profile));
    let mut table = Table::nominal();
    table.thermal = model;
    table.table_id = 0x7E22_00C0;
    let upload = upload_commands(&table);
    assert!(upload.is_ok());
    for cmd in upload.iter().flatten() {
        ok(&mut b, cmd);
    }
    ok(&mut b, &activate_command(&table));
    b.run((MEAN_SAMPLES as u32 + 1) * TEMPERATURE_PERIOD_CYCLES + CONTROL_RATE_HZ);
    b
}

/// Translation (um) and rotation (arcsec) norms of the plant's true pose less
/// `reference`.
fn error(b: &Bench, reference: &Pose<f64>) -> (f64, f64) {
    let pose = b.plant.with(|p| p.true_pose());
    assert!(pose.is_ok());
    let Ok(pose) = pose else { unreachable!() };
    let e = m2ctl::sim::pose_error(&pose, reference);
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    (norm(&e[..3]), norm(&e[3..]))
}

/// The worst held pose error (um, arcsec) of every cycle over `seconds` of the swing
/// after the first minute, on the mechanism of `seed` running `model`, the
/// compensation on (`on`) or off.
fn held_over_swing(seed: u64, model: ThermalModel, on: bool, seconds: f64) -> (f64, f64) {
    let reference = {
        let b = bench(seed, Profile::REFERENCE, model);
        let Ok(p) = b.plant.with(|p| p.true_pose()) else {
            unreachable!("the reference pose")
        };
        p
    };
    let mut b = bench(seed, SWING, model);
    if on {
        let v = ParameterValues::new(&[(PARAMETERS[index::THERMAL_ENABLE].id, 1)]);
        assert!(v.is_ok());
        let Ok(v) = v else { unreachable!() };
        ok(&mut b, &Command::SetParameters(v));
    }
    b.run(60 * CONTROL_RATE_HZ);
    let mut worst = (0.0f64, 0.0f64);
    for _ in 0..seconds as u32 * CONTROL_RATE_HZ {
        b.tick();
        let e = error(&b, &reference);
        worst = (worst.0.max(e.0), worst.1.max(e.1));
    }
    worst
}

/// The mechanism of `seed`: with its fitted coefficients it holds the goal every cycle
/// over a whole orbit; off, the swing moves it by micrometres (through the first peak).
/// Returns the held error with the materials' nominal coefficients through the first
/// peak (um, arcsec).
fn holds_with_its_fitted_coefficients(seed: u64) -> (f64, f64) {
    let truth = Coefficients::drawn(seed);
    let fitted = fitted_model(seed);
    let off = held_over_swing(seed, fitted, false, TO_FIRST_PEAK_S);
    let with_nominal = held_over_swing(seed, Coefficients::NOMINAL.model(), true, TO_FIRST_PEAK_S);
    let with_fitted = held_over_swing(seed, fitted, true, ORBIT_S);
    println!(
        "mechanism {seed} (alpha rod/column/base/platform {:.2?} e-6/K), +-5 K swing over {ORBIT_S} s with a 2 K gradient, every cycle: off {:.3} um / {:.3}\" and on with the nominal coefficients {:.3} um / {:.3}\" through the first peak, on with the fitted ones {:.3} um / {:.3}\" over the orbit",
        truth.expansion_per_k.map(|a| a * 1e6),
        off.0,
        off.1,
        with_nominal.0,
        with_nominal.1,
        with_fitted.0,
        with_fitted.1
    );
    assert!(
        with_fitted.0 <= GOAL_UM && with_fitted.1 <= GOAL_ARCSEC,
        "mechanism {seed}: {with_fitted:?}"
    );
    assert!(off.0 > 3.0 * GOAL_UM, "mechanism {seed}: {off:?}");
    with_nominal
}

#[test]
fn mechanism_1_holds_the_goal_with_its_fitted_coefficients() {
    holds_with_its_fitted_coefficients(1);
}

/// With the materials' nominal coefficients this one misses the goal: the campaign is
/// needed.
#[test]
fn mechanism_2_holds_the_goal_with_its_fitted_coefficients_and_not_with_the_nominal_ones() {
    let nominal = holds_with_its_fitted_coefficients(2);
    assert!(nominal.0 > GOAL_UM, "{nominal:?}");
}

#[test]
fn mechanism_3_holds_the_goal_with_its_fitted_coefficients() {
    holds_with_its_fitted_coefficients(3);
}
