//! The boot self-test of the firmware: IK and FK in `f32` on the golden vectors of the
//! independent reference implementation (`testdata/ik_golden.csv`, compiled in), each
//! checked against the reference. The same function runs on the host, so a host test
//! can compare the target's `f32` bits with the host's.

use crate::kinematics::{fk, ik, FkConfig, Geometry, Pose, LEGS};
use crate::units::ARCSEC_PER_RAD;

/// IK acceptance: every stroke within this of the reference (mm; 1 nm).
pub const IK_TOL_MM: f64 = 1.0e-6;
/// FK(IK(p)) acceptance in translation (mm; 5 nm).
pub const FK_TOL_MM: f64 = 5.0e-6;
/// FK(IK(p)) acceptance in rotation (arcsec).
pub const FK_TOL_ARCSEC: f64 = 1.0e-3;

/// One golden row: pose (mm, mm, mm, arcsec, arcsec, arcsec) and strokes (mm).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GoldenRow {
    /// `[x, y, z]` in mm and `[alpha, beta, gamma]` in arcsec.
    pub pose: [f64; 6],
    /// Reference strokes (mm).
    pub strokes_mm: [f64; LEGS],
}

/// A golden row as the flight image's boot self-test keeps it: in `f32` (half the flash
/// of [`GoldenRow`]'s `f64`). The rounding is far inside the tolerances: at most half an
/// f32 step, 0.24 nm for a stroke below 4 mm against [`IK_TOL_MM`]'s 1 nm, and the pose's
/// rounding moves the strokes by less than 0.01 nm (host test
/// `selftest::boot_rows_are_the_golden_rows_in_f32_and_pass`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BootRow {
    /// `[x, y, z]` in mm and `[alpha, beta, gamma]` in arcsec.
    pub pose: [f32; 6],
    /// Reference strokes (mm).
    pub strokes_mm: [f32; LEGS],
}

impl BootRow {
    /// The row in `f64`, as [`run_row`] takes it.
    pub fn widen(&self) -> GoldenRow {
        GoldenRow {
            pose: self.pose.map(f64::from),
            strokes_mm: self.strokes_mm.map(f64::from),
        }
    }
}

include!(concat!(env!("OUT_DIR"), "/golden.rs"));

/// Iterates over the golden rows (`testdata/ik_golden.csv`, compiled in by build.rs).
pub fn golden_rows() -> impl Iterator<Item = GoldenRow> {
    GOLDEN_ROWS.iter().copied()
}

/// The outcome of one golden row, with the raw `f32` bits for the bit-identity check.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RowOutcome {
    /// `f32` strokes from IK, as bits.
    pub ik_bits: [u32; LEGS],
    /// `f32` pose from FK(IK) started at home, as bits (mm, rad).
    pub fk_bits: [u32; 6],
    /// Largest |IK_f32 - reference| (mm).
    pub ik_err_mm: f64,
    /// Largest FK translation error (mm); NaN if FK failed.
    pub fk_err_mm: f64,
    /// Largest FK rotation error (arcsec); NaN if FK failed.
    pub fk_err_arcsec: f64,
    /// FK Newton steps (0 if failed).
    pub fk_iterations: u8,
    /// Every check of the row passed.
    pub pass: bool,
}

/// Runs IK and FK in `f32` on one row and checks them.
#[allow(clippy::indexing_slicing)] // `k < 3` into six-element poses: k and k + 3 in range.
pub fn run_row(geom: &Geometry<f32>, row: &GoldenRow) -> RowOutcome {
    let mut out = RowOutcome {
        fk_err_mm: f64::NAN,
        fk_err_arcsec: f64::NAN,
        ik_err_mm: f64::NAN,
        ..RowOutcome::default()
    };
    let [x, y, z, a, b, c] = row.pose;
    let pose = Pose::<f32>::from_mm_arcsec([x, y, z], [a, b, c]);
    let Ok(strokes) = ik(geom, &pose) else {
        return out;
    };
    out.ik_bits = strokes.map(f32::to_bits);
    out.ik_err_mm = strokes
        .iter()
        .zip(row.strokes_mm.iter())
        .map(|(s, r)| libm::fabs(f64::from(*s) - r))
        .fold(0.0, larger);
    let Ok(sol) = fk(geom, &strokes, &Pose::home(), &FkConfig::default()) else {
        return out;
    };
    let p = sol.pose.to_array();
    out.fk_bits = p.map(f32::to_bits);
    out.fk_iterations = sol.iterations;
    let mut err_mm = 0.0f64;
    let mut err_as = 0.0f64;
    for k in 0..3 {
        err_mm = larger(err_mm, libm::fabs(f64::from(p[k]) - row.pose[k]));
        err_as = larger(
            err_as,
            libm::fabs(f64::from(p[k + 3]) * ARCSEC_PER_RAD - row.pose[k + 3]),
        );
    }
    out.fk_err_mm = err_mm;
    out.fk_err_arcsec = err_as;
    out.pass = out.ik_err_mm <= IK_TOL_MM && err_mm <= FK_TOL_MM && err_as <= FK_TOL_ARCSEC;
    out
}

