//! The operators' console Yamcs serves from `yamcs/displays/`, `yamcs/lists/` and
//! `yamcs/stacks/` (docs/ground-segment.md, "The console"):
//! * the files are the ones generated from the mission database
//!   (`m2ground::mdb::console_files`; `M2_WRITE_CONSOLE=1` rewrites them);
//! * every parameter and command a file names is one of the mission database, and every
//!   command step's arguments are ones the controller takes (read back from the files
//!   themselves, by this test's own reader);
//! * every stack runs on the simulated controller (the bench) as Yamcs web runs it:
//!   each command must complete with its three verification stages, each verification
//!   must hold within its timeout, evaluated on the values the description decodes from
//!   the controller's own telemetry and compared as Yamcs web compares them.

#![cfg(feature = "host")]

#[path = "../../host-tests/common/mod.rs"]
mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use common::{all_ok, wire};
use m2ctl::link::framing::Deframer;
use m2ctl::link::Command;
use m2ctl::sim::{Bench, InjectedFault, SwitchEnd as PlantSwitch};
use m2ground::gateway::TM_DEFRAMER_LEN;
use m2ground::mdb::{
    self, console_files, mdb, Mdb, Meaning, ParameterKind, SwitchEnd, TM_SOURCE_DATA_OFFSET,
};
use serde_json::Value;

fn yamcs_dir() -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../yamcs")).to_path_buf()
}

/// Every file under `dir` (relative paths), recursively.
fn files_under(root: &Path, dir: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut todo = vec![root.join(dir)];
    while let Some(d) = todo.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                todo.push(p);
            } else if let Ok(rel) = p.strip_prefix(root) {
                out.insert(rel.to_string_lossy().into_owned());
            }
        }
    }
    out
}

/// The console's shipped files, as they are in the repository.
fn shipped() -> BTreeMap<String, String> {
    let root = yamcs_dir();
    let mut out = BTreeMap::new();
    for dir in [mdb::DISPLAYS_DIR, mdb::STACKS_DIR, "lists"] {
        for f in files_under(&root, dir) {
            let text = std::fs::read_to_string(root.join(&f)).unwrap();
            out.insert(f, text);
        }
    }
    out
}

#[test]
fn the_console_files_are_the_ones_generated() {
    let db = mdb();
    let generated = console_files(&db).expect("the console names only what the description has");
    let root = yamcs_dir();
    if std::env::var_os("M2_WRITE_CONSOLE").is_some() {
        for (f, _) in shipped() {
            if !generated.iter().any(|g| g.path == f) {
                std::fs::remove_file(root.join(&f)).unwrap();
            }
        }
        for g in &generated {
            let p = root.join(&g.path);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(&p, &g.text).unwrap();
        }
    }
    let files = shipped();
    let mut wrong = Vec::new();
    for g in &generated {
        match files.get(&g.path) {
            Some(t) if *t == g.text => {}
            Some(_) => wrong.push(format!("{} differs", g.path)),
            None => wrong.push(format!("{} missing", g.path)),
        }
    }
    for f in files.keys() {
        if !generated.iter().any(|g| &g.path == f) {
            wrong.push(format!(
                "{f} is not generated (a stale file Yamcs would serve)"
            ));
        }
    }
    assert!(
        wrong.is_empty(),
        "yamcs/ console files out of date: {wrong:?}\n\
         regenerate: M2_WRITE_CONSOLE=1 cargo test --features host --test console"
    );
}

// ----------------------------------------------------------------- the files' names

/// The Yamcs parameters and commands of the description, by qualified name.
struct Vocabulary {
    db: Mdb,
    parameters: BTreeMap<String, ParameterKind>,
}

impl Vocabulary {
    fn new() -> Self {
        let db = mdb();
        let parameters = db
            .parameters()
            .into_iter()
            .map(|(k, v)| (format!("/{}/{k}", db.name), v))
            .collect();
        Self { db, parameters }
    }

