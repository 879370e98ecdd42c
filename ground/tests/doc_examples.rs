//! Every command example of the documentation runs (issue 19, item 6): each `m2ground`
//! command of a ```` ```sh ```` block of README.md and docs/*.md is run through the built
//! binary (`CARGO_BIN_EXE_m2ground`, the test profile's build: a `cargo run --release
//! ... --bin m2ground -- ARGS` line runs as `m2ground ARGS`) and must succeed; where the
//! example says what it prints or does, that is checked too ([`checks`]).
//!
//! How a block is read (the rules, in order):
//! * a `#` at the start of a line or after a blank starts a comment (to the end of the
//!   line), as in the shell; a line ending in `\` continues on the
//!   next, and so does an indented line after a command (a synopsis spread over lines);
//! * `NAME="..."` sets a variable for the rest of the block; `$NAME` is its value;
//!   `$(m2ground ...)` is that command's output, trimmed, as the shell makes it;
//! * a command is `m2ground ARGS` or `cargo run ... --bin m2ground -- ARGS`; a block line
//!   that names m2ground in another form fails the test (it would be missed);
//! * documented alternatives: `[ ... ]` is an optional part (it may nest); `a|b` within
//!   a word, and `x | y` between words (inside `[...]`: between the group's word
//!   sequences; outside: between single words) are alternatives. One documented line runs
//!   as several commands, not as the cross product: every optional part left out and the
//!   first of every alternative (minimal); then every other alternative once, with every
//!   optional part given; last every optional part given with the first alternatives
//!   (full, last so that the files later lines read are its). Every word of the example
//!   is so run at least once;
//! * placeholders (`N`, `unix:PATH`, ...) are replaced by the values of [`PLACEHOLDERS`],
//!   each with why; the examples of one document run in document order in one scratch
//!   directory holding a copy of `testdata/`, so a file an example writes is the input of
//!   a later one (plan.csv, meas.csv, c1/...); an input no example writes is a fixture
//!   the test provides ([`FIXTURES`]).
//!
//! Nothing is skipped silently: the examples that take minutes (the calibration studies)
//! run in the `#[ignore]`d test `the_long_examples_run` ([`LONG`], with their time:
//! `cargo test --features host --test doc_examples -- --ignored`), the ones refused by
//! design are [`EXPECTED_REFUSALS`] (their refusal is asserted), the ones not run at all
//! are [`NOT_RUN`] with the reason; the test fails if a list names an example the
//! documents do not hold (or no longer produce), or a check is never used.

#![cfg(feature = "host")]

use std::collections::{BTreeMap, BTreeSet};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command as Process, Output, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use m2ctl::link::command::{ParameterIds, ParameterValues};
use m2ctl::link::schedule::{ObtOffset, RequestIdList, ScheduleCommand};
use m2ctl::link::time::TimeReportRate;
use m2ctl::link::{decode_telecommand, Command, Deframer, MemoryId, TmTime, WirePose};
use m2ctl::table::{Table, TABLE_LEN};
use m2ground::tc::{parse_hex_lines, request_id_of};

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
/// The documents whose examples the lists below name most.
const OPERATIONS: &str = "docs/operations.md";
const CALIBRATION: &str = "docs/calibration.md";
const EXE: &str = env!("CARGO_BIN_EXE_m2ground");

/// How long one example may take (the quick ones; [`LONG`] have their own).
const QUICK_TIMEOUT: Duration = Duration::from_secs(300);
/// How long a long one may take.
const LONG_TIMEOUT: Duration = Duration::from_secs(3600);

/// Examples that take minutes, run only by the `#[ignore]`d test: (document, m2ground
/// subcommand, wall time measured here: the test profile's build on a 2-core machine
/// shared with other work, load 5..9; the documents' figures are release builds). The
/// whole ignored test took 10.7 min.
const LONG: &[(&str, &str, &str)] = &[
    (CALIBRATION, "table3", "19 s (docs: ~20 s)"),
    (CALIBRATION, "compare-cuckoo", "130 s (docs: ~85 s)"),
    (CALIBRATION, "bench", "42 s"),
    (CALIBRATION, "tracker-table", "197 s (docs: ~2 min)"),
    (CALIBRATION, "tracker-stats", "34 s (docs: ~30 s)"),
    (
        CALIBRATION,
        "tracker-plan",
        "73 s, run twice: with and without --criterion d-optimal (docs: ~30 s)",
    ),
    (
        CALIBRATION,
        "tracker-defaults",
        "not yet timed by this test (docs: 20-40 min, release; LONG_TIMEOUT allows an hour)",
    ),
];

/// Commands (as expanded, before placeholders) refused by design: (document, command,
/// what stderr says, why).
const EXPECTED_REFUSALS: &[(&str, &str, &str, &str)] = &[
    (
        CALIBRATION,
        "calibrate --data meas.csv --nominal testdata/geometry.toml --out calibrated.toml \
         --solver lm-unbounded --seed N --report --truth truth.toml --plot errors.svg",
        "the flight validation refuses this table",
        "the unbounded LM fit of this simulated campaign moves a joint more than 1 mm from \
         nominal (0x0412): calibrate writes no table the controller would refuse",
    ),
    (
        CALIBRATION,
        "calibrate --data meas.csv --nominal testdata/geometry.toml --out calibrated.toml \
         --solver smcs --seed N --report --truth truth.toml --plot errors.svg",
        "the flight validation refuses this table",
        "SMCS (the paper's cuckoo search, docs/calibration.md Table 3) ends more than 1 mm from nominal \
         on this campaign (0x0412): no table is written",
    ),
    (
        CALIBRATION,
        "calibrate --points c1/points.csv --strokes c1/strokes.csv --targets c1/targets.toml \
         --nominal testdata/geometry.toml --out calibrated.toml --tracker class15+6 \
         --no-prior --fixed-noise --alpha 0.01 --outliers remove --points-format auto \
         --units mm --residual-plot residuals.svg --report --truth c1/truth.toml \
         --plot errors.svg",
        "the flight validation refuses this table",
        "the bundle fit without its prior moves a joint more than 1 mm from nominal on this \
         campaign (0x0412): no table is written",
    ),
];

