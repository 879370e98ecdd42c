//! A minimal ground station for the tests: encodes framed telecommands with the crate's
//! encoder and parses the controller's telemetry frames into owned records.
#![allow(dead_code)]

use m2ctl::link::framing::Deframer;
use m2ctl::link::tc::{encode_telecommand, TcHeader};
use m2ctl::link::tm::{parse_tm, EventSeverity, TmReport, Verification};
use m2ctl::link::{
    encode_frame, Command, Housekeeping, MemoryId, RequestId, MAX_TC_FRAME_LEN, MAX_TC_PACKET_LEN,
};

/// One telemetry packet, owned.
#[derive(Clone, Debug, PartialEq)]
pub enum Tm {
    /// TM[1,x].
    Verify(RequestId, Verification),
    /// TM[3,25].
    Hk(Housekeeping),
    /// TM[5,x].
    Event(EventSeverity, u16, [u32; 2]),
    /// TM[6,6].
    Dump(MemoryId, u16, Vec<u8>),
    /// TM[17,2].
    Ping,
}

/// Sends telecommands, collects telemetry.
pub struct Station {
    seq: u16,
    deframer: Deframer,
    /// Every TM packet received, in order.
    pub log: Vec<Tm>,
    /// Frames that failed to parse (must stay empty).
    pub bad_frames: usize,
}

impl Station {
    pub fn new() -> Self {
        Station {
            seq: 0,
            deframer: Deframer::new(),
            log: Vec::new(),
            bad_frames: 0,
        }
    }

    /// The packet (unframed) and its request ID.
    pub fn packet(&mut self, cmd: &Command) -> (Vec<u8>, RequestId) {
        let mut buf = [0u8; MAX_TC_PACKET_LEN];
        let n = encode_telecommand(cmd, TcHeader::new(self.seq), &mut buf).unwrap();
        self.seq = (self.seq + 1) & 0x3fff;
        let pkt = buf[..n].to_vec();
        let rid = RequestId::from_packet(&pkt).unwrap();
        (pkt, rid)
    }

    /// A framed telecommand and its request ID.
    pub fn frame(&mut self, cmd: &Command) -> (Vec<u8>, RequestId) {
        let (pkt, rid) = self.packet(cmd);
        let mut out = [0u8; MAX_TC_FRAME_LEN];
        let n = encode_frame(&pkt, &mut out).unwrap();
        (out[..n].to_vec(), rid)
    }

    /// Feeds received bytes (any split) into the deframer and parses complete frames.
    pub fn receive(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if let Some(frame) = self.deframer.push_byte(b) {
                match frame.map(|f| f.to_vec()) {
                    Ok(f) => match parse_tm(&f) {
                        Ok(tm) => self.log.push(match tm.report {
                            TmReport::Verification { request_id, report } => {
                                Tm::Verify(request_id, report)
                            }
                            TmReport::Housekeeping(h) => Tm::Hk(h),
                            TmReport::Event {
                                severity,
                                event_id,
                                aux,
                            } => Tm::Event(severity, event_id, aux),
                            TmReport::DumpChunk {
                                memory,
                                offset_bytes,
                                bytes,
                            } => Tm::Dump(memory, offset_bytes, bytes.to_vec()),
                            TmReport::PingReply => Tm::Ping,
                        }),
                        Err(_) => self.bad_frames += 1,
                    },
                    Err(_) => self.bad_frames += 1,
                }
            }
        }
    }

    /// Verification reports for one request, in order.
    pub fn reports(&self, rid: RequestId) -> Vec<Verification> {
        self.log
            .iter()
            .filter_map(|t| match t {
                Tm::Verify(r, v) if *r == rid => Some(*v),
                _ => None,
            })
            .collect()
    }

    /// The newest housekeeping report.
    pub fn last_hk(&self) -> Option<Housekeeping> {
        self.log.iter().rev().find_map(|t| match t {
            Tm::Hk(h) => Some(*h),
            _ => None,
        })
    }

    /// Events with this ID.
    pub fn events(&self, id: u16) -> Vec<[u32; 2]> {
        self.log
            .iter()
            .filter_map(|t| match t {
                Tm::Event(_, e, aux) if *e == id => Some(*aux),
                _ => None,
            })
            .collect()
    }
}
