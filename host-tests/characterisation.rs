//! Characterisation of the whole link as the ground sees it: one scripted session on the
//! host bench (the controller, link service and worker the firmware runs, on the
//! simulated plant) whose complete downlink byte stream, every framed TM packet as the
//! station receives it, must equal a golden recording bit for bit.
//!
//! It pins what the flight image's size work may not change: every TM packet's headers
//! (sequence counts, message type counters, times), source data and CRC-16, the framing,
//! the order and timing of reports, and through them the telecommand decoding, the
//! command paths and the results of the kinematics, planning and supervision behind
//! them. The session: boot, pings, one-shot housekeeping, telecommands refused by the
//! link (bad CRC, wrong APID, unknown service, wrong length, bad argument), a table
//! upload, commit and activation, a dump of the active table, moves absolute and
//! relative (the periodic housekeeping while they run), a refused move, a stop, a move
//! check, a direct stroke, an injected encoder fault and its clear, parameters set and
//! reported, the ST[11] schedule (insert, summary, time shift, delete, enable, release
//! of a move and a move check, disable, reset), ST[9] time reports, a switch to the
//! other bank and back to the nominal table.
//!
//! The golden file is `testdata/characterisation/host-telemetry.bin` (its SHA-256 in
//! `host-telemetry.sha256`). It was recorded at the start of the flash-size work (branch
//! `flash`, on 56f9836) and is not to be re-recorded to make a change pass: a change
//! that alters it changes what the ground receives. Where a change of the downlink is
//! intended, re-record it, say why in the commit, and check the difference:
//!
//! ```sh
//! M2_BLESS=1 cargo test --features host --test characterisation
//! ```

mod common;

use common::{activate, all_ok, calibrated_table, install, wire, JOB_CYCLES};
use m2ctl::controller::schedule::obt_of_cycle;
use m2ctl::controller::State;
use m2ctl::link::framing::Deframer;
use m2ctl::link::schedule::{ObtOffset, RequestIdList, ScheduleCommand};
use m2ctl::link::time::TimeReportRate;
use m2ctl::link::tm::{parse_tm, TmTime};
use m2ctl::link::{Command, MemoryId, ParameterIds, ParameterValues};
use m2ctl::sim::{Bench, InjectedFault};

const GOLDEN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/testdata/characterisation/host-telemetry.bin"
);
const GOLDEN_SHA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/testdata/characterisation/host-telemetry.sha256"
);

/// The packets' CRC-16/CCITT-FALSE from the crc crate (not the crate under test's).
const CCITT: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);

/// Parameter IDs used here (docs/icd.md, ST[20]).
const PIVOT_Z: u16 = 0x0003;
const MOVE_SPEED: u16 = 0x0010;
const HK_PERIOD: u16 = 0x0020;
const FOLLOWING_WARNING: u16 = 0x0030;

/// Sends a raw packet (as the ground built it, possibly altered) and runs `cycles`.
fn send_raw(r: &mut Bench, packet: &[u8], cycles: u32) {
    r.uplink_bytes(&m2ctl::station::frame(packet));
    r.run(cycles);
}

/// Sends a telecommand and runs until its reports are complete, then `extra` cycles.
fn cmd(r: &mut Bench, c: &Command, extra: u32) {
    r.command(c, JOB_CYCLES);
    r.run(extra);
}

fn sched(c: ScheduleCommand) -> Command {
    Command::Schedule(c)
}

/// The on-board time `s` seconds after the next cycle's.
fn obt_in(r: &Bench, s: f64) -> TmTime {
    let now = obt_of_cycle(r.ctl.cycle() + 1);
    now.checked_offset((s * 65536.0) as i64).unwrap()
}

