//! "Is this move possible?" without moving: every reason a pose is refused.

use super::geometry::{Geometry, LEGS};
use super::ik::strokes_unchecked;
use super::pose::Pose;
use super::real::Real;

/// Every reason a pose is refused (bit masks; bit i = leg i+1 or axis i of
/// `[x, y, z, alpha, beta, gamma]`). All zero/false means the pose is accepted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Refusals {
    /// A pose component is NaN or infinite (no other check is then made).
    pub non_finite: bool,
    /// Axes beyond the workspace half-range.
    pub axes_outside: u8,
    /// Legs that cannot reach (negative radicand).
    pub legs_unreachable: u8,
    /// Legs whose stroke is below the slider's lower limit.
    pub legs_below_min: u8,
    /// Legs whose stroke is above the slider's upper limit.
    pub legs_above_max: u8,
}

impl Refusals {
    /// True when nothing refuses the pose.
    pub fn is_empty(&self) -> bool {
        *self == Refusals::default()
    }

    /// Packs the refusals into one word for telemetry:
    /// bit 0 non-finite, bits 8..13 axes, 16..21 unreachable, 24..29 below min,
    /// and the above-max legs in bits 1..6 (leg i at bit i+1).
    pub fn to_bits(&self) -> u32 {
        u32::from(self.non_finite)
            | (u32::from(self.legs_above_max) << 1)
            | (u32::from(self.axes_outside) << 8)
            | (u32::from(self.legs_unreachable) << 16)
            | (u32::from(self.legs_below_min) << 24)
    }
}

/// Strokes (valid only where no leg is refused) and every refusal reason.
pub fn evaluate<T: Real>(geom: &Geometry<T>, pose: &Pose<T>) -> ([T; LEGS], Refusals) {
    let mut r = Refusals::default();
    let v = pose.to_array();
    if let Some(w) = &geom.workspace {
        let limits = [
            w.translation_mm[0],
            w.translation_mm[1],
            w.translation_mm[2],
            w.rotation_rad[0],
            w.rotation_rad[1],
            w.rotation_rad[2],
        ];
        for (k, (v, lim)) in v.iter().zip(limits.iter()).enumerate() {
            // `!(x <= lim)` is also true for NaN and infinity: a non-finite pose always
            // sets a bit here, so the finiteness check below runs only then.
            r.axes_outside |= u8::from(!(v.abs() <= *lim)) << k;
        }
    }
    // With a workspace, a pose inside it is finite (see above).
    if (geom.workspace.is_none() || r.axes_outside != 0) && !pose.is_finite() {
        return (
            [T::ZERO; LEGS],
            Refusals {
                non_finite: true,
                ..Refusals::default()
            },
        );
    }
    let (strokes, unreachable) = strokes_unchecked(geom, pose);
    r.legs_unreachable = unreachable;
    if let Some(lim) = &geom.stroke {
        // Unreachable legs carry stroke 0, which validated limits always contain.
        for (i, ((s, lo), hi)) in strokes
            .iter()
            .zip(lim.min_mm.iter())
            .zip(lim.max_mm.iter())
            .enumerate()
        {
            r.legs_below_min |= u8::from(*s < *lo) << i;
            r.legs_above_max |= u8::from(*s > *hi) << i;
        }
    }
    (strokes, r)
}

/// Checks a pose without producing strokes: every reason it is refused.
pub fn check<T: Real>(geom: &Geometry<T>, pose: &Pose<T>) -> Refusals {
    evaluate(geom, pose).1
}
