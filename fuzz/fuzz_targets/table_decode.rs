//! The table decoder and validation. The input overwrites the nominal table image from
//! its first bytes on (so most of the image stays plausible) and the CRC is fixed, so
//! inputs get past the CRC into the decoder and validation. Properties: nothing panics;
//! a table that decodes re-encodes exactly; a validated table derives a geometry and
//! the flight IK/FK run on it without panicking.
#![no_main]

use libfuzzer_sys::fuzz_target;
use m2ctl::kinematics::{fk, ik, FkConfig, Geometry, Pose};
use m2ctl::table::layout::{CRC32, TABLE_CRC_OFFSET};
use m2ctl::table::{validate, Table, ValidationConfig, TABLE_LEN};

fuzz_target!(|bytes: &[u8]| {
    // Raw: any bytes at all.
    let _ = Table::decode(bytes);
    // Structured: a mutated nominal image with a valid CRC.
    let mut image = Table::nominal().to_bytes();
    let (offset, data) = match bytes.split_first() {
        Some((o, d)) => (usize::from(*o) * 2, d),
        None => (0, bytes),
    };
    for (i, b) in data.iter().enumerate() {
        if let Some(dst) = image.get_mut(offset + i) {
            *dst = *b;
        }
    }
    let crc = CRC32.checksum(&image[..TABLE_CRC_OFFSET]);
    image[TABLE_CRC_OFFSET..].copy_from_slice(&crc.to_le_bytes());
    let Ok(t) = Table::decode(&image) else { return };
    assert_eq!(t.to_bytes(), image, "a decoded table re-encodes exactly");
    if validate(&t, &ValidationConfig::flight()).is_ok() {
        let g = Geometry::<f32>::new(&t.geometry_params()).expect("validated geometry");
        let home = Pose::home();
        let s = ik(&g, &home).expect("home is inside every validated workspace");
        let _ = fk(&g, &s, &home, &FkConfig::default());
    }
    let _ = TABLE_LEN;
});
