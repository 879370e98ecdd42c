#!/usr/bin/env bash
# Installs what the project needs on a fresh Debian machine with rustup (idempotent):
# the Cortex-M4F Rust target, QEMU for Arm, Arm binutils and gcc (for the instruction
# counter tools/qemu-insncount), valgrind (host benchmark), defmt-print (decodes the
# firmware's log) and stress-ng (the QEMU tests under CPU load, scripts/qemu-load-test.sh).
set -euo pipefail
need_apt=()
command -v qemu-system-arm >/dev/null || need_apt+=(qemu-system-arm)
command -v arm-none-eabi-nm >/dev/null || need_apt+=(binutils-arm-none-eabi)
command -v gcc >/dev/null || need_apt+=(gcc)
[ -f /usr/include/stdio.h ] || need_apt+=(libc6-dev)
command -v valgrind >/dev/null || need_apt+=(valgrind)
command -v stress-ng >/dev/null || need_apt+=(stress-ng)
# Ground segment (scripts/ground-segment.sh, scripts/yamcs-e2e.sh): Java 17 for Yamcs,
# Chromium for the web UI screenshot.
command -v java >/dev/null || need_apt+=(openjdk-17-jre-headless)
command -v chromium >/dev/null || need_apt+=(chromium)
if [ ${#need_apt[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need_apt[@]}"
fi
rustup target list --installed | grep -qx thumbv7em-none-eabihf || rustup target add thumbv7em-none-eabihf
rustup component list --installed | grep -q '^clippy' || rustup component add clippy
rustup component list --installed | grep -q '^rustfmt' || rustup component add rustfmt
command -v defmt-print >/dev/null || cargo install defmt-print --locked --version 1.2.0
# Coverage-guided fuzzing (scripts/fuzz.sh): a nightly toolchain and cargo-fuzz.
rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked --version 0.13.2
# Python spacepackets: the independent PUS encoder of ground/tests/link.rs.
python3 -c 'import spacepackets' 2>/dev/null || pip install --quiet spacepackets
# Ground segment: Yamcs 5.12 server jars (AGPL; installed from PyPI, never vendored),
# the XTCE writer, the Yamcs client, the XTCE schema validator.
python3 - <<'PY' 2>/dev/null || pip install --quiet "fprime-yamcs-bundle==5.12.8.0" "yamcs-pymdb==1.4.0" "yamcs-client==2.1.0" "space-packet-parser==6.2.0"
import importlib.metadata as m
want = {"fprime-yamcs-bundle": "5.12.8.0", "yamcs-pymdb": "1.4.0", "yamcs-client": "2.1.0", "space-packet-parser": "6.2.0"}
raise SystemExit(any(m.version(k) != v for k, v in want.items()))
PY
echo "setup: rust target, qemu-system-arm, arm binutils, gcc, valgrind, stress-ng, defmt-print, nightly + cargo-fuzz, Yamcs ground segment ready"
