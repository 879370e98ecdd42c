//! Runs the firmware image in QEMU (mps2-an386, or another board's machine) with its
//! first serial port on a Unix socket, so a host test can send telecommand bytes and
//! read telemetry bytes like a ground station.
#![allow(dead_code)]

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use m2ctl::controller::event;
use m2ctl::link::hk::Housekeeping;
use m2ctl::link::tm::{TmTime, Verification};
use m2ctl::link::{Command as Tc, RequestId};
use m2ctl::station::Station;

/// The flight image built by `cargo build --profile flight --target thumbv7em-none-eabihf
/// --features firmware --bin m2fw` (scripts/qemu-link-test.sh builds it).
pub fn firmware_elf() -> PathBuf {
    elf_at("target/thumbv7em-none-eabihf/flight/m2fw")
}

/// An image under the crate directory; panics with a hint if it was not built.
pub fn elf_at(relative: &str) -> PathBuf {
    let p = super::repo_root().join(relative);
    assert!(
        p.exists(),
        "{} missing: build the firmware first (scripts/qemu-link-test.sh, scripts/qemu-fault-test.sh)",
        p.display()
    );
    p
}

/// Virtual time of QEMU's CPU: every guest instruction takes 2^ICOUNT_SHIFT ns (8 ns:
/// 125 M instructions per second of guest time), and the timers, the watchdog and the
/// control rate run on this clock only. `sleep=off`: while the guest waits (WFI) its
/// clock skips to the next timer deadline instead of following the host's clock, so
/// guest time is a function of the instructions executed, whatever the host's load.
/// With `sleep=on` an idle guest's clock followed host time: a QEMU process the host
/// did not schedule for 10 ms (two cores shared by parallel builds) saw 10 ms pass in
/// one step while its guest idled, more than the watchdog's window, and the watchdog
/// reset a guest whose every control cycle had completed (the link test failed so in
/// about 1 run of 5; docs/firmware.md, "Firmware in QEMU").
pub const ICOUNT_SHIFT: u32 = 3;

/// QEMU arguments of the default board.
pub const MPS2_AN386: &[&str] = &["-cpu", "cortex-m4", "-machine", "mps2-an386"];
/// QEMU arguments of the second board (STM32F405, Cortex-M4F implied).
pub const NETDUINOPLUS2: &[&str] = &["-machine", "netduinoplus2"];

/// A running QEMU with the firmware; killed on drop.
pub struct Qemu {
    child: Child,
    /// UART0 as a byte stream.
    pub uart: UnixStream,
    sock: PathBuf,
    monitor: PathBuf,
}

impl Qemu {
    /// Starts QEMU with the flight image and connects to UART0.
    pub fn start() -> Qemu {
        Self::start_elf(&firmware_elf())
    }

    /// Starts QEMU (mps2-an386) with `elf` and connects to UART0.
    pub fn start_elf(elf: &std::path::Path) -> Qemu {
        Self::start_elf_on(elf, MPS2_AN386)
    }

    /// Starts QEMU's `machine` (its `-cpu`/`-machine` arguments) with `elf` and connects
    /// to its first serial port.
    pub fn start_elf_on(elf: &std::path::Path, machine: &[&str]) -> Qemu {
        let sock = std::env::temp_dir().join(format!(
            "m2fw-uart-{}-{}.sock",
            std::process::id(),
            rand_suffix()
        ));
        let _ = std::fs::remove_file(&sock);
        let monitor = sock.with_extension("monitor");
        let _ = std::fs::remove_file(&monitor);
        let child = Command::new("qemu-system-arm")
            .args(machine)
            .arg("-nographic")
            .arg("-monitor")
            .arg(format!("unix:{},server=on,wait=off", monitor.display()))
            .arg("-icount")
            .arg(format!("shift={ICOUNT_SHIFT},sleep=off"))
            .arg("-chardev")
            .arg(format!(
                "socket,id=tc,path={},server=on,wait=on",
                sock.display()
            ))
            .args(["-serial", "chardev:tc", "-kernel"])
            .arg(elf)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("qemu-system-arm (scripts/setup.sh installs it)");
        let t0 = Instant::now();
        let uart = loop {
            match UnixStream::connect(&sock) {
                Ok(s) => break s,
                Err(_) if t0.elapsed() < Duration::from_secs(20) => {
                    std::thread::sleep(Duration::from_millis(50))
                }
                Err(e) => panic!("cannot connect to QEMU's UART socket: {e}"),
            }
        };
        uart.set_read_timeout(Some(Duration::from_millis(100)))
            .unwrap();
        Qemu {
            child,
            uart,
            sock,
            monitor,
        }
    }

