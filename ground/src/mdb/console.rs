//! The operators' console Yamcs serves (docs/ground-segment.md, "The console"): the
//! housekeeping display, the parameter lists `scripts/ground-segment.sh` creates at
//! start-up and the command stacks of the routine procedures (table upload, calibration
//! pose sequence, recovery of a faulted leg).
//!
//! Every parameter and command they name is looked up in this description while they
//! are built (a name it lacks is an error, not a file), and every command step's
//! arguments pass the checks the `m2ground tc` encoder makes
//! ([`crate::tc::command_from_args`]: the controller's ranges). [`console_files`]
//! writes them as the files of `yamcs/displays/`, `yamcs/lists/` and `yamcs/stacks/`
//! (Yamcs buckets `displays` and `stacks`); `ground/tests/console.rs` fails when a
//! file there differs from them (`M2_WRITE_CONSOLE=1` rewrites them), when a file
//! names a parameter or command the description lacks, and when a stack run on the
//! simulated controller has a command that does not complete or a verification that
//! does not hold.

use std::collections::BTreeMap;

use serde::Serialize;
use serde_json::{json, Value};

use super::{LinkHealthKind, Mdb, Meaning, POSE_AXES};
use m2ctl::motion::{DEFAULT_MAX_ACCEL_MM_PER_S2, DEFAULT_MAX_SPEED_MM_PER_S};
use m2ctl::table::Table;
use m2ctl::units::UM_PER_MM;

mod opi;

/// What a Yamcs parameter of the description holds: what a display shows it as and what
/// a stack's verification may compare it with.
#[derive(Clone, Debug, PartialEq)]
pub enum ParameterKind {
    /// A calibrated number (engineering value = raw x scale), shown with
    /// `fraction_digits` decimals.
    Float {
        /// Engineering unit.
        unit: Option<&'static str>,
        /// Decimals shown (the description's number format).
        fraction_digits: Option<u32>,
    },
    /// An integer: a count, an identifier, the raw word of a bit field.
    Integer,
    /// One label of the named enumeration.
    Enum {
        /// Enumeration name.
        enumeration: &'static str,
    },
    /// `true` / `false`: a boolean field, or one named bit of a bit-field word.
    Boolean,
    /// Bytes.
    Binary,
    /// The array of a repeated group.
    Array,
}

/// The parameter Yamcs gives one named bit of a bit-field word (`yamcs/tools/gen_xtce.py`
/// names them so; the end-to-end test finds every one the console names in Yamcs):
/// `fault_flags` bit `ENCODER_STUCK` -> `fault_flags_encoder_stuck`.
pub fn bit_parameter_name(field: &str, bit_name: &str) -> String {
    format!("{field}_{}", bit_name.to_ascii_lowercase())
}

impl Mdb {
    /// Every parameter Yamcs has from this description, by name: the fields of every
    /// TM packet, one boolean per named bit of a bit-field word, the array of a repeated
    /// group, the gateway's link-health parameters. (The packet headers' own
    /// parameters, e.g. `obt_seconds`, are Yamcs' business, not the console's.)
    pub fn parameters(&self) -> BTreeMap<String, ParameterKind> {
        let mut out = BTreeMap::new();
        for p in &self.telemetry {
            for f in &p.fields {
                let kind = match f.meaning {
                    Meaning::Number { unit, scale, .. } if scale != 1.0 => ParameterKind::Float {
                        unit,
                        fraction_digits: f.fraction_digits,
                    },
                    Meaning::Number { .. } | Meaning::Fixed { .. } | Meaning::Bits { .. } => {
                        ParameterKind::Integer
                    }
                    Meaning::Enum { enumeration } => ParameterKind::Enum { enumeration },
                    Meaning::Boolean => ParameterKind::Boolean,
                    Meaning::Binary => ParameterKind::Binary,
                };
                out.insert(f.name.clone(), kind);
                if let Meaning::Bits { bit_field } = f.meaning {
                    for (_, bit, _) in self.bit_field(bit_field).map_or(&[][..], |b| &b.bits) {
                        out.insert(bit_parameter_name(&f.name, bit), ParameterKind::Boolean);
                    }
                }
            }
            if let Some(r) = &p.repeated {
                out.insert(r.name.clone(), ParameterKind::Array);
            }
        }
        for l in &self.link_health {
            let kind = match l.kind {
                LinkHealthKind::Counter => ParameterKind::Integer,
                LinkHealthKind::Float => ParameterKind::Float {
                    unit: l.unit,
                    fraction_digits: l.fraction_digits.map(u32::from),
                },
            };
            out.insert(l.name.to_string(), kind);
        }
        out
    }

    /// The bit field of this name.
    pub fn bit_field(&self, name: &str) -> Option<&super::BitField> {
        self.bit_fields.iter().find(|b| b.name == name)
    }

    /// The enumeration of this name.
    pub fn enumeration(&self, name: &str) -> Option<&super::Enumeration> {
        self.enums.iter().find(|e| e.name == name)
    }

    /// A parameter's or command's qualified name in Yamcs (`/M2/state`).
    pub fn qualified(&self, name: &str) -> String {
        format!("/{}/{name}", self.name)
    }

