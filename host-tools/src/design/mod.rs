//! The design compiler: a design is a model of strings (polylines with width, height, speed and
//! state changes) built by generators, checked, and written out as G-code.

pub mod checks;
pub mod deform;
pub mod init;
pub mod model;
pub mod modulate;
pub mod motion;
pub mod parts;
pub mod pen;
pub mod points;
pub mod profile;
pub mod progress;
pub mod raw;
pub mod script;
pub mod transform;
pub mod travel;
pub mod turtle;
pub mod writer;
