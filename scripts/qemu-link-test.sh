#!/usr/bin/env bash
# Builds the flight image and drives it in QEMU over its UART (host-tests/qemu_link.rs):
# ping, housekeeping, a bad packet, a table upload/commit/activate, a move; the
# operations scenario (pivot, move checks, scheduled moves, parameters); bursts that
# keep the TX queue full (TM counters gapless, every report, every record accounted);
# the characterisation: a scripted session whose every reply equals the host bench's.
set -euo pipefail
cd "$(dirname "$0")/.."
export DEFMT_LOG=${DEFMT_LOG:-info}
cargo build --profile flight --target thumbv7em-none-eabihf --features firmware --bin m2fw
cargo test --features host --test qemu_link -- --ignored --nocapture
