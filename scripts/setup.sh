#!/usr/bin/env bash
# Installs what the project needs on a fresh Debian machine with rustup (idempotent):
# the Cortex-M4F Rust target, QEMU for Arm, Arm binutils and gcc (for the instruction
# counter tools/qemu-insncount), valgrind (host benchmark), and defmt-print (decodes the
# firmware's log).
set -euo pipefail
need_apt=()
command -v qemu-system-arm >/dev/null || need_apt+=(qemu-system-arm)
command -v arm-none-eabi-nm >/dev/null || need_apt+=(binutils-arm-none-eabi)
command -v gcc >/dev/null || need_apt+=(gcc)
[ -f /usr/include/stdio.h ] || need_apt+=(libc6-dev)
command -v valgrind >/dev/null || need_apt+=(valgrind)
if [ ${#need_apt[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need_apt[@]}"
fi
rustup target list --installed | grep -qx thumbv7em-none-eabihf || rustup target add thumbv7em-none-eabihf
rustup component list --installed | grep -q '^clippy' || rustup component add clippy
rustup component list --installed | grep -q '^rustfmt' || rustup component add rustfmt
command -v defmt-print >/dev/null || cargo install defmt-print --locked --version 1.2.0
# Python spacepackets: the independent PUS encoder of host-tests/link.rs.
python3 -c 'import spacepackets' 2>/dev/null || pip install --quiet spacepackets
echo "setup: rust target, qemu-system-arm, arm binutils, gcc, valgrind, defmt-print ready"
