//! The parameter table's content and its versioned binary layout.
//!
//! Every field is encoded explicitly, little-endian, at a fixed offset; no `transmute`,
//! no `unsafe`, no dependence on the in-memory layout of the Rust structs. The decoder is
//! a checked parse in the smoltcp style: any byte string gives `Ok` or a [`TableError`],
//! never a panic.
//!
//! # Layout, format version 2 ([`TABLE_FORMAT_VERSION`]), [`TABLE_LEN`] = 564 bytes
//!
//! Written once, as the named byte ranges of [`field`] (smoltcp's `mod field`),
//! little-endian: the encoder and the decoder step through them in order (on the host
//! the position is checked at every field the encoder writes and at every group of
//! consecutive fields the decoder reads, `Writer::at` / `Reader::at`), and the mission
//! database's table-image rows and the ICD's generated table (docs/icd.md section 5) take
//! their offsets and sizes from them.
//!
//! A new format version gets a new number; a decoder of version 2 rejects every other.
//! (Version 1, 516 bytes, had no thermal model: version 2 inserts it before the CRC.)

use crc::CRC_32_ISO_HDLC;

use crate::link::error::sat_u16;
use crate::link::wire::{Field, Order, Reader, Writer};

use crate::kinematics::{GeometryParams, LegParams, StrokeLimits, WorkspaceLimits, LEGS};
use crate::nominal;
use crate::thermal::{ThermalModel, PARTS};

/// Magic at the start of every encoded table.
pub const TABLE_MAGIC: [u8; 4] = *b"M2TB";
/// Binary layout version this code writes and reads.
pub const TABLE_FORMAT_VERSION: u16 = 2;
/// Length of the provenance tag (bytes, ASCII).
pub const PROVENANCE_TAG_LEN: usize = 16;
/// Number of joint coordinates in the table: 6 legs x (a, b) x (x, y, z).
pub const JOINT_COORDS: usize = LEGS * 6;

/// The table's layout as named byte ranges, end to end from offset 0 (little-endian;
/// lengths in mm, angles in rad, frames as [`GeometryParams`] gives them; leg arrays are
/// legs 1..6).
pub mod field {
    use super::{JOINT_COORDS, PROVENANCE_TAG_LEN};
    use crate::kinematics::LEGS;
    use crate::link::wire::{after, field, Field};
    use crate::thermal::PARTS;

    /// Bytes of one `f64`.
    const F64: usize = 8;
    /// Bytes of one `f32`.
    const F32: usize = 4;

