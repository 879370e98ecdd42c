//! The mission story as a test (smaller: fewer targets): the error at the targets,
//! measured by the laser tracker from its target balls, falls from micrometres to the
//! tracker's noise floor after the table calibrated from the tracker export is uploaded
//! by telecommands and activated.

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
}
