//! Failure codes: every `code()` of the flight error types, where it is reported and
//! what its data holds.

use serde::Serialize;

use super::housekeeping::housekeeping_fields;
use super::names::{hex4, thousands, uniform, upper_snake};
use m2ctl::controller::params::{ParamError, PARAMETERS};
use m2ctl::controller::schedule::ScheduleError;
use m2ctl::controller::{CommandError, State};
use m2ctl::kinematics::{FkError, GeometryError, IkError, Refusals};
use m2ctl::link::command::TABLE_CHUNK_MAX_LEN;
use m2ctl::link::schedule::{MAX_SCHEDULED_TC_LEN, SCHEDULE_CAPACITY};
use m2ctl::link::tc::{RequestId, MIN_TC_PACKET_LEN};
use m2ctl::link::{service, subtype, LinkError, MAX_TC_PACKET_LEN, PUS_C_VERSION};
use m2ctl::motion::{MotionError, StrokeMoveError};
use m2ctl::supervision::FaultFlags;
use m2ctl::table::{StoreError, TableError, ValidationError};

/// Where a failure code reaches the ground (docs/icd.md section 7, column "report").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind", content = "code")]
pub enum ReportedIn {
    /// TM[1,2]: the decoder refuses the packet.
    AcceptanceFailure,
    /// TM[1,4]: the controller refuses to begin.
    StartFailure,
    /// TM[1,8]: something that had started failed.
    CompletionFailure,
    /// TM[1,8], or TM[1,4] when it happens while a move is being planned.
    CompletionOrStartFailure,
    /// No report (there is no request ID to report on): counted in housekeeping.
    CountedOnly,
    /// Never itself: the report carries the code it wraps.
    AsWrappedCode,
    /// Only inside the failure data of the code given.
    InsideDataOf(u16),
    /// Never on the wire (a family enumerated for completeness).
    NotReported,
}

/// One failure code: docs/icd.md's row (section 7) and the mission database's
/// enumeration value (label and meaning).
#[derive(Clone, Debug, Serialize)]
pub struct FailureCode {
    /// The code (a `code()` of the flight error types).
    pub code: u16,
    /// Family prefix of the label.
    pub family: &'static str,
    /// Enumeration label: family and variant name (`MOTION_TARGET_REFUSED`).
    pub label: String,
    /// Origin column of docs/icd.md.
    pub origin: &'static str,
    /// What it means.
    pub meaning: String,
    /// Which report carries it.
    pub report: ReportedIn,
    /// What its failure data (u32) holds; "a/b" is `a << 16 | b`.
    pub data: String,
}

