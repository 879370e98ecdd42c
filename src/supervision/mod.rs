//! Supervision: per-cycle encoder checks, fault flags, latch and clear rules.
//!
//! * [`flags`]: [`FaultFlags`], the telemetry word (stable bit layout).
//! * [`config`](mod@config): [`SupervisionConfig`] from the parameter table plus named
//!   defaults for what the table does not store.
//! * [`supervisor`]: [`Supervisor::check`] once per cycle ([`CycleInputs`] ->
//!   [`Verdict`]); the conditions, debounce counts and detection latencies are tabulated
//!   there.
//!
//! Nothing here allocates or panics; the per-cycle check is a few hundred instructions.

pub mod config;
pub mod flags;
pub mod supervisor;

pub use config::{Debounce, SupervisionConfig};
pub use flags::FaultFlags;
pub use supervisor::{CycleInputs, Supervisor, Verdict, ALL_LEGS};