/// The larger of `a` and `b` (`a` if `b` is NaN): `f64::max` without libm's `fmax`
/// (its only use in the flight image was the boot self-test).
fn larger(a: f64, b: f64) -> f64 {
    if b > a {
        b
    } else {
        a
    }
}

/// FNV-1a offset basis (32-bit).
const FNV_OFFSET: u32 = 0x811c_9dc5;
/// FNV-1a prime (32-bit).
const FNV_PRIME: u32 = 0x0100_0193;

/// Folds words into an FNV-1a digest (a fingerprint of result bits, not a safety CRC).
pub fn fnv1a(mut h: u32, words: &[u32]) -> u32 {
    for w in words {
        for byte in w.to_le_bytes() {
            h ^= u32::from(byte);
            h = h.wrapping_mul(FNV_PRIME);
        }
    }
    h
}

/// Summary of the whole self-test.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Summary {
    /// Rows evaluated.
    pub rows: u32,
    /// Rows that failed a check.
    pub failures: u32,
    /// Largest IK error over the rows (mm).
    pub max_ik_err_mm: f64,
    /// Largest FK translation error (mm).
    pub max_fk_err_mm: f64,
    /// Largest FK rotation error (arcsec).
    pub max_fk_err_arcsec: f64,
    /// Most FK iterations.
    pub max_fk_iterations: u8,
    /// FNV-1a digest over every row's IK and FK bits, in row order.
    pub digest: u32,
}

/// Runs every golden row, calling `each` with the row index and outcome.
pub fn run_all(geom: &Geometry<f32>, mut each: impl FnMut(u32, &RowOutcome)) -> Summary {
    let mut s = Summary {
        digest: FNV_OFFSET,
        ..Summary::default()
    };
    for (i, row) in golden_rows().enumerate() {
        let o = run_row(geom, &row);
        each(i as u32, &o);
        s.rows += 1;
        if !o.pass {
            s.failures += 1;
        }
        // NaN (a failed stage) propagates into the maxima so it cannot hide.
        s.max_ik_err_mm = nan_max(s.max_ik_err_mm, o.ik_err_mm);
        s.max_fk_err_mm = nan_max(s.max_fk_err_mm, o.fk_err_mm);
        s.max_fk_err_arcsec = nan_max(s.max_fk_err_arcsec, o.fk_err_arcsec);
        s.max_fk_iterations = s.max_fk_iterations.max(o.fk_iterations);
        s.digest = fnv1a(s.digest, &o.ik_bits);
        s.digest = fnv1a(s.digest, &o.fk_bits);
    }
    if s.rows == 0 {
        s.failures = 1;
    }
    s
}

fn nan_max(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each boot row is a golden row (the first, then every stride-th) rounded to f32,
    /// and passes the self-test with the flight geometry, as the row it rounds does.
    #[test]
    fn boot_rows_are_the_golden_rows_in_f32_and_pass() {
        let stride = GOLDEN_ROWS.len().div_ceil(BOOT_GOLDEN_ROWS.len());
        let geom = Geometry::<f32>::new(&crate::nominal::prototype_with_flight_limits());
        assert!(geom.is_ok());
        let Ok(geom) = geom else { return };
        for (k, boot) in BOOT_GOLDEN_ROWS.iter().enumerate() {
            let golden = &GOLDEN_ROWS[k * stride];
            let pairs = boot
                .pose
                .iter()
                .zip(golden.pose.iter())
                .chain(boot.strokes_mm.iter().zip(golden.strokes_mm.iter()));
            for (b, g) in pairs {
                assert_eq!(*b, *g as f32, "row {}", k * stride);
            }
            let wide = run_row(&geom, &boot.widen());
            assert!(wide.pass, "boot row {k}: {wide:?}");
            assert!(run_row(&geom, golden).pass);
            // The rounding's share of the IK error: far inside the 1 nm tolerance.
            let exact = run_row(&geom, golden);
            assert!(
                (wide.ik_err_mm - exact.ik_err_mm).abs() < 0.3e-6,
                "{wide:?} {exact:?}"
            );
        }
    }
}
