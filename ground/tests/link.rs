//! Link layer: TC encode -> frame -> deframe -> decode round trips, every rejection with
//! its failure code, deframer recovery, TM emit/parse, fuzzing with arbitrary bytes, an
//! independent encoder (Python `spacepackets`), and the `m2ground tc` output.
//!
//! `cargo test --features host --test link -- --nocapture` prints the fuzz case counts.

#![cfg(feature = "host")]

#[path = "../../host-tests/common/mod.rs"]
mod common;

use std::sync::atomic::{AtomicUsize, Ordering};

use m2ctl::link::command::{TABLE_CHUNK_MAX_LEN, WIRE_POSE_LEN};
use m2ctl::link::framing::{max_cobs_len, max_frame_len, DEFRAMER_BUFFER_LEN};
use m2ctl::link::hk::HK_REPORT_LEN;
use m2ctl::link::schedule::{ActivityBlock, ObtOffset, RequestIdList, ScheduleCommand};
use m2ctl::link::tc::{TcHeader, MIN_TC_PACKET_LEN};
use m2ctl::link::time::TimeReportRate;
use m2ctl::link::tm::{dump_chunks, event_id, parse_tm, EmitError};
use m2ctl::link::*;
use m2ctl::table::{Table, TABLE_LEN};
use m2ground::tc::{
    hex_lines, parse_hex_lines, run_tc, upload_commands, upload_procedure, TcOutput, TcSequencer,
};
use proptest::prelude::*;

fn all_commands() -> Vec<Command> {
    let pose = WirePose {
        translation_nm: [1500, -2000, 30000],
        rotation_uas: [-2_000_000, 1_000_000, 7],
    };
    let extreme = WirePose::from_array([i32::MIN, i32::MAX, 0, -1, 1, i32::MAX]);
    vec![
        Command::Ping,
        Command::HousekeepingOneShot,
        Command::MoveAbsolute(pose),
        Command::MoveAbsolute(extreme),
        Command::MoveRelative(pose),
        Command::Stop,
        Command::ClearFault,
        Command::DirectStroke {
            leg: 1,
            delta_nm: -12345,
        },
        Command::DirectStroke {
            leg: 6,
            delta_nm: i32::MAX,
        },
        Command::CommitTable { crc32: 0xdead_beef },
        Command::ActivateTable {
            table_id: 7,
            crc32: 0x89ab_cdef,
        },
        Command::SwitchBank,
        Command::RevertToNominal,
        Command::LoadTableChunk(TableChunk::new(0, &[0u8; TABLE_CHUNK_MAX_LEN]).unwrap()),
        Command::LoadTableChunk(TableChunk::new((TABLE_LEN - 4) as u16, &[0, 1, 0xff, 0]).unwrap()),
        Command::DumpTable(MemoryId::ActiveTable),
        Command::DumpTable(MemoryId::UploadBuffer),
        // Time-based schedule (ST[11]) and time reports (ST[9]).
        schedule_insert(),
        Command::Schedule(ScheduleCommand::Delete(
            RequestIdList::new(&[
                RequestId::from_bytes([0x18, 0xb2, 0xc0, 0x01]),
                RequestId::from_bytes([0x18, 0xb2, 0xff, 0xff]),
            ])
            .unwrap(),
        )),
        Command::Schedule(ScheduleCommand::TimeShiftAll(ObtOffset::from_parts(
            -1, 0x8000,
        ))),
        Command::Schedule(ScheduleCommand::EnableRelease),
        Command::Schedule(ScheduleCommand::DisableRelease),
        Command::Schedule(ScheduleCommand::Reset),
        Command::Schedule(ScheduleCommand::SummaryReport),
        Command::SetTimeReportRate(TimeReportRate::Every { exponent: 8 }),
        Command::SetTimeReportRate(TimeReportRate::Off),
    ]
}

/// A TC[11,4] of two activities (a ping and a move).
fn schedule_insert() -> Command {
    let ping = packet(&Command::Ping, 3);
    let mv = packet(
        &Command::MoveAbsolute(WirePose::from_array([1, -2, 3, -4, 5, -6])),
        4,
    );
    let block = ActivityBlock::new(&[
        (
            TmTime {
                seconds: 12,
                fraction: 0x8000,
            },
            &ping[..],
        ),
        (
            TmTime {
                seconds: 0xffff_0000,
                fraction: 1,
            },
            &mv[..],
        ),
    ])
    .unwrap();
    Command::Schedule(ScheduleCommand::Insert(block))
}

fn packet(cmd: &Command, seq: u16) -> Vec<u8> {
    let mut buf = [0u8; MAX_TC_PACKET_LEN];
    let n = encode_telecommand(cmd, TcHeader::new(seq), &mut buf).unwrap();
    buf[..n].to_vec()
}

/// Recomputes the CRC-16/CCITT-FALSE of a packet (after a deliberate edit).
fn fix_crc(p: &mut [u8]) {
    let crc = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);
    let n = p.len();
    let c = crc.checksum(&p[..n - 2]);
    p[n - 2..].copy_from_slice(&c.to_be_bytes());
}

fn deframe_all(bytes: &[u8]) -> Vec<Result<Vec<u8>, FrameError>> {
    // Sized for telemetry, the longer direction (the default is the telecommands').
    let mut d: Deframer<{ max_cobs_len(m2ctl::link::MAX_TM_PACKET_LEN) }> = Deframer::new();
    let mut out = Vec::new();
    for &b in bytes {
        if let Some(r) = d.push_byte(b) {
            out.push(r.map(|p| p.to_vec()));
        }
    }
    out
}

fn reject_code(p: &[u8]) -> u16 {
    match decode_telecommand(p) {
        Ok(tc) => panic!("accepted {tc:?}"),
        Err(r) => r.error.code(),
    }
}

#[test]
fn every_command_round_trips_through_frame_and_decoder() {
    let mut stream = Vec::new();
    let cmds = all_commands();
    for (i, c) in cmds.iter().enumerate() {
        let p = packet(c, i as u16 * 1000);
        let mut f = vec![0u8; MAX_TC_FRAME_LEN];
        let n = encode_frame(&p, &mut f).unwrap();
        assert!(n <= max_frame_len(p.len()));
        assert!(!f[1..n - 1].contains(&0), "COBS body has no zero");
        stream.extend_from_slice(&f[..n]);
    }
    let frames = deframe_all(&stream);
    assert_eq!(frames.len(), cmds.len());
    for (i, (f, c)) in frames.iter().zip(&cmds).enumerate() {
        let tc = decode_telecommand(f.as_ref().unwrap()).unwrap();
        assert_eq!(&tc.command, c);
        assert_eq!(tc.request_id.apid(), M2_APID);
        assert_eq!(tc.request_id.seq_count(), (i as u16 * 1000) & 0x3fff);
        assert_eq!(tc.ack, AckFlags::ALL);
    }
    println!("round trip: {} commands", cmds.len());
}

#[test]
fn header_fields_are_carried() {
    let mut buf = [0u8; 64];
    let h = TcHeader {
        seq_count: 0x3fff,
        source_id: 0xbeef,
        ack: AckFlags(0b1001),
    };
    let n = encode_telecommand(&Command::Stop, h, &mut buf).unwrap();
    let tc = decode_telecommand(&buf[..n]).unwrap();
    assert_eq!(tc.source_id, 0xbeef);
    assert!(tc.ack.acceptance() && tc.ack.completion() && !tc.ack.start());
    assert_eq!(tc.request_id.seq_count(), 0x3fff);
    assert_eq!(tc.request_id.to_bytes(), buf[..4]);
    // Too small an output buffer is an error, not a panic.
    assert!(encode_telecommand(&Command::Stop, h, &mut buf[..10]).is_err());
}

#[test]
fn wrong_crc_is_rejected_with_its_code() {
    for c in all_commands() {
        let mut p = packet(&c, 7);
        let n = p.len();
        p[n - 1] ^= 0x01;
        let r = decode_telecommand(&p).unwrap_err();
        assert_eq!(r.error.code(), 0x0505, "{c:?}");
        assert_eq!(r.request_id.unwrap().seq_count(), 7);
        // A flipped payload bit too.
        let mut p = packet(&c, 7);
        p[8] ^= 0x40;
        assert_eq!(reject_code(&p), 0x0505);
    }
}

