//! The controller's state, cut into the parts it owns. Each part is plain data with the
//! operations that concern it alone (tested here, part by part); what needs several
//! parts at once (a control cycle, a telecommand) is the controller's (`mod.rs`,
//! `commands.rs`, `motion.rs`, `jobs.rs`).

use super::motion::{Motion, MoveCheckJob};
use super::params::InForce;
use super::verification::PendingTc;
use super::{ActiveTable, Ops, PendingTable, State};
use crate::hw::{DriveError, TravelSwitches};
use crate::kinematics::{FkConfig, Pose, LEGS};
use crate::motion::OutputLimiter;
use crate::supervision::FaultFlags;
use crate::table::upload::UploadBuffer;
use crate::table::{BootReport, BootSource};

/// What runs, what is pending, what the operator selected, the upload buffer and the
/// banks' health.
#[derive(Clone, Debug)]
pub(super) struct Tables {
    /// The running table, its CRC and working geometry.
    pub active: ActiveTable,
    /// The running geometry is usable; `false` only after a defect (the compiled-in
    /// nominal table failed to derive): every motion is refused.
    pub geometry_ok: bool,
    /// Counts activations and reloads; scrub results name the generation they checked.
    pub generation: u32,
    /// The boot's report (table source, bank status, selection).
    pub boot: BootReport,
    /// A committed table waiting for activation.
    pub pending: Option<PendingTable>,
    /// What the operator's last completed selection chose (`None`: none made since
    /// boot and no selection record found at boot).
    pub selection_source: Option<BootSource>,
    /// TC[6,2] chunks.
    pub upload: UploadBuffer,
    /// Flash-bank health from the background scrub: bit 0 bank A, bit 1 bank B corrupt.
    pub bank_health: u8,
}

/// The on-board parameters in force and what they and the running table make of the
/// settings.
#[derive(Clone, Copy, Debug)]
pub(super) struct Settings {
    /// The parameters (ST[20]) with their check word.
    pub params: InForce,
    /// The frames, motion limits and housekeeping period derived from them.
    pub ops: Ops,
}

/// The estimate of where the mechanism is: the encoders' last reading and forward
/// kinematics of it, warm-started.
#[derive(Clone, Copy, Debug)]
pub(super) struct FkEstimate {
    /// FK settings.
    pub cfg: FkConfig<f32>,
    /// Last good FK pose (internal frames; warm start and telemetry).
    pub pose: Pose<f32>,
    /// `pose` is this cycle's.
    pub valid: bool,
    /// Newton iterations of the last FK.
    pub iterations: u8,
    /// Last encoder reading (mm).
    pub encoders_mm: [f32; LEGS],
    /// `encoders_mm` is this cycle's.
    pub encoders_valid: bool,
}

impl FkEstimate {
    /// Nothing read yet.
    pub fn new() -> Self {
        Self {
            cfg: FkConfig::default(),
            pose: Pose::home(),
            valid: false,
            iterations: 0,
            encoders_mm: [0.0; LEGS],
            encoders_valid: false,
        }
    }
}

/// The end-of-travel switches as the motion must respect them (ICD section 6, "End of
/// travel").
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct EndOfTravel {
    /// The switches and reference sensors as read in the last cycle.
    pub switches: TravelSwitches,
    /// Every switch seen active or unreadable while the end-of-travel fault has been
    /// latched: the directions a direct stroke may not take until the clear.
    pub since_latch: TravelSwitches,
    /// Legs the current motion may not move toward smaller / larger strokes: every
    /// switch seen since the motion began (a switch that releases mid-motion keeps its
    /// leg held, so the command never jumps back to the path).
    pub clamp_negative: u8,
    /// See `clamp_negative`.
    pub clamp_positive: u8,
    /// The set of active switches last reported by event 0x0007 (its aux0).
    pub reported: u32,
}

impl EndOfTravel {
    /// At rest: the next motion's clamp starts from its own first cycle's switches.
    pub fn rest(&mut self) {
        self.clamp_negative = 0;
        self.clamp_positive = 0;
    }

    /// The clamp applied to a stroke command just before it goes to the drives: a leg
    /// whose switch blocks larger strokes (upper switch active, or an input unreadable)
    /// is commanded no further up than its previous command `prev`, one blocked toward
    /// smaller strokes no further down; blocked both ways, it keeps its previous
    /// command. A block lasts from the cycle the switch is seen to the end of the
    /// motion ([`EndOfTravel::rest`]).
    pub fn clamp(&mut self, mut strokes: [f32; LEGS], prev: &[f32; LEGS]) -> [f32; LEGS] {
        self.clamp_negative |= self.switches.blocked_negative();
        self.clamp_positive |= self.switches.blocked_positive();
        for (i, (s, prev)) in strokes.iter_mut().zip(prev.iter()).enumerate() {
            let bit = 1u8 << i;
            // `!(a <= b)` also catches NaN: the leg keeps its previous command.
            if self.clamp_positive & bit != 0 && !(*s <= *prev) {
                *s = *prev;
            }
            if self.clamp_negative & bit != 0 && !(*s >= *prev) {
                *s = *prev;
            }
        }
        strokes
    }

