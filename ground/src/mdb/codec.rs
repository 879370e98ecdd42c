//! Encoding and decoding by the description (what Yamcs does with the XTCE).

use super::{ArgValue, Field, Mdb, Meaning, Telecommand, TmPacket, Wire, TC_APP_DATA_OFFSET};
use m2ctl::link::tc::{TcHeader, APID_MASK, SEQ_COUNT_MASK};
use m2ctl::link::{
    encode_telecommand, CCSDS_PRIMARY_HEADER_LEN, M2_APID, MAX_TC_PACKET_LEN, PUS_C_VERSION,
};

impl Field {
    /// Raw integer of this field in `data` (offsets relative to `data`); `None` if out of
    /// bounds or a byte field.
    pub fn read_raw(&self, data: &[u8]) -> Option<i64> {
        let n = self.wire.fixed_len()?;
        let b = data.get(self.offset..self.offset.checked_add(n)?)?;
        let u = b.iter().fold(0u64, |acc, x| (acc << 8) | u64::from(*x));
        Some(match self.wire {
            Wire::I32 => i64::from(u32::try_from(u).ok()? as i32),
            _ => i64::try_from(u).ok()?,
        })
    }

    /// Engineering value of a raw number (raw x scale), for numbers.
    pub fn to_eng(&self, raw: i64) -> f64 {
        match self.meaning {
            Meaning::Number { scale, .. } => raw as f64 * scale,
            _ => raw as f64,
        }
    }

    /// Raw value of an engineering value (nearest, half away from zero), range-checked.
    pub fn to_raw(&self, eng: f64) -> Result<i64, String> {
        let (scale, range) = match self.meaning {
            Meaning::Number { scale, range, .. } => (scale, range),
            _ => (1.0, None),
        };
        if let Some((lo, hi)) = range {
            if !(lo..=hi).contains(&eng) {
                return Err(format!("{} = {eng}: outside {lo}..={hi}", self.name));
            }
        }
        let raw = (eng / scale).round();
        let (lo, hi) = self.wire.raw_range().ok_or("not a number field")?;
        if !raw.is_finite() || raw < lo as f64 || raw > hi as f64 {
            return Err(format!("{} = {eng}: beyond the wire range", self.name));
        }
        Ok(raw as i64)
    }

    /// Is this an operator argument (not a constant)?
    pub fn is_argument(&self) -> bool {
        !matches!(self.meaning, Meaning::Fixed { .. })
    }
}

impl Telecommand {
    /// Operator arguments, in order.
    pub fn arguments(&self) -> impl Iterator<Item = &Field> {
        self.fields.iter().filter(|f| f.is_argument())
    }

    /// Application data encoded by the description from raw argument values.
    pub fn encode_app_data(&self, args: &[ArgValue]) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        if let Some(f) = self.function_id {
            out.extend(f.to_be_bytes());
        }
        let mut next = args.iter();
        for f in &self.fields {
            if out.len() != f.offset {
                return Err(format!(
                    "{}.{}: offset {} != {}",
                    self.name,
                    f.name,
                    f.offset,
                    out.len()
                ));
            }
            let value = match f.meaning {
                Meaning::Fixed { value } => ArgValue::Int(value),
                _ => next
                    .next()
                    .cloned()
                    .ok_or_else(|| format!("{}: missing argument {}", self.name, f.name))?,
            };
            match (f.wire, value) {
                (Wire::Packet { min_len, max_len }, ArgValue::Bytes(b)) => {
                    if !(min_len..=max_len).contains(&b.len()) {
                        return Err(format!("{}: {} bytes", f.name, b.len()));
                    }
                    out.extend(b);
                }
                (Wire::Bytes { min_len, max_len }, ArgValue::Bytes(b)) => {
                    if !(min_len..=max_len).contains(&b.len()) {
                        return Err(format!("{}: {} bytes", f.name, b.len()));
                    }
                    let n = u16::try_from(b.len()).map_err(|e| e.to_string())?;
                    out.extend(n.to_be_bytes());
                    out.extend(b);
                }
                (w, ArgValue::Int(v)) => {
                    let (lo, hi) = w.raw_range().ok_or("bytes field given an integer")?;
                    if !(lo..=hi).contains(&v) {
                        return Err(format!("{} = {v}: beyond the wire range", f.name));
                    }
                    let n = w.fixed_len().unwrap_or(0);
                    let be = v.to_be_bytes();
                    out.extend(be.get(be.len() - n..).unwrap_or(&[]));
                }
                (_, v) => return Err(format!("{}: wrong value kind {v:?}", f.name)),
            }
        }
        if next.next().is_some() {
            return Err(format!("{}: too many arguments", self.name));
        }
        Ok(out)
    }

    /// The whole TC packet encoded by the description (what Yamcs' XTCE encoder and PUS
    /// post-processor produce): primary header, PUS-C secondary header, application
    /// data, CRC-16/CCITT-FALSE.
    pub fn encode_packet(&self, args: &[ArgValue], header: TcHeader) -> Result<Vec<u8>, String> {
        let app = self.encode_app_data(args)?;
        let mut p = Vec::with_capacity(TC_APP_DATA_OFFSET + app.len() + 2);
        // Packet ID: version 0, type TC (bit 12), secondary header (bit 11), APID.
        let packet_id: u16 = (1 << 12) | (1 << 11) | (M2_APID & APID_MASK);
        let seq: u16 = (0b11 << 14) | (header.seq_count & SEQ_COUNT_MASK);
        let total = TC_APP_DATA_OFFSET + app.len() + 2;
        let data_len =
            u16::try_from(total - CCSDS_PRIMARY_HEADER_LEN - 1).map_err(|e| e.to_string())?;
        p.extend(packet_id.to_be_bytes());
        p.extend(seq.to_be_bytes());
        p.extend(data_len.to_be_bytes());
        p.push((PUS_C_VERSION << 4) | (header.ack.0 & 0x0f));
        p.push(self.service);
        p.push(self.subtype);
        p.extend(header.source_id.to_be_bytes());
        p.extend(app);
        let crc = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740).checksum(&p);
        p.extend(crc.to_be_bytes());
        Ok(p)
    }

    /// The same telecommand encoded by the flight link's encoder (for comparison).
    pub fn encode_by_link(&self, args: &[ArgValue], header: TcHeader) -> Result<Vec<u8>, String> {
        let cmd = (self.build)(args)?;
        let mut buf = [0u8; MAX_TC_PACKET_LEN];
        let n = encode_telecommand(&cmd, header, &mut buf).map_err(|e| format!("{e:?}"))?;
        Ok(buf.get(..n).unwrap_or(&[]).to_vec())
    }
}

impl Mdb {
    /// The telecommand of this name.
    pub fn telecommand(&self, name: &str) -> Option<&Telecommand> {
        self.telecommands.iter().find(|t| t.name == name)
    }

    /// The TM packet of this name.
    pub fn tm_packet(&self, name: &str) -> Option<&TmPacket> {
        self.telemetry.iter().find(|t| t.name == name)
    }

    /// Pretty JSON (the input of `yamcs/tools/gen_xtce.py`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}