#[test]
fn wrong_lengths_are_rejected() {
    let p = packet(&Command::MoveAbsolute(WirePose::default()), 1);
    // Truncated at every length.
    for n in 0..p.len() {
        let code = reject_code(&p[..n]);
        assert_eq!(code, 0x0501, "truncated to {n}");
        let r = decode_telecommand(&p[..n]).unwrap_err();
        assert_eq!(r.request_id.is_some(), n >= 4);
    }
    // Trailing bytes.
    let mut long = p.clone();
    long.push(0xaa);
    assert_eq!(reject_code(&long), 0x0502);
    // Length field too small (CRC fixed): the frame is longer than declared.
    let mut q = p.clone();
    q[5] -= 1;
    assert_eq!(reject_code(&q), 0x0502);
    // Length field below the minimum packet.
    let mut q = packet(&Command::Ping, 1);
    q[4] = 0;
    q[5] = 0;
    assert_eq!(reject_code(&q), 0x0501);
    // Valid CRC, but application data of the wrong length for the function.
    let mut q = p.clone();
    q.remove(p.len() - 3);
    q[5] -= 1;
    fix_crc(&mut q);
    assert_eq!(reject_code(&q), 0x050c);
    // Oversized: a packet beyond MAX_TC_PACKET_LEN, and a declared length beyond it.
    let mut big = vec![0u8; MAX_TC_PACKET_LEN + 1];
    big[..6].copy_from_slice(&p[..6]);
    assert_eq!(reject_code(&big), 0x0503);
    let mut q = p.clone();
    q[4] = 0x10;
    assert_eq!(reject_code(&q), 0x0503);
    assert_eq!(MIN_TC_PACKET_LEN, 13);
}

#[test]
fn unknown_service_subtype_function_and_bad_arguments_are_rejected() {
    let edit = |c: &Command, f: &dyn Fn(&mut Vec<u8>)| {
        let mut p = packet(c, 3);
        f(&mut p);
        fix_crc(&mut p);
        p
    };
    assert_eq!(reject_code(&edit(&Command::Ping, &|p| p[7] = 99)), 0x0509);
    assert_eq!(reject_code(&edit(&Command::Ping, &|p| p[7] = 1)), 0x0509);
    assert_eq!(reject_code(&edit(&Command::Ping, &|p| p[8] = 3)), 0x050a);
    assert_eq!(reject_code(&edit(&Command::Stop, &|p| p[8] = 2)), 0x050a);
    assert_eq!(
        reject_code(&edit(&Command::Stop, &|p| p[12] = 0x99)),
        0x050b
    );
    let ds = Command::DirectStroke {
        leg: 1,
        delta_nm: 5,
    };
    assert_eq!(reject_code(&edit(&ds, &|p| p[13] = 0)), 0x050d);
    assert_eq!(reject_code(&edit(&ds, &|p| p[13] = 7)), 0x050d);
    let dump = Command::DumpTable(MemoryId::ActiveTable);
    assert_eq!(reject_code(&edit(&dump, &|p| p[11] = 3)), 0x050d);
    // Chunk past the end of the table.
    let chunk = Command::LoadTableChunk(TableChunk::new(0, &[1, 2, 3, 4]).unwrap());
    let past = edit(&chunk, &|p| {
        p[12..14].copy_from_slice(&((TABLE_LEN - 3) as u16).to_be_bytes())
    });
    let r = decode_telecommand(&past).unwrap_err();
    assert_eq!(r.error.code(), 0x050e);
    assert_eq!(r.error.data(), ((TABLE_LEN as u32 - 3) << 16) | 4);
    // Chunk into the active table (memory 2) is refused.
    assert_eq!(reject_code(&edit(&chunk, &|p| p[11] = 2)), 0x050d);
    // Chunk length field disagreeing with the data.
    assert_eq!(reject_code(&edit(&chunk, &|p| p[15] = 5)), 0x050c);
    // Builder refuses empty, too long and out-of-range chunks.
    assert!(TableChunk::new(0, &[]).is_err());
    assert!(TableChunk::new(0, &[0; TABLE_CHUNK_MAX_LEN + 1]).is_err());
    assert!(TableChunk::new(TABLE_LEN as u16, &[0]).is_err());
}

#[test]
fn wrong_apid_header_and_pus_version_are_rejected() {
    let mut p = packet(&Command::Ping, 9);
    p[1] ^= 0x01;
    fix_crc(&mut p);
    let r = decode_telecommand(&p).unwrap_err();
    assert_eq!(r.error, LinkError::WrongApid { apid: M2_APID ^ 1 });
    assert_eq!(r.error.code(), 0x0506);
    // A TM (type bit clear) is not a TC.
    let mut p = packet(&Command::Ping, 9);
    p[0] &= !0x10;
    fix_crc(&mut p);
    assert_eq!(reject_code(&p), 0x0507);
    // Segmented packet.
    let mut p = packet(&Command::Ping, 9);
    p[2] &= 0x3f;
    fix_crc(&mut p);
    assert_eq!(reject_code(&p), 0x0507);
    // PUS-A (version 1).
    let mut p = packet(&Command::Ping, 9);
    p[6] = (1 << 4) | (p[6] & 0x0f);
    fix_crc(&mut p);
    assert_eq!(reject_code(&p), 0x0508);
}

#[test]
fn deframer_recovers_after_garbage_overflow_and_bad_cobs() {
    let good = tc_frame(&Command::Ping, 1);
    let mut stream: Vec<u8> = Vec::new();
    // Garbage without zeros, then a good frame (its leading 0x00 ends the garbage).
    stream.extend([0x55u8; 17]);
    stream.extend(&good);
    // An overflow: more non-zero bytes than the buffer.
    stream.extend(std::iter::repeat_n(0x11u8, DEFRAMER_BUFFER_LEN + 50));
    stream.extend(&good);
    // Invalid COBS (code byte pointing past the frame end).
    stream.extend([0x00, 0x09, 0x01, 0x00]);
    stream.extend(&good);
    // Zeros only.
    stream.extend([0u8; 10]);
    stream.extend(&good);
    let out = deframe_all(&stream);
    let oks: Vec<_> = out.iter().filter_map(|r| r.as_ref().ok()).collect();
    let errs: Vec<_> = out.iter().filter_map(|r| r.as_ref().err()).collect();
    assert_eq!(oks.len(), 4, "{out:?}");
    let decoded: Vec<_> = oks
        .iter()
        .filter_map(|p| decode_telecommand(p).ok())
        .collect();
    assert_eq!(decoded.len(), 4);
    assert!(decoded.iter().all(|t| t.command == Command::Ping));
    assert!(errs.contains(&&FrameError::Overflow));
    assert_eq!(errs.len(), 3, "{out:?}"); // garbage, overflow, bad COBS
    assert!(errs.contains(&&FrameError::BadCobs));
    // Slice API gives the same.
    let mut d: Deframer = Deframer::new();
    let mut rest = &stream[..];
    let mut n_ok = 0;
    while !rest.is_empty() {
        let (used, r) = d.push(rest);
        if let Some(Ok(p)) = r {
            n_ok += usize::from(decode_telecommand(p).is_ok());
        }
        rest = &rest[used..];
    }
    assert_eq!(n_ok, 4);
    // A frame exactly filling the buffer still decodes (the largest telecommand).
    let big = tc_frame(&all_commands()[13], 2);
    assert!(big.len() - 2 <= DEFRAMER_BUFFER_LEN);
    let out = deframe_all(&big);
    assert!(decode_telecommand(out[0].as_ref().unwrap()).is_ok());
    // encode_frame refuses a too-small buffer.
    let mut small = [0u8; 8];
    assert!(encode_frame(&packet(&Command::Ping, 0), &mut small).is_err());
}

fn tc_frame(c: &Command, seq: u16) -> Vec<u8> {
    let p = packet(c, seq);
    let mut f = vec![0u8; MAX_TC_FRAME_LEN];
    let n = encode_frame(&p, &mut f).unwrap();
    f.truncate(n);
    f
}

