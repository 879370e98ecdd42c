//! The per-cycle supervisor: raw conditions, debouncing, latching, clearing.
//!
//! ## Cycle contract
//!
//! Once per control cycle, after reading the encoders and running FK, before stepping the
//! motion, the controller calls [`Supervisor::check`] with [`CycleInputs`]. Cycle `c` below
//! is the call's index; a condition "present at `c`" is one the inputs of call `c` show.
//!
//! ## Conditions and detection latency
//!
//! With debounce `N` (consecutive cycles, 0 treated as 1), a condition present from cycle
//! `c0` on is reported in the [`Verdict`] of cycle **`c0 + N - 1`** (same cycle for
//! `N = 1`). With the defaults ([`super::SupervisionConfig::from_table`] of the nominal
//! table):
//!
//! | flag | condition at cycle c | N (default) | latency |
//! |---|---|---|---|
//! | `ENCODER_READ_FAILURE` | read `Err` (no response, corrupted frame, or the encoder's own error bit: `SelfCheckFailed`), or a non-finite stroke (that leg) | 1 | c0 |
//! | `ENCODER_JUMP` | `|m_c - m_prev| > jump_mm_per_cycle * cycles since m_prev` | 1 | c0 |
//! | `DRIVE_FAULT` | `drive` is `Err` (result of the last command) | 1 | c0 |
//! | `FOLLOWING_WARNING` | `|m_c - commanded_prev| > following_warning_mm` | 5 | c0 + 4 |
//! | `FOLLOWING_ERROR` | `|m_c - commanded_prev| > following_fault_mm` | 3 | c0 + 2 |
//! | `SOFT_LIMIT` | `m_c` beyond `[soft_min, soft_max]` by > tolerance | 3 | c0 + 2 |
//! | `FK_NOT_CONVERGED` | `fk` is `Some(Err)` | 3 | c0 + 2 |
//! | `POSE_OUTSIDE_WORKSPACE` | FK pose axis beyond half-range by > tolerance | 3 | c0 + 2 |
//! | `ENCODER_STUCK` | see below | 1 | a + W |
//! | `LIMIT_SWITCH` | `switches.end_of_travel() != 0`: an end-of-travel switch active, or a switch input unreadable (that leg) | 1 (fixed) | c0 |
//! | `ENCODER_WARNING` (warning) | `encoder_warning_legs != 0`: the encoder's own warning bit (that leg) | 1 (fixed) | c0 |
//!
//! Stuck: while motion is commanded, each slider keeps an anchor (reading and commanded
//! stroke) that moves whenever the reading has progressed `stuck_min_progress_mm` from
//! it. The condition is present when `W = stuck_window_cycles` readings have passed since
//! the anchor (set at cycle `a`) without such progress, and the commanded stroke has moved
//! at least `stuck_min_commanded_mm` from the anchor's. Detection at `a + W` (default
//! W = 200): for a slider frozen at cycle `f`, `a` is the last cycle before `f` at which
//! the reading progressed (at most `stuck_min_progress_mm / speed` cycles before `f`).
//! Anchors are reset whenever motion is not commanded.
//!
//! End of travel: the switches are a hardware input, not a measurement; there is nothing
//! to filter, so `LIMIT_SWITCH` latches in the cycle a switch is first seen (the
//! controller has already kept that cycle's drive command from moving the leg further
//! toward it) and cannot be cleared while any switch is active or unreadable. The
//! reference sensors are information only and never raise anything.
//!
//! Checks that cannot be evaluated in a cycle (no encoder reading: following, jump, soft
//! limit, stuck; no FK: FK and workspace) keep their debounce counts unchanged: a missed
//! reading neither confirms nor clears a condition.
//!
//! ## Latching and clearing
//!
//! A fault, once raised, stays in [`Supervisor::latched`] (the controller stops and refuses
//! moves) until [`Supervisor::clear`], which succeeds only if none of the latched faults'
//! conditions was present — or unverifiable — in the most recent `check`. Warnings are
//! never latched: [`Verdict::warnings`] lists those present (after debounce) this cycle.
//!
//! Cost: a few hundred Cortex-M4 instructions (six legs times a few comparisons, no
//! division, no square root).

