//! Ground-side file formats: the geometry file (`geometry.toml` format, with an optional
//! `[limits]` extension) and the pose/stroke CSV (`ik_golden.csv` column format).
//!
//! Every error names the file line and the problem.
//!
//! ## Geometry file
//! ```toml
//! p0 = [0.0, 0.0, -150.0]          # home position of M's origin in B (mm)
//! [[leg]]                          # exactly six, in slider order
//! a = [67.8981, 61.7825, -134.1]   # lower joint at zero stroke, frame B (mm)
//! b = [103.3452, 35.5846, 85.7]    # upper joint, frame M (mm)
//! # ... five more [[leg]] tables
//! [limits]                         # optional extension; omitted = no limits applied
//! stroke_min_mm = -5.0             # a number for all sliders, or six numbers
//! stroke_max_mm = 5.0
//! translation_mm = 2.0             # workspace half-range: a number or [x, y, z]
//! rotation_arcsec = 600.0          # workspace half-range: a number or [alpha, beta, gamma]
//! [provenance]                     # optional, free text carried through by the tools
//! calibration_id = "..."
//! ```
//! Within `[limits]`, the stroke pair and the workspace pair are each all-or-nothing.
//! Two legs whose lower (or upper) joints are closer than [`MIN_JOINT_SPACING_MM`] are
//! refused: a duplicated leg is a copy-paste error, and its Jacobian is singular.

use std::fmt;
use std::ops::Range;

use serde::Deserialize;
use toml::Spanned;

use m2ctl::kinematics::{
    GeometryError, GeometryParams, LegParams, StrokeLimits, WorkspaceLimits, LEGS,
};
use m2ctl::table::{ValidationConfig, ValidationError};
use m2ctl::units::ARCSEC_PER_RAD;

/// Smallest distance between the lower joints (or between the upper joints) of two legs
/// (mm). Real spherical joints are tens of mm apart; closer than this is a duplicated leg.
pub const MIN_JOINT_SPACING_MM: f64 = 1.0;

/// A file problem, with the 1-based line where it was found (0 when it concerns the
/// whole file).
#[derive(Clone, Debug, PartialEq)]
pub struct FileError {
    /// 1-based line number, 0 if not tied to a line.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(f, "line {}: {}", self.line, self.message)
        } else {
            write!(f, "{}", self.message)
        }
    }
}

impl std::error::Error for FileError {}

/// A [`FileError`] at `line` (1-based, 0 for the whole file); the file readers of the
/// crate all build their errors with it.
pub(crate) fn err(line: usize, message: impl Into<String>) -> FileError {
    FileError {
        line,
        message: message.into(),
    }
}

/// The 1-based line of `text` where the byte range `span` (a TOML span) starts.
pub(crate) fn line_of(text: &str, span: &Range<usize>) -> usize {
    let end = span.start.min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|b| **b == b'\n')
        .count()
        + 1
}

