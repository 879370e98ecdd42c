//! The one test bench: the real controller, link service and background worker (the
//! code the firmware runs), the simulated plant, a mock NOR flash and a ground station,
//! advanced together one control cycle at a time. The host tests, the mission demo and
//! the soak all run on it.
//!
//! A [`Bench::tick`] does what one millisecond does on the target, in priority order:
//! the plant moves for one period; the control task runs [`Controller::control_cycle`];
//! the link service passes once (telecommands in, telemetry out, job messages); the
//! background worker takes [`BenchConfig::worker_steps_per_cycle`] steps. The uplink and
//! downlink carry bytes; with [`BenchConfig::uart_bytes_per_cycle`] set they carry at
//! most that many per cycle each way, as a UART would.

use std::collections::VecDeque;

use super::drive_train::{DriveTrainConfig, DriveTrainError};
use super::plant::{Plant, PlantConfig, SharedPlant};
use crate::controller::comms::{JobPort, LinkService, RxBytes, TxBytes};
use crate::controller::telemetry::{host_queue, TmConsumer, TmProducer};
use crate::controller::{Controller, JobRequest, JobResult, ResetInfo, State, Worker};
use crate::link::{Command, Housekeeping, RequestId};
use crate::nominal::PROTOTYPE;
use crate::station::Station;
use crate::table::mock_flash::MockFlash;
use crate::table::{BankLayout, TableStore, ValidationConfig};
use crate::timing::CYCLE_S;

/// Size of the simulated flash (bytes): the QEMU board's 4 MiB.
pub const SIM_FLASH_BYTES: usize = 0x40_0000;
/// Size of one table bank in the simulated flash (bytes).
pub const SIM_BANK_SIZE: u32 = 0x1_0000;
/// The simulated flash's bank layout: two banks at the top, as on the QEMU board.
pub const SIM_LAYOUT: BankLayout =
    BankLayout::two_banks(SIM_FLASH_BYTES as u32 - 2 * SIM_BANK_SIZE, SIM_BANK_SIZE);
/// Default simulated sector-erase time (control cycles): 0.3 s, a NOR sector.
pub const DEFAULT_ERASE_CYCLES: u32 = 300;
/// Default simulated program time of one 32-byte chunk (control cycles).
pub const DEFAULT_PROGRAM_CYCLES: u32 = 1;
/// Default plant seed of the bench.
pub const DEFAULT_PLANT_SEED: u64 = 11;
/// A UART at 115,200 baud, 8N1, carries 11.52 bytes per millisecond.
pub const UART_115200_BYTES_PER_CYCLE: usize = 11;
/// Bytes the simulated UART transmit queue holds (as the target's TX queue).
pub const SIM_TX_QUEUE_LEN: usize = 1024;

/// Bench settings.
#[derive(Clone, Copy, Debug)]
pub struct BenchConfig {
    /// What uploaded tables are validated against.
    pub validation: ValidationConfig,
    /// Background worker steps per control cycle.
    pub worker_steps_per_cycle: u32,
    /// Sector-erase time of the mock flash (cycles).
    pub erase_cycles: u32,
    /// Program time of one chunk (cycles).
    pub program_cycles: u32,
    /// Bytes per cycle each way on the link (`None`: unlimited).
    pub uart_bytes_per_cycle: Option<usize>,
}

impl Default for BenchConfig {
    fn default() -> Self {
        Self {
            validation: ValidationConfig::flight(),
            worker_steps_per_cycle: 1,
            erase_cycles: DEFAULT_ERASE_CYCLES,
            program_cycles: DEFAULT_PROGRAM_CYCLES,
            uart_bytes_per_cycle: None,
        }
    }
}

/// The worker as the link service's job port (on the target: two queues).
struct WorkerPort<'a> {
    worker: &'a mut Worker<MockFlash>,
    results: &'a mut VecDeque<JobResult>,
}

impl JobPort for WorkerPort<'_> {
    fn send(&mut self, request: &JobRequest) -> bool {
        self.worker.submit(request)
    }
    fn recv(&mut self) -> Option<JobResult> {
        self.results.pop_front()
    }
}

/// Bytes from the station, at most `budget` per pass.
struct Uplink<'a> {
    bytes: &'a mut VecDeque<u8>,
    budget: usize,
}

impl RxBytes for Uplink<'_> {
    fn pop(&mut self) -> Option<u8> {
        if self.budget == 0 {
            return None;
        }
        self.budget -= 1;
        self.bytes.pop_front()
    }
}

/// The UART transmit queue: whole frames in, drained toward the station at the line
/// rate (or at once without a rate).
struct Downlink<'a> {
    queue: &'a mut VecDeque<u8>,
}

impl TxBytes for Downlink<'_> {
    fn free(&self) -> usize {
        SIM_TX_QUEUE_LEN.saturating_sub(self.queue.len())
    }
    fn push(&mut self, frame: &[u8]) {
        self.queue.extend(frame.iter().copied());
    }
}

