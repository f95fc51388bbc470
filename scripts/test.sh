#!/usr/bin/env bash
# All tests: host unit, property and end-to-end tests of every crate, then the portable core on
# an emulated Cortex-M4 (QEMU), whose step-event digest must equal the host's.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo test --workspace
bash scripts/qemu-test.sh
