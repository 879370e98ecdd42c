//! Supervision thresholds and debounce counts, and where they come from.
//!
//! The calibrated parameter table ([`crate::table::Table`]) stores the following-error
//! thresholds, the jump threshold, the stuck window and progress, one warning and one
//! fault debounce count, the slider soft limits and the workspace. What it does not store
//! has a named default here:
//!
//! | field | source |
//! |---|---|
//! | `following_warning_mm`, `following_fault_mm` | table |
//! | `jump_mm_per_cycle` | table |
//! | `stuck_min_progress_mm`, `stuck_window_cycles` | table |
//! | `stuck_min_commanded_mm` | [`DEFAULT_STUCK_MIN_COMMANDED_MM`] |
//! | `soft_min_mm`, `soft_max_mm` | table stroke limits |
//! | `soft_limit_tolerance_mm` | [`DEFAULT_SOFT_LIMIT_TOLERANCE_MM`] |
//! | `workspace_translation_mm`, `workspace_rotation_rad` | table workspace |
//! | `workspace_tolerance_mm`, `workspace_tolerance_rad` | [`DEFAULT_WORKSPACE_TOLERANCE_MM`], [`DEFAULT_WORKSPACE_TOLERANCE_RAD`] |
//! | `debounce.following_warning` | table `warning_debounce_cycles` |
//! | `debounce.following_fault`, `soft_limit`, `fk`, `workspace` | table `fault_debounce_cycles` |
//! | `debounce.read_failure`, `jump`, `drive`, `stuck` | [`DEFAULT_IMMEDIATE_DEBOUNCE_CYCLES`] (1) |
//!
//! Following error is supervised in **stroke** (mm per slider), not in pose: the table
//! stores it so, it needs no kinematics, and it names the slider.

use crate::kinematics::{StrokeLimits, WorkspaceLimits, LEGS};
use crate::table::{SupervisionThresholds, Table};
use crate::units::ARCSEC_PER_RAD;

/// Least commanded stroke change over the stuck window for a slider to count as
/// "commanded to move" (mm): 10 um. A reversal through the drive train's backlash
/// leaves the slider still while its command turns back by the backlash and the
/// friction's break-away (3.2 um with the realistic defaults, `sim::drive_train`, a
/// worn nut up to 10 um): with the table's least progress of 1 um, a dead band of up to
/// 9 um is passed without a stuck fault (it was 3 um, which left 2 um and latched a
/// false fault on slow reversals: issue 21, host test
/// `fine_positioning::a_slow_reversal_through_the_backlash_is_no_fault_and_completes`).
/// A jammed slider is still caught once its command has gone 10 um (and the window),
/// or earlier by the following-error fault (`a_jam_is_still_caught`).
pub const DEFAULT_STUCK_MIN_COMMANDED_MM: f32 = 0.010;
/// Tolerance beyond the soft stroke limit before [`super::FaultFlags::SOFT_LIMIT`] (mm):
/// 1 um, ten encoder counts, so encoder noise at a target on the limit is no fault.
pub const DEFAULT_SOFT_LIMIT_TOLERANCE_MM: f32 = 0.001;
/// Tolerance beyond the workspace in translation (mm): 1 um, above the FK pose noise
/// from encoder quantisation (~0.1 um).
pub const DEFAULT_WORKSPACE_TOLERANCE_MM: f32 = 0.001;
/// Tolerance beyond the workspace in rotation (arcsec): above the FK pose noise (~0.1").
pub const DEFAULT_WORKSPACE_TOLERANCE_ARCSEC: f64 = 1.0;
/// [`DEFAULT_WORKSPACE_TOLERANCE_ARCSEC`] in rad.
pub const DEFAULT_WORKSPACE_TOLERANCE_RAD: f32 =
    (DEFAULT_WORKSPACE_TOLERANCE_ARCSEC / ARCSEC_PER_RAD) as f32;
/// Debounce of the checks that act on the first occurrence (read failure, jump, drive
/// fault, stuck — the stuck check has its own window).
pub const DEFAULT_IMMEDIATE_DEBOUNCE_CYCLES: u16 = 1;

/// Consecutive control cycles a condition must persist before it is reported (warning)
/// or latched (fault). 0 is treated as 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Debounce {
    /// Following-error warning.
    pub following_warning: u16,
    /// Following-error fault.
    pub following_fault: u16,
    /// Encoder stuck (after its window).
    pub stuck: u16,
    /// Encoder jump.
    pub jump: u16,
    /// Encoder read failure.
    pub read_failure: u16,
    /// Soft limit.
    pub soft_limit: u16,
    /// FK not converged.
    pub fk: u16,
    /// Pose outside the workspace.
    pub workspace: u16,
    /// Drive fault.
    pub drive: u16,
}

