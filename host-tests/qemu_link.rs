//! The flight image in QEMU (mps2-an386), driven over its UART like a ground station:
//! ping, housekeeping, a table upload with commit and activation, a move, and a
//! malformed packet. Needs the firmware built and QEMU installed, so it is `#[ignore]`d
//! in the plain test run; `scripts/qemu-link-test.sh` (and CI) runs it.
#![allow(clippy::needless_range_loop)] // index loops over six legs/axes read clearer here

mod common;

use std::time::{Duration, Instant};

use common::qemu::{Link, Qemu, OK3};
use m2ctl::controller::{event, State};
use m2ctl::link::command::WirePose;
use m2ctl::link::tm::{dump_chunks, Verification};
use m2ctl::link::{Command, TableChunk};
use m2ctl::station::Tm;
use m2ctl::table::Table;
use m2ctl::units::{NM_PER_UM, UAS_PER_ARCSEC_I32};

/// A UART at 115,200 baud, 8N1, carries 11.52 bytes per millisecond.
const UART_BYTES_PER_MS: usize = 11;

/// A host stall of the QEMU process: 5 x the watchdog's 200 ms from last feed to reset
/// (`board::mps2_an386::WATCHDOG_TIMEOUT_CYCLES`, twice).
const HOST_STALL: Duration = Duration::from_millis(1000);
/// The flight image's stack budget (issue 9, docs/budgets.md "Firmware figures"): the painted
/// peak over each path stays within it (the STACK region is 12 KiB: the rest is margin).
const STACK_BUDGET_BYTES: u32 = 8 * 1024;

/// Prints the flight image's painted stack peak so far (`path`: what ran) and asserts
/// it is within [`STACK_BUDGET_BYTES`].
fn assert_stack_within_budget(l: &Link, path: &str) {
    let (stack_bottom, stack_top) = common::qemu::stack_region();
    let peak = l.q.stack_peak_bytes(stack_bottom, stack_top);
    println!(
        "STACK flight image peak_bytes={peak} of {} ({path})",
        stack_top - stack_bottom
    );
    assert!(
        peak <= STACK_BUDGET_BYTES,
        "stack peak {peak} bytes over the {STACK_BUDGET_BYTES}-byte budget"
    );
}

#[test]
#[ignore = "needs QEMU and the firmware image: scripts/qemu-link-test.sh"]
fn firmware_in_qemu_answers_telecommands() {
    let t = Duration::from_secs(20);
    // Boot event, then ping.
    let mut l = Link::booted(Qemu::start(), t);
    let rid = l.send(&Command::Ping);
    assert_eq!(l.complete(rid, t), OK3);
    assert_ping_answered(&l, rid);

    // Housekeeping: nominal table, idle.
    let hk = l.housekeeping(t);
    assert_eq!((hk.state, hk.active_table_id), (State::Idle.code(), 0));

    // A malformed packet (bad CRC) is refused with the link's code.
    l.assert_bad_crc_refused(t);

    // A TC burst: eight telecommands in one write, every one answered in order.
    let burst = [
        Command::Ping,
        Command::HousekeepingOneShot,
        Command::Ping,
        Command::Ping,
        Command::HousekeepingOneShot,
        Command::Ping,
        Command::Ping,
        Command::HousekeepingOneShot,
    ];
    let mut bytes = Vec::new();
    let mut rids = Vec::new();
    for c in &burst {
        let (frame, rid) = l.st.frame(c).unwrap();
        bytes.extend_from_slice(&frame);
        rids.push(rid);
    }
    l.q.send(&bytes);
    for (c, rid) in burst.iter().zip(&rids) {
        assert_eq!(l.complete(*rid, t), OK3, "burst TC {rid:?}");
        // Each answered by its own reply, not by a neighbour's.
        match c {
            Command::Ping => assert_ping_answered(&l, *rid),
            _ => assert!(
                l.st.hk_answer(*rid).is_some(),
                "burst TC {rid:?}: no report"
            ),
        }
    }
    println!(
        "TC burst: {} TCs in one {}-byte write, all answered",
        burst.len(),
        bytes.len()
    );

    // Upload a calibrated table paced from the ground side at 115,200 baud (11 bytes
    // per millisecond of host time; QEMU's UART has no baud timing of its own, and the
    // guest's clock, which skips its idle time, sees at most that rate), commit,
    // activate.
    let mut table = Table::nominal();
    table.table_id = 77;
    table.legs[0].a_mm[0] += 0.02;
    let bytes = table.to_bytes();
    let mut upload = Vec::new();
    let mut rids = Vec::new();
    for (off, chunk) in dump_chunks(&bytes) {
        let (frame, rid) =
            l.st.frame(&Command::LoadTableChunk(
                TableChunk::new(off, chunk).unwrap(),
            ))
            .unwrap();
        upload.extend_from_slice(&frame);
        rids.push(rid);
    }
    let t_up = Instant::now();
    for piece in upload.chunks(UART_BYTES_PER_MS) {
        l.q.send(piece);
        std::thread::sleep(Duration::from_millis(1));
    }
    for (i, rid) in rids.iter().enumerate() {
        assert_eq!(l.complete(*rid, t), OK3, "chunk {i}");
    }
    println!(
        "upload: {} bytes paced at {UART_BYTES_PER_MS} bytes/ms, all {} chunks accepted in {:.2} s",
        upload.len(),
        rids.len(),
        t_up.elapsed().as_secs_f64()
    );
    let rid = l.send(&Command::CommitTable {
        crc32: table.crc32(),
    });
    // The host does not schedule QEMU for longer than the watchdog's whole window
    // (NMI, then reset: 2 x 10 control periods) while the commit runs: guest time
    // must not see it (no reboot, checked below with the activation).
    l.q.stall_host(HOST_STALL);
    assert_eq!(l.complete(rid, t), OK3);
    let rid = l.send(&Command::ActivateTable {
        table_id: table.table_id,
        crc32: table.crc32(),
    });
    let reps = l.complete(rid, t);
    assert_eq!(
        l.st.events(event::BOOT).len(),
        1,
        "the firmware rebooted: boot detail {:?}",
        l.st.events(event::BOOT_DETAIL)
    );
    assert_eq!(reps, OK3);

    // A 50 um move: completion on arrival, then housekeeping shows the new table.
    let target = WirePose {
        translation_nm: [50_000, 0, 0],
        rotation_uas: [0, 0, 0],
    };
    let rid = l.send(&Command::MoveAbsolute(target));
    assert_eq!(l.complete(rid, Duration::from_secs(60)), OK3);
    let hk = l.housekeeping(t);
    assert_eq!(hk.active_table_id, 77);
    assert_eq!(hk.active_table_crc32, table.crc32());
    assert!(
        (hk.pose_commanded.translation_nm[0] - 50_000).abs() <= 1,
        "{hk:?}"
    );
    assert!(
        (hk.pose_fk.translation_nm[0] - 50_000).abs() < 200,
        "{hk:?}"
    );
    assert_eq!(l.st.bad_frames, 0);
    println!(
        "QEMU link: {} TM packets received, all parsed",
        l.st.log.len()
    );
    // The stack the flight image used on this whole path (boot, TC burst, upload,
    // background commit with flash writes, activation, scrubs, housekeeping, a move).
    assert_stack_within_budget(&l, "memory.x STACK");
}

