//! Flight image (target only, `--features firmware`): the M2 mechanism controller as an
//! RTIC 2 application on the board the features select (`m2ctl::board::active`: QEMU's
//! mps2-an386 by default, the STM32F405 Netduino Plus 2 with `board-netduinoplus2`).
//!
//! # Tasks, by priority (the order `sim::Bench` calls the same code on the host)
//! | priority | task | bound to (mps2-an386) | does | at most |
//! |---|---|---|---|---|
//! | 4 | `uart_rx` | `UART_RX`: UART0 RX (IRQ 0) | one received byte into the RX queue, overrun bit | ~40 instructions per byte |
//! | 3 | `control` | `CONTROL_TIMER`: TIMER0 (IRQ 8), 1 kHz | `Controller::control_cycle`, deadline check, watchdog feed, pends the two below | one control cycle |
//! | 2 | `uart_tx` | `UART_TX`: UART0 TX (IRQ 1, also pended by the link service) | one byte from the TX queue to the UART | ~30 instructions per byte |
//! | 1 | `link_service` | `LINK_SERVICE`: IRQ 30 (pended by `control`) | `LinkService`: telecommands in (at most `MAX_TC_PER_PASS`), job messages, telemetry frames out | one pass |
//! | 1 | `worker` | `WORKER`: IRQ 31 (pended by `control`, runs after the link pass) | one `Worker::step`: a validation, a flash operation, a scrub check | one step |
//! | 0 | `idle` | - | sleeps (WFI) | - |
//!
//! The tasks bind the board-independent names of `board::device::interrupt`; each
//! board maps them onto its lines (the Netduino Plus 2: USART1, TIM3, and three unused
//! CAN2 lines for the software-pended ones; its one USART1 line hands TXE to `UART_TX`).
//!
//! The link service and the worker share priority 1: neither preempts the other, so
//! the worst-case stack is the larger of the two plus the tasks above (RTIC's single
//! stack, stack-resource policy), and the link service waits at most one worker step
//! (the longest is a table validation, measured by `m2cyclebench`).
//! The controller is the one shared resource (`control` and `link_service`): the link
//! service holds its lock (priority ceiling 3) for one telecommand, one telemetry
//! record or one job message at a time, so the control task waits at most for the
//! longest of those (measured by `m2cyclebench`: its `LOCK` sections); encoding, a move
//! check's IK/FK and an activation's geometry derivation happen outside the lock.
//! Everything else moves through bounded single-producer/single-consumer queues
//! (`heapless::spsc`) owned by exactly one task at each end, without locks: UART bytes
//! (RX, TX), job requests and results (link service <-> idle). The control task never
//! waits for the UART, the flash or the worker.
//!
//! # Failure behaviour
//! * An overrun (the next timer tick came before the cycle ended) is reported with
//!   `Controller::note_overrun`; consecutive overruns hold the mechanism.
//! * The watchdog is fed only by a completed control cycle; its NMI records the cause,
//!   its second expiry resets. HardFault, a stack overflow into the MPU guard, an
//!   unexpected interrupt and a panic record their cause and reset; the next boot
//!   reports cause and boot count (`Controller::set_reset_info`, events 0x0020/0x0021,
//!   housekeeping).
//! * A failed boot self-test halts the board before anything is commanded and before
//!   the watchdog runs (the mechanism stays where it is; safe mode is outside this image).
//!
//! No semihosting and no log: telemetry is the only output. The controller drives the
//! board's `Sliders`: on mps2-an386 (QEMU has no sliders) the slider model
//! `m2ctl::board::qemu_sliders` behind the hardware traits, on the Netduino Plus 2 the
//! drivers of `m2ctl::drivers`.
#![no_std]
#![no_main]

use core::mem::MaybeUninit;
use m2ctl::board::active as board;
use m2ctl::controller::comms::{Exclusive, JobPort, RxBytes, TxBytes};
use m2ctl::controller::{
    Controller, JobRequest, JobResult, ResetCause, ResetInfo, TmConsumer, TmProducer, TmQueue,
    Worker,
};
use m2ctl::hw::SliderDrives;
use m2ctl::kinematics::Geometry;
use m2ctl::table::{BootReport, Table, TableStore, ValidationConfig};
use m2ctl::{nominal, selftest};

#[cfg(feature = "panic-never")]
use panic_never as _;

/// A panic is a defect (the `panic-never` build proves the image has no panic path):
/// record it and reset.
#[cfg(not(feature = "panic-never"))]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    board::record_and_reset(ResetCause::Panic)
}