/// Every failure code the controller has, by family (one instance of each variant of
/// the flight error types), with what docs/icd.md says of it. A variant missing here
/// fails `ground/tests/mdb.rs` (every `=> 0x0NNN` arm of a `code()` must be listed).
pub fn failure_codes() -> Vec<FailureCode> {
    use ReportedIn::{
        AcceptanceFailure as Acc, AsWrappedCode, CompletionFailure as Compl,
        CompletionOrStartFailure, CountedOnly, InsideDataOf, NotReported, StartFailure as Start,
    };
    let mut v: Vec<FailureCode> = Vec::new();
    let mut push = |family: &'static str,
                    origin: &'static str,
                    code: u16,
                    debug: String,
                    (report, meaning, data): (ReportedIn, String, String)| {
        v.push(FailureCode {
            code,
            family,
            label: format!("{family}_{}", upper_snake(&debug)),
            origin,
            meaning,
            report,
            data,
        });
    };
    let d = |r: ReportedIn, meaning: &str, data: &str| (r, meaning.to_string(), data.to_string());
    let validation = m2ctl::table::ValidationConfig::flight();
    let (ws_mm, ws_arcsec) = super::names::workspace_caps();
    let max_obt_ms = u64::from(u32::MAX) * u64::from(m2ctl::timing::CYCLE_US) / 1000;
    use m2ctl::table::validate::field_index as fi;
    let range = |a: u16, b: u16| format!("{a}..{}", b - 1);

    for (e, doc) in [
        (
            LinkError::Truncated { got: 0, needed: 0 },
            d(
                Acc,
                &format!(
                    "truncated: shorter than {MIN_TC_PACKET_LEN} bytes or than the length field"
                ),
                "received/needed",
            ),
        ),
        (
            LinkError::LengthMismatch {
                got: 0,
                declared: 0,
            },
            d(
                Acc,
                "wrong length: bytes after the packet's declared end",
                "received/declared",
            ),
        ),
        (
            LinkError::Oversized,
            d(
                Acc,
                &format!("oversized: packet or declared length > {MAX_TC_PACKET_LEN}"),
                "0",
            ),
        ),
        (
            LinkError::BadFraming,
            d(CountedOnly, "bad COBS framing", "0"),
        ),
        (
            LinkError::BadCrc { found: 0 },
            d(Acc, "CRC-16 mismatch", "CRC found"),
        ),
        (
            LinkError::WrongApid { apid: 0 },
            d(Acc, "wrong APID", "APID found"),
        ),
        (
            LinkError::BadPrimaryHeader,
            d(
                Acc,
                "not an unsegmented version-0 TC with secondary header",
                "0",
            ),
        ),
        (
            LinkError::UnsupportedPusVersion { version: 0 },
            d(Acc, &format!("PUS version not {PUS_C_VERSION}"), "version"),
        ),
        (
            LinkError::UnknownService { service: 0 },
            d(Acc, "unknown service", "service"),
        ),
        (
            LinkError::UnknownSubtype {
                service: 0,
                subtype: 0,
            },
            d(Acc, "unknown subtype", "service/subtype"),
        ),
        (
            LinkError::UnknownFunction { function_id: 0 },
            d(Acc, "unknown function ID", "function ID"),
        ),
        (
            LinkError::AppDataLength {
                got: 0,
                expected: 0,
            },
            d(Acc, "application data length wrong", "received/expected"),
        ),
        (
            LinkError::InvalidArgument { index: 0 },
            d(
                Acc,
                "argument out of range (leg, memory ID, a count of parameters or activities, the \
                 time report rate)",
                "argument index (0-based; TC[8,1]'s function ID not counted)",
            ),
        ),
        (
            LinkError::ChunkOutOfRange {
                offset: 0,
                length: 0,
            },
            d(
                Acc,
                &format!("table chunk empty, > {TABLE_CHUNK_MAX_LEN} bytes or beyond the table"),
                "offset/length",
            ),
        ),
        (
            LinkError::EmbeddedTc { index: 0, code: 0 },
            d(
                Acc,
                &format!(
                    "a TC[{s},{}]'s embedded telecommand is refused (the code it would get \
                     alone; {} also when longer than {MAX_SCHEDULED_TC_LEN} bytes, {} when it \
                     cannot be scheduled)",
                    subtype::SCHEDULE_INSERT,
                    hex4(LinkError::Oversized.code()),
                    hex4(
                        LinkError::NotSchedulable {
                            service: 0,
                            subtype: 0
                        }
                        .code()
                    ),
                    s = service::SCHEDULING,
                ),
                "activity index/code",
            ),
        ),
        (
            LinkError::NotSchedulable {
                service: 0,
                subtype: 0,
            },
            d(
                InsideDataOf(LinkError::EmbeddedTc { index: 0, code: 0 }.code()),
                &format!(
                    "a telecommand that cannot be scheduled: TC[{},x] or a table chunk TC[{},{}]",
                    service::SCHEDULING,
                    service::MEMORY,
                    subtype::MEMORY_LOAD
                ),
                "service/subtype",
            ),
        ),
    ] {
        push("LINK", "link", e.code(), format!("{e:?}"), doc);
    }
    let in_geometry = InsideDataOf(ValidationError::Geometry(GeometryError::NonFinite).code());
    let geometry = [
        (GeometryError::NonFinite, "non-finite"),
        (
            GeometryError::UpperNotAboveLower { leg: 0 },
            "upper joint not above the lower",
        ),
        (
            GeometryError::BadStrokeLimits { leg: 0 },
            "bad stroke limits",
        ),
        (GeometryError::BadWorkspaceLimits, "bad workspace"),
    ];
    for (e, meaning) in geometry {
        push(
            "GEOMETRY",
            "geometry",
            e.code(),
            format!("{e:?}"),
            d(in_geometry, meaning, "—"),
        );
    }
    for (e, meaning) in [
        (IkError::NonFinite, "non-finite pose"),
        (
            IkError::OutsideWorkspace { axes: 0 },
            "pose outside the workspace",
        ),
        (IkError::Unreachable { legs: 0 }, "a leg cannot reach"),
        (
            IkError::StrokeLimit { legs: 0 },
            "a stroke beyond its limit",
        ),
    ] {
        push(
            "IK",
            "IK",
            e.code(),
            format!("{e:?}"),
            d(NotReported, meaning, "—"),
        );
    }
    let in_fk = InsideDataOf(
        ValidationError::FkFailed {
            corner: 0,
            fk_code: 0,
        }
        .code(),
    );
    for (e, meaning) in [
        (FkError::NonFinite, "non-finite"),
        (
            FkError::Unreachable {
                legs: 0,
                iterations: 0,
            },
            "a leg cannot reach on the way",
        ),
        (
            FkError::SingularJacobian { iterations: 0 },
            "singular Jacobian",
        ),
        (FkError::NotConverged { iterations: 0 }, "not converged"),
        (
            FkError::ResidualTooLarge { iterations: 0 },
            "residual too large",
        ),
    ] {
        push(
            "FK",
            "FK",
            e.code(),
            format!("{e:?}"),
            d(in_fk, meaning, "—"),
        );
    }
    for (e, meaning) in [
        (TableError::WrongLength { got: 0 }, "wrong length"),
        (TableError::BadMagic, "bad magic"),
        (
            TableError::UnsupportedVersion { version: 0 },
            "unsupported format version",
        ),
        (
            TableError::BadLengthField { length: 0 },
            "length field wrong",
        ),
        (TableError::BadCrc, "CRC-32 wrong"),
        (TableError::ReservedNotZero, "reserved field not 0"),
        (TableError::MissingLimits, "limits missing"),
    ] {
        push(
            "TABLE",
            "table image",
            e.code(),
            format!("{e:?}"),
            d(Start, meaning, "0"),
        );
    }
    let geometry_codes = geometry.map(|(e, _)| e.code());
    for (e, doc) in [
        (
            ValidationError::ProvenanceNotAscii { index: 0 },
            d(Compl, "provenance tag not printable ASCII", "byte index"),
        ),
        (
            ValidationError::NonFinite { field: 0 },
            d(
                Compl,
                "a number is NaN or infinite",
                &format!(
                    "field: {} joints, {} p0, {} stroke min, {} stroke max, {} workspace \
                     translation, {} workspace rotation, {} the f32 thresholds",
                    range(0, fi::P0),
                    range(fi::P0, fi::STROKE_MIN),
                    range(fi::STROKE_MIN, fi::STROKE_MAX),
                    range(fi::STROKE_MAX, fi::WORKSPACE_TRANSLATION),
                    range(fi::WORKSPACE_TRANSLATION, fi::WORKSPACE_ROTATION),
                    range(fi::WORKSPACE_ROTATION, fi::SUPERVISION),
                    range(fi::SUPERVISION, fi::SUPERVISION + 4),
                ),
            ),
        ),
        (
            ValidationError::CoordinateOffNominal { index: 0 },
            d(
                Compl,
                &format!(
                    "a joint coordinate or p0 component more than {} mm off nominal",
                    uniform(&[validation.max_coordinate_deviation_mm])
                ),
                &format!(
                    "coordinate index ({} joints, {} p0)",
                    range(0, fi::P0),
                    range(fi::P0, fi::STROKE_MIN)
                ),
            ),
        ),
        (
            ValidationError::RodLengthImplausible { leg: 0 },
            d(
                Compl,
                &format!(
                    "a rod length more than {} mm off nominal",
                    uniform(&[validation.max_rod_deviation_mm])
                ),
                "leg (0-based)",
            ),
        ),
        (
            ValidationError::Geometry(GeometryError::NonFinite),
            d(
                Compl,
                "geometry unusable (rods, limits)",
                &format!(
                    "geometry code {}..{} ({})",
                    hex4(geometry_codes.iter().copied().min().unwrap_or(0)),
                    hex4(geometry_codes.iter().copied().max().unwrap_or(0)),
                    geometry.map(|(_, m)| m).join(", ")
                ),
            ),
        ),
        (
            ValidationError::StrokeLimitBeyondCap { leg: 0 },
            d(
                Compl,
                &format!(
                    "a stroke limit beyond ±{} mm",
                    uniform(&[validation.max_abs_stroke_limit_mm])
                ),
                "leg (0-based)",
            ),
        ),
        (
            ValidationError::WorkspaceBeyondCap { axis: 0 },
            d(
                Compl,
                &format!(
                    "a workspace half-range beyond ±{} mm / ±{}\"",
                    ws_mm, ws_arcsec
                ),
                "axis 0..5",
            ),
        ),
        (
            ValidationError::Supervision { field: 0 },
            d(
                Compl,
                "a supervision threshold not positive, or warning >= fault",
                "field 0..6 in layout order: the first not positive; 1 (the fault threshold) \
                 when warning >= fault",
            ),
        ),
        (
            ValidationError::Unreachable { legs: 0 },
            d(Compl, "part of the workspace unreachable", "leg mask"),
        ),
        (
            ValidationError::StrokeLimitExceeded { legs: 0 },
            d(
                Compl,
                "part of the workspace beyond a stroke limit",
                "leg mask",
            ),
        ),
        (
            ValidationError::FkFailed {
                corner: 0,
                fk_code: 0,
            },
            d(
                Compl,
                "FK from home fails at a workspace corner",
                "FK code low byte << 8 / corner",
            ),
        ),
        (
            ValidationError::FkInaccurate { corner: 0 },
            d(Compl, "FK at a corner does not return the corner", "corner"),
        ),
        (
            ValidationError::BadConfig,
            d(Compl, "validation configuration out of range (defect)", "0"),
        ),
        (
            ValidationError::Thermal { field: 0 },
            d(
                Compl,
                "thermal model out of range",
                "field: 1 reference, 2 expansion, 3 column length, 4 sensor",
            ),
        ),
    ] {
        push("VALIDATION", "validation", e.code(), format!("{e:?}"), doc);
    }
    for (e, doc) in [
        (
            StoreError::BadLayout,
            d(Compl, "bank layout does not fit the flash (defect)", "0"),
        ),
        (
            StoreError::Flash(embedded_storage::nor_flash::NorFlashErrorKind::Other),
            d(Compl, "the flash driver failed (e.g. power loss)", "0"),
        ),
        (
            StoreError::Invalid(ValidationError::BadConfig),
            d(
                AsWrappedCode,
                "refused by validation (nested; reported as its 0x041x code)",
                "—",
            ),
        ),
        (
            StoreError::VerifyFailed,
            d(Compl, "read-back after a write differs", "0"),
        ),
        (
            StoreError::NoRecord(m2ctl::table::BankStatus::Blank),
            d(
                Compl,
                "the bank holds no complete, CRC-valid record (switch bank)",
                "the bank's status flag (boot flags above)",
            ),
        ),
        (
            StoreError::Busy,
            d(Compl, "a write is already in progress (defect guard)", "0"),
        ),
        (
            StoreError::NotExpected,
            d(
                Compl,
                "the record is not the one expected (activate of a vanished pending table)",
                "0",
            ),
        ),
        (
            StoreError::ThresholdConflict,
            d(
                Compl,
                "activate, switch bank or revert: the table's following-error thresholds with \
                 the overrides in force (parameters 0x0030/0x0031) would leave the warning not \
                 below the fault threshold; nothing persisted",
                "0",
            ),
        ),
    ] {
        push("STORE", "store", e.code(), format!("{e:?}"), doc);
    }
    for (e, doc) in [
        (
            MotionError::NonFinite,
            d(Start, "move: non-finite pose", "0"),
        ),
        (
            MotionError::BadLimits { leg: 0 },
            d(Start, "move: motion limits invalid", "0"),
        ),
        (
            MotionError::StartRefused(Refusals::default()),
            d(
                Start,
                "move: the start pose (of the held strokes) is refused by the workspace check",
                "refusal bits",
            ),
        ),
        (
            MotionError::TargetRefused(Refusals::default()),
            d(
                Start,
                "move: the target is refused by the workspace check",
                "refusal bits",
            ),
        ),
        (
            MotionError::PathRefused {
                sample: 0,
                refusals: Refusals::default(),
            },
            d(
                Start,
                "move: the straight path leaves the workspace/stroke range between its ends",
                "refusal bits",
            ),
        ),
        (
            MotionError::TooLong,
            d(
                Start,
                &format!(
                    "move too long (more than 2^{} cycles)",
                    m2ctl::motion::MAX_MOVE_CYCLES.trailing_zeros()
                ),
                "0",
            ),
        ),
    ] {
        push("MOTION", "motion", e.code(), format!("{e:?}"), doc);
    }
    let max_delta_id = PARAMETERS
        .get(m2ctl::controller::params::index::DIRECT_MAX_DELTA)
        .map_or(0, |p| p.id);
    for (e, doc) in [
        (
            StrokeMoveError::BadLeg,
            d(Start, "direct stroke: bad leg", "0"),
        ),
        (
            StrokeMoveError::NonFinite,
            d(Start, "direct stroke: non-finite stroke or delta", "0"),
        ),
        (
            StrokeMoveError::BadLimits,
            d(Start, "direct stroke: limits invalid", "0"),
        ),
        (
            StrokeMoveError::DeltaTooLarge,
            d(
                Start,
                &format!(
                    "direct stroke: the delta exceeds the largest direct-stroke delta \
                     (parameter {})",
                    hex4(max_delta_id)
                ),
                "0",
            ),
        ),
        (
            StrokeMoveError::OutsideStrokeRange,
            d(
                Start,
                "direct stroke: destination outside the stroke limits and no closer",
                "0",
            ),
        ),
        (
            StrokeMoveError::TooLong,
            d(Start, "direct stroke: too long", "0"),
        ),
    ] {
        push("STROKE", "motion", e.code(), format!("{e:?}"), doc);
    }
    // The controller's own codes; its pass-through variants (Motion, Stroke, TableDecode,
    // Store) carry the codes listed above.
    let job_offset = housekeeping_fields()
        .iter()
        .find(|(f, _)| f.name == "job")
        .map_or(0, |(f, _)| f.offset);
    for (e, doc) in [
        (
            CommandError::Faulted(FaultFlags::empty()),
            d(
                Start,
                "a fault is latched: clear it first",
                "latched fault flags",
            ),
        ),
        (
            CommandError::Busy(State::Moving),
            d(
                Start,
                "busy: a motion is in progress (stop first; tables change between motions only)",
                "state code",
            ),
        ),
        (
            CommandError::FaultPersists(FaultFlags::empty()),
            d(
                Start,
                "clear refused: the fault condition persists",
                "blocking fault flags",
            ),
        ),
        (
            CommandError::NoPose,
            d(
                Start,
                "the pose of the held strokes is unknown (FK failed)",
                "0",
            ),
        ),
        (
            CommandError::UploadIncomplete(0),
            d(
                Start,
                "commit: table bytes missing from the upload buffer",
                "bytes missing",
            ),
        ),
        (
            CommandError::CrcMismatch(0),
            d(
                Start,
                "commit: CRC-32 does not match the uploaded bytes",
                "CRC computed",
            ),
        ),
        (
            CommandError::NoPending,
            d(Start, "activate: no table pending", "0"),
        ),
        (
            CommandError::Stopped,
            d(
                CompletionOrStartFailure,
                "move ended early by a stop telecommand",
                "0",
            ),
        ),
        (
            CommandError::AbortedByFault(FaultFlags::empty()),
            d(
                CompletionOrStartFailure,
                "move ended early by a fault",
                "latched fault flags",
            ),
        ),
        (
            CommandError::PendingMismatch { pending_id: 0 },
            d(
                Start,
                "activate: the named table is not the pending one",
                "pending table ID",
            ),
        ),
        (
            CommandError::EncoderSuspect(0),
            d(
                Start,
                "direct stroke: the leg's own encoder is suspect",
                "reasons (section 3)",
            ),
        ),
        (
            CommandError::NoGeometry,
            d(
                Start,
                "no usable geometry (defect guard): all motion refused",
                "0",
            ),
        ),
        (
            CommandError::JobBusy(0),
            d(
                Start,
                "a table job is running",
                &format!("job (`job`, offset {job_offset})"),
            ),
        ),
        (
            CommandError::TowardEndOfTravel(0),
            d(
                Start,
                "direct stroke toward an end-of-travel switch that is active or was seen since \
                 the fault latched",
                "legs blocked in the move's direction (bit i = leg i+1)",
            ),
        ),
        (
            CommandError::NotInPosition(0),
            d(
                Compl,
                "the move's sliders were not in position (every encoder at rest within the \
                 in-position tolerance of its setpoint for the dwell, parameters 0x0015 and \
                 0x0016) within the fine positioning's timeout after the path",
                "legs not in position (bit i = leg i+1)",
            ),
        ),
        (
            CommandError::ExposureHold(0),
            d(
                Start,
                "an operator move (absolute, relative, direct stroke) during an exposure hold",
                "the hold's seconds left (rounded up)",
            ),
        ),
    ] {
        push("CONTROLLER", "controller", e.code(), format!("{e:?}"), doc);
    }
    for (e, doc) in [
        (
            ParamError::UnknownId(0),
            d(Start, "unknown parameter ID", "the ID"),
        ),
        (
            ParamError::OutOfRange(0),
            d(Start, "value outside the parameter's range", "the ID"),
        ),
        (
            ParamError::WarningNotBelowFault,
            d(
                Start,
                "following warning threshold not below the fault threshold",
                "0",
            ),
        ),
        (
            ParamError::Repeated(0),
            d(
                Start,
                "a TC[20,1] or TC[20,3] names a parameter ID twice",
                "the ID",
            ),
        ),
        (
            ParamError::DeadBandAboveStep,
            d(
                Start,
                "thermal compensation's dead band (0x0062) above its largest step (0x0061)",
                "0",
            ),
        ),
    ] {
        push("CONTROLLER", "parameters", e.code(), format!("{e:?}"), doc);
    }
    // The schedule's codes (CommandError::Schedule passes them through).
    for (e, doc) in [
        (
            ScheduleError::Full { free: 0 },
            d(
                Start,
                &format!("insert: the activities do not all fit ({SCHEDULE_CAPACITY} places)"),
                "free places",
            ),
        ),
        (
            ScheduleError::ReleaseTimeInPast { index: 0 },
            d(
                Start,
                "insert: a release time is earlier than now",
                "activity index",
            ),
        ),
        (
            ScheduleError::DuplicateRequestId { index: 0 },
            d(
                Start,
                "insert: a request ID is already scheduled or repeated in the TC",
                "activity index",
            ),
        ),
        (
            ScheduleError::NotScheduled { index: 0 },
            d(
                Start,
                "delete: a request ID is not scheduled, or listed twice",
                "index in the TC",
            ),
        ),
        (
            ScheduleError::ShiftOutOfRange {
                request_id: RequestId::default(),
            },
            d(
                Start,
                "time shift: an activity would be earlier than now or beyond the clock's range",
                "the request ID of the first such activity in release order",
            ),
        ),
        (
            ScheduleError::ReleaseTimeBeyondClock { index: 0 },
            d(
                Start,
                &format!(
                    "insert: a release time beyond the clock's range ({}.{:03} s)",
                    thousands(i64::try_from(max_obt_ms / 1000).unwrap_or(i64::MAX)),
                    max_obt_ms % 1000
                ),
                "activity index",
            ),
        ),
    ] {
        push("SCHEDULE", "schedule", e.code(), format!("{e:?}"), doc);
    }
    v
}

/// The values of the `failure_code` enumeration: 0 (none), then every code of
/// [`failure_codes`] with its label and meaning.
pub(super) fn failure_code_values() -> Vec<(i64, String, String)> {
    let mut v = vec![(0, "NONE".to_string(), "no failure".to_string())];
    v.extend(
        failure_codes()
            .into_iter()
            .map(|c| (i64::from(c.code), c.label, c.meaning)),
    );
    v
}
