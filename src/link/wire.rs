//! The wire toolkit: one place for the conversions between working units and wire
//! integers, and for the byte cursors every layout uses.
//!
//! * Rounding: [`round_sat_i32`] (f64, exact), [`mm_to_nm_f32`] and
//!   [`pose_to_wire_f32`] (f32, the flight telemetry path).
//! * Cursors: [`Reader`] and [`Writer`] over byte slices, big-endian (the PUS fields)
//!   or little-endian (the parameter table), checked: a read past the end is `None`, a
//!   write past the end is `None`, nothing panics.
//! * Layouts: a [`Field`] is a named byte range (smoltcp's `mod field`); every fixed
//!   layout (housekeeping, flash records, the table image) declares its fields once as
//!   `const`s built with [`field`] and [`after`], and reads and writes them through
//!   [`Fields`] and [`FieldsMut`] (checked: a field past the end or of the wrong width
//!   is `None`). The mission database and the ICD read the same constants.

use super::command::WirePose;
use crate::kinematics::{Pose, LEGS};
use crate::units::{NM_PER_MM, NM_PER_MM_F32, UAS_PER_RAD};

/// Rounds half away from zero to the nearest i32, saturating; NaN gives 0.
pub fn round_sat_i32(v: f64) -> i32 {
    // On the bit pattern, integers only: f64 is software arithmetic on the target, and
    // this serves the housekeeping's 24 rotations and lengths. Equal to
    // `libm::round(v) as i32` (host test `link::round_sat_i32_is_libm_round_saturated`).
    let bits = v.to_bits();
    let abs = bits & !(1 << 63);
    if abs > f64::INFINITY.to_bits() {
        return 0;
    }
    // |v| = m 2^(e - 52), m with its leading one at bit 52.
    let e = (abs >> 52) as i32 - 1023;
    let magnitude: u64 = if e < -1 {
        // Below one half.
        0
    } else if e < 31 {
        let m = (abs & ((1 << 52) - 1)) | (1 << 52);
        let shift = (52 - e) as u32;
        // Adding one half and truncating rounds half away from zero: at most 2^31.
        (m + (1 << (shift - 1))) >> shift
    } else {
        // 2^31 or more (infinity included).
        1 << 31
    };
    if bits >> 63 != 0 {
        // -2^31 is i32::MIN itself.
        (magnitude.min(1 << 31) as i64).wrapping_neg() as i32
    } else {
        magnitude.min(i32::MAX as u64) as i32
    }
}

/// Below this magnitude every f32 multiple of 0.5 is exact, so rounding in f32 is
/// exact too (2^22).
const F32_EXACT_HALF_LIMIT: f32 = 4_194_304.0;

/// Rounds an f32 half away from zero to i32 (saturating, NaN gives 0).
fn round_f32(v: f32) -> i32 {
    let r = if v >= 0.0 { v + 0.5 } else { v - 0.5 };
    // `as` saturates and maps NaN to 0.
    r as i32
}

/// A length in mm to the nearest nm, in f32 where that is exact to 1 nm (|v| < 4 mm:
/// the product carries at most ~0.25 nm of rounding, so a half-way value may round to
/// the neighbour), in f64 beyond. Saturates; NaN gives 0.
pub fn mm_to_nm_f32(v: f32) -> i32 {
    let p = v * NM_PER_MM_F32;
    if p.abs() < F32_EXACT_HALF_LIMIT {
        round_f32(p)
    } else {
        round_sat_i32(f64::from(v) * NM_PER_MM)
    }
}

/// A telemetry pose (nm, uas) of an f32 pose: translations by [`mm_to_nm_f32`];
/// rotations need more than f32's 24 bits in micro-arcseconds and take the exact f64
/// path. (f64 is software floating point on the Cortex-M4F: this keeps the 1 Hz
/// housekeeping inside the cycle budget.)
pub fn pose_to_wire_f32(pose: &Pose<f32>) -> WirePose {
    WirePose {
        translation_nm: pose.translation_mm.map(mm_to_nm_f32),
        rotation_uas: pose
            .rotation_rad
            .map(|v| round_sat_i32(f64::from(v) * UAS_PER_RAD)),
    }
}

