//! The ground-segment gateway (`m2ground gateway`, `m2ground::gateway`): COBS
//! frames from the controller to whole packets for Yamcs and back, resynchronisation
//! after garbage, the time correlation, and the whole gateway on real sockets with a
//! fake controller, a fake Yamcs link and a fake Yamcs HTTP server.

#![cfg(feature = "host")]

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::os::unix::net::UnixListener;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use m2ctl::link::framing::Deframer;
use m2ctl::link::tm::{parse_tm, EventSeverity, TmReport, TmTime, TmWriter};
use m2ctl::link::{decode_telecommand, Command, Housekeeping, WirePose, MAX_TM_FRAME_LEN};
use m2ground::gateway::{
    base64, ccsds_packet_len, coefficients_json, event_json, http_post_json, link_health_json,
    rfc3339, run, tm_obt_s, Correlator, Options, Stats, TcPath, TimeFit, TmPath, Uart,
    TM_DEFRAMER_LEN,
};
use m2ground::tc::{frame, TcSequencer};

/// The packet of one frame.
fn deframe_one(f: &[u8]) -> Vec<u8> {
    let mut d: Deframer<TM_DEFRAMER_LEN> = Deframer::new();
    for b in f {
        if let Some(r) = d.push_byte(*b) {
            return r.unwrap().to_vec();
        }
    }
    panic!("no frame")
}

/// Framed TM packets as the controller sends them, and the bare packets.
fn controller_tm(n: usize) -> (Vec<u8>, Vec<Vec<u8>>) {
    let mut w = TmWriter::new();
    let mut stream = Vec::new();
    let mut packets = Vec::new();
    for i in 0..n {
        let mut out = [0u8; MAX_TM_FRAME_LEN];
        let t = TmTime::from_millis(1000 * i as u64 + 250);
        let len = match i % 3 {
            0 => w.emit_ping_reply(t, &mut out),
            1 => w.emit_event(t, EventSeverity::Medium, 0x0011, [i as u32, 0], &mut out),
            _ => {
                let hk = Housekeeping {
                    cycle_counter: i as u32,
                    pose_fk: WirePose::from_array([0, -1, 0x100, 0, 0, 7]),
                    ..Housekeeping::default()
                };
                w.emit_housekeeping(t, &hk, &mut out)
            }
        }
        .unwrap();
        let f = &out[..len];
        stream.extend_from_slice(f);
        packets.push(deframe_one(f));
    }
    (stream, packets)
}

#[test]
fn tm_frames_become_whole_packets_for_any_split() {
    let (stream, packets) = controller_tm(9);
    for chunk in [1, 2, 3, 7, 64, stream.len()] {
        let mut path = TmPath::new();
        let mut out = Vec::new();
        for c in stream.chunks(chunk) {
            path.push(c, &mut out);
        }
        assert_eq!(out, packets, "chunks of {chunk}");
        assert_eq!(path.bad_frames, 0);
        for p in &out {
            parse_tm(p).expect("a valid PUS packet");
        }
    }
}

#[test]
fn tm_resynchronises_after_garbage_and_drops_bad_frames() {
    let (stream, packets) = controller_tm(6);
    let mut path = TmPath::new();
    let mut out = Vec::new();
    // Garbage without a delimiter, then the stream: the leading 0x00 of the first frame
    // ends the garbage as one bad frame; every packet arrives.
    path.push(&[0x17, 0x42, 0xff, 0x03, 0x99], &mut out);
    path.push(&stream, &mut out);
    assert_eq!(out, packets);
    assert_eq!(path.bad_frames, 1, "the garbage is one dropped frame");
    // A lost byte inside a frame: that frame is dropped, the next ones arrive.
    let mut damaged = stream.clone();
    let second_frame_start = damaged[1..].iter().position(|&b| b == 0).unwrap() + 2;
    damaged.remove(second_frame_start + 5);
    let mut path = TmPath::new();
    let mut out = Vec::new();
    path.push(&damaged, &mut out);
    assert!(
        out.len() >= packets.len() - 1,
        "{} of {}",
        out.len(),
        packets.len()
    );
    assert!(
        !out.contains(&packets[1]),
        "the damaged packet is not forwarded"
    );
    assert_eq!(&out[1..], &packets[2..]);
    // An overlong frame (noise with no delimiter for 1000 bytes) is dropped too.
    let mut path = TmPath::new();
    let mut out = Vec::new();
    path.push(&[0x00], &mut out);
    path.push(&[0x55; 1000], &mut out);
    path.push(&stream, &mut out);
    assert_eq!(out, packets);
    assert_eq!(path.bad_frames, 1);
    // A valid COBS frame whose CCSDS length field disagrees with its size.
    let mut short = packets[0].clone();
    short.push(0xaa);
    let mut path = TmPath::new();
    let mut out = Vec::new();
    path.push(&frame(&short), &mut out);
    path.push(&stream, &mut out);
    assert_eq!(out, packets);
    assert_eq!(path.bad_frames, 1);
}

