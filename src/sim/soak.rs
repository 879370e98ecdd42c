//! The model-based soak: the real controller, link service and worker on the bench,
//! driven by a long seeded random sequence of valid and invalid telecommands, plant
//! faults and repairs, and power cuts (also in the middle of flash writes), with the
//! operator contract checked **every cycle**:
//!
//! 1. commanded strokes stay inside the running table's stroke limits, and no slider is
//!    taken outside them (or further outside, after a slip displaced it) by the controller;
//! 2. no commanded stroke changes by more than the speed limit times a cycle (plus
//!    rounding) from the last command or from what the drives held, whatever the
//!    sequence;
//! 3. while a fault is latched nothing moves except a stop ramp and the recovery move's
//!    own leg (the drives: a slider may still settle on its drive train);
//! 4. during a recovery move the other legs keep exactly their setpoints;
//! 5. every telecommand gets its service-1 reports in a valid order (none lost: the
//!    telemetry queue never drops);
//! 6. after every reboot the running table is the one the operator's last completed
//!    selection implies (or, if a selection was being written at the cut, that one),
//!    never a table nobody committed;
//! 7. no leg's commanded stroke moves toward an end-of-travel switch that the cycle's
//!    read showed active (or unreadable), unless the drives hold where their sliders are;
//! 8. no commanded step exceeds the speed limit in force (the parameters the operator
//!    set and the controller applied), whatever was upset in RAM;
//! 9. no upset value is ever persisted: the parameters in flash are always a set the
//!    operator's telecommands made (checked after every parameter job and reboot);
//! 10. a detected upset always clears after its repair: from the cycle fault 0x100
//!     latches, the reload (event 0x0013) comes within [`REPAIR_CYCLES`], whatever job
//!     was running;
//! 11. a coordinated move's completion success is never reported while a true slider is
//!     outside the in-position tolerance of its setpoint (`motion::fine`; not checked
//!     while an encoder is made to lie: stuck, offset or noisier than specified).
//!
//! The plant has the realistic drive train (`sim::drive_train`: microsteps, backlash,
//! lead error, stiction, settling).
//!
//! The adversary also upsets RAM, single bits at random moments (during moves, during
//! table jobs): the parameters in force, their check word, the running table, its
//! derived geometry, the supervision thresholds, the derived settings and the output
//! stage's limits.
//!
//! The adversary's plant faults include the switches' (a switch misadjusted into the
//! path of the sliders, stuck active, an unreadable input) and encoder warnings.
//!
//! The sequence comes from a [`Choices`] source: a seeded generator for the soak test
//! (`host-tests/soak.rs`, `M2_SOAK_SECONDS`, `M2_SOAK_SEED`) or the fuzzer's bytes
//! (`fuzz/fuzz_targets/controller.rs`): one model, one set of invariants.

#![allow(clippy::needless_range_loop)] // index loops over six legs read clearer here

use std::collections::HashMap;

use crate::controller::{event, State};
use crate::kinematics::LEGS;
use crate::link::command::WirePose;
use crate::link::tm::{dump_chunks, Verification};
use crate::link::{Command, MemoryId, RequestId, TableChunk};
use crate::motion::{CYCLE_S, DEFAULT_MAX_SPEED_MM_PER_S};
use crate::nominal::PROTOTYPE;
use crate::sim::bench::UART_115200_BYTES_PER_CYCLE;
use crate::sim::drive_train::DriveTrainConfig;
use crate::sim::{Bench, BenchConfig, InjectedFault, Plant, PlantConfig, SwitchEnd};
use crate::station::Tm;
use crate::table::mock_flash::{MockFlash, TearMode};
use crate::table::Table;
use crate::units::UM_PER_MM;

/// Stroke tolerance beyond a soft limit (mm): the supervision's own tolerance.
const LIMIT_TOL_MM: f64 = 1e-3;
/// Rounding allowance on one setpoint step (mm): f32 strokes near 5 mm.
const STEP_ROUNDING_MM: f64 = 2e-6;
/// A slider "at rest" moves less than this per cycle (mm): 0.1 nm, above the f32
/// resolution of a held stroke (a hold rounds the setpoint to the f32 of the interface).
const STILL_MM: f64 = 1e-7;

/// Cycles within which a detected upset must be repaired (invariant 10): two scrub
/// periods (the reload may wait for a job that runs: a commit erases 0.3 s sectors) and
/// the slowest job.
pub const REPAIR_CYCLES: u64 = 6_000;

/// What the soak knows the controller should run after a reboot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct TableRef {
    id: u32,
    crc: u32,
}

impl TableRef {
    fn of(t: &Table) -> Self {
        Self {
            id: t.table_id,
            crc: t.crc32(),
        }
    }
}

/// Where the soak's decisions come from.
pub trait Choices {
    /// Uniform in [-1, 1).
    fn sym(&mut self) -> f64;
    /// Whether the source is exhausted (a fuzz input consumed): the driver stops.
    fn exhausted(&self) -> bool {
        false
    }
}

/// Deterministic xorshift64* generator (the soak test's source).
#[derive(Clone, Copy, Debug)]
pub struct SeededChoices(pub u64);

impl Choices for SeededChoices {
    fn sym(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

/// Decisions read from bytes (a fuzz input): two bytes per decision, then exhausted.
#[derive(Clone, Debug)]
pub struct ByteChoices<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> ByteChoices<'a> {
    /// Over `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, at: 0 }
    }
}

impl Choices for ByteChoices<'_> {
    fn sym(&mut self) -> f64 {
        let hi = self.bytes.get(self.at).copied().unwrap_or(0);
        let lo = self.bytes.get(self.at + 1).copied().unwrap_or(0);
        self.at += 2;
        f64::from(u16::from_be_bytes([hi, lo])) / 32768.0 - 1.0
    }
    fn exhausted(&self) -> bool {
        self.at >= self.bytes.len()
    }
}

/// A plausible calibrated table: nominal joints moved by tens of micrometres.
pub fn calibrated_table(id: u32) -> Table {
    let mut t = Table::nominal();
    t.table_id = id;
    for (i, leg) in t.legs.iter_mut().enumerate() {
        leg.a_mm[0] += 0.01 * i as f64;
        leg.b_mm[1] -= 0.02;
    }
    t
}

