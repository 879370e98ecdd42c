//! The flight image's `f64` arithmetic, written for size: addition, subtraction,
//! multiplication, division, comparisons and the conversions the code uses, on the bit
//! patterns, rounding to nearest even as IEEE 754 requires.
//!
//! The Cortex-M4F's FPU has no double precision, so every `f64` operation is a call into
//! the compiler's run-time library (`compiler_builtins`). Its routines are written for
//! speed: 3,978 bytes of the 64 KiB flight image for the thirteen the image calls
//! (`__adddf3` 904, `__divdf3` 920, `__muldf3` 776, `__truncdfsf2` 310, six comparisons
//! 574, four conversions 408, their `__aeabi_*` entry points 86). The `f64` work is the
//! parameter table's: its geometry derivation and validation (the background worker),
//! the wire units of a move telecommand and of housekeeping (the link service); never
//! the control cycle, whose kinematics are `f32` on the FPU. Here the same operations
//! share one rounding routine ([`round_pack`], after Berkeley SoftFloat's
//! `softfloat_roundPackToF64`), one unpacking and one comparison.
//!
//! **Bit for bit the library's.** Every result, NaN payloads included, is the one
//! `compiler_builtins` gives: the special cases (NaN, infinities, zeros) are decided in
//! the library's order and with its NaN rules (a NaN operand is returned quieted, the
//! first one if both are, and by the addition also made positive; an invalid operation
//! gives `0x7ff8_0000_0000_0000`), and the
//! finite results are IEEE 754's, which are unique. Host test `softfloat` compares each
//! function with the library's own routine (`__adddf3` ... of the host's
//! `compiler_builtins`, the same source as the target's) and with the host FPU, on
//! millions of operands of every class (zeros, subnormals, normals around every
//! boundary, infinities, NaNs with payloads) and on the rounding ties.
//!
//! On the target ([`aeabi`]) these are the `__aeabi_*` entry points the compiler calls:
//! `compiler_builtins` defines them as weak symbols so that a program can supply its own.
//! Elsewhere (host builds) nothing is replaced: the functions here are only tested.

/// The sign bit.
const SIGN: u64 = 1 << 63;
/// +infinity (the exponent field all ones).
const INF: u64 = 0x7ff << 52;
/// The quiet bit of a NaN.
const QUIET: u64 = 1 << 51;
/// The NaN of an invalid operation.
const QNAN: u64 = INF | QUIET;
/// The fraction field.
const FRAC: u64 = (1 << 52) - 1;
/// The implicit leading bit of a normal number.
const HIDDEN: u64 = 1 << 52;
/// The exponent bias.
const BIAS: i32 = 1023;

/// `x >> n`, with every bit shifted out ORed into bit 0 (the sticky bit of rounding).
fn shr_jam(x: u64, n: u32) -> u64 {
    if n == 0 {
        x
    } else if n < 64 {
        (x >> n) | u64::from(x << (64 - n) != 0)
    } else {
        u64::from(x != 0)
    }
}

/// The biased exponent and the significand of a finite nonzero `|x|`, the significand
/// with its leading one at bit 52 (a subnormal is normalised: its exponent is then
/// 1 - the shift, down to -51).
#[inline(never)]
fn unpack(x: u64) -> (i32, u64) {
    let e = ((x >> 52) & 0x7ff) as i32;
    let f = x & FRAC;
    if e == 0 {
        let shift = f.leading_zeros() - 11;
        (1 - shift as i32, f << shift)
    } else {
        (e, f | HIDDEN)
    }
}

/// The double nearest to `sig * 2^(exp - 1084)` (ties to even), with `sign`: `sig` has
/// its leading one at bit 62 (10 bits below the result's last one, the lowest a sticky
/// bit), `exp` is the result's biased exponent less one; a negative `exp` gives a
/// subnormal (or zero), a large one infinity. Berkeley SoftFloat's
/// `softfloat_roundPackToF64` for round-to-nearest-even, which the library's results
/// equal.
#[inline(never)]
fn round_pack(sign: u64, exp: i32, sig: u64) -> u64 {
    let (mut exp, mut sig) = (exp, sig);
    if !(0..0x7fd).contains(&exp) {
        if exp < 0 {
            sig = shr_jam(sig, exp.unsigned_abs());
            exp = 0;
        } else if exp > 0x7fd || sig.wrapping_add(0x200) >= SIGN {
            return sign | INF;
        }
    }
    let round_bits = sig & 0x3ff;
    sig = (sig + 0x200) >> 10;
    if round_bits == 0x200 {
        sig &= !1;
    }
    if sig == 0 {
        exp = 0;
    }
    // An addition: a significand rounded up to 2^53 carries into the exponent.
    sign | ((exp as u64) << 52).wrapping_add(sig)
}

