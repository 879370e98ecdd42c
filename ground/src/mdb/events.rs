//! Service-5 events: IDs, severities and the meaning of their auxiliary words.

use super::housekeeping::source_codes;
use super::{AuxDecode, AuxPart, Event, Mdb, SeverityUse};
use m2ctl::link::tm::{event_id, EventSeverity};
use m2ctl::link::{service, subtype};
use m2ctl::table::BootSource;

/// The events (IDs from [`event_id`], severities as the controller sends them).
pub fn events() -> Vec<Event> {
    use EventSeverity::{High, Info, Low, Medium};
    let sev = |s: &[(EventSeverity, &'static str)]| {
        s.iter()
            .map(|(s, when)| SeverityUse {
                severity: severity_name(*s),
                subtype: s.subtype(),
                when,
            })
            .collect()
    };
    let ev = |id: u16,
              name: &'static str,
              description: &str,
              severities: Vec<SeverityUse>,
              (aux0, aux1): (&str, &str),
              message: &'static str| Event {
        id,
        name,
        description: description.into(),
        severities,
        aux0: aux0.into(),
        aux1: aux1.into(),
        message,
        aux0_decode: Vec::new(),
        aux1_decode: Vec::new(),
    };
    let sources = format!("source ({})", source_codes("nominal", ""));
    let request_id_word = "request ID of the released TC (packet ID << 16, sequence control)";
    let all = vec![
        ev(
            event_id::STATE_CHANGED,
            "STATE_CHANGED",
            "controller state changed",
            sev(&[(Info, "")]),
            ("old state", "new state"),
            "controller state {aux0} -> {aux1}",
        ),
        ev(
            event_id::FAULT_LATCHED,
            "FAULT_LATCHED",
            "fault latched",
            sev(&[(High, "")]),
            (
                "all latched fault flags",
                "newly latched flags (bits 0..23), legs they name (bits 24..29)",
            ),
            "fault latched: flags {aux0}, new {aux1}",
        ),
        ev(
            event_id::FAULTS_CLEARED,
            "FAULTS_CLEARED",
            "faults cleared",
            sev(&[(Info, "")]),
            ("flags cleared", "0"),
            "faults cleared: flags {aux0}",
        ),
        ev(
            event_id::WARNING_CHANGED,
            "WARNING_CHANGED",
            "warning flags changed",
            sev(&[(Low, "")]),
            ("warning flags", "legs of the warnings"),
            "warning flags now {aux0}",
        ),
        ev(
            event_id::MOVE_REFUSED,
            "MOVE_REFUSED",
            "move refused",
            sev(&[(Low, "")]),
            ("refusal bits", "failure code"),
            "move refused: refusal bits {aux0}, failure code {aux1}",
        ),
        ev(
            event_id::SETPOINT_REFUSED,
            "SETPOINT_REFUSED",
            "a setpoint on a planned path failed IK (defect guard; the motion holds)",
            sev(&[(High, "")]),
            ("refusal bits", "control cycle"),
            "setpoint on a planned path failed IK (motion holds): refusal bits {aux0}, cycle {aux1}",
        ),
        ev(
            event_id::END_OF_TRAVEL,
            "END_OF_TRAVEL",
            "end of travel: the set of active end-of-travel switches changed to a non-empty one",
            sev(&[(High, "")]),
            (
                "legs at the lower switch (bits 0..5), at the upper switch (bits 8..13), with an \
                 unreadable input (bits 16..21)",
                "control cycle",
            ),
            "end of travel: switches {aux0} at cycle {aux1} (legs stopped toward them)",
        ),
        ev(
            event_id::TABLE_ACTIVATED,
            "TABLE_ACTIVATED",
            "table activated (now running)",
            sev(&[(Info, "")]),
            ("table ID", "CRC-32"),
            "table {aux0} activated, CRC-32 {aux1}",
        ),
        ev(
            event_id::TABLE_REJECTED,
            "TABLE_REJECTED",
            "table command refused or failed (commit, activate, switch bank, revert)",
            sev(&[(Medium, "")]),
            (
                "failure code",
                "for a commit: the uploaded table's ID when every byte was loaded since the last \
                 commit and the image decodes (magic, version, length, CRC-32, reserved), else 0 \
                 (so 0 with 0x0705); 0 for the others",
            ),
            "table rejected: failure code {aux0}, table {aux1}",
        ),
        ev(
            event_id::TABLE_COMMITTED,
            "TABLE_COMMITTED",
            "table committed to flash (now pending)",
            sev(&[(Info, "")]),
            (
                "table ID",
                &format!(
                    "bank ({} A, {} B)",
                    BootSource::BankA.code(),
                    BootSource::BankB.code()
                ),
            ),
            "table {aux0} committed to bank {aux1}",
        ),
        ev(
            event_id::TABLE_RELOADED,
            "TABLE_RELOADED",
            "running table reloaded from its source after a RAM upset",
            sev(&[(Medium, "")]),
            ("table ID", &sources),
            "table {aux0} reloaded from {aux1} after a RAM upset",
        ),
        ev(
            event_id::BANK_HEALTH,
            "BANK_HEALTH",
            "flash bank health changed",
            sev(&[(Info, "when healthy"), (Medium, "when corrupt")]),
            ("bit 0 bank A, bit 1 bank B corrupt", "0"),
            "flash bank health {aux0}",
        ),
        ev(
            event_id::BOOT,
            "BOOT",
            "boot finished",
            sev(&[(Info, ""), (Low, "if the boot fell back")]),
            (
                &format!("boot {sources}"),
                "running table ID",
            ),
            "boot finished: source {aux0}, table {aux1}",
        ),
        ev(
            event_id::BOOT_DETAIL,
            "BOOT_DETAIL",
            "boot detail",
            sev(&[(Info, "")]),
            (
                "boot flags (below)",
                "reset cause (bits 0..7), boot count (bits 16..31)",
            ),
            "boot detail: flags {aux0}, reset cause and count {aux1}",
        ),
        ev(
            event_id::DEADLINE_MISSED,
            "DEADLINE_MISSED",
            &format!(
                "control cycles overran {} times in a row: motion stopped",
                m2ctl::controller::OVERRUN_HOLD_LIMIT
            ),
            sev(&[(High, "")]),
            ("consecutive overruns", "overruns since boot"),
            "control cycles overran {aux0} times in a row (total {aux1}): motion stopped",
        ),
        ev(
            event_id::PARAMETERS_CHANGED,
            "PARAMETERS_CHANGED",
            "on-board parameters changed (persisted and applied)",
            sev(&[(Info, "")]),
            (
                "the parameters this TC[20,3] set (bit i = parameter index i)",
                "every parameter set now (the set mask: `parameters_set`, offset 213)",
            ),
            "on-board parameters changed: {aux0} set (all set: {aux1})",
        ),
        ev(
            event_id::PARAMETERS_IGNORED,
            "PARAMETERS_IGNORED",
            "persisted on-board parameters not applied (at boot, or when the repair of an upset \
             re-reads them): out of range, or following-error overrides that would leave the \
             warning not below the running table's fault threshold",
            sev(&[(Low, "")]),
            ("the parameters not applied (bit i = parameter index i)", "0"),
            "persisted parameters {aux0} not applied: the defaults or the table's thresholds run",
        ),
        ev(
            event_id::SENSOR_FAULT,
            "SENSOR_FAULT",
            "a temperature sensor the running table's thermal model uses became faulty (open, \
             shorted or stuck); once per failure",
            sev(&[(Low, "")]),
            (
                "sensors that became faulty (bit i = sensor i)",
                "every sensor's fault now: open (bits 0..7), shorted (bits 8..15), stuck (bits \
                 16..23)",
            ),
            "temperature sensors {aux0} faulty (open, shorted, stuck: {aux1})",
        ),
        ev(
            event_id::THERMAL_FROZEN,
            "THERMAL_FROZEN",
            "the thermal compensation froze at its last offset: it is enabled and a \
             temperature sensor its model uses is faulty (once per freeze)",
            sev(&[(Low, "")]),
            ("faulty sensors the thermal model uses (bit i = sensor i)", "0"),
            "thermal compensation frozen: sensors {aux0} faulty",
        ),
        ev(
            event_id::EXPOSURE_HOLD_STARTED,
            "EXPOSURE_HOLD_STARTED",
            "an exposure hold began: no compensation step, no scheduled activity released \
             and no operator move until it ends",
            sev(&[(Info, "")]),
            (
                "what began it (0 the telecommand, 1 the discrete input)",
                "its timeout (s)",
            ),
            "exposure hold began (source {aux0}, timeout {aux1} s)",
        ),
        ev(
            event_id::EXPOSURE_HOLD_ENDED,
            "EXPOSURE_HOLD_ENDED",
            "the exposure hold ended",
            sev(&[(Info, "")]),
            (
                "why (0 a telecommand with timeout 0, 1 the timeout passed, 2 the discrete \
                 input was released)",
                "0",
            ),
            "exposure hold ended (reason {aux0})",
        ),
        ev(
            event_id::ACTIVITY_RELEASED,
            "ACTIVITY_RELEASED",
            "time-tagged activity released: its telecommand runs now",
            sev(&[(Info, "")]),
            (request_id_word, "release time (OBT, whole seconds)"),
            "scheduled activity {aux0} released (release time {aux1} s)",
        ),
        ev(
            event_id::ACTIVITY_FAILED,
            "ACTIVITY_FAILED",
            &format!(
                "a released activity's telecommand failed (its TM[{v},{}]/[{v},{}]/[{v},{}] has \
                 the details)",
                subtype::ACCEPTANCE_FAILURE,
                subtype::START_FAILURE,
                subtype::COMPLETION_FAILURE,
                v = service::VERIFICATION
            ),
            sev(&[(Medium, "")]),
            (
                "request ID of the released TC",
                "report subtype << 16, failure code",
            ),
            "released activity {aux0} failed: subtype and code {aux1}",
        ),
        ev(
            event_id::ACTIVITY_EXPIRED,
            "ACTIVITY_EXPIRED",
            "activity deleted unrun: its release time passed while release was disabled",
            sev(&[(Low, "")]),
            ("request ID of the TC", "release time (OBT, whole seconds)"),
            "activity {aux0} deleted unrun: release time {aux1} s passed while release was disabled",
        ),
    ];
    all.into_iter()
        .map(|mut e| {
            (e.aux0_decode, e.aux1_decode) = aux_decoding(e.id);
            e
        })
        .collect()
}

