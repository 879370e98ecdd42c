//! The float abstraction that lets one implementation of the kinematics run in `f32` on
//! the flight computer and in `f64` on the ground and in the simulated plant.
//!
//! Only what the equations need is here. Two functions are deliberately not the obvious
//! library calls, because the firmware must be fast and exact on a single-precision FPU:
//!
//! * [`Real::sqrt`] for `f32` is a Newton iteration from a bit-level first guess (plain
//!   FPU divide/multiply/add). `libm::sqrtf` is a bit-by-bit software loop on Cortex-M4F
//!   (libm has no ARM hardware path) and `core` has no stable `f32::sqrt` in `no_std`.
//!   The result is within 2 ulp of the correctly rounded root; the kinematics only use it
//!   where such an error is suppressed by a factor of about 1e-2 (see `ik`).
//! * [`Real::sin_cosm1`] returns `sin x` and `cos x - 1` (not `cos x`), so that the
//!   rotation minus the identity can be formed without cancellation. For the small angles
//!   of the mechanism (|x| <= [`SMALL_ANGLE_RAD`]) it is a short polynomial; beyond (frame
//!   rotations, never flight poses), `f32` reduces the argument modulo pi/2 and uses a
//!   longer polynomial (f32 arithmetic only), `f64` calls `libm`.
//!
//! Both are deterministic IEEE-754 arithmetic (no fused multiply-add is emitted by rustc
//! unless asked), so the target and the host produce bit-identical `f32` results.

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// Angles up to this magnitude (rad, about 5.7 degrees) use the polynomial path of
/// [`Real::sin_cosm1`]. The truncation error there is below 1e-14 relative.
pub const SMALL_ANGLE_RAD: f64 = 0.1;

/// A real number type the kinematics can be evaluated in (`f32` or `f64`).
///
/// It is a nalgebra scalar with field arithmetic, so the kinematics' vectors and
/// matrices are nalgebra's fixed-size `Vector3<T>` / `Matrix3<T>` (stack values, no
/// allocation), the vocabulary the ground tools use too. The methods below are ours,
/// not nalgebra's `RealField` ones, for the reasons in the module docs.
pub trait Real:
    nalgebra::Scalar
    + nalgebra::Field
    + nalgebra::ClosedAddAssign
    + nalgebra::ClosedSubAssign
    + nalgebra::ClosedMulAssign
    + Copy
    + Debug
    + Default
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + 'static
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// 2.
    const TWO: Self;
    /// 0.5.
    const HALF: Self;
    /// Machine epsilon of the type.
    const EPSILON: Self;
    /// Nearest value of this type (round to nearest even).
    fn from_f64(v: f64) -> Self;
    /// Exact widening (or identity) to `f64`.
    fn to_f64(self) -> f64;
    /// Square root (see the module docs for the `f32` accuracy). NaN for negative input.
    fn sqrt(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Neither NaN nor infinite.
    fn is_finite(self) -> bool;
    /// `(sin x, cos x - 1)` for `x` in radians.
    fn sin_cosm1(self) -> (Self, Self);
    /// `asin x` (rad), libm (software on the Cortex-M4F; frames only, not the IK/FK).
    fn asin(self) -> Self;
    /// `atan2(self, x)` (rad), libm.
    fn atan2(self, x: Self) -> Self;
    /// The larger of two values (NaN-free inputs assumed).
    fn max(self, other: Self) -> Self {
        if other > self {
            other
        } else {
            self
        }
    }
}

/// Coefficients of the odd sine series, x^3 .. x^9 (1/3!, 1/5!, 1/7!, 1/9!).
const SIN_COEFF: [f64; 4] = [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0];
/// Coefficients of cos x - 1 in powers x^2 .. x^10.
const COSM1_COEFF: [f64; 5] = [
    -0.5,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
];

