//! The adversary: single-bit RAM upsets (parameters, table, geometry, supervision
//! thresholds, derived settings, output limits), plant faults (encoders, drives,
//! sliders, end-of-travel switches) and the operator's repairs of them, power cuts (now,
//! or armed to strike inside a flash write) and the reboot they cause.

use crate::kinematics::LEGS;
use crate::sim::{InjectedFault, SwitchEnd};
use crate::table::mock_flash::TearMode;

use super::{Choices, Soak};

impl<C: Choices> Soak<C> {
    /// One RAM bit flipped, as a radiation upset would: the parameters in force or
    /// their check word, the running table, its geometry, the supervision thresholds,
    /// the derived settings or the output stage's limits.
    pub(super) fn upset(&mut self) {
        let bit = self.below(32) as u32;
        let which = self.below(7);
        let k = self.below(64);
        let flip32 = |x: &mut f32| *x = f32::from_bits(x.to_bits() ^ (1 << bit));
        let flip64 =
            |x: &mut f64| *x = f64::from_bits(x.to_bits() ^ (1u64 << (bit + 32 * (k as u32 & 1))));
        self.upsets += 1;
        self.note(format!(
            "upset: target {which} index {k} bit {bit} (state {:?}, job {})",
            self.r.ctl.state(),
            self.r.ctl.housekeeping().job
        ));
        match which {
            0 => self.r.ctl.upset_parameters(k % 21, bit),
            1 => self.r.ctl.upset(|a, _| {
                let leg = &mut a.geom.legs[k % LEGS];
                match k / LEGS % 6 {
                    0 => flip32(&mut leg.d0_mm[k % 3]),
                    1 => flip32(&mut leg.two_d0_xy_mm[k % 2]),
                    2 => flip32(&mut leg.d0z_sq_mm2),
                    3 => flip32(&mut leg.inv_two_d0z_per_mm),
                    4 => flip32(&mut leg.b_mm[k % 3]),
                    _ => flip32(&mut leg.rod_mm),
                }
            }),
            2 => self.r.ctl.upset(|a, _| match k % 3 {
                0 => flip64(&mut a.table.p0_mm[k % 3]),
                1 => flip64(&mut a.table.legs[k % LEGS].a_mm[k % 3]),
                _ => flip64(&mut a.table.stroke_limits.max_mm[k % LEGS]),
            }),
            3 => self.r.ctl.upset(|_, c| match k % 3 {
                0 => flip32(&mut c.following_fault_mm),
                1 => flip32(&mut c.jump_mm_per_cycle),
                _ => flip32(&mut c.following_warning_mm),
            }),
            4 => self.r.ctl.upset_ops(|o| match k % 3 {
                0 => flip32(&mut o.motion.max_speed_mm_per_s[k % LEGS]),
                1 => flip32(&mut o.motion.max_accel_mm_per_s2[k % LEGS]),
                _ => flip32(&mut o.direct.0),
            }),
            5 => self.r.ctl.upset_output_limits(k % 8, bit),
            _ => self
                .r
                .ctl
                .upset(|a, _| flip64(&mut a.table.workspace.translation_mm[k % 3])),
        }
    }

    /// Maintenance at rest: the plant's faults repaired, a drive that missed steps
    /// re-referenced (its count and setpoint shifted to where its slider is). What the
    /// drives hold changed without a command, so the continuity checks of the next cycle
    /// start from what they hold now (the 10-minute run flagged the first setpoint of a
    /// recovery move, correctly taken from the re-referenced drive, as a 74.7 um step
    /// from the count before the repair).
    pub(super) fn repair(&mut self) {
        self.r.plant.with(|p| p.clear_faults());
        self.note("plant repaired".into());
        self.repaired = true;
        self.prev_drives = self.r.plant.with(|p| p.drive_setpoints_mm());
        self.prev_positions = self.r.plant.with(|p| p.drive_positions_mm());
    }

