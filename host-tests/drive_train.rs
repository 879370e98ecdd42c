//! The simulated drive train (`sim::drive_train`): each effect against a hand
//! calculation, the ideal configuration bit for bit equal to the plant without one, and
//! (ignored, run by hand) issue 21's open-loop accuracy study on the host bench.

mod common;

use common::{wire, TestRng};
use m2ctl::controller::params::{index, PARAMETERS};
use m2ctl::hw::{SliderDrives, StrokeEncoders};
use m2ctl::kinematics::{ik, Pose, LEGS};
use m2ctl::link::command::ParameterValues;
use m2ctl::link::tm::Verification;
use m2ctl::link::Command;
use m2ctl::nominal::PROTOTYPE;
use m2ctl::plant::Sliders;
use m2ctl::sim::drive_train::{
    drive_full_step_um, drive_microstep_um, drive_screw_lead_mm, DriveTrain, DriveTrainConfig,
    DriveTrainError, DriveTrainParam, LegDriveTrain, DEFAULT_MICROSTEP_ERROR_UM,
};
use m2ctl::sim::pose_error;
use m2ctl::sim::{Bench, InjectedFault, Plant, PlantConfig};

/// One control cycle (s).
const DT_S: f64 = 0.001;
/// Tolerance of the hand calculations (mm): far below any effect, far above rounding.
const EPS_MM: f64 = 1e-12;

fn only(leg: LegDriveTrain) -> DriveTrain {
    DriveTrain::new(DriveTrainConfig::uniform(leg), &[0.0; LEGS]).unwrap()
}

/// Drives every leg to `x_mm`, quasi-statically (no settling stage in these configs),
/// and returns leg 0's slider (mm).
fn drive(t: &mut DriveTrain, x_mm: f64) -> f64 {
    t.update(&[x_mm; LEGS], DT_S);
    t.sliders_mm()[0]
}

fn um(v: f64) -> f64 {
    v * 1e-3
}

#[test]
fn microstep_and_full_step_come_from_the_drive_constants() {
    // 1 mm lead, 200 full steps per turn, 64 microsteps per step, direct drive.
    assert!((drive_microstep_um() - 1000.0 / (200.0 * 64.0)).abs() < 1e-12);
    assert!((drive_full_step_um() - 1000.0 / 200.0).abs() < 1e-12);
    assert!((drive_screw_lead_mm() - 1.0).abs() < 1e-15);
    let r = LegDriveTrain::realistic(0);
    assert_eq!(r.microstep_um, drive_microstep_um());
    assert_eq!(r.full_step_um, drive_full_step_um());
    assert_eq!(r.lead_error_period_mm, drive_screw_lead_mm());
    // The fine positioning counts its corrections in the same microstep (derived from
    // the same constants, in f32).
    let fine_um = f64::from(m2ctl::motion::fine::MICROSTEP_MM) * 1e3;
    assert!(
        (fine_um / drive_microstep_um() - 1.0).abs() < 1e-7,
        "{fine_um}"
    );
    // Every realistic default on, and accepted.
    DriveTrainConfig::realistic().check().unwrap();
    assert!(r.backlash_um > 0.0 && r.lead_error_um > 0.0 && r.microstep_error_um > 0.0);
    assert!(r.stiction_um > 0.0 && r.settling_time_constant_s > 0.0);
}

#[test]
fn microsteps_quantise_the_motor_position() {
    let mut t = only(LegDriveTrain {
        microstep_um: 0.3125,
        ..LegDriveTrain::IDEAL
    });
    // Nearest microstep: 0.2 um -> 1 microstep, 0.15 um -> 0, -0.5 um -> -2 (0.625).
    assert!((drive(&mut t, um(0.2)) - um(0.3125)).abs() < EPS_MM);
    assert!(drive(&mut t, um(0.15)).abs() < EPS_MM);
    assert!((drive(&mut t, um(-0.5)) - um(-0.625)).abs() < EPS_MM);
    assert!((drive(&mut t, um(100.1)) - um(320.0 * 0.3125)).abs() < EPS_MM);
}

