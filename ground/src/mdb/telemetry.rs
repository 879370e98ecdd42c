//! Telemetry packets: every TM layout with its fields and docs/icd.md rows.

use super::events::severity_name;
use super::fields::{count, field, obt_fields};
use super::housekeeping::housekeeping_fields;
use super::{tm_kind, Meaning, Repeated, TmPacket, Wire, CUC_COARSE_BYTES, CUC_FINE_BYTES};
use m2ctl::link::command::{FunctionId, TABLE_CHUNK_MAX_LEN};
use m2ctl::link::hk::HK_REPORT_LEN;
use m2ctl::link::schedule::{
    ACTIVITY_COUNT_LEN, RELEASE_TIME_LEN, SCHEDULE_CAPACITY, SUMMARY_ENTRY_LEN,
};
use m2ctl::link::tc::REQUEST_ID_LEN;
use m2ctl::link::time::TIME_REPORT_LEN;
use m2ctl::link::tm::EventSeverity;
use m2ctl::link::tm::MOVE_CHECK_REPORT_LEN;
use m2ctl::link::{service, subtype, TM_TIMESTAMP_LEN};

pub(super) fn telemetry() -> Vec<TmPacket> {
    let rid = |off| {
        vec![
            count(
                "tc_packet_id",
                off,
                Wire::U16,
                "request ID: packet ID of the TC (version, type, sec. header, APID)",
            ),
            count(
                "tc_sequence_control",
                off + 2,
                Wire::U16,
                "request ID: sequence flags and count of the TC",
            ),
        ]
    };
    let mut failure = rid(0);
    failure.extend([
        field(
            "failure_code",
            4,
            Wire::U16,
            Meaning::Enum {
                enumeration: "failure_code",
            },
            "failure code",
        ),
        count(
            "failure_data",
            6,
            Wire::U32,
            "failure datum (per code: refusal bits, flags, a/b = a << 16 | b)",
        ),
    ]);
    vec![
        TmPacket {
            name: "verification_success".into(),
            service: service::VERIFICATION,
            subtypes: vec![
                subtype::ACCEPTANCE_SUCCESS,
                subtype::START_SUCCESS,
                subtype::COMPLETION_SUCCESS,
            ],
            fields: rid(0),
            fixed_len: Some(4),
            description: "TM[1,1] acceptance, [1,3] start, [1,7] completion success".into(),
            repeated: None,
            kinds: vec![
                tm_kind(&[subtype::ACCEPTANCE_SUCCESS], "acceptance success", "request ID (4)"),
                tm_kind(&[subtype::START_SUCCESS], "start success", "request ID"),
                tm_kind(&[subtype::COMPLETION_SUCCESS], "completion success", "request ID"),
            ],
        },
        TmPacket {
            name: "verification_failure".into(),
            service: service::VERIFICATION,
            subtypes: vec![
                subtype::ACCEPTANCE_FAILURE,
                subtype::START_FAILURE,
                subtype::COMPLETION_FAILURE,
            ],
            fields: failure,
            fixed_len: Some(10),
            description: "TM[1,2] acceptance, [1,4] start, [1,8] completion failure".into(),
            repeated: None,
            kinds: vec![
                tm_kind(
                    &[subtype::ACCEPTANCE_FAILURE],
                    "acceptance failure",
                    "request ID (4); failure code u16; failure data u32",
                ),
                tm_kind(
                    &[subtype::START_FAILURE],
                    "start failure",
                    "request ID; code u16; data u32",
                ),
                tm_kind(
                    &[subtype::COMPLETION_FAILURE],
                    "completion failure",
                    "request ID; code u16; data u32",
                ),
            ],
        },
        TmPacket {
            name: "housekeeping".into(),
            service: service::HOUSEKEEPING,
            subtypes: vec![subtype::HK_REPORT],
            fields: housekeeping_fields().into_iter().map(|(f, _)| f).collect(),
            fixed_len: Some(HK_REPORT_LEN),
            description: "TM[3,25] housekeeping report".into(),
            repeated: None,
            kinds: vec![tm_kind(
                &[subtype::HK_REPORT],
                "housekeeping report",
                &format!("{HK_REPORT_LEN} bytes, section 6"),
            )],
        },
        TmPacket {
            name: "event".into(),
            service: service::EVENT,
            subtypes: vec![
                subtype::EVENT_INFO,
                subtype::EVENT_LOW,
                subtype::EVENT_MEDIUM,
                subtype::EVENT_HIGH,
            ],
            fields: vec![
                field(
                    "event_id",
                    0,
                    Wire::U16,
                    Meaning::Enum {
                        enumeration: "event_id",
                    },
                    "event ID",
                ),
                count("event_aux0", 2, Wire::U32, "auxiliary word 0 (per event)"),
                count("event_aux1", 6, Wire::U32, "auxiliary word 1 (per event)"),
            ],
            fixed_len: Some(m2ctl::link::tm::EVENT_REPORT_LEN),
            description: "TM[5,1] info, [5,2] low, [5,3] medium, [5,4] high severity event".into(),
            repeated: None,
            kinds: {
                let all = [
                    EventSeverity::Info,
                    EventSeverity::Low,
                    EventSeverity::Medium,
                    EventSeverity::High,
                ];
                let names: Vec<String> = all
                    .iter()
                    .map(|s| {
                        format!("{} {}", s.subtype(), severity_name(*s).to_ascii_lowercase())
                    })
                    .collect();
                vec![tm_kind(
                    &all.map(EventSeverity::subtype),
                    &format!("event: {} severity", names.join(", ")),
                    "event ID u16; aux0 u32; aux1 u32",
                )]
            },
        },
        TmPacket {
            name: "table_dump".into(),
            service: service::MEMORY,
            subtypes: vec![subtype::MEMORY_DUMP_REPORT],
            fields: vec![
                field(
                    "dump_memory_id",
                    0,
                    Wire::U8,
                    Meaning::Enum {
                        enumeration: "memory_id",
                    },
                    "memory area",
                ),
                count("dump_offset", 1, Wire::U16, "offset of the chunk (bytes)"),
                field(
                    "dump_data",
                    3,
                    Wire::Bytes {
                        min_len: 1,
                        max_len: TABLE_CHUNK_MAX_LEN,
                    },
                    Meaning::Binary,
                    "chunk bytes (u16 length, then the bytes)",
                ),
            ],
            fixed_len: None,
            description: "TM[6,6] table dump chunk".into(),
            repeated: None,
            kinds: vec![tm_kind(
                &[subtype::MEMORY_DUMP_REPORT],
                "table dump chunk",
                &format!(
                    "memory ID u8; offset u16; length u16 (1..{TABLE_CHUNK_MAX_LEN}); `length` bytes"
                ),
            )],
        },
        TmPacket {
            name: "move_check".into(),
            service: service::FUNCTION,
            subtypes: vec![subtype::MOVE_CHECK_REPORT],
            fields: {
                let mut f = rid(0);
                for r in &mut f {
                    r.name = format!("check_{}", r.name);
                }
                f.extend([
                    field(
                        "check_code",
                        4,
                        Wire::U16,
                        Meaning::Enum {
                            enumeration: "failure_code",
                        },
                        "the code MOVE_ABSOLUTE would be refused with now (0: it would be accepted)",
                    ),
                    field(
                        "check_target_refusals",
                        6,
                        Wire::U32,
                        Meaning::Bits {
                            bit_field: "refusal_bits",
                        },
                        "refusal bits of the target pose",
                    ),
                    field(
                        "check_path_refusals",
                        10,
                        Wire::U32,
                        Meaning::Bits {
                            bit_field: "refusal_bits",
                        },
                        "refusal bits of the first refused path point (0: none)",
                    ),
                    count(
                        "check_path_sample",
                        14,
                        Wire::U8,
                        "index of that path point (0: none)",
                    ),
                ]);
                f
            },
            fixed_len: Some(MOVE_CHECK_REPORT_LEN),
            description: "TM[8,130] move check report (answer to CHECK_MOVE)".into(),
            repeated: None,
            kinds: vec![tm_kind(
                &[subtype::MOVE_CHECK_REPORT],
                &format!(
                    "move check report (answer to function 0x{:04X})",
                    FunctionId::CheckMove.code()
                ),
                "request ID (4); code u16; target refusal bits u32; path refusal bits u32; \
                 path point u8",
            )],
        },
        TmPacket {
            name: "parameter_report".into(),
            service: service::PARAMETER,
            subtypes: vec![subtype::PARAMETER_REPORT],
            fields: vec![count(
                "report_count",
                0,
                Wire::U8,
                "number of (ID, value) pairs",
            )],
            fixed_len: None,
            description: "TM[20,2] parameter report: count, then (ID u16, value i32) pairs".into(),
            kinds: vec![tm_kind(
                &[subtype::PARAMETER_REPORT],
                &format!(
                    "parameter report (answer to TC[{},{}])",
                    service::PARAMETER,
                    subtype::PARAMETER_REPORT_REQUEST
                ),
                "count u8; that many (parameter ID u16, value i32), in parameter-index order",
            )],
            repeated: Some(Repeated {
                name: "report_parameters".into(),
                count_field: "report_count".into(),
                offset: 1,
                element_len: m2ctl::link::tm::PARAMETER_ENTRY_LEN,
                max_count: m2ctl::link::command::MAX_PARAMETERS_PER_TC,
                fields: vec![
                    count(
                        "report_parameter_id",
                        0,
                        Wire::U16,
                        "parameter ID (the parameter_id enumeration's values)",
                    ),
                    count(
                        "report_value",
                        2,
                        Wire::I32,
                        "the parameter's effective value (its wire unit)",
                    ),
                ],
            }),
        },
        TmPacket {
            name: "cuc_time_report".into(),
            service: service::TIME,
            subtypes: vec![subtype::TIME_REPORT],
            fields: {
                let mut f = vec![field(
                    "cuc_report_rate",
                    0,
                    Wire::U8,
                    Meaning::Enum {
                        enumeration: "time_report_rate",
                    },
                    "time report rate in force",
                )];
                f.extend(obt_fields(
                    "cuc_report_obt_",
                    1,
                    "on-board time of the report",
                ));
                f
            },
            fixed_len: Some(TIME_REPORT_LEN),
            description: "TM[9,2] CUC time report (on-board time since boot)".into(),
            repeated: None,
            kinds: vec![tm_kind(
                &[subtype::TIME_REPORT],
                "time report",
                &format!(
                    "rate u8 (as TC[{},{}]); OBT CUC {CUC_COARSE_BYTES}+{CUC_FINE_BYTES} \
                     ({TM_TIMESTAMP_LEN} bytes) (section 10)",
                    service::TIME,
                    subtype::SET_TIME_REPORT_RATE
                ),
            )],
        },
        TmPacket {
            name: "schedule_summary".into(),
            service: service::SCHEDULING,
            subtypes: vec![subtype::SCHEDULE_SUMMARY_REPORT],
            fields: vec![count(
                "summary_count",
                0,
                Wire::U8,
                "activities in the schedule (N)",
            )],
            fixed_len: None,
            description: "TM[11,13] time-based schedule summary: release time and request ID \
                          of every activity, in release order"
                .into(),
            kinds: vec![tm_kind(
                &[subtype::SCHEDULE_SUMMARY_REPORT],
                "schedule summary",
                &format!(
                    "N u8; N × (release time CUC {CUC_COARSE_BYTES}+{CUC_FINE_BYTES}, request ID \
                     {REQUEST_ID_LEN} bytes), in release order"
                ),
            )],
            repeated: Some(Repeated {
                name: "summary_activities".into(),
                count_field: "summary_count".into(),
                offset: ACTIVITY_COUNT_LEN,
                element_len: SUMMARY_ENTRY_LEN,
                max_count: SCHEDULE_CAPACITY,
                fields: {
                    let mut f = obt_fields("activity_release_", 0, "release time");
                    f.extend([
                        count(
                            "activity_tc_packet_id",
                            RELEASE_TIME_LEN,
                            Wire::U16,
                            "request ID: packet ID of the embedded TC",
                        ),
                        count(
                            "activity_tc_sequence_control",
                            RELEASE_TIME_LEN + 2,
                            Wire::U16,
                            "request ID: sequence flags and count of the embedded TC",
                        ),
                    ]);
                    f
                },
            }),
        },
        // docs/icd.md's order: the ping reply last.
        TmPacket {
            name: "ping_reply".into(),
            service: service::TEST,
            subtypes: vec![subtype::PING_REPLY],
            fields: Vec::new(),
            fixed_len: Some(0),
            description: "TM[17,2] are-you-alive reply".into(),
            repeated: None,
            kinds: vec![tm_kind(&[subtype::PING_REPLY], "are-you-alive reply", "none")],
        },
    ]
}
