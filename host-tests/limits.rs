//! End-of-travel switches and encoder warnings, end to end (issue 11's controller side):
//! the switch read every cycle, the leg stopped in that direction in the cycle the
//! switch is seen, the fault and event in that cycle's telemetry, recovery only away
//! from the switch, the clear refused while a switch is active, unreadable inputs
//! blocking both ways, encoder warnings in housekeeping without stopping anything, and
//! the same through the real step/direction driver with embedded-hal-mock pins.
#![allow(clippy::needless_range_loop)] // index loops over six legs read clearer here

mod common;

use std::cell::RefCell;
use std::rc::Rc;

use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal_mock::eh1::digital::{
    Mock as PinMock, State as PinState, Transaction as PinTransaction,
};

use common::{all_ok, wire};
use m2ctl::controller::{event, Controller, State, TmConsumer, TmRecord};
use m2ctl::drivers::stepper::{
    StepDirDrives, StepPulses, StepperConfig, StepperLeg, StepperPolarity,
};
use m2ctl::drivers::switches::{LegSwitches, SwitchPolarity, TravelSwitchInputs};
use m2ctl::drivers::Mechanism;
use m2ctl::hw::{
    EncoderError, EncoderWarnings, IssuedStrokes, StrokeEncoders, TravelSwitches,
    ENCODER_MM_PER_COUNT,
};
use m2ctl::kinematics::{FkSolution, Pose, LEGS};
use m2ctl::link::tm::{EventSeverity, Verification};
use m2ctl::link::{Command, RequestId};
use m2ctl::sim::bench::{SIM_FLASH_BYTES, SIM_LAYOUT};
use m2ctl::sim::{Bench, InjectedFault, SwitchEnd};
use m2ctl::station::{Station, Tm};
use m2ctl::supervision::{CycleInputs, FaultFlags, SupervisionConfig, Supervisor};
use m2ctl::table::mock_flash::MockFlash;
use m2ctl::table::{TableStore, ValidationConfig};
use m2ctl::units::UM_PER_MM;

/// Failure code of a direct stroke toward an end-of-travel switch.
const TOWARD_END_OF_TRAVEL: u16 = 0x070E;
/// Failure code of a move ended by a fault.
const ABORTED_BY_FAULT: u16 = 0x0709;
/// Failure code of a refused clear.
const FAULT_PERSISTS: u16 = 0x0703;
/// Cycles a coordinated move of about a millimetre takes, with margin.
const MOVE_CYCLES: u32 = 20_000;
/// Cycles a direct stroke of some micrometres takes, with margin.
const STROKE_CYCLES: u32 = 5_000;

fn bit(leg: usize) -> u8 {
    1 << leg
}

/// The switch mask of `end` in a reading.
fn at_end(sw: &TravelSwitches, end: SwitchEnd) -> u8 {
    match end {
        SwitchEnd::Lower => sw.lower,
        SwitchEnd::Upper => sw.upper,
    }
}

/// `a` is not beyond `b` toward `end` (upper: not larger; lower: not smaller).
fn not_beyond(a: f64, b: f64, end: SwitchEnd) -> bool {
    match end {
        SwitchEnd::Upper => a <= b,
        SwitchEnd::Lower => a >= b,
    }
}

/// +1 toward the upper end, -1 toward the lower.
fn sign(end: SwitchEnd) -> i32 {
    match end {
        SwitchEnd::Upper => 1,
        SwitchEnd::Lower => -1,
    }
}

/// The END_OF_TRAVEL aux0 bit of `leg` at `end`.
fn eot_word(leg: usize, end: SwitchEnd) -> u32 {
    match end {
        SwitchEnd::Lower => 1 << leg,
        SwitchEnd::Upper => 1 << (8 + leg),
    }
}

/// Runs until `rid` has finished (or `max` cycles).
fn wait(r: &mut Bench, rid: RequestId, max: u32) -> Vec<Verification> {
    for _ in 0..max {
        if r.st.finished(rid) {
            break;
        }
        r.tick();
    }
    r.st.reports(rid)
}

/// Events received since log index `from`.
fn events_since(r: &Bench, from: usize) -> Vec<(EventSeverity, u16, [u32; 2])> {
    r.st.log[from..]
        .iter()
        .filter_map(|t| match t {
            Tm::Event(s, id, aux) => Some((*s, *id, *aux)),
            _ => None,
        })
        .collect()
}

/// What [`trip`] saw.
struct Tripped {
    r: Bench,
    /// Cycles from the move's start to the first read showing the switch.
    seen_after: u32,
    /// True slider stroke beyond the switch when it was seen (mm).
    overshoot_mm: f64,
}