use super::config::SupervisionConfig;
use super::flags::FaultFlags;
use crate::hw::{DriveError, EncoderError, TravelSwitches};
use crate::kinematics::{FkError, FkSolution, LEGS};

/// What the controller knows at the supervision point of one control cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CycleInputs {
    /// The six encoder strokes read this cycle (mm, along base z, 0 at home), or why not.
    pub encoders: Result<[f32; LEGS], EncoderError>,
    /// The strokes commanded in the previous cycle (mm): the setpoint the drives were
    /// following when the encoders were read. This cycle's setpoint does not exist yet
    /// at this point of the cycle (motion is stepped after supervision).
    pub commanded_prev_mm: [f32; LEGS],
    /// A move (trajectory, stop ramp or direct-stroke move) was commanding motion in the
    /// previous cycle (`Setpoint::moving`); false while holding.
    pub motion_commanded: bool,
    /// Forward kinematics of this cycle's readings, `None` if not run (no reading).
    pub fk: Option<Result<FkSolution<f32>, FkError>>,
    /// Result of the previous cycle's drive command.
    pub drive: Result<(), DriveError>,
    /// The end-of-travel switches and reference sensors, read this cycle right after the
    /// encoders ([`crate::hw::EndOfTravel::read_switches`]).
    pub switches: TravelSwitches,
    /// Legs (bit i = leg i+1) whose encoder flagged its warning bit in this cycle's read
    /// ([`crate::hw::EncoderWarnings::warning_legs`]).
    pub encoder_warning_legs: u8,
}

/// The supervisor's answer for one cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Verdict {
    /// Warnings present this cycle, after debounce (not latched).
    pub warnings: FaultFlags,
    /// Legs (bit i = leg i+1) of the warnings.
    pub warning_legs: u8,
    /// Faults latched by this cycle (not latched before).
    pub new_faults: FaultFlags,
    /// Legs (bit i = leg i+1) of the new faults (0 for pose-level faults).
    pub new_fault_legs: u8,
    /// Every latched fault after this cycle.
    pub latched: FaultFlags,
}

impl Verdict {
    /// A fault is latched: the controller must stop and refuse moves.
    pub fn must_stop(&self) -> bool {
        !self.latched.is_empty()
    }
}

/// Per-leg debounce counters of one check.
type LegCounts = [u16; LEGS];

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Counters {
    following_warning: LegCounts,
    following_fault: LegCounts,
    stuck: LegCounts,
    jump: LegCounts,
    read_failure: LegCounts,
    soft_limit: LegCounts,
    drive: LegCounts,
    fk: u16,
    workspace: u16,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct StuckState {
    anchored: bool,
    anchor_measured_mm: [f32; LEGS],
    anchor_commanded_mm: [f32; LEGS],
    readings_since_anchor: [u16; LEGS],
}

/// Per-cycle encoder supervision with debouncing and latching (see the module
/// documentation for conditions, latencies and the clearing rule).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Supervisor {
    cfg: SupervisionConfig,
    counts: Counters,
    stuck: StuckState,
    /// Last valid reading and the cycles since it (for the jump check).
    last_measured_mm: Option<[f32; LEGS]>,
    cycles_since_measured: u16,
    latched: FaultFlags,
    /// Legs per latched fault bit (index = bit).
    latched_legs: [u8; FaultFlags::FAULT_BITS],
    /// Raw fault conditions present in the last check (before debounce).
    present: FaultFlags,
    /// Fault checks that could not be evaluated in the last check.
    unverified: FaultFlags,
    /// Conditions of faults raised outside the per-cycle checks (RAM scrub, deadline):
    /// present until their owner says they are gone.
    external_present: FaultFlags,
}

