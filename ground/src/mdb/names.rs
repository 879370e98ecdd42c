//! Names and numbers as the code and docs/icd.md write them: labels from the
//! code's own identifiers, the telecommand of a [`Command`], thousands and hex formats.

use m2ctl::link::schedule::ScheduleCommand;
use m2ctl::link::Command;

/// `MoveAbsolute` / `Truncated { got: 1 }` -> `MOVE_ABSOLUTE` / `TRUNCATED`.
pub fn upper_snake(debug: &str) -> String {
    let ident: String = debug
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric())
        .collect();
    let mut out = String::new();
    for (i, c) in ident.chars().enumerate() {
        if c.is_ascii_uppercase() && i > 0 {
            out.push('_');
        }
        out.push(c.to_ascii_uppercase());
    }
    out
}

/// The description's name of the telecommand that carries `command` (an exhaustive
/// match: a new [`Command`] variant does not compile until it is named here).
pub fn telecommand_name(command: &Command) -> String {
    match command {
        Command::Ping => "PING".into(),
        Command::HousekeepingOneShot => "HOUSEKEEPING_ONE_SHOT".into(),
        Command::LoadTableChunk(_) => "LOAD_TABLE_CHUNK".into(),
        Command::DumpTable(_) => "DUMP_TABLE".into(),
        Command::ReportParameters(_) => "REPORT_PARAMETER".into(),
        Command::SetParameters(_) => "SET_PARAMETER".into(),
        Command::Schedule(s) => match s {
            ScheduleCommand::EnableRelease => "SCHEDULE_ENABLE_RELEASE",
            ScheduleCommand::DisableRelease => "SCHEDULE_DISABLE_RELEASE",
            ScheduleCommand::Reset => "SCHEDULE_RESET",
            ScheduleCommand::Insert(_) => "SCHEDULE_INSERT_ACTIVITY",
            ScheduleCommand::Delete(_) => "SCHEDULE_DELETE_ACTIVITY",
            ScheduleCommand::TimeShiftAll(_) => "SCHEDULE_TIME_SHIFT_ALL",
            ScheduleCommand::SummaryReport => "SCHEDULE_SUMMARY_REPORT",
        }
        .into(),
        Command::SetTimeReportRate(_) => "SET_TIME_REPORT_RATE".into(),
        Command::MoveAbsolute(_)
        | Command::CheckMove(_)
        | Command::MoveRelative(_)
        | Command::Stop
        | Command::ClearFault
        | Command::DirectStroke { .. }
        | Command::CommitTable { .. }
        | Command::ActivateTable { .. }
        | Command::SwitchBank
        | Command::RevertToNominal
        | Command::ExposureHold { .. } => command
            .function_id()
            .map(|f| upper_snake(&format!("{f:?}")))
            .unwrap_or_default(),
    }
}

/// `1,234,567`.
pub fn thousands(v: i64) -> String {
    let digits = v.unsigned_abs().to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    if v < 0 {
        format!("-{out}")
    } else {
        out
    }
}

/// `0x050A`: a code or an ID as docs/icd.md writes it.
pub fn hex4(v: u16) -> String {
    format!("0x{v:04X}")
}

/// `2` or `2/2/3`: one number if all are equal (after rounding to 1e-9).
pub(super) fn uniform(values: &[f64]) -> String {
    let r: Vec<f64> = values.iter().map(|v| (v * 1e9).round() / 1e9).collect();
    if r.windows(2).all(|w| w[0] == w[1]) {
        format!("{}", r.first().copied().unwrap_or(0.0))
    } else {
        r.iter()
            .map(|v| format!("{v}"))
            .collect::<Vec<_>>()
            .join("/")
    }
}

/// The flight validation's workspace caps as the ICD writes them (the largest half-ranges
/// a table may hold): x, y, z in mm and alpha, beta, gamma in arcsec, each [`uniform`].
pub(super) fn workspace_caps() -> (String, String) {
    let ws = m2ctl::table::ValidationConfig::flight().max_workspace;
    let arcsec: Vec<f64> = ws
        .rotation_rad
        .iter()
        .map(|r| r * m2ctl::units::ARCSEC_PER_RAD)
        .collect();
    (uniform(&ws.translation_mm), uniform(&arcsec))
}
