//! The generated blocks in a document: their marker lines, where they are, splicing new
//! text between the markers (everything else kept byte for byte), and the drift report.

use super::diff::line_diff;
use super::{blocks, Block, REGENERATE};

/// The line that opens block `name`.
pub fn begin_marker(name: &str) -> String {
    format!("<!-- BEGIN GENERATED: {name} ({REGENERATE}) -->")
}

/// The line that closes block `name`.
pub fn end_marker(name: &str) -> String {
    format!("<!-- END GENERATED: {name} -->")
}

const BEGIN_PREFIX: &str = "<!-- BEGIN GENERATED: ";

/// Where each block's text is in `doc`: (block index, first line after BEGIN, END line).
pub(super) fn locate(doc: &[&str], blocks: &[Block]) -> Result<Vec<(usize, usize, usize)>, String> {
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
