//! The calibrated parameter table: content, binary layout, validation, A/B flash store.
//!
//! * [`layout`]: [`Table`] (joint centres, p0, limits, supervision thresholds, ID,
//!   provenance) and its versioned little-endian encoding with a CRC-32
//!   ([`Table::encode`], [`Table::decode`]).
//! * [`validate`](mod@validate): the checks a table passes before it is activated
//!   (finite, near nominal, plausible rods, whole workspace reachable within the slider
//!   limits, FK converging at the corners), with stable error codes.
//! * [`store`]: two banks in NOR flash behind `embedded-storage`'s `NorFlash`, written
//!   so that a power cut at any byte leaves the old or the new table, never a mixture;
//!   the operator's selection record (what boots), boot with a fallback to the
//!   compiled-in nominal table; non-blocking writes (a state machine polled by the
//!   background task).
//! * [`upload`]: the upload buffer that TC[6,2] chunks fill, and its commit checks.
//! * `mock_flash` (feature `host`): a NOR flash model that cuts power after any byte.
//!
//! Flow (cFS table services): a candidate is loaded into an inactive RAM buffer, decoded
//! and [`validate()`]d; the store writes it to the bank not holding the running table
//! (pending); activating it persists a selection record and switches the controller's
//! geometry to it between motions.
//!
//! Error codes for telemetry (family 0x04xx): [`TableError`] 0x0401.., [`ValidationError`]
//! 0x0410.., [`StoreError`] 0x0430...

pub mod layout;
#[cfg(feature = "host")]
pub mod mock_flash;
pub mod store;
pub mod upload;
pub mod validate;

pub use layout::{
    Provenance, SupervisionThresholds, Table, TableError, DEFAULT_SUPERVISION, TABLE_LEN,
};
pub use store::{
    Bank, BankLayout, BankStatus, BootReport, BootSource, CommitReport, FlashStatus, Selection,
    StoreError, TableStore, WriteDone, WritePoll,
};
pub use validate::{validate, Validation, ValidationConfig, ValidationError, ValidationState};