/// The controller behind the link service's lock, counting the acquisitions (on the
/// target each is an RTIC resource lock: the architecture's figure "locks per
/// telecommand, per telemetry record").
struct Counted<'a> {
    ctl: &'a mut Controller<SharedPlant>,
    locks: &'a mut u64,
}

impl crate::controller::comms::Exclusive<Controller<SharedPlant>> for Counted<'_> {
    fn lock<R>(&mut self, f: impl FnOnce(&mut Controller<SharedPlant>) -> R) -> R {
        *self.locks += 1;
        f(self.ctl)
    }
}

/// Controller + plant + flash + ground station (module documentation).
pub struct Bench {
    /// The controller.
    pub ctl: Controller<SharedPlant>,
    /// The plant (the controller owns its own handle as its hardware).
    pub plant: SharedPlant,
    /// The background worker (owns the flash).
    pub worker: Worker<MockFlash>,
    /// The link service.
    pub link: LinkService,
    /// The ground station.
    pub st: Station,
    cfg: BenchConfig,
    uplink: VecDeque<u8>,
    downlink: VecDeque<u8>,
    results: VecDeque<JobResult>,
    /// Every byte the downlink carried to the station, once [`Bench::tap_downlink`] is on.
    tap: Option<Vec<u8>>,
    /// Control cycles run since the bench was built (across reboots).
    pub cycles: u64,
    /// Locks of the controller the link service took (across reboots).
    pub locks: u64,
}

impl Default for Bench {
    fn default() -> Self {
        Self::new()
    }
}

impl Bench {
    /// The nominal mechanism (plant seed [`DEFAULT_PLANT_SEED`]), a blank flash.
    pub fn new() -> Self {
        Self::with_flash(MockFlash::new(SIM_FLASH_BYTES))
    }

    /// The nominal mechanism (plant seed [`DEFAULT_PLANT_SEED`]).
    fn nominal_plant() -> Plant {
        Plant::new(
            &PROTOTYPE,
            PlantConfig {
                seed: DEFAULT_PLANT_SEED,
                ..PlantConfig::default()
            },
        )
        .unwrap_or_else(|e| panic!("nominal geometry: {e:?}"))
    }

    /// The nominal mechanism on this drive train, a blank flash; refused as
    /// [`Plant::with_drive_train`] refuses the configuration.
    pub fn with_drive_train(train: DriveTrainConfig) -> Result<Self, DriveTrainError> {
        Ok(Self::with_plant(
            Self::nominal_plant().with_drive_train(train)?,
        ))
    }

    /// The nominal mechanism on this flash.
    pub fn with_flash(flash: MockFlash) -> Self {
        Self::build(
            Self::nominal_plant().shared(),
            flash,
            BenchConfig::default(),
            Station::new(),
            host_queue(),
        )
    }

    /// This plant, a blank flash.
    pub fn with_plant(plant: Plant) -> Self {
        Self::build(
            plant.shared(),
            MockFlash::new(SIM_FLASH_BYTES),
            BenchConfig::default(),
            Station::new(),
            host_queue(),
        )
    }

    /// Everything chosen.
    pub fn with(plant: Plant, flash: MockFlash, cfg: BenchConfig) -> Self {
        Self::build(plant.shared(), flash, cfg, Station::new(), host_queue())
    }

    fn build(
        plant: SharedPlant,
        mut flash: MockFlash,
        cfg: BenchConfig,
        st: Station,
        (producer, consumer): (TmProducer, TmConsumer),
    ) -> Self {
        flash.set_timing(cfg.erase_cycles, cfg.program_cycles);
        let mut store = TableStore::new(flash, SIM_LAYOUT)
            .unwrap_or_else(|(_, e)| panic!("simulated flash layout: {e:?}"));
        let (table, boot) = store.boot(&cfg.validation);
        // The drives come up holding where they are.
        plant.with(crate::hw::SliderDrives::hold);
        let mut ctl = Controller::new(plant.clone(), table, boot, producer);
        ctl.restore_parameters(&store.parameters());
        Self {
            ctl,
            plant,
            worker: Worker::new(store, cfg.validation),
            link: LinkService::new(consumer),
            st,
            cfg,
            uplink: VecDeque::new(),
            downlink: VecDeque::new(),
            results: VecDeque::new(),
            tap: None,
            cycles: 0,
            locks: 0,
        }
    }

    /// Sets the reset information the board would give (before the first tick).
    pub fn set_reset_info(&mut self, info: ResetInfo) {
        self.ctl.set_reset_info(info);
    }

    /// One millisecond (module documentation): the plant moves, then one period
    /// (`crate::pass`).
    pub fn tick(&mut self) {
        self.plant.with(|p| p.step(f64::from(CYCLE_S)));
        crate::pass::period(self);
        self.cycles += 1;
    }

