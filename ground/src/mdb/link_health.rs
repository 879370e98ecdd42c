//! The link's health as the gateway sees it (`m2ground gateway`): its counters and the
//! time correlation's quality, published to Yamcs as local parameters of the mission
//! database (set through Yamcs' `BatchSetParameterValues`), each described here once
//! with its unit and alarm.

use serde::Serialize;

use super::AlarmRule;

/// One link-health quantity of the gateway.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LinkHealth {
    /// TM packets forwarded to Yamcs (count since the gateway started).
    TmPackets,
    /// TM frames dropped: bad COBS, overflow, a length field that disagrees (count).
    TmBadFrames,
    /// TM packets dropped because the backlog was full while Yamcs was away (count).
    TmBacklogDropped,
    /// TC packets forwarded to the controller (count).
    TcPackets,
    /// TC packets refused: longer than the controller accepts (count).
    TcRefused,
    /// Events Yamcs did not take after all retries (count).
    EventsLost,
    /// Time-correlation coefficient updates Yamcs accepted (count).
    TcoUpdates,
    /// Arrival of the newest TM packet after the UTC the correlation it was stamped with
    /// gives its on-board time (ms): the transport delay plus the correlation's error
    /// (>= 0 but for the gateway's tolerance before it corrects the line).
    TcoResidualMs,
}

/// How a link-health quantity is typed in Yamcs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LinkHealthKind {
    /// An unsigned 64-bit count.
    Counter,
    /// A 64-bit float.
    Float,
}

/// A link-health parameter of the mission database.
#[derive(Clone, Debug, Serialize)]
pub struct LinkHealthParameter {
    /// Which quantity.
    pub quantity: LinkHealth,
    /// Parameter name (in the mission database's space system).
    pub name: &'static str,
    /// Type.
    pub kind: LinkHealthKind,
    /// Engineering unit.
    pub unit: Option<&'static str>,
    /// Decimals shown (floats).
    pub fraction_digits: Option<u8>,
    /// What it counts or measures.
    pub description: &'static str,
    /// When Yamcs raises an alarm (None: never).
    pub alarm: Option<AlarmRule>,
    /// Consecutive values in alarm before it is raised (debounce).
    pub min_violations: u32,
    /// Why its alarm matters to the operator.
    pub why: &'static str,
}

/// Worst delay of a TM packet after the correlation in force before it is an alarm
/// (ms): beyond it Yamcs' generation times are off by more than a housekeeping period.
pub const TCO_RESIDUAL_ALARM_MS: f64 = 1000.0;

impl LinkHealth {
    /// Every quantity, in publication order.
    pub const ALL: [LinkHealth; 8] = [
        LinkHealth::TmPackets,
        LinkHealth::TmBadFrames,
        LinkHealth::TmBacklogDropped,
        LinkHealth::TcPackets,
        LinkHealth::TcRefused,
        LinkHealth::EventsLost,
        LinkHealth::TcoUpdates,
        LinkHealth::TcoResidualMs,
    ];

    /// Its parameter (exhaustive: a new quantity does not compile until described).
    pub fn parameter(self) -> LinkHealthParameter {
        let counter =
            |name, description, alarm: Option<(&'static str, &'static str)>| LinkHealthParameter {
                quantity: self,
                name,
                kind: LinkHealthKind::Counter,
                unit: None,
                fraction_digits: None,
                description,
                alarm: alarm.map(|(level, _)| AlarmRule::Above { limit: 0.0, level }),
                min_violations: 1,
                why: alarm.map_or("", |(_, why)| why),
            };
        match self {
            LinkHealth::TmPackets => counter(
                "link_tm_packets",
                "TM packets the gateway forwarded to Yamcs",
                None,
            ),
            LinkHealth::TmBadFrames => counter(
                "link_tm_bad_frames",
                "TM frames the gateway dropped (bad COBS, overflow, wrong length field)",
                Some(("WARNING", "telemetry was corrupted on the serial link")),
            ),
            LinkHealth::TmBacklogDropped => counter(
                "link_tm_backlog_dropped",
                "TM packets dropped from the gateway's full backlog while Yamcs was away",
                Some((
                    "WARNING",
                    "telemetry was lost while Yamcs was not connected",
                )),
            ),
            LinkHealth::TcPackets => counter(
                "link_tc_packets",
                "TC packets the gateway forwarded to the controller",
                None,
            ),
            LinkHealth::TcRefused => counter(
                "link_tc_refused",
                "TC packets the gateway refused (longer than the controller accepts)",
                Some(("WARNING", "a telecommand never reached the controller")),
            ),
            LinkHealth::EventsLost => counter(
                "link_events_lost",
                "events Yamcs did not take from the gateway after all retries",
                Some(("WARNING", "controller events are missing from Yamcs")),
            ),
            LinkHealth::TcoUpdates => counter(
                "link_tco_updates",
                "time-correlation coefficient updates Yamcs accepted",
                None,
            ),
            LinkHealth::TcoResidualMs => LinkHealthParameter {
                quantity: self,
                name: "link_tco_residual",
                kind: LinkHealthKind::Float,
                unit: Some("ms"),
                fraction_digits: Some(1),
                description: "arrival of the newest TM packet after the UTC the time \
                              correlation it was stamped with gives its on-board time",
                alarm: Some(AlarmRule::Above {
                    limit: TCO_RESIDUAL_ALARM_MS,
                    level: "WATCH",
                }),
                min_violations: 3,
                why: "TM time stamps are off (or telemetry arrives late) by more than 1 s",
            },
        }
    }
}

/// The link-health parameters.
pub fn link_health() -> Vec<LinkHealthParameter> {
    LinkHealth::ALL.iter().map(|q| q.parameter()).collect()
}
