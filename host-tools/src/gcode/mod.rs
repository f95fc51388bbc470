//! G-code text as the printer reads it, below both the design compiler and the job tools:
//! [`read`] reads a file with the firmware's own parser and layer detector, [`annotation`] is
//! the one annotation comment and [`bead`] the bead's cross-section model (both written by
//! designs, read by the 3D page), and [`number`] writes
//! compact numbers for JSON and comments. Nothing here imports the design compiler or the job
//! tools.

pub mod annotation;
pub mod bead;
pub mod number;
pub mod read;