fn sample_hk() -> Housekeeping {
    Housekeeping {
        state: 3,
        boot_source: 2,
        active_bank: 2,
        fk_iterations: 2,
        fk_valid: true,
        cycle_counter: 123_456,
        fault_flags: 0x8000_0001,
        warning_flags: 0x10,
        refusal_bits: 0x0100_0002,
        active_table_id: 42,
        active_table_crc32: 0x1234_5678,
        pose_fk: WirePose::from_array([1, -2, 3, -4, 5, -6]),
        pose_commanded: WirePose::from_array([i32::MAX, i32::MIN, 0, 7, 8, 9]),
        strokes_commanded_nm: [100, -200, 300, -400, 500, -600],
        encoders_nm: [0, 100, -100, 1_000_000, -5_000_000, 7],
        tc_accepted: 65535,
        tc_rejected: 3,
        last_failure_code: 0x0505,
        moving_legs: 0b10_1010,
        fault_legs: 0b01_0101,
        pending_bank: 1,
        pending_table_id: 0xfedc_ba98,
        job: 2,
        selected_source: 0xff,
        tm_dropped: 11,
        tc_frames_dropped: 12,
        uart_overruns: 13,
        cycle_overruns: 14,
        reset_cause: 3,
        boot_count: 0xabcd,
        bank_health: 0b10,
        pivot_nm: [-1_000_000_000, 25_000_000, 1_000_000_000],
        pose_fk_operator: WirePose::from_array([10, -20, 30, -40, 50, -60]),
        pose_commanded_operator: WirePose::from_array([-1, i32::MIN, i32::MAX, 0, 1, 2]),
        parameters_set: 0x0007_0001,
        schedule: m2ctl::link::hk::ScheduleHk {
            activities: 16,
            release_enabled: true,
            released: 0x0102,
            failed: 3,
            next_release: TmTime {
                seconds: 77,
                fraction: 0x8000,
            },
            time_report_rate: 0xff,
        },
        limit_lower_legs: 0b00_0001,
        limit_upper_legs: 0b10_0000,
        reference_legs: 0b00_0100,
        switch_unreadable_legs: 0b01_0000,
        in_position_legs: 0b01_0110,
        temperatures_centi_k: [29_315, 29_316, 0, 29_400, 21_315, 37_315, 29_315, 1],
        sensors_open: 0b0000_0100,
        sensors_short: 0,
        sensors_stuck: 0b1000_0000,
        thermal_state: 0b101,
        thermal_offsets_nm: [1_234, -2_345, 0, 4_567, -5_678, 6_789],
    }
}

fn tm_packet(frame: &[u8]) -> Vec<u8> {
    let out = deframe_all(frame);
    assert_eq!(out.len(), 1);
    out[0].clone().unwrap()
}

#[test]
fn telemetry_emitters_round_trip_and_count() {
    let mut w = TmWriter::new();
    let mut buf = [0u8; MAX_TM_FRAME_LEN];
    let t = TmTime::from_millis(12_345);
    assert_eq!(t.seconds, 12);
    assert_eq!(t.fraction, (345 * 65536 / 1000) as u16);
    let rid = RequestId {
        packet_id: 0x18b2,
        sequence_control: 0xc005,
    };
    let reports = [
        Verification::AcceptanceSuccess,
        Verification::acceptance_failure(&LinkError::BadCrc { found: 0xabcd }),
        Verification::StartSuccess,
        Verification::StartFailure {
            code: 0x0202,
            data: 0x0100_0000,
        },
        Verification::CompletionSuccess,
        Verification::CompletionFailure {
            code: 0x0418,
            data: 9,
        },
    ];
    for (i, v) in reports.iter().enumerate() {
        let n = w.emit_verification(t, rid, *v, &mut buf).unwrap();
        let p = tm_packet(&buf[..n]);
        let tm = parse_tm(&p).unwrap();
        assert_eq!(tm.apid, M2_APID);
        assert_eq!(tm.seq_count, i as u16);
        assert_eq!(tm.msg_counter, i as u16);
        assert_eq!(tm.time, t);
        assert_eq!(
            tm.report,
            TmReport::Verification {
                request_id: rid,
                report: *v
            }
        );
    }
    let hk = sample_hk();
    let n = w.emit_housekeeping(t, &hk, &mut buf).unwrap();
    let p = tm_packet(&buf[..n]);
    assert_eq!(p.len(), 6 + 7 + 6 + HK_REPORT_LEN + 2);
    let tm = parse_tm(&p).unwrap();
    assert_eq!(tm.report, TmReport::Housekeeping(hk));
    assert_eq!((tm.seq_count, tm.msg_counter), (6, 0));
    let n = w
        .emit_event(
            t,
            EventSeverity::High,
            event_id::FAULT_LATCHED,
            [1, 2],
            &mut buf,
        )
        .unwrap();
    let ev = tm_packet(&buf[..n]);
    let tm = parse_tm(&ev).unwrap();
    assert_eq!(
        tm.report,
        TmReport::Event {
            severity: EventSeverity::High,
            event_id: event_id::FAULT_LATCHED,
            aux: [1, 2]
        }
    );
    let n = w.emit_ping_reply(t, &mut buf).unwrap();
    assert_eq!(
        parse_tm(&tm_packet(&buf[..n])).unwrap().report,
        TmReport::PingReply
    );
    // Table dump: chunks reassemble the table.
    let table = Table::nominal().to_bytes();
    let mut back = Vec::new();
    for (off, bytes) in dump_chunks(&table) {
        let n = w
            .emit_table_dump_chunk(t, MemoryId::ActiveTable, off, bytes, &mut buf)
            .unwrap();
        match parse_tm(&tm_packet(&buf[..n])).unwrap().report {
            TmReport::DumpChunk {
                memory,
                offset_bytes,
                bytes,
            } => {
                assert_eq!(memory, MemoryId::ActiveTable);
                assert_eq!(usize::from(offset_bytes), back.len());
                back.extend_from_slice(bytes);
            }
            r => panic!("{r:?}"),
        }
    }
    assert_eq!(back, table);
    assert_eq!(
        w.emit_table_dump_chunk(t, MemoryId::ActiveTable, 0, &[], &mut buf),
        Err(EmitError::BadChunk)
    );
    // A too-small buffer fails without consuming a sequence count.
    let before = w.next_seq_count();
    assert_eq!(
        w.emit_housekeeping(t, &hk, &mut buf[..40]),
        Err(EmitError::BufferTooSmall)
    );
    assert_eq!(w.next_seq_count(), before);
    // Sequence count wraps at 2^14.
    let mut w = TmWriter::new();
    for _ in 0..(1 << 14) {
        w.emit_ping_reply(t, &mut buf).unwrap();
    }
    assert_eq!(w.next_seq_count(), 0);
}

#[test]
fn wire_pose_converts_units() {
    let p = WirePose::from_array([1_000_000, -500, 0, 1_000_000, -2_500_000, 0]);
    let pose = p.to_pose::<f64>();
    assert!((pose.translation_mm[0] - 1.0).abs() < 1e-15);
    assert!((pose.translation_mm[1] + 0.0005).abs() < 1e-15);
    let arcsec = pose.rotation_arcsec();
    assert!((arcsec[0] - 1.0).abs() < 1e-9 && (arcsec[1] + 2.5).abs() < 1e-9);
    assert_eq!(WirePose::from_pose(&pose), p);
    let f32_pose = p.to_pose::<f32>();
    assert_eq!(WirePose::from_pose(&f32_pose), p);
    let mut b = [0u8; WIRE_POSE_LEN];
    let mut w = m2ctl::link::wire::Writer::new(&mut b, m2ctl::link::wire::Order::Big);
    assert_eq!(w.pose(&p), Some(()));
    assert_eq!(b[..4], 1_000_000i32.to_be_bytes());
    let mut r = m2ctl::link::wire::Reader::new(&b, m2ctl::link::wire::Order::Big);
    assert_eq!(r.pose(), Some(p));
    let nan = m2ctl::kinematics::Pose {
        translation_mm: [f64::NAN, 1e300, -1e300],
        rotation_rad: [0.0; 3],
    };
    assert_eq!(
        WirePose::from_pose(&nan).translation_nm,
        [0, i32::MAX, i32::MIN]
    );
}

static FUZZ_CASES: AtomicUsize = AtomicUsize::new(0);
static FUZZ_FRAMES: AtomicUsize = AtomicUsize::new(0);
static MUTANT_CASES: AtomicUsize = AtomicUsize::new(0);
static MUTANT_ACCEPTED: AtomicUsize = AtomicUsize::new(0);

/// Fuzz cases per proptest property (moderate: the suite stays fast).
const FUZZ_CASES_PER_PROPERTY: u32 = 4000;

fn feed_everything(bytes: &[u8]) -> usize {
    let mut d: Deframer = Deframer::new();
    let mut frames = 0;
    for &b in bytes {
        if let Some(Ok(p)) = d.push_byte(b) {
            frames += 1;
            let _ = decode_telecommand(p);
            let _ = parse_tm(p);
        }
    }
    // The raw bytes as a packet too.
    let _ = decode_telecommand(bytes);
    let _ = parse_tm(bytes);
    let _ = Housekeeping::parse(bytes);
    frames
}

