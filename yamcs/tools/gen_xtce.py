#!/usr/bin/env python3
"""Generate the Yamcs mission database of the M2 controller from its description.

    m2ground mdb-json --out mdb.json
    python3 yamcs/tools/gen_xtce.py mdb.json OUT_DIR

writes OUT_DIR/mdb/m2.xml (XTCE 1.2, yamcs-pymdb). (Events are not Yamcs' to decode:
the gateway posts them, named by the same description.) The JSON is the only input: this script
knows the PUS packet structure and how Yamcs verifies a PUS command, never the
controller's vocabulary (every telecommand, field, unit, calibration, enumeration, bit
and event comes from `ground/src/mdb/`). See docs/ground-segment.md.
"""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from yamcs.pymdb import (
    AcceptedVerifier,
    Algorithm,
    AggregateDataType,
    AlarmLevel,
    AlgorithmCheck,
    ArrayParameter,
    ArgumentEntry,
    BinaryArgument,
    BinaryEncoding,
    BinaryParameter,
    BooleanParameter,
    Command,
    CommandLevel,
    CompleteVerifier,
    Container,
    DataSource,
    EnumeratedArgument,
    EnumeratedParameter,
    EnumerationAlarm,
    ExecutionVerifier,
    FixedValueEntry,
    FloatArgument,
    FloatMember,
    FloatParameter,
    InputParameter,
    IntegerArgument,
    IntegerEncoding,
    IntegerEncodingScheme,
    IntegerMember,
    IntegerParameter,
    OutputParameter,
    ParameterEntry,
    ParameterTrigger,
    ParameterValue,
    Polynomial,
    System,
    ThresholdAlarm,
    TransmissionConstraint,
    UnnamedJavaAlgorithm,
    all_of,
    any_of,
    eq,
)

WIRE_BITS = {"u8": 8, "u16": 16, "u32": 32, "i32": 32}
LENGTH_PREFIX_BITS = 16


def encoding(wire: str) -> IntegerEncoding:
    scheme = (
        IntegerEncodingScheme.TWOS_COMPLEMENT
        if wire == "i32"
        else IntegerEncodingScheme.UNSIGNED
    )
    return IntegerEncoding(bits=WIRE_BITS[wire], scheme=scheme)


def uint(bits: int) -> IntegerEncoding:
    return IntegerEncoding(bits=bits, scheme=IntegerEncodingScheme.UNSIGNED)


