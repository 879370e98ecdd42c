//! The ground-segment gateway (host): joins Yamcs' TCP link (`TcpTcTmDataLink`, raw
//! CCSDS packets back to back) and the controller's byte stream of COBS frames (the
//! QEMU UART socket, or a serial device on a bench), with the link's own framing
//! ([`m2ctl::link::framing`]); and correlates the controller's on-board time with UTC
//! for Yamcs' time correlation service. `m2ground gateway`, docs/ground-segment.md.
//!
//! * Controller -> Yamcs ([`TmPath`]): bytes are deframed (`0x00, COBS(packet), 0x00`);
//!   a frame that does not decode, overflows or whose CCSDS length field disagrees with
//!   its size is dropped and counted, and the stream resynchronises at the next `0x00`.
//!   Whole packets go to Yamcs unchanged (Yamcs checks the CRC); while Yamcs is not
//!   connected they are kept (up to [`DEFAULT_BACKLOG_PACKETS`]) and sent on connection,
//!   so the boot telemetry is not lost.
//! * Yamcs -> controller ([`TcPath`]): the TCP stream is cut into packets by their
//!   CCSDS length field; each is framed and written to the controller. A packet longer
//!   than the controller accepts ([`MAX_TC_PACKET_LEN`]) is skipped and counted.
//! * Time ([`Correlator`]): the controller's TM time is CUC 4+2 seconds since boot. For
//!   every TM packet the gateway knows its on-board time and when it arrived (UTC, host
//!   clock); it fits `utc = boot + rate * obt` to the lower envelope of the last
//!   [`CORRELATION_WINDOW`] samples (delays only add).
//!   Whenever Yamcs' coefficients would be off by more than [`CORRELATION_TOLERANCE_S`]
//!   (first packet, clock drift, a controller reboot) the gateway sets them by HTTP
//!   (`POST /api/tco/{instance}/{service}/coefficients`: UTC of raw OBT 0 and UTC seconds
//!   per raw count), and Yamcs stamps every packet with `UTC = boot + rate * OBT`.
//! * Events ([`event_json`]): every TM[5,x] packet forwarded to Yamcs is also posted as a
//!   Yamcs event (`POST /api/archive/{instance}/events`) with the source
//!   [`EVENT_SOURCE`], the event's label as type, its severity, the on-board time through
//!   the correlation in force and its text with the auxiliary words named by the mission
//!   database ([`Mdb::event_text`]). Yamcs 5.12's own PUS event decoder sets no source,
//!   and the web UI's event table cannot sort events without one.

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use m2ctl::link::framing::{encode_frame, max_cobs_len, max_frame_len, Deframer};
use m2ctl::link::tm::TIME_FRACTIONS_PER_SECOND;
use m2ctl::link::tm::{parse_tm, TmReport};
use m2ctl::link::{
    CCSDS_PRIMARY_HEADER_LEN, MAX_TC_PACKET_LEN, MAX_TM_PACKET_LEN, PUS_TM_SEC_HEADER_LEN_NO_TIME,
    TM_TIMESTAMP_LEN,
};
use m2ctl::units::{MS_PER_S, US_PER_S};

use crate::mdb::{mdb, yamcs_severity, LinkHealth, LinkHealthKind, Mdb, EVENT_SOURCE};

/// Deframer buffer for telemetry: the COBS encoding of the largest TM packet.
pub const TM_DEFRAMER_LEN: usize = max_cobs_len(MAX_TM_PACKET_LEN);
/// TM packets kept while Yamcs is not connected (oldest dropped first).
pub const DEFAULT_BACKLOG_PACKETS: usize = 4096;
/// Samples (at least [`SAMPLE_SPACING_S`] apart) the correlation is fitted over.
pub const CORRELATION_WINDOW: usize = 32;
/// Error of Yamcs' coefficients at the newest packet that triggers new ones (s).
pub const CORRELATION_TOLERANCE_S: f64 = 0.005;
/// An on-board time this far below the previous one is a controller reboot (s).
pub const REBOOT_STEP_S: f64 = 1.0;
/// Offset of the CUC timestamp in a TM packet (bytes).
pub const TM_TIME_OFFSET: usize = CCSDS_PRIMARY_HEADER_LEN + PUS_TM_SEC_HEADER_LEN_NO_TIME;
/// Offset of the PUS service in a TM secondary header (bytes; the subtype follows).
const PUS_TM_SERVICE_OFFSET: usize = 1;
/// The CCSDS data length field holds the packet length minus this.
const CCSDS_LENGTH_OFFSET: usize = CCSDS_PRIMARY_HEADER_LEN + 1;
/// Offset of the CCSDS data length field (bytes).
const CCSDS_LENGTH_FIELD: usize = 4;
/// Seconds of Yamcs' gradient per raw CUC 4+2 count.
pub const GRADIENT_S_PER_COUNT: f64 = 1.0 / TIME_FRACTIONS_PER_SECOND as f64;
/// Attempts to set the correlation when Yamcs connects, [`CONNECT_RETRY`] apart.
const TCO_CONNECT_TRIES: usize = 20;
/// Longest wait for Yamcs' answer to a coefficient update.
const HTTP_TIMEOUT: Duration = Duration::from_millis(500);
/// Read chunk (bytes).
const READ_CHUNK: usize = 4096;
/// How long the UART/Yamcs connections are retried at start (s).
const CONNECT_RETRY: Duration = Duration::from_millis(100);
/// Retry period of a failed coefficient update.
const TCO_RETRY: Duration = Duration::from_secs(1);

