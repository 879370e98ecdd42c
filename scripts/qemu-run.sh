#!/usr/bin/env bash
# Cargo runner for the thumbv7em-none-eabihf target (.cargo/config.toml): runs an ELF in
# QEMU mps2-an386 and decodes its defmt log. QEMU's exit code (the firmware's, through
# semihosting) is this script's.
#   cargo run --release --target thumbv7em-none-eabihf --features firmware --bin m2selftest
set -euo pipefail
elf=${1:?usage: qemu-run.sh ELF}
set +e
qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none -serial none \
  -semihosting-config enable=on,target=native -kernel "$elf" | defmt-print -e "$elf"
rc=${PIPESTATUS[0]}
exit "$rc"
