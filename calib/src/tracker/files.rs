//! The three input files of a calibration from laser-tracker points. Every error names
//! the file line.
//!
//! ## Target file (`targets.toml`): what the drawings say
//! ```toml
//! ball_sigma_mm = 0.1        # mounting tolerance of a ball about its nominal centre (1 sigma)
//! fiducial_sigma_mm = 0.02   # drawing tolerance of a fiducial nest (1 sigma)
//! [[ball]]                   # target balls (SMRs) on the moving platform, >= 3
//! name = "B1"
//! m = [100.0, 0.0, 100.0]    # nominal centre, frame M (mm)
//! [[fiducial]]               # SMR nests on the base plate, >= 3, not collinear
//! name = "F1"
//! b = [106.066, 106.066, -140.0]  # drawing centre, frame B (mm)
//! ```
//!
//! ## Tracker point export (`points.csv`): what the tracker measured
//! ```text
//! pose,point,x_mm,y_mm,z_mm[,sigma_mm]
//! base,F1,1234.5678,...        # fiducials: pose = "base"
//! 1,B1,1301.2345,...           # balls: pose = the mechanism pose index (>= 1)
//! ```
//! Coordinates in the tracker's own frame (origin at the tracker head, as the instrument
//! measures; not an aligned part frame), mm. `sigma_mm` (optional column, may be empty
//! in a row): the tracker software's 1-sigma uncertainty per coordinate for that point;
//! without it the tracker class's noise model gives the (anisotropic) covariance. Lines
//! starting with `#` and blank lines are skipped; the first other line is the header;
//! columns in any order, unknown columns are refused.
//!
//! ## Strokes (`strokes.csv`): what the encoders read at each pose (housekeeping)
//! ```text
//! pose,s1_mm,s2_mm,s3_mm,s4_mm,s5_mm,s6_mm
//! 1,0.0123,...
//! ```
//!
//! Refused with the line: malformed rows, non-numbers, non-finite values, a point name
//! the target file does not define, a ball in the `base` rows or a fiducial in a pose's
//! rows, the same point twice in a pose, a point closer than [`MIN_RANGE_MM`] or farther
//! than [`MAX_RANGE_MM`] from the tracker, a pose with fewer than 3 balls, a pose
//! without strokes or strokes without a pose, fewer than 3 fiducials, a duplicated pose
//! in the strokes.

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;

use serde::Deserialize;
use toml::Spanned;

use crate::files::{data_lines, err, line_of, parse_toml, split_fields, FileError};
use m2ctl::kinematics::LEGS;
use m2ctl::sim::tracker::NamedPoint;

/// Closest plausible tracker-to-point range (mm): trackers do not measure inside 0.5 m
/// reliably; a smaller value is a wrong frame or unit.
pub const MIN_RANGE_MM: f64 = 500.0;
/// Farthest plausible range (mm): beyond the 40 m of a long-range tracker.
pub const MAX_RANGE_MM: f64 = 40_000.0;
/// Fewest balls per pose (a rigid pose needs three non-collinear points).
pub const MIN_BALLS_PER_POSE: usize = 3;
/// Fewest fiducials (a registration needs three non-collinear points).
pub const MIN_FIDUCIALS: usize = 3;
/// Pose column value of the base fiducial rows.
pub const BASE_POSE: &str = "base";
/// Column names of the point export, in the written order (the last is optional).
pub const POINT_COLUMNS: [&str; 6] = ["pose", "point", "x_mm", "y_mm", "z_mm", "sigma_mm"];
/// Column names of the stroke file.
pub const STROKE_COLUMNS: [&str; 7] =
    ["pose", "s1_mm", "s2_mm", "s3_mm", "s4_mm", "s5_mm", "s6_mm"];

// ---------------------------------------------------------------------------------------
// Target file
// ---------------------------------------------------------------------------------------