#[test]
fn microstep_nonlinearity_repeats_every_full_step() {
    let a_um = 0.14;
    let mut t = only(LegDriveTrain {
        microstep_error_um: a_um,
        full_step_um: 5.0,
        ..LegDriveTrain::IDEAL
    });
    // sin(2 pi x / 5 um): +a at a quarter step, -a at three quarters, 0 at whole and
    // half steps, the same one full step later.
    for (x_um, err_um) in [
        (1.25, a_um),
        (3.75, -a_um),
        (2.5, 0.0),
        (5.0, 0.0),
        (6.25, a_um),
        (-1.25, -a_um),
    ] {
        let s = drive(&mut t, um(x_um));
        assert!((s - um(x_um + err_um)).abs() < 1e-11, "{x_um} um: {s}");
    }
}

#[test]
fn lead_error_is_periodic_in_the_screw_turn() {
    let a_um = 0.5;
    let mut t = only(LegDriveTrain {
        lead_error_um: a_um,
        lead_error_period_mm: 0.5,
        ..LegDriveTrain::IDEAL
    });
    // Period 0.5 mm: +a at 0.125 mm, -a at 0.375 mm, 0 at 0.25 and 0.5 mm; periodic.
    for (x_mm, err_um) in [
        (0.125, a_um),
        (0.375, -a_um),
        (0.25, 0.0),
        (0.5, 0.0),
        (1.125, a_um),
        (-0.125, -a_um),
    ] {
        let s = drive(&mut t, x_mm);
        assert!((s - (x_mm + um(err_um))).abs() < 1e-11, "{x_mm} mm: {s}");
    }
    // The phase shifts it: a quarter period ahead, +a at zero stroke.
    let t = DriveTrain::new(
        DriveTrainConfig::uniform(LegDriveTrain {
            lead_error_um: a_um,
            lead_error_period_mm: 0.5,
            lead_error_phase_rad: core::f64::consts::FRAC_PI_2,
            ..LegDriveTrain::IDEAL
        }),
        &[0.0; LEGS],
    )
    .unwrap();
    assert!((t.sliders_mm()[0] - um(a_um)).abs() < 1e-15);
}

#[test]
fn a_reversal_loses_exactly_the_backlash() {
    let b_um = 5.0;
    let mut t = only(LegDriveTrain {
        backlash_um: b_um,
        ..LegDriveTrain::IDEAL
    });
    // Gap centred at the start: the first 2.5 um move nothing.
    assert_eq!(drive(&mut t, um(2.0)), 0.0);
    let up = drive(&mut t, um(10.0));
    assert!((up - um(10.0 - b_um / 2.0)).abs() < EPS_MM, "{up}");
    // Reversal by less than the backlash: the slider stays.
    assert_eq!(drive(&mut t, um(6.0)), up);
    // Back to the start: 10 um of drive travel, 10 - 5 um of slider travel.
    let back = drive(&mut t, 0.0);
    assert!(
        ((up - back) - um(10.0 - b_um)).abs() < EPS_MM,
        "{up} {back}"
    );
    // Continuing in the same direction loses nothing more.
    let further = drive(&mut t, um(-20.0));
    assert!(((back - further) - um(20.0)).abs() < EPS_MM);
}

#[test]
fn stiction_needs_the_breakaway_deadband() {
    let d_um = 0.2;
    // Coulomb (kinetic lag = deadband).
    let mut t = only(LegDriveTrain {
        stiction_um: d_um,
        kinetic_lag_um: d_um,
        ..LegDriveTrain::IDEAL
    });
    // Sub-deadband commands (either side) do not move the slider.
    for x_um in [0.05, 0.15, 0.2, -0.2, -0.1, 0.0] {
        assert_eq!(drive(&mut t, um(x_um)), 0.0, "{x_um}");
    }
    // Beyond: it moves, d behind the drive.
    assert!((drive(&mut t, um(0.3)) - um(0.1)).abs() < EPS_MM);
    assert!((drive(&mut t, um(1.0)) - um(0.8)).abs() < EPS_MM);
    // Turning back by less than 2 d: stuck again.
    assert!((drive(&mut t, um(0.65)) - um(0.8)).abs() < EPS_MM);
    assert!((drive(&mut t, um(0.4)) - um(0.6)).abs() < EPS_MM);

    // Stick-slip (no kinetic lag): once broken away it catches up with the drive.
    let mut t = only(LegDriveTrain {
        stiction_um: d_um,
        kinetic_lag_um: 0.0,
        ..LegDriveTrain::IDEAL
    });
    assert_eq!(drive(&mut t, um(0.15)), 0.0);
    assert!((drive(&mut t, um(0.3)) - um(0.3)).abs() < EPS_MM);
    // Sliding on while the drive keeps going, stuck when it stops.
    assert!((drive(&mut t, um(0.35)) - um(0.35)).abs() < EPS_MM);
    assert!((drive(&mut t, um(0.35)) - um(0.35)).abs() < EPS_MM);
    assert!((drive(&mut t, um(0.5)) - um(0.35)).abs() < EPS_MM);
    assert!((drive(&mut t, um(0.6)) - um(0.6)).abs() < EPS_MM);
}