    /// 4 bytes: magic `"M2TB"` ([`super::TABLE_MAGIC`]).
    pub const MAGIC: Field = field(0, 4);
    /// u16: format version ([`super::TABLE_FORMAT_VERSION`]).
    pub const FORMAT_VERSION: Field = after(&MAGIC, 2);
    /// u16: total length in bytes, CRC included ([`super::TABLE_LEN`]).
    pub const LENGTH: Field = after(&FORMAT_VERSION, 2);
    /// u32: table ID.
    pub const TABLE_ID: Field = after(&LENGTH, 4);
    /// u32: calibration ID.
    pub const CALIBRATION_ID: Field = after(&TABLE_ID, 4);
    /// ASCII: provenance tag, NUL/space padded.
    pub const PROVENANCE_TAG: Field = after(&CALIBRATION_ID, PROVENANCE_TAG_LEN);
    /// 36 x f64: joint centres, leg-major: `a.x a.y a.z` (mm, frame B at zero stroke)
    /// then `b.x b.y b.z` (mm, frame M).
    pub const JOINTS: Field = after(&PROVENANCE_TAG, JOINT_COORDS * F64);
    /// 3 x f64: p0, home position of M's origin (mm, frame B).
    pub const P0: Field = after(&JOINTS, 3 * F64);
    /// 6 x f64: slider stroke lower limits (mm).
    pub const STROKE_MIN: Field = after(&P0, LEGS * F64);
    /// 6 x f64: slider stroke upper limits (mm).
    pub const STROKE_MAX: Field = after(&STROKE_MIN, LEGS * F64);
    /// 3 x f64: workspace half-range x, y, z (mm, base axes).
    pub const WORKSPACE_TRANSLATION: Field = after(&STROKE_MAX, 3 * F64);
    /// 3 x f64: workspace half-range alpha, beta, gamma (rad).
    pub const WORKSPACE_ROTATION: Field = after(&WORKSPACE_TRANSLATION, 3 * F64);
    /// f32: following-error warning threshold (mm).
    pub const FOLLOWING_ERROR_WARNING: Field = after(&WORKSPACE_ROTATION, F32);
    /// f32: following-error fault threshold (mm).
    pub const FOLLOWING_ERROR_FAULT: Field = after(&FOLLOWING_ERROR_WARNING, F32);
    /// f32: encoder jump threshold (mm per control cycle).
    pub const ENCODER_JUMP: Field = after(&FOLLOWING_ERROR_FAULT, F32);
    /// f32: stuck detection, least progress counted as motion (mm).
    pub const STUCK_MIN_PROGRESS: Field = after(&ENCODER_JUMP, F32);
    /// u16: stuck detection window (control cycles).
    pub const STUCK_DETECTION_CYCLES: Field = after(&STUCK_MIN_PROGRESS, 2);
    /// u16: warning debounce (consecutive control cycles).
    pub const WARNING_DEBOUNCE: Field = after(&STUCK_DETECTION_CYCLES, 2);
    /// u16: fault debounce (consecutive control cycles).
    pub const FAULT_DEBOUNCE: Field = after(&WARNING_DEBOUNCE, 2);
    /// u16: reserved, must be 0.
    pub const RESERVED: Field = after(&FAULT_DEBOUNCE, 2);
    /// f32: thermal model, reference temperature (deg C) at which the geometry holds.
    pub const THERMAL_REFERENCE: Field = after(&RESERVED, F32);
    /// 4 x f32: thermal model, linear expansion coefficient of the rods, slider columns,
    /// base plate, platform (1/K; `thermal::Part` order).
    pub const THERMAL_EXPANSION: Field = after(&THERMAL_REFERENCE, PARTS * F32);
    /// f32: thermal model, slider column length from its foot to the lower joint at
    /// zero stroke (mm).
    pub const THERMAL_COLUMN_LENGTH: Field = after(&THERMAL_EXPANSION, F32);
    /// 24 x u8: thermal model, the sensor (0..8) governing each part of each leg,
    /// leg-major, parts in `thermal::Part` order.
    pub const THERMAL_SENSORS: Field = after(&THERMAL_COLUMN_LENGTH, LEGS * PARTS);
    /// u32: CRC-32/ISO-HDLC of every byte before it.
    pub const CRC: Field = after(&THERMAL_SENSORS, 4);
}

/// Bytes of the trailing CRC-32.
pub const TABLE_CRC_LEN: usize = field::CRC.end - field::CRC.start;
/// Length of an encoded table (bytes, CRC included).
pub const TABLE_LEN: usize = field::CRC.end;
/// Offset of the CRC-32 (it covers `0..TABLE_CRC_OFFSET`).
pub const TABLE_CRC_OFFSET: usize = TABLE_LEN - TABLE_CRC_LEN;

// The length field is a u16 and the documented layout is 564 bytes.
const _: () = assert!(TABLE_LEN == 564 && TABLE_LEN <= u16::MAX as usize);
// The CRC is the last field, as the store and the upload path assume.
const _: () = assert!(TABLE_CRC_OFFSET == field::CRC.start);

/// The CRC-32 used for the table and the flash record header (ISO-HDLC, as zlib/Ethernet).
pub const CRC32: NibbleCrc32 = NibbleCrc32::new(&CRC_32_ISO_HDLC);

/// A reflected 32-bit CRC of the `crc` crate's catalogue, computed four bits at a time
/// with a 16-entry table (64 bytes). The crate's byte-wise table is 1 KB of the flight
/// image's flash (which has a 64 KiB goal); bit by bit (its `NoTable`) a table's CRC
/// costs about 33,000 instructions, and a commit computes it under the controller's
/// lock. This costs about twice the byte-wise form. Equal to the crate's result on
/// every input (host test `table::nibble_crc32_equals_the_crc_crate`).
#[derive(Clone, Copy, Debug)]
pub struct NibbleCrc32 {
    /// CRC of the four-bit value `i` (the reflected polynomial applied four times).
    table: [u32; 16],
    /// Initial register (reflected).
    init: u32,
    /// Final XOR.
    xorout: u32,
}

