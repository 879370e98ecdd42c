//! Geometry/CSV files and the `m2ground ik`/`fk` commands, run as a newcomer would.
#![allow(clippy::needless_range_loop)] // index loops over six legs/axes read clearer here
#![cfg(feature = "host")]

#[path = "../../host-tests/common/mod.rs"]
mod common;

use std::process::Command;

use m2calib::files::{format_geometry, parse_csv, parse_geometry, GeometryFile};
use m2ctl::nominal::{prototype_with_flight_limits, PROTOTYPE};

const GEOMETRY: &str = concat!(
    concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
    "/testdata/geometry.toml"
);
const GOLDEN: &str = concat!(
    concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
    "/testdata/ik_golden.csv"
);

fn m2ground(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_m2ground"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `text` written to `name` in `dir` (a test's own `tmp_dir`, removed when the test ends).
fn tmp(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn cli_ik_reproduces_the_golden_strokes_and_fk_inverts_it() {
    let (ok, out, err) = m2ground(&["ik", "--geometry", GEOMETRY, "--input", GOLDEN]);
    assert!(ok, "{err}");
    let rows = parse_csv(&out, 0..12).unwrap();
    let golden = common::golden();
    assert_eq!(rows.len(), golden.len());
    let mut worst = 0.0f64;
    for (r, (_, s)) in rows.iter().zip(&golden) {
        for i in 0..6 {
            worst = worst.max((r.values[6 + i] - s[i]).abs());
        }
    }
    assert!(worst <= 1e-6, "{worst:e}");
    // fk of that output returns the poses (f64, 15 decimals printed).
    let dir = tmp_dir("ik-fk");
    let ik_out = tmp(&dir, "ik_out.csv", &out);
    let (ok, out, err) = m2ground(&[
        "fk",
        "--geometry",
        GEOMETRY,
        "--input",
        ik_out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let back = parse_csv(&out, 0..12).unwrap();
    for (b, (p, _)) in back.iter().zip(&golden) {
        for k in 0..6 {
            assert!(
                (b.values[k] - p[k]).abs() < 1e-9,
                "{:?} vs {:?}",
                b.values,
                p
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn cli_writes_output_file_and_applies_file_limits() {
    let mut text = std::fs::read_to_string(GEOMETRY).unwrap();
    text.push_str("\n[limits]\nstroke_min_mm = -0.5\nstroke_max_mm = 0.5\ntranslation_mm = 2.0\nrotation_arcsec = 600.0\n");
    let dir = tmp_dir("output");
    let g = tmp(&dir, "limited.toml", &text);
    let out = dir.join("out.csv");
    // The golden rows with 1 mm z exceed +-0.5 mm strokes: refused, naming the line.
    let (ok, _, err) = m2ground(&[
        "ik",
        "--geometry",
        g.to_str().unwrap(),
        "--input",
        GOLDEN,
        "--output",
        out.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        err.contains("line") && err.contains("stroke limits"),
        "{err}"
    );
    let (ok, _, err) = m2ground(&[
        "ik",
        "--geometry",
        GEOMETRY,
        "--input",
        GOLDEN,
        "--output",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 41);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_files_name_the_line_and_exit_nonzero() {
    let dir = tmp_dir("bad-files");
    let cases: &[(&str, &str, &str)] = &[
        (
            "x_mm,y_mm,z_mm,rx_arcsec,ry_arcsec,rz_arcsec\n0,0,0,0,0,0\n1,2,x,0,0,0\n",
            "line 3",
            "not a number",
        ),
        (
            "x_mm,y_mm,z_mm,rx_arcsec,ry_arcsec,rz_arcsec\n0,0,NaN,0,0,0\n",
            "line 2",
            "finite",
        ),
        (
            "x_mm,y_mm,x_mm,rx_arcsec,ry_arcsec,rz_arcsec\n",
            "line 1",
            "twice",
        ),
        (
            "x_mm,y_mm,rx_arcsec,ry_arcsec,rz_arcsec\n",
            "line 1",
            "missing column 'z_mm'",
        ),
        (
            "# c\nx_mm,y_mm,z_mm,rx_arcsec,ry_arcsec,rz_arcsec\n0,0,0,0,0\n",
            "line 3",
            "expected 6 fields",
        ),
        (
            "x_mm,y_mm,z_mm,rx_arcsec,ry_arcsec,rz_arcsec\n90,0,0,0,0,0\n",
            "line 2",
            "cannot reach",
        ),
    ];
    for (i, (csv, line, what)) in cases.iter().enumerate() {
        let p = tmp(&dir, &format!("bad{i}.csv"), csv);
        let (ok, out, err) =
            m2ground(&["ik", "--geometry", GEOMETRY, "--input", p.to_str().unwrap()]);
        assert!(!ok && out.is_empty(), "case {i}: {out}");
        assert!(err.contains(line) && err.contains(what), "case {i}: {err}");
    }
    let geoms: &[(&str, &str, &str)] = &[
        (
            "p0 = [0.0, 0.0, -150.0]\n[[leg]]\na = [1.0, 2.0]\nb = [1.0, 2.0, 3.0]\n",
            "line 3",
            "",
        ),
        (
            "p0 = [0.0, 0.0, -150.0]\n[[leg]]\na = [1.0, 2.0, -134.1]\nb = [1.0, 2.0, 85.7]\n",
            "line 2",
            "exactly 6",
        ),
        ("p0 = [0.0, 0.0, -150.0\n", "line 1", ""),
    ];
    // A NaN in leg 3's b (line 20 of the reference file) and a leg whose upper joint is
    // below its lower joint.
    let good = std::fs::read_to_string(GEOMETRY).unwrap();
    let nan = good.replacen(
        "b = [-82.4898, 71.7073, 85.7000]",
        "b = [-82.4898, nan, 85.7000]",
        1,
    );
    let low = good.replacen(
        "a = [19.5562, -89.6928, -134.1000]",
        "a = [19.5562, -89.6928, 134.1000]",
        1,
    );
    let line_of = |t: &str, pat: &str| t.lines().position(|l| l.contains(pat)).unwrap() + 1;
    let nan_line = format!("line {}", line_of(&nan, "nan"));
    let low_line = format!("line {}", line_of(&low, "-89.6928, 134.1000]"));
    let mut geoms = geoms.to_vec();
    geoms.push((
        &nan,
        &nan_line,
        "leg 3 b: every value must be a finite number",
    ));
    geoms.push((&low, &low_line, "leg 5: the upper joint must be"));
    for (i, (toml, line, what)) in geoms.iter().enumerate() {
        let p = tmp(&dir, &format!("bad{i}.toml"), toml);
        let (ok, _, err) = m2ground(&["ik", "--geometry", p.to_str().unwrap(), "--input", GOLDEN]);
        assert!(!ok, "geometry case {i}");
        assert!(
            err.contains(line) && err.contains(what),
            "geometry case {i}: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn geometry_file_round_trips_exactly_with_limits_and_provenance() {
    let file = GeometryFile {
        params: prototype_with_flight_limits(),
        provenance: vec![("calibration_id".into(), "test-0001".into())],
    };
    let text = format_geometry(&file, "round trip");
    assert_eq!(parse_geometry(&text).unwrap(), file);
    let plain = GeometryFile {
        params: PROTOTYPE,
        provenance: vec![],
    };
    assert_eq!(parse_geometry(&format_geometry(&plain, "")).unwrap(), plain);
}

// ---- Issue 8, "ground tool refuses nonsense": each case failed before the fix. ----

/// A fresh directory for one test's files.
fn tmp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("m2ctl-refuse-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A simulated 120-pose measurement file written by the real binary.
fn campaign_csv(dir: &std::path::Path) -> String {
    let p = dir.join("meas.csv");
    let (ok, _, err) = m2ground(&["simulate-campaign", "--out", p.to_str().unwrap()]);
    assert!(ok, "{err}");
    std::fs::read_to_string(p).unwrap()
}

/// `text` with field `field` (0-based) of file line `line` (1-based) replaced.
fn with_field(text: &str, line: usize, field: usize, value: &str) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut f: Vec<String> = lines[line - 1].split(',').map(str::to_string).collect();
    f[field] = value.to_string();
    lines[line - 1] = f.join(",");
    lines.join("\n") + "\n"
}

/// Runs `calibrate` on `csv` (with `--report --plot` if `report`); returns (exit ok,
/// stderr, whether the output file or the plot exists).
fn calibrate_csv(
    dir: &std::path::Path,
    csv: &str,
    nominal: &str,
    report: bool,
) -> (bool, String, bool) {
    let data = dir.join("edited.csv");
    std::fs::write(&data, csv).unwrap();
    let out = dir.join("calibrated.toml");
    let plot = dir.join("errors.svg");
    let _ = std::fs::remove_file(&out);
    let _ = std::fs::remove_file(&plot);
    let mut args = vec![
        "calibrate",
        "--data",
        data.to_str().unwrap(),
        "--nominal",
        nominal,
        "--out",
        out.to_str().unwrap(),
    ];
    if report {
        args.extend(["--report", "--plot", plot.to_str().unwrap()]);
    }
    let (ok, _, err) = m2ground(&args);
    (ok, err, out.exists() || plot.exists())
}

#[test]
fn calibrate_refuses_implausible_measurements_with_the_line_and_writes_nothing() {
    let dir = tmp_dir("calibrate");
    let good = campaign_csv(&dir);
    // Line 1 is the comment, 2 the header, data from line 3. Field 6 = s1_mm, 0 = x_mm,
    // 3 = rx_arcsec.
    let cases: &[(usize, usize, &str, &str)] = &[
        (17, 6, "1e308", "stroke"), // one stroke of 1e308 (was: "inf um", exit 0)
        (40, 8, "1e30", "stroke"),  // one value of 1e30 (was: six parameters at the bound)
        (25, 0, "1e30", "workspace"), // a pose far outside the workspace
        (30, 3, "-7200", "workspace"), // 2 degrees: far outside the +-600" workspace
        (33, 10, "6.5", "stroke"),  // beyond the 5 mm slider range
        (50, 7, "-4.0", "inconsistent"), // a stroke mm off what the pose needs
    ];
    for ((line, field, value, what), report) in cases.iter().flat_map(|c| [(c, false), (c, true)]) {
        let csv = with_field(&good, *line, *field, value);
        let (ok, err, wrote) = calibrate_csv(&dir, &csv, GEOMETRY, report);
        assert!(!ok, "line {line} = {value} (report {report}): accepted");
        assert!(
            !wrote,
            "line {line} = {value}: a file was written on refusal"
        );
        assert!(
            err.contains(&format!("line {line}")) && err.contains(what),
            "line {line} = {value} (report {report}): {err}"
        );
    }
    // The unedited file is accepted.
    let (ok, err, wrote) = calibrate_csv(&dir, &good, GEOMETRY, true);
    assert!(ok && wrote, "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The reference geometry with leg `copy_to` (1-based) a copy of leg `copy_from`.
fn duplicated_leg_geometry(copy_from: usize, copy_to: usize) -> (String, usize) {
    let text = std::fs::read_to_string(GEOMETRY).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let leg_lines: Vec<usize> = lines
        .iter()
        .enumerate()
        .filter(|(_, l)| l.trim() == "[[leg]]")
        .map(|(i, _)| i)
        .collect();
    let mut out: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    let (src, dst) = (leg_lines[copy_from - 1], leg_lines[copy_to - 1]);
    out[dst + 1] = lines[src + 1].to_string();
    out[dst + 2] = lines[src + 2].to_string();
    (out.join("\n") + "\n", dst + 2)
}

#[test]
fn ik_and_calibrate_refuse_a_geometry_with_a_duplicated_leg() {
    let dir = tmp_dir("dupleg");
    let (text, a_line) = duplicated_leg_geometry(2, 4);
    let g = dir.join("dup.toml");
    std::fs::write(&g, &text).unwrap();
    let out = dir.join("ik.csv");
    let (ok, stdout, err) = m2ground(&[
        "ik",
        "--geometry",
        g.to_str().unwrap(),
        "--input",
        GOLDEN,
        "--output",
        out.to_str().unwrap(),
    ]);
    assert!(
        !ok && stdout.is_empty() && !out.exists(),
        "ik accepted: {err}"
    );
    assert!(
        err.contains(&format!("line {a_line}")) && err.contains("leg 4") && err.contains("leg 2"),
        "{err}"
    );
    let good = campaign_csv(&dir);
    let (ok, err, wrote) = calibrate_csv(&dir, &good, g.to_str().unwrap(), false);
    assert!(!ok && !wrote, "calibrate accepted: {err}");
    assert!(err.contains("leg 4"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn tc_upload_refuses_tables_the_flight_validation_refuses() {
    let dir = tmp_dir("upload");
    let base = std::fs::read_to_string(GEOMETRY).unwrap();
    let limits = "\n[limits]\nstroke_min_mm = -5.0\nstroke_max_mm = 5.0\ntranslation_mm = 2.0\nrotation_arcsec = 600.0\n";
    let good = format!("{base}{limits}");
    let off = good.replacen(
        "a = [19.5562, 89.6928, -134.1000]",
        "a = [29.5562, 89.6928, -134.1000]",
        1,
    );
    let wide = format!(
        "{base}\n[limits]\nstroke_min_mm = -1e300\nstroke_max_mm = 1e300\ntranslation_mm = 2.0\nrotation_arcsec = 600.0\n"
    );
    assert_ne!(off, good);
    for (name, text, what) in [
        ("joint 10 mm off", &off, "0x0412"),
        ("+-1e300 stroke limits", &wide, "0x0415"),
    ] {
        let g = dir.join("table.toml");
        std::fs::write(&g, text).unwrap();
        let out = dir.join("upload.bin");
        let _ = std::fs::remove_file(&out);
        let (ok, stdout, err) = m2ground(&[
            "tc",
            "--out",
            out.to_str().unwrap(),
            "upload",
            g.to_str().unwrap(),
        ]);
        assert!(!ok, "{name}: encoded");
        assert!(
            stdout.is_empty() && !out.exists(),
            "{name}: wrote something"
        );
        assert!(
            err.contains("flight validation") && err.contains(what),
            "{name}: {err}"
        );
        // Hex on stdout is refused the same way.
        let (ok, stdout, _) = m2ground(&["tc", "upload", g.to_str().unwrap()]);
        assert!(!ok && stdout.is_empty(), "{name}: hex encoded");
    }
    let g = dir.join("table.toml");
    std::fs::write(&g, &good).unwrap();
    let (ok, stdout, err) = m2ground(&["tc", "upload", g.to_str().unwrap()]);
    assert!(ok && stdout.lines().count() > 2, "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn calibrate_from_tracker_points_writes_a_table_or_nothing() {
    let dir = tmp_dir("points");
    let d = dir.to_str().unwrap();
    let (ok, _, err) = m2ground(&[
        "simulate-tracker-campaign",
        "--out-dir",
        d,
        "--campaign",
        "4",
    ]);
    assert!(ok, "{err}");
    let out = dir.join("cal.toml");
    let run = || {
        let _ = std::fs::remove_file(&out);
        let r = m2ground(&[
            "calibrate",
            "--points",
            &format!("{d}/points.csv"),
            "--strokes",
            &format!("{d}/strokes.csv"),
            "--targets",
            &format!("{d}/targets.toml"),
            "--nominal",
            GEOMETRY,
            "--out",
            out.to_str().unwrap(),
        ]);
        (r, out.exists())
    };
    let ((ok, stdout, err), wrote) = run();
    assert!(ok && wrote, "{err}");
    assert!(
        stdout.contains("predicted accuracy") && stdout.contains("observability"),
        "{stdout}"
    );
    // A ball of pose 20 renamed to another ball of the same pose: refused with the line.
    let points = std::fs::read_to_string(dir.join("points.csv")).unwrap();
    let line = points
        .lines()
        .position(|l| l.starts_with("20,B1,"))
        .unwrap()
        + 1;
    std::fs::write(
        dir.join("points.csv"),
        points.replacen("\n20,B1,", "\n20,B2,", 1),
    )
    .unwrap();
    let ((ok, stdout, err), wrote) = run();
    assert!(!ok && !wrote && stdout.is_empty(), "accepted: {err}");
    assert!(
        err.contains("points.csv") && err.contains(&format!("line {line}")),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
