#!/usr/bin/env python3
"""The Yamcs archive across starts of scripts/ground-segment.sh (scripts/yamcs-e2e.sh
runs it in a second and a third start after the end-to-end test):

    python3 yamcs/tools/archive_check.py kept    # the earlier run's events are still there
    python3 yamcs/tools/archive_check.py clean   # after --clean: only this start's

Waits (the wall clock only bounds it) for this start's BOOT event, then counts. In
both, the parameter lists of yamcs/lists are there once each with their shipped
patterns (scripts/ground-segment.sh creates or updates them at every start: the
end-to-end test changed one, which the plain start must have put back); the list the
end-to-end test made as an operator's own is still there after the plain start
(start-up leaves other lists alone) and gone after --clean.
"""

from __future__ import annotations

import os
import sys
import time

from yamcs.client import YamcsClient

from console import shipped_lists, yamcs_lists
from users import credentials

URL = os.environ.get("M2_YAMCS_URL", "localhost:8090")
# A list the end-to-end test (yamcs/tools/e2e.py, point 10) creates as an operator would.
OWN_LIST = {"name": "e2e: an operator's own list", "description": "made by yamcs/tools/e2e.py",
            "patterns": ["/M2/state", "/M2/cycle_counter"]}


def main() -> int:
    mode = sys.argv[1] if len(sys.argv) == 2 else ""
    if mode not in ("kept", "clean"):
        print(__doc__, file=sys.stderr)
        return 2
    archive = YamcsClient(URL, credentials=credentials("observer")).get_archive("m2")
    want_boots = 2 if mode == "kept" else 1
    t0 = time.time()
    while True:
        events = list(archive.list_events())
        boots = [e for e in events if e.event_type == "BOOT"]
        if len(boots) >= want_boots or time.time() - t0 > 60:
            break
        time.sleep(1)
    refused = [e for e in events if e.event_type == "MOVE_REFUSED"]
    if mode == "kept":
        ok = len(boots) >= 2 and len(refused) >= 1
        what = "the archive kept the earlier run"
    else:
        ok = len(boots) == 1 and not refused
        what = "--clean started from an empty archive"
    print(f"  {'ok  ' if ok else 'FAIL'} {what}: {len(events)} events, {len(boots)} BOOT, "
          f"{len(refused)} MOVE_REFUSED")
    have: dict[str, list] = {}
    for l in yamcs_lists("observer"):
        have.setdefault(l["name"], []).append(l.get("patterns"))
    shipped = shipped_lists()
    wrong = [w["name"] for w in shipped if have.get(w["name"]) != [w["patterns"]]]
    lists_ok = bool(shipped) and not wrong
    print(f"  {'ok  ' if lists_ok else 'FAIL'} the {len(shipped)} parameter lists of yamcs/lists "
          f"are there once each after a {'plain' if mode == 'kept' else '--clean'} start; "
          f"wrong or missing: {wrong}")
    own = have.get(OWN_LIST["name"], [])
    own_ok = own == [OWN_LIST["patterns"]] if mode == "kept" else not own
    print(f"  {'ok  ' if own_ok else 'FAIL'} the operator's own list "
          f"{'kept as it was' if mode == 'kept' else 'gone with the archive'}: {own}")
    return 0 if ok and lists_ok and own_ok else 1


if __name__ == "__main__":
    sys.exit(main())
