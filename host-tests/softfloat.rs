//! The target's `f64` arithmetic (`m2ctl::softfloat`, which replaces the run-time
//! library's routines in the firmware images) against the run-time library itself and
//! the host's FPU, bit for bit.
//!
//! The reference routines are `compiler_builtins`' own (`__adddf3`, `__divdf3`, ...),
//! linked into every Rust program: the same source as the target's library, compiled
//! for the host. Every result must equal theirs, NaN payloads included; every non-NaN
//! result must also equal the host FPU's (IEEE 754, round to nearest even).
//!
//! Operands: random bit patterns of every class (zeros, subnormals, the smallest and
//! largest normals, exponents around one and around each other, infinities, NaNs with
//! random payloads), pairs aligned to produce rounding ties, cancellation, overflow and
//! underflow. `cargo test --features host --test softfloat -- --ignored` also runs every
//! `f32`, `u32` and `i32` through the conversions (4,294,967,296 each).
#![allow(unsafe_code)] // Calls the run-time library's `extern "C"` routines to compare.

mod common;

use common::TestRng;
use m2ctl::softfloat;

extern "C" {
    fn __adddf3(a: f64, b: f64) -> f64;
    fn __subdf3(a: f64, b: f64) -> f64;
    fn __muldf3(a: f64, b: f64) -> f64;
    fn __divdf3(a: f64, b: f64) -> f64;
    fn __truncdfsf2(a: f64) -> f32;
    fn __extendsfdf2(a: f32) -> f64;
    fn __floatsidf(a: i32) -> f64;
    fn __floatunsidf(a: u32) -> f64;
    fn __fixdfsi(a: f64) -> i32;
}

/// The library's routine on bit patterns.
fn lib2(f: unsafe extern "C" fn(f64, f64) -> f64, a: u64, b: u64) -> u64 {
    // SAFETY: the run-time library's pure functions of two doubles.
    unsafe { f(f64::from_bits(a), f64::from_bits(b)) }.to_bits()
}

/// Random doubles of every class.
struct Operands(TestRng);

impl Operands {
    fn next(&mut self) -> u64 {
        let r = self.0.bits();
        let sign = (r >> 63) << 63;
        let pick = self.0.bits();
        let exp: u64 = match pick % 16 {
            0 => 0,                           // zero and subnormals
            1 => 1,                           // the smallest normals
            2 => 0x7ff,                       // infinities and NaNs
            3 => 0x7fe,                       // the largest normals
            4 => 0x3ff + (pick >> 8) % 5 - 2, // around one
            5 => (pick >> 8) % 60,            // near the subnormals
            6 => 0x7ff - (pick >> 8) % 60,    // near overflow
            _ => (pick >> 8) % 0x800,         // anywhere
        };
        let frac_bits = self.0.bits();
        let frac = match (pick >> 20) % 8 {
            0 => 0,
            1 => (1 << 52) - 1,
            2 => 1,
            3 => frac_bits & ((1 << 52) - 1) & !((1 << ((pick >> 24) % 52)) - 1), // trailing zeros
            4 => (1 << 52) - 1 - (frac_bits % 16),
            _ => frac_bits & ((1 << 52) - 1),
        };
        sign | (exp << 52) | frac
    }

    /// A second operand related to `a`: the same or a nearby exponent (cancellation,
    /// ties), half an ulp, or independent.
    fn related(&mut self, a: u64) -> u64 {
        let pick = self.0.bits();
        let exp = (a >> 52) & 0x7ff;
        match pick % 7 {
            0 => {
                let d = (pick >> 8) % 64;
                let e = exp.saturating_sub(d);
                ((pick >> 62) << 63) | (e << 52) | (self.0.bits() & ((1 << 52) - 1))
            }
            1 => a ^ (1 << 63) ^ (self.0.bits() % 4), // nearly -a
            6 => a ^ (self.0.bits() % 4),             // nearly a
            2 => {
                // 2^-53 .. 2^-54 of a: a rounding tie or just off it
                let e = exp.saturating_sub(53 + (pick >> 8) % 2);
                ((pick >> 40) << 63) | (e << 52) | ((pick >> 9) % 3)
            }
            _ => self.next(),
        }
    }
}

