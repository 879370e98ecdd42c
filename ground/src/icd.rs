//! The tables of `docs/icd.md` that restate the code (codes, IDs, offsets, lengths,
//! units, ranges), generated from the mission database ([`crate::mdb`], the
//! description the Yamcs XTCE is also generated from) and the flight constants instead
//! of being typed twice.
//!
//! Each generated block sits in the document between two marker lines:
//!
//! ```text
//! <!-- BEGIN GENERATED: failure-codes (m2ground icd-tables --write docs/icd.md) -->
//! | code | origin | meaning | report | failure data |
//! ...
//! <!-- END GENERATED: failure-codes -->
//! ```
//!
//! [`regenerate`] replaces what is between the markers and nothing else;
//! [`drift`] says which blocks of a document differ from the code (`ground/tests/icd.rs`
//! fails on it; `m2ground icd-tables --check docs/icd.md` prints it). Building the blocks
//! also checks the description for what a table would show wrong (rows that do not
//! tile a layout, a subtype in no row, a function whose arguments do not add up to
//! its length): [`blocks`] returns that as an error.

use crate::mdb::{
    self, hex4, thousands, FailureCode, Field, Mdb, ReportedIn, Telecommand, Wire, PERFORM_FUNCTION,
};
use m2ctl::controller::event;
use m2ctl::controller::params::PARAMETERS;
use m2ctl::kinematics::{Refusals, LEGS};
use m2ctl::link::command::{FunctionId, FUNCTION_ID_LEN};
use m2ctl::link::hk::HK_REPORT_LEN;
use m2ctl::link::tc::{APID_MASK, SEQ_COUNT_MASK};
use m2ctl::link::{service, subtype, LinkError, M2_APID};
use m2ctl::table::layout::TABLE_CRC_OFFSET;
use m2ctl::table::store::{boot_flags, BOOT_FLAGS_BANK_B_SHIFT, BOOT_FLAGS_SELECTION_SHIFT};
use m2ctl::table::{BootSource, TABLE_LEN};

/// The command that rewrites the generated blocks of `docs/icd.md`.
pub const REGENERATE: &str = "m2ground icd-tables --write docs/icd.md";

/// One generated block: its name (in the markers) and its text (whole lines, each
/// ending with a newline).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Block {
    /// Name in the markers.
    pub name: &'static str,
    /// The generated lines.
    pub text: String,
}

/// The line that opens block `name`.
pub fn begin_marker(name: &str) -> String {
    format!("<!-- BEGIN GENERATED: {name} ({REGENERATE}) -->")
}

/// The line that closes block `name`.
pub fn end_marker(name: &str) -> String {
    format!("<!-- END GENERATED: {name} -->")
}

const BEGIN_PREFIX: &str = "<!-- BEGIN GENERATED: ";

// ---------------------------------------------------------------------------------
// Markdown.

/// Column alignment of a table.
#[derive(Clone, Copy)]
enum Align {
    Left,
    Right,
}

/// A markdown table: header, separator, rows (a `|` in a cell is escaped).
fn table(header: &[(&str, Align)], rows: &[Vec<String>]) -> Result<String, String> {
    let line = |cells: &[String]| format!("| {} |\n", cells.join(" | "));
    let mut out = line(
        &header
            .iter()
            .map(|(h, _)| h.to_string())
            .collect::<Vec<_>>(),
    );
    let sep: Vec<&str> = header
        .iter()
        .map(|(_, a)| match a {
            Align::Left => "---",
            Align::Right => "---:",
        })
        .collect();
    out.push_str(&format!("|{}|\n", sep.join("|")));
    for r in rows {
        if r.len() != header.len() {
            return Err(format!(
                "a row of {} cells under {} columns: {r:?}",
                r.len(),
                header.len()
            ));
        }
        if let Some(c) = r
            .iter()
            .find(|c| c.contains('\n') || c.trim() != c.as_str())
        {
            return Err(format!("cell {c:?}: a line break or surrounding spaces"));
        }
        let cells: Vec<String> = r.iter().map(|c| c.replace('|', "\\|")).collect();
        out.push_str(&line(&cells));
    }
    Ok(out)
}

/// Width of generated prose lines (as the hand-written prose of docs/icd.md).
const WRAP: usize = 87;

