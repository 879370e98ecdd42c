//! The housekeeping report TM[3,25]: [`Housekeeping`] and its byte layout.
//!
//! # Layout (source data of TM[3,25], [`HK_REPORT_LEN`] = 133 bytes, big-endian)
//!
//! | offset | size | type    | field                                                        |
//! |-------:|-----:|---------|--------------------------------------------------------------|
//! |      0 |    1 | u8      | structure ID ([`HK_STRUCTURE_ID`] = 1)                       |
//! |      1 |    1 | u8      | controller state (the controller's enum code)                |
//! |      2 |    1 | u8      | boot source (0 nominal, 1 bank A, 2 bank B)                  |
//! |      3 |    1 | u8      | active table bank (0 none/nominal, 1 A, 2 B)                 |
//! |      4 |    1 | u8      | last FK iteration count                                      |
//! |      5 |    1 | u8      | FK valid (1: `pose_fk` is this cycle's FK; 0: FK failed)     |
//! |      6 |    4 | u32     | control cycle counter                                        |
//! |     10 |    4 | u32     | fault flags (latched)                                        |
//! |     14 |    4 | u32     | warning flags                                                |
//! |     18 |    4 | u32     | last refusal bits (`kinematics::Refusals::to_bits`)          |
//! |     22 |    4 | u32     | active table ID                                              |
//! |     26 |    4 | u32     | active table CRC-32                                          |
//! |     30 |   24 | 6 x i32 | pose from FK: x, y, z (nm), alpha, beta, gamma (uas)         |
//! |     54 |   24 | 6 x i32 | commanded pose (nm, uas)                                     |
//! |     78 |   24 | 6 x i32 | commanded strokes, legs 1..6 (nm)                            |
//! |    102 |   24 | 6 x i32 | encoder readings, legs 1..6 (nm; multiples of 100 nm = one 0.1 um count) |
//! |    126 |    2 | u16     | telecommands accepted (wrapping)                             |
//! |    128 |    2 | u16     | telecommands rejected (wrapping)                             |
//! |    130 |    2 | u16     | last failure code (0: none)                                  |
//! |    132 |    1 | u8      | moving legs mask (bit i = leg i+1)                           |

use super::command::{WirePose, WIRE_POSE_LEN};
use crate::kinematics::LEGS;

/// Structure ID of the one housekeeping report.
pub const HK_STRUCTURE_ID: u8 = 1;
/// Length of the TM[3,25] source data (bytes).
pub const HK_REPORT_LEN: usize = 133;

/// One housekeeping sample, filled by the controller.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Housekeeping {
    /// Controller state (the controller's `u8` enum code).
    pub state: u8,
    /// Boot source (`table::BootSource::code`: 0 nominal, 1 bank A, 2 bank B).
    pub boot_source: u8,
    /// Bank holding the active table (0 none/nominal, 1 A, 2 B).
    pub active_bank: u8,
    /// Newton iterations of the last FK.
    pub fk_iterations: u8,
    /// True when `pose_fk` comes from this cycle's successful FK.
    pub fk_valid: bool,
    /// Control cycle counter.
    pub cycle_counter: u32,
    /// Latched fault flags.
    pub fault_flags: u32,
    /// Warning flags.
    pub warning_flags: u32,
    /// Refusal bits of the last refused move (`kinematics::Refusals::to_bits`).
    pub refusal_bits: u32,
    /// Active table ID.
    pub active_table_id: u32,
    /// Active table CRC-32.
    pub active_table_crc32: u32,
    /// Pose from FK of the encoder readings (nm, uas).
    pub pose_fk: WirePose,
    /// Commanded pose (nm, uas).
    pub pose_commanded: WirePose,
    /// Commanded strokes, legs 1..6 (nm).
    pub strokes_commanded_nm: [i32; LEGS],
    /// Encoder readings, legs 1..6 (nm).
    pub encoders_nm: [i32; LEGS],
    /// Telecommands accepted (wrapping).
    pub tc_accepted: u16,
    /// Telecommands rejected (wrapping).
    pub tc_rejected: u16,
    /// Last failure code sent in a verification report (0: none).
    pub last_failure_code: u16,
    /// Legs currently commanded to move (bit i = leg i+1).
    pub moving_legs: u8,
}

