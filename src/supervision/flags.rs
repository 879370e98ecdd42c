//! Fault and warning flags: one `u32` word with a stable bit layout for telemetry.
//!
//! | bit | flag | kind |
//! |---|---|---|
//! | 0 | [`FaultFlags::FOLLOWING_ERROR`] | fault (latched) |
//! | 1 | [`FaultFlags::ENCODER_STUCK`] | fault |
//! | 2 | [`FaultFlags::ENCODER_JUMP`] | fault |
//! | 3 | [`FaultFlags::ENCODER_READ_FAILURE`] | fault |
//! | 4 | [`FaultFlags::SOFT_LIMIT`] | fault |
//! | 5 | [`FaultFlags::FK_NOT_CONVERGED`] | fault |
//! | 6 | [`FaultFlags::POSE_OUTSIDE_WORKSPACE`] | fault |
//! | 7 | [`FaultFlags::DRIVE_FAULT`] | fault |
//! | 8 | [`FaultFlags::TABLE_CORRUPT`] | fault (raised by the RAM scrub) |
//! | 9 | [`FaultFlags::DEADLINE_MISSED`] | fault (raised by consecutive cycle overruns) |
//! | 10 | [`FaultFlags::LIMIT_SWITCH`] | fault (an end-of-travel switch active, or its input unreadable) |
//! | 11 | [`FaultFlags::OUTPUT_LIMITED`] | fault (the output stage clamped a stroke step) |
//! | 12..15 | reserved for faults | |
//! | 16 | [`FaultFlags::FOLLOWING_WARNING`] | warning (not latched) |
//! | 17 | [`FaultFlags::ENCODER_WARNING`] | warning (the encoder's own warning bit) |
//! | 18..31 | reserved for warnings | |
//!
//! Bits are never renumbered; new checks take reserved bits.

use core::ops::{BitAnd, BitOr, BitOrAssign, Not};

/// A set of fault and warning flags (see the module documentation for the layout).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct FaultFlags(u32);

impl FaultFlags {
    /// Bit 0: |measured - commanded stroke| above the fault threshold.
    pub const FOLLOWING_ERROR: Self = Self(1 << 0);
    /// Bit 1: encoder makes no progress while its slider is commanded to move.
    pub const ENCODER_STUCK: Self = Self(1 << 1);
    /// Bit 2: encoder reading changed more than physically possible in one cycle.
    pub const ENCODER_JUMP: Self = Self(1 << 2);
    /// Bit 3: encoder did not answer, answered corrupted, or gave a non-finite value.
    pub const ENCODER_READ_FAILURE: Self = Self(1 << 3);
    /// Bit 4: measured stroke beyond the slider's soft limit.
    pub const SOFT_LIMIT: Self = Self(1 << 4);
    /// Bit 5: forward kinematics of the measured strokes failed.
    pub const FK_NOT_CONVERGED: Self = Self(1 << 5);
    /// Bit 6: measured pose outside the workspace.
    pub const POSE_OUTSIDE_WORKSPACE: Self = Self(1 << 6);
    /// Bit 7: a drive reported a fault.
    pub const DRIVE_FAULT: Self = Self(1 << 7);
    /// Bit 8: the RAM image of the running table, its geometry or the supervision
    /// thresholds no longer match their CRC/derivation (a memory upset).
    pub const TABLE_CORRUPT: Self = Self(1 << 8);
    /// Bit 9: control cycles overran their period several times in a row.
    pub const DEADLINE_MISSED: Self = Self(1 << 9);
    /// Bit 10: an end-of-travel switch of a slider is active, or one of its switch
    /// inputs cannot be read (`hw::TravelSwitches::end_of_travel`).
    pub const LIMIT_SWITCH: Self = Self(1 << 10);
    /// Bit 11: a stroke command stepped beyond the speed or acceleration limit in force and was
    /// clamped by the output stage (`motion::limiter`): the geometry or the planner is
    /// wrong; the drives hold at once.
    pub const OUTPUT_LIMITED: Self = Self(1 << 11);
    /// Bit 16 (warning): following error above the warning threshold.
    pub const FOLLOWING_WARNING: Self = Self(1 << 16);
    /// Bit 17 (warning): an encoder reports its warning bit (position still valid;
    /// maintenance asked for, e.g. a dirty scale).
    pub const ENCODER_WARNING: Self = Self(1 << 17);