/// The ping `rid` was answered: a TM[17,2] among the packets its execution made
/// (`Station::answer`), not any ping reply received so far.
fn assert_ping_answered(l: &Link, rid: m2ctl::link::RequestId) {
    let answer =
        l.st.answer(rid)
            .expect("ping: acceptance and start reports");
    assert!(
        answer.iter().any(|(_, tm)| **tm == Tm::Ping),
        "ping {rid:?}: no TM[17,2] in its answer {answer:?}"
    );
}

/// Fails if the firmware rebooted (more than one boot event), naming the phase.
fn assert_one_boot(l: &Link, phase: &str) {
    assert_eq!(
        l.st.events(event::BOOT).len(),
        1,
        "the firmware rebooted during {phase}: boot detail (flags, cause | count << 16) {:?}",
        l.st.events(event::BOOT_DETAIL)
    );
}

/// Seconds of an on-board time.
fn secs(t: m2ctl::link::tm::TmTime) -> f64 {
    t.to_ticks() as f64 / m2ctl::link::tm::TIME_FRACTIONS_PER_SECOND as f64
}

/// The answer (TM[20,2]) to a parameter report telecommand.
fn report_parameters(l: &mut Link, ids: &[u16], t: Duration) -> Vec<(u16, i32)> {
    let rid = l.send(&Command::ReportParameters(
        m2ctl::link::command::ParameterIds::new(ids).unwrap(),
    ));
    assert_eq!(l.complete(rid, t), OK3);
    // This request's TM[20,2] (made when it was executed), not the latest received.
    l.st.answer(rid)
        .expect("TC[20,1]: acceptance and start reports")
        .iter()
        .find_map(|(_, tm)| match tm {
            Tm::Parameters(v) => Some(v.clone()),
            _ => None,
        })
        .expect("TM[20,2]")
}