/// The scripted session; returns the downlink bytes.
fn session() -> Vec<u8> {
    let mut r = Bench::new();
    r.tap_downlink();
    // Boot events and the first housekeeping.
    r.run(1_200);

    cmd(&mut r, &Command::Ping, 3);
    cmd(&mut r, &Command::HousekeepingOneShot, 3);

    // Refused by the link: each gives a TM[1,2].
    let (good, _) = r.st.packet(&Command::Ping).unwrap();
    let mut bad_crc = good.clone();
    *bad_crc.last_mut().unwrap() ^= 0x5a;
    send_raw(&mut r, &bad_crc, 3);
    let (mut wrong_apid, _) = r.st.packet(&Command::Ping).unwrap();
    wrong_apid[1] ^= 0x01;
    let n = wrong_apid.len();
    let crc = CCITT.checksum(&wrong_apid[..n - 2]);
    wrong_apid[n - 2..].copy_from_slice(&crc.to_be_bytes());
    send_raw(&mut r, &wrong_apid, 3);
    let (mut unknown, _) = r.st.packet(&Command::Ping).unwrap();
    unknown[7] = 42; // service
    let crc = CCITT.checksum(&unknown[..n - 2]);
    unknown[n - 2..].copy_from_slice(&crc.to_be_bytes());
    send_raw(&mut r, &unknown, 3);
    send_raw(&mut r, &good[..good.len() - 1], 3);
    cmd(
        &mut r,
        &Command::DirectStroke {
            leg: 1,
            delta_nm: 900_000_000,
        },
        3,
    );
    cmd(&mut r, &Command::DumpTable(MemoryId::UploadBuffer), 20);

    // A calibrated table: upload, commit, activate, dump it back.
    let t = calibrated_table(0x00C0_FFEE);
    let reps = install(&mut r, &t, true);
    assert!(all_ok(&reps), "{reps:?}");
    r.run(50);
    cmd(&mut r, &activate(&t), 10);
    cmd(&mut r, &Command::DumpTable(MemoryId::ActiveTable), 50);

    // Moves: absolute, relative, refused, stopped, checked.
    cmd(
        &mut r,
        &Command::MoveAbsolute(wire(120.0, -80.0, 40.0, 20.0, -15.0, 30.0)),
        0,
    );
    r.settle(20_000);
    cmd(
        &mut r,
        &Command::MoveRelative(wire(-30.0, 10.0, 5.0, -5.0, 2.0, 0.0)),
        0,
    );
    r.settle(20_000);
    cmd(
        &mut r,
        &Command::MoveAbsolute(wire(9_000.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        5,
    );
    r.send(&Command::MoveAbsolute(wire(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    r.run(300);
    cmd(&mut r, &Command::Stop, 0);
    r.settle(20_000);
    cmd(
        &mut r,
        &Command::CheckMove(wire(200.0, 0.0, -50.0, 0.0, 60.0, 0.0)),
        5,
    );
    cmd(
        &mut r,
        &Command::CheckMove(wire(0.0, 5_000.0, 0.0, 0.0, 0.0, 0.0)),
        5,
    );

    // Recovery move of one slider.
    cmd(
        &mut r,
        &Command::DirectStroke {
            leg: 3,
            delta_nm: 4_000,
        },
        0,
    );
    r.settle(20_000);

    // A fault: a slipped encoder scale, then cleared.
    r.plant.with(|p| {
        p.inject(InjectedFault::EncoderJump {
            leg: 4,
            jump_mm: 0.2,
        })
    });
    r.run(50);
    assert_eq!(r.ctl.state(), State::Faulted);
    cmd(
        &mut r,
        &Command::MoveRelative(wire(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        3,
    );
    cmd(&mut r, &Command::ClearFault, 3);
    r.plant.with(|p| p.clear_faults());
    r.run(50);
    cmd(&mut r, &Command::ClearFault, 20);
    r.settle(20_000);

    // Parameters: set (persisted by the worker), report, a refused set.
    let set = ParameterValues::new(&[
        (PIVOT_Z, 250_000_000),
        (MOVE_SPEED, 150_000),
        (HK_PERIOD, 500),
        (FOLLOWING_WARNING, 4_000),
    ])
    .unwrap();
    cmd(&mut r, &Command::SetParameters(set), 400);
    let ids =
        ParameterIds::new(&[PIVOT_Z, MOVE_SPEED, HK_PERIOD, FOLLOWING_WARNING, 0x0001]).unwrap();
    cmd(&mut r, &Command::ReportParameters(ids), 3);
    let bad = ParameterValues::new(&[(MOVE_SPEED, -1)]).unwrap();
    cmd(&mut r, &Command::SetParameters(bad), 3);
    let unknown = ParameterIds::new(&[0x7777]).unwrap();
    cmd(&mut r, &Command::ReportParameters(unknown), 3);
    cmd(
        &mut r,
        &Command::MoveAbsolute(wire(50.0, 50.0, 0.0, 0.0, 0.0, 10.0)),
        0,
    );
    r.settle(20_000);

    // ST[9] time reports every second, for three seconds.
    cmd(
        &mut r,
        &Command::SetTimeReportRate(TimeReportRate::Every { exponent: 0 }),
        3_000,
    );
    cmd(&mut r, &Command::SetTimeReportRate(TimeReportRate::Off), 3);

    // ST[11]: insert, summary, time shift, delete one, release the rest.
    let at = [obt_in(&r, 1.0), obt_in(&r, 1.5), obt_in(&r, 9.0)];
    let (insert, ids) =
        r.st.schedule_insert(&[
            (
                at[0],
                Command::MoveRelative(wire(-20.0, 0.0, 10.0, 0.0, 0.0, -10.0)),
            ),
            (
                at[1],
                Command::CheckMove(wire(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
            ),
            (at[2], Command::Ping),
        ])
        .unwrap();
    cmd(&mut r, &insert, 3);
    cmd(&mut r, &sched(ScheduleCommand::SummaryReport), 3);
    cmd(
        &mut r,
        &sched(ScheduleCommand::TimeShiftAll(ObtOffset::from_parts(
            0, 0x4000,
        ))),
        3,
    );
    cmd(
        &mut r,
        &sched(ScheduleCommand::Delete(
            RequestIdList::new(&ids[2..]).unwrap(),
        )),
        3,
    );
    cmd(&mut r, &sched(ScheduleCommand::SummaryReport), 3);
    cmd(&mut r, &sched(ScheduleCommand::EnableRelease), 0);
    r.run(2_500);
    r.settle(20_000);
    cmd(&mut r, &sched(ScheduleCommand::SummaryReport), 3);
    cmd(&mut r, &sched(ScheduleCommand::DisableRelease), 3);
    let (insert, _) =
        r.st.schedule_insert(&[(obt_in(&r, 5.0), Command::Stop)])
            .unwrap();
    cmd(&mut r, &insert, 3);
    cmd(&mut r, &sched(ScheduleCommand::Reset), 3);
    cmd(&mut r, &sched(ScheduleCommand::SummaryReport), 3);

    // Banks: the other bank (empty: refused), back to the nominal table.
    cmd(&mut r, &Command::SwitchBank, 20);
    cmd(&mut r, &Command::RevertToNominal, 50);
    cmd(&mut r, &Command::HousekeepingOneShot, 3);
    r.run(1_500);

    assert_eq!(r.st.bad_frames, 0, "the station could not read a frame");
    r.downlink_tapped().to_vec()
}

/// SHA-256 (FIPS 180-4), for the summary of the recording.
fn sha256(data: &[u8]) -> [u8; 32] {
    const K: [u32; 64] = [
        0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4,
        0xab1c5ed5, 0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe,
        0x9bdc06a7, 0xc19bf174, 0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f,
        0x4a7484aa, 0x5cb0a9dc, 0x76f988da, 0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7,
        0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967, 0x27b70a85, 0x2e1b2138, 0x4d2c6dfc,
        0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85, 0xa2bfe8a1, 0xa81a664b,
        0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070, 0x19a4c116,
        0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
        0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7,
        0xc67178f2,
    ];
    let mut h: [u32; 8] = [
        0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c, 0x1f83d9ab,
        0x5be0cd19,
    ];
    let mut msg = data.to_vec();
    msg.push(0x80);
    while msg.len() % 64 != 56 {
        msg.push(0);
    }
    msg.extend_from_slice(&(data.len() as u64 * 8).to_be_bytes());
    for block in msg.chunks_exact(64) {
        let mut w = [0u32; 64];
        for (i, c) in block.chunks_exact(4).enumerate() {
            w[i] = u32::from_be_bytes([c[0], c[1], c[2], c[3]]);
        }
        for i in 16..64 {
            let s0 = w[i - 15].rotate_right(7) ^ w[i - 15].rotate_right(18) ^ (w[i - 15] >> 3);
            let s1 = w[i - 2].rotate_right(17) ^ w[i - 2].rotate_right(19) ^ (w[i - 2] >> 10);
            w[i] = w[i - 16]
                .wrapping_add(s0)
                .wrapping_add(w[i - 7])
                .wrapping_add(s1);
        }
        let mut v = h;
        for i in 0..64 {
            let s1 = v[4].rotate_right(6) ^ v[4].rotate_right(11) ^ v[4].rotate_right(25);
            let ch = (v[4] & v[5]) ^ (!v[4] & v[6]);
            let t1 = v[7]
                .wrapping_add(s1)
                .wrapping_add(ch)
                .wrapping_add(K[i])
                .wrapping_add(w[i]);
            let s0 = v[0].rotate_right(2) ^ v[0].rotate_right(13) ^ v[0].rotate_right(22);
            let maj = (v[0] & v[1]) ^ (v[0] & v[2]) ^ (v[1] & v[2]);
            let t2 = s0.wrapping_add(maj);
            v = [
                t1.wrapping_add(t2),
                v[0],
                v[1],
                v[2],
                v[3].wrapping_add(t1),
                v[4],
                v[5],
                v[6],
            ];
        }
        for (a, b) in h.iter_mut().zip(v) {
            *a = a.wrapping_add(b);
        }
    }
    let mut out = [0u8; 32];
    for (o, v) in out.chunks_exact_mut(4).zip(h) {
        o.copy_from_slice(&v.to_be_bytes());
    }
    out
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// The frames of a downlink stream (delimiter-separated, delimiters dropped).
fn frames(stream: &[u8]) -> Vec<&[u8]> {
    stream
        .split(|b| *b == 0)
        .filter(|f| !f.is_empty())
        .collect()
}

/// One line describing a frame: its packet's numbers and type, or why it does not parse.
fn describe(frame: &[u8]) -> String {
    let mut d: Deframer<{ m2ctl::link::MAX_TM_FRAME_LEN }> = Deframer::new();
    let mut packet = None;
    for &b in [0].iter().chain(frame).chain(&[0]) {
        if let Some(Ok(p)) = d.push_byte(b) {
            packet = Some(p.to_vec());
        }
    }
    match packet.as_deref().map(parse_tm) {
        Some(Ok(tm)) => format!(
            "TM[{},{}] seq {} msg {} at {:?}: {}",
            tm.service,
            tm.subtype,
            tm.seq_count,
            tm.msg_counter,
            tm.time,
            hex(packet.as_deref().unwrap_or(&[]))
        ),
        Some(Err(e)) => format!("unparsable ({e:?}): {}", hex(frame)),
        None => format!("undeframable: {}", hex(frame)),
    }
}

#[test]
fn the_downlink_of_a_scripted_session_is_the_recorded_one_bit_for_bit() {
    let got = session();
    let got_sha = hex(&sha256(&got));
    if std::env::var_os("M2_BLESS").is_some() {
        std::fs::create_dir_all(std::path::Path::new(GOLDEN).parent().unwrap()).unwrap();
        std::fs::write(GOLDEN, &got).unwrap();
        std::fs::write(GOLDEN_SHA, format!("{got_sha}  host-telemetry.bin\n")).unwrap();
        println!(
            "recorded {} bytes, {} frames, SHA-256 {got_sha}",
            got.len(),
            frames(&got).len()
        );
        return;
    }
    let want = std::fs::read(GOLDEN).unwrap_or_else(|e| {
        panic!("{GOLDEN}: {e} (record it with M2_BLESS=1, module documentation)")
    });
    let want_sha = hex(&sha256(&want));
    let listed = std::fs::read_to_string(GOLDEN_SHA).unwrap_or_default();
    assert!(
        listed.starts_with(&want_sha),
        "{GOLDEN} does not match its recorded SHA-256 ({listed:?}, the file has {want_sha})"
    );
    if got == want {
        println!(
            "downlink: {} bytes, {} frames, SHA-256 {got_sha}, equal to the recording",
            got.len(),
            frames(&got).len()
        );
        return;
    }
    let (gf, wf) = (frames(&got), frames(&want));
    let first = gf.iter().zip(&wf).position(|(g, w)| g != w);
    let detail = match first {
        Some(i) => format!(
            "first different frame #{i}:\n  recorded: {}\n  now:      {}",
            describe(wf[i]),
            describe(gf[i])
        ),
        None => format!("the first {} frames agree", gf.len().min(wf.len())),
    };
    panic!(
        "the downlink differs from the recording:\n  recorded: {} bytes, {} frames, SHA-256 {want_sha}\n  now:      {} bytes, {} frames, SHA-256 {got_sha}\n{detail}",
        want.len(),
        wf.len(),
        got.len(),
        gf.len()
    );
}

/// The session is deterministic: two runs give the same bytes (else the golden file
/// could not pin anything).
#[test]
fn the_session_is_deterministic() {
    let a = session();
    let b = session();
    assert!(a == b, "two runs of the session differ");
    assert!(frames(&a).len() > 200, "{} frames", frames(&a).len());
}

#[test]
fn sha256_is_the_standard_one() {
    assert_eq!(
        hex(&sha256(b"abc")),
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    );
    assert_eq!(
        hex(&sha256(&[0x61; 1000])),
        "41edece42d63e8d9bf515a9ba6932e1c20cbc9f5a5d134645adb5db1b9737ea3"
    );
}