/// Bits of an auxiliary word.
const AUX_BITS: u32 = u32::BITS;
/// How the controller packs its event words (defined with the event IDs).
pub use m2ctl::link::tm::event_id::{
    ACTIVITY_SUBTYPE_SHIFT, FAULT_LEGS_SHIFT, SENSOR_SHORT_SHIFT, SENSOR_STUCK_SHIFT,
};

/// How each event's auxiliary words are named (the meanings of [`events`]' aux texts).
fn aux_decoding(id: u16) -> (Vec<AuxPart>, Vec<AuxPart>) {
    let part = |shift: u32, width: u32, decode: AuxDecode| AuxPart {
        shift,
        width,
        decode,
    };
    let whole = |decode: AuxDecode| vec![part(0, AUX_BITS, decode)];
    let e = |enumeration| AuxDecode::Enum { enumeration };
    let b = |bit_field| AuxDecode::Bits { bit_field };
    let flags_and_legs = vec![
        part(0, FAULT_LEGS_SHIFT, b("fault_flags")),
        part(FAULT_LEGS_SHIFT, AUX_BITS - FAULT_LEGS_SHIFT, b("leg_mask")),
    ];
    match id {
        event_id::STATE_CHANGED => (whole(e("controller_state")), whole(e("controller_state"))),
        event_id::FAULT_LATCHED => (whole(b("fault_flags")), flags_and_legs),
        event_id::FAULTS_CLEARED => (whole(b("fault_flags")), Vec::new()),
        event_id::WARNING_CHANGED => (whole(b("fault_flags")), whole(b("leg_mask"))),
        event_id::MOVE_REFUSED => (whole(b("refusal_bits")), whole(e("failure_code"))),
        event_id::SETPOINT_REFUSED => (whole(b("refusal_bits")), Vec::new()),
        event_id::TABLE_REJECTED => (whole(e("failure_code")), Vec::new()),
        event_id::TABLE_COMMITTED => (Vec::new(), whole(e("bank"))),
        event_id::TABLE_RELOADED => (Vec::new(), whole(e("boot_source"))),
        event_id::BOOT => (whole(e("boot_source")), Vec::new()),
        event_id::ACTIVITY_FAILED => (
            Vec::new(),
            vec![part(0, ACTIVITY_SUBTYPE_SHIFT, e("failure_code"))],
        ),
        event_id::SENSOR_FAULT => (
            whole(b("sensor_mask")),
            vec![
                part(0, SENSOR_SHORT_SHIFT, b("sensor_mask")),
                part(
                    SENSOR_SHORT_SHIFT,
                    SENSOR_STUCK_SHIFT - SENSOR_SHORT_SHIFT,
                    b("sensor_mask"),
                ),
                part(SENSOR_STUCK_SHIFT, 8, b("sensor_mask")),
            ],
        ),
        event_id::THERMAL_FROZEN => (whole(b("sensor_mask")), Vec::new()),
        _ => (Vec::new(), Vec::new()),
    }
}

