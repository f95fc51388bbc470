//! Host-side tools: a compiler from procedural designs to G-code, and tools that check,
//! preview, resample and send G-code jobs. G-code is parsed with the firmware's own parser,
//! so the host reads exactly what the printer reads.
#![deny(missing_docs)]

pub mod additive;
pub mod cli;
pub mod cure;
pub mod grow;
pub mod job;
pub mod sender;
pub mod timebased;
// Design compiler (ht-design).
pub mod checks;
pub mod deform;
pub mod fileio;
pub mod gcode_read;
pub mod model;
pub mod modulate;
pub mod motion;
pub mod parts;
pub mod preview;
pub mod profile;
pub mod script;
pub mod stats;
pub mod turtle;
pub mod writer;