/// A paragraph wrapped at [`WRAP`] columns (no line starts with what markdown would read
/// as a list item or a heading).
fn paragraph(text: &str) -> String {
    let mut out = String::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        let starts_block = |w: &str| {
            w.starts_with('#')
                || w == "-"
                || w == "*"
                || w == "+"
                || w.strip_suffix('.')
                    .is_some_and(|n| n.chars().all(|c| c.is_ascii_digit()))
        };
        if !line.is_empty()
            && line.chars().count() + 1 + word.chars().count() > WRAP
            && !starts_block(word)
        {
            out.push_str(&line);
            out.push('\n');
            line.clear();
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() {
        out.push_str(&line);
        out.push('\n');
    }
    out
}

/// `a..b` of a bit or byte range, or `a` alone.
fn span(first: u32, last: u32) -> String {
    if first == last {
        format!("{first}")
    } else {
        format!("{first}..{last}")
    }
}

// ---------------------------------------------------------------------------------
// Section 2: packets.

fn packet_block() -> Result<String, String> {
    let crc = m2ctl::link::tc::CRC16_ALGORITHM;
    let seq_bits = SEQ_COUNT_MASK.count_ones();
    let flag = |b: bool| if b { "reflected" } else { "no reflection" };
    let xorout = if crc.xorout == 0 {
        "no xor out".to_string()
    } else {
        format!("xor out {:#06X}", crc.xorout)
    };
    if crc.refin != crc.refout {
        return Err("the TC CRC reflects input and output differently".into());
    }
    let rows = vec![
        vec![
            "APID".into(),
            format!(
                "**`0x{M2_APID:03X}`** ({M2_APID}), both directions; TCs with another APID are \
                 refused (code {})",
                hex4(LinkError::WrongApid { apid: 0 }.code())
            ),
        ],
        vec!["packet version".into(), "0".into()],
        vec![
            "sequence flags".into(),
            format!(
                "`0b11` (unsegmented); anything else is refused ({})",
                hex4(LinkError::BadPrimaryHeader.code())
            ),
        ],
        vec![
            "TC sequence count".into(),
            format!("chosen by the sender ({seq_bits} bits), echoed in the request ID"),
        ],
        vec![
            "TM sequence count".into(),
            format!(
                "0 after boot, +1 per TM packet, wraps at {}",
                u32::from(SEQ_COUNT_MASK) + 1
            ),
        ],
        vec![
            "packet error control".into(),
            format!(
                "CRC-16/CCITT-FALSE (poly 0x{:04X}, init 0x{:04X}, {}, {xorout}) over the \
                 whole packet except the CRC; mandatory in TC and TM",
                crc.poly,
                crc.init,
                flag(crc.refin)
            ),
        ],
    ];
    if u32::from(M2_APID) & !u32::from(APID_MASK) != 0 {
        return Err(format!("APID {M2_APID:#x} wider than its field"));
    }
    table(&[("item", Align::Left), ("value", Align::Left)], &rows)
}

// ---------------------------------------------------------------------------------
// Section 3: telecommands.

fn tc_label(service: u8, subtypes: &[u8]) -> String {
    let sub = match (subtypes.first(), subtypes.last()) {
        (Some(a), Some(b)) if a != b => format!("{a}..{b}"),
        (Some(a), _) => format!("{a}"),
        _ => String::new(),
    };
    format!("[{service},{sub}]")
}

fn telecommands_block(db: &Mdb) -> Result<String, String> {
    let mut rows: Vec<Vec<String>> = Vec::new();
    let mut seen: Vec<(u8, u8)> = Vec::new();
    let mut i = 0;
    while let Some(tc) = db.telecommands.get(i) {
        let key = (tc.service, tc.subtype);
        if seen.contains(&key) {
            return Err(format!(
                "TC{} is described in two places: list its telecommands together",
                tc_label(tc.service, &[tc.subtype])
            ));
        }
        seen.push(key);
        let group: Vec<&Telecommand> = db.telecommands[i..]
            .iter()
            .take_while(|t| (t.service, t.subtype) == key)
            .collect();
        i += group.len();
        let label = format!("TC{}", tc_label(tc.service, &[tc.subtype]));
        if group.iter().any(|t| t.function_id.is_some()) {
            rows.push(vec![
                label,
                PERFORM_FUNCTION.0.into(),
                PERFORM_FUNCTION.1.into(),
            ]);
        } else if let [only] = group.as_slice() {
            rows.push(vec![
                label,
                only.title.clone(),
                only.app_data_layout.clone(),
            ]);
        } else {
            return Err(format!(
                "{label}: several telecommands without function IDs"
            ));
        }
    }
    table(
        &[
            ("TC", Align::Left),
            ("meaning", Align::Left),
            ("application data", Align::Left),
        ],
        &rows,
    )
}

/// End of the last fixed-size field (bytes of application data the fields take).
fn fields_end(fields: &[Field]) -> Option<usize> {
    fields
        .iter()
        .map(|f| f.wire.fixed_len().map(|n| f.offset + n))
        .try_fold(0, |acc, end| end.map(|e| acc.max(e)))
}

fn functions_block(db: &Mdb) -> Result<String, String> {
    let mut rows = Vec::new();
    for tc in &db.telecommands {
        let Some(id) = tc.function_id else { continue };
        let f = FunctionId::from_code(id)
            .ok_or_else(|| format!("{}: function {} unknown to the link", tc.name, hex4(id)))?;
        let ad = FUNCTION_ID_LEN + f.args_len();
        let described = fields_end(&tc.fields).unwrap_or(0).max(FUNCTION_ID_LEN);
        if described != ad {
            return Err(format!(
                "{}: the description's arguments end at byte {described}, the link takes {ad}",
                tc.name
            ));
        }
        rows.push(vec![
            hex4(id),
            tc.title.clone(),
            tc.app_data_layout.clone(),
            ad.to_string(),
        ]);
    }
    table(
        &[
            ("ID", Align::Left),
            ("function", Align::Left),
            ("arguments after the ID", Align::Left),
            ("AD bytes", Align::Left),
        ],
        &rows,
    )
}

// ---------------------------------------------------------------------------------
// Section 4: telemetry, events.

fn telemetry_block(db: &Mdb) -> Result<String, String> {
    // Rows in the description's order, the subtypes of one service in subtype order
    // (verification: 1, 2, 3, 4, 7, 8 although two layouts describe them).
    let mut rows: Vec<(u8, Vec<u8>, String, String)> = Vec::new();
    for p in &db.telemetry {
        let mut covered: Vec<u8> = p.kinds.iter().flat_map(|k| k.subtypes.clone()).collect();
        covered.sort_unstable();
        let mut want = p.subtypes.clone();
        want.sort_unstable();
        if covered != want {
            return Err(format!(
                "TM packet {}: its rows cover subtypes {covered:?}, it has {want:?}",
                p.name
            ));
        }
        for k in &p.kinds {
            rows.push((
                p.service,
                k.subtypes.clone(),
                k.title.clone(),
                k.data_layout.clone(),
            ));
        }
    }
    let mut sorted: Vec<(u8, Vec<u8>, String, String)> = Vec::new();
    for r in rows {
        // Insert after the last row of the same service with a smaller first subtype,
        // when the previous row is of the same service; otherwise append.
        let same_service_tail = sorted.iter().rev().take_while(|s| s.0 == r.0).count();
        let start = sorted.len() - same_service_tail;
        let at = sorted[start..]
            .iter()
            .position(|s| s.1.first() > r.1.first())
            .map_or(sorted.len(), |p| start + p);
        sorted.insert(at, r);
    }
    let rows: Vec<Vec<String>> = sorted
        .into_iter()
        .map(|(svc, subs, title, data)| vec![format!("TM{}", tc_label(svc, &subs)), title, data])
        .collect();
    table(
        &[
            ("TM", Align::Left),
            ("meaning", Align::Left),
            ("source data", Align::Left),
        ],
        &rows,
    )
}

fn events_block(db: &Mdb) -> Result<String, String> {
    let rows: Vec<Vec<String>> = db
        .events
        .iter()
        .map(|e| {
            let sev: Vec<String> = e
                .severities
                .iter()
                .map(|s| {
                    let base = format!("{} ({})", s.severity.to_ascii_lowercase(), s.subtype);
                    if s.when.is_empty() {
                        base
                    } else {
                        format!("{base} {}", s.when)
                    }
                })
                .collect();
            vec![
                hex4(e.id),
                e.description.clone(),
                sev.join(", "),
                e.aux0.clone(),
                e.aux1.clone(),
            ]
        })
        .collect();
    table(
        &[
            ("ID", Align::Left),
            ("event", Align::Left),
            ("severity (subtype)", Align::Left),
            ("aux0", Align::Left),
            ("aux1", Align::Left),
        ],
        &rows,
    )
}

fn bits_span(word: u32) -> Result<(u32, u32), String> {
    if word == 0 {
        return Err("an empty bit group".into());
    }
    let first = word.trailing_zeros();
    let last = 31 - word.leading_zeros();
    if (first..=last).any(|b| word & (1 << b) == 0) {
        return Err(format!("bits {word:#x} are not contiguous"));
    }
    Ok((first, last))
}

fn boot_flags_block() -> Result<String, String> {
    let statuses = mdb::bank_status_flags();
    let bank_word = statuses.iter().fold(0u32, |w, (b, _)| w | (1 << b));
    let (first, last) = bits_span(bank_word)?;
    if first != 0 {
        return Err("bank A's status does not start at bit 0".into());
    }
    let fell_back = u32::from(boot_flags::FELL_BACK).trailing_zeros();
    let list: Vec<String> = statuses
        .iter()
        .enumerate()
        .map(|(i, (b, what))| {
            if i == 0 {
                format!("bit {b} {what}")
            } else {
                format!("{b} {what}")
            }
        })
        .collect();
    let sources = [BootSource::Nominal, BootSource::BankA, BootSource::BankB];
    let choice_bits = 32
        - sources
            .iter()
            .map(|s| u32::from(s.code()))
            .max()
            .unwrap_or(0)
            .leading_zeros();
    let sel = BOOT_FLAGS_SELECTION_SHIFT;
    Ok(paragraph(&format!(
        "**Boot flags** (event {} aux0): bank A's status in bits {}, bank B's in bits {} ({}); \
         bit {fell_back}: the boot fell back (the selected table could not be booted); bit \
         {sel}: a valid selection record was found; bits {} its choice ({} nominal, {} A, {} B).",
        hex4(event::BOOT_DETAIL),
        span(first, last),
        span(
            first + BOOT_FLAGS_BANK_B_SHIFT,
            last + BOOT_FLAGS_BANK_B_SHIFT
        ),
        list.join(", "),
        span(sel + 1, sel + choice_bits),
        sources[0].code(),
        sources[1].code(),
        sources[2].code(),
    )))
}

fn reset_causes_block() -> Result<String, String> {
    let list: Vec<String> = mdb::reset_causes()
        .iter()
        .map(|(code, name, note)| {
            if note.is_empty() {
                format!("{code} {name}")
            } else {
                format!("{code} {name} ({note})")
            }
        })
        .collect();
    Ok(paragraph(&format!("**Reset cause**: {}.", list.join(", "))))
}

// ---------------------------------------------------------------------------------
// Section 5: the table image; 5a: the parameters.

fn table_image_block(db: &Mdb) -> Result<String, String> {
    let mut at = 0;
    let mut rows = Vec::new();
    for r in &db.table_image {
        if r.offset != at {
            return Err(format!(
                "table image: {:?} at {}, expected {at}",
                r.field, r.offset
            ));
        }
        at += r.size;
        rows.push(vec![
            r.offset.to_string(),
            r.size.to_string(),
            r.ty.clone(),
            r.field.clone(),
            r.unit.to_string(),
            r.validation.clone(),
        ]);
    }
    if at != TABLE_LEN {
        return Err(format!(
            "table image: the rows end at {at}, the image is {TABLE_LEN} bytes"
        ));
    }
    if db.table_image.last().map(|r| r.offset) != Some(TABLE_CRC_OFFSET) {
        return Err("table image: the last row is not the CRC".into());
    }
    let mut out = table(
        &[
            ("offset", Align::Right),
            ("size", Align::Right),
            ("type", Align::Left),
            ("field", Align::Left),
            ("unit", Align::Left),
            ("range accepted by validation", Align::Left),
        ],
        &rows,
    )?;
    // An empty unit cell is written `| |`, as by hand.
    out = out.replace("|  |", "| |");
    Ok(out)
}

/// `nm/s^2` -> `nm/s²`.
fn unit_cell(unit: &str) -> String {
    unit.replace("^2", "²")
}

fn parameters_block() -> Result<String, String> {
    let mut rows = Vec::new();
    for d in PARAMETERS.iter() {
        let name = mdb::parameter_description(d.name).ok_or_else(|| {
            format!(
                "parameter {} ({}): no description in ground::mdb",
                d.name,
                hex4(d.id)
            )
        })?;
        let range = if d.min == -d.max {
            format!("±{}", thousands(i64::from(d.max)))
        } else {
            format!(
                "{}..{}",
                thousands(i64::from(d.min)),
                thousands(i64::from(d.max))
            )
        };
        rows.push(vec![
            hex4(d.id),
            name,
            unit_cell(d.unit),
            range,
            mdb::parameter_default(d),
        ]);
    }
    table(
        &[
            ("ID", Align::Left),
            ("name", Align::Left),
            ("unit", Align::Left),
            ("range", Align::Left),
            ("default", Align::Left),
        ],
        &rows,
    )
}

// ---------------------------------------------------------------------------------
// Section 6: housekeeping, states, flags, refusal bits.

fn wire_name(w: Wire) -> Result<&'static str, String> {
    Ok(match w {
        Wire::U8 => "u8",
        Wire::U16 => "u16",
        Wire::U32 => "u32",
        Wire::I32 => "i32",
        Wire::Bytes { .. } | Wire::Packet { .. } => {
            return Err("a variable-length field in housekeeping".into())
        }
    })
}

