//! The operator contract under the conditions where it broke (issue 8): recovery moves
//! with suspect encoders, setpoint continuity after faults, table banks and the
//! selection, and the telemetry words the ICD promises. Each test names the defect it
//! reproduces.
#![allow(clippy::needless_range_loop)] // index loops over six legs read clearer here

mod common;

use common::{activate, all_ok, calibrated_table, install, upload, wire, JOB_CYCLES};
use m2ctl::controller::{event, State};
use m2ctl::link::command::WirePose;
use m2ctl::link::tm::{EventSeverity, Verification};
use m2ctl::link::Command;
use m2ctl::motion::{MotionLimits, CYCLE_S, DEFAULT_DIRECT_SPEED_MM_PER_S};
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::{Bench, InjectedFault, Plant, PlantConfig};
use m2ctl::station::Tm;
use m2ctl::supervision::FaultFlags;
use m2ctl::table::{Table, TABLE_LEN};
use m2ctl::units::{MM_PER_NM, UM_PER_MM};

fn plant_at(strokes_mm: [f64; 6]) -> Plant {
    let mut p = Plant::new(
        &PROTOTYPE,
        PlantConfig {
            seed: 3,
            ..PlantConfig::default()
        },
    )
    .unwrap();
    p.set_strokes_mm(&strokes_mm);
    p
}

fn drive_setpoints(r: &Bench) -> [f64; 6] {
    r.plant.with(|p| p.drive_setpoints_mm())
}

fn true_strokes(r: &Bench) -> [f64; 6] {
    r.plant.with(|p| p.strokes_mm())
}

/// Runs `cycles`, returning the largest commanded stroke step of any leg in one cycle
/// (mm) seen in housekeeping-free controller state.
fn run_max_step(r: &mut Bench, cycles: u32) -> f64 {
    let mut prev = r.ctl.strokes_commanded_mm();
    let mut worst = 0.0f64;
    for _k in 0..cycles {
        r.tick();
        let now = r.ctl.strokes_commanded_mm();
        for i in 0..6 {
            if std::env::var("DBG").is_ok() && (now[i] - prev[i]).abs() > 1e-3 {
                eprintln!(
                    "cycle {_k} leg {i}: {} -> {} state {:?}",
                    prev[i],
                    now[i],
                    r.ctl.state()
                );
            }
            worst = worst.max(f64::from((now[i] - prev[i]).abs()));
        }
        prev = now;
    }
    worst
}

fn start_failure_code(v: &[Verification]) -> Option<u16> {
    v.iter().find_map(|r| match r {
        Verification::StartFailure { code, .. } => Some(*code),
        _ => None,
    })
}

/// Defect 1a: booted with one encoder not answering, a +1 um recovery move of leg 2 drove
/// all six sliders from where they were back to 0 (the readings started at zero).
#[test]
fn recovery_move_with_an_encoder_not_answering_at_boot_moves_nothing_else() {
    let mut p = plant_at([0.4, 2.87, -1.2, 0.9, -0.3, 1.5]);
    p.inject(InjectedFault::EncoderNoResponse { leg: 0 });
    let mut r = Bench::with_plant(p);
    r.run(5);
    assert!(r.ctl.faults().contains(FaultFlags::ENCODER_READ_FAILURE));
    let held = drive_setpoints(&r);
    let rid = r.send(&Command::DirectStroke {
        leg: 2,
        delta_nm: 1_000,
    });
    r.run(2_000);
    let reps = r.st.reports(rid);
    // No reading this cycle means no leg's encoder can vouch for the move: refused.
    assert_eq!(start_failure_code(&reps), Some(0x070B), "{reps:?}");
    assert_eq!(drive_setpoints(&r), held, "a drive setpoint changed");
    let t = true_strokes(&r);
    for i in 0..6 {
        assert!((t[i] - held[i]).abs() < 1e-12, "leg {} moved: {t:?}", i + 1);
    }
}

/// Defect 1b: after an encoder read failure during a move, a zero-length recovery move
/// made every leg jump back by the distance travelled since the last good reading.
#[test]
fn zero_length_recovery_after_a_read_failure_during_a_move_moves_no_leg() {
    let mut r = Bench::with_plant(plant_at([0.0; 6]));
    r.run(2);
    r.send(&Command::MoveAbsolute(wire(
        1200.0, -300.0, 200.0, 0.0, 0.0, 0.0,
    )));
    r.run(1500);
    r.plant
        .with(|p| p.inject(InjectedFault::EncoderNoResponse { leg: 3 }));
    r.settle(2_000);
    assert_eq!(r.ctl.state(), State::Faulted);
    // The encoder answers again, the fault is still latched: recovery is allowed.
    r.plant.with(|p| p.clear_faults());
    r.run(3);
    let held = drive_setpoints(&r);
    let before = true_strokes(&r);
    let reps = r.command(
        &Command::DirectStroke {
            leg: 1,
            delta_nm: 0,
        },
        1_000,
    );
    assert!(all_ok(&reps), "{reps:?}");
    r.run(200);
    assert_eq!(drive_setpoints(&r), held);
    let after = true_strokes(&r);
    for i in 0..6 {
        assert!(
            (after[i] - before[i]).abs() < 1e-9,
            "leg {} moved {} um",
            i + 1,
            (after[i] - before[i]) * UM_PER_MM
        );
    }
}

