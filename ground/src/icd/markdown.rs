//! The markdown the generated blocks are made of: tables with aligned columns, wrapped
//! paragraphs, the `a..b` notation of bit and byte ranges and the `[service,subtype]`
//! label of a packet type.

/// Column alignment of a table.
#[derive(Clone, Copy)]
pub(super) enum Align {
    Left,
    Right,
}

/// A markdown table: header, separator, rows (a `|` in a cell is escaped).
pub(super) fn table(header: &[(&str, Align)], rows: &[Vec<String>]) -> Result<String, String> {
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
pub(super) fn paragraph(text: &str) -> String {
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
pub(super) fn span(first: u32, last: u32) -> String {
    if first == last {
        format!("{first}")
    } else {
        format!("{first}..{last}")
    }
}

/// The first and last bit of a contiguous bit group `word` (an error if it is empty or
/// has a gap).
pub(super) fn bits_span(word: u32) -> Result<(u32, u32), String> {
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

/// `[service,subtype]` of a packet type, `[service,a..b]` for a run of subtypes.
pub(super) fn tc_label(service: u8, subtypes: &[u8]) -> String {
    let sub = match (subtypes.first(), subtypes.last()) {
        (Some(a), Some(b)) if a != b => format!("{a}..{b}"),
        (Some(a), _) => format!("{a}"),
        _ => String::new(),
    };
    format!("[{service},{sub}]")
}
