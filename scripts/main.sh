#!/usr/bin/env bash
# The main job, one command on a fresh machine:
#  1. installs the prerequisites (scripts/setup.sh);
#  2. the mission story on the simulated plant (m2ground mission): a mechanism with
#     manufacturing errors, the real controller moving to targets by telecommand, a
#     calibration campaign, ground calibration (improved cuckoo search + LM), the table
#     uploaded/validated/activated by telecommand, the targets again; summary + plot;
#  3. the flight firmware on the emulated Cortex-M4F: kinematics self-test (target bits
#     == host bits), then the flight image driven over its UART, then its fault handling (overruns, a
#     hang reset by the watchdog, a stack overflow caught by the MPU guard);
#  4. the second board (STM32F405, QEMU netduinoplus2): its self-test and its flight
#     image over USART1;
#  5. the firmware figures (instruction counts, sizes, stack).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
mkdir -p target/mission
cargo build --release --features host --bin m2ground
target/release/m2ground mission --plot target/mission/errors.svg "$@"
scripts/qemu-selftest.sh
scripts/qemu-link-test.sh
scripts/qemu-fault-test.sh
scripts/qemu-selftest-netduinoplus2.sh
scripts/qemu-link-test-netduinoplus2.sh
scripts/bench.sh
echo
echo "main: mission plot target/mission/errors.svg; all steps passed"
