//! Issue 21's controller half on the host bench with the realistic drive train
//! (`sim::drive_train`): a move completes only when its sliders are in position, a move
//! that cannot get there ends with 0x070F naming the legs, a move already in position
//! completes without motion, a slider that creeps at rest is reported (and corrected by
//! the next move), a reversal through the backlash is no fault while a jam still is, and
//! the in-position parameters are validated.

mod common;

use common::{all_ok, wire, TestRng};
use m2ctl::controller::params::{
    index, DEFAULT_IN_POSITION_DWELL_CYCLES, DEFAULT_IN_POSITION_TOLERANCE_NM, PARAMETERS,
};
use m2ctl::kinematics::{ik, Pose, LEGS};
use m2ctl::link::command::ParameterValues;
use m2ctl::link::tm::Verification;
use m2ctl::link::{Command, WirePose};
use m2ctl::sim::drive_train::{DriveTrainConfig, LegDriveTrain};
use m2ctl::sim::{Bench, InjectedFault};
use m2ctl::supervision::FaultFlags;

/// Most cycles a move of these tests may take.
const MOVE_CYCLES: u32 = 20_000;
/// The in-position tolerance in force (mm): the default.
const TOL_MM: f64 = DEFAULT_IN_POSITION_TOLERANCE_NM as f64 * 1e-6;
/// ST[20] IDs of the in-position parameters.
const TOLERANCE_ID: u16 = PARAMETERS[index::IN_POSITION_TOLERANCE].id;
const DWELL_ID: u16 = PARAMETERS[index::IN_POSITION_DWELL].id;

fn bench(train: DriveTrainConfig) -> Bench {
    let mut r = Bench::with_drive_train(train).unwrap();
    r.run(2);
    r
}

/// The largest |true slider - its setpoint| (mm), the setpoint being IK of `target` on
/// the true geometry (the controller's table is the true geometry here).
fn slider_error_mm(r: &Bench, target: &WirePose) -> f64 {
    let pose: Pose<f64> = target.to_pose();
    let set = r.plant.with(|p| ik(p.truth(), &pose)).unwrap();
    let s = r.plant.with(|p| p.strokes_mm());
    s.iter()
        .zip(set)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
}

/// Runs `cmd` until it finishes; returns its reports.
fn run_move(r: &mut Bench, cmd: &Command) -> Vec<Verification> {
    r.command(cmd, MOVE_CYCLES)
}

#[test]
fn a_move_completes_only_with_every_slider_in_position() {
    let mut r = bench(DriveTrainConfig::realistic());
    for (i, t) in [
        wire(400.0, -300.0, 200.0, 20.0, -30.0, 10.0),
        wire(-250.0, 500.0, -100.0, -40.0, 15.0, -25.0),
        wire(-250.0, 500.0, -90.0, -40.0, 15.0, -25.0),
    ]
    .iter()
    .enumerate()
    {
        let rid = r.send(&Command::MoveAbsolute(*t));
        let mut n = 0;
        while !r.st.finished(rid) && n < MOVE_CYCLES {
            r.tick();
            n += 1;
        }
        assert!(
            all_ok(&r.st.reports(rid)),
            "move {i}: {:?}",
            r.st.reports(rid)
        );
        let e = slider_error_mm(&r, t);
        assert!(
            e <= TOL_MM,
            "move {i}: completed with a slider {:.4} um off",
            e * 1e3
        );
        // Open loop, each slider would be about half the backlash off: the closed loop
        // corrected after the path, and the completion waited for it.
        let enc = r.ctl.hk_sample().encoders_mm;
        let pose: Pose<f64> = t.to_pose();
        let set = r.plant.with(|p| ik(p.truth(), &pose)).unwrap();
        assert!(
            r.ctl.in_position_legs() == 0b11_1111,
            "move {i}: {:06b} {:?}",
            r.ctl.in_position_legs(),
            enc.iter()
                .zip(set)
                .map(|(e, s)| (*e as f64 - s) * 1e3)
                .collect::<Vec<_>>()
        );
    }
}

#[test]
fn open_loop_the_same_move_completes_out_of_position() {
    // The reference the previous test is measured against: the in-position rule made
    // loose (100 um, one cycle), every slider is left short by the drive train.
    let mut r = bench(DriveTrainConfig::realistic());
    let set = ParameterValues::new(&[(TOLERANCE_ID, 100_000), (DWELL_ID, 1)]).unwrap();
    assert!(all_ok(
        &r.command(&Command::SetParameters(set), MOVE_CYCLES)
    ));
    let t = wire(400.0, -300.0, 200.0, 20.0, -30.0, 10.0);
    let reps = run_move(&mut r, &Command::MoveAbsolute(t));
    assert!(all_ok(&reps));
    assert!(slider_error_mm(&r, &t) > 10.0 * TOL_MM);
}

