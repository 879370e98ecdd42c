//! The exposure hold (issue 22): a telecommand (TC[8,1] 0x0007, its timeout in seconds,
//! 0 to end it) or the camera's discrete input (`hw::ExposureInput`) says the camera is
//! exposing. Until the hold ends or times out (events 0x0052/0x0053) no thermal
//! compensation step is made, no scheduled activity is released
//! (`ground/tests/schedule.rs`) and operator moves are refused with 0x0710 (data: the
//! seconds left); a stop is always accepted.

mod common;

use common::{all_ok, install, wire};
use m2ctl::controller::event;
use m2ctl::controller::params::{index, PARAMETERS};
use m2ctl::kinematics::LEGS;
use m2ctl::link::command::MAX_EXPOSURE_HOLD_S;
use m2ctl::link::tm::Verification;
use m2ctl::link::{Command, FunctionId, ParameterValues};
use m2ctl::sim::thermal::{Coefficients, Profile, REFERENCE_C};
use m2ctl::sim::Bench;
use m2ctl::table::Table;
use m2ctl::timing::CONTROL_RATE_HZ;

/// The failure (code, data) among the reports, if any.
fn failure(v: &[Verification]) -> Option<(u16, u32)> {
    v.iter().find_map(Verification::failure)
}

/// An operator move of 10 um along x.
fn a_move() -> Command {
    Command::MoveAbsolute(wire(10.0, 0.0, 0.0, 0.0, 0.0, 0.0))
}

