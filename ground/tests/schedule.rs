//! Time-tagged telecommands (PUS ST[11]) and time reports (ST[9]) on the bench: what
//! docs/icd.md section 10 promises, each promise a test.

#![cfg(feature = "host")]

#[path = "../../host-tests/common/mod.rs"]
mod common;

use std::collections::{BTreeMap, BTreeSet};

use common::{all_ok, wire};
use m2ctl::controller::schedule::{obt_of_cycle, request_id_word, MAX_OBT};
use m2ctl::controller::{event, State};
use m2ctl::kinematics::Pose;
use m2ctl::link::command::WirePose;
use m2ctl::link::schedule::{
    ActivityBlock, ObtOffset, RequestIdList, ScheduleCommand, SummaryEntry, MAX_SCHEDULED_TC_LEN,
    SCHEDULE_CAPACITY,
};
use m2ctl::link::tc::{TcHeader, CRC16};
use m2ctl::link::time::TimeReportRate;
use m2ctl::link::tm::{TmTime, Verification, TIME_FRACTIONS_PER_SECOND};
use m2ctl::link::{
    encode_telecommand, service, subtype, Command, RequestId, TableChunk, MAX_TC_PACKET_LEN,
};
use m2ctl::sim::{Bench, InjectedFault};
use m2ctl::station::Tm;
use m2ctl::timing::CYCLE_S_F64;
use m2ctl::units::ARCSEC_PER_RAD;

/// One CUC fraction (s).
const TICK_S: f64 = 1.0 / TIME_FRACTIONS_PER_SECOND as f64;

fn obt(s: f64) -> TmTime {
    m2ground::tc::obt_from_seconds(s).unwrap()
}

fn secs(t: TmTime) -> f64 {
    t.to_ticks() as f64 * TICK_S
}

/// Runs until the next tick's link pass is the first whose OBT is at or after `t`.
fn run_until_just_before(r: &mut Bench, t: TmTime) {
    while obt_of_cycle(r.ctl.cycle() + 1) < t {
        r.tick();
    }
}

/// Sends a TC[11,4] of these activities; returns its request ID and the embedded ones.
fn insert(r: &mut Bench, activities: &[(TmTime, Command)]) -> (RequestId, Vec<RequestId>) {
    let (cmd, ids) = r.st.schedule_insert(activities).unwrap();
    (r.send(&cmd), ids)
}

fn sched(c: ScheduleCommand) -> Command {
    Command::Schedule(c)
}

/// Passes a telecommand may wait behind released activities (16 due at once, 4 a pass).
const PASSES: u32 = 8;

/// Sends a telecommand and runs until its reports are complete (it completes in the
/// pass that takes it: the next one, or a later one when due activities use the pass's
/// budget); returns its request ID, its reports and the OBT it executed at.
fn run_tc(r: &mut Bench, c: &Command) -> (RequestId, Vec<Verification>, TmTime) {
    let rid = r.send(c);
    for _ in 0..PASSES {
        if r.st.finished(rid) {
            break;
        }
        r.tick();
    }
    let at =
        r.st.report_time(rid, Verification::AcceptanceSuccess)
            .unwrap_or_default();
    (rid, r.st.reports(rid), at)
}

/// Sends a schedule TC and returns its reports.
fn command(r: &mut Bench, c: ScheduleCommand) -> Vec<Verification> {
    run_tc(r, &sched(c)).1
}

fn start_failure(v: &[Verification]) -> Option<(u16, u32)> {
    v.iter().find_map(|r| match r {
        Verification::StartFailure { code, data } => Some((*code, *data)),
        _ => None,
    })
}

fn acceptance_failure(v: &[Verification]) -> Option<(u16, u32)> {
    v.iter().find_map(|r| match r {
        Verification::AcceptanceFailure { code, data } => Some((*code, *data)),
        _ => None,
    })
}

/// The schedule as a TM[11,13] reports it now.
fn summary(r: &mut Bench) -> Vec<SummaryEntry> {
    let reps = command(r, ScheduleCommand::SummaryReport);
    assert!(all_ok(&reps), "{reps:?}");
    r.st.last_summary().expect("a TM[11,13]").to_vec()
}

fn true_pose(r: &Bench) -> Pose<f64> {
    r.plant.with(|p| p.true_pose()).unwrap()
}

/// The plant's true pose is `target` to encoder resolution (nominal geometry).
fn assert_at(r: &Bench, target: &WirePose, what: &str) {
    let truth = true_pose(r);
    let t: Pose<f64> = target.to_pose();
    for k in 0..3 {
        assert!(
            (truth.translation_mm[k] - t.translation_mm[k]).abs() < 1e-4,
            "{what}: axis {k}: {truth:?} vs {t:?}"
        );
        assert!(
            (truth.rotation_rad[k] - t.rotation_rad[k]).abs() * ARCSEC_PER_RAD < 0.02,
            "{what}: rotation {k}: {truth:?} vs {t:?}"
        );
    }
}

fn released(r: &Bench) -> Vec<u32> {
    r.st.events(event::ACTIVITY_RELEASED)
        .iter()
        .map(|a| a[0])
        .collect()
}

/// A raw TC packet with a correct length field and CRC (to build malformed ones).
fn raw_tc(service: u8, subtype: u8, app: &[u8], seq: u16, apid: u16) -> Vec<u8> {
    // Sequence counts far from the station's own (no request ID shared).
    let seq = RAW_SEQ_BASE + seq;
    let mut p = Vec::new();
    p.extend((0x1800u16 | apid).to_be_bytes());
    p.extend((0xc000u16 | seq).to_be_bytes());
    let len = (6 + 5 + app.len() + 2 - 7) as u16;
    p.extend(len.to_be_bytes());
    p.extend([0x2f, service, subtype, 0, 0]);
    p.extend(app);
    let crc = CRC16.checksum(&p);
    p.extend(crc.to_be_bytes());
    p
}

/// First sequence count of the test's hand-made packets.
const RAW_SEQ_BASE: u16 = 10_000;

fn packet(c: &Command, seq: u16) -> Vec<u8> {
    let mut buf = [0u8; MAX_TC_PACKET_LEN];
    let n = encode_telecommand(c, TcHeader::new(RAW_SEQ_BASE + seq), &mut buf).unwrap();
    buf[..n].to_vec()
}

/// TC[11,4] application data from raw parts (N, then (time, packet) pairs).
fn insert_app(n: u8, activities: &[(TmTime, Vec<u8>)]) -> Vec<u8> {
    let mut app = vec![n];
    for (t, p) in activities {
        app.extend(t.to_bytes());
        app.extend(p);
    }
    app
}

/// Sends a raw packet, returns its reports.
fn send_raw(r: &mut Bench, pkt: &[u8]) -> Vec<Verification> {
    let rid = RequestId::from_packet(pkt).unwrap();
    common::tick_packet(r, pkt);
    r.run(1);
    r.st.reports(rid)
}

