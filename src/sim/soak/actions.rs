//! The random operator actions: valid and invalid telecommands (moves, direct strokes,
//! stops and clears, table uploads good and bad, selections, parameter sets, dumps),
//! garbage on the line, and the choice of the adversary's turns (`injection`). Every
//! telecommand sent is recorded for the report check (`verification`).

use crate::controller::State;
use crate::link::command::WirePose;
use crate::link::tm::dump_chunks;
use crate::link::{Command, MemoryId, RequestId, TableChunk};
use crate::table::Table;

use super::{Choices, Soak};

/// A plausible calibrated table: nominal joints moved by tens of micrometres.
pub fn calibrated_table(id: u32) -> Table {
    let mut t = Table::nominal();
    t.table_id = id;
    for (i, leg) in t.legs.iter_mut().enumerate() {
        leg.a_mm[0] += 0.01 * i as f64;
        leg.b_mm[1] -= 0.02;
    }
    t
}

impl<C: Choices> Soak<C> {
    fn send(&mut self, cmd: &Command) -> RequestId {
        if !matches!(cmd, Command::LoadTableChunk(_)) {
            self.note(format!("TC {cmd:?} in state {:?}", self.r.ctl.state()));
        }
        let from = self.r.st.log.len();
        let rid = self.r.queue(cmd);
        self.tcs_sent += 1;
        self.in_flight.push((rid, from));
        rid
    }

    /// A random pose inside (mostly), near or outside the +-2 mm / +-600" workspace.
    fn pose(&mut self) -> WirePose {
        let scale = match self.below(10) {
            0 => 1.3,
            1 => 1.02,
            _ => 0.6,
        };
        let mut v = [0i32; 6];
        for k in 0..6 {
            let r = self.rng.sym() * scale;
            v[k] = if k < 3 {
                (r * 2.0e6) as i32
            } else {
                (r * 600.0e6) as i32
            };
        }
        WirePose::from_array(v)
    }

    fn small_delta(&mut self) -> WirePose {
        let mut v = [0i32; 6];
        for k in 0..6 {
            let r = self.rng.sym();
            v[k] = if k < 3 {
                (r * 0.3e6) as i32
            } else {
                (r * 60.0e6) as i32
            };
        }
        WirePose::from_array(v)
    }

    /// A table to upload: plausible (known afterwards) or one the controller must refuse.
    fn table(&mut self, good: bool) -> Table {
        let id = 10 + self.below(1000) as u32;
        let mut t = calibrated_table(id);
        // The plant's thermal model (the compensation has something to follow).
        t.thermal = crate::sim::thermal::Coefficients::NOMINAL.model();
        t.legs[self.below(6)].b_mm[self.below(3)] += self.rng.sym() * 0.05;
        if !good {
            match self.below(3) {
                0 => t.p0_mm[0] = f64::NAN,
                1 => t.legs[2].a_mm[1] += 5.0,
                _ => {
                    t.stroke_limits.min_mm = [-0.4; 6];
                    t.stroke_limits.max_mm = [0.4; 6];
                }
            }
        }
        t
    }

    fn upload(&mut self, t: &Table, corrupt_crc: bool, skip_chunk: bool) {
        let bytes = t.to_bytes();
        let chunks: Vec<(u16, Vec<u8>)> =
            dump_chunks(&bytes).map(|(o, b)| (o, b.to_vec())).collect();
        let skip = if skip_chunk {
            Some(self.below(chunks.len()))
        } else {
            None
        };
        for (i, (off, data)) in chunks.iter().enumerate() {
            if Some(i) != skip {
                self.send(&Command::LoadTableChunk(
                    TableChunk::new(*off, data).unwrap(),
                ));
            }
        }
        let crc = if corrupt_crc {
            t.crc32() ^ 0x10
        } else {
            t.crc32()
        };
        self.send(&Command::CommitTable { crc32: crc });
    }

