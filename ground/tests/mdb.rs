//! The mission database (`m2ground::mdb`) against the flight code: a telecommand,
//! housekeeping field, event, failure code or flag bit that the code has and the
//! description lacks (or describes differently) fails here. The XTCE generated from the
//! description is checked against the XTCE schema and against Yamcs in
//! `scripts/yamcs-e2e.sh`.

#![cfg(feature = "host")]

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use m2ctl::kinematics::Refusals;
use m2ctl::link::command::WirePose;
use m2ctl::link::hk::{ScheduleHk, HK_REPORT_LEN};
use m2ctl::link::tc::TcHeader;
use m2ctl::link::tm::{parse_tm, EventSeverity, TmTime, TmWriter, Verification};
use m2ctl::link::{
    AckFlags, Command, Deframer, Housekeeping, LinkError, MemoryId, RequestId, M2_APID,
};
use m2ctl::table::{Table, TABLE_LEN};
use m2ground::mdb::{self, mdb, telecommand_name, ArgValue, Field, Meaning, Telecommand, Wire};

fn src(path: &str) -> String {
    let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join(path);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Raw argument samples for one field: both range ends, zero/one inside, a middle value.
fn samples(f: &Field) -> Vec<ArgValue> {
    match f.wire {
        Wire::Bytes { min_len, max_len } => [min_len, (min_len + max_len) / 2, max_len]
            .iter()
            .map(|&n| ArgValue::Bytes((0..n).map(|i| (i * 37 + 11) as u8).collect()))
            .collect(),
        // An embedded telecommand (TC[11,4]): real packets of this controller, the
        // shortest (ping), a move and one with other header fields.
        Wire::Packet { .. } => [
            (Command::Ping, TcHeader::new(3)),
            (
                Command::MoveAbsolute(WirePose::from_array([1_500, 0, -20, 0, 0, 7])),
                TcHeader::new(0x3fff),
            ),
            (
                Command::Stop,
                TcHeader {
                    seq_count: 9,
                    source_id: 0xbeef,
                    ack: AckFlags::NONE,
                },
            ),
        ]
        .iter()
        .map(|(c, h)| {
            let mut buf = [0u8; 256];
            let n = m2ctl::link::encode_telecommand(c, *h, &mut buf).unwrap();
            ArgValue::Bytes(buf[..n].to_vec())
        })
        .collect(),
        // An enumeration's samples are its values (it may have gaps).
        _ if matches!(f.meaning, Meaning::Enum { .. }) => {
            let Meaning::Enum { enumeration } = f.meaning else {
                unreachable!()
            };
            let e = mdb()
                .enums
                .into_iter()
                .find(|e| e.name == enumeration)
                .unwrap();
            e.values.iter().map(|v| ArgValue::Int(v.0)).collect()
        }
        w => {
            let (lo, hi) = match f.meaning {
                Meaning::Number {
                    range: Some((lo, hi)),
                    ..
                } => (f.to_raw(lo).unwrap(), f.to_raw(hi).unwrap()),
                _ => w.raw_range().unwrap(),
            };
            let mut v = vec![lo, hi, lo + (hi - lo) / 3];
            if lo <= 1 && hi >= 1 {
                v.push(1);
            }
            v.into_iter().map(ArgValue::Int).collect()
        }
    }
}

/// Argument vectors covering every sample of every argument (others at their first
/// sample), for a table-chunk TC with offsets that keep the chunk inside the table.
fn arg_sets(tc: &Telecommand) -> Vec<Vec<ArgValue>> {
    let args: Vec<&Field> = tc.arguments().collect();
    let per: Vec<Vec<ArgValue>> = args.iter().map(|f| samples(f)).collect();
    let mut sets = vec![per.iter().map(|s| s[0].clone()).collect::<Vec<_>>()];
    for (i, s) in per.iter().enumerate() {
        for v in s {
            let mut set: Vec<ArgValue> = per.iter().map(|s| s[0].clone()).collect();
            set[i] = v.clone();
            sets.push(set);
        }
    }
    if tc.name == "LOAD_TABLE_CHUNK" {
        // Offset + length must stay inside the table: pair them.
        sets = vec![
            vec![ArgValue::Int(0), ArgValue::Bytes(vec![7; 128])],
            vec![ArgValue::Int(384), ArgValue::Bytes(vec![0x5a; 128])],
            vec![ArgValue::Int(512), ArgValue::Bytes(vec![1, 2, 3, 4])],
            vec![ArgValue::Int(515), ArgValue::Bytes(vec![0xff])],
        ];
    }
    sets
}

#[test]
fn every_telecommand_the_parser_knows_is_described_and_no_other() {
    let m = mdb();
    let described: BTreeSet<(u8, u8)> = m
        .telecommands
        .iter()
        .map(|t| (t.service, t.subtype))
        .collect();
    let mut known = BTreeSet::new();
    for svc in 0..=255u8 {
        for sub in 0..=255u8 {
            match Command::parse(svc, sub, &[]) {
                Err(LinkError::UnknownService { .. }) | Err(LinkError::UnknownSubtype { .. }) => {}
                _ => {
                    known.insert((svc, sub));
                }
            }
        }
    }
    assert_eq!(known, described, "PUS (service, subtype) pairs");

    let (fsvc, fsub) = Command::Stop.message_type();
    let described_fns: BTreeSet<u16> = m
        .telecommands
        .iter()
        .filter_map(|t| t.function_id)
        .collect();
    let mut known_fns = BTreeSet::new();
    for id in 0..=u16::MAX {
        let mut ad = id.to_be_bytes().to_vec();
        ad.extend([0u8; 32]);
        if !matches!(
            Command::parse(fsvc, fsub, &ad),
            Err(LinkError::UnknownFunction { .. })
        ) {
            known_fns.insert(id);
        }
    }
    assert_eq!(known_fns, described_fns, "TC[8,1] function IDs");
    println!(
        "{} telecommands described: {} PUS types, {} functions",
        m.telecommands.len(),
        known.len(),
        known_fns.len()
    );
}

#[test]
fn every_described_telecommand_encodes_as_the_link_does() {
    let m = mdb();
    let headers = [
        TcHeader::new(0),
        TcHeader {
            seq_count: 0x3fff,
            source_id: 0xbeef,
            ack: AckFlags(0b1001),
        },
        TcHeader {
            seq_count: 77,
            source_id: 1,
            ack: AckFlags::NONE,
        },
    ];
    let mut checked = 0;
    for tc in &m.telecommands {
        let names: BTreeSet<&str> = tc.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(
            names.len(),
            tc.fields.len(),
            "{}: duplicate field names",
            tc.name
        );
        for args in arg_sets(tc) {
            let cmd = (tc.build)(&args).unwrap_or_else(|e| panic!("{}: {e}", tc.name));
            assert_eq!(telecommand_name(&cmd), tc.name);
            assert_eq!(cmd.message_type(), (tc.service, tc.subtype), "{}", tc.name);
            assert_eq!(cmd.function_id().map(|f| f.code()), tc.function_id);
            let app = tc.encode_app_data(&args).unwrap();
            let mut link_app = [0u8; 256];
            let n = cmd.emit_app_data(&mut link_app).unwrap();
            assert_eq!(app, link_app[..n], "{} {args:?}", tc.name);
            assert_eq!(
                Command::parse(tc.service, tc.subtype, &app),
                Ok(cmd),
                "{}: the flight parser reads the description's bytes back",
                tc.name
            );
            for h in headers {
                assert_eq!(
                    tc.encode_packet(&args, h).unwrap(),
                    tc.encode_by_link(&args, h).unwrap(),
                    "{} {args:?} {h:?}",
                    tc.name
                );
                checked += 1;
            }
        }
    }
    println!("{checked} telecommand packets encoded by the description == by the link");
}

#[test]
fn out_of_range_arguments_are_refused_by_the_description() {
    let m = mdb();
    let stroke = m.telecommand("DIRECT_STROKE").unwrap();
    let leg = stroke.arguments().next().unwrap();
    assert!(leg.to_raw(0.0).is_err() && leg.to_raw(7.0).is_err());
    assert_eq!(leg.to_raw(6.0), Ok(6));
    let mv = m.telecommand("MOVE_ABSOLUTE").unwrap();
    let x = mv.arguments().next().unwrap();
    assert_eq!(x.to_raw(12.5), Ok(12_500), "um -> nm");
    assert!(x.to_raw(2_147_484.0).is_err(), "beyond the i32 nm range");
    let rx = mv.arguments().nth(3).unwrap();
    assert_eq!(rx.to_raw(-3.25), Ok(-3_250_000), "arcsec -> micro-arcsec");
    // The flight parser refuses what the description refuses.
    let bad_leg = stroke
        .encode_app_data(&[ArgValue::Int(7), ArgValue::Int(0)])
        .unwrap();
    assert_eq!(
        Command::parse(stroke.service, stroke.subtype, &bad_leg),
        Err(LinkError::InvalidArgument { index: 0 })
    );
}

/// Every member distinct, none zero: a field read at the wrong offset shows.
fn distinct_housekeeping() -> Housekeeping {
    // No `..Default::default()`: a new member does not compile until it is set here.
    Housekeeping {
        state: 3,
        boot_source: 2,
        active_bank: 1,
        fk_iterations: 9,
        fk_valid: true,
        cycle_counter: 0x0102_0304,
        fault_flags: 0x0000_0081,
        warning_flags: 0x0001_0000,
        refusal_bits: 0x0102_0408,
        active_table_id: 0x1122_3344,
        active_table_crc32: 0xdead_beef,
        pose_fk: WirePose::from_array([-1_500, 2_500, -3_500, 4_000_000, -5_000_000, 6_000_000]),
        pose_commanded: WirePose::from_array([11, -22, 33, -44, 55, -66]),
        strokes_commanded_nm: [-101, 202, -303, 404, -505, 606],
        encoders_nm: [1_100, -2_200, 3_300, -4_400, 5_500, -6_600],
        tc_accepted: 0xabcd,
        tc_rejected: 0x1234,
        last_failure_code: 0x0604,
        moving_legs: 0b10_1101,
        fault_legs: 0b01_0010,
        pending_bank: 2,
        pending_table_id: 0x5566_7788,
        job: 3,
        selected_source: 1,
        tm_dropped: 0x0a0b,
        tc_frames_dropped: 0x0c0d,
        uart_overruns: 0x0e0f,
        cycle_overruns: 0x1011,
        reset_cause: 4,
        boot_count: 0x1213,
        bank_health: 2,
        pivot_nm: [-7_070_707, 8_080_808, -9_090_909],
        pose_fk_operator: WirePose::from_array([71, -72, 73, -74_000, 75_000, -76_000]),
        pose_commanded_operator: WirePose::from_array([-81, 82, -83, 84_000, -85_000, 86_000]),
        parameters_set: 0x0004_0021,
        schedule: ScheduleHk {
            activities: 14,
            release_enabled: true,
            released: 0x1415,
            failed: 0x1617,
            next_release: TmTime {
                seconds: 0x1819_1a1b,
                fraction: 0x1c1d,
            },
            time_report_rate: 5,
        },
        limit_lower_legs: 0b00_0101,
        limit_upper_legs: 0b10_1000,
        reference_legs: 0b01_0001,
        switch_unreadable_legs: 0b00_0110,
        in_position_legs: 0b10_1101,
        temperatures_centi_k: [
            29_301, 29_402, 29_503, 29_604, 29_705, 29_806, 29_907, 30_008,
        ],
        sensors_open: 0b0000_0011,
        sensors_short: 0b0011_0000,
        sensors_stuck: 0b1100_0000,
        thermal_state: 0b011,
        thermal_offsets_nm: [-1_001, 2_002, -3_003, 4_004, -5_005, 6_006],
    }
}

#[test]
fn housekeeping_fields_are_read_back_by_the_description() {
    let hk = distinct_housekeeping();
    let mut bytes = [0u8; HK_REPORT_LEN];
    hk.emit(&mut bytes);
    let fields = mdb::housekeeping_fields();
    let mut covered = vec![0u8; HK_REPORT_LEN];
    for (f, get) in &fields {
        let n = f
            .wire
            .fixed_len()
            .expect("housekeeping fields are fixed-size");
        for c in covered.iter_mut().skip(f.offset).take(n) {
            *c += 1;
        }
        let raw = f.read_raw(&bytes).unwrap_or_else(|| panic!("{}", f.name));
        match (get, &f.meaning) {
            (Some(get), _) => assert_eq!(raw, get(&hk), "{} at offset {}", f.name, f.offset),
            (None, Meaning::Fixed { value }) => assert_eq!(raw, *value, "{}", f.name),
            (None, m) => panic!("{}: no accessor and not a constant ({m:?})", f.name),
        }
    }
    assert!(
        covered.iter().all(|&c| c == 1),
        "fields must tile the {HK_REPORT_LEN} bytes exactly once: {covered:?}"
    );
    assert_eq!(
        Housekeeping::parse(&bytes),
        Some(hk),
        "the link reads its own report back"
    );
    // Units and calibrations of the poses: the FK pose x is -1.5 um, rx is 4 arcsec.
    let by_name: BTreeMap<&str, &Field> =
        fields.iter().map(|(f, _)| (f.name.as_str(), f)).collect();
    let x = by_name["pose_fk_x"];
    assert_eq!(x.to_eng(x.read_raw(&bytes).unwrap()), -1.5);
    let rx = by_name["pose_fk_rx"];
    assert_eq!(rx.to_eng(rx.read_raw(&bytes).unwrap()), 4.0);
    assert!(matches!(
        x.meaning,
        Meaning::Number {
            unit: Some("um"),
            ..
        }
    ));
    assert!(matches!(
        rx.meaning,
        Meaning::Number {
            unit: Some("arcsec"),
            ..
        }
    ));
    println!(
        "{} housekeeping fields tile {HK_REPORT_LEN} bytes",
        fields.len()
    );
}

/// Source data of a TM packet the link's writer emits.
fn emitted(f: impl FnOnce(&mut TmWriter, &mut [u8]) -> usize) -> (Vec<u8>, u8, u8) {
    let mut w = TmWriter::new();
    let mut frame = [0u8; m2ctl::link::MAX_TM_FRAME_LEN];
    let n = f(&mut w, &mut frame);
    let mut d: Deframer<{ m2ground::gateway::TM_DEFRAMER_LEN }> = Deframer::new();
    let pkt = frame[..n]
        .iter()
        .find_map(|b| d.push_byte(*b).map(|r| r.unwrap().to_vec()))
        .unwrap();
    let tm = parse_tm(&pkt).unwrap();
    assert_eq!(tm.apid, M2_APID);
    (
        pkt[mdb::TM_SOURCE_DATA_OFFSET..pkt.len() - 2].to_vec(),
        tm.service,
        tm.subtype,
    )
}

fn field_values(p: &m2ground::mdb::TmPacket, data: &[u8]) -> BTreeMap<String, i64> {
    p.fields
        .iter()
        .filter_map(|f| f.read_raw(data).map(|v| (f.name.clone(), v)))
        .collect()
}

#[test]
fn other_tm_packets_are_read_back_by_the_description() {
    let m = mdb();
    let rid = RequestId {
        packet_id: 0x18b2,
        sequence_control: 0xc000 | 1234,
    };
    let t = TmTime::from_millis(1500);
    for (report, name) in [
        (Verification::AcceptanceSuccess, "verification_success"),
        (Verification::CompletionSuccess, "verification_success"),
        (
            Verification::StartFailure {
                code: 0x0604,
                data: 0x0000_0100,
            },
            "verification_failure",
        ),
        (
            Verification::CompletionFailure {
                code: 0x0708,
                data: 7,
            },
            "verification_failure",
        ),
    ] {
        let (data, svc, sub) = emitted(|w, out| w.emit_verification(t, rid, report, out).unwrap());
        let p = m.tm_packet(name).unwrap();
        assert_eq!((p.service, p.fixed_len), (svc, Some(data.len())));
        assert!(p.subtypes.contains(&sub), "{name}: subtype {sub}");
        let v = field_values(p, &data);
        assert_eq!(v["tc_packet_id"], i64::from(rid.packet_id));
        assert_eq!(v["tc_sequence_control"], i64::from(rid.sequence_control));
        if let Some((code, datum)) = report.failure() {
            assert_eq!(
                (v["failure_code"], v["failure_data"]),
                (i64::from(code), i64::from(datum))
            );
        }
    }
    for sev in [
        EventSeverity::Info,
        EventSeverity::Low,
        EventSeverity::Medium,
        EventSeverity::High,
    ] {
        let (data, svc, sub) = emitted(|w, out| {
            w.emit_event(t, sev, 0x0011, [0x0706, 0xfeed_f00d], out)
                .unwrap()
        });
        let p = m.tm_packet("event").unwrap();
        assert_eq!((p.service, p.fixed_len), (svc, Some(data.len())));
        assert!(p.subtypes.contains(&sub));
        let v = field_values(p, &data);
        assert_eq!(
            (v["event_id"], v["event_aux0"], v["event_aux1"]),
            (0x0011, 0x0706, 0xfeed_f00d)
        );
    }
    let chunk: Vec<u8> = (0..77u8).collect();
    let (data, svc, sub) = emitted(|w, out| {
        w.emit_table_dump_chunk(t, MemoryId::ActiveTable, 256, &chunk, out)
            .unwrap()
    });
    let p = m.tm_packet("table_dump").unwrap();
    assert_eq!((p.service, p.subtypes.as_slice()), (svc, [sub].as_slice()));
    let v = field_values(p, &data);
    assert_eq!((v["dump_memory_id"], v["dump_offset"]), (2, 256));
    let bytes_field = p
        .fields
        .iter()
        .find(|f| matches!(f.wire, Wire::Bytes { .. }))
        .unwrap();
    let len = u16::from_be_bytes([data[bytes_field.offset], data[bytes_field.offset + 1]]);
    assert_eq!(&data[bytes_field.offset + 2..], &chunk[..]);
    assert_eq!(usize::from(len), chunk.len());
    let (data, svc, sub) = emitted(|w, out| w.emit_ping_reply(t, out).unwrap());
    let p = m.tm_packet("ping_reply").unwrap();
    assert_eq!(
        (p.service, p.subtypes.as_slice(), data.len()),
        (svc, [sub].as_slice(), 0)
    );
    let (data, _, _) = emitted(|w, out| {
        w.emit_housekeeping(t, &distinct_housekeeping(), out)
            .unwrap()
    });
    assert_eq!(
        m.tm_packet("housekeeping").unwrap().fixed_len,
        Some(data.len())
    );
}

/// `NAME: u16 = 0x....;` constants inside `pub mod <module> { ... }` of a source file.
fn consts_in_module(text: &str, module: &str) -> BTreeMap<String, u16> {
    let start = text.find(&format!("pub mod {module}")).expect("module");
    let body = &text[start..];
    let end = body.find("\n}").expect("module end");
    body[..end]
        .lines()
        .filter_map(|l| {
            let l = l.trim();
            let rest = l.strip_prefix("pub const ")?;
            let (name, value) = rest.split_once(": u16 = ")?;
            let value = value.trim_end_matches(';');
            let v = u16::from_str_radix(value.trim_start_matches("0x"), 16).ok()?;
            Some((name.to_string(), v))
        })
        .collect()
}

#[test]
fn every_event_is_described_with_its_id_and_severities() {
    let code_events = consts_in_module(&src("src/link/tm.rs"), "event_id");
    assert!(code_events.len() >= 10, "{code_events:?}");
    let described: BTreeMap<String, u16> = mdb::events()
        .iter()
        .map(|e| (e.name.to_string(), e.id))
        .collect();
    assert_eq!(code_events, described, "event IDs");

    // Severities at every place the controller sends the event: the EventSeverity
    // variants named in the statement that emits it.
    let ctl: String = [
        "mod",
        "commands",
        "motion",
        "jobs",
        "verification",
        "telemetry",
        "schedule",
        "time",
    ]
    .iter()
    .map(|f| src(&format!("src/controller/{f}.rs")))
    .collect();
    let mut seen: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut prev_end = 0;
    for (at, _) in ctl.match_indices("event::") {
        let name: String = ctl[at + 7..]
            .chars()
            .take_while(|c| c.is_ascii_uppercase() || *c == '_')
            .collect();
        if !described.contains_key(&name) {
            continue;
        }
        // From the previous event's name (or 400 bytes back) to this one.
        let window = &ctl[prev_end.max(at.saturating_sub(400))..at];
        prev_end = at;
        for (sev, label) in [
            (EventSeverity::Info, "Info"),
            (EventSeverity::Low, "Low"),
            (EventSeverity::Medium, "Medium"),
            (EventSeverity::High, "High"),
        ] {
            if window.contains(&format!("EventSeverity::{label}")) {
                seen.entry(name.clone())
                    .or_default()
                    .insert(mdb::severity_name(sev).to_string());
            }
        }
    }
    for e in mdb::events() {
        let want: BTreeSet<String> = e
            .severities
            .iter()
            .map(|s| s.severity.to_string())
            .collect();
        assert_eq!(seen.get(e.name), Some(&want), "severities of {}", e.name);
    }
}

#[test]
fn every_failure_code_in_the_code_is_enumerated() {
    let m = mdb();
    let codes = &m
        .enums
        .iter()
        .find(|e| e.name == "failure_code")
        .unwrap()
        .values;
    let by_code: BTreeMap<i64, &str> = codes.iter().map(|(v, l, _)| (*v, l.as_str())).collect();
    assert_eq!(by_code.len(), codes.len(), "failure codes unique");
    let labels: BTreeSet<&str> = codes.iter().map(|(_, l, _)| l.as_str()).collect();
    assert_eq!(labels.len(), codes.len(), "labels unique");
    // Every `=> 0x0NNN` arm of a `code()` in the flight sources.
    let mut found = BTreeSet::new();
    for file in [
        "src/link/error.rs",
        "src/kinematics/geometry.rs",
        "src/kinematics/ik.rs",
        "src/kinematics/fk.rs",
        "src/table/layout.rs",
        "src/table/validate.rs",
        "src/table/store/mod.rs",
        "src/motion/trajectory.rs",
        "src/motion/stroke.rs",
        "src/controller/error.rs",
        "src/controller/params.rs",
        "src/controller/schedule.rs",
    ] {
        for line in src(file).lines() {
            if let Some((_, rest)) = line.split_once("=> 0x0") {
                let hex: String = rest.chars().take_while(|c| c.is_ascii_hexdigit()).collect();
                if hex.len() == 3 {
                    found.insert(i64::from_str_radix(&hex, 16).unwrap());
                }
            }
        }
    }
    let missing: Vec<String> = found
        .iter()
        .filter(|c| !by_code.contains_key(c))
        .map(|c| format!("{c:#06x}"))
        .collect();
    assert!(
        missing.is_empty(),
        "codes in the sources but not enumerated: {missing:?}"
    );
    assert!(found.len() >= 60, "{} codes found", found.len());
    println!(
        "{} failure codes enumerated, {} found in the sources",
        codes.len(),
        found.len()
    );
}

#[test]
fn every_fault_flag_and_refusal_bit_is_named() {
    // Flags: every `pub const NAME: Self = Self(1 << n);` of supervision/flags.rs.
    let mut code_flags = BTreeMap::new();
    for line in src("src/supervision/flags.rs").lines() {
        let l = line.trim();
        if let Some(rest) = l.strip_prefix("pub const ") {
            if let Some((name, v)) = rest
                .split_once(": Self = Self(1 << ")
                .filter(|(n, _)| !n.starts_with("ALL_"))
            {
                let bit: u32 = v.trim_end_matches(");").parse().unwrap();
                code_flags.insert(name.to_string(), bit);
            }
        }
    }
    let described: BTreeMap<String, u32> = mdb::fault_flag_bits()
        .into_iter()
        .map(|(b, n, _)| (n, b))
        .collect();
    assert_eq!(code_flags, described, "fault/warning flags");

    let bits = mdb::refusal_bits();
    let positions: BTreeSet<u32> = bits.iter().map(|b| b.0).collect();
    assert_eq!(positions.len(), bits.len(), "refusal bits distinct");
    let all = Refusals {
        non_finite: true,
        axes_outside: 0x3f,
        legs_unreachable: 0x3f,
        legs_below_min: 0x3f,
        legs_above_max: 0x3f,
    }
    .to_bits();
    let union = positions.iter().fold(0u32, |a, b| a | (1 << b));
    assert_eq!(
        union, all,
        "the named refusal bits are exactly the word's bits"
    );
}

#[test]
fn the_json_export_holds_the_whole_description() {
    let m = mdb();
    let v: serde_json::Value = serde_json::from_str(&m.to_json()).unwrap();
    assert_eq!(v["link"]["apid"], M2_APID);
    assert_eq!(
        v["telecommands"].as_array().unwrap().len(),
        m.telecommands.len()
    );
    assert_eq!(v["telemetry"].as_array().unwrap().len(), m.telemetry.len());
    // Every enum/bit-field reference resolves.
    let enums: BTreeSet<&str> = m.enums.iter().map(|e| e.name).collect();
    let bitf: BTreeSet<&str> = m.bit_fields.iter().map(|b| b.name).collect();
    let fields = m
        .telecommands
        .iter()
        .flat_map(|t| t.fields.iter())
        .chain(m.telemetry.iter().flat_map(|t| t.fields.iter()));
    for f in fields {
        match &f.meaning {
            Meaning::Enum { enumeration } => assert!(enums.contains(enumeration), "{}", f.name),
            Meaning::Bits { bit_field } => assert!(bitf.contains(bit_field), "{}", f.name),
            _ => {}
        }
    }
    // Parameter names are unique across TM packets (one Yamcs namespace).
    let mut names = BTreeSet::new();
    for p in &m.telemetry {
        for f in &p.fields {
            if p.name == "verification_failure" && f.name.starts_with("tc_") {
                continue; // the request ID is shared by both verification layouts
            }
            assert!(
                names.insert(f.name.clone()) || p.name == "verification_success",
                "{}",
                f.name
            );
        }
    }
}

#[test]
fn every_parameter_is_described_with_its_unit_range_and_default() {
    use m2ctl::controller::params::PARAMETERS;
    let m = mdb();
    let ids = &m
        .enums
        .iter()
        .find(|e| e.name == "parameter_id")
        .unwrap()
        .values;
    assert_eq!(ids.len(), PARAMETERS.len());
    for (d, (id, label, meaning)) in PARAMETERS.iter().zip(ids) {
        let text = mdb::parameter_description(d.name)
            .unwrap_or_else(|| panic!("parameter {} ({:#06x}) has no description", d.name, d.id));
        assert_eq!(
            (*id, label.as_str()),
            (i64::from(d.id), d.name.to_ascii_uppercase().as_str())
        );
        assert!(
            meaning.starts_with(&text) && meaning.contains(d.unit),
            "{meaning}"
        );
    }
}

/// A table whose every field differs from the nominal one's and from its neighbours'.
fn distinct_table() -> Table {
    let mut t = Table::nominal();
    t.table_id = 0xA1A2_A3A4;
    t.provenance.calibration_id = 0xB1B2_B3B4;
    t.provenance.tag = *b"ICD-LAYOUT-CHECK";
    for (i, leg) in t.legs.iter_mut().enumerate() {
        leg.a_mm[0] += 0.001 * (i + 1) as f64;
        leg.b_mm[2] -= 0.002 * (i + 1) as f64;
    }
    t.p0_mm = [1.25, -2.5, 3.75];
    t.stroke_limits.min_mm[2] = -4.5;
    t.stroke_limits.max_mm[4] = 4.25;
    t.workspace.translation_mm[1] = 1.5;
    t.workspace.rotation_rad[2] = 1e-3;
    t.supervision.following_error_warning_mm = 0.125;
    t.supervision.following_error_fault_mm = 0.25;
    t.supervision.encoder_jump_mm_per_cycle = 0.0625;
    t.supervision.stuck_min_progress_mm = 0.003;
    t.supervision.stuck_detection_cycles = 0x1234;
    t.supervision.warning_debounce_cycles = 7;
    t.supervision.fault_debounce_cycles = 9;
    t
}

#[test]
fn table_image_rows_are_where_the_encoder_puts_them() {
    let rows = mdb::table_image();
    for t in [Table::nominal(), distinct_table()] {
        let bytes = t.to_bytes();
        let mut at = 0;
        for r in &rows {
            assert_eq!(r.offset, at, "{}", r.field);
            assert_eq!(
                &bytes[r.offset..r.offset + r.size],
                (r.bytes_of)(&t).as_slice(),
                "{} at {}+{}",
                r.field,
                r.offset,
                r.size
            );
            at += r.size;
        }
        assert_eq!(at, TABLE_LEN, "the rows tile the image");
        assert_eq!(Table::decode(&bytes), Ok(t), "the image decodes back");
    }
}

#[test]
fn event_words_are_named_from_the_description_s_own_vocabularies() {
    let m = mdb();
    let mut named = 0;
    for e in &m.events {
        for parts in [&e.aux0_decode, &e.aux1_decode] {
            let mut used = 0u64;
            for p in parts.iter() {
                match p.decode {
                    mdb::AuxDecode::Enum { enumeration } => assert!(
                        m.enums.iter().any(|x| x.name == enumeration),
                        "{}: no enumeration {enumeration}",
                        e.name
                    ),
                    mdb::AuxDecode::Bits { bit_field } => {
                        let f = m.bit_fields.iter().find(|x| x.name == bit_field);
                        let f = f.unwrap_or_else(|| panic!("{}: no bit field {bit_field}", e.name));
                        assert!(
                            f.bits.iter().all(|(b, _, _)| *b < p.width),
                            "{}: {bit_field} has bits beyond its {} bits",
                            e.name,
                            p.width
                        );
                    }
                }
                assert!(p.width > 0 && p.shift + p.width <= 32, "{}: {p:?}", e.name);
                let mask = ((1u64 << p.width) - 1) << p.shift;
                assert_eq!(used & mask, 0, "{}: parts overlap", e.name);
                used |= mask;
                named += 1;
            }
        }
    }
    assert!(named >= 10, "{named} named parts");
    // Every state pair reads back as the states' Rust names.
    use m2ctl::controller::State;
    let states = [
        State::Idle,
        State::Moving,
        State::Stopping,
        State::StrokeMoving,
        State::Faulted,
    ];
    for a in states {
        for b in states {
            let (_, text) = m
                .event_text(
                    m2ctl::link::tm::event_id::STATE_CHANGED,
                    u32::from(a.code()),
                    u32::from(b.code()),
                )
                .unwrap();
            assert_eq!(
                text,
                format!(
                    "controller state {} -> {}",
                    mdb::upper_snake(&format!("{a:?}")),
                    mdb::upper_snake(&format!("{b:?}"))
                )
            );
        }
    }
    // Every failure code in a MOVE_REFUSED reads back as its label.
    for c in mdb::failure_codes() {
        let (_, text) = m
            .event_text(
                m2ctl::link::tm::event_id::MOVE_REFUSED,
                0,
                u32::from(c.code),
            )
            .unwrap();
        assert!(
            text.ends_with(&format!("failure code {}", c.label)),
            "{text}"
        );
        assert!(text.contains("refusal bits none (0x0)"), "{text}");
    }
}

#[test]
fn calibrated_numbers_show_one_raw_count_and_no_rounding_noise() {
    let m = mdb();
    let fields = m
        .telemetry
        .iter()
        .flat_map(|p| p.fields.iter())
        .chain(m.telecommands.iter().flat_map(|t| t.fields.iter()));
    let mut checked = 0;
    for f in fields {
        let Meaning::Number { scale, .. } = f.meaning else {
            assert_eq!(f.fraction_digits, None, "{}", f.name);
            continue;
        };
        if scale == 1.0 {
            assert_eq!(f.fraction_digits, None, "{}: an integer", f.name);
            continue;
        }
        let d = f
            .fraction_digits
            .unwrap_or_else(|| panic!("{}: no format", f.name)) as usize;
        let show = |raw: i64, d: usize| format!("{:.*}", d, raw as f64 * scale);
        // Enough: neighbouring raw values never show alike.
        for k in (-2_000i64..2_000).chain([4_990, 65_534, 1_000_000]) {
            assert_ne!(
                show(k, d),
                show(k + 1, d),
                "{}: raw {k} with {d} decimals",
                f.name
            );
        }
        // The fewest: with one decimal less some neighbours collide.
        if d > 0 {
            assert!(
                (0i64..100_000).any(|k| show(k, d - 1) == show(k + 1, d - 1)),
                "{}: {d} decimals are more than one raw count needs",
                f.name
            );
        }
        checked += 1;
    }
    assert!(checked > 20, "{checked} calibrated fields");
    // The example: 4,991 nm.
    let x = m
        .telemetry
        .iter()
        .flat_map(|p| p.fields.iter())
        .find(|f| f.name == "pose_fk_x")
        .unwrap();
    assert_eq!(
        format!("{:.*}", x.fraction_digits.unwrap() as usize, 4991.0 * 0.001),
        "4.991"
    );
    assert_ne!(
        format!("{}", 4991.0 * 0.001),
        "4.991",
        "the noise the format removes"
    );
}

/// The flight commands an operator must confirm: what they change is not undone by the
/// next command, or they bypass the pose checks (exhaustive: a new command does not
/// compile until it is classified here).
fn must_confirm(c: &Command) -> bool {
    use m2ctl::link::schedule::ScheduleCommand;
    match c {
        Command::ActivateTable { .. }
        | Command::SwitchBank
        | Command::RevertToNominal
        | Command::DirectStroke { .. }
        | Command::CommitTable { .. }
        | Command::Schedule(ScheduleCommand::Reset) => true,
        Command::Schedule(
            ScheduleCommand::EnableRelease
            | ScheduleCommand::DisableRelease
            | ScheduleCommand::Insert(_)
            | ScheduleCommand::Delete(_)
            | ScheduleCommand::TimeShiftAll(_)
            | ScheduleCommand::SummaryReport,
        )
        | Command::Ping
        | Command::HousekeepingOneShot
        | Command::LoadTableChunk(_)
        | Command::DumpTable(_)
        | Command::ReportParameters(_)
        | Command::SetParameters(_)
        | Command::SetTimeReportRate(_)
        | Command::MoveAbsolute(_)
        | Command::CheckMove(_)
        | Command::MoveRelative(_)
        | Command::Stop
        | Command::ClearFault
        | Command::ExposureHold { .. } => false,
    }
}

#[test]
fn dangerous_telecommands_are_critical_and_no_other() {
    let mut critical = Vec::new();
    for tc in mdb().telecommands {
        let command = (tc.build)(&arg_sets(&tc)[0]).unwrap_or_else(|e| panic!("{}: {e}", tc.name));
        assert_eq!(
            tc.critical.is_some(),
            must_confirm(&command),
            "{}: critical {:?}, builds {command:?}",
            tc.name,
            tc.critical
        );
        if tc.critical.is_some() {
            critical.push(tc.name.clone());
        }
    }
    assert_eq!(critical.len(), 6, "{critical:?}");
}

/// The housekeeping packet's fields in a mission database.
fn housekeeping_fields_of(m: &mdb::Mdb) -> &[Field] {
    &m.telemetry
        .iter()
        .find(|p| p.name == "housekeeping")
        .expect("a housekeeping packet")
        .fields
}

#[test]
fn health_parameters_have_their_alarms() {
    let m = mdb();
    let hk = housekeeping_fields_of(&m);
    for a in &m.alarms {
        let f = hk
            .iter()
            .find(|f| f.name == a.parameter)
            .unwrap_or_else(|| panic!("alarm on {}: no housekeeping field", a.parameter));
        assert!(a.min_violations >= 1);
        match (&a.rule, &f.meaning) {
            (mdb::AlarmRule::States { levels }, Meaning::Enum { enumeration }) => {
                let e = m.enums.iter().find(|e| e.name == *enumeration).unwrap();
                for (label, _) in levels {
                    assert!(
                        e.values.iter().any(|v| &v.1 == label),
                        "{}: no state {label}",
                        a.parameter
                    );
                }
            }
            (mdb::AlarmRule::Above { .. }, Meaning::Number { .. } | Meaning::Bits { .. }) => {}
            (r, mm) => panic!("{}: rule {r:?} on {mm:?}", a.parameter),
        }
    }
    // FAULTED, and only FAULTED, is a critical state (the controller's own name).
    let state = m.alarms.iter().find(|a| a.parameter == "state").unwrap();
    let mdb::AlarmRule::States { levels } = &state.rule else {
        panic!("state: {:?}", state.rule)
    };
    let faulted = mdb::upper_snake(&format!("{:?}", m2ctl::controller::State::Faulted));
    assert_eq!(levels, &vec![(faulted, "CRITICAL")]);
    // Any latched fault flag and any count of lost data raise an alarm.
    for p in [
        "fault_flags",
        "warning_flags",
        "tm_dropped",
        "cycle_overruns",
        "uart_overruns",
        "tc_rejected",
        "sensors_open",
        "sensors_short",
        "sensors_stuck",
    ] {
        let a = m.alarms.iter().find(|a| a.parameter == p);
        assert!(
            matches!(a.map(|a| &a.rule), Some(mdb::AlarmRule::Above { limit, .. }) if *limit == 0.0),
            "{p}: {a:?}"
        );
    }
}

#[test]
fn link_health_parameters_are_described_once_with_alarms_on_the_error_counters() {
    use m2ground::mdb::{LinkHealth, LinkHealthKind, TCO_RESIDUAL_ALARM_MS};
    let m = mdb();
    // Every quantity once, under a name no TM field has.
    let names: BTreeSet<_> = m.link_health.iter().map(|p| p.name).collect();
    assert_eq!(names.len(), m.link_health.len());
    assert_eq!(m.link_health.len(), LinkHealth::ALL.len());
    for p in &m.link_health {
        assert!(
            m.telemetry
                .iter()
                .all(|t| t.fields.iter().all(|f| f.name != p.name)),
            "{}: also a TM field",
            p.name
        );
        assert_eq!(p.quantity.parameter().name, p.name);
        assert!(p.min_violations >= 1 && !p.description.is_empty());
    }
    // Any count of lost or corrupted traffic raises an alarm; the plain counts do not.
    let rule = |q: LinkHealth| {
        m.link_health
            .iter()
            .find(|p| p.quantity == q)
            .unwrap()
            .alarm
            .clone()
    };
    for q in [
        LinkHealth::TmBadFrames,
        LinkHealth::TmBacklogDropped,
        LinkHealth::TcRefused,
        LinkHealth::EventsLost,
    ] {
        assert!(
            matches!(rule(q), Some(mdb::AlarmRule::Above { limit, .. }) if limit == 0.0),
            "{q:?}"
        );
    }
    for q in [
        LinkHealth::TmPackets,
        LinkHealth::TcPackets,
        LinkHealth::TcoUpdates,
    ] {
        assert!(rule(q).is_none(), "{q:?}");
    }
    // The correlation's residual: a float in ms, in alarm above its limit.
    let r = LinkHealth::TcoResidualMs.parameter();
    assert_eq!((r.kind, r.unit), (LinkHealthKind::Float, Some("ms")));
    assert!(
        matches!(r.alarm, Some(mdb::AlarmRule::Above { limit, .. }) if limit == TCO_RESIDUAL_ALARM_MS)
    );
}

/// A controller state to send a telecommand in (the transmission-constraint test).
#[derive(Clone, Copy, Debug)]
enum Situation {
    /// A 1 mm move under way.
    Moving,
    /// A fault latched (a corrupted encoder frame), its cause gone.
    Faulted,
    /// Idle, a table job (revert to nominal) running.
    Job,
}

/// A bench in `s`.
fn bench_in(s: Situation) -> m2ctl::sim::Bench {
    use m2ctl::controller::State;
    use m2ctl::sim::{Bench, InjectedFault};
    let mut r = Bench::new();
    r.run(2);
    match s {
        Situation::Moving => {
            r.send(&Command::MoveAbsolute(WirePose::from_array([
                1_000_000, 0, 0, 0, 0, 0,
            ])));
            for _ in 0..20 {
                if r.ctl.state() == State::Moving {
                    break;
                }
                r.tick();
            }
            assert_eq!(r.ctl.state(), State::Moving);
        }
        Situation::Faulted => {
            r.plant
                .with(|p| p.inject(InjectedFault::EncoderCorrupted { leg: 0 }));
            for _ in 0..50 {
                if r.ctl.state() == State::Faulted {
                    break;
                }
                r.tick();
            }
            r.plant.with(|p| p.clear_faults());
            r.run(2);
            assert_eq!(r.ctl.state(), State::Faulted);
        }
        Situation::Job => {
            r.send(&Command::RevertToNominal);
            assert!(r.ctl.housekeeping().job != 0, "no job running");
        }
    }
    r
}

/// Every telecommand's transmission constraint is exactly where the controller refuses
/// it for its state: sent while moving, while faulted and while a table job runs, on
/// the simulated bench, it is refused with 0x0702 (busy), 0x0701 (faulted) or 0x070D
/// (job) if and only if its constraint excludes that state.
#[test]
fn transmission_constraints_are_where_the_controller_refuses() {
    use m2ctl::controller::State;
    const STATE_REFUSALS: [u16; 3] = [0x0701, 0x0702, 0x070D];
    let label = |s: State| mdb::upper_snake(&format!("{s:?}"));
    let mut constrained = 0;
    for tc in mdb().telecommands {
        let command = (tc.build)(&arg_sets(&tc)[0]).unwrap_or_else(|e| panic!("{}: {e}", tc.name));
        for s in [Situation::Moving, Situation::Faulted, Situation::Job] {
            let excluded = tc.constraint.as_ref().is_some_and(|c| match s {
                Situation::Moving => !c.states.contains(&label(State::Moving)),
                Situation::Faulted => !c.states.contains(&label(State::Faulted)),
                Situation::Job => c.no_job,
            });
            let mut r = bench_in(s);
            let rid = r.send(&command);
            r.run(5);
            let reports = r.st.reports(rid);
            let refused = reports.iter().any(|v| {
                matches!(v, Verification::StartFailure { code, .. }
                    | Verification::CompletionFailure { code, .. } if STATE_REFUSALS.contains(code))
            });
            assert_eq!(
                refused, excluded,
                "{} in {s:?}: constraint {:?}, reports {reports:?}",
                tc.name, tc.constraint
            );
        }
        if let Some(c) = &tc.constraint {
            constrained += 1;
            assert!(c.timeout_s > 0.0 && !c.why.is_empty(), "{}: {c:?}", tc.name);
        }
    }
    assert_eq!(constrained, 9, "constrained telecommands");
}

/// The derived parameters' inputs are housekeeping fields in the derived unit; the
/// following error's alarm levels are the controller's default thresholds, the
/// temperature deviation's the thermal calibration's largest soak around the model's
/// default reference, with a sensor without a value left out.
#[test]
fn derived_parameters_come_from_housekeeping_in_their_unit() {
    use m2ctl::table::DEFAULT_SUPERVISION;
    use m2ctl::thermal::{ThermalModel, NO_TEMPERATURE, TEMP_SENSORS};
    use mdb::Computation;
    let m = mdb();
    let hk = housekeeping_fields_of(&m);
    let field = |d: &str, name: &str| {
        hk.iter()
            .find(|f| f.name == name)
            .unwrap_or_else(|| panic!("{d}: no housekeeping field {name}"))
            .clone()
    };
    for d in &m.derived {
        assert!(d.min_violations >= 1 && !d.above.is_empty());
        let inputs: Vec<String> = match &d.computation {
            Computation::LargestDifference { pairs } => pairs
                .iter()
                .flat_map(|(a, b)| [a.clone(), b.clone()])
                .collect(),
            Computation::LargestDeviation { fields, .. } => fields.clone(),
        };
        assert!(!inputs.is_empty());
        for name in &inputs {
            let f = field(d.name, name);
            assert!(
                matches!(f.meaning, Meaning::Number { unit: Some(u), .. } if u == d.unit),
                "{}: {name} is {:?}",
                d.name,
                f.meaning
            );
        }
        assert!(
            hk.iter().all(|f| f.name != d.name),
            "{} is a TM field",
            d.name
        );
    }
    let fe = m
        .derived
        .iter()
        .find(|d| d.name == "following_error_max")
        .unwrap();
    let Computation::LargestDifference { pairs } = &fe.computation else {
        panic!("{:?}", fe.computation)
    };
    assert_eq!(pairs.len(), m2ctl::kinematics::LEGS);
    let um = |mm: f32| f64::from(mm) * 1e3;
    assert_eq!(
        fe.above,
        vec![
            (
                "WARNING",
                um(DEFAULT_SUPERVISION.following_error_warning_mm).round()
            ),
            (
                "CRITICAL",
                um(DEFAULT_SUPERVISION.following_error_fault_mm).round()
            ),
        ]
    );
    let td = m
        .derived
        .iter()
        .find(|d| d.name == "temperature_deviation_max")
        .unwrap();
    let Computation::LargestDeviation {
        fields,
        from,
        absent,
    } = &td.computation
    else {
        panic!("{:?}", td.computation)
    };
    assert_eq!(fields.len(), TEMP_SENSORS);
    assert_eq!(*from, f64::from(ThermalModel::NONE.reference_c) + 273.15);
    // A sensor without a value reads NO_TEMPERATURE on the wire: its engineering value.
    let Meaning::Number { scale, .. } = field(td.name, &fields[0]).meaning else {
        unreachable!()
    };
    assert_eq!(*absent, f64::from(NO_TEMPERATURE) * scale);
    assert_eq!(
        td.above,
        vec![("WARNING", m2calib::thermal::LARGEST_SOAK_K)]
    );
}
