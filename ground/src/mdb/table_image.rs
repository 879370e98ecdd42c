//! The parameter table image (TC[6,2] chunks, TM[6,6] dumps).

use serde::Serialize;

use super::names::{hex4, uniform};
use m2ctl::kinematics::{GeometryError, LEGS};
use m2ctl::table::{Table, TableError, ValidationError, TABLE_LEN};
use m2ctl::thermal as th;

/// The validation's code and detail for a thermal model field (`thermal::ThermalModelError::code`).
fn thermal_code(field: u8) -> String {
    format!(
        "{} detail {field}",
        hex4(ValidationError::Thermal { field }.code())
    )
}

/// One row of the table image's layout (docs/icd.md section 5; little-endian).
#[derive(Clone, Debug, Serialize)]
pub struct TableImageRow {
    /// Offset in the image (bytes).
    pub offset: usize,
    /// Size (bytes).
    pub size: usize,
    /// Type as docs/icd.md writes it (`u16`, `36 × f64`, `ASCII`, `bytes`).
    pub ty: String,
    /// What it holds.
    pub field: String,
    /// Unit (empty: none).
    pub unit: &'static str,
    /// What validation accepts (with the refusal codes).
    pub validation: String,
    /// The row's bytes in an image of this table (checked against [`Table::to_bytes`] by
    /// `ground/tests/icd.rs`).
    #[serde(skip)]
    pub bytes_of: fn(&Table) -> Vec<u8>,
}