    /// Every fault bit in use (bits 0..11).
    pub const ALL_FAULTS: Self = Self(0x0000_0FFF);
    /// Every warning bit in use (bits 16, 17).
    pub const ALL_WARNINGS: Self = Self(0x0003_0000);

    /// Every single flag with its name: the one list of names the mission database, the
    /// ICD's tables and the tools print (host only in use; the flight image links none).
    pub const NAMED: [(Self, &'static str); 14] = [
        (Self::FOLLOWING_ERROR, "FOLLOWING_ERROR"),
        (Self::ENCODER_STUCK, "ENCODER_STUCK"),
        (Self::ENCODER_JUMP, "ENCODER_JUMP"),
        (Self::ENCODER_READ_FAILURE, "ENCODER_READ_FAILURE"),
        (Self::SOFT_LIMIT, "SOFT_LIMIT"),
        (Self::FK_NOT_CONVERGED, "FK_NOT_CONVERGED"),
        (Self::POSE_OUTSIDE_WORKSPACE, "POSE_OUTSIDE_WORKSPACE"),
        (Self::DRIVE_FAULT, "DRIVE_FAULT"),
        (Self::TABLE_CORRUPT, "TABLE_CORRUPT"),
        (Self::DEADLINE_MISSED, "DEADLINE_MISSED"),
        (Self::LIMIT_SWITCH, "LIMIT_SWITCH"),
        (Self::OUTPUT_LIMITED, "OUTPUT_LIMITED"),
        (Self::FOLLOWING_WARNING, "FOLLOWING_WARNING"),
        (Self::ENCODER_WARNING, "ENCODER_WARNING"),
    ];

    /// The name of a single flag (`None` for a set of several flags or for no flag).
    pub fn name(self) -> Option<&'static str> {
        Self::NAMED
            .iter()
            .find(|(f, _)| *f == self)
            .map(|(_, n)| *n)
    }

    /// Bit positions of the faults, in bit order (index = bit).
    pub const FAULT_BITS: usize = 12;

    /// No flag.
    pub const fn empty() -> Self {
        Self(0)
    }

    /// The telemetry word.
    pub const fn bits(self) -> u32 {
        self.0
    }

    /// From a telemetry word, dropping bits no flag uses.
    pub const fn from_bits_truncate(bits: u32) -> Self {
        Self(bits & (Self::ALL_FAULTS.0 | Self::ALL_WARNINGS.0))
    }

    /// No flag set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Every flag of `other` is set.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    /// Some flag of `other` is set.
    pub const fn intersects(self, other: Self) -> bool {
        self.0 & other.0 != 0
    }

    /// Flags in either.
    pub const fn union(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }

    /// Flags in both.
    pub const fn intersection(self, other: Self) -> Self {
        Self(self.0 & other.0)
    }

    /// Flags of `self` not in `other`.
    pub const fn difference(self, other: Self) -> Self {
        Self(self.0 & !other.0)
    }

    /// Sets the flags of `other`.
    pub fn insert(&mut self, other: Self) {
        self.0 |= other.0;
    }

    /// Clears the flags of `other`.
    pub fn remove(&mut self, other: Self) {
        self.0 &= !other.0;
    }

    /// Sets or clears the flags of `other`.
    pub fn set(&mut self, other: Self, on: bool) {
        if on {
            self.insert(other);
        } else {
            self.remove(other);
        }
    }
}

impl BitOr for FaultFlags {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        self.union(rhs)
    }
}

impl BitOrAssign for FaultFlags {
    fn bitor_assign(&mut self, rhs: Self) {
        self.insert(rhs);
    }
}

impl BitAnd for FaultFlags {
    type Output = Self;
    fn bitand(self, rhs: Self) -> Self {
        self.intersection(rhs)
    }
}

impl Not for FaultFlags {
    type Output = Self;
    /// The complement within the flags in use.
    fn not(self) -> Self {
        Self::from_bits_truncate(!self.0)
    }
}
