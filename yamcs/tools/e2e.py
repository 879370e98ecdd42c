#!/usr/bin/env python3
"""End-to-end test of the ground segment through Yamcs (scripts/yamcs-e2e.sh runs it
inside scripts/ground-segment.sh): the flight image in QEMU, the gateway and Yamcs are
up; everything below goes through yamcs-client, as an operator's tool would.

Checks (each failure exits non-zero with the reason):
 1. ping completes, with the acceptance, start and completion stages in the command
    history; the packet Yamcs encoded is byte-identical to `m2ground tc ping`'s;
 2. housekeeping parameters update (new values every period) with their units;
 3. a move given in um/arcsec completes with every verifier stage, byte-identical to
    `m2ground tc move-absolute`, and the housekeeping pose (FK of the encoders) reaches the target;
 4. a refused move fails at the start stage with its failure code, and the refusal
    bits show decoded in housekeeping;
 5. a table uploaded as LOAD_TABLE_CHUNK commands (byte-identical to `m2ground tc
    upload`), committed and activated, is the active table in housekeeping;
 6. the controller's events are listed by Yamcs with their severities;
 7. TM time: the CUC 4+2 on-board time (seconds and fraction) turned into UTC by the
    time-correlation coefficients the gateway set, and received after generation;
 8. link health: the gateway's counters and time-correlation residual are Yamcs
    parameters with the values the gateway has, their alarms as described;
 9. security: the operator (this test's user) commands; the observer reads but its
    command is refused (HTTP 403) and reaches nothing; without a login nothing is served.
Prints the figures: commands sent, parameters seen, packets, timings.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from datetime import timezone
import urllib.error
import urllib.request
from pathlib import Path

from yamcs.client import YamcsClient, YamcsError

from users import basic_auth, credentials

ROOT = Path(__file__).resolve().parents[2]
URL = os.environ.get("M2_YAMCS_URL", "localhost:8090")
M2GROUND = os.environ.get("M2GROUND", str(ROOT / "target/release/m2ground"))
INSTANCE, PROCESSOR, NS = "m2", "realtime", "/M2/"
STAGES = ("Acceptance", "Start", "Completion")

failures: list[str] = []
passed = [0]
figures: dict[str, object] = {}


def check(ok: bool, what: str) -> bool:
    print(("  ok   " if ok else "  FAIL ") + what, flush=True)
    if ok:
        passed[0] += 1
    else:
        failures.append(what)
    return ok


def m2ground_packets(*args: str) -> list[bytes]:
    out = subprocess.run(
        [M2GROUND, "tc", "--unframed", *args], check=True, capture_output=True, text=True
    ).stdout
    return [bytes.fromhex(line) for line in out.split()]


# Packet fields read from the archived binary (ICD section 2): PUS service and subtype,
# the CUC 4+2 on-board time stamp, the request ID of a service-1 report.
TC_PACKET_ID = 0x1800 | 0x0B2  # TC, secondary header, APID 0x0B2


def pus_type(b: bytes) -> tuple[int, int]:
    return b[7], b[8]


def obt_of(b: bytes) -> int:
    """The packet's time stamp: raw CUC 4+2 on-board time (1/65536 s)."""
    return int.from_bytes(b[13:19], "big")


def request_id(seq: int) -> bytes:
    return TC_PACKET_ID.to_bytes(2, "big") + (0xC000 | (seq & 0x3FFF)).to_bytes(2, "big")


class Report:
    """One archived TM packet and the parameters Yamcs decoded from it (the parameter
    values with that packet's generation time), read when asked for."""

    def __init__(self, op: "Operator", packet):
        self.op, self.packet = op, packet
        self.obt = obt_of(packet.binary)
        self.generation_time = packet.generation_time
        self.reception_time = packet.reception_time

    def value(self, name: str, timeout=15.0):
        return self.op.wait(f"{name} of the packet at OBT {self.obt / 65536:.3f} s",
                            lambda: self.op.snapshot(self.generation_time).get(name), timeout)