    /// One random operator (or adversary) action.
    pub fn act(&mut self) {
        let pending = self.r.ctl.pending_table();
        match self.below(32) {
            31 => self.set_thermal_parameters(),
            26 => {
                // An exposure hold of 1 to 3 s (one time in eight), or its end.
                let timeout_s = if self.below(8) == 0 {
                    1 + self.below(3) as u16
                } else {
                    0
                };
                self.send(&Command::ExposureHold { timeout_s });
            }
            // The camera's discrete input raised (one time in eight) for an exposure of
            // 0.1 to 3 s.
            27 if self.below(8) == 0 => {
                let cycles = 100 + self.below(2_901) as u64;
                self.note(format!("exposure input raised for {cycles} cycles"));
                self.r.plant.with(|p| p.set_exposing(true));
                self.input_release_at = Some(self.cycles + cycles);
            }
            27 => {}
            28 => self.set_thermal_parameters(),
            29 => self.sensor_failure(),
            30 => {
                // A small move scheduled 0.2..3 s ahead (an exposure hold may hold it).
                let d = self.small_delta();
                let ahead_s = 0.2 + 2.8 * self.uniform();
                let cycle = self.r.ctl.cycle();
                let at = crate::controller::schedule::obt_of_cycle(
                    cycle
                        .wrapping_add((ahead_s * f64::from(crate::timing::CONTROL_RATE_HZ)) as u32),
                );
                if let Ok((cmd, _)) = self.r.st.schedule_insert(&[(at, Command::MoveRelative(d))]) {
                    self.send(&cmd);
                }
            }
            23 => self.set_parameters(),
            24 | 25 => self.upset(),
            0..=4 => {
                let p = self.pose();
                self.send_move(&Command::MoveAbsolute(p));
            }
            5 | 6 => {
                let d = self.small_delta();
                self.send_move(&Command::MoveRelative(d));
            }
            7 => {
                self.send(&Command::Stop);
            }
            8 => {
                // The operator repairs what the fault report points at, then clears.
                if self.below(2) == 0 && matches!(self.r.ctl.state(), State::Faulted) {
                    self.repair();
                }
                self.send(&Command::ClearFault);
            }
            9 | 10 => {
                let leg = 1 + self.below(6) as u8;
                let delta_nm = (self.rng.sym() * 0.2e6) as i32;
                self.send(&Command::DirectStroke { leg, delta_nm });
            }
            11 => {
                let t = self.table(true);
                self.known.insert(t.crc32(), t);
                self.upload(&t, false, false);
            }
            12 => {
                let t = self.table(false);
                self.upload(&t, false, false);
            }
            13 => {
                // A plausible table uploaded badly; the upload buffer keeps its bytes, so a
                // later upload may complete it legitimately: it is a known table.
                let t = self.table(true);
                self.known.insert(t.crc32(), t);
                let (bad_crc, skip) = (self.below(2) == 0, self.below(2) == 0);
                self.upload(&t, bad_crc, skip || !bad_crc);
            }
            14 | 15 => {
                // Activate the pending table by name, or a wrong name.
                let (cmd, crc) = match pending {
                    Some(p) if self.below(4) != 0 => (
                        Command::ActivateTable {
                            table_id: p.table_id,
                            crc32: p.report.table_crc,
                        },
                        p.report.table_crc,
                    ),
                    _ => {
                        let crc = self.below(1 << 30) as u32;
                        (
                            Command::ActivateTable {
                                table_id: self.below(50) as u32,
                                crc32: crc,
                            },
                            crc,
                        )
                    }
                };
                let rid = self.send(&cmd);
                self.selecting.push((rid, Some(crc)));
            }
            16 => {
                let rid = self.send(&Command::SwitchBank);
                self.selecting.push((rid, None));
            }
            17 => {
                let rid = self.send(&Command::RevertToNominal);
                self.selecting.push((rid, Some(Table::nominal().crc32())));
            }
            18 => {
                let cmd = match self.below(4) {
                    0 => Command::Ping,
                    1 => Command::HousekeepingOneShot,
                    2 => Command::DumpTable(MemoryId::ActiveTable),
                    _ => Command::DumpTable(MemoryId::UploadBuffer),
                };
                self.send(&cmd);
            }
            19 => {
                // Garbage on the line, or a packet with a bad CRC.
                if self.below(2) == 0 {
                    let n = 1 + self.below(80);
                    let g: Vec<u8> = (0..n).map(|_| self.below(256) as u8).collect();
                    self.r.uplink_bytes(&g);
                } else {
                    let from = self.r.st.log.len();
                    let (mut p, rid) = self.r.st.packet(&Command::Ping).unwrap();
                    let last = p.len() - 1;
                    p[last] ^= 0x40;
                    self.r.uplink_bytes(&crate::station::frame(&p));
                    self.tcs_sent += 1;
                    self.in_flight.push((rid, from));
                }
            }
            20 => self.inject_fault(),
            // Repairs (re-referencing a drive that missed steps) are maintenance at rest:
            // a drive does not re-reference itself in the middle of a motion.
            21 => {
                if matches!(self.r.ctl.state(), State::Idle | State::Faulted) {
                    self.repair();
                }
            }
            _ => self.power_cut(),
        }
    }