/// Defect 1c: with a 0.3 mm encoder jump on leg 6, a recovery move of leg 2 physically
/// moved leg 6 by 0.3 mm (it was commanded to its jumped reading).
#[test]
fn recovery_move_of_a_healthy_leg_keeps_the_other_legs_exactly_where_their_drives_hold() {
    let mut r = Bench::with_plant(plant_at([0.1, -0.2, 0.3, 0.0, 0.2, 0.4]));
    r.run(2);
    r.plant.with(|p| {
        p.inject(InjectedFault::EncoderJump {
            leg: 5,
            jump_mm: 0.3,
        })
    });
    r.run(5);
    assert!(r.ctl.faults().contains(FaultFlags::ENCODER_JUMP));
    let held = drive_setpoints(&r);
    let held_f32 = r.ctl.strokes_commanded_mm();
    let before = true_strokes(&r);
    let delta_mm = 0.02;
    let rid = r.send(&Command::DirectStroke {
        leg: 2,
        delta_nm: (delta_mm / MM_PER_NM) as i32,
    });
    // Every cycle of the move commands the other legs exactly what their drives held.
    while !r.st.finished(rid) {
        r.tick();
        let c = r.ctl.strokes_commanded_mm();
        for i in (0..6).filter(|i| *i != 1) {
            assert_eq!(
                c[i].to_bits(),
                held_f32[i].to_bits(),
                "leg {} commanded",
                i + 1
            );
        }
    }
    assert!(all_ok(&r.st.reports(rid)), "{:?}", r.st.reports(rid));
    r.run(20);
    let after = true_strokes(&r);
    let sp = drive_setpoints(&r);
    // The drive interface carries f32 (resolution 1e-8 mm at these strokes).
    let f32_res = |v: f64| v.abs().max(1.0) * f64::from(f32::EPSILON);
    for i in 0..6 {
        if i == 1 {
            assert!(
                (sp[i] - (held[i] + delta_mm)).abs() < 1e-6,
                "leg 2 setpoint {sp:?}"
            );
            assert!(
                (after[i] - (before[i] + delta_mm)).abs() < 1e-6,
                "leg 2 {after:?}"
            );
        } else {
            assert!(
                (sp[i] - held[i]).abs() <= f32_res(held[i]),
                "leg {} setpoint changed",
                i + 1
            );
            assert!(
                (after[i] - before[i]).abs() <= f32_res(held[i]),
                "leg {} moved",
                i + 1
            );
        }
    }
    // A recovery move of the leg whose encoder jumped is refused, with the reason.
    let rid = r.send(&Command::DirectStroke {
        leg: 6,
        delta_nm: -10_000,
    });
    let reps = r.st.reports(rid);
    let Some(Verification::StartFailure { code, data }) = reps.last().copied() else {
        panic!("{reps:?}")
    };
    assert_eq!(code, 0x070B);
    assert_ne!(
        data & m2ctl::controller::error::suspect::JUMP,
        0,
        "{data:#x}"
    );
}

/// Defect 1d: a 4.3 mm encoder jump on leg 3, then a recovery move "towards the range"
/// drove the real slider from 0.8 to 5.095 mm, beyond the 5 mm soft limit.
#[test]
fn recovery_move_of_a_leg_with_a_jumped_encoder_is_refused_and_no_slider_leaves_its_limits() {
    let mut r = Bench::with_plant(plant_at([0.0, 0.0, 0.8, 0.0, 0.0, 0.0]));
    r.run(2);
    r.plant.with(|p| {
        p.inject(InjectedFault::EncoderJump {
            leg: 2,
            jump_mm: 4.3,
        })
    });
    r.run(5);
    for delta_nm in [-900_000, -100_000, 100_000] {
        let rid = r.send(&Command::DirectStroke { leg: 3, delta_nm });
        r.run(3_000);
        assert_eq!(
            start_failure_code(&r.st.reports(rid)),
            Some(0x070B),
            "delta {delta_nm} nm: {:?}",
            r.st.reports(rid)
        );
    }
    let t = true_strokes(&r);
    // The drives hold in their f32 resolution (a hold rounds 0.8 mm by 1e-8 mm).
    assert!((t[2] - 0.8).abs() < 1e-7, "{t:?}");
    assert!(t.iter().all(|s| s.abs() <= 5.0));
}