/// Commands (as expanded, before placeholders) not run at all: (document, command, why).
const NOT_RUN: &[(&str, &str, &str)] = &[(
    "docs/ground-segment.md",
    "gateway --uart unix:PATH",
    "without --listen the gateway binds the documented 127.0.0.1:10015, where a ground \
     segment running on this shared machine (scripts/ground-segment.sh, yamcs-e2e.sh) \
     listens and its Yamcs connects: the test would take or break their link. Every \
     other form of the example runs, --listen on a port of the test's",
)];

/// Placeholders: (document, the word before it, placeholder, what replaces it and why).
const PLACEHOLDERS: &[(&str, &str, &str, &str)] = &[
    (
        CALIBRATION,
        "--seed",
        "N",
        "1: any seed; 1 is the tools' default",
    ),
    (
        OPERATIONS,
        "--seed",
        "N",
        "1: any seed; 1 is the tools' default",
    ),
    (
        OPERATIONS,
        "--targets",
        "N",
        "4: any number of targets; 4 keeps the mission short",
    ),
    (
        "docs/ground-segment.md",
        "--uart",
        "unix:PATH",
        "a Unix socket of the test's, where a stand-in controller sends one TM frame (section \
         8 of the ICD) and closes",
    ),
    (
        "docs/ground-segment.md",
        "--uart",
        "tcp:HOST:PORT",
        "tcp:127.0.0.1:PORT, a listener of the test's with the same stand-in controller",
    ),
    (
        "docs/ground-segment.md",
        "--uart",
        "/dev/ttyX",
        "a file holding that TM frame: opened read-write as the gateway opens a serial \
         device, read to its end (no serial port here)",
    ),
    (
        "docs/ground-segment.md",
        "--listen",
        "127.0.0.1:10015",
        "127.0.0.1 on a free port: the documented one may be a running ground segment's",
    ),
    (
        "docs/ground-segment.md",
        "--tco-url",
        "http://127.0.0.1:8090/api/tco/m2/tco0/coefficients",
        "the same path on an HTTP stand-in of the test's: a Yamcs on this machine must not \
         be sent time correlations",
    ),
    (
        "docs/ground-segment.md",
        "--events-url",
        "http://127.0.0.1:8090/api/archive/m2/events",
        "the same path on an HTTP stand-in of the test's: a Yamcs on this machine must not \
         be sent events",
    ),
];

/// Inputs the test provides (no example writes them): (document, file, how, why).
const FIXTURES: &[(&str, &str, &str)] = &[(
    "docs/icd.md",
    "calibrated.toml",
    "a calibrated geometry with [limits]: `m2ground simulate-campaign` then `m2ground \
     calibrate` against testdata/geometry.toml with the [limits] of docs/operations.md (stroke +-5 mm, \
     workspace 2 mm, 600\"); the ICD's upload examples name such a file",
)];

/// The example `[limits]` of docs/operations.md (section "Geometry file").
const LIMITS: &str = "\n[limits]\nstroke_min_mm = -5.0\nstroke_max_mm = 5.0\n\
                      translation_mm = 2.0\nrotation_arcsec = 600.0\n";

// ---------------------------------------------------------------------------------
// Reading the documents.

/// One documented command: where, and its m2ground arguments as written (with the
/// `[ ]` and `|` notation).
#[derive(Clone, Debug)]
struct Example {
    line: usize,
    via_cargo: bool,
    words: Vec<String>,
}

/// README.md and docs/*.md, repository-relative.
fn documents() -> Vec<String> {
    let mut docs: Vec<String> = std::fs::read_dir(Path::new(ROOT).join("docs"))
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    docs.sort();
    let mut v = vec!["README.md".to_string()];
    v.extend(docs);
    v
}

fn read(doc: &str) -> String {
    std::fs::read_to_string(Path::new(ROOT).join(doc)).unwrap()
}

/// The lines of each ```sh block: (line number, text).
fn sh_blocks(text: &str) -> Vec<Vec<(usize, String)>> {
    let mut blocks = Vec::new();
    // None: outside a block; Some(None): in another language's; Some(Some(lines)): sh.
    let mut current: Option<Option<Vec<(usize, String)>>> = None;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            current = match current.take() {
                Some(Some(b)) => {
                    blocks.push(b);
                    None
                }
                Some(None) => None,
                None if line.trim() == "```sh" => Some(Some(Vec::new())),
                None => Some(None),
            };
            continue;
        }
        if let Some(Some(b)) = current.as_mut() {
            b.push((i + 1, line.to_string()));
        }
    }
    blocks
}

/// The line without its `# comment`.
fn strip_comment(line: &str) -> &str {
    let mut prev_space = true;
    for (i, c) in line.char_indices() {
        if c == '#' && prev_space {
            return &line[..i];
        }
        prev_space = c.is_whitespace();
    }
    line
}

/// Whitespace-separated words, a `$( ... )` kept whole.
fn words(s: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut w = String::new();
    let mut depth = 0usize;
    let mut chars = s.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '$' && chars.peek() == Some(&'(') {
            depth += 1;
            w.push(c);
            w.push(chars.next().unwrap());
            continue;
        }
        if depth > 0 {
            if c == '(' {
                depth += 1;
            } else if c == ')' {
                depth -= 1;
            }
            w.push(c);
            continue;
        }
        if c.is_whitespace() {
            if !w.is_empty() {
                out.push(std::mem::take(&mut w));
            }
        } else {
            w.push(c);
        }
    }
    if !w.is_empty() {
        out.push(w);
    }
    out
}

/// The m2ground arguments of a command's words, and whether it was a `cargo run`.
fn m2ground_args(w: &[String]) -> Option<(bool, Vec<String>)> {
    match w.first().map(String::as_str) {
        Some("m2ground") => Some((false, w[1..].to_vec())),
        Some("cargo") if w.get(1).map(String::as_str) == Some("run") => {
            let bin = w.windows(2).any(|p| p[0] == "--bin" && p[1] == "m2ground");
            let dashes = w.iter().position(|x| x == "--")?;
            bin.then(|| (true, w[dashes + 1..].to_vec()))
        }
        _ => None,
    }
}