#[test]
fn a_move_that_cannot_reach_position_fails_with_0x070f_naming_the_legs() {
    let mut r = bench(DriveTrainConfig::realistic());
    // z by 50 um: every slider moves about 50 um up. Leg 2 jams 2 um short of its
    // setpoint (too little for the stuck check, 10 um, or the following error, 50 um).
    let t = wire(0.0, 0.0, 50.0, 0.0, 0.0, 0.0);
    let pose: Pose<f64> = t.to_pose();
    let set = r.plant.with(|p| ik(p.truth(), &pose)).unwrap();
    let rid = r.send(&Command::MoveAbsolute(t));
    let mut jammed = false;
    let mut n = 0;
    while !r.st.finished(rid) && n < MOVE_CYCLES {
        if !jammed && r.plant.with(|p| p.strokes_mm()[1]) >= set[1] - 0.002 {
            r.plant
                .with(|p| p.inject(InjectedFault::StuckSlider { leg: 1 }));
            jammed = true;
        }
        r.tick();
        n += 1;
    }
    assert!(jammed);
    let reps = r.st.reports(rid);
    assert_eq!(
        reps.last(),
        Some(&Verification::CompletionFailure {
            code: 0x070F,
            data: 0b10
        }),
        "{reps:?}"
    );
    assert!(r.ctl.faults().is_empty(), "no fault: {:?}", r.ctl.faults());
    assert_eq!(r.ctl.housekeeping().last_failure_code, 0x070F);
}

#[test]
fn a_move_already_in_position_completes_without_motion() {
    let mut r = bench(DriveTrainConfig::realistic());
    let t = wire(100.0, 50.0, -30.0, 5.0, 0.0, -8.0);
    assert!(all_ok(&r.command(&Command::MoveAbsolute(t), MOVE_CYCLES)));
    r.settle(MOVE_CYCLES);
    let held = r.plant.with(|p| p.drive_setpoints_mm());
    let rid = r.send(&Command::MoveAbsolute(t));
    let mut n = 0;
    while !r.st.finished(rid) && n < MOVE_CYCLES {
        r.tick();
        n += 1;
        assert_eq!(r.plant.with(|p| p.drive_setpoints_mm()), held, "cycle {n}");
    }
    assert!(all_ok(&r.st.reports(rid)));
    // It still waited for the dwell.
    assert!(n >= DEFAULT_IN_POSITION_DWELL_CYCLES as u32, "{n}");
}

#[test]
fn a_slider_that_creeps_at_rest_is_reported_and_the_next_move_corrects_it() {
    let mut r = bench(DriveTrainConfig::realistic());
    let t = wire(-200.0, 100.0, 80.0, 0.0, 12.0, 0.0);
    assert!(all_ok(&r.command(&Command::MoveAbsolute(t), MOVE_CYCLES)));
    r.settle(MOVE_CYCLES);
    assert_eq!(r.ctl.in_position_legs(), 0b11_1111);
    // Leg 4's drive loses 5 um (missed steps at rest): its slider creeps about 2 um
    // back once the backlash is taken up.
    r.plant.with(|p| {
        p.inject(InjectedFault::MissedSteps {
            leg: 3,
            lost_mm: 0.005,
        })
    });
    let held = r.plant.with(|p| p.drive_setpoints_mm());
    r.run(500);
    // Reported, not corrected at rest (the controller moves on telecommands only).
    assert_eq!(r.ctl.in_position_legs(), 0b11_0111);
    assert_eq!(r.plant.with(|p| p.drive_setpoints_mm()), held);
    assert!(r.ctl.faults().is_empty());
    // The move to the same target brings it back.
    assert!(all_ok(&r.command(&Command::MoveAbsolute(t), MOVE_CYCLES)));
    assert_eq!(r.ctl.in_position_legs(), 0b11_1111);
    assert!(slider_error_mm(&r, &t) <= TOL_MM);
}