/// Sequential big-endian writer over a fixed array.
struct W<'a> {
    buf: &'a mut [u8; HK_REPORT_LEN],
    pos: usize,
}

impl W<'_> {
    fn put(&mut self, b: &[u8]) {
        let end = self.pos.saturating_add(b.len());
        if let Some(dst) = self.buf.get_mut(self.pos..end) {
            dst.copy_from_slice(b);
        }
        self.pos = end;
    }
}

/// Sequential big-endian reader; `None` past the end.
struct R<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl R<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let end = self.pos.checked_add(N)?;
        let out: [u8; N] = self.buf.get(self.pos..end)?.try_into().ok()?;
        self.pos = end;
        Some(out)
    }
    fn u8(&mut self) -> Option<u8> {
        self.take().map(u8::from_be_bytes)
    }
    fn u16(&mut self) -> Option<u16> {
        self.take().map(u16::from_be_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_be_bytes)
    }
    fn i32s(&mut self) -> Option<[i32; LEGS]> {
        let mut v = [0i32; LEGS];
        for x in v.iter_mut() {
            *x = self.take().map(i32::from_be_bytes)?;
        }
        Some(v)
    }
    fn pose(&mut self) -> Option<WirePose> {
        self.take::<WIRE_POSE_LEN>().map(|b| WirePose::parse(&b))
    }
}

impl Housekeeping {
    /// Writes the TM[3,25] source data.
    pub fn emit(&self, out: &mut [u8; HK_REPORT_LEN]) {
        let mut w = W { buf: out, pos: 0 };
        w.put(&[
            HK_STRUCTURE_ID,
            self.state,
            self.boot_source,
            self.active_bank,
            self.fk_iterations,
            u8::from(self.fk_valid),
        ]);
        for v in [
            self.cycle_counter,
            self.fault_flags,
            self.warning_flags,
            self.refusal_bits,
            self.active_table_id,
            self.active_table_crc32,
        ] {
            w.put(&v.to_be_bytes());
        }
        let mut pose = [0u8; WIRE_POSE_LEN];
        self.pose_fk.emit(&mut pose);
        w.put(&pose);
        self.pose_commanded.emit(&mut pose);
        w.put(&pose);
        for v in self.strokes_commanded_nm.iter().chain(&self.encoders_nm) {
            w.put(&v.to_be_bytes());
        }
        for v in [self.tc_accepted, self.tc_rejected, self.last_failure_code] {
            w.put(&v.to_be_bytes());
        }
        w.put(&[self.moving_legs]);
    }

    /// Checked parse of the TM[3,25] source data (exact length, structure ID 1).
    pub fn parse(bytes: &[u8]) -> Option<Housekeeping> {
        if bytes.len() != HK_REPORT_LEN {
            return None;
        }
        let mut r = R { buf: bytes, pos: 0 };
        if r.u8()? != HK_STRUCTURE_ID {
            return None;
        }
        Some(Housekeeping {
            state: r.u8()?,
            boot_source: r.u8()?,
            active_bank: r.u8()?,
            fk_iterations: r.u8()?,
            fk_valid: r.u8()? != 0,
            cycle_counter: r.u32()?,
            fault_flags: r.u32()?,
            warning_flags: r.u32()?,
            refusal_bits: r.u32()?,
            active_table_id: r.u32()?,
            active_table_crc32: r.u32()?,
            pose_fk: r.pose()?,
            pose_commanded: r.pose()?,
            strokes_commanded_nm: r.i32s()?,
            encoders_nm: r.i32s()?,
            tc_accepted: r.u16()?,
            tc_rejected: r.u16()?,
            last_failure_code: r.u16()?,
            moving_legs: r.u8()?,
        })
    }
}