#[test]
fn three_moves_are_released_at_their_times_and_the_mirror_is_where_the_schedule_says() {
    let mut r = Bench::new();
    r.run(2);
    let home = wire(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let targets = [
        wire(150.0, -80.0, 40.0, 20.0, 0.0, -10.0),
        wire(-100.0, 120.0, 0.0, 0.0, -25.0, 15.0),
        wire(30.0, 30.0, -60.0, 10.0, 10.0, 10.0),
    ];
    // Release times off the millisecond grid, in one TC[11,4], inserted out of order.
    let times = [obt(2.0 + 7.0 * TICK_S), obt(5.25), obt(8.5 + 3.0 * TICK_S)];
    let acts: Vec<(TmTime, Command)> = [2, 0, 1]
        .iter()
        .map(|&i| (times[i], Command::MoveAbsolute(targets[i])))
        .collect();
    let (ins, ids) = insert(&mut r, &acts);
    assert!(all_ok(&r.st.reports(ins)), "{:?}", r.st.reports(ins));
    let ids = [ids[1], ids[2], ids[0]];
    let hk = r.hk();
    assert_eq!(
        (hk.schedule.activities, hk.schedule.next_release),
        (3, times[0]),
        "housekeeping: three scheduled, the next at T1"
    );
    // The summary lists them in release order.
    let s = summary(&mut r);
    assert_eq!(
        s,
        (0..3)
            .map(|i| SummaryEntry {
                release: times[i],
                request_id: ids[i],
            })
            .collect::<Vec<_>>()
    );
    let mut previous = home;
    for i in 0..3 {
        run_until_just_before(&mut r, times[i]);
        // Until its time the mirror is where the previous activity left it and the
        // activity has not run.
        assert_at(&r, &previous, &format!("before activity {i}"));
        assert!(r.st.reports(ids[i]).is_empty());
        assert_eq!(r.ctl.state(), State::Idle);
        r.tick();
        // Released in the first pass at or after its time: the reports carry an OBT in
        // [T, T + 1 cycle).
        let t_acc =
            r.st.report_time(ids[i], Verification::AcceptanceSuccess)
                .unwrap_or_else(|| panic!("activity {i} not released: {:?}", r.st.log));
        let late = secs(t_acc) - secs(times[i]);
        assert!(
            (0.0..CYCLE_S_F64).contains(&late),
            "activity {i}: {late} s late"
        );
        assert_eq!(released(&r).last(), Some(&request_id_word(ids[i])));
        assert_eq!(r.ctl.state(), State::Moving);
        r.settle(2_900);
        assert!(
            all_ok(&r.st.reports(ids[i])),
            "{i}: {:?}",
            r.st.reports(ids[i])
        );
        assert_at(&r, &targets[i], &format!("after activity {i}"));
        previous = targets[i];
    }
    let hk = r.hk();
    assert_eq!(
        (
            hk.schedule.activities,
            hk.schedule.released,
            hk.schedule.failed
        ),
        (0, 3, 0)
    );
    assert!(r.st.events(event::ACTIVITY_FAILED).is_empty());
}

#[test]
fn a_full_schedule_refuses_further_inserts_and_changes_nothing() {
    let mut r = Bench::new();
    r.run(1);
    let ping = |k: usize| (obt(10.0 + k as f64), Command::Ping);
    // Fourteen activities in two inserts of seven.
    for chunk in [0..7, 7..14] {
        let (ins, _) = insert(&mut r, &chunk.map(ping).collect::<Vec<_>>());
        assert!(all_ok(&r.st.reports(ins)), "{:?}", r.st.reports(ins));
    }
    let before = summary(&mut r);
    assert_eq!(before.len(), 14);
    // Three more do not fit in two places: refused, all or nothing.
    let (ins, _) = insert(&mut r, &(14..17).map(ping).collect::<Vec<_>>());
    assert_eq!(start_failure(&r.st.reports(ins)), Some((0x0B01, 2)));
    assert_eq!(summary(&mut r), before);
    // Two fill it; the seventeenth is refused with no room left.
    let (ins, _) = insert(&mut r, &(14..16).map(ping).collect::<Vec<_>>());
    assert!(all_ok(&r.st.reports(ins)));
    let full = summary(&mut r);
    assert_eq!(full.len(), SCHEDULE_CAPACITY);
    let (ins, refused_ids) = insert(&mut r, &[ping(16)]);
    assert_eq!(start_failure(&r.st.reports(ins)), Some((0x0B01, 0)));
    assert_eq!(summary(&mut r), full);
    assert_eq!(r.hk().schedule.activities, 16);
    // Every activity releases at its time, the refused one never.
    r.run(27_000);
    assert_eq!(released(&r).len(), SCHEDULE_CAPACITY);
    assert!(r.st.reports(refused_ids[0]).is_empty());
    assert!(full.iter().all(|e| all_ok(&r.st.reports(e.request_id))));
}

#[test]
fn released_telecommands_that_fail_are_reported_under_their_own_request_id_with_an_event() {
    let mut r = Bench::new();
    r.run(1);
    // 1. Refused at release (start failure): a target outside the workspace; and a second
    //    move at the same time as a first one (released in insertion order): busy.
    let (ins, ids) = insert(
        &mut r,
        &[
            (
                obt(1.0),
                Command::MoveAbsolute(wire(9_000.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
            ),
            (
                obt(2.0),
                Command::MoveAbsolute(wire(100.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
            ),
            (
                obt(2.0),
                Command::MoveAbsolute(wire(0.0, 100.0, 0.0, 0.0, 0.0, 0.0)),
            ),
        ],
    );
    assert!(all_ok(&r.st.reports(ins)));
    r.run(2_100);
    let failed = r.st.events(event::ACTIVITY_FAILED);
    assert_eq!(
        start_failure(&r.st.reports(ids[0])).map(|f| f.0),
        Some(0x0604)
    );
    assert!(r.st.reports(ids[1]).contains(&Verification::StartSuccess));
    assert_eq!(
        start_failure(&r.st.reports(ids[2])),
        Some((0x0702, u32::from(State::Moving.code())))
    );
    assert_eq!(
        failed,
        [
            [request_id_word(ids[0]), (4 << 16) | 0x0604],
            [request_id_word(ids[2]), (4 << 16) | 0x0702],
        ]
    );
    r.settle(5_000);
    assert!(all_ok(&r.st.reports(ids[1])));
    // 2. Fails after its start (completion failure): a fault during the released move.
    let soon = obt(secs(r.ctl.obt()) + 0.5);
    let (_, ids) = insert(
        &mut r,
        &[(
            soon,
            Command::MoveAbsolute(wire(400.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        )],
    );
    r.run(1_000);
    assert_eq!(r.ctl.state(), State::Moving);
    r.plant.with(|p| {
        p.inject(InjectedFault::EncoderJump {
            leg: 2,
            jump_mm: 0.3,
        })
    });
    r.settle(5_000);
    let last = *r.st.reports(ids[0]).last().unwrap();
    let Verification::CompletionFailure { code: 0x0709, .. } = last else {
        panic!("{:?}", r.st.reports(ids[0]))
    };
    assert_eq!(
        r.st.events(event::ACTIVITY_FAILED).last(),
        Some(&[request_id_word(ids[0]), (8 << 16) | 0x0709])
    );
    let hk = r.hk();
    assert_eq!((hk.schedule.released, hk.schedule.failed), (4, 3));
    // 3. A successful released move reports no failure event.
    assert_eq!(r.st.events(event::ACTIVITY_FAILED).len(), 3);
}

#[test]
fn delete_and_time_shift_are_all_or_nothing_and_summaries_follow_them() {
    let mut r = Bench::new();
    r.run(1);
    // Equal release times keep their insertion order.
    let (ins, ids) = insert(
        &mut r,
        &[
            (obt(3.0), Command::Ping),
            (obt(2.0), Command::HousekeepingOneShot),
            (obt(3.0), Command::Stop),
        ],
    );
    assert!(all_ok(&r.st.reports(ins)));
    let order: Vec<RequestId> = summary(&mut r).iter().map(|e| e.request_id).collect();
    assert_eq!(order, [ids[1], ids[0], ids[2]]);
    // Deletes naming an unknown ID, or an ID twice, change nothing.
    let unknown = RequestId {
        packet_id: ids[0].packet_id,
        sequence_control: ids[0].sequence_control ^ 0x0100,
    };
    let before = summary(&mut r);
    for (list, index) in [
        (vec![ids[0], unknown], 1),
        (vec![ids[0], ids[0]], 1),
        (vec![unknown], 0),
    ] {
        let reps = command(
            &mut r,
            ScheduleCommand::Delete(RequestIdList::new(&list).unwrap()),
        );
        assert_eq!(start_failure(&reps), Some((0x0B04, index)), "{list:?}");
        assert_eq!(summary(&mut r), before);
    }
    let reps = command(
        &mut r,
        ScheduleCommand::Delete(RequestIdList::new(&[ids[0]]).unwrap()),
    );
    assert!(all_ok(&reps));
    let s = summary(&mut r);
    assert_eq!(
        s.iter().map(|e| e.request_id).collect::<Vec<_>>(),
        [ids[1], ids[2]]
    );
    // A shift that would put an activity in the past is refused; a valid one moves
    // every release time by exactly the offset.
    let back = ObtOffset::from_parts(-2, 0);
    let reps = command(&mut r, ScheduleCommand::TimeShiftAll(back));
    assert_eq!(
        start_failure(&reps),
        Some((0x0B05, request_id_word(ids[1])))
    );
    assert_eq!(summary(&mut r), s);
    let shift = ObtOffset::from_parts(1, 0x8000); // +1.5 s
    assert!(all_ok(&command(
        &mut r,
        ScheduleCommand::TimeShiftAll(shift)
    )));
    let shifted = summary(&mut r);
    for (a, b) in s.iter().zip(&shifted) {
        assert_eq!(b.release.to_ticks(), a.release.to_ticks() + 0x1_8000);
        assert_eq!(a.request_id, b.request_id);
    }
    let back = ObtOffset::from_parts(-1, 0xc000); // -0.25 s
    assert!(all_ok(&command(
        &mut r,
        ScheduleCommand::TimeShiftAll(back)
    )));
    // Each releases at its shifted time (3.25 s and 4.25 s), not at its original one.
    run_until_just_before(&mut r, obt(3.25));
    assert!(r.st.reports(ids[1]).is_empty());
    r.tick();
    assert!(all_ok(&r.st.reports(ids[1])));
    run_until_just_before(&mut r, obt(4.25));
    assert!(r.st.reports(ids[2]).is_empty());
    r.tick();
    assert!(all_ok(&r.st.reports(ids[2])));
    assert!(
        r.st.reports(ids[0]).is_empty(),
        "the deleted one never runs"
    );
    assert!(summary(&mut r).is_empty());
}

#[test]
fn disabled_release_keeps_activities_and_enabling_deletes_those_whose_time_passed() {
    let mut r = Bench::new();
    r.run(1);
    let (_, ids) = insert(
        &mut r,
        &[(obt(1.0), Command::Ping), (obt(3.0), Command::Ping)],
    );
    assert!(all_ok(&command(&mut r, ScheduleCommand::DisableRelease)));
    assert!(!r.hk().schedule.release_enabled);
    r.run(2_000);
    // Nothing ran; both are still scheduled (the first one overdue).
    assert!(r.st.reports(ids[0]).is_empty());
    assert_eq!(summary(&mut r).len(), 2);
    // Enabling deletes the overdue one (never run), and the other runs at its time.
    assert!(all_ok(&command(&mut r, ScheduleCommand::EnableRelease)));
    assert_eq!(
        r.st.events(event::ACTIVITY_EXPIRED),
        [[request_id_word(ids[0]), 1]]
    );
    assert_eq!(
        summary(&mut r)
            .iter()
            .map(|e| e.request_id)
            .collect::<Vec<_>>(),
        [ids[1]]
    );
    run_until_just_before(&mut r, obt(3.0));
    assert!(r.st.reports(ids[1]).is_empty());
    r.tick();
    assert!(all_ok(&r.st.reports(ids[1])));
    r.run(1_000);
    assert!(r.st.reports(ids[0]).is_empty());
    assert!(r.hk().schedule.release_enabled);
}

#[test]
fn reset_deletes_every_activity_and_leaves_release_disabled() {
    let mut r = Bench::new();
    r.run(1);
    let (_, ids) = insert(
        &mut r,
        &[(obt(1.0), Command::Ping), (obt(1.5), Command::Stop)],
    );
    assert!(all_ok(&command(&mut r, ScheduleCommand::Reset)));
    let hk = r.hk();
    assert_eq!(
        (hk.schedule.activities, hk.schedule.release_enabled),
        (0, false)
    );
    assert!(summary(&mut r).is_empty());
    // Inserted after the reset: nothing runs until release is enabled again.
    let (_, later) = insert(&mut r, &[(obt(2.0), Command::Ping)]);
    r.run(1_500);
    assert!(ids
        .iter()
        .chain(&later)
        .all(|id| r.st.reports(*id).is_empty()));
    assert!(all_ok(&command(&mut r, ScheduleCommand::EnableRelease)));
    run_until_just_before(&mut r, obt(2.0));
    r.tick();
    assert!(all_ok(&r.st.reports(later[0])));
    assert!(ids.iter().all(|id| r.st.reports(*id).is_empty()));
}

#[test]
fn a_controller_reset_empties_the_schedule_release_enabled_time_reports_off() {
    let mut r = Bench::new();
    r.run(1);
    let t = obt(3.0);
    let (_, ids) = insert(
        &mut r,
        &[(
            t,
            Command::MoveAbsolute(wire(300.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        )],
    );
    assert!(all_ok(&command(&mut r, ScheduleCommand::DisableRelease)));
    assert!(all_ok(&r.command(
        &Command::SetTimeReportRate(TimeReportRate::Every { exponent: 0 }),
        2
    )));
    let hk = r.hk();
    assert_eq!(
        (
            hk.schedule.activities,
            hk.schedule.release_enabled,
            hk.schedule.time_report_rate
        ),
        (1, false, 0)
    );
    let before = true_pose(&r);
    let mut r = r.reboot();
    r.run(2);
    let hk = r.hk();
    assert_eq!(
        (
            hk.schedule.activities,
            hk.schedule.release_enabled,
            hk.schedule.time_report_rate
        ),
        (0, true, 0xFF),
        "after a reset: empty, release enabled, time reports off"
    );
    assert_eq!(hk.schedule.next_release, TmTime::default());
    let reports_before =
        r.st.log
            .iter()
            .filter(|t| matches!(t, Tm::TimeReport(..)))
            .count();
    r.run(4_000);
    assert!(r.st.reports(ids[0]).is_empty(), "the move never runs");
    let after = true_pose(&r);
    assert!((after.translation_mm[0] - before.translation_mm[0]).abs() < 1e-6);
    assert_eq!(
        r.st.log
            .iter()
            .filter(|t| matches!(t, Tm::TimeReport(..)))
            .count(),
        reports_before
    );
}

#[test]
fn malformed_inserts_are_refused_with_their_codes_and_change_nothing() {
    let mut r = Bench::new();
    r.run(1);
    let apid = m2ctl::link::M2_APID;
    let ping = packet(&Command::Ping, 100);
    let t = obt(5.0);
    let mut bad_crc = ping.clone();
    *bad_crc.last_mut().unwrap() ^= 1;
    let nested = packet(&sched(ScheduleCommand::SummaryReport), 101);
    let other_apid = raw_tc(service::TEST, subtype::PING, &[], 102, 0x0B3);
    let unknown_fn = raw_tc(
        service::FUNCTION,
        subtype::PERFORM_FUNCTION,
        &[0x77, 0x77],
        103,
        apid,
    );
    let chunk = packet(
        &Command::LoadTableChunk(TableChunk::new(0, &[0u8; 60]).unwrap()),
        104,
    );
    assert!(chunk.len() > MAX_SCHEDULED_TC_LEN);
    // A 4-byte chunk: a 22-byte TC[6,2], well within a slot.
    let small_chunk = packet(
        &Command::LoadTableChunk(TableChunk::new(0, b"M2TB").unwrap()),
        105,
    );
    assert_eq!(small_chunk.len(), 22);
    let mut cut = ping.clone();
    cut.truncate(10);
    let ins = |app: &[u8], seq: u16| {
        raw_tc(
            service::SCHEDULING,
            subtype::SCHEDULE_INSERT,
            app,
            seq,
            apid,
        )
    };
    let cases: Vec<(&str, Vec<u8>, (u16, u32))> = vec![
        ("N = 0", ins(&[0], 1), (0x050D, 0)),
        ("no N", ins(&[], 2), (0x050C, 1)),
        (
            "N = 2, one activity",
            ins(&insert_app(2, &[(t, ping.clone())]), 3),
            (0x050C, (20 << 16) | 26),
        ),
        (
            "trailing byte",
            ins(&[insert_app(1, &[(t, ping.clone())]), vec![0]].concat(), 4),
            (0x050C, (21 << 16) | 20),
        ),
        (
            "bad CRC inside",
            ins(&insert_app(1, &[(t, bad_crc)]), 5),
            (0x050F, 0x0505),
        ),
        (
            "TC[11,x] inside: cannot be scheduled",
            ins(&insert_app(1, &[(t, nested)]), 6),
            (0x050F, 0x0510),
        ),
        (
            "a table chunk that fits a slot: cannot be scheduled",
            ins(&insert_app(1, &[(t, small_chunk.clone())]), 13),
            (0x050F, 0x0510),
        ),
        (
            "a table chunk after a valid activity",
            ins(&insert_app(2, &[(t, ping.clone()), (t, small_chunk)]), 14),
            (0x050F, (1 << 16) | 0x0510),
        ),
        (
            "other APID inside",
            ins(&insert_app(1, &[(t, other_apid)]), 7),
            (0x050F, 0x0506),
        ),
        (
            "unknown function inside",
            ins(&insert_app(1, &[(t, unknown_fn.clone())]), 8),
            (0x050F, 0x050B),
        ),
        (
            "longer than a slot",
            ins(&insert_app(1, &[(t, chunk)]), 9),
            (0x050F, 0x0503),
        ),
        (
            "cut short",
            ins(&insert_app(1, &[(t, cut)]), 10),
            (0x050F, 0x0501),
        ),
        (
            "second activity bad",
            ins(&insert_app(2, &[(t, ping.clone()), (t, unknown_fn)]), 11),
            (0x050F, (1 << 16) | 0x050B),
        ),
        (
            "too long",
            ins(&insert_app(9, &vec![(t, ping.clone()); 9]), 12),
            (0x050C, (172 << 16) | 160),
        ),
    ];
    for (what, pkt, want) in &cases {
        let reps = send_raw(&mut r, pkt);
        assert_eq!(acceptance_failure(&reps), Some(*want), "{what}: {reps:?}");
    }
    // Refused when they execute (start failure): a time in the past, beyond the clock,
    // a request ID repeated in the TC or already scheduled.
    let now = r.ctl.obt();
    let past = now.checked_offset(-1).unwrap();
    let ping2 = packet(&Command::Ping, 200);
    let start_cases: Vec<(&str, Vec<u8>, (u16, u32))> = vec![
        (
            "in the past",
            ins(
                &insert_app(2, &[(t, ping2.clone()), (past, ping.clone())]),
                20,
            ),
            (0x0B02, 1),
        ),
        (
            "beyond the clock",
            ins(
                &insert_app(1, &[(MAX_OBT.checked_offset(1).unwrap(), ping.clone())]),
                21,
            ),
            (0x0B06, 0),
        ),
        (
            "twice in the TC",
            ins(&insert_app(2, &[(t, ping.clone()), (t, ping.clone())]), 22),
            (0x0B03, 1),
        ),
    ];
    for (what, pkt, want) in &start_cases {
        let reps = send_raw(&mut r, pkt);
        assert_eq!(start_failure(&reps), Some(*want), "{what}: {reps:?}");
    }
    assert!(summary(&mut r).is_empty(), "nothing was inserted");
    let ok = ins(&insert_app(1, &[(t, ping.clone())]), 30);
    assert!(all_ok(&send_raw(&mut r, &ok)));
    let again = ins(&insert_app(1, &[(t, ping.clone())]), 31);
    assert_eq!(start_failure(&send_raw(&mut r, &again)), Some((0x0B03, 0)));
    assert_eq!(summary(&mut r).len(), 1);
    // The release time may be now (it runs in the next pass) and up to the clock's end.
    let edge = ins(
        &insert_app(
            2,
            &[
                (r.ctl.obt().checked_offset(66).unwrap(), ping2),
                (MAX_OBT, packet(&Command::Stop, 201)),
            ],
        ),
        32,
    );
    let reps = send_raw(&mut r, &edge);
    assert!(all_ok(&reps), "{reps:?}");
    // Malformed deletes, shifts and time-report rates: acceptance failures.
    for (what, pkt, want) in [
        (
            "delete N = 0",
            raw_tc(
                service::SCHEDULING,
                subtype::SCHEDULE_DELETE,
                &[0],
                40,
                apid,
            ),
            (0x050D, 0),
        ),
        (
            "delete N = 17",
            raw_tc(
                service::SCHEDULING,
                subtype::SCHEDULE_DELETE,
                &[17],
                41,
                apid,
            ),
            (0x050D, 0),
        ),
        (
            "delete short",
            raw_tc(
                service::SCHEDULING,
                subtype::SCHEDULE_DELETE,
                &[1, 0x18, 0xb2],
                42,
                apid,
            ),
            (0x050C, (3 << 16) | 5),
        ),
        (
            "shift short",
            raw_tc(
                service::SCHEDULING,
                subtype::SCHEDULE_TIME_SHIFT_ALL,
                &[0; 5],
                43,
                apid,
            ),
            (0x050C, (5 << 16) | 6),
        ),
        (
            "enable with data",
            raw_tc(
                service::SCHEDULING,
                subtype::SCHEDULE_ENABLE,
                &[1],
                44,
                apid,
            ),
            (0x050C, 1 << 16),
        ),
        (
            "unknown subtype",
            raw_tc(service::SCHEDULING, 6, &[], 45, apid),
            (0x050A, (11 << 16) | 6),
        ),
        (
            "rate 9",
            raw_tc(service::TIME, subtype::SET_TIME_REPORT_RATE, &[9], 46, apid),
            (0x050D, 0),
        ),
    ] {
        let reps = send_raw(&mut r, &pkt);
        assert_eq!(acceptance_failure(&reps), Some(want), "{what}: {reps:?}");
    }
    // The one at 5 s and the one at the clock's end (the other ran).
    assert_eq!(summary(&mut r).len(), 2);
}

#[test]
fn releases_share_the_four_telecommands_of_a_cycle_and_go_first() {
    let mut r = Bench::new();
    r.run(1);
    let t = obt(1.0);
    let (_, ids) = insert(&mut r, &vec![(t, Command::Ping); 6]);
    run_until_just_before(&mut r, t);
    let accepted = r.ctl.housekeeping().tc_accepted;
    // A ground telecommand arriving in the same cycle waits for the released ones.
    let ping = r.queue(&Command::Ping);
    r.tick();
    let ran = |r: &Bench| {
        ids.iter()
            .filter(|id| !r.st.reports(**id).is_empty())
            .count()
    };
    assert_eq!(ran(&r), 4);
    assert!(r.st.reports(ping).is_empty());
    let first =
        r.st.report_time(ids[0], Verification::AcceptanceSuccess)
            .unwrap();
    r.tick();
    assert_eq!(ran(&r), 6);
    let last =
        r.st.report_time(ids[5], Verification::AcceptanceSuccess)
            .unwrap();
    assert!((secs(last) - secs(first) - CYCLE_S_F64).abs() < 2.0 * TICK_S);
    assert!(all_ok(&r.st.reports(ping)), "then the uplink's");
    assert_eq!(
        r.ctl.housekeeping().tc_accepted,
        accepted + 7,
        "released telecommands count as accepted ones"
    );
    // In insertion order.
    assert_eq!(
        released(&r),
        ids.iter().map(|i| request_id_word(*i)).collect::<Vec<_>>()
    );
}

#[test]
fn a_release_time_equal_to_now_is_accepted_and_runs_in_the_next_pass() {
    let mut r = Bench::new();
    r.run(3);
    // The insert executes in the next pass, at this OBT.
    let now = obt_of_cycle(r.ctl.cycle() + 1);
    let (ins, ids) = insert(&mut r, &[(now, Command::Ping)]);
    assert_eq!(
        r.st.report_time(ins, Verification::AcceptanceSuccess),
        Some(now)
    );
    assert!(all_ok(&r.st.reports(ins)));
    assert!(r.st.reports(ids[0]).is_empty());
    r.tick();
    assert!(all_ok(&r.st.reports(ids[0])));
    assert_eq!(
        r.st.report_time(ids[0], Verification::AcceptanceSuccess),
        Some(obt_of_cycle(r.ctl.cycle()))
    );
}

#[test]
fn time_reports_and_summaries_yield_to_reports_and_events_in_the_queue() {
    use m2ctl::controller::TmRecord;
    assert!(TmRecord::TimeReport {
        rate: TimeReportRate::Every { exponent: 0 }
    }
    .is_bulk());
    assert!(TmRecord::ScheduleSummary(Default::default()).is_bulk());
}

#[test]
fn time_reports_come_at_the_obt_multiples_of_their_period_with_their_own_time() {
    let mut r = Bench::new();
    r.run(1);
    assert!(
        r.st.log.iter().all(|t| !matches!(t, Tm::TimeReport(..))),
        "off at boot"
    );
    for exponent in [0u8, 1] {
        let from = r.st.log.len();
        let (rid, reps, at) = run_tc(
            &mut r,
            &Command::SetTimeReportRate(TimeReportRate::Every { exponent }),
        );
        assert!(all_ok(&reps));
        let _ = rid;
        assert_eq!(r.hk().schedule.time_report_rate, exponent);
        r.run(6_500);
        let period = 1u32 << exponent;
        let reports: Vec<(TmTime, TimeReportRate, TmTime)> = r.st.log[from..]
            .iter()
            .zip(&r.st.log_times[from..])
            .filter_map(|(t, time)| match t {
                Tm::TimeReport(rate, obt) => Some((*time, *rate, *obt)),
                _ => None,
            })
            .collect();
        assert!(reports.len() >= (6 / period) as usize, "{reports:?}");
        // The first at the first multiple of the period after the TC, then one a period.
        assert_eq!(reports[0].2.seconds, (at.seconds / period + 1) * period);
        for w in reports.windows(2) {
            assert_eq!(w[1].2.seconds - w[0].2.seconds, period);
        }
        for (time, rate, obt) in &reports {
            assert_eq!(*rate, TimeReportRate::Every { exponent });
            assert_eq!(obt, time, "the OBT field is the packet's time");
            assert_eq!((obt.fraction, obt.seconds % period), (0, 0));
        }
    }
    let reps = r.command(&Command::SetTimeReportRate(TimeReportRate::Off), 2);
    assert!(all_ok(&reps));
    let n = r.st.log.len();
    r.run(3_000);
    assert!(r.st.log[n..]
        .iter()
        .all(|t| !matches!(t, Tm::TimeReport(..))));
}

#[test]
fn the_summary_report_and_the_time_report_are_read_back_by_the_mission_database() {
    use m2ctl::link::tm::TmWriter;
    use m2ground::mdb::{mdb, TM_SOURCE_DATA_OFFSET};
    let m = mdb();
    let entries: Vec<SummaryEntry> = (0..3u16)
        .map(|k| SummaryEntry {
            release: TmTime {
                seconds: 1000 + u32::from(k),
                fraction: 0x1234 * k,
            },
            request_id: RequestId {
                packet_id: 0x18b2,
                sequence_control: 0xc000 | (7 + k),
            },
        })
        .collect();
    let mut w = TmWriter::new();
    let mut frame = [0u8; 300];
    let n = w
        .emit_schedule_summary(TmTime::default(), &entries, &mut frame)
        .unwrap();
    let pkt = m2ctl::link::Deframer::<300>::new();
    let mut d = pkt;
    let p = frame[..n]
        .iter()
        .find_map(|b| d.push_byte(*b).map(|r| r.unwrap().to_vec()))
        .unwrap();
    let data = &p[TM_SOURCE_DATA_OFFSET..p.len() - 2];
    let desc = m.tm_packet("schedule_summary").unwrap();
    let count = desc.fields[0].read_raw(data).unwrap();
    assert_eq!(count, 3);
    let rep = desc.repeated.as_ref().unwrap();
    assert_eq!(rep.element_len, 10);
    for (k, e) in entries.iter().enumerate() {
        let el = &data[rep.offset + k * rep.element_len..];
        let v: BTreeMap<&str, i64> = rep
            .fields
            .iter()
            .map(|f| (f.name.as_str(), f.read_raw(el).unwrap()))
            .collect();
        assert_eq!(v["activity_release_seconds"], i64::from(e.release.seconds));
        assert_eq!(
            v["activity_release_fraction"],
            i64::from(e.release.fraction)
        );
        assert_eq!(
            v["activity_tc_packet_id"],
            i64::from(e.request_id.packet_id)
        );
        assert_eq!(
            v["activity_tc_sequence_control"],
            i64::from(e.request_id.sequence_control)
        );
    }
    let n = w
        .emit_time_report(
            TmTime {
                seconds: 64,
                fraction: 0,
            },
            TimeReportRate::Every { exponent: 6 },
            &mut frame,
        )
        .unwrap();
    let mut d = m2ctl::link::Deframer::<300>::new();
    let p = frame[..n]
        .iter()
        .find_map(|b| d.push_byte(*b).map(|r| r.unwrap().to_vec()))
        .unwrap();
    let data = &p[TM_SOURCE_DATA_OFFSET..p.len() - 2];
    let desc = m.tm_packet("cuc_time_report").unwrap();
    assert_eq!(desc.fixed_len, Some(data.len()));
    let v: BTreeMap<&str, i64> = desc
        .fields
        .iter()
        .map(|f| (f.name.as_str(), f.read_raw(data).unwrap()))
        .collect();
    assert_eq!(
        (
            v["cuc_report_rate"],
            v["cuc_report_obt_seconds"],
            v["cuc_report_obt_fraction"]
        ),
        (6, 64, 0)
    );
}

#[test]
fn the_ground_tool_numbers_the_embedded_telecommand_first_and_the_controller_takes_it() {
    let exe = env!("CARGO_BIN_EXE_m2ground");
    let out = std::process::Command::new(exe)
        .args([
            "tc",
            "--seq",
            "40",
            "--unframed",
            "schedule",
            "at=1.25",
            "move-absolute",
            "x=120",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let frames = m2ground::tc::parse_hex_lines(&String::from_utf8_lossy(&out.stdout)).unwrap();
    assert_eq!(frames.len(), 1);
    let tc = m2ctl::link::decode_telecommand(&frames[0]).unwrap();
    assert_eq!(tc.request_id.seq_count(), 41);
    let Command::Schedule(ScheduleCommand::Insert(block)) = tc.command else {
        panic!("{:?}", tc.command)
    };
    let a: Vec<_> = block.activities().collect();
    assert_eq!(a.len(), 1);
    assert_eq!(a[0].release, obt(1.25));
    let inner = m2ctl::link::decode_telecommand(a[0].packet).unwrap();
    assert_eq!(inner.request_id.seq_count(), 40);
    assert_eq!(
        inner.command,
        Command::MoveAbsolute(wire(120.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    );
    // On the bench: released at 1.25 s, the mirror goes there.
    let mut r = Bench::new();
    r.run(1);
    common::tick_packet(&mut r, &frames[0]);
    assert!(all_ok(&r.st.reports(tc.request_id)));
    run_until_just_before(&mut r, obt(1.25));
    r.tick();
    r.settle(3_000);
    assert!(all_ok(&r.st.reports(inner.request_id)));
    assert_at(
        &r,
        &wire(120.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        "released by the ground tool's TC",
    );
    // Delete by sequence count, time reports, nesting refused.
    for (args, check) in [
        (
            vec![
                "schedule-delete-activity",
                "activity_packet_id=0x18b2",
                "activity_sequence_control=0xc028",
            ],
            Command::Schedule(ScheduleCommand::Delete(
                RequestIdList::new(&[inner.request_id]).unwrap(),
            )),
        ),
        (
            vec![
                "schedule-time-shift-all",
                "shift_seconds=-1",
                "shift_fraction=0.5",
            ],
            sched(ScheduleCommand::TimeShiftAll(ObtOffset::from_parts(
                -1, 0x8000,
            ))),
        ),
        (
            vec!["set-time-report-rate", "rate=EVERY_8_S"],
            Command::SetTimeReportRate(TimeReportRate::Every { exponent: 3 }),
        ),
        (
            vec!["set-time-report-rate", "rate=off"],
            Command::SetTimeReportRate(TimeReportRate::Off),
        ),
        (
            vec!["schedule-summary-report"],
            sched(ScheduleCommand::SummaryReport),
        ),
        (vec!["schedule-reset"], sched(ScheduleCommand::Reset)),
        (
            vec!["schedule-enable-release"],
            sched(ScheduleCommand::EnableRelease),
        ),
    ] {
        let out = std::process::Command::new(exe)
            .args(["tc", "--unframed"])
            .args(&args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let f = m2ground::tc::parse_hex_lines(&String::from_utf8_lossy(&out.stdout)).unwrap();
        assert_eq!(
            m2ctl::link::decode_telecommand(&f[0]).unwrap().command,
            check,
            "{args:?}"
        );
    }
    let out = std::process::Command::new(exe)
        .args(["tc", "schedule", "at=-1", "ping"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not an on-board time"));
}

/// The decoded forms stay small: `Command` is copied on the link service's stack, the
/// schedule is static RAM of the controller (figures printed).
#[test]
fn ram_of_the_schedule_and_the_command() {
    let cmd = std::mem::size_of::<Command>();
    let schedule = std::mem::size_of::<m2ctl::controller::schedule::Schedule>();
    let activity = std::mem::size_of::<m2ctl::controller::schedule::Activity>();
    let block = std::mem::size_of::<ActivityBlock>();
    let summary = std::mem::size_of::<m2ctl::controller::schedule::ScheduleSummary>();
    let hk = std::mem::size_of::<m2ctl::link::Housekeeping>();
    let times = std::mem::size_of::<m2ctl::controller::time::TimeReports>();
    println!(
        "Command {cmd} B (ActivityBlock {block} B), Schedule {schedule} B ({SCHEDULE_CAPACITY} x Activity {activity} B), TimeReports {times} B, summary copy {summary} B (housekeeping sample {hk} B)"
    );
    assert!(cmd <= 176, "Command {cmd} B");
    assert!(schedule <= SCHEDULE_CAPACITY * (MAX_SCHEDULED_TC_LEN + 24) + 32);
}

// ---------------------------------------------------------------------------------
// The property: no sequence of schedule telecommands panics, releases an activity
// twice, releases one that was not (or no longer) scheduled, or releases it early; and
// the summary and housekeeping always agree with a model of the schedule.

use proptest::prelude::*;

#[derive(Clone, Debug)]
enum Op {
    /// Insert activities at now + these offsets (ms; negative = in the past).
    Insert(Vec<(i32, u8)>),
    /// Delete: indices into the IDs inserted so far (modulo), or a random ID.
    Delete(Vec<u16>),
    Shift(i32),
    Enable,
    Disable,
    Reset,
    Summary,
    Run(u16),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => prop::collection::vec((-20i32..1_200, 0u8..5), 1..4).prop_map(Op::Insert),
        1 => prop::collection::vec(any::<u16>(), 1..4).prop_map(Op::Delete),
        1 => (-1_500i32..1_500).prop_map(Op::Shift),
        2 => Just(Op::Enable),
        2 => Just(Op::Disable),
        1 => Just(Op::Reset),
        2 => Just(Op::Summary),
        4 => (0u16..1_500).prop_map(Op::Run),
    ]
}

fn activity_command(kind: u8) -> Command {
    match kind {
        0 => Command::Ping,
        1 => Command::HousekeepingOneShot,
        2 => Command::Stop,
        3 => Command::MoveRelative(wire(20.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        _ => Command::MoveAbsolute(wire(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
    }
}

/// The model: request ID -> release time of what is scheduled.
type Model = BTreeMap<RequestId, TmTime>;

fn check_releases(r: &Bench, model: &mut Model, seen: &mut usize, ever: &mut BTreeSet<u32>) {
    let log = &r.st.log;
    for (tm, &time) in log.iter().zip(&r.st.log_times).skip(*seen) {
        let Tm::Event(_, id, aux) = *tm else {
            continue;
        };
        let found = model
            .iter()
            .find(|(rid, _)| request_id_word(**rid) == aux[0])
            .map(|(r, t)| (*r, *t));
        match id {
            event::ACTIVITY_RELEASED => {
                let (rid, t) = found
                    .unwrap_or_else(|| panic!("released {:#x}, not scheduled: {model:?}", aux[0]));
                assert!(time >= t, "released at {time:?} before its time {t:?}");
                assert!(ever.insert(aux[0]), "released twice: {:#x}", aux[0]);
                model.remove(&rid);
            }
            event::ACTIVITY_EXPIRED => {
                let (rid, t) =
                    found.unwrap_or_else(|| panic!("expired {:#x}, not scheduled", aux[0]));
                assert!(t < time);
                model.remove(&rid);
            }
            _ => {}
        }
    }
    *seen = log.len();
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]
    #[test]
    fn no_sequence_of_schedule_telecommands_panics_or_releases_twice(ops in prop::collection::vec(op(), 1..24)) {
        let mut r = Bench::new();
        r.run(1);
        let mut model: Model = BTreeMap::new();
        let mut inserted: Vec<RequestId> = Vec::new();
        let mut seen = 0usize;
        let mut ever = BTreeSet::new();
        let mut enabled = true;
        for op in ops {
            // The schedule TC executes in the next tick's link pass (or a later one if
            // released activities take the pass's budget), after that pass's releases.
            let next = obt_of_cycle(r.ctl.cycle() + 1);
            match op {
                Op::Insert(acts) => {
                    let acts: Vec<(TmTime, Command)> = acts
                        .iter()
                        .map(|(dt, k)| {
                            let t = next.checked_offset(i64::from(*dt) * 66).unwrap_or_default();
                            (t, activity_command(*k))
                        })
                        .collect();
                    let (cmd, ids) = r.st.schedule_insert(&acts).unwrap();
                    let (_, reps, now) = run_tc(&mut r, &cmd);
                    check_releases(&r, &mut model, &mut seen, &mut ever);
                    if all_ok(&reps) {
                        for (id, (t, _)) in ids.iter().zip(&acts) {
                            model.insert(*id, *t);
                        }
                    } else {
                        let fits = model.len() + acts.len() <= SCHEDULE_CAPACITY;
                        let past = acts.iter().any(|(t, _)| *t < now);
                        prop_assert!(!fits || past, "refused {reps:?} though it fits and is not past");
                    }
                    inserted.extend(ids);
                }
                Op::Delete(picks) => {
                    let ids: Vec<RequestId> = picks
                        .iter()
                        .map(|p| if inserted.is_empty() || *p == u16::MAX { RequestId::default() } else { inserted[usize::from(*p) % inserted.len()] })
                        .collect();
                    let (_, reps, _) = run_tc(&mut r, &sched(ScheduleCommand::Delete(RequestIdList::new(&ids).unwrap())));
                    check_releases(&r, &mut model, &mut seen, &mut ever);
                    let distinct: BTreeSet<_> = ids.iter().collect();
                    let ok = distinct.len() == ids.len() && ids.iter().all(|i| model.contains_key(i));
                    prop_assert_eq!(all_ok(&reps), ok, "{:?}", reps);
                    if ok {
                        for i in &ids {
                            model.remove(i);
                        }
                    }
                }
                Op::Shift(ms) => {
                    let off = ObtOffset::from_ticks(i64::from(ms) * 66).unwrap();
                    let (_, reps, now) = run_tc(&mut r, &sched(ScheduleCommand::TimeShiftAll(off)));
                    check_releases(&r, &mut model, &mut seen, &mut ever);
                    let ok = model.values().all(|t| t.checked_offset(off.ticks()).is_some_and(|s| s >= now));
                    prop_assert_eq!(all_ok(&reps), ok, "{:?}", reps);
                    if ok {
                        for t in model.values_mut() {
                            *t = t.checked_offset(off.ticks()).unwrap();
                        }
                    }
                }
                Op::Enable => {
                    prop_assert!(all_ok(&command(&mut r, ScheduleCommand::EnableRelease)));
                    enabled = true;
                    check_releases(&r, &mut model, &mut seen, &mut ever);
                }
                Op::Disable => {
                    prop_assert!(all_ok(&command(&mut r, ScheduleCommand::DisableRelease)));
                    enabled = false;
                }
                Op::Reset => {
                    prop_assert!(all_ok(&command(&mut r, ScheduleCommand::Reset)));
                    check_releases(&r, &mut model, &mut seen, &mut ever);
                    model.clear();
                    enabled = false;
                }
                Op::Summary => {
                    let s = summary(&mut r);
                    check_releases(&r, &mut model, &mut seen, &mut ever);
                    let got: BTreeMap<RequestId, TmTime> = s.iter().map(|e| (e.request_id, e.release)).collect();
                    prop_assert_eq!(&got, &model);
                    prop_assert!(s.windows(2).all(|w| w[0].release <= w[1].release), "release order");
                }
                Op::Run(n) => r.run(u32::from(n)),
            }
            check_releases(&r, &mut model, &mut seen, &mut ever);
            let hk = r.ctl.housekeeping();
            prop_assert_eq!(usize::from(hk.schedule.activities), model.len());
            prop_assert_eq!(hk.schedule.release_enabled, enabled);
            // With release enabled nothing stays overdue beyond a few cycles.
            if enabled {
                let late = obt_of_cycle(r.ctl.cycle()).checked_offset(-66 * 5).unwrap_or_default();
                prop_assert!(model.values().all(|t| *t >= late), "overdue while enabled: {:?}", model);
            }
        }
        // At the end, everything still scheduled releases (or expires) as the model says.
        prop_assert!(all_ok(&command(&mut r, ScheduleCommand::EnableRelease)));
        check_releases(&r, &mut model, &mut seen, &mut ever);
        let last = model.values().max().copied().unwrap_or_default();
        run_until_just_before(&mut r, last);
        r.run(5);
        check_releases(&r, &mut model, &mut seen, &mut ever);
        prop_assert!(model.is_empty(), "left over: {:?}", model);
        prop_assert!(summary(&mut r).is_empty());
        if std::env::var("SCHED_STATS").is_ok() {
            eprintln!(
                "inserted {} released {} expired {} failed {} left {}",
                inserted.len(),
                ever.len(),
                r.st.events(event::ACTIVITY_EXPIRED).len(),
                r.st.events(event::ACTIVITY_FAILED).len(),
                model.len()
            );
        }
        // No released telecommand ran twice: at most one acceptance report per ID.
        for id in &inserted {
            let n = r.st.reports(*id).iter().filter(|v| matches!(v, Verification::AcceptanceSuccess)).count();
            prop_assert!(n <= 1, "{id:?} accepted {n} times");
        }
    }
}

/// Issue 18, item 3: a refused time shift (0x0B05) names the first activity **in
/// release order** that would leave the clock's range (before now or beyond 2^32
/// cycles), whatever the order they were inserted in. With activities due at +3700 s
/// (inserted first), +3650 s and +3800 s, a shift of -7200 s named the +3800 s one.
#[test]
fn a_refused_time_shift_names_the_first_activity_in_release_order_that_leaves_the_range() {
    let mut r = Bench::new();
    r.run(1);
    let now = secs(r.ctl.obt());
    let (a, first) = insert(&mut r, &[(obt(now + 3700.0), Command::Ping)]);
    assert!(all_ok(&r.st.reports(a)));
    let (b, rest) = insert(
        &mut r,
        &[
            (obt(now + 3650.0), Command::Ping),
            (obt(now + 3800.0), Command::HousekeepingOneShot),
        ],
    );
    assert!(all_ok(&r.st.reports(b)));
    let (at_3700, at_3650, at_3800) = (first[0], rest[0], rest[1]);
    let before = summary(&mut r);
    let max_obt_s = secs(m2ctl::controller::schedule::MAX_OBT);
    for (offset, named, why) in [
        (ObtOffset::from_parts(-7200, 0), at_3650, "all before now"),
        (
            ObtOffset::from_parts(i32::MAX, 0),
            at_3650,
            "all beyond the clock",
        ),
        (
            ObtOffset::from_parts(-3675, 0),
            at_3650,
            "only the earliest before now",
        ),
        (ObtOffset::from_parts(-3720, 0), at_3650, "two before now"),
        (
            ObtOffset::from_parts((max_obt_s - now - 3750.0) as i32, 0),
            at_3800,
            "only the latest beyond the clock",
        ),
        (
            ObtOffset::from_parts((max_obt_s - now - 3680.0) as i32, 0),
            at_3700,
            "the later two beyond the clock",
        ),
    ] {
        let reps = command(&mut r, ScheduleCommand::TimeShiftAll(offset));
        assert_eq!(
            start_failure(&reps),
            Some((0x0B05, request_id_word(named))),
            "{why}: {reps:?}"
        );
        assert_eq!(summary(&mut r), before, "{why}: nothing moved");
    }
}

/// Issue 18, item 2, the other side of the rule: every telecommand of this controller
/// but ST[11] itself and a table chunk TC[6,2] can be scheduled, and runs at release as
/// a received one.
#[test]
fn every_telecommand_but_st11_and_table_chunks_can_be_scheduled() {
    use m2ctl::link::command::{ParameterIds, ParameterValues};
    use m2ctl::link::MemoryId;
    let mut r = Bench::new();
    r.run(1);
    let base = secs(r.ctl.obt()) + 1.0;
    let schedulable = [
        Command::Ping,
        Command::HousekeepingOneShot,
        Command::DumpTable(MemoryId::ActiveTable),
        Command::ReportParameters(ParameterIds::new(&[0x0010]).unwrap()),
        Command::SetParameters(ParameterValues::new(&[(0x0010, 150_000)]).unwrap()),
        Command::SetTimeReportRate(TimeReportRate::Every { exponent: 3 }),
        Command::CheckMove(wire(5.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        Command::MoveAbsolute(wire(5.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        Command::Stop,
        Command::ClearFault,
    ];
    let mut ids = Vec::new();
    for (k, cmd) in schedulable.iter().enumerate() {
        // One second apart: each finishes before the next is released.
        let (ins, embedded) = insert(&mut r, &[(obt(base + k as f64), *cmd)]);
        assert!(
            all_ok(&r.st.reports(ins)),
            "{cmd:?}: {:?}",
            r.st.reports(ins)
        );
        ids.push(embedded[0]);
    }
    r.run(1_000 * schedulable.len() as u32 + 2_000);
    for (cmd, id) in schedulable.iter().zip(&ids) {
        assert!(
            all_ok(&r.st.reports(*id)),
            "{cmd:?} at release: {:?}",
            r.st.reports(*id)
        );
    }
    let released = r.st.events(event::ACTIVITY_RELEASED);
    assert_eq!(released.len(), schedulable.len());
}

#[test]
fn an_exposure_hold_holds_every_release_until_it_ends_then_they_run_in_order() {
    let mut r = Bench::new();
    r.run(1);
    let target = wire(20.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let (_, ids) = insert(
        &mut r,
        &[
            (obt(1.0), Command::MoveAbsolute(target)),
            (obt(1.5), Command::Ping),
        ],
    );
    // A 3 s hold from about 0.01 s: both release times pass during it.
    let (_, reps, at) = run_tc(&mut r, &Command::ExposureHold { timeout_s: 3 });
    assert!(all_ok(&reps), "{reps:?}");
    let hold_end = secs(at) + 3.0;
    run_until_just_before(&mut r, obt(hold_end - 0.01));
    assert!(released(&r).is_empty(), "released during the hold");
    assert!(r.st.reports(ids[0]).is_empty() && r.st.reports(ids[1]).is_empty());
    assert_eq!(r.ctl.state(), State::Idle);
    // The hold times out (event 0x0053, reason 1); the activities follow, in time order.
    r.run(50);
    assert_eq!(r.st.events(event::EXPOSURE_HOLD_ENDED), [[1, 0]]);
    assert_eq!(
        released(&r),
        [request_id_word(ids[0]), request_id_word(ids[1])]
    );
    r.settle(20_000);
    assert!(all_ok(&r.st.reports(ids[0])), "{:?}", r.st.reports(ids[0]));
    assert_at(&r, &target, "the held move, after the hold");
}
