//! Table-validation benchmark image (target only, `--features firmware`, built with the
//! flight profile so it measures the flight image's code): the validation of a table in
//! bounded steps (`table::validate::ValidationState::step`, one per worker step once
//! the worker runs it so), each step a separately measured section for the instruction
//! counter (`bench_start`/`bench_end`).
//!
//! Validations measured: the nominal table with the flight configuration (3 grid
//! points per axis), then with every other grid density the configuration allows (2, 4,
//! 5), each accepted in exactly `validation_steps` steps; then a table with two nearly
//! redundant legs whose FK from home at workspace corner 1 runs to its iteration limit
//! without converging (the longest corner step), refused so (0x041A, detail 0x0401; the
//! host test `table::validate::tests::twin_legs_of_the_self_test` expects the same).
//!
//! Sections: `BENCH n=1` is the empty pair; then one per step. A `VALIDATION table=..
//! points=.. first=n steps=k code=.. detail=..` line (defmt log) names the sections of
//! each validation, `VALIDATION_STATE bytes=..` gives the state's size (RAM it takes
//! beside the table). `scripts/bench.sh` joins them. Exits through semihosting: 0 if
//! every validation gave what it should, so the figures are what they claim.
//!
//! A separate image, not the self-test's: linked beside the validation, the IK's
//! `strokes_unchecked` is no longer inlined into the workspace check (as in `m2fw`),
//! which would change the self-test image's IK figure.
#![no_std]
#![no_main]
#![deny(unsafe_code)]

use core::hint::black_box;

use cortex_m as _; // critical-section implementation (single core) for defmt
use cortex_m_rt::entry;
use defmt_semihosting as _;
use m2ctl::board::active as hw;
use m2ctl::table::validate::{
    validation_steps, ValidationState, MAX_GRID_POINTS_PER_AXIS, MIN_GRID_POINTS_PER_AXIS,
};
use m2ctl::table::{Table, ValidationConfig, ValidationError};

/// Grid points per axis of the validations of the nominal table: the flight
/// configuration's first, then every other the configuration allows.
const GRIDS: [u8; 4] = [
    ValidationConfig::flight().grid_points_per_axis,
    MIN_GRID_POINTS_PER_AXIS,
    4,
    MAX_GRID_POINTS_PER_AXIS,
];

/// Offset (mm) of the twin leg of the last table (see the module docs).
const TWIN_LEG_OFFSET_MM: f64 = 0.1;
/// What that validation returns: FK failed (0x041A) at corner 1, not converged (FK code
/// 0x0304: its low byte in the detail's high byte).
const TWIN_LEG_REFUSAL: (u16, u16) = (0x041a, 0x0401);

/// A panic is a defect: end the run with the board's panic exit code.
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    defmt::error!("PANIC");
    hw::exit(hw::EXIT_PANIC)
}

#[entry]
fn main() -> ! {
    defmt::info!(
        "VALIDATION_STATE bytes={=u32}",
        core::mem::size_of::<ValidationState>() as u32
    );
    hw::bench_start();
    hw::bench_end();
    let mut section = 1;
    let mut ok = true;
    let nominal = Table::nominal();
    for points in GRIDS {
        let cfg = ValidationConfig {
            grid_points_per_axis: points,
            ..ValidationConfig::flight()
        };
        let (r, steps) = measure("nominal", &nominal, &cfg, &mut section);
        if r.is_err() || steps != validation_steps(points) {
            defmt::error!("the nominal table refused, or not in its steps");
            ok = false;
        }
    }
    // Leg 2 a twin of leg 1, under a coordinate tolerance that lets it through.
    let mut twin = nominal;
    let (l0, e) = (twin.legs[0], TWIN_LEG_OFFSET_MM);
    twin.legs[1].a_mm = [l0.a_mm[0] + e, l0.a_mm[1] - 0.7 * e, l0.a_mm[2]];
    twin.legs[1].b_mm = [l0.b_mm[0] + 0.3 * e, l0.b_mm[1] + e, l0.b_mm[2]];
    let cfg = ValidationConfig {
        max_coordinate_deviation_mm: 200.0,
        ..ValidationConfig::flight()
    };
    let (r, _) = measure("twin_legs", &twin, &cfg, &mut section);
    if r.map_err(|e| (e.code(), e.detail())) != Err(TWIN_LEG_REFUSAL) {
        defmt::error!("the twin-leg table not refused by FK at its iteration limit");
        ok = false;
    }
    if ok {
        defmt::info!("VALIDBENCH PASS");
        hw::exit(hw::EXIT_PASS)
    } else {
        defmt::error!("VALIDBENCH FAIL");
        hw::exit(hw::EXIT_FAIL)
    }
}

/// Validates `t` against `cfg` step by step, one section per step from section
/// `*section + 1` on, and announces them (`VALIDATION` line, module docs). The result
/// and the number of steps.
fn measure(
    name: &str,
    t: &Table,
    cfg: &ValidationConfig,
    section: &mut u32,
) -> (Result<(), ValidationError>, u32) {
    let t = black_box(t);
    let c = black_box(cfg);
    let mut v = ValidationState::new();
    let mut steps = 0u32;
    let result = loop {
        hw::bench_start();
        let r = v.step(t, c);
        hw::bench_end();
        steps += 1;
        if let Some(r) = black_box(r) {
            break r;
        }
    };
    let (code, detail) = match result {
        Ok(()) => (0, 0),
        Err(e) => (e.code(), e.detail()),
    };
    defmt::info!(
        "VALIDATION table={=str} points={=u8} first={=u32} steps={=u32} code={=u16:#06x} detail={=u16:#06x}",
        name,
        cfg.grid_points_per_axis,
        *section + 1,
        steps,
        code,
        detail
    );
    *section += steps;
    (result, steps)
}
