//! The flight image in QEMU (mps2-an386), driven over its UART like a ground station:
//! ping, housekeeping, a table upload with commit and activation, a move, and a
//! malformed packet. Needs the firmware built and QEMU installed, so it is `#[ignore]`d
//! in the plain test run; `scripts/qemu-link-test.sh` (and CI) runs it.
#![allow(clippy::needless_range_loop)] // index loops over six legs/axes read clearer here

mod common;

use std::time::{Duration, Instant};

use common::qemu::Qemu;
use m2ctl::controller::{event, State};
use m2ctl::ground::station::{Station, Tm};
use m2ctl::link::command::WirePose;
use m2ctl::link::tm::{dump_chunks, Verification};
use m2ctl::link::{Command, RequestId, TableChunk};
use m2ctl::table::Table;

struct Link {
    q: Qemu,
    st: Station,
}

impl Link {
    fn send(&mut self, cmd: &Command) -> RequestId {
        let (frame, rid) = self.st.frame(cmd).unwrap();
        self.q.send(&frame);
        rid
    }

    /// Reads telemetry until `done` holds or `timeout` passes.
    fn until(&mut self, timeout: Duration, mut done: impl FnMut(&Station) -> bool) -> bool {
        let t0 = Instant::now();
        while t0.elapsed() < timeout {
            let bytes = self.q.read_for(Duration::from_millis(50));
            self.st.receive(&bytes);
            if done(&self.st) {
                return true;
            }
        }
        false
    }

    fn complete(&mut self, rid: RequestId, timeout: Duration) -> Vec<Verification> {
        self.until(timeout, |s| {
            s.reports(rid).iter().any(|v| {
                matches!(
                    v,
                    Verification::CompletionSuccess
                        | Verification::CompletionFailure { .. }
                        | Verification::StartFailure { .. }
                        | Verification::AcceptanceFailure { .. }
                )
            })
        });
        self.st.reports(rid)
    }
}

/// A UART at 115,200 baud, 8N1, carries 11.52 bytes per millisecond.
const UART_BYTES_PER_MS: usize = 11;

/// A host stall of the QEMU process: 5 x the watchdog's 20 ms from last feed to reset.
const HOST_STALL: Duration = Duration::from_millis(100);

const OK3: [Verification; 3] = [
    Verification::AcceptanceSuccess,
    Verification::StartSuccess,
    Verification::CompletionSuccess,
];

#[test]
#[ignore = "needs QEMU and the firmware image: scripts/qemu-link-test.sh"]
fn firmware_in_qemu_answers_telecommands() {
    let mut l = Link {
        q: Qemu::start(),
        st: Station::new(),
    };
    let t = Duration::from_secs(20);

    // Boot event, then ping.
    assert!(
        l.until(t, |s| !s.events(event::BOOT).is_empty()),
        "no boot event"
    );
    let rid = l.send(&Command::Ping);
    assert_eq!(l.complete(rid, t), OK3);
    assert!(l.st.log.contains(&Tm::Ping));

    // Housekeeping: nominal table, idle.
    let rid = l.send(&Command::HousekeepingOneShot);
    assert_eq!(l.complete(rid, t), OK3);
    let hk = l.st.last_hk().unwrap();
    assert_eq!((hk.state, hk.active_table_id), (State::Idle.code(), 0));

    // A malformed packet (bad CRC) is refused with the link's code.
    let (mut pkt, rid) = l.st.packet(&Command::Ping).unwrap();
    let n = pkt.len();
    pkt[n - 1] ^= 0xff;
    let mut frame = vec![0u8; pkt.len() * 2 + 4];
    let fl = m2ctl::link::encode_frame(&pkt, &mut frame).unwrap();
    l.q.send(&frame[..fl]);
    let reps = l.complete(rid, t);
    assert!(
        matches!(
            reps[..],
            [Verification::AcceptanceFailure { code: 0x0505, .. }]
        ),
        "{reps:?}"
    );

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
    for rid in &rids {
        assert_eq!(l.complete(*rid, t), OK3, "burst TC {rid:?}");
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
    let rid = l.send(&Command::HousekeepingOneShot);
    assert_eq!(l.complete(rid, t), OK3);
    let hk = l.st.last_hk().unwrap();
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
    let (stack_bottom, stack_top) = common::qemu::stack_region();
    let peak = l.q.stack_peak_bytes(stack_bottom, stack_top);
    println!(
        "STACK flight image peak_bytes={peak} of {} (memory.x STACK)",
        stack_top - stack_bottom
    );
    assert!(peak < stack_top - stack_bottom);
}