#[allow(clippy::indexing_slicing)] // Table indices are nibbles: below 16, the table's size.
impl NibbleCrc32 {
    /// The CRC of `alg`, which must be a reflected 32-bit algorithm (checked when the
    /// constant is evaluated: compilation fails otherwise).
    pub const fn new(alg: &crc::Algorithm<u32>) -> Self {
        assert!(alg.width == 32 && alg.refin && alg.refout);
        let poly = alg.poly.reverse_bits();
        let mut table = [0u32; 16];
        let mut i = 0;
        while i < 16 {
            let mut c = i as u32;
            let mut bit = 0;
            while bit < 4 {
                c = if c & 1 != 0 { (c >> 1) ^ poly } else { c >> 1 };
                bit += 1;
            }
            table[i] = c;
            i += 1;
        }
        Self {
            table,
            init: alg.init.reverse_bits(),
            xorout: alg.xorout,
        }
    }

    /// The CRC of `bytes`.
    pub fn checksum(&self, bytes: &[u8]) -> u32 {
        let mut c = self.init;
        for b in bytes {
            c ^= u32::from(*b);
            c = (c >> 4) ^ self.table[(c & 0xf) as usize];
            c = (c >> 4) ^ self.table[(c & 0xf) as usize];
        }
        c ^ self.xorout
    }
}

/// Where a calibrated table came from (written by the ground tool).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Provenance {
    /// Identifier of the calibration campaign/run that produced the joint coordinates.
    pub calibration_id: u32,
    /// Free ASCII tag (e.g. date and tool version), padded with NUL or spaces.
    pub tag: [u8; PROVENANCE_TAG_LEN],
}

/// Thresholds of the encoder/following-error supervision, in the working units of the
/// controller (mm of slider stroke along base z, control cycles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupervisionThresholds {
    /// |commanded - measured stroke| above which a following-error warning is raised (mm).
    pub following_error_warning_mm: f32,
    /// |commanded - measured stroke| above which a following-error fault latches (mm);
    /// must exceed the warning threshold.
    pub following_error_fault_mm: f32,
    /// Largest plausible change of one encoder reading between two consecutive control
    /// cycles (mm per cycle); a larger jump is an encoder fault.
    pub encoder_jump_mm_per_cycle: f32,
    /// Least encoder progress (mm) over the stuck window that counts as "moving" while a
    /// motion is commanded.
    pub stuck_min_progress_mm: f32,
    /// Stuck window: a slider commanded to move that progresses less than
    /// `stuck_min_progress_mm` for this many consecutive control cycles is stuck (cycles).
    pub stuck_detection_cycles: u16,
    /// Consecutive control cycles a warning condition must persist before it is reported.
    pub warning_debounce_cycles: u16,
    /// Consecutive control cycles a fault condition must persist before it latches.
    pub fault_debounce_cycles: u16,
}

/// Default following-error warning threshold (mm): 5 um, 50 encoder counts.
pub const DEFAULT_FOLLOWING_ERROR_WARNING_MM: f32 = 0.005;
/// Default following-error fault threshold (mm): 50 um.
pub const DEFAULT_FOLLOWING_ERROR_FAULT_MM: f32 = 0.05;
/// Default encoder jump threshold (mm per cycle): 0.1 mm, far above any slider speed
/// times a control period, far below a lost encoder bit of significance.
pub const DEFAULT_ENCODER_JUMP_MM_PER_CYCLE: f32 = 0.1;
/// Default least progress over the stuck window (mm): 1 um, 10 encoder counts.
pub const DEFAULT_STUCK_MIN_PROGRESS_MM: f32 = 0.001;
/// Default stuck window (control cycles).
pub const DEFAULT_STUCK_DETECTION_CYCLES: u16 = 200;
/// Default warning debounce (control cycles).
pub const DEFAULT_WARNING_DEBOUNCE_CYCLES: u16 = 5;
/// Default fault debounce (control cycles).
pub const DEFAULT_FAULT_DEBOUNCE_CYCLES: u16 = 3;