/// What one check pass found.
#[derive(Default)]
struct Tally {
    /// Raw conditions present.
    present: FaultFlags,
    /// Faults raised (debounced).
    raised: FaultFlags,
    /// Legs per raised fault bit.
    legs: [u8; FaultFlags::FAULT_BITS],
}

impl Tally {
    /// Records a per-leg check: `cond` and `raised_legs` are leg masks, `bit` the flag's
    /// bit position. Not inlined: six checks call it (24 bytes of flash less).
    #[inline(never)]
    fn record(&mut self, flag: FaultFlags, cond: u8, raised_legs: u8, bit: usize) {
        self.present.set(flag, cond != 0);
        if raised_legs != 0 {
            self.raised |= flag;
            if let Some(l) = self.legs.get_mut(bit) {
                *l |= raised_legs;
            }
        }
    }
}

/// Advances one debounce counter; true when the condition has persisted `n` cycles.
fn debounce(count: &mut u16, condition: bool, n: u16) -> bool {
    if condition {
        *count = count.saturating_add(1);
        *count >= n.max(1)
    } else {
        *count = 0;
        false
    }
}

/// Per-leg debounce: `conditions` is a leg mask; returns the mask of legs raised.
fn debounce_legs(counts: &mut LegCounts, conditions: u8, n: u16) -> u8 {
    let mut raised = 0u8;
    for (i, c) in counts.iter_mut().enumerate() {
        let bit = 1u8 << i;
        if debounce(c, conditions & bit != 0, n) {
            raised |= bit;
        }
    }
    raised
}

/// Bit position of [`FaultFlags::LIMIT_SWITCH`] (index of its recorded legs).
const LIMIT_SWITCH_BIT: usize = FaultFlags::LIMIT_SWITCH.bits().trailing_zeros() as usize;

/// Every leg (bits 0..5): the leg mask of telemetry.
pub const ALL_LEGS: u8 = (1u8 << LEGS) - 1;

/// The leg mask of a 0-based leg index from a hardware error; an index out of range
/// blames every leg (the failure must not go unreported).
fn leg_bit(leg: u8) -> u8 {
    if usize::from(leg) < LEGS {
        1u8 << leg
    } else {
        ALL_LEGS
    }
}

/// Per-leg debounce, or, when `hold` (check not evaluable), counters unchanged and the
/// legs already beyond the debounce count.
fn hold_or_debounce(counts: &mut LegCounts, conditions: u8, hold: bool, n: u16) -> u8 {
    if hold {
        // Held: raised only if already beyond the debounce count.
        let mut raised = 0u8;
        for (i, c) in counts.iter().enumerate() {
            if *c >= n.max(1) {
                raised |= 1u8 << i;
            }
        }
        raised
    } else {
        debounce_legs(counts, conditions, n)
    }
}

impl Supervisor {
    /// A supervisor with no fault latched and no history.
    pub fn new(cfg: SupervisionConfig) -> Self {
        Self {
            cfg,
            counts: Counters::default(),
            stuck: StuckState::default(),
            last_measured_mm: None,
            cycles_since_measured: 0,
            latched: FaultFlags::empty(),
            latched_legs: [0; FaultFlags::FAULT_BITS],
            present: FaultFlags::empty(),
            unverified: FaultFlags::empty(),
            external_present: FaultFlags::empty(),
        }
    }

    /// Latches a fault found outside the per-cycle checks (e.g. the RAM scrub), with
    /// its condition present (`present`) until [`Supervisor::set_external_condition`]
    /// says it is gone. Returns whether it was newly latched.
    pub fn raise_external(&mut self, flag: FaultFlags, present: bool) -> bool {
        let new = !self.latched.contains(flag);
        self.latched |= flag;
        self.external_present.set(flag, present);
        new
    }