fn housekeeping_block() -> Result<String, String> {
    let mut at = 0;
    let mut rows = Vec::new();
    for row in mdb::housekeeping_rows() {
        let fields: Vec<&Field> = row.fields.iter().map(|(f, _)| f).collect();
        let first = fields.first().ok_or("a housekeeping row without fields")?;
        if first.offset != at {
            return Err(format!(
                "housekeeping: {} at {}, expected {at}",
                first.name, first.offset
            ));
        }
        let mut end = at;
        for f in &fields {
            if f.offset != end {
                return Err(format!(
                    "housekeeping: {} at {}, expected {end}",
                    f.name, f.offset
                ));
            }
            end += f
                .wire
                .fixed_len()
                .ok_or("a variable-length field in housekeeping")?;
        }
        let ty = match fields.as_slice() {
            [one] => wire_name(one.wire)?.to_string(),
            [sec, frac] if sec.name.ends_with("seconds") && frac.name.ends_with("fraction") => {
                format!("CUC {}+{}", mdb::CUC_COARSE_BYTES, mdb::CUC_FINE_BYTES)
            }
            many if many.iter().all(|f| f.wire == first.wire) => {
                format!("{} × {}", many.len(), wire_name(first.wire)?)
            }
            _ => {
                return Err(format!(
                    "housekeeping: row {:?} mixes types",
                    row.description
                ))
            }
        };
        rows.push(vec![
            at.to_string(),
            (end - at).to_string(),
            ty,
            row.description.clone(),
        ]);
        at = end;
    }
    if at != HK_REPORT_LEN {
        return Err(format!(
            "housekeeping: the rows end at {at}, the report is {HK_REPORT_LEN}"
        ));
    }
    table(
        &[
            ("offset", Align::Right),
            ("size", Align::Right),
            ("type", Align::Left),
            ("field", Align::Left),
        ],
        &rows,
    )
}

