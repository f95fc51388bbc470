//! Inputs the fuzz targets (firmware/fuzz) found, replayed through the same harness (included
//! from `firmware/fuzz/src/lib.rs`, so the checks are the fuzzer's own) on every `cargo test`.

#[path = "../fuzz/src/lib.rs"]
#[allow(dead_code)]
mod harness;

use harness::{run_executive, run_host_stream};

/// `executive` crash-6b2100…: G1 on USB, M524 on the TFT, M109 S200 and a G1 on USB, then
/// the harness's final `M400`: after the cancel the printer is Idle with nothing queued, but the
/// M400 is never answered (`busy: processing` for ever). The same on one port (M524 on USB):
/// an executive bug (cancel vs. the owed M400 `ok`), reported to the executive's owner.
#[test]
#[ignore = "executive: M400 after a cancel never answered (reported, printer/ owner)"]
fn executive_cancel_then_heater_wait() {
    run_executive(&[0x62, 0x8a, 0x6f, 0x62]);
}

#[test]
fn host_stream_clean() {
    run_host_stream(&[6, 3, 64, 0]);
}