/// The default supervision thresholds (also those of the nominal table).
pub const DEFAULT_SUPERVISION: SupervisionThresholds = SupervisionThresholds {
    following_error_warning_mm: DEFAULT_FOLLOWING_ERROR_WARNING_MM,
    following_error_fault_mm: DEFAULT_FOLLOWING_ERROR_FAULT_MM,
    encoder_jump_mm_per_cycle: DEFAULT_ENCODER_JUMP_MM_PER_CYCLE,
    stuck_min_progress_mm: DEFAULT_STUCK_MIN_PROGRESS_MM,
    stuck_detection_cycles: DEFAULT_STUCK_DETECTION_CYCLES,
    warning_debounce_cycles: DEFAULT_WARNING_DEBOUNCE_CYCLES,
    fault_debounce_cycles: DEFAULT_FAULT_DEBOUNCE_CYCLES,
};

/// Table ID of the compiled-in nominal table.
pub const NOMINAL_TABLE_ID: u32 = 0;
/// Calibration ID of the compiled-in nominal table (no calibration).
pub const NOMINAL_CALIBRATION_ID: u32 = 0;
/// Provenance tag of the compiled-in nominal table.
pub const NOMINAL_TAG: [u8; PROVENANCE_TAG_LEN] = *b"NOMINAL-PROTO-V1";

/// The calibrated parameter table: everything the controller needs that may change on
/// orbit. Unlike [`GeometryParams`] the limits are always present.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Table {
    /// Operator-visible table identifier (reported in housekeeping).
    pub table_id: u32,
    /// Ground-tool provenance.
    pub provenance: Provenance,
    /// Joint centres of legs 1..6 (`a`: frame B at zero stroke, `b`: frame M; mm).
    pub legs: [LegParams; LEGS],
    /// Home position of M's origin in B (mm).
    pub p0_mm: [f64; 3],
    /// Slider soft stroke limits (mm).
    pub stroke_limits: StrokeLimits,
    /// Workspace half-ranges (mm, rad).
    pub workspace: WorkspaceLimits,
    /// Supervision thresholds.
    pub supervision: SupervisionThresholds,
    /// Thermal model (issue 22; [`ThermalModel::NONE`]: no compensation).
    pub thermal: ThermalModel,
}

/// Why bytes are not a table. Stable numeric codes for telemetry (family 0x04xx).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableError {
    /// Fewer or more bytes than the length field / [`TABLE_LEN`] says.
    WrongLength {
        /// Bytes given (saturated at `u16::MAX`).
        got: u16,
    },
    /// The first four bytes are not [`TABLE_MAGIC`].
    BadMagic,
    /// A format version this code does not read.
    UnsupportedVersion {
        /// Version found.
        version: u16,
    },
    /// The length field disagrees with the format version's length.
    BadLengthField {
        /// Length field found.
        length: u16,
    },
    /// The CRC-32 over the table does not match.
    BadCrc,
    /// A reserved field is not zero.
    ReservedNotZero,
    /// [`GeometryParams`] without stroke or workspace limits cannot become a table.
    MissingLimits,
}

impl TableError {
    /// Stable numeric code for telemetry.
    pub const fn code(&self) -> u16 {
        match self {
            TableError::WrongLength { .. } => 0x0401,
            TableError::BadMagic => 0x0402,
            TableError::UnsupportedVersion { .. } => 0x0403,
            TableError::BadLengthField { .. } => 0x0404,
            TableError::BadCrc => 0x0405,
            TableError::ReservedNotZero => 0x0406,
            TableError::MissingLimits => 0x0407,
        }
    }
}