#[test]
fn settling_is_first_order_with_its_time_constant() {
    let tau_s = 0.005;
    let h_um = 10.0;
    let mut t = only(LegDriveTrain {
        settling_time_constant_s: tau_s,
        ..LegDriveTrain::IDEAL
    });
    // A step of the drive: the equilibrium jumps, the slider not yet.
    t.update(&[um(h_um); LEGS], 0.0);
    assert_eq!(t.sliders_mm()[0], 0.0);
    assert!(!t.at_rest());
    // s(t) = h (1 - exp(-t / tau)); at t = tau: 6.3212055883 um.
    let mut crossed_at_ms = None;
    for ms in 1..=40u32 {
        t.update(&[um(h_um); LEGS], DT_S);
        let s = t.sliders_mm()[0];
        let t_s = f64::from(ms) * DT_S;
        let hand = um(h_um) * (1.0 - (-t_s / tau_s).exp());
        assert!((s - hand).abs() < 1e-12, "{ms} ms: {s} vs {hand}");
        if ms == 5 {
            assert!((s - um(6.321_205_588_3)).abs() < 1e-12, "{s}");
        }
        if crossed_at_ms.is_none() && s >= um(h_um) * (1.0 - (-1.0f64).exp()) - 1e-15 {
            crossed_at_ms = Some(ms);
        }
    }
    assert_eq!(crossed_at_ms, Some(5), "63.2 % reached at tau");
    // At rest once within 1 pm: tau ln(10 um / 1 pm) = 80.6 ms.
    let mut ms = 40u32;
    while !t.at_rest() {
        t.update(&[um(h_um); LEGS], DT_S);
        ms += 1;
        assert!(ms < 200);
    }
    assert_eq!(ms, 81);
    assert_eq!(t.sliders_mm()[0], um(h_um));
}

#[test]
fn bad_parameters_are_refused() {
    let bad = [
        (
            LegDriveTrain {
                backlash_um: -1.0,
                ..LegDriveTrain::IDEAL
            },
            DriveTrainParam::BacklashUm,
        ),
        (
            LegDriveTrain {
                stiction_um: f64::NAN,
                ..LegDriveTrain::IDEAL
            },
            DriveTrainParam::StictionUm,
        ),
        (
            LegDriveTrain {
                stiction_um: 0.1,
                kinetic_lag_um: 0.2,
                ..LegDriveTrain::IDEAL
            },
            DriveTrainParam::KineticLagUm,
        ),
        (
            LegDriveTrain {
                lead_error_um: 0.3,
                ..LegDriveTrain::IDEAL
            },
            DriveTrainParam::LeadErrorPeriodMm,
        ),
        (
            LegDriveTrain {
                microstep_error_um: 0.1,
                full_step_um: -5.0,
                ..LegDriveTrain::IDEAL
            },
            DriveTrainParam::FullStepUm,
        ),
        (
            LegDriveTrain {
                settling_time_constant_s: f64::INFINITY,
                ..LegDriveTrain::IDEAL
            },
            DriveTrainParam::SettlingTimeConstantS,
        ),
    ];
    for (leg_cfg, param) in bad {
        let mut cfg = DriveTrainConfig::ideal();
        cfg.legs[4] = leg_cfg;
        let want = DriveTrainError { leg: 4, param };
        assert_eq!(cfg.check(), Err(want));
        assert_eq!(DriveTrain::new(cfg, &[0.0; LEGS]).err(), Some(want));
        let plant = Plant::new(&PROTOTYPE, PlantConfig::default()).unwrap();
        assert_eq!(plant.with_drive_train(cfg).err(), Some(want));
    }
}

