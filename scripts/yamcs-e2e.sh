#!/usr/bin/env bash
# End-to-end test of the ground segment, for CI (docs/ground-segment.md): brings up
# m2fw in QEMU, the gateway and Yamcs (scripts/ground-segment.sh), runs
# yamcs/tools/e2e.py through yamcs-client (ping, housekeeping with units and UTC time,
# a move in um/arcsec with every verifier stage, a refused move, a table upload/commit/
# activate, events with severities, sources and named words, number formats, critical
# commands, transmission constraints (a command held during a move), alarms and the
# derived following error, users and roles: the observer refused (403), the operator not;
# every Yamcs-encoded TC byte-identical to m2ground tc's; the console as start-up left
# it: the parameter lists, the display and stack buckets, the table-upload stack run by
# Yamcs web in headless Chromium against the controller, the housekeeping display drawn
# with Yamcs' values: <target>/ground-segment/yamcs-{stack,display}.png), then takes
# headless Chromium screenshots of the Yamcs pages with the housekeeping parameter list
# and the events (yamcs/tools/screenshot.py, Chromium over DevTools; the events page must
# show its rows and no error): <target>/ground-segment/yamcs-{housekeeping,events}.png.
# Before: the work directory follows CARGO_TARGET_DIR. After: two more starts, the
# archive kept, then --clean, each with the parameter lists once
# (yamcs/tools/archive_check.py).
# Needs scripts/setup.sh. About 2-3 minutes once built.
set -euo pipefail
cd "$(dirname "$0")/.."
# The ground segment finds cargo's target directory wherever CARGO_TARGET_DIR puts it.
want=/tmp/m2-target-dir-check
got=$(CARGO_TARGET_DIR=$want scripts/ground-segment.sh --where)
if [ "$got" != "$want/ground-segment" ]; then
  echo "yamcs-e2e: FAIL ground-segment.sh with CARGO_TARGET_DIR=$want works in $got" >&2; exit 1
fi
echo "yamcs-e2e: ok ground-segment.sh with CARGO_TARGET_DIR=$want works in $got"
# A fresh archive for the test; afterwards two more starts: the archive is kept
# (the test's events are still there), and --clean empties it.
scripts/ground-segment.sh --clean -- bash -c '
set -euo pipefail
python3 yamcs/tools/e2e.py
id=$(cat "$M2_GROUND_DIR/plist_id")
python3 yamcs/tools/screenshot.py \
  "http://$M2_YAMCS_URL/telemetry/parameter-lists/$id/realtime?c=m2__realtime" \
  "$M2_GROUND_DIR/yamcs-housekeeping.png" --wait-s 12 --user observer
# The Events page of the web UI (Yamcs sorts events by source; an event without one
# broke the table): rows of the boot, no error banner.
python3 yamcs/tools/screenshot.py "http://$M2_YAMCS_URL/events?c=m2__realtime" \
  "$M2_GROUND_DIR/yamcs-events.png" --wait-s 10 --user observer \
  --expect BOOT_DETAIL --expect STATE_CHANGED --forbid localeCompare --forbid "Cannot read properties"
'
echo "yamcs-e2e: restart: the archive is kept"
scripts/ground-segment.sh -- python3 yamcs/tools/archive_check.py kept
echo "yamcs-e2e: restart with --clean"
scripts/ground-segment.sh --clean -- python3 yamcs/tools/archive_check.py clean