    /// The new aux0 of event 0x0007 if the set of active (or unreadable) switches
    /// changed to a non-empty one (remembered either way).
    pub fn changed_report(&mut self) -> Option<u32> {
        let word = end_of_travel_word(&self.switches);
        if word == self.reported {
            return None;
        }
        self.reported = word;
        (word != 0).then_some(word)
    }
}

/// Bit of the lowest leg in the lower-switch byte of event 0x0007's aux0.
const EOT_LOWER_SHIFT: u32 = 0;
/// Bit of the lowest leg in the upper-switch byte.
const EOT_UPPER_SHIFT: u32 = 8;
/// Bit of the lowest leg in the unreadable-input byte.
const EOT_UNREADABLE_SHIFT: u32 = 16;

/// aux0 of event 0x0007: legs at the lower switch (bits 0..5), at the upper switch
/// (bits 8..13), with an unreadable input (bits 16..21); 0: none.
pub(super) fn end_of_travel_word(s: &TravelSwitches) -> u32 {
    let legs = crate::supervision::ALL_LEGS;
    (u32::from(s.lower & legs) << EOT_LOWER_SHIFT)
        | (u32::from(s.upper & legs) << EOT_UPPER_SHIFT)
        | (u32::from(s.unreadable & legs) << EOT_UNREADABLE_SHIFT)
}

/// Every input active (or unreadable) in either reading.
pub(super) fn or_switches(a: &TravelSwitches, b: &TravelSwitches) -> TravelSwitches {
    TravelSwitches {
        lower: a.lower | b.lower,
        upper: a.upper | b.upper,
        reference: a.reference | b.reference,
        unreadable: a.unreadable | b.unreadable,
    }
}

/// The motion and what was last commanded.
#[derive(Clone, Copy, Debug)]
pub(super) struct MotionPart {
    /// What moves now (or holds).
    pub now: Motion,
    /// The pose of the commanded/held strokes: the last path setpoint, or FK of the
    /// strokes the drives hold (internal frames).
    pub pose: Pose<f32>,
    /// The strokes commanded to the drives in the last cycle, or (at rest) the strokes
    /// they hold (mm).
    pub strokes_mm: [f32; LEGS],
    /// The output stage every command passes (`motion::limiter`).
    pub limiter: OutputLimiter,
    /// The drives' answer to the last command (or poll).
    pub last_drive: Result<(), DriveError>,
    /// A motion was commanded in the last cycle (supervision's stuck check).
    pub moving_prev: bool,
    /// A stop or a fault ended a move while it was being planned.
    pub plan_aborted: bool,
    /// Refusal bits of the last refused move (housekeeping).
    pub refusal_bits: u32,
    /// A move check executed but not yet evaluated (the link service evaluates it
    /// outside the controller's lock: [`MoveCheckJob`]).
    pub check: Option<MoveCheckJob>,
    /// The strokes the encoders must read to be in position (mm): the last
    /// coordinated move's setpoint, or where the drives were told to hold (housekeeping
    /// `in_position_legs`; [`crate::motion::fine`]).
    pub setpoint_mm: [f32; LEGS],
    /// Which way each leg's command last moved: the side the next fine positioning
    /// approaches from.
    pub approach: crate::motion::fine::Approach,
}

/// Control-cycle overruns (`Controller::note_overrun`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct DeadlineMonitor {
    /// Overruns since boot (wrapping).
    pub overruns: u16,
    /// Overruns in a row.
    pub consecutive: u16,
}

impl DeadlineMonitor {
    /// One more overrun; true when this one makes `limit` in a row (the mechanism must
    /// hold now).
    pub fn overrun(&mut self, limit: u16) -> bool {
        self.overruns = self.overruns.wrapping_add(1);
        self.consecutive = self.consecutive.saturating_add(1);
        self.consecutive == limit
    }

    /// A cycle met its deadline; true if it ends a run of overruns.
    pub fn met(&mut self) -> bool {
        let ended = self.consecutive > 0;
        self.consecutive = 0;
        ended
    }
}

/// The telecommand ledger: counters, the last failure, the one long-running telecommand
/// still owed a report.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct TcLedger {
    /// Telecommands accepted (wrapping).
    pub accepted: u16,
    /// Telecommands rejected (wrapping).
    pub rejected: u16,
    /// The last failure code reported (0 none).
    pub last_failure_code: u16,
    /// The telecommand whose start or completion report is still to come.
    pub pending: Option<PendingTc>,
}