/// `a + b` (bit patterns).
pub fn add(a: u64, b: u64) -> u64 {
    let (aa, ba) = (a & !SIGN, b & !SIGN);
    // Zeros, infinities and NaNs, in the library's order.
    if aa.wrapping_sub(1) >= INF - 1 || ba.wrapping_sub(1) >= INF - 1 {
        // The library's addition returns a NaN operand quieted and positive.
        if aa > INF {
            return aa | QUIET;
        }
        if ba > INF {
            return ba | QUIET;
        }
        if aa == INF {
            return if a ^ b == SIGN { QNAN } else { a };
        }
        if ba == INF {
            return b;
        }
        if aa == 0 {
            return if ba == 0 { a & b } else { b };
        }
        if ba == 0 {
            return a;
        }
    }
    let (a, b) = if aa < ba { (b, a) } else { (a, b) };
    let (ea, ma) = unpack(a);
    let (eb, mb) = unpack(b);
    // Nine guard bits and a sticky bit: |b| aligned to |a|'s exponent.
    let sb = shr_jam(mb << 9, (ea - eb) as u32);
    let sig = if (a ^ b) & SIGN == 0 {
        (ma << 9) + sb
    } else {
        (ma << 9) - sb
    };
    if sig == 0 {
        // x - x is +0 when rounding to nearest.
        return 0;
    }
    let shift = sig.leading_zeros() - 1;
    round_pack(a & SIGN, ea - shift as i32, sig << shift)
}

/// `a - b` (bit patterns): `a + (-b)`, as the library computes it.
pub fn sub(a: u64, b: u64) -> u64 {
    add(a, b ^ SIGN)
}

/// The 128-bit product of `a` and `b`: (high, low) halves.
fn mul_wide(a: u64, b: u64) -> (u64, u64) {
    const LOW: u64 = 0xffff_ffff;
    let (a1, a0) = (a >> 32, a & LOW);
    let (b1, b0) = (b >> 32, b & LOW);
    let p00 = a0 * b0;
    let p01 = a0 * b1;
    let p10 = a1 * b0;
    let mid = (p00 >> 32) + (p01 & LOW) + (p10 & LOW);
    let high = a1 * b1 + (p01 >> 32) + (p10 >> 32) + (mid >> 32);
    (high, (p00 & LOW) | (mid << 32))
}

/// `a * b` (bit patterns).
pub fn mul(a: u64, b: u64) -> u64 {
    let sign = (a ^ b) & SIGN;
    let (aa, ba) = (a & !SIGN, b & !SIGN);
    if aa > INF {
        return a | QUIET;
    }
    if ba > INF {
        return b | QUIET;
    }
    if aa == INF {
        return if ba != 0 { aa | sign } else { QNAN };
    }
    if ba == INF {
        return if aa != 0 { ba | sign } else { QNAN };
    }
    if aa == 0 || ba == 0 {
        return sign;
    }
    let (ea, ma) = unpack(a);
    let (eb, mb) = unpack(b);
    let (high, low) = mul_wide(ma << 10, mb << 11);
    let mut sig = high | u64::from(low != 0);
    let mut exp = ea + eb - BIAS;
    if sig < 1 << 62 {
        exp -= 1;
        sig <<= 1;
    }
    round_pack(sign, exp, sig)
}