proptest! {
    #![proptest_config(ProptestConfig { cases: FUZZ_CASES_PER_PROPERTY, failure_persistence: None, ..ProptestConfig::default() })]

    /// Arbitrary bytes (with plenty of zeros) never panic the deframer or the decoders.
    #[test]
    fn fuzz_arbitrary_bytes(bytes in proptest::collection::vec(
        prop_oneof![3 => any::<u8>(), 1 => Just(0u8)], 0..700)) {
        FUZZ_CASES.fetch_add(1, Ordering::Relaxed);
        FUZZ_FRAMES.fetch_add(feed_everything(&bytes), Ordering::Relaxed);
    }

    /// Valid telecommands with random byte edits: never panic; an accepted mutant is
    /// exactly what re-encoding its command gives (nothing half-parsed).
    #[test]
    fn fuzz_mutated_telecommands(which in 0usize..17, seq in 0u16..0x4000,
        edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..4),
        fix in any::<bool>()) {
        MUTANT_CASES.fetch_add(1, Ordering::Relaxed);
        let mut p = packet(&all_commands()[which], seq);
        for (at, v) in &edits {
            let i = at % p.len();
            p[i] = *v;
        }
        if fix && p.len() >= 2 { fix_crc(&mut p); }
        if let Ok(tc) = decode_telecommand(&p) {
            MUTANT_ACCEPTED.fetch_add(1, Ordering::Relaxed);
            let h = TcHeader { seq_count: tc.request_id.seq_count(), source_id: tc.source_id, ack: tc.ack };
            let mut buf = [0u8; MAX_TC_PACKET_LEN];
            let n = encode_telecommand(&tc.command, h, &mut buf).unwrap();
            prop_assert_eq!(&buf[..n], &p[..]);
        }
        let mut f = vec![0u8; MAX_TC_FRAME_LEN];
        let n = encode_frame(&p, &mut f).unwrap();
        feed_everything(&f[..n]);
    }
}

#[test]
fn fuzz_reaches_every_decoder_stage_and_accepted_mutants_reencode_exactly() {
    // Runs the properties again explicitly so the counts are known, and asserts the
    // fuzzing is not toothless: frames reach the decoders, mutants are both accepted and
    // refused, and every accepted mutant re-encodes byte for byte.
    let start = std::time::Instant::now();
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig {
        cases: FUZZ_CASES_PER_PROPERTY,
        failure_persistence: None,
        ..ProptestConfig::default()
    });
    let count = AtomicUsize::new(0);
    let frames = AtomicUsize::new(0);
    let bytes_fed = AtomicUsize::new(0);
    runner
        .run(
            &proptest::collection::vec(prop_oneof![3 => any::<u8>(), 1 => Just(0u8)], 0..700),
            |bytes| {
                count.fetch_add(1, Ordering::Relaxed);
                bytes_fed.fetch_add(bytes.len(), Ordering::Relaxed);
                frames.fetch_add(feed_everything(&bytes), Ordering::Relaxed);
                Ok(())
            },
        )
        .unwrap();
    println!(
        "fuzz: {} arbitrary-byte cases ({} bytes, {} COBS frames decoded as TC and TM) in {:.2?}, no panic",
        count.load(Ordering::Relaxed),
        bytes_fed.load(Ordering::Relaxed),
        frames.load(Ordering::Relaxed),
        start.elapsed()
    );
    assert_eq!(
        count.load(Ordering::Relaxed),
        FUZZ_CASES_PER_PROPERTY as usize
    );
    // Mutated valid telecommands (byte edits, CRC re-fixed half of the time).
    let start = std::time::Instant::now();
    let cases = AtomicUsize::new(0);
    let accepted = AtomicUsize::new(0);
    let cmds = all_commands();
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig {
        cases: FUZZ_CASES_PER_PROPERTY,
        failure_persistence: None,
        ..ProptestConfig::default()
    });
    runner
        .run(
            &(
                0..cmds.len(),
                0u16..0x4000,
                proptest::collection::vec((any::<usize>(), any::<u8>()), 1..4),
                any::<bool>(),
            ),
            |(which, seq, edits, fix)| {
                cases.fetch_add(1, Ordering::Relaxed);
                let mut p = packet(&cmds[which], seq);
                for (at, v) in &edits {
                    let i = at % p.len();
                    p[i] = *v;
                }
                if fix {
                    fix_crc(&mut p);
                }
                if let Ok(tc) = decode_telecommand(&p) {
                    accepted.fetch_add(1, Ordering::Relaxed);
                    let h = TcHeader {
                        seq_count: tc.request_id.seq_count(),
                        source_id: tc.source_id,
                        ack: tc.ack,
                    };
                    let mut buf = [0u8; MAX_TC_PACKET_LEN];
                    let n = encode_telecommand(&tc.command, h, &mut buf).unwrap();
                    prop_assert_eq!(&buf[..n], &p[..]);
                }
                Ok(())
            },
        )
        .unwrap();
    println!(
        "fuzz: {} mutated-TC cases ({} still accepted after the edit) in {:.2?}, no panic",
        cases.load(Ordering::Relaxed),
        accepted.load(Ordering::Relaxed),
        start.elapsed()
    );
    let (n, a) = (
        cases.load(Ordering::Relaxed),
        accepted.load(Ordering::Relaxed),
    );
    assert!(
        frames.load(Ordering::Relaxed) > 0,
        "no frame reached the decoders"
    );
    assert!(
        a > 0 && a < n,
        "mutants accepted {a} of {n}: one path never ran"
    );
}

/// The TCs of host-tests/py/pus_tcs.py, encoded here.
fn python_reference_set() -> Vec<(&'static str, Command, u16)> {
    vec![
        ("ping", Command::Ping, 0),
        ("hk", Command::HousekeepingOneShot, 1),
        (
            "move_abs",
            Command::MoveAbsolute(WirePose::from_array([
                1500, -2000, 30000, -2_000_000, 1_000_000, 7,
            ])),
            2,
        ),
        (
            "move_rel",
            Command::MoveRelative(WirePose::from_array([-1, 0, i32::MAX, 0, i32::MIN, 0])),
            3,
        ),
        ("stop", Command::Stop, 4),
        (
            "direct_stroke",
            Command::DirectStroke {
                leg: 6,
                delta_nm: -12345,
            },
            5,
        ),
        ("commit", Command::CommitTable { crc32: 0xdead_beef }, 6),
        (
            "activate",
            Command::ActivateTable {
                table_id: 42,
                crc32: 0x0123_4567,
            },
            16383,
        ),
        (
            "load_chunk",
            Command::LoadTableChunk(TableChunk::new(128, &[0, 1, 2, 0xff]).unwrap()),
            7,
        ),
        ("dump", Command::DumpTable(MemoryId::ActiveTable), 8),
    ]
}

#[test]
fn python_spacepackets_encodes_identical_telecommands() {
    let script = concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/host-tests/py/pus_tcs.py"
    );
    let out = std::process::Command::new("python3")
        .arg(script)
        .output()
        .unwrap_or_else(|e| panic!("cannot run python3 ({e}); install python3 and `pip install spacepackets` (scripts/setup.sh)"));
    assert!(
        out.status.success(),
        "host-tests/py/pus_tcs.py failed: python package 'spacepackets' missing? run `pip install spacepackets` (scripts/setup.sh)\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let py: Vec<(String, String)> = text
        .lines()
        .map(|l| {
            let (a, b) = l.split_once(' ').unwrap();
            (a.to_string(), b.to_string())
        })
        .collect();
    let ours = python_reference_set();
    assert_eq!(py.len(), ours.len());
    for ((name, hex), (n2, cmd, seq)) in py.iter().zip(&ours) {
        assert_eq!(name, n2);
        let p = packet(cmd, *seq);
        let mine: String = p.iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(&mine, hex, "{name}: Rust vs Python spacepackets");
        // And the Python bytes decode to the command.
        let bytes = parse_hex_lines(hex).unwrap().remove(0);
        assert_eq!(&decode_telecommand(&bytes).unwrap().command, cmd);
    }
    println!(
        "python spacepackets cross-check: {} TCs byte-identical",
        ours.len()
    );
}

