//! Cycle benchmark image (target only, `--features firmware`, built with the flight
//! profile so it measures the flight image's code): the controller, link service and
//! background worker of `m2fw` on the board's slider model and table flash, run one
//! control period at a time in the order the flight image runs them by priority (as
//! `sim::Bench` does on the host): control cycle, link pass, worker step. Each of the
//! three is a separately measured section for the instruction counter
//! (`bench_start`/`bench_end`); its stack depth is measured from the painted stack.
//!
//! Sections: `BENCH n=1` is the empty pair; then every period contributes three
//! sections, control (n), link (n+1), worker (n+2). A `GROUP name=.. first=n
//! periods=k` line (defmt log) names the periods of each scenario: idle, a move, a TC
//! burst, housekeeping, a table upload, the background commit, the activation, the
//! scrubs, a move check TC[8,1] 0x0006, set parameters TC[20,3], four scheduled
//! (ST[11]) move checks released in one pass.
//! `STACK part=.. peak_bytes=..` lines give the deepest stack of each part; `BOOT` the
//! boot path's. `scripts/bench.sh` joins the two. Exits through semihosting (0 if
//! every scenario did what it should, so the figures are what they claim).
#![no_std]
#![no_main]

use core::mem::MaybeUninit;

use cortex_m as _; // critical-section implementation (single core) for defmt
use cortex_m_rt::entry;
use defmt_semihosting as _;
use heapless::Deque;
use m2ctl::board::active::{self as hw, Board, Sliders, TableFlash};
use m2ctl::controller::comms::{JobPort, LinkService, RxBytes, TxBytes};
use m2ctl::controller::{Controller, JobRequest, JobResult, ResetCause, State, Worker};
use m2ctl::hw::SliderDrives;
use m2ctl::link::command::ParameterValues;
use m2ctl::link::command::WirePose;
use m2ctl::link::schedule::{ActivityBlock, ScheduleCommand, MAX_SCHEDULED_TC_LEN};
use m2ctl::link::tc::{encode_telecommand, TcHeader};
use m2ctl::link::TmTime;
use m2ctl::link::{encode_frame, Command, MAX_TC_PACKET_LEN};
use m2ctl::pass::Period;
use m2ctl::table::{Table, TableStore, ValidationConfig};
use m2ctl::timing::{cycle_to_us, HK_PERIOD_CYCLES};

/// A panic is a defect: end the run with the board's panic exit code.
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    defmt::error!("PANIC");
    hw::exit(hw::EXIT_PANIC)
}

/// Uplink bytes the bench can hold (one TC burst).
const UPLINK_LEN: usize = 2048;
/// Largest frame of one telecommand (bytes).
const TC_FRAME_LEN: usize = 2 * MAX_TC_PACKET_LEN + 4;
/// Idle periods measured.
const IDLE_PERIODS: u32 = 20;
/// The scenarios' move (and move check): 0.8/-0.6/0.4 mm, 45/-30/20 arcsec.
const MOVE_TARGET: WirePose = WirePose {
    translation_nm: [800_000, -600_000, 400_000],
    rotation_uas: [45_000_000, -30_000_000, 20_000_000],
};
/// Time-tagged move checks released in one pass (= `MAX_TC_PER_PASS`, the most one
/// pass takes).
const SCHEDULED_CHECKS: usize = m2ctl::controller::comms::MAX_TC_PER_PASS;
/// Scheduled move checks per TC[11,4] (its application data holds at most three moves).
const CHECKS_PER_INSERT: usize = 2;
/// The scheduled checks are released this many control cycles after their insert.
const RELEASE_AFTER_CYCLES: u32 = 50;
/// Parameter ID of the housekeeping period (TC[20,3]).
const HK_PERIOD_PARAM_ID: u16 = 0x0020;
/// Most periods a scenario may take before it counts as failed.
const MAX_PERIODS: u32 = 20_000;
/// Table ID of the table the benchmark uploads and commits.
const BENCH_TABLE_ID: u32 = 9;

/// Stack peak of each part (bytes).
#[derive(Default)]
struct Peaks {
    control: u32,
    link: u32,
    worker: u32,
}

/// Bytes waiting on the uplink.
struct Uplink(Deque<u8, UPLINK_LEN>);

impl RxBytes for Uplink {
    fn pop(&mut self) -> Option<u8> {
        self.0.pop_front()
    }
}

/// Downlink that only counts bytes (unlimited room, like an empty TX queue).
struct Downlink {
    bytes: u32,
    frames: u32,
}