class Generator:
    def __init__(self, mdb: dict):
        self.mdb = mdb
        self.link = mdb["link"]
        self.system = System(mdb["name"])
        self.enums = {e["name"]: e["values"] for e in mdb["enums"]}
        self.bit_fields = {b["name"]: b["bits"] for b in mdb["bit_fields"]}
        self.alarms = {a["parameter"]: a for a in mdb.get("alarms", [])}
        self.alarmed: set[str] = set()
        self.params: dict[str, object] = {}
        # Parameter (= type) name -> decimals shown (the description's fraction_digits).
        self.number_formats: dict[str, int] = {}

    # ------------------------------------------------------------------ link health

    def link_health(self):
        """The gateway's link-health parameters: local parameters (Yamcs takes their
        values from the gateway through its HTTP API), with their alarms."""
        s = self.system
        for p in self.mdb["link_health"]:
            name = p["name"]
            rule = p["alarm"]
            alarm = None
            if rule is not None:
                if rule["kind"] != "above":
                    raise ValueError(f"{name}: unknown link-health alarm rule {rule['kind']}")
                alarm = ThresholdAlarm(**{f"{rule['level'].lower()}_high": rule["limit"]},
                                       minimum_violations=p["min_violations"])
            common = dict(data_source=DataSource.LOCAL, persistent=False, units=p["unit"],
                          short_description=p["description"], alarm=alarm)
            if p["kind"] == "counter":
                param = IntegerParameter(s, name, signed=False, bits=64, **common)
            elif p["kind"] == "float":
                param = FloatParameter(s, name, bits=64, **common)
                if p.get("fraction_digits") is not None:
                    self.number_formats[name] = p["fraction_digits"]
            else:
                raise ValueError(f"{name}: unknown kind {p['kind']}")
            if name in self.params:
                raise ValueError(f"{name}: a link-health parameter named like a TM field")
            self.params[name] = param

    # ------------------------------------------------------------------ derived

    def derived(self):
        """Parameters Yamcs derives from each housekeeping report: a JavaScript algorithm
        (Yamcs' default engine) per parameter, its inputs the housekeeping fields, with
        the parameter's alarm."""
        s = self.system
        for d in self.mdb["derived"]:
            name = d["name"]
            if name in self.params:
                raise ValueError(f"{name}: a derived parameter named like another parameter")
            alarm = ThresholdAlarm(**{f"{level.lower()}_high": limit for level, limit in d["above"]},
                                   minimum_violations=d["min_violations"])
            out = FloatParameter(s, name, bits=64, units=d["unit"], data_source=DataSource.DERIVED,
                                 short_description=d["description"], alarm=alarm)
            self.params[name] = out
            self.number_formats[name] = d["fraction_digits"]
            inputs = []

            def bind(var, field):
                if field not in self.params:
                    raise ValueError(f"{name}: input {field} is not a telemetry parameter")
                inputs.append(InputParameter(self.params[field], name=var, required=True))
            c = d["computation"]
            if c["kind"] == "largest_difference":
                terms = []
                for i, (a, b) in enumerate(c["pairs"]):
                    bind(f"a{i}", a)
                    bind(f"b{i}", b)
                    terms.append(f"Math.abs(a{i}.value - b{i}.value)")
                text = f"out.value = Math.max({', '.join(terms)});"
            elif c["kind"] == "largest_deviation":
                lines = ["var m = 0;"]
                for i, f in enumerate(c["fields"]):
                    bind(f"f{i}", f)
                    lines.append(f"if (f{i}.value != {c['absent']!r}) "
                                 f"m = Math.max(m, Math.abs(f{i}.value - {c['from']!r}));")
                text = "\n".join(lines + ["out.value = m;"])
            else:
                raise ValueError(f"{name}: unknown computation {c['kind']}")
            Algorithm(
                s,
                f"{name}_algorithm",
                language="JavaScript",
                text=text,
                inputs=inputs,
                outputs=[OutputParameter(out, name="out")],
                # Run once per housekeeping report: on its first input's update (every
                # input comes in the same report). Without a trigger Yamcs runs it on
                # every input but warns at each start ("No trigger set for algorithm").
                triggers=[ParameterTrigger(inputs[0].parameter)],
                short_description=d["description"],
            )

    # ------------------------------------------------------------------ telemetry

    def choices(self, enumeration: str):
        return [(v, label, meaning) for v, label, meaning in self.enums[enumeration]]

    def parameter(self, f: dict):
        """The parameter of a TM field (created once, shared by containers)."""
        name = f["name"]
        if name in self.params:
            return self.params[name]
        m = f["meaning"]
        wire = f["wire"]["type"]
        desc = f["description"]
        s = self.system
        kind = m["kind"]
        alarm = self.alarm(name)
        if kind == "number" and m["scale"] != 1.0:
            if f.get("fraction_digits") is not None:
                self.number_formats[name] = f["fraction_digits"]
            p = FloatParameter(
                s,
                name,
                bits=64,
                units=m["unit"],
                encoding=encoding(wire),
                calibrator=Polynomial([0.0, m["scale"]]),
                short_description=desc,
            )
        elif kind in ("number", "fixed", "bits"):
            p = IntegerParameter(
                s,
                name,
                signed=wire == "i32",
                bits=64 if wire == "u32" else 32,
                units=m.get("unit"),
                encoding=encoding(wire),
                short_description=desc,
                alarm=alarm,
            )
        elif kind == "enum":
            p = EnumeratedParameter(
                s,
                name,
                choices=self.choices(m["enumeration"]),
                encoding=encoding(wire),
                short_description=desc,
                alarm=alarm,
            )
        elif kind == "boolean":
            p = BooleanParameter(s, name, encoding=encoding(wire), short_description=desc)
        elif kind == "binary":
            p = BinaryParameter(
                s,
                name,
                encoding=BinaryEncoding(length_bits=LENGTH_PREFIX_BITS),
                short_description=desc,
            )
        else:
            raise ValueError(f"{name}: unknown meaning {kind}")
        self.params[name] = p
        return p

    def constraint(self, c):
        """The description's transmission constraint as pymdb's (None: none)."""
        if c is None:
            return None
        state = self.params["state"]
        states = [eq(state, label) for label in c["states"]]
        allowed = states[0] if len(states) == 1 else any_of(*states)
        expr = all_of(allowed, eq(self.params["job"], 0)) if c["no_job"] else allowed
        return TransmissionConstraint(expr, timeout=c["timeout_s"])

    def alarm(self, name: str):
        """The description's alarm of a parameter, as pymdb's alarm (None: none)."""
        a = self.alarms.get(name)
        if a is None:
            return None
        self.alarmed.add(name)
        rule = a["rule"]
        if rule["kind"] == "states":
            return EnumerationAlarm({label: AlarmLevel[level] for label, level in rule["levels"]},
                                    minimum_violations=a["min_violations"])
        if rule["kind"] == "above":
            level = rule["level"].lower()
            return ThresholdAlarm(**{f"{level}_high": rule["limit"]},
                                  minimum_violations=a["min_violations"])
        raise ValueError(f"{name}: unknown alarm rule {rule['kind']}")

    def entries(self, fields: list[dict], base_byte: int) -> list[ParameterEntry]:
        """Entries at absolute bit positions; a bit-field word also gets one boolean
        parameter per named bit, overlaid on the word."""
        out = []
        for f in fields:
            at = (base_byte + f["offset"]) * 8
            out.append(ParameterEntry(self.parameter(f), bitpos=at))
            m = f["meaning"]
            if m["kind"] == "bits":
                width = WIRE_BITS[f["wire"]["type"]]
                for bit, bname, meaning in self.bit_fields[m["bit_field"]]:
                    pname = f"{f['name']}_{bname.lower()}"
                    if pname not in self.params:
                        self.params[pname] = BooleanParameter(
                            self.system,
                            pname,
                            encoding=uint(1),
                            short_description=f"{f['name']} bit {bit}: {meaning}",
                        )
                    out.append(
                        ParameterEntry(self.params[pname], bitpos=at + width - 1 - bit)
                    )
        return out

    def member(self, f: dict):
        """An aggregate member for one field of a repeated group (numbers only)."""
        m = f["meaning"]
        wire = f["wire"]["type"]
        if m["kind"] != "number":
            raise ValueError(f"{f['name']}: repeated fields are numbers")
        if m["scale"] != 1.0:
            return FloatMember(
                f["name"],
                bits=64,
                units=m["unit"],
                encoding=encoding(wire),
                calibrator=Polynomial([0.0, m["scale"]]),
                short_description=f["description"],
            )
        return IntegerMember(
            f["name"],
            signed=wire == "i32",
            bits=64 if wire == "u32" else 32,
            units=m.get("unit"),
            encoding=encoding(wire),
            short_description=f["description"],
        )

    def repeated_entry(self, rep: dict, base_byte: int) -> ParameterEntry:
        """A repeated group (e.g. the activities of TM[11,13]) as one array parameter
        of aggregates whose length is the count field."""
        fields = sorted(rep["fields"], key=lambda f: f["offset"])
        at = 0
        for f in fields:
            if f["offset"] != at:
                raise ValueError(f"{rep['name']}.{f['name']}: not contiguous")
            at += WIRE_BITS[f["wire"]["type"]] // 8
        if at != rep["element_len"]:
            raise ValueError(f"{rep['name']}: fields cover {at} of {rep['element_len']} bytes")
        element = AggregateDataType(members=[self.member(f) for f in fields])
        array = ArrayParameter(
            self.system,
            rep["name"],
            data_type=element,
            length=ParameterValue(self.params[rep["count_field"]]),
            short_description=f"up to {rep['max_count']} entries",
        )
        self.params[rep["name"]] = array
        return ParameterEntry(array, bitpos=(base_byte + rep["offset"]) * 8)

    def telemetry(self):
        s = self.system
        L = self.link
        hdr = lambda name, bits, desc: IntegerParameter(  # noqa: E731
            s, name, signed=False, bits=32, encoding=uint(bits), short_description=desc
        )
        self.apid = hdr("ccsds_apid", 11, "APID of the packet")
        self.seq = hdr("ccsds_seq_count", 14, "packet sequence count")
        ccsds = Container(
            s,
            "ccsds",
            entries=[
                ParameterEntry(self.apid, bitpos=5),
                ParameterEntry(self.seq, bitpos=18),
            ],
            short_description="CCSDS space packet (root container)",
        )
        time_at = L["tm_time_offset"]
        coarse = L["cuc_coarse_bytes"] * 8
        fine = L["cuc_fine_bytes"] * 8
        self.service = hdr("pus_service", 8, "PUS service of the TM packet")
        self.subtype = hdr("pus_subtype", 8, "PUS subtype of the TM packet")
        self.obt_s = hdr("obt_seconds", coarse, "on-board time: seconds since boot (CUC coarse)")
        self.obt_f = hdr("obt_fraction", fine, "on-board time: 1/65536 s (CUC fine)")
        pus_tm = Container(
            s,
            "pus_tm",
            base=ccsds,
            condition=eq(self.apid, L["apid"]),
            entries=[
                ParameterEntry(self.service, bitpos=7 * 8),
                ParameterEntry(self.subtype, bitpos=8 * 8),
                ParameterEntry(
                    hdr("pus_msg_counter", 16, "message type counter (per service)"),
                    bitpos=9 * 8,
                ),
                ParameterEntry(self.obt_s, bitpos=time_at * 8),
                ParameterEntry(self.obt_f, bitpos=time_at * 8 + coarse),
            ],
            short_description="PUS-C TM packet of the M2 controller",
        )
        # Time reports (APID 0, no secondary header): the on-board time the gateway
        # read from the controller's last TM packet, for Yamcs' time correlation.
        Container(
            s,
            "time_report",
            base=ccsds,
            condition=eq(self.apid, 0),
            entries=[
                ParameterEntry(
                    hdr("time_report_seconds", coarse, "OBT of the time report (s)"),
                    bitpos=6 * 8,
                ),
                ParameterEntry(
                    hdr("time_report_fraction", fine, "OBT of the time report (1/65536 s)"),
                    bitpos=6 * 8 + coarse,
                ),
            ],
            short_description="time correlation sample (ground segment gateway)",
        )
        src = L["tm_source_data_offset"]
        packets = {p["name"]: p for p in self.mdb["telemetry"]}
        # Service 1: the request ID's APID and sequence count and the report's subtype
        # as parameters of the verification container only, so that no other packet
        # re-triggers the command verifiers (Pus1Verifier) with stale values.
        self.ver_apid = hdr("ver_tc_apid", 11, "APID of the verified TC")
        self.ver_seq = hdr("ver_tc_seq_count", 14, "sequence count of the verified TC")
        self.ver_sub = hdr("ver_subtype", 8, "subtype of the verification report")
        success = packets["verification_success"]
        failure = packets["verification_failure"]
        ver = Container(
            s,
            "verification",
            base=pus_tm,
            condition=eq(self.service, success["service"]),
            entries=[
                ParameterEntry(self.ver_sub, bitpos=8 * 8),
                ParameterEntry(self.ver_apid, bitpos=src * 8 + 5),
                ParameterEntry(self.ver_seq, bitpos=(src + 2) * 8 + 2),
            ]
            + self.entries(success["fields"], src),
            short_description=success["description"],
        )
        shared = {f["name"] for f in success["fields"]}
        Container(
            s,
            "verification_failure",
            base=ver,
            condition=self.subtype_condition(failure["subtypes"]),
            entries=self.entries([f for f in failure["fields"] if f["name"] not in shared], src),
            short_description=failure["description"],
        )
        for p in self.mdb["telemetry"]:
            if p["service"] == success["service"]:
                continue
            entries = self.entries(p["fields"], src)
            if p.get("repeated"):
                entries.append(self.repeated_entry(p["repeated"], src))
            Container(
                s,
                p["name"],
                base=pus_tm,
                condition=self.packet_condition(p),
                entries=entries,
                short_description=p["description"],
                hint_partition=True,
            )

    def subtype_condition(self, subtypes: list[int]):
        conds = [eq(self.subtype, st) for st in subtypes]
        return conds[0] if len(conds) == 1 else any_of(*conds)

    def packet_condition(self, p: dict):
        return all_of(eq(self.service, p["service"]), self.subtype_condition(p["subtypes"]))

    # ------------------------------------------------------------------ commands

    def argument(self, f: dict):
        m = f["meaning"]
        wire = f["wire"]
        kind = m["kind"]
        name, desc = f["name"], f["description"]
        if kind == "number":
            lo, hi = m["range"] if m["range"] else (None, None)
            if m["scale"] != 1.0:
                # Yamcs applies an argument's calibrator from engineering to raw.
                return FloatArgument(
                    name,
                    bits=64,
                    minimum=lo,
                    maximum=hi,
                    units=m["unit"],
                    encoding=encoding(wire["type"]),
                    calibrator=Polynomial([0.0, 1.0 / m["scale"]]),
                    short_description=desc,
                )
            return IntegerArgument(
                name,
                signed=wire["type"] == "i32",
                bits=64 if wire["type"] == "u32" else 32,
                minimum=int(lo) if lo is not None else None,
                maximum=int(hi) if hi is not None else None,
                units=m["unit"],
                encoding=encoding(wire["type"]),
                short_description=desc,
            )
        if kind == "enum":
            return EnumeratedArgument(
                name,
                choices=self.choices(m["enumeration"]),
                encoding=encoding(wire["type"]),
                short_description=desc,
            )
        if kind == "binary":
            # "packet": an embedded CCSDS packet, no length prefix (its own length field
            # delimits it); "bytes": a u16 length, then the bytes.
            prefix = None if wire["type"] == "packet" else LENGTH_PREFIX_BITS
            return BinaryArgument(
                name,
                min_length=wire["min_len"],
                max_length=wire["max_len"],
                encoding=BinaryEncoding(length_bits=prefix),
                short_description=desc,
            )
        raise ValueError(f"{name}: no argument for meaning {kind}")

    def verifier_check(self, stage: dict) -> AlgorithmCheck:
        failure = self.params["failure_code"], self.params["failure_data"]
        return AlgorithmCheck(
            UnnamedJavaAlgorithm(
                "org.yamcs.pus.Pus1Verifier({stage: %d, template: \"%s\"})"
                % (
                    stage["success_subtype"],
                    "failure code {failure_code} data {failure_data}",
                ),
                inputs=[
                    InputParameter("/yamcs/cmd/arg/apid", name="sentApid"),
                    InputParameter("/yamcs/cmdHist/ccsds-seqcount", name="sentSeqCount"),
                    InputParameter(self.ver_apid, name="rcvdApid"),
                    InputParameter(self.ver_seq, name="rcvdSeqCount"),
                    InputParameter(self.ver_sub, name="reportSubType"),
                    InputParameter(failure[0], name="failure_code"),
                    InputParameter(failure[1], name="failure_data"),
                ],
            )
        )

    def commands(self):
        s = self.system
        L = self.link
        base = Command(
            s,
            "pus_tc",
            abstract=True,
            arguments=[
                IntegerArgument("apid", signed=False, bits=32, encoding=uint(11)),
                IntegerArgument(
                    "ack_flags",
                    signed=False,
                    bits=32,
                    minimum=0,
                    maximum=15,
                    default=L["default_ack_flags"],
                    encoding=uint(4),
                    short_description="acknowledgement flags: 8 acceptance, 4 start, 2 progress, 1 completion",
                ),
                IntegerArgument("service", signed=False, bits=32, encoding=uint(8)),
                IntegerArgument("subtype", signed=False, bits=32, encoding=uint(8)),
                IntegerArgument(
                    "source_id",
                    signed=False,
                    bits=32,
                    default=0,
                    encoding=uint(16),
                    short_description="PUS source ID",
                ),
            ],
            short_description="PUS-C telecommand of the M2 controller",
        )
        base_args = {a.name: a for a in base.arguments}
        base.entries = [
            FixedValueEntry("00", "ccsds_version", bits=3),
            FixedValueEntry("01", "ccsds_type_tc", bits=1),
            FixedValueEntry("01", "ccsds_sec_header", bits=1),
            ArgumentEntry(base_args["apid"]),
            FixedValueEntry("03", "ccsds_seq_flags", bits=2),
            FixedValueEntry("0000", "ccsds_seq_count", bits=14),
            FixedValueEntry("0000", "ccsds_length", bits=16),
            FixedValueEntry("%02x" % L["pus_version"], "pus_version", bits=4),
            ArgumentEntry(base_args["ack_flags"]),
            ArgumentEntry(base_args["service"]),
            ArgumentEntry(base_args["subtype"]),
            ArgumentEntry(base_args["source_id"]),
        ]
        stages = {v["name"]: v for v in self.mdb["verification"]}
        for tc in self.mdb["telecommands"]:
            entries = []
            args = []
            if tc["function_id"] is not None:
                entries.append(FixedValueEntry("%04x" % tc["function_id"], "function_id", bits=16))
            for f in tc["fields"]:
                if f["meaning"]["kind"] == "fixed":
                    bits = WIRE_BITS[f["wire"]["type"]]
                    entries.append(
                        FixedValueEntry(
                            "%0*x" % (bits // 4, f["meaning"]["value"]), f["name"], bits=bits
                        )
                    )
                else:
                    a = self.argument(f)
                    args.append(a)
                    entries.append(ArgumentEntry(a))
            cmd = Command(
                s,
                tc["name"],
                base=base,
                assignments={
                    "apid": L["apid"],
                    "service": tc["service"],
                    "subtype": tc["subtype"],
                },
                arguments=args,
                entries=entries,
                # Critical: Yamcs asks the operator to confirm, with the reason.
                level=CommandLevel.CRITICAL if tc.get("critical") else CommandLevel.NORMAL,
                warning_message=tc.get("critical"),
                # Sent only in the states the controller takes it in (Yamcs holds it
                # until housekeeping shows one, at most the timeout).
                constraint=self.constraint(tc.get("constraint")),
                short_description=f"TC[{tc['service']},{tc['subtype']}]"
                + (f" function 0x{tc['function_id']:04x}" if tc["function_id"] is not None else "")
                + f": {tc['description']}",
            )
            cmd.accepted_verifier = AcceptedVerifier(
                check=self.verifier_check(stages["Acceptance"]),
                timeout=10.0,
                name="Acceptance",
            )
            cmd.execution_verifiers.append(
                ExecutionVerifier(
                    check=self.verifier_check(stages["Start"]), timeout=10.0, name="Start"
                )
            )
            cmd.complete_verifiers.append(
                CompleteVerifier(
                    check=self.verifier_check(stages["Completion"]),
                    timeout=tc["completion_timeout_s"],
                    name="Completion",
                )
            )


def postprocess(xml: str, number_formats: dict[str, int]) -> str:
    """What pymdb does not write: one name per verifier algorithm (pymdb names them all
    "Unnamed"; Yamcs needs <command>_<stage>), and the number format (ToString/NumberFormat,
    XTCE 1.2) of each calibrated parameter: its description's fraction digits."""
    ns = "http://www.omg.org/spec/XTCE/20180204"
    ET.register_namespace("", ns)
    ET.register_namespace("xsi", "http://www.w3.org/2001/XMLSchema-instance")
    root = ET.fromstring(xml)
    q = lambda tag: f"{{{ns}}}{tag}"  # noqa: E731
    for mc in root.iter(q("MetaCommand")):
        for vs in mc.iter(q("VerifierSet")):
            for verifier in vs:
                for alg in verifier.iter(q("CustomAlgorithm")):
                    alg.set("name", f"{mc.get('name')}_{verifier.get('name')}")
    done = set()
    for t in root.iter(q("FloatParameterType")):
        digits = number_formats.get(t.get("name"))
        if digits is None:
            continue
        to_string = ET.Element(q("ToString"))
        ET.SubElement(to_string, q("NumberFormat"), {
            "minimumFractionDigits": str(digits), "maximumFractionDigits": str(digits)})
        # XTCE order: after the encoding, before ValidRange and the alarms.
        later = [i for i, c in enumerate(t)
                 if c.tag in (q("ValidRange"), q("DefaultAlarm"), q("ContextAlarmList"))]
        t.insert(later[0] if later else len(t), to_string)
        done.add(t.get("name"))
    missing = set(number_formats) - done
    if missing:
        raise ValueError(f"no float parameter type for the number formats of {sorted(missing)}")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode")


def main(argv: list[str]) -> int:
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    mdb = json.loads(Path(argv[1]).read_text())
    out = Path(argv[2])
    g = Generator(mdb)
    g.telemetry()
    g.link_health()
    g.derived()
    g.commands()
    missing = set(g.alarms) - g.alarmed
    if missing:
        raise ValueError(f"alarms of parameters that are not integers or enumerations: {sorted(missing)}")
    (out / "mdb").mkdir(parents=True, exist_ok=True)
    xml = g.system.dumps(
        top_comment="Generated by yamcs/tools/gen_xtce.py from m2ground mdb-json: do not edit."
    )
    (out / "mdb" / "m2.xml").write_text(postprocess(xml, g.number_formats))
    n_params = len(g.params)
    print(
        f"gen_xtce: {len(mdb['telecommands'])} commands, {len(mdb['telemetry'])} TM packets, "
        f"{n_params} parameters, {len(mdb['events'])} events -> {out}/mdb/m2.xml"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