/// UART receive queue (bytes): two largest telecommand frames.
const RX_QUEUE_LEN: usize = 1024;
/// UART transmit queue (bytes): the link service queues whole frames only, while they
/// fit; what does not fit waits in the controller's telemetry queue.
const TX_QUEUE_LEN: usize = 2048;
/// Job request and result queues (one slot each: the controller has at most one
/// operator job and one scrub outstanding, and the link service holds back a request
/// the queue has no room for).
const JOB_QUEUE_LEN: usize = 2;

type RxIn = heapless::spsc::Producer<'static, u8, RX_QUEUE_LEN>;
type RxOut = heapless::spsc::Consumer<'static, u8, RX_QUEUE_LEN>;
type TxIn = heapless::spsc::Producer<'static, u8, TX_QUEUE_LEN>;
type TxOut = heapless::spsc::Consumer<'static, u8, TX_QUEUE_LEN>;

/// The RX queue as the link service reads it.
struct RxQueue<'a>(&'a mut RxOut);

impl RxBytes for RxQueue<'_> {
    fn pop(&mut self) -> Option<u8> {
        self.0.dequeue()
    }
}

/// The TX queue as the link service fills it.
struct TxQueue<'a> {
    queue: &'a mut TxIn,
    pushed: bool,
}

impl TxBytes for TxQueue<'_> {
    fn free(&self) -> usize {
        self.queue.capacity() - self.queue.len()
    }
    fn push(&mut self, frame: &[u8]) {
        for b in frame {
            // Only called when the whole frame fits (LinkService::transmit).
            let _ = self.queue.enqueue(*b);
        }
        self.pushed = true;
    }
}

/// The worker's two queues as the link service's job port.
struct WorkerQueues<'a> {
    requests: &'a mut heapless::spsc::Producer<'static, JobRequest, JOB_QUEUE_LEN>,
    results: &'a mut heapless::spsc::Consumer<'static, JobResult, JOB_QUEUE_LEN>,
}

impl JobPort for WorkerQueues<'_> {
    fn send(&mut self, request: &JobRequest) -> bool {
        self.requests.enqueue(*request).is_ok()
    }
    fn recv(&mut self) -> Option<JobResult> {
        self.results.dequeue()
    }
}

/// An RTIC resource (holding a `&'static mut`) as the link service's [`Exclusive`]
/// access to the controller.
struct Locked<'a, M>(&'a mut M);

impl<X: 'static, M: rtic::Mutex<T = &'static mut X>> Exclusive<X> for Locked<'_, M> {
    fn lock<R>(&mut self, f: impl FnOnce(&mut X) -> R) -> R {
        self.0.lock(|x| f(x))
    }
}

/// Stops here for good (boot self-test failed, hardware missing): nothing commanded,
/// no watchdog running.
fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

/// Boot self-test of the flight kinematics on a subset of the golden vectors (every
/// tenth row, kept in f32: `selftest::BootRow`; the self-test image m2selftest checks
/// all of them). Not inlined: its frame is gone before the controller is built.
#[inline(never)]
fn boot_selftest_passes() -> bool {
    // The nominal geometry through its one out-of-line copy (the worker's validation
    // configuration and the nominal table call it too): inlined here, it was a second
    // copy of its ~180 bytes.
    let nominal: fn() -> m2ctl::kinematics::GeometryParams = nominal::prototype_with_flight_limits;
    let Ok(geom) = Geometry::<f32>::new(&core::hint::black_box(nominal)()) else {
        return false;
    };
    selftest::BOOT_GOLDEN_ROWS
        .iter()
        .all(|row| selftest::run_row(&geom, &row.widen()).pass)
}

/// The worker (owning the table store) and the controller, each built by its own
/// non-inlined function straight into its static slot, and the boot selection in
/// between, so that init's stack holds at most one of these large objects at a time.
#[inline(never)]
fn build_core(
    flash: board::TableFlash,
    sliders: board::Sliders,
    reset: ResetInfo,
    tm: TmProducer,
    ctl_slot: &'static mut MaybeUninit<Controller<board::Sliders>>,
    worker_slot: &'static mut MaybeUninit<Worker<board::TableFlash>>,
) -> Option<(
    &'static mut Controller<board::Sliders>,
    &'static mut Worker<board::TableFlash>,
)> {
    let worker = build_worker(worker_slot, flash)?;
    let (table, boot) = boot_selection(worker);
    let ctl = build_controller(ctl_slot, sliders, table, boot, reset, tm);
    // The on-board parameters persisted with the selection record (pivot, limits...).
    ctl.restore_parameters(&worker.store_mut().parameters());
    Some((ctl, worker))
}

