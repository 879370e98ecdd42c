//! ICD section 7: the failure codes and the codes nested in them.

use super::markdown::{paragraph, table, Align};
use crate::mdb::{hex4, FailureCode, Mdb, ReportedIn};
use m2ctl::link::{service, subtype};

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

pub(super) fn failure_codes_block(db: &Mdb) -> Result<String, String> {
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

pub(super) fn nested_codes_block(db: &Mdb) -> Result<String, String> {
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
