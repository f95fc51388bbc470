//! Bytes → host link (two ports) → executive → planner → step generator, with pause, resume,
//! cancel and the other realtime requests mixed in, on virtual time. Invariants: see
//! `firmware_fuzz::Harness` (no panic, travel limits, axis speed limits, no wedge).
//!
//! The input is a little program: each byte is an op (top 3 bits) and an argument (low 5 bits):
//! raw bytes to the USB or TFT port, a line from a dictionary of meaningful commands, time
//! passing, a button request or a heater sensor fault; the first byte chooses the policy
//! (ours, the conventional `fifo` model, manual paused lines, unsegmented).
//!
//! `scripts/fuzz-smoke.sh` runs it; by hand (from `firmware/fuzz`, see that script for the
//! flags): `cargo +nightly fuzz run executive`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| firmware_fuzz::run_executive(data));