class Operator:
    """An operator's tool on Yamcs. Telemetry is selected by request ID and on-board time
    stamp (the raw CUC time of the archived packets), never as the latest value Yamcs
    has: the controller in QEMU runs on its own clock, ahead of a loaded host."""

    def __init__(self):
        self.client = YamcsClient(URL, credentials=credentials("operator"))
        self.proc = self.client.get_processor(INSTANCE, PROCESSOR)
        self.conn = self.proc.create_command_connection()
        self.mdb = self.client.get_mdb(INSTANCE)
        self.archive = self.client.get_archive(INSTANCE)
        self.sent = 0
        self.stage_times: dict[str, list[float]] = {s: [] for s in STAGES}
        # Every parameter value of the controller, by its packet's generation time.
        self._lock = threading.Lock()
        self._values: dict = {}
        names = [p.qualified_name for p in self.mdb.list_parameters() if p.qualified_name.startswith(NS)]
        self.subscription = self.proc.create_parameter_subscription(
            names, on_data=self._on_data, send_from_cache=False)

    def _on_data(self, data):
        with self._lock:
            for pv in data.parameters:
                self._values.setdefault(pv.generation_time, {})[pv.name.rsplit("/", 1)[-1]] = pv

    def snapshot(self, generation_time) -> dict:
        with self._lock:
            return dict(self._values.get(generation_time, {}))

    @staticmethod
    def wait(what: str, find, timeout: float):
        """find() until it is not None; the wall clock only bounds the wait."""
        t0 = time.time()
        while True:
            found = find()
            if found is not None:
                return found
            if time.time() - t0 > timeout:
                raise TimeoutError(what)
            time.sleep(0.2)

    def packets(self, service: int, subtype: int) -> list:
        """Archived packets TM[service,subtype], in on-board time order."""
        out = [p for p in self.archive.list_packets() if pus_type(p.binary) == (service, subtype)]
        return sorted(out, key=lambda p: obt_of(p.binary))

    def report(self, seq: int, subtype: int, timeout=30.0) -> Report:
        """The TM[1,subtype] for the telecommand with sequence count `seq` (its request ID)."""
        rid = request_id(seq)
        return self.wait(f"TM[1,{subtype}] of TC seq {seq}", lambda: next(
            (Report(self, p) for p in self.packets(1, subtype) if p.binary[19:23] == rid), None), timeout)

    def answer(self, seq: int, service: int, subtype: int, timeout=30.0) -> Report:
        """A TM[service,subtype] that names request ID `seq` in its first four bytes."""
        rid = request_id(seq)
        return self.wait(f"TM[{service},{subtype}] of TC seq {seq}", lambda: next(
            (Report(self, p) for p in self.packets(service, subtype) if p.binary[19:23] == rid), None),
            timeout)

    def hk_after(self, obt: int, timeout=30.0) -> Report:
        """The first housekeeping report made after on-board time `obt` (raw CUC)."""
        return self.wait(f"housekeeping after OBT {obt / 65536:.3f} s", lambda: next(
            (Report(self, p) for p in self.packets(3, 25) if obt_of(p.binary) > obt), None), timeout)

    def hk_before(self, obt: int) -> Report:
        """The last housekeeping report made before on-board time `obt` (raw CUC)."""
        before = [p for p in self.packets(3, 25) if obt_of(p.binary) < obt]
        if not before:
            raise LookupError(f"no housekeeping before OBT {obt / 65536:.3f} s")
        return Report(self, before[-1])

    def newest_obt(self) -> int:
        """The newest time stamp archived: a lower bound of the controller's clock (for
        choosing a future release time, never for selecting what is checked)."""
        newest = itertools.islice(self.archive.list_packets(descending=True, page_size=50), 50)
        return max(obt_of(p.binary) for p in newest)

    def command(self, name: str, args=None, timeout=30.0):
        cmd = self.conn.issue(NS + name, args=args or {})
        self.sent += 1
        try:
            cmd.await_complete(timeout=timeout)
        except TimeoutError:
            pass
        return cmd

    def done(self, cmd, subtype=7) -> Report:
        """The service-1 report `subtype` (7: completion) of a command Yamcs issued."""
        return self.report(cmd.attributes.get("ccsds-seqcount"), subtype)

    def stages(self, cmd) -> dict[str, str]:
        acks = cmd.acknowledgments
        out = {}
        for s in STAGES:
            a = acks.get(s) or acks.get("Verifier_" + s)
            out[s] = a.status if a else "missing"
            if a and a.status == "OK" and a.time and cmd.generation_time:
                self.stage_times[s].append((a.time - cmd.generation_time).total_seconds())
        return out


def same_bytes(op: Operator, cmd, reference_args: list[str], index: int = 0) -> bool:
    seq = cmd.attributes.get("ccsds-seqcount")
    sent = cmd.attributes.get("binary")  # as the PUS post-processor sent it (seq, length, CRC)
    ours = m2ground_packets("--seq", str(seq - index), *reference_args)[index]
    return check(
        sent == ours,
        f"{cmd.name.split('/')[-1]}: Yamcs' packet == m2ground tc's ({len(ours)} bytes, seq {seq})",
    ) or print(f"       yamcs    {sent.hex() if sent else None}\n       m2ground {ours.hex()}")


def get_json(path: str, user: str = "operator"):
    """GET a Yamcs API path as `user` (yamcs/etc/users.yaml)."""
    req = urllib.request.Request(f"http://{URL}{path}", headers={"Authorization": basic_auth(user)})
    return json.load(urllib.request.urlopen(req, timeout=10))


def http_status(path: str, user: str | None, body: bytes | None = None) -> int:
    """The HTTP status of a request to Yamcs as `user` (None: no login)."""
    headers = {"Content-Type": "application/json"}
    if user:
        headers["Authorization"] = basic_auth(user)
    req = urllib.request.Request(f"http://{URL}{path}", data=body, headers=headers,
                                 method="POST" if body is not None else "GET")
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


