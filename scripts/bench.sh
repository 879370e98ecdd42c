#!/usr/bin/env bash
# Firmware figures on the emulated Cortex-M4F (mps2-an386), measured with the project's
# own instruction counter (tools/qemu-insncount, a QEMU TCG plugin built here with gcc):
# IK, FK warm-started within 10 um, whole control periods of the flight code per
# scenario (control cycle, link pass, worker step), image sizes and stack peaks.
# Prints the figures, then gates the flight budgets: exits 1 if a control cycle is over
# 20,000 instructions, a worker or validation step over 100,000, the image's static worst
# case stack over 8,192 bytes or its flash over 65,536 bytes (scripts/main.sh runs it, so
# CI fails then). `scripts/bench.sh --write` also rewrites the generated budget table of
# docs/budgets.md with the figures. Needs only the clone and scripts/setup.sh.
set -euo pipefail
write=0
[ "${1:-}" = "--write" ] && write=1
cd "$(dirname "$0")/.."
D=target/thumbv7em-none-eabihf/release
export DEFMT_LOG=${DEFMT_LOG:-info}
cargo build --release --target thumbv7em-none-eabihf --features firmware --bin m2selftest
# The flight image and the cycle and validation benchmarks of its code: the
# size-optimised flight profile.
cargo build --profile flight --target thumbv7em-none-eabihf --features firmware --bin m2fw --bin m2cyclebench --bin m2validbench
F=target/thumbv7em-none-eabihf/flight
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
  # The markers must be functions of their own: folded with another (--icf=all), every
  # call of that one would restart or end a measured section.
  local shared
  shared=$(arm-none-eabi-nm "$1" | awk -v s="${s#0x}" -v e="${e#0x}" '($1 == s && $3 != "bench_start") || ($1 == e && $3 != "bench_end") {print $3}')
  [ -z "$shared" ] || { echo "bench: a marker shares its address with: $shared ($1)" >&2; exit 2; }
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
# The same kinematics as the flight image compiles them (profile flight, opt-level z).
cargo build --profile flight --target thumbv7em-none-eabihf --features firmware --bin m2selftest
ks=$(count "$F/m2selftest")
es=$(pick "$ks" 1)
echo "IK in the flight profile (opt-level z):          $(( $(pick "$ks" 2) - es )) instructions (flight goal <= 1000)"
echo "FK in the flight profile (opt-level z):          $(( $(pick "$ks" 3) - es )) instructions (flight goal <= 8000)"
read -r text data bss _ < <(sizes "$D/m2selftest")
stack=$(run_log "$D/m2selftest" | sed -n 's/.*STACK peak_bytes=\([0-9]*\).*/\1/p')
echo "self-test image flash (text + data):             $((text + data)) bytes (goal <= 65536)"
echo "self-test image RAM (data + bss + stack peak):   $((data + bss + stack)) bytes = $data + $bss + $stack (goal <= 16384)"

# Table validation in bounded steps (m2validbench, flight profile): one section per
# `ValidationState::step`; its `VALIDATION table=.. points=.. first=<n> steps=<k>
# code=.. detail=..` lines name each validation's (the nominal table on every grid
# density, the flight configuration's first; then a table refused by an FK at its
# iteration limit, the longest corner step: its last). Per validation: steps, result,
# largest step, last step, all steps; then the largest step of all, the goal's figure.
v=$(count "$F/m2validbench")
e=$(pick "$v" 1)
vlog=$(run_log "$F/m2validbench")
echo "$vlog" | grep -q "VALIDBENCH PASS" || { echo "bench: m2validbench failed:" >&2; echo "$vlog" >&2; exit 1; }
echo "table validation in steps (ValidationState: $(echo "$vlog" | sed -n 's/.*VALIDATION_STATE bytes=\([0-9]*\).*/\1/p') bytes):"
echo "$vlog" | sed -n 's/.*VALIDATION table=\([a-z_]*\) points=\([0-9]*\) first=\([0-9]*\) steps=\([0-9]*\) code=\(0x[0-9a-f]*\) detail=\(0x[0-9a-f]*\).*/\1 \2 \3 \4 \5 \6/p' |
while read -r name points first steps code detail; do
  echo "$v" | awk -F'[ =]' -v f="$first" -v p="$steps" -v e="$e" -v name="$name" -v n="$points" -v c="$code" -v d="$detail" '
    $1 == "BENCH" && $3 >= f && $3 < f + p { x = $5 - e; t += x; if (x > m) { m = x; at = $3 - f + 1 }; last = x }
    END { printf "  %-9s %d grid points: %3d steps, result %s/%s, largest step %6d (step %3d), last %6d, all steps %9d instructions\n", name, n, p, c, d, m, at, last, t }'
done
echo "$v" | awk -F'[ =]' -v e="$e" '$1 == "BENCH" && $3 > 1 { x = $5 - e; if (x > m) m = x }
  END { printf "largest validation step (flight profile):        %d instructions (goal <= 100000)\n", m }' | tee "$work/validation.txt"

