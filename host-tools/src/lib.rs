//! Host-side tools: a compiler from procedural designs to G-code, and tools that check,
//! preview, resample and send G-code jobs. G-code is parsed with the firmware's own parser,
//! so the host reads exactly what the printer reads.
//!
//! The folders follow the architecture:
//! - [`gcode`]: G-code text as the printer reads it (the reader on the firmware's parser), the
//!   annotation comment and compact numbers: the floor the design compiler and the job tools
//!   stand on;
//! - [`design`]: the design model, its generators (turtle, strings, scripts, deformations,
//!   modulation, parts), the checks and the G-code writer;
//! - [`job`]: G-code jobs: reading, the job model and its edits, stats, preview, the sender;
//! - [`paste`]: paste printing: growth, time-based jobs, the cure check;
//! - [`additive`]: polygon-frame additive printing onto an existing part;
//! - [`cli`] and [`fileio`]: the command line and bounded, non-destructive file I/O;
//! - [`mem`]: the heap in use, for the script sandbox's memory budget.
#![deny(missing_docs)]

pub mod additive;
pub mod cli;
pub mod design;
pub mod fileio;
pub mod gcode;
pub mod job;
pub mod mem;
pub mod paste;
