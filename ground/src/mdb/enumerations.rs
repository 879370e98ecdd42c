//! Enumerations: controller states, boot sources, banks, memory IDs, time report
//! rates, on-board parameters, reset causes.

use super::names::{thousands, upper_snake};
use m2ctl::controller::params::PARAMETERS;
use m2ctl::controller::State;
use m2ctl::link::command::MemoryId;
use m2ctl::link::time::{TimeReportRate, MAX_TIME_REPORT_EXPONENT};
use m2ctl::table::BootSource;

/// The controller states: code, label, name and what it means (docs/icd.md section 6).
pub fn controller_state_doc() -> Vec<(u8, String, &'static str, &'static str)> {
    // Exhaustive: a new state does not compile until it is listed.
    let all = [
        State::Idle,
        State::Moving,
        State::Stopping,
        State::StrokeMoving,
        State::Faulted,
    ];
    all.iter()
        .map(|s| {
            let (name, meaning) = match s {
                State::Idle => ("idle", "holding position, ready"),
                State::Moving => ("moving", "planning or following a path"),
                State::Stopping => ("stopping", "decelerating after a stop or a fault"),
                State::StrokeMoving => ("direct-stroke move", "recovery"),
                State::Faulted => (
                    "faulted",
                    "at rest, moves refused until a clear fault TC succeeds",
                ),
            };
            (s.code(), upper_snake(&format!("{s:?}")), name, meaning)
        })
        .collect()
}

pub(super) fn controller_states() -> Vec<(i64, String, String)> {
    controller_state_doc()
        .into_iter()
        .map(|(code, label, name, meaning)| (i64::from(code), label, format!("{name} ({meaning})")))
        .collect()
}

pub(super) fn boot_sources() -> Vec<(i64, String, String)> {
    [BootSource::Nominal, BootSource::BankA, BootSource::BankB]
        .iter()
        .map(|b| {
            let meaning = match b {
                BootSource::Nominal => "the compiled-in nominal table",
                BootSource::BankA => "flash bank A",
                BootSource::BankB => "flash bank B",
            };
            (
                i64::from(b.code()),
                upper_snake(&format!("{b:?}")),
                meaning.into(),
            )
        })
        .collect()
}

pub(super) fn banks() -> Vec<(i64, String, String)> {
    boot_sources()
        .into_iter()
        .map(|(v, l, m)| {
            if v == i64::from(BootSource::Nominal.code()) {
                (v, "NONE".into(), "no bank (nominal table)".into())
            } else {
                (v, l, m)
            }
        })
        .collect()
}

pub(super) fn memory_ids() -> Vec<(i64, String, String)> {
    [MemoryId::UploadBuffer, MemoryId::ActiveTable]
        .iter()
        .map(|m| {
            let meaning = match m {
                MemoryId::UploadBuffer => "the upload buffer (RAM)",
                MemoryId::ActiveTable => "the active parameter table",
            };
            (
                i64::from(m.code()),
                upper_snake(&format!("{m:?}")),
                meaning.into(),
            )
        })
        .collect()
}

pub(super) fn time_report_rates() -> Vec<(i64, String, String)> {
    let mut v: Vec<(i64, String, String)> = (0..=MAX_TIME_REPORT_EXPONENT)
        .map(|n| {
            (
                i64::from(n),
                format!("EVERY_{}_S", 1u32 << n),
                format!("a TM[9,2] every 2^{n} = {} s", 1u32 << n),
            )
        })
        .collect();
    v.push((
        i64::from(TimeReportRate::Off.code()),
        "OFF".into(),
        "no time reports (the state at boot)".into(),
    ));
    v
}