/// Offset and size of the housekeeping field `name`.
fn hk_field(name: &str) -> Result<(usize, usize), String> {
    mdb::housekeeping_fields()
        .into_iter()
        .find(|(f, _)| f.name == name)
        .and_then(|(f, _)| Some((f.offset, f.wire.fixed_len()?)))
        .ok_or_else(|| format!("no housekeeping field {name}"))
}

fn controller_states_block() -> Result<String, String> {
    let (state_at, _) = hk_field("state")?;
    let list: Vec<String> = mdb::controller_state_doc()
        .iter()
        .map(|(code, _, name, meaning)| format!("{code} {name} ({meaning})"))
        .collect();
    Ok(paragraph(&format!(
        "**Controller states** (HK byte {state_at}): {}. The state is derived from the motion \
         and the latched faults; every change is event {}.",
        list.join(", "),
        hex4(event::STATE_CHANGED)
    )))
}

fn fault_flags_block() -> Result<String, String> {
    let (flags_at, flags_len) = hk_field("fault_flags")?;
    let flags = mdb::fault_flags_doc();
    let list = |warning: bool| -> Vec<String> {
        flags
            .iter()
            .filter(|f| f.warning == warning)
            .enumerate()
            .map(|(i, f)| {
                if i == 0 {
                    format!("bit {} {}", f.bit, f.name)
                } else {
                    format!("{} {}", f.bit, f.name)
                }
            })
            .collect()
    };
    let table_corrupt = flags
        .iter()
        .find(|f| f.label == "TABLE_CORRUPT")
        .ok_or("no TABLE_CORRUPT flag")?
        .bit;
    Ok(paragraph(&format!(
        "**Fault flags** (HK bytes {flags_at}..{}, event {}): {}. **Warning flags**: {}. \
         Detection latencies: `src/supervision/supervisor.rs`. A fault stops any motion at the \
         acceleration limit (bit {table_corrupt}: at once) and latches; once at rest the drives \
         hold where their sliders are. A clear is accepted only when no latched fault's \
         condition is present.",
        flags_at + flags_len,
        hex4(event::FAULT_LATCHED),
        list(false).join(", "),
        list(true).join(", "),
    )))
}

