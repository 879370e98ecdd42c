//! Shared helpers of the host tests.
#![allow(dead_code)]

pub mod qemu;

use m2ctl::kinematics::{Pose, ARCSEC_PER_RAD};

/// Deterministic xorshift64* generator: the tests' own, independent of the crate's RNGs.
pub struct TestRng(pub u64);

impl TestRng {
    /// Uniform in [-1, 1).
    pub fn sym(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

/// Workspace half-range of the issue: translation (mm).
pub const WS_MM: f64 = 2.0;
/// Workspace half-range of the issue: rotation (arcsec).
pub const WS_ARCSEC: f64 = 600.0;

/// Poses over the +-2 mm, +-600 arcsec workspace: every one of the 64 corners, then
/// random interior points. Components are f32-representable so that the f32 and f64
/// evaluations see identical inputs.
pub fn workspace_poses(n_random: usize, seed: u64) -> Vec<Pose<f64>> {
    let mut out = Vec::new();
    for c in 0..64u32 {
        let s = |k: u32| if c & (1 << k) != 0 { 1.0 } else { -1.0 };
        out.push(pose_f32_exact([
            s(0) * WS_MM,
            s(1) * WS_MM,
            s(2) * WS_MM,
            s(3) * WS_ARCSEC,
            s(4) * WS_ARCSEC,
            s(5) * WS_ARCSEC,
        ]));
    }
    let mut rng = TestRng(seed);
    for _ in 0..n_random {
        let v = [
            rng.sym() * WS_MM,
            rng.sym() * WS_MM,
            rng.sym() * WS_MM,
            rng.sym() * WS_ARCSEC,
            rng.sym() * WS_ARCSEC,
            rng.sym() * WS_ARCSEC,
        ];
        out.push(pose_f32_exact(v));
    }
    out
}

/// A pose from mm/arcsec whose components are rounded to f32 first.
pub fn pose_f32_exact(v: [f64; 6]) -> Pose<f64> {
    Pose::<f32>::from_array([
        v[0] as f32,
        v[1] as f32,
        v[2] as f32,
        (v[3] / ARCSEC_PER_RAD) as f32,
        (v[4] / ARCSEC_PER_RAD) as f32,
        (v[5] / ARCSEC_PER_RAD) as f32,
    ])
    .cast()
}

/// The golden CSV rows (pose mm/arcsec, strokes mm) of the reference, via the crate's
/// file parser.
pub fn golden() -> Vec<([f64; 6], [f64; 6])> {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/testdata/ik_golden.csv"
    ))
    .unwrap();
    m2ctl::ground::files::parse_csv(&text, 0..12)
        .unwrap()
        .into_iter()
        .map(|r| {
            let p: [f64; 6] = r.values[..6].try_into().unwrap();
            let s: [f64; 6] = r.values[6..].try_into().unwrap();
            (p, s)
        })
        .collect()
}