    /// Stops the QEMU process for `pause` of host time (SIGSTOP, then SIGCONT), as a
    /// loaded host does when it does not schedule it: the guest's clock must not see
    /// that time ([`ICOUNT_SHIFT`]).
    pub fn stall_host(&self, pause: Duration) {
        let _stopped = self.stop();
        std::thread::sleep(pause);
    }

    /// Stops the QEMU process (SIGSTOP) until the returned guard is dropped (SIGCONT):
    /// guest time stands still meanwhile, so the ground can act on what it has
    /// received without the guest running on.
    pub fn stop(&self) -> Stopped {
        signal(self.child.id(), "-STOP");
        Stopped(self.child.id())
    }

    /// Sends bytes to the firmware's UART.
    pub fn send(&mut self, bytes: &[u8]) {
        self.uart.write_all(bytes).unwrap();
    }

    /// Reads whatever arrives within `wait`: one polling step of [`Link::until`]. What
    /// arrived within a wall-clock wait decides nothing: the tests select telemetry by
    /// request ID and time stamp.
    pub fn read_for(&mut self, wait: Duration) -> Vec<u8> {
        let t0 = Instant::now();
        let mut out = Vec::new();
        let mut buf = [0u8; 4096];
        while t0.elapsed() < wait {
            match self.uart.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => out.extend_from_slice(&buf[..n]),
                Err(e)
                    if e.kind() == std::io::ErrorKind::WouldBlock
                        || e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => panic!("UART read: {e}"),
            }
        }
        out
    }
}

impl Qemu {
    /// Resets the guest from outside (QEMU monitor `system_reset`, as the reset pin or
    /// a debugger would); RAM keeps its contents.
    pub fn system_reset(&self) {
        let mut mon = UnixStream::connect(&self.monitor).expect("QEMU monitor socket");
        mon.set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
        // Its banner and prompt first, then the command; it has run when the monitor
        // shows its prompt again (closing the socket earlier can drop the command).
        fn prompt_until(mon: &mut UnixStream, seen: &mut String, n: usize) {
            let mut buf = [0u8; 4096];
            let t0 = Instant::now();
            while seen.matches("(qemu)").count() < n && t0.elapsed() < Duration::from_secs(10) {
                if let Ok(k) = mon.read(&mut buf) {
                    seen.push_str(&String::from_utf8_lossy(&buf[..k]));
                }
            }
        }
        let mut seen = String::new();
        prompt_until(&mut mon, &mut seen, 1);
        mon.write_all(b"system_reset\n").unwrap();
        prompt_until(&mut mon, &mut seen, 2);
        assert!(seen.matches("(qemu)").count() >= 2, "monitor: {seen:?}");
    }

    /// Reads `words` 32-bit words of guest memory at `addr` through QEMU's monitor.
    pub fn read_words(&self, addr: u32, words: usize) -> Vec<u32> {
        let mut mon = UnixStream::connect(&self.monitor).expect("QEMU monitor socket");
        mon.set_read_timeout(Some(Duration::from_millis(500)))
            .unwrap();
        mon.write_all(format!("xp /{words}wx {addr:#x}\n").as_bytes())
            .unwrap();
        let mut text = String::new();
        let mut buf = [0u8; 65536];
        let t0 = Instant::now();
        let mut out = Vec::new();
        while out.len() < words && t0.elapsed() < Duration::from_secs(20) {
            if let Ok(n) = mon.read(&mut buf) {
                if n == 0 {
                    break;
                }
                text.push_str(&String::from_utf8_lossy(&buf[..n]));
            }
            out = parse_xp(&text);
        }
        assert_eq!(
            out.len(),
            words,
            "monitor answered {} of {words} words",
            out.len()
        );
        out
    }