/// The scripted sequence both plants run: commands, holds, missed steps, a jam, a
/// repair, a relocation.
fn script(step: usize) -> Option<[f32; LEGS]> {
    match step {
        0 => Some([0.1, -0.2, 0.3, 0.0, 0.05, -0.05]),
        400 => Some([-0.3, 0.25, 0.0013, 0.7, -0.0001, 0.2]),
        700 => Some([0.0; LEGS]),
        _ => None,
    }
}

#[test]
fn ideal_configuration_is_bit_identical_to_the_plant_core() {
    // Reference: the no_std slider core the plant was before drive trains (true
    // stroke = drive position - missed travel), stepped by hand.
    let speed = m2ctl::sim::plant::DEFAULT_MAX_SPEED_MM_PER_S;
    let zeroed = LegDriveTrain {
        // Every amplitude zero, the periods and phases not: the stages are off.
        full_step_um: 5.0,
        lead_error_period_mm: 0.5,
        lead_error_phase_rad: 1.0,
        ..LegDriveTrain::IDEAL
    };
    for cfg in [DriveTrainConfig::ideal(), DriveTrainConfig::uniform(zeroed)] {
        let pcfg = PlantConfig {
            seed: 9,
            ..PlantConfig::default()
        };
        let mut default_plant = Plant::new(&PROTOTYPE, pcfg).unwrap();
        let mut p = Plant::new(&PROTOTYPE, pcfg)
            .unwrap()
            .with_drive_train(cfg)
            .unwrap();
        let mut core = Sliders::<f64>::default();
        let mut loss = [0.0f64; LEGS];
        let mut jammed = [false; LEGS];
        for k in 0..1200usize {
            if let Some(sp) = script(k) {
                p.command_strokes_mm(&sp).unwrap();
                default_plant.command_strokes_mm(&sp).unwrap();
                core.command(&sp);
            }
            match k {
                150 => {
                    for q in [&mut p, &mut default_plant] {
                        q.inject(InjectedFault::MissedSteps {
                            leg: 2,
                            lost_mm: 0.0123,
                        });
                        q.inject(InjectedFault::StuckSlider { leg: 4 });
                    }
                    loss[2] += 0.0123;
                    jammed[4] = true;
                }
                300 => {
                    p.hold();
                    default_plant.hold();
                    core.hold();
                }
                550 => {
                    p.clear_faults();
                    default_plant.clear_faults();
                    core.shift(2, -loss[2]);
                    loss[2] = 0.0;
                    jammed[4] = false;
                }
                900 => {
                    let at = [0.01, -0.02, 0.03, -0.04, 0.05, -0.06];
                    p.set_strokes_mm(&at);
                    default_plant.set_strokes_mm(&at);
                    core = Sliders::at(at);
                }
                _ => {}
            }
            p.step(DT_S);
            default_plant.step(DT_S);
            core.step(speed * DT_S, |leg| jammed[leg]);
            let mut want = core.positions_mm();
            for (w, l) in want.iter_mut().zip(loss.iter()) {
                *w -= l;
            }
            let got = p.strokes_mm();
            assert_eq!(
                got.map(f64::to_bits),
                want.map(f64::to_bits),
                "step {k}: {got:?} vs {want:?}"
            );
            assert_eq!(
                got.map(f64::to_bits),
                default_plant.strokes_mm().map(f64::to_bits)
            );
            assert_eq!(p.settled(), default_plant.settled());
            // Same noise stream, same strokes: the same encoder counts.
            assert_eq!(p.read_counts(), default_plant.read_counts());
        }
    }
}