    pub(super) fn inject_fault(&mut self) {
        let leg = self.below(6) as u8;
        let end = if self.below(2) == 0 {
            SwitchEnd::Lower
        } else {
            SwitchEnd::Upper
        };
        let f = match self.below(12) {
            0 => InjectedFault::EncoderNoResponse { leg },
            1 => InjectedFault::EncoderCorrupted { leg },
            2 => InjectedFault::EncoderJump {
                leg,
                jump_mm: self.rng.sym() * 0.5,
            },
            3 => InjectedFault::EncoderStuck { leg },
            4 => InjectedFault::MissedSteps {
                leg,
                lost_mm: self.rng.sym() * 0.1,
            },
            5 => InjectedFault::StuckSlider { leg },
            6 => InjectedFault::NoiseBurst {
                leg,
                sigma_mm: 0.05,
            },
            7 => InjectedFault::DriveFault { leg },
            8 => {
                // Into the path: up to 1 mm from where the slider is now, on the side
                // of the switch (already passed if the distance is small).
                let here = self.r.plant.with(|p| p.strokes_mm())[usize::from(leg)];
                let d = 1.0 * self.uniform() - 0.05;
                let at_mm = match end {
                    SwitchEnd::Lower => here - d,
                    SwitchEnd::Upper => here + d,
                };
                InjectedFault::SwitchMisadjusted { leg, end, at_mm }
            }
            9 => InjectedFault::SwitchStuckActive { leg, end },
            10 => InjectedFault::SwitchUnreadable { leg },
            _ => InjectedFault::EncoderWarning { leg },
        };
        self.faults_injected += 1;
        if matches!(f, InjectedFault::MissedSteps { .. }) {
            // The slip itself is the fault: its cycle is not a commanded motion, nor is
            // the slider's drift after it (invariant 1).
            self.repaired = true;
            self.slipped |= 1 << leg;
        }
        self.note(format!("inject {f:?}"));
        self.r.plant.with(|p| p.inject(f));
    }

    /// A power cut now, or armed to strike inside the next flash write.
    pub(super) fn power_cut(&mut self) {
        if self.below(2) == 0 {
            let steps = self.below(3000) as u64;
            let tear = if self.below(2) == 0 {
                TearMode::Clean
            } else {
                TearMode::TornByte
            };
            self.r.flash_mut().cut_power_after(steps, tear);
        } else {
            self.reboot();
        }
    }

    pub(super) fn reboot(&mut self) {
        self.note("reboot".into());
        // Whatever was in flight dies with the controller; only the completed selection
        // (or the one being written) may run after the reboot.
        self.check_reports(true);
        self.moves.clear();
        self.watching = None;
        self.placed = None;
        self.slipped = 0;
        let candidates = std::mem::take(&mut self.selecting);
        let in_writes = !self.r.flash_mut().is_powered();
        if in_writes {
            self.cuts_in_writes += 1;
        }
        let old = std::mem::take(&mut self.r);
        self.r = old.reboot();
        self.reboots += 1;
        self.in_flight.clear();
        self.log_seen = self.r.st.log.len();
        self.r.tick();
        self.cycles += 1;
        // 6. The table it boots is the one the operator selected.
        self.check_boot(&candidates);
        self.prev_cmd = self.r.ctl.strokes_commanded_mm();
        self.prev_truth = self.r.plant.with(|p| p.strokes_mm());
        // A boot applies no compensation, holds no exposure and has released nothing.
        self.prev_applied = [0.0; LEGS];
        self.prev_hold = false;
        self.prev_released = 0;
        self.prev_drives = self.r.plant.with(|p| p.drive_setpoints_mm());
        self.prev_positions = self.r.plant.with(|p| p.drive_positions_mm());
        self.prev_state = self.r.ctl.state();
        self.prev_moving_legs = self.r.ctl.housekeeping().moving_legs;
        self.prev_faulted = !self.r.ctl.faults().is_empty();
        self.tm_dropped_seen = 0;
        self.rest_cycles = 0;
        self.corrupt_since = None;
        self.read_step_limits();
        let _ = self.check_persisted_parameters();
        self.setting.clear();
    }
}
