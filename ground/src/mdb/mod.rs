//! The mission database (host): one machine-readable description of the whole
//! telecommand/telemetry vocabulary of `docs/icd.md`, built from the flight code's own
//! constants, and the single source of the Yamcs XTCE (`m2ground mdb-json` ->
//! `yamcs/tools/gen_xtce.py` -> `m2.xml`, see `docs/ground-segment.md`).
//!
//! What it holds:
//! * every telecommand: PUS service/subtype, TC[8,1] function ID, arguments with their
//!   wire type, engineering unit, calibration (engineering value = raw x `scale`, e.g.
//!   0.001 um per nm) and valid range; a `build` function that turns raw argument values
//!   into the flight [`Command`], so the tests can encode every described telecommand
//!   through the description and compare it with the link's encoder;
//! * every telemetry packet with its fields (offset in the source data, wire type, unit,
//!   calibration, enumeration or named bit field), the housekeeping fields each with an
//!   accessor into [`Housekeeping`](m2ctl::link::Housekeeping), so the tests read an
//!   emitted report back by the description;
//! * the enumerations (controller state, boot source, bank, memory ID, failure codes,
//!   event IDs) and the bit fields (fault/warning flags, refusal bits, leg masks);
//! * the events with their severities and the meaning of their auxiliary words;
//! * how service-1 reports verify each telecommand (acceptance, start, completion).
//!
//! Drift between this module and the flight code is a failing test
//! (`ground/tests/mdb.rs`): a telecommand the parser knows but the description lacks, a
//! housekeeping field at another offset, an event, failure code or flag bit the code has
//! and the description does not.
//!
//! The parts (every public item is re-exported here, so `ground::mdb::X` is the path):
//! * `mod.rs`: the description's types ([`Mdb`], [`Telecommand`], [`TmPacket`],
//!   [`Field`], ...), the link constants and [`mdb`], which assembles the whole;
//! * `telecommands`: argument readers, `build` functions, every telecommand;
//! * `housekeeping`: the TM[3,25] rows, offsets from `m2ctl::link::hk::field`;
//! * `telemetry`: every other TM packet layout;
//! * `enumerations`, `bit_fields`, `failure_codes`, `events`: the vocabularies;
//! * `table_image`: the parameter table image's layout;
//! * `link_health`: the gateway's counters and time-correlation quality as parameters;
//! * `console`: the operators' console Yamcs serves (display, parameter lists, command
//!   stacks), every name looked up here;
//! * `fields`, `names`: field constructors, labels and number formats;
//! * `codec`: encoding and decoding by the description (what Yamcs does with the XTCE).

mod alarms;
mod bit_fields;
mod codec;
mod console;
mod enumerations;
mod events;
mod failure_codes;
mod fields;
mod housekeeping;
mod link_health;
mod names;
mod table_image;
mod telecommands;
mod telemetry;

pub use alarms::{alarms, derived};
pub use bit_fields::{bank_status_flags, fault_flag_bits, fault_flags_doc, refusal_bits, FlagDoc};
use bit_fields::{leg_mask_bits, sensor_mask_bits, thermal_state_bits};
pub use console::{
    bit_parameter_name, calibration_stack, clear_fault_stack, console_files, display_par,
    housekeeping_display, parameter_lists, recovery_stroke_um, stacks, switch_recovery_stack,
    table_upload_stack, upload_stack_table, Argument, Cell, Comparison, ConsoleFile, Display,
    DisplayRow, Lit, ParameterKind, ParameterList, Section, Stack, Step, SwitchEnd,
    ARRIVAL_TOLERANCE_ARCSEC, ARRIVAL_TOLERANCE_UM, DISPLAYS_DIR, LISTS_FILE,
    RECOVERY_STOP_DISTANCES, STACKS_DIR, STACK_ADVANCEMENT, UPLOAD_STACK_TABLE_ID,
    VERIFY_TIMEOUT_MS,
};
use enumerations::{
    banks, boot_sources, controller_states, memory_ids, parameter_ids, time_report_rates,
};
pub use enumerations::{
    controller_state_doc, parameter_default, parameter_description, reset_causes,
};
pub use events::{events, severity_name, yamcs_severity, EVENT_SOURCE};
use failure_codes::failure_code_values;
pub use failure_codes::{failure_codes, FailureCode, ReportedIn};
pub use fields::{POSE_AXES, S_PER_CUC_FRACTION};
pub use housekeeping::{housekeeping_fields, housekeeping_rows, HkGetter, HkRow};
pub use link_health::{
    link_health, LinkHealth, LinkHealthKind, LinkHealthParameter, TCO_RESIDUAL_ALARM_MS,
};
pub use names::{hex4, telecommand_name, thousands, upper_snake};
pub use table_image::{table_image, TableImageRow};
use telecommands::telecommands;
pub use telecommands::PERFORM_FUNCTION;
use telemetry::telemetry;