fn refusal_bits_block() -> Result<String, String> {
    let bits = |r: Refusals| bits_span(r.to_bits());
    let none = Refusals::default();
    let all_legs = (1u8 << LEGS) - 1;
    let mut groups = [
        (
            bits(Refusals {
                non_finite: true,
                ..none
            })?,
            "non-finite pose".to_string(),
        ),
        (
            bits(Refusals {
                legs_above_max: all_legs,
                ..none
            })?,
            "legs above the upper stroke limit".to_string(),
        ),
        (
            bits(Refusals {
                axes_outside: 0x3f,
                ..none
            })?,
            format!(
                "axes outside the workspace ({})",
                "x, y, z, alpha, beta, gamma"
            ),
        ),
        (
            bits(Refusals {
                legs_unreachable: all_legs,
                ..none
            })?,
            "legs unreachable".to_string(),
        ),
        (
            bits(Refusals {
                legs_below_min: all_legs,
                ..none
            })?,
            "legs below the lower stroke limit".to_string(),
        ),
    ];
    groups.sort_by_key(|((first, _), _)| *first);
    let parts: Vec<String> = groups
        .iter()
        .map(|((first, last), what)| {
            let mut what = what.clone();
            // Leg i at bit i: say so where the bit number is the leg number.
            if what.starts_with("legs") && *first == 1 {
                what.push_str(" (leg i at bit i)");
            }
            if first == last {
                format!("bit {first} {what}")
            } else {
                format!("bits {first}..{last} {what}")
            }
        })
        .collect();
    Ok(paragraph(&format!(
        "**Refusal bits** (`kinematics::Refusals::to_bits`): {}.",
        parts.join("; ")
    )))
}

