//! The target's memory copy, fill and compare (`m2ctl::mem`, which replace the run-time
//! library's `memcpy`, `memset`, `memcmp` and their ARM ABI variants in the firmware
//! images) against the slice operations: every source and destination alignment 0..8,
//! every length 0..80 and some long ones, random contents; the bytes around the
//! destination untouched.
#![allow(unsafe_code)] // Calls the raw-pointer routines of `m2ctl::mem` under test.

mod common;

use common::TestRng;
use m2ctl::mem;

const GUARD: usize = 16;

#[test]
fn copy_is_a_slice_copy_at_every_alignment_and_length() {
    let mut rng = TestRng(0xc0_9e5);
    let lengths: Vec<usize> = (0..80).chain([255, 256, 257, 516, 1031, 1300]).collect();
    for n in lengths {
        for src_off in 0..8 {
            for dst_off in 0..8 {
                let src: Vec<u8> = (0..n + 2 * GUARD).map(|_| rng.bits() as u8).collect();
                let mut dst: Vec<u8> = (0..n + 2 * GUARD).map(|_| rng.bits() as u8).collect();
                let mut want = dst.clone();
                want[GUARD + dst_off..GUARD + dst_off + n]
                    .copy_from_slice(&src[GUARD + src_off..GUARD + src_off + n]);
                let d = dst[GUARD + dst_off..].as_mut_ptr();
                let s = src[GUARD + src_off..].as_ptr();
                // SAFETY: both regions (n bytes past an offset below GUARD) are inside
                // their vectors, which are distinct.
                unsafe { mem::copy(d, s, n) };
                assert_eq!(dst, want, "n {n}, src +{src_off}, dst +{dst_off}");
            }
        }
    }
}

#[test]
fn fill_sets_exactly_the_bytes_asked() {
    let mut rng = TestRng(0xf111);
    for n in (0..80).chain([255, 256, 516, 1300]) {
        for off in 0..8 {
            for value in [0u8, 0xff, 0x5a, rng.bits() as u8] {
                let mut buf: Vec<u8> = (0..n + 2 * GUARD).map(|_| rng.bits() as u8).collect();
                let mut want = buf.clone();
                want[GUARD + off..GUARD + off + n].fill(value);
                let p = buf[GUARD + off..].as_mut_ptr();
                // SAFETY: inside the vector.
                unsafe { mem::fill(p, value, n) };
                assert_eq!(buf, want, "n {n}, +{off}, value {value:#x}");
            }
        }
    }
}

#[test]
fn compare_orders_as_unsigned_bytes() {
    let mut rng = TestRng(0xc3);
    for n in 0..70 {
        let a: Vec<u8> = (0..n).map(|_| rng.bits() as u8).collect();
        // SAFETY: both vectors hold n bytes.
        assert_eq!(
            unsafe { mem::compare(a.as_ptr(), a.clone().as_ptr(), n) },
            0
        );
        if n == 0 {
            continue;
        }
        let mut b = a.clone();
        let k = (rng.bits() as usize) % n;
        b[k] = b[k].wrapping_add(1 + (rng.bits() % 255) as u8);
        // SAFETY: as above.
        let got = unsafe { mem::compare(a.as_ptr(), b.as_ptr(), n) };
        assert_eq!(got, i32::from(a[k]) - i32::from(b[k]), "n {n}, byte {k}");
        assert_eq!(got.signum(), a.cmp(&b) as i32);
    }
}
