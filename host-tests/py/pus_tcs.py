#!/usr/bin/env python3
"""Independent encoder of m2ctl telecommands with the Python `spacepackets` package.

Builds the TCs of docs/icd.md from the ICD alone (struct.pack for the application data,
spacepackets.ecss.PusTc for the PUS-C packet and its CRC-16) and prints one line per TC:
`name hex`. ground/tests/link.rs compares them byte for byte with the Rust encoder.
"""
import struct
import sys

try:
    from spacepackets.ecss import PusTc
except ImportError:
    sys.stderr.write("python package 'spacepackets' missing: pip install spacepackets\n")
    sys.exit(3)

APID = 0x0B2  # M2_APID

# (name, sequence count, service, subtype, application data)
TCS = [
    ("ping", 0, 17, 1, b""),
    ("hk", 1, 3, 27, b""),
    # move absolute: function 0x0001, x,y,z nm, alpha,beta,gamma uas (i32 BE)
    ("move_abs", 2, 8, 1, struct.pack(">H6i", 0x0001, 1500, -2000, 30000, -2000000, 1000000, 7)),
    ("move_rel", 3, 8, 1, struct.pack(">H6i", 0x0002, -1, 0, 2147483647, 0, -2147483648, 0)),
    ("stop", 4, 8, 1, struct.pack(">H", 0x0003)),
    ("direct_stroke", 5, 8, 1, struct.pack(">HBi", 0x0005, 6, -12345)),
    ("commit", 6, 8, 1, struct.pack(">HI", 0x0010, 0xDEADBEEF)),
    # activate: function 0x0011, expected table ID u32, expected CRC-32 u32
    ("activate", 16383, 8, 1, struct.pack(">HII", 0x0011, 42, 0x01234567)),
    # table chunk: memory 1, offset 128, length 4, data
    ("load_chunk", 7, 6, 2, struct.pack(">BHH", 1, 128, 4) + bytes([0, 1, 2, 0xFF])),
    ("dump", 8, 6, 5, bytes([2])),
]

for name, seq, service, subtype, app_data in TCS:
    tc = PusTc(service=service, message_subtype=subtype, apid=APID, seq_count=seq,
               app_data=app_data, source_id=0, ack_flags=0b1111)
    print(name, tc.pack().hex())