    /// [`Supervisor::raise_external`] of a fault that names `legs` (bit i = leg i+1;
    /// housekeeping `fault_legs`), its condition gone at once (clearable at rest).
    pub fn raise_external_on(&mut self, flag: FaultFlags, legs: u8) -> bool {
        let new = self.raise_external(flag, false);
        let bit = flag.bits().trailing_zeros() as usize;
        if let Some(l) = self.latched_legs.get_mut(bit) {
            *l |= legs;
        }
        new
    }

    /// Whether the condition of an externally raised fault is still present (a latched
    /// fault can only be cleared once it is not).
    pub fn set_external_condition(&mut self, flag: FaultFlags, present: bool) {
        self.external_present.set(flag, present);
    }

    /// The configuration in use.
    pub fn config(&self) -> &SupervisionConfig {
        &self.cfg
    }

    /// Replaces the configuration (e.g. a new table activated); keeps latches and history.
    pub fn set_config(&mut self, cfg: SupervisionConfig) {
        self.cfg = cfg;
    }

    /// The latched faults.
    pub fn latched(&self) -> FaultFlags {
        self.latched
    }

    /// The legs (bit i = leg i+1) recorded with any of the latched faults in `flags`.
    pub fn latched_legs(&self, flags: FaultFlags) -> u8 {
        let mut legs = 0u8;
        for (bit, l) in self.latched_legs.iter().enumerate() {
            if flags.bits() & self.latched.bits() & (1u32 << bit) != 0 {
                legs |= *l;
            }
        }
        legs
    }

    /// Fault conditions present (before debounce) in the last check, and those of
    /// externally raised faults.
    pub fn present(&self) -> FaultFlags {
        self.present | self.external_present
    }

    /// True when no latched fault's condition was present or unverifiable in the last
    /// check: a clear telecommand may be accepted.
    pub fn can_clear(&self) -> bool {
        self.blocking().is_empty()
    }

    /// Latched faults that prevent clearing (condition present or unverifiable).
    pub fn blocking(&self) -> FaultFlags {
        self.latched & (self.present | self.unverified | self.external_present)
    }

    /// Clears every latch if [`Supervisor::can_clear`]; otherwise changes nothing and
    /// returns the blocking faults. Debounce counts and stuck windows restart.
    pub fn clear(&mut self) -> Result<(), FaultFlags> {
        let blocking = self.blocking();
        if !blocking.is_empty() {
            return Err(blocking);
        }
        self.latched = FaultFlags::empty();
        self.latched_legs = [0; FaultFlags::FAULT_BITS];
        self.counts = Counters::default();
        self.stuck = StuckState::default();
        Ok(())
    }

