#!/usr/bin/env bash
# Host figures of the flight kinematics on x86: instructions per call of IK and FK, f32
# and f64, counted by valgrind's callgrind (exact and repeatable for the same binary).
# Inputs (src/bin/m2kinbench.rs): 1000 poses uniform in +-2 mm / +-600 arcsec, FK
# warm-started 10 um / 1 arcsec away. Callgrind collects only inside the non-inlined
# wrapper of the measured call (--toggle-collect), so setup and checks are not counted.
# A benchmark, not a test: it prints figures. Profiles stay in target/bench-host/ for
# callgrind_annotate.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --features host --bin m2kinbench
BIN=$PWD/target/release/m2kinbench
OUT=target/bench-host
mkdir -p "$OUT"
for b in ik-f32 ik-f64 fk-f32 fk-f64; do
  f="$OUT/callgrind.$b.out"
  fn="measured_${b/-/_}"
  log=$(valgrind --tool=callgrind --callgrind-out-file="$f" --toggle-collect="*::$fn" \
    "$BIN" "$b" 2>/dev/null)
  calls=$(echo "$log" | sed -n 's/.*calls=\([0-9]*\).*/\1/p')
  steps=$(echo "$log" | sed -n 's/.*steps=\([0-9]*\).*/\1/p')
  total=$(sed -n 's/^totals: *\([0-9]*\).*/\1/p' "$f")
  [ -n "$calls" ] && [ -n "$total" ] || { echo "bench-host: no figure for $b" >&2; exit 1; }
  per=$(awk -v t="$total" -v n="$calls" 'BEGIN { printf "%.1f", t / n }')
  extra=""
  [ -n "$steps" ] && extra=$(awk -v s="$steps" -v n="$calls" 'BEGIN { printf " (%.2f Newton steps per call)", s / n }')
  printf "%-7s %9s instructions per call over %s calls%s\n" "$b" "$per" "$calls" "$extra"
done
