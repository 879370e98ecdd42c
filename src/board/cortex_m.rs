//! The Cortex-M4 core parts every board has, written once (each board re-exports
//! them): the reset record in no-init RAM (reset cause, boot counter), the fault
//! handlers that record their cause and reset (HardFault, MemManage, unexpected
//! interrupts), the MPU stack guard, stack painting and peak, and for the test images
//! the semihosting exit and the instruction-count markers. What differs between boards
//! comes from the board's `memory.x` (the STACK region) or stays in the board (the
//! mps2-an386 watchdog's NMI).
#![allow(unsafe_code)] // Core registers, linker symbols, no-init and painted RAM.

use core::mem::MaybeUninit;
use core::ptr::{addr_of, addr_of_mut, read_volatile, write_volatile};
use core::sync::atomic::{AtomicU32, Ordering};

use super::memory_x;
use crate::hw::{ResetCause, ResetInfo};

// ---------------------------------------------------------------------------------
// Reset record: four words in `.uninit` (cortex-m-rt's section that is not zeroed at
// boot; RAM keeps them across a system or watchdog reset, and so does QEMU: they are
// in no loaded segment).

pub(super) mod reset_record {
    use super::*;

    /// Marks a record written by this firmware.
    const MAGIC: u32 = 0x4D32_5253; // "M2RS"
    /// Cause word while the firmware runs: no reset announced.
    const CAUSE_NONE: u32 = 0xFF;

    #[link_section = ".uninit.m2_reset_record"]
    static mut RECORD: MaybeUninit<[u32; 4]> = MaybeUninit::uninit();

    fn word(i: usize) -> *mut u32 {
        // SAFETY: `add(i)` stays inside RECORD (four u32 words): the only callers,
        // `read` and `write` below, pass 0..=3. `addr_of_mut!` takes the address without
        // making a reference to the `static mut`.
        unsafe { addr_of_mut!(RECORD).cast::<u32>().add(i) }
    }

    fn check(cause: u32, count: u32) -> u32 {
        !(MAGIC ^ cause ^ count.rotate_left(8))
    }

    fn read() -> Option<(u32, u32)> {
        // SAFETY: aligned volatile reads of RECORD's four words (`word`), RAM that holds
        // whatever bits the last run or power-on left; every bit pattern is a valid u32,
        // and a record not written whole fails its check word below. Only this module
        // touches RECORD, never through a reference; single core: `on_boot` (init) and
        // `announce` (a fault or NMI handler, just before the reset) can preempt each
        // other but never run at once.
        let w = unsafe { [0, 1, 2, 3].map(|i| read_volatile(word(i))) };
        (w[0] == MAGIC && w[3] == check(w[1], w[2])).then_some((w[1], w[2]))
    }

    fn write(cause: u32, count: u32) {
        // SAFETY: aligned volatile writes of RECORD's four words (`word`), plain RAM
        // that no other code uses (`.uninit`, no reference to it exists); a write cut
        // short by a fault leaves a record whose check word fails (see `read`).
        unsafe {
            write_volatile(word(0), MAGIC);
            write_volatile(word(1), cause);
            write_volatile(word(2), count);
            write_volatile(word(3), check(cause, count));
        }
    }

    /// At boot: the cause the last reset recorded and the boot count; re-arms the
    /// record. No valid record (the first boot after power-on, also after a power cut:
    /// no-init RAM does not keep it): power-on, boot count 1. A valid record without an
    /// announced cause: a reset software did not announce, whose cause the board gives
    /// (`unannounced`: on mps2-an386 an external reset, the watchdog announcing itself
    /// from its NMI; on the STM32 what its reset flags say).
    pub fn on_boot(unannounced: ResetCause) -> ResetInfo {
        let (cause, count) = match read() {
            None => (ResetCause::PowerOn, 1),
            Some((c, n)) => {
                let cause = match u8::try_from(c).ok().and_then(ResetCause::from_code) {
                    Some(cause) => cause,
                    None => unannounced,
                };
                (cause, n.wrapping_add(1))
            }
        };
        write(CAUSE_NONE, count);
        ResetInfo {
            cause,
            boot_count: (count & 0xFFFF) as u16,
        }
    }

    /// Records the cause of the coming reset (keeps the boot count).
    pub fn announce(cause: ResetCause) {
        let count = read().map_or(0, |(_, n)| n);
        write(u32::from(cause.code()), count);
    }
}

/// Records `cause` in the reset record and resets the system.
pub fn record_and_reset(cause: ResetCause) -> ! {
    reset_record::announce(cause);
    cortex_m::peripheral::SCB::sys_reset()
}

