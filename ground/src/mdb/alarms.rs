//! Alarms of the housekeeping parameters: which values Yamcs raises an alarm on, and
//! at which level (Yamcs levels WATCH, WARNING, DISTRESS, CRITICAL, SEVERE).

use super::names::upper_snake;
use super::{AlarmRule, DerivedParameter, ParameterAlarm};
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
        above_zero(
            "sensors_open",
            "WARNING",
            "a temperature sensor reads open (its mean is withheld)",
        ),
        above_zero(
            "sensors_short",
            "WARNING",
            "a temperature sensor reads shorted (its mean is withheld)",
        ),
        above_zero(
            "sensors_stuck",
            "WARNING",
            "a temperature sensor repeats one reading (its mean is withheld)",
        ),
    ]
}

/// Parameters Yamcs derives from each housekeeping report, with their alarms.
///
/// `following_error_max`: the largest difference between a leg's commanded (or held)
/// stroke and its encoder reading in the same report, in um. The controller supervises
/// the same quantity every control cycle against the active table's thresholds and
/// latches its own warning and fault; the ground's alarm shows it to the operator at the
/// thresholds' defaults (`table::DEFAULT_SUPERVISION`: 5 and 50 um),
/// debounced over two reports: one report caught in a backlash reversal (a few um for
/// a few cycles) is not an alarm.
///
/// `temperature_deviation_max`: the largest distance of a sensor's mean from the
/// thermal model's default reference temperature (sensors without a value left out),
/// WARNING beyond the largest soak of the thermal calibration's default design
/// (`m2calib::thermal::LARGEST_SOAK_K`): outside the range the coefficients were
/// measured over. A faulty sensor raises its health mask's alarm instead.
pub fn derived() -> Vec<DerivedParameter> {
    use super::housekeeping::{K_PER_CENTI_K, UNIT_K};
    use super::Computation;
    use m2calib::thermal::LARGEST_SOAK_K;
    use m2ctl::thermal::{ThermalModel, NO_TEMPERATURE, TEMP_SENSORS, ZERO_CELSIUS_CENTI_K};
    const REFERENCE_C: f64 = ThermalModel::NONE.reference_c as f64;
    // Divided, not multiplied by 0.01: 273.15 exactly as written, not 273.15000000000003.
    let celsius_to_k = f64::from(ZERO_CELSIUS_CENTI_K) / (1.0 / K_PER_CENTI_K);
    use m2ctl::kinematics::LEGS;
    use m2ctl::table::DEFAULT_SUPERVISION;
    use m2ctl::units::UM_PER_MM;
    let um = |mm: f32| (f64::from(mm) * UM_PER_MM).round();
    vec![
        DerivedParameter {
            name: "following_error_max",
            unit: super::UNIT_UM,
            description: format!(
                "largest |commanded stroke - encoder reading| over legs 1..{LEGS} in one \
             housekeeping report (um; Yamcs algorithm)"
            ),
            fraction_digits: 3,
            computation: Computation::LargestDifference {
                pairs: (1..=LEGS)
                    .map(|i| (format!("stroke_cmd_leg{i}"), format!("encoder_leg{i}")))
                    .collect(),
            },
            above: vec![
                (
                    "WARNING",
                    um(DEFAULT_SUPERVISION.following_error_warning_mm),
                ),
                ("CRITICAL", um(DEFAULT_SUPERVISION.following_error_fault_mm)),
            ],
            min_violations: 2,
            why: "a slider lags its command: the controller warns, then faults, at its thresholds",
        },
        DerivedParameter {
            name: "temperature_deviation_max",
            unit: UNIT_K,
            description: format!(
                "largest |temperature - reference| over the sensors 0..{} with a value, the \
             reference the thermal model's default ({REFERENCE_C} deg C) (K; Yamcs algorithm)",
                TEMP_SENSORS - 1
            ),
            fraction_digits: 2,
            computation: Computation::LargestDeviation {
                fields: (0..TEMP_SENSORS)
                    .map(|i| format!("temperature_sensor{i}"))
                    .collect(),
                from: REFERENCE_C + celsius_to_k,
                absent: f64::from(NO_TEMPERATURE) * K_PER_CENTI_K,
            },
            above: vec![("WARNING", LARGEST_SOAK_K)],
            min_violations: 2,
            why: "a part is further from the reference than the thermal calibration measured: \
              the compensation extrapolates",
        },
    ]
}
