//! The driver's endstops and the homing it watches (the motion part runs G28; see
//! `motion/homing.rs`): switch readings in, the approach's watch mask and the axes homed out.

use super::Printer;
use crate::homing::{Endstops, HomingConfig};
use crate::motion::{Axis, AXES};

impl Printer {
    /// Home with endstops (the driver reports them with [`Printer::set_endstop`] or, when its
    /// step interrupt watches them, [`Printer::endstop_trip`]). Without this G28 moves to the
    /// axes' minimum and trusts it.
    pub fn enable_endstops(&mut self, cfg: HomingConfig) {
        self.motion.enable_endstops(cfg);
    }

    /// The driver's reading of `axis`'s switch; a switch that closes during an approach
    /// towards it ends the approach at once.
    pub fn set_endstop(&mut self, axis: Axis, pressed: bool) {
        self.motion.set_endstop(axis, pressed);
    }

    /// The switches as last reported, bit i = axis i pressed.
    pub fn endstops(&self) -> u8 {
        self.motion.endstops()
    }

    /// The board's step interrupt stopped an approach at its switch; `undone` are the steps of
    /// the events it dropped (generated, never taken).
    pub fn endstop_trip(&mut self, axis: Axis, undone: [i32; AXES]) {
        self.motion.endstop_trip(axis, undone);
    }

    /// The board's step queue still holds or runs events of the executive: homing waits.
    pub fn set_steps_in_flight(&mut self, in_flight: bool) {
        self.motion.set_steps_in_flight(in_flight);
    }

    /// Bit i set: the running approach ends at axis i's switch (the step interrupt watches it).
    pub fn homing_watch(&self) -> u8 {
        self.motion.homing_watch()
    }

    /// Read the switches (idle, M119): not during an approach, whose switch the driver watches.
    pub fn sample_endstops(&mut self, e: &mut impl Endstops) {
        self.motion.sample_endstops(e);
    }

    /// Axes homed and not lost since (bit i = axis i).
    pub fn homed_axes(&self) -> u8 {
        self.motion.homed_axes()
    }

    /// Axes homed since the last call (the board's step interrupt lifts its travel limits).
    pub fn take_homed(&mut self) -> u8 {
        self.motion.take_homed()
    }
}