#[inline(never)]
fn build_worker(
    slot: &'static mut MaybeUninit<Worker<board::TableFlash>>,
    flash: board::TableFlash,
) -> Option<&'static mut Worker<board::TableFlash>> {
    let store = TableStore::new(flash, board::TABLE_LAYOUT).ok()?;
    // Built here, not in build_core: its ~500 bytes are then not on the stack while the
    // controller is built (the boot path is the image's deepest stack).
    Some(slot.write(Worker::new(store, ValidationConfig::flight())))
}

/// The table boot selection (`TableStore::boot`): what the operator last selected, if
/// it is intact and valid, else the fallback.
#[inline(never)]
fn boot_selection(worker: &mut Worker<board::TableFlash>) -> (Table, BootReport) {
    worker.boot()
}

#[inline(never)]
fn build_controller(
    slot: &'static mut MaybeUninit<Controller<board::Sliders>>,
    mut sliders: board::Sliders,
    table: Table,
    boot: BootReport,
    reset: ResetInfo,
    tm: TmProducer,
) -> &'static mut Controller<board::Sliders> {
    sliders.hold();
    let ctl = Controller::unstarted_in(slot, sliders, table, boot, tm);
    // Called out of line (through a pointer the optimiser cannot see through), so that
    // its frame (FK of the held strokes) and the construction's are not on the stack
    // together.
    let start: fn(&mut Controller<board::Sliders>) = Controller::start;
    core::hint::black_box(start)(ctl);
    ctl.set_reset_info(reset);
    ctl
}

/// The link service, built in its static slot by a non-inlined function (its frame,
/// with whatever temporary the construction needs, is gone before init's other work).
#[inline(never)]
fn build_link(
    slot: &'static mut MaybeUninit<m2ctl::controller::comms::LinkService>,
    tm: TmConsumer,
) -> &'static mut m2ctl::controller::comms::LinkService {
    slot.write(m2ctl::controller::comms::LinkService::new(tm))
}

/// The worker's request side: hands the next request to the worker where it lies in
/// the queue (by reference, peeked), and takes it off the queue only once the worker
/// took it; a refused request waits there for the next step. Not inlined, like
/// [`step_worker`]: their frames are never on the stack together.
#[inline(never)]
fn take_request(
    worker: &mut Worker<board::TableFlash>,
    requests: &mut heapless::spsc::Consumer<'static, JobRequest, JOB_QUEUE_LEN>,
) {
    if requests.peek().is_some_and(|r| worker.submit(r)) {
        // Taken: the worker copied it.
        drop_front(requests);
    }
}

/// Removes the front request (already copied by the worker).
#[inline(never)]
fn drop_front(requests: &mut heapless::spsc::Consumer<'static, JobRequest, JOB_QUEUE_LEN>) {
    let _ = requests.dequeue();
}

/// One worker step, taken only while the result queue has room for its result (so a
/// result is never held back on the stack or in a side slot).
#[inline(never)]
fn step_worker(
    worker: &mut Worker<board::TableFlash>,
    results: &mut heapless::spsc::Producer<'static, JobResult, JOB_QUEUE_LEN>,
) {
    if !results.ready() {
        return;
    }
    if let Some(r) = worker.step(board::ticks()) {
        // Room was checked above: this cannot fail.
        let _ = results.enqueue(r);
    }
}

#[rtic::app(device = m2ctl::board::active::device, peripherals = false)]
mod app {
    use super::*;
    use board::device::interrupt;
    use board::{Board, ControlTimer, UartErrors, UartRx, UartTx, Watchdog};
    use heapless::spsc::{Consumer, Producer, Queue};
    use m2ctl::controller::comms::LinkService;

    // The controller and the worker live in init's static slots (built in place: the
    // controller alone is ~6 KB, more than init could afford to move on its stack);
    // the resources are references to them.
    #[shared]
    struct Shared {
        ctl: &'static mut Controller<board::Sliders>,
    }