/// [`SMALL_ANGLE_RAD`] in f32 (compared in f32: an f64 compare is software on the target).
const SMALL_ANGLE_RAD_F32: f32 = SMALL_ANGLE_RAD as f32;
/// The sine coefficients rounded to f32 once, at compile time. x^3 and x^5 suffice in
/// f32 up to [`SMALL_ANGLE_RAD`]: the x^7 term is at most 2.0e-11 there, 2e-10 of
/// `sin x`, 3e-3 of an f32 rounding unit.
const SIN_COEFF_F32: [f32; 2] = [SIN_COEFF[0] as f32, SIN_COEFF[1] as f32];
/// The `cos - 1` coefficients rounded to f32 (x^2 .. x^6; the x^8 term is at most
/// 2.5e-13 up to [`SMALL_ANGLE_RAD`], 5e-11 of `cos x - 1`).
const COSM1_COEFF_F32: [f32; 3] = [
    COSM1_COEFF[0] as f32,
    COSM1_COEFF[1] as f32,
    COSM1_COEFF[2] as f32,
];

/// The sine coefficients x^3 .. x^11 in f32, for the reduced argument |r| <= pi/4 of
/// [`sin_cosm1_reduced_f32`] (the x^13 term is at most 7e-12 there, 1e-11 of `sin r`).
const SIN_COEFF_REDUCED_F32: [f32; 5] = [
    SIN_COEFF[0] as f32,
    SIN_COEFF[1] as f32,
    SIN_COEFF[2] as f32,
    SIN_COEFF[3] as f32,
    (-1.0 / 39_916_800.0) as f32,
];
/// The `cos - 1` coefficients x^2 .. x^12 in f32 for |r| <= pi/4 (the x^14 term is at
/// most 4e-13 there).
const COSM1_COEFF_REDUCED_F32: [f32; 6] = [
    COSM1_COEFF[0] as f32,
    COSM1_COEFF[1] as f32,
    COSM1_COEFF[2] as f32,
    COSM1_COEFF[3] as f32,
    COSM1_COEFF[4] as f32,
    (1.0 / 479_001_600.0) as f32,
];
/// pi/2 in three f32 parts (Cody-Waite reduction; Cephes' `sinf` constants, doubled):
/// `PIO2_HI` has 8 significant bits and `PIO2_MID` 11, so `n * PIO2_HI` and
/// `n * PIO2_MID` are exact for |n| < 2^13 (|x| < 12,800 rad).
const PIO2_HI: f32 = 1.570_312_5;
/// (The digits of the two parts below are their exact f32 values, as in Cephes.)
#[allow(clippy::excessive_precision)]
const PIO2_MID: f32 = 4.837_512_969_970_703e-4;
#[allow(clippy::excessive_precision)]
const PIO2_LO: f32 = 7.549_789_954_891_882e-8;

/// `(sin x, cos x - 1)` of an `f32` beyond [`SMALL_ANGLE_RAD`], in f32 arithmetic only
/// (libm's `sinf` computes in f64: software on the Cortex-M4F): `x = n pi/2 + r` with
/// |r| <= pi/4 (Cody-Waite), the series of `sin r` and `cos r - 1`, and the quadrant
/// `n mod 4`. Within a few f32 rounding units of the exact values for |x| < 12,800 rad
/// (host test against f64); NaN for a non-finite `x`. Not inlined: the rare large-angle
/// path (frame rotations) stays out of the small-angle callers.
#[inline(never)]
fn sin_cosm1_reduced_f32(x: f32) -> (f32, f32) {
    if !x.is_finite() {
        return (f32::NAN, f32::NAN);
    }
    let half = if x < 0.0 { -0.5 } else { 0.5 };
    // Nearest integer of x 2/pi (the cast saturates: no panic for any finite x).
    let n = (x * core::f32::consts::FRAC_2_PI + half) as i32;
    let nf = n as f32;
    let r = ((x - nf * PIO2_HI) - nf * PIO2_MID) - nf * PIO2_LO;
    let y = r * r;
    let s = r + r * poly_in_square(y, &SIN_COEFF_REDUCED_F32);
    let c = poly_in_square(y, &COSM1_COEFF_REDUCED_F32);
    match n & 3 {
        0 => (s, c),
        // x = r + pi/2: sin x = cos r, cos x = -sin r.
        1 => (1.0 + c, -s - 1.0),
        // x = r + pi: sin x = -sin r, cos x = -cos r.
        2 => (-s, -c - 2.0),
        // x = r + 3 pi/2: sin x = -cos r, cos x = sin r.
        _ => (-(1.0 + c), s - 1.0),
    }
}