fn tc_packets() -> Vec<Vec<u8>> {
    let mut seq = TcSequencer::new(5);
    [
        Command::Ping,
        Command::MoveAbsolute(WirePose::from_array([1_500, 0, 0, -2_000_000, 0, 0])),
        Command::Stop,
        Command::CommitTable { crc32: 0xdead_beef },
    ]
    .iter()
    .map(|c| seq.packet(c).unwrap())
    .collect()
}

#[test]
fn tc_packets_become_frames_the_controller_decodes_for_any_split() {
    let packets = tc_packets();
    let stream = packets.concat();
    for chunk in [1, 2, 5, 6, 7, 13, stream.len()] {
        let mut path = TcPath::new();
        let mut frames = Vec::new();
        for c in stream.chunks(chunk) {
            path.push(c, &mut frames);
        }
        assert_eq!(frames.len(), packets.len(), "chunks of {chunk}");
        for (f, p) in frames.iter().zip(&packets) {
            assert_eq!(f, &frame(p), "framed exactly as m2ground tc frames it");
            let got = deframe_one(f);
            assert_eq!(&got, p);
            decode_telecommand(&got).expect("the controller accepts it");
        }
    }
}

#[test]
fn an_oversized_tc_is_skipped_and_the_stream_continues() {
    let packets = tc_packets();
    // A CCSDS header declaring 1000 bytes, and its 1000 bytes.
    let mut big = vec![0x18, 0xb2, 0xc0, 0x00];
    big.extend(((1000 - 7) as u16).to_be_bytes());
    big.resize(1000, 0x11);
    let mut stream = packets[0].clone();
    stream.extend(&big);
    stream.extend(&packets[1]);
    let mut path = TcPath::new();
    let mut frames = Vec::new();
    for c in stream.chunks(100) {
        path.push(c, &mut frames);
    }
    assert_eq!(path.refused, 1);
    assert_eq!(frames, vec![frame(&packets[0]), frame(&packets[1])]);
    assert_eq!(ccsds_packet_len(&big), Some(1000));
}

/// Arrivals of packets generated every `step_s` of on-board time on a clock running at
/// `obt_rate` on-board seconds per UTC second, delayed 2..40 ms (pseudo-random).
fn arrivals(boot: f64, obt_rate: f64, step_s: f64, n: usize) -> Vec<(f64, f64)> {
    let mut x: u64 = 7;
    (0..n)
        .map(|i| {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let delay = 0.002 + (x >> 40) as f64 / (1u64 << 24) as f64 * 0.038;
            let obt = step_s * i as f64;
            (obt, boot + obt / obt_rate + delay)
        })
        .collect()
}