/// What an on-board parameter is, by its name in [`PARAMETERS`] (the flight image
/// carries no such text); `None` for a parameter not described here, which fails
/// `ground/tests/mdb.rs`.
pub fn parameter_description(name: &str) -> Option<String> {
    Some(match name {
        "pivot_x" => "pivot x (in M's coordinates)".into(),
        "pivot_y" => "pivot y".into(),
        "pivot_z" => "pivot z".into(),
        "user_alpha" => {
            "user frame alpha (rotation of the user frame from the base, Rz Ry Rx)".into()
        }
        "user_beta" => "user frame beta".into(),
        "user_gamma" => "user frame gamma".into(),
        "move_speed" => "coordinated-move speed limit per slider".into(),
        "move_accel" => "coordinated-move acceleration limit per slider".into(),
        "direct_speed" => "direct-stroke speed".into(),
        "direct_accel" => "direct-stroke acceleration".into(),
        "direct_max_delta" => "largest direct-stroke delta".into(),
        "hk_period" => format!(
            "housekeeping period (in control cycles of {} ms)",
            m2ctl::timing::CYCLE_US / 1000
        ),
        "following_warning" => "following-error warning threshold".into(),
        "following_fault" => "following-error fault threshold".into(),
        "encoder_jump" => "encoder jump threshold".into(),
        "stuck_progress" => "stuck detection: least progress".into(),
        "stuck_window" => "stuck detection: window".into(),
        "warning_debounce" => "warning debounce".into(),
        "fault_debounce" => "fault debounce".into(),
        "in_position_tolerance" => {
            "in-position tolerance: a move completes once every slider's mean encoder reading \
             at rest is within it (less half a count) of its setpoint"
                .into()
        }
        "in_position_dwell" => {
            "in-position dwell: the sliders at rest this long before completion, and before \
             each correction of the fine positioning"
                .into()
        }
        "thermal_compensation" => {
            "thermal compensation: 1 follows the running table's thermal model at rest in \
             bounded steps, 0 ramps its offset back to zero by the same steps"
                .into()
        }
        "thermal_max_step" => {
            "thermal compensation's largest change of a slider's offset per step (a step \
             per second at rest)"
                .into()
        }
        "thermal_min_step" => {
            "thermal compensation's dead band: no step until some slider's offset differs \
             by this much; at most the largest step"
                .into()
        }
        _ => return None,
    })
}

/// A parameter's default as docs/icd.md writes it.
pub fn parameter_default(d: &m2ctl::controller::params::ParamDef) -> String {
    match d.default {
        m2ctl::controller::params::Default::Fixed(v) => thousands(i64::from(v)),
        m2ctl::controller::params::Default::Table => "the running table's".into(),
    }
}

/// The on-board parameters (ST[20]) with their unit, range and default.
pub(super) fn parameter_ids() -> Vec<(i64, String, String)> {
    PARAMETERS
        .iter()
        .map(|d| {
            (
                i64::from(d.id),
                d.name.to_ascii_uppercase(),
                format!(
                    "{} ({}; {}..={}; default {})",
                    parameter_description(d.name).unwrap_or_else(|| d.name.to_string()),
                    d.unit,
                    d.min,
                    d.max,
                    parameter_default(d)
                ),
            )
        })
        .collect()
}

/// The reset causes: code, name, note (docs/icd.md section 4 and housekeeping).
pub fn reset_causes() -> Vec<(u8, &'static str, &'static str)> {
    use m2ctl::controller::ResetCause;
    [
        ResetCause::PowerOn,
        ResetCause::Watchdog,
        ResetCause::Software,
        ResetCause::HardFault,
        ResetCause::Panic,
        ResetCause::External,
    ]
    .iter()
    .map(|c| {
        // Exhaustive: a new cause does not compile until it is named here.
        let (name, note) = match c {
            ResetCause::PowerOn => ("power-on", ""),
            ResetCause::Watchdog => ("watchdog", ""),
            ResetCause::Software => ("software", ""),
            ResetCause::HardFault => ("HardFault", "including a stack overflow into the guard"),
            ResetCause::Panic => ("panic", ""),
            ResetCause::External => (
                "external",
                "a reset software did not announce: the reset pin, a debugger, QEMU's system_reset",
            ),
        };
        (c.code(), name, note)
    })
    .collect()
}