/// The target definitions: nominal ball centres (frame M), fiducial drawing centres
/// (frame B) and their tolerances.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetFile {
    /// Balls on the moving platform, nominal centres (frame M, mm).
    pub balls: Vec<NamedPoint>,
    /// Fiducial nests on the base, drawing centres (frame B, mm).
    pub fiducials: Vec<NamedPoint>,
    /// Mounting tolerance of a ball (1 sigma per coordinate, mm): the prior of the fit.
    pub ball_sigma_mm: f64,
    /// Drawing tolerance of a fiducial (1 sigma per coordinate, mm).
    pub fiducial_sigma_mm: f64,
}

/// Default ball radius from the platform axis (mm): the issue's "about 100 mm".
pub const DEFAULT_BALL_RADIUS_MM: f64 = 100.0;
/// Default ball height in frame M (mm): 14.3 mm above the upper joint plane.
pub const DEFAULT_BALL_Z_M_MM: f64 = 100.0;
/// Default number of balls (the paper's four).
pub const DEFAULT_BALLS: usize = 4;
/// Default fiducial radius on the base plate (mm).
pub const DEFAULT_FIDUCIAL_RADIUS_MM: f64 = 150.0;
/// Default fiducial height in frame B (mm): on the base plate, below the lower joints.
pub const DEFAULT_FIDUCIAL_Z_B_MM: f64 = -140.0;
/// Default number of fiducials.
pub const DEFAULT_FIDUCIALS: usize = 4;
/// Default ball mounting tolerance (mm, 1 sigma): SMR nests glued to the platform.
pub const DEFAULT_BALL_SIGMA_MM: f64 = 0.1;
/// Default fiducial drawing tolerance (mm, 1 sigma): machined nests.
pub const DEFAULT_FIDUCIAL_SIGMA_MM: f64 = 0.02;

impl Default for TargetFile {
    /// Four balls 100 mm from the platform axis (every 90 deg, from +x) at z_M = 100 mm,
    /// four fiducials 150 mm from the base axis (every 90 deg, from 45 deg) at
    /// z_B = -140 mm.
    fn default() -> Self {
        let ring = |n: usize, r: f64, phase_deg: f64, z: f64, prefix: char| {
            (0..n)
                .map(|k| {
                    let a = (phase_deg + 360.0 * k as f64 / n as f64).to_radians();
                    NamedPoint {
                        name: format!("{prefix}{}", k + 1),
                        mm: [r * a.cos(), r * a.sin(), z],
                    }
                })
                .collect()
        };
        Self {
            balls: ring(
                DEFAULT_BALLS,
                DEFAULT_BALL_RADIUS_MM,
                0.0,
                DEFAULT_BALL_Z_M_MM,
                'B',
            ),
            fiducials: ring(
                DEFAULT_FIDUCIALS,
                DEFAULT_FIDUCIAL_RADIUS_MM,
                45.0,
                DEFAULT_FIDUCIAL_Z_B_MM,
                'F',
            ),
            ball_sigma_mm: DEFAULT_BALL_SIGMA_MM,
            fiducial_sigma_mm: DEFAULT_FIDUCIAL_SIGMA_MM,
        }
    }
}

impl TargetFile {
    /// The default layout with the balls `radius_mm` from the platform axis.
    pub fn with_ball_radius(radius_mm: f64) -> Self {
        let mut t = Self::default();
        for b in t.balls.iter_mut() {
            let r = (b.mm[0] * b.mm[0] + b.mm[1] * b.mm[1]).sqrt();
            if r > 0.0 {
                b.mm[0] *= radius_mm / r;
                b.mm[1] *= radius_mm / r;
            }
        }
        t
    }

