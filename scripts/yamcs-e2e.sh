#!/usr/bin/env bash
# End-to-end test of the ground segment, for CI (docs/ground-segment.md): brings up
# m2fw in QEMU, the gateway and Yamcs (scripts/ground-segment.sh), runs
# yamcs/tools/e2e.py through yamcs-client (ping, housekeeping with units and UTC time,
# a move in um/arcsec with every verifier stage, a refused move, a table upload/commit/
# activate, events with severities; every Yamcs-encoded TC byte-identical to m2ground
# tc's), then takes a headless Chromium screenshot of the Yamcs page with the
# housekeeping parameters (yamcs/tools/screenshot.py, Chromium over DevTools):
# target/ground-segment/yamcs-housekeeping.png.
# Needs scripts/setup.sh. About 1-2 minutes once built.
set -euo pipefail
cd "$(dirname "$0")/.."
exec scripts/ground-segment.sh -- bash -c '
set -euo pipefail
python3 yamcs/tools/e2e.py
id=$(cat "$M2_GROUND_DIR/plist_id")
python3 yamcs/tools/screenshot.py \
  "http://$M2_YAMCS_URL/telemetry/parameter-lists/$id/realtime?c=m2__realtime" \
  "$M2_GROUND_DIR/yamcs-housekeeping.png" --wait-s 12
'
