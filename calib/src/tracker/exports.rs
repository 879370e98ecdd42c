//! Point exports as calibration teams have them, read into the project's point records
//! ([`PointRecord`], mm, the tracker's own frame). Every error names the file line.
//!
//! Formats ([`ExportFormat`]):
//! * **native**: the project's `pose,point,x_mm,y_mm,z_mm[,sigma_mm]`
//!   ([`super::files::parse_export`]).
//! * **SpatialAnalyzer-style CSV** (`sa`): a header with the columns `Collection`,
//!   `Group`, `Point` (or `Name`, `Target`, `Point Name`), `X`, `Y`, `Z` and optionally
//!   `Sigma` (or `Uncertainty`, `U`), in any order, names case-insensitive; other
//!   columns are ignored. Mapping: the group named as the base (default `base`, option
//!   `base_group`) holds the fiducials; any other group is a mechanism pose whose number
//!   is the one integer in its name (`Pose 12`, `P012`, `12`; a name with no or two
//!   integers is refused); `Point` is the ball or fiducial name of the target file;
//!   `Collection` must be one and the same in every row (an export of one job).
//! * **generic CSV** (`csv`): the columns named by the user
//!   ([`GenericColumns`]: pose, point, x, y, z, optional sigma); the pose column holds
//!   the base group's name or a pose number as in the SA mapping.
//!
//! Delimiter: `,`, `;` or tab, whichever the header line uses (one of them only).
//! Blank lines and lines starting with `#` or `//` are skipped.
//!
//! **Units**: mm, m or in (`mm`, `millimeter(s)`, `millimetre(s)`; `m`, `meter(s)`,
//! `metre(s)`; `in`, `inch`, `inches`). A file declares its unit in the coordinate
//! columns' names (`X (mm)`, `X [in]`, `X_m`) or in a line before the header (`Units:
//! mm`, `# Length units = Millimeters`, `Units,mm`); the user may give one
//! ([`ExportOptions::units`]). Refused: no unit anywhere (a number without a unit is
//! ambiguous: mm and in differ by 25.4, m and mm by 1000), two declarations that differ
//! (the columns among themselves, the columns and the preamble, the file and the user),
//! a unit word not in the list. Sigmas are in the coordinates' unit.
//!
//! **Frame**: the tracker's own frame (origin at the tracker head) by default, as the
//! instrument measures; the noise model needs each point's line of sight. For an export
//! in another frame (e.g. a part frame aligned in the tracker software), give the
//! tracker head's position in that frame ([`ExportOptions::tracker_at`], same unit):
//! the points are shifted so that it is the origin (a rotation of the frame does not
//! matter: the registration to the base absorbs it, and the lines of sight are the same
//! vectors). A point closer than 0.5 m or farther than 40 m from the tracker is refused
//! (a wrong unit or frame).

use std::collections::HashMap;

use super::files::{check_range, parse_export, push_unique, PointPose, PointRecord, BASE_POSE};
use crate::files::{err, split_fields, FileError};

/// A length unit of an export.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LengthUnit {
    /// Millimetres.
    Mm,
    /// Metres.
    M,
    /// Inches.
    In,
}

impl LengthUnit {
    /// mm per unit.
    pub fn mm(&self) -> f64 {
        match self {
            LengthUnit::Mm => 1.0,
            LengthUnit::M => 1000.0,
            LengthUnit::In => 25.4,
        }
    }

    /// Parses a unit word (case-insensitive); `None` if not a supported unit.
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "mm" | "millimeter" | "millimeters" | "millimetre" | "millimetres" => {
                Some(LengthUnit::Mm)
            }
            "m" | "meter" | "meters" | "metre" | "metres" => Some(LengthUnit::M),
            "in" | "inch" | "inches" | "\"" => Some(LengthUnit::In),
            _ => None,
        }
    }

    /// Short name.
    pub fn name(&self) -> &'static str {
        match self {
            LengthUnit::Mm => "mm",
            LengthUnit::M => "m",
            LengthUnit::In => "in",
        }
    }
}