/// Byte order of a layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// Network order (CCSDS, PUS).
    Big,
    /// The parameter table's order.
    Little,
}

/// A checked reader over bytes.
#[derive(Clone, Copy, Debug)]
pub struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
    order: Order,
}

impl<'a> Reader<'a> {
    /// At the start of `buf`. Out of line: inlined at its sixteen flight call sites, 20
    /// bytes of flash more.
    #[inline(never)]
    pub const fn new(buf: &'a [u8], order: Order) -> Self {
        Self { buf, pos: 0, order }
    }

    /// Bytes read so far.
    pub const fn position(&self) -> usize {
        self.pos
    }

    /// Checks, on the host, that the next byte is the first of `f`, a field of a layout
    /// that starts at `base` in this buffer (read in the order of its named fields):
    /// `None` if it is not, so a read out of place fails every host test. The flight build
    /// pays nothing (as [`Writer::at`]).
    #[inline]
    pub fn at(&self, base: usize, f: &Field) -> Option<()> {
        #[cfg(any(test, feature = "host"))]
        if base.checked_add(f.start)? != self.pos {
            return None;
        }
        #[cfg(not(any(test, feature = "host")))]
        let _ = (base, f);
        Some(())
    }

    /// Bytes left.
    pub fn remaining(&self) -> &'a [u8] {
        self.buf.get(self.pos..).unwrap_or(&[])
    }

    /// The next `N` bytes.
    pub fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let end = self.pos.checked_add(N)?;
        let out: [u8; N] = self.buf.get(self.pos..end)?.try_into().ok()?;
        self.pos = end;
        Some(out)
    }

    /// The next `n` bytes as a slice.
    pub fn bytes(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.pos.checked_add(n)?;
        let out = self.buf.get(self.pos..end)?;
        self.pos = end;
        Some(out)
    }

    /// A u8.
    pub fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|b| b[0])
    }

    /// A u16 in the reader's order.
    pub fn u16(&mut self) -> Option<u16> {
        let b = self.take()?;
        Some(match self.order {
            Order::Big => u16::from_be_bytes(b),
            Order::Little => u16::from_le_bytes(b),
        })
    }

    /// A u32 in the reader's order.
    pub fn u32(&mut self) -> Option<u32> {
        let b = self.take()?;
        Some(match self.order {
            Order::Big => u32::from_be_bytes(b),
            Order::Little => u32::from_le_bytes(b),
        })
    }

    /// An i32 in the reader's order.
    pub fn i32(&mut self) -> Option<i32> {
        self.u32().map(|v| v as i32)
    }

    /// An f32 in the reader's order.
    pub fn f32(&mut self) -> Option<f32> {
        self.u32().map(f32::from_bits)
    }

    /// An f64 in the reader's order.
    pub fn f64(&mut self) -> Option<f64> {
        let b = self.take()?;
        Some(match self.order {
            Order::Big => f64::from_be_bytes(b),
            Order::Little => f64::from_le_bytes(b),
        })
    }

    /// `N` f64 in the reader's order.
    pub fn f64s<const N: usize>(&mut self) -> Option<[f64; N]> {
        let mut out = [0.0; N];
        for o in out.iter_mut() {
            *o = self.f64()?;
        }
        Some(out)
    }

    /// Six i32 (one per leg).
    pub fn i32s(&mut self) -> Option<[i32; LEGS]> {
        let mut v = [0i32; LEGS];
        for x in v.iter_mut() {
            *x = self.i32()?;
        }
        Some(v)
    }

    /// A wire pose (six i32).
    pub fn pose(&mut self) -> Option<WirePose> {
        Some(WirePose::from_array(self.i32s()?))
    }
}

/// Copies `src` to the start of `dst`; `None` (and nothing copied) if it does not fit.
/// The flight code's one slice copy: `copy_from_slice` checks the lengths again and
/// panics on a mismatch, and in the size-built flight image that check is not always
/// inlined next to the one that makes it impossible, so a panic branch would remain.
#[inline]
pub fn copy_prefix<T: Copy>(dst: &mut [T], src: &[T]) -> Option<()> {
    let dst = dst.get_mut(..src.len())?;
    for (d, s) in dst.iter_mut().zip(src) {
        *d = *s;
    }
    Some(())
}

