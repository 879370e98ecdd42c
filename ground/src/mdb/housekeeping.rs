//! Housekeeping (TM[3,25]): one row per field, offsets from
//! [`m2ctl::link::hk::field`], each with a getter into [`Housekeeping`].

use super::enumerations::reset_causes;
use super::fields::{calibrated, count, field, fixed, obt_fields, pose_fields, POSE_AXES};
use super::{Field, Meaning, Wire, UNIT_UM};
use m2ctl::controller::jobs::JobKind;
use m2ctl::controller::params::PARAMETERS;
use m2ctl::kinematics::LEGS;
use m2ctl::link::command::WirePose;
use m2ctl::link::hk::{field as hk_field, HK_STRUCTURE_ID, NO_SELECTION};
use m2ctl::link::schedule::SCHEDULE_CAPACITY;
use m2ctl::link::time::TimeReportRate;
use m2ctl::link::tm::event_id;
use m2ctl::link::{service, subtype, Housekeeping};
use m2ctl::table::BootSource;
use m2ctl::thermal::{
    MEAN_SAMPLES, NO_TEMPERATURE, SENSOR_MAX_C, SENSOR_MIN_C, STUCK_SAMPLES, TEMP_SENSORS,
};
use m2ctl::timing::{CONTROL_RATE_HZ, TEMPERATURE_PERIOD_CYCLES};
use m2ctl::units::UM_PER_NM;

/// Reads one housekeeping member as the raw integer of its wire field.
pub type HkGetter = fn(&Housekeeping) -> i64;

fn hk_pose(p: &WirePose, k: usize) -> i64 {
    p.to_array().get(k).copied().map_or(0, i64::from)
}

macro_rules! pose_getters {
    ($member:ident) => {
        [
            |h: &Housekeeping| hk_pose(&h.$member, 0),
            |h: &Housekeeping| hk_pose(&h.$member, 1),
            |h: &Housekeeping| hk_pose(&h.$member, 2),
            |h: &Housekeeping| hk_pose(&h.$member, 3),
            |h: &Housekeeping| hk_pose(&h.$member, 4),
            |h: &Housekeeping| hk_pose(&h.$member, 5),
        ]
    };
}

macro_rules! leg_getters {
    ($member:ident) => {
        [
            |h: &Housekeeping| i64::from(h.$member[0]),
            |h: &Housekeeping| i64::from(h.$member[1]),
            |h: &Housekeeping| i64::from(h.$member[2]),
            |h: &Housekeeping| i64::from(h.$member[3]),
            |h: &Housekeeping| i64::from(h.$member[4]),
            |h: &Housekeeping| i64::from(h.$member[5]),
        ]
    };
}

/// One row of the housekeeping layout as docs/icd.md shows it (section 6): one field, or
/// a group of consecutive fields of one item (a pose, the six legs, a CUC time).
#[derive(Clone, Debug)]
pub struct HkRow {
    /// What the row holds: for one field, that field's description.
    pub description: String,
    /// Its fields with their accessors into [`Housekeeping`] (the structure ID has none:
    /// it is the constant [`HK_STRUCTURE_ID`]).
    pub fields: Vec<(Field, Option<HkGetter>)>,
}

impl HkRow {
    fn single(f: Field, get: Option<HkGetter>) -> HkRow {
        HkRow {
            description: f.description.clone(),
            fields: vec![(f, get)],
        }
    }

    fn group(description: String, fields: Vec<(Field, Option<HkGetter>)>) -> HkRow {
        HkRow {
            description,
            fields,
        }
    }
}

/// `0 nominal, 1 A, 2 B` with the codes of [`BootSource`] (`bank`: "bank A" for "A").
pub(super) fn source_codes(nominal: &str, bank: &str) -> String {
    format!(
        "{} {nominal}, {} {bank}A, {} {bank}B",
        BootSource::Nominal.code(),
        BootSource::BankA.code(),
        BootSource::BankB.code()
    )
}