    /// The unqualified name of `qualified` if it is in this description's space system.
    pub fn unqualified<'a>(&self, qualified: &'a str) -> Option<&'a str> {
        qualified
            .strip_prefix('/')?
            .strip_prefix(self.name)?
            .strip_prefix('/')
    }
}

// ------------------------------------------------------------------------ displays

/// One cell of a display row.
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    /// The parameter's value as text (with its unit, numbers with the description's
    /// decimals).
    Value(String),
    /// A lamp: lit while the boolean parameter is true.
    Lamp {
        /// The parameter (boolean).
        parameter: String,
        /// What lit means.
        lit: Lit,
    },
}

/// What a lit lamp means (its colour).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lit {
    /// Good (green): in position.
    Good,
    /// Activity (blue): moving.
    Activity,
    /// Attention (amber): a warning.
    Attention,
    /// Bad (red): a fault, a switch reached.
    Bad,
}

/// One row of a display section: a label and its cells, one per column.
#[derive(Clone, Debug, PartialEq)]
pub struct DisplayRow {
    /// Row label.
    pub label: String,
    /// Cells (`None`: nothing in that column).
    pub cells: Vec<Option<Cell>>,
}

/// A titled group of rows on a display, which is also a parameter list.
#[derive(Clone, Debug, PartialEq)]
pub struct Section {
    /// Title.
    pub title: &'static str,
    /// What it shows (the parameter list's description).
    pub description: &'static str,
    /// Column headings.
    pub columns: Vec<&'static str>,
    /// Rows.
    pub rows: Vec<DisplayRow>,
    /// Column of the display it is placed in (0: left, 1: right).
    pub placement: usize,
}

/// A display: titled sections of parameter values and lamps.
#[derive(Clone, Debug, PartialEq)]
pub struct Display {
    /// File name without extension (in the `displays` bucket).
    pub name: &'static str,
    /// Title.
    pub title: &'static str,
    /// Sections.
    pub sections: Vec<Section>,
}

impl Section {
    /// Every parameter of the section, in row order (each once).
    pub fn parameters(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for row in &self.rows {
            for cell in row.cells.iter().flatten() {
                let p = match cell {
                    Cell::Value(p) | Cell::Lamp { parameter: p, .. } => p,
                };
                if !out.contains(p) {
                    out.push(p.clone());
                }
            }
        }
        out
    }
}

impl Display {
    /// Every parameter of the display, in section and row order (each once).
    pub fn parameters(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for p in self.sections.iter().flat_map(Section::parameters) {
            if !out.contains(&p) {
                out.push(p);
            }
        }
        out
    }
}

/// Looks parameter names up in the description while a display or stack is built.
struct Names<'a> {
    mdb: &'a Mdb,
    known: BTreeMap<String, ParameterKind>,
}

impl<'a> Names<'a> {
    fn new(mdb: &'a Mdb) -> Self {
        Self {
            mdb,
            known: mdb.parameters(),
        }
    }

    /// `name` if the description has it.
    fn get(&self, name: &str) -> Result<String, String> {
        if self.known.contains_key(name) {
            Ok(name.to_string())
        } else {
            Err(format!("{name}: no such parameter in the mission database"))
        }
    }

    /// The boolean parameter of bit `bit` (its name in the bit field) of `field`.
    fn bit(&self, field: &str, bit: &str) -> Result<String, String> {
        self.get(&bit_parameter_name(field, bit))
    }

    fn kind(&self, name: &str) -> Option<&ParameterKind> {
        self.known.get(name)
    }

    /// The named bits of a bit field.
    fn bits(&self, bit_field: &str) -> Result<Vec<String>, String> {
        Ok(self
            .mdb
            .bit_field(bit_field)
            .ok_or_else(|| format!("{bit_field}: no such bit field"))?
            .bits
            .iter()
            .map(|(_, name, _)| name.clone())
            .collect())
    }

    fn value_row(&self, label: &str, name: &str) -> Result<DisplayRow, String> {
        Ok(DisplayRow {
            label: label.into(),
            cells: vec![Some(Cell::Value(self.get(name)?))],
        })
    }
}

/// The leg-mask bit field (bit i = leg i+1) and its bit names (`LEG1`...).
const LEG_MASK: &str = "leg_mask";
/// The fault-flag bit field, shared by the latched-fault and the warning words.
const FAULT_FLAGS: &str = "fault_flags";