/// Counters of the gateway (all directions).
#[derive(Debug, Default)]
pub struct Stats {
    /// TM packets forwarded to Yamcs.
    pub tm_packets: AtomicU64,
    /// TM frames dropped (bad COBS, overflow, length field disagrees).
    pub tm_bad_frames: AtomicU64,
    /// TM packets dropped because the backlog was full.
    pub tm_backlog_dropped: AtomicU64,
    /// TC packets forwarded to the controller.
    pub tc_packets: AtomicU64,
    /// TC packets refused (longer than the controller accepts).
    pub tc_refused: AtomicU64,
    /// Coefficient updates accepted by Yamcs.
    pub tco_updates: AtomicU64,
    /// Events posted to Yamcs.
    pub events_posted: AtomicU64,
    /// Events Yamcs did not take (after [`EVENT_POST_TRIES`] attempts).
    pub events_lost: AtomicU64,
    /// Bits (`f64::to_bits`) of the newest TM packet's arrival after the UTC the
    /// correlation in force gives its on-board time (ms); 0 until the first.
    pub tco_residual_ms_bits: AtomicU64,
}

impl Stats {
    fn add(c: &AtomicU64, n: u64) {
        c.fetch_add(n, Ordering::Relaxed);
    }

    /// The value of a link-health quantity (counters as they are, exactly below 2^53).
    pub fn health(&self, q: LinkHealth) -> f64 {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed) as f64;
        match q {
            LinkHealth::TmPackets => g(&self.tm_packets),
            LinkHealth::TmBadFrames => g(&self.tm_bad_frames),
            LinkHealth::TmBacklogDropped => g(&self.tm_backlog_dropped),
            LinkHealth::TcPackets => g(&self.tc_packets),
            LinkHealth::TcRefused => g(&self.tc_refused),
            LinkHealth::EventsLost => g(&self.events_lost),
            LinkHealth::TcoUpdates => g(&self.tco_updates),
            LinkHealth::TcoResidualMs => {
                f64::from_bits(self.tco_residual_ms_bits.load(Ordering::Relaxed))
            }
        }
    }

    /// One line for the log.
    pub fn line(&self) -> String {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        format!(
            "TM {} packets ({} bad frames, {} dropped from the backlog), TC {} packets ({} refused), {} time correlations, {} events posted ({} lost)",
            g(&self.tm_packets),
            g(&self.tm_bad_frames),
            g(&self.tm_backlog_dropped),
            g(&self.tc_packets),
            g(&self.tc_refused),
            g(&self.tco_updates),
            g(&self.events_posted),
            g(&self.events_lost)
        )
    }
}

/// The packet length a CCSDS primary header declares (bytes), if 6 bytes are there.
pub fn ccsds_packet_len(header: &[u8]) -> Option<usize> {
    let b = header.get(CCSDS_LENGTH_FIELD..CCSDS_LENGTH_FIELD + 2)?;
    Some(usize::from(u16::from_be_bytes([b[0], b[1]])) + CCSDS_LENGTH_OFFSET)
}

/// Controller -> Yamcs: COBS frames in, whole CCSDS packets out.
#[derive(Debug, Default)]
pub struct TmPath {
    deframer: Deframer<TM_DEFRAMER_LEN>,
    /// Frames dropped so far.
    pub bad_frames: u64,
}

impl TmPath {
    /// An empty path.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes bytes from the controller (any split); appends every complete, consistent
    /// packet to `out`.
    pub fn push(&mut self, bytes: &[u8], out: &mut Vec<Vec<u8>>) {
        for &b in bytes {
            match self.deframer.push_byte(b) {
                None => {}
                Some(Ok(p)) if ccsds_packet_len(p) == Some(p.len()) => out.push(p.to_vec()),
                Some(_) => self.bad_frames += 1,
            }
        }
    }
}

