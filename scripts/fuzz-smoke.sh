#!/usr/bin/env bash
# Runs each fuzz target of firmware/fuzz (default 20 s each; FUZZ_SECONDS to change, e.g.
# FUZZ_SECONDS=600 before a release) from the committed seeds and finds. Fails on any finding
# (the crashing input is left in firmware/fuzz/artifacts/<target>/): fix it and commit the input
# as firmware/fuzz/finds/<target>/<name>, which `cargo test` (CI) replays from then on
# (firmware/tests/fuzz_regressions.rs). Not part of CI: fuzzing is random exploration and CI is
# deterministic (docs/testing.md).
#
# Builds with nightly and the flags cargo-fuzz passes (coverage instrumentation for libFuzzer,
# debug assertions, overflow checks; no AddressSanitizer: the firmware library is safe Rust, a
# panic is the finding), so cargo-fuzz itself is not needed. `cargo +nightly fuzz run <target>`
# from firmware/fuzz works too when cargo-fuzz is installed.
#
# Depth (issue 24: inputs stayed at ~22 bytes): each target has a maximum input length
# (`-max_len`, FUZZ_MAX_LEN to override for all) fitting what it reads — a whole slicer layer
# for the G-code targets, a card image's first blocks for `card_image` — and libFuzzer starts
# at that length (`-len_control=0`) instead of growing inputs slowly from a few bytes; the
# committed seeds include whole slicer layers and FAT16 images (tests/tests/fuzz_seeds.rs).
set -euo pipefail
cd "$(dirname "$0")/../firmware/fuzz"
secs="${FUZZ_SECONDS:-20}"
# FUZZ_TARGETS to choose; FUZZ_TIMEOUT (s, default 20) is libFuzzer's wall-clock limit for one
# input: a whole slicer layer printed under instrumentation takes ~12 s of CPU, more on a
# loaded machine.
read -r -a targets <<< "${FUZZ_TARGETS:-parse_stream executive host_stream card_image}"
if ! rustup toolchain list | grep -q '^nightly'; then
  rustup toolchain install nightly --profile minimal
fi
export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions -Coverflow-checks"
# --target keeps the flags off build scripts (as cargo-fuzz does).
triple=x86_64-unknown-linux-gnu
tdir="${CARGO_TARGET_DIR:-target}"
cargo +nightly build --release --target "$triple" --bins
# Longest input per target, bytes.
max_len_of() {
  case "$1" in
    parse_stream) echo 16384 ;;   # a slicer layer of a few hundred lines
    executive) echo 16384 ;;      # a layer as raw USB chunks, with time and buttons
    host_stream) echo 1024 ;;     # chunk sizes and noise records
    card_image) echo 65536 ;;     # MBR, boot sector, FAT, directories, file data (128 blocks)
    *) echo 4096 ;;
  esac
}
for t in "${targets[@]}"; do
  mkdir -p "corpus/$t" "artifacts/$t"
  seeds=()
  [ -d "seeds/$t" ] && seeds+=("seeds/$t")
  [ -d "finds/$t" ] && seeds+=("finds/$t")
  max_len="${FUZZ_MAX_LEN:-$(max_len_of "$t")}"
  echo "== fuzz $t (${secs} s, inputs up to ${max_len} bytes)"
  "$tdir/$triple/release/$t" -max_total_time="$secs" -timeout="${FUZZ_TIMEOUT:-20}" -rss_limit_mb=1024 \
    -max_len="$max_len" -len_control=0 \
    -print_final_stats=1 -artifact_prefix="artifacts/$t/" "corpus/$t" "${seeds[@]}"
done