/// A checked writer over bytes.
#[derive(Debug)]
pub struct Writer<'a> {
    buf: &'a mut [u8],
    pos: usize,
    order: Order,
}

impl<'a> Writer<'a> {
    /// At the start of `buf`. Out of line: inlined at its five flight call sites, 16
    /// bytes of flash more.
    #[inline(never)]
    pub fn new(buf: &'a mut [u8], order: Order) -> Self {
        Self { buf, pos: 0, order }
    }

    /// Bytes written so far.
    pub const fn position(&self) -> usize {
        self.pos
    }

    /// Writes raw bytes; `None` (and nothing written) if they do not fit.
    pub fn put(&mut self, bytes: &[u8]) -> Option<()> {
        copy_prefix(self.buf.get_mut(self.pos..)?, bytes)?;
        self.pos = self.pos.checked_add(bytes.len())?;
        Some(())
    }

    /// Checks, on the host, that the next byte is the first of `f`, a field of a layout
    /// that starts at `base` in this buffer (a layout written in the order of its named
    /// fields): `None` if it is not, so a write out of place fails every host test. The
    /// flight build trusts those tests and pays nothing (no check, no code).
    #[inline]
    pub fn at(&mut self, base: usize, f: &Field) -> Option<()> {
        #[cfg(any(test, feature = "host"))]
        if base.checked_add(f.start)? != self.pos {
            return None;
        }
        #[cfg(not(any(test, feature = "host")))]
        let _ = (base, f);
        Some(())
    }

    /// The next `n` bytes, taken whole (a fixed layout written by its named fields
    /// through [`FieldsMut`]); `None`, and nothing taken, if they do not fit.
    pub fn reserve(&mut self, n: usize) -> Option<&mut [u8]> {
        let start = self.pos;
        let end = start.checked_add(n)?;
        if end > self.buf.len() {
            return None;
        }
        self.pos = end;
        self.buf.get_mut(start..end)
    }

    /// A u8.
    pub fn u8(&mut self, v: u8) -> Option<()> {
        self.put(&[v])
    }

    /// A u16 in the writer's order.
    pub fn u16(&mut self, v: u16) -> Option<()> {
        match self.order {
            Order::Big => self.put(&v.to_be_bytes()),
            Order::Little => self.put(&v.to_le_bytes()),
        }
    }

    /// A u32 in the writer's order.
    pub fn u32(&mut self, v: u32) -> Option<()> {
        match self.order {
            Order::Big => self.put(&v.to_be_bytes()),
            Order::Little => self.put(&v.to_le_bytes()),
        }
    }

    /// An i32 in the writer's order.
    pub fn i32(&mut self, v: i32) -> Option<()> {
        self.u32(v as u32)
    }

    /// An f32 in the writer's order.
    pub fn f32(&mut self, v: f32) -> Option<()> {
        self.u32(v.to_bits())
    }

    /// An f64 in the writer's order.
    pub fn f64(&mut self, v: f64) -> Option<()> {
        match self.order {
            Order::Big => self.put(&v.to_be_bytes()),
            Order::Little => self.put(&v.to_le_bytes()),
        }
    }

    /// f64 values in the writer's order.
    pub fn f64s(&mut self, v: &[f64]) -> Option<()> {
        for x in v {
            self.f64(*x)?;
        }
        Some(())
    }

    /// Six i32.
    pub fn i32s(&mut self, v: &[i32; LEGS]) -> Option<()> {
        for x in v {
            self.i32(*x)?;
        }
        Some(())
    }

    /// A wire pose.
    pub fn pose(&mut self, p: &WirePose) -> Option<()> {
        self.i32s(&p.to_array())
    }
}

/// A field of a layout: its byte range.
pub type Field = core::ops::Range<usize>;

/// The field of `len` bytes at `start`.
pub const fn field(start: usize, len: usize) -> Field {
    start..start + len
}

/// The field of `len` bytes just after `prev` (layouts declared end to end).
pub const fn after(prev: &Field, len: usize) -> Field {
    prev.end..prev.end + len
}

/// Checked reads of named fields over bytes.
#[derive(Clone, Copy, Debug)]
pub struct Fields<'a> {
    buf: &'a [u8],
    order: Order,
}

