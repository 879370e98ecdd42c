#!/usr/bin/env bash
# The whole ground segment on this machine (docs/ground-segment.md):
#   the flight image m2fw in QEMU (UART0 on a Unix socket)
#   <-> m2ground gateway (COBS frames <-> CCSDS packets, time correlation)
#   <-> Yamcs 5.12 (PyPI fprime-yamcs-bundle jars; web UI http://localhost:8090)
# with the mission database generated from m2ground mdb-json, and the operators' console:
# the housekeeping display and the command stacks served from yamcs/displays and
# yamcs/stacks, the parameter lists of yamcs/lists created at start-up.
#
#   scripts/ground-segment.sh                 # bring it up; Ctrl-C stops everything
#   scripts/ground-segment.sh --clean         # the same, after deleting the Yamcs archive
#   scripts/ground-segment.sh --where         # print the work directory and exit
#   scripts/ground-segment.sh [--clean] -- CMD ARGS...  # bring it up, run CMD, stop; CMD's exit code
#
# Needs scripts/setup.sh (QEMU, Python yamcs packages, Java 17). Work files, logs and
# the Yamcs archive are in <cargo target directory>/ground-segment/ (target/ unless
# CARGO_TARGET_DIR or the cargo configuration says otherwise); the archive is kept
# between starts (replay, history) unless --clean is given; the rest is regenerated.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
# Where cargo puts its binaries (CARGO_TARGET_DIR, .cargo/config.toml...): cargo knows.
TARGET=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
W=$TARGET/ground-segment
HTTP_PORT=${M2_YAMCS_HTTP_PORT:-8090}
LINK_PORT=${M2_YAMCS_LINK_PORT:-10015}
export DEFMT_LOG=${DEFMT_LOG:-info}