    /// The link service's pass (what runs below the control task each cycle).
    fn link_pass(&mut self) {
        let budget = self.cfg.uart_bytes_per_cycle.unwrap_or(usize::MAX);
        let mut rx = Uplink {
            bytes: &mut self.uplink,
            budget,
        };
        let mut ctl = Counted {
            ctl: &mut self.ctl,
            locks: &mut self.locks,
        };
        let mut port = WorkerPort {
            worker: &mut self.worker,
            results: &mut self.results,
        };
        let mut tx = Downlink {
            queue: &mut self.downlink,
        };
        self.link.pass(&mut ctl, &mut rx, &mut port, &mut tx);
        // The line carries the queued bytes to the station.
        let n = budget.min(self.downlink.len());
        let bytes: Vec<u8> = self.downlink.drain(..n).collect();
        if let Some(tap) = &mut self.tap {
            tap.extend_from_slice(&bytes);
        }
        self.st.receive(&bytes);
    }

    /// From now on, records every byte the downlink carries to the station (the frames
    /// as the station receives them): [`Bench::downlink_tapped`].
    pub fn tap_downlink(&mut self) {
        self.tap.get_or_insert_with(Vec::new);
    }

    /// The downlink bytes recorded since [`Bench::tap_downlink`] (empty if not tapped).
    pub fn downlink_tapped(&self) -> &[u8] {
        self.tap.as_deref().unwrap_or(&[])
    }

    /// Runs `cycles` ticks.
    pub fn run(&mut self, cycles: u32) {
        for _ in 0..cycles {
            self.tick();
        }
    }

    /// Puts raw bytes on the uplink (as the ground's UART would send them).
    pub fn uplink_bytes(&mut self, bytes: &[u8]) {
        self.uplink.extend(bytes.iter().copied());
    }

    /// Bytes still waiting on the uplink.
    pub fn uplink_len(&self) -> usize {
        self.uplink.len()
    }

    /// Frames a telecommand onto the uplink and runs one cycle; returns its request ID.
    pub fn send(&mut self, cmd: &Command) -> RequestId {
        let rid = self.queue(cmd);
        self.tick();
        rid
    }

    /// Frames a telecommand onto the uplink without running a cycle.
    pub fn queue(&mut self, cmd: &Command) -> RequestId {
        let (frame, rid) = self
            .st
            .frame(cmd)
            .unwrap_or_else(|e| panic!("encode {cmd:?}: {e}"));
        self.uplink_bytes(&frame);
        rid
    }

    /// Sends a telecommand and runs until its completion (success or failure) or a
    /// start/acceptance failure, at most `max` cycles; returns its reports.
    pub fn command(&mut self, cmd: &Command, max: u32) -> Vec<crate::link::tm::Verification> {
        let rid = self.send(cmd);
        for _ in 0..max {
            if self.st.finished(rid) {
                break;
            }
            self.tick();
        }
        self.st.reports(rid)
    }

    /// Runs until the controller is at rest (idle or faulted), no table job runs and
    /// the sliders have settled, at most `max` cycles; returns the cycles run, or
    /// `None` if it never settled.
    pub fn try_settle(&mut self, max: u32) -> Option<u32> {
        for n in 0..max {
            self.tick();
            let h = self.ctl.housekeeping();
            if matches!(self.ctl.state(), State::Idle | State::Faulted)
                && h.job == 0
                && self.plant.with(|p| p.settled())
            {
                return Some(n);
            }
        }
        None
    }

    /// As [`Bench::try_settle`], panicking if it never settles (tests).
    pub fn settle(&mut self, max: u32) -> u32 {
        self.try_settle(max).unwrap_or_else(|| {
            panic!(
                "not settled after {max} cycles, state {:?}",
                self.ctl.state()
            )
        })
    }

    /// A one-shot housekeeping report, as the ground receives it.
    pub fn hk(&mut self) -> Housekeeping {
        let rid = self.send(&Command::HousekeepingOneShot);
        for _ in 0..1000 {
            if self.st.finished(rid) {
                break;
            }
            self.tick();
        }
        self.st
            .last_hk()
            .unwrap_or_else(|| panic!("no housekeeping received"))
    }

    /// The flash (power cuts, bit flips).
    pub fn flash_mut(&mut self) -> &mut MockFlash {
        self.worker.store_mut().flash_mut()
    }

    /// Power cycle: the controller and the worker restart from what the flash holds
    /// now (power restored); the plant keeps its sliders where they are; the station
    /// keeps its log.
    pub fn reboot(self) -> Self {
        let Bench {
            ctl,
            link,
            plant,
            worker,
            st,
            cfg,
            cycles,
            locks,
            ..
        } = self;
        // The telemetry queue's storage outlives the controller: its halves are handed
        // to the next ones, emptied (what was queued at the cut is lost).
        let queue = (ctl.into_tm_producer(), link.into_queue());
        let mut flash = worker.into_store().into_inner();
        flash.power_cycle();
        let mut b = Self::build(plant, flash, cfg, st, queue);
        b.cycles = cycles;
        b.locks = locks;
        b
    }
}

impl crate::pass::Period for Bench {
    fn control(&mut self) {
        self.ctl.control_cycle();
    }

    fn link(&mut self) {
        self.link_pass();
    }

    fn worker(&mut self) {
        for _ in 0..self.cfg.worker_steps_per_cycle {
            if let Some(r) = self.worker.step(self.ctl.cycle()) {
                self.results.push_back(r);
            }
        }
    }
}