/// A coordinated move of `z_um` (pure translation along z: every slider moves by about
/// the same stroke) crossing the `end` switch of `leg`, misadjusted to `at_mm`. Checks,
/// every cycle: in the first cycle whose read shows the switch, that leg's commanded
/// stroke is not beyond the previous cycle's, the fault and the END_OF_TRAVEL event are
/// in that cycle's telemetry; never afterwards while the switch is active does the
/// command or the slider move further toward it; the move ends with 0x0709.
fn trip(leg: usize, end: SwitchEnd, at_mm: f64, z_um: f64) -> Tripped {
    let mut r = Bench::new();
    r.run(2);
    r.plant.with(|p| {
        p.inject(InjectedFault::SwitchMisadjusted {
            leg: leg as u8,
            end,
            at_mm,
        })
    });
    r.run(2);
    assert!(
        r.ctl.faults().is_empty(),
        "the switch is not in the way yet"
    );
    let rid = r.send(&Command::MoveAbsolute(wire(0.0, 0.0, z_um, 0.0, 0.0, 0.0)));
    let mut seen: Option<(u32, f64)> = None;
    let mut cycles_after_rest = 0;
    for n in 1..=MOVE_CYCLES {
        let prev = r.ctl.strokes_commanded_mm();
        let log_from = r.st.log.len();
        r.tick();
        let sw = r.ctl.switches();
        let active = at_end(&sw, end) & bit(leg) != 0;
        let cmd = r.ctl.strokes_commanded_mm();
        let truth = r.plant.with(|p| p.strokes_mm())[leg];
        if active {
            assert!(
                not_beyond(f64::from(cmd[leg]), f64::from(prev[leg]), end),
                "cycle {n}: leg {} commanded {} after {} with its {end:?} switch active",
                leg + 1,
                cmd[leg],
                prev[leg]
            );
        }
        match seen {
            None if active => {
                seen = Some((n, truth));
                assert!(r.ctl.faults().contains(FaultFlags::LIMIT_SWITCH));
                let ev = events_since(&r, log_from);
                let cycle = r.ctl.cycle() - 1;
                assert!(
                    ev.contains(&(
                        EventSeverity::High,
                        event::END_OF_TRAVEL,
                        [eot_word(leg, end), cycle]
                    )),
                    "END_OF_TRAVEL not in the cycle's telemetry: {ev:?}"
                );
                assert!(
                    ev.iter().any(|(s, id, aux)| *s == EventSeverity::High
                        && *id == event::FAULT_LATCHED
                        && aux[1] & FaultFlags::LIMIT_SWITCH.bits() != 0
                        && (aux[1] >> 24) as u8 & bit(leg) != 0),
                    "FAULT_LATCHED with the leg not in the cycle's telemetry: {ev:?}"
                );
            }
            Some((_, truth_seen)) if active => assert!(
                not_beyond(truth, truth_seen, end),
                "cycle {n}: the slider moved on toward the switch: {truth} after {truth_seen}"
            ),
            _ => {}
        }
        if r.st.finished(rid) && r.ctl.state() == State::Faulted {
            cycles_after_rest += 1;
            if cycles_after_rest > 200 {
                break;
            }
        }
    }
    let (seen_after, truth_seen) = seen.expect("the move never reached the switch");
    let reps = r.st.reports(rid);
    assert!(
        matches!(
            reps.as_slice(),
            [
                Verification::AcceptanceSuccess,
                Verification::StartSuccess,
                Verification::CompletionFailure { code: ABORTED_BY_FAULT, data }
            ] if data & FaultFlags::LIMIT_SWITCH.bits() != 0
        ),
        "{reps:?}"
    );
    assert_eq!(r.ctl.state(), State::Faulted);
    let hk = r.hk();
    assert_eq!(at_end(&switches_of(&hk), end), bit(leg), "HK switch byte");
    assert!(hk.fault_flags & FaultFlags::LIMIT_SWITCH.bits() != 0);
    assert!(hk.fault_legs & bit(leg) != 0);
    Tripped {
        r,
        seen_after,
        overshoot_mm: f64::from(sign(end)) * (truth_seen - at_mm),
    }
}

/// The switch bytes of a housekeeping report.
fn switches_of(hk: &m2ctl::link::Housekeeping) -> TravelSwitches {
    TravelSwitches {
        lower: hk.limit_lower_legs,
        upper: hk.limit_upper_legs,
        reference: hk.reference_legs,
        unreadable: hk.switch_unreadable_legs,
    }
}