impl Table {
    /// The compiled-in nominal table: [`nominal::prototype_with_flight_limits`], the
    /// default supervision thresholds, table ID [`NOMINAL_TABLE_ID`].
    pub const fn nominal() -> Table {
        let g = nominal::prototype_with_flight_limits();
        // `prototype_with_flight_limits` always sets both limits; the fallbacks are the
        // same constants, so the nominal table is the same either way.
        let stroke_limits = match g.stroke_limits {
            Some(s) => s,
            None => StrokeLimits {
                min_mm: [-nominal::STROKE_LIMIT_MM; LEGS],
                max_mm: [nominal::STROKE_LIMIT_MM; LEGS],
            },
        };
        let workspace = match g.workspace {
            Some(w) => w,
            None => WorkspaceLimits {
                translation_mm: [nominal::WORKSPACE_TRANSLATION_MM; 3],
                rotation_rad: [nominal::WORKSPACE_ROTATION_ARCSEC / crate::units::ARCSEC_PER_RAD;
                    3],
            },
        };
        Table {
            table_id: NOMINAL_TABLE_ID,
            provenance: Provenance {
                calibration_id: NOMINAL_CALIBRATION_ID,
                tag: NOMINAL_TAG,
            },
            legs: g.legs,
            p0_mm: g.p0_mm,
            stroke_limits,
            workspace,
            supervision: DEFAULT_SUPERVISION,
            thermal: ThermalModel::NONE,
        }
    }

    /// A table from geometry parameters, which must carry both limits; no thermal
    /// model ([`ThermalModel::NONE`]; set `thermal` for one).
    pub fn from_geometry(
        params: &GeometryParams,
        table_id: u32,
        provenance: Provenance,
        supervision: SupervisionThresholds,
    ) -> Result<Table, TableError> {
        let (Some(stroke_limits), Some(workspace)) = (params.stroke_limits, params.workspace)
        else {
            return Err(TableError::MissingLimits);
        };
        Ok(Table {
            table_id,
            provenance,
            legs: params.legs,
            p0_mm: params.p0_mm,
            stroke_limits,
            workspace,
            supervision,
            thermal: ThermalModel::NONE,
        })
    }

    /// The geometry for the kinematics (limits always `Some`).
    pub const fn geometry_params(&self) -> GeometryParams {
        GeometryParams {
            legs: self.legs,
            p0_mm: self.p0_mm,
            stroke_limits: Some(self.stroke_limits),
            workspace: Some(self.workspace),
        }
    }

    /// Joint coordinate `index` in table order (leg-major; per leg `a.xyz` then `b.xyz`),
    /// mm. `None` past [`JOINT_COORDS`].
    pub fn joint_coord_mm(&self, index: usize) -> Option<f64> {
        let leg = self.legs.get(index / 6)?;
        let k = index % 6;
        if k < 3 {
            leg.a_mm.get(k).copied()
        } else {
            leg.b_mm.get(k - 3).copied()
        }
    }

    /// Encodes the table into its binary layout, CRC included.
    pub fn encode(&self, out: &mut [u8; TABLE_LEN]) {
        // The buffer is exactly the layout's length: every field fits.
        let _ = self.write(&mut Writer::new(out, Order::Little));
        let crc = out
            .get(..TABLE_CRC_OFFSET)
            .map_or(0, |body| CRC32.checksum(body));
        for (dst, src) in out.iter_mut().skip(TABLE_CRC_OFFSET).zip(crc.to_le_bytes()) {
            *dst = src;
        }
    }

