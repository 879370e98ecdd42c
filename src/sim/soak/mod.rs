//! The model-based soak: the real controller, link service and worker on the bench,
//! driven by a long seeded random sequence of valid and invalid telecommands, plant
//! faults and repairs, and power cuts (also in the middle of flash writes), with the
//! operator contract checked **every cycle**:
//!
//! 1. commanded strokes stay inside the running table's stroke limits (outside them, only
//!    a hold where a drive stands or a command back toward them: a slip can carry a
//!    slider out), and no slider is taken outside them (or further outside, after a slip
//!    displaced it) by the controller;
//! 2. no commanded stroke changes by more than the speed limit times a cycle (plus
//!    rounding) from the last command or from what the drives held, whatever the
//!    sequence;
//! 3. while a fault is latched nothing moves except a stop ramp and the recovery move's
//!    own leg (the drives: a slider may still settle on its drive train);
//! 4. during a recovery move the other legs keep their setpoints (to the f32 rounding of
//!    a stroke, which a real drive's microsteps cannot see);
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
//!     while an encoder is made to lie: stuck, offset or noisier than specified, nor
//!     once a compensation step has begun since the completion);
//! 12. the thermal compensation's applied offset never changes by more than the largest
//!     step any parameter allows (`thermal::compensation::MAX_STEP_HIGHEST_MM`) in a
//!     cycle, across enables, disables, sensor failures and recoveries, power cuts and
//!     upsets (invariant 2 bounds what the drives do with it);
//! 13. during an exposure hold (telecommand or discrete input) the applied offset does
//!     not change, no scheduled activity is released and no operator motion starts;
//! 14. a mirror put in position stays there: from a completion invariant 11 found in
//!     position, while the controller stays idle, unfaulted, with no plant fault and its
//!     setpoint unchanged, no true slider stands further from its setpoint and applied
//!     offset than the last compensation step, twice the in-position tolerance and the
//!     encoder noise's sigma, across compensation steps, upsets, table activations,
//!     parameter sets and exposure holds.
//!
//! The plant's parts swing from +1 to +5 K over a 10-minute orbit with a 2 K gradient, its
//! sensors fail and recover at random; the tables the soak uploads carry the thermal
//! model, and the operator enables and disables the compensation, holds exposures by
//! telecommand and by the discrete input, and schedules moves.
//!
//! The plant has the realistic drive train (`sim::drive_train`: microsteps, backlash,
//! lead error, stiction, settling). One coordinated move in two sent while the
//! controller is idle is let run to its end with no other action ([`WATCH_ONE_IN`]), so
//! that moves complete and invariant 11 checks them (330 to 420 per 20 s run; the
//! figures' `moves_in_position`); the fuzzer's inputs do not wait
//! ([`Choices::watches_moves`]).
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
//!
//! The parts, one job each:
//! * this file: the [`Soak`] itself (bench, model state, counters) and its driver
//!   (`round`, `step`, `drain`);
//! * [`choices`]: where the decisions come from (seeded generator or fuzz bytes);
//! * `actions`: the random operator actions (telecommands, valid and invalid);
//! * `injection`: the adversary (RAM upsets, plant faults and their repair, power cuts
//!   and the reboot they cause);
//! * `invariants`: the checks run every cycle (invariants 1 to 5, 7, 8, 10 to 14);
//! * `model`: what the operator may expect of flash (the table to boot, invariant 6;
//!   the persisted parameters, invariant 9; the speed limits in force);
//! * `verification`: every telecommand's service-1 reports (invariant 5);
//! * `report`: the figures, the violations with the history that led to them (to
//!   replay a run to a violation).

#![allow(clippy::needless_range_loop)] // index loops over six legs read clearer here

mod actions;
pub mod choices;
mod injection;
mod invariants;
mod model;
mod report;
mod verification;

use std::collections::HashMap;

use crate::controller::State;
use crate::kinematics::LEGS;
use crate::link::RequestId;
use crate::nominal::PROTOTYPE;
use crate::sim::bench::UART_115200_BYTES_PER_CYCLE;
use crate::sim::drive_train::DriveTrainConfig;
use crate::sim::thermal::{Coefficients, Profile, SensorConfig, Swing, ThermalConfig};
use crate::sim::{Bench, BenchConfig, Plant, PlantConfig};
use crate::table::mock_flash::MockFlash;
use crate::table::Table;

pub use actions::calibrated_table;
pub use choices::{ByteChoices, Choices, SeededChoices};
pub use invariants::REPAIR_CYCLES;
use model::TableRef;
pub use report::SoakFigures;

/// One coordinated move in this many sent while the controller is idle is watched: the
/// soak lets it run to its end (no other action, no fault, no cut) so that it completes
/// and invariant 11 checks it. Without this a move (seconds long, actions every 0.15 s
/// on average) almost never completed: 1 to 3 per 20 s run were checked.
pub const WATCH_ONE_IN: usize = 2;
/// Longest watch (cycles, 60 s): a 2.6 mm stroke at the slowest speed the soak sets
/// (0.05 mm/s) is 52 s; a watched move that dies in a reboot ends its watch at once.
pub const WATCH_CYCLES: u32 = 60_000;

