#!/usr/bin/env bash
# The main job: set up a fresh machine, then print the built-in job in the simulator with a
# pause requested mid-layer, comparing our firmware's pause with a conventional FIFO firmware;
# then the same pause on the flashed image on the emulated SKR 2 (a 10 mm version of the part,
# docs/board-emu.md) beside the simulator's timeline.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
cargo run --release -q -p sim --bin sim -- demo --out out "$@"
echo
echo "The flashed image on the emulated board (builds the image; about a minute):"
bash scripts/board-emu.sh --job out/board-demo.gcode \
  --pause-request-after "$(cat out/board-demo.request-s)" --resume-after 1 \
  --json out/board-demo-board.json
cargo run --release -q -p sim --bin sim -- demo --out out --compare-board out/board-demo-board.json