// ---------------------------------------------------------------------------------
// Section 7: failure codes.

fn report_cell(r: ReportedIn) -> String {
    let v = service::VERIFICATION;
    match r {
        ReportedIn::AcceptanceFailure => format!("TM[{v},{}]", subtype::ACCEPTANCE_FAILURE),
        ReportedIn::StartFailure => format!("TM[{v},{}]", subtype::START_FAILURE),
        ReportedIn::CompletionFailure => format!("TM[{v},{}]", subtype::COMPLETION_FAILURE),
        ReportedIn::CompletionOrStartFailure => format!(
            "TM[{v},{}] (TM[{v},{}] while planning)",
            subtype::COMPLETION_FAILURE,
            subtype::START_FAILURE
        ),
        ReportedIn::CountedOnly => "(counted, no report)".into(),
        ReportedIn::AsWrappedCode | ReportedIn::InsideDataOf(_) | ReportedIn::NotReported => {
            "—".into()
        }
    }
}

/// Failure codes that a report can carry (the others only appear inside another
/// code's data, or nowhere).
fn reported(c: &FailureCode) -> bool {
    !matches!(
        c.report,
        ReportedIn::InsideDataOf(_) | ReportedIn::NotReported
    )
}

fn failure_codes_block(db: &Mdb) -> Result<String, String> {
    let mut seen = std::collections::BTreeSet::new();
    for c in &db.failure_codes {
        if !seen.insert(c.code) {
            return Err(format!("failure code {} described twice", hex4(c.code)));
        }
    }
    let rows: Vec<Vec<String>> = db
        .failure_codes
        .iter()
        .filter(|c| reported(c))
        .map(|c| {
            vec![
                hex4(c.code),
                c.origin.to_string(),
                c.meaning.clone(),
                report_cell(c.report),
                c.data.clone(),
            ]
        })
        .collect();
    table(
        &[
            ("code", Align::Left),
            ("origin", Align::Left),
            ("meaning", Align::Left),
            ("report", Align::Left),
            ("failure data", Align::Left),
        ],
        &rows,
    )
}

