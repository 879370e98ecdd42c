//! `docs/icd.md` against the code. Its tables that restate the code (codes, IDs,
//! offsets, lengths, units, ranges, severities) are generated from the mission
//! database (`m2ground::icd`, `m2ground icd-tables`): the checked-in document must
//! be what the generator writes, so a code or a description that changes without the
//! document, or a hand edit inside a generated block, fails here with the diff and the
//! command that regenerates it. The description itself is checked against the flight
//! code in `ground/tests/mdb.rs`; here also what a run of the controller sends.

#![cfg(feature = "host")]

#[path = "../../host-tests/common/mod.rs"]
mod common;

use std::collections::BTreeSet;
use std::process::Command as Process;

use common::{all_ok, calibrated_table, install, wire, JOB_CYCLES};
use m2ctl::controller::event;
use m2ctl::link::Command;
use m2ctl::sim::{Bench, InjectedFault, SwitchEnd};
use m2ctl::station::Tm;
use m2ground::icd;

const ICD: &str = "docs/icd.md";

fn icd() -> String {
    std::fs::read_to_string(concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/docs/icd.md"
    ))
    .unwrap()
}

/// docs/icd.md as the generator writes it (the checked-in one unless it drifted).
fn generated_icd() -> String {
    icd::regenerate(&icd()).unwrap_or_else(|e| panic!("{ICD}: {e}"))
}

#[test]
fn the_icd_tables_are_the_ones_generated_from_the_code() {
    let drift = icd::drift(&icd()).unwrap_or_else(|e| panic!("{ICD}: {e}"));
    assert!(drift.is_empty(), "{}", icd::drift_report(ICD, &drift));
    let names: Vec<&str> = icd::blocks().unwrap().iter().map(|b| b.name).collect();
    println!(
        "{} generated blocks up to date: {}",
        names.len(),
        names.join(", ")
    );
}

/// The document with the first line of block `name` that contains `from` changed to
/// contain `to`.
fn edit_in_block(doc: &str, name: &str, from: &str, to: &str) -> String {
    let begin = icd::begin_marker(name);
    let start = doc.find(&begin).unwrap() + begin.len();
    let end = start + doc[start..].find(&icd::end_marker(name)).unwrap();
    let at = start + doc[start..end].find(from).unwrap();
    format!("{}{to}{}", &doc[..at], &doc[at + from.len()..])
}

#[test]
fn a_hand_edit_of_a_generated_cell_is_drift_and_regenerating_undoes_only_it() {
    // From the generated document, so that only the test above fails on drift.
    let doc = generated_icd();
    // A wrong failure code, a wrong housekeeping offset, and prose added outside any
    // block (the generator leaves prose alone).
    let edited = edit_in_block(&doc, "failure-codes", "| 0x0604 |", "| 0x0640 |");
    let edited = edit_in_block(&edited, "housekeeping", "| 143 | 2 |", "| 144 | 2 |");
    let prose = "\nA paragraph added after the last block.\n";
    let edited = format!("{edited}{prose}");
    assert_ne!(edited, doc);
    let drift = icd::drift(&edited).unwrap();
    let names: Vec<&str> = drift.iter().map(|d| d.name).collect();
    assert_eq!(names, ["housekeeping", "failure-codes"]);
    let report = icd::drift_report(ICD, &drift);
    assert!(
        report.contains("housekeeping, failure-codes")
            && report.contains("icd-tables --write docs/icd.md"),
        "{report}"
    );
    assert!(
        report.contains("- | 0x0640 |") && report.contains("+ | 0x0604 |"),
        "{report}"
    );
    assert!(
        report.contains("- | 144 | 2 |") && report.contains("+ | 143 | 2 |"),
        "{report}"
    );
    let fixed = icd::regenerate(&edited).unwrap();
    assert_eq!(
        fixed,
        format!("{doc}{prose}"),
        "the blocks restored, the prose kept"
    );
    assert_eq!(
        icd::regenerate(&fixed).unwrap(),
        fixed,
        "regenerating is idempotent"
    );
}

#[test]
fn a_missing_or_unknown_block_is_refused() {
    let doc = generated_icd();
    let gone = doc.replace(&icd::begin_marker("events"), "");
    let e = icd::drift(&gone).unwrap_err();
    assert!(e.contains("events"), "{e}");
    let unknown = doc.replacen(
        &icd::begin_marker("events"),
        &format!(
            "{}\n{}\n{}",
            icd::begin_marker("no-such-table"),
            icd::end_marker("no-such-table"),
            icd::begin_marker("events")
        ),
        1,
    );
    let e = icd::drift(&unknown).unwrap_err();
    assert!(e.contains("no-such-table"), "{e}");
}