/// Everything the supervisor compares against. Strokes in mm along base z (0 at home),
/// poses as in [`crate::kinematics::Pose`] (mm, rad).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupervisionConfig {
    /// |measured - commanded stroke| above which the following warning is raised (mm).
    pub following_warning_mm: f32,
    /// |measured - commanded stroke| above which the following fault latches (mm).
    pub following_fault_mm: f32,
    /// Largest plausible change of one encoder between consecutive readings (mm per
    /// cycle; scaled by the cycles elapsed when readings were missed).
    pub jump_mm_per_cycle: f32,
    /// Least encoder progress that counts as moving (mm).
    pub stuck_min_progress_mm: f32,
    /// Least commanded stroke change over the stuck window for the slider to count as
    /// commanded to move (mm).
    pub stuck_min_commanded_mm: f32,
    /// Stuck window (cycles): readings while motion is commanded without progress.
    pub stuck_window_cycles: u16,
    /// Soft lower stroke limit per slider (mm).
    pub soft_min_mm: [f32; LEGS],
    /// Soft upper stroke limit per slider (mm).
    pub soft_max_mm: [f32; LEGS],
    /// How far beyond a soft limit a reading may be before it counts (mm).
    pub soft_limit_tolerance_mm: f32,
    /// Workspace half-range of x, y, z (mm).
    pub workspace_translation_mm: [f32; 3],
    /// Workspace half-range of alpha, beta, gamma (rad).
    pub workspace_rotation_rad: [f32; 3],
    /// How far beyond the workspace a translation may be before it counts (mm).
    pub workspace_tolerance_mm: f32,
    /// How far beyond the workspace a rotation may be before it counts (rad).
    pub workspace_tolerance_rad: f32,
    /// Debounce counts per check.
    pub debounce: Debounce,
}

impl SupervisionConfig {
    /// The table's thresholds with the given soft stroke limits and workspace (f64 ->
    /// f32 once), and the defaults of this module for what the table does not store.
    pub fn new(
        thresholds: &SupervisionThresholds,
        stroke_limits: &StrokeLimits,
        workspace: &WorkspaceLimits,
    ) -> Self {
        let t = thresholds;
        Self {
            following_warning_mm: t.following_error_warning_mm,
            following_fault_mm: t.following_error_fault_mm,
            jump_mm_per_cycle: t.encoder_jump_mm_per_cycle,
            stuck_min_progress_mm: t.stuck_min_progress_mm,
            stuck_min_commanded_mm: DEFAULT_STUCK_MIN_COMMANDED_MM,
            stuck_window_cycles: t.stuck_detection_cycles,
            soft_min_mm: stroke_limits.min_mm.map(|v| v as f32),
            soft_max_mm: stroke_limits.max_mm.map(|v| v as f32),
            soft_limit_tolerance_mm: DEFAULT_SOFT_LIMIT_TOLERANCE_MM,
            workspace_translation_mm: workspace.translation_mm.map(|v| v as f32),
            workspace_rotation_rad: workspace.rotation_rad.map(|v| v as f32),
            workspace_tolerance_mm: DEFAULT_WORKSPACE_TOLERANCE_MM,
            workspace_tolerance_rad: DEFAULT_WORKSPACE_TOLERANCE_RAD,
            debounce: Debounce {
                following_warning: t.warning_debounce_cycles,
                following_fault: t.fault_debounce_cycles,
                stuck: DEFAULT_IMMEDIATE_DEBOUNCE_CYCLES,
                jump: DEFAULT_IMMEDIATE_DEBOUNCE_CYCLES,
                read_failure: DEFAULT_IMMEDIATE_DEBOUNCE_CYCLES,
                soft_limit: t.fault_debounce_cycles,
                fk: t.fault_debounce_cycles,
                workspace: t.fault_debounce_cycles,
                drive: DEFAULT_IMMEDIATE_DEBOUNCE_CYCLES,
            },
        }
    }

    /// From a parameter table: its thresholds, stroke limits and workspace.
    pub fn from_table(table: &Table) -> Self {
        Self::new(&table.supervision, &table.stroke_limits, &table.workspace)
    }
}

impl From<&Table> for SupervisionConfig {
    fn from(table: &Table) -> Self {
        Self::from_table(table)
    }
}

impl From<&SupervisionThresholds> for SupervisionConfig {
    /// The thresholds with the nominal flight stroke limits and workspace
    /// ([`crate::nominal::prototype_with_flight_limits`]).
    fn from(thresholds: &SupervisionThresholds) -> Self {
        let nominal = crate::nominal::prototype_with_flight_limits();
        let stroke = nominal.stroke_limits.unwrap_or(StrokeLimits {
            min_mm: [-crate::nominal::STROKE_LIMIT_MM; LEGS],
            max_mm: [crate::nominal::STROKE_LIMIT_MM; LEGS],
        });
        let workspace = nominal.workspace.unwrap_or(WorkspaceLimits {
            translation_mm: [crate::nominal::WORKSPACE_TRANSLATION_MM; 3],
            rotation_rad: [crate::nominal::WORKSPACE_ROTATION_ARCSEC / ARCSEC_PER_RAD; 3],
        });
        Self::new(thresholds, &stroke, &workspace)
    }
}

impl Default for SupervisionConfig {
    /// The table defaults ([`crate::table::DEFAULT_SUPERVISION`]) with the nominal limits.
    fn default() -> Self {
        Self::from(&crate::table::DEFAULT_SUPERVISION)
    }
}
