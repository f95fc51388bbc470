//! Arbitrary bytes through the whole front end: host link (line assembly, line numbers,
//! checksums, realtime requests) → G-code parser → emitter round trip → machine state and layer
//! detection. Must never panic, and must keep its invariants (see
//! `firmware_fuzz::run_parse_stream`).
//!
//! `scripts/fuzz-smoke.sh` runs it; by hand: `cargo +nightly fuzz run parse_stream` (from
//! `firmware/fuzz`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| firmware_fuzz::run_parse_stream(data));
