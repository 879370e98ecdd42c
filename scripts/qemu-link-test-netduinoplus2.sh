#!/usr/bin/env bash
# The flight image of the second board (STM32F405 Netduino Plus 2) in QEMU's
# netduinoplus2 machine, driven over USART1 (host-tests/qemu_link_netduinoplus2.rs):
# boot event, ping, housekeeping (the faults QEMU's missing GPIO/encoders imply), a bad
# packet, a refused move. Needs what scripts/qemu-link-test.sh needs.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --profile flight --target thumbv7em-none-eabihf --features firmware,board-netduinoplus2 --bin m2fw
cp target/thumbv7em-none-eabihf/flight/m2fw target/m2fw-netduinoplus2.elf
cargo test --features host --test qemu_link_netduinoplus2 -- --ignored --nocapture
