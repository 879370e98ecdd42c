//! Alarms of the housekeeping parameters: which values Yamcs raises an alarm on, and
//! at which level (Yamcs levels WATCH, WARNING, DISTRESS, CRITICAL, SEVERE).

use super::names::upper_snake;
use super::{AlarmRule, ParameterAlarm};
use m2ctl::controller::State;

/// Yamcs' alarm level of a controller state (exhaustive: a new state does not compile
/// until it is given one); `None`: no alarm.
fn state_level(s: State) -> Option<&'static str> {
    match s {
        State::Faulted => Some("CRITICAL"),
        State::Idle | State::Moving | State::Stopping | State::StrokeMoving => None,
    }
}

/// The alarms. Counters count since boot: any non-zero value is in alarm until the
/// controller reboots (a rise, not a rate).
pub fn alarms() -> Vec<ParameterAlarm> {
    let states = [
        State::Idle,
        State::Moving,
        State::Stopping,
        State::StrokeMoving,
        State::Faulted,
    ];
    let above_zero =
        |parameter: &'static str, level: &'static str, why: &'static str| ParameterAlarm {
            parameter,
            rule: AlarmRule::Above { limit: 0.0, level },
            min_violations: 1,
            why,
        };
    vec![
        ParameterAlarm {
            parameter: "state",
            rule: AlarmRule::States {
                levels: states
                    .iter()
                    .filter_map(|s| Some((upper_snake(&format!("{s:?}")), state_level(*s)?)))
                    .collect(),
            },
            min_violations: 1,
            why: "a latched fault: moves refused until CLEAR_FAULT succeeds",
        },
        above_zero("fault_flags", "CRITICAL", "a fault is latched"),
        above_zero("warning_flags", "WARNING", "a warning is raised"),
        above_zero(
            "tm_dropped",
            "WARNING",
            "telemetry was lost on board since boot",
        ),
        above_zero(
            "cycle_overruns",
            "WARNING",
            "control cycles overran their period since boot",
        ),
        above_zero(
            "uart_overruns",
            "WARNING",
            "UART bytes were lost since boot",
        ),
        above_zero(
            "tc_rejected",
            "WATCH",
            "telecommands were refused by the link since boot",
        ),
    ]
}
