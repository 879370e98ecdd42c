//! Numbering and framing of telecommands as a ground station sends them (host): the
//! sequencer every station (the mission demo's, the tests', the gateway's, the
//! simulated bench's) shares.

use crate::link::schedule::{ActivityBlock, ScheduleCommand};
use crate::link::tc::{AckFlags, EncodeError, RequestId, TcHeader};
use crate::link::tm::TmTime;
use crate::link::{encode_frame, encode_telecommand, Command, MAX_TC_PACKET_LEN};

/// Numbers telecommands in sequence: every encoded TC takes the next sequence count
/// (14 bits, wrapping) and carries the source ID and acknowledgement flags given here.
#[derive(Clone, Copy, Debug)]
pub struct TcSequencer {
    /// Sequence count of the next TC.
    pub next_seq_count: u16,
    /// Source ID of every TC.
    pub source_id: u16,
    /// Acknowledgement flags of every TC.
    pub ack: AckFlags,
}

impl TcSequencer {
    /// Starting at `first_seq_count`, source ID 0, all acknowledgements.
    pub fn new(first_seq_count: u16) -> TcSequencer {
        TcSequencer {
            next_seq_count: first_seq_count,
            source_id: 0,
            ack: AckFlags::ALL,
        }
    }

    fn header(&mut self) -> TcHeader {
        let h = TcHeader {
            seq_count: self.next_seq_count,
            source_id: self.source_id,
            ack: self.ack,
        };
        self.next_seq_count = self.next_seq_count.wrapping_add(1) & crate::link::tc::SEQ_COUNT_MASK;
        h
    }

    /// The PUS packet (unframed) of the next TC.
    pub fn packet(&mut self, command: &Command) -> Result<Vec<u8>, String> {
        let mut buf = [0u8; MAX_TC_PACKET_LEN];
        let n = encode_telecommand(command, self.header(), &mut buf)
            .map_err(|EncodeError::BufferTooSmall| format!("{command:?}: packet too long"))?;
        Ok(buf[..n].to_vec())
    }

    /// The framed bytes (`0x00, COBS(packet), 0x00`) of the next TC.
    pub fn frame(&mut self, command: &Command) -> Result<Vec<u8>, String> {
        let packet = self.packet(command)?;
        Ok(frame(&packet))
    }

    /// Frames of a command sequence, one per command.
    pub fn frames(&mut self, commands: &[Command]) -> Result<Vec<Vec<u8>>, String> {
        commands.iter().map(|c| self.frame(c)).collect()
    }

    /// A TC[11,4] inserting `activities` (release time, telecommand): each embedded
    /// telecommand is numbered by this sequencer first (in order), then the insert
    /// itself. Returns the insert and the embedded request IDs (what a delete names).
    pub fn schedule_insert(
        &mut self,
        activities: &[(TmTime, Command)],
    ) -> Result<(Command, Vec<RequestId>), String> {
        let mut packets = Vec::new();
        for (release, command) in activities {
            if matches!(command, Command::Schedule(_)) {
                return Err("a schedule telecommand cannot be scheduled".into());
            }
            packets.push((*release, self.packet(command)?));
        }
        let ids = packets
            .iter()
            .map(|(_, p)| RequestId::from_packet(p).unwrap_or_default())
            .collect();
        let refs: Vec<(TmTime, &[u8])> = packets.iter().map(|(t, p)| (*t, p.as_slice())).collect();
        let block = ActivityBlock::new(&refs).map_err(|e| {
            format!(
                "the activities do not make a TC[11,4] (code {:#06x}, data {:#x}): at most {} \
                 bytes, embedded telecommands of at most {} bytes",
                e.code(),
                e.data(),
                crate::link::schedule::MAX_INSERT_APP_DATA_LEN,
                crate::link::schedule::MAX_SCHEDULED_TC_LEN
            )
        })?;
        Ok((Command::Schedule(ScheduleCommand::Insert(block)), ids))
    }
}

/// COBS frame of a packet.
pub fn frame(packet: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; crate::link::framing::max_frame_len(packet.len())];
    let n = encode_frame(packet, &mut out).unwrap_or(0);
    out.truncate(n);
    out
}
