//! Geometry/CSV files and the `m2ground ik`/`fk` commands, run as a newcomer would.
#![allow(clippy::needless_range_loop)] // index loops over six legs/axes read clearer here

mod common;

use std::process::Command;

use m2ctl::ground::files::{format_geometry, parse_csv, parse_geometry, GeometryFile};
use m2ctl::nominal::{prototype_with_flight_limits, PROTOTYPE};

const GEOMETRY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/testdata/geometry.toml");
const GOLDEN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/testdata/ik_golden.csv");

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

fn tmp(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("m2ctl-files-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
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
    let ik_out = tmp("ik_out.csv", &out);
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
}

#[test]
fn cli_writes_output_file_and_applies_file_limits() {
    let mut text = std::fs::read_to_string(GEOMETRY).unwrap();
    text.push_str("\n[limits]\nstroke_min_mm = -0.5\nstroke_max_mm = 0.5\ntranslation_mm = 2.0\nrotation_arcsec = 600.0\n");
    let g = tmp("limited.toml", &text);
    let out = std::env::temp_dir().join(format!("m2ctl-out-{}.csv", std::process::id()));
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
}

#[test]
fn bad_files_name_the_line_and_exit_nonzero() {
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
        let p = tmp(&format!("bad{i}.csv"), csv);
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
        let p = tmp(&format!("bad{i}.toml"), toml);
        let (ok, _, err) = m2ground(&["ik", "--geometry", p.to_str().unwrap(), "--input", GOLDEN]);
        assert!(!ok, "geometry case {i}");
        assert!(
            err.contains(line) && err.contains(what),
            "geometry case {i}: {err}"
        );
    }
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