use serde::Serialize;

use m2ctl::link::tm::TIME_FRACTIONS_PER_SECOND;
use m2ctl::link::{
    subtype, AckFlags, Command, CCSDS_PRIMARY_HEADER_LEN, M2_APID, MAX_TC_PACKET_LEN,
    PUS_C_VERSION, PUS_TC_SEC_HEADER_LEN, PUS_TM_SEC_HEADER_LEN_NO_TIME, TM_TIMESTAMP_LEN,
};
use m2ctl::timing::{CYCLE_S_F64, HK_PERIOD_CYCLES};

/// Engineering unit of translations and strokes.
pub const UNIT_UM: &str = "um";
/// Engineering unit of rotations.
pub const UNIT_ARCSEC: &str = "arcsec";
/// Offset of the TM source data in a TM packet (bytes): primary header + secondary
/// header with its CUC 4+2 timestamp.
pub const TM_SOURCE_DATA_OFFSET: usize =
    CCSDS_PRIMARY_HEADER_LEN + PUS_TM_SEC_HEADER_LEN_NO_TIME + TM_TIMESTAMP_LEN;
/// Offset of the TC application data in a TC packet (bytes).
pub const TC_APP_DATA_OFFSET: usize = CCSDS_PRIMARY_HEADER_LEN + PUS_TC_SEC_HEADER_LEN;
/// Bytes of the CUC coarse time (seconds since controller boot).
pub const CUC_COARSE_BYTES: usize = 4;
/// Bytes of the CUC fine time (1/65536 s).
pub const CUC_FINE_BYTES: usize = TM_TIMESTAMP_LEN - CUC_COARSE_BYTES;
/// Completion window of telecommands that finish within the cycle that accepts them (s).
pub const QUICK_COMPLETION_S: f64 = 10.0;
/// Completion window of moves (s): long enough for any move inside the workspace.
pub const MOVE_COMPLETION_S: f64 = 600.0;
/// Acceptance and start windows (s).
pub const ACK_WINDOW_S: f64 = 10.0;

/// How a field is encoded on the wire (big-endian).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum Wire {
    /// Unsigned 8 bits.
    U8,
    /// Unsigned 16 bits.
    U16,
    /// Unsigned 32 bits.
    U32,
    /// Two's complement 32 bits.
    I32,
    /// A u16 byte count followed by that many bytes.
    Bytes {
        /// Fewest bytes.
        min_len: usize,
        /// Most bytes.
        max_len: usize,
    },
    /// An embedded CCSDS packet (a telecommand of a TC[11,4] activity): the bytes alone,
    /// no prefix; the packet's own length field delimits it.
    Packet {
        /// Fewest bytes.
        min_len: usize,
        /// Most bytes.
        max_len: usize,
    },
}

impl Wire {
    /// Encoded size (bytes) of a fixed-size type; `None` for [`Wire::Bytes`].
    pub const fn fixed_len(self) -> Option<usize> {
        match self {
            Wire::U8 => Some(1),
            Wire::U16 => Some(2),
            Wire::U32 | Wire::I32 => Some(4),
            Wire::Bytes { .. } | Wire::Packet { .. } => None,
        }
    }

    /// Bytes of the length prefix of [`Wire::Bytes`].
    pub const LENGTH_PREFIX_LEN: usize = 2;

    /// Raw range of an integer type.
    pub fn raw_range(self) -> Option<(i64, i64)> {
        match self {
            Wire::U8 => Some((0, i64::from(u8::MAX))),
            Wire::U16 => Some((0, i64::from(u16::MAX))),
            Wire::U32 => Some((0, i64::from(u32::MAX))),
            Wire::I32 => Some((i64::from(i32::MIN), i64::from(i32::MAX))),
            Wire::Bytes { .. } | Wire::Packet { .. } => None,
        }
    }
}