/// Issue 13's operations scenario on the flight image: set a pivot (and the
/// housekeeping period) by ST[20], check moves without moving, schedule three rotations
/// about the pivot by ST[11] in one insert, let them release, see the mirror turn about
/// the pivot, read the parameters back. Prints the timeline.
///
/// QEMU's guest runs on its own clock (`-icount`, `sleep=off`) and runs ahead of the
/// host whenever the host does not read (a loaded machine): every report checked here
/// is selected by request ID and time stamp, never as the latest one received. To
/// make that race certain rather than occasional, the station reads the telemetry of
/// all three scheduled moves before it checks the first.
#[test]
#[ignore = "needs QEMU and the firmware image: scripts/qemu-link-test.sh"]
fn operations_in_qemu_pivot_check_schedule_parameters() {
    use m2ctl::controller::schedule::obt_of_cycle;
    use m2ctl::link::command::ParameterValues;
    use m2ctl::link::tm::TmTime;
    const PIVOT_X: u16 = 0x0001;
    const PIVOT_Y: u16 = 0x0002;
    const PIVOT_Z: u16 = 0x0003;
    const HK_PERIOD: u16 = 0x0020;
    /// The housekeeping period set below (cycles, ms).
    const HK_PERIOD_CYCLES: i32 = 500;
    /// The mirror vertex 250 mm above M's origin (nm).
    const PIVOT_Z_NM: i32 = 250_000_000;
    /// Seconds of guest time from the guest's clock (at most the newest packet time
    /// plus one housekeeping period, QEMU stopped) to the first scheduled release:
    /// what the guest may run on after QEMU continues before the insert reaches it.
    const RELEASE_MARGIN_S: f64 = 2.5;
    let t = Duration::from_secs(20);
    let mut l = Link::booted(Qemu::start(), t);

    // 1. The pivot and a 0.5 s housekeeping period, persisted, then applied.
    let rid = l.send(&Command::SetParameters(
        ParameterValues::new(&[(PIVOT_Z, PIVOT_Z_NM), (HK_PERIOD, HK_PERIOD_CYCLES)]).unwrap(),
    ));
    assert_eq!(l.complete(rid, t), OK3);
    assert_eq!(l.st.events(event::PARAMETERS_CHANGED).len(), 1);
    let set_at =
        l.st.report_time(rid, Verification::CompletionSuccess)
            .unwrap();
    println!(
        "OPS t={:7.3} s  pivot z = 250 mm, HK period 500 cycles: set, persisted, applied",
        secs(set_at)
    );
    // Applied before the completion report: the first housekeeping made after it
    // (a later time stamp) shows the pivot.
    let set_i =
        l.st.report_index(rid, Verification::CompletionSuccess)
            .unwrap();
    let (hk_at, hk) = l.hk_after(set_i, t);
    assert_eq!(
        hk.pivot_nm,
        [0, 0, PIVOT_Z_NM],
        "housekeeping at {:.3} s, after the set's completion at {:.3} s",
        secs(hk_at),
        secs(set_at)
    );
    assert_one_boot(&l, "the parameter set");

    // 2. Move checks: nothing moves, the answers are the move's.
    for (target, want) in [
        (WirePose::from_array([0, 0, 0, 100_000_000, 0, 0]), 0),
        (WirePose::from_array([0, 0, 0, 700_000_000, 0, 0]), 0x0604),
    ] {
        let rid = l.send(&Command::CheckMove(target));
        assert_eq!(l.complete(rid, t), OK3);
        let check =
            l.st.log
                .iter()
                .find_map(|tm| match tm {
                    Tm::MoveCheck(r, c) if *r == rid => Some(*c),
                    _ => None,
                })
                .expect("TM[8,130]");
        assert_eq!(check.code, want, "{check:?}");
        println!(
            "OPS            check move rx = {}\": code {:#06x}, target refusal bits {:#010x}",
            target.rotation_uas[0] / UAS_PER_ARCSEC_I32,
            check.code,
            check.target_refusals
        );
        assert_one_boot(&l, "a move check");
    }

    // 3. Three rotations about the pivot, one TC[11,4], 3 s apart. The release times
    // are chosen with QEMU stopped: its guest clock stands still, at least the newest
    // packet time received and less than that plus one housekeeping period; the first
    // release is RELEASE_MARGIN_S after that. Should the guest still run past it before
    // the insert reaches it (refused 0x0B02, nothing inserted), the refusal's own time
    // stamp is the next lower bound of its clock.
    let poses = [
        [0, 0, 0, 100_000_000, 0, 0],
        [0, 0, 0, 100_000_000, -80_000_000, 0],
        [0, 0, 0, 100_000_000, -80_000_000, 60_000_000],
    ];
    let mut attempts = 0;
    let (acts, ids, now) = loop {
        attempts += 1;
        let stopped = l.stop_and_drain();
        let now = secs(*l.st.log_times.iter().max().unwrap());
        let first = now + f64::from(HK_PERIOD_CYCLES) / 1000.0 + RELEASE_MARGIN_S;
        let acts: Vec<_> = poses
            .iter()
            .enumerate()
            .map(|(k, p)| {
                (
                    m2ctl::station::obt_from_seconds(first + 3.0 * k as f64).unwrap(),
                    Command::MoveAbsolute(WirePose::from_array(*p)),
                )
            })
            .collect();
        let (insert, ids) = l.st.schedule_insert(&acts).unwrap();
        let rid = l.send(&insert);
        drop(stopped);
        let reps = l.complete(rid, t);
        if reps == OK3 {
            break (acts, ids, now);
        }
        assert!(
            attempts < 3
                && matches!(
                    reps[..],
                    [
                        Verification::AcceptanceSuccess,
                        Verification::StartFailure { code: 0x0B02, .. }
                    ]
                ),
            "schedule insert (attempt {attempts}): {reps:?}"
        );
        println!(
            "OPS            insert refused 0x0B02 (executed at {:.3} s, after the first release {first:.3} s): again",
            secs(l.st.report_time(rid, Verification::AcceptanceSuccess).unwrap())
        );
    };
    let due: Vec<TmTime> = acts.iter().map(|(t, _)| *t).collect();
    println!(
        "OPS t={now:7.3} s  three moves scheduled at {:.3}, {:.3}, {:.3} s",
        secs(due[0]),
        secs(due[1]),
        secs(due[2])
    );
    let rid = l.send(&Command::Schedule(
        m2ctl::link::schedule::ScheduleCommand::SummaryReport,
    ));
    assert_eq!(l.complete(rid, t), OK3);
    // Listed: the activities not yet released when this request's summary was made
    // (normally all three), in release order.
    let listed: Vec<_> =
        l.st.answer(rid)
            .expect("TC[11,17]: acceptance and start reports")
            .iter()
            .find_map(|(_, tm)| match tm {
                Tm::ScheduleSummary(s) => Some(s.iter().map(|e| e.request_id).collect::<Vec<_>>()),
                _ => None,
            })
            .expect("TM[11,13]");
    assert!(!listed.is_empty(), "no activity listed");
    assert_eq!(listed, ids[ids.len() - listed.len()..]);
    assert_one_boot(&l, "the schedule insert");

    // 4. Each released at its time, completed, the mirror turned about the pivot. The
    // station takes in all three moves' telemetry first.
    assert!(
        l.until(Duration::from_secs(60), |s| s.finished(ids[2])),
        "the third activity did not finish"
    );
    for (k, id) in ids.iter().enumerate() {
        let reps = l.complete(*id, Duration::from_secs(30));
        assert_one_boot(&l, &format!("activity {k}"));
        assert_eq!(reps, OK3, "activity {k}");
        let released_at =
            l.st.report_time(*id, Verification::AcceptanceSuccess)
                .unwrap();
        let (released, arrived) = (
            secs(released_at),
            secs(
                l.st.report_time(*id, Verification::CompletionSuccess)
                    .unwrap(),
            ),
        );
        assert!(
            released >= secs(due[k]) && released < secs(due[k]) + 0.002,
            "activity {k}: released {released} s, due {} s",
            secs(due[k])
        );
        // The first housekeeping made after arrival k (time stamp later than its
        // completion report) and, sampled as well as stamped, before the release of
        // k + 1: the pivot has not moved (operator translation ~ 0), M's origin has
        // (about |c| x angle).
        let arrived_i =
            l.st.report_index(*id, Verification::CompletionSuccess)
                .unwrap();
        let (hk_at, hk) = l.hk_after(arrived_i, t);
        if let Some(next) = ids.get(k + 1) {
            let next_release =
                l.st.report_time(*next, Verification::AcceptanceSuccess)
                    .unwrap();
            assert!(
                hk_at < next_release && obt_of_cycle(hk.cycle_counter) < next_release,
                "activity {k}: no housekeeping between arrival {arrived:.3} s and the next release {:.3} s (first after arrival: stamped {:.3} s, sampled at cycle {})",
                secs(next_release),
                secs(hk_at),
                hk.cycle_counter
            );
        }
        let op = hk.pose_fk_operator.to_array();
        let origin = hk.pose_fk.to_array();
        let pivot_um = op[..3].iter().map(|v| v.abs()).max().unwrap() as f64 / NM_PER_UM;
        let origin_um = origin[..3].iter().map(|v| v.abs()).max().unwrap() as f64 / NM_PER_UM;
        // At rest the commanded pose is FK of the held strokes: the target to 1 mas.
        let cmd = hk.pose_commanded_operator.to_array();
        for (got, want) in cmd[3..].iter().zip(&poses[k][3..]) {
            assert!(
                (got - want).abs() <= 1_000,
                "activity {k}: housekeeping at {:.3} s: {cmd:?}",
                secs(hk_at)
            );
        }
        assert!(
            pivot_um < 0.5,
            "activity {k}: the pivot moved {pivot_um} um"
        );
        assert!(
            origin_um > 50.0,
            "activity {k}: M's origin moved only {origin_um} um"
        );
        println!(
            "OPS t={released:7.3} s  move {} released (due {:.3} s), arrived {arrived:.3} s: rx/ry/rz = {}/{}/{}\" in housekeeping at {:.3} s, pivot moved {pivot_um:.3} um (FK of the encoders, 0.1 um counts), M's origin {origin_um:.1} um",
            k + 1,
            secs(due[k]),
            poses[k][3] / UAS_PER_ARCSEC_I32,
            poses[k][4] / UAS_PER_ARCSEC_I32,
            poses[k][5] / UAS_PER_ARCSEC_I32,
            secs(hk_at),
        );
    }
    assert_eq!(l.st.events(event::ACTIVITY_RELEASED).len(), 3);
    assert!(l.st.events(event::ACTIVITY_FAILED).is_empty());

    // 5. Read the parameters back.
    let back = report_parameters(&mut l, &[PIVOT_X, PIVOT_Y, PIVOT_Z, HK_PERIOD], t);
    assert_eq!(
        back,
        vec![
            (PIVOT_X, 0),
            (PIVOT_Y, 0),
            (PIVOT_Z, PIVOT_Z_NM),
            (HK_PERIOD, HK_PERIOD_CYCLES)
        ]
    );
    println!("OPS            parameters read back: {back:?}");
    let boots: Vec<f64> =
        l.st.log
            .iter()
            .zip(&l.st.log_times)
            .filter(|(m, _)| matches!(m, Tm::Event(_, id, _) if *id == event::BOOT))
            .map(|(_, t)| secs(*t))
            .collect();
    assert_eq!(
        boots.len(),
        1,
        "the firmware rebooted: boot events at {boots:?} s (of the boot count), detail {:?}",
        l.st.events(event::BOOT_DETAIL)
    );
    assert_eq!(l.st.bad_frames, 0);
    // The stack on this path (boot, parameters, move checks, scheduled moves released).
    assert_stack_within_budget(&l, "operations: move checks, scheduled moves");
}