impl TxBytes for Downlink {
    fn free(&self) -> usize {
        usize::MAX
    }
    fn push(&mut self, frame: &[u8]) {
        self.bytes = self.bytes.wrapping_add(frame.len() as u32);
        self.frames = self.frames.wrapping_add(1);
    }
}

/// The worker behind the job port, results in a small queue (the flight image: two
/// spsc queues).
struct Port<'a> {
    worker: &'a mut Worker<TableFlash>,
    results: &'a mut Deque<JobResult, 2>,
}

impl JobPort for Port<'_> {
    fn send(&mut self, request: &JobRequest) -> bool {
        self.worker.submit(request)
    }
    fn recv(&mut self) -> Option<JobResult> {
        self.results.pop_front()
    }
}

struct Rig {
    ctl: &'static mut Controller<Sliders>,
    worker: &'static mut Worker<TableFlash>,
    link: LinkService,
    timer: hw::ControlTimer,
    up: Uplink,
    down: Downlink,
    results: Deque<JobResult, 2>,
    peaks: Peaks,
    /// Stack depth of the bench itself where a period's parts are called (bytes):
    /// subtracted from each part's painted peak.
    base_depth_bytes: u32,
    /// Sections measured so far (the counter's `n` of the last one).
    sections: u32,
    seq: u16,
}

impl Period for Rig {
    fn control(&mut self) {
        hw::repaint_stack();
        self.control_part();
        self.peaks.control = self.peaks.control.max(self.part_peak_bytes());
    }

    fn link(&mut self) {
        hw::repaint_stack();
        self.link_part();
        self.peaks.link = self.peaks.link.max(self.part_peak_bytes());
    }

    fn worker(&mut self) {
        hw::repaint_stack();
        let r = self.worker_part();
        self.peaks.worker = self.peaks.worker.max(self.part_peak_bytes());
        if let Some(r) = r {
            let _ = self.results.push_back(r);
        }
    }
}

impl Rig {
    /// One control period in the firmware's order (`m2ctl::pass::period`, the one
    /// description of that order): control cycle, link pass, worker step, each measured
    /// ([`Period`] below; each in its own function, as in the flight image's tasks, so
    /// the bench's stack does not carry all three frames at once).
    #[inline(never)]
    fn period(&mut self) {
        self.timer.acknowledge();
        self.base_depth_bytes = hw::stack_depth_bytes();
        m2ctl::pass::period(self);
        self.sections += 3;
    }

    /// The painted stack peak since the last repaint, less the bench's own depth.
    fn part_peak_bytes(&self) -> u32 {
        hw::stack_peak_bytes().saturating_sub(self.base_depth_bytes)
    }

    #[inline(never)]
    fn control_part(&mut self) {
        hw::bench_start();
        self.ctl.control_cycle();
        hw::bench_end();
    }

    #[inline(never)]
    fn link_part(&mut self) {
        hw::bench_start();
        let mut ctl: &mut Controller<Sliders> = self.ctl;
        let mut port = Port {
            worker: self.worker,
            results: &mut self.results,
        };
        self.link
            .pass(&mut ctl, &mut self.up, &mut port, &mut self.down);
        hw::bench_end();
    }

    #[inline(never)]
    fn worker_part(&mut self) -> Option<JobResult> {
        hw::bench_start();
        let r = self.worker.step(hw::ticks());
        hw::bench_end();
        r
    }

    /// Frames `cmd` onto the uplink.
    #[inline(never)]
    fn queue(&mut self, cmd: &Command) -> bool {
        let mut pkt = [0u8; MAX_TC_PACKET_LEN];
        let mut frame = [0u8; TC_FRAME_LEN];
        let Ok(n) = encode_telecommand(cmd, TcHeader::new(self.seq), &mut pkt) else {
            return false;
        };
        self.seq = self.seq.wrapping_add(1);
        let Some(p) = pkt.get(..n) else { return false };
        let Ok(fl) = encode_frame(p, &mut frame) else {
            return false;
        };
        frame
            .get(..fl)
            .is_some_and(|f| f.iter().all(|b| self.up.0.push_back(*b).is_ok()))
    }