/// What a field's value means.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Meaning {
    /// A number; engineering value = raw x `scale`, in `unit`.
    Number {
        /// Engineering unit (`None`: a count or an identifier).
        unit: Option<&'static str>,
        /// Engineering value per raw unit (1 when uncalibrated).
        scale: f64,
        /// Valid engineering range, inclusive (telecommand arguments).
        range: Option<(f64, f64)>,
    },
    /// One value of a named enumeration ([`Mdb::enums`]).
    Enum {
        /// Enumeration name.
        enumeration: &'static str,
    },
    /// A word of named flag bits ([`Mdb::bit_fields`]).
    Bits {
        /// Bit field name.
        bit_field: &'static str,
    },
    /// 0 = false, 1 = true.
    Boolean,
    /// A constant the encoder writes (not an operator argument).
    Fixed {
        /// The value.
        value: i64,
    },
    /// Opaque bytes (table chunks).
    Binary,
}

/// One field of a telecommand's application data or of a TM packet's source data.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Field {
    /// Name (lower snake case; unique within its packet).
    pub name: String,
    /// Offset from the start of the application/source data (bytes).
    pub offset: usize,
    /// Wire encoding.
    pub wire: Wire,
    /// Meaning.
    pub meaning: Meaning,
    /// What it is (frame and unit included).
    pub description: String,
    /// Decimals its engineering value is shown with ([`Meaning::fraction_digits`]):
    /// Yamcs' number format, so that 4,991 nm shows as `4.991 um`, not
    /// `4.9910000000000005 um`.
    pub fraction_digits: Option<u32>,
}

impl Meaning {
    /// The fewest decimals that show one raw count of a calibrated number
    /// (`ceil(-log10(scale))`: 3 for 0.001 um per nm, 6 for 1e-6 arcsec per
    /// micro-arcsecond, 5 for 1/65536 s); `None` for anything shown as an integer.
    pub fn fraction_digits(&self) -> Option<u32> {
        /// Below this, `-log10(scale)` is taken as the integer it is meant to be.
        const LOG_ROUNDING: f64 = 1e-9;
        match *self {
            Meaning::Number { scale, .. } if scale != 1.0 && scale > 0.0 => {
                Some((-scale.log10() - LOG_ROUNDING).ceil().max(0.0) as u32)
            }
            _ => None,
        }
    }
}

/// A raw argument value of a telecommand.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ArgValue {
    /// An integer in the wire's raw units.
    Int(i64),
    /// Bytes of a [`Wire::Bytes`] argument.
    Bytes(Vec<u8>),
}

/// Builds the flight command from raw argument values (operator arguments only, in
/// description order); `Err` if a value is out of range.
pub type BuildFn = fn(&[ArgValue]) -> Result<Command, String>;

/// One telecommand.
#[derive(Clone, Debug, Serialize)]
pub struct Telecommand {
    /// Name (upper snake case).
    pub name: String,
    /// PUS service.
    pub service: u8,
    /// PUS subtype.
    pub subtype: u8,
    /// TC[8,1] function ID (the first two bytes of the application data).
    pub function_id: Option<u16>,
    /// Application-data fields after the function ID (offsets count from the start of
    /// the application data, function ID included).
    pub fields: Vec<Field>,
    /// What it does.
    pub description: String,
    /// Its short name in docs/icd.md (section 3: the telecommand list, or the TC[8,1]
    /// function table).
    pub title: String,
    /// Its application data as the flight link takes it (docs/icd.md section 3; after
    /// the function ID for a TC[8,1] function). The description's `fields` may restrict
    /// it (one parameter per TC[20,x], one activity per TC[11,4]).
    pub app_data_layout: String,
    /// Seconds within which the completion report must come.
    pub completion_timeout_s: f64,
    /// Why it is critical (Yamcs significance CRITICAL: the operator confirms it);
    /// `None`: a normal telecommand.
    pub critical: Option<&'static str>,
    /// The controller state in which it is sent (a Yamcs transmission constraint: Yamcs
    /// holds it until housekeeping shows that state, at most the constraint's timeout);
    /// `None`: sent at once.
    pub constraint: Option<Constraint>,
    /// Raw arguments -> flight command.
    #[serde(skip)]
    pub build: BuildFn,
}