/// The kinds of telecommand in the bursts, and what each makes besides its three
/// verification reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum BurstTc {
    /// TC[6,5], memory ID 2: the running table as TM[6,6] chunks.
    Dump,
    /// TC[3,27]: one TM[3,25].
    Hk,
    /// TC[17,1]: one TM[17,2].
    Ping,
    /// TC[20,1] with this many parameter IDs: one TM[20,2].
    Params(usize),
}

/// The firmware's UART receive queue (bytes, `RX_QUEUE_LEN` of src/main.rs): a burst
/// is one write that fits in it with room to spare, so the uplink loses nothing (the
/// link takes 4 telecommands per control cycle, QEMU delivers as fast as the guest
/// reads).
const BURST_MAX_BYTES: usize = 900;

/// Issue 18: the link's counters, exact under load. Bursts of telecommands in one
/// write (sixteen table dumps; seeded random mixes of dumps, one-shot housekeeping,
/// pings and parameter reports, ack flags 0xF) keep the TX queue full for many link
/// passes: a pass queues at most the TX queue's 2 KB of frames (the UART task drains
/// them after the pass), a burst makes ~80 (16 dumps) to ~110 (a mix) dump chunks of
/// ~155 bytes each besides its reports, four telecommands a pass.
/// Then, from the ground (ICD sections 1 and 2):
/// 1. every TM packet's sequence count is the previous one's + 1 (mod 16384), the
///    first after boot 0;
/// 2. per service the message type counters run 0, 1, 2, ... with no gap;
/// 3. every telecommand's acceptance, start and completion reports arrived;
/// 4. every record the controller made before the final housekeeping report either
///    arrived or is counted in that report's `tm_dropped` (offset 141), per kind.
#[test]
#[ignore = "needs QEMU and the firmware image: scripts/qemu-link-test.sh"]
fn burst_telemetry_counters_gapless_and_every_record_accounted() {
    use common::TestRng;
    use m2ctl::controller::params::PARAMETERS;
    use m2ctl::link::command::{ParameterIds, MAX_PARAMETERS_PER_TC, TABLE_CHUNK_MAX_LEN};
    use m2ctl::link::tm::TmTime;
    use m2ctl::link::MemoryId;
    use m2ctl::table::TABLE_LEN;
    const SEQ_MOD: u32 = 16384;
    // A burst drains in well under a second of host time; when its marker's reports
    // are lost (the defect this test is for) the wait ends here.
    const DRAIN_TIMEOUT: Duration = Duration::from_secs(8);
    let chunks_per_dump = TABLE_LEN.div_ceil(TABLE_CHUNK_MAX_LEN);
    let t = Duration::from_secs(20);
    let t0 = Instant::now();
    let mut l = Link::booted(Qemu::start(), t);

    // The bursts: sixteen dumps, then four seeded mixes.
    let mut bursts: Vec<(String, Vec<BurstTc>)> =
        vec![("16 x TC[6,5]".to_string(), vec![BurstTc::Dump; 16])];
    for seed in [0x5eed_0001u64, 0x5eed_0002, 0x5eed_0003, 0x5eed_0004] {
        let mut rng = TestRng(seed);
        let mut mix = Vec::new();
        while mix.len() < 48 {
            let r = rng.bits() % 20;
            mix.push(match r {
                0..=9 => BurstTc::Dump,
                10..=12 => BurstTc::Hk,
                13..=15 => BurstTc::Ping,
                _ => BurstTc::Params(1 + (rng.bits() % MAX_PARAMETERS_PER_TC as u64) as usize),
            });
        }
        bursts.push((format!("mix seed {seed:#x}"), mix));
    }

    let command = |k: BurstTc| match k {
        BurstTc::Dump => Command::DumpTable(MemoryId::ActiveTable),
        BurstTc::Hk => Command::HousekeepingOneShot,
        BurstTc::Ping => Command::Ping,
        BurstTc::Params(n) => Command::ReportParameters(
            ParameterIds::new(&PARAMETERS.iter().take(n).map(|p| p.id).collect::<Vec<_>>())
                .unwrap(),
        ),
    };
    // Every telecommand sent, in order: (burst, kind, request ID).
    let mut sent: Vec<(usize, BurstTc, m2ctl::link::RequestId)> = Vec::new();
    for (b, (name, kinds)) in bursts.iter().enumerate() {
        let mut bytes = Vec::new();
        let mut rids = Vec::new();
        for &k in kinds {
            let (frame, rid) = l.st.frame(&command(k)).unwrap();
            if bytes.len() + frame.len() > BURST_MAX_BYTES {
                break;
            }
            bytes.extend_from_slice(&frame);
            rids.push(rid);
            sent.push((b, k, rid));
        }
        l.q.send(&bytes);
        // A ping in its own write after the burst: executed after every telecommand of
        // the burst (the uplink is in order), so once its completion is here each of
        // theirs has arrived or never will. Waited for on telemetry, the wall clock
        // only an upper bound.
        let marker = l.send(&Command::Ping);
        sent.push((b, BurstTc::Ping, marker));
        let drained = l.until(DRAIN_TIMEOUT, |s| {
            s.finished(marker) || rids.iter().all(|r| s.finished(*r))
        });
        let reports: usize = rids
            .iter()
            .chain([&marker])
            .map(|r| l.st.reports(*r).len())
            .sum();
        println!(
            "BURST {name}: {} TCs in one {}-byte write, then a ping: {reports} of their {} reports received; drained: {drained}",
            rids.len(),
            bytes.len(),
            3 * (rids.len() + 1)
        );
    }
    // Quiet link: the accounting report, this request's own housekeeping.
    let rid = l.send(&Command::HousekeepingOneShot);
    assert_eq!(l.complete(rid, t), OK3, "the final housekeeping request");
    let h_i =
        l.st.answer_indices(rid)
            .and_then(|a| a.into_iter().find(|i| matches!(l.st.log[*i], Tm::Hk(_))))
            .expect("the final housekeeping request's report");
    let h = l.st.hk_answer(rid).unwrap();
    let h_at: TmTime = l.st.log_times[h_i];
    let mut failures: Vec<String> = Vec::new();

    // 1. Sequence count: 0 after boot, +1 per packet.
    let headers = &l.st.log_headers;
    if headers.first().map(|h| h.seq_count) != Some(0) {
        failures.push(format!(
            "(1) first packet after boot has sequence count {:?}, not 0",
            headers.first().map(|h| h.seq_count)
        ));
    }
    let seq_gaps: Vec<String> = headers
        .windows(2)
        .enumerate()
        .filter(|(_, w)| u32::from(w[1].seq_count) != (u32::from(w[0].seq_count) + 1) % SEQ_MOD)
        .map(|(i, w)| {
            format!(
                "packet {}: {} -> {} (TM[{},{}] after TM[{},{}])",
                i + 1,
                w[0].seq_count,
                w[1].seq_count,
                w[1].service,
                w[1].subtype,
                w[0].service,
                w[0].subtype
            )
        })
        .collect();
    if !seq_gaps.is_empty() {
        failures.push(format!(
            "(1) sequence count not +1 at {} of {} packets: {seq_gaps:?}",
            seq_gaps.len(),
            headers.len()
        ));
    }
    // 2. Per service: message type counters from 0, +1 per packet of the service.
    let mut services: Vec<u8> = headers.iter().map(|h| h.service).collect();
    services.sort_unstable();
    services.dedup();
    for svc in services {
        let counters: Vec<u16> = headers
            .iter()
            .filter(|h| h.service == svc)
            .map(|h| h.msg_counter)
            .collect();
        let mut gaps: Vec<String> = Vec::new();
        if counters[0] != 0 {
            gaps.push(format!("first {}", counters[0]));
        }
        gaps.extend(
            counters
                .windows(2)
                .filter(|w| w[1] != w[0].wrapping_add(1))
                .map(|w| format!("{} -> {}", w[0], w[1])),
        );
        if !gaps.is_empty() {
            failures.push(format!(
                "(2) service {svc}: message type counter not contiguous over {} packets: {gaps:?}",
                counters.len()
            ));
        }
    }
    // 3. Every telecommand's three reports.
    let mut incomplete = Vec::new();
    for (b, k, rid) in &sent {
        let reps = l.st.reports(*rid);
        if reps != OK3 {
            incomplete.push(format!("{} {k:?} {rid:?}: {reps:?}", bursts[*b].0));
        }
    }
    if !incomplete.is_empty() {
        failures.push(format!(
            "(3) {} of {} telecommands without their acceptance, start and completion reports: {incomplete:?}",
            incomplete.len(),
            sent.len()
        ));
    }
    // 4. Records made before the final report (pushed before it: the queue is in
    // order) against those received before it, per kind; the difference is what that
    // report counts as dropped. Periodic housekeeping: every whole second of OBT
    // before the report's (at 1 Hz from cycle 0; one stamped with the report's own
    // cycle is queued after it). Events are not predicted: those received are counted
    // as made.
    let mut made = [0i64; 6];
    let mut got = [0i64; 6];
    const KINDS: [&str; 6] = [
        "TM[1,x]", "TM[6,6]", "TM[3,25]", "TM[17,2]", "TM[20,2]", "other",
    ];
    for (_, k, _) in &sent {
        made[0] += 3;
        match k {
            BurstTc::Dump => made[1] += chunks_per_dump as i64,
            BurstTc::Hk => made[2] += 1,
            BurstTc::Ping => made[3] += 1,
            BurstTc::Params(_) => made[4] += 1,
        }
    }
    made[0] += 1; // the final request's acceptance
    made[2] += (0u32..)
        .take_while(|s| {
            TmTime {
                seconds: *s,
                fraction: 0,
            } < h_at
        })
        .count() as i64;
    let mut events = 0;
    for m in &l.st.log[..h_i] {
        let kind = match m {
            Tm::Verify(..) => 0,
            Tm::Dump(..) => 1,
            Tm::Hk(_) => 2,
            Tm::Ping => 3,
            Tm::Parameters(_) => 4,
            Tm::Event(..) => {
                events += 1;
                continue;
            }
            _ => 5,
        };
        got[kind] += 1;
    }
    let missing: i64 = made.iter().zip(&got).map(|(m, g)| m - g).sum();
    let table: Vec<String> = KINDS
        .iter()
        .zip(made.iter().zip(&got))
        .map(|(n, (m, g))| format!("{n} {g}/{m}"))
        .collect();
    println!(
        "BURST accounting before the final HK (OBT {:.3} s, seq {}): received/made {table:?}, events {events}; missing {missing}, HK tm_dropped {}, tc_accepted {}, tc_rejected {}, tc_frames_dropped {}, uart_overruns {}",
        secs(h_at),
        headers[h_i].seq_count,
        h.tm_dropped,
        h.tc_accepted,
        h.tc_rejected,
        h.tc_frames_dropped,
        h.uart_overruns
    );
    if made.iter().zip(&got).any(|(m, g)| g > m) || missing != i64::from(h.tm_dropped) {
        failures.push(format!(
            "(4) received/made per kind {table:?}: {missing} records missing, tm_dropped {}",
            h.tm_dropped
        ));
    }
    // The uplink itself lost nothing (else (3) and (4) would blame the downlink).
    assert_eq!(
        (
            h.tc_frames_dropped,
            h.uart_overruns,
            usize::from(h.tc_accepted)
        ),
        (0, 0, sent.len() + 1),
        "uplink: frames dropped, UART overruns, telecommands accepted"
    );
    assert_eq!(l.st.bad_frames, 0);
    assert_one_boot(&l, "the bursts");
    println!(
        "BURST {} TCs in {} bursts, {} TM packets, {:.1} s",
        sent.len(),
        bursts.len(),
        l.st.log.len(),
        t0.elapsed().as_secs_f64()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// What a telecommand produced, as the ground sees it, without packet times and
/// sequence counts (the guest's clock and the bench's differ): its verification reports,
/// its move-check report, and the records queued with it ([`m2ctl::station::Station::answer`]:
/// dump chunks, parameter report, schedule summary, a refusal's event), periodic
/// housekeeping and time reports left out.
fn reply_of(st: &m2ctl::station::Station, rid: m2ctl::link::RequestId) -> Vec<Tm> {
    let mut v: Vec<Tm> = st
        .log
        .iter()
        .filter(|t| matches!(t, Tm::Verify(r, _) | Tm::MoveCheck(r, _) if *r == rid))
        .cloned()
        .collect();
    v.extend(
        st.answer(rid)
            .unwrap_or_default()
            .into_iter()
            .filter(|(_, t)| !matches!(t, Tm::Hk(_) | Tm::TimeReport(..)))
            .map(|(_, t)| t.clone()),
    );
    v
}

/// The scripted session of [`the_flight_image_answers_as_the_host_bench`]: each
/// telecommand is sent once the previous one has its final report. Covers every reply
/// kind but housekeeping (whose contents are the plant's): ping, dumps of the nominal and
/// an uploaded table, parameter reports and a refused set, move checks in and out of the
/// workspace, refused moves (workspace, range, direct stroke), a commit without an
/// upload, an upload with commit and activation, a move, the schedule's insert, summary
/// and reset, a refused switch to an empty bank, a revert.
fn characterisation_script(st: &mut m2ctl::station::Station) -> Vec<Command> {
    use m2ctl::link::command::{ParameterIds, ParameterValues};
    use m2ctl::link::schedule::ScheduleCommand;
    use m2ctl::link::tm::TmTime;
    use m2ctl::link::MemoryId;
    let mut table = Table::nominal();
    table.table_id = 4242;
    table.legs[2].b_mm[1] -= 0.015;
    let bytes = table.to_bytes();
    let pose = |x_nm: i32, rx_uas: i32| WirePose::from_array([x_nm, 0, 0, rx_uas, 0, 0]);
    let far = |s: u32| TmTime {
        seconds: s,
        fraction: 0,
    };
    let (insert, _) = st
        .schedule_insert(&[(far(90_000), Command::Ping), (far(80_000), Command::Stop)])
        .unwrap();
    let mut script = vec![
        Command::Ping,
        Command::DumpTable(MemoryId::ActiveTable),
        Command::ReportParameters(ParameterIds::new(&[0x0001, 0x0002, 0x0003, 0x0020]).unwrap()),
        Command::SetParameters(ParameterValues::new(&[(0x0020, 0)]).unwrap()),
        Command::CheckMove(pose(20_000, 0)),
        Command::CheckMove(pose(0, 700_000_000)),
        Command::MoveAbsolute(pose(0, 700_000_000)),
        Command::MoveRelative(pose(9_000_000, 0)),
        Command::DirectStroke {
            leg: 1,
            delta_nm: 100_000_000,
        },
        Command::CommitTable { crc32: 0xdead_beef },
    ];
    for (off, chunk) in dump_chunks(&bytes) {
        script.push(Command::LoadTableChunk(
            TableChunk::new(off, chunk).unwrap(),
        ));
    }
    script.extend([
        Command::CommitTable {
            crc32: table.crc32(),
        },
        Command::ActivateTable {
            table_id: table.table_id,
            crc32: table.crc32(),
        },
        Command::DumpTable(MemoryId::ActiveTable),
        Command::MoveAbsolute(pose(30_000, 0)),
        insert,
        Command::Schedule(ScheduleCommand::SummaryReport),
        Command::Schedule(ScheduleCommand::Reset),
        Command::SwitchBank,
        Command::RevertToNominal,
        Command::Ping,
    ]);
    script
}

/// Characterisation of the flight image against the host (issue 20): the same scripted
/// session run on the host bench (`sim::Bench`, the same controller code over the
/// simulated plant) and on the flight image in QEMU must give the ground the same reply
/// to every telecommand, packet for packet (parsed; times and sequence counts aside). The
/// host side is itself pinned byte for byte by `host-tests/characterisation.rs`'s golden
/// recording, so this pins the flight image's replies to it.
#[test]
#[ignore = "needs QEMU and the firmware image: scripts/qemu-link-test.sh"]
fn the_flight_image_answers_as_the_host_bench() {
    const BENCH_MAX_CYCLES: u32 = 60_000;
    let t = Duration::from_secs(60);

    let mut bench = m2ctl::sim::Bench::new();
    bench.run(10);
    let script = characterisation_script(&mut bench.st);
    let mut host = Vec::new();
    for cmd in &script {
        let rid = bench.send(cmd);
        for _ in 0..BENCH_MAX_CYCLES {
            if bench.st.finished(rid) {
                break;
            }
            bench.tick();
        }
        // A cycle more: a move check's report may follow its completion's cycle.
        bench.run(2);
        host.push(reply_of(&bench.st, rid));
    }

    let mut l = Link::booted(Qemu::start(), Duration::from_secs(20));
    let script_q = characterisation_script(&mut l.st);
    assert_eq!(script, script_q, "the same script on both sides");
    let mut flight = Vec::new();
    for cmd in &script_q {
        let rid = l.send(cmd);
        l.complete(rid, t);
        flight.push((rid, cmd));
    }
    // Everything the last telecommand made has arrived once its final report has.
    let flight: Vec<Vec<Tm>> = flight
        .iter()
        .map(|(rid, _)| reply_of(&l.st, *rid))
        .collect();
    let mut packets = 0;
    for (i, ((h, f), cmd)) in host.iter().zip(&flight).zip(&script).enumerate() {
        assert!(!h.is_empty(), "TC {i} ({cmd:?}): no reply on the host");
        assert_eq!(h, f, "TC {i} ({cmd:?}): host bench vs flight image in QEMU");
        packets += h.len();
    }
    println!(
        "characterisation: {} telecommands, {packets} reply packets, the flight image's equal to the host bench's",
        script.len()
    );
    assert_eq!(l.st.bad_frames, 0);
}
