//! Self-test and benchmark image (target only, `--features firmware`): the golden-vector
//! self-test of the flight kinematics, then the instruction-count benchmark sections,
//! then exit through semihosting with 0 only if every check passed. (The flight image,
//! `m2fw`, runs the same self-test at boot and then the controller.)
//!
//! The log goes out as defmt frames over semihosting; decode with
//! `defmt-print -e <this ELF>`. Lines tagged `BITS` carry the raw f32 results that
//! the host test `firmware_bits_match_host` compares with the host's.
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m as _; // critical-section implementation (single core) for defmt
use cortex_m_rt::entry;
use defmt_semihosting as _;
use m2ctl::board::active as hw;
use m2ctl::kinematics::{fk, ik, FkConfig, Geometry, Pose};
use m2ctl::{nominal, selftest};

/// A panic is a defect: end the run with the board's panic exit code.
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    defmt::error!("PANIC");
    hw::exit(hw::EXIT_PANIC)
}

/// Warm-start offset for the FK benchmark, per translation axis (mm): 5.7 um on each
/// axis is 9.9 um in all, "within 10 um" of the true pose.
const FK_BENCH_OFFSET_MM: f32 = 0.0057;
/// Warm-start offset for the FK benchmark, per rotation axis (rad; 2 arcsec).
const FK_BENCH_OFFSET_RAD: f32 = 2.0 / 206_264.8;

#[entry]
fn main() -> ! {
    defmt::info!("m2fw: M2 mechanism controller, kinematics self-test");
    let Ok(geom) = Geometry::<f32>::new(&nominal::prototype_with_flight_limits()) else {
        defmt::error!("nominal geometry invalid");
        hw::exit(hw::EXIT_FAIL)
    };
    let summary = selftest::run_all(&geom, |i, o| {
        defmt::info!(
            "BITS row={=u32} pass={=bool} it={=u8} ik={} fk={}",
            i,
            o.pass,
            o.fk_iterations,
            o.ik_bits,
            o.fk_bits
        );
    });
    defmt::info!(
        "SUMMARY rows={=u32} failures={=u32} max_ik_err_nm={=f64} max_fk_err_nm={=f64} max_fk_err_arcsec={=f64} max_fk_iter={=u8} digest={=u32:#010x}",
        summary.rows,
        summary.failures,
        summary.max_ik_err_mm * 1e6,
        summary.max_fk_err_mm * 1e6,
        summary.max_fk_err_arcsec,
        summary.max_fk_iterations,
        summary.digest
    );

    bench(&geom);

    let peak = hw::stack_peak_bytes();
    defmt::info!(
        "STACK peak_bytes={=u32} region_bytes={=u32}",
        peak,
        hw::stack_region_bytes()
    );
    if summary.failures == 0 {
        defmt::info!("SELFTEST PASS");
        hw::exit(hw::EXIT_PASS)
    } else {
        defmt::error!("SELFTEST FAIL");
        hw::exit(hw::EXIT_FAIL)
    }
}

/// Instruction-count sections for `qemu-insncount` (BENCH n=1: empty, n=2: IK,
/// n=3: FK warm-started within 10 um). Results are checked so a failure is visible.
fn bench(geom: &Geometry<f32>) {
    // A workspace pose away from home (mm, arcsec).
    let target = Pose::<f32>::from_mm_arcsec([0.8, -0.6, 0.4], [45.0, -30.0, 20.0]);

    hw::bench_start();
    hw::bench_end();

    let g = black_box(geom);
    let p = black_box(target);
    hw::bench_start();
    let strokes = ik(g, &p);
    hw::bench_end();
    let Ok(strokes) = black_box(strokes) else {
        defmt::error!("bench: IK failed");
        return;
    };

    let mut start = target;
    for v in start.translation_mm.iter_mut() {
        *v += FK_BENCH_OFFSET_MM;
    }
    for v in start.rotation_rad.iter_mut() {
        *v += FK_BENCH_OFFSET_RAD;
    }
    let cfg = FkConfig::default();
    let s = black_box(strokes);
    let st = black_box(start);
    hw::bench_start();
    let sol = fk(g, &s, &st, &cfg);
    hw::bench_end();
    match black_box(sol) {
        Ok(sol) => defmt::info!(
            "bench: FK warm start converged in {=u8} steps",
            sol.iterations
        ),
        Err(_) => defmt::error!("bench: FK failed"),
    }
}