/// Entered from the fault trampoline with a fresh stack.
extern "C" fn fault_reset() -> ! {
    record_and_reset(ResetCause::HardFault)
}

// HardFault and MemManage: the stack pointer may be in the guard region (a stack
// overflow), so the handler pushes nothing: it resets MSP to the top of the stack,
// then records the cause and resets the system.
core::arch::global_asm!(
    ".section .text.m2_fault_entry,\"ax\",%progbits",
    ".global HardFault",
    ".type HardFault,%function",
    ".thumb_func",
    "HardFault:",
    ".global MemoryManagement",
    ".type MemoryManagement,%function",
    ".thumb_func",
    "MemoryManagement:",
    "ldr r0, =_stack_start",
    "msr msp, r0",
    "b {reset}",
    ".ltorg",
    reset = sym fault_reset,
);

/// An interrupt or exception without a handler: a defect; record and reset.
// SAFETY: cortex-m-rt requires `unsafe fn` here because this handler also serves the NMI
// (on a board that binds none) and can preempt any critical section. It touches no data
// a critical section guards: only the reset record (volatile words of its own) and the
// SCB's reset request. Only the hardware calls it, through the vector table.
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(_irqn: i16) {
    record_and_reset(ResetCause::HardFault)
}

// ---------------------------------------------------------------------------------
// Stack: the single stack (RTIC's one shared stack) of `memory.x`'s STACK region, at
// the bottom of RAM; below it an MPU region with no access (on either board nothing the
// firmware uses lies there), so an overflow faults (MemManage) instead of reaching
// anything.

extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}

/// Size of the stack (bytes), from `memory.x`.
pub const STACK_BYTES: u32 = memory_x::STACK_LENGTH;
/// Size of the guard region below the stack (bytes; a power of two, the stack bottom
/// aligned to it, as the MPU requires).
pub const STACK_GUARD_BYTES: u32 = 1 << 20;
// The guard must be a valid MPU region at the stack bottom.
const _: () = assert!(STACK_GUARD_BYTES.is_power_of_two() && STACK_GUARD_BYTES >= 32);
const _: () = assert!(memory_x::STACK_ORIGIN % STACK_GUARD_BYTES == 0);
const _: () = assert!(memory_x::STACK_ORIGIN >= STACK_GUARD_BYTES);

/// MPU RASR: execute never, region enable; SIZE field is log2(size) - 1; AP 0 = no
/// access.
const RASR_XN: u32 = 1 << 28;
const RASR_ENABLE: u32 = 1;
/// MPU CTRL: enable, default memory map for privileged code elsewhere.
const MPU_CTRL_ENABLE: u32 = 1 << 0;
const MPU_CTRL_PRIVDEFENA: u32 = 1 << 2;

/// Makes the region below the stack fault on any access, and MemManage faults taken
/// at the highest configurable priority (above every task). Call once from init.
pub fn enable_stack_guard(
    mpu: &mut cortex_m::peripheral::MPU,
    scb: &mut cortex_m::peripheral::SCB,
) {
    let base = memory_x::STACK_ORIGIN - STACK_GUARD_BYTES;
    let size_field = STACK_GUARD_BYTES.trailing_zeros() - 1;
    // SAFETY: region 0 covers only the unused space below the stack (nothing is linked
    // or mapped there on either board: the asserts above tie it to memory.x); the
    // default map stays in force everywhere else (PRIVDEFENA), so no code or data
    // becomes inaccessible. MemManage at priority 0 preempts every task, which is sound
    // because its handler (the fault entry above) shares no data with them: it records
    // the cause and resets.
    unsafe {
        mpu.rnr.write(0);
        mpu.rbar.write(base);
        mpu.rasr.write(RASR_XN | (size_field << 1) | RASR_ENABLE);
        mpu.ctrl.write(MPU_CTRL_ENABLE | MPU_CTRL_PRIVDEFENA);
        scb.set_priority(
            cortex_m::peripheral::scb::SystemHandler::MemoryManagement,
            0,
        );
    }
    scb.enable(cortex_m::peripheral::scb::Exception::MemoryManagement);
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}

/// Value cortex-m-rt's `paint-stack` writes over the stack before `main`.
const STACK_PAINT: u32 = 0xCCCC_CCCC;

fn stack_bounds() -> (usize, usize) {
    (
        addr_of!(_stack_end) as usize,
        addr_of!(_stack_start) as usize,
    )
}