/// Column names of a generic CSV export.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GenericColumns {
    /// Pose (or base group) column.
    pub pose: String,
    /// Point name column.
    pub point: String,
    /// Coordinate columns.
    pub xyz: [String; 3],
    /// Optional 1-sigma column.
    pub sigma: Option<String>,
}

impl GenericColumns {
    /// Parses `pose=COL,point=COL,x=COL,y=COL,z=COL[,sigma=COL]`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let mut m: HashMap<String, String> = HashMap::new();
        for part in s.split(',') {
            let (k, v) = part
                .split_once('=')
                .ok_or_else(|| format!("--columns: '{part}' is not KEY=COLUMN"))?;
            let k = k.trim().to_ascii_lowercase();
            if !["pose", "point", "x", "y", "z", "sigma"].contains(&k.as_str()) {
                return Err(format!(
                    "--columns: unknown key '{k}' (pose, point, x, y, z, sigma)"
                ));
            }
            if m.insert(k.clone(), v.trim().to_string()).is_some() {
                return Err(format!("--columns: '{k}' given twice"));
            }
        }
        let take = |k: &str| {
            m.get(k)
                .cloned()
                .ok_or_else(|| format!("--columns: '{k}=COLUMN' is missing"))
        };
        Ok(Self {
            pose: take("pose")?,
            point: take("point")?,
            xyz: [take("x")?, take("y")?, take("z")?],
            sigma: m.get("sigma").cloned(),
        })
    }
}

/// Format of a point export.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ExportFormat {
    /// Native if the header is the native one, SA-style if it has Collection and Group
    /// columns; else refused (name the columns with the generic format).
    Auto,
    /// `pose,point,x_mm,y_mm,z_mm[,sigma_mm]`.
    Native,
    /// SpatialAnalyzer-style `Collection,Group,Point,X,Y,Z`.
    SpatialAnalyzer,
    /// Columns named by the user.
    Generic(GenericColumns),
}

/// Options of reading an export.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportOptions {
    /// The format.
    pub format: ExportFormat,
    /// The unit the user says the file is in (must agree with the file's own).
    pub units: Option<LengthUnit>,
    /// The tracker head's position in the export's frame (export unit); `None`: the
    /// export is in the tracker's frame.
    pub tracker_at: Option<[f64; 3]>,
    /// Name of the group (pose column value) of the base fiducials.
    pub base_group: String,
}

impl Default for ExportOptions {
    fn default() -> Self {
        Self {
            format: ExportFormat::Auto,
            units: None,
            tracker_at: None,
            base_group: BASE_POSE.to_string(),
        }
    }
}

fn skip(l: &str) -> bool {
    let t = l.trim();
    t.is_empty() || t.starts_with('#') || t.starts_with("//")
}

/// A unit declaration line before the header (`Units: mm`, `# Length units = inch`,
/// `Units,mm`): its unit word.
fn unit_declaration(l: &str) -> Option<String> {
    let t = l
        .trim()
        .trim_start_matches('#')
        .trim_start_matches("//")
        .trim();
    let lower = t.to_ascii_lowercase();
    let rest = lower
        .strip_prefix("length units")
        .or_else(|| lower.strip_prefix("length unit"))
        .or_else(|| lower.strip_prefix("units"))
        .or_else(|| lower.strip_prefix("unit"))?;
    let rest = rest.trim_start();
    let rest = rest
        .strip_prefix(':')
        .or_else(|| rest.strip_prefix('='))
        .or_else(|| rest.strip_prefix(','))
        .or_else(|| rest.strip_prefix(';'))?;
    Some(
        rest.trim()
            .trim_matches(|c| c == ',' || c == ';')
            .trim()
            .to_string(),
    )
}

/// A column name with a unit: `X (mm)`, `X [in]`, `X_m` -> (`x`, Some(unit word)).
fn split_unit(name: &str) -> (String, Option<String>) {
    let t = name.trim();
    for (open, close) in [('(', ')'), ('[', ']')] {
        if let (Some(a), true) = (t.rfind(open), t.ends_with(close)) {
            return (
                t[..a].trim().to_ascii_lowercase(),
                Some(t[a + 1..t.len() - 1].trim().to_string()),
            );
        }
    }
    if let Some((base, u)) = t.rsplit_once('_') {
        if LengthUnit::parse(u).is_some() {
            return (base.trim().to_ascii_lowercase(), Some(u.to_string()));
        }
    }
    (t.to_ascii_lowercase(), None)
}