#[test]
fn time_correlation_fits_the_clock_and_follows_a_reboot() {
    let boot = 1_764_583_200.25; // 2025-12-01T10:00:00.25Z
                                 // A controller clock at the nominal rate, and one running 20 % slow (QEMU when the
                                 // emulation cannot keep the 1 kHz cycle), packets every 0.25 s for 5 minutes.
    for obt_rate in [1.0, 0.8] {
        let mut c = Correlator::new();
        let mut updates = 0;
        let mut worst: f64 = 0.0;
        for (i, (obt, arrival)) in arrivals(boot, obt_rate, 0.25, 1200).into_iter().enumerate() {
            if c.sample(obt, arrival).is_some() {
                updates += 1;
            }
            // After the first 40 s, Yamcs' UTC of every packet is within 25 ms of when it
            // was generated (delays 2..40 ms: the least delay, the envelope's noise and the
            // update tolerance add up to about 20 ms).
            let fit = c.published().unwrap();
            if i > 160 {
                worst = worst.max((fit.utc(obt) - (boot + obt / obt_rate)).abs());
            }
        }
        let fit = c.published().unwrap();
        println!(
            "clock rate {obt_rate}: fitted {:.6} UTC s per OBT s, worst error {:.1} ms, {updates} updates",
            fit.rate,
            worst * 1e3
        );
        assert!((fit.rate - 1.0 / obt_rate).abs() < 1e-3, "{fit:?}");
        assert!(worst < 0.025, "worst error {worst} s");
        assert!(updates < 100, "{updates} updates");
    }
    // A reboot: OBT restarts at 0, the correlation is redone at once.
    let mut c = Correlator::new();
    for (obt, arrival) in arrivals(boot, 1.0, 0.25, 400) {
        c.sample(obt, arrival);
    }
    let reboot = boot + 200.0;
    let fit = c
        .sample(0.0, reboot + 0.004)
        .expect("a reboot changes the correlation");
    assert!((fit.utc(0.0) - reboot).abs() < 0.005);
    // The JSON Yamcs' SetCoefficients takes.
    assert_eq!(rfc3339(0.0), "1970-01-01T00:00:00.000000Z");
    assert_eq!(rfc3339(boot), "2025-12-01T10:00:00.250000Z");
    assert_eq!(rfc3339(951_782_400.5), "2000-02-29T00:00:00.500000Z");
    let j: serde_json::Value = serde_json::from_str(&coefficients_json(&TimeFit {
        boot_unix_s: boot,
        rate: 1.25,
    }))
    .unwrap();
    assert_eq!(j["utc"], "2025-12-01T10:00:00.250000Z");
    assert_eq!(j["obt"], "0");
    assert_eq!(j["gradient"].as_f64().unwrap(), 1.25 / 65536.0);
    // The OBT of a TM packet: 1.25 s.
    let (_, packets) = controller_tm(2);
    assert_eq!(tm_obt_s(&packets[1]), Some(1.25));
}

/// Reads from `s` until `n` bytes arrived or 10 s passed.
fn read_n(s: &mut impl Read, n: usize) -> Vec<u8> {
    let t0 = Instant::now();
    let mut out = Vec::new();
    let mut buf = [0u8; 4096];
    while out.len() < n && t0.elapsed() < Duration::from_secs(10) {
        match s.read(&mut buf) {
            Ok(0) => break,
            Ok(k) => out.extend_from_slice(&buf[..k]),
            Err(_) => {}
        }
    }
    out
}

