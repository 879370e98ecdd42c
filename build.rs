//! Build script:
//! * puts the board's memory map on the linker search path as `board-memory.x`, which
//!   the package root's `memory.x` (what cortex-m-rt's `link.x` includes; the linker
//!   finds it first, in its working directory) includes, and, for a board with its own
//!   interrupt table, its `device.x` (cortex-m-rt's `device` feature), for the firmware,
//!   thumb targets only: `memory/mps2-an386.x` + `memory/mps2-an386-device.x` (the
//!   default board) or `memory/netduinoplus2.x` (feature `board-netduinoplus2`; its
//!   `device.x` is the stm32f4 PAC's). No `device.x` may sit in the package root (the
//!   linker would take that one for every board), and `memory.x` there stays
//!   board-independent;
//! * reads the TABLE and STACK regions of the board's memory map into Rust constants
//!   (`memory_x.rs`), so the board glue can assert at compile time that its table
//!   layout and stack guard match it;
//! * turns `testdata/ik_golden.csv` into Rust constants for the self-test, so the
//!   firmware image carries no decimal parser (f64 parsing is ~20 KiB of flash).
use std::{env, fs, path::PathBuf};

const GOLDEN_CSV: &str = "testdata/ik_golden.csv";
/// Memory map of the default board (QEMU mps2-an386).
const MEMORY_MPS2: &str = "memory/mps2-an386.x";
/// Memory map of the Netduino Plus 2 (feature `board-netduinoplus2`).
const MEMORY_NETDUINOPLUS2: &str = "memory/netduinoplus2.x";
/// Interrupt handler names of the default board (its RTIC device description).
const DEVICE_MPS2: &str = "memory/mps2-an386-device.x";
/// The board's map in OUT_DIR, included by the package root's `memory.x`.
const BOARD_MEMORY: &str = "board-memory.x";
const GOLDEN_COLUMNS: usize = 12;
/// The flight image's boot self-test takes every this-many-th golden row (flash).
const BOOT_ROW_STRIDE: usize = 10;

fn main() {
    println!("cargo:rerun-if-changed={MEMORY_MPS2}");
    println!("cargo:rerun-if-changed={DEVICE_MPS2}");
    println!("cargo:rerun-if-changed={MEMORY_NETDUINOPLUS2}");
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed={GOLDEN_CSV}");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let target = env::var("TARGET").unwrap_or_default();
    let netduinoplus2 = env::var_os("CARGO_FEATURE_BOARD_NETDUINOPLUS2").is_some();
    if target.starts_with("thumb") {
        if netduinoplus2 {
            fs::write(
                out.join(BOARD_MEMORY),
                include_bytes!("memory/netduinoplus2.x"),
            )
            .expect("write board-memory.x");
            // The PAC's device.x is the one: none of ours may shadow it (OUT_DIR outlives a
            // change of board features).
            let _ = fs::remove_file(out.join("device.x"));
        } else {
            fs::write(
                out.join(BOARD_MEMORY),
                include_bytes!("memory/mps2-an386.x"),
            )
            .expect("write board-memory.x");
            fs::write(
                out.join("device.x"),
                include_bytes!("memory/mps2-an386-device.x"),
            )
            .expect("write device.x");
        }
        // A memory.x of an older build in OUT_DIR would shadow nothing (the root's is
        // found first) but would mislead a reader: gone.
        let _ = fs::remove_file(out.join("memory.x"));
        println!("cargo:rustc-link-search={}", out.display());
    }
    write_memory_constants(
        &out,
        if netduinoplus2 {
            MEMORY_NETDUINOPLUS2
        } else {
            MEMORY_MPS2
        },
    );
    let text = fs::read_to_string(GOLDEN_CSV).expect("read testdata/ik_golden.csv");
    let mut rows = String::new();
    let mut n = 0usize;
    let mut boot_rows = String::new();
    let mut n_boot = 0usize;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with('x') {
            continue;
        }
        let v: Vec<f64> = line
            .split(',')
            .map(|f| f.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .unwrap_or_else(|e| panic!("{GOLDEN_CSV}:{}: {e}", i + 1));
        assert_eq!(
            v.len(),
            GOLDEN_COLUMNS,
            "{GOLDEN_CSV}:{}: expected 12 fields",
            i + 1
        );
        let row = format!(
            "    GoldenRow {{ pose: [{:?}, {:?}, {:?}, {:?}, {:?}, {:?}], strokes_mm: [{:?}, {:?}, {:?}, {:?}, {:?}, {:?}] }},\n",
            v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9], v[10], v[11]
        );
        if n % BOOT_ROW_STRIDE == 0 {
            // The boot rows in f32 (`selftest::BootRow`): Rust prints the shortest
            // decimal that reads back as the same f32.
            let f = |k: usize| format!("{:?}", v[k] as f32);
            boot_rows.push_str(&format!(
                "    BootRow {{ pose: [{}, {}, {}, {}, {}, {}], strokes_mm: [{}, {}, {}, {}, {}, {}] }},\n",
                f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7), f(8), f(9), f(10), f(11)
            ));
            n_boot += 1;
        }
        rows.push_str(&row);
        n += 1;
    }
    let code = format!(
        "/// The golden rows of `{GOLDEN_CSV}`, generated by build.rs.\npub const GOLDEN_ROWS: [GoldenRow; {n}] = [\n{rows}];\n\
         /// Every {BOOT_ROW_STRIDE}th golden row (from the first): the flight image's boot self-test\n\
         /// (the self-test image runs all of them), in f32.\npub const BOOT_GOLDEN_ROWS: [BootRow; {n_boot}] = [\n{boot_rows}];\n"
    );
    fs::write(out.join("golden.rs"), code).expect("write golden.rs");
}