/// The housekeeping display: the controller's state, the pose (operator's frames and
/// base frame, from FK and commanded), every leg's commanded stroke, encoder, in-position,
/// motion, switch and fault lamps, every fault and warning flag, the tables, the health
/// counters and the link's health.
pub fn housekeeping_display(mdb: &Mdb) -> Result<Display, String> {
    let n = Names::new(mdb);
    let legs = n.bits(LEG_MASK)?;
    let flags = n.bits(FAULT_FLAGS)?;
    let lamp = |field: &str, bit: &str, lit: Lit| -> Result<Option<Cell>, String> {
        Ok(Some(Cell::Lamp {
            parameter: n.bit(field, bit)?,
            lit,
        }))
    };
    let value =
        |name: &str| -> Result<Option<Cell>, String> { Ok(Some(Cell::Value(n.get(name)?))) };

    let controller = Section {
        title: "Controller",
        description: "State, the last failure reported and the refusal bits of the last refused \
                      move, FK, the background job, the cycle",
        columns: vec![""],
        rows: vec![
            n.value_row("state", "state")?,
            n.value_row("last failure code", "last_failure_code")?,
            n.value_row("refusal bits (last refusal)", "refusal_bits")?,
            DisplayRow {
                label: "FK valid".into(),
                cells: vec![Some(Cell::Lamp {
                    parameter: n.get("fk_valid")?,
                    lit: Lit::Good,
                })],
            },
            n.value_row("background job", "job")?,
            n.value_row("control cycle", "cycle_counter")?,
        ],
        placement: 0,
    };

    let mut pose_rows = Vec::new();
    for axis in POSE_AXES {
        pose_rows.push(DisplayRow {
            label: axis.into(),
            cells: vec![
                value(&format!("pose_fk_op_{axis}"))?,
                value(&format!("pose_cmd_op_{axis}"))?,
                value(&format!("pose_fk_{axis}"))?,
                value(&format!("pose_cmd_{axis}"))?,
            ],
        });
    }
    let pose = Section {
        title: "Pose",
        description:
            "Pose from FK of the encoders and commanded, in the operator's frames (pivot, \
                      user frame: what moves command) and of the platform origin in the base frame",
        columns: vec!["FK", "commanded", "FK (base)", "commanded (base)"],
        rows: pose_rows,
        placement: 0,
    };

    let mut leg_rows = Vec::new();
    for (i, leg) in legs.iter().enumerate() {
        let k = i + 1;
        leg_rows.push(DisplayRow {
            label: format!("leg {k}"),
            cells: vec![
                value(&format!("stroke_cmd_leg{k}"))?,
                value(&format!("encoder_leg{k}"))?,
                lamp("in_position_legs", leg, Lit::Good)?,
                lamp("moving_legs", leg, Lit::Activity)?,
                lamp("limit_lower_legs", leg, Lit::Bad)?,
                lamp("limit_upper_legs", leg, Lit::Bad)?,
                lamp("switch_unreadable_legs", leg, Lit::Bad)?,
                lamp("fault_legs", leg, Lit::Bad)?,
            ],
        });
    }
    let legs_section = Section {
        title: "Legs",
        description: "Every leg: commanded stroke, encoder, in position, moving, end-of-travel \
                      switches, unreadable switch input, named by a latched fault",
        columns: vec![
            "commanded",
            "encoder",
            "in pos.",
            "moving",
            "lower sw.",
            "upper sw.",
            "sw. unread",
            "fault",
        ],
        rows: leg_rows,
        placement: 1,
    };

    let mut flag_rows = vec![DisplayRow {
        label: "word".into(),
        cells: vec![value("fault_flags")?, value("warning_flags")?],
    }];
    for flag in &flags {
        flag_rows.push(DisplayRow {
            label: flag.to_ascii_lowercase().replace('_', " "),
            cells: vec![
                lamp("fault_flags", flag, Lit::Bad)?,
                lamp("warning_flags", flag, Lit::Attention)?,
            ],
        });
    }
    let faults = Section {
        title: "Faults and warnings",
        description: "The latched fault flags and the warning flags, word and bit by bit",
        columns: vec!["latched", "warning"],
        rows: flag_rows,
        placement: 1,
    };

    let table = Section {
        title: "Table",
        description: "The running table, the pending (committed) one, what boots",
        columns: vec![""],
        rows: vec![
            n.value_row("running table ID", "active_table_id")?,
            n.value_row("running table CRC-32", "active_table_crc32")?,
            n.value_row("running table from", "active_bank")?,
            n.value_row("pending table ID", "pending_table_id")?,
            n.value_row("pending table in", "pending_bank")?,
            n.value_row("selected for boot", "selected_source")?,
            n.value_row("booted from", "boot_source")?,
        ],
        placement: 0,
    };

    let mut health_rows = vec![
        n.value_row("TCs accepted", "tc_accepted")?,
        n.value_row("TCs rejected", "tc_rejected")?,
        n.value_row("TC frames dropped", "tc_frames_dropped")?,
        n.value_row("TM records dropped", "tm_dropped")?,
        n.value_row("UART overruns", "uart_overruns")?,
        n.value_row("cycle overruns", "cycle_overruns")?,
        n.value_row("boot count", "boot_count")?,
        n.value_row("reset cause", "reset_cause")?,
    ];
    for l in &mdb.link_health {
        health_rows.push(n.value_row(&l.name.replace('_', " "), l.name)?);
    }
    let health = Section {
        title: "Health",
        description: "The controller's counters since boot and the link's health (the gateway's \
                      counters and time-correlation residual)",
        columns: vec![""],
        rows: health_rows,
        placement: 0,
    };

    Ok(Display {
        name: "housekeeping",
        title: "M2 housekeeping",
        sections: vec![controller, pose, table, health, legs_section, faults],
    })
}

// ------------------------------------------------------------------ parameter lists

/// A Yamcs parameter list (created at start-up by `scripts/ground-segment.sh`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParameterList {
    /// Name (the key by which start-up finds it again).
    pub name: String,
    /// Description.
    pub description: String,
    /// Qualified parameter names (Yamcs' patterns; exact names here).
    pub patterns: Vec<String>,
}