#[test]
fn the_gateway_on_sockets_forwards_both_ways_and_sets_the_time_correlation() {
    let dir = std::env::temp_dir().join(format!("m2-gw-test-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let sock = dir.join("uart.sock");
    let _ = std::fs::remove_file(&sock);
    // The fake controller: a Unix socket server, as QEMU's chardev.
    let controller = UnixListener::bind(&sock).unwrap();
    // The fake Yamcs HTTP server (time correlation).
    let http = TcpListener::bind("127.0.0.1:0").unwrap();
    let tco_url = format!(
        "http://{}/api/tco/m2/tco0/coefficients",
        http.local_addr().unwrap()
    );
    let http_thread = std::thread::spawn(move || {
        let (mut s, _) = http.accept().unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let mut req = Vec::new();
        let mut buf = [0u8; 1024];
        while !String::from_utf8_lossy(&req).contains("\"offset\"") {
            let n = s.read(&mut buf).unwrap();
            if n == 0 {
                break;
            }
            req.extend_from_slice(&buf[..n]);
        }
        s.write_all(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\n{}")
            .unwrap();
        String::from_utf8(req).unwrap()
    });

    let yamcs_side = TcpListener::bind("127.0.0.1:0").unwrap();
    let link_addr = yamcs_side.local_addr().unwrap();
    let (rx, tx) = Uart::Unix(sock.clone())
        .open(Duration::from_secs(5))
        .unwrap();
    let (mut qemu, _) = controller.accept().unwrap();
    let stats = Arc::new(Stats::default());
    let stop = Arc::new(AtomicBool::new(false));
    let options = Options {
        tco_url: Some(tco_url),
        events_url: None,
        backlog: 100,
        ..Options::default()
    };
    let gw = {
        let (stats, stop) = (stats.clone(), stop.clone());
        std::thread::spawn(move || run(yamcs_side, rx, tx, &options, stats, stop))
    };

    // TM before Yamcs connects is kept; garbage in between is dropped.
    let (stream, packets) = controller_tm(6);
    let (a, b) = stream.split_at(stream.len() / 2);
    qemu.write_all(a).unwrap();
    qemu.write_all(&[0x42, 0x42, 0x42]).unwrap();
    qemu.write_all(b).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    let mut yamcs = TcpStream::connect(link_addr).unwrap();
    yamcs
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let want: usize = packets.iter().map(|p| p.len()).sum();
    let got = read_n(&mut yamcs, want);
    // The garbage landed inside one frame: that packet is lost, the others arrive whole.
    let mut arrived = Vec::new();
    let mut rest = &got[..];
    while let Some(len) = ccsds_packet_len(rest) {
        arrived.push(rest[..len].to_vec());
        rest = &rest[len..];
    }
    assert!(rest.is_empty());
    assert!(arrived.len() >= packets.len() - 1);
    for p in &arrived {
        assert!(packets.contains(p));
        assert!(matches!(
            parse_tm(p).unwrap().report,
            TmReport::PingReply | TmReport::Event { .. } | TmReport::Housekeeping(_)
        ));
    }

    // Live TM after the connection.
    let (more, more_packets) = controller_tm(3);
    qemu.write_all(&more).unwrap();
    let want: usize = more_packets.iter().map(|p| p.len()).sum();
    assert_eq!(read_n(&mut yamcs, want), more_packets.concat());

    // TC from Yamcs, raw packets back to back, split arbitrarily.
    let tcs = tc_packets();
    let all = tcs.concat();
    for c in all.chunks(3) {
        yamcs.write_all(c).unwrap();
    }
    qemu.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let want_frames: Vec<u8> = tcs.iter().flat_map(|p| frame(p)).collect();
    assert_eq!(read_n(&mut qemu, want_frames.len()), want_frames);

    // The time correlation reached "Yamcs".
    let req = http_thread.join().unwrap();
    assert!(
        req.starts_with("POST /api/tco/m2/tco0/coefficients HTTP/1.1\r\n"),
        "{req}"
    );
    let body = req.split("\r\n\r\n").nth(1).unwrap();
    let j: serde_json::Value = serde_json::from_str(body).unwrap();
    assert_eq!(j["obt"], "0");

    // The TC thread counts a packet after its write returns, and the correlation after
    // Yamcs' answer is read, which on a busy machine can be after the other side has
    // seen them: wait for the counts, do not assume them.
    let deadline = Instant::now() + Duration::from_secs(10);
    while (stats.tc_packets.load(Ordering::Relaxed) < tcs.len() as u64
        || stats.tco_updates.load(Ordering::Relaxed) < 1)
        && Instant::now() < deadline
    {
        std::thread::sleep(Duration::from_millis(10));
    }

    // The controller's stream ends: the gateway stops.
    drop(qemu);
    let r = gw.join().unwrap();
    assert!(r.is_ok(), "{r:?}");
    assert!(stop.load(Ordering::Relaxed));
    let line = stats.line();
    println!("gateway on sockets: {line}");
    assert!(
        line.contains(&format!("TC {} packets (0 refused)", tcs.len())),
        "{line}"
    );
    assert!(line.contains("1 time correlations"), "{line}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// One TM[5,x] packet (unframed) as the controller emits it, at OBT 3.5 s.
fn event_packet(severity: EventSeverity, id: u16, aux: [u32; 2]) -> Vec<u8> {
    let mut out = [0u8; MAX_TM_FRAME_LEN];
    let len = TmWriter::new()
        .emit_event(TmTime::from_millis(3500), severity, id, aux, &mut out)
        .unwrap();
    deframe_one(&out[..len])
}

#[test]
fn events_go_to_yamcs_with_a_source_and_their_words_named() {
    use m2ctl::controller::{CommandError, State};
    use m2ctl::kinematics::Refusals;
    use m2ctl::link::tm::event_id;
    use m2ctl::motion::trajectory::MotionError;
    use m2ctl::supervision::flags::FaultFlags;
    let mdb = m2ground::mdb::mdb();
    let fit = TimeFit {
        boot_unix_s: 1_764_583_200.0,
        rate: 1.25,
    };
    let json = |p: &[u8], fit| -> serde_json::Value {
        serde_json::from_str(&event_json(&mdb, p, fit).expect("an event")).unwrap()
    };
    // States by their Rust names.
    let p = event_packet(
        EventSeverity::Info,
        event_id::STATE_CHANGED,
        [
            u32::from(State::Idle.code()),
            u32::from(State::Moving.code()),
        ],
    );
    let j = json(&p, Some(fit));
    assert_eq!(j["source"], "M2");
    assert_eq!(j["type"], "STATE_CHANGED");
    assert_eq!(j["severity"], "INFO");
    assert_eq!(j["message"], "controller state IDLE -> MOVING");
    assert_eq!(j["time"], rfc3339(fit.utc(3.5)));
    assert_eq!(j["extra"]["obt"], (3.5f64 * 65536.0).to_string());
    // The packet's sequence count: a repeated post is the same event for Yamcs.
    let seq = u16::from_be_bytes([p[2], p[3]]) & 0x3FFF;
    assert_eq!(j["sequenceNumber"], seq);
    // Refusal bits and failure code by name; Low = Yamcs WATCH.
    let refusal = Refusals {
        axes_outside: 0b1,
        ..Refusals::default()
    };
    let code = CommandError::Motion(MotionError::TargetRefused(refusal)).code();
    let p = event_packet(
        EventSeverity::Low,
        event_id::MOVE_REFUSED,
        [refusal.to_bits(), u32::from(code)],
    );
    let j = json(&p, None);
    assert_eq!(j["severity"], "WATCH");
    assert!(
        j.get("time").is_none(),
        "no correlation: Yamcs' mission time"
    );
    assert_eq!(
        j["message"],
        format!(
            "move refused: refusal bits X_OUTSIDE_WORKSPACE (0x{:x}), failure code MOTION_TARGET_REFUSED",
            refusal.to_bits()
        )
    );
    // Fault flags and the legs they name (bits 24..); High = CRITICAL.
    let flags = FaultFlags::ENCODER_STUCK.bits() | FaultFlags::ENCODER_JUMP.bits();
    let new = FaultFlags::ENCODER_JUMP.bits() | (0b100_010 << 24);
    let j = json(
        &event_packet(EventSeverity::High, event_id::FAULT_LATCHED, [flags, new]),
        Some(fit),
    );
    assert_eq!(j["severity"], "CRITICAL");
    assert_eq!(
        j["message"],
        format!(
            "fault latched: flags ENCODER_STUCK|ENCODER_JUMP (0x{flags:x}), new ENCODER_JUMP, LEG2|LEG6 (0x{new:x})"
        )
    );
    // An event that names nothing shows its numbers; an unknown ID is still an event.
    let j = json(
        &event_packet(EventSeverity::Info, event_id::TABLE_ACTIVATED, [77, 0x1234]),
        None,
    );
    assert_eq!(j["message"], "table 77 activated, CRC-32 4660");
    let j = json(&event_packet(EventSeverity::Medium, 0x7777, [1, 2]), None);
    assert_eq!(
        (&j["type"], &j["severity"]),
        (&"EVENT_30583".into(), &"DISTRESS".into())
    );
    // Other packets, and a corrupt event (CRC), are not events.
    let (_, packets) = controller_tm(1);
    assert!(event_json(&mdb, &packets[0], None).is_none());
    let mut bad = event_packet(EventSeverity::Info, event_id::BOOT, [0, 0]);
    bad[20] ^= 1;
    assert!(event_json(&mdb, &bad, None).is_none());
}

#[test]
fn base64_matches_the_rfc_4648_test_vectors() {
    // RFC 4648 section 10.
    for (plain, encoded) in [
        ("", ""),
        ("f", "Zg=="),
        ("fo", "Zm8="),
        ("foo", "Zm9v"),
        ("foob", "Zm9vYg=="),
        ("fooba", "Zm9vYmE="),
        ("foobar", "Zm9vYmFy"),
    ] {
        assert_eq!(base64(plain.as_bytes()), encoded, "{plain:?}");
    }
}

/// One HTTP request as a fake server receives it: its head (up to the blank line).
fn one_request_head(
    listener: TcpListener,
    status: &'static str,
) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let mut head = Vec::new();
        let mut b = [0u8; 1];
        while !head.ends_with(b"\r\n\r\n") && s.read(&mut b).unwrap() == 1 {
            head.push(b[0]);
        }
        s.write_all(format!("HTTP/1.1 {status}\r\nContent-Length: 0\r\n\r\n").as_bytes())
            .unwrap();
        String::from_utf8(head).unwrap()
    })
}

#[test]
fn a_user_in_the_url_goes_to_yamcs_as_basic_authentication_and_stays_out_of_errors() {
    // With a user: Basic base64("gateway:s3cret") (RFC 7617), and the path and host.
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let server = one_request_head(listener, "200 OK");
    http_post_json(
        &format!("http://gateway:s3cret@127.0.0.1:{port}/api/tco/m2/tco0/coefficients"),
        "{}",
    )
    .unwrap();
    let head = server.join().unwrap();
    assert!(
        head.starts_with("POST /api/tco/m2/tco0/coefficients HTTP/1.1\r\n"),
        "{head}"
    );
    assert!(
        head.contains(&format!("Host: 127.0.0.1:{port}\r\n")),
        "{head}"
    );
    assert!(
        head.contains("\r\nAuthorization: Basic Z2F0ZXdheTpzM2NyZXQ=\r\n"),
        "{head}"
    );
    // Without: no Authorization header.
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let server = one_request_head(listener, "200 OK");
    http_post_json(&format!("http://127.0.0.1:{port}/x"), "{}").unwrap();
    assert!(!server.join().unwrap().contains("Authorization"));
    // Refused (Yamcs: 403 when the user may not): an error that names the URL, not the
    // password.
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let server = one_request_head(listener, "403 Forbidden");
    let e = http_post_json(&format!("http://gateway:s3cret@127.0.0.1:{port}/x"), "{}").unwrap_err();
    server.join().unwrap();
    assert!(
        e.contains("403") && e.contains(&format!("127.0.0.1:{port}/x")),
        "{e}"
    );
    assert!(!e.contains("s3cret"), "{e}");
}

#[test]
fn link_health_goes_to_yamcs_as_the_mdb_describes_it() {
    use m2ground::mdb::{mdb, LinkHealth, LinkHealthKind};
    use std::sync::atomic::AtomicU64;
    let m = mdb();
    let stats = Stats::default();
    // A distinct value in every counter, a residual of 12.5 ms.
    let counters: [(&AtomicU64, LinkHealth, u64); 7] = [
        (&stats.tm_packets, LinkHealth::TmPackets, 101),
        (&stats.tm_bad_frames, LinkHealth::TmBadFrames, 3),
        (&stats.tm_backlog_dropped, LinkHealth::TmBacklogDropped, 5),
        (&stats.tc_packets, LinkHealth::TcPackets, 17),
        (&stats.tc_refused, LinkHealth::TcRefused, 2),
        (&stats.events_lost, LinkHealth::EventsLost, 7),
        (&stats.tco_updates, LinkHealth::TcoUpdates, 11),
    ];
    for (c, _, v) in &counters {
        c.store(*v, Ordering::Relaxed);
    }
    stats
        .tco_residual_ms_bits
        .store(12.5f64.to_bits(), Ordering::Relaxed);
    let body: serde_json::Value = serde_json::from_str(&link_health_json(&m, &stats)).unwrap();
    let sets = body["request"].as_array().unwrap();
    // One value per described parameter, every quantity described once.
    assert_eq!(sets.len(), m.link_health.len());
    assert_eq!(m.link_health.len(), LinkHealth::ALL.len());
    for p in &m.link_health {
        let name = format!("/M2/{}", p.name);
        let set: Vec<_> = sets
            .iter()
            .filter(|s| s["id"]["name"] == name.as_str())
            .collect();
        assert_eq!(set.len(), 1, "{name}");
        let v = &set[0]["value"];
        match p.kind {
            LinkHealthKind::Counter => {
                let want = counters.iter().find(|c| c.1 == p.quantity).unwrap().2;
                assert_eq!(v["type"], "UINT64", "{name}");
                assert_eq!(v["uint64Value"], want.to_string().as_str(), "{name}");
            }
            LinkHealthKind::Float => {
                assert_eq!(p.quantity, LinkHealth::TcoResidualMs);
                assert_eq!(v["type"], "DOUBLE", "{name}");
                assert_eq!(v["doubleValue"].as_f64(), Some(12.5), "{name}");
            }
        }
    }
}

#[test]
fn the_gateway_publishes_its_bad_frames_to_yamcs() {
    // A fake controller that sends garbage, a fake Yamcs HTTP server for the parameters:
    // a post arrives whose link_tm_bad_frames counts the dropped frame.
    let dir = std::env::temp_dir().join(format!("m2-gw-health-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let sock = dir.join("uart.sock");
    let _ = std::fs::remove_file(&sock);
    let controller = UnixListener::bind(&sock).unwrap();
    let http = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!(
        "http://gateway:pw@{}/api/processors/m2/realtime/parameters:batchSet",
        http.local_addr().unwrap()
    );
    let yamcs_side = TcpListener::bind("127.0.0.1:0").unwrap();
    let (rx, tx) = Uart::Unix(sock.clone())
        .open(Duration::from_secs(5))
        .unwrap();
    let (mut qemu, _) = controller.accept().unwrap();
    let stats = Arc::new(Stats::default());
    let stop = Arc::new(AtomicBool::new(false));
    let options = Options {
        backlog: 10,
        parameters_url: Some(url),
        health_every: Duration::from_millis(100),
        ..Options::default()
    };
    let gw = {
        let (stats, stop) = (stats.clone(), stop.clone());
        std::thread::spawn(move || run(yamcs_side, rx, tx, &options, stats, stop))
    };
    // A frame that is not COBS of a packet (a zero-length code byte).
    qemu.write_all(&[0x00, 0x05, 0x01, 0x00]).unwrap();
    let t0 = Instant::now();
    let mut bad_frames = None;
    while bad_frames != Some(1) && t0.elapsed() < Duration::from_secs(20) {
        let (mut s, _) = http.accept().unwrap();
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut req = Vec::new();
        let mut buf = [0u8; 4096];
        while !req.ends_with(b"]}") {
            match s.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => req.extend_from_slice(&buf[..n]),
            }
        }
        s.write_all(b"HTTP/1.1 200 OK\r\nContent-Length: 0\r\n\r\n")
            .unwrap();
        let text = String::from_utf8(req).unwrap();
        assert!(text.starts_with("POST /api/processors/m2/realtime/parameters:batchSet "));
        assert!(
            text.contains("Authorization: Basic Z2F0ZXdheTpwdw==\r\n"),
            "{text}"
        );
        let body: serde_json::Value =
            serde_json::from_str(text.split("\r\n\r\n").nth(1).unwrap()).unwrap();
        bad_frames = body["request"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["id"]["name"] == "/M2/link_tm_bad_frames")
            .and_then(|s| s["value"]["uint64Value"].as_str()?.parse::<u64>().ok());
    }
    assert_eq!(bad_frames, Some(1));
    assert_eq!(stats.tm_bad_frames.load(Ordering::Relaxed), 1);
    stop.store(true, Ordering::Relaxed);
    drop(qemu);
    let _ = gw.join();
    let _ = std::fs::remove_dir_all(&dir);
}

/// Each event is posted with its TM packet's sequence count as Yamcs' sequence number,
/// so two events at the same time stay two, and a repeated post stays one.
#[test]
fn events_carry_their_packet_sequence_count() {
    use m2ctl::link::tm::event_id;
    let mdb = m2ground::mdb::mdb();
    let mut w = TmWriter::new();
    let mut seqs = Vec::new();
    for k in 0..3u32 {
        let mut out = [0u8; MAX_TM_FRAME_LEN];
        let len = w
            .emit_event(
                TmTime::from_millis(3500),
                EventSeverity::Info,
                event_id::BOOT,
                [k, 0],
                &mut out,
            )
            .unwrap();
        let p = deframe_one(&out[..len]);
        let j: serde_json::Value =
            serde_json::from_str(&event_json(&mdb, &p, None).expect("an event")).unwrap();
        let seq = u16::from_be_bytes([p[2], p[3]]) & 0x3FFF;
        assert_eq!(j["sequenceNumber"], seq);
        seqs.push(seq);
    }
    assert_eq!(seqs, vec![0, 1, 2]);
}