/// Figures of a soak run.
#[derive(Clone, Copy, Debug, Default)]
pub struct SoakFigures {
    /// Control cycles run.
    pub cycles: u64,
    /// Telecommands sent.
    pub tcs_sent: u64,
    /// Telecommands whose reports were complete and in order.
    pub tcs_done: u64,
    /// Telecommands that completed successfully.
    pub completed: u64,
    /// Reboots (power cuts).
    pub reboots: u64,
    /// Reboots that struck inside a flash write.
    pub cuts_in_writes: u64,
    /// Plant faults injected.
    pub faults_injected: u64,
    /// Cycles per state (idle, moving, stopping, recovery move, faulted).
    pub state_cycles: [u64; 5],
    /// End-of-travel events (0x0007) received: switches seen active.
    pub switch_trips: u64,
    /// Cycles in motion with a leg blocked by an active (or unreadable) switch: the
    /// cycles invariant 7 constrained.
    pub blocked_motion_cycles: u64,
    /// RAM upsets injected.
    pub upsets: u64,
    /// Repairs (reloads) after detected upsets.
    pub repairs: u64,
    /// Coordinated moves whose completion success invariant 11 checked.
    pub moves_in_position: u64,
    /// Invariant violations.
    pub violations: u64,
}

/// The soak: the bench, the model of what the operator may expect, and the checks.
pub struct Soak<C> {
    /// The bench under test.
    pub r: Bench,
    rng: C,
    /// Tables the soak uploaded (by CRC), so any booted table must be one of them.
    known: HashMap<u32, Table>,
    /// The last table whose activation (activate, switch bank, revert) completed.
    selected: TableRef,
    /// Selection telecommands in flight: request ID and the CRC of the table each
    /// selects (`None`: switch bank, whose table the soak does not model).
    selecting: Vec<(RequestId, Option<u32>)>,
    /// Telecommands sent since the last reboot, with the log length when sent.
    in_flight: Vec<(RequestId, usize)>,
    /// The coordinated moves sent (invariant 11).
    moves: Vec<RequestId>,
    /// Moves invariant 11 checked.
    moves_in_position: u64,
    /// The cycle after a plant repair (a drive re-referenced: its count moves, the
    /// slider does not): the commanded-stroke checks skip it.
    repaired: bool,
    /// Telecommands whose reports were checked complete.
    tcs_done: u64,
    /// Telecommands that completed successfully.
    completed: u64,
    /// Cycles per state (Idle, Moving, Stopping, StrokeMoving, Faulted).
    state_cycles: [u64; 5],
    tcs_sent: u64,
    reboots: u64,
    cuts_in_writes: u64,
    faults_injected: u64,
    cycles: u64,
    switch_trips: u64,
    blocked_motion_cycles: u64,
    violations: Vec<String>,
    /// Where the station log was at the last check.
    log_seen: usize,
    prev_cmd: [f32; LEGS],
    prev_truth: [f64; LEGS],
    prev_drives: [f64; LEGS],
    /// The drives' positions at the end of the last cycle (mm): where a hold commands.
    prev_positions: [f64; LEGS],
    prev_state: State,
    /// The legs of the motion of the last cycle (housekeeping's `moving_legs`).
    prev_moving_legs: u8,
    prev_faulted: bool,
    tm_dropped_seen: u16,
    /// Consecutive cycles in the faulted state.
    rest_cycles: u32,
    /// The last actions, printed at the first violation.
    history: Vec<String>,
    /// The parameter set known persisted (its persisted form): invariant 9.
    params_confirmed: [u8; crate::table::store::PARAMETERS_LEN],
    /// TC[20,3]s in flight and their pairs: each may have been applied, in order.
    setting: Vec<(RequestId, Vec<(u16, i32)>)>,
    /// Speed limits in force (mm per cycle): coordinated, direct (invariant 8).
    step_limits_mm: (f64, f64),
    /// The oldest upset detection (fault 0x100) not yet repaired (invariant 10).
    corrupt_since: Option<u64>,
    /// RAM upsets injected.
    upsets: u64,
    /// Reloads after a detected upset (events 0x0013).
    repairs: u64,
}

/// Actions kept in the history.
const HISTORY_LEN: usize = 30;
/// Violations printed (all are counted).
const MAX_PRINTED_VIOLATIONS: usize = 20;

fn fresh_bench(flash: MockFlash) -> Bench {
    let plant = Plant::new(
        &crate::sim::manufacturing::perturbed(&PROTOTYPE, 0.05, 77),
        PlantConfig {
            seed: 5,
            ..PlantConfig::default()
        },
    )
    .unwrap()
    .with_drive_train(DriveTrainConfig::realistic())
    .unwrap();
    Bench::with(
        plant,
        flash,
        BenchConfig {
            uart_bytes_per_cycle: Some(UART_115200_BYTES_PER_CYCLE),
            ..BenchConfig::default()
        },
    )
}

impl<C: Choices> Soak<C> {
    /// A fresh bench on a blank flash, decisions from `choices`.
    pub fn new(choices: C) -> Self {
        let r = fresh_bench(MockFlash::new(crate::sim::bench::SIM_FLASH_BYTES));
        let nominal = Table::nominal();
        let mut known = HashMap::new();
        known.insert(nominal.crc32(), nominal);
        let prev_cmd = r.ctl.strokes_commanded_mm();
        Self {
            r,
            rng: choices,
            known,
            selected: TableRef::of(&nominal),
            selecting: Vec::new(),
            in_flight: Vec::new(),
            moves: Vec::new(),
            moves_in_position: 0,
            repaired: false,
            tcs_done: 0,
            completed: 0,
            state_cycles: [0; 5],
            tcs_sent: 0,
            reboots: 0,
            cuts_in_writes: 0,
            faults_injected: 0,
            cycles: 0,
            switch_trips: 0,
            blocked_motion_cycles: 0,
            violations: Vec::new(),
            log_seen: 0,
            prev_cmd,
            prev_truth: [0.0; LEGS],
            prev_drives: [0.0; LEGS],
            prev_positions: [0.0; LEGS],
            prev_state: State::Idle,
            prev_moving_legs: 0,
            prev_faulted: false,
            tm_dropped_seen: 0,
            rest_cycles: 0,
            history: Vec::new(),
            params_confirmed: crate::controller::Parameters::none().encode(),
            setting: Vec::new(),
            step_limits_mm: (0.0, 0.0),
            corrupt_since: None,
            upsets: 0,
            repairs: 0,
        }
        .with_limits_from_controller()
    }

