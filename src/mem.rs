//! The flight image's memory copy, fill and compare, written for size: the routines the
//! compiler calls for every struct copy, zeroing and slice comparison it does not
//! inline (`memcpy`, `memset`, `memcmp` and the ARM run-time ABI's `__aeabi_memcpy*`,
//! `__aeabi_memset*`, `__aeabi_memclr*`).
//!
//! `compiler_builtins`' versions are written for speed (unrolled, misaligned words
//! shifted into place): 1,580 bytes of the 64 KiB flight image (`memcpy` 730,
//! `__aeabi_memclr` 208, `__aeabi_memset4` 184, `__aeabi_memclr4` 174,
//! `__aeabi_memcpy4` 156, `memcmp` 116, `__aeabi_memcpy` 12). These copy and fill four
//! words a step when the addresses allow it (every copy of a struct of the flight
//! code: they are word-aligned), else a byte at a time, in ~250 bytes. Their accesses
//! are volatile so that the optimiser cannot turn their loops back into calls to
//! themselves.
//!
//! Tested on the host ([`copy`], [`fill`], [`compare`]: host test `mem`, every
//! alignment and length against the slice operations); on the target they serve every
//! copy of the flight code (the QEMU tests). The exported symbols replace
//! `compiler_builtins`' weak ones on the target only (`exports`).
#![allow(unsafe_code)] // Raw-pointer memory routines: the contracts of memcpy and memset.

use core::ptr::{read_volatile, write_volatile};

/// Copies `n` bytes from `src` to `dst`: words while both are word-aligned, then bytes.
///
/// # Safety
/// `src` readable and `dst` writable for `n` bytes, the regions not overlapping (the
/// contract of `memcpy`).
pub unsafe fn copy(dst: *mut u8, src: *const u8, n: usize) {
    let mut i = 0;
    if (dst as usize | src as usize) & 3 == 0 {
        // Four words a step (a struct copy is most of the flight code's copying).
        while n - i >= 16 {
            // SAFETY: both addresses are word-aligned and the four words are inside the
            // regions.
            unsafe {
                let (s, d) = (src.add(i).cast::<u32>(), dst.add(i).cast::<u32>());
                let w = [
                    read_volatile(s),
                    read_volatile(s.add(1)),
                    read_volatile(s.add(2)),
                    read_volatile(s.add(3)),
                ];
                write_volatile(d, w[0]);
                write_volatile(d.add(1), w[1]);
                write_volatile(d.add(2), w[2]);
                write_volatile(d.add(3), w[3]);
            }
            i += 16;
        }
        while n - i >= 4 {
            // SAFETY: both addresses are word-aligned and the word is inside the regions.
            unsafe {
                write_volatile(
                    dst.add(i).cast::<u32>(),
                    read_volatile(src.add(i).cast::<u32>()),
                );
            }
            i += 4;
        }
    }
    while i < n {
        // SAFETY: inside the regions (the caller's contract).
        unsafe { write_volatile(dst.add(i), read_volatile(src.add(i))) };
        i += 1;
    }
}

/// Sets `n` bytes at `dst` to `value`: words while the address is word-aligned, then
/// bytes.
///
/// # Safety
/// `dst` writable for `n` bytes (the contract of `memset`).
pub unsafe fn fill(dst: *mut u8, value: u8, n: usize) {
    let mut i = 0;
    if dst as usize & 3 == 0 {
        let word = u32::from(value) * 0x0101_0101;
        while n - i >= 16 {
            // SAFETY: word-aligned and the four words inside the region.
            unsafe {
                let d = dst.add(i).cast::<u32>();
                write_volatile(d, word);
                write_volatile(d.add(1), word);
                write_volatile(d.add(2), word);
                write_volatile(d.add(3), word);
            }
            i += 16;
        }
        while n - i >= 4 {
            // SAFETY: word-aligned and inside the region.
            unsafe { write_volatile(dst.add(i).cast::<u32>(), word) };
            i += 4;
        }
    }
    while i < n {
        // SAFETY: inside the region.
        unsafe { write_volatile(dst.add(i), value) };
        i += 1;
    }
}

/// The difference of the first differing bytes of `a` and `b` (as unsigned), 0 if the
/// `n` bytes are equal (the contract of `memcmp`).
///
/// # Safety
/// `a` and `b` readable for `n` bytes.
pub unsafe fn compare(a: *const u8, b: *const u8, n: usize) -> i32 {
    for i in 0..n {
        // SAFETY: inside the regions.
        let (x, y) = unsafe { (read_volatile(a.add(i)), read_volatile(b.add(i))) };
        if x != y {
            return i32::from(x) - i32::from(y);
        }
    }
    0
}

/// The symbols the compiler's calls are linked to, on the target (module
/// documentation): `compiler_builtins` defines them as weak symbols.
#[cfg(all(target_arch = "arm", target_os = "none"))]
pub mod exports {
    use super::{compare, copy, fill};

    /// `memcpy`.
    ///
    /// # Safety
    /// C's contract: `src` readable and `dst` writable for `n` bytes, not overlapping.
    #[no_mangle]
    pub unsafe extern "C" fn memcpy(dst: *mut u8, src: *const u8, n: usize) -> *mut u8 {
        // SAFETY: the caller keeps `memcpy`'s contract, which is `copy`'s: `src`
        // readable and `dst` writable for `n` bytes, not overlapping.
        unsafe { copy(dst, src, n) };
        dst
    }

