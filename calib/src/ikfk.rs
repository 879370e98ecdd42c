//! The `m2ground ik` and `m2ground fk` commands, as functions of text in, text out
//! (the binary only does the file handling).

use super::eval::AXES;
use super::files::{
    csv_header, csv_line, parse_csv, read_geometry, FileError, POSE_COLUMNS, STROKE_COLUMNS,
};
use m2ctl::kinematics::{fk, ik, FkConfig, FkError, Geometry, GeometryParams, IkError, Pose, LEGS};

/// Describes an IK refusal in plain words (legs and axes 1-based).
pub fn describe_ik_error(e: &IkError) -> String {
    fn list(mask: u8, names: &[&str]) -> String {
        names
            .iter()
            .enumerate()
            .filter(|(i, _)| mask & (1 << i) != 0)
            .map(|(_, n)| *n)
            .collect::<Vec<_>>()
            .join(", ")
    }
    const LEG_NAMES: [&str; 6] = ["1", "2", "3", "4", "5", "6"];
    match e {
        IkError::NonFinite => "pose has a non-finite component".into(),
        IkError::OutsideWorkspace { axes } => {
            format!("pose outside the workspace on axis {}", list(*axes, &AXES))
        }
        IkError::Unreachable { legs } => {
            format!(
                "leg {} cannot reach the pose (negative radicand)",
                list(*legs, &LEG_NAMES)
            )
        }
        IkError::StrokeLimit { legs } => {
            format!(
                "slider {} beyond its stroke limits",
                list(*legs, &LEG_NAMES)
            )
        }
    }
}

/// Describes an FK failure in plain words.
pub fn describe_fk_error(e: &FkError) -> String {
    match e {
        FkError::NonFinite => "non-finite stroke".into(),
        FkError::Unreachable { legs, iterations } => {
            format!(
                "iterate left the reachable set (legs mask {legs:#04x}) after {iterations} steps"
            )
        }
        FkError::SingularJacobian { iterations } => {
            format!("Jacobian singular after {iterations} steps")
        }
        FkError::NotConverged { iterations } => format!("no convergence in {iterations} steps"),
        FkError::ResidualTooLarge { iterations } => {
            format!("strokes inconsistent: residual above tolerance after {iterations} steps")
        }
    }
}

fn load(geometry: &std::path::Path) -> Result<Geometry<f64>, String> {
    let g: GeometryParams = read_geometry(geometry)?.params;
    Geometry::new(&g).map_err(|e| {
        format!(
            "{}: {}",
            geometry.display(),
            super::files::describe_geometry_error(&e)
        )
    })
}

fn with_name(name: &str, e: FileError) -> String {
    format!("{name}: {e}")
}

/// `ik`: pose columns in, 12-column CSV out (f64).
pub fn run_ik(geom: &Geometry<f64>, input_name: &str, input: &str) -> Result<String, String> {
    let rows = parse_csv(input, POSE_COLUMNS).map_err(|e| with_name(input_name, e))?;
    let mut out = csv_header();
    out.push('\n');
    for r in rows {
        let v: [f64; 6] = r
            .values
            .as_slice()
            .try_into()
            .map_err(|_| format!("{input_name}: line {}: internal column count", r.line))?;
        let pose = Pose::<f64>::from_mm_arcsec([v[0], v[1], v[2]], [v[3], v[4], v[5]]);
        let s = ik(geom, &pose)
            .map_err(|e| format!("{input_name}: line {}: {}", r.line, describe_ik_error(&e)))?;
        out.push_str(&csv_line(&v, &s));
        out.push('\n');
    }
    Ok(out)
}

/// `fk`: stroke columns in, 12-column CSV out (f64), each row solved from home.
pub fn run_fk(geom: &Geometry<f64>, input_name: &str, input: &str) -> Result<String, String> {
    let rows = parse_csv(input, STROKE_COLUMNS).map_err(|e| with_name(input_name, e))?;
    let mut out = csv_header();
    out.push('\n');
    let cfg = FkConfig::<f64> {
        max_iterations: 20,
        ..FkConfig::default()
    };
    for r in rows {
        let s: [f64; LEGS] = r
            .values
            .as_slice()
            .try_into()
            .map_err(|_| format!("{input_name}: line {}: internal column count", r.line))?;
        let sol = fk(geom, &s, &Pose::home(), &cfg)
            .map_err(|e| format!("{input_name}: line {}: {}", r.line, describe_fk_error(&e)))?;
        let p = sol.pose;
        let [a, b, c] = p.rotation_arcsec();
        let [x, y, z] = p.translation_mm;
        out.push_str(&csv_line(&[x, y, z, a, b, c], &s));
        out.push('\n');
    }
    Ok(out)
}

/// Loads the geometry and input file, runs `ik` or `fk`.
pub fn run_file(
    which: IkFk,
    geometry: &std::path::Path,
    input: &std::path::Path,
) -> Result<String, String> {
    let geom = load(geometry)?;
    let text = std::fs::read_to_string(input).map_err(|e| format!("{}: {e}", input.display()))?;
    let name = input.display().to_string();
    match which {
        IkFk::Ik => run_ik(&geom, &name, &text),
        IkFk::Fk => run_fk(&geom, &name, &text),
    }
}

/// Which direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IkFk {
    /// Pose -> strokes.
    Ik,
    /// Strokes -> pose.
    Fk,
}