    /// Evaluates one control cycle (see the module documentation).
    pub fn check(&mut self, inp: &CycleInputs) -> Verdict {
        let cfg = self.cfg;
        let db = cfg.debounce;
        let mut t = Tally::default();
        let mut unverified = FaultFlags::empty();
        let mut warnings = FaultFlags::empty();
        let mut warning_legs = 0u8;

        // --- Encoder read --------------------------------------------------------------
        let (read_fail_legs, measured) = match &inp.encoders {
            // No answer, a corrupted frame, or an intact frame whose error bit says the
            // encoder's own check failed (`SelfCheckFailed`): no trustworthy reading of
            // that leg this cycle, so all three are a read failure of that leg.
            Err(EncoderError::NoResponse { leg })
            | Err(EncoderError::Corrupted { leg })
            | Err(EncoderError::SelfCheckFailed { leg }) => (leg_bit(*leg), None),
            Ok(m) => {
                let mut bad = 0u8;
                for (i, v) in m.iter().enumerate() {
                    if !v.is_finite() {
                        bad |= 1u8 << i;
                    }
                }
                (bad, if bad == 0 { Some(*m) } else { None })
            }
        };
        let read_failed = measured.is_none();
        let read_raised = debounce_legs(
            &mut self.counts.read_failure,
            read_fail_legs,
            db.read_failure,
        );
        t.record(
            FaultFlags::ENCODER_READ_FAILURE,
            read_fail_legs,
            read_raised,
            3,
        );

        // --- Checks on the readings ----------------------------------------------------
        let mut jump_cond = 0u8;
        let mut warn_cond = 0u8;
        let mut fault_cond = 0u8;
        let mut soft_cond = 0u8;
        let mut stuck_cond = 0u8;
        if let Some(m) = measured {
            let gap = f32::from(self.cycles_since_measured.max(1));
            for (i, ((((mi, ci), lo), hi), last)) in m
                .iter()
                .zip(inp.commanded_prev_mm.iter())
                .zip(cfg.soft_min_mm.iter())
                .zip(cfg.soft_max_mm.iter())
                .zip(self.last_measured_mm.unwrap_or(m).iter())
                .enumerate()
            {
                let bit = 1u8 << i;
                // `!(x <= t)` also flags NaN.
                if !((*mi - *last).abs() <= cfg.jump_mm_per_cycle * gap) {
                    jump_cond |= bit;
                }
                let e = (*mi - *ci).abs();
                if !(e <= cfg.following_warning_mm) {
                    warn_cond |= bit;
                }
                if !(e <= cfg.following_fault_mm) {
                    fault_cond |= bit;
                }
                let tol = cfg.soft_limit_tolerance_mm;
                if *mi < *lo - tol || *mi > *hi + tol {
                    soft_cond |= bit;
                }
            }
            self.last_measured_mm = Some(m);
            self.cycles_since_measured = 1;
            stuck_cond = self.update_stuck(&m, inp);
        } else {
            self.cycles_since_measured = self.cycles_since_measured.saturating_add(1);
            unverified |= FaultFlags::ENCODER_JUMP
                | FaultFlags::FOLLOWING_ERROR
                | FaultFlags::SOFT_LIMIT
                | FaultFlags::ENCODER_STUCK;
        }
        let hold = read_failed;
        let c = &mut self.counts;
        let jump_raised = hold_or_debounce(&mut c.jump, jump_cond, hold, db.jump);
        t.record(FaultFlags::ENCODER_JUMP, jump_cond, jump_raised, 2);
        let fault_raised =
            hold_or_debounce(&mut c.following_fault, fault_cond, hold, db.following_fault);
        t.record(FaultFlags::FOLLOWING_ERROR, fault_cond, fault_raised, 0);
        let soft_raised = hold_or_debounce(&mut c.soft_limit, soft_cond, hold, db.soft_limit);
        t.record(FaultFlags::SOFT_LIMIT, soft_cond, soft_raised, 4);
        let stuck_raised = hold_or_debounce(&mut c.stuck, stuck_cond, hold, db.stuck);
        t.record(FaultFlags::ENCODER_STUCK, stuck_cond, stuck_raised, 1);
        let warn_raised = hold_or_debounce(
            &mut c.following_warning,
            warn_cond,
            hold,
            db.following_warning,
        );
        if warn_raised != 0 {
            warnings |= FaultFlags::FOLLOWING_WARNING;
            warning_legs |= warn_raised;
        }

        // --- Pose ------------------------------------------------------------------------
        match &inp.fk {
            None => {
                unverified |= FaultFlags::FK_NOT_CONVERGED | FaultFlags::POSE_OUTSIDE_WORKSPACE;
                if c.fk >= db.fk.max(1) {
                    t.raised |= FaultFlags::FK_NOT_CONVERGED;
                }
                if c.workspace >= db.workspace.max(1) {
                    t.raised |= FaultFlags::POSE_OUTSIDE_WORKSPACE;
                }
            }
            Some(Err(_)) => {
                t.present |= FaultFlags::FK_NOT_CONVERGED;
                unverified |= FaultFlags::POSE_OUTSIDE_WORKSPACE;
                if debounce(&mut c.fk, true, db.fk) {
                    t.raised |= FaultFlags::FK_NOT_CONVERGED;
                }
                if c.workspace >= db.workspace.max(1) {
                    t.raised |= FaultFlags::POSE_OUTSIDE_WORKSPACE;
                }
            }
            Some(Ok(sol)) => {
                debounce(&mut c.fk, false, db.fk);
                let mut outside = false;
                for (v, lim) in sol
                    .pose
                    .translation_mm
                    .iter()
                    .zip(cfg.workspace_translation_mm.iter())
                {
                    outside |= !(v.abs() <= *lim + cfg.workspace_tolerance_mm);
                }
                for (v, lim) in sol
                    .pose
                    .rotation_rad
                    .iter()
                    .zip(cfg.workspace_rotation_rad.iter())
                {
                    outside |= !(v.abs() <= *lim + cfg.workspace_tolerance_rad);
                }
                t.present.set(FaultFlags::POSE_OUTSIDE_WORKSPACE, outside);
                if debounce(&mut c.workspace, outside, db.workspace) {
                    t.raised |= FaultFlags::POSE_OUTSIDE_WORKSPACE;
                }
            }
        }

        // --- Drives ------------------------------------------------------------------------
        let drive_cond = match &inp.drive {
            Ok(()) => 0u8,
            Err(DriveError::DriveFault { leg }) => leg_bit(*leg),
        };
        let drive_raised = debounce_legs(&mut c.drive, drive_cond, db.drive);
        t.record(FaultFlags::DRIVE_FAULT, drive_cond, drive_raised, 7);

        // --- End of travel, encoder warnings ---------------------------------------------
        // A switch is a hardware input: latched in the cycle it is seen (N = 1).
        let eot_cond = inp.switches.end_of_travel() & ALL_LEGS;
        t.record(
            FaultFlags::LIMIT_SWITCH,
            eot_cond,
            eot_cond,
            LIMIT_SWITCH_BIT,
        );
        let enc_warn = inp.encoder_warning_legs & ALL_LEGS;
        if enc_warn != 0 {
            warnings |= FaultFlags::ENCODER_WARNING;
            warning_legs |= enc_warn;
        }

        // --- Latch -----------------------------------------------------------------------------
        let new_faults = t.raised.difference(self.latched);
        let mut new_fault_legs = 0u8;
        for (bit, (l, latched_l)) in t.legs.iter().zip(self.latched_legs.iter_mut()).enumerate() {
            if new_faults.bits() & (1u32 << bit) != 0 {
                *latched_l |= *l;
                new_fault_legs |= *l;
            }
        }
        self.latched |= new_faults;
        self.present = t.present;
        self.unverified = unverified;
        Verdict {
            warnings,
            warning_legs,
            new_faults,
            new_fault_legs,
            latched: self.latched,
        }
    }