    /// The fields in layout order into `w` (out of line: inlined into
    /// [`Table::encode`], 32 bytes of flash more).
    #[inline(never)]
    fn write(&self, w: &mut Writer<'_>) -> Option<()> {
        let at = |w: &mut Writer<'_>, f: Field| w.at(0, &f);
        at(w, field::MAGIC)?;
        w.put(&TABLE_MAGIC)?;
        at(w, field::FORMAT_VERSION)?;
        w.u16(TABLE_FORMAT_VERSION)?;
        at(w, field::LENGTH)?;
        w.u16(TABLE_LEN as u16)?;
        at(w, field::TABLE_ID)?;
        w.u32(self.table_id)?;
        at(w, field::CALIBRATION_ID)?;
        w.u32(self.provenance.calibration_id)?;
        at(w, field::PROVENANCE_TAG)?;
        w.put(&self.provenance.tag)?;
        at(w, field::JOINTS)?;
        for leg in &self.legs {
            w.f64s(&leg.a_mm)?;
            w.f64s(&leg.b_mm)?;
        }
        at(w, field::P0)?;
        w.f64s(&self.p0_mm)?;
        at(w, field::STROKE_MIN)?;
        w.f64s(&self.stroke_limits.min_mm)?;
        at(w, field::STROKE_MAX)?;
        w.f64s(&self.stroke_limits.max_mm)?;
        at(w, field::WORKSPACE_TRANSLATION)?;
        w.f64s(&self.workspace.translation_mm)?;
        at(w, field::WORKSPACE_ROTATION)?;
        w.f64s(&self.workspace.rotation_rad)?;
        let s = &self.supervision;
        at(w, field::FOLLOWING_ERROR_WARNING)?;
        w.f32(s.following_error_warning_mm)?;
        at(w, field::FOLLOWING_ERROR_FAULT)?;
        w.f32(s.following_error_fault_mm)?;
        at(w, field::ENCODER_JUMP)?;
        w.f32(s.encoder_jump_mm_per_cycle)?;
        at(w, field::STUCK_MIN_PROGRESS)?;
        w.f32(s.stuck_min_progress_mm)?;
        at(w, field::STUCK_DETECTION_CYCLES)?;
        w.u16(s.stuck_detection_cycles)?;
        at(w, field::WARNING_DEBOUNCE)?;
        w.u16(s.warning_debounce_cycles)?;
        at(w, field::FAULT_DEBOUNCE)?;
        w.u16(s.fault_debounce_cycles)?;
        at(w, field::RESERVED)?;
        w.u16(0)?;
        let th = &self.thermal;
        at(w, field::THERMAL_REFERENCE)?;
        w.f32(th.reference_c)?;
        at(w, field::THERMAL_EXPANSION)?;
        for a in &th.expansion_per_k {
            w.f32(*a)?;
        }
        at(w, field::THERMAL_COLUMN_LENGTH)?;
        w.f32(th.column_length_mm)?;
        at(w, field::THERMAL_SENSORS)?;
        for leg in &th.sensor_of {
            w.put(leg)?;
        }
        at(w, field::CRC)
    }

    /// The encoded table (convenience for callers with no buffer at hand).
    pub fn to_bytes(&self) -> [u8; TABLE_LEN] {
        let mut out = [0u8; TABLE_LEN];
        self.encode(&mut out);
        out
    }

    /// CRC-32 of the encoded table (the value stored in its last four bytes).
    pub fn crc32(&self) -> u32 {
        let bytes = self.to_bytes();
        stored_crc(&bytes).unwrap_or(0)
    }

