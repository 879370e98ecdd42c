//! The flight image of the second board (STM32F405 Netduino Plus 2, feature
//! `board-netduinoplus2`) in QEMU's `netduinoplus2` machine, driven over USART1 like a
//! ground station: boot event, ping, housekeeping, a malformed packet, a refused move.
//!
//! QEMU 7.2 models that machine's USART, SPI and timers but not its GPIO, RCC, IWDG or
//! flash interface (src/board/netduinoplus2.rs): the link and the control task run;
//! the BiSS chain answers nothing (SPI with no slave) and the drives' FAULT inputs read
//! low (active), so the controller reports the encoder and drive faults and refuses
//! motion: that is what this test checks, with the link itself. Needs the image built
//! and QEMU, so it is `#[ignore]`d in the plain test run;
//! `scripts/qemu-link-test-netduinoplus2.sh` (and CI) runs it.

mod common;

use std::time::Duration;

use common::qemu::{elf_at, Link, Qemu, NETDUINOPLUS2, OK3};
use m2ctl::controller::{event, ResetCause, State};
use m2ctl::link::command::WirePose;
use m2ctl::link::tm::Verification;
use m2ctl::link::Command;
use m2ctl::station::Tm;
use m2ctl::supervision::FaultFlags;

/// The flight image for this board, as the script leaves it.
const ELF: &str = "target/m2fw-netduinoplus2.elf";

#[test]
#[ignore = "needs QEMU and the netduinoplus2 image: scripts/qemu-link-test-netduinoplus2.sh"]
fn netduinoplus2_flight_image_answers_over_usart1() {
    let t = Duration::from_secs(20);
    let mut l = Link::booted(Qemu::start_elf_on(&elf_at(ELF), NETDUINOPLUS2), t);
    let rid = l.send(&Command::Ping);
    assert_eq!(l.complete(rid, t), OK3);
    // This ping's own reply (among the packets its execution made), not any received.
    let answer =
        l.st.answer(rid)
            .expect("ping: acceptance and start reports");
    assert!(answer.iter().any(|(_, tm)| **tm == Tm::Ping), "{answer:?}");

    let hk = l.housekeeping(t);
    println!(
        "HK: state {} faults {:#x} warnings {:#x} fault legs {:#04x} cycle {} reset cause {} boot {}",
        hk.state, hk.fault_flags, hk.warning_flags, hk.fault_legs, hk.cycle_counter,
        hk.reset_cause, hk.boot_count
    );
    // First boot of a fresh QEMU, on the nominal table.
    assert_eq!(hk.reset_cause, ResetCause::PowerOn.code());
    assert_eq!(hk.boot_count, 1);
    assert_eq!(hk.active_table_id, 0);
    // No encoder answers in QEMU and every drive's FAULT input reads low (active): both
    // faults are latched on all six legs, the state is faulted.
    assert_ne!(hk.fault_flags & FaultFlags::ENCODER_READ_FAILURE.bits(), 0);
    assert_ne!(hk.fault_flags & FaultFlags::DRIVE_FAULT.bits(), 0);
    assert_eq!(hk.fault_legs, 0x3f);
    assert_eq!(hk.state, State::Faulted.code());

    // The control task runs (TIM3 at the control rate): the cycle counter advances.
    let later = l.housekeeping(t);
    assert!(
        later.cycle_counter > hk.cycle_counter,
        "cycle counter {} then {}",
        hk.cycle_counter,
        later.cycle_counter
    );

    // A malformed packet (bad CRC) is refused with the link's code.
    l.assert_bad_crc_refused(t);

    // A move with faults latched is refused with a code; nothing is commanded.
    let rid = l.send(&Command::MoveAbsolute(WirePose {
        translation_nm: [50_000, 0, 0],
        rotation_uas: [0, 0, 0],
    }));
    let reps = l.complete(rid, t);
    println!("move while faulted: {reps:?}");
    assert!(
        reps.iter().any(|v| matches!(
            v,
            Verification::StartFailure { .. } | Verification::AcceptanceFailure { .. }
        )),
        "{reps:?}"
    );
    let after = l.housekeeping(t);
    assert_eq!(after.strokes_commanded_nm, hk.strokes_commanded_nm);
    assert_eq!(
        l.st.events(event::BOOT).len(),
        1,
        "the firmware rebooted: boot detail {:?}",
        l.st.events(event::BOOT_DETAIL)
    );
}
