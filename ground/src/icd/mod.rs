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
//!
//! The parts, one job each (their public items re-exported here): `markdown` (tables and
//! wrapped prose), one file per ICD section group (`packets`, `telemetry`, `table`,
//! `housekeeping`, `failures`), `document` (markers, splicing, drift) and `diff`.

mod diff;
mod document;
mod failures;
mod housekeeping;
mod markdown;
mod packets;
mod table;
mod telemetry;

pub use diff::line_diff;
pub use document::{begin_marker, drift, drift_report, end_marker, regenerate, splice, Drift};

use crate::mdb;
use failures::{failure_codes_block, nested_codes_block};
use housekeeping::{
    controller_states_block, fault_flags_block, housekeeping_block, refusal_bits_block,
};
use packets::{functions_block, packet_block, telecommands_block};
use table::{parameters_block, table_image_block};
use telemetry::{boot_flags_block, events_block, reset_causes_block, telemetry_block};

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