    /// Updates the stuck anchors with a valid reading; returns the legs whose stuck
    /// condition is present.
    fn update_stuck(&mut self, m: &[f32; LEGS], inp: &CycleInputs) -> u8 {
        let st = &mut self.stuck;
        if !inp.motion_commanded || !st.anchored {
            st.anchored = inp.motion_commanded;
            st.anchor_measured_mm = *m;
            st.anchor_commanded_mm = inp.commanded_prev_mm;
            st.readings_since_anchor = [0; LEGS];
            return 0;
        }
        let cfg = &self.cfg;
        let mut cond = 0u8;
        for (i, ((((am, ac), n), mi), ci)) in st
            .anchor_measured_mm
            .iter_mut()
            .zip(st.anchor_commanded_mm.iter_mut())
            .zip(st.readings_since_anchor.iter_mut())
            .zip(m.iter())
            .zip(inp.commanded_prev_mm.iter())
            .enumerate()
        {
            if (*mi - *am).abs() >= cfg.stuck_min_progress_mm {
                *am = *mi;
                *ac = *ci;
                *n = 0;
            } else {
                *n = n.saturating_add(1);
                if *n >= cfg.stuck_window_cycles.max(1)
                    && (*ci - *ac).abs() >= cfg.stuck_min_commanded_mm
                {
                    cond |= 1u8 << i;
                }
            }
        }
        cond
    }
}