    /// Distance of the balls from the platform axis (mm, mean).
    pub fn ball_radius_mm(&self) -> f64 {
        self.balls
            .iter()
            .map(|b| (b.mm[0] * b.mm[0] + b.mm[1] * b.mm[1]).sqrt())
            .sum::<f64>()
            / self.balls.len().max(1) as f64
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBall {
    name: Spanned<String>,
    m: Spanned<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFiducial {
    name: Spanned<String>,
    b: Spanned<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTargets {
    ball_sigma_mm: Spanned<f64>,
    fiducial_sigma_mm: Spanned<f64>,
    ball: Spanned<Vec<RawBall>>,
    fiducial: Spanned<Vec<RawFiducial>>,
}

/// Whether three or more points span a plane (not collinear).
fn spans_plane(points: &[[f64; 3]]) -> bool {
    let Some(first) = points.first() else {
        return false;
    };
    let d: Vec<nalgebra::Vector3<f64>> = points
        .iter()
        .map(|p| nalgebra::Vector3::from(*p) - nalgebra::Vector3::from(*first))
        .collect();
    let scale = d.iter().map(|v| v.norm()).fold(0.0, f64::max);
    d.iter().any(|u| {
        d.iter().any(|v| {
            u.cross(v).norm() > crate::calib::registration::MIN_SPREAD_RATIO * scale * scale
        })
    })
}

/// Parses a target file.
pub fn parse_targets(text: &str) -> Result<TargetFile, FileError> {
    let raw: RawTargets = parse_toml(text)?;
    let mut names: HashMap<String, usize> = HashMap::new();
    let mut take =
        |name: &Spanned<String>, mm: &Spanned<[f64; 3]>| -> Result<NamedPoint, FileError> {
            let line = line_of(text, &name.span());
            let n = name.get_ref().trim().to_string();
            if n.is_empty() || n.contains(',') || n.eq_ignore_ascii_case(BASE_POSE) {
                return Err(err(
                    line,
                    format!("point name '{n}' is empty, has a comma or is reserved"),
                ));
            }
            if let Some(prev) = names.insert(n.clone(), line) {
                return Err(err(
                    line,
                    format!("point name '{n}' already defined on line {prev}"),
                ));
            }
            if !mm.get_ref().iter().all(|v| v.is_finite()) {
                return Err(err(
                    line_of(text, &mm.span()),
                    format!("{n}: every coordinate must be finite"),
                ));
            }
            Ok(NamedPoint {
                name: n,
                mm: *mm.get_ref(),
            })
        };
    let balls = raw
        .ball
        .get_ref()
        .iter()
        .map(|b| take(&b.name, &b.m))
        .collect::<Result<Vec<_>, _>>()?;
    let fiducials = raw
        .fiducial
        .get_ref()
        .iter()
        .map(|f| take(&f.name, &f.b))
        .collect::<Result<Vec<_>, _>>()?;
    for (what, list, span, min) in [
        ("[[ball]]", &balls, raw.ball.span(), MIN_BALLS_PER_POSE),
        (
            "[[fiducial]]",
            &fiducials,
            raw.fiducial.span(),
            MIN_FIDUCIALS,
        ),
    ] {
        let pts: Vec<[f64; 3]> = list.iter().map(|p| p.mm).collect();
        if list.len() < min || !spans_plane(&pts) {
            return Err(err(
                line_of(text, &span),
                format!("{what}: need at least {min} points, not all on one line"),
            ));
        }
    }
    for (what, v) in [
        ("ball_sigma_mm", &raw.ball_sigma_mm),
        ("fiducial_sigma_mm", &raw.fiducial_sigma_mm),
    ] {
        if !(v.get_ref().is_finite() && *v.get_ref() > 0.0) {
            return Err(err(
                line_of(text, &v.span()),
                format!("{what} must be a positive number of mm"),
            ));
        }
    }
    Ok(TargetFile {
        balls,
        fiducials,
        ball_sigma_mm: *raw.ball_sigma_mm.get_ref(),
        fiducial_sigma_mm: *raw.fiducial_sigma_mm.get_ref(),
    })
}

fn fmt3(v: &[f64; 3]) -> String {
    format!("[{:?}, {:?}, {:?}]", v[0], v[1], v[2])
}

/// Writes a target file (round-trips exactly).
pub fn format_targets(t: &TargetFile, header_comment: &str) -> String {
    let mut s = String::new();
    for l in header_comment.lines() {
        let _ = writeln!(s, "# {l}");
    }
    let _ = writeln!(
        s,
        "# Balls: nominal centres in frame M (mm); fiducials: drawing centres in frame B (mm)."
    );
    let _ = writeln!(s, "ball_sigma_mm = {:?}", t.ball_sigma_mm);
    let _ = writeln!(s, "fiducial_sigma_mm = {:?}", t.fiducial_sigma_mm);
    for b in &t.balls {
        let _ = writeln!(s, "\n[[ball]]\nname = \"{}\"\nm = {}", b.name, fmt3(&b.mm));
    }
    for f in &t.fiducials {
        let _ = writeln!(
            s,
            "\n[[fiducial]]\nname = \"{}\"\nb = {}",
            f.name,
            fmt3(&f.mm)
        );
    }
    s
}

// ---------------------------------------------------------------------------------------
// CSV helpers
// ---------------------------------------------------------------------------------------

/// The header's column positions for `columns` (the last `optional` may be missing).
fn header_index(
    line: usize,
    header: &str,
    columns: &[&str],
    optional: usize,
) -> Result<(Vec<Option<usize>>, usize), FileError> {
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    for (i, n) in names.iter().enumerate() {
        if names[..i].contains(n) {
            return Err(err(
                line,
                format!("column '{n}' appears twice in the header"),
            ));
        }
        if !columns.contains(n) {
            return Err(err(
                line,
                format!("unknown column '{n}' (expected {})", columns.join(",")),
            ));
        }
    }
    let mut idx = Vec::new();
    for (k, c) in columns.iter().enumerate() {
        let p = names.iter().position(|n| n == c);
        if p.is_none() && k < columns.len() - optional {
            return Err(err(line, format!("missing column '{c}'")));
        }
        idx.push(p);
    }
    Ok((idx, names.len()))
}

fn number(line: usize, col: &str, f: &str) -> Result<f64, FileError> {
    let v: f64 = f
        .parse()
        .map_err(|_| err(line, format!("column '{col}': '{f}' is not a number")))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(err(
            line,
            format!("column '{col}': '{f}' is not a finite number"),
        ))
    }
}

fn pose_index(line: usize, f: &str) -> Result<u32, FileError> {
    match f.parse::<u32>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(err(
            line,
            format!("column 'pose': '{f}' is neither '{BASE_POSE}' nor a pose number >= 1"),
        )),
    }
}

// ---------------------------------------------------------------------------------------
// Point export
// ---------------------------------------------------------------------------------------

/// Which measurement a point belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum PointPose {
    /// The base fiducials.
    Base,
    /// Mechanism pose number (>= 1).
    Pose(u32),
}

/// One measured point.
#[derive(Clone, Debug, PartialEq)]
pub struct PointRecord {
    /// 1-based file line (0 for generated data).
    pub line: usize,
    /// Fiducial set or pose number.
    pub pose: PointPose,
    /// Point name (target file).
    pub name: String,
    /// Coordinates in the tracker frame (mm).
    pub y_mm: [f64; 3],
    /// Per-coordinate 1-sigma uncertainty (mm), if the export gives one.
    pub sigma_mm: Option<f64>,
}

/// Appends `rec` unless its point was already measured in the same pose (fiducial set
/// or pose): that is refused naming both lines. `seen` maps (pose, name) to the line.
pub(super) fn push_unique(
    out: &mut Vec<PointRecord>,
    seen: &mut HashMap<(PointPose, String), usize>,
    rec: PointRecord,
) -> Result<(), FileError> {
    if let Some(prev) = seen.insert((rec.pose, rec.name.clone()), rec.line) {
        return Err(err(
            rec.line,
            format!(
                "point {} of the same measurement already on line {prev}",
                rec.name
            ),
        ));
    }
    out.push(rec);
    Ok(())
}

/// Refuses a point whose distance from the tracker `y_mm` (tracker frame, mm) is outside
/// [`MIN_RANGE_MM`]..[`MAX_RANGE_MM`], naming it, its line and what is likely wrong
/// (`hint`, which differs by reader).
pub(super) fn check_range(
    line: usize,
    name: &str,
    y_mm: &[f64; 3],
    hint: &str,
) -> Result<(), FileError> {
    let range = (y_mm[0] * y_mm[0] + y_mm[1] * y_mm[1] + y_mm[2] * y_mm[2]).sqrt();
    if !(MIN_RANGE_MM..=MAX_RANGE_MM).contains(&range) {
        return Err(err(
            line,
            format!(
                "point {name} is {range:.1} mm from the tracker: outside {MIN_RANGE_MM}..{MAX_RANGE_MM} mm ({hint})"
            ),
        ));
    }
    Ok(())
}

/// Parses a tracker point export (see the module docs). Checks that need the target file
/// (names, counts) are in [`check_export`].
pub fn parse_export(text: &str) -> Result<Vec<PointRecord>, FileError> {
    let mut lines = data_lines(text);
    let (hline, header) = lines
        .next()
        .ok_or_else(|| err(0, "no header line (file is empty)"))?;
    let (idx, nfields) = header_index(hline, header, &POINT_COLUMNS, 1)?;
    let col = |k: usize| idx[k].unwrap_or(usize::MAX);
    let mut out: Vec<PointRecord> = Vec::new();
    let mut seen: HashMap<(PointPose, String), usize> = HashMap::new();
    for (ln, l) in lines {
        let f = split_fields(ln, l, ',', nfields)?;
        let pose = if f[col(0)].eq_ignore_ascii_case(BASE_POSE) {
            PointPose::Base
        } else {
            PointPose::Pose(pose_index(ln, f[col(0)])?)
        };
        let name = f[col(1)].to_string();
        if name.is_empty() {
            return Err(err(ln, "column 'point': empty name"));
        }
        let mut y = [0.0; 3];
        for (k, v) in y.iter_mut().enumerate() {
            *v = number(ln, POINT_COLUMNS[2 + k], f[col(2 + k)])?;
        }
        check_range(
            ln,
            &name,
            &y,
            "coordinates must be in the tracker's own frame, mm",
        )?;
        let sigma_mm = match idx[5] {
            Some(p) if !f[p].is_empty() => {
                let s = number(ln, "sigma_mm", f[p])?;
                if s <= 0.0 {
                    return Err(err(ln, format!("column 'sigma_mm': {s} is not positive")));
                }
                Some(s)
            }
            _ => None,
        };
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

/// Writes a point export (coordinates to 1 nm, 6 decimals of mm).
pub fn format_export(points: &[PointRecord], header_comment: &str) -> String {
    let mut s = String::new();
    for l in header_comment.lines() {
        let _ = writeln!(s, "# {l}");
    }
    let with_sigma = points.iter().any(|p| p.sigma_mm.is_some());
    let n = if with_sigma { 6 } else { 5 };
    let _ = writeln!(s, "{}", POINT_COLUMNS[..n].join(","));
    for p in points {
        let pose = match p.pose {
            PointPose::Base => BASE_POSE.to_string(),
            PointPose::Pose(k) => k.to_string(),
        };
        let _ = write!(
            s,
            "{pose},{},{:.6},{:.6},{:.6}",
            p.name, p.y_mm[0], p.y_mm[1], p.y_mm[2]
        );
        if with_sigma {
            let _ = write!(
                s,
                ",{}",
                p.sigma_mm.map(|v| format!("{v:?}")).unwrap_or_default()
            );
        }
        s.push('\n');
    }
    s
}

// ---------------------------------------------------------------------------------------
// Strokes
// ---------------------------------------------------------------------------------------

/// Encoder strokes at one pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrokeRecord {
    /// 1-based file line (0 for generated data).
    pub line: usize,
    /// Pose number (>= 1).
    pub pose: u32,
    /// Strokes (mm), slider order.
    pub strokes_mm: [f64; LEGS],
}

/// Parses a stroke file.
pub fn parse_strokes(text: &str) -> Result<Vec<StrokeRecord>, FileError> {
    let mut lines = data_lines(text);
    let (hline, header) = lines
        .next()
        .ok_or_else(|| err(0, "no header line (file is empty)"))?;
    let (idx, nfields) = header_index(hline, header, &STROKE_COLUMNS, 0)?;
    let col = |k: usize| idx[k].unwrap_or(usize::MAX);
    let mut out: Vec<StrokeRecord> = Vec::new();
    let mut seen: HashMap<u32, usize> = HashMap::new();
    for (ln, l) in lines {
        let f = split_fields(ln, l, ',', nfields)?;
        let pose = pose_index(ln, f[col(0)])?;
        let mut strokes_mm = [0.0; LEGS];
        for (k, v) in strokes_mm.iter_mut().enumerate() {
            *v = number(ln, STROKE_COLUMNS[1 + k], f[col(1 + k)])?;
        }
        if let Some(prev) = seen.insert(pose, ln) {
            return Err(err(ln, format!("pose {pose} already on line {prev}")));
        }
        out.push(StrokeRecord {
            line: ln,
            pose,
            strokes_mm,
        });
    }
    Ok(out)
}

/// Writes a stroke file (15 decimals of mm).
pub fn format_strokes(strokes: &[StrokeRecord], header_comment: &str) -> String {
    let mut s = String::new();
    for l in header_comment.lines() {
        let _ = writeln!(s, "# {l}");
    }
    let _ = writeln!(s, "{}", STROKE_COLUMNS.join(","));
    for r in strokes {
        let v: Vec<String> = r.strokes_mm.iter().map(|x| format!("{x:.15}")).collect();
        let _ = writeln!(s, "{},{}", r.pose, v.join(","));
    }
    s
}

// ---------------------------------------------------------------------------------------
// Cross-file checks
// ---------------------------------------------------------------------------------------

/// Which file a cross-file error concerns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Which {
    /// The point export.
    Points,
    /// The stroke file.
    Strokes,
}

/// Checks the point export and the strokes against the target file: every name defined
/// and in the right place, >= 3 balls per pose, >= 3 fiducials, every pose with strokes
/// and every stroke row with a pose. Returns the pose numbers in ascending order.
pub fn check_export(
    targets: &TargetFile,
    points: &[PointRecord],
    strokes: &[StrokeRecord],
) -> Result<Vec<u32>, (Which, FileError)> {
    // Each refusal names the file it is in and the line.
    let in_points = |line: usize, message: String| (Which::Points, err(line, message));
    let in_strokes = |line: usize, message: String| (Which::Strokes, err(line, message));
    let is_ball = |n: &str| targets.balls.iter().any(|b| b.name == n);
    let is_fid = |n: &str| targets.fiducials.iter().any(|f| f.name == n);
    let mut per_pose: BTreeMap<u32, (usize, usize)> = BTreeMap::new();
    let mut fiducials = 0;
    for p in points {
        match p.pose {
            PointPose::Base => {
                if is_ball(&p.name) {
                    return Err(in_points(
                        p.line,
                        format!(
                            "{} is a ball, not a fiducial: balls belong to a pose",
                            p.name
                        ),
                    ));
                }
                if !is_fid(&p.name) {
                    return Err(in_points(
                        p.line,
                        format!("fiducial {} is not in the target file", p.name),
                    ));
                }
                fiducials += 1;
            }
            PointPose::Pose(k) => {
                if is_fid(&p.name) {
                    return Err(in_points(
                        p.line,
                        format!(
                            "{} is a fiducial: fiducials belong to the '{BASE_POSE}' rows",
                            p.name
                        ),
                    ));
                }
                if !is_ball(&p.name) {
                    return Err(in_points(
                        p.line,
                        format!("ball {} is not in the target file", p.name),
                    ));
                }
                let e = per_pose.entry(k).or_insert((0, p.line));
                e.0 += 1;
            }
        }
    }
    if fiducials < MIN_FIDUCIALS {
        return Err(in_points(0, format!("{fiducials} fiducials measured ('{BASE_POSE}' rows): the registration needs at least {MIN_FIDUCIALS}")));
    }
    for (k, (n, line)) in &per_pose {
        if *n < MIN_BALLS_PER_POSE {
            return Err(in_points(
                *line,
                format!("pose {k} has {n} balls: at least {MIN_BALLS_PER_POSE} are needed"),
            ));
        }
        if !strokes.iter().any(|s| s.pose == *k) {
            return Err(in_points(
                *line,
                format!("pose {k} has no strokes in the stroke file"),
            ));
        }
    }
    for s in strokes {
        if !per_pose.contains_key(&s.pose) {
            return Err(in_strokes(
                s.line,
                format!("pose {} has strokes but no measured balls", s.pose),
            ));
        }
    }
    Ok(per_pose.keys().copied().collect())
}