/// Horner evaluation of `sum c_k y^(k+1)` for `y = x^2`.
#[inline(always)]
fn poly_in_square<T: Real, const N: usize>(y: T, coeff: &[T; N]) -> T {
    let mut acc = T::ZERO;
    for c in coeff.iter().rev() {
        acc = (acc + *c) * y;
    }
    acc
}

impl Real for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const TWO: Self = 2.0;
    const HALF: Self = 0.5;
    const EPSILON: Self = f32::EPSILON;
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline]
    fn sqrt(self) -> Self {
        sqrt_f32_newton(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::from_bits(self.to_bits() & 0x7fff_ffff)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[inline]
    fn sin_cosm1(self) -> (Self, Self) {
        if self.abs() <= SMALL_ANGLE_RAD_F32 {
            let y = self * self;
            let s = self + self * poly_in_square(y, &SIN_COEFF_F32);
            let c = poly_in_square(y, &COSM1_COEFF_F32);
            (s, c)
        } else {
            sin_cosm1_reduced_f32(self)
        }
    }
    #[inline]
    fn asin(self) -> Self {
        // asin x = atan2(x, sqrt(1 - x^2)), with (1 - x)(1 + x) exact near |x| = 1 to
        // the rounding of the product. libm's `asinf` takes its square root in f64
        // (software on the Cortex-M4F).
        libm::atan2f(self, sqrt_f32_newton((1.0 - self) * (1.0 + self)))
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        libm::atan2f(self, x)
    }
}

impl Real for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const TWO: Self = 2.0;
    const HALF: Self = 0.5;
    const EPSILON: Self = f64::EPSILON;
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn sqrt(self) -> Self {
        sqrt_f64(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        libm::fabs(self)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    #[inline]
    fn sin_cosm1(self) -> (Self, Self) {
        if self.abs() <= SMALL_ANGLE_RAD {
            let y = self * self;
            let s = self + self * poly_in_square(y, &SIN_COEFF);
            let c = poly_in_square(y, &COSM1_COEFF);
            (s, c)
        } else {
            let h = libm::sin(0.5 * self);
            (libm::sin(self), -2.0 * h * h)
        }
    }
    #[inline]
    fn asin(self) -> Self {
        libm::asin(self)
    }
    #[inline]
    fn atan2(self, x: Self) -> Self {
        libm::atan2(self, x)
    }
}

/// Correctly rounded square root of an `f64` (IEEE-754 round to nearest, bit-identical
/// to `libm::sqrt`: host test `kinematics::sqrt_f64_is_libm_bit_for_bit`), computed
/// digit by digit on the integer mantissa: shifts, adds and compares only. The flight
/// image needs an f64 square root only to derive and check a table's geometry (a few
/// dozen calls per table); libm's is 776 bytes of flash with its table, this 336, at
/// about 2,000 instructions a call. NaN (exactly `f64::NAN`) for NaN and negative
/// input; the input for +-0 and +infinity.
pub fn sqrt_f64(x: f64) -> f64 {
    /// Explicit mantissa bits of an f64.
    const MANT_BITS: u32 = 52;
    /// Exponent bias plus the mantissa bits: `x = m * 2^(biased - EXP_OFFSET)`.
    const EXP_OFFSET: i32 = 1075;
    /// Exponent bias of an f64.
    const EXP_BIAS: i32 = 1023;
    // The special cases on the bit pattern (no f64 comparison: software on the target).
    let bits = x.to_bits();
    if bits > f64::INFINITY.to_bits() {
        // NaN (a positive NaN pattern, or any negative number but -0).
        return if bits == (-0.0f64).to_bits() {
            x
        } else {
            f64::NAN
        };
    }
    if bits == 0 || bits == f64::INFINITY.to_bits() {
        return x;
    }
    let biased = ((bits >> MANT_BITS) & 0x7ff) as i32;
    let frac = bits & ((1u64 << MANT_BITS) - 1);
    // x = m * 2^e with m in [2^52, 2^53) (subnormals normalised).
    let (mut m, mut e) = if biased == 0 {
        let shift = frac.leading_zeros() - (63 - MANT_BITS);
        (frac << shift, 1 - EXP_OFFSET - shift as i32)
    } else {
        (frac | (1u64 << MANT_BITS), biased - EXP_OFFSET)
    };
    // An even exponent: m in [2^52, 2^54).
    if e & 1 != 0 {
        m <<= 1;
        e -= 1;
    }
    // sqrt(x) = sqrt(R) * 2^(e/2 - 26) with R = m * 2^52 (in [2^104, 2^106)); the
    // integer root of R, in [2^52, 2^53], one bit per step from the top, bringing down
    // two bits of R each time (R's low 52 bits are zero). The remainder stays below
    // 2 root + 1 < 2^54: u64 throughout.
    let mut rem: u64 = 0;
    let mut root: u64 = 0;
    for pair in (0..=MANT_BITS).rev() {
        let shift = 2 * pair;
        let two_bits = if shift >= MANT_BITS {
            (m >> (shift - MANT_BITS)) & 3
        } else {
            0
        };
        rem = (rem << 2) | two_bits;
        let trial = (root << 2) | 1;
        root <<= 1;
        if rem >= trial {
            rem -= trial;
            root |= 1;
        }
    }
    // Round to nearest: (root + 1/2)^2 = root^2 + root + 1/4 is never an integer, so
    // the root rounds up exactly when the remainder exceeds root (no ties).
    if rem > root {
        root += 1;
    }
    // root in [2^52, 2^53]: adding it to the exponent field one below carries into the
    // exponent when root = 2^53.
    let exp_field = (e / 2 + 26 + EXP_BIAS - 1) as u64;
    f64::from_bits((exp_field << MANT_BITS) + root)
}

/// Number of Newton steps after the bit-level first guess: the guess is within 3.5 %,
/// and each step squares the relative error (3.5e-2 -> 6e-4 -> 2e-7 -> f32 rounding).
const SQRT_NEWTON_STEPS: usize = 3;
/// Magic constant of the classic `sqrt` first guess (halves the exponent in the bits).
const SQRT_GUESS_MAGIC: u32 = 0x1fbd_1df5;

/// Square root of an `f32` by Newton's method, FPU add/multiply/divide only.
/// Returns NaN for negative or NaN input, the input for 0 and +infinity.
fn sqrt_f32_newton(x: f32) -> f32 {
    if x.is_nan() || x < 0.0 {
        return f32::NAN;
    }
    if x == 0.0 || x == f32::INFINITY {
        return x;
    }
    // Scale subnormal/tiny inputs into the normal range so the bit guess holds.
    let (xs, scale) = if x < f32::MIN_POSITIVE * 4.0 {
        (x * 16_777_216.0, 1.0 / 4096.0) // 2^24 in, 2^-12 out
    } else {
        (x, 1.0)
    };
    let mut r = f32::from_bits(SQRT_GUESS_MAGIC.wrapping_add(xs.to_bits() >> 1));
    for _ in 0..SQRT_NEWTON_STEPS {
        r = 0.5 * (r + xs / r);
    }
    r * scale
}