/// The pose of a group name: the base group, or the one integer in the name.
fn pose_of_group(line: usize, group: &str, base: &str) -> Result<PointPose, FileError> {
    if group.trim().eq_ignore_ascii_case(base) {
        return Ok(PointPose::Base);
    }
    let mut numbers = Vec::new();
    let mut cur = String::new();
    for c in group.chars().chain(std::iter::once(' ')) {
        if c.is_ascii_digit() {
            cur.push(c);
        } else if !cur.is_empty() {
            numbers.push(std::mem::take(&mut cur));
        }
    }
    match numbers.as_slice() {
        [n] => match n.parse::<u32>() {
            Ok(k) if k >= 1 => Ok(PointPose::Pose(k)),
            _ => Err(err(
                line,
                format!("group '{group}': pose number {n} is not a number >= 1"),
            )),
        },
        [] => Err(err(
            line,
            format!(
                "group '{group}' is neither the base group '{base}' nor a pose (a name with one pose number, e.g. 'Pose 12')"
            ),
        )),
        _ => Err(err(
            line,
            format!(
                "group '{group}' has {} numbers: which is the pose is ambiguous (one pose number per group name)",
                numbers.len()
            ),
        )),
    }
}

/// Reads a point export in `opts`' format, unit and frame.
pub fn read_export(text: &str, opts: &ExportOptions) -> Result<Vec<PointRecord>, FileError> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l))
        .filter(|(_, l)| !l.trim().is_empty());
    // Preamble: comments and unit declarations, then the header.
    let mut declared: Vec<(usize, String)> = Vec::new();
    let (hline, header) = loop {
        let Some((n, l)) = lines.next() else {
            return Err(err(0, "no header line (file is empty)"));
        };
        if let Some(u) = unit_declaration(l) {
            declared.push((n, u));
            continue;
        }
        if skip(l) {
            continue;
        }
        break (n, l);
    };
    let delims: Vec<char> = [',', ';', '\t']
        .into_iter()
        .filter(|d| header.contains(*d))
        .collect();
    let delim = match delims.as_slice() {
        [d] => *d,
        [] => return Err(err(hline, "header has no delimiter (comma, semicolon or tab)")),
        _ => {
            return Err(err(
                hline,
                "header mixes delimiters (comma, semicolon, tab): which one separates columns is ambiguous",
            ))
        }
    };
    let names: Vec<&str> = header.split(delim).map(str::trim).collect();
    let split: Vec<(String, Option<String>)> = names.iter().map(|n| split_unit(n)).collect();
    let native_header = names
        .iter()
        .all(|n| super::files::POINT_COLUMNS.contains(n))
        && names.contains(&"x_mm");
    let has = |k: &str| split.iter().any(|(n, _)| n == k);
    let format = match &opts.format {
        ExportFormat::Auto if native_header => ExportFormat::Native,
        ExportFormat::Auto if has("collection") && has("group") => ExportFormat::SpatialAnalyzer,
        ExportFormat::Auto => {
            return Err(err(
                hline,
                format!(
                    "header '{header}' is neither the native pose,point,x_mm,y_mm,z_mm nor a SpatialAnalyzer-style Collection,Group,Point,X,Y,Z: name the columns (--points-format csv --columns pose=..,point=..,x=..,y=..,z=..)"
                ),
            ))
        }
        f => f.clone(),
    };
    if format == ExportFormat::Native {
        if let Some(u) = opts.units.filter(|u| *u != LengthUnit::Mm) {
            return Err(err(
                hline,
                format!(
                    "the native export is in mm (x_mm, ...), but the unit given is {}: ambiguous",
                    u.name()
                ),
            ));
        }
        if let Some((n, u)) = declared.first() {
            if LengthUnit::parse(u) != Some(LengthUnit::Mm) {
                return Err(err(
                    *n,
                    format!("the native export is in mm, but this line declares '{u}'"),
                ));
            }
        }
        let mut pts = parse_export(text)?;
        if let Some(t) = opts.tracker_at {
            for p in pts.iter_mut() {
                for (y, t) in p.y_mm.iter_mut().zip(t.iter()) {
                    *y -= t;
                }
            }
        }
        return Ok(pts);
    }
    // Column positions.
    let find = |want: &[&str], what: &str| -> Result<usize, FileError> {
        let hits: Vec<usize> = split
            .iter()
            .enumerate()
            .filter(|(_, (n, _))| want.contains(&n.as_str()))
            .map(|(i, _)| i)
            .collect();
        match hits.as_slice() {
            [i] => Ok(*i),
            [] => Err(err(
                hline,
                format!("no {what} column (one of: {})", want.join(", ")),
            )),
            _ => Err(err(
                hline,
                format!("{} {what} columns: ambiguous", hits.len()),
            )),
        }
    };
    let find_opt = |want: &[&str], what: &str| -> Result<Option<usize>, FileError> {
        match find(want, what) {
            Ok(i) => Ok(Some(i)),
            Err(e) if e.message.starts_with("no ") => Ok(None),
            Err(e) => Err(e),
        }
    };
    let lower = |s: &str| s.trim().to_ascii_lowercase();
    let (c_coll, c_pose, c_point, c_xyz, c_sigma) = match &format {
        ExportFormat::SpatialAnalyzer => (
            Some(find(&["collection"], "Collection")?),
            find(&["group"], "Group")?,
            find(
                &["point", "name", "target", "point name", "pointname"],
                "Point",
            )?,
            [find(&["x"], "X")?, find(&["y"], "Y")?, find(&["z"], "Z")?],
            find_opt(&["sigma", "uncertainty", "u"], "Sigma")?,
        ),
        ExportFormat::Generic(c) => (
            None,
            find(&[lower(&c.pose).as_str()], &format!("'{}' (pose)", c.pose))?,
            find(
                &[lower(&c.point).as_str()],
                &format!("'{}' (point)", c.point),
            )?,
            [
                find(
                    &[split_unit(&c.xyz[0]).0.as_str()],
                    &format!("'{}' (x)", c.xyz[0]),
                )?,
                find(
                    &[split_unit(&c.xyz[1]).0.as_str()],
                    &format!("'{}' (y)", c.xyz[1]),
                )?,
                find(
                    &[split_unit(&c.xyz[2]).0.as_str()],
                    &format!("'{}' (z)", c.xyz[2]),
                )?,
            ],
            match &c.sigma {
                Some(s) => Some(find(
                    &[split_unit(s).0.as_str()],
                    &format!("'{s}' (sigma)"),
                )?),
                None => None,
            },
        ),
        _ => unreachable!("native handled above"),
    };
    // The unit: every declaration must agree.
    let mut unit: Option<(LengthUnit, String)> = None;
    let mut agree = |u: &str, whence: String, line: usize| -> Result<(), FileError> {
        let lu = LengthUnit::parse(u).ok_or_else(|| {
            err(
                line,
                format!("{whence}: unit '{u}' is not one of mm, m, in"),
            )
        })?;
        match &unit {
            Some((prev, pw)) if *prev != lu => Err(err(
                line,
                format!(
                    "{whence} says {}, {pw} says {}: the unit is ambiguous",
                    lu.name(),
                    prev.name()
                ),
            )),
            Some(_) => Ok(()),
            None => {
                unit = Some((lu, whence));
                Ok(())
            }
        }
    };
    for (n, u) in &declared {
        agree(u, format!("line {n}"), *n)?;
    }
    for &c in c_xyz.iter().chain(c_sigma.iter()) {
        if let Some(u) = &split[c].1 {
            agree(u, format!("column '{}'", names[c]), hline)?;
        }
    }
    if let Some(u) = opts.units {
        agree(u.name(), "the unit given (--units)".into(), hline)?;
    }
    let Some((unit, _)) = unit else {
        return Err(err(
            hline,
            "no length unit: the columns do not name one (e.g. 'X (mm)') and no 'Units: ...' line precedes the header; give --units mm|m|in",
        ));
    };
    let k = unit.mm();
    let range_hint = format!(
        "unit {}: a wrong unit, or coordinates not in the tracker's frame: give the tracker's position with --tracker-at",
        unit.name()
    );
    let mut out = Vec::new();
    let mut seen: HashMap<(PointPose, String), usize> = HashMap::new();
    let mut collection: Option<(String, usize)> = None;
    for (ln, l) in lines {
        if skip(l) {
            continue;
        }
        let f = split_fields(ln, l, delim, names.len())?;
        if let Some(c) = c_coll {
            match &collection {
                None => collection = Some((f[c].to_string(), ln)),
                Some((name, first)) if name != f[c] => {
                    return Err(err(
                        ln,
                        format!(
                            "collection '{}' differs from '{name}' (line {first}): export one collection (one job) per file",
                            f[c]
                        ),
                    ))
                }
                _ => {}
            }
        }
        let pose = match &format {
            ExportFormat::Generic(_) => match f[c_pose].parse::<u32>() {
                Ok(n) if n >= 1 => PointPose::Pose(n),
                _ => pose_of_group(ln, f[c_pose], &opts.base_group)?,
            },
            _ => pose_of_group(ln, f[c_pose], &opts.base_group)?,
        };
        let name = f[c_point].to_string();
        if name.is_empty() {
            return Err(err(ln, "empty point name"));
        }
        let mut y = [0.0; 3];
        for a in 0..3 {
            let s = f[c_xyz[a]];
            let v: f64 = s.parse().map_err(|_| {
                err(
                    ln,
                    format!("column '{}': '{s}' is not a number", names[c_xyz[a]]),
                )
            })?;
            if !v.is_finite() {
                return Err(err(
                    ln,
                    format!("column '{}': '{s}' is not finite", names[c_xyz[a]]),
                ));
            }
            y[a] = (v - opts.tracker_at.map_or(0.0, |t| t[a])) * k;
        }
        let sigma_mm = match c_sigma {
            Some(c) if !f[c].is_empty() => {
                let v: f64 = f[c].parse().map_err(|_| {
                    err(
                        ln,
                        format!("column '{}': '{}' is not a number", names[c], f[c]),
                    )
                })?;
                if !(v.is_finite() && v > 0.0) {
                    return Err(err(
                        ln,
                        format!("column '{}': {v} is not a positive number", names[c]),
                    ));
                }
                Some(v * k)
            }
            _ => None,
        };
        check_range(ln, &name, &y, &range_hint)?;
        push_unique(
            &mut out,
            &mut seen,
            PointRecord {
                line: ln,
                pose,
                name,
                y_mm: y,
                sigma_mm,
            },
        )?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SA: &str = "// SpatialAnalyzer point export\nUnits: Millimeters\nCollection,Group,Point,X,Y,Z\nA,base,F1,1000.0,2000.0,-100.0\nA,base,F2,1100.0,2000.0,-100.0\nA,Pose 1,B1,1000.5,2000.5,300.0\nA,P002,B1,1000.6,2000.5,300.0\n";

    #[test]
    fn spatial_analyzer_csv_maps_groups_to_poses() {
        let p = read_export(SA, &ExportOptions::default()).unwrap();
        assert_eq!(p.len(), 4);
        assert_eq!(p[0].pose, PointPose::Base);
        assert_eq!((p[0].line, p[0].name.as_str()), (4, "F1"));
        assert_eq!(p[2].pose, PointPose::Pose(1));
        assert_eq!(p[3].pose, PointPose::Pose(2));
        assert_eq!(p[3].y_mm, [1000.6, 2000.5, 300.0]);
    }

    #[test]
    fn units_are_converted_and_ambiguity_refused() {
        // Metres in the column names.
        let m = "Collection;Group;Point;X (m);Y (m);Z (m)\nA;base;F1;1.0;2.0;-0.1\n";
        let p = read_export(m, &ExportOptions::default()).unwrap();
        assert_eq!(p[0].y_mm, [1000.0, 2000.0, -100.0]);
        // Inches from the user.
        let i = "Collection,Group,Point,X,Y,Z\nA,base,F1,40,80,-4\n";
        let o = ExportOptions {
            units: Some(LengthUnit::In),
            ..Default::default()
        };
        let p = read_export(i, &o).unwrap();
        assert!((p[0].y_mm[0] - 1016.0).abs() < 1e-9);
        // No unit anywhere.
        let e = read_export(i, &ExportOptions::default()).unwrap_err();
        assert!(e.line == 1 && e.message.contains("no length unit"), "{e}");
        // The file says mm, the user in.
        let e = read_export(SA, &o).unwrap_err();
        assert!(e.message.contains("ambiguous"), "{e}");
        // Columns disagree.
        let d = "Collection,Group,Point,X (mm),Y (in),Z (mm)\nA,base,F1,1000,2000,-100\n";
        let e = read_export(d, &ExportOptions::default()).unwrap_err();
        assert!(e.line == 1 && e.message.contains("ambiguous"), "{e}");
        // An unknown unit word.
        let u = "Units: furlongs\nCollection,Group,Point,X,Y,Z\nA,base,F1,1,2,3\n";
        let e = read_export(u, &ExportOptions::default()).unwrap_err();
        assert!(e.line == 1 && e.message.contains("furlongs"), "{e}");
        // The native format is mm only.
        let n = "pose,point,x_mm,y_mm,z_mm\nbase,F1,1000,2000,-100\n";
        assert!(read_export(n, &o)
            .unwrap_err()
            .message
            .contains("ambiguous"));
        assert_eq!(read_export(n, &ExportOptions::default()).unwrap().len(), 1);
    }

    #[test]
    fn generic_csv_with_named_columns_and_frame() {
        let g = "# exported from the tracker software\nMeas;Target;East [mm];North [mm];Up [mm];U [mm]\nbase;F1;100.0;200.0;-10.0;0.02\n7;B2;150.0;200.0;300.0;\n";
        let cols =
            GenericColumns::parse("pose=Meas,point=Target,x=East,y=North,z=Up,sigma=U").unwrap();
        let o = ExportOptions {
            format: ExportFormat::Generic(cols),
            tracker_at: Some([-2000.0, 0.0, 0.0]),
            ..Default::default()
        };
        let p = read_export(g, &o).unwrap();
        assert_eq!(p[0].y_mm, [2100.0, 200.0, -10.0]);
        assert_eq!(p[0].sigma_mm, Some(0.02));
        assert_eq!(
            (p[1].pose, p[1].line, p[1].sigma_mm),
            (PointPose::Pose(7), 4, None)
        );
        // Without the frame option the points are inside 0.5 m of the tracker: refused.
        let o2 = ExportOptions {
            tracker_at: None,
            ..o.clone()
        };
        let e = read_export(g, &o2).unwrap_err();
        assert!(e.line == 3 && e.message.contains("--tracker-at"), "{e}");
        assert!(GenericColumns::parse("pose=a,point=b,x=c,y=d").is_err());
    }

    #[test]
    fn malformed_rows_are_refused_with_their_line() {
        let bad = |s: &str, line: usize, what: &str| {
            let e = read_export(s, &ExportOptions::default()).unwrap_err();
            assert!(e.line == line && e.message.contains(what), "{e}");
        };
        let h = "Units: mm\nCollection,Group,Point,X,Y,Z\n";
        bad(&format!("{h}A,base,F1,1000,x,0\n"), 3, "not a number");
        bad(&format!("{h}A,base,F1,1000,0\n"), 3, "fields");
        bad(&format!("{h}A,Pose 3-4,B1,1000,0,0\n"), 3, "ambiguous");
        bad(&format!("{h}A,Setup,B1,1000,0,0\n"), 3, "neither");
        bad(
            &format!("{h}A,base,F1,1000,0,0\nB,base,F2,1000,10,0\n"),
            4,
            "collection",
        );
        bad(
            &format!("{h}A,base,F1,1000,0,0\nA,base,F1,1000,10,0\n"),
            4,
            "already on line 3",
        );
        bad("Units: mm\nFoo,Bar\n1,2\n", 2, "neither the native");
        bad("Units: mm\nCollection,Group;Point\n", 2, "mixes delimiters");
    }
}