/// Every m2ground example of a document, and the block lines that name m2ground in a
/// form not understood (they would be missed).
fn examples(doc: &str) -> (Vec<Example>, Vec<String>) {
    let mut out = Vec::new();
    let mut unread = Vec::new();
    for block in sh_blocks(&read(doc)) {
        let mut commands: Vec<(usize, String)> = Vec::new();
        let mut continues = false;
        for (n, raw) in &block {
            let line = strip_comment(raw).trim_end();
            if line.trim().is_empty() {
                continues = false;
                continue;
            }
            let (body, more) = match line.strip_suffix('\\') {
                Some(b) => (b.trim(), true),
                None => (line.trim(), false),
            };
            let indented = raw.starts_with(char::is_whitespace);
            match commands.last_mut() {
                Some((_, c)) if continues || indented => {
                    c.push(' ');
                    c.push_str(body);
                }
                _ => commands.push((*n, body.to_string())),
            }
            continues = more;
        }
        let mut vars: Vec<(String, String)> = Vec::new();
        for (n, c) in commands {
            if let Some((k, v)) = c.split_once("=\"") {
                if k.chars().all(|ch| ch.is_ascii_alphanumeric() || ch == '_') && v.ends_with('"') {
                    vars.push((k.to_string(), v.trim_end_matches('"').to_string()));
                    continue;
                }
            }
            let mut expanded = c.clone();
            for (k, v) in &vars {
                expanded = expanded.replace(&format!("${k} "), &format!("{v} "));
            }
            match m2ground_args(&words(&expanded)) {
                Some((via_cargo, words)) => out.push(Example {
                    line: n,
                    via_cargo,
                    words,
                }),
                None if expanded.contains("m2ground") => {
                    unread.push(format!("{doc}:{n}: {c}"));
                }
                None => {}
            }
        }
    }
    (out, unread)
}

// ---------------------------------------------------------------------------------
// Documented alternatives.

#[derive(Clone, Debug)]
enum Node {
    /// A word and its alternatives (`a|b`, `x | y`).
    Word(Vec<String>),
    /// `[ ... ]` (optional) with its alternative word sequences.
    Group(Vec<Vec<Node>>),
}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Open,
    Close,
    Bar,
    Word(String),
}

fn tokens(words: &[String]) -> Vec<Tok> {
    let mut out = Vec::new();
    for w in words {
        if w == "|" {
            out.push(Tok::Bar);
            continue;
        }
        let mut s = w.as_str();
        while let Some(r) = s.strip_prefix('[') {
            out.push(Tok::Open);
            s = r;
        }
        let mut closes = 0;
        while let Some(r) = s.strip_suffix(']') {
            closes += 1;
            s = r;
        }
        if !s.is_empty() {
            out.push(Tok::Word(s.to_string()));
        }
        out.extend(std::iter::repeat_n(Tok::Close, closes));
    }
    out
}

/// The alternatives of a sequence up to its closing `]` (or the end).
fn parse(toks: &[Tok], i: &mut usize, in_group: bool) -> Vec<Vec<Node>> {
    let mut alts = vec![Vec::new()];
    while *i < toks.len() {
        let t = toks[*i].clone();
        *i += 1;
        let Some(seq) = alts.last_mut() else {
            unreachable!()
        };
        match t {
            Tok::Close => {
                assert!(in_group, "unbalanced ] in {toks:?}");
                return alts;
            }
            Tok::Open => {
                let inner = parse(toks, i, true);
                seq.push(Node::Group(inner));
            }
            Tok::Bar if in_group => {
                alts.push(Vec::new());
            }
            Tok::Bar => {
                // Outside brackets: the word before and the word after are alternatives.
                let Some(Tok::Word(next)) = toks.get(*i).cloned() else {
                    panic!("| not between words in {toks:?}");
                };
                *i += 1;
                match seq.last_mut() {
                    Some(Node::Word(a)) => a.push(next),
                    other => panic!("| after {other:?} in {toks:?}"),
                }
            }
            Tok::Word(w) => {
                let alternatives = if w.contains('|') && !w.contains("$(") {
                    w.split('|').map(str::to_string).collect()
                } else {
                    vec![w]
                };
                seq.push(Node::Word(alternatives));
            }
        }
    }
    assert!(!in_group, "unclosed [ in {toks:?}");
    alts
}

/// Number of alternatives of each choice point, in walk order.
fn choice_points(seq: &[Node], out: &mut Vec<usize>) {
    for n in seq {
        match n {
            Node::Word(a) => {
                if a.len() > 1 {
                    out.push(a.len());
                }
            }
            Node::Group(alts) => {
                if alts.len() > 1 {
                    out.push(alts.len());
                }
                for a in alts {
                    choice_points(a, out);
                }
            }
        }
    }
}

/// The alternative a choice point of `n` alternatives takes (the next point's number
/// is `next_point`).
fn choose(n: usize, pick: Option<(usize, usize)>, next_point: &mut usize) -> usize {
    if n < 2 {
        return 0;
    }
    let c = *next_point;
    *next_point += 1;
    match pick {
        Some((pc, k)) if pc == c => k,
        _ => 0,
    }
}

/// The words of one variant: optional parts given if `full`, choice point `c` at
/// alternative `k` for `pick = Some((c, k))`, every other at its first.
fn render(
    seq: &[Node],
    full: bool,
    pick: Option<(usize, usize)>,
    next_point: &mut usize,
    out: &mut Vec<String>,
) {
    for n in seq {
        match n {
            Node::Word(a) => {
                let k = choose(a.len(), pick, next_point);
                out.push(a[k].clone());
            }
            Node::Group(alts) => {
                let k = choose(alts.len(), pick, next_point);
                for (j, a) in alts.iter().enumerate() {
                    let mut words = Vec::new();
                    render(a, full, pick, next_point, &mut words);
                    if j == k && full {
                        out.extend(words);
                    }
                }
            }
        }
    }
}