#[test]
fn the_encoder_reads_the_slider_not_the_drive() {
    // Backlash 4 um on the plant: after a reversal the drive is back where it started,
    // the encoder (true slider) is the backlash short of it.
    let cfg = DriveTrainConfig::uniform(LegDriveTrain {
        backlash_um: 4.0,
        ..LegDriveTrain::IDEAL
    });
    let mut p = Plant::new(
        &PROTOTYPE,
        PlantConfig {
            encoder_noise_mm: 0.0,
            ..PlantConfig::default()
        },
    )
    .unwrap()
    .with_drive_train(cfg)
    .unwrap();
    p.command_strokes_mm(&[0.01; LEGS]).unwrap();
    while !p.settled() {
        p.step(DT_S);
    }
    // 10 um of drive, 2 um of half-gap: 8 um = 80 counts.
    assert_eq!(p.read_counts().unwrap(), [80; LEGS]);
    p.command_strokes_mm(&[0.0; LEGS]).unwrap();
    while !p.settled() {
        p.step(DT_S);
    }
    assert_eq!(p.drive_positions_mm(), [0.0; LEGS]);
    // Back 10 um of drive: 10 - 4 um of slider, from 8 um to 2 um.
    assert_eq!(p.read_counts().unwrap(), [20; LEGS]);
}

#[test]
fn the_plant_is_settled_only_when_the_sliders_are() {
    // Settling lag 20 ms: the drive arrives first, the slider (and encoder) after.
    let tau_s = 0.020;
    let cfg = DriveTrainConfig::uniform(LegDriveTrain {
        settling_time_constant_s: tau_s,
        ..LegDriveTrain::IDEAL
    });
    let mut p = Plant::new(
        &PROTOTYPE,
        PlantConfig {
            encoder_noise_mm: 0.0,
            ..PlantConfig::default()
        },
    )
    .unwrap()
    .with_drive_train(cfg)
    .unwrap();
    // 0.1 mm at 0.5 mm/s: the drive arrives after 200 cycles.
    p.command_strokes_mm(&[0.1; LEGS]).unwrap();
    for _ in 0..200 {
        p.step(DT_S);
    }
    // (to rounding: 200 steps of 0.5 um, the last 1.5 pm left for the next step).
    assert!((p.drive_positions_mm()[0] - 0.1f32 as f64).abs() < 1e-8);
    assert!(!p.settled());
    // Behind by about v tau = 0.5 mm/s * 20 ms = 10 um. Exactly, for the drive moving
    // h = 0.5 um at the start of each 1 ms and the lag closing a share a = 1 - exp(-dt /
    // tau) of the gap in it: the gap after k cycles is e_k = (e_{k-1} + h)(1 - a), so
    // e_200 = h (1 - a) (1 - (1 - a)^200) / a = 9.7516 um (v tau less about v dt / 2).
    let h_mm = 0.0005;
    let keep = (-DT_S / tau_s).exp();
    let hand_lag_mm = h_mm * keep * (1.0 - keep.powi(200)) / (1.0 - keep);
    let lag_mm = p.drive_positions_mm()[0] - p.strokes_mm()[0];
    assert!(
        (lag_mm - hand_lag_mm).abs() < 1e-9,
        "{lag_mm} vs {hand_lag_mm}"
    );
    let mut n = 0;
    while !p.settled() {
        p.step(DT_S);
        n += 1;
        assert!(n < 1000);
    }
    // The remaining ~10 um decay to 1 pm: tau ln(10 um / 1 pm) = 322 ms.
    assert!((300..=340).contains(&n), "{n}");
    assert_eq!(p.strokes_mm(), [0.1f32 as f64; LEGS]);
}

// -------------------------------------------------------------------------------------
// Issue 21's measurement: today's (open-loop) controller on drive trains.

/// Targets of the study: +-1 mm, +-60 arcsec (issue 21).
const STUDY_MOVES: usize = 200;
const STUDY_UM: f64 = 1000.0;
const STUDY_ARCSEC: f64 = 60.0;
/// In-position figures of the issue (um, arcsec).
const GOOD_UM: f64 = 0.1;
const GOOD_ARCSEC: f64 = 0.2;
/// Seed of the study's targets (`M2_STUDY_SEED=n` runs the study on another set:
/// [`study_seed`]).
const STUDY_SEED: u64 = 0x21_d21e;

/// The study's seed: [`STUDY_SEED`], or `M2_STUDY_SEED` if set (a decimal number).
fn study_seed() -> u64 {
    std::env::var("M2_STUDY_SEED")
        .map(|v| {
            v.parse()
                .unwrap_or_else(|e| panic!("M2_STUDY_SEED={v}: {e}"))
        })
        .unwrap_or(STUDY_SEED)
}
/// Most cycles a move may take (a 2 mm stroke at 0.5 mm/s is 4,000).
const MOVE_CYCLES: u32 = 60_000;

