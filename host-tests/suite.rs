//! The test suite itself: every file in `host-tests/` is a registered test target.
//! (`Cargo.toml` has `autotests = false` because the suite lives in `host-tests/`, so a
//! new file would otherwise never run.)

use std::collections::BTreeSet;

#[test]
fn every_host_test_file_is_registered_in_cargo_toml() {
    let root = env!("CARGO_MANIFEST_DIR");
    let manifest = std::fs::read_to_string(format!("{root}/Cargo.toml")).unwrap();
    let registered: BTreeSet<String> = manifest
        .lines()
        .filter_map(|l| l.trim().strip_prefix("path = \"host-tests/"))
        .filter_map(|l| l.strip_suffix('"'))
        .map(str::to_owned)
        .collect();
    let files: BTreeSet<String> = std::fs::read_dir(format!("{root}/host-tests"))
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".rs"))
        .collect();
    let missing: Vec<_> = files.difference(&registered).collect();
    assert!(
        missing.is_empty(),
        "not registered as [[test]]: {missing:?}"
    );
    let stale: Vec<_> = registered.difference(&files).collect();
    assert!(stale.is_empty(), "registered but missing: {stale:?}");
}
