//! ICD section 6: the housekeeping report, the controller states, the fault flags and
//! the refusal bits.

use super::markdown::{bits_span, paragraph, table, Align};
use crate::mdb::{self, hex4, Field, Wire};
use m2ctl::controller::event;
use m2ctl::kinematics::{Refusals, LEGS};
use m2ctl::link::hk::HK_REPORT_LEN;

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

pub(super) fn housekeeping_block() -> Result<String, String> {
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

pub(super) fn controller_states_block() -> Result<String, String> {
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

pub(super) fn fault_flags_block() -> Result<String, String> {
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

pub(super) fn refusal_bits_block() -> Result<String, String> {
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
