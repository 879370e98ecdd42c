#!/usr/bin/env bash
# Builds the firmware, runs its self-test in QEMU (mps2-an386, Cortex-M4F), decodes the
# defmt log, and checks that the target's f32 results are bit-identical to the host's.
# Needs: rust target thumbv7em-none-eabihf, qemu-system-arm, defmt-print (see README).
# Exit status: non-zero if the build, the self-test or the comparison fails.
set -euo pipefail
cd "$(dirname "$0")/.."
ELF=target/thumbv7em-none-eabihf/release/m2selftest
LOG=target/m2selftest.log
export DEFMT_LOG=${DEFMT_LOG:-info}
cargo build --release --target thumbv7em-none-eabihf --features firmware --bin m2selftest
set +e
timeout 120 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none -serial none \
  -semihosting-config enable=on,target=native -kernel "$ELF" > target/m2selftest.bin
rc=$?
set -e
defmt-print -e "$ELF" < target/m2selftest.bin > "$LOG"
grep -E "SUMMARY|STACK|SELFTEST" "$LOG"
if [ "$rc" -ne 0 ]; then
  echo "qemu-selftest: firmware exited with $rc" >&2
  exit 1
fi
M2_FIRMWARE_LOG="$PWD/$LOG" cargo test --features host --test firmware -- --ignored --nocapture
