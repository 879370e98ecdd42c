//! The target's f32 results are bit-identical to the host's (same code, IEEE-754).
//!
//! Needs the decoded log of the firmware's QEMU run, produced by
//! `scripts/qemu-selftest.sh` (which then runs this test) or `.ci/run`:
//! `M2_FIRMWARE_LOG=target/m2fw-selftest.log cargo test --features host --test firmware -- --ignored`.
#![allow(clippy::needless_range_loop)] // index loops over six legs/axes read clearer here

use m2ctl::kinematics::Geometry;
use m2ctl::nominal::prototype_with_flight_limits;
use m2ctl::selftest::{run_all, RowOutcome};

fn parse_list(s: &str) -> Vec<u32> {
    s.trim_matches(|c| c == '[' || c == ']')
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect()
}

fn field<'a>(line: &'a str, key: &str) -> &'a str {
    let start = line
        .find(key)
        .unwrap_or_else(|| panic!("{key} missing in {line}"))
        + key.len();
    let rest = &line[start..];
    if rest.starts_with('[') {
        &rest[..=rest.find(']').unwrap()]
    } else {
        rest.split_whitespace().next().unwrap()
    }
}

#[test]
#[ignore = "needs the firmware's QEMU log: run scripts/qemu-selftest.sh"]
fn firmware_bits_match_host() {
    let path =
        std::env::var("M2_FIRMWARE_LOG").expect("set M2_FIRMWARE_LOG to the decoded firmware log");
    let log = std::fs::read_to_string(&path).unwrap();
    let geom = Geometry::<f32>::new(&prototype_with_flight_limits()).unwrap();
    let mut host: Vec<RowOutcome> = Vec::new();
    let summary = run_all(&geom, |_, o| host.push(*o));
    let target: Vec<&str> = log.lines().filter(|l| l.contains("BITS row=")).collect();
    assert_eq!(target.len(), host.len(), "rows in the firmware log");
    for (i, (line, h)) in target.iter().zip(&host).enumerate() {
        assert_eq!(field(line, "row=").parse::<usize>().unwrap(), i);
        assert_eq!(
            parse_list(field(line, "ik=")),
            h.ik_bits.to_vec(),
            "row {i} IK bits"
        );
        assert_eq!(
            parse_list(field(line, "fk=")),
            h.fk_bits.to_vec(),
            "row {i} FK bits"
        );
        assert_eq!(
            field(line, "it=").parse::<u8>().unwrap(),
            h.fk_iterations,
            "row {i}"
        );
        assert_eq!(
            field(line, "pass=").parse::<bool>().unwrap(),
            h.pass,
            "row {i}"
        );
    }
    let s = log
        .lines()
        .find(|l| l.contains("SUMMARY"))
        .expect("SUMMARY line");
    let digest = u32::from_str_radix(field(s, "digest=").trim_start_matches("0x"), 16).unwrap();
    assert_eq!(digest, summary.digest);
    assert!(log.contains("SELFTEST PASS"));
    println!(
        "{} rows: target f32 bits == host f32 bits, digest {digest:#010x}",
        host.len()
    );
}