/// The bytes of `f` in `buf` if they are exactly `N`.
#[inline]
fn exact<const N: usize>(buf: &[u8], f: Field) -> Option<&[u8]> {
    buf.get(f).filter(|b| b.len() == N)
}

impl<'a> Fields<'a> {
    /// Over `buf`, multi-byte fields in `order`.
    pub const fn new(buf: &'a [u8], order: Order) -> Self {
        Self { buf, order }
    }

    /// The bytes of `f`.
    #[inline]
    pub fn bytes(&self, f: Field) -> Option<&'a [u8]> {
        self.buf.get(f)
    }

    /// A reader over `f` (a field holding an array or a nested layout).
    #[inline]
    pub fn reader(&self, f: Field) -> Option<Reader<'a>> {
        Some(Reader::new(self.bytes(f)?, self.order))
    }

    /// A one-byte field.
    #[inline]
    pub fn u8(&self, f: Field) -> Option<u8> {
        Reader::new(exact::<1>(self.buf, f)?, self.order).u8()
    }

    /// A two-byte field.
    #[inline]
    pub fn u16(&self, f: Field) -> Option<u16> {
        Reader::new(exact::<2>(self.buf, f)?, self.order).u16()
    }

    /// A four-byte unsigned field.
    #[inline]
    pub fn u32(&self, f: Field) -> Option<u32> {
        Reader::new(exact::<4>(self.buf, f)?, self.order).u32()
    }

    /// A four-byte signed field.
    #[inline]
    pub fn i32(&self, f: Field) -> Option<i32> {
        Reader::new(exact::<4>(self.buf, f)?, self.order).i32()
    }

    /// A four-byte IEEE-754 field.
    #[inline]
    pub fn f32(&self, f: Field) -> Option<f32> {
        Reader::new(exact::<4>(self.buf, f)?, self.order).f32()
    }

    /// An eight-byte IEEE-754 field.
    #[inline]
    pub fn f64(&self, f: Field) -> Option<f64> {
        Reader::new(exact::<8>(self.buf, f)?, self.order).f64()
    }
}

/// Checked writes of named fields over bytes.
#[derive(Debug)]
pub struct FieldsMut<'a> {
    buf: &'a mut [u8],
    order: Order,
}

impl<'a> FieldsMut<'a> {
    /// Over `buf`, multi-byte fields in `order`.
    pub fn new(buf: &'a mut [u8], order: Order) -> Self {
        Self { buf, order }
    }