    /// Checked parse of an encoded table: exact length, magic, version, length field,
    /// CRC, reserved field. Values are not judged here (NaN decodes); see
    /// [`super::validate()`].
    pub fn decode(bytes: &[u8]) -> Result<Table, TableError> {
        if bytes.len() != TABLE_LEN {
            return Err(TableError::WrongLength {
                got: sat_u16(bytes.len()),
            });
        }
        let mut r = Reader::new(bytes, Order::Little);
        let short = TableError::WrongLength {
            got: sat_u16(bytes.len()),
        };
        // Each field read where `field` puts it (checked on the host; see `Reader::at`).
        let at = |r: &Reader<'_>, f: Field| r.at(0, &f).ok_or(short);
        at(&r, field::MAGIC)?;
        if r.take::<4>() != Some(TABLE_MAGIC) {
            return Err(TableError::BadMagic);
        }
        at(&r, field::FORMAT_VERSION)?;
        let version = r.u16().ok_or(short)?;
        if version != TABLE_FORMAT_VERSION {
            return Err(TableError::UnsupportedVersion { version });
        }
        at(&r, field::LENGTH)?;
        let length = r.u16().ok_or(short)?;
        if usize::from(length) != TABLE_LEN {
            return Err(TableError::BadLengthField { length });
        }
        let body = bytes.get(..TABLE_CRC_OFFSET).ok_or(short)?;
        if Some(CRC32.checksum(body)) != stored_crc(bytes) {
            return Err(TableError::BadCrc);
        }
        // Decoded field by field into the one table value that is returned (no array
        // or struct temporaries: this runs on the worker's and the link's stack).
        let mut t = ZEROED_TABLE;
        at(&r, field::TABLE_ID)?;
        t.table_id = r.u32().ok_or(short)?;
        at(&r, field::CALIBRATION_ID)?;
        t.provenance.calibration_id = r.u32().ok_or(short)?;
        at(&r, field::PROVENANCE_TAG)?;
        t.provenance.tag = r.take::<PROVENANCE_TAG_LEN>().ok_or(short)?;
        at(&r, field::JOINTS)?;
        for leg in t.legs.iter_mut() {
            for x in leg.a_mm.iter_mut().chain(leg.b_mm.iter_mut()) {
                *x = r.f64().ok_or(short)?;
            }
        }
        // p0, the stroke limits and the workspace: consecutive f64 fields, in order.
        at(&r, field::P0)?;
        let f64_fields = t
            .p0_mm
            .iter_mut()
            .chain(t.stroke_limits.min_mm.iter_mut())
            .chain(t.stroke_limits.max_mm.iter_mut())
            .chain(t.workspace.translation_mm.iter_mut())
            .chain(t.workspace.rotation_rad.iter_mut());
        for x in f64_fields {
            *x = r.f64().ok_or(short)?;
        }
        let s = &mut t.supervision;
        at(&r, field::FOLLOWING_ERROR_WARNING)?;
        s.following_error_warning_mm = r.f32().ok_or(short)?;
        s.following_error_fault_mm = r.f32().ok_or(short)?;
        s.encoder_jump_mm_per_cycle = r.f32().ok_or(short)?;
        s.stuck_min_progress_mm = r.f32().ok_or(short)?;
        at(&r, field::STUCK_DETECTION_CYCLES)?;
        s.stuck_detection_cycles = r.u16().ok_or(short)?;
        s.warning_debounce_cycles = r.u16().ok_or(short)?;
        s.fault_debounce_cycles = r.u16().ok_or(short)?;
        at(&r, field::RESERVED)?;
        if r.u16().ok_or(short)? != 0 {
            return Err(TableError::ReservedNotZero);
        }
        let th = &mut t.thermal;
        at(&r, field::THERMAL_REFERENCE)?;
        th.reference_c = r.f32().ok_or(short)?;
        for a in th.expansion_per_k.iter_mut() {
            *a = r.f32().ok_or(short)?;
        }
        th.column_length_mm = r.f32().ok_or(short)?;
        at(&r, field::THERMAL_SENSORS)?;
        for leg in th.sensor_of.iter_mut() {
            *leg = r.take::<PARTS>().ok_or(short)?;
        }
        at(&r, field::CRC)?;
        Ok(t)
    }
}

/// All fields zero: what [`Table::decode`] fills in.
const ZEROED_TABLE: Table = Table {
    table_id: 0,
    provenance: Provenance {
        calibration_id: 0,
        tag: [0; PROVENANCE_TAG_LEN],
    },
    legs: [LegParams {
        a_mm: [0.0; 3],
        b_mm: [0.0; 3],
    }; LEGS],
    p0_mm: [0.0; 3],
    stroke_limits: StrokeLimits {
        min_mm: [0.0; LEGS],
        max_mm: [0.0; LEGS],
    },
    workspace: WorkspaceLimits {
        translation_mm: [0.0; 3],
        rotation_rad: [0.0; 3],
    },
    supervision: SupervisionThresholds {
        following_error_warning_mm: 0.0,
        following_error_fault_mm: 0.0,
        encoder_jump_mm_per_cycle: 0.0,
        stuck_min_progress_mm: 0.0,
        stuck_detection_cycles: 0,
        warning_debounce_cycles: 0,
        fault_debounce_cycles: 0,
    },
    thermal: ThermalModel {
        reference_c: 0.0,
        expansion_per_k: [0.0; PARTS],
        column_length_mm: 0.0,
        sensor_of: [[0; PARTS]; LEGS],
    },
};

/// The CRC-32 stored in the last four bytes of an encoded table; `None` if too short.
pub fn stored_crc(bytes: &[u8]) -> Option<u32> {
    let tail: [u8; TABLE_CRC_LEN] = bytes.get(TABLE_CRC_OFFSET..TABLE_LEN)?.try_into().ok()?;
    Some(u32::from_le_bytes(tail))
}
