//! QEMU mps2-an386 (Cortex-M4F, FPU on): process exit through semihosting, stack-peak
//! measurement from cortex-m-rt's painted stack, instruction-count markers.
#![allow(unsafe_code)] // Board glue: reads linker symbols and painted RAM.

/// Value cortex-m-rt's `paint-stack` writes over the stack before `main`.
const STACK_PAINT: u32 = 0xCCCC_CCCC;

extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}

/// Bytes of stack used so far: scans the painted region from its low end upwards for the
/// first word that is no longer the paint value.
pub fn stack_peak_bytes() -> u32 {
    // SAFETY: both symbols come from cortex-m-rt's linker script and bound the stack
    // region, which is plain RAM; volatile reads of aligned words inside it are sound.
    unsafe {
        let lo = core::ptr::addr_of!(_stack_end) as usize;
        let hi = core::ptr::addr_of!(_stack_start) as usize;
        let mut p = lo;
        while p < hi && core::ptr::read_volatile(p as *const u32) == STACK_PAINT {
            p += 4;
        }
        (hi - p) as u32
    }
}

/// Size of the stack region (bytes) between `_stack_end` and `_stack_start`.
pub fn stack_region_bytes() -> u32 {
    let lo = core::ptr::addr_of!(_stack_end) as usize;
    let hi = core::ptr::addr_of!(_stack_start) as usize;
    (hi - lo) as u32
}

/// Ends the QEMU run with an exit code (0 = pass).
pub fn exit(code: i32) -> ! {
    semihosting::process::exit(code)
}

/// Marker for `qemu-insncount`: start of a measured section.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_start() {
    core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
}

/// Marker for `qemu-insncount`: end of a measured section (a different body from
/// `bench_start`, so the linker cannot merge the two).
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_end() {
    core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::Release);
    core::hint::black_box(0u32);
}