fn nested_codes_block(db: &Mdb) -> Result<String, String> {
    // One entry per family, in order: its code range and the code whose data holds it.
    let mut parts: Vec<String> = Vec::new();
    let mut families: Vec<(&str, u16, u16, u16)> = Vec::new();
    for c in &db.failure_codes {
        let ReportedIn::InsideDataOf(container) = c.report else {
            continue;
        };
        match families.iter_mut().find(|f| f.0 == c.origin) {
            Some(f) if f.3 == container => {
                f.1 = f.1.min(c.code);
                f.2 = f.2.max(c.code);
            }
            Some(_) => return Err(format!("{} codes inside two different codes", c.origin)),
            None => families.push((c.origin, c.code, c.code, container)),
        }
    }
    for (origin, first, last, container) in families {
        parts.push(format!(
            "{}..{} {origin} (in {})",
            hex4(first),
            hex4(last),
            hex4(container)
        ));
    }
    Ok(paragraph(&format!(
        "Nested codes (appear only inside another code's data): {}.",
        parts.join(", ")
    )))
}

// ---------------------------------------------------------------------------------
// The blocks and the document.

/// Every generated block, in document order.
pub fn blocks() -> Result<Vec<Block>, String> {
    let db = mdb::mdb();
    let named = |name: &'static str, text: Result<String, String>| {
        text.map(|text| Block { name, text })
            .map_err(|e| format!("{name}: {e}"))
    };
    Ok(vec![
        named("packet", packet_block())?,
        named("telecommands", telecommands_block(&db))?,
        named("functions", functions_block(&db))?,
        named("telemetry", telemetry_block(&db))?,
        named("events", events_block(&db))?,
        named("boot-flags", boot_flags_block())?,
        named("reset-causes", reset_causes_block())?,
        named("table-image", table_image_block(&db))?,
        named("parameters", parameters_block())?,
        named("housekeeping", housekeeping_block())?,
        named("controller-states", controller_states_block())?,
        named("fault-flags", fault_flags_block())?,
        named("refusal-bits", refusal_bits_block())?,
        named("failure-codes", failure_codes_block(&db))?,
        named("nested-codes", nested_codes_block(&db))?,
    ])
}

/// Where each block's text is in `doc`: (block index, first line after BEGIN, END line).
fn locate(doc: &[&str], blocks: &[Block]) -> Result<Vec<(usize, usize, usize)>, String> {
    let mut found = Vec::new();
    let mut i = 0;
    while i < doc.len() {
        let line = doc[i];
        if let Some(rest) = line.strip_prefix(BEGIN_PREFIX) {
            let name = rest.split([' ', '(']).next().unwrap_or("");
            let k = blocks
                .iter()
                .position(|b| b.name == name)
                .ok_or_else(|| format!("line {}: no generated block is called {name:?}", i + 1))?;
            if line != begin_marker(name) {
                return Err(format!(
                    "line {}: the marker should read {:?}",
                    i + 1,
                    begin_marker(name)
                ));
            }
            let end = end_marker(name);
            let close = doc[i + 1..]
                .iter()
                .position(|l| l.starts_with(BEGIN_PREFIX) || l.starts_with("<!-- END GENERATED"))
                .map(|p| i + 1 + p)
                .filter(|&p| doc[p] == end)
                .ok_or_else(|| {
                    format!(
                        "line {}: block {name} has no {end:?} before the next marker",
                        i + 1
                    )
                })?;
            if found.iter().any(|(b, _, _)| *b == k) {
                return Err(format!("line {}: block {name} appears twice", i + 1));
            }
            found.push((k, i + 1, close));
            i = close + 1;
        } else if line.starts_with("<!-- END GENERATED") {
            return Err(format!("line {}: {line:?} without its BEGIN marker", i + 1));
        } else {
            i += 1;
        }
    }
    let missing: Vec<&str> = blocks
        .iter()
        .enumerate()
        .filter(|(k, _)| !found.iter().any(|(b, _, _)| b == k))
        .map(|(_, b)| b.name)
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "no markers for block(s) {missing:?}: put {:?} and {:?} around where each goes",
            begin_marker("NAME"),
            end_marker("NAME")
        ));
    }
    Ok(found)
}