#[test]
fn a_hold_refuses_operator_moves_with_its_seconds_left_and_ends_by_telecommand() {
    let mut b = Bench::new();
    b.run(10);
    assert!(all_ok(
        &b.command(&Command::ExposureHold { timeout_s: 30 }, 10)
    ));
    assert_eq!(b.st.events(event::EXPOSURE_HOLD_STARTED), [[0, 30]]);
    assert_eq!(
        b.hk().thermal_state,
        m2ctl::link::hk::thermal_state::EXPOSURE_HOLD
    );
    b.run(2 * CONTROL_RATE_HZ);
    // About 28 s left (rounded up).
    let reps = b.command(&a_move(), 10);
    assert_eq!(failure(&reps), Some((0x0710, 28)), "{reps:?}");
    let reps = b.command(
        &Command::MoveRelative(wire(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        10,
    );
    assert_eq!(failure(&reps).map(|f| f.0), Some(0x0710));
    let reps = b.command(
        &Command::DirectStroke {
            leg: 1,
            delta_nm: 1_000,
        },
        10,
    );
    assert_eq!(failure(&reps).map(|f| f.0), Some(0x0710));
    // Nothing moved; a stop is still accepted.
    assert!(b
        .plant
        .with(|p| p.strokes_mm())
        .iter()
        .all(|s| s.abs() < 1e-6));
    assert!(all_ok(&b.command(&Command::Stop, 10)));
    // Timeout 0 ends it (reason 0), and moves are accepted again.
    assert!(all_ok(
        &b.command(&Command::ExposureHold { timeout_s: 0 }, 10)
    ));
    assert_eq!(b.st.events(event::EXPOSURE_HOLD_ENDED), [[0, 0]]);
    let reps = b.command(&a_move(), 20_000);
    assert!(all_ok(&reps), "{reps:?}");
    // Ending when no hold is in force changes nothing and says nothing.
    assert!(all_ok(
        &b.command(&Command::ExposureHold { timeout_s: 0 }, 10)
    ));
    assert_eq!(b.st.events(event::EXPOSURE_HOLD_ENDED).len(), 1);
}

#[test]
fn a_hold_times_out_and_a_new_one_restarts_the_timeout() {
    let mut b = Bench::new();
    b.run(10);
    assert!(all_ok(
        &b.command(&Command::ExposureHold { timeout_s: 2 }, 10)
    ));
    b.run(CONTROL_RATE_HZ);
    // Re-armed from now: 2 s more.
    assert!(all_ok(
        &b.command(&Command::ExposureHold { timeout_s: 2 }, 10)
    ));
    assert_eq!(b.st.events(event::EXPOSURE_HOLD_STARTED).len(), 1);
    b.run(2 * CONTROL_RATE_HZ - 20);
    assert!(b.st.events(event::EXPOSURE_HOLD_ENDED).is_empty());
    assert_eq!(failure(&b.command(&a_move(), 5)).map(|f| f.0), Some(0x0710));
    b.run(30);
    assert_eq!(b.st.events(event::EXPOSURE_HOLD_ENDED), [[1, 0]]);
    assert!(all_ok(&b.command(&a_move(), 20_000)));
}

#[test]
fn a_timeout_beyond_the_longest_is_refused_at_acceptance_and_changes_nothing() {
    let mut b = Bench::new();
    b.run(10);
    let (mut pkt, _) =
        b.st.packet(&Command::ExposureHold {
            timeout_s: MAX_EXPOSURE_HOLD_S,
        })
        .unwrap();
    // The timeout is the last two bytes before the CRC: one more second.
    let n = pkt.len();
    let t = u16::from_be_bytes([pkt[n - 4], pkt[n - 3]]) + 1;
    pkt[n - 4..n - 2].copy_from_slice(&t.to_be_bytes());
    let crc = m2ctl::link::tc::CRC16.checksum(&pkt[..n - 2]);
    pkt[n - 2..].copy_from_slice(&crc.to_be_bytes());
    let rid = m2ctl::link::RequestId::from_packet(&pkt).unwrap();
    common::tick_packet(&mut b, &pkt);
    b.run(5);
    let reps = b.st.reports(rid);
    assert!(
        matches!(reps.first(), Some(Verification::AcceptanceFailure { .. })),
        "{reps:?}"
    );
    assert!(b.st.events(event::EXPOSURE_HOLD_STARTED).is_empty());
    assert!(all_ok(&b.command(&a_move(), 20_000)));
    assert_eq!(FunctionId::ExposureHold.code(), 0x0007);
}

#[test]
fn the_discrete_input_holds_while_active_and_its_release_ends_the_hold() {
    let mut b = Bench::new();
    b.run(10);
    b.plant.with(|p| p.set_exposing(true));
    b.run(1);
    assert_eq!(
        b.st.events(event::EXPOSURE_HOLD_STARTED),
        [[1, u32::from(MAX_EXPOSURE_HOLD_S)]]
    );
    assert_eq!(failure(&b.command(&a_move(), 5)).map(|f| f.0), Some(0x0710));
    // A telecommand's timeout 0 does not end the input's hold.
    assert!(all_ok(
        &b.command(&Command::ExposureHold { timeout_s: 0 }, 10)
    ));
    assert_eq!(failure(&b.command(&a_move(), 5)).map(|f| f.0), Some(0x0710));
    b.plant.with(|p| p.set_exposing(false));
    b.run(1);
    assert_eq!(b.st.events(event::EXPOSURE_HOLD_ENDED), [[2, 0]]);
    assert!(all_ok(&b.command(&a_move(), 20_000)));
}

/// The nominal table with the plant's thermal model.
fn table_with_model() -> Table {
    let mut t = Table::nominal();
    t.thermal = Coefficients::NOMINAL.model();
    t.table_id = 0x7E22_0002;
    t
}

/// A bench on a plant at +5 K running [`table_with_model`], the sensors' first means
/// taken (compensation still off).
fn warm_bench() -> Bench {
    let plant = common::thermal_plant(
        Profile {
            mean_c: REFERENCE_C + 5.0,
            ..Profile::REFERENCE
        },
        11,
    );
    let mut b = Bench::with_plant(plant);
    assert!(all_ok(&install(&mut b, &table_with_model(), true)));
    b.run(3 * CONTROL_RATE_HZ);
    b
}

#[test]
fn no_compensation_step_during_a_hold_and_the_steps_resume_after_it() {
    let mut b = warm_bench();
    assert!(all_ok(
        &b.command(&Command::ExposureHold { timeout_s: 20 }, 10)
    ));
    let set = ParameterValues::new(&[(PARAMETERS[index::THERMAL_ENABLE].id, 1)]).unwrap();
    assert!(all_ok(&b.command(&Command::SetParameters(set), 2_000)));
    let strokes = b.plant.with(|p| p.strokes_mm());
    for _ in 0..15 * CONTROL_RATE_HZ {
        b.tick();
        assert_eq!(b.ctl.compensation().applied_mm(), [0.0; LEGS]);
    }
    // The drives did not move during the hold.
    assert_eq!(b.plant.with(|p| p.strokes_mm()), strokes);
    b.run(10 * CONTROL_RATE_HZ);
    assert_eq!(b.st.events(event::EXPOSURE_HOLD_ENDED), [[1, 0]]);
    assert!(b
        .ctl
        .compensation()
        .applied_mm()
        .iter()
        .any(|v| v.abs() > 1e-4));
}

#[test]
fn a_move_already_running_finishes_and_a_clear_is_accepted_during_a_hold() {
    let mut b = Bench::new();
    b.run(10);
    let rid = b.send(&Command::MoveAbsolute(wire(200.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    b.run(50);
    assert!(all_ok(
        &b.command(&Command::ExposureHold { timeout_s: 60 }, 10)
    ));
    // The move started before the hold completes during it.
    for _ in 0..20_000 {
        if b.st.finished(rid) {
            break;
        }
        b.tick();
    }
    assert_eq!(
        b.st.reports(rid).last(),
        Some(&Verification::CompletionSuccess)
    );
    assert!(b.ctl.exposure_hold_active());
    assert!(all_ok(&b.command(&Command::ClearFault, 10)));
}

/// A hold that begins while a compensation step's fine positioning is under way: like a
/// move already running, it finishes, moving each slider by no more than the step and
/// twice the in-position tolerance, and within the fine positioning's timeout; then
/// nothing moves until the hold ends (no further step).
#[test]
fn a_steps_fine_positioning_under_way_finishes_within_the_step_during_a_hold() {
    use m2ctl::controller::params::DEFAULT_IN_POSITION_TOLERANCE_NM;
    use m2ctl::motion::fine::TIMEOUT_CYCLES;
    let mut b = warm_bench();
    let set = ParameterValues::new(&[(PARAMETERS[index::THERMAL_ENABLE].id, 1)]);
    assert!(set.is_ok());
    assert!(set.is_ok_and(|set| all_ok(&b.command(&Command::SetParameters(set), 2_000))));
    // Until the first step.
    let mut step_mm = 0.0f32;
    for _ in 0..3 * CONTROL_RATE_HZ {
        b.tick();
        let a = b.ctl.compensation().applied_mm();
        step_mm = a.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        if step_mm > 0.0 {
            break;
        }
    }
    assert!(step_mm > 0.0, "no step");
    let applied = b.ctl.compensation().applied_mm();
    let before = b.plant.with(|p| p.strokes_mm());
    // The hold, at once (its telecommand takes a few cycles to be executed).
    b.send(&Command::ExposureHold { timeout_s: 20 });
    while !b.ctl.exposure_hold_active() {
        b.tick();
    }
    let bound_mm = f64::from(step_mm) + 2.0 * f64::from(DEFAULT_IN_POSITION_TOLERANCE_NM) * 1e-6;
    let mut moved_mm = 0.0f64;
    for _ in 0..TIMEOUT_CYCLES {
        b.tick();
        let now = b.plant.with(|p| p.strokes_mm());
        for (n, s) in now.iter().zip(before.iter()) {
            moved_mm = moved_mm.max((n - s).abs());
        }
        assert_eq!(
            b.ctl.compensation().applied_mm(),
            applied,
            "a step in a hold"
        );
    }
    assert!(moved_mm > 0.0, "the fine positioning did not run");
    assert!(
        moved_mm <= bound_mm,
        "moved {moved_mm} mm, step {step_mm} mm"
    );
    // Finished: nothing moves for the rest of the hold.
    let after = b.plant.with(|p| p.strokes_mm());
    for _ in 0..10 * CONTROL_RATE_HZ {
        b.tick();
        assert!(b.ctl.exposure_hold_active());
        assert_eq!(b.plant.with(|p| p.strokes_mm()), after);
    }
}