/// Deserialises a TOML file, a syntax or schema error named by its line.
pub(crate) fn parse_toml<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, FileError> {
    toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, &s)).unwrap_or(0);
        err(line, e.message().trim().to_string())
    })
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLeg {
    a: Spanned<[f64; 3]>,
    b: Spanned<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum OneOrMany {
    One(f64),
    Many(Vec<f64>),
}

/// A number for every slot, or exactly `N` numbers.
fn expand<const N: usize>(
    text: &str,
    v: &Spanned<OneOrMany>,
    what: &str,
) -> Result<[f64; N], FileError> {
    match v.get_ref() {
        OneOrMany::One(x) => Ok([*x; N]),
        OneOrMany::Many(xs) => <[f64; N]>::try_from(xs.as_slice()).map_err(|_| {
            err(
                line_of(text, &v.span()),
                format!(
                    "{what}: expected one number or {N} numbers, found {}",
                    xs.len()
                ),
            )
        }),
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLimits {
    stroke_min_mm: Option<Spanned<OneOrMany>>,
    stroke_max_mm: Option<Spanned<OneOrMany>>,
    translation_mm: Option<Spanned<OneOrMany>>,
    rotation_arcsec: Option<Spanned<OneOrMany>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGeometry {
    p0: Spanned<[f64; 3]>,
    leg: Spanned<Vec<RawLeg>>,
    limits: Option<Spanned<RawLimits>>,
    provenance: Option<toml::Table>,
}

/// A geometry file's content.
#[derive(Clone, Debug, PartialEq)]
pub struct GeometryFile {
    /// The parameters (validated).
    pub params: GeometryParams,
    /// Free-text provenance entries (`[provenance]`), in file order of keys.
    pub provenance: Vec<(String, String)>,
}

fn check_finite(text: &str, span: &Range<usize>, what: &str, v: &[f64]) -> Result<(), FileError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(err(
            line_of(text, span),
            format!("{what}: every value must be a finite number, got {v:?}"),
        ))
    }
}

/// Parses a geometry file's text.
pub fn parse_geometry(text: &str) -> Result<GeometryFile, FileError> {
    let raw: RawGeometry = parse_toml(text)?;
    check_finite(text, &raw.p0.span(), "p0", raw.p0.get_ref())?;
    let legs_raw = raw.leg.get_ref();
    if legs_raw.len() != LEGS {
        return Err(err(
            line_of(text, &raw.leg.span()),
            format!(
                "expected exactly {LEGS} [[leg]] tables, found {}",
                legs_raw.len()
            ),
        ));
    }
    let mut legs = [LegParams {
        a_mm: [0.0; 3],
        b_mm: [0.0; 3],
    }; LEGS];
    for (i, (out, l)) in legs.iter_mut().zip(legs_raw.iter()).enumerate() {
        check_finite(
            text,
            &l.a.span(),
            &format!("leg {} a", i + 1),
            l.a.get_ref(),
        )?;
        check_finite(
            text,
            &l.b.span(),
            &format!("leg {} b", i + 1),
            l.b.get_ref(),
        )?;
        *out = LegParams {
            a_mm: *l.a.get_ref(),
            b_mm: *l.b.get_ref(),
        };
    }
    check_distinct_legs(text, legs_raw, &legs)?;
    let mut params = GeometryParams::new(legs, *raw.p0.get_ref());
    if let Some(lim) = &raw.limits {
        let lim_line = line_of(text, &lim.span());
        let lim = lim.get_ref();
        match (&lim.stroke_min_mm, &lim.stroke_max_mm) {
            (Some(lo), Some(hi)) => {
                let min_mm = expand::<LEGS>(text, lo, "stroke_min_mm")?;
                let max_mm = expand::<LEGS>(text, hi, "stroke_max_mm")?;
                check_finite(text, &lo.span(), "stroke_min_mm", &min_mm)?;
                check_finite(text, &hi.span(), "stroke_max_mm", &max_mm)?;
                params.stroke_limits = Some(StrokeLimits { min_mm, max_mm });
            }
            (None, None) => {}
            _ => {
                return Err(err(
                    lim_line,
                    "[limits]: give both stroke_min_mm and stroke_max_mm, or neither",
                ));
            }
        }
        match (&lim.translation_mm, &lim.rotation_arcsec) {
            (Some(t), Some(r)) => {
                let translation_mm = expand::<3>(text, t, "translation_mm")?;
                let rotation_arcsec = expand::<3>(text, r, "rotation_arcsec")?;
                check_finite(text, &t.span(), "translation_mm", &translation_mm)?;
                check_finite(text, &r.span(), "rotation_arcsec", &rotation_arcsec)?;
                params.workspace = Some(WorkspaceLimits {
                    translation_mm,
                    rotation_rad: rotation_arcsec.map(|a| a / ARCSEC_PER_RAD),
                });
            }
            (None, None) => {}
            _ => {
                return Err(err(
                    lim_line,
                    "[limits]: give both translation_mm and rotation_arcsec, or neither",
                ));
            }
        }
    }
    params.validate().map_err(|e| {
        let line = match e {
            GeometryError::UpperNotAboveLower { leg } => legs_raw
                .get(usize::from(leg))
                .map(|l| line_of(text, &l.a.span()))
                .unwrap_or(0),
            _ => raw
                .limits
                .as_ref()
                .map(|l| line_of(text, &l.span()))
                .unwrap_or(0),
        };
        err(line, describe_geometry_error(&e))
    })?;
    let provenance = raw
        .provenance
        .map(|t| {
            t.into_iter()
                .map(|(k, v)| {
                    let s = match v {
                        toml::Value::String(s) => s,
                        other => other.to_string(),
                    };
                    (k, s)
                })
                .collect()
        })
        .unwrap_or_default();
    Ok(GeometryFile { params, provenance })
}

fn distance_mm(p: &[f64; 3], q: &[f64; 3]) -> f64 {
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

/// Refuses two legs sharing a lower or an upper joint (closer than
/// [`MIN_JOINT_SPACING_MM`]), at the later leg's line.
fn check_distinct_legs(
    text: &str,
    raw: &[RawLeg],
    legs: &[LegParams; LEGS],
) -> Result<(), FileError> {
    for (j, (lj, rj)) in legs.iter().zip(raw.iter()).enumerate() {
        for (i, li) in legs.iter().enumerate().take(j) {
            for (what, p, q, span) in [
                ("lower joint a", &lj.a_mm, &li.a_mm, rj.a.span()),
                ("upper joint b", &lj.b_mm, &li.b_mm, rj.b.span()),
            ] {
                let d = distance_mm(p, q);
                if d < MIN_JOINT_SPACING_MM {
                    return Err(err(
                        line_of(text, &span),
                        format!(
                            "leg {}: {what} is {d:.3} mm from leg {}'s (a duplicated leg?); joints of different legs must be at least {MIN_JOINT_SPACING_MM} mm apart",
                            j + 1,
                            i + 1
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Plain-words description of a flight-validation refusal
/// ([`m2ctl::table::validate()`]), with its telemetry code and detail word.
pub fn describe_validation_error(e: &ValidationError) -> String {
    let legs = |mask: u8| {
        (0..LEGS)
            .filter(|i| mask & (1 << i) != 0)
            .map(|i| (i + 1).to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let what = match e {
        ValidationError::ProvenanceNotAscii { index } => {
            format!("provenance tag byte {index} is not printable ASCII")
        }
        ValidationError::NonFinite { field } => format!("field {field} is not finite"),
        ValidationError::CoordinateOffNominal { index } => {
            let name = if usize::from(*index) < m2ctl::table::layout::JOINT_COORDS {
                crate::calib::param_name(usize::from(*index))
            } else {
                format!(
                    "p0[{}]",
                    usize::from(*index) - m2ctl::table::layout::JOINT_COORDS
                )
            };
            format!(
                "{name} is more than {} mm from nominal",
                m2ctl::table::validate::DEFAULT_MAX_COORDINATE_DEVIATION_MM
            )
        }
        ValidationError::RodLengthImplausible { leg } => format!(
            "rod {} is more than {} mm longer or shorter than nominal",
            leg + 1,
            m2ctl::table::validate::DEFAULT_MAX_ROD_DEVIATION_MM
        ),
        ValidationError::Geometry(g) => describe_geometry_error(g),
        ValidationError::StrokeLimitBeyondCap { leg } => format!(
            "slider {} stroke limit beyond the compiled-in +-{} mm",
            leg + 1,
            m2ctl::nominal::STROKE_LIMIT_MM
        ),
        ValidationError::WorkspaceBeyondCap { axis } => format!(
            "workspace half-range of axis {} beyond the compiled-in cap",
            ["x", "y", "z", "alpha", "beta", "gamma"]
                .get(usize::from(*axis))
                .unwrap_or(&"?")
        ),
        ValidationError::Thermal { field } => {
            use m2ctl::thermal as th;
            let what = match field {
                1 => format!(
                    "reference temperature (allowed {}..{} C)",
                    th::SENSOR_MIN_C,
                    th::SENSOR_MAX_C
                ),
                2 => format!(
                    "expansion coefficient (allowed 0..{:e} per K)",
                    th::MAX_EXPANSION_PER_K
                ),
                3 => format!("column length (allowed 0..{} mm)", th::MAX_COLUMN_LENGTH_MM),
                4 => format!("sensor index (allowed 0..{})", th::TEMP_SENSORS - 1),
                _ => format!("field {field}"),
            };
            format!("thermal model: {what} out of range")
        }
        ValidationError::Supervision { field } => {
            format!("supervision threshold {field} not positive or not ordered")
        }
        ValidationError::Unreachable { legs: m } => {
            format!("leg {} cannot reach part of the workspace", legs(*m))
        }
        ValidationError::StrokeLimitExceeded { legs: m } => format!(
            "slider {} would exceed its stroke limits inside the workspace",
            legs(*m)
        ),
        ValidationError::FkFailed { corner, .. } => {
            format!("forward kinematics fails at workspace corner {corner}")
        }
        ValidationError::FkInaccurate { corner } => {
            format!("forward kinematics inaccurate at workspace corner {corner}")
        }
        ValidationError::BadConfig => "validation configuration out of range".into(),
    };
    format!(
        "the flight validation refuses this table: {what} (code {:#06x}, detail {:#06x})",
        e.code(),
        e.detail()
    )
}

/// Runs the flight code's table validation ([`m2ctl::table::validate()`] with
/// [`ValidationConfig::flight`]) on a geometry, as the controller will before it stores
/// the table. A geometry without `[limits]` is checked with the compiled-in flight
/// limits (those a table built from it for upload would need to carry).
pub fn validate_for_flight(params: &GeometryParams) -> Result<(), String> {
    let mut g = *params;
    let flight = m2ctl::nominal::prototype_with_flight_limits();
    if g.stroke_limits.is_none() {
        g.stroke_limits = flight.stroke_limits;
    }
    if g.workspace.is_none() {
        g.workspace = flight.workspace;
    }
    let table = m2ctl::table::Table::from_geometry(
        &g,
        0,
        m2ctl::table::Provenance {
            calibration_id: 0,
            tag: [b' '; m2ctl::table::layout::PROVENANCE_TAG_LEN],
        },
        m2ctl::table::DEFAULT_SUPERVISION,
    )
    .map_err(|e| format!("table: {e:?}"))?;
    validate_table_for_flight(&table)
}

/// [`validate_for_flight`] for a table already built.
pub fn validate_table_for_flight(table: &m2ctl::table::Table) -> Result<(), String> {
    m2ctl::table::validate(table, &ValidationConfig::flight())
        .map_err(|e| describe_validation_error(&e))
}

/// Plain-words description of a geometry error.
pub fn describe_geometry_error(e: &GeometryError) -> String {
    match e {
        GeometryError::NonFinite => "a value is not a finite number".into(),
        GeometryError::UpperNotAboveLower { leg } => format!(
            "leg {}: the upper joint must be at least {} mm above the lower joint at home",
            leg + 1,
            m2ctl::kinematics::geometry::MIN_ROD_VERTICAL_MM
        ),
        GeometryError::BadStrokeLimits { leg } => format!(
            "slider {}: stroke limits must satisfy min <= 0 <= max",
            leg + 1
        ),
        GeometryError::BadWorkspaceLimits => "workspace half-ranges must not be negative".into(),
    }
}

/// Reads and parses a geometry file; errors are prefixed with the path.
pub fn read_geometry(path: &std::path::Path) -> Result<GeometryFile, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    parse_geometry(&text).map_err(|e| format!("{}: {e}", path.display()))
}

fn fmt3(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", parts.join(", "))
}

/// Writes a geometry file (round-trips exactly: every f64 in shortest exact form).
pub fn format_geometry(file: &GeometryFile, header_comment: &str) -> String {
    let p = &file.params;
    let mut s = String::new();
    for l in header_comment.lines() {
        s.push_str(&format!("# {l}\n"));
    }
    s.push_str(
        "# Units: mm. a = lower joint at zero stroke (frame B), b = upper joint (frame M).\n",
    );
    s.push_str(&format!("p0 = {}\n", fmt3(&p.p0_mm)));
    for leg in &p.legs {
        s.push_str(&format!(
            "\n[[leg]]\na = {}\nb = {}\n",
            fmt3(&leg.a_mm),
            fmt3(&leg.b_mm)
        ));
    }
    if p.stroke_limits.is_some() || p.workspace.is_some() {
        s.push_str("\n[limits]\n");
        if let Some(st) = &p.stroke_limits {
            s.push_str(&format!("stroke_min_mm = {}\n", fmt3(&st.min_mm)));
            s.push_str(&format!("stroke_max_mm = {}\n", fmt3(&st.max_mm)));
        }
        if let Some(w) = &p.workspace {
            s.push_str(&format!("translation_mm = {}\n", fmt3(&w.translation_mm)));
            let r = w.rotation_rad.map(|x| x * ARCSEC_PER_RAD);
            s.push_str(&format!("rotation_arcsec = {}\n", fmt3(&r)));
        }
    }
    if !file.provenance.is_empty() {
        s.push_str("\n[provenance]\n");
        for (k, v) in &file.provenance {
            s.push_str(&format!("{k} = {}\n", toml::Value::String(v.clone())));
        }
    }
    s
}

/// Column names of the pose/stroke CSV, in order.
pub const CSV_COLUMNS: [&str; 12] = [
    "x_mm",
    "y_mm",
    "z_mm",
    "rx_arcsec",
    "ry_arcsec",
    "rz_arcsec",
    "s1_mm",
    "s2_mm",
    "s3_mm",
    "s4_mm",
    "s5_mm",
    "s6_mm",
];
/// Indices of the pose columns within [`CSV_COLUMNS`].
pub const POSE_COLUMNS: Range<usize> = 0..6;
/// Indices of the stroke columns within [`CSV_COLUMNS`].
pub const STROKE_COLUMNS: Range<usize> = 6..12;

/// One CSV data row: the columns that were asked for, in [`CSV_COLUMNS`] order.
#[derive(Clone, Debug, PartialEq)]
pub struct CsvRow {
    /// 1-based line of the row in the file.
    pub line: usize,
    /// The requested values (pose: mm, mm, mm, arcsec x3; strokes: mm x6).
    pub values: Vec<f64>,
}

/// The lines of a CSV file that hold data or the header, numbered from 1 and trimmed:
/// blank lines and `#` comments are skipped.
pub(crate) fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// The trimmed fields of data line `line` (`text`, split at `delim`); refused unless
/// there are `expected` of them, as many as the header has.
pub(crate) fn split_fields(
    line: usize,
    text: &str,
    delim: char,
    expected: usize,
) -> Result<Vec<&str>, FileError> {
    let fields: Vec<&str> = text.split(delim).map(str::trim).collect();
    if fields.len() != expected {
        return Err(err(
            line,
            format!(
                "expected {expected} fields as in the header, found {}",
                fields.len()
            ),
        ));
    }
    Ok(fields)
}

/// Parses a pose/stroke CSV and extracts the columns `wanted` (indices into
/// [`CSV_COLUMNS`]). Lines starting with `#` and blank lines are skipped; the first other
/// line is the header. Unknown columns are ignored; a duplicated or missing wanted column,
/// a wrong field count, a non-number or a non-finite number is an error.
pub fn parse_csv(text: &str, wanted: Range<usize>) -> Result<Vec<CsvRow>, FileError> {
    let mut lines = data_lines(text);
    let (hline, header) = lines
        .next()
        .ok_or_else(|| err(0, "no header line (file is empty)"))?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    for (i, n) in names.iter().enumerate() {
        if names[..i].contains(n) {
            return Err(err(
                hline,
                format!("column '{n}' appears twice in the header"),
            ));
        }
    }
    let mut index = Vec::new();
    for k in wanted.clone() {
        let name = CSV_COLUMNS[k];
        match names.iter().position(|n| *n == name) {
            Some(p) => index.push(p),
            None => {
                if names.iter().all(|n| n.parse::<f64>().is_ok()) {
                    return Err(err(hline, format!("expected a header line naming the columns, found numbers (first missing: '{name}')")));
                }
                return Err(err(hline, format!("missing column '{name}'")));
            }
        }
    }
    let mut rows = Vec::new();
    for (ln, l) in lines {
        let fields = split_fields(ln, l, ',', names.len())?;
        let mut values = Vec::with_capacity(index.len());
        for (&p, k) in index.iter().zip(wanted.clone()) {
            let f = fields[p];
            let v: f64 = f.parse().map_err(|_| {
                err(
                    ln,
                    format!("column '{}': '{f}' is not a number", CSV_COLUMNS[k]),
                )
            })?;
            if !v.is_finite() {
                return Err(err(
                    ln,
                    format!("column '{}': '{f}' is not a finite number", CSV_COLUMNS[k]),
                ));
            }
            values.push(v);
        }
        rows.push(CsvRow { line: ln, values });
    }
    Ok(rows)
}

/// The 12-column CSV header line.
pub fn csv_header() -> String {
    CSV_COLUMNS.join(",")
}

/// One 12-column CSV line: pose (mm, arcsec) then strokes (mm), 15 decimals.
pub fn csv_line(pose_mm_arcsec: &[f64; 6], strokes_mm: &[f64; LEGS]) -> String {
    pose_mm_arcsec
        .iter()
        .chain(strokes_mm.iter())
        .map(|v| format!("{v:.15}"))
        .collect::<Vec<_>>()
        .join(",")
}