fn f64s_le(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The table image's rows, in offset order (they tile [`TABLE_LEN`] bytes): offsets and
/// sizes are the flight code's named fields (`m2ctl::table::layout::field`).
pub fn table_image() -> Vec<TableImageRow> {
    use m2ctl::link::wire::Field;
    use m2ctl::table::layout::{
        field, JOINT_COORDS, TABLE_CRC_OFFSET, TABLE_FORMAT_VERSION, TABLE_MAGIC,
    };
    #[derive(Clone, Copy)]
    enum Ty {
        Bytes,
        Ascii,
        U16,
        U32,
        F32,
        F64,
    }
    let validation = m2ctl::table::ValidationConfig::flight();
    let (ws_mm, ws_arcsec) = super::names::workspace_caps();
    let code = |e: ValidationError| hex4(e.code());
    let non_finite = code(ValidationError::NonFinite { field: 0 });
    let dev = uniform(&[validation.max_coordinate_deviation_mm]);
    let cap = uniform(&[validation.max_abs_stroke_limit_mm]);
    let stroke_cap = code(ValidationError::StrokeLimitBeyondCap { leg: 0 });
    let ws_cap = code(ValidationError::WorkspaceBeyondCap { axis: 0 });
    let legs = format!("legs 1..{LEGS}");
    type Row = (
        Ty,
        Field,
        String,
        &'static str,
        String,
        fn(&Table) -> Vec<u8>,
    );
    let rows: Vec<Row> = vec![
        (
            Ty::Bytes,
            field::MAGIC,
            format!("magic `\"{}\"`", String::from_utf8_lossy(&TABLE_MAGIC)),
            "",
            "exact".into(),
            |_| TABLE_MAGIC.to_vec(),
        ),
        (
            Ty::U16,
            field::FORMAT_VERSION,
            "format version".into(),
            "",
            format!("{TABLE_FORMAT_VERSION}"),
            |_| TABLE_FORMAT_VERSION.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            field::LENGTH,
            "total length, CRC included".into(),
            "bytes",
            format!("{TABLE_LEN}"),
            |_| u16::try_from(TABLE_LEN).unwrap_or(0).to_le_bytes().to_vec(),
        ),
        (
            Ty::U32,
            field::TABLE_ID,
            "table ID (reported in HK)".into(),
            "",
            "any".into(),
            |t| t.table_id.to_le_bytes().to_vec(),
        ),
        (
            Ty::U32,
            field::CALIBRATION_ID,
            "calibration ID".into(),
            "",
            "any".into(),
            |t| t.provenance.calibration_id.to_le_bytes().to_vec(),
        ),
        (
            Ty::Ascii,
            field::PROVENANCE_TAG,
            "provenance tag, NUL/space padded".into(),
            "",
            format!(
                "printable ASCII or NUL ({})",
                code(ValidationError::ProvenanceNotAscii { index: 0 })
            ),
            |t| t.provenance.tag.to_vec(),
        ),
        (
            Ty::F64,
            field::JOINTS,
            format!(
                "joint centres, leg-major: leg i (1..{LEGS}) at this offset + {} (i - 1): `a.x \
                 a.y a.z` (frame B, zero stroke), then `b.x b.y b.z` (frame M)",
                JOINT_COORDS / LEGS * core::mem::size_of::<f64>()
            ),
            "mm",
            format!(
                "finite ({non_finite}); within {dev} mm of nominal ({}); rod length within {} mm \
                 of nominal ({}); upper joint >= {} mm above the lower at home ({})",
                code(ValidationError::CoordinateOffNominal { index: 0 }),
                uniform(&[validation.max_rod_deviation_mm]),
                code(ValidationError::RodLengthImplausible { leg: 0 }),
                uniform(&[m2ctl::kinematics::geometry::MIN_ROD_VERTICAL_MM]),
                code(ValidationError::Geometry(GeometryError::NonFinite)),
            ),
            |t| {
                t.legs
                    .iter()
                    .flat_map(|l| f64s_le(&l.a_mm).into_iter().chain(f64s_le(&l.b_mm)))
                    .collect()
            },
        ),
        (
            Ty::F64,
            field::P0,
            "p0: home position of M's origin in B".into(),
            "mm",
            format!("finite, within {dev} mm of nominal"),
            |t| f64s_le(&t.p0_mm),
        ),
        (
            Ty::F64,
            field::STROKE_MIN,
            format!("slider stroke lower limits, {legs}"),
            "mm",
            format!("finite; >= -{cap} mm ({stroke_cap}); contains 0"),
            |t| f64s_le(&t.stroke_limits.min_mm),
        ),
        (
            Ty::F64,
            field::STROKE_MAX,
            format!("slider stroke upper limits, {legs}"),
            "mm",
            format!("finite; <= {cap} mm ({stroke_cap}); contains 0"),
            |t| f64s_le(&t.stroke_limits.max_mm),
        ),
        (
            Ty::F64,
            field::WORKSPACE_TRANSLATION,
            "workspace half-range x, y, z (base axes)".into(),
            "mm",
            format!("finite, >= 0, <= {} mm ({ws_cap})", ws_mm),
            |t| f64s_le(&t.workspace.translation_mm),
        ),
        (
            Ty::F64,
            field::WORKSPACE_ROTATION,
            "workspace half-range alpha, beta, gamma".into(),
            "rad",
            format!("finite, >= 0, <= {} arcsec ({ws_cap})", ws_arcsec),
            |t| f64s_le(&t.workspace.rotation_rad),
        ),
        (
            Ty::F32,
            field::FOLLOWING_ERROR_WARNING,
            "following-error warning threshold".into(),
            "mm",
            format!(
                "> 0, < fault threshold ({})",
                code(ValidationError::Supervision { field: 0 })
            ),
            |t| {
                t.supervision
                    .following_error_warning_mm
                    .to_le_bytes()
                    .to_vec()
            },
        ),
        (
            Ty::F32,
            field::FOLLOWING_ERROR_FAULT,
            "following-error fault threshold".into(),
            "mm",
            "> 0".into(),
            |t| {
                t.supervision
                    .following_error_fault_mm
                    .to_le_bytes()
                    .to_vec()
            },
        ),
        (
            Ty::F32,
            field::ENCODER_JUMP,
            "encoder jump threshold".into(),
            "mm per control cycle",
            "> 0".into(),
            |t| {
                t.supervision
                    .encoder_jump_mm_per_cycle
                    .to_le_bytes()
                    .to_vec()
            },
        ),
        (
            Ty::F32,
            field::STUCK_MIN_PROGRESS,
            "stuck detection: least progress counted as motion".into(),
            "mm",
            "> 0".into(),
            |t| t.supervision.stuck_min_progress_mm.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            field::STUCK_DETECTION_CYCLES,
            "stuck detection window".into(),
            "control cycles",
            "> 0".into(),
            |t| t.supervision.stuck_detection_cycles.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            field::WARNING_DEBOUNCE,
            "warning debounce".into(),
            "control cycles",
            "> 0".into(),
            |t| t.supervision.warning_debounce_cycles.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            field::FAULT_DEBOUNCE,
            "fault debounce".into(),
            "control cycles",
            "> 0".into(),
            |t| t.supervision.fault_debounce_cycles.to_le_bytes().to_vec(),
        ),
        (
            Ty::U16,
            field::RESERVED,
            "reserved".into(),
            "",
            format!("0 ({})", hex4(TableError::ReservedNotZero.code())),
            |_| 0u16.to_le_bytes().to_vec(),
        ),
        (
            Ty::F32,
            field::THERMAL_REFERENCE,
            "thermal model: reference temperature of the geometry".into(),
            "deg C",
            format!(
                "{}..{} ({})",
                th::SENSOR_MIN_C,
                th::SENSOR_MAX_C,
                thermal_code(1)
            ),
            |t| t.thermal.reference_c.to_le_bytes().to_vec(),
        ),
        (
            Ty::F32,
            field::THERMAL_EXPANSION,
            "thermal model: expansion coefficient of rods, slider columns, base plate, platform"
                .into(),
            "1/K",
            format!("0..{:e} ({})", th::MAX_EXPANSION_PER_K, thermal_code(2)),
            |t| {
                t.thermal
                    .expansion_per_k
                    .iter()
                    .flat_map(|a| a.to_le_bytes())
                    .collect()
            },
        ),
        (
            Ty::F32,
            field::THERMAL_COLUMN_LENGTH,
            "thermal model: slider column length, foot to lower joint at zero stroke".into(),
            "mm",
            format!("0..{} ({})", th::MAX_COLUMN_LENGTH_MM, thermal_code(3)),
            |t| t.thermal.column_length_mm.to_le_bytes().to_vec(),
        ),
        (
            Ty::Bytes,
            field::THERMAL_SENSORS,
            "thermal model: sensor governing each part (leg-major; rod, column, base, platform)"
                .into(),
            "",
            format!("0..{} ({})", th::TEMP_SENSORS - 1, thermal_code(4)),
            |t| t.thermal.sensor_of.iter().flatten().copied().collect(),
        ),
        (
            Ty::U32,
            field::CRC,
            format!("CRC-32/ISO-HDLC (zlib) of bytes 0..{TABLE_CRC_OFFSET}"),
            "",
            format!("must match ({})", hex4(TableError::BadCrc.code())),
            |t| t.crc32().to_le_bytes().to_vec(),
        ),
    ];
    rows.into_iter()
        .map(|(ty, range, field, unit, validation, bytes_of)| {
            let (elem, name) = match ty {
                Ty::Bytes => (1, "bytes"),
                Ty::Ascii => (1, "ASCII"),
                Ty::U16 => (2, "u16"),
                Ty::U32 | Ty::F32 => (4, if matches!(ty, Ty::U32) { "u32" } else { "f32" }),
                Ty::F64 => (8, "f64"),
            };
            let n = range.len() / elem;
            let ty = match ty {
                Ty::Bytes | Ty::Ascii => name.to_string(),
                _ if n == 1 => name.to_string(),
                _ => format!("{n} × {name}"),
            };
            TableImageRow {
                offset: range.start,
                size: range.len(),
                ty,
                field,
                unit,
                validation,
                bytes_of,
            }
        })
        .collect()
}