/// The parameter lists: the whole housekeeping display, then one per section.
pub fn parameter_lists(mdb: &Mdb, display: &Display) -> Vec<ParameterList> {
    let q = |names: Vec<String>| names.iter().map(|p| mdb.qualified(p)).collect();
    let mut out = vec![ParameterList {
        name: format!("{} housekeeping", mdb.name),
        description: "Everything the housekeeping display shows".into(),
        patterns: q(display.parameters()),
    }];
    for s in &display.sections {
        out.push(ParameterList {
            name: format!("{} {}", mdb.name, s.title.to_ascii_lowercase()),
            description: s.description.into(),
            patterns: q(s.parameters()),
        });
    }
    out
}

// ------------------------------------------------------------------------- stacks

/// A comparison of a verification step (all of a step's must hold).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Comparison {
    /// Qualified parameter name.
    pub parameter: String,
    /// `eq`, `neq`, `lt`, `lte`, `gt`, `gte` (Yamcs web compares `eq`/`neq` as text,
    /// the others as numbers).
    pub operator: &'static str,
    /// The value compared with.
    pub value: Value,
}

/// One argument of a command step.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Argument {
    /// Argument name.
    pub name: String,
    /// Engineering value (a number, an enumeration label, bytes in hex).
    pub value: Value,
}

/// One step of a Yamcs command stack (`.ycs`, Yamcs web's format).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Step {
    /// Text for the operator (Markdown).
    Text {
        /// The text.
        text: String,
    },
    /// Lists parameters' values (shown below the step when it runs).
    Check {
        /// What for.
        comment: String,
        /// Qualified parameter names, each `{"parameter": name}`.
        parameters: Vec<BTreeMap<&'static str, String>>,
    },
    /// Sends a telecommand; the stack goes on when it completes (the stack's
    /// advancement) and stops if it fails.
    Command {
        /// Qualified command name.
        name: String,
        /// What it does here.
        comment: String,
        /// Arguments.
        arguments: Vec<Argument>,
    },
    /// Waits until every comparison holds, at most `timeout` ms; the stack stops if not.
    Verify {
        /// What it verifies.
        comment: String,
        /// Comparisons.
        condition: Vec<Comparison>,
        /// Timeout (ms).
        timeout: u32,
    },
}

/// A command stack: its file in the `stacks` bucket and its steps.
#[derive(Clone, Debug, PartialEq)]
pub struct Stack {
    /// Path in the `stacks` bucket (`recovery/clear-fault.ycs`).
    pub path: String,
    /// Steps.
    pub steps: Vec<Step>,
}

/// Acknowledgment that advances a stack past a command step: Yamcs' `CommandComplete`,
/// set when the command's last verifier (TM[1,7]) succeeds; a failure stops the stack.
pub const STACK_ADVANCEMENT: &str = "CommandComplete";
/// Timeout of a verification step (ms): ten housekeeping periods (the values compared
/// come with housekeeping).
pub const VERIFY_TIMEOUT_MS: u32 = 10_000;
/// Table ID of the table the shipped upload stack installs (the nominal geometry with
/// the flight limits, as a flash table): one no other procedure uses.
pub const UPLOAD_STACK_TABLE_ID: u32 = 100;
/// How far a pose reached by a move may be from its target and still count as reached
/// (um, arcsec): the end-to-end test's bound for a move in position (measured 0.03 um,
/// 0.07"); each slider is within the in-position tolerance (0.1 um) of its setpoint.
pub const ARRIVAL_TOLERANCE_UM: f64 = 0.3;
/// See [`ARRIVAL_TOLERANCE_UM`].
pub const ARRIVAL_TOLERANCE_ARCSEC: f64 = 0.3;
/// Times the stop distance of a coordinated move at the default limits (speed^2 / 2
/// acceleration: 20 um) that a recovery stroke moves a leg off its switch.
pub const RECOVERY_STOP_DISTANCES: f64 = 5.0;

/// A `.ycs` file: its schema, steps and advancement, in Yamcs web's key order.
#[derive(Serialize)]
struct YcsFile<'a> {
    #[serde(rename = "$schema")]
    schema: &'static str,
    steps: &'a [Step],
    advancement: Advancement,
}

/// When a stack's cursor moves past a command step.
#[derive(Serialize)]
struct Advancement {
    acknowledgment: &'static str,
    wait: u32,
}

impl Stack {
    /// The `.ycs` file (Yamcs web's JSON stack format, with its advancement).
    pub fn to_ycs(&self) -> String {
        let file = YcsFile {
            schema: "https://yamcs.org/schema/stack.schema.json",
            steps: &self.steps,
            advancement: Advancement {
                acknowledgment: STACK_ADVANCEMENT,
                wait: 0,
            },
        };
        serde_json::to_string_pretty(&file).unwrap_or_default() + "\n"
    }
}

/// Builds stack steps, checking every name and argument against the description.
struct StackBuilder<'a> {
    names: Names<'a>,
    steps: Vec<Step>,
}

/// Renders a stack value as the `name=value` word of `m2ground tc`.
fn arg_word(name: &str, value: &Value) -> String {
    match value {
        Value::String(s) => format!("{name}={s}"),
        v => format!("{name}={v}"),
    }
}