/// Yamcs -> controller: a stream of CCSDS packets in, COBS frames out.
#[derive(Debug, Default)]
pub struct TcPath {
    buf: Vec<u8>,
    /// Bytes of an oversized packet still to skip.
    skip: usize,
    /// Packets refused so far (too long for the controller).
    pub refused: u64,
}

impl TcPath {
    /// An empty path.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes bytes from Yamcs (any split); appends the frame of every complete packet to
    /// `out`. A packet longer than [`MAX_TC_PACKET_LEN`] is skipped whole.
    pub fn push(&mut self, mut bytes: &[u8], out: &mut Vec<Vec<u8>>) {
        if self.skip > 0 {
            let n = self.skip.min(bytes.len());
            self.skip -= n;
            bytes = &bytes[n..];
        }
        self.buf.extend_from_slice(bytes);
        loop {
            let Some(len) = ccsds_packet_len(&self.buf) else {
                return;
            };
            if len > MAX_TC_PACKET_LEN {
                self.refused += 1;
                let n = len.min(self.buf.len());
                self.skip = len - n;
                self.buf.drain(..n);
                continue;
            }
            if self.buf.len() < len {
                return;
            }
            let packet: Vec<u8> = self.buf.drain(..len).collect();
            let mut frame = vec![0u8; max_frame_len(packet.len())];
            if let Ok(n) = encode_frame(&packet, &mut frame) {
                frame.truncate(n);
                out.push(frame);
            }
        }
    }
}

/// The on-board time of a TM packet (s since boot), from its CUC 4+2 timestamp.
pub fn tm_obt_s(packet: &[u8]) -> Option<f64> {
    let t = packet.get(TM_TIME_OFFSET..TM_TIME_OFFSET + TM_TIMESTAMP_LEN)?;
    let seconds = u32::from_be_bytes([t[0], t[1], t[2], t[3]]);
    let fraction = u16::from_be_bytes([t[4], t[5]]);
    Some(f64::from(seconds) + f64::from(fraction) * GRADIENT_S_PER_COUNT)
}

/// On-board time -> UTC: `utc = boot + rate * obt`, fitted to packet arrivals.
///
/// The rate (UTC seconds per on-board second) is the slope between the least-delayed
/// packets of the first and last thirds of the window (1 until the window spans
/// [`MIN_RATE_SPAN_S`]): the controller's clock need not run at the host's rate (in QEMU
/// it runs slower when the emulation cannot keep up with the 1 kHz cycle). The line is
/// then moved down onto the least-delayed packet, since delays only ever add.
#[derive(Debug, Default)]
pub struct Correlator {
    /// `(obt_s, arrival_unix_s)` of the kept packets, at least [`SAMPLE_SPACING_S`] apart.
    window: VecDeque<(f64, f64)>,
    /// The line last given to Yamcs.
    published: Option<TimeFit>,
    last_obt_s: Option<f64>,
}

/// A correlation line: `utc = boot_unix_s + rate * obt_s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeFit {
    /// UTC of on-board time 0 (UNIX seconds).
    pub boot_unix_s: f64,
    /// UTC seconds per on-board second.
    pub rate: f64,
}

impl TimeFit {
    /// UTC (UNIX seconds) of an on-board time.
    pub fn utc(&self, obt_s: f64) -> f64 {
        self.boot_unix_s + self.rate * obt_s
    }
}

/// Smallest on-board span over which the clock rate is fitted (s).
pub const MIN_RATE_SPAN_S: f64 = 2.0;
/// Smallest on-board time between two kept samples (s).
pub const SAMPLE_SPACING_S: f64 = 0.5;

impl Correlator {
    /// No sample yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// One packet with on-board time `obt_s` arrived at `arrival_unix_s`; returns the new
    /// line when Yamcs' coefficients must change (they would be off by more than
    /// [`CORRELATION_TOLERANCE_S`] at this packet).
    pub fn sample(&mut self, obt_s: f64, arrival_unix_s: f64) -> Option<TimeFit> {
        if self
            .last_obt_s
            .is_some_and(|last| obt_s + REBOOT_STEP_S < last)
        {
            self.window.clear(); // a reboot: the old arrivals belong to the old epoch
            self.published = None;
        }
        self.last_obt_s = Some(obt_s);
        match self.window.back_mut() {
            Some(last) if obt_s - last.0 < SAMPLE_SPACING_S => {
                // Keep the less delayed of two close packets.
                if arrival_unix_s - obt_s < last.1 - last.0 {
                    *last = (obt_s, arrival_unix_s);
                }
            }
            _ => {
                if self.window.len() == CORRELATION_WINDOW {
                    self.window.pop_front();
                }
                self.window.push_back((obt_s, arrival_unix_s));
            }
        }
        let fit = self.fit();
        let off = self
            .published
            .is_none_or(|p| (p.utc(obt_s) - fit.utc(obt_s)).abs() > CORRELATION_TOLERANCE_S);
        if off {
            self.published = Some(fit);
            Some(fit)
        } else {
            None
        }
    }

