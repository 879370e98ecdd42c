//! What the operator may expect of flash: the table a boot must run (invariant 6), the
//! parameters flash may hold (invariant 9), and the speed limits in force that
//! invariant 8 checks against.

use crate::link::RequestId;
use crate::motion::CYCLE_S;
use crate::table::Table;

use super::{Choices, Soak};

/// What the soak knows the controller should run after a reboot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct TableRef {
    pub(super) id: u32,
    pub(super) crc: u32,
}

impl TableRef {
    pub(super) fn of(t: &Table) -> Self {
        Self {
            id: t.table_id,
            crc: t.crc32(),
        }
    }
}

impl<C: Choices> Soak<C> {
    /// Invariant 6, after a reboot: the running table is the last completed selection,
    /// or one of `candidates` (the selections in flight at the cut, whose record may
    /// have been written), never a table nobody uploaded. Adopts a written candidate.
    pub(super) fn check_boot(&mut self, candidates: &[(RequestId, Option<u32>)]) {
        let running = TableRef {
            id: self.r.ctl.active_table().table_id,
            crc: self.r.ctl.active_table().crc32(),
        };
        if !self.known.contains_key(&running.crc) {
            self.violation(format!("booted an unknown table {running:?}"));
        }
        if running != self.selected {
            // A selection telecommand whose job may have persisted its record before the
            // reboot, its completion report not yet on the ground.
            let written = candidates
                .iter()
                .any(|(_, crc)| crc.is_none_or(|c| c == running.crc));
            if written {
                // The selection being written reached its commit point before the cut.
                self.selected = running;
            } else {
                self.violation(format!(
                    "booted {running:?}, the last completed selection was {:?}",
                    self.selected
                ));
            }
        }
    }

    pub(super) fn read_step_limits(&mut self) {
        let l = self
            .r
            .ctl
            .parameters()
            .step_limits(self.r.ctl.active_table());
        let dt = f64::from(CYCLE_S);
        self.step_limits_mm = (f64::from(l.coordinated.0) * dt, f64::from(l.direct.0) * dt);
    }

    /// Invariant 9: the parameters in flash are a set the operator's telecommands made:
    /// the one known persisted, or it with the sets in flight applied in order (each
    /// may or may not have been). What flash holds then becomes the one known.
    /// Returns whether it could check (not while a cut has struck: the reboot checks
    /// again once power is back, with the sets still in flight).
    pub(super) fn check_persisted_parameters(&mut self) -> bool {
        use crate::controller::Parameters;
        if !self.r.flash_mut().is_powered() {
            return false;
        }
        let stored = self.r.worker.store_mut().persisted_parameters();
        let decoded = Parameters::decode(&stored).encode();
        // The running table as uploaded (the RAM copy may be upset).
        let crc = self.r.ctl.housekeeping().active_table_crc32;
        let table = self
            .known
            .get(&crc)
            .copied()
            .unwrap_or(*self.r.ctl.active_table());
        let mut allowed = vec![self.params_confirmed];
        for (_, pairs) in &self.setting {
            let grown: Vec<_> = allowed
                .iter()
                .filter_map(|b| Parameters::decode(b).with(pairs, &table).ok())
                .map(|p| p.encode())
                .collect();
            allowed.extend(grown);
        }
        if allowed.contains(&decoded) {
            self.params_confirmed = decoded;
        } else {
            self.violation(format!(
                "persisted parameters no telecommand made (an upset adopted?): {:?}",
                Parameters::decode(&stored)
            ));
        }
        true
    }

    /// The speed limits in force after a parameter set completed: what flash holds
    /// (invariant 9 checks it is a set the operator made), never the controller's RAM.
    pub(super) fn read_step_limits_from_model(&mut self) {
        let stored = self.r.worker.store_mut().persisted_parameters();
        let l =
            crate::controller::Parameters::decode(&stored).step_limits(self.r.ctl.active_table());
        let dt = f64::from(CYCLE_S);
        self.step_limits_mm = (f64::from(l.coordinated.0) * dt, f64::from(l.direct.0) * dt);
    }
}
