//! ICD section 5: the table image and (5a) the parameters it holds.

use super::markdown::{table, Align};
use crate::mdb::{self, hex4, thousands, Mdb};
use m2ctl::controller::params::PARAMETERS;
use m2ctl::table::layout::TABLE_CRC_OFFSET;
use m2ctl::table::TABLE_LEN;

pub(super) fn table_image_block(db: &Mdb) -> Result<String, String> {
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

pub(super) fn parameters_block() -> Result<String, String> {
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
