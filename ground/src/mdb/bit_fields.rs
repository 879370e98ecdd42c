//! Bit fields: fault and warning flags, bank status flags, refusal bits, leg masks.

use super::fields::POSE_AXES;
use super::names::hex4;
use m2ctl::kinematics::{Refusals, LEGS};
use m2ctl::link::tm::event_id;
use m2ctl::supervision::FaultFlags;
use m2ctl::table::{TableError, ValidationError};

/// Bit position of a one-bit word.
fn bit_of(word: u32) -> u32 {
    word.trailing_zeros()
}

/// One fault or warning flag: bit, label, its name in docs/icd.md (section 6) and what
/// it means (the mission database's bit description).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FlagDoc {
    /// Bit position (from [`FaultFlags`]).
    pub bit: u32,
    /// Label (the `FaultFlags` constant's name).
    pub label: &'static str,
    /// Its name in docs/icd.md.
    pub name: String,
    /// What it means.
    pub meaning: &'static str,
    /// A warning (not latched), not a fault.
    pub warning: bool,
}

/// The fault and warning flags, bits from [`FaultFlags`].
pub fn fault_flags_doc() -> Vec<FlagDoc> {
    let flags: [(FaultFlags, String, &str); FaultFlags::NAMED.len()] = [
        (
            FaultFlags::FOLLOWING_ERROR,
            "following error".into(),
            "fault: |measured - commanded stroke| above the fault threshold",
        ),
        (
            FaultFlags::ENCODER_STUCK,
            "encoder stuck".into(),
            "fault: encoder makes no progress while its slider moves",
        ),
        (
            FaultFlags::ENCODER_JUMP,
            "encoder jump".into(),
            "fault: encoder changed more than physically possible in one cycle",
        ),
        (
            FaultFlags::ENCODER_READ_FAILURE,
            "encoder read failure".into(),
            "fault: encoder did not answer, corrupted or non-finite",
        ),
        (
            FaultFlags::SOFT_LIMIT,
            "slider beyond soft limit".into(),
            "fault: measured stroke beyond the soft limit",
        ),
        (
            FaultFlags::FK_NOT_CONVERGED,
            "FK not converged".into(),
            "fault: FK of the measured strokes failed",
        ),
        (
            FaultFlags::POSE_OUTSIDE_WORKSPACE,
            "pose outside workspace".into(),
            "fault: measured pose outside the workspace",
        ),
        (
            FaultFlags::DRIVE_FAULT,
            "drive fault".into(),
            "fault: a drive reported a fault",
        ),
        (
            FaultFlags::TABLE_CORRUPT,
            "running table, parameters or settings corrupt in RAM (scrub, checks)".into(),
            "fault: the running table, geometry, thresholds or parameters in RAM failed the \
             scrub or their check",
        ),
        (
            FaultFlags::DEADLINE_MISSED,
            format!(
                "deadline missed ({} consecutive control-cycle overruns)",
                m2ctl::controller::OVERRUN_HOLD_LIMIT
            ),
            "fault: control cycles overran their period 3 times in a row",
        ),
        (
            FaultFlags::LIMIT_SWITCH,
            "end of travel (an end-of-travel switch active or a switch input unreadable)".into(),
            "fault: an end-of-travel switch active, or a switch input unreadable",
        ),
        (
            FaultFlags::OUTPUT_LIMITED,
            "output limited (a stroke step beyond the speed or acceleration limit was clamped: \
             geometry or planner wrong; the drives held at once)"
                .into(),
            "fault: the output stage clamped a stroke step beyond the speed or acceleration \
             limit",
        ),
        (
            FaultFlags::FOLLOWING_WARNING,
            "following error above the warning threshold".into(),
            "warning: following error above the warning threshold",
        ),
        (
            FaultFlags::ENCODER_WARNING,
            format!(
                "encoder warning (the encoder's own warning bit: position valid, maintenance \
                 asked for; legs in event {}, not latched, motion goes on)",
                hex4(event_id::WARNING_CHANGED)
            ),
            "warning: an encoder reports its warning bit (maintenance: e.g. a dirty scale)",
        ),
    ];
    flags
        .into_iter()
        .map(|(f, name, meaning)| FlagDoc {
            bit: bit_of(f.bits()),
            label: f.name().unwrap_or("?"),
            name,
            meaning,
            warning: FaultFlags::ALL_WARNINGS.contains(f),
        })
        .collect()
}

/// The fault and warning flags as (bit, label, meaning), bits from [`FaultFlags`].
pub fn fault_flag_bits() -> Vec<(u32, String, String)> {
    fault_flags_doc()
        .into_iter()
        .map(|f| (f.bit, f.label.to_string(), f.meaning.to_string()))
        .collect()
}