    fn fit(&self) -> TimeFit {
        let w = &self.window;
        let n = w.len() as f64;
        let (first, last) = (
            w.front().map_or(0.0, |s| s.0),
            w.back().map_or(0.0, |s| s.0),
        );
        let mut rate = 1.0;
        if last - first >= MIN_RATE_SPAN_S {
            // Least squares first, then the slope between the least-delayed packets of the
            // first and the last third of the window (delays only add, so the lower
            // envelope is the clock; the thirds keep the two points far apart).
            let mx = w.iter().map(|s| s.0).sum::<f64>() / n;
            let my = w.iter().map(|s| s.1).sum::<f64>() / n;
            let sxy: f64 = w.iter().map(|s| (s.0 - mx) * (s.1 - my)).sum();
            let sxx: f64 = w.iter().map(|s| (s.0 - mx) * (s.0 - mx)).sum();
            let ls = sxy / sxx;
            let third = (last - first) / 3.0;
            let lowest = |half: &mut dyn Iterator<Item = &(f64, f64)>| {
                half.min_by(|a, b| (a.1 - ls * a.0).total_cmp(&(b.1 - ls * b.0)))
                    .copied()
            };
            rate = match (
                lowest(&mut w.iter().filter(|s| s.0 <= first + third)),
                lowest(&mut w.iter().filter(|s| s.0 >= last - third)),
            ) {
                (Some(a), Some(b)) if b.0 > a.0 => (b.1 - a.1) / (b.0 - a.0),
                _ => ls,
            };
        }
        let boot_unix_s = w
            .iter()
            .map(|s| s.1 - rate * s.0)
            .fold(f64::INFINITY, f64::min);
        TimeFit { boot_unix_s, rate }
    }

    /// The line Yamcs has.
    pub fn published(&self) -> Option<TimeFit> {
        self.published
    }
}

/// `2026-12-01T10:20:22.123456Z` for UNIX seconds (proleptic Gregorian, UTC).
pub fn rfc3339(unix_s: f64) -> String {
    const S_PER_DAY: i64 = 86_400;
    let total_us = (unix_s * f64::from(US_PER_S)).round() as i64;
    let secs = total_us.div_euclid(i64::from(US_PER_S));
    let us = total_us.rem_euclid(i64::from(US_PER_S));
    let days = secs.div_euclid(S_PER_DAY);
    let tod = secs.rem_euclid(S_PER_DAY);
    // Civil from days (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{us:06}Z",
        tod / 3600,
        tod / 60 % 60,
        tod % 60
    )
}

/// The JSON body of Yamcs' `SetCoefficients` for a correlation line: UTC of raw OBT 0
/// and the UTC seconds per raw CUC count.
pub fn coefficients_json(fit: &TimeFit) -> String {
    format!(
        "{{\"utc\":\"{}\",\"obt\":\"0\",\"gradient\":{:e},\"offset\":0.0}}",
        rfc3339(fit.boot_unix_s),
        fit.rate * GRADIENT_S_PER_COUNT
    )
}

/// The body of Yamcs' `BatchSetParameterValues` setting every link-health parameter of
/// the mission database (`/{space system}/{name}`, local parameters) to `stats`' values:
/// counters as `UINT64`, floats as `DOUBLE`.
pub fn link_health_json(mdb: &Mdb, stats: &Stats) -> String {
    let values: Vec<String> = mdb
        .link_health
        .iter()
        .map(|p| {
            let v = stats.health(p.quantity);
            let value = match p.kind {
                LinkHealthKind::Counter => {
                    format!("{{\"type\":\"UINT64\",\"uint64Value\":\"{}\"}}", v as u64)
                }
                LinkHealthKind::Float => {
                    format!("{{\"type\":\"DOUBLE\",\"doubleValue\":{v:?}}}")
                }
            };
            format!(
                "{{\"id\":{{\"name\":\"/{}/{}\"}},\"value\":{value}}}",
                json_str(mdb.name),
                json_str(p.name)
            )
        })
        .collect();
    format!("{{\"request\":[{}]}}", values.join(","))
}

/// Attempts to post one event, [`TCO_RETRY`] apart.
pub const EVENT_POST_TRIES: usize = 5;

/// Escapes `s` as the contents of a JSON string.
fn json_str(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if u32::from(c) < 0x20 => out.push_str(&format!("\\u{:04x}", u32::from(c))),
            c => out.push(c),
        }
    }
    out
}

