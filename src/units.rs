//! Unit conversion factors, each defined once (flight code, simulation, ground tools and
//! tests all take them from here).
//!
//! The units in use:
//! * length: millimetres (mm) in the kinematics and the table; nanometres (nm, i32) on
//!   the wire; micrometres (um) in the ground's engineering displays; picometres (pm) in
//!   the encoder and drive arithmetic; metres (m) for tracker distances;
//! * angle: radians (rad) in the kinematics; arcseconds (arcsec) for operators and
//!   files; micro-arcseconds (uas, i32) on the wire; milli-arcseconds (mas) in the
//!   ST[20] parameters;
//! * time: seconds (s), milliseconds (ms), microseconds (us).
//!
//! A factor `A_PER_B` multiplies a quantity in B to give it in A. A factor that is
//! needed in several types is defined once, in the exact integer where one exists, and
//! the other types are derived from it (`_F32`, `_I64` suffixes; no suffix is `f64`).
//! The reciprocals are computed here (`1.0 / x`, correctly rounded, so equal to the
//! decimal literal: checked below).

use core::f64::consts::PI;

/// Nanometres per millimetre (exact integer).
pub const NM_PER_MM_I64: i64 = 1_000_000;
/// Nanometres per millimetre.
pub const NM_PER_MM: f64 = NM_PER_MM_I64 as f64;
/// Nanometres per millimetre in f32 (exact: 10^6 < 2^24).
pub const NM_PER_MM_F32: f32 = NM_PER_MM_I64 as f32;
/// Millimetres per nanometre.
pub const MM_PER_NM: f64 = 1.0 / NM_PER_MM;
/// Micrometres per millimetre.
pub const UM_PER_MM: f64 = 1.0e3;
/// Millimetres per micrometre.
pub const MM_PER_UM: f64 = 1.0 / UM_PER_MM;
/// Nanometres per micrometre.
pub const NM_PER_UM: f64 = 1.0e3;
/// Micrometres per nanometre.
pub const UM_PER_NM: f64 = 1.0 / NM_PER_UM;
/// Picometres per millimetre.
pub const PM_PER_MM: f64 = 1.0e9;
/// Millimetres per metre.
pub const MM_PER_M: f64 = 1.0e3;

/// Arcseconds per radian (180 * 3600 / pi).
pub const ARCSEC_PER_RAD: f64 = 180.0 * 3600.0 / PI;
/// Micro-arcseconds per arcsecond (exact integer).
pub const UAS_PER_ARCSEC_I32: i32 = 1_000_000;
/// Micro-arcseconds per arcsecond.
pub const UAS_PER_ARCSEC: f64 = UAS_PER_ARCSEC_I32 as f64;
/// Arcseconds per micro-arcsecond.
pub const ARCSEC_PER_UAS: f64 = 1.0 / UAS_PER_ARCSEC;
/// Micro-arcseconds per radian.
pub const UAS_PER_RAD: f64 = ARCSEC_PER_RAD * UAS_PER_ARCSEC;
/// Milli-arcseconds per arcsecond.
pub const MAS_PER_ARCSEC: f64 = 1.0e3;

/// Microseconds per second.
pub const US_PER_S: u32 = 1_000_000;
/// Milliseconds per second.
pub const MS_PER_S: u32 = 1_000;
/// Microseconds per millisecond.
pub const US_PER_MS: u32 = 1_000;

// The derived reciprocals are the decimal values they stand for, to the bit.
const _: () = assert!(MM_PER_NM == 1.0e-6);
const _: () = assert!(MM_PER_UM == 1.0e-3);
const _: () = assert!(UM_PER_NM == 1.0e-3);
const _: () = assert!(ARCSEC_PER_UAS == 1.0e-6);
const _: () = assert!(NM_PER_MM_F32 == 1.0e6);
const _: () = assert!(US_PER_MS * MS_PER_S == US_PER_S);
