//! What a soak run reports: its figures, and each violation printed with the actions
//! that led to it and the state it was seen in, so a long run can be replayed to it
//! (same seed, `M2_SOAK_CYCLES`).

use super::{Choices, Soak};

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
    /// Coordinated moves watched to their end ([`super::WATCH_ONE_IN`]).
    pub moves_watched: u64,
    /// Invariant violations.
    pub violations: u64,
    /// Cycles the compensation's applied offset changed (invariant 12 checked them).
    pub thermal_steps: u64,
    /// Cycles an exposure hold was in force (invariant 13 checked them).
    pub hold_cycles: u64,
    /// Operator moves refused by an exposure hold (0x0710).
    pub hold_refusals: u64,
    /// Completions in position invariant 14 then watched at rest.
    pub placements: u64,
    /// Cycles invariant 14 checked (idle, watched from a completion in position).
    pub placed_cycles: u64,
    /// Compensation steps within them.
    pub placed_steps: u64,
    /// The furthest a slider so watched stood from its setpoint and offset beyond the
    /// last compensation step (um; invariant 14 allows twice the in-position tolerance
    /// and the encoder noise's sigma).
    pub placed_worst_um: f64,
}

/// Actions kept in the history.
const HISTORY_LEN: usize = 30;
/// Violations printed (all are counted).
const MAX_PRINTED_VIOLATIONS: usize = 20;

impl<C: Choices> Soak<C> {
    pub(super) fn violation(&mut self, what: String) {
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

    pub(super) fn note(&mut self, what: String) {
        if self.history.len() == HISTORY_LEN {
            self.history.remove(0);
        }
        self.history.push(format!("cycle {}: {what}", self.cycles));
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
            moves_watched: self.moves_watched,
            violations: self.violations.len() as u64,
            thermal_steps: self.thermal_steps,
            hold_cycles: self.hold_cycles,
            hold_refusals: self.hold_refusals,
            placements: self.placements,
            placed_cycles: self.placed_cycles,
            placed_steps: self.placed_steps,
            placed_worst_um: self.placed_worst_mm * crate::units::UM_PER_MM,
        }
    }
}