/// The body of Yamcs' `CreateEvent` for a TM[5,x] packet (`None` for any other packet,
/// or one that does not parse): type = the event's label, severity as Yamcs' PUS event
/// decoder maps the subtype, source [`EVENT_SOURCE`], the message with the auxiliary
/// words named ([`Mdb::event_text`]), the time = `fit` applied to the packet's on-board
/// time (Yamcs' mission time without a correlation), the sequence number = the TM
/// packet's sequence count (Yamcs keeps one event per time, source and sequence number,
/// so a post repeated after a lost answer archives the event once: the e2e once saw
/// BOOT twice at the same time under load), and in `extra` the event ID, the raw
/// auxiliary words and the on-board time (raw CUC 4+2).
pub fn event_json(mdb: &Mdb, packet: &[u8], fit: Option<TimeFit>) -> Option<String> {
    let tm = parse_tm(packet).ok()?;
    let TmReport::Event {
        severity,
        event_id,
        aux: [aux0, aux1],
    } = tm.report
    else {
        return None;
    };
    let (label, text) = match mdb.event_text(event_id, aux0, aux1) {
        Some((e, text)) => (e.name.to_string(), text),
        None => (
            format!("EVENT_{event_id}"),
            format!("unknown event {event_id}: aux {aux0}, {aux1}"),
        ),
    };
    let obt_s = tm_obt_s(packet)?;
    let obt_raw = packet
        .get(TM_TIME_OFFSET..TM_TIME_OFFSET + TM_TIMESTAMP_LEN)?
        .iter()
        .fold(0u64, |acc, b| (acc << 8) | u64::from(*b));
    let time = fit
        .map(|f| format!(",\"time\":\"{}\"", rfc3339(f.utc(obt_s))))
        .unwrap_or_default();
    Some(format!(
        "{{\"type\":\"{}\",\"message\":\"{}\",\"severity\":\"{}\",\"source\":\"{}\"{time},\
         \"sequenceNumber\":{},\"extra\":{{\"event_id\":\"{event_id}\",\"aux0\":\"{aux0}\",\"aux1\":\"{aux1}\",\"obt\":\"{obt_raw}\"}}}}",
        json_str(&label),
        json_str(&text),
        yamcs_severity(severity),
        json_str(EVENT_SOURCE),
        tm.seq_count,
    ))
}

/// Longest status line read from an HTTP answer (bytes).
const HTTP_STATUS_LINE_MAX: usize = 4096;

/// Standard base64 (RFC 4648 section 4, with padding) of `bytes`.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(char::from(ALPHABET[(n >> (18 - 6 * i) & 0x3F) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// `url` without a `user:password@` (for logs and errors).
pub fn without_user(url: &str) -> String {
    let (scheme, rest) = url.split_once("://").unwrap_or(("", url));
    let (authority, path) = rest.split_once('/').unwrap_or((rest, ""));
    let host = authority.rsplit_once('@').map_or(authority, |(_, h)| h);
    format!("{scheme}://{host}/{path}")
}

/// POSTs `body` (JSON) to `url` (`http://[user:password@]host:port/path`, plain HTTP on
/// the local machine; a user in the URL is sent as HTTP Basic authentication, which
/// Yamcs accepts with its security enabled); `Ok` on a 2xx answer (read from the
/// status line only).
pub fn http_post_json(url: &str, body: &str) -> Result<(), String> {
    let rest = url
        .strip_prefix("http://")
        .ok_or_else(|| format!("{url}: only http:// URLs"))?;
    let (authority, path) = rest.split_once('/').unwrap_or((rest, ""));
    let (credentials, host) = match authority.rsplit_once('@') {
        Some((user, host)) => (Some(user), host),
        None => (None, authority),
    };
    let auth = credentials
        .map(|c| format!("Authorization: Basic {}\r\n", base64(c.as_bytes())))
        .unwrap_or_default();
    // Errors name the URL without its password.
    let url = without_user(url);
    let addr = std::net::ToSocketAddrs::to_socket_addrs(host)
        .map_err(|e| format!("{host}: {e}"))?
        .next()
        .ok_or_else(|| format!("{host}: no address"))?;
    let mut s =
        TcpStream::connect_timeout(&addr, HTTP_TIMEOUT).map_err(|e| format!("{host}: {e}"))?;
    s.set_read_timeout(Some(HTTP_TIMEOUT))
        .map_err(|e| e.to_string())?;
    let req = format!(
        "POST /{path} HTTP/1.1\r\nHost: {host}\r\n{auth}Content-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    s.write_all(req.as_bytes()).map_err(|e| e.to_string())?;
    // Only the status line: waiting for the server to close (`read_to_end`) held the
    // caller, the TM path among them, for the whole read timeout (500 ms) whenever Yamcs
    // kept the connection open; the e2e test saw TM reach Yamcs later and later (1.1 to
    // 6.7 s after generation over four reports, 15 coefficient updates) in one CI run.
    let mut answer = Vec::new();
    let mut chunk = [0u8; 256];
    while !answer.windows(2).any(|w| w == b"\r\n") && answer.len() < HTTP_STATUS_LINE_MAX {
        match s.read(&mut chunk) {
            Ok(0) | Err(_) => break,
            Ok(n) => answer.extend_from_slice(chunk.get(..n).unwrap_or(&[])),
        }
    }
    let text = String::from_utf8_lossy(&answer);
    let status = text.split_whitespace().nth(1).unwrap_or("");
    if status.starts_with('2') {
        Ok(())
    } else {
        Err(format!(
            "{url}: {}",
            text.lines().next().unwrap_or("no answer")
        ))
    }
}

/// Where the controller's byte stream is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Uart {
    /// A Unix socket (QEMU `-chardev socket,path=...,server=on`).
    Unix(PathBuf),
    /// A TCP socket (QEMU `-chardev socket,host=...,port=...,server=on`).
    Tcp(String),
    /// A serial device, already configured (`stty -F DEV 115200 raw -echo`).
    Device(PathBuf),
}

