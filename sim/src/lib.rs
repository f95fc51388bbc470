//! The firmware library on virtual time: a host-link model, the firmware's own command queue,
//! planner and step generator, a heater model, and recorders that measure pauses.
#![deny(missing_docs)]

pub mod demo;
pub mod demo_board;
pub mod engine;
pub mod exec;
pub mod flash;
pub mod heater;
pub mod hostlink;
pub mod job;
pub mod lab;
pub mod layers;
pub mod machines;
pub mod metrics;
pub mod patterns;
pub mod plot;
pub mod port;
pub mod powercut;
pub mod recorder;
pub mod run;
pub mod scenario;
pub mod sd;
pub mod serve;
pub mod session;
pub mod split;
pub mod stream;
pub mod thermal;
