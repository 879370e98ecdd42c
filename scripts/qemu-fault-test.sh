#!/usr/bin/env bash
# Builds the fault-test build of the flight image (--features fault-test: overruns and a
# hang after power-on, a stack overflow after the watchdog reset) and checks in QEMU that
# each fault is detected, resets the board and is reported with its cause
# (host-tests/qemu_faults.rs). Then rebuilds the flight image itself.
set -euo pipefail
cd "$(dirname "$0")/.."
F=target/thumbv7em-none-eabihf/flight
cargo build --profile flight --target thumbv7em-none-eabihf --features firmware,fault-test --bin m2fw
cp "$F/m2fw" target/m2fw-fault-test
cargo build --profile flight --target thumbv7em-none-eabihf --features firmware --bin m2fw
cargo test --features host --test qemu_faults -- --ignored --nocapture
