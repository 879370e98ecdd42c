//! `docs/icd.md` against the code, table by table: failure codes, event IDs and their
//! severities, function IDs and lengths, the housekeeping layout and the table layout.
//! Any drift between the document and the implementation fails here.

mod common;

use std::collections::BTreeSet;

use common::{all_ok, calibrated_table, install, wire, JOB_CYCLES};
use m2ctl::controller::event;
use m2ctl::ground::station::Tm;
use m2ctl::link::command::{FunctionId, WirePose, FUNCTION_ID_LEN};
use m2ctl::link::hk::{ScheduleHk, HK_REPORT_LEN};
use m2ctl::link::tm::EventSeverity;
use m2ctl::link::tm::TmTime;
use m2ctl::link::{Command, Housekeeping};
use m2ctl::sim::{Bench, InjectedFault, SwitchEnd};
use m2ctl::table::{Table, TABLE_LEN};

fn icd() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/icd.md")).unwrap()
}

/// The rows of the markdown table that follows the heading line containing `heading`:
/// cells trimmed, the header and separator rows skipped.
fn table_after(text: &str, heading: &str) -> Vec<Vec<String>> {
    let mut lines = text.lines().skip_while(|l| !l.contains(heading)).skip(1);
    let mut rows = Vec::new();
    let mut started = false;
    for l in lines.by_ref() {
        let l = l.trim();
        if l.starts_with('|') {
            started = true;
            let cells: Vec<String> = l
                .trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect();
            if cells
                .iter()
                .all(|c| c.chars().all(|ch| ch == '-' || ch == ':'))
            {
                continue;
            }
            rows.push(cells);
        } else if started {
            break;
        }
    }
    // Drop the header row.
    if !rows.is_empty() {
        rows.remove(0);
    }
    rows
}

fn hex(cell: &str) -> Option<u32> {
    cell.strip_prefix("0x")
        .and_then(|h| u32::from_str_radix(h, 16).ok())
}

/// Every failure code the controller can report in a service-1 report: the mission
/// database's one sample of each variant (itself checked against every `code()` arm of
/// the flight sources by `host-tests/mdb.rs`), without the nested families (geometry,
/// IK, FK codes appear only inside another code's data).
fn code_side_codes() -> BTreeSet<u16> {
    m2ctl::ground::mdb::failure_codes()
        .into_iter()
        .filter(|c| !matches!(c.family, "GEOMETRY" | "IK" | "FK"))
        .map(|c| c.code)
        .collect()
}

#[test]
fn failure_code_table_lists_exactly_the_codes_of_the_code() {
    let rows = table_after(&icd(), "## 7. Failure codes");
    let documented: BTreeSet<u16> = rows
        .iter()
        .filter_map(|r| r.first().and_then(|c| hex(c)))
        .map(|c| c as u16)
        .collect();
    let code = code_side_codes();
    let missing: Vec<_> = code
        .difference(&documented)
        .map(|c| format!("{c:#06x}"))
        .collect();
    let stale: Vec<_> = documented
        .difference(&code)
        .map(|c| format!("{c:#06x}"))
        .collect();
    assert!(
        missing.is_empty(),
        "codes missing from the ICD: {missing:?}"
    );
    assert!(
        stale.is_empty(),
        "ICD codes the code does not have: {stale:?}"
    );
    // Every row says which report carries the code.
    for r in &rows {
        assert!(
            r.get(3)
                .is_some_and(|c| c.contains("TM[1,") || c.contains('—') || c.contains("no report")),
            "row without a report type: {r:?}"
        );
    }
}

/// The event table's IDs and severities.
fn documented_events() -> Vec<(u16, String)> {
    table_after(&icd(), "### Events (service 5)")
        .into_iter()
        .filter_map(|r| {
            let id = hex(r.first()?)? as u16;
            Some((id, r.get(2)?.clone()))
        })
        .collect()
}