/// One configuration's figures.
struct Row {
    /// Largest true slider error at completion (um): |true slider - IK of the target on
    /// the true geometry|.
    max_slider_um: f64,
    /// Moves completed with every true slider within [`GOOD_UM`] of its setpoint.
    sliders_good: usize,
    /// Moves ended by the in-position timeout (0x070F).
    not_in_position: usize,
    max_um: f64,
    max_arcsec: f64,
    max_settled_um: f64,
    max_settled_arcsec: f64,
    good: usize,
    completed: usize,
    aborted: Vec<String>,
    refused: usize,
}

fn flag_names(bits: u32) -> String {
    m2ctl::supervision::FaultFlags::NAMED
        .into_iter()
        .filter(|(f, _)| bits & f.bits() != 0)
        .map(|(_, name)| name)
        .collect::<Vec<_>>()
        .join("+")
}

/// The open-loop controller of before issue 21, as a configuration: an in-position
/// tolerance (100 um) no drive train's error reaches and a dwell of one cycle, so every
/// move completes the cycle after its path, uncorrected.
const OPEN_LOOP: &[(u16, i32)] = &[
    (PARAMETERS[index::IN_POSITION_TOLERANCE].id, 100_000),
    (PARAMETERS[index::IN_POSITION_DWELL].id, 1),
];

fn study(train: DriveTrainConfig, params: &[(u16, i32)]) -> Row {
    let mut r = Bench::with_drive_train(train).unwrap();
    r.run(2);
    if !params.is_empty() {
        let set = ParameterValues::new(params).unwrap();
        let reps = r.command(&Command::SetParameters(set), MOVE_CYCLES);
        assert_eq!(reps.last(), Some(&Verification::CompletionSuccess));
    }
    let mut rng = TestRng(study_seed());
    let mut row = Row {
        max_slider_um: 0.0,
        sliders_good: 0,
        not_in_position: 0,
        max_um: 0.0,
        max_arcsec: 0.0,
        max_settled_um: 0.0,
        max_settled_arcsec: 0.0,
        good: 0,
        completed: 0,
        aborted: Vec::new(),
        refused: 0,
    };
    let worst = |e: &[f64; 6]| {
        (
            e[..3].iter().fold(0.0f64, |m, v| m.max(v.abs())),
            e[3..].iter().fold(0.0f64, |m, v| m.max(v.abs())),
        )
    };
    for _ in 0..STUDY_MOVES {
        let t = wire(
            rng.sym() * STUDY_UM,
            rng.sym() * STUDY_UM,
            rng.sym() * STUDY_UM,
            rng.sym() * STUDY_ARCSEC,
            rng.sym() * STUDY_ARCSEC,
            rng.sym() * STUDY_ARCSEC,
        );
        let target: Pose<f64> = t.to_pose();
        let reps = r.command(&Command::MoveAbsolute(t), MOVE_CYCLES);
        match reps.last() {
            Some(Verification::CompletionSuccess) => {
                // The pose the moment the completion is reported.
                let truth = r.plant.with(|p| p.true_pose()).unwrap();
                let (e_um, e_as) = worst(&pose_error(&truth, &target));
                let set_mm = r.plant.with(|p| ik(p.truth(), &target)).unwrap();
                let sliders = r.plant.with(|p| p.strokes_mm());
                let s_um = sliders
                    .iter()
                    .zip(set_mm)
                    .fold(0.0f64, |m, (s, t)| m.max((s - t).abs() * 1e3));
                row.max_slider_um = row.max_slider_um.max(s_um);
                if s_um <= GOOD_UM {
                    row.sliders_good += 1;
                }
                row.completed += 1;
                row.max_um = row.max_um.max(e_um);
                row.max_arcsec = row.max_arcsec.max(e_as);
                if e_um <= GOOD_UM && e_as <= GOOD_ARCSEC {
                    row.good += 1;
                }
                r.try_settle(MOVE_CYCLES);
                let settled = r.plant.with(|p| p.true_pose()).unwrap();
                let (s_um, s_as) = worst(&pose_error(&settled, &target));
                row.max_settled_um = row.max_settled_um.max(s_um);
                row.max_settled_arcsec = row.max_settled_arcsec.max(s_as);
            }
            Some(Verification::CompletionFailure { code: 0x070F, .. }) => {
                row.not_in_position += 1;
                r.try_settle(MOVE_CYCLES);
            }
            Some(Verification::CompletionFailure { code: 0x0709, data }) => {
                row.aborted.push(flag_names(*data));
                r.try_settle(MOVE_CYCLES);
                r.command(&Command::ClearFault, MOVE_CYCLES);
                r.try_settle(MOVE_CYCLES);
            }
            other => {
                row.refused += 1;
                eprintln!("move refused or unfinished: {other:?} ({reps:?})");
                r.command(&Command::ClearFault, MOVE_CYCLES);
                r.try_settle(MOVE_CYCLES);
            }
        }
    }
    row
}