    fn command(&self, qualified: &str) -> Option<&mdb::Telecommand> {
        let name = qualified.strip_prefix(&format!("/{}/", self.db.name))?;
        self.db.telecommand(name)
    }
}

/// The `<pv_name>`s of an `.opi` file.
fn opi_pvs(text: &str) -> Vec<String> {
    text.split("<pv_name>")
        .skip(1)
        .filter_map(|s| s.split("</pv_name>").next())
        .filter(|s| !s.is_empty())
        .map(String::from)
        .collect()
}

/// What is wrong with a comparison of a verify step (None: Yamcs web can evaluate it as
/// meant).
fn bad_comparison(v: &Vocabulary, c: &Value) -> Option<String> {
    let p = c["parameter"].as_str().unwrap_or_default();
    let op = c["operator"].as_str().unwrap_or_default();
    let value = &c["value"];
    let Some(kind) = v.parameters.get(p) else {
        return Some(format!("{p}: no such parameter"));
    };
    if !["eq", "neq", "lt", "lte", "gt", "gte"].contains(&op) {
        return Some(format!("{p}: operator {op}"));
    }
    let ok = match kind {
        ParameterKind::Enum { enumeration } => {
            let labels: Vec<&str> =
                v.db.enums
                    .iter()
                    .find(|e| e.name == *enumeration)
                    .map(|e| e.values.iter().map(|(_, l, _)| l.as_str()).collect())
                    .unwrap_or_default();
            matches!(op, "eq" | "neq") && value.as_str().is_some_and(|l| labels.contains(&l))
        }
        ParameterKind::Boolean => matches!(op, "eq" | "neq") && value.is_boolean(),
        ParameterKind::Integer => value.is_i64() || value.is_u64(),
        // Yamcs web compares eq/neq as text: "12.5" is not "12.500".
        ParameterKind::Float { .. } => !matches!(op, "eq" | "neq") && value.is_number(),
        ParameterKind::Binary | ParameterKind::Array => false,
    };
    (!ok).then(|| format!("{p} {op} {value}: not comparable with a {kind:?}"))
}

/// The `name=value` word of `m2ground tc` for a stack argument.
fn arg_word(a: &Value) -> String {
    let name = a["name"].as_str().unwrap_or_default();
    match &a["value"] {
        Value::String(s) => format!("{name}={s}"),
        v => format!("{name}={v}"),
    }
}

