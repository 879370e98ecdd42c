//! Flight image (target only, `--features firmware`): the M2 mechanism controller.
//!
//! Boot: kinematics self-test on the golden vectors (a failure ends the QEMU run with
//! exit code 1: on a real board this is where safe mode would be entered), table boot
//! selection from the two flash banks, then the 1 kHz cyclic executive
//! ([`Controller::tick`]) forever. Telecommands arrive as COBS frames on UART0 and
//! telemetry leaves the same way (docs/icd.md). QEMU has no sliders: the board drives
//! a `no_std` slider/encoder model ([`SliderModel`]) behind the same traits.
#![no_std]
#![no_main]
#![deny(unsafe_code)]

use cortex_m as _; // critical-section implementation (single core) for defmt
use cortex_m_rt::entry;
use defmt_semihosting as _;
use embedded_hal_nb::serial::{Read, Write};
use m2ctl::board::active::{self as hw, CycleTimer, TableFlash, Uart};
use m2ctl::controller::{Controller, ControllerConfig};
use m2ctl::kinematics::Geometry;
use m2ctl::link::framing::Deframer;
use m2ctl::link::MAX_TC_PACKET_LEN;
use m2ctl::motion::CYCLE_S;
use m2ctl::nominal;
use m2ctl::plant_model::SliderModel;
use m2ctl::selftest;
use m2ctl::table::{TableStore, FLIGHT_LAYOUT};

/// Exit code: the boot self-test failed.
const EXIT_SELFTEST_FAIL: i32 = 1;
/// Speed of the QEMU slider model (mm/s): faster than the motion limits, so the model
/// follows the setpoints like a good drive.
const MODEL_SLIDER_SPEED_MM_PER_S: f32 = 1.0;
/// Most UART bytes taken per cycle (bounds the cycle time; the rest waits in the UART).
const MAX_RX_BYTES_PER_CYCLE: usize = 64;

/// UART transmitter as a telemetry sink (blocking per byte; the UART is faster than
/// the telemetry rate).
struct UartSink<'a>(&'a mut Uart);

impl m2ctl::controller::TmSink for UartSink<'_> {
    fn send(&mut self, frame: &[u8]) {
        for b in frame {
            let _ = nb::block!(self.0.write(*b));
        }
    }
}

#[entry]
fn main() -> ! {
    defmt::info!("m2fw: M2 mechanism controller");
    let Ok(geom) = Geometry::<f32>::new(&nominal::prototype_with_flight_limits()) else {
        defmt::error!("nominal geometry invalid");
        hw::exit(EXIT_SELFTEST_FAIL)
    };
    let summary = selftest::run_all(&geom, |_, _| {});
    if summary.failures != 0 {
        defmt::error!(
            "SELFTEST FAIL: {=u32} of {=u32} rows",
            summary.failures,
            summary.rows
        );
        hw::exit(EXIT_SELFTEST_FAIL)
    }
    defmt::info!(
        "SELFTEST PASS rows={=u32} digest={=u32:#010x}",
        summary.rows,
        summary.digest
    );

    let store = match TableStore::new(TableFlash::take(), FLIGHT_LAYOUT) {
        Ok(s) => s,
        Err(_) => {
            defmt::error!("table store layout invalid");
            hw::exit(EXIT_SELFTEST_FAIL)
        }
    };
    let mech = SliderModel::new(MODEL_SLIDER_SPEED_MM_PER_S, CYCLE_S);
    let mut ctl = Controller::new(mech, store, ControllerConfig::default());
    defmt::info!(
        "table: source={=u8} id={=u32}",
        ctl.boot_report().source.code(),
        ctl.active_table().table_id
    );

    let Some(peripherals) = cortex_m::Peripherals::take() else {
        defmt::error!("peripherals taken twice");
        hw::exit(EXIT_SELFTEST_FAIL)
    };
    let mut timer = CycleTimer::start(peripherals.SYST);
    let mut uart = Uart::uart0();
    let mut deframer: Deframer = Deframer::new();
    let mut packet = [0u8; MAX_TC_PACKET_LEN];
    loop {
        // Take received bytes; at most one complete telecommand per cycle.
        let mut tc_len: Option<usize> = None;
        for _ in 0..MAX_RX_BYTES_PER_CYCLE {
            let Ok(byte) = uart.read() else { break };
            if let Some(Ok(frame)) = deframer.push_byte(byte) {
                if let Some(dst) = packet.get_mut(..frame.len()) {
                    dst.copy_from_slice(frame);
                    tc_len = Some(frame.len());
                }
                break;
            }
        }
        let tc = tc_len.and_then(|n| packet.get(..n));
        ctl.mechanism_mut().step();
        ctl.tick(tc, &mut UartSink(&mut uart));
        timer.wait();
    }
}
