#!/usr/bin/env python3
"""The Yamcs archive across starts of scripts/ground-segment.sh (scripts/yamcs-e2e.sh
runs it in a second and a third start after the end-to-end test):

    python3 yamcs/tools/archive_check.py kept    # the earlier run's events are still there
    python3 yamcs/tools/archive_check.py clean   # after --clean: only this start's

Waits (the wall clock only bounds it) for this start's BOOT event, then counts.
"""

from __future__ import annotations

import os
import sys
import time

from yamcs.client import YamcsClient

from users import credentials

URL = os.environ.get("M2_YAMCS_URL", "localhost:8090")


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
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