/// Recovery after [`trip`]: the clear refused while the switch is active; a direct
/// stroke toward it refused with 0x070E and nothing moving; away accepted, the switch
/// releases; toward it still refused until the clear; the clear succeeds; a normal move
/// works again.
fn recover(mut r: Bench, leg: usize, end: SwitchEnd) {
    let v = r.command(&Command::ClearFault, 10);
    assert_eq!(
        v,
        [
            Verification::AcceptanceSuccess,
            Verification::StartFailure {
                code: FAULT_PERSISTS,
                data: FaultFlags::LIMIT_SWITCH.bits()
            }
        ],
        "clear while the switch is active"
    );
    let leg1 = leg as u8 + 1;
    let toward = |um: i32| Command::DirectStroke {
        leg: leg1,
        delta_nm: sign(end) * um * 1000,
    };
    let cmd_before = r.ctl.strokes_commanded_mm();
    let drives_before = r.plant.with(|p| p.drive_setpoints_mm());
    let truth_before = r.plant.with(|p| p.strokes_mm());
    let v = r.command(&toward(10), 10);
    assert_eq!(
        v,
        [
            Verification::AcceptanceSuccess,
            Verification::StartFailure {
                code: TOWARD_END_OF_TRAVEL,
                data: u32::from(bit(leg))
            }
        ],
        "direct stroke toward the switch"
    );
    r.run(50);
    assert_eq!(r.ctl.strokes_commanded_mm(), cmd_before);
    assert_eq!(r.plant.with(|p| p.drive_setpoints_mm()), drives_before);
    assert_eq!(r.plant.with(|p| p.strokes_mm()), truth_before);
    assert_eq!(r.ctl.state(), State::Faulted);
    // Away: accepted; the slider leaves the switch.
    assert!(all_ok(&r.command(&toward(-20), STROKE_CYCLES)));
    assert_eq!(
        at_end(&r.ctl.switches(), end) & bit(leg),
        0,
        "still at the switch"
    );
    assert!(r.ctl.faults().contains(FaultFlags::LIMIT_SWITCH));
    // The switch seen since the latch still blocks that direction until the clear.
    let v = r.command(&toward(5), 10);
    assert_eq!(
        v.last(),
        Some(&Verification::StartFailure {
            code: TOWARD_END_OF_TRAVEL,
            data: u32::from(bit(leg))
        })
    );
    assert!(all_ok(&r.command(&Command::ClearFault, 10)));
    assert!(r.ctl.faults().is_empty());
    assert_eq!(r.ctl.state(), State::Idle);
    // A normal move works again (home: away from the switch).
    assert!(all_ok(&r.command(
        &Command::MoveAbsolute(wire(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        MOVE_CYCLES
    )));
    r.settle(MOVE_CYCLES);
    let truth = r.plant.with(|p| p.strokes_mm());
    for i in 0..LEGS {
        assert!(truth[i].abs() < 1e-3, "leg {} at {} mm", i + 1, truth[i]);
    }
    assert!(r.ctl.faults().is_empty());
}

#[test]
fn a_limit_switch_stops_its_leg_in_the_cycle_it_is_seen() {
    // Leg 3's upper switch misadjusted to +0.4 mm; a move up by 1 mm crosses it.
    let t = trip(2, SwitchEnd::Upper, 0.4, 1000.0);
    println!(
        "upper switch of leg 3 seen {} cycles into the move, slider {:.3} um beyond it when seen, not a nanometre further after",
        t.seen_after,
        t.overshoot_mm * UM_PER_MM
    );
    // Within one cycle of the slowest path speed (0.2 mm/s = 0.2 um per cycle).
    assert!(
        (0.0..=2.0e-4 + 1e-9).contains(&t.overshoot_mm),
        "{}",
        t.overshoot_mm
    );
}

#[test]
fn only_a_move_away_from_the_switch_is_accepted_then_the_clear() {
    let t = trip(2, SwitchEnd::Upper, 0.4, 1000.0);
    recover(t.r, 2, SwitchEnd::Upper);
}

#[test]
fn the_lower_switch_is_symmetric() {
    // Leg 5's lower switch misadjusted to -0.3 mm; a move down by 0.8 mm crosses it.
    let t = trip(4, SwitchEnd::Lower, -0.3, -800.0);
    println!(
        "lower switch of leg 5 seen {} cycles into the move, slider {:.3} um beyond it",
        t.seen_after,
        t.overshoot_mm * UM_PER_MM
    );
    assert!((0.0..=2.0e-4 + 1e-9).contains(&t.overshoot_mm));
    recover(t.r, 4, SwitchEnd::Lower);
}

#[test]
fn a_switch_that_releases_mid_motion_keeps_its_leg_held_to_the_end_of_the_motion() {
    // Leg 1's upper switch reads active for 5 cycles in the middle of a move up (a
    // contact glitch), then releases while the stop ramp runs: the leg's command stays
    // where the switch found it (no jump back to the path), the others ramp down
    // continuously.
    let mut r = Bench::new();
    r.run(2);
    let rid = r.send(&Command::MoveAbsolute(wire(0.0, 0.0, 600.0, 0.0, 0.0, 0.0)));
    r.run(1_200);
    assert_eq!(r.ctl.state(), State::Moving);
    let end = SwitchEnd::Upper;
    r.plant
        .with(|p| p.inject(InjectedFault::SwitchStuckActive { leg: 0, end }));
    let before = r.ctl.strokes_commanded_mm()[0];
    let step_mm = f64::from(m2ctl::motion::DEFAULT_MAX_SPEED_MM_PER_S * m2ctl::motion::CYCLE_S);
    let mut held = None;
    for n in 1..=MOVE_CYCLES {
        if n == 6 {
            r.plant.with(|p| p.clear_faults());
        }
        let prev = r.ctl.strokes_commanded_mm();
        r.tick();
        let cmd = r.ctl.strokes_commanded_mm();
        if n <= 5 {
            assert_eq!(r.ctl.switches().upper, 0b1);
        }
        let h = *held.get_or_insert(cmd[0]);
        assert_eq!(
            cmd[0], h,
            "cycle {n}: leg 1 left the stroke the switch found"
        );
        for i in 1..LEGS {
            assert!(
                f64::from((cmd[i] - prev[i]).abs()) <= step_mm + 1e-6,
                "cycle {n}: leg {} stepped {} mm",
                i + 1,
                cmd[i] - prev[i]
            );
        }
        if r.st.finished(rid) {
            break;
        }
    }
    assert_eq!(held, Some(before), "held at the previous cycle's command");
    assert_eq!(r.ctl.switches().upper, 0);
    assert!(matches!(
        r.st.reports(rid).last(),
        Some(Verification::CompletionFailure {
            code: ABORTED_BY_FAULT,
            ..
        })
    ));
    // Released: the clear is accepted at once.
    assert!(all_ok(&r.command(&Command::ClearFault, 10)));
}

#[test]
fn an_unreadable_switch_input_blocks_both_directions_and_latches() {
    // At rest: leg 2's inputs become unreadable.
    let mut r = Bench::new();
    r.run(2);
    r.plant
        .with(|p| p.inject(InjectedFault::SwitchUnreadable { leg: 1 }));
    let from = r.st.log.len();
    r.tick();
    assert!(r.ctl.faults().contains(FaultFlags::LIMIT_SWITCH));
    let cycle = r.ctl.cycle() - 1;
    assert!(events_since(&r, from).contains(&(
        EventSeverity::High,
        event::END_OF_TRAVEL,
        [1 << (16 + 1), cycle]
    )));
    let hk = r.hk();
    assert_eq!(switches_of(&hk).unreadable, 0b10);
    assert_eq!(hk.fault_legs, 0b10);
    for delta_nm in [10_000, -10_000] {
        let v = r.command(&Command::DirectStroke { leg: 2, delta_nm }, 10);
        assert_eq!(
            v.last(),
            Some(&Verification::StartFailure {
                code: TOWARD_END_OF_TRAVEL,
                data: 0b10
            }),
            "delta {delta_nm} nm"
        );
    }
    // Another leg's recovery move is not blocked by it.
    assert!(all_ok(&r.command(
        &Command::DirectStroke {
            leg: 1,
            delta_nm: 10_000
        },
        STROKE_CYCLES
    )));
    let v = r.command(&Command::ClearFault, 10);
    assert_eq!(
        v.last(),
        Some(&Verification::StartFailure {
            code: FAULT_PERSISTS,
            data: FaultFlags::LIMIT_SWITCH.bits()
        })
    );
    r.plant.with(|p| p.clear_faults());
    r.run(2);
    assert!(all_ok(&r.command(&Command::ClearFault, 10)));

    // In motion: leg 4's inputs become unreadable; from that cycle its command never
    // changes again, whichever way the path (and then the stop ramp) goes.
    let rid = r.send(&Command::MoveAbsolute(wire(0.0, 0.0, 600.0, 0.0, 0.0, 0.0)));
    r.run(800);
    assert_eq!(r.ctl.state(), State::Moving);
    r.plant
        .with(|p| p.inject(InjectedFault::SwitchUnreadable { leg: 3 }));
    let held = r.ctl.strokes_commanded_mm()[3];
    let mut others_moved = false;
    for _ in 0..MOVE_CYCLES {
        let prev = r.ctl.strokes_commanded_mm();
        r.tick();
        let cmd = r.ctl.strokes_commanded_mm();
        assert_eq!(cmd[3], held, "leg 4 commanded with its inputs unreadable");
        others_moved |= (0..LEGS).any(|i| i != 3 && cmd[i] != prev[i]);
        if r.st.finished(rid) {
            break;
        }
    }
    assert!(others_moved, "the other legs' stop ramp");
    assert!(matches!(
        r.st.reports(rid).last(),
        Some(Verification::CompletionFailure {
            code: ABORTED_BY_FAULT,
            ..
        })
    ));
}

#[test]
fn an_encoder_warning_is_reported_and_stops_nothing() {
    let mut r = Bench::new();
    r.run(2);
    let rid = r.send(&Command::MoveAbsolute(wire(0.0, 0.0, 300.0, 0.0, 0.0, 0.0)));
    r.run(300);
    assert_eq!(r.ctl.state(), State::Moving);
    r.plant
        .with(|p| p.inject(InjectedFault::EncoderWarning { leg: 2 }));
    let from = r.st.log.len();
    r.tick();
    let w = FaultFlags::ENCODER_WARNING.bits();
    assert_eq!(r.ctl.housekeeping().warning_flags, w);
    assert!(events_since(&r, from).contains(&(
        EventSeverity::Low,
        event::WARNING_CHANGED,
        [w, 0b100]
    )));
    // Not a fault: the move arrives.
    assert!(all_ok(&wait(&mut r, rid, MOVE_CYCLES)));
    assert!(r.ctl.faults().is_empty());
    let hk = r.hk();
    assert_eq!(hk.warning_flags, w);
    assert_eq!(hk.fault_flags, 0);
    // The encoder stops warning: the flag goes, with an event.
    r.plant.with(|p| p.clear_faults());
    let from = r.st.log.len();
    r.tick();
    assert_eq!(r.ctl.housekeeping().warning_flags, 0);
    assert!(events_since(&r, from).contains(&(EventSeverity::Low, event::WARNING_CHANGED, [0, 0])));
}

#[test]
fn supervisor_latches_a_switch_in_the_cycle_it_is_seen_and_holds_it_while_present() {
    // The latency table's rows: LIMIT_SWITCH and ENCODER_WARNING at c0, with their legs.
    let mut sup = Supervisor::new(SupervisionConfig::default());
    let home = [0.0f32; LEGS];
    let inputs = |switches: TravelSwitches, warn: u8| CycleInputs {
        encoders: Ok(home),
        commanded_prev_mm: home,
        motion_commanded: false,
        fk: Some(Ok(FkSolution {
            pose: Pose::home(),
            iterations: 1,
            residual_mm: 0.0,
        })),
        drive: Ok(()),
        switches,
        encoder_warning_legs: warn,
    };
    let none = TravelSwitches::default();
    // The reference sensors are information only.
    let reference = TravelSwitches {
        reference: 0b11_1111,
        ..none
    };
    for _ in 0..10 {
        assert_eq!(
            sup.check(&inputs(reference, 0)).latched,
            FaultFlags::empty()
        );
    }
    let upper5 = TravelSwitches {
        upper: 0b1_0000,
        ..none
    };
    let v = sup.check(&inputs(upper5, 0));
    assert_eq!(v.new_faults, FaultFlags::LIMIT_SWITCH);
    assert_eq!(v.new_fault_legs, 0b1_0000);
    assert_eq!(sup.clear(), Err(FaultFlags::LIMIT_SWITCH));
    // Released: clearable.
    sup.check(&inputs(none, 0));
    assert_eq!(sup.clear(), Ok(()));
    // Unreadable, and a leg mask beyond the six legs ignored.
    let v = sup.check(&inputs(
        TravelSwitches {
            unreadable: 0b1100_0001,
            ..none
        },
        0,
    ));
    assert_eq!(v.new_fault_legs, 0b1);
    // An encoder warning: present while reported, never latched, legs named.
    let mut sup = Supervisor::new(SupervisionConfig::default());
    let v = sup.check(&inputs(none, 0b10));
    assert_eq!(v.warnings, FaultFlags::ENCODER_WARNING);
    assert_eq!(v.warning_legs, 0b10);
    assert!(v.latched.is_empty());
    let v = sup.check(&inputs(none, 0));
    assert!(v.warnings.is_empty());
}

// =====================================================================================
// The real step/direction driver under the controller.

/// Microsteps per mm of the test drives: one microstep is one encoder count (0.1 um).
const USTEPS_PER_MM: i64 = 10_000;

/// The sliders driven by step pulses: per leg the direction last set, the true position
/// (microsteps from home), and the pulses received.
#[derive(Default)]
struct Motors {
    dir_positive: [bool; LEGS],
    position: [i64; LEGS],
    pulses: [u64; LEGS],
    /// Pulses received in the positive direction.
    pulses_positive: [u64; LEGS],
}

type SharedMotors = Rc<RefCell<Motors>>;

/// A step-pulse generator whose pulses move the motor at once (the train of a cycle is
/// complete by the next command: nothing is ever unsent).
struct MotorPulses {
    leg: usize,
    motors: SharedMotors,
}

impl StepPulses for MotorPulses {
    type Error = ();
    fn start(&mut self, count: u32) -> Result<(), ()> {
        let mut m = self.motors.borrow_mut();
        let step = if m.dir_positive[self.leg] { 1 } else { -1 };
        m.position[self.leg] += step * i64::from(count);
        m.pulses[self.leg] += u64::from(count);
        if step > 0 {
            m.pulses_positive[self.leg] += u64::from(count);
        }
        Ok(())
    }
    fn stop(&mut self) -> u32 {
        0
    }
}

/// The direction input of the motor's drive (high: positive).
struct MotorDir {
    leg: usize,
    motors: SharedMotors,
}

impl PinErrorType for MotorDir {
    type Error = core::convert::Infallible;
}
impl OutputPin for MotorDir {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.motors.borrow_mut().dir_positive[self.leg] = false;
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.motors.borrow_mut().dir_positive[self.leg] = true;
        Ok(())
    }
}

/// Absolute encoders on the motors' true positions (1 count = 1 microstep = 0.1 um).
struct MotorEncoders(SharedMotors);

impl StrokeEncoders for MotorEncoders {
    fn read_counts(&mut self) -> Result<[i32; LEGS], EncoderError> {
        Ok(self.0.borrow().position.map(|p| p as i32))
    }
}
impl EncoderWarnings for MotorEncoders {
    fn warning_legs(&self) -> u8 {
        0
    }
}

type Drives = StepDirDrives<MotorPulses, MotorDir, PinMock, PinMock>;
type Rig = Mechanism<MotorEncoders, Drives, TravelSwitchInputs<PinMock>>;

/// The mock pins of the rig with their expectations, checked by `done`.
struct Pins {
    enable: Vec<PinMock>,
    fault: Vec<PinMock>,
    switches: Vec<PinMock>,
}

impl Pins {
    fn done(&mut self) {
        for p in self
            .enable
            .iter_mut()
            .chain(self.fault.iter_mut())
            .chain(self.switches.iter_mut())
        {
            p.done();
        }
    }
}

/// A controller on the real driver: step/direction drives (1 mm lead screw, 200 steps,
/// 50 microsteps), switch inputs and the drives' ENABLE and FAULT on mock pins expecting
/// exactly `cycles` control cycles: ENABLE set active (low) once at construction; every
/// FAULT input read once per cycle (high: healthy), every switch input once per cycle
/// and once at construction, its level from `switch_level(leg, input, read)` (input 0
/// lower, 1 upper, 2 reference; read 0 is the construction's, read k is cycle k's).
fn rig(
    cycles: usize,
    switch_level: impl Fn(usize, usize, usize) -> bool,
) -> (Controller<Rig>, SharedMotors, Pins, Station, TmConsumer) {
    let motors = SharedMotors::default();
    let enable: Vec<PinMock> = (0..LEGS)
        .map(|_| PinMock::new(&[PinTransaction::set(PinState::Low)]))
        .collect();
    let fault: Vec<PinMock> = (0..LEGS)
        .map(|_| PinMock::new(&vec![PinTransaction::get(PinState::High); cycles]))
        .collect();
    let switches: Vec<PinMock> = (0..3 * LEGS)
        .map(|k| {
            let (leg, input) = (k / 3, k % 3);
            let reads: Vec<PinTransaction> = (0..=cycles)
                .map(|read| {
                    PinTransaction::get(if switch_level(leg, input, read) {
                        PinState::High
                    } else {
                        PinState::Low
                    })
                })
                .collect();
            PinMock::new(&reads)
        })
        .collect();
    let legs = std::array::from_fn(|i| StepperLeg {
        pulses: MotorPulses {
            leg: i,
            motors: motors.clone(),
        },
        dir: MotorDir {
            leg: i,
            motors: motors.clone(),
        },
        enable: enable[i].clone(),
        fault: fault[i].clone(),
    });
    let cfg = StepperConfig {
        lead_screw_pitch_nm: 1_000_000,
        full_steps_per_rev: 200,
        microsteps_per_step: 50,
        gear_motor_revs: 1,
        gear_screw_revs: 1,
        max_microsteps_per_cycle: 100,
        travel_limit_nm: 6_000_000,
        polarity: StepperPolarity {
            dir_high_is_positive: true,
            enable_active_high: false,
            fault_active_high: false,
        },
    };
    let mut drives = StepDirDrives::new(legs, cfg).map_err(|(e, _)| e).unwrap();
    assert_eq!(cfg.microsteps_per_mm(), USTEPS_PER_MM as f64);
    // The encoders say where the sliders are: the drives count from there.
    drives.align_issued_mm(&[0.0; LEGS]);
    let sw_legs = std::array::from_fn(|i| LegSwitches {
        lower: switches[3 * i].clone(),
        upper: switches[3 * i + 1].clone(),
        reference: switches[3 * i + 2].clone(),
    });
    let mech = Mechanism {
        encoders: MotorEncoders(motors.clone()),
        drives,
        switches: TravelSwitchInputs::new(
            sw_legs,
            SwitchPolarity {
                end_active_high: true,
                reference_active_high: true,
            },
        ),
        exposure: m2ctl::drivers::exposure::NoExposureLine,
    };
    let flash: MockFlash = MockFlash::new(SIM_FLASH_BYTES);
    let mut store = TableStore::new(flash, SIM_LAYOUT)
        .map_err(|(_, e)| e)
        .unwrap();
    let (table, boot) = store.boot(&ValidationConfig::flight());
    let (producer, consumer) = m2ctl::controller::telemetry::host_queue();
    let ctl = Controller::new(mech, table, boot, producer);
    (
        ctl,
        motors,
        Pins {
            enable,
            fault,
            switches,
        },
        Station::new(),
        consumer,
    )
}

/// Hands a telecommand to the controller (between cycles, decoded as the link service
/// does).
fn tc(ctl: &mut Controller<Rig>, st: &mut Station, cmd: &Command) -> RequestId {
    let (packet, rid) = st.packet(cmd).unwrap();
    let decoded = m2ctl::link::tc::decode_telecommand(&packet).unwrap();
    ctl.execute_telecommand(&decoded);
    rid
}

/// Takes the controller's queued telemetry records.
fn drain(tm: &mut TmConsumer, log: &mut Vec<(u32, TmRecord)>) {
    while let Some(s) = tm.pop() {
        log.push((s.cycle, s.record));
    }
}

fn reports(log: &[(u32, TmRecord)], rid: RequestId) -> Vec<Verification> {
    log.iter()
        .filter_map(|(_, r)| match r {
            TmRecord::Verification { request_id, report } if *request_id == rid => Some(*report),
            _ => None,
        })
        .collect()
}

#[test]
fn missed_steps_of_the_real_stepper_driver_are_detected_by_the_encoders() {
    // A move up 0.5 mm on the step/direction driver; 1,200 cycles in, leg 4's rotor
    // slips back 700 microsteps (70 um) at once: what the drive issued (its own count,
    // `SliderDrives::setpoints_mm`) and what the encoder reads part by 70 um, above the
    // 50 um following-error fault threshold.
    const CYCLES: usize = 6_000;
    const SLIP_AT: usize = 1_200;
    const SLIP_USTEPS: i64 = 700;
    let (mut ctl, motors, mut pins, mut st, mut tm) = rig(CYCLES, |_, _, _| false);
    let mut log = Vec::new();
    let rid = tc(
        &mut ctl,
        &mut st,
        &Command::MoveAbsolute(wire(0.0, 0.0, 500.0, 0.0, 0.0, 0.0)),
    );
    let mut detected = None;
    for c in 1..=CYCLES {
        if c == SLIP_AT {
            motors.borrow_mut().position[3] -= SLIP_USTEPS;
        }
        ctl.control_cycle();
        drain(&mut tm, &mut log);
        if c < SLIP_AT {
            assert!(ctl.faults().is_empty(), "cycle {c}: {:?}", ctl.faults());
        } else if detected.is_none() && !ctl.faults().is_empty() {
            detected = Some(c - SLIP_AT);
            assert_eq!(ctl.faults(), FaultFlags::FOLLOWING_ERROR);
            assert_eq!(ctl.housekeeping().fault_legs, 0b1000);
        }
    }
    // Fault debounce 3: latched in the third cycle that sees the slip.
    assert_eq!(detected, Some(2), "cycles from the slip to the fault");
    assert!(matches!(
        reports(&log, rid).last(),
        Some(Verification::CompletionFailure {
            code: ABORTED_BY_FAULT,
            ..
        })
    ));
    assert_eq!(ctl.state(), State::Faulted);
    // At rest the drive holds its issued count; the encoder shows the loss exactly.
    let hk = ctl.housekeeping();
    let issued = ctl.mechanism().drives.issued_microsteps();
    let m = motors.borrow();
    for i in 0..LEGS {
        let lost = if i == 3 { SLIP_USTEPS } else { 0 };
        assert_eq!(m.position[i], issued[i] - lost, "leg {}", i + 1);
        let gap_nm = i64::from(hk.strokes_commanded_nm[i]) - i64::from(hk.encoders_nm[i]);
        let want_nm = lost * 1_000_000 / USTEPS_PER_MM;
        assert!(
            (gap_nm - want_nm).abs() <= 1,
            "leg {}: issued - encoder = {gap_nm} nm, lost {want_nm} nm",
            i + 1
        );
    }
    let issued_mm = ctl.mechanism().drives.issued_strokes_mm();
    println!(
        "stepper slip of {SLIP_USTEPS} microsteps (70 um) on leg 4 detected {} cycles later; at rest issued {:.4} mm, encoder {:.4} mm",
        detected.unwrap_or(0),
        issued_mm[3],
        m.position[3] as f64 * ENCODER_MM_PER_COUNT
    );
    drop(m);
    pins.done();
}

#[test]
fn a_switch_pin_stops_the_stepper_leg_in_the_cycle_it_reads_active() {
    // A move up 0.5 mm; leg 2's upper switch input (normally closed: high = active)
    // reads high from cycle 900 on. From that cycle no pulse moves leg 2 up (the driver
    // is inhibited in the read, and the controller does not command it further); the
    // fault latches; a direct stroke down is the recovery and sends only negative pulses.
    const CYCLES: usize = 5_000;
    const TRIP_AT: usize = 900;
    let (mut ctl, motors, mut pins, mut st, mut tm) = rig(CYCLES, |leg, input, read| {
        leg == 1 && input == 1 && (TRIP_AT..TRIP_AT + 1_500).contains(&read)
    });
    let mut log = Vec::new();
    let rid = tc(
        &mut ctl,
        &mut st,
        &Command::MoveAbsolute(wire(0.0, 0.0, 500.0, 0.0, 0.0, 0.0)),
    );
    let mut up_pulses_at_trip = 0;
    let mut position_at_trip = 0;
    let mut recovery = None;
    for c in 1..=CYCLES {
        let up_before = motors.borrow().pulses_positive[1];
        ctl.control_cycle();
        drain(&mut tm, &mut log);
        let m = motors.borrow();
        if c < TRIP_AT {
            assert!(ctl.faults().is_empty());
        }
        if c == TRIP_AT {
            assert_eq!(
                m.pulses_positive[1], up_before,
                "an upward pulse in the cycle the switch read active"
            );
            assert!(ctl.faults().contains(FaultFlags::LIMIT_SWITCH));
            assert!(log.iter().any(|(cy, r)| *cy == (c - 1) as u32
                && matches!(r, TmRecord::Event { id, aux, .. }
                    if *id == event::END_OF_TRAVEL && aux[0] == 1 << (8 + 1))));
            up_pulses_at_trip = m.pulses_positive[1];
            position_at_trip = m.position[1];
            assert!(position_at_trip > 0, "leg 2 was moving up");
        }
        if (TRIP_AT..TRIP_AT + 1_500).contains(&c) {
            assert_eq!(m.pulses_positive[1], up_pulses_at_trip, "cycle {c}");
            assert!(m.position[1] <= position_at_trip);
        }
        drop(m);
        if c == TRIP_AT + 1_000 {
            assert!(matches!(
                reports(&log, rid).last(),
                Some(Verification::CompletionFailure {
                    code: ABORTED_BY_FAULT,
                    ..
                })
            ));
            assert_eq!(ctl.state(), State::Faulted);
            let up = tc(
                &mut ctl,
                &mut st,
                &Command::DirectStroke {
                    leg: 2,
                    delta_nm: 5_000,
                },
            );
            drain(&mut tm, &mut log);
            assert_eq!(
                reports(&log, up).last(),
                Some(&Verification::StartFailure {
                    code: TOWARD_END_OF_TRAVEL,
                    data: 0b10
                })
            );
            recovery = Some(tc(
                &mut ctl,
                &mut st,
                &Command::DirectStroke {
                    leg: 2,
                    delta_nm: -20_000,
                },
            ));
        }
    }
    let recovery = recovery.unwrap();
    assert_eq!(
        reports(&log, recovery),
        [
            Verification::AcceptanceSuccess,
            Verification::StartSuccess,
            Verification::CompletionSuccess
        ]
    );
    let m = motors.borrow();
    assert_eq!(m.pulses_positive[1], up_pulses_at_trip);
    assert_eq!(m.position[1], position_at_trip - 200, "20 um down");
    drop(m);
    // The switch released (read TRIP_AT + 1500 on): the clear is accepted.
    let clear = tc(&mut ctl, &mut st, &Command::ClearFault);
    drain(&mut tm, &mut log);
    assert_eq!(
        reports(&log, clear).last(),
        Some(&Verification::CompletionSuccess)
    );
    assert!(ctl.faults().is_empty());
    // Every pin was used exactly as expected: each switch input and fault input read
    // once per cycle, ENABLE set once.
    pins.done();
}
