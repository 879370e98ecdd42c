#!/usr/bin/env bash
# Coverage-guided fuzzing (libFuzzer + AddressSanitizer, cargo-fuzz on nightly) of the
# three targets in fuzz/: the deframer + telecommand decoder, the table decoder +
# validation, and the controller on the bench with the soak's invariants as assertions.
#   scripts/fuzz.sh [seconds per target] [target ...]     (default 60 s, all three)
# The seed corpus (fuzz/seeds/<target>) stays untouched; the growing corpus lives in
# target/fuzz-corpus/<target>. Prints libFuzzer's final line (executions, coverage) per
# target; exits non-zero if a target finds a crash or an invariant violation.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(deframe_tc table_decode controller)
# Leak checking stays on, with one suppression: each bench's telemetry queue is leaked
# on purpose (fuzz/lsan.supp says why); the controller target builds one bench per input
# (25 KB each, about 40 MB over a 30 s run).
export LSAN_OPTIONS="suppressions=$PWD/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
# LTO and sanitizer coverage do not link together: fuzz builds go without LTO.
export CARGO_PROFILE_RELEASE_LTO=false
(cd fuzz && for t in "${targets[@]}"; do cargo +nightly fuzz build "$t"; done)
for t in "${targets[@]}"; do
  corpus=target/fuzz-corpus/$t
  mkdir -p "$corpus"
  log=target/fuzz-$t.log
  set +e
  (cd fuzz && cargo +nightly fuzz run "$t" "../$corpus" "seeds/$t" -- \
      -max_total_time="$secs" -print_final_stats=1 -rss_limit_mb=4096) > "$log" 2>&1
  rc=$?
  set -e
  stats=$(grep -E "^#[0-9]+.*(DONE|pulse|NEW|REDUCE)" "$log" | tail -1)
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  echo "fuzz $t: ${secs} s, ${execs:-?} executions; last status: ${stats}"
  if [ "$rc" -ne 0 ]; then
    echo "fuzz $t: FAILED (exit $rc), see $log" >&2
    grep -E "panicked|ERROR|SUMMARY" "$log" | head -5 >&2
    exit 1
  fi
done