    #[local]
    struct Local {
        timer: ControlTimer,
        watchdog: Watchdog,
        uart_rx: UartRx,
        rx_in: RxIn,
        uart_tx: UartTx,
        tx_out: TxOut,
        link: &'static mut LinkService,
        rx_out: RxOut,
        tx_in: TxIn,
        uart_errors: UartErrors,
        requests_tx: Producer<'static, JobRequest, JOB_QUEUE_LEN>,
        results_rx: Consumer<'static, JobResult, JOB_QUEUE_LEN>,
        worker: &'static mut Worker<board::TableFlash>,
        requests_rx: Consumer<'static, JobRequest, JOB_QUEUE_LEN>,
        results_tx: Producer<'static, JobResult, JOB_QUEUE_LEN>,
        fault_stage: fault_test::Stage,
    }

    #[init(local = [
        rx_q: Queue<u8, RX_QUEUE_LEN> = Queue::new(),
        tx_q: Queue<u8, TX_QUEUE_LEN> = Queue::new(),
        req_q: Queue<JobRequest, JOB_QUEUE_LEN> = Queue::new(),
        res_q: Queue<JobResult, JOB_QUEUE_LEN> = Queue::new(),
        tm_q: TmQueue = TmQueue::new(),
        ctl_slot: MaybeUninit<Controller<board::Sliders>> = MaybeUninit::uninit(),
        worker_slot: MaybeUninit<Worker<board::TableFlash>> = MaybeUninit::uninit(),
        link_slot: MaybeUninit<LinkService> = MaybeUninit::uninit(),
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let mut core = cx.core;
        board::enable_stack_guard(&mut core.MPU, &mut core.SCB);
        let Some(b) = Board::take() else { halt() };

        if !boot_selftest_passes() {
            halt()
        }
        // The telemetry queue: the controller produces, the link service consumes.
        let (tm_in, tm_out) = cx.local.tm_q.split();
        let Some((ctl, worker)) = build_core(
            b.flash,
            b.sliders,
            b.reset,
            TmProducer::new(tm_in),
            cx.local.ctl_slot,
            cx.local.worker_slot,
        ) else {
            halt()
        };

        // Queues and I/O.
        let (uart_rx, uart_tx, uart_errors) = b.uart0.split();
        let (rx_in, rx_out) = cx.local.rx_q.split();
        let (tx_in, tx_out) = cx.local.tx_q.split();
        let (requests_tx, requests_rx) = cx.local.req_q.split();
        let (results_tx, results_rx) = cx.local.res_q.split();
        let mut timer = b.timer;
        let mut watchdog = b.watchdog;
        let fault_stage = fault_test::Stage::after(b.reset.cause);
        timer.start();
        watchdog.start();
        (
            Shared { ctl },
            Local {
                timer,
                watchdog,
                uart_rx,
                rx_in,
                uart_tx,
                tx_out,
                link: build_link(cx.local.link_slot, TmConsumer::new(tm_out)),
                rx_out,
                tx_in,
                uart_errors,
                requests_tx,
                results_rx,
                worker,
                requests_rx,
                results_tx,
                fault_stage,
            },
        )
    }

    /// UART0 receive: one byte into the RX queue.
    #[task(binds = UART_RX, priority = 4, local = [uart_rx, rx_in])]
    fn uart_rx(cx: uart_rx::Context) {
        cx.local.uart_rx.on_interrupt(cx.local.rx_in);
    }

    /// The 1 kHz control task.
    #[task(binds = CONTROL_TIMER, priority = 3, shared = [ctl], local = [timer, watchdog, fault_stage])]
    fn control(mut cx: control::Context) {
        cx.local.timer.acknowledge();
        let timer = &*cx.local.timer;
        let stage = &mut *cx.local.fault_stage;
        cx.shared.ctl.lock(|c| {
            c.control_cycle();
            stage.in_cycle(c.cycle(), timer);
            if timer.tick_pending() {
                c.note_overrun();
            } else {
                c.note_deadline_met();
            }
        });
        cx.local.watchdog.feed();
        rtic::pend(interrupt::LINK_SERVICE);
        rtic::pend(interrupt::WORKER);
    }

    /// The link service: one pass after every control cycle.
    #[task(binds = LINK_SERVICE, priority = 1, shared = [ctl],
           local = [link, rx_out, tx_in, uart_errors, requests_tx, results_rx])]
    fn link_service(cx: link_service::Context) {
        let link = cx.local.link;
        let new_errors = cx.local.uart_errors.take_new();
        if new_errors > 0 {
            link.add_uart_overruns(new_errors);
        }
        let mut shared = cx.shared.ctl;
        let mut ctl = Locked(&mut shared);
        let mut tx = TxQueue {
            queue: cx.local.tx_in,
            pushed: false,
        };
        link.pass(
            &mut ctl,
            &mut RxQueue(cx.local.rx_out),
            &mut WorkerQueues {
                requests: cx.local.requests_tx,
                results: cx.local.results_rx,
            },
            &mut tx,
        );
        if tx.pushed {
            rtic::pend(interrupt::UART_TX);
        }
    }

    /// UART0 transmit: the next byte of the TX queue.
    #[task(binds = UART_TX, priority = 2, local = [uart_tx, tx_out])]
    fn uart_tx(cx: uart_tx::Context) {
        cx.local.uart_tx.on_interrupt(cx.local.tx_out);
    }

    /// The background worker: one step per control period, after the link pass (the
    /// same priority: neither preempts the other, so their stacks never add up).
    #[task(binds = WORKER, priority = 1, local = [worker, requests_rx, results_tx])]
    fn worker(cx: worker::Context) {
        let l = cx.local;
        // A refused request waits in its queue; no step while the result queue is full.
        take_request(l.worker, l.requests_rx);
        step_worker(l.worker, l.results_tx);
    }

    /// Nothing else to do: sleep until the next interrupt.
    #[idle]
    fn idle(_cx: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }
}