/// Longest rest after a watched move (cycles, 5 s; chosen below it): with no action,
/// the compensation, when enabled, steps the mirror it put in position (invariant 14).
/// Without it a run saw 0 or 1 such step.
pub const WATCH_REST_CYCLES: usize = 5_000;

/// The soak plant's mean temperature above the tables' reference (K): a power cut
/// rebuilds the plant at the start of its orbit, so the swing alone would keep it near
/// the reference; with this the compensation has offsets to follow from every boot.
const MEAN_OFFSET_K: f64 = 3.0;
/// ... its uniform swing about that mean (K, amplitude): from +1 to +5 K, within issue
/// 22's +-5 K.
const SWING_K: f64 = 2.0;
/// ... its period (s): an orbit shortened to 10 minutes so a 20 s run sees it move.
const ORBIT_S: f64 = 600.0;
/// ... and its gradient across the base (K): issue 22's 2 K.
const GRADIENT_K: f64 = 2.0;

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
    /// The coordinated moves sent, until their reports end (invariant 11), each with the
    /// station log's length when it was sent.
    moves: Vec<(RequestId, usize)>,
    /// Moves invariant 11 checked.
    moves_in_position: u64,
    /// The move being watched: no action until its reports end ([`Soak::round`]).
    watching: Option<(RequestId, usize)>,
    /// Moves watched.
    moves_watched: u64,
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
    /// The applied compensation offset after the last cycle (invariant 12).
    prev_applied: [f32; LEGS],
    /// An exposure hold was in force after the last cycle (invariant 13).
    prev_hold: bool,
    /// Activities released since boot after the last cycle (housekeeping's count).
    prev_released: u16,
    /// Cycles the applied offset changed (compensation steps).
    thermal_steps: u64,
    /// Cycles an exposure hold was in force.
    hold_cycles: u64,
    /// Operator moves refused by a hold (0x0710).
    hold_refusals: u64,
    /// When the camera's discrete input, raised, falls again (cycle).
    input_release_at: Option<u64>,
    /// A mirror put in position, watched while idle (invariant 14).
    placed: Option<invariants::Placed>,
    /// Placements invariant 14 watched.
    placements: u64,
    /// Cycles invariant 14 checked.
    placed_cycles: u64,
    /// Compensation steps within them.
    placed_steps: u64,
    /// The furthest a watched slider stood beyond the last step (mm).
    placed_worst_mm: f64,
    /// Legs that slipped (missed steps) and have not been commanded since: their
    /// sliders still drift with the slip (invariant 1).
    slipped: u8,
}

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
    .unwrap()
    .with_thermal(ThermalConfig {
        profile: Profile {
            mean_c: crate::sim::thermal::REFERENCE_C + MEAN_OFFSET_K,
            swing: Swing::Sine {
                amplitude_k: SWING_K,
                period_s: ORBIT_S,
            },
            gradient_k: GRADIENT_K,
            gradient_angle_rad: 0.4,
            ..Profile::REFERENCE
        },
        truth: Coefficients::NOMINAL,
        sensors: SensorConfig::drawn(5),
    })
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
            watching: None,
            moves_watched: 0,
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
            prev_applied: [0.0; LEGS],
            prev_hold: false,
            prev_released: 0,
            thermal_steps: 0,
            hold_cycles: 0,
            hold_refusals: 0,
            input_release_at: None,
            placed: None,
            placements: 0,
            placed_cycles: 0,
            placed_steps: 0,
            placed_worst_mm: 0.0,
            slipped: 0,
        }
        .with_limits_from_controller()
    }

    /// The speed limits in force, read from the controller (at boot: nothing upset yet).
    fn with_limits_from_controller(mut self) -> Self {
        self.read_step_limits();
        self
    }

    fn uniform(&mut self) -> f64 {
        (self.rng.sym() + 1.0) / 2.0
    }

    /// A choice in 0..n.
    pub fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n - 1)
    }

    /// Control cycles run so far.
    pub fn cycles(&self) -> u64 {
        self.cycles
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

    /// Time passing (up to `max_gap` cycles, chosen), then one action. While a move is
    /// watched ([`WATCH_ONE_IN`]), time passes first, with no action, until its reports
    /// end (at most [`WATCH_CYCLES`]).
    pub fn round(&mut self, max_gap: usize) {
        let mut watched = 0;
        while let Some((rid, from)) = self.watching {
            if self.r.st.finished_since(from, rid) || watched >= WATCH_CYCLES {
                self.watching = None;
                // The mirror it put in position then rests a while (invariant 14 with
                // the compensation stepping, when enabled).
                for _ in 0..self.below(WATCH_REST_CYCLES) {
                    self.step();
                }
            } else {
                self.step();
                watched += 1;
            }
        }
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
        if self.input_release_at.is_some_and(|t| self.cycles >= t) {
            self.input_release_at = None;
            self.r.plant.with(|p| p.set_exposing(false));
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