/// The status flags of one flash bank in the boot flags (event BOOT_DETAIL aux0), from
/// [`m2ctl::table::BankStatus::flag`]: (bit, what).
pub fn bank_status_flags() -> Vec<(u32, &'static str)> {
    use m2ctl::table::BankStatus;
    let all = [
        BankStatus::Blank,
        BankStatus::ReadFailed,
        BankStatus::HeaderCorrupt,
        BankStatus::BodyCorrupt(TableError::BadCrc),
        BankStatus::Rejected(ValidationError::BadConfig),
        BankStatus::Standby { sequence: 0 },
        BankStatus::Active { sequence: 0 },
    ];
    all.iter()
        .map(|b| {
            // Exhaustive: a new status does not compile until it is named here.
            let what = match b {
                BankStatus::Blank => "blank",
                BankStatus::ReadFailed => "read failed",
                BankStatus::HeaderCorrupt => "header corrupt",
                BankStatus::BodyCorrupt(_) => "body corrupt",
                BankStatus::Rejected(_) => "refused by validation",
                BankStatus::Standby { .. } => "valid standby",
                BankStatus::Active { .. } => "selected and running",
            };
            (bit_of(u32::from(b.flag())), what)
        })
        .collect()
}

/// The refusal bits, positions from [`Refusals::to_bits`].
pub fn refusal_bits() -> Vec<(u32, String, String)> {
    let mut v = vec![(
        bit_of(
            Refusals {
                non_finite: true,
                ..Refusals::default()
            }
            .to_bits(),
        ),
        "NON_FINITE".to_string(),
        "a pose component is NaN or infinite".to_string(),
    )];
    for leg in 0..LEGS {
        let m = 1u8 << leg;
        let one = |r: Refusals| bit_of(r.to_bits());
        v.push((
            one(Refusals {
                legs_above_max: m,
                ..Refusals::default()
            }),
            format!("LEG{}_ABOVE_MAX", leg + 1),
            format!("leg {} above the upper stroke limit", leg + 1),
        ));
        v.push((
            one(Refusals {
                legs_unreachable: m,
                ..Refusals::default()
            }),
            format!("LEG{}_UNREACHABLE", leg + 1),
            format!("leg {} cannot reach", leg + 1),
        ));
        v.push((
            one(Refusals {
                legs_below_min: m,
                ..Refusals::default()
            }),
            format!("LEG{}_BELOW_MIN", leg + 1),
            format!("leg {} below the lower stroke limit", leg + 1),
        ));
    }
    for (axis, name) in POSE_AXES.iter().enumerate() {
        v.push((
            bit_of(
                Refusals {
                    axes_outside: 1 << axis,
                    ..Refusals::default()
                }
                .to_bits(),
            ),
            format!("{}_OUTSIDE_WORKSPACE", name.to_ascii_uppercase()),
            format!("axis {name} beyond the workspace half-range"),
        ));
    }
    v.sort_by_key(|b| b.0);
    v
}

pub(super) fn leg_mask_bits() -> Vec<(u32, String, String)> {
    (0..LEGS as u32)
        .map(|i| {
            (
                i,
                format!("LEG{}", i + 1),
                format!("leg {} (bit i = leg i+1)", i + 1),
            )
        })
        .collect()
}

/// Temperature sensor masks (housekeeping): bit i = sensor i (0-based, the channel of
/// the thermal model's `sensor_of`).
pub(super) fn sensor_mask_bits() -> Vec<(u32, String, String)> {
    (0..m2ctl::thermal::TEMP_SENSORS as u32)
        .map(|i| {
            (
                i,
                format!("SENSOR{i}"),
                format!("temperature sensor {i} (bit i = sensor i)"),
            )
        })
        .collect()
}

/// The bits of housekeeping's `thermal_state` (`link::hk::thermal_state`).
pub(super) fn thermal_state_bits() -> Vec<(u32, String, String)> {
    use m2ctl::link::hk::thermal_state::{ENABLED, EXPOSURE_HOLD, FROZEN};
    [
        (
            ENABLED,
            "ENABLED",
            "thermal compensation enabled (parameter 0x0060)",
        ),
        (
            FROZEN,
            "FROZEN",
            "compensation frozen at its last offset by a faulty sensor",
        ),
        (
            EXPOSURE_HOLD,
            "EXPOSURE_HOLD",
            "an exposure hold is in force",
        ),
    ]
    .into_iter()
    .map(|(bit, name, doc)| (bit.trailing_zeros(), name.to_string(), doc.to_string()))
    .collect()
}
