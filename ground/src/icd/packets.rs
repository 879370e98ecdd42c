//! ICD section 2 (the packet's fixed fields: APID, version, sequence flags and counts,
//! the CRC) and section 3 (the telecommands and the functions of service 8).

use super::markdown::{table, tc_label, Align};
use crate::mdb::{hex4, Field, Mdb, Telecommand, PERFORM_FUNCTION};
use m2ctl::link::command::{FunctionId, FUNCTION_ID_LEN};
use m2ctl::link::tc::{APID_MASK, SEQ_COUNT_MASK};
use m2ctl::link::{LinkError, M2_APID};

pub(super) fn packet_block() -> Result<String, String> {
    let crc = m2ctl::link::tc::CRC16_ALGORITHM;
    let seq_bits = SEQ_COUNT_MASK.count_ones();
    let flag = |b: bool| if b { "reflected" } else { "no reflection" };
    let xorout = if crc.xorout == 0 {
        "no xor out".to_string()
    } else {
        format!("xor out {:#06X}", crc.xorout)
    };
    if crc.refin != crc.refout {
        return Err("the TC CRC reflects input and output differently".into());
    }
    let rows = vec![
        vec![
            "APID".into(),
            format!(
                "**`0x{M2_APID:03X}`** ({M2_APID}), both directions; TCs with another APID are \
                 refused (code {})",
                hex4(LinkError::WrongApid { apid: 0 }.code())
            ),
        ],
        vec!["packet version".into(), "0".into()],
        vec![
            "sequence flags".into(),
            format!(
                "`0b11` (unsegmented); anything else is refused ({})",
                hex4(LinkError::BadPrimaryHeader.code())
            ),
        ],
        vec![
            "TC sequence count".into(),
            format!("chosen by the sender ({seq_bits} bits), echoed in the request ID"),
        ],
        vec![
            "TM sequence count".into(),
            format!(
                "0 after boot, +1 per TM packet, wraps at {}",
                u32::from(SEQ_COUNT_MASK) + 1
            ),
        ],
        vec![
            "packet error control".into(),
            format!(
                "CRC-16/CCITT-FALSE (poly 0x{:04X}, init 0x{:04X}, {}, {xorout}) over the \
                 whole packet except the CRC; mandatory in TC and TM",
                crc.poly,
                crc.init,
                flag(crc.refin)
            ),
        ],
    ];
    if u32::from(M2_APID) & !u32::from(APID_MASK) != 0 {
        return Err(format!("APID {M2_APID:#x} wider than its field"));
    }
    table(&[("item", Align::Left), ("value", Align::Left)], &rows)
}

pub(super) fn telecommands_block(db: &Mdb) -> Result<String, String> {
    let mut rows: Vec<Vec<String>> = Vec::new();
    let mut seen: Vec<(u8, u8)> = Vec::new();
    let mut i = 0;
    while let Some(tc) = db.telecommands.get(i) {
        let key = (tc.service, tc.subtype);
        if seen.contains(&key) {
            return Err(format!(
                "TC{} is described in two places: list its telecommands together",
                tc_label(tc.service, &[tc.subtype])
            ));
        }
        seen.push(key);
        let group: Vec<&Telecommand> = db.telecommands[i..]
            .iter()
            .take_while(|t| (t.service, t.subtype) == key)
            .collect();
        i += group.len();
        let label = format!("TC{}", tc_label(tc.service, &[tc.subtype]));
        if group.iter().any(|t| t.function_id.is_some()) {
            rows.push(vec![
                label,
                PERFORM_FUNCTION.0.into(),
                PERFORM_FUNCTION.1.into(),
            ]);
        } else if let [only] = group.as_slice() {
            rows.push(vec![
                label,
                only.title.clone(),
                only.app_data_layout.clone(),
            ]);
        } else {
            return Err(format!(
                "{label}: several telecommands without function IDs"
            ));
        }
    }
    table(
        &[
            ("TC", Align::Left),
            ("meaning", Align::Left),
            ("application data", Align::Left),
        ],
        &rows,
    )
}

/// End of the last fixed-size field (bytes of application data the fields take).
fn fields_end(fields: &[Field]) -> Option<usize> {
    fields
        .iter()
        .map(|f| f.wire.fixed_len().map(|n| f.offset + n))
        .try_fold(0, |acc, end| end.map(|e| acc.max(e)))
}

pub(super) fn functions_block(db: &Mdb) -> Result<String, String> {
    let mut rows = Vec::new();
    for tc in &db.telecommands {
        let Some(id) = tc.function_id else { continue };
        let f = FunctionId::from_code(id)
            .ok_or_else(|| format!("{}: function {} unknown to the link", tc.name, hex4(id)))?;
        let ad = FUNCTION_ID_LEN + f.args_len();
        let described = fields_end(&tc.fields).unwrap_or(0).max(FUNCTION_ID_LEN);
        if described != ad {
            return Err(format!(
                "{}: the description's arguments end at byte {described}, the link takes {ad}",
                tc.name
            ));
        }
        rows.push(vec![
            hex4(id),
            tc.title.clone(),
            tc.app_data_layout.clone(),
            ad.to_string(),
        ]);
    }
    table(
        &[
            ("ID", Align::Left),
            ("function", Align::Left),
            ("arguments after the ID", Align::Left),
            ("AD bytes", Align::Left),
        ],
        &rows,
    )
}