def main() -> int:
    t_start = time.time()
    op = Operator()
    print("e2e: connected to Yamcs", URL)

    # 1. Ping.
    print("1. ping")
    cmd = op.command("PING")
    st = op.stages(cmd)
    check(cmd.is_success(), f"PING completed ({cmd.error or 'OK'})")
    check(all(v == "OK" for v in st.values()), f"PING verifier stages {st}")
    same_bytes(op, cmd, ["ping"])

    # 2. Housekeeping with units and correlated time: three consecutive reports (by
    # on-board time) made after the ping's completion.
    print("2. housekeeping")
    hk0 = op.hk_after(op.done(cmd).obt)
    hk1 = op.hk_after(hk0.obt)
    hk2 = op.hk_after(hk1.obt)
    c0, c1, c2 = (h.value("cycle_counter").eng_value for h in (hk0, hk1, hk2))
    check(c2 > c1 > c0, f"cycle counter updates every report ({c0}, {c1}, {c2})")
    period = (hk2.generation_time - hk1.generation_time).total_seconds()
    cycles = c2 - c1
    figures["housekeeping period (UTC s, cycles)"] = (round(period, 3), cycles)
    # 1 s of OBT; in UTC it is that times QEMU's guest/host rate (1.0 unloaded, up to
    # ~5 while Yamcs' JVM starts beside it on two cores): a check of units, not pacing.
    check(0.5 < period < 10.0, f"housekeeping every {period:.3f} s UTC ({cycles} control cycles)")
    units = {}
    for p in ("pose_fk_x", "pose_fk_rx", "encoder_leg1", "stroke_cmd_leg6"):
        info = op.mdb.get_parameter(NS + p)
        units[p] = info.units
    check(units["pose_fk_x"] == ["um"] and units["pose_fk_rx"] == ["arcsec"] and units["encoder_leg1"] == ["um"],
          f"units {units}")
    state = hk2.value("state")
    check(state.eng_value == "IDLE", f"state {state.eng_value} (raw {state.raw_value})")

    # 3. A move in um / arcsec; the first housekeeping made after its completion.
    print("3. move")
    target = {"x": 12.5, "y": -7.25, "z": 3.0, "rx": -3.25, "ry": 1.5, "rz": 2.0}
    t0 = time.time()
    cmd = op.command("MOVE_ABSOLUTE", target, timeout=120)
    move_s = time.time() - t0
    st = op.stages(cmd)
    check(cmd.is_success(), f"MOVE_ABSOLUTE completed in {move_s:.1f} s ({cmd.error or 'OK'})")
    check(all(v == "OK" for v in st.values()), f"MOVE_ABSOLUTE verifier stages {st}")
    same_bytes(op, cmd, ["move-absolute", "x=12.5", "y=-7.25", "z=3",
                         "rx=-3.25", "ry=1.5", "rz=2"])
    hk = op.hk_after(op.done(cmd).obt)
    errs = {}
    for axis, want in target.items():
        fk = hk.value("pose_fk_" + axis).eng_value
        cmdv = hk.value("pose_cmd_" + axis).eng_value
        errs[axis] = round(fk - want, 4)
        check(abs(cmdv - want) < 1e-6, f"commanded {axis} = {cmdv} (target {want})")
    figures["pose reached - target (um, arcsec)"] = errs
    check(all(abs(e) < 0.3 for e in errs.values()), f"housekeeping pose reaches the target: {errs}")
    check(hk.value("state").eng_value == "IDLE", "state IDLE after the move")

    # 4. A refused move: 5 mm is outside the +-2 mm workspace; the first housekeeping
    # made after its start failure report.
    print("4. refused move")
    cmd = op.command("MOVE_ABSOLUTE", {"x": 5000.0, "y": 0, "z": 0, "rx": 0, "ry": 0, "rz": 0})
    st = op.stages(cmd)
    check(cmd.is_failure(), f"refused move failed: {cmd.error}")
    check(st["Acceptance"] == "OK" and st["Start"] == "NOK", f"refused at the start stage: {st}")
    check("MOTION_TARGET_REFUSED" in (cmd.error or ""), "failure code MOTION_TARGET_REFUSED in the command history")
    hk = op.hk_after(op.done(cmd, subtype=4).obt)
    code = hk.value("last_failure_code").eng_value
    bits = {b: hk.value("refusal_bits_" + b).eng_value for b in
            ("x_outside_workspace", "y_outside_workspace", "non_finite", "leg1_above_max")}
    check(code == "MOTION_TARGET_REFUSED", f"housekeeping last failure code {code}")
    check(bits["x_outside_workspace"] is True and bits["y_outside_workspace"] is False
          and bits["non_finite"] is False,
          f"refusal bits decoded: {bits} (word 0x{hk.value('refusal_bits').raw_value:08x})")
    pose_after = hk.value("pose_cmd_x").eng_value
    check(abs(pose_after - 12.5) < 1e-6, "a refused move changes nothing (commanded x still 12.5 um)")

    # 5. Table upload, commit, activate.
    print("5. table upload")
    work = tempfile.TemporaryDirectory()
    geometry = Path(work.name) / "calibrated.toml"
    geometry.write_text((ROOT / "testdata/geometry.toml").read_text()
                        + "\n[limits]\nstroke_min_mm = -5.0\nstroke_max_mm = 5.0\n"
                        "translation_mm = 2.0\nrotation_arcsec = 600.0\n")
    upload_args = ["upload", str(geometry), "--table-id", "77", "--activate"]
    reference = m2ground_packets(*upload_args)
    chunks, commit, activate = reference[:-2], reference[-2], reference[-1]
    for i, p in enumerate(chunks):
        app = p[11:-2]
        offset = int.from_bytes(app[1:3], "big")
        n = int.from_bytes(app[3:5], "big")
        cmd = op.command("LOAD_TABLE_CHUNK", {"offset": offset, "data": app[5:5 + n]})
        check(cmd.is_success(), f"LOAD_TABLE_CHUNK offset {offset}, {n} bytes ({cmd.error or 'OK'})")
        same_bytes(op, cmd, upload_args, index=i)
    crc = int.from_bytes(commit[13:17], "big")
    cmd = op.command("COMMIT_TABLE", {"crc32": crc}, timeout=60)
    check(cmd.is_success(), f"COMMIT_TABLE crc32 0x{crc:08x} ({cmd.error or 'OK'})")
    same_bytes(op, cmd, upload_args, index=len(chunks))
    # Activate names the pending table: its ID and CRC-32.
    cmd = op.command("ACTIVATE_TABLE", {"table_id": 77, "crc32": crc}, timeout=60)
    check(cmd.is_success(), f"ACTIVATE_TABLE ({cmd.error or 'OK'})")
    same_bytes(op, cmd, upload_args, index=len(chunks) + 1)
    check(activate[13:21] == (77).to_bytes(4, "big") + crc.to_bytes(4, "big"),
          "the activate TC names table 77 and its CRC")
    hk = op.hk_after(op.done(cmd).obt)
    tid, tcrc = hk.value("active_table_id").eng_value, hk.value("active_table_crc32").eng_value
    check(tid == 77 and tcrc == crc, f"housekeeping: active table {tid}, CRC-32 0x{tcrc:08x}")
    bank = hk.value("active_bank").eng_value
    check(bank in ("BANK_A", "BANK_B"), f"active table in flash {bank}")

    # 5b. Operations: an on-board parameter (the pivot), a move check, a scheduled move.
    print("5b. operations")
    cmd = op.command("SET_PARAMETER", {"parameter_id": "PIVOT_Z", "value": 250_000_000}, timeout=60)
    check(cmd.is_success(), f"SET_PARAMETER PIVOT_Z = 250 mm ({cmd.error or 'OK'})")
    same_bytes(op, cmd, ["set-parameter", "parameter_id=PIVOT_Z", "value=250000000"])
    pivot = op.hk_after(op.done(cmd).obt).value("pivot_z").eng_value
    check(abs(pivot - 250_000.0) < 1e-6, f"housekeeping pivot_z = {pivot} um")
    cmd = op.command("REPORT_PARAMETER", {"parameter_id": "PIVOT_Z"})
    check(cmd.is_success(), f"REPORT_PARAMETER ({cmd.error or 'OK'})")
    cmd = op.command("CHECK_MOVE", {"x": 5000.0, "y": 0, "z": 0, "rx": 0, "ry": 0, "rz": 0})
    check(cmd.is_success(), f"CHECK_MOVE completed ({cmd.error or 'OK'})")
    # This check's TM[8,130] (its request ID), not the latest check_code.
    code = op.answer(cmd.attributes.get("ccsds-seqcount"), 8, 130).value("check_code").eng_value
    check(code == "MOTION_TARGET_REFUSED", f"TM[8,130] check_code {code} (nothing moved)")
    x = op.hk_after(op.done(cmd).obt).value("pose_cmd_x").eng_value
    check(abs(x - 12.5) < 1e-6, "the move check moved nothing")
    # A move released by the on-board schedule 3 s after the newest time stamp archived
    # (the controller's clock is at least that). Should the controller's clock have
    # passed it before the insert arrives (refused 0x0B02, nothing inserted), the
    # refusal's own time stamp is the next lower bound.
    inner_seq = 9000
    inner = m2ground_packets("--seq", str(inner_seq), "move-absolute", "x=-20", "y=5")[0]
    floor = op.newest_obt()
    for attempt in range(3):
        obt_s = floor / 65536 + 3.0
        cmd = op.command("SCHEDULE_INSERT_ACTIVITY", {
            "release_seconds": int(obt_s), "release_fraction": obt_s - int(obt_s), "telecommand": inner})
        if cmd.is_success() or attempt == 2:
            break
        refusal = op.done(cmd, subtype=4)
        if int.from_bytes(refusal.packet.binary[23:25], "big") != 0x0B02:
            break
        print(f"       insert refused 0x0B02 at OBT {refusal.obt / 65536:.3f} s (release {obt_s:.3f} s): again")
        floor = refusal.obt
    check(cmd.is_success(), f"SCHEDULE_INSERT_ACTIVITY at OBT {obt_s:.3f} s ({cmd.error or 'OK'})")
    # Released count: in the last housekeeping made before the insert was executed, and
    # in the first made after the released move's completion (its request ID).
    released0 = op.hk_before(op.done(cmd, subtype=1).obt).value("schedule_released").eng_value
    accepted = op.report(inner_seq, 1, timeout=90)
    arrived = op.report(inner_seq, 7, timeout=90)
    check(obt_s <= accepted.obt / 65536 < obt_s + 0.002,
          f"the activity ran at OBT {accepted.obt / 65536:.4f} s (release {obt_s:.4f} s)")
    hk = op.hk_after(arrived.obt)
    check(hk.value("schedule_released").eng_value == released0 + 1,
          f"housekeeping: one activity released (release OBT {obt_s:.3f} s, HK at OBT {hk.obt / 65536:.3f} s)")
    x = hk.value("pose_cmd_op_x").eng_value
    check(abs(x + 20.0) < 0.01, f"the released move arrived: commanded x (operator frames) {x} um")

    # 6. Events with severities: listed once Yamcs has archived the ones this run made
    # (the wall clock only bounds the wait).
    print("6. events")
    mdb_json = json.loads(subprocess.run(
        [M2GROUND, "mdb-json"], check=True, capture_output=True, text=True).stdout)
    names = {e["name"] for e in mdb_json["events"]}
    states = {label for _, label, _ in next(e for e in mdb_json["enums"] if e["name"] == "controller_state")["values"]}
    expected = {"BOOT", "BOOT_DETAIL", "STATE_CHANGED", "MOVE_REFUSED", "PARAMETERS_CHANGED",
                "ACTIVITY_RELEASED", "TABLE_COMMITTED", "TABLE_ACTIVATED"}

    def archived_events():
        ev = [e for e in op.client.get_archive(INSTANCE).list_events() if e.event_type in names]
        return ev if expected <= {e.event_type for e in ev} else None
    try:
        events = op.wait("the run's events archived", archived_events, 30.0)
    except TimeoutError:
        events = [e for e in op.client.get_archive(INSTANCE).list_events() if e.event_type in names]
    seen = {}
    for e in events:
        seen.setdefault(e.event_type, set()).add(e.severity)
    for e in events[-12:]:
        print(f"       {e.generation_time.astimezone(timezone.utc):%H:%M:%S.%f} {e.severity:8s} {e.event_type:16s} {e.message}")
    check(seen.get("BOOT") == {"INFO"}, f"BOOT event INFO: {seen.get('BOOT')}")
    details = [e.message for e in events if e.event_type == "BOOT_DETAIL"]
    check(len(details) == 1, f"one boot during the test (no reset): {details}")
    check(seen.get("STATE_CHANGED") == {"INFO"}, f"STATE_CHANGED INFO: {seen.get('STATE_CHANGED')}")
    check(seen.get("MOVE_REFUSED") == {"WATCH"}, f"MOVE_REFUSED WATCH (PUS low severity): {seen.get('MOVE_REFUSED')}")
    check(seen.get("PARAMETERS_CHANGED") == {"INFO"}, f"PARAMETERS_CHANGED INFO: {seen.get('PARAMETERS_CHANGED')}")
    check(seen.get("ACTIVITY_RELEASED") == {"INFO"}, f"ACTIVITY_RELEASED INFO: {seen.get('ACTIVITY_RELEASED')}")
    check("TABLE_COMMITTED" in seen and "TABLE_ACTIVATED" in seen, "table committed and activated events")
    # Every event has a source (the web UI's event table sorts by it), and the texts name
    # states, refusal bits and failure codes (the gateway posts them, named by the MDB).
    every = list(op.client.get_archive(INSTANCE).list_events())
    sourceless = [e.event_type for e in every if not e.source]
    check(bool(every) and not sourceless,
          f"every event has a source ({len(every)} events, sources {sorted({e.source for e in every})}; "
          f"without: {sourceless})")
    changes = [e.message for e in events if e.event_type == "STATE_CHANGED"]
    named = [m for m in changes if m.startswith("controller state ")
             and {x.strip() for x in m[len("controller state "):].split("->")} <= states]
    check(bool(changes) and named == changes, f"STATE_CHANGED texts name the states: {changes[:3]}")
    refused = [e.message for e in events if e.event_type == "MOVE_REFUSED"]
    check(bool(refused) and all("X_OUTSIDE_WORKSPACE" in m and "MOTION_TARGET_REFUSED" in m for m in refused),
          f"MOVE_REFUSED text names the refusal bit and the failure code: {refused}")
    figures["events (type: severities)"] = {k: sorted(v) for k, v in sorted(seen.items())}

    # 6b. The MDB as Yamcs serves it: number formats and critical commands.
    print("6b. number formats, significance")

    def api(path):
        return get_json(f"/api/mdb/{INSTANCE}/{path}")
    formats, wrong = 0, []
    for pkt in mdb_json["telemetry"]:
        for f in pkt["fields"]:
            if f.get("fraction_digits") is None:
                continue
            nf = api("parameters/M2/" + f["name"]).get("type", {}).get("numberFormat", {})
            formats += 1
            if (nf.get("minimumFractionDigits"), nf.get("maximumFractionDigits")) != (f["fraction_digits"],) * 2:
                wrong.append((f["name"], f["fraction_digits"], nf))
    check(formats > 20 and not wrong,
          f"{formats} calibrated parameters carry their number format in Yamcs "
          f"(pose_fk_x: {api('parameters/M2/pose_fk_x')['type'].get('numberFormat')}); wrong: {wrong[:3]}")
    sig, wrong = {}, []
    for tc in mdb_json["telecommands"]:
        got = api("commands/M2/" + tc["name"]).get("significance", {})
        level = got.get("consequenceLevel", "NONE")
        if tc.get("critical"):
            sig[tc["name"]] = level
            if level != "CRITICAL" or got.get("reasonForWarning") != tc["critical"]:
                wrong.append((tc["name"], got))
        elif level not in ("NONE", "NORMAL"):
            wrong.append((tc["name"], got))
    check(len(sig) >= 6 and not wrong, f"critical commands in Yamcs: {sig}; wrong: {wrong[:3]}")

    # 6c. Alarms: the description's alarms as Yamcs serves them; none on the state while
    # IDLE; a telecommand the link refuses raises tc_rejected's alarm.
    print("6c. alarms")
    defined, wrong = [], []
    for a in mdb_json["alarms"]:
        got = api("parameters/M2/" + a["parameter"]).get("type", {}).get("defaultAlarm", {})
        rule = a["rule"]
        if rule["kind"] == "states":
            have = {(e.get("label"), e.get("level")) for e in got.get("enumerationAlarms", [])}
            ok = {tuple(x) for x in rule["levels"]} <= have
        else:
            have = [(r.get("level"), r.get("maxInclusive")) for r in got.get("staticAlarmRanges", [])]
            ok = (rule["level"], rule["limit"]) in have
        (defined if ok else wrong).append((a["parameter"], have))
    check(len(defined) == len(mdb_json["alarms"]) >= 7 and not wrong,
          f"{len(defined)} alarms defined in Yamcs (state: {dict(defined).get('state')}); wrong: {wrong}")

    def active_alarms():
        body = get_json(f"/api/processors/{INSTANCE}/{PROCESSOR}/alarms")
        return {a["id"]["name"].rsplit("/", 1)[-1]: a for a in body.get("alarms", [])}
    hk = op.hk_after(op.newest_obt())
    check(hk.value("state").eng_value == "IDLE" and "state" not in active_alarms(),
          f"no alarm on the state while IDLE (active: {sorted(active_alarms())})")
    # A chunk that would end past the table: the link refuses it (acceptance fails).
    cmd = op.command("LOAD_TABLE_CHUNK", {"offset": 515, "data": bytes(4)})
    check(op.stages(cmd)["Acceptance"] == "NOK", f"chunk past the table refused at acceptance ({cmd.error})")
    rejected = op.hk_after(op.done(cmd, subtype=2).obt).value("tc_rejected").eng_value
    try:
        alarm = op.wait("tc_rejected's alarm", lambda: active_alarms().get("tc_rejected"), 15.0)
    except TimeoutError:
        alarm = None
    check(rejected > 0 and alarm is not None and alarm.get("severity") == "WATCH",
          f"tc_rejected = {rejected} raises a WATCH alarm: {alarm and {k: alarm.get(k) for k in ('severity', 'type', 'violations')}}")
    figures["active alarms"] = {k: v.get("severity") for k, v in active_alarms().items()}

    # 7. Time: CUC 4+2 decoded and correlated to UTC (checked last, when the QEMU
    # controller's clock has settled).
    print("7. time")
    tco_client = op.client.get_tco_client(INSTANCE, "tco0")
    # Packets with a non-zero CUC fraction (housekeeping comes on whole seconds): a
    # ping's own reports (its request ID). Those received since the coefficients in
    # force were set were stamped with them (the gateway sets coefficients before it
    # forwards a packet).
    checked = []
    for _ in range(5):
        cmd = op.command("PING")
        seq = cmd.attributes.get("ccsds-seqcount")
        reports = [op.report(seq, sub) for sub in (1, 3, 7)]
        st = tco_client.get_status()
        c = st.coefficients
        if c is None or st.coefficients_time is None:
            continue
        for r in reports:
            if r.reception_time < st.coefficients_time:
                continue
            raw = r.obt
            if raw & 0xFFFF == 0:
                continue
            want = c.utc.timestamp() + c.gradient * (raw - c.obt) + (c.offset or 0.0)
            checked.append((r.generation_time.timestamp() - want, raw))
        if checked:
            figures["time correlation (gradient s/count, UTC s per OBT s)"] = (
                c.gradient, round(c.gradient * 65536, 4))
            break
    if check(bool(checked), f"{len(checked)} packets with a CUC fraction stamped by the coefficients in force"):
        worst = max(abs(e) for e, _ in checked)
        raw = checked[0][1]
        check(worst <= 0.0011, f"generation time = UTC(OBT) by the coefficients within {worst * 1e3:.2f} ms, "
              f"e.g. OBT 0x{raw:012x} = {raw >> 16} s + {raw & 0xFFFF}/65536 s (CUC 4+2 decoded)")
    # Four consecutive housekeeping reports (by on-board time) after that ping.
    lags = []
    last = op.hk_after(op.done(cmd).obt)
    for _ in range(4):
        last = op.hk_after(last.obt)
        lags.append((last.reception_time - last.generation_time).total_seconds())
    figures["reception - generation of 4 reports (ms)"] = [round(x * 1e3, 1) for x in lags]
    med = sorted(lags)[len(lags) // 2]
    # The exact property is checked above (generation time = UTC(OBT) by the
    # coefficients). The lag itself depends on how fast QEMU emulates on this host
    # (0.2-1.2 s seen under load; the gateway publishes it as link_tco_residual, step 8),
    # so only a gross correlation error (a wrong epoch or second) fails here.
    check(-5.0 <= med <= 5.0, f"TM time correlated to UTC: reports received {med * 1e3:.1f} ms (median) after generation (bound +-5 s: QEMU's clock follows host load)")

    # 8. Link health: the gateway's counters as local parameters (it sets them every 2 s
    # through Yamcs' API), with the description's alarms.
    print("8. link health")
    health = {p["name"]: p for p in mdb_json["link_health"]}

    def health_values():
        out = {}
        for name in health:
            try:
                v = get_json(f"/api/processors/{INSTANCE}/{PROCESSOR}/parameters/M2/{name}")
            except urllib.error.HTTPError:
                return None
            if "engValue" not in v:
                return None
            ev = v["engValue"]
            out[name] = (float(ev.get("uint64Value", ev.get("doubleValue", "nan"))), v)
        return out
    link_info = op.client.get_link(INSTANCE, "m2-gateway").get_info()

    def settled():
        # Values published after the last TC went out (the gateway's TC count is the link's).
        vals = health_values()
        return vals if vals and vals["link_tc_packets"][0] == link_info.out_count else None
    try:
        vals = op.wait("link health with the link's TC count", settled, 20.0)
    except TimeoutError:
        vals = health_values() or {}
    shown = {k: v[0] for k, v in vals.items()}
    figures["link health"] = shown
    check(len(vals) == len(health) >= 8,
          f"{len(vals)} link-health parameters with values in Yamcs: {shown}")
    check(shown.get("link_tc_packets") == link_info.out_count and shown.get("link_tm_packets", 0) > 0,
          f"gateway TC packets {shown.get('link_tc_packets')} = the link's TC out {link_info.out_count}; "
          f"TM packets {shown.get('link_tm_packets')}")
    errors = ("link_tm_bad_frames", "link_tm_backlog_dropped", "link_tc_refused", "link_events_lost")
    # The residual is >= 0 but for the 5 ms the gateway lets its line lag
    # (gateway::CORRELATION_TOLERANCE_S) before it corrects it.
    check(all(shown.get(e) == 0 for e in errors) and -5.0 <= shown.get("link_tco_residual", -99) < 60_000,
          f"no link errors, time-correlation residual {shown.get('link_tco_residual')} ms")
    defined, wrong = [], []
    for name, p in health.items():
        if p["alarm"] is None:
            continue
        got = api("parameters/M2/" + name).get("type", {}).get("defaultAlarm", {})
        have = [(r.get("level"), r.get("maxInclusive")) for r in got.get("staticAlarmRanges", [])]
        ok = (p["alarm"]["level"], p["alarm"]["limit"]) in have
        (defined if ok else wrong).append((name, have))
    check(len(defined) >= 5 and not wrong, f"link-health alarms in Yamcs: {defined}; wrong: {wrong}")
    # The alarm works on these parameters: a bad frame (set by the operator, who may
    # write local parameters) raises link_tm_bad_frames' WARNING; the gateway's next
    # publication puts the real count back.
    req = urllib.request.Request(
        f"http://{URL}/api/processors/{INSTANCE}/{PROCESSOR}/parameters/M2/link_tm_bad_frames",
        data=json.dumps({"type": "UINT64", "uint64Value": "1"}).encode(),
        headers={"Content-Type": "application/json", "Authorization": basic_auth("operator")}, method="PUT")
    urllib.request.urlopen(req, timeout=10)
    try:
        alarm = op.wait("link_tm_bad_frames' alarm", lambda: active_alarms().get("link_tm_bad_frames"), 15.0)
    except TimeoutError:
        alarm = None
    check(alarm is not None and alarm.get("severity") == "WARNING",
          f"link_tm_bad_frames = 1 raises a WARNING alarm: {alarm and alarm.get('severity')}")
    try:
        back = op.wait("the gateway's count back", lambda: (lambda v: v if v and v["link_tm_bad_frames"][0] == 0 else None)(health_values()), 15.0)
    except TimeoutError:
        back = None
    check(back is not None, "the gateway's next publication sets link_tm_bad_frames back to its count, 0")
    # Writing them is the gateway's (and the operator's) right, not the observer's.
    req = urllib.request.Request(
        f"http://{URL}/api/processors/{INSTANCE}/{PROCESSOR}/parameters/M2/link_tm_bad_frames",
        data=json.dumps({"type": "UINT64", "uint64Value": "0"}).encode(),
        headers={"Content-Type": "application/json", "Authorization": basic_auth("observer")}, method="PUT")
    try:
        urllib.request.urlopen(req, timeout=10)
        code = 200
    except urllib.error.HTTPError as e:
        code = e.code
    check(code == 403, f"the observer cannot set a link-health parameter: HTTP {code}")

    # 9. Security (yamcs/etc/security.yaml, roles.yaml, users.yaml): this test logs in as
    # the operator, whose commands went through above. The observer reads but cannot
    # command: refused with 403, and nothing reaches the controller; without a login
    # Yamcs serves nothing.
    print("9. security")
    me = get_json("/api/user")
    check(me.get("name") == "operator" and not me.get("superuser"),
          f"this test is the operator (not a superuser): {me.get('name')}, roles {me.get('roles')}")
    observer = YamcsClient(URL, credentials=credentials("observer"))
    obs_proc = observer.get_processor(INSTANCE, PROCESSOR)
    seen_by_observer = obs_proc.get_parameter_value(NS + "cycle_counter")
    check(seen_by_observer is not None and get_json(f"/api/links/{INSTANCE}", "observer").get("links"),
          f"the observer reads telemetry (cycle_counter {seen_by_observer and seen_by_observer.eng_value}) and links")
    tc_before = op.client.get_link(INSTANCE, "m2-gateway").get_info().out_count
    status = http_status(f"/api/processors/{INSTANCE}/{PROCESSOR}/commands{NS}PING", "observer", b"{}")
    try:
        obs_proc.issue_command(NS + "PING")
        refused = "not refused"
    except YamcsError as e:  # yamcs-client: "403 Client Error: ..."
        refused = f"{type(e).__name__}: {e}"
    check(status == 403 and refused.startswith("YamcsError: 403"),
          f"the observer's PING is refused: HTTP {status}; yamcs-client {refused}")
    cmd = op.command("PING")
    tc_after = op.client.get_link(INSTANCE, "m2-gateway").get_info().out_count
    check(cmd.is_success() and tc_after == tc_before + 1,
          f"the operator's PING goes through ({cmd.error or 'OK'}); link TC {tc_before} -> {tc_after}: "
          "one, the operator's, none of the observer's")
    anon = {p: http_status(p, None) for p in (f"/api/links/{INSTANCE}", f"/api/mdb/{INSTANCE}/parameters")}
    anon_cmd = http_status(f"/api/processors/{INSTANCE}/{PROCESSOR}/commands{NS}PING", None, b"{}")
    check(set(anon.values()) == {401} and anon_cmd == 401,
          f"without a login: reads {anon}, command {anon_cmd} (401)")
    figures["security (observer command, anonymous)"] = (status, anon_cmd)

    # A parameter list of the housekeeping for the web UI (and its screenshot).
    body = json.dumps({
        "name": "M2 housekeeping",
        "description": "Pose from FK, commanded pose, encoders, state, table, flags",
        "patterns": ["/M2/state", "/M2/pose_fk_*", "/M2/pose_cmd_*", "/M2/encoder_leg*",
                     "/M2/active_table_*", "/M2/last_failure_code", "/M2/refusal_bits",
                     "/M2/refusal_bits_x_outside_workspace", "/M2/fault_flags", "/M2/cycle_counter",
                     "/M2/tc_accepted", "/M2/tc_rejected"],
    }).encode()
    req = urllib.request.Request(f"http://{URL}/api/parameter-lists/{INSTANCE}/lists", data=body,
                                 headers={"Content-Type": "application/json",
                                          "Authorization": basic_auth("operator")}, method="POST")
    info = json.load(urllib.request.urlopen(req, timeout=10))
    out_dir = Path(os.environ.get("M2_GROUND_DIR", "."))
    (out_dir / "plist_id").write_text(info["id"])
    check(bool(info.get("id")), f"parameter list for the web UI: {info['id']}")

    # Figures.
    links = {l.name: l for l in op.client.list_links(INSTANCE)}
    link = links.get("m2-gateway")
    params = list(op.mdb.list_parameters())
    with_values = 0
    for p in params:
        v = op.proc.get_parameter_value(p.qualified_name)
        with_values += v is not None
    packets = sum(1 for _ in op.client.get_archive(INSTANCE).list_packets())
    figures["commands sent through Yamcs"] = op.sent
    figures["parameters in the MDB / with a value"] = (len(params), with_values)
    figures["TM packets in / TC packets out (link)"] = (link.in_count, link.out_count) if link else None
    figures["TM packets archived"] = packets
    figures["events archived"] = len(events)
    for s in STAGES:
        t = op.stage_times[s]
        if t:
            figures[f"{s} after release (s): min/median/max"] = (
                round(min(t), 3), round(sorted(t)[len(t) // 2], 3), round(max(t), 3))
    figures["wall time (s)"] = round(time.time() - t_start, 1)
    print("e2e figures:")
    for k, v in figures.items():
        print(f"  {k}: {v}")
    print(f"e2e: {passed[0]} passed, {len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
