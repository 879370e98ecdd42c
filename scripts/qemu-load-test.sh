#!/usr/bin/env bash
# The QEMU tests once more with the host's CPUs oversubscribed (issue 18: the link
# contract must hold on a busy machine). stress-ng runs 2 CPU hogs per core (at least
# 4) while the flight image's link, operations and burst tests
# (host-tests/qemu_link.rs), its fault handling (host-tests/qemu_faults.rs) and the
# second board's link (host-tests/qemu_link_netduinoplus2.rs) run ROUNDS times (default
# 1). The guest runs on virtual time (-icount) and runs ahead of a host that does not
# read: every test selects telemetry by request ID and time stamp, so load may only
# make them slower, never fail them.
#   scripts/qemu-load-test.sh [ROUNDS]
# Builds the images first, without load (scripts/setup.sh installs stress-ng).
# Exit status: non-zero if any test run failed (each is run in every round; the
# pass counts are printed).
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=${1:-1}
F=target/thumbv7em-none-eabihf/flight
cargo build --profile flight --target thumbv7em-none-eabihf --features firmware,fault-test --bin m2fw
cp "$F/m2fw" target/m2fw-fault-test
cargo build --profile flight --target thumbv7em-none-eabihf --features firmware,board-netduinoplus2 --bin m2fw
cp "$F/m2fw" target/m2fw-netduinoplus2.elf
# Last: the flight image of mps2-an386 is the one tests find at $F/m2fw.
cargo build --profile flight --target thumbv7em-none-eabihf --features firmware --bin m2fw
tests=(qemu_link qemu_faults qemu_link_netduinoplus2)
cargo test --features host --no-run "${tests[@]/#/--test=}"

hogs=$(( 2 * $(nproc) ))
[ "$hogs" -ge 4 ] || hogs=4
# Bounded on its own too (an upper bound; it is stopped when the tests are done).
stress-ng --cpu "$hogs" --timeout $(( 600 * rounds ))s --quiet &
stress=$!
trap 'kill "$stress" 2>/dev/null || true; wait "$stress" 2>/dev/null || true' EXIT
sleep 1
echo "qemu-load-test: stress-ng --cpu $hogs on $(nproc) cores; load $(cut -d' ' -f1-3 /proc/loadavg)"

log=target/qemu-load-test.log
: > "$log"
failed=0
t0=$(date +%s)
for round in $(seq "$rounds"); do
  for t in "${tests[@]}"; do
    if ! cargo test --features host --test "$t" -- --ignored --nocapture 2>&1 | tee -a "$log"; then
      failed=$(( failed + 1 ))
      echo "qemu-load-test: round $round: $t FAILED" >&2
    fi
  done
done
echo
echo "qemu-load-test: under stress-ng --cpu $hogs, $rounds round(s) in $(( $(date +%s) - t0 )) s; load $(cut -d' ' -f1-3 /proc/loadavg)"
# Per test: runs passed of runs (the test binaries' own result lines).
grep -oE 'test [A-Za-z0-9_]+ \.\.\. (ok|FAILED)' "$log" | awk '
  { name = $2; runs[name]++; if ($NF == "ok") ok[name]++ }
  END { for (n in runs) printf "  %s: %d of %d passed\n", n, ok[n], runs[n] }' | sort
[ "$failed" -eq 0 ]
