//! The firmware library on virtual time: a host-link model, the firmware's own command queue,
//! planner and step generator, a heater model, and recorders that measure pauses.
#![deny(missing_docs)]