/// `a / b` (bit patterns).
pub fn div(a: u64, b: u64) -> u64 {
    let sign = (a ^ b) & SIGN;
    let (aa, ba) = (a & !SIGN, b & !SIGN);
    if aa > INF {
        return a | QUIET;
    }
    if ba > INF {
        return b | QUIET;
    }
    if aa == INF {
        return if ba == INF { QNAN } else { INF | sign };
    }
    if ba == INF {
        return sign;
    }
    if aa == 0 {
        return if ba == 0 { QNAN } else { sign };
    }
    if ba == 0 {
        return INF | sign;
    }
    let (ea, mut ma) = unpack(a);
    let (eb, mb) = unpack(b);
    let mut exp = ea - eb + BIAS - 1;
    if ma < mb {
        exp -= 1;
        ma <<= 1;
    }
    // mb <= ma < 2 mb: the quotient ma 2^63 / mb, 64 bits (bit 63 set), nine bits a
    // step. Each step's digit is estimated with the processor's 32-bit division from the
    // top bits (never above the true digit, at most two below it: the correction loop
    // makes it exact), so the remainder is exact and the result does not depend on the
    // estimate's quality.
    let top = ((mb >> 32) as u32 & 0x1f_ffff) + 1;
    let (mut q, mut r) = (0u64, ma);
    for _ in 0..7 {
        let x = r << 9;
        let mut d = u64::from((x >> 32) as u32 / top);
        r = x - d * mb;
        while r >= mb {
            r -= mb;
            d += 1;
        }
        q = (q << 9) | d;
    }
    // Bit 62 leading, the dropped bit and the remainder as the sticky bit.
    round_pack(sign, exp, (q >> 1) | u64::from(q & 1 != 0 || r != 0))
}

/// The order of `a` and `b`: -1, 0, 1, or 2 if either is a NaN (+0 equals -0).
#[inline(never)]
pub fn compare(a: u64, b: u64) -> i32 {
    let (aa, ba) = (a & !SIGN, b & !SIGN);
    if aa > INF || ba > INF {
        return 2;
    }
    if aa | ba == 0 {
        return 0;
    }
    // Sign and magnitude to one signed scale.
    let key = |x: u64, abs: u64| {
        if x & SIGN != 0 {
            -(abs as i64)
        } else {
            abs as i64
        }
    };
    let (ka, kb) = (key(a, aa), key(b, ba));
    if ka < kb {
        -1
    } else {
        i32::from(ka > kb)
    }
}

/// `f32` to `f64` (exact; a NaN keeps its payload, quiet or not, as in the library).
pub fn from_f32(a: u32) -> u64 {
    let sign = u64::from(a >> 31) << 63;
    let aa = a & 0x7fff_ffff;
    let abs = if aa >= 0x7f80_0000 {
        INF | (u64::from(aa & 0x007f_ffff) << 29)
    } else if aa >= 0x0080_0000 {
        (u64::from(aa) << 29) + (((BIAS - 127) as u64) << 52)
    } else if aa != 0 {
        // A subnormal float is a normal double.
        let scale = aa.leading_zeros() - 8;
        ((u64::from(aa) << (29 + scale)) ^ HIDDEN) | (u64::from(BIAS as u32 - 126 - scale) << 52)
    } else {
        0
    };
    sign | abs
}

/// `f64` to `f32`, rounded to nearest even (a NaN keeps the top of its payload and is
/// quieted, as in the library).
pub fn to_f32(a: u64) -> u32 {
    let sign = ((a >> 32) as u32) & 0x8000_0000;
    let aa = a & !SIGN;
    // The f32 exponent range in f64 terms: [2^-126, 2^128).
    const UNDERFLOW: u64 = ((BIAS - 126) as u64) << 52;
    const OVERFLOW: u64 = ((BIAS + 128) as u64) << 52;
    let abs = if (UNDERFLOW..OVERFLOW).contains(&aa) {
        let r = ((aa >> 29) - (((BIAS - 127) as u64) << 23)) as u32;
        round_even(r, aa & 0x1fff_ffff)
    } else if aa > INF {
        0x7fc0_0000 | (((aa & (QUIET - 1)) >> 29) as u32 & 0x003f_ffff)
    } else if aa >= OVERFLOW {
        0x7f80_0000
    } else {
        // A subnormal float or zero (from below 2^-126): the significand shifted with a
        // sticky bit, as the library does it (a double subnormal gives 0).
        let shift = (BIAS - 127 + 1) as u32 - (aa >> 52) as u32;
        if shift > 52 {
            0
        } else {
            let m = (aa & FRAC) | HIDDEN;
            let d = (m >> shift) | u64::from(m << (64 - shift) != 0);
            round_even((d >> 29) as u32, d & 0x1fff_ffff)
        }
    };
    sign | abs
}

