//! Control-cycle benchmark image (target only, `--features firmware`): the controller
//! with the QEMU slider model, measured with `qemu-insncount` markers around whole
//! control cycles. BENCH n=1: empty pair; n=2: the cycle that receives and plans a move;
//! n=3..5: steady cycles during the move; n=6: a cycle that also emits housekeeping.
//! Exits through semihosting (0 if the move was running without a fault).
#![no_std]
#![no_main]
#![deny(unsafe_code)]

use cortex_m as _; // critical-section implementation (single core) for defmt
use cortex_m_rt::entry;
use defmt_semihosting as _;
use m2ctl::board::active::{self as hw, TableFlash};
use m2ctl::controller::{Controller, ControllerConfig, State, TmSink, HK_PERIOD_CYCLES};
use m2ctl::link::command::WirePose;
use m2ctl::link::tc::{encode_telecommand, TcHeader};
use m2ctl::link::{Command, MAX_TC_PACKET_LEN};
use m2ctl::motion::CYCLE_S;
use m2ctl::plant_model::SliderModel;
use m2ctl::table::{TableStore, FLIGHT_LAYOUT};

/// Exit code: the benchmark ran as intended.
const EXIT_PASS: i32 = 0;
/// Exit code: the move did not run (the figures would not be what they claim).
const EXIT_FAIL: i32 = 1;
/// Exit code: panic.
const EXIT_PANIC: i32 = 101;

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    defmt::error!("PANIC");
    hw::exit(EXIT_PANIC)
}

#[entry]
fn main() -> ! {
    hw::bench_start();
    hw::bench_end();
    let ok = bench_cycle();
    defmt::info!("STACK peak_bytes={=u32}", hw::stack_peak_bytes());
    hw::exit(if ok { EXIT_PASS } else { EXIT_FAIL })
}

/// Telemetry sink that only counts bytes (the benchmark measures the controller).
struct CountingSink(u32);

impl TmSink for CountingSink {
    fn send(&mut self, frame: &[u8]) {
        self.0 = self.0.wrapping_add(frame.len() as u32);
    }
}

/// Speed of the slider model in the cycle benchmark (mm/s).
const BENCH_MODEL_SPEED_MM_PER_S: f32 = 1.0;
/// Cycles into the move before the steady-cycle measurements (cruising by then).
const BENCH_CRUISE_CYCLES: u32 = 1500;

/// Instruction counts of whole control cycles. Returns whether the move was running
/// without a fault throughout.
#[inline(never)]
fn bench_cycle() -> bool {
    let Ok(store) = TableStore::new(TableFlash::take(), FLIGHT_LAYOUT) else {
        defmt::error!("bench: store");
        return false;
    };
    let mech = SliderModel::new(BENCH_MODEL_SPEED_MM_PER_S, CYCLE_S);
    let mut ctl = Controller::new(mech, store, ControllerConfig::default());
    let mut sink = CountingSink(0);
    // Run to just after a housekeeping cycle so the measured cycles emit none.
    for _ in 0..2 {
        ctl.mechanism_mut().step();
        ctl.tick(None, &mut sink);
    }
    let target = WirePose {
        translation_nm: [800_000, -600_000, 400_000],
        rotation_uas: [45_000_000, -30_000_000, 20_000_000],
    };
    let mut pkt = [0u8; MAX_TC_PACKET_LEN];
    let Ok(n) = encode_telecommand(&Command::MoveAbsolute(target), TcHeader::new(1), &mut pkt)
    else {
        defmt::error!("bench: encode");
        return false;
    };
    let tc = pkt.get(..n);
    ctl.mechanism_mut().step();
    hw::bench_start();
    ctl.tick(tc, &mut sink);
    hw::bench_end();
    for _ in 0..BENCH_CRUISE_CYCLES {
        ctl.mechanism_mut().step();
        ctl.tick(None, &mut sink);
    }
    for _ in 0..3 {
        ctl.mechanism_mut().step();
        hw::bench_start();
        ctl.tick(None, &mut sink);
        hw::bench_end();
    }
    while ctl.cycle() % HK_PERIOD_CYCLES != 0 {
        ctl.mechanism_mut().step();
        ctl.tick(None, &mut sink);
    }
    ctl.mechanism_mut().step();
    hw::bench_start();
    ctl.tick(None, &mut sink);
    hw::bench_end();
    let hk = ctl.housekeeping();
    defmt::info!(
        "CONTROLLER size_bytes={=u32}",
        core::mem::size_of_val(&ctl) as u32
    );
    defmt::info!(
        "bench: control cycles measured in state {=u8}, faults {=u32:#x}, {=u32} TM bytes",
        hk.state,
        hk.fault_flags,
        sink.0
    );
    hk.state == State::Moving.code() && hk.fault_flags == 0
}