impl Uart {
    /// `unix:PATH`, `tcp:HOST:PORT` or a device path.
    pub fn parse(s: &str) -> Uart {
        if let Some(p) = s.strip_prefix("unix:") {
            Uart::Unix(p.into())
        } else if let Some(a) = s.strip_prefix("tcp:") {
            Uart::Tcp(a.into())
        } else {
            Uart::Device(s.into())
        }
    }

    /// Opens it (retrying for `wait`): a reader and a writer.
    #[allow(clippy::type_complexity)]
    pub fn open(
        &self,
        wait: Duration,
    ) -> Result<(Box<dyn Read + Send>, Box<dyn Write + Send>), String> {
        let t0 = std::time::Instant::now();
        loop {
            let r: std::io::Result<(Box<dyn Read + Send>, Box<dyn Write + Send>)> = match self {
                Uart::Unix(p) => std::os::unix::net::UnixStream::connect(p)
                    .and_then(|s| Ok((Box::new(s.try_clone()?) as _, Box::new(s) as _))),
                Uart::Tcp(a) => TcpStream::connect(a.as_str())
                    .and_then(|s| Ok((Box::new(s.try_clone()?) as _, Box::new(s) as _))),
                Uart::Device(p) => std::fs::OpenOptions::new()
                    .read(true)
                    .write(true)
                    .open(p)
                    .and_then(|f| Ok((Box::new(f.try_clone()?) as _, Box::new(f) as _))),
            };
            match r {
                Ok(rw) => return Ok(rw),
                Err(e) if t0.elapsed() >= wait => return Err(format!("{self:?}: {e}")),
                Err(_) => std::thread::sleep(CONNECT_RETRY),
            }
        }
    }
}

/// What the gateway needs besides its sockets.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Yamcs' SetCoefficients URL; no time correlation without it.
    pub tco_url: Option<String>,
    /// Yamcs' CreateEvent URL (`.../api/archive/{instance}/events`); no events without it.
    pub events_url: Option<String>,
    /// TM packets kept while Yamcs is away.
    pub backlog: usize,
    /// Print the counters this often.
    pub stats_every: Option<Duration>,
    /// Yamcs' BatchSetParameterValues URL
    /// (`.../api/processors/{instance}/{processor}/parameters:batchSet`); no link-health
    /// parameters without it.
    pub parameters_url: Option<String>,
    /// Publish the link-health parameters this often.
    pub health_every: Duration,
}

fn now_unix_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