/// Lowest stack address found used so far (`u32::MAX`: not measured yet).
static STACK_DEEPEST: AtomicU32 = AtomicU32::new(u32::MAX);
/// Window below the deepest known use where the scan starts (bytes): a part that went
/// deeper than that scrubbed the word at the window's start, and the scan falls back
/// to the whole region.
const STACK_SCAN_WINDOW_BYTES: usize = 1024;

/// Where the paint may have been scrubbed since the last measurement: a window below
/// the deepest known use, or the whole region.
fn scan_from() -> usize {
    let (lo, _) = stack_bounds();
    match STACK_DEEPEST.load(Ordering::Relaxed) {
        u32::MAX => lo,
        d => {
            let start = (d as usize).saturating_sub(STACK_SCAN_WINDOW_BYTES).max(lo);
            // SAFETY: `start` is in [lo, d]: `d` is an address a scan of the stack region
            // found (lo <= d <= hi, a multiple of 4 as lo is) and `start` is no lower than
            // lo, so an aligned word of the stack region's RAM; read as a plain u32 (any
            // value is valid), never through a reference.
            if unsafe { read_volatile(start as *const u32) } == STACK_PAINT {
                start
            } else {
                lo
            }
        }
    }
}

/// Bytes of stack used so far (since the last [`repaint_stack`]): scans the painted
/// region upwards for the first word that is no longer the paint value.
pub fn stack_peak_bytes() -> u32 {
    let (_, hi) = stack_bounds();
    let mut p = scan_from();
    // SAFETY: `p` starts in [lo, hi) word-aligned (`scan_from`) and is read only while
    // `p < hi`: words of the linker script's stack region, plain RAM, read volatile as
    // u32 (any value is valid; words that live frames use are read, never referenced).
    while p < hi && unsafe { read_volatile(p as *const u32) } == STACK_PAINT {
        p += 4;
    }
    STACK_DEEPEST.fetch_min(p as u32, Ordering::Relaxed);
    (hi - p) as u32
}

/// Size of the stack region (bytes) between `_stack_end` and `_stack_start`.
pub fn stack_region_bytes() -> u32 {
    let (lo, hi) = stack_bounds();
    (hi - lo) as u32
}

/// Bytes of stack in use at the caller (top of the stack minus the stack pointer).
pub fn stack_depth_bytes() -> u32 {
    let (_, hi) = stack_bounds();
    (hi as u32).wrapping_sub(cortex_m::register::msp::read())
}

/// Margin left unpainted below the stack pointer by [`repaint_stack`] (bytes): this
/// function's own frame.
const REPAINT_MARGIN_BYTES: usize = 64;

/// Paints the unused stack again (below the caller's frame, down to the deepest point
/// used so far), so that a later [`stack_peak_bytes`] measures the deepest use since
/// now (benchmark images).
#[inline(never)]
pub fn repaint_stack() {
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = scan_from();
    while p + REPAINT_MARGIN_BYTES < sp {
        // SAFETY: `p` is word-aligned, at least `lo` (`scan_from`) and below this
        // frame's stack pointer by more than the margin: stack region no live frame
        // uses. An interrupt that preempts uses it only while it runs, when this loop
        // does not, so the paint overwrites no live data.
        unsafe { write_volatile(p as *mut u32, STACK_PAINT) };
        p += 4;
    }
}

// ---------------------------------------------------------------------------------
// Test images only: semihosting exit and instruction-count markers.

/// Ends the QEMU run with an exit code (0 = pass). Test images only: without a
/// debugger, semihosting is a fault; the flight image never calls it.
pub fn exit(code: i32) -> ! {
    semihosting::process::exit(code)
}

/// Exit code of a test image whose every check passed.
pub const EXIT_PASS: i32 = 0;
/// Exit code of a test image in which a check failed (its figures would not be what
/// they claim).
pub const EXIT_FAIL: i32 = 1;
/// Exit code of a panic in a test image.
pub const EXIT_PANIC: i32 = 101;

/// Marker for the instruction counter: start of a measured section. Its body is its
/// own (a value no other function loads): with an empty body the linker's identical
/// code folding (`--icf=all`) gave it the address of every other empty function
/// (`DefaultPreInit`, empty trait methods), and the counter restarted at each call of
/// one inside a measured section (a link pass measured 16 instructions).
/// `scripts/bench.sh` checks that no other symbol shares its address.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_start() {
    core::sync::atomic::compiler_fence(Ordering::SeqCst);
    core::hint::black_box(0x5354_4152u32);
}

/// Marker for the instruction counter: end of a measured section (a different body
/// from `bench_start`, so the linker cannot merge the two).
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_end() {
    core::sync::atomic::compiler_fence(Ordering::Release);
    core::hint::black_box(0u32);
}