#[test]
fn event_table_lists_exactly_the_event_ids_of_the_code() {
    // The mission database's events, each checked against the flight constants and the
    // emitting code by host-tests/mdb.rs.
    let code: BTreeSet<u16> = m2ctl::ground::mdb::events().iter().map(|e| e.id).collect();
    let doc: BTreeSet<u16> = documented_events().into_iter().map(|(id, _)| id).collect();
    assert_eq!(doc, code);
}

fn severity_name(s: EventSeverity) -> &'static str {
    match s {
        EventSeverity::Info => "info",
        EventSeverity::Low => "low",
        EventSeverity::Medium => "medium",
        EventSeverity::High => "high",
    }
}

#[test]
fn every_event_arrives_with_the_severity_the_icd_names() {
    // A scenario that raises most events: boot, moves, a refusal, a fault and its
    // clear, a warning, table commit/activation/rejection.
    let mut r = Bench::new();
    r.run(2);
    let mv = r.send(&Command::MoveAbsolute(wire(600.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    r.run(1500);
    r.plant.with(|p| {
        p.inject(InjectedFault::EncoderJump {
            leg: 1,
            jump_mm: 0.3,
        })
    });
    r.settle(5_000);
    assert!(!r.st.reports(mv).is_empty());
    r.plant.with(|p| p.clear_faults());
    r.run(3);
    assert!(all_ok(&r.command(&Command::ClearFault, 10)));
    r.send(&Command::MoveAbsolute(wire(
        9_000.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    )));
    let t = calibrated_table(3);
    assert!(all_ok(&install(&mut r, &t, true)));
    let mut bad = t;
    bad.legs[0].a_mm[0] += 5.0;
    install(&mut r, &bad, false);
    r.command(&Command::SwitchBank, JOB_CYCLES);
    // A following warning: missed steps between the warning and the fault threshold.
    r.plant.with(|p| {
        p.inject(InjectedFault::MissedSteps {
            leg: 2,
            lost_mm: 0.01,
        })
    });
    r.run(20);
    // A parameter set (persisted, then event 0x0040).
    r.plant.with(|p| p.clear_faults());
    r.settle(5_000);
    r.command(&Command::ClearFault, 10);
    let set = Command::SetParameters(
        m2ctl::link::command::ParameterValues::new(&[(0x0003, 25_000_000)]).unwrap(),
    );
    assert!(all_ok(&r.command(&set, JOB_CYCLES)));
    // An end-of-travel switch (stuck active): event 0x0007, then repaired.
    r.plant.with(|p| {
        p.inject(InjectedFault::SwitchStuckActive {
            leg: 3,
            end: SwitchEnd::Upper,
        })
    });
    r.run(3);
    r.plant.with(|p| p.clear_faults());
    r.run(3);
    let documented = documented_events();
    let mut seen = BTreeSet::new();
    for tm in &r.st.log {
        if let Tm::Event(sev, id, _) = tm {
            let (_, doc) = documented
                .iter()
                .find(|(d, _)| d == id)
                .unwrap_or_else(|| panic!("event {id:#06x} not in the ICD"));
            assert!(
                doc.contains(severity_name(*sev)),
                "event {id:#06x} came as {sev:?}, the ICD says {doc:?}"
            );
            seen.insert(*id);
        }
    }
    for id in [
        event::STATE_CHANGED,
        event::FAULT_LATCHED,
        event::FAULTS_CLEARED,
        event::WARNING_CHANGED,
        event::MOVE_REFUSED,
        event::TABLE_ACTIVATED,
        event::TABLE_REJECTED,
        event::TABLE_COMMITTED,
        event::BOOT,
        event::BOOT_DETAIL,
        event::PARAMETERS_CHANGED,
        event::END_OF_TRAVEL,
    ] {
        assert!(seen.contains(&id), "the scenario did not raise {id:#06x}");
    }
}

#[test]
fn function_table_matches_the_function_ids_and_lengths() {
    let rows = table_after(&icd(), "### TC[8,1] functions");
    let doc: Vec<(u16, usize)> = rows
        .iter()
        .filter_map(|r| Some((hex(r.first()?)? as u16, r.get(3)?.parse().ok()?)))
        .collect();
    let code: Vec<(u16, usize)> = FunctionId::ALL
        .iter()
        .map(|f| (f.code(), FUNCTION_ID_LEN + f.args_len()))
        .collect();
    assert_eq!(doc, code);
}

/// Parses a layout table (offset, size, ...) and checks it is contiguous from 0 to
/// `total`; returns (offset, size) per row.
fn contiguous_layout(heading: &str, total: usize) -> Vec<(usize, usize)> {
    let rows = table_after(&icd(), heading);
    let mut at = 0;
    let mut out = Vec::new();
    for r in &rows {
        let off: usize = r[0].parse().unwrap_or_else(|_| panic!("{r:?}"));
        let size: usize = r[1].parse().unwrap_or_else(|_| panic!("{r:?}"));
        assert_eq!(
            off, at,
            "{heading}: row {r:?} does not follow the previous one"
        );
        at += size;
        out.push((off, size));
    }
    assert_eq!(at, total, "{heading}: the rows end at {at}");
    out
}

#[test]
fn housekeeping_table_matches_the_emitted_bytes() {
    let rows = contiguous_layout("## 6. Housekeeping TM[3,25]", HK_REPORT_LEN);
    // Each field set to a marker, found at its documented offset (fields in row order).
    let mut hk = Housekeeping {
        state: 0x11,
        boot_source: 0x12,
        active_bank: 0x13,
        fk_iterations: 0x14,
        fk_valid: true,
        cycle_counter: 0x1616_1616,
        fault_flags: 0x1717_1717,
        warning_flags: 0x1818_1818,
        refusal_bits: 0x1919_1919,
        active_table_id: 0x1a1a_1a1a,
        active_table_crc32: 0x1b1b_1b1b,
        pose_fk: WirePose::from_array([0x1c1c_1c1c; 6]),
        pose_commanded: WirePose::from_array([0x1d1d_1d1d; 6]),
        strokes_commanded_nm: [0x1e1e_1e1e; 6],
        encoders_nm: [0x1f1f_1f1f; 6],
        tc_accepted: 0x2020,
        tc_rejected: 0x2121,
        last_failure_code: 0x2222,
        moving_legs: 0x23,
        fault_legs: 0x24,
        pending_bank: 0x25,
        pending_table_id: 0x2626_2626,
        job: 0x27,
        selected_source: 0x28,
        tm_dropped: 0x2929,
        tc_frames_dropped: 0x2a2a,
        uart_overruns: 0x2b2b,
        cycle_overruns: 0x2c2c,
        reset_cause: 0x2d,
        boot_count: 0x2e2e,
        bank_health: 0x2f,
        pivot_nm: [0x3030_3030; 3],
        pose_fk_operator: WirePose::from_array([0x3131_3131; 6]),
        pose_commanded_operator: WirePose::from_array([0x3232_3232; 6]),
        parameters_set: 0x3333_3333,
        schedule: ScheduleHk {
            activities: 0x34,
            release_enabled: true,
            released: 0x3636,
            failed: 0x3737,
            next_release: TmTime {
                seconds: 0x3838_3838,
                fraction: 0x3838,
            },
            time_report_rate: 0x39,
        },
        limit_lower_legs: 0x3a,
        limit_upper_legs: 0x3b,
        reference_legs: 0x3c,
        switch_unreadable_legs: 0x3d,
    };
    let mut bytes = [0u8; HK_REPORT_LEN];
    hk.emit(&mut bytes);
    assert_eq!(bytes[0], 1, "structure ID");
    for (k, (off, size)) in rows.iter().enumerate().skip(1) {
        // Rows 5 (FK valid) and 33 (release enabled) are booleans.
        let marker = if k == 5 || k == 37 { 1 } else { 0x10 + k as u8 };
        assert!(
            bytes[*off..off + size].iter().all(|b| *b == marker),
            "row {k} at {off}+{size}: {:02x?}",
            &bytes[*off..off + size]
        );
    }
    hk.fk_valid = false;
    hk.emit(&mut bytes);
    assert_eq!(Housekeeping::parse(&bytes), Some(hk));
}

#[test]
fn table_layout_matches_the_encoded_image() {
    let rows = contiguous_layout("### The table image", TABLE_LEN);
    let mut t = Table::nominal();
    t.table_id = 0xA1A2_A3A4;
    t.provenance.calibration_id = 0xB1B2_B3B4;
    t.p0_mm = [1.25, -2.5, 3.75];
    t.supervision.following_error_warning_mm = 0.125;
    t.supervision.stuck_detection_cycles = 0x1234;
    let b = t.to_bytes();
    let at = |field: usize| rows[field].0;
    assert_eq!(&b[at(0)..at(0) + 4], b"M2TB");
    assert_eq!(
        u32::from_le_bytes(b[at(3)..at(3) + 4].try_into().unwrap()),
        t.table_id
    );
    assert_eq!(
        u32::from_le_bytes(b[at(4)..at(4) + 4].try_into().unwrap()),
        t.provenance.calibration_id
    );
    assert_eq!(
        f64::from_le_bytes(b[at(7)..at(7) + 8].try_into().unwrap()),
        1.25
    );
    assert_eq!(
        f64::from_le_bytes(b[at(7) + 16..at(7) + 24].try_into().unwrap()),
        3.75
    );
    assert_eq!(
        f32::from_le_bytes(b[at(12)..at(12) + 4].try_into().unwrap()),
        0.125
    );
    assert_eq!(
        u16::from_le_bytes(b[at(16)..at(16) + 2].try_into().unwrap()),
        0x1234
    );
    assert_eq!(
        u32::from_le_bytes(b[at(20)..at(20) + 4].try_into().unwrap()),
        t.crc32()
    );
}

#[test]
fn activate_of_a_pending_table_reports_each_stage_and_the_boot_follows() {
    // The ICD's verification table for a table job: start at once, completion later.
    let mut r = Bench::new();
    r.run(1);
    let t = calibrated_table(4);
    let reps = install(&mut r, &t, false);
    assert!(all_ok(&reps));
    let rid = r.send(&Command::ActivateTable {
        table_id: 4,
        crc32: t.crc32(),
    });
    let reps = r.st.reports(rid);
    assert_eq!(
        reps,
        [
            m2ctl::link::tm::Verification::AcceptanceSuccess,
            m2ctl::link::tm::Verification::StartSuccess
        ],
        "completion only when the selection is written"
    );
    r.run(JOB_CYCLES);
    assert!(all_ok(&r.st.reports(rid)));
}

/// "1,000..500,000" / "±648,000,000" / "0" -> (min, max) or a single value.
fn icd_number(cell: &str) -> Option<i64> {
    cell.replace(',', "").trim().parse().ok()
}

#[test]
fn parameter_table_matches_the_parameters_of_the_code() {
    use m2ctl::controller::params::{Default, PARAMETERS};
    let rows = table_after(&icd(), "## 5a. On-board parameters");
    assert_eq!(rows.len(), PARAMETERS.len(), "one row per parameter");
    for (r, d) in rows.iter().zip(PARAMETERS.iter()) {
        assert_eq!(hex(&r[0]), Some(u32::from(d.id)), "{r:?}");
        let unit = r[2].replace('²', "^2");
        assert!(unit.starts_with(d.unit), "{r:?}: unit {}", d.unit);
        let (lo, hi) = if let Some(m) = r[3].strip_prefix('±') {
            let m = icd_number(m).unwrap();
            (-m, m)
        } else {
            let (a, b) = r[3].split_once("..").unwrap_or_else(|| panic!("{r:?}"));
            (icd_number(a).unwrap(), icd_number(b).unwrap())
        };
        assert_eq!((lo, hi), (i64::from(d.min), i64::from(d.max)), "{r:?}");
        match d.default {
            Default::Fixed(v) => assert_eq!(icd_number(&r[4]), Some(i64::from(v)), "{r:?}"),
            Default::Table => assert!(r[4].contains("table"), "{r:?}"),
        }
    }
}