if [ "${1:-}" = "--where" ]; then echo "$W"; exit 0; fi   # the work directory, nothing started
cmd=()
clean=0
if [ "${1:-}" = "--clean" ]; then clean=1; shift; fi
if [ "${1:-}" = "--" ]; then shift; cmd=("$@"); fi
if [ $# -gt 0 ] && [ ${#cmd[@]} -eq 0 ]; then
  echo "usage: scripts/ground-segment.sh [--clean] [-- CMD ARGS...]" >&2
  exit 2
fi

for p in "$HTTP_PORT" "$LINK_PORT"; do
  if (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then
    echo "ground-segment: port $p is in use (another Yamcs or gateway?)" >&2
    exit 1
  fi
done

echo "ground-segment: building m2fw (QEMU) and m2ground"
cargo build --release --target thumbv7em-none-eabihf --features firmware --bin m2fw
cargo build --release --features host --bin m2ground
M2GROUND=$TARGET/release/m2ground
ELF=$TARGET/thumbv7em-none-eabihf/release/m2fw
LIB=$(python3 -c 'import fprime_yamcs_bundle, os; print(os.path.join(os.path.dirname(fprime_yamcs_bundle.__file__), "lib"))')
[ -f "$LIB/yamcs-core-5.12.8.jar" ] || { echo "ground-segment: Yamcs jars missing in $LIB (scripts/setup.sh)" >&2; exit 1; }

# The archive (yamcs/data) survives a restart; everything else is regenerated.
if [ "$clean" = 1 ]; then
  echo "ground-segment: --clean: deleting the Yamcs archive $W/yamcs/data"
  rm -rf "$W/yamcs/data"
fi
rm -rf "$W/yamcs/etc" "$W/yamcs/mdb" "$W/logs" "$W/uart.sock"
mkdir -p "$W/yamcs/etc" "$W/yamcs/data" "$W/logs"
echo "ground-segment: Yamcs archive $W/yamcs/data ($(du -sh "$W/yamcs/data" | cut -f1))"
cp "$ROOT"/yamcs/etc/* "$W/yamcs/etc/"
sed -i "s/port: 8090/port: $HTTP_PORT/" "$W/yamcs/etc/yamcs.yaml"
sed -i "s/port: 10015/port: $LINK_PORT/" "$W/yamcs/etc/yamcs.m2.yaml"
"$M2GROUND" mdb-json --out "$W/mdb.json"
python3 "$ROOT/yamcs/tools/gen_xtce.py" "$W/mdb.json" "$W/yamcs"
python3 -c '
import sys
from space_packet_parser.xtce.validation import validate_xtce
r = validate_xtce(sys.argv[1], level="schema", allow_schema_download=False, print_results=False, raise_on_error=False)
print("ground-segment: XTCE schema validation:", "valid" if r else "INVALID")
sys.exit(0 if r else 1)
' "$W/yamcs/mdb/m2.xml"

pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
}
trap cleanup EXIT
trap 'exit 130' INT TERM

SOCK=$W/uart.sock
# Guest time: 8 ns per instruction (125 M instructions per guest second: a control
# cycle's <= 20,000 instructions take <= 0.16 ms of its 1 ms, whatever the host's load;
# -icount shift=auto stretched instructions under load until cycles overran). While the
# guest idles its clock follows the host's (sleep=on), which paces the controller to
# UTC; a QEMU stalled for two watchdog windows (200 ms) would see them pass in one step
# and reset (docs/firmware.md, "Firmware in QEMU"), so QEMU runs at a higher scheduling priority
# where the user may set one.
prio=()
if [ "$(id -u)" -eq 0 ]; then prio=(nice -n -10); fi
"${prio[@]}" qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none -icount shift=3 \
  -semihosting-config enable=on,target=native \
  -chardev "socket,id=uart0,path=$SOCK,server=on,wait=on" -serial chardev:uart0 \
  -kernel "$ELF" > "$W/logs/qemu.log" 2>&1 &
pids+=($!)

# Yamcs' security is on (yamcs/etc/security.yaml): the gateway logs in as its own user
# (role Gateway: time correlation, events and its link-health parameters only), by
# HTTP Basic authentication.
GW_USER=$(python3 "$ROOT/yamcs/tools/users.py" gateway)
"$M2GROUND" gateway --uart "unix:$SOCK" --listen "127.0.0.1:$LINK_PORT" \
  --tco-url "http://$GW_USER@127.0.0.1:$HTTP_PORT/api/tco/m2/tco0/coefficients" \
  --events-url "http://$GW_USER@127.0.0.1:$HTTP_PORT/api/archive/m2/events" \
  --parameters-url "http://$GW_USER@127.0.0.1:$HTTP_PORT/api/processors/m2/realtime/parameters:batchSet" \
  --health-s 2 --stats-s 10 \
  > "$W/logs/gateway.log" 2>&1 &
pids+=($!)

# The console's displays and stacks are served from the repository (yamcs/etc/yamcs.yaml,
# buckets `displays` and `stacks`: ${env.M2_CONSOLE_DIR}/...).
(cd "$W/yamcs" && M2_CONSOLE_DIR="$ROOT/yamcs" exec java -cp "$LIB/*" org.yamcs.YamcsServer --etc-dir etc --data-dir data) \
  > "$W/logs/yamcs.log" 2>&1 &
pids+=($!)

echo "ground-segment: waiting for Yamcs and the link"
for _ in $(seq 1 120); do
  if python3 - "$HTTP_PORT" "$ROOT/yamcs/tools" <<'EOF' 2>/dev/null; then break; fi
import sys, json, urllib.request
sys.path.insert(0, sys.argv[2])
from users import basic_auth
req = urllib.request.Request(f"http://127.0.0.1:{sys.argv[1]}/api/links/m2",
                             headers={"Authorization": basic_auth("observer")})
links = json.load(urllib.request.urlopen(req, timeout=2))
sys.exit(0 if any(l.get("status") == "OK" and int(l.get("dataInCount", 0)) > 0 for l in links.get("links", [])) else 1)
EOF
  for p in "${pids[@]}"; do kill -0 "$p" 2>/dev/null || { echo "ground-segment: a process died; logs in $W/logs" >&2; tail -20 "$W"/logs/*.log >&2; exit 1; }; done
  sleep 1
done
# The console's parameter lists (yamcs/lists, generated from the mission database): created,
# or updated to the shipped definition, at every start (the archive keeps lists).
M2_YAMCS_URL="localhost:$HTTP_PORT" python3 "$ROOT/yamcs/tools/console.py" lists
echo "ground-segment: up. Yamcs web UI http://localhost:$HTTP_PORT (instance m2; users in yamcs/etc/users.yaml); logs in $W/logs"

if [ ${#cmd[@]} -gt 0 ]; then
  set +e
  M2_YAMCS_URL="localhost:$HTTP_PORT" M2_GROUND_DIR="$W" M2GROUND="$M2GROUND" "${cmd[@]}" &
  cmd_pid=$!
  pids+=("$cmd_pid")
  wait "$cmd_pid"
  rc=$?
  set -e
  echo "ground-segment: gateway: $(grep 'gateway: TM' "$W/logs/gateway.log" | tail -1 | sed 's/^gateway: //')"
  exit $rc
fi
echo "ground-segment: Ctrl-C to stop"
wait "${pids[0]}" || true