/// The commands one documented line runs as (module documentation): minimal, every
/// other alternative, full; duplicates removed (the last kept).
fn variants(words: &[String]) -> Vec<Vec<String>> {
    let toks = tokens(words);
    let mut i = 0;
    let mut top = parse(&toks, &mut i, false);
    assert_eq!(top.len(), 1);
    let seq = top.remove(0);
    let mut points = Vec::new();
    choice_points(&seq, &mut points);
    let one = |full: bool, pick: Option<(usize, usize)>| {
        let mut out = Vec::new();
        render(&seq, full, pick, &mut 0, &mut out);
        out
    };
    let mut v = vec![one(false, None)];
    for (c, n) in points.iter().enumerate() {
        for k in 1..*n {
            v.push(one(true, Some((c, k))));
        }
    }
    v.push(one(true, None));
    let mut kept: Vec<Vec<String>> = Vec::new();
    for (i, x) in v.iter().enumerate() {
        if !v[i + 1..].contains(x) {
            kept.push(x.clone());
        }
    }
    kept
}

#[test]
fn the_expansion_rules_do_what_the_module_documentation_says() {
    let w = |s: &str| words(s);
    let join =
        |v: Vec<Vec<String>>| -> Vec<String> { v.into_iter().map(|x| x.join(" ")).collect() };
    assert_eq!(
        join(variants(&w(
            "mission --plot e.svg [--seed N] [--tracker paper|realistic]"
        ))),
        [
            "mission --plot e.svg",
            "mission --plot e.svg --seed N --tracker realistic",
            "mission --plot e.svg --seed N --tracker paper",
        ]
    );
    assert_eq!(
        join(variants(&w(
            "gateway --uart unix:P | tcp:H | /dev/X [--wait-s 30]"
        ))),
        [
            "gateway --uart unix:P",
            "gateway --uart tcp:H --wait-s 30",
            "gateway --uart /dev/X --wait-s 30",
            "gateway --uart unix:P --wait-s 30",
        ]
    );
    assert_eq!(
        join(variants(&w(
            "c --out x [--a 0.1 | --b] [--report [--truth t] [--plot p]]"
        ))),
        [
            "c --out x",
            "c --out x --b --report --truth t --plot p",
            "c --out x --a 0.1 --report --truth t --plot p",
        ]
    );
    assert_eq!(join(variants(&w("tc ping"))), ["tc ping"]);
    assert_eq!(
        words("tc a=$(m2ground tc --unframed x=1) b"),
        ["tc", "a=$(m2ground tc --unframed x=1)", "b"]
    );
    assert_eq!(strip_comment("tc ping   # one frame # x"), "tc ping   ");
}

// ---------------------------------------------------------------------------------
// Running.

/// One command run.
struct Run {
    /// The command as expanded, placeholders not yet replaced (the key of the lists).
    key: String,
    /// The arguments run.
    args: Vec<String>,
    out: Output,
    dir: PathBuf,
}

impl Run {
    fn stdout(&self) -> String {
        String::from_utf8_lossy(&self.out.stdout).into_owned()
    }
    fn stderr(&self) -> String {
        String::from_utf8_lossy(&self.out.stderr).into_owned()
    }
}

/// Runs m2ground with `args` in `dir`, killed after `timeout`.
fn m2ground(args: &[String], dir: &Path, timeout: Duration) -> Output {
    let mut child = Process::new(EXE)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let drain = |r: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut v = Vec::new();
            if let Some(mut r) = r {
                let _ = r.read_to_end(&mut v);
            }
            v
        })
    };
    let out = drain(child.stdout.take().map(|s| Box::new(s) as _));
    let err = drain(child.stderr.take().map(|s| Box::new(s) as _));
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "m2ground {}: still running after {timeout:?}",
                args.join(" ")
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    Output {
        status,
        stdout: out.join().unwrap(),
        stderr: err.join().unwrap(),
    }
}

/// `$(m2ground ...)` in a word replaced by that command's output (trimmed).
fn command_substitution(word: &str, dir: &Path) -> String {
    let Some(start) = word.find("$(") else {
        return word.to_string();
    };
    let inner = &word[start + 2..word.rfind(')').unwrap()];
    let w = words(inner);
    let (_, args) = m2ground_args(&w).unwrap_or_else(|| panic!("$({inner}): not m2ground"));
    let out = m2ground(&args, dir, QUICK_TIMEOUT);
    assert!(
        out.status.success(),
        "$({inner}): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    format!(
        "{}{}{}",
        &word[..start],
        String::from_utf8_lossy(&out.stdout).trim(),
        &word[word.rfind(')').unwrap() + 1..]
    )
}

/// A scratch directory with a copy of testdata/.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("m2-doc-examples-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("testdata")).unwrap();
    for e in std::fs::read_dir(Path::new(ROOT).join("testdata")).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_file() {
            std::fs::copy(e.path(), dir.join("testdata").join(e.file_name())).unwrap();
        }
    }
    dir
}

/// The ICD's section-8 frames: ("TC frame" | "TM frame") -> bytes.
fn icd_example_frame(which: &str) -> Vec<u8> {
    let icd = read("docs/icd.md");
    let line = icd
        .lines()
        .find(|l| l.starts_with(which))
        .unwrap_or_else(|| panic!("docs/icd.md has no line `{which} ...`"));
    line[which.len()..]
        .split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}

/// A free local TCP port.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// An HTTP server that answers every request 200 (the gateway's time-correlation
/// target); its port.
fn http_stand_in() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = l.local_addr().unwrap().port();
    std::thread::spawn(move || {
        for s in l.incoming() {
            let Ok(mut s) = s else { continue };
            let _ = s.set_read_timeout(Some(Duration::from_millis(500)));
            let mut buf = [0u8; 4096];
            let _ = s.read(&mut buf);
            let _ =
                s.write_all(b"HTTP/1.1 200 OK\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
        }
    });
    port
}

