//! `m2kinbench`: the host benchmark of the flight kinematics (feature `host`), made to
//! run under `valgrind --tool=callgrind` (see `scripts/bench-host.sh`): it calls each
//! measured function once per pose through a non-inlined wrapper, and the script
//! collects only inside that wrapper (`--toggle-collect`) and divides by the calls.
//!
//! Inputs (the same as issue 10's side-by-side measurement): [`POSES`] poses uniform in
//! the flight workspace (+-2 mm, +-600 arcsec per axis, seeded); strokes = IK of each
//! pose in the measured precision; FK warm-started [`WARM_START_MM`] (translation) and
//! [`WARM_START_ARCSEC`] (rotation) away from the true pose, in a random direction.
//!
//! Usage: `m2kinbench [ik-f32|ik-f64|fk-f32|fk-f64|all]` (default `all`). It prints the
//! number of calls and a checksum so the results are used; figures come from callgrind.
//! Every call's result is checked (a failed IK or FK ends the run with an error).

use std::hint::black_box;
use std::process::ExitCode;

use m2ctl::kinematics::{
    fk, ik, FkConfig, FkError, FkSolution, Geometry, IkError, Pose, Real, LEGS,
};
use m2ctl::nominal::{
    prototype_with_flight_limits, WORKSPACE_ROTATION_ARCSEC, WORKSPACE_TRANSLATION_MM,
};
use m2ctl::units::ARCSEC_PER_RAD;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// Poses per measured function.
pub const POSES: usize = 1000;
/// Seed of the pose and warm-start draws.
const SEED: u64 = 10;
/// Distance of the FK warm start from the true pose in translation (mm; 10 um).
pub const WARM_START_MM: f64 = 0.010;
/// Angular distance of the FK warm start from the true pose (arcsec).
pub const WARM_START_ARCSEC: f64 = 1.0;

/// One FK case: measured strokes (mm), warm start.
struct FkCase<T> {
    strokes_mm: [T; LEGS],
    start: Pose<T>,
}

/// A random unit 3-vector (uniform direction).
fn unit3(rng: &mut Pcg64) -> [f64; 3] {
    loop {
        let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..=1.0));
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n > 1e-3 && n <= 1.0 {
            return v.map(|x| x / n);
        }
    }
}

/// The benchmark's poses (mm, arcsec) and warm-start offsets (mm, arcsec), in f64.
fn draws() -> Vec<([f64; 6], [f64; 6])> {
    let mut rng = Pcg64::seed_from_u64(SEED);
    (0..POSES)
        .map(|_| {
            let t: [f64; 3] = std::array::from_fn(|_| {
                rng.random_range(-WORKSPACE_TRANSLATION_MM..=WORKSPACE_TRANSLATION_MM)
            });
            let r: [f64; 3] = std::array::from_fn(|_| {
                rng.random_range(-WORKSPACE_ROTATION_ARCSEC..=WORKSPACE_ROTATION_ARCSEC)
            });
            let dt = unit3(&mut rng).map(|v| v * WARM_START_MM);
            let dr = unit3(&mut rng).map(|v| v * WARM_START_ARCSEC);
            (
                [t[0], t[1], t[2], r[0], r[1], r[2]],
                [dt[0], dt[1], dt[2], dr[0], dr[1], dr[2]],
            )
        })
        .collect()
}

fn pose<T: Real>(v: &[f64; 6]) -> Pose<T> {
    Pose::from_mm_arcsec([v[0], v[1], v[2]], [v[3], v[4], v[5]])
}

fn poses<T: Real>() -> Vec<Pose<T>> {
    draws().iter().map(|(p, _)| pose(p)).collect()
}

fn fk_cases<T: Real>(geom: &Geometry<T>) -> Result<Vec<FkCase<T>>, IkError> {
    draws()
        .iter()
        .map(|(p, d)| {
            let truth: Pose<T> = pose(p);
            let strokes_mm = ik(geom, &truth)?;
            let mut start = truth;
            for (v, dv) in start.translation_mm.iter_mut().zip(&d[..3]) {
                *v += T::from_f64(*dv);
            }
            for (v, dv) in start.rotation_rad.iter_mut().zip(&d[3..]) {
                *v += T::from_f64(*dv / ARCSEC_PER_RAD);
            }
            Ok(FkCase { strokes_mm, start })
        })
        .collect()
}

// The measured wrappers: callgrind collects inside these only (their names are matched
// by scripts/bench-host.sh).

#[inline(never)]
fn measured_ik_f32(g: &Geometry<f32>, p: &Pose<f32>) -> Result<[f32; LEGS], IkError> {
    ik(g, p)
}