/// Issue 21's table, measured: run with
/// `cargo test --features host --test drive_train -- --ignored --nocapture` (the test
/// profile is optimised).
#[test]
#[ignore = "a benchmark (minutes): run by hand, it prints issue 21's table"]
fn open_loop_accuracy_study() {
    let leg = |f: fn(&mut LegDriveTrain)| DriveTrainConfig {
        legs: core::array::from_fn(|i| {
            let mut l = LegDriveTrain {
                lead_error_phase_rad: LegDriveTrain::realistic(i).lead_error_phase_rad,
                ..LegDriveTrain::IDEAL
            };
            f(&mut l);
            l
        }),
    };
    let rows: [(&str, DriveTrainConfig); 10] = [
        ("ideal", DriveTrainConfig::ideal()),
        ("backlash 2 um", leg(|l| l.backlash_um = 2.0)),
        ("backlash 5 um", leg(|l| l.backlash_um = 5.0)),
        (
            "lead error 0.5 um (0.5 mm period)",
            leg(|l| {
                l.lead_error_um = 0.5;
                l.lead_error_period_mm = 0.5;
            }),
        ),
        (
            "stiction 0.2 um",
            leg(|l| {
                l.stiction_um = 0.2;
                l.kinetic_lag_um = 0.2;
            }),
        ),
        (
            "backlash 3, lead error 0.3, stiction 0.1 um",
            leg(|l| {
                l.backlash_um = 3.0;
                l.lead_error_um = 0.3;
                l.lead_error_period_mm = drive_screw_lead_mm();
                l.stiction_um = 0.1;
                l.kinetic_lag_um = 0.1;
            }),
        ),
        // Beyond the table: the other stages alone.
        (
            "stiction 0.2 um, stick-slip (no kinetic lag)",
            leg(|l| l.stiction_um = 0.2),
        ),
        (
            "microsteps of the drive (64: 0.078 um) + nonlinearity 0.14 um",
            leg(|l| {
                l.microstep_um = drive_microstep_um();
                l.microstep_error_um = DEFAULT_MICROSTEP_ERROR_UM;
                l.full_step_um = drive_full_step_um();
            }),
        ),
        (
            "settling 20 ms",
            leg(|l| l.settling_time_constant_s = 0.020),
        ),
        (
            "realistic defaults (sim::drive_train)",
            DriveTrainConfig::realistic(),
        ),
    ];
    println!(
        "| drive train | controller | pose error at completion, max | after settling, max | slider error at completion, max | moves with every slider within {GOOD_UM} um | moves within {GOOD_UM} um / {GOOD_ARCSEC}\" | aborted by a fault | not in position (0x070F) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    // `M2_STUDY_ROWS=word` runs only the rows whose name contains it.
    let only = std::env::var("M2_STUDY_ROWS").unwrap_or_default();
    for (name, cfg) in rows.into_iter().filter(|(n, _)| n.contains(only.as_str())) {
        for (ctl, params) in [("open loop", OPEN_LOOP), ("closed loop", &[][..])] {
            let row = study(cfg, params);
            let mut codes: Vec<(String, usize)> = Vec::new();
            for a in &row.aborted {
                match codes.iter_mut().find(|(c, _)| c == a) {
                    Some((_, n)) => *n += 1,
                    None => codes.push((a.clone(), 1)),
                }
            }
            let codes = codes
                .iter()
                .map(|(c, n)| format!("{n} {c}"))
                .collect::<Vec<_>>()
                .join(", ");
            println!(
                "| {name} | {ctl} | {:.4} um / {:.4}\" | {:.4} um / {:.4}\" | {:.4} um | {:.0} % | {:.0} % ({} of {} completed) | {}{}{} | {} |",
                row.max_um,
                row.max_arcsec,
                row.max_settled_um,
                row.max_settled_arcsec,
                row.max_slider_um,
                100.0 * row.sliders_good as f64 / STUDY_MOVES as f64,
                100.0 * row.good as f64 / STUDY_MOVES as f64,
                row.good,
                row.completed,
                row.aborted.len(),
                if codes.is_empty() { String::new() } else { format!(" ({codes})") },
                if row.refused > 0 { format!("; {} refused", row.refused) } else { String::new() },
                row.not_in_position,
            );
        }
    }
}

/// For `n` moves of `size_um` on a fresh realistic bench (default parameters): odd
/// moves from home along a seeded unit vector (translation only), even moves back home.
/// Per move completed: the path's cycles (from the telecommand to the first cycle the
/// commanded strokes are within 10 nm of the target's, where the path ends) and the
/// cycles to its completion; and the number of moves that ended in 0x070F.
fn time_to_in_position(size_um: f64, n: usize) -> (Vec<(u32, u32)>, usize) {
    let mut r = Bench::with_drive_train(DriveTrainConfig::realistic()).unwrap();
    r.run(2);
    let mut rng = TestRng(STUDY_SEED ^ size_um.to_bits());
    let mut out = Vec::new();
    let mut failed = 0;
    for k in 0..n {
        let v = [rng.sym(), rng.sym(), rng.sym()];
        let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-9);
        let to = if k % 2 == 0 { size_um / norm } else { 0.0 };
        let t = wire(to * v[0], to * v[1], to * v[2], 0.0, 0.0, 0.0);
        let pose: Pose<f64> = t.to_pose();
        let set = r.plant.with(|p| ik(p.truth(), &pose)).unwrap();
        let rid = r.send(&Command::MoveAbsolute(t));
        let mut c = 1;
        let mut path_end = None;
        while !r.st.finished(rid) && c < MOVE_CYCLES {
            r.tick();
            c += 1;
            let cmd = r.ctl.strokes_commanded_mm();
            if path_end.is_none()
                && cmd
                    .iter()
                    .zip(set)
                    .all(|(a, b)| (f64::from(*a) - b).abs() < 1e-5)
            {
                path_end = Some(c);
            }
        }
        match r.st.reports(rid).last() {
            Some(Verification::CompletionSuccess) => out.push((path_end.unwrap_or(0), c)),
            Some(Verification::CompletionFailure { code: 0x070F, .. }) => failed += 1,
            other => panic!("{size_um} um: {other:?}"),
        }
        r.try_settle(MOVE_CYCLES);
    }
    (out, failed)
}