/// Replaces the placeholders of `args` (a gateway's controller stand-ins started
/// here); marks the entries of [`PLACEHOLDERS`] used.
fn substitute(
    doc: &str,
    args: &[String],
    dir: &Path,
    used: &Mutex<BTreeSet<usize>>,
) -> Vec<String> {
    let frame = icd_example_frame("TM frame");
    let mut out = Vec::new();
    for (i, w) in args.iter().enumerate() {
        let before = if i > 0 { args[i - 1].as_str() } else { "" };
        let entry = PLACEHOLDERS
            .iter()
            .position(|(d, b, p, _)| *d == doc && *b == before && *p == w.as_str());
        let Some(k) = entry else {
            out.push(w.clone());
            continue;
        };
        used.lock().unwrap().insert(k);
        let value = match (before, w.as_str()) {
            ("--seed", "N") => "1".to_string(),
            ("--targets", "N") => "4".to_string(),
            ("--uart", "unix:PATH") => {
                let p = dir.join("uart.sock");
                let _ = std::fs::remove_file(&p);
                let l = std::os::unix::net::UnixListener::bind(&p).unwrap();
                let f = frame.clone();
                std::thread::spawn(move || {
                    if let Ok((mut s, _)) = l.accept() {
                        let _ = s.write_all(&f);
                        std::thread::sleep(Duration::from_millis(200));
                    }
                });
                format!("unix:{}", p.display())
            }
            ("--uart", "tcp:HOST:PORT") => {
                let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
                let port = l.local_addr().unwrap().port();
                let f = frame.clone();
                std::thread::spawn(move || {
                    if let Ok((mut s, _)) = l.accept() {
                        let _ = s.write_all(&f);
                        std::thread::sleep(Duration::from_millis(200));
                    }
                });
                format!("tcp:127.0.0.1:{port}")
            }
            ("--uart", "/dev/ttyX") => {
                let p = dir.join("ttyX");
                std::fs::write(&p, &frame).unwrap();
                p.display().to_string()
            }
            ("--listen", _) => format!("127.0.0.1:{}", free_port()),
            ("--tco-url" | "--events-url", url) => {
                url.replace("127.0.0.1:8090", &format!("127.0.0.1:{}", http_stand_in()))
            }
            _ => panic!("placeholder {w} after {before}: no value"),
        };
        out.push(value);
    }
    out
}

