//! Control-cycle benchmark image (target only, `--features firmware`): the controller
//! with the QEMU slider model, measured with `qemu-insncount` markers around whole
//! control cycles. BENCH n=1: empty pair; n=2: the cycle that receives a move
//! telecommand (decode, acceptance report, both ends checked); n=3..7: the next five
//! cycles (the path sampled `controller::PLAN_SAMPLES_PER_CYCLE` IK per cycle, start report, the
//! move begins); n=8..10: steady cycles during the move; n=11: a cycle that also emits
//! housekeeping.
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
/// Cycles measured after the telecommand cycle (planning, then the first move cycles).
const BENCH_PLANNING_CYCLES: u32 = 5;

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
    for _ in 0..BENCH_PLANNING_CYCLES {
        ctl.mechanism_mut().step();
        hw::bench_start();
        ctl.tick(None, &mut sink);
        hw::bench_end();
    }
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
    let moving_ok = hk.state == State::Moving.code() && hk.fault_flags == 0;
    moving_ok && bench_table_cycles(&mut ctl, &mut sink)
}

/// Most cycles to wait for the move to end before the table benchmark.
const MAX_WAIT_CYCLES: u32 = 100_000;
/// Table ID of the table the benchmark commits.
const BENCH_TABLE_ID: u32 = 9;

/// BENCH n=12: the cycle that commits an uploaded table (CRC, decode, validation,
/// flash write of the inactive bank); n=13: the cycle that activates it. Both are
/// accepted only while the mechanism is at rest.
fn bench_table_cycles<M, F>(ctl: &mut Controller<M, F>, sink: &mut CountingSink) -> bool
where
    M: m2ctl::hw::SliderDrives + m2ctl::hw::StrokeEncoders,
    F: embedded_storage::nor_flash::NorFlash,
{
    for _ in 0..MAX_WAIT_CYCLES {
        if ctl.state() == State::Idle {
            break;
        }
        ctl.tick(None, sink);
    }
    let mut table = m2ctl::table::Table::nominal();
    table.table_id = BENCH_TABLE_ID;
    let bytes = table.to_bytes();
    let mut seq = 10u16;
    let mut send =
        |ctl: &mut Controller<M, F>, sink: &mut CountingSink, cmd: &Command, measure: bool| {
            let mut pkt = [0u8; MAX_TC_PACKET_LEN];
            let Ok(n) = encode_telecommand(cmd, TcHeader::new(seq), &mut pkt) else {
                return;
            };
            seq += 1;
            if measure {
                hw::bench_start();
            }
            ctl.tick(pkt.get(..n), sink);
            if measure {
                hw::bench_end();
            }
        };
    for (off, chunk) in m2ctl::link::tm::dump_chunks(&bytes) {
        if let Ok(c) = m2ctl::link::TableChunk::new(off, chunk) {
            send(ctl, sink, &Command::LoadTableChunk(c), false);
        }
    }
    send(
        ctl,
        sink,
        &Command::CommitTable {
            crc32: table.crc32(),
        },
        true,
    );
    send(ctl, sink, &Command::ActivateTable, true);
    let ok = ctl.active_table().table_id == BENCH_TABLE_ID;
    if !ok {
        defmt::error!("bench: the committed table did not become active");
    }
    ok
}