/// Runs the gateway until the controller's stream ends or `stop` is set: TM from
/// `uart_rx` to the Yamcs client accepted on `listener`, TC back to `uart_tx`.
pub fn run(
    listener: TcpListener,
    uart_rx: Box<dyn Read + Send>,
    uart_tx: Box<dyn Write + Send>,
    options: &Options,
    stats: Arc<Stats>,
    stop: Arc<AtomicBool>,
) -> Result<(), String> {
    let client: Arc<Mutex<Option<TcpStream>>> = Arc::new(Mutex::new(None));
    // The correlation line Yamcs should have (set by the TM path, given to each new
    // Yamcs connection before the backlog).
    let latest_fit: Arc<Mutex<Option<TimeFit>>> = Arc::new(Mutex::new(None));
    let backlog: Arc<Mutex<VecDeque<Vec<u8>>>> = Arc::new(Mutex::new(VecDeque::new()));
    let uart_tx = Arc::new(Mutex::new(uart_tx));
    let capacity = options.backlog.max(1);

    // Events: posted on their own thread, in the order their packets went to Yamcs, each
    // with the correlation line in force when its packet went (the one Yamcs stamped it
    // with).
    let events_tx = options.events_url.clone().map(|url| {
        let (tx, rx) = mpsc::channel::<(Vec<u8>, Option<TimeFit>)>();
        let (stats, stop) = (stats.clone(), stop.clone());
        std::thread::spawn(move || {
            let mdb = mdb();
            while let Ok((packet, fit)) = rx.recv() {
                let Some(body) = event_json(&mdb, &packet, fit) else {
                    continue;
                };
                let mut posted = false;
                for _ in 0..EVENT_POST_TRIES {
                    if stop.load(Ordering::Relaxed) {
                        break;
                    }
                    match http_post_json(&url, &body) {
                        Ok(()) => {
                            posted = true;
                            break;
                        }
                        Err(e) => {
                            eprintln!("gateway: event not posted: {e}");
                            std::thread::sleep(TCO_RETRY);
                        }
                    }
                }
                Stats::add(
                    if posted {
                        &stats.events_posted
                    } else {
                        &stats.events_lost
                    },
                    1,
                );
            }
        });
        tx
    });
    let is_event = |p: &[u8]| {
        p.get(CCSDS_PRIMARY_HEADER_LEN + PUS_TM_SERVICE_OFFSET)
            == Some(&m2ctl::link::service::EVENT)
    };

    // Yamcs connections: one at a time, the newest wins; its TC go to the controller.
    listener.set_nonblocking(true).map_err(|e| e.to_string())?;
    {
        let (client, backlog, uart_tx, stats, stop) = (
            client.clone(),
            backlog.clone(),
            uart_tx.clone(),
            stats.clone(),
            stop.clone(),
        );
        let (latest_fit, tco_url) = (latest_fit.clone(), options.tco_url.clone());
        let events_tx = events_tx.clone();
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                let Ok((mut s, _)) = listener.accept() else {
                    std::thread::sleep(CONNECT_RETRY);
                    continue;
                };
                let _ = s.set_nonblocking(false);
                let _ = s.set_nodelay(true);
                // Send what arrived while nobody listened, then go live. The correlation
                // first, so that the kept packets get their on-board times (Yamcs' HTTP
                // server is up before its link connects; retried briefly).
                if let (Some(url), Some(fit)) = (&tco_url, latest_fit.lock().ok().and_then(|f| *f))
                {
                    for _ in 0..TCO_CONNECT_TRIES {
                        if http_post_json(url, &coefficients_json(&fit)).is_ok() {
                            Stats::add(&stats.tco_updates, 1);
                            break;
                        }
                        std::thread::sleep(CONNECT_RETRY);
                    }
                }
                if let (Ok(mut c), Ok(mut b)) = (client.lock(), backlog.lock()) {
                    let ok = b.iter().all(|p| s.write_all(p).is_ok());
                    if let (true, Some(tx)) = (ok, &events_tx) {
                        let fit = latest_fit.lock().ok().and_then(|f| *f);
                        for p in b.iter().filter(|p| is_event(p)) {
                            let _ = tx.send((p.clone(), fit));
                        }
                    }
                    Stats::add(&stats.tm_packets, b.len() as u64);
                    b.clear();
                    if ok {
                        *c = s.try_clone().ok();
                    }
                }
                let (uart_tx, stats, stop) = (uart_tx.clone(), stats.clone(), stop.clone());
                std::thread::spawn(move || {
                    let mut tc = TcPath::new();
                    let mut buf = [0u8; READ_CHUNK];
                    let mut frames = Vec::new();
                    while !stop.load(Ordering::Relaxed) {
                        let n = match s.read(&mut buf) {
                            Ok(0) | Err(_) => break,
                            Ok(n) => n,
                        };
                        let before = tc.refused;
                        tc.push(&buf[..n], &mut frames);
                        Stats::add(&stats.tc_refused, tc.refused - before);
                        for f in frames.drain(..) {
                            if let Ok(mut w) = uart_tx.lock() {
                                if w.write_all(&f).and_then(|_| w.flush()).is_ok() {
                                    Stats::add(&stats.tc_packets, 1);
                                }
                            }
                        }
                    }
                });
            }
        });
    }

    // Time correlation: coefficient updates go out on their own thread (Yamcs may not
    // be up yet: retry until accepted, newest estimate first).
    let tco_tx = options.tco_url.clone().map(|url| {
        let (tx, rx) = mpsc::channel::<TimeFit>();
        let (stats, stop) = (stats.clone(), stop.clone());
        std::thread::spawn(move || {
            let mut pending: Option<TimeFit> = None;
            while !stop.load(Ordering::Relaxed) {
                match rx.recv_timeout(TCO_RETRY) {
                    Ok(b) => pending = Some(b),
                    Err(mpsc::RecvTimeoutError::Timeout) => {}
                    Err(mpsc::RecvTimeoutError::Disconnected) => break,
                }
                while let Ok(b) = rx.try_recv() {
                    pending = Some(b);
                }
                if let Some(b) = pending {
                    match http_post_json(&url, &coefficients_json(&b)) {
                        Ok(()) => {
                            Stats::add(&stats.tco_updates, 1);
                            eprintln!(
                                "gateway: time correlation set: OBT 0 = {} UTC, {:.6} UTC s per OBT s",
                                rfc3339(b.boot_unix_s),
                                b.rate
                            );
                            pending = None;
                        }
                        Err(_) => std::thread::sleep(TCO_RETRY),
                    }
                }
            }
        });
        tx
    });

    // Link health: the counters as Yamcs parameters (a post Yamcs refuses is logged; the
    // next one carries the newer values).
    if let Some(url) = options.parameters_url.clone() {
        let (stats, stop) = (stats.clone(), stop.clone());
        let every = options.health_every.max(CONNECT_RETRY);
        std::thread::spawn(move || {
            let mdb = mdb();
            let mut failing = false;
            while !stop.load(Ordering::Relaxed) {
                match http_post_json(&url, &link_health_json(&mdb, &stats)) {
                    Ok(()) => failing = false,
                    Err(e) if !failing => {
                        eprintln!("gateway: link health not posted: {e}");
                        failing = true;
                    }
                    Err(_) => {}
                }
                std::thread::sleep(every);
            }
        });
    }

    // Statistics.
    if let Some(every) = options.stats_every {
        let (stats, stop) = (stats.clone(), stop.clone());
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                std::thread::sleep(every);
                eprintln!("gateway: {}", stats.line());
            }
        });
    }

    // Controller -> Yamcs, on this thread.
    let mut uart_rx = uart_rx;
    let mut tm = TmPath::new();
    let mut correlator = Correlator::new();
    let mut buf = [0u8; READ_CHUNK];
    let mut packets = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let n = match uart_rx.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e)
                if e.kind() == std::io::ErrorKind::WouldBlock
                    || e.kind() == std::io::ErrorKind::TimedOut
                    || e.kind() == std::io::ErrorKind::Interrupted =>
            {
                continue
            }
            Err(e) => return Err(format!("controller stream: {e}")),
        };
        let arrival = now_unix_s();
        let before = tm.bad_frames;
        tm.push(&buf[..n], &mut packets);
        Stats::add(&stats.tm_bad_frames, tm.bad_frames - before);
        for p in packets.drain(..) {
            if let (Some(tx), Some(obt), Some(url)) = (&tco_tx, tm_obt_s(&p), &options.tco_url) {
                if let Some(fit) = correlator.sample(obt, arrival) {
                    if let Ok(mut f) = latest_fit.lock() {
                        *f = Some(fit);
                    }
                    // Before this packet goes to Yamcs, so that Yamcs stamps it with the
                    // corrected line; if Yamcs does not answer at once, retry later.
                    let live = client.lock().map(|c| c.is_some()).unwrap_or(false);
                    if live && http_post_json(url, &coefficients_json(&fit)).is_ok() {
                        Stats::add(&stats.tco_updates, 1);
                    } else {
                        let _ = tx.send(fit);
                    }
                }
                // The residual against the line Yamcs stamps this packet with (set just
                // above when it changed): >= 0 but for the tolerance the line may lag by.
                if let Some(line) = correlator.published() {
                    let residual_ms = (arrival - line.utc(obt)) * f64::from(MS_PER_S);
                    stats
                        .tco_residual_ms_bits
                        .store(residual_ms.to_bits(), Ordering::Relaxed);
                }
            }
            let (Ok(mut c), Ok(mut b)) = (client.lock(), backlog.lock()) else {
                continue;
            };
            let sent = c.as_mut().is_some_and(|s| s.write_all(&p).is_ok());
            if sent {
                Stats::add(&stats.tm_packets, 1);
                if let (Some(tx), true) = (&events_tx, is_event(&p)) {
                    let _ = tx.send((p, correlator.published()));
                }
            } else {
                *c = None;
                if b.len() == capacity {
                    b.pop_front();
                    Stats::add(&stats.tm_backlog_dropped, 1);
                }
                b.push_back(p);
            }
        }
    }
    stop.store(true, Ordering::Relaxed);
    eprintln!("gateway: controller stream closed; {}", stats.line());
    Ok(())
}
