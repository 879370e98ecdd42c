#!/usr/bin/env bash
# Firmware figures on the emulated Cortex-M4F (mps2-an386): instruction counts of IK and
# of FK warm-started within 10 um (shared/tools/qemu-insncount), image sizes, stack peak.
# A benchmark, not a test: it prints figures. Run after scripts/qemu-selftest.sh or alone.
set -euo pipefail
cd "$(dirname "$0")/.."
ELF=target/thumbv7em-none-eabihf/release/m2selftest
TOOL=${QEMU_INSNCOUNT:-../shared/tools/qemu-insncount}
export DEFMT_LOG=${DEFMT_LOG:-info}
cargo build --release --target thumbv7em-none-eabihf --features firmware --bin m2selftest
# The tool's directory may be read-only: build the plugin in a scratch copy.
work=$(mktemp -d)
cp "$TOOL"/* "$work"/ && chmod -R u+w "$work"
"$work/build.sh" >/dev/null
out=$("$work/count.sh" "$ELF" 2>&1 >/dev/null | tr -cd '[:print:]\n' | grep -E "^(BENCH|TOTAL)" || true)
[ -n "$out" ] || out=$("$work/count.sh" "$ELF" 2>/dev/null | tr -cd '[:print:]\n' | grep -E "BENCH|TOTAL")
echo "$out"
empty=$(echo "$out" | awk -F'insns=' '/BENCH n=1 /{print $2}')
ik=$(echo "$out" | awk -F'insns=' '/BENCH n=2 /{print $2}')
fk=$(echo "$out" | awk -F'insns=' '/BENCH n=3 /{print $2}')
echo "IK (one pose, six strokes, all checks):        $((ik - empty)) instructions (goal <= 1000)"
echo "FK (warm start within 10 um, with residual):   $((fk - empty)) instructions (goal <= 8000)"
read -r text data bss _ < <(arm-none-eabi-size "$ELF" | tail -1)
echo "flash (text + data):                           $((text + data)) bytes (goal <= 65536)"
timeout 120 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none -serial none \
  -semihosting-config enable=on,target=native -kernel "$ELF" > "$work/run.bin" || true
stack=$(defmt-print -e "$ELF" < "$work/run.bin" | sed -n 's/.*STACK peak_bytes=\([0-9]*\).*/\1/p')
echo "RAM (data + bss + measured stack peak):        $((data + bss + stack)) bytes = $data + $bss + $stack (goal <= 16384)"
rm -rf "$work"