    /// A TC[11,4] inserting [`CHECKS_PER_INSERT`] copies of `cmd`, all released at
    /// `release` (each its own packet, with its own sequence count).
    #[inline(never)]
    fn schedule_insert(&mut self, release: TmTime, cmd: &Command) -> Option<Command> {
        let mut pkts = [[0u8; MAX_SCHEDULED_TC_LEN]; CHECKS_PER_INSERT];
        let mut lens = [0usize; CHECKS_PER_INSERT];
        for (pkt, len) in pkts.iter_mut().zip(lens.iter_mut()) {
            *len = encode_telecommand(cmd, TcHeader::new(self.seq), pkt).ok()?;
            self.seq = self.seq.wrapping_add(1);
        }
        let mut acts: heapless::Vec<(TmTime, &[u8]), CHECKS_PER_INSERT> = heapless::Vec::new();
        for (pkt, len) in pkts.iter().zip(lens.iter()) {
            acts.push((release, pkt.get(..*len)?)).ok()?;
        }
        let block = ActivityBlock::new(&acts).ok()?;
        Some(Command::Schedule(ScheduleCommand::Insert(block)))
    }

    /// One lock body `f` as its own measured section, named `name` (`LOCK` line).
    #[inline(never)]
    fn lock_section<R>(&mut self, name: &str, f: impl FnOnce(&mut Controller<Sliders>) -> R) -> R {
        let ctl = &mut *self.ctl;
        hw::bench_start();
        let r = f(ctl);
        hw::bench_end();
        self.sections += 1;
        defmt::info!("LOCK name={=str} section={=u32}", name, self.sections);
        r
    }

    /// `cmd` handed to the controller as the link service does it (one lock body).
    #[inline(never)]
    fn lock_tc(&mut self, name: &str, cmd: &Command) -> bool {
        let mut pkt = [0u8; MAX_TC_PACKET_LEN];
        let Ok(n) = encode_telecommand(cmd, TcHeader::new(self.seq), &mut pkt) else {
            return false;
        };
        self.seq = self.seq.wrapping_add(1);
        let Some(p) = pkt.get(..n) else { return false };
        self.lock_section(name, |c| m2ctl::controller::comms::deliver(c, p));
        true
    }

    /// Runs `periods` periods as the group `name`.
    fn group(&mut self, name: &str, periods: u32) {
        let first = self.sections + 1;
        for _ in 0..periods {
            self.period();
        }
        defmt::info!(
            "GROUP name={=str} first={=u32} periods={=u32}",
            name,
            first,
            periods
        );
    }

    /// Runs periods as the group `name` until `done` holds (at most [`MAX_PERIODS`]);
    /// returns whether it did.
    fn group_until(&mut self, name: &str, mut done: impl FnMut(&mut Rig) -> bool) -> bool {
        let first = self.sections + 1;
        let mut n = 0;
        let mut ok = false;
        while n < MAX_PERIODS {
            self.period();
            n += 1;
            if done(self) {
                ok = true;
                break;
            }
        }
        defmt::info!(
            "GROUP name={=str} first={=u32} periods={=u32}",
            name,
            first,
            n
        );
        ok
    }
}

#[entry]
fn main() -> ! {
    // In static storage from the start (cortex-m-rt turns an entry's `static mut` into
    // a `&'static mut`): built on the stack, its 22 KB would overflow it.
    static mut TM_QUEUE: m2ctl::controller::TmQueue = m2ctl::controller::TmQueue::new();
    hw::bench_start();
    hw::bench_end();
    let ok = run(TM_QUEUE);
    hw::exit(if ok { hw::EXIT_PASS } else { hw::EXIT_FAIL })
}