# Whole control periods of the flight code (m2cyclebench): per scenario the largest
# control cycle, link-service pass and worker step (sections n, n+1, n+2 per period).
c=$(count "$F/m2cyclebench")
e=$(pick "$c" 1)
log=$(run_log "$F/m2cyclebench")
echo "$log" | grep -E "GROUP|STACK|BOOT|SIZES|bench:" || true
echo "$log" | sed -n 's/.*GROUP name=\([a-z_]*\) first=\([0-9]*\) periods=\([0-9]*\).*/\1 \2 \3/p' |
while read -r name first periods; do
  echo "$c" | awk -F'[ =]' -v f="$first" -v p="$periods" -v e="$e" -v name="$name" '
    $1 == "BENCH" { n = $3; v = $5 - e; if (n >= f && n < f + 3 * p) { k = (n - f) % 3; if (v > m[k]) m[k] = v } }
    END { printf "%-13s %5d periods: control cycle max %6d (goal <= 20000), link pass max %8d, worker step max %8d instructions\n", name, p, m[0], m[1], m[2] }'
done | tee "$work/groups.txt"
# The controller's lock bodies, each alone (m2cyclebench's `LOCK name=.. section=n`
# lines): the longest is what a control cycle may wait for the link service's lock.
echo "$log" | sed -n 's/.*LOCK name=\([a-z_]*\) section=\([0-9]*\).*/\1 \2/p' |
while read -r name n; do
  echo "$c" | awk -F'[ =]' -v n="$n" -v e="$e" -v name="$name" '
    $1 == "BENCH" && $3 == n { printf "lock body %-24s %8d instructions\n", name, $5 - e }'
done
# Static worst-case stack of each m2fw task (frames along the deepest direct-call chain);
# the measured peak of the flight image is printed by scripts/qemu-link-test.sh.
python3 scripts/stack-depth.py "$F/m2fw" main CONTROL_TIMER LINK_SERVICE WORKER UART_RX UART_TX | grep STATIC | tee "$work/static.txt"
# The whole image's worst case: idle (thread mode, after init) preempted by a priority-1
# task, preempted by UART TX, by the control task, by UART RX (goal <= 8192); the boot
# path (main's STATIC line: init, before any interrupt is enabled) is the other candidate.
python3 scripts/stack-depth.py "$F/m2fw" --nested main:frame LINK_SERVICE,WORKER UART_TX CONTROL_TIMER UART_RX | tee "$work/nested.txt"
read -r ftext fdata fbss _ < <(sizes "$F/m2fw")
echo "flight image m2fw flash (text + data):           $((ftext + fdata)) bytes (goal <= 65536); RAM data + bss $((fdata + fbss)) bytes"

# The budgets (the design card's; docs/budgets.md): each figure against its limit.
cycle=$(sed -n 's/.*control cycle max *\([0-9]*\).*/\1/p' "$work/groups.txt" | sort -n | tail -1)
step=$(sed -n 's/.*worker step max *\([0-9]*\).*/\1/p' "$work/groups.txt" | sort -n | tail -1)
vstep=$(sed -n 's/.*largest validation step.*: *\([0-9]*\) instructions.*/\1/p' "$work/validation.txt")
nested=$(sed -n 's/^NESTED depth_bytes=\([0-9]*\).*/\1/p' "$work/nested.txt")
boot=$(sed -n 's/^STATIC root=main depth_bytes=\([0-9]*\).*/\1/p' "$work/static.txt")
flash=$((ftext + fdata))
fail=0
table="| budget | measured | limit |
|---|---|---|"
gate() { # name value limit unit
  local verdict=ok
  [ -n "$2" ] || { echo "bench: no figure for $1" >&2; fail=1; return; }
  if [ "$2" -gt "$3" ]; then verdict=EXCEEDED; fail=1; fi
  printf 'BUDGET %-52s %8d %s (limit %d): %s\n' "$1" "$2" "$4" "$3" "$verdict"
  table="$table
| $1 | $2 $4 | <= $3 |"
}
gate "control cycle, largest of every scenario" "$cycle" 20000 instructions
gate "worker step, largest of every scenario" "$step" 100000 instructions
gate "table validation step, largest" "$vstep" 100000 instructions
gate "stack, static worst case of the whole image (NESTED)" "$nested" 8192 bytes
gate "stack, boot path (STATIC main: init, no interrupt enabled)" "$boot" 8192 bytes
gate "flight image m2fw flash (text + data)" "$flash" 65536 bytes
if [ "$write" = 1 ]; then
  python3 - "$table" "$(git rev-parse --short HEAD)" <<'PY'
import sys, re
table, rev = sys.argv[1], sys.argv[2]
p = "docs/budgets.md"
s = open(p).read()
begin, end = "<!-- BEGIN GENERATED: scripts/bench.sh -->", "<!-- END GENERATED: scripts/bench.sh -->"
block = f"{begin}\n_Written by `scripts/bench.sh --write` at commit {rev}._\n\n{table}\n{end}"
if begin in s:
    s = re.sub(re.escape(begin) + ".*?" + re.escape(end), lambda m: block, s, flags=re.S)
else:
    s = s.replace("\n## Firmware figures", "\n" + block + "\n\n## Firmware figures", 1)
open(p, "w").write(s)
PY
  echo "docs/budgets.md: budget table written"
fi
[ "$fail" = 0 ] || { echo "bench: a flight budget is exceeded (BUDGET lines above)" >&2; exit 1; }