/// The housekeeping report's rows, in offset order (the fields tile
/// [`HK_REPORT_LEN`](m2ctl::link::hk::HK_REPORT_LEN) bytes: `ground/tests/mdb.rs` reads an
/// emitted report back by them).
pub fn housekeeping_rows() -> Vec<HkRow> {
    let one = |f: Field, get: HkGetter| HkRow::single(f, Some(get));
    let e = |name: &str, off, enumeration, d: &str| {
        field(name, off, Wire::U8, Meaning::Enum { enumeration }, d)
    };
    let b = |name: &str, off, wire, bit_field, d: &str| {
        field(name, off, wire, Meaning::Bits { bit_field }, d)
    };
    let leg_bits = "bit i = leg i+1";
    let mut v: Vec<HkRow> = vec![
        HkRow::single(
            fixed(
                "structure_id",
                hk_field::STRUCTURE_ID.start,
                Wire::U8,
                i64::from(HK_STRUCTURE_ID),
                &format!("structure ID = {HK_STRUCTURE_ID}"),
            ),
            None,
        ),
        one(
            e(
                "state",
                hk_field::STATE.start,
                "controller_state",
                "controller state",
            ),
            |h| i64::from(h.state),
        ),
        one(
            e(
                "boot_source",
                hk_field::BOOT_SOURCE.start,
                "boot_source",
                &format!("boot source: {}", source_codes("nominal", "bank ")),
            ),
            |h| i64::from(h.boot_source),
        ),
        one(
            e(
                "active_bank",
                hk_field::ACTIVE_BANK.start,
                "bank",
                &format!(
                    "source of the running table: {}",
                    source_codes("nominal", "")
                ),
            ),
            |h| i64::from(h.active_bank),
        ),
        one(
            count(
                "fk_iterations",
                hk_field::FK_ITERATIONS.start,
                Wire::U8,
                "last FK Newton iteration count",
            ),
            |h| i64::from(h.fk_iterations),
        ),
        one(
            field(
                "fk_valid",
                hk_field::FK_VALID.start,
                Wire::U8,
                Meaning::Boolean,
                "FK valid (1: the FK pose is this cycle's; 0: FK failed or no reading)",
            ),
            |h| i64::from(h.fk_valid),
        ),
        one(
            count(
                "cycle_counter",
                hk_field::CYCLE_COUNTER.start,
                Wire::U32,
                "control cycle counter: the cycle the report was sampled in, the one its time \
                 stamp names",
            ),
            |h| i64::from(h.cycle_counter),
        ),
        one(
            b(
                "fault_flags",
                hk_field::FAULT_FLAGS.start,
                Wire::U32,
                "fault_flags",
                "fault flags (latched)",
            ),
            |h| i64::from(h.fault_flags),
        ),
        one(
            b(
                "warning_flags",
                hk_field::WARNING_FLAGS.start,
                Wire::U32,
                "fault_flags",
                "warning flags",
            ),
            |h| i64::from(h.warning_flags),
        ),
        one(
            b(
                "refusal_bits",
                hk_field::REFUSAL_BITS.start,
                Wire::U32,
                "refusal_bits",
                "refusal bits of the last refused move",
            ),
            |h| i64::from(h.refusal_bits),
        ),
        one(
            count(
                "active_table_id",
                hk_field::ACTIVE_TABLE_ID.start,
                Wire::U32,
                "running table ID",
            ),
            |h| i64::from(h.active_table_id),
        ),
        one(
            count(
                "active_table_crc32",
                hk_field::ACTIVE_TABLE_CRC32.start,
                Wire::U32,
                "running table CRC-32",
            ),
            |h| i64::from(h.active_table_crc32),
        ),
    ];
    let poses: [(&str, usize, &str, String, [HkGetter; 6]); 2] = [
        (
            "pose_fk_",
            hk_field::POSE_FK.start,
            "pose from FK of the encoders",
            "pose from FK of the encoders (nm, µas; order as the TC pose)".into(),
            pose_getters!(pose_fk),
        ),
        (
            "pose_cmd_",
            hk_field::POSE_COMMANDED.start,
            "commanded pose",
            "commanded pose: the path setpoint, or the pose of the held strokes (nm, µas)".into(),
            pose_getters!(pose_commanded),
        ),
    ];
    for (prefix, off, what, row, getters) in poses {
        let fields = pose_fields(prefix, off, what)
            .into_iter()
            .zip(getters)
            .map(|(f, g)| (f, Some(g)))
            .collect();
        v.push(HkRow::group(row, fields));
    }
    let legs: [(&str, usize, &str, String, [HkGetter; 6]); 2] = [
        (
            "stroke_cmd_leg",
            hk_field::STROKES_COMMANDED.start,
            "commanded stroke (um; wire i32 in nm)",
            format!("commanded (or held) strokes, legs 1..{LEGS} (nm)"),
            leg_getters!(strokes_commanded_nm),
        ),
        (
            "encoder_leg",
            hk_field::ENCODERS.start,
            "encoder reading (um; wire i32 in nm, multiples of one 0.1 um count)",
            format!(
                "encoder readings, legs 1..{LEGS} (nm; the encoders count 0.1 µm, so multiples \
                 of 100)"
            ),
            leg_getters!(encoders_nm),
        ),
    ];
    for (prefix, off, what, row, getters) in legs {
        let fields = getters
            .into_iter()
            .enumerate()
            .map(|(i, g)| {
                (
                    calibrated(
                        &format!("{prefix}{}", i + 1),
                        off + 4 * i,
                        Wire::I32,
                        UNIT_UM,
                        UM_PER_NM,
                        &format!("leg {}: {what}", i + 1),
                    ),
                    Some(g),
                )
            })
            .collect();
        v.push(HkRow::group(row, fields));
    }
    let jobs = [
        JobKind::Commit,
        JobKind::Select,
        JobKind::Reload,
        JobKind::Parameters,
    ]
    .map(|j| {
        // Exhaustive: a new job does not compile until it is named here.
        let name = match j {
            JobKind::Commit => "commit",
            JobKind::Select => "selection",
            JobKind::Reload => "reload",
            JobKind::Parameters => "parameters",
        };
        format!("{} {name}", j.code())
    });
    v.extend([
        one(
            count(
                "tc_accepted",
                hk_field::TC_ACCEPTED.start,
                Wire::U16,
                "telecommands accepted (wrapping)",
            ),
            |h| i64::from(h.tc_accepted),
        ),
        one(
            count(
                "tc_rejected",
                hk_field::TC_REJECTED.start,
                Wire::U16,
                "telecommands rejected (wrapping)",
            ),
            |h| i64::from(h.tc_rejected),
        ),
        one(
            field(
                "last_failure_code",
                hk_field::LAST_FAILURE_CODE.start,
                Wire::U16,
                Meaning::Enum {
                    enumeration: "failure_code",
                },
                "last failure code reported (0 none)",
            ),
            |h| i64::from(h.last_failure_code),
        ),
        one(
            b(
                "moving_legs",
                hk_field::MOVING_LEGS.start,
                Wire::U8,
                "leg_mask",
                &format!("legs commanded to move ({leg_bits})"),
            ),
            |h| i64::from(h.moving_legs),
        ),
        one(
            b(
                "fault_legs",
                hk_field::FAULT_LEGS.start,
                Wire::U8,
                "leg_mask",
                &format!("legs named by the latched faults ({leg_bits})"),
            ),
            |h| i64::from(h.fault_legs),
        ),
        one(
            e(
                "pending_bank",
                hk_field::PENDING_BANK.start,
                "bank",
                &format!(
                    "bank of the pending (committed, not activated) table: {}",
                    source_codes("none", "")
                ),
            ),
            |h| i64::from(h.pending_bank),
        ),
        one(
            count(
                "pending_table_id",
                hk_field::PENDING_TABLE_ID.start,
                Wire::U32,
                "pending table ID (0 if none)",
            ),
            |h| i64::from(h.pending_table_id),
        ),
        one(
            count(
                "job",
                hk_field::JOB.start,
                Wire::U8,
                &format!("background job running: 0 none, {}", jobs.join(", ")),
            ),
            |h| i64::from(h.job),
        ),
        one(
            count(
                "selected_source",
                hk_field::SELECTED_SOURCE.start,
                Wire::U8,
                &format!(
                    "selected table (what boots): {}, {NO_SELECTION} no selection record",
                    source_codes("nominal", "")
                ),
            ),
            |h| i64::from(h.selected_source),
        ),
        one(
            count(
                "tm_dropped",
                hk_field::TM_DROPPED.start,
                Wire::U16,
                "telemetry records dropped (queue full; wrapping)",
            ),
            |h| i64::from(h.tm_dropped),
        ),
        one(
            count(
                "tc_frames_dropped",
                hk_field::TC_FRAMES_DROPPED.start,
                Wire::U16,
                "telecommand frames dropped (too long or bad COBS; wrapping)",
            ),
            |h| i64::from(h.tc_frames_dropped),
        ),
        one(
            count(
                "uart_overruns",
                hk_field::UART_OVERRUNS.start,
                Wire::U16,
                "UART receive overruns and receive-queue overflows (wrapping)",
            ),
            |h| i64::from(h.uart_overruns),
        ),
        one(
            count(
                "cycle_overruns",
                hk_field::CYCLE_OVERRUNS.start,
                Wire::U16,
                "control-cycle overruns (wrapping)",
            ),
            |h| i64::from(h.cycle_overruns),
        ),
        one(
            count(
                "reset_cause",
                hk_field::RESET_CAUSE.start,
                Wire::U8,
                &format!(
                    "reset cause (as in event 0x{:04X}): {}",
                    event_id::BOOT_DETAIL,
                    reset_causes()
                        .iter()
                        .map(|(code, name, _)| format!("{code} {name}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ),
            |h| i64::from(h.reset_cause),
        ),
        one(
            count(
                "boot_count",
                hk_field::BOOT_COUNT.start,
                Wire::U16,
                "boot count (wrapping)",
            ),
            |h| i64::from(h.boot_count),
        ),
        one(
            count(
                "bank_health",
                hk_field::BANK_HEALTH.start,
                Wire::U8,
                "flash bank health: bit 0 bank A, bit 1 bank B record corrupt",
            ),
            |h| i64::from(h.bank_health),
        ),
    ]);
    let pivot: [HkGetter; 3] = [
        |h| i64::from(h.pivot_nm[0]),
        |h| i64::from(h.pivot_nm[1]),
        |h| i64::from(h.pivot_nm[2]),
    ];
    let pivot_ids = PARAMETERS
        .get(m2ctl::controller::params::index::PIVOT..m2ctl::controller::params::index::PIVOT + 3)
        .unwrap_or(&[])
        .iter()
        .map(|d| d.id)
        .collect::<Vec<_>>();
    let pivot_fields = pivot
        .into_iter()
        .enumerate()
        .map(|(k, g)| {
            let axis = POSE_AXES.get(k).copied().unwrap_or("");
            (
                calibrated(
                    &format!("pivot_{axis}"),
                    hk_field::PIVOT.start + 4 * k,
                    Wire::I32,
                    UNIT_UM,
                    UM_PER_NM,
                    &format!(
                        "pivot in M's coordinates, {axis} (um; wire i32 in nm; ST[20] parameter)"
                    ),
                ),
                Some(g),
            )
        })
        .collect();
    v.push(HkRow::group(
        format!(
            "the pivot in M's coordinates, x, y, z (nm; parameters {}..{})",
            pivot_ids.first().copied().unwrap_or(0),
            pivot_ids.last().copied().unwrap_or(0)
        ),
        pivot_fields,
    ));
    let operator: [(&str, usize, &str, &str, [HkGetter; 6]); 2] = [
        (
            "pose_fk_op_",
            hk_field::POSE_FK_OPERATOR.start,
            "pose from FK in the operator's frames (about the pivot, in the user frame)",
            "pose from FK in the operator's frames (pivot, user frame; nm, µas)",
            pose_getters!(pose_fk_operator),
        ),
        (
            "pose_cmd_op_",
            hk_field::POSE_COMMANDED_OPERATOR.start,
            "commanded pose in the operator's frames (about the pivot, in the user frame)",
            "commanded pose in the operator's frames (nm, µas)",
            pose_getters!(pose_commanded_operator),
        ),
    ];
    for (prefix, off, what, row, getters) in operator {
        let fields = pose_fields(prefix, off, what)
            .into_iter()
            .zip(getters)
            .map(|(f, g)| (f, Some(g)))
            .collect();
        v.push(HkRow::group(row.into(), fields));
    }
    v.push(one(
        count(
            "parameters_set",
            hk_field::PARAMETERS_SET.start,
            Wire::U32,
            "on-board parameters set by TC[20,3] (bit i = parameter index i, rows of section \
             5a in order; clear: default)",
        ),
        |h| i64::from(h.parameters_set),
    ));
    // Time-based schedule (ST[11]) and time reports (ST[9]): offsets 217..230.
    v.extend([
        one(
            count(
                "schedule_activities",
                hk_field::SCHEDULE_ACTIVITIES.start,
                Wire::U8,
                &format!("time-tagged activities in the schedule (0..{SCHEDULE_CAPACITY})"),
            ),
            |h| i64::from(h.schedule.activities),
        ),
        one(
            field(
                "schedule_release_enabled",
                hk_field::SCHEDULE_RELEASE_ENABLED.start,
                Wire::U8,
                Meaning::Boolean,
                "release of activities: 1 enabled, 0 disabled",
            ),
            |h| i64::from(h.schedule.release_enabled),
        ),
        one(
            count(
                "schedule_released",
                hk_field::SCHEDULE_RELEASED.start,
                Wire::U16,
                "activities released since boot (wrapping)",
            ),
            |h| i64::from(h.schedule.released),
        ),
        one(
            count(
                "schedule_failed",
                hk_field::SCHEDULE_FAILED.start,
                Wire::U16,
                "released activities whose telecommand failed (wrapping)",
            ),
            |h| i64::from(h.schedule.failed),
        ),
    ]);
    let next_what = "release time of the next activity (0 if none)";
    let next: [HkGetter; 2] = [
        |h| i64::from(h.schedule.next_release.seconds),
        |h| i64::from(h.schedule.next_release.fraction),
    ];
    v.push(HkRow::group(
        next_what.into(),
        obt_fields(
            "schedule_next_release_",
            hk_field::SCHEDULE_NEXT_RELEASE.start,
            next_what,
        )
        .into_iter()
        .zip(next)
        .map(|(f, g)| (f, Some(g)))
        .collect(),
    ));
    v.push(one(
        field(
            "time_report_rate",
            hk_field::TIME_REPORT_RATE.start,
            Wire::U8,
            Meaning::Enum {
                enumeration: "time_report_rate",
            },
            &format!(
                "time report rate (TC[{},{}]): N of 2^N s, {} off",
                service::TIME,
                subtype::SET_TIME_REPORT_RATE,
                TimeReportRate::Off.code()
            ),
        ),
        |h| i64::from(h.schedule.time_report_rate),
    ));
    let switches: [(&str, usize, String, HkGetter); 5] = [
        (
            "limit_lower_legs",
            hk_field::LIMIT_LOWER_LEGS.start,
            format!("legs at their lower end-of-travel switch ({leg_bits}; the last cycle's read)"),
            |h| i64::from(h.limit_lower_legs),
        ),
        (
            "limit_upper_legs",
            hk_field::LIMIT_UPPER_LEGS.start,
            format!("legs at their upper end-of-travel switch ({leg_bits})"),
            |h| i64::from(h.limit_upper_legs),
        ),
        (
            "reference_legs",
            hk_field::REFERENCE_LEGS.start,
            format!("legs at their reference (home) sensor ({leg_bits}; information only)"),
            |h| i64::from(h.reference_legs),
        ),
        (
            "switch_unreadable_legs",
            hk_field::SWITCH_UNREADABLE_LEGS.start,
            format!(
                "legs with a switch input that cannot be read ({leg_bits}; treated as both \
                 ends active)"
            ),
            |h| i64::from(h.switch_unreadable_legs),
        ),
        (
            "in_position_legs",
            hk_field::IN_POSITION_LEGS.start,
            format!(
                "legs whose encoder reads within the in-position tolerance (plus half a \
                 count) of the setpoint of the last coordinated move, or of where the drives \
                 were told to hold ({leg_bits}); at rest a slider that creeps out is \
                 reported here, not moved"
            ),
            |h| i64::from(h.in_position_legs),
        ),
    ];
    for (name, off, what, g) in switches {
        v.push(one(b(name, off, Wire::U8, "leg_mask", &what), g));
    }
    // The temperature sensors (issue 22): each one's mean, then why a sensor has none.
    let temps: [HkGetter; TEMP_SENSORS] = [
        |h| i64::from(h.temperatures_centi_k[0]),
        |h| i64::from(h.temperatures_centi_k[1]),
        |h| i64::from(h.temperatures_centi_k[2]),
        |h| i64::from(h.temperatures_centi_k[3]),
        |h| i64::from(h.temperatures_centi_k[4]),
        |h| i64::from(h.temperatures_centi_k[5]),
        |h| i64::from(h.temperatures_centi_k[6]),
        |h| i64::from(h.temperatures_centi_k[7]),
    ];
    let temperature_fields = temps
        .into_iter()
        .enumerate()
        .map(|(i, g)| {
            (
                calibrated(
                    &format!("temperature_sensor{i}"),
                    hk_field::TEMPERATURES_CENTI_K.start + 2 * i,
                    Wire::U16,
                    UNIT_K,
                    K_PER_CENTI_K,
                    &format!(
                        "temperature sensor {i}: mean of its last {MEAN_SAMPLES} readings (K; \
                         wire u16 in 0.01 K; {NO_TEMPERATURE}: none, the sensor faulty or \
                         before its first mean)"
                    ),
                ),
                Some(g),
            )
        })
        .collect();
    v.push(HkRow::group(
        format!(
            "temperature sensors 0..{}: each one's mean of its last {MEAN_SAMPLES} readings \
             (one per {} ms; 0.01 K, so deg C = value / 100 - 273.15; {NO_TEMPERATURE}: none, \
             the sensor faulty or before its first mean)",
            TEMP_SENSORS - 1,
            u64::from(TEMPERATURE_PERIOD_CYCLES) * 1000 / u64::from(CONTROL_RATE_HZ)
        ),
        temperature_fields,
    ));
    let sensor_bits = "bit i = sensor i";
    let sensor_faults: [(&str, usize, String, HkGetter); 3] = [
        (
            "sensors_open",
            hk_field::SENSORS_OPEN.start,
            format!("temperature sensors open: reading full scale or above {SENSOR_MAX_C} deg C ({sensor_bits})"),
            |h| i64::from(h.sensors_open),
        ),
        (
            "sensors_short",
            hk_field::SENSORS_SHORT.start,
            format!("temperature sensors shorted: reading below {SENSOR_MIN_C} deg C ({sensor_bits})"),
            |h| i64::from(h.sensors_short),
        ),
        (
            "sensors_stuck",
            hk_field::SENSORS_STUCK.start,
            format!(
                "temperature sensors stuck: the same count {STUCK_SAMPLES} readings in a row \
                 ({sensor_bits})"
            ),
            |h| i64::from(h.sensors_stuck),
        ),
    ];
    for (name, off, what, g) in sensor_faults {
        v.push(one(b(name, off, Wire::U8, "sensor_mask", &what), g));
    }
    v.push(one(
        b(
            "thermal_state",
            hk_field::THERMAL_STATE.start,
            Wire::U8,
            "thermal_state",
            "thermal compensation and exposure hold: bit 0 compensation enabled, bit 1 \
             frozen by a faulty sensor, bit 2 exposure hold in force",
        ),
        |h| i64::from(h.thermal_state),
    ));
    let offsets: [HkGetter; LEGS] = leg_getters!(thermal_offsets_nm);
    let fields = offsets
        .into_iter()
        .enumerate()
        .map(|(i, g)| {
            (
                calibrated(
                    &format!("thermal_offset_leg{}", i + 1),
                    hk_field::THERMAL_OFFSETS.start + 4 * i,
                    Wire::I32,
                    UNIT_UM,
                    UM_PER_NM,
                    &format!(
                        "leg {}: thermal compensation's applied stroke offset (um; wire i32 in nm)",
                        i + 1
                    ),
                ),
                Some(g),
            )
        })
        .collect();
    v.push(HkRow::group(
        format!(
            "thermal compensation's applied stroke offsets, legs 1..{LEGS} (nm, along base z): \
             the drives hold the reported strokes plus these"
        ),
        fields,
    ));
    v
}

/// Engineering unit of temperatures.
pub const UNIT_K: &str = "K";
/// Kelvin per raw unit of a housekeeping temperature.
pub const K_PER_CENTI_K: f64 = 0.01;

/// The housekeeping fields with their accessors into [`Housekeeping`]: the fields of
/// [`housekeeping_rows`], in order.
pub fn housekeeping_fields() -> Vec<(Field, Option<HkGetter>)> {
    housekeeping_rows()
        .into_iter()
        .flat_map(|r| r.fields)
        .collect()
}