    /// A writer over `f` (a field holding an array or a nested layout).
    #[inline]
    pub fn writer(&mut self, f: Field) -> Option<Writer<'_>> {
        Some(Writer::new(self.buf.get_mut(f)?, self.order))
    }

    /// Writes `bytes` into `f` (exactly its width).
    #[inline]
    pub fn set_bytes(&mut self, f: Field, bytes: &[u8]) -> Option<()> {
        let dst = self.buf.get_mut(f)?;
        if dst.len() != bytes.len() {
            return None;
        }
        copy_prefix(dst, bytes)
    }

    /// A one-byte field.
    #[inline]
    pub fn set_u8(&mut self, f: Field, v: u8) -> Option<()> {
        self.set_bytes(f, &[v])
    }

    /// A two-byte field.
    #[inline]
    pub fn set_u16(&mut self, f: Field, v: u16) -> Option<()> {
        let b = match self.order {
            Order::Big => v.to_be_bytes(),
            Order::Little => v.to_le_bytes(),
        };
        self.set_bytes(f, &b)
    }

    /// A four-byte unsigned field.
    #[inline]
    pub fn set_u32(&mut self, f: Field, v: u32) -> Option<()> {
        let b = match self.order {
            Order::Big => v.to_be_bytes(),
            Order::Little => v.to_le_bytes(),
        };
        self.set_bytes(f, &b)
    }

    /// A four-byte signed field.
    #[inline]
    pub fn set_i32(&mut self, f: Field, v: i32) -> Option<()> {
        self.set_u32(f, v as u32)
    }

    /// A four-byte IEEE-754 field.
    #[inline]
    pub fn set_f32(&mut self, f: Field, v: f32) -> Option<()> {
        self.set_u32(f, v.to_bits())
    }

    /// An eight-byte IEEE-754 field.
    #[inline]
    pub fn set_f64(&mut self, f: Field, v: f64) -> Option<()> {
        let b = match self.order {
            Order::Big => v.to_bits().to_be_bytes(),
            Order::Little => v.to_bits().to_le_bytes(),
        };
        self.set_bytes(f, &b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cursors_are_checked_and_rounding_is_half_away_from_zero() {
        let mut buf = [0u8; 7];
        let mut w = Writer::new(&mut buf, Order::Big);
        assert_eq!(w.u32(0x0102_0304), Some(()));
        assert_eq!(w.u16(0x0506), Some(()));
        assert_eq!(
            w.u16(0x0708),
            None,
            "past the end: refused, nothing written"
        );
        assert_eq!(w.position(), 6);
        let mut r = Reader::new(&buf, Order::Big);
        assert_eq!(r.u32(), Some(0x0102_0304));
        assert_eq!(r.u16(), Some(0x0506));
        assert_eq!(r.u16(), None);
        let mut l = Reader::new(&buf, Order::Little);
        assert_eq!(l.u16(), Some(0x0201));
        assert_eq!(round_sat_i32(2.5), 3);
        assert_eq!(round_sat_i32(-2.5), -3);
        assert_eq!(round_sat_i32(f64::NAN), 0);
        assert_eq!(round_sat_i32(1e300), i32::MAX);
        assert_eq!(mm_to_nm_f32(0.0015), 1500);
        assert_eq!(mm_to_nm_f32(-0.0015), -1500);
        assert_eq!(mm_to_nm_f32(f32::NAN), 0);
    }

    #[test]
    fn a_layout_written_out_of_place_fails_on_the_host() {
        const A: Field = field(0, 2);
        const B: Field = after(&A, 4);
        let mut buf = [0u8; 9];
        let mut w = Writer::new(&mut buf, Order::Big);
        assert_eq!(w.u8(7), Some(()));
        // The layout starts at 1: A is next, B is not.
        assert_eq!(w.at(1, &A), Some(()));
        assert_eq!(w.at(1, &B), None);
        assert_eq!(w.u16(0x0102), Some(()));
        assert_eq!(w.at(1, &B), Some(()));
        assert_eq!(w.at(1, &A), None);
        assert_eq!(w.at(usize::MAX, &B), None);
    }

    #[test]
    fn a_layout_read_out_of_place_fails_on_the_host() {
        const A: Field = field(0, 2);
        const B: Field = after(&A, 4);
        let buf = [0u8; 9];
        let mut r = Reader::new(&buf, Order::Big);
        assert_eq!(r.u8(), Some(0));
        assert_eq!(r.at(1, &A), Some(()));
        assert_eq!(r.at(1, &B), None);
        assert_eq!(r.u16(), Some(0));
        assert_eq!(r.at(1, &B), Some(()));
        assert_eq!(r.at(1, &A), None);
        assert_eq!(r.at(usize::MAX, &B), None);
    }

    #[test]
    fn named_fields_are_checked_for_bounds_and_width() {
        const A: Field = field(0, 2);
        const B: Field = after(&A, 4);
        const C: Field = after(&B, 8);
        assert_eq!((B.clone(), C.clone()), (2..6, 6..14));
        let mut buf = [0u8; 14];
        let mut w = FieldsMut::new(&mut buf, Order::Big);
        assert_eq!(w.set_u16(A, 0x0102), Some(()));
        assert_eq!(w.set_i32(B, -2), Some(()));
        assert_eq!(w.set_f64(C, 1.5), Some(()));
        assert_eq!(w.set_u32(A, 7), None, "wrong width: nothing written");
        assert_eq!(w.set_u16(13..15, 7), None, "past the end");
        let r = Fields::new(&buf, Order::Big);
        assert_eq!(r.u16(A), Some(0x0102));
        assert_eq!(r.i32(B), Some(-2));
        assert_eq!(r.f64(C), Some(1.5));
        assert_eq!(r.u32(A), None);
        assert_eq!(&buf[..6], &[1, 2, 0xff, 0xff, 0xff, 0xfe]);
        let r = Fields::new(&buf, Order::Little);
        assert_eq!(r.u16(A), Some(0x0201));
    }
}
