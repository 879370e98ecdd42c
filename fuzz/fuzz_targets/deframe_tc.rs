//! The byte stream into the controller: the COBS deframer, then the telecommand decoder
//! (and the ground's telemetry parser) on every frame. Properties: nothing panics; a
//! decoded telecommand re-encodes to exactly the packet it came from.
#![no_main]

use libfuzzer_sys::fuzz_target;
use m2ctl::link::framing::Deframer;
use m2ctl::link::tc::{decode_telecommand, encode_telecommand, TcHeader};
use m2ctl::link::tm::parse_tm;
use m2ctl::link::{Housekeeping, MAX_TC_PACKET_LEN};

fuzz_target!(|bytes: &[u8]| {
    let mut d: Deframer<{ m2ctl::controller::comms::RX_FRAME_BUFFER_LEN }> = Deframer::new();
    for &b in bytes {
        if let Some(Ok(p)) = d.push_byte(b) {
            if let Ok(tc) = decode_telecommand(p) {
                let h = TcHeader {
                    seq_count: tc.request_id.seq_count(),
                    source_id: tc.source_id,
                    ack: tc.ack,
                };
                let mut buf = [0u8; MAX_TC_PACKET_LEN];
                let n = encode_telecommand(&tc.command, h, &mut buf).expect("re-encode");
                assert_eq!(&buf[..n], p, "a decoded TC must re-encode exactly");
            }
            let _ = parse_tm(p);
        }
    }
    let _ = decode_telecommand(bytes);
    let _ = parse_tm(bytes);
    let _ = Housekeeping::parse(bytes);
});