/// Everything wrong with one console file: a parameter or command the description
/// lacks, a command step with a missing, unknown or refused argument, a verification
/// Yamcs web cannot evaluate as meant.
fn problems(v: &Vocabulary, path: &str, text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let param = |p: &str, out: &mut Vec<String>| {
        if !v.parameters.contains_key(p) {
            out.push(format!(
                "{path}: {p}: no such parameter in the mission database"
            ));
        }
    };
    if path.ends_with(".opi") {
        let pvs = opi_pvs(text);
        if pvs.is_empty() {
            out.push(format!("{path}: no parameter"));
        }
        for p in pvs {
            param(&p, &mut out);
        }
        return out;
    }
    let json: Value = match serde_json::from_str(text) {
        Ok(j) => j,
        Err(e) => return vec![format!("{path}: not JSON: {e}")],
    };
    if path.ends_with(".par") {
        for p in json["parameters"].as_array().into_iter().flatten() {
            param(p.as_str().unwrap_or_default(), &mut out);
        }
    } else if path.ends_with(".json") {
        for list in json.as_array().into_iter().flatten() {
            for p in list["patterns"].as_array().into_iter().flatten() {
                param(p.as_str().unwrap_or_default(), &mut out);
            }
        }
    } else if path.ends_with(".ycs") {
        if json["advancement"]["acknowledgment"] != "CommandComplete" {
            out.push(format!("{path}: advances before a command completes"));
        }
        for (i, step) in json["steps"].as_array().into_iter().flatten().enumerate() {
            match step["type"].as_str().unwrap_or_default() {
                "text" => {}
                "check" => {
                    for p in step["parameters"].as_array().into_iter().flatten() {
                        param(p["parameter"].as_str().unwrap_or_default(), &mut out);
                    }
                }
                "verify" => {
                    for c in step["condition"].as_array().into_iter().flatten() {
                        if let Some(e) = bad_comparison(v, c) {
                            out.push(format!("{path} step {i}: {e}"));
                        }
                    }
                    if step["timeout"].as_u64().unwrap_or(0) == 0 {
                        out.push(format!("{path} step {i}: a verification without timeout"));
                    }
                }
                "command" => {
                    let name = step["name"].as_str().unwrap_or_default();
                    let Some(tc) = v.command(name) else {
                        out.push(format!("{path} step {i}: {name}: no such telecommand"));
                        continue;
                    };
                    let args: Vec<&Value> =
                        step["arguments"].as_array().into_iter().flatten().collect();
                    // Yamcs has no default for them: every argument given.
                    for f in tc.arguments() {
                        if !args.iter().any(|a| a["name"] == f.name.as_str()) {
                            out.push(format!(
                                "{path} step {i}: {name}: argument {} missing",
                                f.name
                            ));
                        }
                    }
                    let words: Vec<String> = args.iter().map(|a| arg_word(a)).collect();
                    if let Err(e) = m2ground::tc::command_from_args(&tc.name, &words) {
                        out.push(format!("{path} step {i}: {name} refused: {e}"));
                    }
                }
                other => out.push(format!("{path} step {i}: step type {other:?}")),
            }
        }
    } else {
        out.push(format!("{path}: not a console file"));
    }
    out
}

#[test]
fn every_name_in_the_console_files_is_in_the_mission_database() {
    let v = Vocabulary::new();
    let files = shipped();
    assert!(files.keys().any(|f| f.ends_with(".opi")) && files.keys().any(|f| f.ends_with(".ycs")));
    let all: Vec<String> = files.iter().flat_map(|(p, t)| problems(&v, p, t)).collect();
    assert!(all.is_empty(), "{all:#?}");
}

/// The checker above fails on what it is there to find (else it proves nothing).
#[test]
fn a_wrong_name_or_a_refused_argument_in_a_console_file_is_found() {
    let v = Vocabulary::new();
    let files = shipped();
    let opi = files.get("displays/housekeeping.opi").expect("the display");
    let table = files
        .get("stacks/table-upload.ycs")
        .expect("the upload stack");
    let leg = files
        .get("stacks/recovery/leg1-upper-switch.ycs")
        .expect("a recovery stack");
    let cases: [(&str, String, &str); 7] = [
        (
            "displays/housekeeping.opi",
            opi.replacen("/M2/encoder_leg1<", "/M2/encoder_leg7<", 1),
            "encoder_leg7: no such parameter",
        ),
        (
            "stacks/table-upload.ycs",
            table.replacen("/M2/COMMIT_TABLE", "/M2/COMMIT", 1),
            "/M2/COMMIT: no such telecommand",
        ),
        (
            "stacks/table-upload.ycs",
            table.replacen("\"/M2/pending_table_id\"", "\"/M2/pending_table\"", 1),
            "pending_table: no such parameter",
        ),
        (
            "stacks/recovery/leg1-upper-switch.ycs",
            leg.replacen("\"value\": -100.0", "\"value\": -5000.0", 1),
            "DIRECT_STROKE refused",
        ),
        (
            "stacks/recovery/leg1-upper-switch.ycs",
            leg.replacen("\"name\": \"leg\"", "\"name\": \"legs\"", 1),
            "argument leg missing",
        ),
        (
            "stacks/recovery/leg1-upper-switch.ycs",
            leg.replacen("\"FAULTED\"", "\"BROKEN\"", 1),
            "not comparable",
        ),
        (
            "stacks/table-upload.ycs",
            table.replacen("\"lte\"", "\"eq\"", 1).replacen(
                "\"/M2/active_table_id\",\n          \"operator\": \"eq\"",
                "\"/M2/pose_fk_op_x\",\n          \"operator\": \"eq\"",
                1,
            ),
            "pose_fk_op_x eq",
        ),
    ];
    for (path, text, want) in cases {
        let orig = files.get(path).unwrap();
        assert_ne!(&text, orig, "the mutation for {want:?} changed nothing");
        let found = problems(&v, path, &text);
        assert!(
            found.iter().any(|p| p.contains(want)),
            "{want:?} not found in {found:?}"
        );
    }
}