    /// Stack bytes the firmware used so far: the painted stack region `[lo, hi)`
    /// (cortex-m-rt paints it with 0xCCCCCCCC) scanned from its low end for the first
    /// word no longer the paint value.
    pub fn stack_peak_bytes(&self, lo: u32, hi: u32) -> u32 {
        let words = self.read_words(lo, ((hi - lo) / 4) as usize);
        let unused = words.iter().take_while(|w| **w == STACK_PAINT).count() as u32;
        hi - lo - 4 * unused
    }
}

/// Sends `name` (`-STOP`, `-CONT`) to process `pid`.
fn signal(pid: u32, name: &str) {
    let ok = Command::new("kill")
        .args([name, &pid.to_string()])
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "kill {name} QEMU");
}

/// A stopped QEMU process ([`Qemu::stop`]); continued (SIGCONT) on drop, also when a
/// test fails while it is stopped.
pub struct Stopped(u32);

impl Drop for Stopped {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-CONT", &self.0.to_string()])
            .status();
    }
}

/// The STACK region `[origin, origin + length)` of the mps2-an386 memory map
/// (`memory/mps2-an386.x`, the one definition).
pub fn stack_region() -> (u32, u32) {
    let text = std::fs::read_to_string(super::repo_root().join("memory/mps2-an386.x"))
        .expect("memory/mps2-an386.x");
    let line = text
        .lines()
        .map(str::trim)
        .find(|l| l.starts_with("STACK"))
        .expect("a STACK region");
    let field = |key: &str| -> u32 {
        let v = line
            .split(key)
            .nth(1)
            .expect(key)
            .trim_start_matches([' ', '=']);
        let v = v.split(',').next().unwrap_or("").trim();
        if let Some(k) = v.strip_suffix('K') {
            k.parse::<u32>().expect("size") * 1024
        } else {
            u32::from_str_radix(v.trim_start_matches("0x"), 16).expect("origin")
        }
    };
    let origin = field("ORIGIN");
    (origin, origin + field("LENGTH"))
}

/// The paint value of cortex-m-rt's `paint-stack`.
pub const STACK_PAINT: u32 = 0xCCCC_CCCC;

/// Words of the monitor's `xp /Nwx` answer (`addr: w w w w` lines).
fn parse_xp(text: &str) -> Vec<u32> {
    text.lines()
        .filter_map(|l| l.split_once(": "))
        .filter(|(a, _)| a.trim().chars().all(|c| c.is_ascii_hexdigit()))
        .flat_map(|(_, ws)| {
            ws.split_whitespace()
                .filter_map(|w| u32::from_str_radix(w.trim_start_matches("0x"), 16).ok())
                .collect::<Vec<_>>()
        })
        .collect()
}

fn rand_suffix() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.sock);
        let _ = std::fs::remove_file(&self.monitor);
    }
}

/// A ground station on the emulator's UART: QEMU and the station that decodes its bytes.
pub struct Link {
    /// The emulator.
    pub q: Qemu,
    /// The ground station.
    pub st: Station,
}

/// A command's three success reports (acceptance, start, completion).
pub const OK3: [Verification; 3] = [
    Verification::AcceptanceSuccess,
    Verification::StartSuccess,
    Verification::CompletionSuccess,
];

impl Link {
    /// A station on `q`'s UART once the firmware's boot event has arrived (asserted,
    /// within `timeout`).
    pub fn booted(q: Qemu, timeout: Duration) -> Link {
        let mut l = Link {
            q,
            st: Station::new(),
        };
        assert!(
            l.until(timeout, |s| !s.events(event::BOOT).is_empty()),
            "no boot event"
        );
        l
    }