fn run(tm_queue: &'static mut m2ctl::controller::TmQueue) -> bool {
    let Some(b) = Board::take() else {
        return false;
    };
    // A fault resets the board (the flight image's handlers): in a benchmark image
    // that is a failure to report, not a run to repeat.
    if b.reset.cause != ResetCause::PowerOn {
        defmt::error!(
            "bench: restarted after a reset (cause {=u8})",
            b.reset.cause.code()
        );
        return false;
    }
    let (tm_in, tm_out) = tm_queue.split();
    let tm_out = m2ctl::controller::TmConsumer::new(tm_out);
    let Some((ctl, worker)) = boot(
        b.flash,
        b.sliders,
        m2ctl::controller::TmProducer::new(tm_in),
    ) else {
        return false;
    };
    defmt::info!(
        "SIZES controller_bytes={=u32} worker_bytes={=u32}",
        core::mem::size_of::<Controller<Sliders>>() as u32,
        core::mem::size_of::<Worker<TableFlash>>() as u32
    );
    // The bench's own state in a static, not on the measured stack.
    let Some(rig) = cortex_m::singleton!(: Rig = Rig {
        ctl,
        worker,
        link: LinkService::new(tm_out),
        timer: b.timer,
        up: Uplink(Deque::new()),
        down: Downlink {
            bytes: 0,
            frames: 0,
        },
        results: Deque::new(),
        peaks: Peaks::default(),
        base_depth_bytes: 0,
        sections: 1,
        seq: 1,
    }) else {
        return false;
    };
    // The lock bodies after the scenarios, not inside them (the bench's own frames
    // are not on the stack twice).
    let ok = scenarios(rig) && lock_bodies(rig, &MOVE_TARGET);
    if !ok {
        defmt::error!("bench: a scenario or a lock body did not do what it should");
    }
    defmt::info!("STACK part=control peak_bytes={=u32}", rig.peaks.control);
    defmt::info!("STACK part=link peak_bytes={=u32}", rig.peaks.link);
    defmt::info!("STACK part=worker peak_bytes={=u32}", rig.peaks.worker);
    defmt::info!(
        "bench: {=u32} TM frames, {=u32} bytes; state {=u8}, faults {=u32:#x}",
        rig.down.frames,
        rig.down.bytes,
        rig.ctl.state().code(),
        rig.ctl.faults().bits()
    );
    ok
}

/// Boot path, as m2fw's init: worker (owning the table store) and controller built in
/// static slots, boot selection in between; prints the path's stack depth.
#[inline(never)]
fn boot(
    flash: TableFlash,
    sliders: Sliders,
    tm: m2ctl::controller::TmProducer,
) -> Option<(
    &'static mut Controller<Sliders>,
    &'static mut Worker<TableFlash>,
)> {
    let ctl_slot =
        cortex_m::singleton!(: MaybeUninit<Controller<Sliders>> = MaybeUninit::uninit())?;
    let worker_slot =
        cortex_m::singleton!(: MaybeUninit<Worker<TableFlash>> = MaybeUninit::uninit())?;
    let base = hw::stack_depth_bytes();
    hw::repaint_stack();
    let worker = build_worker(worker_slot, flash)?;
    let (table, boot) = boot_selection(worker);
    let ctl = build_controller(ctl_slot, sliders, table, boot, tm);
    ctl.restore_parameters(&worker.store_mut().parameters());
    defmt::info!(
        "BOOT stack_peak_bytes={=u32}",
        hw::stack_peak_bytes().saturating_sub(base)
    );
    Some((ctl, worker))
}

// Each part of the boot path out of line, as m2fw's init builds them: the worker, the
// selection and the controller are then never on the stack together (one function
// holding all three overflowed the 12 KiB stack once the worker grew).
#[inline(never)]
fn build_worker(
    slot: &'static mut MaybeUninit<Worker<TableFlash>>,
    flash: TableFlash,
) -> Option<&'static mut Worker<TableFlash>> {
    let store = TableStore::new(flash, hw::TABLE_LAYOUT).ok()?;
    Some(slot.write(Worker::new(store, ValidationConfig::flight())))
}

#[inline(never)]
fn boot_selection(worker: &mut Worker<TableFlash>) -> (Table, m2ctl::table::BootReport) {
    worker.boot()
}

#[inline(never)]
fn build_controller(
    slot: &'static mut MaybeUninit<Controller<Sliders>>,
    mut sliders: Sliders,
    table: Table,
    boot: m2ctl::table::BootReport,
    tm: m2ctl::controller::TmProducer,
) -> &'static mut Controller<Sliders> {
    sliders.hold();
    let ctl = Controller::unstarted_in(slot, sliders, table, boot, tm);
    let start: fn(&mut Controller<Sliders>) = Controller::start;
    core::hint::black_box(start)(ctl);
    ctl
}