/// When a telecommand may be sent: the states in which the controller does not refuse it
/// for its state (a Yamcs transmission constraint on housekeeping's `state` and `job`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Constraint {
    /// Labels of the `controller_state` enumeration it is sent in.
    pub states: Vec<String>,
    /// Sent only while no table job runs (`job` = 0).
    pub no_job: bool,
    /// How long Yamcs waits for the constraint before it fails the command (s).
    pub timeout_s: f64,
    /// The controller's refusal it spares the operator.
    pub why: &'static str,
}

/// One TM packet type.
#[derive(Clone, Debug, Serialize)]
pub struct TmPacket {
    /// Name (lower snake case).
    pub name: String,
    /// PUS service.
    pub service: u8,
    /// PUS subtypes this layout covers.
    pub subtypes: Vec<u8>,
    /// Source-data fields.
    pub fields: Vec<Field>,
    /// Source-data length when fixed (bytes).
    pub fixed_len: Option<usize>,
    /// What it is.
    pub description: String,
    /// A repeated group after the fields (e.g. the activities of TM[11,13]).
    pub repeated: Option<Repeated>,
    /// Its rows in docs/icd.md's telemetry list (section 4): which subtypes, what they
    /// mean, their source data (together they cover `subtypes` once each).
    pub kinds: Vec<TmKind>,
}

/// One row of docs/icd.md's telemetry list: one or more subtypes of a TM packet layout.
#[derive(Clone, Debug, Serialize)]
pub struct TmKind {
    /// PUS subtypes of the row.
    pub subtypes: Vec<u8>,
    /// What they are.
    pub title: String,
    /// Their source data, as docs/icd.md shows it.
    pub data_layout: String,
}

fn tm_kind(subtypes: &[u8], title: &str, data_layout: &str) -> TmKind {
    TmKind {
        subtypes: subtypes.to_vec(),
        title: title.into(),
        data_layout: data_layout.into(),
    }
}

/// A group of fields repeated `count_field` times at the end of a TM packet.
#[derive(Clone, Debug, Serialize)]
pub struct Repeated {
    /// Name of the group (one array parameter in Yamcs).
    pub name: String,
    /// The field holding the number of repetitions.
    pub count_field: String,
    /// Offset of the first repetition in the source data (bytes).
    pub offset: usize,
    /// Bytes of one repetition.
    pub element_len: usize,
    /// Most repetitions.
    pub max_count: usize,
    /// The fields of one repetition (offsets from its start).
    pub fields: Vec<Field>,
}

/// A named enumeration.
#[derive(Clone, Debug, Serialize)]
pub struct Enumeration {
    /// Name.
    pub name: &'static str,
    /// `(value, label, meaning)`.
    pub values: Vec<(i64, String, String)>,
}

/// A word of named flag bits.
#[derive(Clone, Debug, Serialize)]
pub struct BitField {
    /// Name.
    pub name: &'static str,
    /// `(bit, name, meaning)`, bit 0 = least significant.
    pub bits: Vec<(u32, String, String)>,
}

/// One service-5 event.
#[derive(Clone, Debug, Serialize)]
pub struct Event {
    /// Event ID.
    pub id: u16,
    /// Label (upper snake case, the `event_id` constant's name).
    pub name: &'static str,
    /// What it reports.
    pub description: String,
    /// Severities the controller sends it with (TM[5,x] subtype), each with when.
    pub severities: Vec<SeverityUse>,
    /// Meaning of aux0.
    pub aux0: String,
    /// Meaning of aux1.
    pub aux1: String,
    /// One-line text for the operator (`{aux0}`, `{aux1}` are replaced).
    pub message: &'static str,
    /// How aux0 is shown by name ([`Mdb::event_text`]); empty: as a number.
    pub aux0_decode: Vec<AuxPart>,
    /// How aux1 is shown by name; empty: as a number.
    pub aux1_decode: Vec<AuxPart>,
}

/// Bits `shift..shift + width` of an event's auxiliary word, shown by name.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct AuxPart {
    /// Lowest bit of the part.
    pub shift: u32,
    /// Bits of the part.
    pub width: u32,
    /// How its value is named.
    pub decode: AuxDecode,
}

