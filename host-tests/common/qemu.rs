//! Runs the firmware image in QEMU (mps2-an386) with UART0 on a Unix socket, so a host
//! test can send telecommand bytes and read telemetry bytes like a ground station.
#![allow(dead_code)]

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The flight image built by `cargo build --profile flight --target thumbv7em-none-eabihf
/// --features firmware --bin m2fw` (scripts/qemu-link-test.sh builds it).
pub fn firmware_elf() -> PathBuf {
    elf_at("target/thumbv7em-none-eabihf/flight/m2fw")
}

/// An image under the crate directory; panics with a hint if it was not built.
pub fn elf_at(relative: &str) -> PathBuf {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(relative);
    assert!(
        p.exists(),
        "{} missing: build the firmware first (scripts/qemu-link-test.sh, scripts/qemu-fault-test.sh)",
        p.display()
    );
    p
}

/// Virtual time of QEMU's CPU: every guest instruction takes 2^ICOUNT_SHIFT ns (8 ns:
/// 125 M instructions per second of guest time). Timers, the watchdog and the control
/// rate run on this clock, so a loaded host slows the guest down instead of making
/// its cycles overrun; `sleep=on` keeps guest time from running ahead of real time.
pub const ICOUNT_SHIFT: u32 = 3;

/// A running QEMU with the firmware; killed on drop.
pub struct Qemu {
    child: Child,
    /// UART0 as a byte stream.
    pub uart: UnixStream,
    sock: PathBuf,
}

impl Qemu {
    /// Starts QEMU with the flight image and connects to UART0.
    pub fn start() -> Qemu {
        Self::start_elf(&firmware_elf())
    }

    /// Starts QEMU with `elf` and connects to UART0.
    pub fn start_elf(elf: &std::path::Path) -> Qemu {
        let sock = std::env::temp_dir().join(format!(
            "m2fw-uart-{}-{}.sock",
            std::process::id(),
            rand_suffix()
        ));
        let _ = std::fs::remove_file(&sock);
        let child = Command::new("qemu-system-arm")
            .args([
                "-cpu",
                "cortex-m4",
                "-machine",
                "mps2-an386",
                "-nographic",
                "-monitor",
                "none",
            ])
            .arg("-icount")
            .arg(format!("shift={ICOUNT_SHIFT},sleep=on"))
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
        Qemu { child, uart, sock }
    }

    /// Sends bytes to the firmware's UART.
    pub fn send(&mut self, bytes: &[u8]) {
        self.uart.write_all(bytes).unwrap();
    }

    /// Reads whatever arrives within `wait`.
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
    }
}