/// `r` rounded by the 29 bits `rest` below it, to nearest even.
fn round_even(r: u32, rest: u64) -> u32 {
    const HALF: u64 = 1 << 28;
    if rest > HALF || (rest == HALF && r & 1 != 0) {
        r + 1
    } else {
        r
    }
}

/// `u32` to `f64` (exact).
pub fn from_u32(u: u32) -> u64 {
    if u == 0 {
        return 0;
    }
    let lz = u.leading_zeros();
    // The leading one to bit 52, then the exponent added over it (less the one it adds).
    (u64::from(u) << (21 + lz)) + (u64::from(BIAS as u32 + 30 - lz) << 52)
}

/// `i32` to `f64` (exact).
pub fn from_i32(i: i32) -> u64 {
    from_u32(i.unsigned_abs()) | (u64::from(i < 0) << 63)
}

/// `f64` to `i32`, toward zero, saturating; NaN gives 0 (the library's conversion).
pub fn to_i32(a: u64) -> i32 {
    let aa = a & !SIGN;
    let negative = a & SIGN != 0;
    if aa < (BIAS as u64) << 52 {
        0
    } else if aa < ((BIAS + 31) as u64) << 52 {
        let m = (aa & FRAC) | HIDDEN;
        let r = (m >> ((BIAS + 52) as u64 - (aa >> 52))) as u32;
        if negative {
            r.wrapping_neg() as i32
        } else {
            r as i32
        }
    } else if aa <= INF {
        if negative {
            i32::MIN
        } else {
            i32::MAX
        }
    } else {
        0
    }
}

/// The run-time library's entry points the compiler calls for `f64` on the target
/// (ARM run-time ABI names, base-standard calling convention), replacing
/// `compiler_builtins`' weak definitions (module documentation).
#[cfg(all(target_arch = "arm", target_os = "none"))]
#[allow(unsafe_code)] // `no_mangle`: the symbols the compiler's calls are linked to.
pub mod aeabi {
    use super::*;

    /// `a + b`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_dadd(a: f64, b: f64) -> f64 {
        f64::from_bits(add(a.to_bits(), b.to_bits()))
    }
    /// `a - b`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_dsub(a: f64, b: f64) -> f64 {
        f64::from_bits(sub(a.to_bits(), b.to_bits()))
    }
    /// `a * b`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_dmul(a: f64, b: f64) -> f64 {
        f64::from_bits(mul(a.to_bits(), b.to_bits()))
    }
    /// `a / b`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_ddiv(a: f64, b: f64) -> f64 {
        f64::from_bits(div(a.to_bits(), b.to_bits()))
    }
    /// `a < b`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_dcmplt(a: f64, b: f64) -> i32 {
        i32::from(compare(a.to_bits(), b.to_bits()) == -1)
    }
    /// `a <= b`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_dcmple(a: f64, b: f64) -> i32 {
        i32::from(matches!(compare(a.to_bits(), b.to_bits()), -1 | 0))
    }
    /// `a > b`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_dcmpgt(a: f64, b: f64) -> i32 {
        i32::from(compare(a.to_bits(), b.to_bits()) == 1)
    }
    /// `a >= b`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_dcmpge(a: f64, b: f64) -> i32 {
        i32::from(matches!(compare(a.to_bits(), b.to_bits()), 0 | 1))
    }
    /// `a == b`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_dcmpeq(a: f64, b: f64) -> i32 {
        i32::from(compare(a.to_bits(), b.to_bits()) == 0)
    }
    /// Either is a NaN.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_dcmpun(a: f64, b: f64) -> i32 {
        i32::from(compare(a.to_bits(), b.to_bits()) == 2)
    }
    /// `f64` to `f32`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_d2f(a: f64) -> f32 {
        f32::from_bits(to_f32(a.to_bits()))
    }
    /// `f32` to `f64`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_f2d(a: f32) -> f64 {
        f64::from_bits(from_f32(a.to_bits()))
    }
    /// `i32` to `f64`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_i2d(a: i32) -> f64 {
        f64::from_bits(from_i32(a))
    }
    /// `u32` to `f64`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_ui2d(a: u32) -> f64 {
        f64::from_bits(from_u32(a))
    }
    /// `f64` to `i32`.
    #[no_mangle]
    pub extern "aapcs" fn __aeabi_d2iz(a: f64) -> i32 {
        to_i32(a.to_bits())
    }
}