#[inline(never)]
fn scenarios(r: &mut Rig) -> bool {
    // Past the boot events and the first housekeeping.
    r.group("boot", 2);
    r.group("idle", IDLE_PERIODS);

    // A move of 0.8/-0.6/0.4 mm, 45/-30/20 arcsec: its telecommand, planning, cruise,
    // arrival, with a housekeeping report every second.
    let target = MOVE_TARGET;
    if !r.queue(&Command::MoveAbsolute(target)) {
        return false;
    }
    let moved = r.group_until("move", |r| {
        r.ctl.state() == State::Idle && r.ctl.housekeeping().pose_commanded.translation_nm[0] != 0
    });

    // Housekeeping: the period that queues the periodic report and the next (encoding).
    while r.ctl.cycle() % HK_PERIOD_CYCLES != HK_PERIOD_CYCLES - 1 {
        r.period();
    }
    r.group("housekeeping", 2);

    // A TC burst: eight telecommands in one write (ping, one-shot HK, ...), handled at
    // most MAX_TC_PER_PASS per pass.
    let burst = [
        Command::Ping,
        Command::HousekeepingOneShot,
        Command::Ping,
        Command::HousekeepingOneShot,
        Command::Ping,
        Command::Stop,
        Command::Ping,
        Command::HousekeepingOneShot,
    ];
    if !burst.iter().all(|c| r.queue(c)) {
        return false;
    }
    let burst_done = r.group_until("tc_burst", |r| {
        r.up.0.is_empty() && r.link.queue().is_empty()
    });

    // Table upload (chunks in one write), commit (background job: validation, erase,
    // program), activation.
    let mut table = Table::nominal();
    table.table_id = BENCH_TABLE_ID;
    table.legs[0].a_mm[0] += 0.02;
    let bytes = table.to_bytes();
    for (off, chunk) in m2ctl::link::tm::dump_chunks(&bytes) {
        match m2ctl::link::TableChunk::new(off, chunk) {
            Ok(c) => {
                if !r.queue(&Command::LoadTableChunk(c)) {
                    return false;
                }
            }
            Err(_) => return false,
        }
    }
    let uploaded = r.group_until("upload", |r| r.up.0.is_empty());
    if !r.queue(&Command::CommitTable {
        crc32: table.crc32(),
    }) {
        return false;
    }
    let committed = r.group_until("commit", |r| r.ctl.pending_table().is_some());
    if !r.queue(&Command::ActivateTable {
        table_id: table.table_id,
        crc32: table.crc32(),
    }) {
        return false;
    }
    let activated = r.group_until("activate", |r| {
        r.ctl.active_table().table_id == BENCH_TABLE_ID
    });
    // A scrub of the RAM table and both banks once more after the change.
    r.group("scrub", 1_100);
    let clean = r.ctl.faults().is_empty() && r.ctl.housekeeping().bank_health == 0;

    // A move check TC[8,1] 0x0006 of the same 0.8 mm / 45" move: the whole straight path
    // checked (IK of every sample, FK) in one telecommand, so in one link-service lock:
    // its link pass bounds how long the control task may wait for that lock.
    if !r.queue(&Command::CheckMove(target)) {
        return false;
    }
    let checked = r.group_until("check_move", |r| {
        r.up.0.is_empty() && r.link.queue().is_empty()
    });

    // Set parameters TC[20,3] (housekeeping period, the default value): persisted by
    // the worker (a selection record write), then applied.
    let Ok(values) = ParameterValues::new(&[(HK_PERIOD_PARAM_ID, HK_PERIOD_CYCLES as i32)]) else {
        return false;
    };
    if !r.queue(&Command::SetParameters(values)) {
        return false;
    }
    let generation_before = r.ctl.housekeeping().tc_accepted;
    let params_set = r.group_until("set_parameters", |r| {
        r.ctl.housekeeping().job == 0 && r.link.queue().is_empty() && r.up.0.is_empty()
    }) && r.ctl.housekeeping().tc_accepted == generation_before.wrapping_add(1);

    // Four time-tagged move checks released by the schedule (ST[11]) in one pass: two
    // TC[11,4] (at most three moves fit in one) inserting them with the same release
    // time, 50 periods from now.
    let released_before = r.ctl.housekeeping().schedule.released;
    let release = TmTime::from_micros(cycle_to_us(u64::from(
        r.ctl.cycle().wrapping_add(RELEASE_AFTER_CYCLES),
    )));
    for _ in 0..SCHEDULED_CHECKS / CHECKS_PER_INSERT {
        let Some(insert) = r.schedule_insert(release, &Command::CheckMove(target)) else {
            return false;
        };
        if !r.queue(&insert) {
            return false;
        }
    }
    let released = r.group_until("releases", |r| {
        r.ctl.housekeeping().schedule.released
            == released_before.wrapping_add(SCHEDULED_CHECKS as u16)
            && r.link.queue().is_empty()
    });
    let clean = clean && r.ctl.faults().is_empty();
    if !(moved
        && burst_done
        && uploaded
        && committed
        && activated
        && checked
        && params_set
        && released
        && clean)
    {
        defmt::error!(
            "bench: scenario failed: moved {=bool} burst {=bool} upload {=bool} commit {=bool} activate {=bool} check {=bool} params {=bool} releases {=bool} clean {=bool}",
            moved,
            burst_done,
            uploaded,
            committed,
            activated,
            checked,
            params_set,
            released,
            clean
        );
        return false;
    }
    true
}

