//! A numbered, checksummed host over a noisy wire (bytes substituted, dropped, line ends lost
//! or made up, the stream split anywhere), with a layer pause and a resume, compared with the
//! same job over a clean wire: the same moves must execute, once each, in order.
//!
//! Input: byte 0 = number of job lines, byte 1 = where to pause, byte 2.. = chunk sizes until a
//! 0, then noise records of 3 bytes (attempt, position, byte; byte 0xFF = drop).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| firmware_fuzz::run_host_stream(data));
