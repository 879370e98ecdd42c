//! ICD section 4: the telemetry reports, the events, the boot flags and the reset causes.

use super::markdown::{bits_span, paragraph, span, table, tc_label, Align};
use crate::mdb::{self, hex4, Mdb};
use m2ctl::controller::event;
use m2ctl::table::store::{boot_flags, BOOT_FLAGS_BANK_B_SHIFT, BOOT_FLAGS_SELECTION_SHIFT};
use m2ctl::table::BootSource;

pub(super) fn telemetry_block(db: &Mdb) -> Result<String, String> {
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

pub(super) fn events_block(db: &Mdb) -> Result<String, String> {
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

pub(super) fn boot_flags_block() -> Result<String, String> {
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

pub(super) fn reset_causes_block() -> Result<String, String> {
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
