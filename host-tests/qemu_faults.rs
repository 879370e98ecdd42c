//! The fault-test build of the flight image in QEMU (`--features fault-test`, built by
//! `scripts/qemu-fault-test.sh`): faults injected on purpose, one stage per boot, and
//! what the firmware reports about each over its UART, as a ground station sees it:
//! 1. after power-on: five overrunning control cycles (the deadline fault latches,
//!    event 0x0030, housekeeping counts them), then the control task hangs: the
//!    watchdog resets the board;
//! 2. after the watchdog reset: the boot reports the watchdog and boot 2; then a stack
//!    overflow runs into the MPU guard: MemManage, reset;
//! 3. after that reset: the boot reports the fault and boot 3; the link works;
//! 4. after QEMU's system_reset: the boot reports an external reset and boot 4.
//!
//! Boot 1 is a power-on with boot count 1 (a new QEMU process: no reset record in RAM).
//!
//! Needs QEMU and the image, so it is `#[ignore]`d in the plain test run.

mod common;

use std::time::{Duration, Instant};

use common::qemu::{elf_at, Link, Qemu};
use m2ctl::controller::{event, ResetCause};
use m2ctl::station::{Station, Tm};
use m2ctl::supervision::FaultFlags;

/// Where scripts/qemu-fault-test.sh puts the fault-test build of m2fw.
const FAULT_TEST_ELF: &str = "target/m2fw-fault-test";
/// Overrunning cycles the fault-test build injects after power-on (main.rs).
const INJECTED_OVERRUNS: u16 = 5;
/// How long a one-shot housekeeping request may take to be answered.
const HK_TIMEOUT: Duration = Duration::from_secs(10);

impl Link {
    /// Boot-detail events so far: (reset cause code, boot count).
    fn boots(&self) -> Vec<(u32, u32)> {
        self.st
            .events(event::BOOT_DETAIL)
            .iter()
            .map(|aux| (aux[1] & 0xFF, aux[1] >> 16))
            .collect()
    }
}

#[test]
#[ignore = "needs QEMU and the fault-test image: scripts/qemu-fault-test.sh"]
fn overruns_hang_and_overflow_reset_with_their_cause_reported() {
    let mut l = Link {
        q: Qemu::start_elf(&elf_at(FAULT_TEST_ELF)),
        st: Station::new(),
    };
    let t = Duration::from_secs(30);

    // Boot 1: power-on.
    assert!(
        l.until(t, |s| !s.events(event::BOOT_DETAIL).is_empty()),
        "no boot"
    );
    assert_eq!(
        l.boots(),
        [(u32::from(ResetCause::PowerOn.code()), 1)],
        "first boot"
    );

    // Overruns: the deadline fault latches and the event names the count. The report
    // checked is the first periodic housekeeping made after the event (time stamp
    // later than the event's, same boot): made before the hang whatever the host's
    // speed, where a one-shot request sent on seeing the event raced the hang
    // (2.5 s of guest time later, and the guest runs ahead of a loaded host).
    assert!(
        l.until(t, |s| !s.events(event::DEADLINE_MISSED).is_empty()),
        "no deadline-missed event"
    );
    let missed =
        l.st.log
            .iter()
            .position(|m| matches!(m, Tm::Event(_, id, _) if *id == event::DEADLINE_MISSED))
            .unwrap();
    let (hk_at, hk) = l.hk_after(missed, t);
    assert!(
        hk.cycle_overruns >= INJECTED_OVERRUNS,
        "overruns counted: {}",
        hk.cycle_overruns
    );
    assert_ne!(
        hk.fault_flags & FaultFlags::DEADLINE_MISSED.bits(),
        0,
        "{hk:?}"
    );
    println!(
        "overruns: {} counted, deadline fault latched (flags {:#x}; housekeeping at OBT {:.3} s, event at {:.3} s)",
        hk.cycle_overruns,
        hk.fault_flags,
        hk_at.to_ticks() as f64 / 65536.0,
        l.st.log_times[missed].to_ticks() as f64 / 65536.0
    );

    // The hang: the watchdog resets; boot 2 reports it.
    let t_hang = Instant::now();
    assert!(
        l.until(t, |s| s.events(event::BOOT_DETAIL).len() >= 2),
        "no watchdog reset"
    );
    assert_eq!(
        l.boots()[1],
        (u32::from(ResetCause::Watchdog.code()), 2),
        "boot after the hang"
    );
    println!(
        "hang: watchdog reset seen {:.2} s after the overrun report, boot 2 reports cause watchdog",
        t_hang.elapsed().as_secs_f64()
    );

    // The stack overflow: MPU guard, fault, reset; boot 3 reports it.
    assert!(
        l.until(t, |s| s.events(event::BOOT_DETAIL).len() >= 3),
        "no overflow reset"
    );
    assert_eq!(
        l.boots()[2],
        (u32::from(ResetCause::HardFault.code()), 3),
        "boot after the overflow"
    );
    let hk = l.housekeeping(HK_TIMEOUT);
    assert_eq!(
        (hk.reset_cause, hk.boot_count),
        (ResetCause::HardFault.code(), 3)
    );
    assert_eq!(
        hk.fault_flags, 0,
        "a fresh boot has no latched fault: {hk:?}"
    );
    assert_eq!(l.st.bad_frames, 0);
    println!("overflow: MPU guard fault, reset, boot 3 reports cause hard fault; link up");

    // An external reset (QEMU's system_reset, as the reset pin or a debugger): boot 4
    // reports cause 5, external, not the watchdog (ICD section 4, reset causes).
    l.q.system_reset();
    assert!(
        l.until(t, |s| s.events(event::BOOT_DETAIL).len() >= 4),
        "no boot after system_reset"
    );
    assert_eq!(
        l.boots()[3],
        (u32::from(ResetCause::External.code()), 4),
        "boot after an external reset"
    );
    println!("external reset: boot 4 reports cause external");
}
