//! The geometry file format against the flight crate: the reference geometry file
//! (testdata/geometry.toml) parses to exactly the compiled-in nominal geometry.

#![cfg(feature = "host")]

use m2ctl::nominal::PROTOTYPE;

#[test]
fn compiled_in_nominal_matches_the_reference_geometry_file() {
    let text = std::fs::read_to_string(concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/testdata/geometry.toml"
    ))
    .unwrap();
    let file = m2calib::files::parse_geometry(&text).unwrap();
    assert_eq!(file.params, PROTOTYPE);
}
