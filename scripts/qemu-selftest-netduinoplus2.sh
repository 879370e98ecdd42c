#!/usr/bin/env bash
# The kinematics self-test on the second board: builds m2selftest for the STM32F405
# Netduino Plus 2 (feature board-netduinoplus2, memory/netduinoplus2.x), runs it in QEMU's
# netduinoplus2 machine (Cortex-M4F, semihosting + defmt), decodes the log, and checks
# that the target's f32 results are bit-identical to the host's (host-tests/firmware.rs).
# Needs what scripts/qemu-selftest.sh needs (scripts/setup.sh installs it).
# Exit status: non-zero if the build, the self-test or the comparison fails.
set -euo pipefail
cd "$(dirname "$0")/.."
ELF=target/thumbv7em-none-eabihf/release/m2selftest
LOG=target/m2selftest-netduinoplus2.log
export DEFMT_LOG=${DEFMT_LOG:-info}
cargo build --release --target thumbv7em-none-eabihf --features board-netduinoplus2 --bin m2selftest
cp "$ELF" target/m2selftest-netduinoplus2.elf
ELF=target/m2selftest-netduinoplus2.elf
set +e
timeout 120 qemu-system-arm -machine netduinoplus2 -nographic -monitor none -serial none \
  -semihosting-config enable=on,target=native -kernel "$ELF" > target/m2selftest-netduinoplus2.bin
rc=$?
set -e
defmt-print -e "$ELF" < target/m2selftest-netduinoplus2.bin > "$LOG"
grep -E "SUMMARY|STACK|SELFTEST" "$LOG"
if [ "$rc" -ne 0 ]; then
  echo "qemu-selftest-netduinoplus2: firmware exited with $rc" >&2
  exit 1
fi
M2_FIRMWARE_LOG="$PWD/$LOG" cargo test --features host --test firmware -- --ignored --nocapture