    /// `memset`.
    ///
    /// # Safety
    /// C's contract: `dst` writable for `n` bytes.
    #[no_mangle]
    pub unsafe extern "C" fn memset(dst: *mut u8, value: i32, n: usize) -> *mut u8 {
        // SAFETY: the caller keeps `memset`'s contract, which is `fill`'s: `dst`
        // writable for `n` bytes.
        unsafe { fill(dst, value as u8, n) };
        dst
    }

    /// `memcmp`.
    ///
    /// # Safety
    /// C's contract: `a` and `b` readable for `n` bytes.
    #[no_mangle]
    pub unsafe extern "C" fn memcmp(a: *const u8, b: *const u8, n: usize) -> i32 {
        // SAFETY: the caller keeps `memcmp`'s contract, which is `compare`'s: `a` and
        // `b` readable for `n` bytes.
        unsafe { compare(a, b, n) }
    }

    /// `__aeabi_memcpy` (any alignment).
    ///
    /// # Safety
    /// The contract of `memcpy`.
    #[no_mangle]
    pub unsafe extern "aapcs" fn __aeabi_memcpy(dst: *mut u8, src: *const u8, n: usize) {
        // SAFETY: the caller keeps `memcpy`'s contract, which is `copy`'s: `src`
        // readable and `dst` writable for `n` bytes, not overlapping.
        unsafe { copy(dst, src, n) }
    }

    /// `__aeabi_memcpy4` (word-aligned).
    ///
    /// # Safety
    /// The contract of `memcpy`.
    #[no_mangle]
    pub unsafe extern "aapcs" fn __aeabi_memcpy4(dst: *mut u8, src: *const u8, n: usize) {
        // SAFETY: the caller keeps `memcpy`'s contract, which is `copy`'s: `src`
        // readable and `dst` writable for `n` bytes, not overlapping.
        unsafe { copy(dst, src, n) }
    }

    /// `__aeabi_memcpy8` (doubleword-aligned).
    ///
    /// # Safety
    /// The contract of `memcpy`.
    #[no_mangle]
    pub unsafe extern "aapcs" fn __aeabi_memcpy8(dst: *mut u8, src: *const u8, n: usize) {
        // SAFETY: the caller keeps `memcpy`'s contract, which is `copy`'s: `src`
        // readable and `dst` writable for `n` bytes, not overlapping.
        unsafe { copy(dst, src, n) }
    }

    /// `__aeabi_memset(dst, n, value)` (the ABI's argument order).
    ///
    /// # Safety
    /// The contract of `memset`.
    #[no_mangle]
    pub unsafe extern "aapcs" fn __aeabi_memset(dst: *mut u8, n: usize, value: i32) {
        // SAFETY: the caller keeps `memset`'s contract, which is `fill`'s: `dst`
        // writable for `n` bytes.
        unsafe { fill(dst, value as u8, n) }
    }

    /// `__aeabi_memset4`.
    ///
    /// # Safety
    /// The contract of `memset`.
    #[no_mangle]
    pub unsafe extern "aapcs" fn __aeabi_memset4(dst: *mut u8, n: usize, value: i32) {
        // SAFETY: the caller keeps `memset`'s contract, which is `fill`'s: `dst`
        // writable for `n` bytes.
        unsafe { fill(dst, value as u8, n) }
    }

    /// `__aeabi_memset8`.
    ///
    /// # Safety
    /// The contract of `memset`.
    #[no_mangle]
    pub unsafe extern "aapcs" fn __aeabi_memset8(dst: *mut u8, n: usize, value: i32) {
        // SAFETY: the caller keeps `memset`'s contract, which is `fill`'s: `dst`
        // writable for `n` bytes.
        unsafe { fill(dst, value as u8, n) }
    }

    /// `__aeabi_memclr(dst, n)`.
    ///
    /// # Safety
    /// The contract of `memset`.
    #[no_mangle]
    pub unsafe extern "aapcs" fn __aeabi_memclr(dst: *mut u8, n: usize) {
        // SAFETY: the caller keeps `memset`'s contract, which is `fill`'s: `dst`
        // writable for `n` bytes.
        unsafe { fill(dst, 0, n) }
    }

    /// `__aeabi_memclr4`.
    ///
    /// # Safety
    /// The contract of `memset`.
    #[no_mangle]
    pub unsafe extern "aapcs" fn __aeabi_memclr4(dst: *mut u8, n: usize) {
        // SAFETY: the caller keeps `memset`'s contract, which is `fill`'s: `dst`
        // writable for `n` bytes.
        unsafe { fill(dst, 0, n) }
    }

    /// `__aeabi_memclr8`.
    ///
    /// # Safety
    /// The contract of `memset`.
    #[no_mangle]
    pub unsafe extern "aapcs" fn __aeabi_memclr8(dst: *mut u8, n: usize) {
        // SAFETY: the caller keeps `memset`'s contract, which is `fill`'s: `dst`
        // writable for `n` bytes.
        unsafe { fill(dst, 0, n) }
    }
}