fn check_binary(
    name: &str,
    ours: fn(u64, u64) -> u64,
    lib: unsafe extern "C" fn(f64, f64) -> f64,
    fpu: fn(f64, f64) -> f64,
    seed: u64,
    n: usize,
) {
    let mut ops = Operands(TestRng(seed));
    // Results per class: zero, subnormal, normal, infinity, NaN.
    let mut classes = [0usize; 5];
    for i in 0..n {
        let a = ops.next();
        let b = if i % 2 == 0 {
            ops.related(a)
        } else {
            ops.next()
        };
        let (a, b) = if i % 4 < 2 { (a, b) } else { (b, a) };
        let got = ours(a, b);
        let want = lib2(lib, a, b);
        assert_eq!(
            got, want,
            "{name}({a:#018x}, {b:#018x}): {got:#018x}, the library {want:#018x}"
        );
        let g = f64::from_bits(got);
        classes[match () {
            _ if g == 0.0 => 0,
            _ if g.is_subnormal() => 1,
            _ if g.is_finite() => 2,
            _ if g.is_infinite() => 3,
            _ => 4,
        }] += 1;
        let hw = fpu(f64::from_bits(a), f64::from_bits(b));
        if !hw.is_nan() {
            assert_eq!(got, hw.to_bits(), "{name}({a:#018x}, {b:#018x}): FPU");
        } else {
            assert!(f64::from_bits(got).is_nan(), "{name}({a:#018x}, {b:#018x})");
        }
    }
    println!("{name}: {n} pairs, results zero/subnormal/normal/infinite/NaN {classes:?}");
    assert!(classes.iter().all(|c| *c > n / 1000), "{name}: {classes:?}");
}

const N: usize = 3_000_000;

#[test]
fn addition_is_the_librarys() {
    check_binary("add", softfloat::add, __adddf3, |a, b| a + b, 1, N);
}

#[test]
fn subtraction_is_the_librarys() {
    check_binary("sub", softfloat::sub, __subdf3, |a, b| a - b, 2, N);
}

#[test]
fn multiplication_is_the_librarys() {
    check_binary("mul", softfloat::mul, __muldf3, |a, b| a * b, 3, N);
    // Products around the subnormal boundary and overflow, and exact ties: the
    // significands of a and b with few bits, their exponents summing near the edges.
    let mut rng = TestRng(33);
    for _ in 0..N {
        let ea = (rng.bits() % 0x7ff) as i64;
        // The product's exponent near the subnormals or near overflow.
        let target = if rng.bits() % 2 == 0 {
            0x3ff
        } else {
            0x3ff + 0x7fe
        };
        let eb = (target + (rng.bits() % 120) as i64 - 60 - ea).clamp(0, 0x7fe) as u64;
        let ea = ea as u64;
        let fa = rng.bits() & ((1 << 52) - 1) & !((1 << (rng.bits() % 53)) - 1);
        let fb = rng.bits() & ((1 << 52) - 1) & !((1 << (rng.bits() % 53)) - 1);
        let a = ((rng.bits() >> 63) << 63) | (ea << 52) | fa;
        let b = ((rng.bits() >> 63) << 63) | (eb << 52) | fb;
        assert_eq!(
            softfloat::mul(a, b),
            lib2(__muldf3, a, b),
            "mul({a:#x}, {b:#x})"
        );
    }
}

#[test]
fn division_is_the_librarys() {
    check_binary("div", softfloat::div, __divdf3, |a, b| a / b, 4, N);
    // Exact quotients (ties among them) and the exponent edges.
    let mut rng = TestRng(44);
    for _ in 0..N / 2 {
        let q = rng.bits() & ((1 << 53) - 1) & !((1 << (rng.bits() % 54)) - 1);
        let d = (rng.bits() % 1000) + 1;
        let a = (q as f64 * d as f64).to_bits();
        let b = ((d as f64) * f64::from_bits(((rng.bits() % 0x7fe) + 1) << 52)).to_bits();
        assert_eq!(
            softfloat::div(a, b),
            lib2(__divdf3, a, b),
            "div({a:#x}, {b:#x})"
        );
    }
}

#[test]
fn the_units_divisions_of_the_wire_are_the_librarys() {
    // What the flight code divides: every i32 of a wire pose by 1e6 (a sample of them).
    let mut rng = TestRng(45);
    for _ in 0..N {
        let v = rng.bits() as i32;
        let a = f64::from(v).to_bits();
        for d in [1.0e6f64, 1000.0, 3600.0, 206_264.806_247_096_36] {
            assert_eq!(
                softfloat::div(a, d.to_bits()),
                lib2(__divdf3, a, d.to_bits())
            );
        }
    }
}