#[test]
fn the_housekeeping_display_shows_every_leg_axis_and_flag() {
    let db = mdb();
    let files = shipped();
    let pvs: BTreeSet<String> = opi_pvs(files.get("displays/housekeeping.opi").unwrap())
        .into_iter()
        .collect();
    let q = |n: String| format!("/{}/{n}", db.name);
    let mut want = Vec::new();
    for leg in 1..=m2ctl::kinematics::LEGS {
        for f in ["stroke_cmd_leg", "encoder_leg"] {
            want.push(q(format!("{f}{leg}")));
        }
        for f in [
            "in_position_legs",
            "limit_lower_legs",
            "limit_upper_legs",
            "fault_legs",
        ] {
            want.push(q(format!("{f}_leg{leg}")));
        }
    }
    for axis in mdb::POSE_AXES {
        for f in ["pose_fk_op_", "pose_cmd_op_", "pose_fk_", "pose_cmd_"] {
            want.push(q(format!("{f}{axis}")));
        }
    }
    let flags = db
        .bit_fields
        .iter()
        .find(|b| b.name == "fault_flags")
        .unwrap();
    for (_, bit, _) in &flags.bits {
        for word in ["fault_flags", "warning_flags"] {
            want.push(q(mdb::bit_parameter_name(word, bit)));
        }
    }
    for f in [
        "state",
        "last_failure_code",
        "active_table_id",
        "active_table_crc32",
        "active_bank",
    ] {
        want.push(q(f.into()));
    }
    let missing: Vec<&String> = want.iter().filter(|p| !pvs.contains(*p)).collect();
    assert!(missing.is_empty(), "the display lacks {missing:?}");
    // Every value is written in its alarm colour and framed when in alarm, and a
    // calibrated number with the description's decimals.
    let kinds = db.parameters();
    let opi = files.get("displays/housekeeping.opi").unwrap();
    let updates: Vec<&str> = opi
        .split("<widget typeId=")
        .filter(|w| w.contains("<widget_type>Text Update</widget_type>"))
        .collect();
    assert!(updates.len() > 50, "{} values", updates.len());
    for w in &updates {
        let tag = |t: &str| {
            w.split(&format!("<{t}>"))
                .nth(1)
                .and_then(|r| r.split(&format!("</{t}>")).next())
                .unwrap_or_default()
                .to_string()
        };
        let pv = tag("pv_name");
        assert_eq!(tag("forecolor_alarm_sensitive"), "true", "{pv}");
        assert_eq!(tag("border_alarm_sensitive"), "true", "{pv}");
        let name = db.unqualified(&pv).unwrap();
        if let Some(ParameterKind::Float {
            fraction_digits: Some(d),
            ..
        }) = kinds.get(name)
        {
            assert_eq!(
                (tag("format_type"), tag("precision"), tag("show_units")),
                ("1".into(), d.to_string(), "true".into()),
                "{pv}: decimal format with {d} decimals and the unit"
            );
        }
    }
    // The parameter table shows the same parameters, and the first list holds them all.
    let par: Value = serde_json::from_str(files.get("displays/housekeeping.par").unwrap()).unwrap();
    let par: BTreeSet<String> = par["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p.as_str().unwrap().to_string())
        .collect();
    assert_eq!(par, pvs);
    let lists: Value = serde_json::from_str(files.get(mdb::LISTS_FILE).unwrap()).unwrap();
    let first: BTreeSet<String> = lists[0]["patterns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p.as_str().unwrap().to_string())
        .collect();
    assert_eq!(first, pvs);
    let names: BTreeSet<&str> = lists
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names.len(),
        lists.as_array().unwrap().len(),
        "list names are unique"
    );
}

// ------------------------------------------------------- stacks on the simulated bench

/// A parameter's latest value as Yamcs web holds it.
#[derive(Clone, Debug, PartialEq)]
enum Eng {
    Float(f64),
    Int(i64),
    Label(String),
    Bool(bool),
}

impl Eng {
    /// As Yamcs web renders it (`renderValue`): the text its `eq` compares.
    fn text(&self) -> String {
        match self {
            Eng::Float(x) => format!("{x}"),
            Eng::Int(n) => n.to_string(),
            Eng::Label(l) => l.clone(),
            Eng::Bool(b) => b.to_string(),
        }
    }

    fn number(&self) -> Option<f64> {
        match self {
            Eng::Float(x) => Some(*x),
            Eng::Int(n) => Some(*n as f64),
            Eng::Label(_) | Eng::Bool(_) => None,
        }
    }
}

/// The latest value of every parameter, decoded from the bench's downlink by the
/// description (what Yamcs does with the XTCE generated from it).
struct Ground {
    db: Mdb,
    deframer: Deframer<TM_DEFRAMER_LEN>,
    read: usize,
    latest: BTreeMap<String, Eng>,
}

impl Ground {
    fn new() -> Self {
        Self {
            db: mdb(),
            deframer: Deframer::new(),
            read: 0,
            latest: BTreeMap::new(),
        }
    }

    fn update(&mut self, r: &Bench) {
        let bytes = r.downlink_tapped()[self.read..].to_vec();
        self.read += bytes.len();
        let mut packets = Vec::new();
        for b in bytes {
            if let Some(Ok(p)) = self.deframer.push_byte(b) {
                packets.push(p.to_vec());
            }
        }
        for p in packets {
            self.decode(&p);
        }
    }

    fn decode(&mut self, p: &[u8]) {
        let (Some(&service), Some(&subtype)) = (p.get(7), p.get(8)) else {
            return;
        };
        let Some(layout) = self
            .db
            .telemetry
            .iter()
            .find(|t| t.service == service && t.subtypes.contains(&subtype))
        else {
            return;
        };
        let data = &p[TM_SOURCE_DATA_OFFSET.min(p.len())..];
        for f in &layout.fields {
            let Some(raw) = f.read_raw(data) else {
                continue;
            };
            let value = match f.meaning {
                Meaning::Number { scale, .. } if scale != 1.0 => Eng::Float(f.to_eng(raw)),
                Meaning::Number { .. } | Meaning::Fixed { .. } => Eng::Int(raw),
                Meaning::Bits { bit_field } => {
                    let bits = &self
                        .db
                        .bit_fields
                        .iter()
                        .find(|b| b.name == bit_field)
                        .unwrap()
                        .bits;
                    for (bit, name, _) in bits {
                        self.latest.insert(
                            mdb::bit_parameter_name(&f.name, name),
                            Eng::Bool(raw >> bit & 1 == 1),
                        );
                    }
                    Eng::Int(raw)
                }
                Meaning::Enum { enumeration } => {
                    let e = self
                        .db
                        .enums
                        .iter()
                        .find(|e| e.name == enumeration)
                        .unwrap();
                    match e.values.iter().find(|(v, _, _)| *v == raw) {
                        Some((_, label, _)) => Eng::Label(label.clone()),
                        None => Eng::Int(raw),
                    }
                }
                Meaning::Boolean => Eng::Bool(raw != 0),
                Meaning::Binary => continue,
            };
            self.latest.insert(f.name.clone(), value);
        }
    }

    fn value(&self, qualified: &str) -> Option<&Eng> {
        self.latest.get(self.db.unqualified(qualified)?)
    }

    /// Does a comparison hold, as Yamcs web evaluates it?
    fn holds(&self, c: &Value) -> bool {
        let Some(v) = self.value(c["parameter"].as_str().unwrap_or_default()) else {
            return false;
        };
        let want = match &c["value"] {
            Value::String(s) => s.clone(),
            other => other.to_string(),
        };
        let num = |f: fn(f64, f64) -> bool| {
            v.number()
                .zip(want.parse::<f64>().ok())
                .is_some_and(|(a, b)| f(a, b))
        };
        match c["operator"].as_str().unwrap_or_default() {
            "eq" => !matches!(v, Eng::Float(_)) && v.text() == want,
            "neq" => !matches!(v, Eng::Float(_)) && v.text() != want,
            "lt" => num(|a, b| a < b),
            "lte" => num(|a, b| a <= b),
            "gt" => num(|a, b| a > b),
            "gte" => num(|a, b| a >= b),
            _ => false,
        }
    }
}

/// Cycles of the bench per millisecond of a stack's timeout (a 1 ms control cycle).
const CYCLES_PER_MS: f64 = 1.0 / (m2ctl::timing::CYCLE_S_F64 * 1e3);

/// Runs a `.ycs` stack on the bench as Yamcs web runs it; returns the commands sent.
fn run_stack(r: &mut Bench, g: &mut Ground, path: &str, text: &str) -> usize {
    let json: Value = serde_json::from_str(text).unwrap();
    let mut sent = 0;
    for (i, step) in json["steps"].as_array().unwrap().iter().enumerate() {
        g.update(r);
        match step["type"].as_str().unwrap() {
            "text" => {}
            "check" => {
                for p in step["parameters"].as_array().unwrap() {
                    let p = p["parameter"].as_str().unwrap();
                    assert!(
                        g.value(p).is_some(),
                        "{path} step {i}: {p} has no value to list"
                    );
                }
            }
            "command" => {
                let name = step["name"].as_str().unwrap();
                let words: Vec<String> = step["arguments"]
                    .as_array()
                    .map(|a| a.iter().map(arg_word).collect())
                    .unwrap_or_default();
                let tc = g.db.unqualified(name).unwrap().to_string();
                let cmd = m2ground::tc::command_from_args(&tc, &words).unwrap();
                let window = g.db.telecommand(&tc).unwrap().completion_timeout_s;
                let reps = r.command(&cmd, (window / m2ctl::timing::CYCLE_S_F64) as u32);
                assert!(all_ok(&reps), "{path} step {i}: {name} {words:?}: {reps:?}");
                sent += 1;
            }
            "verify" => {
                let timeout = (step["timeout"].as_f64().unwrap() * CYCLES_PER_MS) as u32;
                let cond = step["condition"].as_array().unwrap();
                let mut waited = 0;
                loop {
                    g.update(r);
                    if cond.iter().all(|c| g.holds(c)) {
                        break;
                    }
                    assert!(
                        waited < timeout,
                        "{path} step {i} ({}): not within {timeout} cycles: {:?}",
                        step["comment"],
                        cond.iter()
                            .filter(|c| !g.holds(c))
                            .map(|c| (c.to_string(), g.value(c["parameter"].as_str().unwrap())))
                            .collect::<Vec<_>>()
                    );
                    r.tick();
                    waited += 1;
                }
            }
            other => panic!("{path} step {i}: step type {other}"),
        }
    }
    sent
}

/// A fresh bench whose downlink the ground decodes, with one housekeeping report in.
fn bench() -> (Bench, Ground) {
    let mut r = Bench::new();
    r.tap_downlink();
    let mut g = Ground::new();
    r.run(2_000);
    g.update(&r);
    (r, g)
}

#[test]
fn the_table_upload_stack_installs_its_table_on_the_simulated_controller() {
    let files = shipped();
    let (mut r, mut g) = bench();
    let table = mdb::upload_stack_table().unwrap();
    let before = r.hk();
    assert_ne!(before.active_table_id, table.table_id);
    let sent = run_stack(
        &mut r,
        &mut g,
        "table-upload",
        &files["stacks/table-upload.ycs"],
    );
    let hk = r.hk();
    assert_eq!(sent, 7, "5 chunks, commit, activate");
    assert_eq!(
        (hk.active_table_id, hk.active_table_crc32),
        (table.table_id, table.crc32())
    );
    // The stack's chunks are the table's bytes (read back from the running table).
    assert_eq!(r.ctl.active_table().to_bytes(), table.to_bytes());
}

#[test]
fn the_recovery_stacks_recover_a_leg_stopped_at_its_switch() {
    let files = shipped();
    for leg in 1..=m2ctl::kinematics::LEGS {
        for end in SwitchEnd::ALL {
            let (mut r, mut g) = bench();
            // A switch misadjusted inside the stroke range, reached by a move along z
            // (every slider moves by the same stroke).
            let (plant_end, at_mm, z_um) = match end {
                SwitchEnd::Lower => (PlantSwitch::Lower, -0.4, -1000.0),
                SwitchEnd::Upper => (PlantSwitch::Upper, 0.4, 1000.0),
            };
            r.plant.with(|p| {
                p.inject(InjectedFault::SwitchMisadjusted {
                    leg: (leg - 1) as u8,
                    end: plant_end,
                    at_mm,
                })
            });
            let reps = r.command(
                &Command::MoveAbsolute(wire(0.0, 0.0, z_um, 0.0, 0.0, 0.0)),
                20_000,
            );
            assert!(
                !all_ok(&reps),
                "leg {leg} {end:?}: the move ended at the switch"
            );
            r.settle(5_000);
            r.run(1_000);
            let path = format!("stacks/recovery/leg{leg}-{}-switch.ycs", end.word());
            let sent = run_stack(&mut r, &mut g, &path, &files[&path]);
            assert_eq!(sent, 2, "{path}: direct stroke and clear");
            let hk = r.hk();
            assert_eq!(hk.state, 0, "{path}: idle");
            // Moves work again (away from the switch).
            let back = r.command(
                &Command::MoveAbsolute(wire(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
                20_000,
            );
            assert!(all_ok(&back), "{path}: a move after the recovery: {back:?}");
        }
    }
}

#[test]
fn the_clear_fault_stack_clears_a_fault_whose_cause_is_gone() {
    let files = shipped();
    let (mut r, mut g) = bench();
    r.plant.with(|p| {
        p.inject(InjectedFault::EncoderJump {
            leg: 2,
            jump_mm: 0.3,
        })
    });
    r.settle(5_000);
    r.plant.with(|p| p.clear_faults());
    r.run(1_000);
    let path = "stacks/recovery/clear-fault.ycs";
    assert_eq!(run_stack(&mut r, &mut g, path, &files[path]), 1);
    // Without a fault the stack stops at its first verification: nothing is sent.
    let json: Value = serde_json::from_str(&files[path]).unwrap();
    let first_verify = json["steps"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["type"] == "verify")
        .unwrap();
    g.update(&r);
    r.run(2_000);
    g.update(&r);
    assert!(!first_verify["condition"]
        .as_array()
        .unwrap()
        .iter()
        .all(|c| g.holds(c)));
}

#[test]
fn the_calibration_stack_reaches_every_pose_of_the_plan() {
    let files = shipped();
    let (mut r, mut g) = bench();
    let path = "stacks/calibration-poses.ycs";
    let sent = run_stack(&mut r, &mut g, path, &files[path]);
    let plan = m2calib::plan::plan_poses(&m2calib::plan::PlanConfig::default());
    assert_eq!(sent, plan.len() + 1, "every pose of the plan, then home");
}