    /// Sends `cmd`; its request ID.
    pub fn send(&mut self, cmd: &Tc) -> RequestId {
        let (frame, rid) = self.st.frame(cmd).unwrap();
        self.q.send(&frame);
        rid
    }

    /// A ping with its CRC corrupted is refused at acceptance with the link's CRC code
    /// (ICD: 0x0505) and nothing else: asserted within `timeout`.
    pub fn assert_bad_crc_refused(&mut self, timeout: Duration) {
        let rid = self.send_with_bad_crc(&Tc::Ping);
        let reps = self.complete(rid, timeout);
        assert!(
            matches!(
                reps[..],
                [Verification::AcceptanceFailure { code: 0x0505, .. }]
            ),
            "{reps:?}"
        );
    }

    /// Sends `cmd` with its packet's CRC corrupted (last byte inverted), framed; its
    /// request ID (the firmware refuses it with the link's CRC code, 0x0505).
    pub fn send_with_bad_crc(&mut self, cmd: &Tc) -> RequestId {
        let (mut pkt, rid) = self.st.packet(cmd).unwrap();
        if let Some(last) = pkt.last_mut() {
            *last ^= 0xff;
        }
        let mut frame = vec![0u8; pkt.len() * 2 + 4];
        let n = m2ctl::link::encode_frame(&pkt, &mut frame).unwrap();
        self.q.send(&frame[..n]);
        rid
    }

    /// The verification reports of `rid` once it has a final one (or `timeout`).
    pub fn complete(&mut self, rid: RequestId, timeout: Duration) -> Vec<Verification> {
        self.until(timeout, |s| s.finished(rid));
        self.st.reports(rid)
    }

    /// One-shot housekeeping, its three success reports asserted: the report this
    /// request made ([`Station::hk_answer`]: stamped in the cycle that executed it,
    /// between its acceptance and start reports), not whichever arrived last.
    pub fn housekeeping(&mut self, timeout: Duration) -> Housekeeping {
        let rid = self.send(&Tc::HousekeepingOneShot);
        assert_eq!(self.complete(rid, timeout), OK3, "housekeeping");
        self.st
            .hk_answer(rid)
            .expect("the one-shot's housekeeping report (between its acceptance and start reports)")
    }

    /// The first housekeeping report made after the packet `log[i]` (a later time
    /// stamp, same boot: [`Station::hk_after`]), once it has arrived (asserted within
    /// `timeout`), and its packet time.
    pub fn hk_after(&mut self, i: usize, timeout: Duration) -> (TmTime, Housekeeping) {
        assert!(
            self.until(timeout, |s| s.hk_after(i).next().is_some()),
            "no housekeeping report made after packet {i} ({:?}) within {timeout:?}",
            self.st.log.get(i)
        );
        let (t, h) = self.st.hk_after(i).next().unwrap();
        (t, *h)
    }

    /// Stops QEMU ([`Qemu::stop`]) and reads what it has sent: the station has every
    /// packet the guest made so far, and the guest's clock stands still, until the
    /// guard is dropped. The guest's clock is then at least the newest packet time
    /// received (and less than it plus the housekeeping period: a periodic report is
    /// made every period and sent in the same link pass unless the downlink is backed
    /// up).
    pub fn stop_and_drain(&mut self) -> Stopped {
        let stopped = self.q.stop();
        // QEMU writes the guest's bytes to the socket as the guest sends them: once it
        // is stopped, a read that times out has found everything it sent.
        loop {
            let bytes = self.q.read_for(Duration::from_millis(300));
            if bytes.is_empty() {
                break;
            }
            self.st.receive(&bytes);
        }
        stopped
    }

    /// Reads telemetry until `done` holds or `timeout` passes.
    pub fn until(&mut self, timeout: Duration, mut done: impl FnMut(&Station) -> bool) -> bool {
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
}
