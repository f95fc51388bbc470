#!/usr/bin/env bash
# All tests: host unit, property and end-to-end tests of every crate — among them the
# unmodified SKR 2 image on the emulated board (board-emu/tests/emulated.rs, which builds the
# image itself) — then the portable core on an emulated Cortex-M4 (QEMU), whose step-event
# digest must equal the host's.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/fw-env.sh
bash scripts/setup.sh
# The end-to-end tests use the sim and host-tools binaries this run builds (with the
# workspace's features) instead of rebuilding them for `-p sim -p host-tools` alone (≈ 2 min;
# tests/tests/hosts_common/mod.rs, `bin`).
LAYERPAUSE_WORKSPACE_BINS=1 cargo test --workspace
bash scripts/qemu-test.sh