/// How a part of an auxiliary word is named.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum AuxDecode {
    /// The label of one value of an enumeration ([`Mdb::enums`]).
    Enum {
        /// Enumeration name.
        enumeration: &'static str,
    },
    /// The names of the set bits of a bit field ([`Mdb::bit_fields`]).
    Bits {
        /// Bit field name.
        bit_field: &'static str,
    },
}

/// One severity an event is sent with.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct SeverityUse {
    /// [`severity_name`].
    pub severity: &'static str,
    /// TM[5,x] subtype.
    pub subtype: u8,
    /// When (empty: whenever the event is not sent with another severity).
    pub when: &'static str,
}

/// One verification stage: TM[1,`success`] or TM[1,`success`+1].
#[derive(Clone, Debug, Serialize)]
pub struct VerificationStage {
    /// Yamcs stage name.
    pub name: &'static str,
    /// Subtype of the success report (failure = +1).
    pub success_subtype: u8,
}

/// Link-level constants the ground needs.
#[derive(Clone, Debug, Serialize)]
pub struct LinkInfo {
    /// APID of every TC and TM.
    pub apid: u16,
    /// PUS version.
    pub pus_version: u8,
    /// Default acknowledgement flags of a TC.
    pub default_ack_flags: u8,
    /// Largest TC packet (bytes).
    pub max_tc_packet_len: usize,
    /// Offset of the TM source data (bytes).
    pub tm_source_data_offset: usize,
    /// Offset of the TC application data (bytes).
    pub tc_app_data_offset: usize,
    /// Offset of the CUC timestamp in a TM packet (bytes).
    pub tm_time_offset: usize,
    /// CUC coarse bytes.
    pub cuc_coarse_bytes: usize,
    /// CUC fine bytes.
    pub cuc_fine_bytes: usize,
    /// CUC fractions per second.
    pub cuc_fractions_per_second: u64,
    /// Control cycle (s).
    pub control_cycle_s: f64,
    /// Periodic housekeeping (s).
    pub housekeeping_period_s: f64,
}

/// The whole mission database.
#[derive(Clone, Debug, Serialize)]
pub struct Mdb {
    /// Space system name.
    pub name: &'static str,
    /// Link constants.
    pub link: LinkInfo,
    /// Enumerations.
    pub enums: Vec<Enumeration>,
    /// Bit fields.
    pub bit_fields: Vec<BitField>,
    /// Telecommands.
    pub telecommands: Vec<Telecommand>,
    /// TM packets.
    pub telemetry: Vec<TmPacket>,
    /// Events.
    pub events: Vec<Event>,
    /// Service-1 stages, in order.
    pub verification: Vec<VerificationStage>,
    /// Failure codes with where they are reported and what their data holds (the
    /// `failure_code` enumeration's values).
    pub failure_codes: Vec<FailureCode>,
    /// The parameter table image's layout (what TC[6,2] loads, TM[6,6] dumps).
    pub table_image: Vec<TableImageRow>,
    /// Alarms of housekeeping parameters.
    pub alarms: Vec<ParameterAlarm>,
    /// The gateway's link-health parameters (Yamcs local parameters, with their alarms).
    pub link_health: Vec<LinkHealthParameter>,
    /// Parameters Yamcs derives from housekeeping (algorithms), with their alarms.
    pub derived: Vec<DerivedParameter>,
}