    /// A coordinated move sent: its completion is checked (invariant 11); sent while
    /// idle, it may be watched to its end ([`super::WATCH_ONE_IN`], not by a fuzz
    /// input: [`Choices::watches_moves`]). Its reports come after where the station's
    /// log stands now.
    fn send_move(&mut self, cmd: &Command) {
        let from = self.r.st.log.len();
        let rid = self.send(cmd);
        self.moves.push((rid, from));
        if self.rng.watches_moves()
            && self.r.ctl.state() == State::Idle
            && self.below(super::WATCH_ONE_IN) == 0
        {
            self.watching = Some((rid, from));
            self.moves_watched += 1;
        }
    }

    /// A TC[20,3] of the thermal compensation: enable or disable, and steps (valid, or
    /// a dead band above the step: refused with 0x0724).
    fn set_thermal_parameters(&mut self) {
        use crate::controller::params::{index, PARAMETERS};
        let id = |k: usize| PARAMETERS[k].id;
        let mut pairs = vec![(id(index::THERMAL_ENABLE), (self.below(4) != 0) as i32)];
        if self.below(3) == 0 {
            let max_nm = 50 + self.below(4_951) as i32;
            pairs.push((id(index::THERMAL_MAX_STEP), max_nm));
            pairs.push((id(index::THERMAL_MIN_STEP), 5 + self.below(1_000) as i32));
        }
        let Ok(values) = crate::link::command::ParameterValues::new(&pairs) else {
            return;
        };
        let rid = self.send(&Command::SetParameters(values));
        self.setting.push((rid, pairs));
    }

    /// A temperature sensor fails (open, short, stuck), or every sensor recovers.
    fn sensor_failure(&mut self) {
        use crate::sim::thermal::SensorFailure;
        let ch = self.below(crate::thermal::TEMP_SENSORS);
        let f = match self.below(6) {
            0 => Some(SensorFailure::Open),
            1 => Some(SensorFailure::Short),
            2 => Some(SensorFailure::Stuck),
            _ => None,
        };
        self.note(format!("sensor {ch}: {f:?}"));
        self.r.plant.with(|p| match f {
            Some(f) => p.thermal_mut().inject(ch, f),
            None => p.thermal_mut().clear_failures(),
        });
    }

    /// A valid TC[20,3]: speeds and accelerations within the defaults (so invariant 2's
    /// bound stays an upper bound), a pivot, the housekeeping period.
    fn set_parameters(&mut self) {
        let mut pairs = Vec::new();
        if self.below(2) == 0 {
            pairs.push((0x0010, 50_000 + self.below(150_001) as i32));
        }
        if self.below(2) == 0 {
            pairs.push((0x0011, 200_000 + self.below(800_001) as i32));
        }
        if self.below(2) == 0 {
            pairs.push((0x0012, 10_000 + self.below(40_001) as i32));
        }
        if self.below(2) == 0 || pairs.is_empty() {
            pairs.push((0x0003, (self.rng.sym() * 300e6) as i32));
        }
        if self.below(4) == 0 {
            pairs.push((0x0020, 500 + self.below(1_500) as i32));
        }
        let values = crate::link::command::ParameterValues::new(&pairs);
        let Ok(values) = values else { return };
        let rid = self.send(&Command::SetParameters(values));
        self.setting.push((rid, pairs));
    }
}
