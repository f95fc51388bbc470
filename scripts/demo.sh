#!/usr/bin/env bash
# The main job: set up a fresh machine, then print the built-in job in the simulator with a
# pause requested mid-layer, comparing our firmware's pause with a conventional FIFO firmware.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
cargo run --release -q -p sim --bin sim -- demo --out out "$@"