/// The source Yamcs gives every event of the controller (the web UI sorts by it).
pub const EVENT_SOURCE: &str = "M2";

/// Yamcs' severity of a TM[5,x] subtype (as Yamcs' PUS event decoder maps them).
pub fn yamcs_severity(s: EventSeverity) -> &'static str {
    match s {
        EventSeverity::Info => "INFO",
        EventSeverity::Low => "WATCH",
        EventSeverity::Medium => "DISTRESS",
        EventSeverity::High => "CRITICAL",
    }
}

impl Mdb {
    /// An auxiliary word as the operator reads it: each part by name (an enumeration's
    /// label, or the names of the set bits joined by `|`, `none` if none), the word in
    /// hex after named bits; the number when the event names nothing.
    pub fn aux_text(&self, parts: &[AuxPart], word: u32) -> String {
        if parts.is_empty() {
            return word.to_string();
        }
        let mut has_bits = false;
        let named: Vec<String> = parts
            .iter()
            .map(|p| {
                let v = word.checked_shr(p.shift).unwrap_or(0)
                    & u32::MAX.checked_shr(AUX_BITS - p.width).unwrap_or(0);
                match p.decode {
                    AuxDecode::Enum { enumeration } => self
                        .enums
                        .iter()
                        .find(|e| e.name == enumeration)
                        .and_then(|e| e.values.iter().find(|(x, _, _)| *x == i64::from(v)))
                        .map_or_else(|| format!("{v} (unknown)"), |(_, l, _)| l.clone()),
                    AuxDecode::Bits { bit_field } => {
                        has_bits = true;
                        let bits = self
                            .bit_fields
                            .iter()
                            .find(|f| f.name == bit_field)
                            .map(|f| f.bits.as_slice())
                            .unwrap_or(&[]);
                        let names: Vec<String> = (0..p.width)
                            .filter(|i| v & (1 << i) != 0)
                            .map(|i| {
                                bits.iter()
                                    .find(|(b, _, _)| *b == i)
                                    .map_or_else(|| format!("BIT{i}"), |(_, n, _)| n.clone())
                            })
                            .collect();
                        if names.is_empty() {
                            "none".into()
                        } else {
                            names.join("|")
                        }
                    }
                }
            })
            .collect();
        let text = named.join(", ");
        if has_bits {
            format!("{text} (0x{word:x})")
        } else {
            text
        }
    }

    /// The event `id` with its message, the auxiliary words named ([`Event::message`]
    /// with `{aux0}`, `{aux1}` replaced by [`Mdb::aux_text`]); `None` for an unknown ID.
    pub fn event_text(&self, id: u16, aux0: u32, aux1: u32) -> Option<(&Event, String)> {
        let e = self.events.iter().find(|e| e.id == id)?;
        let text = e
            .message
            .replace("{aux0}", &self.aux_text(&e.aux0_decode, aux0))
            .replace("{aux1}", &self.aux_text(&e.aux1_decode, aux1));
        Some((e, text))
    }
}

/// Label of a severity (Yamcs: INFO, WATCH, DISTRESS, CRITICAL for subtypes 1..4).
pub fn severity_name(s: EventSeverity) -> &'static str {
    match s {
        EventSeverity::Info => "INFO",
        EventSeverity::Low => "LOW",
        EventSeverity::Medium => "MEDIUM",
        EventSeverity::High => "HIGH",
    }
}