/// Defect 1e: a recovery move's leg whose encoder disagrees with what its drive holds
/// (missed steps) is refused with its reason.
#[test]
fn recovery_move_of_a_leg_whose_encoder_disagrees_with_its_drive_is_refused() {
    let mut r = Bench::with_plant(plant_at([0.0; 6]));
    r.run(2);
    r.plant.with(|p| {
        p.inject(InjectedFault::MissedSteps {
            leg: 4,
            lost_mm: 0.08,
        })
    });
    r.run(10);
    assert!(r.ctl.faults().contains(FaultFlags::FOLLOWING_ERROR));
    let rid = r.send(&Command::DirectStroke {
        leg: 5,
        delta_nm: 50_000,
    });
    let reps = r.st.reports(rid);
    let Some(Verification::StartFailure { code, data }) = reps.last().copied() else {
        panic!("{reps:?}")
    };
    assert_eq!(code, 0x070B);
    assert_ne!(data & m2ctl::controller::error::suspect::DISAGREES, 0);
}

/// Defect 2: after an intermittent encoder fault, the first setpoint of the next move was
/// up to 49.8 um off the held strokes; no step may exceed the speed limit times a cycle.
#[test]
fn moves_after_an_intermittent_encoder_fault_start_where_the_drives_hold() {
    let lim = MotionLimits::default();
    let step_limit_mm = f64::from(lim.max_speed_mm_per_s[0] * CYCLE_S) * 1.001 + 1e-6;
    let mut r = Bench::with_plant(plant_at([0.0; 6]));
    r.run(2);
    let rid = r.send(&Command::MoveAbsolute(wire(
        900.0, 0.0, 0.0, 0.0, 0.0, 20.0,
    )));
    let worst = run_max_step(&mut r, 1000);
    // An intermittent read failure: during the move, then repaired.
    r.plant
        .with(|p| p.inject(InjectedFault::EncoderCorrupted { leg: 1 }));
    let worst = worst.max(run_max_step(&mut r, 5));
    r.plant.with(|p| p.clear_faults());
    let worst = worst.max(run_max_step(&mut r, 600));
    assert!(matches!(
        r.st.reports(rid).last(),
        Some(Verification::CompletionFailure { code: 0x0709, .. })
    ));
    let clr = r.command(&Command::ClearFault, 10);
    assert!(all_ok(&clr), "{clr:?}");
    let mv = r.send(&Command::MoveRelative(wire(
        -400.0, 100.0, 0.0, 0.0, 0.0, 0.0,
    )));
    let worst = worst.max(run_max_step(&mut r, 8_000));
    assert!(all_ok(&r.st.reports(mv)), "{:?}", r.st.reports(mv));
    assert!(
        worst <= step_limit_mm,
        "a commanded step of {:.3} um in one cycle (limit {:.3} um)",
        worst * UM_PER_MM,
        step_limit_mm * UM_PER_MM
    );
    // The direct-stroke speed limit holds too.
    let held = drive_setpoints(&r);
    let ds = r.send(&Command::DirectStroke {
        leg: 4,
        delta_nm: 30_000,
    });
    let worst_ds = run_max_step(&mut r, 2_000);
    assert!(all_ok(&r.st.reports(ds)));
    let ds_limit_mm = f64::from(DEFAULT_DIRECT_SPEED_MM_PER_S * CYCLE_S) * 1.001 + 1e-6;
    assert!(
        worst_ds <= ds_limit_mm,
        "direct stroke: {:.4} um in a cycle (limit {:.4})",
        worst_ds * UM_PER_MM,
        ds_limit_mm * UM_PER_MM
    );
    assert!((drive_setpoints(&r)[3] - held[3] - 0.03).abs() < 1e-6);
}