/// Issue 21's second figure: time to "in position" for 1 um, 10 um and 1 mm moves
/// against the path time, realistic drive train, default parameters.
/// Run with `cargo test --features host --test drive_train time_to_in_position --
/// --ignored --nocapture` (`M2_TIME_MOVES=n`: n moves of each size instead of 20).
#[test]
#[ignore = "a benchmark: run by hand, it prints issue 21's time-to-in-position table"]
fn time_to_in_position_study() {
    let moves: usize = std::env::var("M2_TIME_MOVES").map_or(20, |v| v.parse().unwrap());
    println!("| move | path time, mean / max | time to in position, mean / max | after the path, mean / max | not in position (0x070F) |");
    println!("|---|---|---|---|---|");
    for size_um in [1.0, 10.0, 1000.0] {
        let (runs, failed) = time_to_in_position(size_um, moves);
        let stats = |v: Vec<u32>| {
            (
                f64::from(v.iter().sum::<u32>()) / v.len().max(1) as f64,
                v.iter().copied().max().unwrap_or(0),
            )
        };
        let (pm, px) = stats(runs.iter().map(|(p, _)| *p).collect());
        let (cm, cx) = stats(runs.iter().map(|(_, c)| *c).collect());
        let (am, ax) = stats(runs.iter().map(|(p, c)| c - p).collect());
        println!(
            "| {size_um} um ({moves} moves) | {pm:.0} / {px} ms | {cm:.0} / {cx} ms | {am:.0} / {ax} ms | {failed} |"
        );
    }
}