/// Provides the fixtures of a document in its scratch directory.
fn provide_fixtures(doc: &str, dir: &Path) {
    if doc == "docs/icd.md" {
        let geometry = read("testdata/geometry.toml") + LIMITS;
        std::fs::write(dir.join("nominal-with-limits.toml"), geometry).unwrap();
        for args in [
            "simulate-campaign --out fixture-meas.csv",
            "calibrate --data fixture-meas.csv --nominal nominal-with-limits.toml --out calibrated.toml",
        ] {
            let a: Vec<String> = args.split_whitespace().map(str::to_string).collect();
            let out = m2ground(&a, dir, QUICK_TIMEOUT);
            assert!(
                out.status.success(),
                "fixture: m2ground {args}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        assert!(std::fs::read_to_string(dir.join("calibrated.toml"))
            .unwrap()
            .contains("[limits]"));
    }
}

// ---------------------------------------------------------------------------------
// What the examples say they print or do.

/// The packets of hex-line output (framed unless `unframed`).
fn packets(text: &str, unframed: bool) -> Result<Vec<Vec<u8>>, String> {
    let lines = parse_hex_lines(text)?;
    if unframed {
        return Ok(lines);
    }
    let mut out = Vec::new();
    for l in lines {
        out.extend(deframe(&l)?);
    }
    Ok(out)
}

/// The packets of back-to-back frames.
fn deframe(bytes: &[u8]) -> Result<Vec<Vec<u8>>, String> {
    let mut d: Deframer = Deframer::new();
    let mut out = Vec::new();
    for &b in bytes {
        if let Some(r) = d.push_byte(b) {
            out.push(r.map_err(|e| format!("{e:?}"))?.to_vec());
        }
    }
    Ok(out)
}

/// The telecommands a `tc` run printed (or wrote to `--out`), each decoded by the
/// flight decoder.
fn telecommands(r: &Run) -> Result<Vec<m2ctl::link::Telecommand>, String> {
    let unframed = r.args.iter().any(|a| a == "--unframed");
    let pkts = match r.args.iter().position(|a| a == "--out") {
        Some(i) => deframe(&std::fs::read(r.dir.join(&r.args[i + 1])).map_err(|e| e.to_string())?)?,
        None => packets(&r.stdout(), unframed)?,
    };
    if pkts.is_empty() {
        return Err("no telecommand".into());
    }
    pkts.iter()
        .map(|p| decode_telecommand(p).map_err(|e| format!("the controller refuses it: {e:?}")))
        .collect()
}

/// The single telecommand of a run.
fn one(r: &Run) -> Result<m2ctl::link::Telecommand, String> {
    let mut v = telecommands(r)?;
    if v.len() != 1 {
        return Err(format!("{} telecommands, one expected", v.len()));
    }
    Ok(v.remove(0))
}

fn expect(ok: bool, what: impl FnOnce() -> String) -> Result<(), String> {
    if ok {
        Ok(())
    } else {
        Err(what())
    }
}

/// A check of what a run printed or wrote.
type Check = Box<dyn Fn(&Run, &BTreeMap<String, String>) -> Result<(), String>>;

/// The chunks and commit (and what follows) of an upload run, and the table the chunks
/// make (checked: every chunk once, the commit names its CRC).
fn upload_of(r: &Run) -> Result<(Vec<Command>, Table), String> {
    let cmds: Vec<Command> = telecommands(r)?.into_iter().map(|t| t.command).collect();
    let mut bytes = vec![0u8; TABLE_LEN];
    for c in &cmds {
        if let Command::LoadTableChunk(ch) = c {
            bytes[ch.range()].copy_from_slice(ch.bytes());
        }
    }
    let chunks = cmds
        .iter()
        .filter(|c| matches!(c, Command::LoadTableChunk(_)))
        .count();
    expect(chunks == TABLE_LEN.div_ceil(128), || {
        format!("{chunks} chunks")
    })?;
    let table = Table::decode(&bytes).map_err(|e| format!("{e:?}"))?;
    let commit = Command::CommitTable {
        crc32: table.crc32(),
    };
    expect(cmds.get(chunks) == Some(&commit), || {
        format!("no commit after the chunks: {cmds:?}")
    })?;
    Ok((cmds, table))
}

/// A check, boxed.
fn check(f: impl Fn(&Run, &BTreeMap<String, String>) -> Result<(), String> + 'static) -> Check {
    Box::new(f)
}

/// The examples that say what they print or do: (document, command as expanded, check).
/// `earlier` maps the commands run before in the same document to their stdout.
fn checks() -> Vec<(&'static str, &'static str, Check)> {
    let icd = "docs/icd.md";
    let is = |expected: Command| -> Check {
        check(move |r, _| {
            let tc = one(r)?;
            expect(tc.command == expected, || {
                format!("{:?}, expected {expected:?}", tc.command)
            })
        })
    };
    let pose = |v: [i32; 6]| WirePose::from_array(v);
    let sched = Command::Schedule;
    vec![
        (
            icd,
            "tc list",
            check(|r, _| {
                let listed: BTreeSet<String> = r
                    .stdout()
                    .lines()
                    .filter(|l| !l.starts_with(' '))
                    .filter_map(|l| l.split_whitespace().next().map(str::to_string))
                    .collect();
                let described: BTreeSet<String> = m2ground::mdb::mdb()
                    .telecommands
                    .iter()
                    .map(|t| t.name.to_ascii_lowercase().replace('_', "-"))
                    .collect();
                expect(listed == described, || format!("listed {listed:?}"))?;
                expect(r.stdout().contains("value of PIVOT_Z"), || "no parameter ranges".into())
            }),
        ),
        (
            icd,
            "tc ping",
            check(|r, _| {
                let frame = icd_example_frame("TC frame");
                let hex: String = frame.iter().map(|b| format!("{b:02x}")).collect();
                expect(r.stdout() == format!("{hex}\n"), || {
                    format!("{:?}, section 8 has {hex}", r.stdout())
                })
            }),
        ),
        (
            icd,
            "tc --seq 5 move-absolute x=1.5 rx=-2",
            check(|r, _| {
                let tc = one(r)?;
                expect(
                    tc.command == Command::MoveAbsolute(WirePose::from_array([1_500, 0, 0, -2_000_000, 0, 0]))
                        && tc.request_id.seq_count() == 5,
                    || format!("{tc:?}"),
                )
            }),
        ),
        (icd, "tc move-relative z=-0.5", is(Command::MoveRelative(pose([0, 0, -500, 0, 0, 0])))),
        (icd, "tc check-move x=1500", is(Command::CheckMove(pose([1_500_000, 0, 0, 0, 0, 0])))),
        (icd, "tc stop", is(Command::Stop)),
        (icd, "tc clear-fault", is(Command::ClearFault)),
        (icd, "tc switch-bank", is(Command::SwitchBank)),
        (icd, "tc revert-to-nominal", is(Command::RevertToNominal)),
        (icd, "tc housekeeping-one-shot", is(Command::HousekeepingOneShot)),
        (
            icd,
            "tc activate-table table_id=7 crc32=0x1234abcd",
            is(Command::ActivateTable { table_id: 7, crc32: 0x1234_abcd }),
        ),
        (
            icd,
            "tc direct-stroke leg=3 delta=-0.5",
            is(Command::DirectStroke { leg: 3, delta_nm: -500 }),
        ),
        (
            icd,
            "tc set-parameter parameter_id=PIVOT_Z value=250000000",
            is(Command::SetParameters(ParameterValues::new(&[(0x0003, 250_000_000)]).unwrap())),
        ),
        (
            icd,
            "tc report-parameter parameter_id=MOVE_SPEED",
            is(Command::ReportParameters(ParameterIds::new(&[0x0010]).unwrap())),
        ),
        (icd, "tc dump-table memory_id=ACTIVE_TABLE", is(Command::DumpTable(MemoryId::ActiveTable))),
        (
            icd,
            "tc upload calibrated.toml --table-id 7",
            check(move |r, _| {
                let (cmds, table) = upload_of(r)?;
                expect(cmds.len() == 6 && table.table_id == 7, || format!("{cmds:?}"))
            }),
        ),
        (
            icd,
            "tc upload calibrated.toml --table-id 7 --calibration-id 12 --activate",
            check(move |r, _| {
                let (cmds, table) = upload_of(r)?;
                let activate = Command::ActivateTable { table_id: 7, crc32: table.crc32() };
                expect(
                    cmds.len() == 7 && cmds[6] == activate && table.provenance.calibration_id == 12,
                    || format!("{cmds:?}, calibration ID {}", table.provenance.calibration_id),
                )
            }),
        ),
        (
            icd,
            "tc --out tc.bin upload calibrated.toml",
            check(move |r, _| {
                expect(r.out.stdout.is_empty(), || "wrote to stdout".into())?;
                let (cmds, table) = upload_of(r)?;
                expect(cmds.len() == 6 && table.table_id == 1, || format!("{cmds:?}"))
            }),
        ),
        (
            icd,
            "tc --seq 40 schedule at=120.5 move-absolute x=3",
            check(move |r, _| {
                let tc = one(r)?;
                let Command::Schedule(ScheduleCommand::Insert(block)) = tc.command else {
                    return Err(format!("{:?}", tc.command));
                };
                let a: Vec<_> = block.activities().collect();
                let inner = decode_telecommand(a[0].packet).map_err(|e| format!("{e:?}"))?;
                expect(
                    tc.request_id.seq_count() == 41
                        && a.len() == 1
                        && a[0].release == TmTime { seconds: 120, fraction: 0x8000 }
                        && inner.request_id.seq_count() == 40
                        && inner.command == Command::MoveAbsolute(WirePose::from_array([3_000, 0, 0, 0, 0, 0]))
                        && r.stderr().contains("request ID 18b2c028"),
                    || format!("{tc:?} {inner:?} {}", r.stderr()),
                )
            }),
        ),
        (
            icd,
            "tc --seq 41 schedule-insert-activity release_seconds=120 release_fraction=0.5 \
             telecommand=$(m2ground tc --seq 40 --unframed move-absolute x=3)",
            check(|r, earlier| {
                let schedule = &earlier["tc --seq 40 schedule at=120.5 move-absolute x=3"];
                expect(r.stdout() == *schedule, || {
                    format!("{:?} differs from the schedule line's {schedule:?}", r.stdout())
                })
            }),
        ),
        (icd, "tc schedule-enable-release", is(sched(ScheduleCommand::EnableRelease))),
        (icd, "tc schedule-disable-release", is(sched(ScheduleCommand::DisableRelease))),
        (icd, "tc schedule-reset", is(sched(ScheduleCommand::Reset))),
        (icd, "tc schedule-summary-report", is(sched(ScheduleCommand::SummaryReport))),
        (
            icd,
            "tc schedule-delete-activity activity_packet_id=0x18b2 activity_sequence_control=0xc028",
            is(sched(ScheduleCommand::Delete(RequestIdList::new(&[request_id_of(40)]).unwrap()))),
        ),
        (
            icd,
            "tc schedule-time-shift-all shift_seconds=-3 shift_fraction=0.5",
            check(|r, _| {
                let tc = one(r)?;
                let ok = matches!(tc.command,
                    Command::Schedule(ScheduleCommand::TimeShiftAll(o))
                        if o == ObtOffset::from_parts(-3, 0x8000) && o.ticks() == -5 * 0x8000);
                expect(ok, || format!("{:?}, expected -2.5 s", tc.command))
            }),
        ),
        (
            icd,
            "tc set-time-report-rate rate=EVERY_1_S",
            is(Command::SetTimeReportRate(TimeReportRate::Every { exponent: 0 })),
        ),
        (icd, "tc set-time-report-rate rate=OFF", is(Command::SetTimeReportRate(TimeReportRate::Off))),
        (
            OPERATIONS,
            "ik --geometry testdata/geometry.toml --input testdata/ik_golden.csv --output strokes.csv",
            check(|r, _| {
                let csv = std::fs::read_to_string(r.dir.join("strokes.csv")).map_err(|e| e.to_string())?;
                let header = csv.lines().find(|l| !l.starts_with('#')).unwrap_or("");
                expect(
                    header.starts_with("x_mm,y_mm,z_mm,rx_arcsec,ry_arcsec,rz_arcsec,s1_mm")
                        && header.split(',').count() == 12,
                    || format!("header {header}"),
                )
            }),
        ),
        (
            CALIBRATION,
            "plan --out plan.csv",
            check(|r, _| {
                let csv = std::fs::read_to_string(r.dir.join("plan.csv")).map_err(|e| e.to_string())?;
                let rows = csv.lines().filter(|l| !l.starts_with('#') && !l.starts_with("x_mm")).count();
                expect(rows == 120, || format!("{rows} poses, the paper's 120 expected"))
            }),
        ),
        (
            CALIBRATION,
            "simulate-tracker-campaign --out-dir c1",
            check(|r, _| {
                for f in ["targets.toml", "points.csv", "strokes.csv", "truth.toml"] {
                    expect(r.dir.join("c1").join(f).is_file(), || format!("no c1/{f}"))?;
                }
                Ok(())
            }),
        ),
        (
            "docs/ground-segment.md",
            "gateway --uart unix:PATH --listen 127.0.0.1:10015 --tco-url \
             http://127.0.0.1:8090/api/tco/m2/tco0/coefficients --events-url \
             http://127.0.0.1:8090/api/archive/m2/events --wait-s 30 --stats-s 10",
            check(|r, _| {
                expect(r.stderr().contains("controller stream closed"), || r.stderr())
            }),
        ),
    ]
}

/// Checks every run makes: the files it names as outputs were written; a `tc` run's
/// telecommands are ones the controller's decoder accepts.
fn generic_check(r: &Run) -> Result<(), String> {
    for (i, a) in r.args.iter().enumerate() {
        if ["--out", "--output", "--plot", "--truth-out", "--out-dir"].contains(&a.as_str()) {
            let p = r.dir.join(&r.args[i + 1]);
            let written = std::fs::metadata(&p)
                .map(|m| m.is_dir() || m.len() > 0)
                .unwrap_or(false);
            expect(written, || format!("{} not written", p.display()))?;
        }
    }
    if r.args.first().map(String::as_str) == Some("tc") && !r.args.iter().any(|a| a == "list") {
        telecommands(r)?;
    }
    Ok(())
}

/// Everything that was run, refused as listed, or left out.
#[derive(Default)]
struct Tally {
    runs: usize,
    refused: Vec<String>,
    not_run: Vec<String>,
    long: Vec<String>,
    checked: BTreeSet<(String, String)>,
    failures: Vec<String>,
}

/// Runs the examples of `doc`: the quick ones, or (`long`) those of [`LONG`].
fn run_document(doc: &str, long: bool, tally: &mut Tally, used: &Mutex<BTreeSet<usize>>) {
    let (examples, unread) = examples(doc);
    for u in unread {
        tally.failures.push(format!(
            "{u}: names m2ground in a form this test does not read"
        ));
    }
    let checks = checks();
    let dir = scratch(&format!(
        "{}{}",
        doc.replace('/', "-"),
        if long { "-long" } else { "" }
    ));
    provide_fixtures(doc, &dir);
    let mut earlier: BTreeMap<String, String> = BTreeMap::new();
    for ex in &examples {
        let sub = ex.words.first().map(String::as_str).unwrap_or("");
        let long_entry = LONG.iter().find(|(d, s, _)| *d == doc && *s == sub);
        if long_entry.is_some() != long {
            if let Some((_, _, time)) = long_entry {
                tally.long.push(format!(
                    "{doc}:{}: m2ground {} ({time})",
                    ex.line,
                    ex.words.join(" ")
                ));
            }
            continue;
        }
        for v in variants(&ex.words) {
            let key = v.join(" ");
            let where_ = format!(
                "{doc}:{} (`m2ground {key}`{})",
                ex.line,
                if ex.via_cargo {
                    ", a cargo run line"
                } else {
                    ""
                }
            );
            if let Some((_, _, why)) = NOT_RUN
                .iter()
                .find(|(d, k, _)| *d == doc && squash(k) == key)
            {
                tally.not_run.push(format!("{where_}: {why}"));
                continue;
            }
            let args: Vec<String> = substitute(doc, &v, &dir, used)
                .iter()
                .map(|w| command_substitution(w, &dir))
                .collect();
            let t0 = Instant::now();
            let out = m2ground(&args, &dir, if long { LONG_TIMEOUT } else { QUICK_TIMEOUT });
            println!("{where_}: {:.2} s", t0.elapsed().as_secs_f64());
            tally.runs += 1;
            let r = Run {
                key: key.clone(),
                args,
                out,
                dir: dir.clone(),
            };
            let refusal = EXPECTED_REFUSALS
                .iter()
                .find(|(d, k, _, _)| *d == doc && squash(k) == key);
            let result = match refusal {
                Some((_, _, says, why)) => {
                    tally.refused.push(format!("{where_}: {why}"));
                    expect(!r.out.status.success() && r.stderr().contains(says), || {
                        format!(
                            "listed as refused ({says}), but: status {}, stderr {}",
                            r.out.status,
                            r.stderr()
                        )
                    })
                }
                None => expect(r.out.status.success(), || format!("failed: {}", r.stderr()))
                    .and_then(|_| generic_check(&r))
                    .and_then(|_| {
                        match checks
                            .iter()
                            .find(|(d, k, _)| *d == doc && squash(k) == r.key)
                        {
                            Some((d, k, check)) => {
                                tally.checked.insert((d.to_string(), squash(k)));
                                check(&r, &earlier)
                            }
                            None => Ok(()),
                        }
                    }),
            };
            if let Err(e) = result {
                tally.failures.push(format!("{where_}: {e}"));
            }
            earlier.insert(r.key.clone(), r.stdout());
        }
    }
    if tally.failures.is_empty() {
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// A listed command with its line-continuation spaces collapsed.
fn squash(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[test]
fn every_command_example_in_the_documentation_runs() {
    let used = Mutex::new(BTreeSet::new());
    let mut tally = Tally::default();
    let docs = documents();
    for doc in &docs {
        let before = tally.runs;
        run_document(doc, false, &mut tally, &used);
        println!("{doc}: {} commands run", tally.runs - before);
    }
    // Every example accounted for, every list entry still meaningful.
    for (d, k, _, _) in EXPECTED_REFUSALS {
        if !tally
            .refused
            .iter()
            .any(|r| r.starts_with(d) && r.contains(&format!("`m2ground {}`", squash(k))))
        {
            tally.failures.push(format!(
                "EXPECTED_REFUSALS names `{}` ({d}), which no example produces",
                squash(k)
            ));
        }
    }
    for (d, k, _) in NOT_RUN {
        if !tally
            .not_run
            .iter()
            .any(|r| r.starts_with(d) && r.contains(&format!("`m2ground {}`", squash(k))))
        {
            tally.failures.push(format!(
                "NOT_RUN names `{}` ({d}), which no example produces",
                squash(k)
            ));
        }
    }
    for (d, s, _) in LONG {
        if !tally
            .long
            .iter()
            .any(|l| l.starts_with(d) && l.contains(&format!("m2ground {s}")))
        {
            tally
                .failures
                .push(format!("LONG names {s} ({d}), which no example runs"));
        }
    }
    for (d, k, _) in checks() {
        if !tally.checked.contains(&(d.to_string(), squash(k))) {
            tally
                .failures
                .push(format!("the check of `{}` ({d}) was never used", squash(k)));
        }
    }
    let used = used.into_inner().unwrap();
    for (i, (d, b, p, _)) in PLACEHOLDERS.iter().enumerate() {
        if !used.contains(&i) {
            tally
                .failures
                .push(format!("placeholder {b} {p} ({d}) never used"));
        }
    }
    for (d, f, _) in FIXTURES {
        if !read(d).contains(f) {
            tally
                .failures
                .push(format!("fixture {f}: {d} does not name it"));
        }
    }
    for doc in [
        OPERATIONS,
        CALIBRATION,
        "docs/icd.md",
        "docs/ground-segment.md",
    ] {
        assert!(
            !examples(doc).0.is_empty(),
            "{doc}: no m2ground examples found: the extraction is broken"
        );
    }
    println!(
        "\n{} commands run from {} documents ({} checked for what they print or do)",
        tally.runs,
        docs.len(),
        tally.checked.len()
    );
    println!("refused by design (asserted):");
    for r in &tally.refused {
        println!("  {r}");
    }
    println!("not run:");
    for r in &tally.not_run {
        println!("  {r}");
    }
    println!("run only by the ignored test the_long_examples_run:");
    for r in &tally.long {
        println!("  {r}");
    }
    println!("fixtures:");
    for (d, f, how) in FIXTURES {
        println!("  {d}: {f}: {how}");
    }
    println!("placeholders:");
    for (d, b, p, why) in PLACEHOLDERS {
        println!("  {d}: {b} {p} -> {why}");
    }
    assert!(tally.failures.is_empty(), "\n{}", tally.failures.join("\n"));
}

#[test]
#[ignore = "the calibration studies take several minutes: cargo test --features host --test doc_examples -- --ignored"]
fn the_long_examples_run() {
    let used = Mutex::new(BTreeSet::new());
    let mut tally = Tally::default();
    run_document(CALIBRATION, true, &mut tally, &used);
    println!("{} long commands run", tally.runs);
    assert!(tally.runs >= LONG.len(), "{} runs", tally.runs);
    assert!(tally.failures.is_empty(), "\n{}", tally.failures.join("\n"));
}