#[inline(never)]
fn measured_ik_f64(g: &Geometry<f64>, p: &Pose<f64>) -> Result<[f64; LEGS], IkError> {
    ik(g, p)
}

#[inline(never)]
fn measured_fk_f32(
    g: &Geometry<f32>,
    s: &[f32; LEGS],
    start: &Pose<f32>,
    cfg: &FkConfig<f32>,
) -> Result<FkSolution<f32>, FkError> {
    fk(g, s, start, cfg)
}

#[inline(never)]
fn measured_fk_f64(
    g: &Geometry<f64>,
    s: &[f64; LEGS],
    start: &Pose<f64>,
    cfg: &FkConfig<f64>,
) -> Result<FkSolution<f64>, FkError> {
    fk(g, s, start, cfg)
}

/// A measured IK wrapper.
type IkFn<T> = fn(&Geometry<T>, &Pose<T>) -> Result<[T; LEGS], IkError>;

/// Runs one IK benchmark; returns (calls, checksum).
fn run_ik<T: Real>(geom: &Geometry<T>, f: IkFn<T>) -> Result<(usize, f64), String> {
    let mut sum = 0.0;
    let ps = poses::<T>();
    for p in &ps {
        let s = f(black_box(geom), black_box(p)).map_err(|e| format!("IK failed: {e:?}"))?;
        sum += black_box(s).iter().map(|v| v.to_f64()).sum::<f64>();
    }
    Ok((ps.len(), sum))
}

/// A measured FK wrapper.
type FkFn<T> =
    fn(&Geometry<T>, &[T; LEGS], &Pose<T>, &FkConfig<T>) -> Result<FkSolution<T>, FkError>;

/// Runs one FK benchmark; returns (calls, checksum, total Newton steps).
fn run_fk<T: Real>(geom: &Geometry<T>, f: FkFn<T>) -> Result<(usize, f64, u32), String> {
    let cases = fk_cases(geom).map_err(|e| format!("IK of a benchmark pose failed: {e:?}"))?;
    let cfg = FkConfig::default();
    let (mut sum, mut steps) = (0.0, 0u32);
    for c in &cases {
        let sol = f(
            black_box(geom),
            black_box(&c.strokes_mm),
            black_box(&c.start),
            black_box(&cfg),
        )
        .map_err(|e| format!("FK failed: {e:?}"))?;
        let sol = black_box(sol);
        steps += u32::from(sol.iterations);
        sum += sol.pose.to_array().iter().map(|v| v.to_f64()).sum::<f64>();
    }
    Ok((cases.len(), sum, steps))
}

fn run(which: &str) -> Result<(), String> {
    let params = prototype_with_flight_limits();
    let g32 = Geometry::<f32>::new(&params).map_err(|e| format!("{e:?}"))?;
    let g64 = Geometry::<f64>::new(&params).map_err(|e| format!("{e:?}"))?;
    let all = which == "all";
    let mut known = all;
    if all || which == "ik-f32" {
        known = true;
        let (n, sum) = run_ik(&g32, measured_ik_f32)?;
        println!("ik-f32 calls={n} checksum={sum:.6}");
    }
    if all || which == "ik-f64" {
        known = true;
        let (n, sum) = run_ik(&g64, measured_ik_f64)?;
        println!("ik-f64 calls={n} checksum={sum:.6}");
    }
    if all || which == "fk-f32" {
        known = true;
        let (n, sum, steps) = run_fk(&g32, measured_fk_f32)?;
        println!("fk-f32 calls={n} steps={steps} checksum={sum:.6}");
    }
    if all || which == "fk-f64" {
        known = true;
        let (n, sum, steps) = run_fk(&g64, measured_fk_f64)?;
        println!("fk-f64 calls={n} steps={steps} checksum={sum:.6}");
    }
    if known {
        Ok(())
    } else {
        Err(format!(
            "unknown benchmark '{which}' (ik-f32, ik-f64, fk-f32, fk-f64, all)"
        ))
    }
}

fn main() -> ExitCode {
    let which = std::env::args().nth(1).unwrap_or_else(|| "all".to_owned());
    // On the main thread the stack's alignment depends on the size of the environment
    // and the arguments, and some copies cost a few instructions more or less with it.
    // A spawned thread's stack starts page-aligned: the same count from any clone path.
    let outcome = std::thread::spawn(move || run(&which))
        .join()
        .unwrap_or_else(|_| Err("benchmark thread panicked".to_owned()));
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("m2kinbench: {e}");
            ExitCode::FAILURE
        }
    }
}