/// Test build only (`--features fault-test`, scripts/qemu-fault-test.sh): faults
/// injected on purpose, one stage per boot, chosen by the cause of the last reset:
/// * after power-on: [`OVERRUN_CYCLES`] consecutive overrunning cycles from cycle
///   [`OVERRUN_AT_CYCLE`] (the deadline fault must latch), then the control task hangs
///   at cycle [`HANG_AT_CYCLE`] (the watchdog must reset);
/// * after the watchdog reset: a stack overflow at cycle [`OVERFLOW_AT_CYCLE`] (the
///   MPU guard must fault and reset);
/// * after that: normal operation.
///
/// In the flight image [`fault_test::Stage`] is an empty type that does nothing.
#[cfg(feature = "fault-test")]
mod fault_test {
    use super::*;
    use core::hint::black_box;

    /// First overrunning cycle after power-on.
    pub const OVERRUN_AT_CYCLE: u32 = 1500;
    /// Overrunning cycles in a row.
    pub const OVERRUN_CYCLES: u32 = 5;
    /// The control task hangs at this cycle after power-on.
    pub const HANG_AT_CYCLE: u32 = 4000;
    /// The stack overflows at this cycle after the watchdog reset.
    pub const OVERFLOW_AT_CYCLE: u32 = 1500;
    /// Stack frame of one recursion of the overflow (bytes).
    const OVERFLOW_FRAME_BYTES: usize = 512;

    pub enum Stage {
        OverrunThenHang,
        Overflow,
        Normal,
    }

    impl Stage {
        pub fn after(cause: ResetCause) -> Stage {
            match cause {
                ResetCause::PowerOn => Stage::OverrunThenHang,
                ResetCause::Watchdog => Stage::Overflow,
                _ => Stage::Normal,
            }
        }

        pub fn in_cycle(&mut self, cycle: u32, timer: &board::ControlTimer) {
            match self {
                Stage::OverrunThenHang => {
                    if (OVERRUN_AT_CYCLE..OVERRUN_AT_CYCLE + OVERRUN_CYCLES).contains(&cycle) {
                        while !timer.tick_pending() {}
                    }
                    if cycle == HANG_AT_CYCLE {
                        #[allow(clippy::empty_loop)]
                        loop {}
                    }
                }
                Stage::Overflow => {
                    if cycle == OVERFLOW_AT_CYCLE {
                        black_box(recurse(0));
                    }
                }
                Stage::Normal => {}
            }
        }
    }

    /// Recurses until the stack runs into the guard.
    #[inline(never)]
    fn recurse(depth: u32) -> u32 {
        let mut frame = [0u8; OVERFLOW_FRAME_BYTES];
        black_box(&mut frame);
        if black_box(depth) < u32::MAX {
            recurse(depth + 1).wrapping_add(u32::from(frame.first().copied().unwrap_or(0)))
        } else {
            depth
        }
    }
}

/// The flight image injects nothing.
#[cfg(not(feature = "fault-test"))]
mod fault_test {
    use super::*;

    /// No fault injection.
    pub struct Stage;

    impl Stage {
        pub fn after(_cause: ResetCause) -> Stage {
            Stage
        }

        #[inline(always)]
        pub fn in_cycle(&mut self, _cycle: u32, _timer: &board::ControlTimer) {}
    }
}