/// Regions of `memory.x` whose origin and length the board glue checks.
const MEMORY_X_REGIONS: [&str; 2] = ["TABLE", "STACK"];

/// Writes `memory_x.rs`: `<REGION>_ORIGIN` and `<REGION>_LENGTH` (u32) of the regions
/// in [`MEMORY_X_REGIONS`], read from `memory.x`'s MEMORY block.
fn write_memory_constants(out: &std::path::Path, memory_x: &str) {
    let text = fs::read_to_string(memory_x).expect("read the board's memory map");
    let mut code = String::from("// Generated by build.rs from memory.x.\n");
    for name in MEMORY_X_REGIONS {
        let line = text
            .lines()
            .map(str::trim)
            .find(|l| l.split(':').next().map(str::trim) == Some(name))
            .unwrap_or_else(|| panic!("memory.x: no region {name}"));
        let field = |key: &str| -> u64 {
            let rest = line
                .split(key)
                .nth(1)
                .unwrap_or_else(|| panic!("memory.x: {name} has no {key}"));
            let expr = rest
                .trim_start_matches([' ', '='])
                .split(',')
                .next()
                .unwrap_or("");
            eval_size(expr)
                .unwrap_or_else(|| panic!("memory.x: {name} {key}: cannot read {expr:?}"))
        };
        let (origin, length) = (field("ORIGIN"), field("LENGTH"));
        code.push_str(&format!(
            "/// `{name}` origin in memory.x.\npub const {name}_ORIGIN: u32 = {origin:#x};\n/// `{name}` length in memory.x (bytes).\npub const {name}_LENGTH: u32 = {length:#x};\n"
        ));
    }
    fs::write(out.join("memory_x.rs"), code).expect("write memory_x.rs");
}

/// Evaluates a linker-script size: numbers (decimal or 0x hex, optional K/M suffix)
/// joined by `+` and `-`.
fn eval_size(expr: &str) -> Option<u64> {
    let mut total: i64 = 0;
    let mut sign = 1i64;
    for tok in expr
        .replace('+', " + ")
        .replace('-', " - ")
        .split_whitespace()
    {
        match tok {
            "+" => sign = 1,
            "-" => sign = -1,
            t => {
                let (num, mul) = match t.as_bytes().last()? {
                    b'K' => (&t[..t.len() - 1], 1024),
                    b'M' => (&t[..t.len() - 1], 1024 * 1024),
                    _ => (t, 1),
                };
                let v = match num.strip_prefix("0x") {
                    Some(h) => i64::from_str_radix(h, 16).ok()?,
                    None => num.parse::<i64>().ok()?,
                };
                total += sign * v * mul;
            }
        }
    }
    u64::try_from(total).ok()
}
