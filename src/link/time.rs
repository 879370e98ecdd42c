//! PUS ST[9] time management on the wire: TC[9,1] "set the time report generation
//! rate" ([`TimeReportRate`]) and the TM[9,2] CUC time report layout.
//!
//! The controller's on-board time (OBT) is the CUC 4+2 time of its TM
//! ([`super::tm::TmTime`]): seconds and 1/65536 s since boot, derived from the control
//! cycle counter. It is never set by telecommand; the ground correlates it to UTC
//! (docs/icd.md, section "Time management"). The time report gives that correlation a
//! sample whose OBT is an exact multiple of the report period.
//!
//! ECSS-E-ST-70-41C defines the rate as an exponent N (a report every 2^N units). This
//! link has no transfer frames to count, so the unit is one second of OBT:
//! a report every 2^N s, N = 0..=[`MAX_TIME_REPORT_EXPONENT`]. The mission-specific
//! value [`TIME_REPORTS_OFF`] stops the reports (the state at boot).

use super::error::LinkError;
use super::tm::TmTime;
use super::wire::{Order, Reader, Writer};
use super::TM_TIMESTAMP_LEN;

/// Largest exponent N of the time report period 2^N s (256 s).
pub const MAX_TIME_REPORT_EXPONENT: u8 = 8;
/// The TC[9,1] rate value that stops the time reports.
pub const TIME_REPORTS_OFF: u8 = 0xFF;
/// Bytes of the TC[9,1] application data: the rate value u8.
pub const SET_TIME_REPORT_RATE_LEN: usize = 1;
/// Bytes of the TM[9,2] source data: rate value u8, OBT (CUC 4+2).
pub const TIME_REPORT_LEN: usize = 1 + TM_TIMESTAMP_LEN;

/// How often the controller sends TM[9,2].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeReportRate {
    /// No time reports (the state at boot).
    #[default]
    Off,
    /// One report every 2^`exponent` s of OBT, at the OBT multiples of that period.
    Every {
        /// N of the period 2^N s, 0..=[`MAX_TIME_REPORT_EXPONENT`].
        exponent: u8,
    },
}

impl TimeReportRate {
    /// Wire value: the exponent, or [`TIME_REPORTS_OFF`].
    pub const fn code(self) -> u8 {
        match self {
            TimeReportRate::Off => TIME_REPORTS_OFF,
            TimeReportRate::Every { exponent } => exponent,
        }
    }

    /// From the wire value; `None` outside 0..=8 and 0xFF.
    pub const fn from_code(code: u8) -> Option<TimeReportRate> {
        if code == TIME_REPORTS_OFF {
            Some(TimeReportRate::Off)
        } else if code <= MAX_TIME_REPORT_EXPONENT {
            Some(TimeReportRate::Every { exponent: code })
        } else {
            None
        }
    }

    /// The report period (s), `None` when off.
    pub const fn period_s(self) -> Option<u32> {
        match self {
            TimeReportRate::Off => None,
            TimeReportRate::Every { exponent } => 1u32.checked_shl(exponent as u32),
        }
    }

    /// Checked parse of the TC[9,1] application data.
    pub fn parse(app_data: &[u8]) -> Result<TimeReportRate, LinkError> {
        super::command::expect_len(app_data, SET_TIME_REPORT_RATE_LEN)?;
        let code = Reader::new(app_data, Order::Big)
            .u8()
            .ok_or(LinkError::InvalidArgument { index: 0 })?;
        TimeReportRate::from_code(code).ok_or(LinkError::InvalidArgument { index: 0 })
    }

    /// Writes the TC[9,1] application data.
    pub fn emit(self, w: &mut Writer<'_>) -> Option<()> {
        w.u8(self.code())
    }
}

/// The TM[9,2] source data: the rate in force and the OBT of the report.
pub fn time_report_bytes(rate: TimeReportRate, obt: TmTime) -> [u8; TIME_REPORT_LEN] {
    let mut out = [0u8; TIME_REPORT_LEN];
    // The buffer has exactly the layout's length: both puts fit.
    let _ = write_time_report(&mut Writer::new(&mut out, Order::Big), rate, obt);
    out
}

/// Writes the TM[9,2] source data: the rate value u8, the OBT (CUC 4+2).
pub fn write_time_report(w: &mut Writer<'_>, rate: TimeReportRate, obt: TmTime) -> Option<()> {
    w.u8(rate.code())?;
    w.put(&obt.to_bytes())
}

/// Checked parse of the TM[9,2] source data (exact length, a known rate value).
pub fn parse_time_report(d: &[u8]) -> Option<(TimeReportRate, TmTime)> {
    if d.len() != TIME_REPORT_LEN {
        return None;
    }
    let mut r = Reader::new(d, Order::Big);
    let rate = TimeReportRate::from_code(r.u8()?)?;
    Some((rate, TmTime::from_bytes(r.take()?)))
}
