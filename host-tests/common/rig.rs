//! The host test rig: the real controller, the simulated plant, a mock NOR flash and a
//! ground station, ticked together one control cycle at a time.
#![allow(dead_code)]

use m2ctl::controller::{Controller, ControllerConfig, State};
use m2ctl::ground::station::Station;
use m2ctl::link::{Command, RequestId};
use m2ctl::motion::CYCLE_S;
use m2ctl::nominal::PROTOTYPE;
use m2ctl::sim::{Plant, PlantConfig};
use m2ctl::table::mock_flash::MockFlash;
use m2ctl::table::{TableStore, FLIGHT_LAYOUT};

const FLASH_BYTES: usize = 0x40_0000;

pub struct Rig {
    pub ctl: Controller<Plant, MockFlash>,
    pub st: Station,
}

impl Rig {
    pub fn new() -> Rig {
        Self::with_flash(MockFlash::new(FLASH_BYTES))
    }

    pub fn with_flash(flash: MockFlash) -> Rig {
        let plant = Plant::new(
            &PROTOTYPE,
            PlantConfig {
                seed: 11,
                ..PlantConfig::default()
            },
        )
        .unwrap();
        Self::with_plant_and_flash(plant, flash)
    }

    pub fn with_plant(plant: Plant) -> Rig {
        Self::with_plant_and_flash(plant, MockFlash::new(FLASH_BYTES))
    }

    pub fn with_plant_and_flash(plant: Plant, flash: MockFlash) -> Rig {
        let store = TableStore::new(flash, FLIGHT_LAYOUT)
            .map_err(|(_, e)| e)
            .unwrap();
        let ctl = Controller::new(plant, store, ControllerConfig::default());
        Rig {
            ctl,
            st: Station::new(),
        }
    }

    /// One cycle: the plant moves for one period, then the controller ticks.
    pub fn tick(&mut self, packet: Option<&[u8]>) {
        self.ctl.mechanism_mut().step(f64::from(CYCLE_S));
        let st = &mut self.st;
        self.ctl.tick(packet, &mut |f: &[u8]| st.receive(f));
    }

    pub fn run(&mut self, cycles: u32) {
        for _ in 0..cycles {
            self.tick(None);
        }
    }

    /// Sends one telecommand (goes through the framing both ways) and runs one cycle.
    pub fn send(&mut self, cmd: &Command) -> RequestId {
        let (pkt, rid) = self.st.packet(cmd).unwrap();
        self.tick(Some(&pkt));
        rid
    }

    /// Runs until idle (or faulted) with nothing moving, at most `max` cycles.
    pub fn settle(&mut self, max: u32) -> u32 {
        for n in 0..max {
            self.tick(None);
            if matches!(self.ctl.state(), State::Idle | State::Faulted)
                && self.ctl.mechanism_mut().settled()
            {
                return n;
            }
        }
        panic!(
            "not settled after {max} cycles, state {:?}",
            self.ctl.state()
        );
    }

    pub fn hk(&mut self) -> m2ctl::link::Housekeeping {
        self.send(&Command::HousekeepingOneShot);
        self.st.last_hk().unwrap()
    }
}