/// The controller's lock bodies, each measured alone (a `LOCK name=.. section=n` line
/// names its section): what the link service runs while it holds the lock, so the
/// longest a control cycle may wait for it (RTIC's priority ceiling: one lock body).
/// At rest, after the scenarios: a telecommand of each kind the link hands over
/// (a move check only queues its copy; the move starts its planning), the pieces of a
/// move check's report, a housekeeping record's content, a job request handed on, and
/// the activation of a table (`job_finished`, the worker's `Selected`).
#[inline(never)]
fn lock_bodies(r: &mut Rig, target: &WirePose) -> bool {
    let mut ok = true;
    for (name, cmd) in [
        ("tc_ping", Command::Ping),
        ("tc_hk_one_shot", Command::HousekeepingOneShot),
        ("tc_check_move", Command::CheckMove(*target)),
    ] {
        ok &= r.lock_tc(name, &cmd);
    }
    // The move check the last TC queued: taken, evaluated unlocked, reported.
    let mut slot = None;
    r.lock_section("check_take", |c| c.take_move_check(&mut slot));
    ok &= slot.is_some();
    if let Some(job) = &slot {
        let check = job.evaluate();
        let token = job.token();
        r.lock_section("check_report", |c| c.finish_move_check(token, check));
    }
    // What a per-cycle check of the running geometry would cost (issue 19: the
    // flight image re-derives it in the 1 s scrub instead).
    let word = r.lock_section("geometry_check_word", |c| c.geometry_check_word());
    ok &= word != 0;
    // Telemetry records are complete when queued: the link takes them without the
    // controller's lock (no lock body to measure; the dump's is its telecommand's).
    ok &= r.lock_tc(
        "tc_dump",
        &Command::DumpTable(m2ctl::link::MemoryId::ActiveTable),
    );
    // A move: accepted, its planning started (the samples come in the control cycles).
    // (Back toward home: the bench is at `target` already.)
    let back = WirePose {
        translation_nm: target.translation_nm.map(|v| -v / 2),
        rotation_uas: target.rotation_uas.map(|v| -v / 2),
    };
    ok &= r.lock_tc("tc_move_absolute", &Command::MoveAbsolute(back));
    ok &= r.ctl.state() == State::Moving;
    while r.ctl.state() != State::Idle {
        r.ctl.control_cycle();
    }
    // TC[20,3] set parameters (a job request queued), the worker's answer applied
    // (derived settings and thresholds), the request handed on to the worker's queue.
    let Ok(values) = ParameterValues::new(&[(HK_PERIOD_PARAM_ID, HK_PERIOD_CYCLES as i32)]) else {
        return false;
    };
    ok &= r.lock_tc("tc_set_parameters", &Command::SetParameters(values));
    let mut handed = false;
    r.lock_section("job_request_handed_on", |c| {
        c.offer_job_request(|_| {
            handed = true;
            true
        })
    });
    ok &= handed;
    let params = *r.ctl.parameters();
    r.lock_section("job_finished_parameters", |c| {
        c.job_finished(&JobResult::ParametersSaved(params))
    });
    // A TC[11,4] of two move checks (parsed, checked, inserted), then deleted again.
    let release = TmTime::from_micros(cycle_to_us(u64::from(
        r.ctl.cycle().wrapping_add(RELEASE_AFTER_CYCLES),
    )));
    if let Some(insert) = r.schedule_insert(release, &Command::CheckMove(*target)) {
        ok &= r.lock_tc("tc_schedule_insert", &insert);
    } else {
        ok = false;
    }
    ok &= r.lock_tc(
        "tc_schedule_reset",
        &Command::Schedule(ScheduleCommand::Reset),
    );
    // A table activation as the worker's answer: derive, swap, hold (FK).
    let mut table = Table::nominal();
    table.table_id = BENCH_TABLE_ID.wrapping_add(1);
    let result = JobResult::Selected {
        table,
        geom: m2ctl::controller::jobs::derive_geometry(&table),
        selection: m2ctl::table::Selection::nominal(),
    };
    r.lock_section("job_finished_selected", |c| c.job_finished(&result));
    ok &= r.ctl.active_table().table_id == table.table_id;
    // Drain what these queued.
    while r.link.queue().pop().is_some() {}
    ok
}
