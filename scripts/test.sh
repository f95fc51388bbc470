#!/usr/bin/env bash
# All tests: host unit, property and end-to-end tests of every crate.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --workspace