#[test]
fn comparisons_are_ieee() {
    let mut ops = Operands(TestRng(5));
    for i in 0..N {
        let a = ops.next();
        let b = match i % 3 {
            0 => a,
            1 => ops.related(a),
            _ => ops.next(),
        };
        let (x, y) = (f64::from_bits(a), f64::from_bits(b));
        let want = match x.partial_cmp(&y) {
            Some(core::cmp::Ordering::Less) => -1,
            Some(core::cmp::Ordering::Equal) => 0,
            Some(core::cmp::Ordering::Greater) => 1,
            None => 2,
        };
        assert_eq!(softfloat::compare(a, b), want, "compare({a:#x}, {b:#x})");
    }
    for (a, b, want) in [
        (0.0f64, -0.0f64, 0),
        (-0.0, 0.0, 0),
        (f64::MIN_POSITIVE, -f64::MIN_POSITIVE, 1),
        (f64::NEG_INFINITY, f64::MIN, -1),
        (f64::NAN, f64::NAN, 2),
        (1.0, f64::NAN, 2),
    ] {
        assert_eq!(softfloat::compare(a.to_bits(), b.to_bits()), want);
    }
}

#[test]
fn conversions_are_the_librarys() {
    let mut ops = Operands(TestRng(6));
    let mut rng = TestRng(7);
    for _ in 0..N {
        let a = ops.next();
        // SAFETY: the run-time library's pure conversions.
        let (f, i) = unsafe {
            (
                __truncdfsf2(f64::from_bits(a)),
                __fixdfsi(f64::from_bits(a)),
            )
        };
        assert_eq!(softfloat::to_f32(a), f.to_bits(), "to_f32({a:#x})");
        if !f64::from_bits(a).is_nan() {
            assert_eq!(softfloat::to_f32(a), (f64::from_bits(a) as f32).to_bits());
        }
        assert_eq!(softfloat::to_i32(a), i, "to_i32({a:#x})");
        assert_eq!(
            softfloat::to_i32(a),
            f64::from_bits(a) as i32,
            "to_i32({a:#x})"
        );
        let x = rng.bits() as u32;
        check_from_32(x);
    }
    // Around the i32 range and the rounding ties of f32.
    for v in [
        2_147_483_647.0f64,
        2_147_483_647.999,
        2_147_483_648.0,
        -2_147_483_648.0,
        -2_147_483_648.999,
        -2_147_483_649.0,
        0.999_999,
        -0.999_999,
        1.0,
        -1.0,
        f64::from_bits(0x3ff0_0000_1000_0000),
        f64::from_bits(0x3ff0_0000_3000_0000),
        f64::from_bits(0x3ff0_0000_1000_0001),
        f64::from(f32::MAX) * (1.0 + f64::EPSILON),
        f64::from(f32::MIN_POSITIVE) / 3.0,
        f64::from(f32::MIN_POSITIVE) * 0.5,
        1.0e-46,
        1.4e-45,
        0.7e-45,
    ] {
        for v in [v, -v] {
            let a = v.to_bits();
            // SAFETY: as above.
            let (f, i) = unsafe { (__truncdfsf2(v), __fixdfsi(v)) };
            assert_eq!(softfloat::to_f32(a), f.to_bits(), "to_f32({v:e})");
            assert_eq!(softfloat::to_i32(a), i, "to_i32({v:e})");
        }
    }
}

/// `x` as an `f32` pattern, a `u32` and an `i32`, to `f64`.
fn check_from_32(x: u32) {
    // SAFETY: the run-time library's pure conversions.
    let (f, u, i) = unsafe {
        (
            __extendsfdf2(f32::from_bits(x)),
            __floatunsidf(x),
            __floatsidf(x as i32),
        )
    };
    assert_eq!(softfloat::from_f32(x), f.to_bits(), "from_f32({x:#x})");
    assert_eq!(softfloat::from_u32(x), u.to_bits(), "from_u32({x})");
    assert_eq!(softfloat::from_u32(x), f64::from(x).to_bits());
    assert_eq!(
        softfloat::from_i32(x as i32),
        i.to_bits(),
        "from_i32({})",
        x as i32
    );
    assert_eq!(softfloat::from_i32(x as i32), f64::from(x as i32).to_bits());
}

#[test]
#[ignore = "every 32-bit input: about three minutes in the test profile"]
fn every_32_bit_input_converts_as_the_library() {
    for x in 0..=u32::MAX {
        check_from_32(x);
    }
}
