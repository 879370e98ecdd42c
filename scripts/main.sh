#!/usr/bin/env bash
# The main job, one command on a fresh machine: installs the prerequisites, builds the
# flight firmware, runs its self-test on the emulated Cortex-M4F (QEMU mps2-an386) and
# checks the target's f32 results bit for bit against the host's, prints the firmware
# figures (instruction counts, image sizes, stack), and runs the ground tool's IK/FK
# on the reference poses.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/qemu-selftest.sh
scripts/bench.sh
cargo build --release --features host --bin m2ground
mkdir -p target/demo
target/release/m2ground ik --geometry testdata/geometry.toml --input testdata/ik_golden.csv --output target/demo/ik.csv
target/release/m2ground fk --geometry testdata/geometry.toml --input target/demo/ik.csv --output target/demo/fk.csv
echo "ground tool: target/demo/ik.csv (strokes of the reference poses), target/demo/fk.csv (poses back)"
