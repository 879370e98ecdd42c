//! Mirror pose and the rotation convention.
//!
//! A pose is the displacement of the moving frame M from its home position p0:
//! translation `[x, y, z]` (mm, base axes) and rotation angles `[alpha, beta, gamma]`
//! (rad) with `R = Rz(gamma) * Ry(beta) * Rx(alpha)`, exactly as in the source paper.
//! Telecommands and files carry the angles in arcseconds; [`ARCSEC_PER_RAD`] converts.

use nalgebra::Matrix3;

use super::real::Real;
use crate::units::ARCSEC_PER_RAD;

/// Mirror pose relative to home.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose<T> {
    /// Translation of M's origin from p0, along B's axes (mm).
    pub translation_mm: [T; 3],
    /// `[alpha, beta, gamma]` about x, y, z (rad); `R = Rz(gamma) Ry(beta) Rx(alpha)`.
    pub rotation_rad: [T; 3],
}

impl<T: Real> Pose<T> {
    /// The home pose (all strokes zero).
    pub fn home() -> Self {
        Self::default()
    }

    /// A pose from mm and arcsec given in f64 (converted once to `T`).
    pub fn from_mm_arcsec(translation_mm: [f64; 3], rotation_arcsec: [f64; 3]) -> Self {
        Self {
            translation_mm: translation_mm.map(T::from_f64),
            rotation_rad: rotation_arcsec.map(|a| T::from_f64(a / ARCSEC_PER_RAD)),
        }
    }

    /// The six components `[x, y, z, alpha, beta, gamma]` (mm, mm, mm, rad, rad, rad).
    /// Not inlined (nor is [`Pose::from_array`]): a copy of six values, called from
    /// about a dozen places (152 bytes of flash less for the two).
    #[inline(never)]
    pub fn to_array(&self) -> [T; 6] {
        let [x, y, z] = self.translation_mm;
        let [a, b, c] = self.rotation_rad;
        [x, y, z, a, b, c]
    }

    /// Inverse of [`Pose::to_array`].
    #[inline(never)]
    pub fn from_array(v: [T; 6]) -> Self {
        let [x, y, z, a, b, c] = v;
        Self {
            translation_mm: [x, y, z],
            rotation_rad: [a, b, c],
        }
    }

    /// Every component is finite.
    pub fn is_finite(&self) -> bool {
        self.to_array().iter().all(|v| v.is_finite())
    }

    /// Rotation angles in arcsec (f64).
    pub fn rotation_arcsec(&self) -> [f64; 3] {
        self.rotation_rad.map(|r| r.to_f64() * ARCSEC_PER_RAD)
    }

    /// The same pose in another float type.
    pub fn cast<U: Real>(&self) -> Pose<U> {
        Pose {
            translation_mm: self.translation_mm.map(|v| U::from_f64(v.to_f64())),
            rotation_rad: self.rotation_rad.map(|v| U::from_f64(v.to_f64())),
        }
    }
}

/// `R - I` and the sines/cosines of a pose's rotation, formed without cancellation.
#[derive(Clone, Copy, Debug)]
pub struct RotationDelta<T: Real> {
    /// `R - I` (dimensionless).
    pub w: Matrix3<T>,
    /// `sin(gamma)`, `cos(gamma)`: the Jacobian needs `Rz(gamma) e_y = (-sg, cg, 0)`.
    pub sg: T,
    /// `cos(gamma)`.
    pub cg: T,
}

impl<T: Real> RotationDelta<T> {
    /// Builds `R - I` for `R = Rz(gamma) Ry(beta) Rx(alpha)`. Diagonal terms are sums of
    /// `cos - 1` values, never `cos - 1` computed as a difference.
    ///
    /// Out of line: one copy serves the FK's evaluations and the frames (inlined at its
    /// six call sites in the flight image it was 830 bytes of it; out of line, with the
    /// IK's inlined copy below, 500 bytes less); the call costs a flight-profile FK
    /// ~170 instructions of ~7,000.
    #[inline(never)]
    pub fn new(rotation_rad: &[T; 3]) -> Self {
        Self::new_inline(rotation_rad)
    }

    /// [`RotationDelta::new`] inlined into its caller: the IK's, whose goal at opt-level
    /// 3 (600 instructions; 560 with it inlined, 598 with the call) leaves no room for a
    /// call.
    #[inline(always)]
    pub fn new_inline(rotation_rad: &[T; 3]) -> Self {
        let [alpha, beta, gamma] = *rotation_rad;
        let (sa, cma) = alpha.sin_cosm1();
        let (sb, cmb) = beta.sin_cosm1();
        let (sg, cmg) = gamma.sin_cosm1();
        let ca = T::ONE + cma;
        let cb = T::ONE + cmb;
        let cg = T::ONE + cmg;
        let w = Matrix3::new(
            cmg + cmb + cmg * cmb,
            cg * sb * sa - sg * ca,
            cg * sb * ca + sg * sa,
            sg * cb,
            sg * sb * sa + (cmg + cma + cmg * cma),
            sg * sb * ca - cg * sa,
            -sb,
            cb * sa,
            cmb + cma + cmb * cma,
        );
        Self { w, sg, cg }
    }
}
