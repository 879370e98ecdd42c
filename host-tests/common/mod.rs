//! Shared helpers of the host tests.
#![allow(dead_code)]

pub mod qemu;

use m2ctl::kinematics::Pose;
use m2ctl::units::{ARCSEC_PER_RAD, NM_PER_UM, UAS_PER_ARCSEC};

/// Deterministic xorshift64* generator: the tests' own, independent of the crate's RNGs.
pub struct TestRng(pub u64);

impl TestRng {
    /// The next 64 random bits (also the generator's state).
    pub fn bits(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// Uniform in [-1, 1).
    pub fn sym(&mut self) -> f64 {
        (self.bits() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
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

/// The repository's root (the workspace's). These helpers serve the tests of every
/// workspace member (host-tests/ and the ground crates' tests/), whose
/// `CARGO_MANIFEST_DIR` is their own package folder: the root is the nearest folder
/// above it that holds the workspace's one `Cargo.lock`.
pub fn repo_root() -> std::path::PathBuf {
    let mut p = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    while !p.join("Cargo.lock").exists() {
        assert!(
            p.pop(),
            "no Cargo.lock above {}",
            env!("CARGO_MANIFEST_DIR")
        );
    }
    p
}

/// The golden CSV rows (pose mm/arcsec, strokes mm) of the reference. Read here without
/// the ground tools' file parser (m2calib builds on this crate, not the other way):
/// comment lines `#`, one header naming the twelve columns in the reference's order
/// (`x_mm .. rz_arcsec, s1_mm .. s6_mm`), then rows of twelve numbers.
pub fn golden() -> Vec<([f64; 6], [f64; 6])> {
    let text = std::fs::read_to_string(repo_root().join("testdata/ik_golden.csv")).unwrap();
    let mut rows = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'));
    let header: Vec<&str> = rows.next().unwrap().split(',').map(str::trim).collect();
    assert_eq!(header.len(), 12, "golden header: {header:?}");
    assert!(header[0] == "x_mm" && header[5] == "rz_arcsec" && header[6] == "s1_mm");
    rows.map(|l| {
        let v: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
        assert_eq!(v.len(), 12, "golden row: {l}");
        (v[..6].try_into().unwrap(), v[6..].try_into().unwrap())
    })
    .collect()
}

// ---------------------------------------------------------------------------------
// Bench helpers shared by the controller, contract and soak tests.

use m2ctl::link::command::{WirePose, TABLE_CHUNK_MAX_LEN};
use m2ctl::link::tm::{dump_chunks, Verification};
use m2ctl::link::{Command, TableChunk};
use m2ctl::sim::Bench;
use m2ctl::table::{Table, TABLE_LEN};

/// A wire pose from micrometres and arcseconds.
pub fn wire(x_um: f64, y_um: f64, z_um: f64, a_as: f64, b_as: f64, c_as: f64) -> WirePose {
    WirePose {
        translation_nm: [x_um, y_um, z_um].map(|v| (v * NM_PER_UM).round() as i32),
        rotation_uas: [a_as, b_as, c_as].map(|v| (v * UAS_PER_ARCSEC).round() as i32),
    }
}

/// Frames a raw packet onto the uplink and runs one cycle.
pub fn tick_packet(r: &mut Bench, pkt: &[u8]) {
    r.uplink_bytes(&m2ctl::station::frame(pkt));
    r.tick();
}

/// Cycles a table job (commit, activation) may take on the bench (sector erases).
pub const JOB_CYCLES: u32 = 5_000;

/// Acceptance, start and completion, all successful.
pub fn all_ok(v: &[Verification]) -> bool {
    v == [
        Verification::AcceptanceSuccess,
        Verification::StartSuccess,
        Verification::CompletionSuccess,
    ]
}

/// Uploads a table image in chunks (in the given chunk order).
pub fn upload(r: &mut Bench, bytes: &[u8; TABLE_LEN], order: &[usize]) {
    let chunks: Vec<(u16, Vec<u8>)> = dump_chunks(bytes).map(|(o, b)| (o, b.to_vec())).collect();
    for &i in order {
        let (off, data) = &chunks[i];
        let rid = r.send(&Command::LoadTableChunk(
            TableChunk::new(*off, data).unwrap(),
        ));
        assert!(
            all_ok(&r.st.reports(rid)),
            "chunk {i}: {:?}",
            r.st.reports(rid)
        );
    }
}

/// A plausible calibrated table (the soak's generator).
pub fn calibrated_table(id: u32) -> Table {
    m2ctl::sim::soak::calibrated_table(id)
}

/// TC[8,1] activate naming `t`.
pub fn activate(t: &Table) -> Command {
    Command::ActivateTable {
        table_id: t.table_id,
        crc32: t.crc32(),
    }
}

/// Uploads, commits and (optionally) activates a table by telecommand.
pub fn install(r: &mut Bench, t: &Table, activate: bool) -> Vec<Verification> {
    let n = TABLE_LEN.div_ceil(TABLE_CHUNK_MAX_LEN);
    upload(r, &t.to_bytes(), &(0..n).collect::<Vec<_>>());
    let reps = r.command(&Command::CommitTable { crc32: t.crc32() }, JOB_CYCLES);
    if activate && all_ok(&reps) {
        let a = r.command(&self::activate(t), JOB_CYCLES);
        assert!(all_ok(&a), "{a:?}");
    }
    reps
}

/// A plant with the prototype's geometry (no manufacturing error) whose parts sit at
/// `profile`, with calibrated sensors drawn from `seed` and the materials' nominal
/// coefficients as truth (the thermal tests' plant).
pub fn thermal_plant(profile: m2ctl::sim::thermal::Profile, seed: u64) -> m2ctl::sim::Plant {
    use m2ctl::sim::thermal::{Coefficients, SensorConfig, ThermalConfig};
    let cfg = ThermalConfig {
        profile,
        truth: Coefficients::NOMINAL,
        sensors: SensorConfig::drawn(seed),
    };
    let plant = m2ctl::sim::Plant::new(
        &m2ctl::nominal::PROTOTYPE,
        m2ctl::sim::PlantConfig {
            seed,
            ..m2ctl::sim::PlantConfig::default()
        },
    )
    .unwrap_or_else(|e| panic!("plant: {e:?}"));
    plant
        .with_thermal(cfg)
        .unwrap_or_else(|e| panic!("thermal: {e:?}"))
}
