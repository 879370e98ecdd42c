//! Field constructors: plain, counted, calibrated, ranged, fixed, a wire pose, an
//! on-board time.

use super::{Field, Meaning, Wire, CUC_COARSE_BYTES, UNIT_ARCSEC, UNIT_UM};
use m2ctl::link::tm::TIME_FRACTIONS_PER_SECOND;
use m2ctl::units::{ARCSEC_PER_UAS, UM_PER_NM};

pub(super) fn field(
    name: &str,
    offset: usize,
    wire: Wire,
    meaning: Meaning,
    description: &str,
) -> Field {
    Field {
        name: name.into(),
        offset,
        wire,
        fraction_digits: meaning.fraction_digits(),
        meaning,
        description: description.into(),
    }
}

pub(super) fn count(name: &str, offset: usize, wire: Wire, description: &str) -> Field {
    field(
        name,
        offset,
        wire,
        Meaning::Number {
            unit: None,
            scale: 1.0,
            range: None,
        },
        description,
    )
}

pub(super) fn calibrated(
    name: &str,
    offset: usize,
    wire: Wire,
    unit: &'static str,
    scale: f64,
    description: &str,
) -> Field {
    let range = wire
        .raw_range()
        .map(|(lo, hi)| (lo as f64 * scale, hi as f64 * scale));
    field(
        name,
        offset,
        wire,
        Meaning::Number {
            unit: Some(unit),
            scale,
            range,
        },
        description,
    )
}

/// `f` with its valid range narrowed to `lo..=hi` (engineering units): the controller's
/// own, where it is narrower than the wire's.
pub(super) fn ranged(mut f: Field, lo: f64, hi: f64) -> Field {
    if let Meaning::Number { range, .. } = &mut f.meaning {
        *range = Some((lo, hi));
    }
    f
}

/// Axis names of a pose, in wire order.
pub const POSE_AXES: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// The six fields of a wire pose at `offset`: translations in um (raw nm), rotations in
/// arcsec (raw micro-arcseconds).
pub(super) fn pose_fields(prefix: &str, offset: usize, what: &str) -> Vec<Field> {
    POSE_AXES
        .iter()
        .enumerate()
        .map(|(k, axis)| {
            let (unit, scale, frame) = if k < 3 {
                (
                    UNIT_UM,
                    UM_PER_NM,
                    "translation of the moving-platform origin from p0 along base axis",
                )
            } else {
                (
                    UNIT_ARCSEC,
                    ARCSEC_PER_UAS,
                    "rotation R = Rz(gamma) Ry(beta) Rx(alpha), angle about axis",
                )
            };
            calibrated(
                &format!("{prefix}{axis}"),
                offset + 4 * k,
                Wire::I32,
                unit,
                scale,
                &format!("{what}: {frame} {axis} ({unit}; wire i32 in {})", {
                    if k < 3 {
                        "nm"
                    } else {
                        "micro-arcsec"
                    }
                }),
            )
        })
        .collect()
}

pub(super) fn fixed(name: &str, offset: usize, wire: Wire, value: i64, description: &str) -> Field {
    field(name, offset, wire, Meaning::Fixed { value }, description)
}

/// Seconds per CUC fraction (engineering unit of a CUC fine field).
pub const S_PER_CUC_FRACTION: f64 = 1.0 / TIME_FRACTIONS_PER_SECOND as f64;

/// The two fields of a CUC 4+2 on-board time at `offset`: seconds (u32) and the
/// fraction (u16, calibrated to seconds).
pub(super) fn obt_fields(prefix: &str, offset: usize, what: &str) -> Vec<Field> {
    vec![
        field(
            &format!("{prefix}seconds"),
            offset,
            Wire::U32,
            Meaning::Number {
                unit: Some("s"),
                scale: 1.0,
                range: None,
            },
            &format!("{what}: whole seconds of on-board time since boot (CUC coarse)"),
        ),
        calibrated(
            &format!("{prefix}fraction"),
            offset + CUC_COARSE_BYTES,
            Wire::U16,
            "s",
            S_PER_CUC_FRACTION,
            &format!("{what}: fraction of a second (s; wire u16 in 1/65536 s, CUC fine)"),
        ),
    ]
}