    /// The speed limits in force, read from the controller (at boot: nothing upset yet).
    fn with_limits_from_controller(mut self) -> Self {
        self.read_step_limits();
        self
    }

    fn read_step_limits(&mut self) {
        let l = self
            .r
            .ctl
            .parameters()
            .step_limits(self.r.ctl.active_table());
        let dt = f64::from(CYCLE_S);
        self.step_limits_mm = (f64::from(l.coordinated.0) * dt, f64::from(l.direct.0) * dt);
    }

    fn uniform(&mut self) -> f64 {
        (self.rng.sym() + 1.0) / 2.0
    }

    /// A choice in 0..n.
    pub fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n - 1)
    }

    fn violation(&mut self, what: String) {
        if self.violations.len() < MAX_PRINTED_VIOLATIONS {
            // Each printed violation with what led to it and the state it was seen in
            // (a long run is replayed to it with the same seed and `M2_SOAK_CYCLES`).
            eprintln!("history before the violation:");
            for h in &self.history {
                eprintln!("  {h}");
            }
            eprintln!("VIOLATION at cycle {}: {what}", self.cycles);
            eprintln!("  {}", self.snapshot());
        }
        self.violations.push(what);
    }

    /// The state a violation is seen in: controller state, latched faults, moving legs,
    /// commanded strokes now and in the last cycle, the drives' setpoints now and in the
    /// last cycle, the true strokes (mm).
    fn snapshot(&self) -> String {
        let hk = self.r.ctl.housekeeping();
        format!(
            "state {:?} (last {:?}), faults {:#x}, moving legs {:#08b}, commanded {:?} (last {:?}), drives {:?} (last {:?}), true {:?}",
            self.r.ctl.state(),
            self.prev_state,
            self.r.ctl.faults().bits(),
            hk.moving_legs,
            self.r.ctl.strokes_commanded_mm(),
            self.prev_cmd,
            self.r.plant.with(|p| p.drive_setpoints_mm()),
            self.prev_drives,
            self.r.plant.with(|p| p.strokes_mm()),
        )
    }

    /// Control cycles run so far.
    pub fn cycles(&self) -> u64 {
        self.cycles
    }

    fn note(&mut self, what: String) {
        if self.history.len() == HISTORY_LEN {
            self.history.remove(0);
        }
        self.history.push(format!("cycle {}: {what}", self.cycles));
    }

    fn send(&mut self, cmd: &Command) -> RequestId {
        if !matches!(cmd, Command::LoadTableChunk(_)) {
            self.note(format!("TC {cmd:?} in state {:?}", self.r.ctl.state()));
        }
        let from = self.r.st.log.len();
        let rid = self.r.queue(cmd);
        self.tcs_sent += 1;
        self.in_flight.push((rid, from));
        rid
    }

    /// A random pose inside (mostly), near or outside the +-2 mm / +-600" workspace.
    fn pose(&mut self) -> WirePose {
        let scale = match self.below(10) {
            0 => 1.3,
            1 => 1.02,
            _ => 0.6,
        };
        let mut v = [0i32; 6];
        for k in 0..6 {
            let r = self.rng.sym() * scale;
            v[k] = if k < 3 {
                (r * 2.0e6) as i32
            } else {
                (r * 600.0e6) as i32
            };
        }
        WirePose::from_array(v)
    }

    fn small_delta(&mut self) -> WirePose {
        let mut v = [0i32; 6];
        for k in 0..6 {
            let r = self.rng.sym();
            v[k] = if k < 3 {
                (r * 0.3e6) as i32
            } else {
                (r * 60.0e6) as i32
            };
        }
        WirePose::from_array(v)
    }

    /// A table to upload: plausible (known afterwards) or one the controller must refuse.
    fn table(&mut self, good: bool) -> Table {
        let id = 10 + self.below(1000) as u32;
        let mut t = calibrated_table(id);
        t.legs[self.below(6)].b_mm[self.below(3)] += self.rng.sym() * 0.05;
        if !good {
            match self.below(3) {
                0 => t.p0_mm[0] = f64::NAN,
                1 => t.legs[2].a_mm[1] += 5.0,
                _ => {
                    t.stroke_limits.min_mm = [-0.4; 6];
                    t.stroke_limits.max_mm = [0.4; 6];
                }
            }
        }
        t
    }

    fn upload(&mut self, t: &Table, corrupt_crc: bool, skip_chunk: bool) {
        let bytes = t.to_bytes();
        let chunks: Vec<(u16, Vec<u8>)> =
            dump_chunks(&bytes).map(|(o, b)| (o, b.to_vec())).collect();
        let skip = if skip_chunk {
            Some(self.below(chunks.len()))
        } else {
            None
        };
        for (i, (off, data)) in chunks.iter().enumerate() {
            if Some(i) != skip {
                self.send(&Command::LoadTableChunk(
                    TableChunk::new(*off, data).unwrap(),
                ));
            }
        }
        let crc = if corrupt_crc {
            t.crc32() ^ 0x10
        } else {
            t.crc32()
        };
        self.send(&Command::CommitTable { crc32: crc });
    }

    /// One random operator (or adversary) action.
    pub fn act(&mut self) {
        let pending = self.r.ctl.pending_table();
        match self.below(26) {
            23 => self.set_parameters(),
            24 | 25 => self.upset(),
            0..=4 => {
                let p = self.pose();
                let rid = self.send(&Command::MoveAbsolute(p));
                self.moves.push(rid);
            }
            5 | 6 => {
                let d = self.small_delta();
                let rid = self.send(&Command::MoveRelative(d));
                self.moves.push(rid);
            }
            7 => {
                self.send(&Command::Stop);
            }
            8 => {
                // The operator repairs what the fault report points at, then clears.
                if self.below(2) == 0 && matches!(self.r.ctl.state(), State::Faulted) {
                    self.repair();
                }
                self.send(&Command::ClearFault);
            }
            9 | 10 => {
                let leg = 1 + self.below(6) as u8;
                let delta_nm = (self.rng.sym() * 0.2e6) as i32;
                self.send(&Command::DirectStroke { leg, delta_nm });
            }
            11 => {
                let t = self.table(true);
                self.known.insert(t.crc32(), t);
                self.upload(&t, false, false);
            }
            12 => {
                let t = self.table(false);
                self.upload(&t, false, false);
            }
            13 => {
                // A plausible table uploaded badly; the upload buffer keeps its bytes, so a
                // later upload may complete it legitimately: it is a known table.
                let t = self.table(true);
                self.known.insert(t.crc32(), t);
                let (bad_crc, skip) = (self.below(2) == 0, self.below(2) == 0);
                self.upload(&t, bad_crc, skip || !bad_crc);
            }
            14 | 15 => {
                // Activate the pending table by name, or a wrong name.
                let (cmd, crc) = match pending {
                    Some(p) if self.below(4) != 0 => (
                        Command::ActivateTable {
                            table_id: p.table_id,
                            crc32: p.report.table_crc,
                        },
                        p.report.table_crc,
                    ),
                    _ => {
                        let crc = self.below(1 << 30) as u32;
                        (
                            Command::ActivateTable {
                                table_id: self.below(50) as u32,
                                crc32: crc,
                            },
                            crc,
                        )
                    }
                };
                let rid = self.send(&cmd);
                self.selecting.push((rid, Some(crc)));
            }
            16 => {
                let rid = self.send(&Command::SwitchBank);
                self.selecting.push((rid, None));
            }
            17 => {
                let rid = self.send(&Command::RevertToNominal);
                self.selecting.push((rid, Some(Table::nominal().crc32())));
            }
            18 => {
                let cmd = match self.below(4) {
                    0 => Command::Ping,
                    1 => Command::HousekeepingOneShot,
                    2 => Command::DumpTable(MemoryId::ActiveTable),
                    _ => Command::DumpTable(MemoryId::UploadBuffer),
                };
                self.send(&cmd);
            }
            19 => {
                // Garbage on the line, or a packet with a bad CRC.
                if self.below(2) == 0 {
                    let n = 1 + self.below(80);
                    let g: Vec<u8> = (0..n).map(|_| self.below(256) as u8).collect();
                    self.r.uplink_bytes(&g);
                } else {
                    let from = self.r.st.log.len();
                    let (mut p, rid) = self.r.st.packet(&Command::Ping).unwrap();
                    let last = p.len() - 1;
                    p[last] ^= 0x40;
                    self.r.uplink_bytes(&crate::station::frame(&p));
                    self.tcs_sent += 1;
                    self.in_flight.push((rid, from));
                }
            }
            20 => self.inject_fault(),
            // Repairs (re-referencing a drive that missed steps) are maintenance at rest:
            // a drive does not re-reference itself in the middle of a motion.
            21 => {
                if matches!(self.r.ctl.state(), State::Idle | State::Faulted) {
                    self.repair();
                }
            }
            _ => self.power_cut(),
        }
    }

    /// A valid TC[20,3]: speeds and accelerations within the defaults (so invariant 2's
    /// bound stays an upper bound), a pivot, the housekeeping period.
    fn set_parameters(&mut self) {
        let mut pairs = Vec::new();
        if self.below(2) == 0 {
            pairs.push((0x0010, 50_000 + self.below(150_001) as i32));
        }
        if self.below(2) == 0 {
            pairs.push((0x0011, 200_000 + self.below(800_001) as i32));
        }
        if self.below(2) == 0 {
            pairs.push((0x0012, 10_000 + self.below(40_001) as i32));
        }
        if self.below(2) == 0 || pairs.is_empty() {
            pairs.push((0x0003, (self.rng.sym() * 300e6) as i32));
        }
        if self.below(4) == 0 {
            pairs.push((0x0020, 500 + self.below(1_500) as i32));
        }
        let values = crate::link::command::ParameterValues::new(&pairs);
        let Ok(values) = values else { return };
        let rid = self.send(&Command::SetParameters(values));
        self.setting.push((rid, pairs));
    }

    /// One RAM bit flipped, as a radiation upset would: the parameters in force or
    /// their check word, the running table, its geometry, the supervision thresholds,
    /// the derived settings or the output stage's limits.
    fn upset(&mut self) {
        let bit = self.below(32) as u32;
        let which = self.below(7);
        let k = self.below(64);
        let flip32 = |x: &mut f32| *x = f32::from_bits(x.to_bits() ^ (1 << bit));
        let flip64 =
            |x: &mut f64| *x = f64::from_bits(x.to_bits() ^ (1u64 << (bit + 32 * (k as u32 & 1))));
        self.upsets += 1;
        self.note(format!(
            "upset: target {which} index {k} bit {bit} (state {:?}, job {})",
            self.r.ctl.state(),
            self.r.ctl.housekeeping().job
        ));
        match which {
            0 => self.r.ctl.upset_parameters(k % 21, bit),
            1 => self.r.ctl.upset(|a, _| {
                let leg = &mut a.geom.legs[k % LEGS];
                match k / LEGS % 6 {
                    0 => flip32(&mut leg.d0_mm[k % 3]),
                    1 => flip32(&mut leg.two_d0_xy_mm[k % 2]),
                    2 => flip32(&mut leg.d0z_sq_mm2),
                    3 => flip32(&mut leg.inv_two_d0z_per_mm),
                    4 => flip32(&mut leg.b_mm[k % 3]),
                    _ => flip32(&mut leg.rod_mm),
                }
            }),
            2 => self.r.ctl.upset(|a, _| match k % 3 {
                0 => flip64(&mut a.table.p0_mm[k % 3]),
                1 => flip64(&mut a.table.legs[k % LEGS].a_mm[k % 3]),
                _ => flip64(&mut a.table.stroke_limits.max_mm[k % LEGS]),
            }),
            3 => self.r.ctl.upset(|_, c| match k % 3 {
                0 => flip32(&mut c.following_fault_mm),
                1 => flip32(&mut c.jump_mm_per_cycle),
                _ => flip32(&mut c.following_warning_mm),
            }),
            4 => self.r.ctl.upset_ops(|o| match k % 3 {
                0 => flip32(&mut o.motion.max_speed_mm_per_s[k % LEGS]),
                1 => flip32(&mut o.motion.max_accel_mm_per_s2[k % LEGS]),
                _ => flip32(&mut o.direct.0),
            }),
            5 => self.r.ctl.upset_output_limits(k % 8, bit),
            _ => self
                .r
                .ctl
                .upset(|a, _| flip64(&mut a.table.workspace.translation_mm[k % 3])),
        }
    }

    /// Maintenance at rest: the plant's faults repaired, a drive that missed steps
    /// re-referenced (its count and setpoint shifted to where its slider is). What the
    /// drives hold changed without a command, so the continuity checks of the next cycle
    /// start from what they hold now (the 10-minute run flagged the first setpoint of a
    /// recovery move, correctly taken from the re-referenced drive, as a 74.7 um step
    /// from the count before the repair).
    fn repair(&mut self) {
        self.r.plant.with(|p| p.clear_faults());
        self.note("plant repaired".into());
        self.repaired = true;
        self.prev_drives = self.r.plant.with(|p| p.drive_setpoints_mm());
        self.prev_positions = self.r.plant.with(|p| p.drive_positions_mm());
    }

    fn inject_fault(&mut self) {
        let leg = self.below(6) as u8;
        let end = if self.below(2) == 0 {
            SwitchEnd::Lower
        } else {
            SwitchEnd::Upper
        };
        let f = match self.below(12) {
            0 => InjectedFault::EncoderNoResponse { leg },
            1 => InjectedFault::EncoderCorrupted { leg },
            2 => InjectedFault::EncoderJump {
                leg,
                jump_mm: self.rng.sym() * 0.5,
            },
            3 => InjectedFault::EncoderStuck { leg },
            4 => InjectedFault::MissedSteps {
                leg,
                lost_mm: self.rng.sym() * 0.1,
            },
            5 => InjectedFault::StuckSlider { leg },
            6 => InjectedFault::NoiseBurst {
                leg,
                sigma_mm: 0.05,
            },
            7 => InjectedFault::DriveFault { leg },
            8 => {
                // Into the path: up to 1 mm from where the slider is now, on the side
                // of the switch (already passed if the distance is small).
                let here = self.r.plant.with(|p| p.strokes_mm())[usize::from(leg)];
                let d = 1.0 * self.uniform() - 0.05;
                let at_mm = match end {
                    SwitchEnd::Lower => here - d,
                    SwitchEnd::Upper => here + d,
                };
                InjectedFault::SwitchMisadjusted { leg, end, at_mm }
            }
            9 => InjectedFault::SwitchStuckActive { leg, end },
            10 => InjectedFault::SwitchUnreadable { leg },
            _ => InjectedFault::EncoderWarning { leg },
        };
        self.faults_injected += 1;
        if matches!(f, InjectedFault::MissedSteps { .. }) {
            // The slip itself is the fault: its cycle is not a commanded motion.
            self.repaired = true;
        }
        self.note(format!("inject {f:?}"));
        self.r.plant.with(|p| p.inject(f));
    }

    /// A power cut now, or armed to strike inside the next flash write.
    fn power_cut(&mut self) {
        if self.below(2) == 0 {
            let steps = self.below(3000) as u64;
            let tear = if self.below(2) == 0 {
                TearMode::Clean
            } else {
                TearMode::TornByte
            };
            self.r.flash_mut().cut_power_after(steps, tear);
        } else {
            self.reboot();
        }
    }

    fn reboot(&mut self) {
        self.note("reboot".into());
        // Whatever was in flight dies with the controller; only the completed selection
        // (or the one being written) may run after the reboot.
        self.check_reports(true);
        self.moves.clear();
        let candidates = std::mem::take(&mut self.selecting);
        let in_writes = !self.r.flash_mut().is_powered();
        if in_writes {
            self.cuts_in_writes += 1;
        }
        let old = std::mem::take(&mut self.r);
        self.r = old.reboot();
        self.reboots += 1;
        self.in_flight.clear();
        self.log_seen = self.r.st.log.len();
        self.r.tick();
        self.cycles += 1;
        let running = TableRef {
            id: self.r.ctl.active_table().table_id,
            crc: self.r.ctl.active_table().crc32(),
        };
        if !self.known.contains_key(&running.crc) {
            self.violation(format!("booted an unknown table {running:?}"));
        }
        if running != self.selected {
            // A selection telecommand whose job may have persisted its record before the
            // reboot, its completion report not yet on the ground.
            let written = candidates
                .iter()
                .any(|(_, crc)| crc.is_none_or(|c| c == running.crc));
            if written {
                // The selection being written reached its commit point before the cut.
                self.selected = running;
            } else {
                self.violation(format!(
                    "booted {running:?}, the last completed selection was {:?}",
                    self.selected
                ));
            }
        }
        self.prev_cmd = self.r.ctl.strokes_commanded_mm();
        self.prev_truth = self.r.plant.with(|p| p.strokes_mm());
        self.prev_drives = self.r.plant.with(|p| p.drive_setpoints_mm());
        self.prev_positions = self.r.plant.with(|p| p.drive_positions_mm());
        self.prev_state = self.r.ctl.state();
        self.prev_moving_legs = self.r.ctl.housekeeping().moving_legs;
        self.prev_faulted = !self.r.ctl.faults().is_empty();
        self.tm_dropped_seen = 0;
        self.rest_cycles = 0;
        self.corrupt_since = None;
        self.read_step_limits();
        let _ = self.check_persisted_parameters();
        self.setting.clear();
    }

    /// Invariant 9: the parameters in flash are a set the operator's telecommands made:
    /// the one known persisted, or it with the sets in flight applied in order (each
    /// may or may not have been). What flash holds then becomes the one known.
    /// Returns whether it could check (not while a cut has struck: the reboot checks
    /// again once power is back, with the sets still in flight).
    fn check_persisted_parameters(&mut self) -> bool {
        use crate::controller::Parameters;
        if !self.r.flash_mut().is_powered() {
            return false;
        }
        let stored = self.r.worker.store_mut().persisted_parameters();
        let decoded = Parameters::decode(&stored).encode();
        // The running table as uploaded (the RAM copy may be upset).
        let crc = self.r.ctl.housekeeping().active_table_crc32;
        let table = self
            .known
            .get(&crc)
            .copied()
            .unwrap_or(*self.r.ctl.active_table());
        let mut allowed = vec![self.params_confirmed];
        for (_, pairs) in &self.setting {
            let grown: Vec<_> = allowed
                .iter()
                .filter_map(|b| Parameters::decode(b).with(pairs, &table).ok())
                .map(|p| p.encode())
                .collect();
            allowed.extend(grown);
        }
        if allowed.contains(&decoded) {
            self.params_confirmed = decoded;
        } else {
            self.violation(format!(
                "persisted parameters no telecommand made (an upset adopted?): {:?}",
                Parameters::decode(&stored)
            ));
        }
        true
    }

    /// Checks the report order of every telecommand in flight; retires finished ones.
    /// `dying`: the controller is about to reboot (incomplete reports are fine then).
    pub fn check_reports(&mut self, dying: bool) {
        let mut keep = Vec::new();
        let in_flight = std::mem::take(&mut self.in_flight);
        for (rid, from) in in_flight {
            let reps = self.r.st.reports_since(from, rid);
            let finished = match report_order(&reps) {
                Ok(f) => f,
                Err(e) => {
                    self.violation(format!("TC {rid:?}: {e}: {reps:?}"));
                    continue;
                }
            };
            if finished {
                self.tcs_done += 1;
                // A parameter set that completed is in force now (invariant 8's model),
                // and persisted (invariant 9 checks the flash).
                let set = self.setting.iter().position(|(r, _)| *r == rid);
                if let Some(k) = set.filter(|_| self.check_persisted_parameters()) {
                    self.setting.remove(k);
                    if reps.last() == Some(&Verification::CompletionSuccess) {
                        self.read_step_limits_from_model();
                    }
                }
                // A selection refused at start changed nothing; one that completed (or
                // failed after starting) is known from the events.
                self.selecting.retain(|(r, _)| *r != rid);
                if reps.last() == Some(&Verification::CompletionSuccess) {
                    self.completed += 1;
                }
            } else if !dying {
                keep.push((rid, from));
            }
        }
        self.in_flight = keep;
    }

    /// Invariant 11, in the cycle the station receives a coordinated move's completion
    /// success: every true slider within the in-position tolerance in force (and the
    /// encoder noise's sigma: the rule holds the mean reading) of the controller's
    /// setpoint, unless an encoder is made to lie or the controller is no longer idle (a
    /// fault since the completion holds the drives where they are: a new setpoint).
    fn check_moves_completed(&mut self) {
        if self.moves.is_empty() {
            return;
        }
        let moves = std::mem::take(&mut self.moves);
        for rid in moves {
            if !self.r.st.finished(rid) {
                self.moves.push(rid);
            } else if self.r.st.reports(rid).last() == Some(&Verification::CompletionSuccess) {
                self.check_in_position(rid);
            }
        }
    }

    fn check_in_position(&mut self, rid: RequestId) {
        let misleading = self.r.plant.with(|p| {
            p.faults().any(|f| {
                matches!(
                    f,
                    InjectedFault::EncoderStuck { .. }
                        | InjectedFault::EncoderJump { .. }
                        | InjectedFault::NoiseBurst { .. }
                )
            })
        });
        if misleading || self.r.ctl.state() != State::Idle {
            return;
        }
        self.moves_in_position += 1;
        let table = *self.r.ctl.active_table();
        let (tol_mm, _) = self.r.ctl.parameters().in_position(&table);
        let set = self.r.ctl.in_position_setpoint_mm();
        let truth = self.r.plant.with(|p| p.strokes_mm());
        for i in 0..LEGS {
            let e = truth[i] - f64::from(set[i]);
            if !(e.abs() <= f64::from(tol_mm) + crate::sim::plant::DEFAULT_ENCODER_NOISE_MM) {
                self.violation(format!(
                    "move {rid:?} completed with leg {} {:.4} um from its setpoint",
                    i + 1,
                    e * UM_PER_MM
                ));
            }
        }
    }

    /// The speed limits in force after a parameter set completed: what flash holds
    /// (invariant 9 checks it is a set the operator made), never the controller's RAM.
    fn read_step_limits_from_model(&mut self) {
        let stored = self.r.worker.store_mut().persisted_parameters();
        let l =
            crate::controller::Parameters::decode(&stored).step_limits(self.r.ctl.active_table());
        let dt = f64::from(CYCLE_S);
        self.step_limits_mm = (f64::from(l.coordinated.0) * dt, f64::from(l.direct.0) * dt);
    }

    /// The per-cycle invariants (module documentation).
    fn check_cycle(&mut self) {
        let c = self.r.ctl.strokes_commanded_mm();
        let state = self.r.ctl.state();
        let faulted = !self.r.ctl.faults().is_empty();
        let hk = self.r.ctl.housekeeping();
        // The running table as the operator uploaded it (the RAM copy may be upset).
        let limits = self
            .known
            .get(&hk.active_table_crc32)
            .map_or(self.r.ctl.active_table().stroke_limits, |t| t.stroke_limits);
        let truth = self.r.plant.with(|p| p.strokes_mm());
        let drives = self.r.plant.with(|p| p.drive_setpoints_mm());
        let skip = std::mem::take(&mut self.repaired);
        if let Some(n) = self.state_cycles.get_mut(usize::from(state.code())) {
            *n += 1;
        }
        // 1. Inside the limits: what is commanded and where the sliders are.
        for i in 0..LEGS {
            let (lo, hi) = (
                limits.min_mm[i] - LIMIT_TOL_MM,
                limits.max_mm[i] + LIMIT_TOL_MM,
            );
            let ci = f64::from(c[i]);
            if !(lo..=hi).contains(&ci) {
                self.violation(format!(
                    "leg {} commanded {ci} mm outside [{lo}, {hi}]",
                    i + 1
                ));
            }
            // The sliders: never taken outside, nor further outside, by the controller.
            // A slip (missed steps) can displace a slider at rest beyond a limit by
            // itself; the controller must then detect it (soft limit, following error)
            // and only bring it back, which the soak does not forbid. Found by the
            // 10-minute run: an 80 um slip at -4.93 mm put a slider 8 um beyond -5 mm,
            // detected 2 cycles later, and counted as a violation every cycle after.
            let t = truth[i];
            let outward = if t < lo {
                t < self.prev_truth[i] - STILL_MM
            } else {
                t > self.prev_truth[i] + STILL_MM
            };
            let was_inside = (lo..=hi).contains(&self.prev_truth[i]);
            if !(lo..=hi).contains(&t) && (outward || was_inside) && !skip {
                self.violation(format!("leg {} true stroke {t} mm outside", i + 1));
            }
        }
        // 2. Speed: no drive is commanded to a setpoint further than the speed limit
        //    times a cycle from its last one, unless to where it is (a hold), and the
        //    controller's commands are continuous: within a motion from cycle to cycle,
        //    and at its start from what the drives held.
        let step_limit = f64::from(DEFAULT_MAX_SPEED_MM_PER_S * CYCLE_S) + STEP_ROUNDING_MM;
        let moving = |s: State| matches!(s, State::Moving | State::Stopping | State::StrokeMoving);
        let positions = self.r.plant.with(|p| p.drive_positions_mm());
        for i in 0..LEGS {
            let d = (drives[i] - self.prev_drives[i]).abs();
            // A hold: the drive commanded to where it was (it cannot move by that).
            let hold = (drives[i] - self.prev_positions[i]).abs() <= STILL_MM;
            if d > step_limit && !hold && !skip {
                self.violation(format!(
                    "leg {} drive setpoint stepped {:.3} um in one cycle ({:?} -> {state:?})",
                    i + 1,
                    d * UM_PER_MM,
                    self.prev_state
                ));
            }
            // Continuous with the last command, or with what the drives held: a motion
            // that ended in a hold (faulted: the drives hold where they are, e.g. a
            // faulted drive that refused the commands) and a new one that started from
            // the held strokes in the same cycle.
            let from_drives = (f64::from(c[i]) - self.prev_drives[i]).abs();
            let d = if moving(self.prev_state) {
                (f64::from(c[i]) - f64::from(self.prev_cmd[i]))
                    .abs()
                    .min(from_drives)
            } else {
                from_drives
            };
            // Or a hold: commanded to where its drive is (a stop that came to rest with
            // a fault latched holds the drives where their sliders are; a jammed
            // slider's drive then steps back to it without moving anything, and a
            // recovery move may start from there in the same cycle).
            if moving(state) && d > step_limit && !hold {
                self.violation(format!(
                    "leg {} commanded step {:.3} um ({:?} -> {state:?})",
                    i + 1,
                    d * UM_PER_MM,
                    self.prev_state
                ));
            }
        }
        // 3. While faulted and at rest no slider moves (from the second cycle at rest:
        //    the drives take one cycle to reach the stop ramp's last setpoint).
        self.rest_cycles = if state == State::Faulted {
            self.rest_cycles.saturating_add(1)
        } else {
            0
        };
        //    The drives: a slider still settles on its drive train (a first-order tail
        //    after the last step), which the controller does not command.
        if self.rest_cycles > 2 && !skip {
            for i in 0..LEGS {
                if (positions[i] - self.prev_positions[i]).abs() > STILL_MM {
                    self.violation(format!(
                        "leg {} moved {:.6} um while faulted at rest",
                        i + 1,
                        (positions[i] - self.prev_positions[i]) * UM_PER_MM
                    ));
                }
            }
        }
        // 4. During a recovery move only its leg's drive setpoint changes; the others
        //    keep exactly theirs. Checked from the second cycle of the same move: a move
        //    may come to rest (its leg's last setpoint) and the next start in one cycle,
        //    the last step then belonging to the move that ended (invariant 2 bounds it).
        if state == State::StrokeMoving
            && self.prev_state == State::StrokeMoving
            && hk.moving_legs == self.prev_moving_legs
            && !skip
        {
            for i in (0..LEGS).filter(|i| hk.moving_legs & (1 << i) == 0) {
                if drives[i] != self.prev_drives[i] {
                    self.violation(format!(
                        "leg {} drive setpoint {} -> {} during a recovery move of legs {:#08b}",
                        i + 1,
                        self.prev_drives[i],
                        drives[i],
                        hk.moving_legs
                    ));
                }
            }
        }
        // 5. Nothing dropped.
        if hk.tm_dropped != self.tm_dropped_seen {
            self.tm_dropped_seen = hk.tm_dropped;
            self.violation(format!("{} telemetry records dropped", hk.tm_dropped));
        }
        // 7. Not toward an active switch: a blocked leg's command does not move toward
        //    it (a hold, where the drive's setpoint is its slider's position, is no move).
        let sw = self.r.ctl.switches();
        let (neg, pos) = (sw.blocked_negative(), sw.blocked_positive());
        if moving(state) && (neg | pos) != 0 {
            self.blocked_motion_cycles += 1;
        }
        for i in 0..LEGS {
            let bit = 1u8 << i;
            let d = f64::from(c[i]) - f64::from(self.prev_cmd[i]);
            // A hold: the drive commanded to where it was (it cannot move by that).
            let hold = (drives[i] - self.prev_positions[i]).abs() <= STILL_MM;
            let toward = (pos & bit != 0 && d > 0.0) || (neg & bit != 0 && d < 0.0);
            if toward && !hold && !skip {
                self.violation(format!(
                    "leg {} commanded {:+.6} um toward an active end-of-travel switch ({sw:?}, {:?} -> {state:?})",
                    i + 1,
                    d * UM_PER_MM,
                    self.prev_state
                ));
            }
        }
        // 8. The speed limit in force (the output stage's, whatever is upset): each
        //    command's step within the coordinated or the direct limit of the motion.
        if moving(state) && moving(self.prev_state) && !skip {
            // A set in flight may be in force before its completion reaches the model.
            let dt = f64::from(CYCLE_S);
            let in_flight = |id: u16| {
                self.setting
                    .iter()
                    .flat_map(|(_, pairs)| pairs.iter())
                    .filter(|(p, _)| *p == id)
                    .map(|(_, v)| f64::from(*v) / crate::units::NM_PER_MM * dt)
                    .fold(0.0, f64::max)
            };
            let coordinated = self.step_limits_mm.0.max(in_flight(0x0010));
            let direct = self.step_limits_mm.1.max(in_flight(0x0012));
            let limit = match state {
                State::StrokeMoving => direct,
                State::Moving => coordinated,
                _ => coordinated.max(direct),
            } + f64::from(crate::motion::limiter::STEP_TOLERANCE_MM);
            for i in 0..LEGS {
                // As in 2: from the last command, or from what the drive held (a motion
                // that ended in a hold and the next that began there in one cycle); a
                // hold itself is no step.
                let d = (f64::from(c[i]) - f64::from(self.prev_cmd[i]))
                    .abs()
                    .min((f64::from(c[i]) - self.prev_drives[i]).abs());
                let hold = (drives[i] - self.prev_positions[i]).abs() <= STILL_MM;
                if d > limit && !hold {
                    self.violation(format!(
                        "leg {} commanded step {:.4} um over the {:.4} um limit in force ({:?} -> {state:?})",
                        i + 1,
                        d * UM_PER_MM,
                        limit * UM_PER_MM,
                        self.prev_state
                    ));
                }
            }
        }
        // 10. A detected upset is repaired within REPAIR_CYCLES (detections and repairs
        //     are read from the telemetry by `track_selections`).
        if let Some(t) = self.corrupt_since {
            if self.cycles.saturating_sub(t) > REPAIR_CYCLES {
                self.violation(format!(
                    "an upset detected at cycle {t} (fault 0x100) not repaired"
                ));
                self.corrupt_since = None;
            }
        }
        // 6. Track completed selections from the telemetry.
        self.track_selections();
        self.prev_cmd = c;
        self.prev_truth = truth;
        self.prev_drives = drives;
        self.prev_positions = positions;
        self.prev_state = state;
        self.prev_moving_legs = hk.moving_legs;
        self.prev_faulted = faulted;
    }

    /// A completed activation is a TABLE_ACTIVATED event: that table is now the one to
    /// boot.
    fn track_selections(&mut self) {
        let new = self.r.st.log.len();
        for k in self.log_seen..new {
            if let Tm::Event(_, event::END_OF_TRAVEL, _) = self.r.st.log[k] {
                self.switch_trips += 1;
            }
            // Each detection (event 0x0002 naming 0x100 among the new faults) waits for
            // a repair (event 0x0013); the fault may stay latched until cleared.
            if let Tm::Event(_, event::FAULT_LATCHED, [_, new]) = self.r.st.log[k] {
                if new & crate::supervision::FaultFlags::TABLE_CORRUPT.bits() != 0
                    && self.corrupt_since.is_none()
                {
                    self.corrupt_since = Some(self.cycles);
                }
            }
            if let Tm::Event(_, event::TABLE_RELOADED, _) = self.r.st.log[k] {
                self.repairs += 1;
                self.corrupt_since = None;
            }
            // A boot reloads table and parameters from flash: that repairs an upset too.
            // (A detection sent just before a power cut is read after the cut, so the
            // reboot's own reset of the tracking is too early to see it: the 10-minute
            // run flagged one such upset, detected at cycle 167,917,652 and cut 2
            // cycles later, as never repaired.)
            if let Tm::Event(_, event::BOOT, _) = self.r.st.log[k] {
                self.corrupt_since = None;
            }
            if let Tm::Event(_, event::TABLE_ACTIVATED, [id, crc]) = self.r.st.log[k] {
                let t = TableRef { id, crc };
                if !self.known.contains_key(&crc) {
                    self.violation(format!("activated an unknown table {t:?}"));
                }
                self.selected = t;
            }
        }
        self.log_seen = new;
    }

    /// The figures so far.
    pub fn figures(&self) -> SoakFigures {
        SoakFigures {
            cycles: self.cycles,
            tcs_sent: self.tcs_sent,
            tcs_done: self.tcs_done,
            completed: self.completed,
            reboots: self.reboots,
            cuts_in_writes: self.cuts_in_writes,
            faults_injected: self.faults_injected,
            state_cycles: self.state_cycles,
            switch_trips: self.switch_trips,
            blocked_motion_cycles: self.blocked_motion_cycles,
            upsets: self.upsets,
            repairs: self.repairs,
            moves_in_position: self.moves_in_position,
            violations: self.violations.len() as u64,
        }
    }

    /// Every violation found, in order.
    pub fn violations(&self) -> &[String] {
        &self.violations
    }

    /// The decision source is exhausted (a fuzz input consumed).
    pub fn is_exhausted(&self) -> bool {
        self.rng.exhausted()
    }

    /// Telecommands whose reports are still incomplete.
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// Time passing (up to `max_gap` cycles, chosen), then one action.
    pub fn round(&mut self, max_gap: usize) {
        let gap = 1 + self.below(max_gap);
        for _ in 0..gap {
            self.step();
        }
        self.act();
    }

    /// Lets the telecommands in flight finish (`cycles` cycles), then checks them.
    pub fn drain(&mut self, cycles: u32) {
        for _ in 0..cycles {
            self.step();
        }
        self.check_reports(false);
    }

    /// One control cycle, checked; a reboot if the power failed.
    pub fn step(&mut self) {
        if !self.r.flash_mut().is_powered() {
            // The cut struck inside a flash write: the whole controller loses power.
            self.reboot();
            return;
        }
        self.r.tick();
        self.cycles += 1;
        self.check_cycle();
        self.check_moves_completed();
        if self.cycles % 64 == 0 {
            self.check_reports(false);
        }
    }
}

/// A valid service-1 sequence (all acknowledgements requested): `[1,2]`, or `[1,1]` then
/// `[1,4]`, or `[1,1] [1,3]` then `[1,7]` or `[1,8]`; a prefix of one while in flight.
/// Returns whether it is complete.
fn report_order(reps: &[Verification]) -> Result<bool, &'static str> {
    use Verification::*;
    Ok(match reps {
        [] => false,
        [AcceptanceFailure { .. }] => true,
        [AcceptanceSuccess] => false,
        [AcceptanceSuccess, StartFailure { .. }] => true,
        [AcceptanceSuccess, StartSuccess] => false,
        [AcceptanceSuccess, StartSuccess, CompletionSuccess | CompletionFailure { .. }] => true,
        _ => return Err("reports out of order or duplicated"),
    })
}
