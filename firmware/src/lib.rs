//! Portable printer firmware: the G-code front end, machine state, the planner with
//! motion-queue segmentation and a layer-aware pause, the step generator and heater control.
//!
//! `no_std`, no heap: every queue has a fixed capacity chosen in [`config`]. The same code runs
//! on the SKR 2 board (`src/main.rs`, feature `board`), in the simulator (`sim` crate) and in the
//! host tests. Data flows one way:
//!
//! ```text
//! bytes ─► link ─► gcode ─► machine ─► planner (segments, lookahead, pause) ─► stepgen ─► steps
//!                 layer marks ────────────┘                 thermal ◄─ temperature samples
//! ```
//! [`printer`] is the executive that wires these together and is what every driver runs.
#![cfg_attr(not(test), no_std)]
#![deny(missing_docs)]

// The TMC2209 register model (`drivers::tmc2209::model`, host builds only) keeps its datagrams
// in `alloc` vectors.
#[cfg(any(test, feature = "tmc-model"))]
extern crate alloc;

pub mod config;
pub mod drivers;
pub mod motion;

// Front end: host link, G-code parsing, modal machine state, layer detection.
pub mod gcode;
pub mod layer;
pub mod link;
pub mod machine;

// Motion: the planner ring buffer with pause, and step timing.
pub mod planner;
pub mod stepgen;

// Homing sequence and endstops (behind embedded-hal input pins).
pub mod homing;

// Heaters.
pub mod thermal;

// Settings kept in flash (M500/M501) and the NOR-flash model.
pub mod storage;

// The executive every driver (board, sim, tests) runs.
pub mod printer;