impl<'a> StackBuilder<'a> {
    fn new(mdb: &'a Mdb) -> Self {
        Self {
            names: Names::new(mdb),
            steps: Vec::new(),
        }
    }

    fn text(&mut self, text: &str) {
        self.steps.push(Step::Text { text: text.into() });
    }

    fn check(&mut self, comment: &str, parameters: &[String]) -> Result<(), String> {
        let mut ps = Vec::new();
        for p in parameters {
            let q = self.names.mdb.qualified(&self.names.get(p)?);
            ps.push(BTreeMap::from([("parameter", q)]));
        }
        self.steps.push(Step::Check {
            comment: comment.into(),
            parameters: ps,
        });
        Ok(())
    }

    /// A command step: the telecommand and every one of its arguments given, each value
    /// one the encoder takes (the controller's ranges).
    fn command(&mut self, name: &str, args: &[(&str, Value)], comment: &str) -> Result<(), String> {
        let tc = self
            .names
            .mdb
            .telecommand(name)
            .ok_or_else(|| format!("{name}: no such telecommand"))?;
        for f in tc.arguments() {
            if !args.iter().any(|(a, _)| *a == f.name) {
                return Err(format!("{name}: argument {} not given", f.name));
            }
        }
        let words: Vec<String> = args.iter().map(|(a, v)| arg_word(a, v)).collect();
        crate::tc::command_from_args(name, &words)?;
        self.steps.push(Step::Command {
            name: self.names.mdb.qualified(name),
            comment: comment.into(),
            arguments: args
                .iter()
                .map(|(a, v)| Argument {
                    name: (*a).into(),
                    value: v.clone(),
                })
                .collect(),
        });
        Ok(())
    }

    /// The fault clear and its check, the last steps of every recovery: CLEAR_FAULT, then
    /// at rest with no fault latched.
    fn clear_fault(&mut self) -> Result<(), String> {
        self.command("CLEAR_FAULT", &[], "clears the latched fault")?;
        self.verify(
            "no fault latched, at rest: moves are accepted again",
            &[
                ("state", "eq", json!("IDLE")),
                ("fault_flags", "eq", json!(0)),
            ],
        )
    }