#[test]
fn sub_micrometre_reversals_complete_in_position() {
    // Issue 21's remaining 0x070F: small moves that turn the sliders back by less than
    // the backlash (3 um), the gap left inside, or on the side the slider came from (and
    // at power-on, centred). 60 moves on the realistic drive train: even ones 0.2 to
    // 0.9 um from home along a seeded direction, odd ones back home. Each must complete,
    // every true slider within the tolerance of its setpoint. The fine positioning
    // before the one-microstep corrections and the return after a retreat ended moves
    // 31, 48 and 56 of these in 0x070F (12 of 800 such moves; now none of 1,800:
    // docs/decisions.md, "Fine positioning").
    let mut r = bench(DriveTrainConfig::realistic());
    let mut rng = TestRng(7);
    for k in 0..60 {
        let t = if k % 2 == 0 {
            let v = [rng.sym(), rng.sym(), rng.sym()];
            let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-9);
            let size_um = 0.55 + 0.35 * rng.sym();
            let s = size_um / norm;
            wire(s * v[0], s * v[1], s * v[2], 0.0, 0.0, 0.0)
        } else {
            wire(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        };
        let reps = run_move(&mut r, &Command::MoveAbsolute(t));
        assert!(all_ok(&reps), "move {k} to {t:?}: {reps:?}");
        let e = slider_error_mm(&r, &t);
        assert!(e <= TOL_MM, "move {k}: a slider {:.4} um off", e * 1e3);
        r.settle(MOVE_CYCLES);
    }
}

#[test]
fn a_slow_reversal_through_the_backlash_is_no_fault_and_completes() {
    // 5 um of backlash, moves at 10 um/s: a reversal leaves each slider still for about
    // half a second (500 cycles, more than the stuck window of 200) while its command
    // goes 5 um back (more than the 3 um the stuck check once took for a jam).
    let mut r = bench(DriveTrainConfig::uniform(LegDriveTrain {
        backlash_um: 5.0,
        ..LegDriveTrain::realistic(0)
    }));
    let set = ParameterValues::new(&[(0x0010, 10_000)]).unwrap();
    assert!(all_ok(
        &r.command(&Command::SetParameters(set), MOVE_CYCLES)
    ));
    for z_um in [20.0, 0.0, 15.0] {
        let t = wire(0.0, 0.0, z_um, 0.0, 0.0, 0.0);
        let reps = run_move(&mut r, &Command::MoveAbsolute(t));
        assert!(all_ok(&reps), "z {z_um} um: {reps:?}");
        assert!(r.ctl.faults().is_empty(), "{:?}", r.ctl.faults());
        assert!(slider_error_mm(&r, &t) <= TOL_MM);
    }
}

#[test]
fn a_jam_is_still_caught() {
    let mut r = bench(DriveTrainConfig::realistic());
    r.plant
        .with(|p| p.inject(InjectedFault::StuckSlider { leg: 2 }));
    let t = wire(0.0, 0.0, 200.0, 0.0, 0.0, 0.0);
    let reps = run_move(&mut r, &Command::MoveAbsolute(t));
    let faults = r.ctl.faults();
    assert!(
        matches!(
            reps.last(),
            Some(Verification::CompletionFailure { code: 0x0709, .. })
        ),
        "{reps:?}"
    );
    assert!(
        faults.intersects(FaultFlags::ENCODER_STUCK | FaultFlags::FOLLOWING_ERROR),
        "{faults:?}"
    );
    assert_eq!(r.ctl.housekeeping().fault_legs & 0b100, 0b100);
}

#[test]
fn the_in_position_parameters_are_validated_and_a_refused_set_changes_nothing() {
    let mut r = bench(DriveTrainConfig::ideal());
    let before = *r.ctl.parameters();
    for (id, v) in [
        (TOLERANCE_ID, DEFAULT_IN_POSITION_TOLERANCE_NM - 1),
        (TOLERANCE_ID, 100_001),
        (DWELL_ID, 0),
        (DWELL_ID, 201),
    ] {
        let set = ParameterValues::new(&[(0x0010, 100_000), (id, v)]).unwrap();
        let reps = r.command(&Command::SetParameters(set), MOVE_CYCLES);
        assert!(
            reps.iter().any(|v| matches!(
                v,
                Verification::StartFailure { code: 0x0721, data } if *data == u32::from(id)
            ) || matches!(
                v,
                Verification::AcceptanceFailure { code: 0x0721, data } if *data == u32::from(id)
            )),
            "{id:#06x} = {v}: {reps:?}"
        );
        assert_eq!(*r.ctl.parameters(), before, "{id:#06x} = {v}");
    }
    let set = ParameterValues::new(&[(TOLERANCE_ID, 250), (DWELL_ID, 50)]).unwrap();
    assert!(all_ok(
        &r.command(&Command::SetParameters(set), MOVE_CYCLES)
    ));
    let table = *r.ctl.active_table();
    assert_eq!(r.ctl.parameters().in_position(&table), (0.00025, 50));
    assert_eq!(LEGS, 6);
}