/// What was last reported, so that each change is reported once.
#[derive(Clone, Copy, Debug)]
pub(super) struct Reporting {
    /// The state last reported by event 0x0001.
    pub state: State,
    /// The warning flags last reported by event 0x0004.
    pub warnings: FaultFlags,
    /// The boot events were queued.
    pub boot_event_sent: bool,
    /// Persisted parameters not applied at boot (event 0x0041 after the boot events).
    pub params_ignored_at_boot: u32,
    /// The thermal model's sensors faulty when event 0x0050 was last considered.
    pub sensors_faulty: u8,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_deadline_monitor_holds_at_the_limit_once_and_clears_on_a_met_deadline() {
        let mut d = DeadlineMonitor::default();
        assert!(!d.overrun(3));
        assert!(!d.overrun(3));
        assert!(d.overrun(3), "the third in a row");
        assert!(!d.overrun(3), "reported once");
        assert_eq!((d.overruns, d.consecutive), (4, 4));
        assert!(d.met());
        assert!(!d.met());
        assert_eq!(d.overruns, 4);
    }

    #[test]
    fn the_end_of_travel_clamp_never_moves_a_blocked_leg_toward_its_switch() {
        let mut t = EndOfTravel::default();
        t.switches.upper = 0b01; // leg 1 at its upper switch
        t.switches.unreadable = 0b100; // leg 3 blocked both ways
        let prev = [1.0f32; LEGS];
        let out = t.clamp([1.5, 1.5, 0.5, 0.5, f32::NAN, 1.2], &prev);
        assert_eq!(out[0], 1.0, "leg 1 not further up");
        assert_eq!(out[1], 1.5, "leg 2 free");
        assert_eq!(out[2], 1.0, "leg 3 held");
        assert_eq!(out[3], 0.5);
        assert!(
            out[4].is_nan(),
            "an unblocked leg passes (the limiter catches NaN)"
        );
        // The block lasts after the switch releases, until the motion ends.
        t.switches = TravelSwitches::default();
        assert_eq!(t.clamp([2.0; LEGS], &prev)[0], 1.0);
        t.rest();
        assert_eq!(t.clamp([2.0; LEGS], &prev)[0], 2.0);
    }

    #[test]
    fn end_of_travel_is_reported_when_the_set_changes_to_a_non_empty_one() {
        let mut t = EndOfTravel::default();
        assert_eq!(t.changed_report(), None);
        t.switches.lower = 0b10;
        assert_eq!(t.changed_report(), Some(0b10));
        assert_eq!(t.changed_report(), None, "once");
        t.switches.lower = 0;
        assert_eq!(t.changed_report(), None, "released: nothing to report");
        t.switches.unreadable = 0b1;
        assert_eq!(t.changed_report(), Some(1 << EOT_UNREADABLE_SHIFT));
    }
}

/// The exposure hold (issue 22): the camera is exposing, so no compensation step, no
/// scheduled motion and no operator move. Set by telecommand (TC[8,1] 0x0007, with its
/// timeout) or by the board's discrete input (while it is active, at most
/// [`EXPOSURE_INPUT_TIMEOUT_CYCLES`] from its rising edge); held while either is.
/// Counted in control cycles left; its default (no hold) is all zero bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct ExposureHold {
    /// Cycles left of the telecommand's hold (0: none).
    pub tc_left: u32,
    /// Cycles left of the discrete input's hold (0: none, or timed out while the input
    /// stays active: a new rising edge is needed).
    pub input_left: u32,
    /// The input at the last cycle (the rising edge starts a hold).
    pub input_prev: bool,
}

/// The longest hold the discrete input makes (cycles): as long as the telecommand's
/// longest ([`crate::link::command::MAX_EXPOSURE_HOLD_S`]), so that a stuck input does
/// not hold the mechanism for ever.
pub(super) const EXPOSURE_INPUT_TIMEOUT_CYCLES: u32 =
    crate::link::command::MAX_EXPOSURE_HOLD_S as u32 * crate::timing::CONTROL_RATE_HZ;

/// Why an exposure hold ended (event [`crate::link::tm::event_id::EXPOSURE_HOLD_ENDED`]'s
/// aux0).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub(super) enum HoldEnd {
    /// A telecommand with timeout 0 (and the input is not active).
    Telecommand = 0,
    /// Its timeout passed.
    TimedOut = 1,
    /// The discrete input was released.
    InputReleased = 2,
}

impl ExposureHold {
    /// A hold is in force.
    pub fn active(&self) -> bool {
        self.tc_left != 0 || self.input_left != 0
    }

    /// The hold's cycles left (the longer of the two).
    pub fn left_cycles(&self) -> u32 {
        self.tc_left.max(self.input_left)
    }

    /// One control cycle with the input `input`: the rising edge starts the input's
    /// hold, the falling edge ends it, and both count down. Returns why the hold ended
    /// if it ended in this cycle.
    pub fn cycle(&mut self, input: bool) -> Option<HoldEnd> {
        let was = self.active();
        if input && !self.input_prev {
            self.input_left = EXPOSURE_INPUT_TIMEOUT_CYCLES;
        }
        let released = !input && self.input_prev && self.input_left != 0;
        if !input {
            self.input_left = 0;
        }
        self.input_prev = input;
        self.tc_left = self.tc_left.saturating_sub(1);
        self.input_left = self.input_left.saturating_sub(1);
        match (was, self.active()) {
            (true, false) if released => Some(HoldEnd::InputReleased),
            (true, false) => Some(HoldEnd::TimedOut),
            _ => None,
        }
    }
}