    /// A verification step; each comparison's value must be one the parameter can take
    /// (a label of its enumeration, a boolean, a number) and its operator one Yamcs web
    /// applies to it as meant (no text comparison of a calibrated number).
    fn verify(
        &mut self,
        comment: &str,
        condition: &[(&str, &'static str, Value)],
    ) -> Result<(), String> {
        let mut out = Vec::new();
        for (p, op, v) in condition {
            let name = self.names.get(p)?;
            let kind = self.names.kind(&name).cloned();
            let ok = match (&kind, *op, v) {
                (Some(ParameterKind::Enum { enumeration }), "eq" | "neq", Value::String(label)) => {
                    self.names
                        .mdb
                        .enumeration(enumeration)
                        .is_some_and(|e| e.values.iter().any(|(_, l, _)| l == label))
                }
                (Some(ParameterKind::Boolean), "eq" | "neq", Value::Bool(_)) => true,
                (Some(ParameterKind::Integer), _, Value::Number(n)) => n.is_u64() || n.is_i64(),
                (
                    Some(ParameterKind::Float { .. }),
                    "lt" | "lte" | "gt" | "gte",
                    Value::Number(_),
                ) => true,
                _ => false,
            };
            if !ok {
                return Err(format!(
                    "{comment}: {p} {op} {v} cannot be verified on a {kind:?}"
                ));
            }
            out.push(Comparison {
                parameter: self.names.mdb.qualified(&name),
                operator: op,
                value: v.clone(),
            });
        }
        self.steps.push(Step::Verify {
            comment: comment.into(),
            condition: out,
            timeout: VERIFY_TIMEOUT_MS,
        });
        Ok(())
    }

    fn finish(self, path: &str) -> Stack {
        Stack {
            path: path.into(),
            steps: self.steps,
        }
    }
}

/// `[x, y, z, rx, ry, rz]` in um and arcsec as the six pose arguments of a move.
fn pose_args(v: [f64; 6]) -> Vec<(&'static str, Value)> {
    POSE_AXES
        .iter()
        .zip(v)
        .map(|(a, x)| (*a, json!(x)))
        .collect()
}

/// The table upload procedure for `table`: at rest, its chunks, commit, the pending table
/// verified, activate, the running table verified.
pub fn table_upload_stack(mdb: &Mdb, table: &Table) -> Result<Stack, String> {
    let mut s = StackBuilder::new(mdb);
    let cmds = crate::tc::upload_commands(table)?;
    let bytes = table.to_bytes();
    let crc = table.crc32();
    let id = table.table_id;
    let n_chunks = cmds.len() - 1;
    let tag = String::from_utf8_lossy(&table.provenance.tag)
        .trim()
        .to_string();
    s.text(&format!(
        "**Table upload, commit, activate**: table {id} (`{tag}`, calibration {cal}), CRC-32 \
         0x{crc:08x}, {len} bytes in {n_chunks} chunks. Commit writes it to the flash bank the \
         controller does not run from; activate makes it the running table (geometry, limits, \
         supervision thresholds: a critical command). A table job is refused during a motion \
         (`CONTROLLER_BUSY`) and while another runs. This stack was generated for this table \
         (`ground/src/mdb/console.rs`); another table needs its own.",
        cal = table.provenance.calibration_id,
        len = bytes.len(),
    ));
    s.verify(
        "the controller at rest, no table job running",
        &[("state", "eq", json!("IDLE")), ("job", "eq", json!(0))],
    )?;
    for (k, c) in cmds.iter().take(n_chunks).enumerate() {
        let m2ctl::link::Command::LoadTableChunk(chunk) = c else {
            return Err(format!("upload command {k} is not a chunk: {c:?}"));
        };
        let off = usize::from(chunk.offset_bytes());
        let data = bytes
            .get(off..(off + m2ctl::link::command::TABLE_CHUNK_MAX_LEN).min(bytes.len()))
            .ok_or("chunk beyond the table")?;
        let hex: String = data.iter().map(|b| format!("{b:02x}")).collect();
        s.command(
            "LOAD_TABLE_CHUNK",
            &[("offset", json!(off)), ("data", json!(hex))],
            &format!(
                "chunk {} of {n_chunks}: bytes {off}..{}",
                k + 1,
                off + data.len() - 1
            ),
        )?;
    }
    s.command(
        "COMMIT_TABLE",
        &[("crc32", json!(crc))],
        "writes the uploaded table to the bank not in use; completes when written",
    )?;
    s.verify(
        &format!("table {id} pending"),
        &[("pending_table_id", "eq", json!(id))],
    )?;
    s.check(
        "the pending table",
        &["pending_table_id".into(), "pending_bank".into()],
    )?;
    s.command(
        "ACTIVATE_TABLE",
        &[("table_id", json!(id)), ("crc32", json!(crc))],
        "makes the pending table the running one (critical); completes when the selection is written",
    )?;
    s.verify(
        &format!("table {id} running, nothing pending"),
        &[
            ("active_table_id", "eq", json!(id)),
            ("active_table_crc32", "eq", json!(crc)),
            ("pending_table_id", "eq", json!(0)),
        ],
    )?;
    let mut after: Vec<String> = [
        "active_table_id",
        "active_table_crc32",
        "active_bank",
        "selected_source",
    ]
    .map(String::from)
    .to_vec();
    after.extend(POSE_AXES.iter().map(|a| format!("pose_fk_op_{a}")));
    s.check("the running table, the pose it gives the encoders", &after)?;
    Ok(s.finish("table-upload.ycs"))
}

/// The table the shipped upload stack installs: the nominal geometry with the flight
/// limits and the default supervision thresholds, as table [`UPLOAD_STACK_TABLE_ID`].
pub fn upload_stack_table() -> Result<Table, String> {
    let provenance = crate::tc::provenance(&[], None);
    let table = Table::from_geometry(
        &m2ctl::nominal::prototype_with_flight_limits(),
        UPLOAD_STACK_TABLE_ID,
        provenance,
        m2ctl::table::DEFAULT_SUPERVISION,
    )
    .map_err(|e| format!("nominal table: {e:?}"))?;
    m2calib::files::validate_table_for_flight(&table)?;
    Ok(table)
}

/// The calibration pose sequence: the poses of the calibration plan (`m2ground plan`,
/// `m2calib::plan` with its defaults), each reached and verified, with the encoder
/// strokes and the FK pose listed for the campaign; then home.
pub fn calibration_stack(mdb: &Mdb) -> Result<Stack, String> {
    let cfg = m2calib::plan::PlanConfig::default();
    let poses = m2calib::plan::plan_poses(&cfg);
    let mut s = StackBuilder::new(mdb);
    let legs = s.names.bits(LEG_MASK)?;
    let all_legs = (1u64 << legs.len()) - 1;
    s.text(&format!(
        "**Calibration pose sequence**: the {n} poses of the calibration plan (`m2ground plan`: \
         the centre, the corners of a cube of half-side {h} mm and six axis points at {d} mm, \
         each with the eight sign patterns of {r}\" about x, y, z). At each pose the stack waits \
         for the move's completion (every slider in position), verifies the FK pose within \
         {tu} um / {ta}\" of the target and lists the encoder strokes and the pose below the \
         step: the campaign's strokes for the tracker's measurement of that pose (the `M2 legs` \
         list's historical data exports them as CSV). Then back home. The plan's poses are the platform origin's in the base frame: \
         the stack runs only with the default frames (no on-board parameter set).",
        n = poses.len(),
        h = cfg.cube_half_mm.unwrap_or_default(),
        d = cfg.axis_mm.unwrap_or_default(),
        r = cfg.rotation_arcsec,
        tu = ARRIVAL_TOLERANCE_UM,
        ta = ARRIVAL_TOLERANCE_ARCSEC,
    ));
    s.verify(
        "at rest, no fault latched, no on-board parameter set (default frames and limits)",
        &[
            ("state", "eq", json!("IDLE")),
            ("fault_flags", "eq", json!(0)),
            ("parameters_set", "eq", json!(0)),
        ],
    )?;
    let mut listed: Vec<String> = (1..=legs.len())
        .map(|k| format!("encoder_leg{k}"))
        .collect();
    listed.extend(POSE_AXES.iter().map(|a| format!("pose_fk_op_{a}")));
    let targets: Vec<(String, [f64; 6])> = poses
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let v = m2calib::calib::pose_mm_arcsec(p);
            let t = [
                v[0] * UM_PER_MM,
                v[1] * UM_PER_MM,
                v[2] * UM_PER_MM,
                v[3],
                v[4],
                v[5],
            ];
            (format!("pose {} of {}", k + 1, poses.len()), t)
        })
        .chain(std::iter::once(("home".to_string(), [0.0; 6])))
        .collect();
    for (what, t) in &targets {
        // Rounded to the wire's resolution (1 nm, 1 uas) as the encoder rounds it.
        let t = t.map(|x| (x * 1e6).round() / 1e6);
        s.command("MOVE_ABSOLUTE", &pose_args(t), &format!("to {what}"))?;
        let mut cond: Vec<(String, &'static str, Value)> = Vec::new();
        for (axis, x) in POSE_AXES.iter().zip(t) {
            let tol = if axis.starts_with('r') {
                ARRIVAL_TOLERANCE_ARCSEC
            } else {
                ARRIVAL_TOLERANCE_UM
            };
            let p = format!("pose_fk_op_{axis}");
            cond.push((p.clone(), "gte", json!(round6(x - tol))));
            cond.push((p, "lte", json!(round6(x + tol))));
        }
        cond.push(("in_position_legs".into(), "eq", json!(all_legs)));
        cond.push(("state".into(), "eq", json!("IDLE")));
        let cond: Vec<(&str, &'static str, Value)> = cond
            .iter()
            .map(|(p, o, v)| (p.as_str(), *o, v.clone()))
            .collect();
        s.verify(&format!("{what} reached, every slider in position"), &cond)?;
        if what != "home" {
            s.check(&format!("strokes and pose at {what}"), &listed)?;
        }
    }
    Ok(s.finish("calibration-poses.ycs"))
}

/// `x` to 6 decimals (the resolution of the wire's micrometres and arcseconds).
fn round6(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

/// Which end-of-travel switch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SwitchEnd {
    /// The lower switch (a recovery stroke goes up).
    Lower,
    /// The upper switch (a recovery stroke goes down).
    Upper,
}

impl SwitchEnd {
    /// Both, lower first.
    pub const ALL: [SwitchEnd; 2] = [SwitchEnd::Lower, SwitchEnd::Upper];

    /// `lower` / `upper`.
    pub fn word(self) -> &'static str {
        match self {
            SwitchEnd::Lower => "lower",
            SwitchEnd::Upper => "upper",
        }
    }

    /// Sign of a stroke away from this switch.
    pub fn away(self) -> f64 {
        match self {
            SwitchEnd::Lower => 1.0,
            SwitchEnd::Upper => -1.0,
        }
    }
}

/// The recovery stroke off a switch (um): [`RECOVERY_STOP_DISTANCES`] times the stop
/// distance of a coordinated move at the default speed and acceleration limits.
pub fn recovery_stroke_um() -> f64 {
    let v = f64::from(DEFAULT_MAX_SPEED_MM_PER_S);
    let a = f64::from(DEFAULT_MAX_ACCEL_MM_PER_S2);
    (RECOVERY_STOP_DISTANCES * v * v / (2.0 * a) * UM_PER_MM).round()
}

/// The recovery of leg `leg` (1-based) stopped at its `end` switch: the diagnosis, a
/// direct stroke off the switch, the switch verified released, the fault cleared.
pub fn switch_recovery_stack(mdb: &Mdb, leg: usize, end: SwitchEnd) -> Result<Stack, String> {
    let mut s = StackBuilder::new(mdb);
    let legs = s.names.bits(LEG_MASK)?;
    let bit = legs
        .get(leg.wrapping_sub(1))
        .ok_or_else(|| format!("leg {leg}: no such leg"))?
        .clone();
    let field = format!("limit_{}_legs", end.word());
    let switch = s.names.bit(&field, &bit)?;
    let limit_flag = s.names.bit("fault_flags", "LIMIT_SWITCH")?;
    let delta = end.away() * recovery_stroke_um();
    s.text(&format!(
        "**Leg {leg} off its {e} end-of-travel switch**: for a controller FAULTED with \
         `LIMIT_SWITCH` latched because leg {leg} reached its {e} switch (event `END_OF_TRAVEL` \
         names the legs; housekeeping `{field}`). Coordinated moves are refused until the \
         fault is cleared, and the clear is refused while a switch is active. A direct stroke \
         moves leg {leg} alone, {dir} the switch at the recovery speed: {delta} um ({k} times \
         the {stop} um a move at the default limits needs to stop). If the switch stays \
         active, run this stack again from the stroke; a switch active at both ends or one \
         that trips inside the stroke range is a hardware fault to report.",
        e = end.word(),
        dir = "away from",
        k = RECOVERY_STOP_DISTANCES,
        stop = recovery_stroke_um() / RECOVERY_STOP_DISTANCES,
    ));
    s.check(
        "the fault and the switches",
        &[
            "state".into(),
            "fault_flags".into(),
            "fault_legs".into(),
            "limit_lower_legs".into(),
            "limit_upper_legs".into(),
            format!("encoder_leg{leg}"),
            format!("stroke_cmd_leg{leg}"),
            "last_failure_code".into(),
        ],
    )?;
    s.verify(
        &format!(
            "faulted by an end-of-travel switch, leg {leg} at its {} switch",
            end.word()
        ),
        &[
            ("state", "eq", json!("FAULTED")),
            (&limit_flag, "eq", json!(true)),
            (&switch, "eq", json!(true)),
        ],
    )?;
    s.command(
        "DIRECT_STROKE",
        &[("leg", json!(leg)), ("delta", json!(delta))],
        &format!("leg {leg} {delta} um, off the switch; completes on arrival"),
    )?;
    s.verify(
        &format!("leg {leg}'s {} switch released", end.word()),
        &[(&switch, "eq", json!(false))],
    )?;
    s.clear_fault()?;
    s.text(&format!(
        "Recovered: leg {leg} is {stroke} um off the switch; the next move starts from there. \
         Command it away from the switch.",
        stroke = delta.abs()
    ));
    Ok(s.finish(&format!("recovery/leg{leg}-{}-switch.ycs", end.word())))
}

/// Clearing a latched fault whose cause is gone (an encoder answering again, a drive
/// repaired): the diagnosis, the clear, the state verified.
pub fn clear_fault_stack(mdb: &Mdb) -> Result<Stack, String> {
    let mut s = StackBuilder::new(mdb);
    s.text(
        "**Clear a latched fault** once its cause is gone (the event `FAULT_LATCHED` names the \
         flags and legs). The clear is refused (`CLEAR_REFUSED`, the blocking flags as its \
         data) and changes nothing while a latched fault's condition is present: a leg at an \
         end-of-travel switch needs the stack of that leg and switch (`recovery/`) first.",
    );
    let mut listed: Vec<String> = [
        "state",
        "fault_flags",
        "warning_flags",
        "fault_legs",
        "last_failure_code",
    ]
    .map(String::from)
    .to_vec();
    let legs = s.names.bits(LEG_MASK)?.len();
    listed.extend((1..=legs).map(|k| format!("encoder_leg{k}")));
    s.check("the fault", &listed)?;
    s.verify("faulted", &[("state", "eq", json!("FAULTED"))])?;
    s.clear_fault()?;
    Ok(s.finish("recovery/clear-fault.ycs"))
}

/// Every stack the console ships.
pub fn stacks(mdb: &Mdb) -> Result<Vec<Stack>, String> {
    let mut out = vec![
        table_upload_stack(mdb, &upload_stack_table()?)?,
        calibration_stack(mdb)?,
        clear_fault_stack(mdb)?,
    ];
    let legs = mdb.bit_field(LEG_MASK).ok_or("no leg mask")?.bits.len();
    for leg in 1..=legs {
        for end in SwitchEnd::ALL {
            out.push(switch_recovery_stack(mdb, leg, end)?);
        }
    }
    Ok(out)
}

// -------------------------------------------------------------------------- files

/// One file of the console, relative to `yamcs/`.
#[derive(Clone, Debug, PartialEq)]
pub struct ConsoleFile {
    /// Path relative to the repository's `yamcs/` folder (`stacks/table-upload.ycs`).
    pub path: String,
    /// Contents.
    pub text: String,
}

/// Folder (under `yamcs/`) served as the Yamcs bucket `displays`.
pub const DISPLAYS_DIR: &str = "displays";
/// Folder (under `yamcs/`) served as the Yamcs bucket `stacks`.
pub const STACKS_DIR: &str = "stacks";
/// The parameter lists' file (under `yamcs/`), read by `scripts/ground-segment.sh`.
pub const LISTS_FILE: &str = "lists/parameter-lists.json";

/// The parameter table (`.par`) of a display: its parameters, one row each (Yamcs
/// web's parameter-table format).
pub fn display_par(mdb: &Mdb, display: &Display) -> String {
    let v = json!({
        "$schema": "https://yamcs.org/schema/parameter-table.schema.json",
        "scroll": false,
        "parameters": display.parameters().iter().map(|p| mdb.qualified(p)).collect::<Vec<_>>(),
    });
    serde_json::to_string_pretty(&v).unwrap_or_default() + "\n"
}

/// Every file of the console: the housekeeping display (`.opi`, Yamcs Studio's format,
/// which Yamcs web draws, and `.par`, its parameter table), the parameter lists, the
/// stacks.
pub fn console_files(mdb: &Mdb) -> Result<Vec<ConsoleFile>, String> {
    let display = housekeeping_display(mdb)?;
    let names = Names::new(mdb);
    let mut out = vec![
        ConsoleFile {
            path: format!("{DISPLAYS_DIR}/{}.opi", display.name),
            text: opi::display_opi(mdb, &display, &|p| names.kind(p).cloned()),
        },
        ConsoleFile {
            path: format!("{DISPLAYS_DIR}/{}.par", display.name),
            text: display_par(mdb, &display),
        },
        ConsoleFile {
            path: LISTS_FILE.into(),
            text: serde_json::to_string_pretty(&parameter_lists(mdb, &display)).unwrap_or_default()
                + "\n",
        },
    ];
    for s in stacks(mdb)? {
        out.push(ConsoleFile {
            path: format!("{STACKS_DIR}/{}", s.path),
            text: s.to_ycs(),
        });
    }
    Ok(out)
}