fn lines(text: &str) -> Vec<&str> {
    text.split('\n').collect()
}

/// `doc` with every generated block replaced by `blocks`' text; everything outside the
/// markers is kept byte for byte.
pub fn splice(doc: &str, blocks: &[Block]) -> Result<String, String> {
    let src = lines(doc);
    let found = locate(&src, blocks)?;
    let mut out: Vec<String> = Vec::new();
    let mut at = 0;
    let mut order = found.clone();
    order.sort_by_key(|(_, start, _)| *start);
    for (k, start, end) in order {
        out.extend(src[at..start].iter().map(|l| l.to_string()));
        out.extend(blocks[k].text.lines().map(str::to_string));
        at = end;
    }
    out.extend(src[at..].iter().map(|l| l.to_string()));
    Ok(out.join("\n"))
}

/// `doc` with its generated blocks generated from the code.
pub fn regenerate(doc: &str) -> Result<String, String> {
    splice(doc, &blocks()?)
}

/// One block of a document that differs from the code.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Drift {
    /// Block name.
    pub name: &'static str,
    /// Line diff: `-` the document's, `+` the generated.
    pub diff: String,
}

/// The blocks of `doc` that differ from the generated ones.
pub fn drift(doc: &str) -> Result<Vec<Drift>, String> {
    let blocks = blocks()?;
    let src = lines(doc);
    let found = locate(&src, &blocks)?;
    let mut out = Vec::new();
    for (k, start, end) in found {
        let have = src[start..end].join("\n");
        let want = blocks[k].text.trim_end_matches('\n');
        if have != want {
            out.push(Drift {
                name: blocks[k].name,
                diff: line_diff(&have, want),
            });
        }
    }
    out.sort_by_key(|d| blocks.iter().position(|b| b.name == d.name));
    Ok(out)
}

/// What `m2ground icd-tables --check` and the test print for a drifted document.
pub fn drift_report(path: &str, drift: &[Drift]) -> String {
    let names: Vec<&str> = drift.iter().map(|d| d.name).collect();
    let mut out = format!(
        "{path}: generated table(s) {} differ from the code; regenerate them with \
         `cargo run --features host --bin m2ground -- icd-tables --write {path}`\n",
        names.join(", ")
    );
    for d in drift {
        out.push_str(&format!(
            "--- {path} [{}]\n+++ generated [{}]\n{}",
            d.name, d.name, d.diff
        ));
    }
    out
}

/// A line diff (longest common subsequence): `-` lines only in `a`, `+` only in `b`,
/// two lines of context around each change.
pub fn line_diff(a: &str, b: &str) -> String {
    let a: Vec<&str> = a.lines().collect();
    let b: Vec<&str> = b.lines().collect();
    let (n, m) = (a.len(), b.len());
    let mut lcs = vec![vec![0usize; m + 1]; n + 1];
    for i in (0..n).rev() {
        for j in (0..m).rev() {
            lcs[i][j] = if a[i] == b[j] {
                lcs[i + 1][j + 1] + 1
            } else {
                lcs[i + 1][j].max(lcs[i][j + 1])
            };
        }
    }
    let mut ops: Vec<(char, &str)> = Vec::new();
    let (mut i, mut j) = (0, 0);
    while i < n || j < m {
        if i < n && j < m && a[i] == b[j] {
            ops.push((' ', a[i]));
            i += 1;
            j += 1;
        } else if i < n && (j == m || lcs[i + 1][j] >= lcs[i][j + 1]) {
            ops.push(('-', a[i]));
            i += 1;
        } else {
            ops.push(('+', b[j]));
            j += 1;
        }
    }
    const CONTEXT: usize = 2;
    let changed: Vec<usize> = ops
        .iter()
        .enumerate()
        .filter(|(_, (c, _))| *c != ' ')
        .map(|(k, _)| k)
        .collect();
    let near = |k: usize| changed.iter().any(|&c| c.abs_diff(k) <= CONTEXT);
    let mut out = String::new();
    let mut skipped = false;
    for (k, (c, l)) in ops.iter().enumerate() {
        if near(k) {
            if skipped {
                out.push_str("  ...\n");
                skipped = false;
            }
            out.push_str(&format!("{c} {l}\n"));
        } else {
            skipped = true;
        }
    }
    out
}