/// Defect 3: a table commit was accepted while the mirror was moving.
#[test]
fn a_commit_while_moving_is_refused_with_busy() {
    let mut r = Bench::new();
    r.run(1);
    let t = calibrated_table(5);
    upload(&mut r, &t.to_bytes(), &[0, 1, 2, 3, 4]);
    r.send(&Command::MoveAbsolute(wire(800.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    r.run(50);
    let rid = r.send(&Command::CommitTable { crc32: t.crc32() });
    let reps = r.st.reports(rid);
    assert!(
        matches!(
            reps[..],
            [_, Verification::StartFailure { code: 0x0702, data }] if data == u32::from(State::Moving.code())
        ),
        "{reps:?}"
    );
    assert_eq!(r.ctl.housekeeping().job, 0);
    // And a move while a commit runs is refused (job busy) until the commit completes.
    r.settle(20_000);
    let commit = r.send(&Command::CommitTable { crc32: t.crc32() });
    let mv = r.send(&Command::MoveRelative(wire(10.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    assert_eq!(start_failure_code(&r.st.reports(mv)), Some(0x070D));
    for _ in 0..JOB_CYCLES {
        if r.st.finished(commit) {
            break;
        }
        r.tick();
    }
    assert!(all_ok(&r.st.reports(commit)), "{:?}", r.st.reports(commit));
}

/// Defect 4a: switch bank after a commit that was not activated re-activated the old
/// table and silently dropped the committed one. Now the other bank is the pending one,
/// and switching to it activates it; housekeeping shows each step.
#[test]
fn switch_bank_after_an_unactivated_commit_activates_the_pending_table() {
    let mut r = Bench::new();
    r.run(1);
    let t1 = calibrated_table(1);
    let t2 = calibrated_table(2);
    assert!(all_ok(&install(&mut r, &t1, true)));
    assert!(all_ok(&install(&mut r, &t2, false)));
    let hk = r.hk();
    assert_eq!((hk.active_table_id, hk.active_bank), (1, 1));
    assert_eq!((hk.pending_table_id, hk.pending_bank), (2, 2));
    let reps = r.command(&Command::SwitchBank, JOB_CYCLES);
    assert!(all_ok(&reps), "{reps:?}");
    let hk = r.hk();
    assert_eq!((hk.active_table_id, hk.active_bank), (2, 2));
    assert_eq!((hk.pending_table_id, hk.pending_bank), (0, 0));
    assert_eq!(hk.selected_source, 2);
    assert_eq!(
        r.st.events(event::TABLE_ACTIVATED).last(),
        Some(&[2, t2.crc32()])
    );
}

/// Defect 4b: two commits without activation overwrote the bank the running table came
/// from while housekeeping still reported that bank. The running bank is never written.
#[test]
fn two_commits_without_activation_never_overwrite_the_running_bank() {
    let mut r = Bench::new();
    r.run(1);
    let t1 = calibrated_table(1);
    assert!(all_ok(&install(&mut r, &t1, true)));
    let running = r.hk().active_bank;
    let bank_bytes = |r: &mut Bench, bank: u8| {
        let off = if bank == 1 {
            m2ctl::sim::bench::SIM_LAYOUT.bank_a_offset
        } else {
            m2ctl::sim::bench::SIM_LAYOUT.bank_b_offset
        } as usize;
        r.flash_mut().bytes()[off..off + 1024].to_vec()
    };
    let image = bank_bytes(&mut r, running);
    for id in [2, 3] {
        assert!(all_ok(&install(&mut r, &calibrated_table(id), false)));
        assert_eq!(bank_bytes(&mut r, running), image, "running bank written");
        let hk = r.hk();
        assert_eq!((hk.active_table_id, hk.active_bank), (1, running));
        assert_eq!(hk.pending_table_id, id);
        assert_ne!(hk.pending_bank, running);
    }
    // After a reset the selected table runs, not a pending one.
    let mut r = r.reboot();
    r.run(2);
    let hk = r.hk();
    assert_eq!((hk.active_table_id, hk.active_table_crc32), (1, t1.crc32()));
}

/// Defect 5a: revert to nominal did not persist across a reset.
#[test]
fn revert_to_nominal_persists_across_a_reset() {
    let mut r = Bench::new();
    r.run(1);
    assert!(all_ok(&install(&mut r, &calibrated_table(1), true)));
    let reps = r.command(&Command::RevertToNominal, JOB_CYCLES);
    assert!(all_ok(&reps), "{reps:?}");
    let mut r = r.reboot();
    r.run(2);
    let hk = r.hk();
    assert_eq!(
        (
            hk.active_table_id,
            hk.active_table_crc32,
            hk.selected_source
        ),
        (0, Table::nominal().crc32(), 0)
    );
    // And a commit does not change that.
    assert!(all_ok(&install(&mut r, &calibrated_table(2), false)));
    let mut r = r.reboot();
    r.run(2);
    assert_eq!(r.hk().active_table_id, 0);
}

/// Defect 5b: after a refused commit, activate succeeded and activated an older
/// committed table. Activate names the table it expects and is refused otherwise.
#[test]
fn activate_names_the_pending_table_and_a_failed_commit_leaves_nothing_to_activate() {
    let mut r = Bench::new();
    r.run(1);
    let t2 = calibrated_table(2);
    assert!(all_ok(&install(&mut r, &t2, false)));
    // The wrong ID or CRC is refused, naming the pending table.
    for cmd in [
        Command::ActivateTable {
            table_id: 3,
            crc32: t2.crc32(),
        },
        Command::ActivateTable {
            table_id: 2,
            crc32: t2.crc32() ^ 1,
        },
    ] {
        let reps = r.command(&cmd, 10);
        assert!(
            matches!(
                reps[..],
                [
                    _,
                    Verification::StartFailure {
                        code: 0x070A,
                        data: 2
                    }
                ]
            ),
            "{reps:?}"
        );
    }
    // A commit refused by validation erases the pending bank: nothing left to activate.
    let mut bad = calibrated_table(4);
    bad.legs[0].a_mm[0] += 10.0;
    let reps = install(&mut r, &bad, false);
    assert!(
        matches!(
            reps.last(),
            Some(Verification::CompletionFailure { code: 0x0412, .. })
        ),
        "{reps:?}"
    );
    let reps = r.command(&activate(&t2), 10);
    assert!(
        matches!(
            reps[..],
            [_, Verification::StartFailure { code: 0x0707, .. }]
        ),
        "{reps:?}"
    );
    assert_eq!(r.hk().active_table_id, 0);
}

/// ICD: the boot event carries the boot source and the table ID; the boot detail event
/// the flags and the reset cause.
#[test]
fn boot_events_carry_the_words_the_icd_lists() {
    let mut r = Bench::new();
    r.set_reset_info(m2ctl::controller::ResetInfo {
        cause: m2ctl::controller::ResetCause::Watchdog,
        boot_count: 7,
    });
    r.run(2);
    assert_eq!(r.st.events(event::BOOT), [[0, 0]]);
    let detail = r.st.events(event::BOOT_DETAIL);
    assert_eq!(detail.len(), 1);
    // Blank banks (bit 0 of each bank's byte), no selection; reset cause 1, boot 7.
    assert_eq!(detail[0], [0x0101, 1 | (7 << 16)]);
    let hk = r.hk();
    assert_eq!((hk.reset_cause, hk.boot_count), (1, 7));
    // With a selected calibrated table in bank A.
    assert!(all_ok(&install(&mut r, &calibrated_table(9), true)));
    let mut r = r.reboot();
    r.run(2);
    assert_eq!(r.st.events(event::BOOT).last(), Some(&[1, 9]));
    let d = *r.st.events(event::BOOT_DETAIL).last().unwrap();
    assert_eq!(d[0] & 0xff, 1 << 6, "bank A active");
    assert_eq!(d[0] >> 16, 1 | (1 << 1), "a selection record naming bank A");
}

/// ICD: every state change is an event, a coordinated move's Idle -> Moving included.
#[test]
fn every_state_change_is_an_event_including_the_start_of_a_coordinated_move() {
    let mut r = Bench::new();
    r.run(2);
    let mv = r.send(&Command::MoveAbsolute(wire(300.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    r.settle(20_000);
    assert!(all_ok(&r.st.reports(mv)));
    let s = |st: State| u32::from(st.code());
    assert_eq!(
        r.st.events(event::STATE_CHANGED),
        [
            [s(State::Idle), s(State::Moving)],
            [s(State::Moving), s(State::Idle)]
        ]
    );
    // The severity of state events is informative.
    assert!(r.st.log.iter().all(|t| !matches!(
        t,
        Tm::Event(sev, event::STATE_CHANGED, _) if *sev != EventSeverity::Info
    )));
}

/// ICD: a 257-byte telecommand (a frame that still fits the receiver) is refused with
/// TM[1,2] 0x0503; a longer frame is dropped and counted in housekeeping.
#[test]
fn an_oversized_telecommand_is_refused_with_a_report_and_a_longer_frame_is_counted() {
    let mut r = Bench::new();
    r.run(1);
    let (pkt, rid) = r.st.packet(&Command::Ping).unwrap();
    // A ping with 244 bytes of application data: 257 bytes, its length field
    // consistent, its CRC right.
    let mut big = pkt[..11].to_vec();
    big.extend(std::iter::repeat_n(0x5a, 244));
    let len = (big.len() + 2 - 7) as u16;
    big[4..6].copy_from_slice(&len.to_be_bytes());
    let crc = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740).checksum(&big);
    big.extend(crc.to_be_bytes());
    assert_eq!(big.len(), 257);
    common::tick_packet(&mut r, &big);
    r.run(2);
    let reps = r.st.reports(rid);
    assert!(
        matches!(
            reps[..],
            [Verification::AcceptanceFailure { code: 0x0503, .. }]
        ),
        "{reps:?}"
    );
    // A frame longer than any telecommand's is dropped (no request ID to report on).
    let mut frame = vec![0u8];
    frame.extend(std::iter::repeat_n(0x11, 600));
    frame.push(0);
    r.uplink_bytes(&frame);
    r.run(2);
    let hk = r.hk();
    assert_eq!(hk.tc_frames_dropped, 1);
    assert_eq!(r.st.bad_frames, 0);
}

/// ICD: the report type of every controller failure, as the ICD's table says.
#[test]
fn each_failure_arrives_in_the_report_the_icd_names() {
    let mut r = Bench::new();
    r.run(1);
    let t = calibrated_table(6);
    // Start failures (TM[1,4]): missing bytes, CRC mismatch, no pending, busy.
    upload(&mut r, &t.to_bytes(), &[0, 1, 2, 3]);
    let reps = r.command(&Command::CommitTable { crc32: t.crc32() }, 10);
    assert!(
        matches!(reps[..], [_, Verification::StartFailure { code: 0x0705, data }]
            if data as usize == m2ctl::table::layout::TABLE_LEN - 4 * m2ctl::link::command::TABLE_CHUNK_MAX_LEN)
    );
    upload(&mut r, &t.to_bytes(), &[4]);
    let reps = r.command(&Command::CommitTable { crc32: 1 }, 10);
    assert!(
        matches!(reps[..], [_, Verification::StartFailure { code: 0x0706, data }] if data == t.crc32())
    );
    // Completion failures (TM[1,8]): validation refuses the table in the background.
    let mut nan = t;
    nan.p0_mm[1] = f64::NAN;
    let reps = install(&mut r, &nan, false);
    assert!(
        matches!(
            reps[..],
            [
                Verification::AcceptanceSuccess,
                Verification::StartSuccess,
                Verification::CompletionFailure {
                    code: 0x0411,
                    data: 37
                }
            ]
        ),
        "NaN p0.y is field 37: {reps:?}"
    );
    // A stop ends a move with TM[1,8] 0x0708.
    let mv = r.send(&Command::MoveAbsolute(wire(500.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    r.run(500);
    r.send(&Command::Stop);
    r.settle(5_000);
    assert!(matches!(
        r.st.reports(mv)[..],
        [
            _,
            _,
            Verification::CompletionFailure {
                code: 0x0708,
                data: 0
            }
        ]
    ));
    let _ = TABLE_LEN;
    let _ = WirePose::default();
}

/// Issue 18, item 1: telemetry numbers under a backed-up downlink. Sixteen table dumps
/// in one write (and seeded mixes of dumps, pings, one-shot housekeeping and parameter
/// reports) at 115,200 baud keep the TX queue full for many passes. The ground checks
/// that the TM sequence count goes up by one per packet from 0 at boot and that each
/// service's message counter is contiguous (a packet that did not fit the TX queue used
/// to consume its numbers: 64 -> 66); that every telecommand got its acceptance, start
/// and completion reports (one was lost in 1 run of 5); and that whatever was not
/// received is counted in `tm_dropped`.
#[test]
fn telemetry_numbers_are_gapless_and_replies_are_never_dropped_under_a_full_downlink() {
    use m2ctl::link::command::ParameterIds;
    use m2ctl::link::schedule::ScheduleCommand;
    use m2ctl::link::time::TimeReportRate;
    use m2ctl::link::MemoryId;
    use m2ctl::sim::bench::{BenchConfig, SIM_FLASH_BYTES, UART_115200_BYTES_PER_CYCLE};
    use m2ctl::station::TmHeader;
    use m2ctl::table::mock_flash::MockFlash;
    use m2ctl::table::TABLE_LEN;

    let chunks_per_dump = TABLE_LEN.div_ceil(m2ctl::link::command::TABLE_CHUNK_MAX_LEN);
    let mut worst_dropped = 0u16;
    for seed in 0..24u64 {
        let plant = Plant::new(&PROTOTYPE, PlantConfig::default()).unwrap();
        let cfg = BenchConfig {
            uart_bytes_per_cycle: Some(UART_115200_BYTES_PER_CYCLE),
            ..BenchConfig::default()
        };
        let mut r = Bench::with(plant, MockFlash::new(SIM_FLASH_BYTES), cfg);
        r.run(50);
        // Half the seeds with housekeeping at 10 Hz: reports pile up behind the dumps
        // beyond the samples the queue keeps, and are dropped (and counted).
        let hk_period = if seed % 2 == 1 { 100 } else { 1000 };
        if hk_period != 1000 {
            let set = m2ctl::link::command::ParameterValues::new(&[(0x0020, hk_period)]).unwrap();
            assert!(all_ok(&r.command(&Command::SetParameters(set), JOB_CYCLES)));
        }
        let hk0 = r.hk();
        assert_eq!(hk0.tm_dropped, 0);
        let mut rng = common::TestRng(0x9E37_79B9_7F4A_7C15 ^ seed);
        let mut burst = Vec::new();
        let mut sent: Vec<(m2ctl::link::RequestId, Command)> = Vec::new();
        for k in 0..16 {
            let cmd = if seed == 0 {
                Command::DumpTable(MemoryId::ActiveTable)
            } else {
                // Every service that sends telemetry: 1 (all), 3, 5 (the state events of
                // the moves), 6, 8, 9, 11, 17, 20.
                match rng.bits() % 9 {
                    0 | 1 => Command::DumpTable(if k % 2 == 0 {
                        MemoryId::ActiveTable
                    } else {
                        MemoryId::UploadBuffer
                    }),
                    2 => Command::Ping,
                    3 => Command::HousekeepingOneShot,
                    4 => Command::ReportParameters(ParameterIds::new(&[0x0010, 0x0031]).unwrap()),
                    5 => Command::CheckMove(wire(2.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
                    6 => Command::SetTimeReportRate(TimeReportRate::Every { exponent: 0 }),
                    7 => Command::Schedule(ScheduleCommand::SummaryReport),
                    _ => Command::MoveRelative(wire(0.0, 0.0, 0.1, 0.0, 0.0, 0.0)),
                }
            };
            let (frame, rid) = r.st.frame(&cmd).unwrap();
            burst.extend_from_slice(&frame);
            sent.push((rid, cmd));
        }
        // Several bursts back to back, some split mid-frame across cycles.
        let split = (rng.bits() % burst.len() as u64) as usize;
        r.uplink_bytes(&burst[..split]);
        r.tick();
        r.uplink_bytes(&burst[split..]);
        // Until every telecommand has finished and the downlink has drained.
        for _ in 0..20_000 {
            r.tick();
            if sent.iter().all(|(rid, _)| r.st.finished(*rid)) && r.link.queue().is_empty() {
                break;
            }
        }
        r.run(2_000);
        let hk = r.hk();
        r.run(500);

        // 1. Sequence count: 0 at boot, +1 per packet, no gap.
        let numbers: &[TmHeader] = &r.st.log_headers;
        assert_eq!(numbers.len(), r.st.log.len());
        for (i, n) in numbers.iter().enumerate() {
            assert_eq!(
                usize::from(n.seq_count),
                i % 16384,
                "seed {seed}: packet {i} has sequence count {} (previous {:?})",
                n.seq_count,
                i.checked_sub(1).map(|j| numbers[j].seq_count)
            );
        }
        // 2. Each service's message counter from 0, +1 per packet of that service.
        let mut next = std::collections::BTreeMap::<u8, u16>::new();
        for (i, n) in numbers.iter().enumerate() {
            let want = next.entry(n.service).or_insert(0);
            assert_eq!(
                n.msg_counter, *want,
                "seed {seed}: packet {i} of service {} has message counter {}, expected {}",
                n.service, n.msg_counter, want
            );
            *want = want.wrapping_add(1);
        }
        // 3. Every telecommand: acceptance, then start and completion (a move that
        //    finds another one running is refused busy: acceptance, start failure).
        for (rid, cmd) in &sent {
            let v = r.st.reports(*rid);
            let busy = matches!(cmd, Command::MoveRelative(_))
                && v == [
                    Verification::AcceptanceSuccess,
                    Verification::StartFailure {
                        code: 0x0702,
                        data: u32::from(State::Moving.code()),
                    },
                ];
            assert!(
                busy || v
                    == [
                        Verification::AcceptanceSuccess,
                        Verification::StartSuccess,
                        Verification::CompletionSuccess
                    ],
                "seed {seed}: reports of {cmd:?}: {v:?}"
            );
        }
        let checks = sent
            .iter()
            .filter(|(_, c)| matches!(c, Command::CheckMove(_)))
            .count();
        assert_eq!(
            r.st.log
                .iter()
                .filter(|t| matches!(t, Tm::MoveCheck(..)))
                .count(),
            checks,
            "seed {seed}: move check answers"
        );
        let services: std::collections::BTreeSet<u8> = numbers.iter().map(|n| n.service).collect();
        if seed == 1 {
            eprintln!("services seen in seed 1: {services:?}");
        }
        let answered = |want: &dyn Fn(&Tm) -> bool| r.st.log.iter().filter(|t| want(t)).count();
        let pings = sent
            .iter()
            .filter(|(_, c)| matches!(c, Command::Ping))
            .count();
        let reports = sent
            .iter()
            .filter(|(_, c)| matches!(c, Command::ReportParameters(_)))
            .count();
        assert_eq!(
            answered(&|t| matches!(t, Tm::Ping)),
            pings,
            "seed {seed}: ping replies"
        );
        assert_eq!(
            answered(&|t| matches!(t, Tm::Parameters(_))),
            reports,
            "seed {seed}: parameter reports"
        );
        // 4. Bulk records not received are exactly those counted as dropped: every dump
        //    chunk and one-shot report, and the periodic reports up to the last one's.
        let dumps = sent
            .iter()
            .filter(|(_, c)| matches!(c, Command::DumpTable(_)))
            .count();
        let one_shots = sent
            .iter()
            .filter(|(_, c)| matches!(c, Command::HousekeepingOneShot))
            .count()
            + 1; // the final r.hk()
        let final_cycle = hk.cycle_counter;
        // Counted from the report before the burst: periodic reports at every multiple
        // of the period in force.
        let periodic = (hk0.cycle_counter + 1..=final_cycle)
            .filter(|c| c % hk_period as u32 == 0)
            .count();
        let chunks = answered(&|t| matches!(t, Tm::Dump(..)));
        let hks = answered(
            &|t| matches!(t, Tm::Hk(h) if h.cycle_counter > hk0.cycle_counter && h.cycle_counter <= final_cycle),
        );
        let summaries = sent
            .iter()
            .filter(|(_, c)| matches!(c, Command::Schedule(ScheduleCommand::SummaryReport)))
            .count();
        let produced = dumps * chunks_per_dump + one_shots + periodic + summaries;
        let summaries_received = answered(&|t| matches!(t, Tm::ScheduleSummary(_)));
        let dropped = hk.tm_dropped - hk0.tm_dropped;
        assert_eq!(
            chunks + hks + summaries_received + usize::from(dropped),
            produced,
            "seed {seed}: {chunks} chunks + {hks} housekeeping received, {dropped} dropped, {produced} made"
        );
        worst_dropped = worst_dropped.max(dropped);
    }
    eprintln!("most records dropped in one burst: {worst_dropped}");
}

/// ICD section 4, event 0x0011: for a refused commit, aux1 names the uploaded table only
/// when every byte was loaded since the last commit and the image decodes; bytes left in
/// the buffer from an earlier upload never name a table (it used to decode them: a
/// commit refused for missing bytes named the previous upload's table).
#[test]
fn a_refused_commit_names_the_uploaded_table_only_when_all_its_bytes_came() {
    let mut r = Bench::new();
    r.run(1);
    let t = calibrated_table(6);
    assert!(all_ok(&install(&mut r, &t, false)));
    let rejected = |r: &Bench| r.st.events(event::TABLE_REJECTED).last().copied();
    // The same table again, its last chunk not re-sent: the buffer still holds it whole.
    upload(&mut r, &t.to_bytes(), &[0, 1, 2, 3]);
    let reps = r.command(&Command::CommitTable { crc32: t.crc32() }, 10);
    assert!(matches!(
        reps[..],
        [_, Verification::StartFailure { code: 0x0705, .. }]
    ));
    assert_eq!(rejected(&r), Some([0x0705, 0]));
    // Now complete, but the commit names another CRC: the image decodes, so it is named.
    upload(&mut r, &t.to_bytes(), &[4]);
    let reps = r.command(&Command::CommitTable { crc32: 1 }, 10);
    assert!(matches!(
        reps[..],
        [_, Verification::StartFailure { code: 0x0706, .. }]
    ));
    assert_eq!(rejected(&r), Some([0x0706, 6]));
    // A complete upload that does not decode (bad magic): 0.
    let mut bytes = t.to_bytes();
    bytes[0] ^= 0xff;
    upload(&mut r, &bytes, &[0, 1, 2, 3, 4]);
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC)
        .checksum(&bytes[..m2ctl::table::layout::TABLE_CRC_OFFSET]);
    let reps = r.command(&Command::CommitTable { crc32: crc }, 10);
    assert!(
        matches!(
            reps[..],
            [_, Verification::StartFailure { code: 0x0402, .. }]
        ),
        "{reps:?}"
    );
    assert_eq!(rejected(&r), Some([0x0402, 0]));
}

/// Housekeeping's cycle counter is the control cycle its time stamp names (ICD sections
/// 6 and 10: cycle c has OBT floor(c ms)), also when a backed-up downlink sends it late:
/// the sample is taken when the report is made (the report stamped OBT 0 said cycle 1,
/// and a delayed report carried the state of the cycle it was sent in).
#[test]
fn housekeeping_carries_the_cycle_its_time_stamp_names_even_when_sent_late() {
    use m2ctl::controller::schedule::obt_of_cycle;
    use m2ctl::link::MemoryId;
    use m2ctl::sim::bench::{BenchConfig, SIM_FLASH_BYTES, UART_115200_BYTES_PER_CYCLE};
    use m2ctl::table::mock_flash::MockFlash;
    let plant = Plant::new(&PROTOTYPE, PlantConfig::default()).unwrap();
    let cfg = BenchConfig {
        uart_bytes_per_cycle: Some(UART_115200_BYTES_PER_CYCLE),
        ..BenchConfig::default()
    };
    let mut r = Bench::with(plant, MockFlash::new(SIM_FLASH_BYTES), cfg);
    r.run(995);
    // Dumps keep the downlink busy across the report of cycle 1000, and a move changes
    // the commanded strokes while it waits.
    for _ in 0..8 {
        r.queue(&Command::DumpTable(MemoryId::ActiveTable));
    }
    r.run(3);
    r.queue(&Command::MoveAbsolute(wire(20.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    let mut strokes_at = std::collections::BTreeMap::new();
    let mut arrived = None;
    for _ in 0..3_000 {
        r.tick();
        // What the controller commanded at the end of each control cycle.
        strokes_at.insert(r.ctl.cycle() - 1, r.ctl.strokes_commanded_mm());
        if arrived.is_none()
            && r.st
                .log
                .iter()
                .any(|t| matches!(t, Tm::Hk(h) if h.cycle_counter == 1000))
        {
            arrived = Some(r.ctl.cycle() - 1);
        }
    }
    let hks: Vec<(usize, m2ctl::link::Housekeeping)> =
        r.st.log
            .iter()
            .enumerate()
            .filter_map(|(i, t)| match t {
                Tm::Hk(h) => Some((i, *h)),
                _ => None,
            })
            .collect();
    assert_eq!(hks.first().map(|(_, h)| h.cycle_counter), Some(0));
    assert_eq!(r.st.log_times[hks[0].0].to_ticks(), 0);
    for (i, h) in &hks {
        assert_eq!(
            r.st.log_times[*i],
            obt_of_cycle(h.cycle_counter),
            "report {i}: stamped {:?}, says cycle {}",
            r.st.log_times[*i],
            h.cycle_counter
        );
    }
    // The report of cycle 1000 arrived well after it was made, while the move had
    // changed the strokes, and carries the state of cycle 1000.
    let (_, h) = hks.iter().find(|(_, h)| h.cycle_counter == 1000).unwrap();
    let arrived = arrived.unwrap();
    let nm = |c: u32| strokes_at[&c].map(m2ctl::link::wire::mm_to_nm_f32);
    assert!(
        arrived > 1050,
        "sent behind the dumps: arrived after cycle {arrived}"
    );
    assert_ne!(
        nm(arrived),
        nm(1000),
        "the move changed the strokes meanwhile"
    );
    assert_eq!(h.strokes_commanded_nm, nm(1000));
}
