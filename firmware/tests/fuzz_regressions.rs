//! Inputs the fuzz targets (firmware/fuzz) found, replayed through the same harness (included
//! from `firmware/fuzz/src/lib.rs`, so the checks are the fuzzer's own) on every `cargo test`.

#[path = "../fuzz/src/lib.rs"]
#[allow(dead_code)]
mod harness;

use harness::{run_executive, run_host_stream};

/// `executive` crash-6b2100…: G1 on USB, M524 on the TFT, M109 S200 and a G1 on USB, then
/// the harness's final `M400`: it was never answered after the cancel (`busy: processing` for
/// ever). Since the cancel rule of the executive (lines after a cancel are discarded until the
/// host starts anew, after 2 s of silence) the harness waits 3 s before its final M400.
#[test]
fn executive_cancel_then_heater_wait() {
    run_executive(&[0x62, 0x8a, 0x6f, 0x62]);
}

#[test]
fn host_stream_clean() {
    run_host_stream(&[6, 3, 64, 0]);
}
