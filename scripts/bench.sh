#!/usr/bin/env bash
# Firmware figures on the emulated Cortex-M4F (mps2-an386), measured with the project's
# own instruction counter (tools/qemu-insncount, a QEMU TCG plugin built here with gcc):
# IK, FK warm-started within 10 um, whole control cycles, image sizes and stack peaks.
# A benchmark, not a test: it prints figures. Needs only the clone and scripts/setup.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
D=target/thumbv7em-none-eabihf/release
export DEFMT_LOG=${DEFMT_LOG:-info}
cargo build --release --target thumbv7em-none-eabihf --features firmware --bins
plugin=$(tools/qemu-insncount/build.sh)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
qemu() {
  timeout 120 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none -serial none \
    -semihosting-config enable=on,target=native -kernel "$@"
}
# Exact instruction counts between bench_start() and bench_end() of an ELF:
# "BENCH n=<k> insns=<count>" per marker pair, then "TOTAL insns=<n>".
count() {
  local s e
  s=$(arm-none-eabi-nm "$1" | awk '$3=="bench_start"{print "0x"$1}')
  e=$(arm-none-eabi-nm "$1" | awk '$3=="bench_end"{print "0x"$1}')
  [ -n "$s" ] && [ -n "$e" ] || { echo "bench: bench_start/bench_end not found in $1" >&2; exit 2; }
  rm -f "$work/insns.log"
  qemu "$1" -plugin "$plugin,start=$s,end=$e" -d plugin -D "$work/insns.log" > /dev/null 2> "$work/qemu.err" || true
  grep -qE "^TOTAL" "$work/insns.log" 2>/dev/null || { echo "bench: no count from $1:" >&2; cat "$work/qemu.err" >&2; exit 1; }
  grep -E "^(BENCH|TOTAL)" "$work/insns.log"
}
pick() { echo "$1" | awk -F'insns=' -v k="$2" '$0 ~ "BENCH n="k" " {print $2}'; }
run_log() {
  qemu "$1" > "$work/run.bin" || true
  defmt-print -e "$1" < "$work/run.bin"
}
sizes() { arm-none-eabi-size "$1" | tail -1; }

k=$(count "$D/m2selftest"); echo "$k"
e=$(pick "$k" 1)
echo "IK (one pose, six strokes, all checks):          $(( $(pick "$k" 2) - e )) instructions (goal <= 600)"
echo "FK (warm start within 10 um, with residual):     $(( $(pick "$k" 3) - e )) instructions (goal <= 5000)"
read -r text data bss _ < <(sizes "$D/m2selftest")
stack=$(run_log "$D/m2selftest" | sed -n 's/.*STACK peak_bytes=\([0-9]*\).*/\1/p')
echo "self-test image flash (text + data):             $((text + data)) bytes (goal <= 65536)"
echo "self-test image RAM (data + bss + stack peak):   $((data + bss + stack)) bytes = $data + $bss + $stack (goal <= 16384)"

c=$(count "$D/m2cyclebench"); echo "$c"
e=$(pick "$c" 1)
echo "control cycle, steady during a move (3 cycles):  $(( $(pick "$c" 8) - e )), $(( $(pick "$c" 9) - e )), $(( $(pick "$c" 10) - e )) instructions (goal <= 20000)"
echo "control cycle that receives a move telecommand:  $(( $(pick "$c" 2) - e )) instructions"
echo "the next five cycles (planning, move begins):    $(( $(pick "$c" 3) - e )), $(( $(pick "$c" 4) - e )), $(( $(pick "$c" 5) - e )), $(( $(pick "$c" 6) - e )), $(( $(pick "$c" 7) - e )) instructions"
echo "control cycle that also emits housekeeping:      $(( $(pick "$c" 11) - e )) instructions"
echo "cycle that commits a table (validate + flash):   $(( $(pick "$c" 12) - e )) instructions (at rest only)"
echo "cycle that activates a table:                    $(( $(pick "$c" 13) - e )) instructions (at rest only)"
log=$(run_log "$D/m2cyclebench")
cstack=$(echo "$log" | sed -n 's/.*STACK peak_bytes=\([0-9]*\).*/\1/p')
csize=$(echo "$log" | sed -n 's/.*CONTROLLER size_bytes=\([0-9]*\).*/\1/p')
read -r ftext fdata fbss _ < <(sizes "$D/m2fw")
echo "flight image m2fw flash (text + data):           $((ftext + fdata)) bytes"
echo "controller RAM: struct $csize bytes; stack peak of the cycle benchmark $cstack bytes; data + bss of m2fw $((fdata + fbss)) bytes"