#[test]
fn m2ground_icd_tables_checks_and_writes() {
    let exe = env!("CARGO_BIN_EXE_m2ground");
    let dir = std::env::temp_dir().join(format!("m2-icd-tables-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("icd.md");
    let run = |args: &[&str]| {
        Process::new(exe)
            .arg("icd-tables")
            .args(args)
            .output()
            .unwrap()
    };
    let doc = generated_icd();
    std::fs::write(&path, &doc).unwrap();
    let p = path.to_str().unwrap();
    assert!(
        run(&["--check", p]).status.success(),
        "the generated text passes"
    );
    std::fs::write(
        &path,
        edit_in_block(&doc, "events", "| 0x0021 |", "| 0x0022 |"),
    )
    .unwrap();
    let out = run(&["--check", p]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "drift must fail --check");
    assert!(
        err.contains("events") && err.contains("+ | 0x0021 |"),
        "{err}"
    );
    assert!(run(&["--write", p]).status.success());
    assert_eq!(std::fs::read_to_string(&path).unwrap(), doc);
    assert!(run(&["--check", p]).status.success());
    let printed = run(&[]);
    assert!(String::from_utf8_lossy(&printed.stdout).contains(&icd::end_marker("failure-codes")));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn every_event_arrives_with_a_severity_the_description_names() {
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
    // The description's severities (the ICD's event table is generated from them;
    // ground/tests/mdb.rs checks them against the emitting statements, this against what
    // the controller sends in a run).
    let described = m2ground::mdb::events();
    let mut seen = BTreeSet::new();
    for tm in &r.st.log {
        if let Tm::Event(sev, id, _) = tm {
            let e = described
                .iter()
                .find(|e| e.id == *id)
                .unwrap_or_else(|| panic!("event {id:#06x} not described"));
            assert!(
                e.severities
                    .iter()
                    .any(|s| s.severity == m2ground::mdb::severity_name(*sev)),
                "event {id:#06x} came as {sev:?}, the description says {:?}",
                e.severities
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

/// Section 1's telemetry-queue figures are the code's constants (prose, not a generated
/// table: each number is found in its sentence).
#[test]
fn the_telemetry_queue_figures_in_section_1_are_the_codes() {
    use m2ctl::controller::comms::MAX_TC_PER_PASS;
    use m2ctl::controller::telemetry::{
        ADMISSION_FREE_SLOTS, MAX_BULK_PER_TC, MAX_DEFERRED_REPLIES, MAX_REPLIES_PER_TC,
        REPLY_RESERVE, TM_QUEUE_LEN, TM_RESERVED_SLOTS,
    };
    let text = std::fs::read_to_string(concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/docs/icd.md"
    ))
    .unwrap()
    .replace('\n', " ")
    .split_whitespace()
    .collect::<Vec<_>>()
    .join(" ");
    for phrase in [
        format!("At most **{MAX_TC_PER_PASS} telecommands are executed per control cycle**"),
        format!("has **{ADMISSION_FREE_SLOTS} free places**"),
        format!("queues up to {TM_QUEUE_LEN} telemetry records"),
        format!("one telecommand queues at most {MAX_REPLIES_PER_TC} replies at once"),
        format!("still owes at most {MAX_DEFERRED_REPLIES} (a move's start and completion)"),
        format!("events never take the last {REPLY_RESERVE} places"),
        format!("telecommands are taken only with {ADMISSION_FREE_SLOTS} free"),
        format!("queued while more than {REPLY_RESERVE} places are free"),
        format!("queued while more than {TM_RESERVED_SLOTS} places are free"),
        format!("taken with {ADMISSION_FREE_SLOTS} free places gets all {MAX_BULK_PER_TC} chunks"),
    ] {
        assert!(
            text.contains(&phrase),
            "docs/icd.md section 1 lacks: {phrase}"
        );
    }
}

/// Every housekeeping offset the ICD names is where the code puts it: written
/// "`name`, offset N" (prose and generated texts alike), field `name` is at N. (Section
/// 10 named "HK offset 157", pivot y, for the failed-activity count at 221.)
#[test]
fn housekeeping_offsets_in_the_prose_are_the_codes() {
    use m2ground::mdb::housekeeping_rows;
    let fields: Vec<(String, usize)> = housekeeping_rows()
        .into_iter()
        .flat_map(|r| r.fields.into_iter().map(|(f, _)| f))
        .map(|f| (f.name, f.offset))
        .collect();
    let text = std::fs::read_to_string(concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/docs/icd.md"
    ))
    .unwrap()
    .split_whitespace()
    .collect::<Vec<_>>()
    .join(" ");
    let number = |s: &str| -> Option<usize> {
        let d: String = s.chars().take_while(|c| c.is_ascii_digit()).collect();
        d.parse().ok()
    };
    let mut checked = 0;
    // "`name`, offset N"
    for (at, _) in text.match_indices("`, offset ") {
        let name_start = text[..at].rfind('`').unwrap() + 1;
        let name = &text[name_start..at];
        let n = number(&text[at + "`, offset ".len()..]).unwrap();
        let f = fields.iter().find(|f| f.0 == name);
        assert_eq!(f.map(|f| f.1), Some(n), "docs/icd.md: `{name}`, offset {n}");
        checked += 1;
    }
    // A bare "HK offset" cannot be checked against a name: the prose names its field.
    assert!(
        !text.contains("HK offset"),
        "docs/icd.md: write housekeeping offsets as \"`name`, offset N\""
    );
    assert!(checked >= 14, "{checked} offsets checked");
}

/// The table's length and the chunk ranges the ICD's prose states are the code's
/// (the e2e's refused chunk was once left at the length of table format 1).
#[test]
fn the_table_figures_in_the_prose_are_the_codes() {
    use m2ctl::link::command::TABLE_CHUNK_MAX_LEN;
    use m2ctl::table::TABLE_LEN;
    let text = icd().split_whitespace().collect::<Vec<_>>().join(" ");
    let crc_start = TABLE_LEN - 4;
    for phrase in [
        format!("### The table image ({TABLE_LEN} bytes"),
        format!(
            "a table chunk offset 0..{} with 1..{TABLE_CHUNK_MAX_LEN} bytes",
            TABLE_LEN - 1
        ),
        format!("A chunk outside 0..{TABLE_LEN} is refused (0x050E)"),
        format!("(offset + length ≤ {TABLE_LEN}; 0x050E)"),
        format!("the CRC-32 of bytes 0..{crc_start} (= the u32 at {crc_start}..{TABLE_LEN})"),
    ] {
        assert!(text.contains(&phrase), "docs/icd.md lacks: {phrase}");
    }
}

/// The fine positioning's figures in section 3's prose are `motion::fine`'s constants.
#[test]
fn the_fine_positioning_figures_in_the_prose_are_the_codes() {
    use m2ctl::motion::fine::{
        LATE_CORRECTION, MAX_CORRECTIONS, MAX_CORRECTION_MM, MICROSTEP_MM, RETREAT_MM,
        TIMEOUT_CYCLES, TURN_MM,
    };
    use m2ctl::timing::CONTROL_RATE_HZ;
    let um = |mm: f32| format!("{}", (f64::from(mm) * 1e3 * 1e3).round() / 1e3);
    let text = icd().split_whitespace().collect::<Vec<_>>().join(" ");
    for phrase in [
        format!("at most {MAX_CORRECTIONS} corrections per move"),
        format!(
            "at most {} um per leg from its setpoint",
            um(MAX_CORRECTION_MM)
        ),
        format!("a reversal counts once it exceeds {} um", um(TURN_MM)),
        format!("whole microsteps of its drive ({} um)", um(MICROSTEP_MM)),
        format!(
            "is moved {} um back past it and returned by as much",
            um(RETREAT_MM)
        ),
        format!("as is one still not in position at the {LATE_CORRECTION}th correction"),
        format!(
            "A move not in position {} s after its path ends with TM[1,8] 0x070F",
            TIMEOUT_CYCLES / CONTROL_RATE_HZ
        ),
    ] {
        assert!(
            text.contains(&phrase),
            "docs/icd.md section 3 lacks: {phrase}"
        );
    }
}

/// The temperature paragraph of section 6 states the controller's sensor constants.
#[test]
fn the_temperature_figures_in_the_prose_are_the_codes() {
    use m2ctl::thermal::{MEAN_SAMPLES, STUCK_SAMPLES};
    use m2ctl::timing::{CONTROL_RATE_HZ, TEMPERATURE_PERIOD_CYCLES, TEMPERATURE_PHASE_CYCLES};
    let ms = |cycles: u32| cycles * 1000 / CONTROL_RATE_HZ;
    let period_ms = ms(TEMPERATURE_PERIOD_CYCLES);
    let first_mean_ms =
        ms((u32::from(MEAN_SAMPLES) - 1) * TEMPERATURE_PERIOD_CYCLES + TEMPERATURE_PHASE_CYCLES);
    let text = icd().split_whitespace().collect::<Vec<_>>().join(" ");
    for phrase in [
        format!("reads every temperature sensor once per {period_ms} ms"),
        format!("each one's mean of {MEAN_SAMPLES} readings"),
        format!(
            "({MEAN_SAMPLES} readings, the first {} ms into the first {period_ms} ms: {} s after boot",
            ms(TEMPERATURE_PHASE_CYCLES),
            f64::from(first_mean_ms) / 1000.0
        ),
        format!(
            "stuck after {STUCK_SAMPLES} equal readings ({} s)",
            f64::from(ms(u32::from(STUCK_SAMPLES) * TEMPERATURE_PERIOD_CYCLES)) / 1000.0
        ),
    ] {
        assert!(text.contains(&phrase), "docs/icd.md section 6 lacks: {phrase}");
    }
}

/// The thermal compensation paragraph (section 5) and the exposure hold (section 3)
/// say the codes' figures.
#[test]
fn the_compensation_and_exposure_hold_figures_in_the_prose_are_the_codes() {
    use m2ctl::controller::params::{index, ParamError, PARAMETERS};
    use m2ctl::controller::CommandError;
    use m2ctl::link::command::{FunctionId, MAX_EXPOSURE_HOLD_S};
    use m2ctl::link::tm::event_id;
    use m2ctl::thermal::compensation::{DEFAULT_MAX_STEP_MM, DEFAULT_MIN_STEP_MM};
    use m2ctl::timing::{COMPENSATION_PHASE_CYCLES, CONTROL_RATE_HZ};
    let nm = |mm: f32| (f64::from(mm) * 1e6).round() as i64;
    let id = |k: usize| format!("0x{:04X}", PARAMETERS[k].id);
    let text = icd().split_whitespace().collect::<Vec<_>>().join(" ");
    let hold_s = m2ground::mdb::thousands(i64::from(MAX_EXPOSURE_HOLD_S));
    for phrase in [
        format!(
            "(parameters {}..{}, section 5a; off by default)",
            id(index::THERMAL_ENABLE),
            id(index::THERMAL_MIN_STEP)
        ),
        format!(
            "once a second ({} ms into it)",
            COMPENSATION_PHASE_CYCLES * 1000 / CONTROL_RATE_HZ
        ),
        format!(
            "by at most the largest step ({}, default {} nm)",
            id(index::THERMAL_MAX_STEP),
            nm(DEFAULT_MAX_STEP_MM)
        ),
        format!(
            "the dead band ({}, default {} nm)",
            id(index::THERMAL_MIN_STEP),
            nm(DEFAULT_MIN_STEP_MM)
        ),
        format!("with event 0x{:04X} once", event_id::THERMAL_FROZEN),
        format!(
            "above the largest step is refused (0x{:04X})",
            ParamError::DeadBandAboveStep.code()
        ),
        format!(
            "**Exposure hold** (function 0x{:04X}, timeout u16 in seconds, 0..{hold_s})",
            FunctionId::ExposureHold.code()
        ),
        format!(
            "refused with 0x{:04X} (data: the hold's seconds left, rounded up)",
            CommandError::ExposureHold(0).code()
        ),
        format!("at most {hold_s} s (then a new rising edge is needed)"),
        format!(
            "Event 0x{:04X} reports the start",
            event_id::EXPOSURE_HOLD_STARTED
        ),
        format!("0x{:04X} the end", event_id::EXPOSURE_HOLD_ENDED),
        format!(
            "by corrections no larger than its error (as many as its {} s allow)",
            m2ctl::motion::fine::TIMEOUT_CYCLES / CONTROL_RATE_HZ
        ),
        format!(
            "compensation step made just before (within its {} s, each slider moving by at most the step and twice the in-position tolerance)",
            m2ctl::motion::fine::TIMEOUT_CYCLES / CONTROL_RATE_HZ
        ),
        // The behaviour: `thermal_compensated_hold::a_clear_or_an_activation_during_a_steps_fine_positioning_holds_without_a_jump`.
        "A clear fault or a table activation (activate, switch bank, revert) during it ends it where the drives stand: they hold there, nothing jumps".to_string(),
        format!(
            "Housekeeping reports the state (offset {}) and the applied offsets (offset {}), section 6.",
            m2ctl::link::hk::field::THERMAL_STATE.start,
            m2ctl::link::hk::field::THERMAL_OFFSETS.start
        ),
    ] {
        assert!(text.contains(&phrase), "docs/icd.md lacks: {phrase}");
    }
}

/// The packet and report sizes the ICD states are the code's.
#[test]
fn the_packet_sizes_in_the_prose_are_the_codes() {
    use m2ctl::link::hk::HK_REPORT_LEN;
    use m2ctl::link::{MAX_TM_FRAME_LEN, MAX_TM_PACKET_LEN};
    let text = icd().split_whitespace().collect::<Vec<_>>().join(" ");
    for phrase in [
        format!("largest TM packet {MAX_TM_PACKET_LEN} bytes"),
        format!("(TM frame <= {MAX_TM_FRAME_LEN} bytes)"),
        format!("## 6. Housekeeping TM[3,25] ({HK_REPORT_LEN} bytes)"),
    ] {
        assert!(text.contains(&phrase), "docs/icd.md lacks: {phrase}");
    }
}
