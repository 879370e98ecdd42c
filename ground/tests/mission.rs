//! The mission story as a test (smaller: fewer targets): the error at the targets,
//! measured by the laser tracker from its target balls, falls from micrometres to the
//! tracker's noise floor after the table calibrated from the tracker export is uploaded
//! by telecommands and activated; then a +-5 K swing, held, with the thermal
//! compensation off and on.

#![cfg(feature = "host")]

use m2ground::mission::{format_summary, run_mission, MissionConfig};

#[test]
fn calibration_uploaded_by_telecommand_brings_the_error_to_the_noise_floor() {
    let cfg = MissionConfig {
        n_targets: 8,
        progress: false,
        seed: 3,
        ..MissionConfig::default()
    };
    let r = run_mission(&cfg, &mut |l: &str| println!("{l}")).unwrap();
    println!("{}", format_summary(&r));
    assert!(
        r.before.max_um() > 1.0 && r.before.max_arcsec() > 1.0,
        "manufacturing errors show before calibration"
    );
    // The paper's tracker: ~0.05 um / 0.1 arcsec per axis and pose (the reported error
    // includes it).
    assert!(
        r.after.max_um() < 0.5 && r.after.max_arcsec() < 0.5,
        "after: {:?}",
        r.after.max_abs
    );
    assert!(r.after.max_um() < r.before.max_um() / 5.0);
    assert!(r.after.max_arcsec() < r.before.max_arcsec() / 5.0);
    // Issue 22's +-5 K: the held pose moves by micrometres with the compensation off,
    // and stays within the goal (0.3 um / 0.5 arcsec) with it on.
    assert!(r.thermal_off.0 > 1.0, "off: {:?}", r.thermal_off);
    assert!(
        r.thermal_on.0 <= 0.3 && r.thermal_on.1 <= 0.5,
        "on: {:?}",
        r.thermal_on
    );
}