/// A parameter Yamcs computes from the fields of one housekeeping report (a Yamcs
/// algorithm triggered by the report), in their engineering unit.
#[derive(Clone, Debug, Serialize)]
pub struct DerivedParameter {
    /// Name (lower snake case, unique among parameters).
    pub name: &'static str,
    /// Engineering unit (the pairs' unit).
    pub unit: &'static str,
    /// What it is.
    pub description: String,
    /// Decimals it is shown with.
    pub fraction_digits: u32,
    /// How it is computed.
    pub computation: Computation,
    /// In alarm at each `(level, limit)` when above the limit (engineering units).
    pub above: Vec<(&'static str, f64)>,
    /// Consecutive values in alarm before it is raised (debounce).
    pub min_violations: u32,
    /// Why it matters to the operator.
    pub why: &'static str,
}

/// When Yamcs raises an alarm on a parameter.
#[derive(Clone, Debug, Serialize)]
pub struct ParameterAlarm {
    /// The parameter (a TM field's name).
    pub parameter: &'static str,
    /// The rule.
    pub rule: AlarmRule,
    /// Consecutive values in alarm before it is raised (debounce).
    pub min_violations: u32,
    /// Why it matters to the operator.
    pub why: &'static str,
}

/// An alarm rule (levels are Yamcs': WATCH, WARNING, DISTRESS, CRITICAL, SEVERE).
#[derive(Clone, Debug, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum AlarmRule {
    /// An enumerated parameter: the level of each label in alarm.
    States {
        /// `(label, level)`.
        levels: Vec<(String, &'static str)>,
    },
    /// A number: in alarm at `level` when above `limit` (engineering units).
    Above {
        /// Highest value not in alarm.
        limit: f64,
        /// Level.
        level: &'static str,
    },
}

/// How a [`DerivedParameter`] is computed from housekeeping fields.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Computation {
    /// `max_i |a_i - b_i|` over these `(a, b)` field pairs.
    LargestDifference {
        /// The pairs.
        pairs: Vec<(String, String)>,
    },
    /// `max_i |f_i - from|` over the fields whose value is not `absent` (0 when none has
    /// a value).
    LargestDeviation {
        /// The fields.
        fields: Vec<String>,
        /// The value deviations are taken from (engineering units).
        from: f64,
        /// The engineering value a field has when it holds no value.
        absent: f64,
    },
}

/// The mission database.
pub fn mdb() -> Mdb {
    let event_ids = events()
        .iter()
        .map(|e| (i64::from(e.id), e.name.to_string(), e.message.to_string()))
        .collect();
    Mdb {
        name: "M2",
        link: LinkInfo {
            apid: M2_APID,
            pus_version: PUS_C_VERSION,
            default_ack_flags: AckFlags::ALL.0,
            max_tc_packet_len: MAX_TC_PACKET_LEN,
            tm_source_data_offset: TM_SOURCE_DATA_OFFSET,
            tc_app_data_offset: TC_APP_DATA_OFFSET,
            tm_time_offset: CCSDS_PRIMARY_HEADER_LEN + PUS_TM_SEC_HEADER_LEN_NO_TIME,
            cuc_coarse_bytes: CUC_COARSE_BYTES,
            cuc_fine_bytes: CUC_FINE_BYTES,
            cuc_fractions_per_second: TIME_FRACTIONS_PER_SECOND,
            control_cycle_s: CYCLE_S_F64,
            housekeeping_period_s: f64::from(HK_PERIOD_CYCLES) * CYCLE_S_F64,
        },
        enums: vec![
            Enumeration {
                name: "controller_state",
                values: controller_states(),
            },
            Enumeration {
                name: "boot_source",
                values: boot_sources(),
            },
            Enumeration {
                name: "bank",
                values: banks(),
            },
            Enumeration {
                name: "memory_id",
                values: memory_ids(),
            },
            Enumeration {
                name: "failure_code",
                values: failure_code_values(),
            },
            Enumeration {
                name: "event_id",
                values: event_ids,
            },
            Enumeration {
                name: "parameter_id",
                values: parameter_ids(),
            },
            Enumeration {
                name: "time_report_rate",
                values: time_report_rates(),
            },
        ],
        bit_fields: vec![
            BitField {
                name: "fault_flags",
                bits: fault_flag_bits(),
            },
            BitField {
                name: "refusal_bits",
                bits: refusal_bits(),
            },
            BitField {
                name: "leg_mask",
                bits: leg_mask_bits(),
            },
            BitField {
                name: "sensor_mask",
                bits: sensor_mask_bits(),
            },
            BitField {
                name: "thermal_state",
                bits: thermal_state_bits(),
            },
        ],
        telecommands: telecommands(),
        telemetry: telemetry(),
        events: events(),
        verification: vec![
            VerificationStage {
                name: "Acceptance",
                success_subtype: subtype::ACCEPTANCE_SUCCESS,
            },
            VerificationStage {
                name: "Start",
                success_subtype: subtype::START_SUCCESS,
            },
            VerificationStage {
                name: "Completion",
                success_subtype: subtype::COMPLETION_SUCCESS,
            },
        ],
        failure_codes: failure_codes(),
        table_image: table_image(),
        alarms: alarms(),
        link_health: link_health(),
        derived: derived(),
    }
}