#[test]
fn icd_example_bytes_are_true() {
    // Ping TC, sequence count 0, and its TM[17,2] reply (sequence 0, time 0) as printed
    // in docs/icd.md.
    let tc = tc_frame(&Command::Ping, 0);
    let mut w = TmWriter::new();
    let mut buf = [0u8; MAX_TM_FRAME_LEN];
    let n = w.emit_ping_reply(TmTime::default(), &mut buf).unwrap();
    let hex = |b: &[u8]| {
        b.iter()
            .map(|x| format!("{x:02x}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let tc_hex = hex(&tc);
    let tm_frame_hex = hex(&buf[..n]);
    let tm_packet_hex = hex(&tm_packet(&buf[..n]));
    let tc_packet_hex = hex(&packet(&Command::Ping, 0));
    let icd = std::fs::read_to_string(concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/docs/icd.md"
    ))
    .unwrap_or_default();
    println!("ICD example:\n TC packet {tc_packet_hex}\n TC frame {tc_hex}\n TM packet {tm_packet_hex}\n TM frame {tm_frame_hex}");
    for (what, h) in [
        ("TC packet", &tc_packet_hex),
        ("TC frame", &tc_hex),
        ("TM packet", &tm_packet_hex),
        ("TM frame", &tm_frame_hex),
    ] {
        assert!(icd.contains(h.as_str()), "{what} `{h}` not in docs/icd.md");
    }
}

#[test]
fn ground_tc_upload_reassembles_the_table() {
    let dir = std::env::temp_dir().join(format!("m2ctl-link-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let geom = dir.join("calibrated.toml");
    let file = m2calib::files::GeometryFile {
        params: m2ctl::nominal::prototype_with_flight_limits(),
        provenance: vec![("calibration_id".into(), "cal-test-1".into())],
    };
    std::fs::write(&geom, m2calib::files::format_geometry(&file, "test")).unwrap();
    let req = || upload_procedure(&geom, 77, None, false);
    let mut seq = TcSequencer::new(100);
    let text = run_tc(&req().unwrap(), &mut seq, TcOutput::HexLines, false).unwrap();
    let frames = parse_hex_lines(std::str::from_utf8(&text).unwrap()).unwrap();
    assert_eq!(frames.len(), TABLE_LEN.div_ceil(TABLE_CHUNK_MAX_LEN) + 1);
    let mut image = vec![0u8; TABLE_LEN];
    let mut commit = None;
    for (i, f) in frames.iter().enumerate() {
        let out = deframe_all(f);
        let tc = decode_telecommand(out[0].as_ref().unwrap()).unwrap();
        assert_eq!(tc.request_id.seq_count(), 100 + i as u16);
        match tc.command {
            Command::LoadTableChunk(c) => image[c.range()].copy_from_slice(c.bytes()),
            Command::CommitTable { crc32 } => commit = Some(crc32),
            c => panic!("{c:?}"),
        }
    }
    let table = Table::decode(&image).unwrap();
    assert_eq!(table.table_id, 77);
    assert_eq!(&table.provenance.tag[..10], b"cal-test-1");
    assert_eq!(commit, Some(table.crc32()));
    assert_eq!(upload_commands(&table).unwrap().len(), frames.len());
    // Binary output is the frames back to back.
    let mut seq = TcSequencer::new(100);
    let bin = run_tc(&req().unwrap(), &mut seq, TcOutput::Binary, false).unwrap();
    assert_eq!(bin, frames.concat());
    assert_eq!(hex_lines(&frames).into_bytes(), text);
    // A geometry file without limits is refused with a message.
    std::fs::write(
        &geom,
        m2calib::files::format_geometry(
            &m2calib::files::GeometryFile {
                params: m2ctl::nominal::PROTOTYPE,
                provenance: vec![],
            },
            "x",
        ),
    )
    .unwrap();
    let e = req().unwrap_err();
    assert!(e.contains("[limits]"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn m2ground_tc_cli_writes_frames() {
    let exe = env!("CARGO_BIN_EXE_m2ground");
    let run = |args: &[&str]| {
        let o = std::process::Command::new(exe).args(args).output().unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8(o.stdout).unwrap()
    };
    let decoded = |out: &str| {
        let f = parse_hex_lines(out).unwrap();
        assert_eq!(f.len(), 1, "{out}");
        decode_telecommand(deframe_all(&f[0])[0].as_ref().unwrap()).unwrap()
    };
    let ping = run(&["tc", "ping"]);
    assert_eq!(
        ping.trim(),
        hex_lines(&[tc_frame(&Command::Ping, 0)]).trim()
    );
    let tc = decoded(&run(&[
        "tc",
        "--seq",
        "5",
        "move-relative",
        "x=1.5",
        "y=-2",
        "rx=-0.25",
    ]));
    assert_eq!(
        tc.command,
        Command::MoveRelative(WirePose::from_array([1500, -2000, 0, -250_000, 0, 0]))
    );
    assert_eq!(tc.request_id.seq_count(), 5);
    // Every telecommand of the mission database is reachable by its name.
    let pose = WirePose::from_array([0, 0, -1000, 0, 0, 2_000_000]);
    for (args, cmd) in [
        (vec!["stop"], Command::Stop),
        (vec!["housekeeping-one-shot"], Command::HousekeepingOneShot),
        (vec!["switch-bank"], Command::SwitchBank),
        (vec!["revert-to-nominal"], Command::RevertToNominal),
        (vec!["clear-fault"], Command::ClearFault),
        (
            vec!["MOVE_ABSOLUTE", "z=-1", "rz=2"],
            Command::MoveAbsolute(pose),
        ),
        (vec!["check-move", "rz=2", "z=-1"], Command::CheckMove(pose)),
        (
            vec!["direct-stroke", "leg=3", "delta=-0.5"],
            Command::DirectStroke {
                leg: 3,
                delta_nm: -500,
            },
        ),
        (
            vec!["activate-table", "table_id=42", "crc32=0x01234567"],
            Command::ActivateTable {
                table_id: 42,
                crc32: 0x0123_4567,
            },
        ),
        (
            vec!["commit-table", "crc32=4294967295"],
            Command::CommitTable { crc32: u32::MAX },
        ),
        (
            vec!["dump-table", "memory_id=upload_buffer"],
            Command::DumpTable(m2ctl::link::MemoryId::UploadBuffer),
        ),
        (
            vec!["load-table-chunk", "offset=512", "data=0a0b0c0d"],
            Command::LoadTableChunk(TableChunk::new(512, &[10, 11, 12, 13]).unwrap()),
        ),
        (
            vec!["set-parameter", "parameter_id=PIVOT_Z", "value=-250000000"],
            Command::SetParameters(
                m2ctl::link::command::ParameterValues::new(&[(3, -250_000_000)]).unwrap(),
            ),
        ),
        (
            vec!["report-parameter", "parameter_id=0x0010"],
            Command::ReportParameters(m2ctl::link::command::ParameterIds::new(&[0x10]).unwrap()),
        ),
    ] {
        let mut a = vec!["tc"];
        a.extend(&args);
        assert_eq!(decoded(&run(&a)).command, cmd, "{args:?}");
    }
    let names: std::collections::BTreeSet<String> = run(&["tc", "list"])
        .lines()
        .filter(|l| !l.starts_with(' '))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .collect();
    let described: std::collections::BTreeSet<String> = m2ground::mdb::mdb()
        .telecommands
        .iter()
        .map(|t| t.name.to_ascii_lowercase().replace('_', "-"))
        .collect();
    assert_eq!(names, described);
    // Nonsense is refused with its reason, and nothing is written.
    for (args, why) in [
        (vec!["move-absolute", "x=3000000"], "outside"),
        (vec!["move-absolute", "q=1"], "no argument q"),
        (vec!["move-absolute", "x=1", "x=2"], "twice"),
        (vec!["move-absolute", "x"], "name=value"),
        (vec!["move-absolute", "x=abc"], "not a number"),
        (vec!["direct-stroke", "leg=7", "delta=1"], "outside"),
        (vec!["direct-stroke", "leg=3"], "missing argument delta"),
        (
            vec!["set-parameter", "parameter_id=NOPE", "value=1"],
            "not one of",
        ),
        (
            vec!["set-parameter", "parameter_id=0x7777", "value=1"],
            "not one of",
        ),
        (vec!["dump-table", "memory_id=9"], "not one of"),
        (vec!["fly-to-the-moon"], "no such telecommand"),
    ] {
        let mut a = vec!["tc"];
        a.extend(&args);
        let o = std::process::Command::new(exe).args(&a).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} accepted");
        assert!(o.stdout.is_empty(), "{args:?} wrote {:?}", o.stdout);
        assert!(err.contains(why), "{args:?}: {err}");
    }
    let unframed = run(&["tc", "--unframed", "ping"]);
    assert_eq!(unframed.trim(), "18b2c00000062f11010000ee7d");
}

/// Issue 19, item 6: `m2ground tc` checks every argument against the controller's own
/// range. For each range the edge value is encoded (as the controller reads it back) and
/// the value just outside is refused with the argument's name and range, nothing written;
/// where the controller's check is a function of its own, that function is asked too, so
/// that the ground's range is the controller's.
#[test]
fn m2ground_tc_refuses_what_the_controller_refuses_and_takes_its_edges() {
    use m2ctl::controller::params::{ParamError, Parameters, PARAMETERS};
    use m2ctl::controller::schedule::MAX_OBT;
    use m2ctl::motion::stroke::{DirectStrokeLimits, StrokeMoveError};
    use m2ctl::motion::StrokeMove;
    use m2ground::tc::request_id_of;
    let exe = env!("CARGO_BIN_EXE_m2ground");
    let run = |args: &[String]| {
        let o = std::process::Command::new(exe)
            .arg("tc")
            .args(args)
            .output()
            .unwrap();
        (
            o.status.success(),
            o.stdout,
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let words = |s: &str| -> Vec<String> { s.split_whitespace().map(str::to_string).collect() };
    // The edge: accepted, one telecommand the flight decoder reads as `expected`.
    let accepted = |args: Vec<String>, expected: &dyn Fn(&Telecommand) -> bool| {
        let (ok, out, err) = run(&args);
        assert!(ok, "{args:?} refused: {err}");
        let frames = parse_hex_lines(&String::from_utf8_lossy(&out)).unwrap();
        assert_eq!(frames.len(), 1, "{args:?}");
        let tc = decode_telecommand(deframe_all(&frames[0])[0].as_ref().unwrap()).unwrap();
        assert!(expected(&tc), "{args:?}: {tc:?}");
    };
    // Just outside: refused, naming the argument and its range, nothing written.
    let refused = |args: Vec<String>, says: &[&str]| {
        let (ok, out, err) = run(&args);
        assert!(!ok, "{args:?} accepted");
        assert!(out.is_empty(), "{args:?} wrote {out:?}");
        for s in says {
            assert!(err.contains(s), "{args:?}: {err:?} does not say {s:?}");
        }
    };
    let mut cases = 0;

    // TC[20,3]: the value's range is that of the parameter named.
    let nominal = Table::nominal();
    for p in &PARAMETERS {
        let name = p.name.to_ascii_uppercase();
        let set = |v: i64| words(&format!("set-parameter parameter_id={name} value={v}"));
        for v in [p.min, p.max] {
            accepted(set(i64::from(v)), &|tc| {
                tc.command
                    == Command::SetParameters(command::ParameterValues::new(&[(p.id, v)]).unwrap())
            });
            let on_board = Parameters::default().with(&[(p.id, v)], &nominal);
            assert!(
                !matches!(on_board, Err(ParamError::OutOfRange(_))),
                "{name} {v}"
            );
        }
        for v in [i64::from(p.min) - 1, i64::from(p.max) + 1] {
            refused(
                set(v),
                &[
                    &format!("value = {v}: outside {}..={} {}", p.min, p.max, p.unit),
                    &name,
                ],
            );
            let on_board = Parameters::default().with(&[(p.id, v as i32)], &nominal);
            assert_eq!(on_board, Err(ParamError::OutOfRange(p.id)), "{name} {v}");
        }
        cases += 4;
    }

    // TC[11,4] release times: within the on-board clock, 0 ..= MAX_OBT (4,294,967.295 s).
    let release_of = |tc: &Telecommand| match tc.command {
        Command::Schedule(ScheduleCommand::Insert(b)) => b.activities().next().map(|a| a.release),
        _ => None,
    };
    let max_s = "4294967.295";
    accepted(words(&format!("schedule at={max_s} ping")), &|tc| {
        release_of(tc) == Some(MAX_OBT)
    });
    accepted(words("schedule at=0 ping"), &|tc| {
        release_of(tc)
            == Some(TmTime {
                seconds: 0,
                fraction: 0,
            })
    });
    refused(
        words("schedule at=4294967.296 ping"),
        &["at = 4294967.296", "outside 0..=4294967.295 s"],
    );
    refused(
        words("schedule at=-0.0001 ping"),
        &["at = -0.0001", "outside 0..=4294967.295 s"],
    );
    // The same in the mission database's form (Yamcs' arguments).
    let ping = |seq: u16| {
        let mut p = [0u8; MAX_TC_PACKET_LEN];
        let n = encode_telecommand(&Command::Ping, TcHeader::new(seq), &mut p).unwrap();
        p[..n]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<String>()
    };
    let insert = |s: &str, f: &str, tc: &str| {
        words(&format!(
            "schedule-insert-activity release_seconds={s} release_fraction={f} telecommand={tc}"
        ))
    };
    accepted(insert("4294967", "0.295", &ping(1)), &|tc| {
        release_of(tc) == Some(MAX_OBT)
    });
    refused(
        insert("4294967", "0.2951", &ping(1)),
        &["release time", "outside 0..=4294967.295 s"],
    );
    refused(
        insert("4294968", "0", &ping(1)),
        &["release_seconds = 4294968: outside 0..=4294967"],
    );
    refused(
        insert("0", "1", &ping(1)),
        &["release_fraction = 1: outside 0..="],
    );
    // The embedded telecommand: 13..64 bytes, one of this controller's, schedulable.
    let hex = |c: &Command| {
        let mut p = [0u8; MAX_TC_PACKET_LEN];
        let n = encode_telecommand(c, TcHeader::new(2), &mut p).unwrap();
        p[..n]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<String>()
    };
    assert_eq!(ping(1).len(), 2 * MIN_TC_PACKET_LEN);
    refused(
        insert("1", "0", &ping(1)[2..]),
        &["telecommand: 12 bytes, outside 13..=64"],
    );
    refused(
        insert("1", "0", &"00".repeat(65)),
        &["telecommand: 65 bytes, outside 13..=64"],
    );
    let mut bad_crc = ping(1);
    let last = if bad_crc.ends_with('0') { "1" } else { "0" };
    bad_crc.replace_range(bad_crc.len() - 1.., last);
    refused(
        insert("1", "0", &bad_crc),
        &["not a telecommand of this controller (link code 0x0505"],
    );
    refused(
        insert("1", "0", &hex(&Command::Schedule(ScheduleCommand::Reset))),
        &["SCHEDULE_RESET cannot be scheduled", "0x0510"],
    );
    let chunk = Command::LoadTableChunk(TableChunk::new(0, &[1]).unwrap());
    refused(
        insert("1", "0", &hex(&chunk)),
        &["LOAD_TABLE_CHUNK cannot be scheduled"],
    );
    refused(
        words("schedule at=1 load-table-chunk offset=0 data=01"),
        &["cannot be scheduled"],
    );
    cases += 13;

    // Direct stroke: legs 1..6; |delta| up to the largest DIRECT_MAX_DELTA (1,000 um).
    for leg in [1u8, 6] {
        accepted(words(&format!("direct-stroke leg={leg} delta=1")), &|tc| {
            tc.command
                == Command::DirectStroke {
                    leg,
                    delta_nm: 1_000,
                }
        });
    }
    for leg in [0, 7] {
        refused(
            words(&format!("direct-stroke leg={leg} delta=1")),
            &[&format!("leg = {leg}: outside 1..=6")],
        );
    }
    let max_delta_nm = PARAMETERS[m2ctl::controller::params::index::DIRECT_MAX_DELTA].max;
    assert_eq!(max_delta_nm, 1_000_000);
    for sign in [1, -1] {
        accepted(
            words(&format!("direct-stroke leg=2 delta={}", sign * 1000)),
            &|tc| {
                tc.command
                    == Command::DirectStroke {
                        leg: 2,
                        delta_nm: sign * max_delta_nm,
                    }
            },
        );
        refused(
            words(&format!(
                "direct-stroke leg=2 delta={}",
                f64::from(sign) * 1000.001
            )),
            &["delta = ", "outside -1000..=1000 um"],
        );
    }
    // On board, with DIRECT_MAX_DELTA at its largest: 1 mm is planned, 1.000001 mm refused.
    let in_force = Parameters::default()
        .with(&[(0x0014, max_delta_nm)], &nominal)
        .unwrap()
        .direct_limits(&nominal)
        .2;
    let limits = DirectStrokeLimits {
        max_delta_mm: in_force,
        ..DirectStrokeLimits::default()
    };
    assert!(StrokeMove::plan(&[0.0; 6], 1, 1.0, &limits).is_ok());
    assert_eq!(
        StrokeMove::plan(&[0.0; 6], 1, 1.000_001, &limits).err(),
        Some(StrokeMoveError::DeltaTooLarge)
    );
    cases += 8;

    // Table chunks: offset 0..TABLE_LEN-1, 1..128 bytes, offset + length <= TABLE_LEN.
    let load = |offset: usize, n: usize| {
        words(&format!(
            "load-table-chunk offset={offset} data={}",
            "5a".repeat(n)
        ))
    };
    for (offset, n) in [
        (TABLE_LEN - 4, 4),
        (TABLE_LEN - 1, 1),
        (0, TABLE_CHUNK_MAX_LEN),
    ] {
        accepted(load(offset, n), &|tc| {
            tc.command
                == Command::LoadTableChunk(TableChunk::new(offset as u16, &vec![0x5a; n]).unwrap())
        });
    }
    for (offset, n, says) in [
        (
            TABLE_LEN - 3,
            4,
            format!(
                "data: 4 bytes at offset {} end at {}, outside the table (offset + length <= {TABLE_LEN})",
                TABLE_LEN - 3,
                TABLE_LEN + 1
            ),
        ),
        (
            TABLE_LEN,
            1,
            format!("offset = {TABLE_LEN}: outside 0..={} byte", TABLE_LEN - 1),
        ),
        (
            0,
            TABLE_CHUNK_MAX_LEN + 1,
            "data: 129 bytes, outside 1..=128".to_string(),
        ),
        (0, 0, "data: 0 bytes, outside 1..=128".to_string()),
    ] {
        refused(load(offset, n), &[says.as_str()]);
        assert!(
            TableChunk::new(offset as u16, &vec![0x5a; n]).is_err(),
            "{offset} {n}"
        );
    }
    cases += 7;

    // TC[11,5]: only request IDs a schedule can hold (this controller's unsegmented TCs).
    let (first, last) = (request_id_of(0), request_id_of(0x3fff));
    assert_eq!(
        (
            first.packet_id,
            first.sequence_control,
            last.sequence_control
        ),
        (0x18b2, 0xc000, 0xffff)
    );
    for seq_control in [0xc000u16, 0xffff] {
        accepted(
            words(&format!(
                "schedule-delete-activity activity_packet_id=0x18b2 activity_sequence_control={seq_control:#06x}"
            )),
            &|tc| {
                tc.command
                    == Command::Schedule(ScheduleCommand::Delete(
                        RequestIdList::new(&[RequestId { packet_id: 0x18b2, sequence_control: seq_control }]).unwrap(),
                    ))
            },
        );
    }
    for (pid, sc, says) in [
        (
            "0x18b1",
            "0xc000",
            "activity_packet_id = 6321 (0x18b1): outside 6322 (0x18b2)..=6322 (0x18b2)",
        ),
        (
            "0x18b3",
            "0xc000",
            "activity_packet_id = 6323 (0x18b3): outside",
        ),
        (
            "0x18b2",
            "0xbfff",
            "activity_sequence_control = 49151 (0xbfff): outside 49152 (0xc000)..=65535 (0xffff)",
        ),
        (
            "0x18b2",
            "0x10000",
            "activity_sequence_control = 65536: outside 0..=65535",
        ),
    ] {
        refused(
            words(&format!(
                "schedule-delete-activity activity_packet_id={pid} activity_sequence_control={sc}"
            )),
            &[says],
        );
    }
    cases += 6;

    // Everything else within its wire type, or its enumeration.
    accepted(
        words("schedule-time-shift-all shift_seconds=2147483647 shift_fraction=0.9999847412109375"),
        &|tc| {
            tc.command
                == Command::Schedule(ScheduleCommand::TimeShiftAll(ObtOffset::from_parts(
                    i32::MAX,
                    0xffff,
                )))
        },
    );
    refused(
        words("schedule-time-shift-all shift_seconds=2147483648 shift_fraction=0"),
        &["shift_seconds = 2147483648: outside -2147483648..=2147483647 s"],
    );
    refused(
        words("schedule-time-shift-all shift_seconds=0 shift_fraction=1"),
        &["shift_fraction = 1: outside 0..="],
    );
    accepted(
        words("move-absolute x=2147483.647 rz=-2147.483648"),
        &|tc| {
            tc.command
                == Command::MoveAbsolute(WirePose::from_array([i32::MAX, 0, 0, 0, 0, i32::MIN]))
        },
    );
    refused(
        words("move-absolute x=2147483.648"),
        &["x = 2147483.648: outside -2147483.648..=2147483.647 um"],
    );
    refused(
        words("check-move rz=-2147.483649"),
        &["rz = -2147.483649: outside -2147.483648..=2147.483647 arcsec"],
    );
    accepted(words("commit-table crc32=0xffffffff"), &|tc| {
        tc.command == Command::CommitTable { crc32: u32::MAX }
    });
    refused(
        words("commit-table crc32=0x100000000"),
        &["crc32 = 4294967296: outside 0..=4294967295"],
    );
    accepted(words("set-time-report-rate rate=8"), &|tc| {
        tc.command == Command::SetTimeReportRate(TimeReportRate::Every { exponent: 8 })
    });
    refused(
        words("set-time-report-rate rate=9"),
        &["rate = 9: not one of"],
    );
    cases += 10;

    // The options: a 14-bit sequence count, 4-bit acknowledgement flags.
    accepted(words("--seq 16383 --ack 15 ping"), &|tc| {
        tc.request_id.seq_count() == 0x3fff && tc.ack == AckFlags::ALL
    });
    refused(
        words("--seq 16384 ping"),
        &["--seq", "16384 is not in 0..=16383"],
    );
    refused(words("--ack 16 ping"), &["--ack", "16 is not in 0..=15"]);
    cases += 3;
    println!("{cases} edge and outside cases");
}

/// The wire's rounding to whole nm / uas is libm's round-half-away-from-zero then a
/// saturating conversion, value for value: halves, their neighbours, the i32 range's
/// ends and 1,000,000 random f64 bit patterns. Negative control: truncation differs.
#[test]
fn round_sat_i32_is_libm_round_saturated() {
    use m2ctl::link::wire::round_sat_i32;
    let check = |v: f64| {
        assert_eq!(
            round_sat_i32(v),
            libm::round(v) as i32,
            "{v:e} ({:#x})",
            v.to_bits()
        )
    };
    let edges = [
        0.0,
        -0.0,
        0.5,
        -0.5,
        1.5,
        -1.5,
        2.5,
        -2.5,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        2147483647.0,
        2147483647.5,
        2147483648.0,
        -2147483648.0,
        -2147483648.25,
        -2147483648.5,
        -2147483649.0,
        1e300,
        -1e300,
        f64::MIN_POSITIVE,
    ];
    for v in edges {
        check(v);
    }
    for k in -100_000i64..100_000 {
        let half = k as f64 + 0.5;
        for v in [
            half,
            f64::from_bits(half.to_bits() + 1),
            f64::from_bits(half.to_bits() - 1),
        ] {
            check(v);
        }
    }
    // Half-integers and their neighbours near the saturation and at every exponent.
    for e in 0..34 {
        for k in [
            (1i64 << e) - 1,
            1i64 << e,
            (1i64 << e) + 1,
            2147483646,
            2147483647,
        ] {
            for s in [1.0, -1.0] {
                let half = s * (k as f64 + 0.5);
                for v in [
                    half,
                    f64::from_bits(half.to_bits() + 1),
                    f64::from_bits(half.to_bits() - 1),
                    s * k as f64,
                ] {
                    check(v);
                }
            }
        }
    }
    let mut rng = common::TestRng(0x853c_49e6_748f_ea9b);
    for _ in 0..1_000_000 {
        check(f64::from_bits(rng.bits()));
        // Magnitudes of the wire's values (up to ~2.2e9 nm or uas).
        check(rng.sym() * 2.2e9);
    }
    assert_ne!(round_sat_i32(2.7), 2.7f64 as i32);
}

/// ICD section 3: the failure data of 0x050D is the argument's 0-based index in the
/// application data, TC[8,1]'s function ID not counted.
#[test]
fn an_argument_out_of_range_names_its_index_not_counting_the_function_id() {
    let data_of = |p: &[u8]| match decode_telecommand(p) {
        Ok(tc) => panic!("accepted {tc:?}"),
        Err(r) => (r.error.code(), r.error.data()),
    };
    let edit = |c: &Command, f: &dyn Fn(&mut Vec<u8>)| {
        let mut p = packet(c, 3);
        f(&mut p);
        fix_crc(&mut p);
        p
    };
    // Application data starts at byte 11 (6 primary + 5 secondary header bytes).
    const AD: usize = 11;
    let ds = Command::DirectStroke {
        leg: 1,
        delta_nm: 5,
    };
    // Direct stroke: function ID at AD..AD+2, the leg at AD+2 is argument 0.
    for leg in [0u8, 7, 255] {
        assert_eq!(
            data_of(&edit(&ds, &|p| p[AD + 2] = leg)),
            (0x050d, 0),
            "leg {leg}"
        );
    }
    // Memory IDs (TC[6,5], TC[6,2]): argument 0.
    let dump = Command::DumpTable(MemoryId::ActiveTable);
    assert_eq!(data_of(&edit(&dump, &|p| p[AD] = 3)), (0x050d, 0));
    let chunk = Command::LoadTableChunk(TableChunk::new(0, &[1, 2, 3, 4]).unwrap());
    assert_eq!(data_of(&edit(&chunk, &|p| p[AD] = 2)), (0x050d, 0));
    // The count N: 0, or above 16 where 16 is the limit.
    let report = Command::ReportParameters(command::ParameterIds::new(&[0x0010]).unwrap());
    assert_eq!(data_of(&edit(&report, &|p| p[AD] = 0)), (0x050d, 0));
    let mut long = packet(&report, 3);
    long[AD] = 17;
    let crc_at = long.len() - 2;
    long.splice(crc_at..crc_at, std::iter::repeat_n(0u8, 16 * 2));
    let len = (long.len() - 7) as u16;
    long[4..6].copy_from_slice(&len.to_be_bytes());
    fix_crc(&mut long);
    assert_eq!(data_of(&long), (0x050d, 0));
    let del = Command::Schedule(ScheduleCommand::Delete(
        RequestIdList::new(&[RequestId::from_bytes([0x18, 0xb2, 0xc0, 0x05])]).unwrap(),
    ));
    assert_eq!(data_of(&edit(&del, &|p| p[AD] = 0)), (0x050d, 0));
    // TC[9,1]'s rate.
    let rate = Command::SetTimeReportRate(TimeReportRate::Every { exponent: 1 });
    assert_eq!(data_of(&edit(&rate, &|p| p[AD] = 9)), (0x050d, 0));
}

#[test]
fn nibble_crc16_equals_the_crc_crate() {
    use m2ctl::link::tc::{NibbleCrc16, CRC16};
    let reference = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);
    assert_eq!(CRC16.checksum(b"123456789"), crc::CRC_16_IBM_3740.check);
    assert_eq!(CRC16.checksum(&[]), reference.checksum(&[]));
    // Another catalogue entry through the same construction (its own check value).
    let xmodem = NibbleCrc16::new(&crc::CRC_16_XMODEM);
    assert_eq!(xmodem.checksum(b"123456789"), crc::CRC_16_XMODEM.check);
    let mut rng = common::TestRng(0x5eed_c0de_1616_0001);
    for _ in 0..20_000 {
        let len = (rng.bits() % 300) as usize;
        let bytes: Vec<u8> = (0..len).map(|_| rng.bits() as u8).collect();
        assert_eq!(
            CRC16.checksum(&bytes),
            reference.checksum(&bytes),
            "{bytes:02x?}"
        );
    }
}

/// The TM packet as spacepackets' creator writes it (what `TmWriter` used before its own
/// header writer): the reference of `tm_packets_equal_spacepackets_creator`.
fn spacepackets_tm(
    seq_count: u16,
    msg_counter: u16,
    message: (u8, u8),
    time: TmTime,
    source: &[u8],
) -> Vec<u8> {
    use arbitrary_int::{u11, u14};
    use spacepackets::ecss::tm::{PusTmCreator, PusTmSecondaryHeader};
    use spacepackets::ecss::{CreatorConfig, MessageTypeId};
    use spacepackets::{PacketId, PacketSequenceControl, SequenceFlags, SpHeader};
    let stamp = time.to_bytes();
    let sp = SpHeader::new(
        PacketId::new_for_tm(true, u11::new(M2_APID)),
        PacketSequenceControl::new(SequenceFlags::Unsegmented, u14::new(seq_count & 0x3fff)),
        0,
    );
    let sec = PusTmSecondaryHeader::new(
        MessageTypeId::new(message.0, message.1),
        msg_counter,
        0,
        &stamp,
    );
    let tm = PusTmCreator::new(sp, sec, source, CreatorConfig::default());
    let mut out = vec![0u8; MAX_TM_PACKET_LEN];
    let n = tm.write_to_slice(&mut out).unwrap();
    out.truncate(n);
    out
}

#[test]
fn tm_packets_equal_spacepackets_creator() {
    use m2ctl::link::tm::MAX_TM_SOURCE_DATA_LEN;
    use std::collections::BTreeMap;
    // The services whose message type counters the writer keeps; others carry 0.
    let counted = [
        service::VERIFICATION,
        service::HOUSEKEEPING,
        service::EVENT,
        service::MEMORY,
        service::FUNCTION,
        service::TEST,
        service::PARAMETER,
        service::TIME,
        service::SCHEDULING,
    ];
    let mut rng = common::TestRng(0x7e1e_3e77_0000_0019);
    let mut w = TmWriter::new();
    let mut counters = BTreeMap::<u8, u16>::new();
    let mut buf = [0u8; MAX_TM_FRAME_LEN];
    // Past the 14-bit sequence count's wrap and the first message counters' 2^16 wrap
    // (service 1 takes about half of the packets).
    for i in 0..140_000u32 {
        let svc = if rng.bits() % 2 == 0 {
            service::VERIFICATION
        } else {
            (rng.bits() % 256) as u8
        };
        let sub = rng.bits() as u8;
        let time = TmTime {
            seconds: rng.bits() as u32,
            fraction: rng.bits() as u16,
        };
        let len = if i % 7 == 0 {
            MAX_TM_SOURCE_DATA_LEN
        } else {
            (rng.bits() % (MAX_TM_SOURCE_DATA_LEN as u64 + 1)) as usize
        };
        let source: Vec<u8> = (0..len).map(|_| rng.bits() as u8).collect();
        let msg_counter = if counted.contains(&svc) {
            *counters.entry(svc).or_insert(0)
        } else {
            0
        };
        let want = spacepackets_tm(i as u16, msg_counter, (svc, sub), time, &source);
        let n = w.emit_packet(time, (svc, sub), &source, &mut buf).unwrap();
        assert_eq!(tm_packet(&buf[..n]), want, "packet {i}");
        if let Some(c) = counters.get_mut(&svc) {
            *c = c.wrapping_add(1);
        }
    }
    assert!(
        counters[&service::VERIFICATION] < 10_000,
        "service 1 wrapped"
    );
}

/// What the one emit path (`TmSource`) refuses, as the per-packet emitters with their
/// own buffers refused it: a summary beyond the schedule's 16 activities and a
/// parameter report beyond the source data (a too-small buffer), a dump chunk empty or
/// beyond 128 bytes (a bad chunk); nothing is counted.
#[test]
fn emitters_refuse_oversized_source_data_as_before() {
    use m2ctl::link::schedule::SummaryEntry;
    let mut w = TmWriter::new();
    let mut buf = [0u8; MAX_TM_FRAME_LEN];
    let t = TmTime::default();
    let entries = vec![SummaryEntry::default(); 17];
    assert_eq!(
        w.emit_schedule_summary(t, &entries, &mut buf),
        Err(EmitError::BufferTooSmall)
    );
    assert!(w.emit_schedule_summary(t, &entries[..16], &mut buf).is_ok());
    // The largest source data is the housekeeping report's: a count byte and as many
    // 6-byte entries as fit beside it (46 of the 279 bytes), one more does not.
    let fit = (m2ctl::link::hk::HK_REPORT_LEN - 1) / 6;
    let values = vec![(1u16, -1i32); fit + 1];
    assert_eq!(
        w.emit_parameter_report(t, &values, &mut buf),
        Err(EmitError::BufferTooSmall)
    );
    assert!(w.emit_parameter_report(t, &values[..fit], &mut buf).is_ok());
    assert_eq!(
        w.emit_table_dump_chunk(t, MemoryId::ActiveTable, 0, &[7; 129], &mut buf),
        Err(EmitError::BadChunk)
    );
    assert_eq!(w.next_seq_count(), 2);
}
