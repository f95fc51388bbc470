//! G28 through the planner with endstops ([`crate::homing`]): the executive side.
//!
//! Two kinds of driver report the switches:
//!
//! * one that takes each step event when it is due and reads the switches after it (the
//!   simulator, the tests): it calls [`Printer::set_endstop`] as soon as a switch changes; an
//!   approach stops at the step its switch triggers;
//! * one whose step interrupt runs events queued ahead of time (the board, up to 2 ms): the
//!   interrupt watches the approach's switch before each of its events
//!   ([`crate::drivers::homing_watch`]) and drops what is left when it triggers; the motion
//!   loop then calls [`Printer::endstop_trip`] with the steps that were generated but not
//!   taken, tells the executive whether events are still in flight
//!   ([`Printer::set_steps_in_flight`]: homing decides on a move's end only once its last
//!   step has really been taken) and latches the switches for M119 and those decisions with
//!   [`Printer::sample_endstops`].
//!
//! Without switches ([`Printer::enable_endstops`] not called) G28 moves each named axis to its
//! minimum, as before.

use super::{Command, Printer};
use crate::homing::{Endstops, Homing, HomingConfig, MoveEnd, Next};
use crate::motion::{Axis, MoveRequest};
use crate::planner::BlockKind;

impl Printer {
    /// This machine has minimum endstops on X, Y and Z: G28 homes with them (`cfg`: speeds and
    /// distances).
    pub fn enable_endstops(&mut self, cfg: HomingConfig) {
        self.homing_cfg = Some(cfg);
    }

    /// The switch of `axis` is pressed (`true`) or open. During an approach of that axis the
    /// motion stops at once, at the step the driver has just taken.
    pub fn set_endstop(&mut self, axis: Axis, pressed: bool) {
        let bit = 1u8 << axis.index();
        let was = self.endstops & bit != 0;
        if pressed {
            self.endstops |= bit;
        } else {
            self.endstops &= !bit;
        }
        if !pressed || was {
            return;
        }
        let Some(mut h) = self.homing else {
            return;
        };
        if h.current()
            .is_some_and(|m| m.stop_at_switch && m.axis == axis)
        {
            let _ = self.stepgen.unload();
            let pos = self.stepgen.position();
            self.planner.clear(pos);
            self.planner.exec_done();
            h.finished(MoveEnd::Triggered);
            self.homing = Some(h);
        }
    }

    /// Switch states, bit i = axis i pressed.
    pub fn endstops(&self) -> u8 {
        self.endstops
    }

    /// The switch of `axis` stopped the running approach in a driver that runs step events
    /// ahead: `undone` (steps per axis, signed) were generated but never taken. The move ends
    /// there and the executive's position goes back by `undone`. Ignored unless an approach of
    /// `axis` is running (a trip that arrives after M112 or a quick stop changes nothing).
    pub fn endstop_trip(&mut self, axis: Axis, undone: [i32; crate::motion::AXES]) {
        self.endstops |= 1 << axis.index();
        let Some(mut h) = self.homing else {
            return;
        };
        if !h
            .current()
            .is_some_and(|m| m.stop_at_switch && m.axis == axis)
        {
            return;
        }
        let _ = self.stepgen.unload();
        let mut pos = self.stepgen.position();
        for (p, u) in pos.iter_mut().zip(undone) {
            *p = p.wrapping_sub(u);
        }
        self.stepgen.set_position(pos);
        self.planner.clear(pos);
        self.planner.exec_done();
        h.finished(MoveEnd::Triggered);
        self.homing = Some(h);
    }

    /// The driver still has step events queued or running (true) or has taken every event it
    /// was given (false). Homing decides on the end of a move only when nothing is in flight.
    /// Drivers that take each event when due never call this.
    pub fn set_steps_in_flight(&mut self, in_flight: bool) {
        self.steps_in_flight = in_flight;
    }

    /// Axes (bit i) whose switch ends the running homing move: the step interrupt of a driver
    /// that runs events ahead watches these switches before each event of the move.
    pub fn homing_watch(&self) -> u8 {
        self.homing
            .and_then(|h| h.current())
            .filter(|m| m.stop_at_switch)
            .map_or(0, |m| 1 << m.axis.index())
    }

    /// Latch the switches (for M119 and homing's decisions) from `e`, for a driver that runs
    /// step events ahead. Not during an approach: there the step interrupt's watch decides
    /// ([`Printer::endstop_trip`]); a switch seen here would stop the move at the executive's
    /// position, which is ahead of the axis.
    pub fn sample_endstops(&mut self, e: &mut impl Endstops) {
        if self.homing_watch() != 0 {
            return;
        }
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let bit = 1u8 << axis.index();
            if e.triggered(axis) {
                self.endstops |= bit;
            } else {
                self.endstops &= !bit;
            }
        }
    }

    /// Axes homed on their switches and not lost since (bit i = X, Y, Z; drivers switched
    /// off lose the position). The board's step interrupt refuses moves of the others.
    pub fn homed_axes(&self) -> u8 {
        self.homed.homed & !self.position_lost
    }

    /// Axes homed (set to their minimum) since the last call, bit i = X, Y, Z: the board sets
    /// its step interrupt's position of those axes to their minimum.
    pub fn take_homed(&mut self) -> u8 {
        core::mem::take(&mut self.homed.fresh)
    }

    /// Run the homing sequence of the G28 at the head of the command queue. True when it is
    /// over (done or failed): the command is then taken off the queue.
    pub(super) fn home_with_endstops(&mut self, mask: u8, cfg: HomingConfig) -> bool {
        if !self.motion_idle() || self.steps_in_flight {
            return false;
        }
        let mut h = self
            .homing
            .unwrap_or_else(|| Homing::new(mask, &cfg, &self.cfg));
        let over = loop {
            if let Some(m) = h.current() {
                // The move ran to its end (a trigger would have finished it already).
                let switch = self.endstops & (1 << m.axis.index()) != 0;
                h.finished(MoveEnd::Completed { switch });
            }
            match h.next_step() {
                Next::Move(m) => {
                    if m.stop_at_switch && self.endstops & (1 << m.axis.index()) != 0 {
                        h.finished(MoveEnd::Triggered);
                        continue;
                    }
                    let mut target = self.stepgen.position();
                    let spm = self.cfg.axis(m.axis).steps_per_mm;
                    let d = libm::roundf(m.distance_mm * spm) as i32;
                    let i = m.axis.index();
                    target[i] = target[i].saturating_add(d);
                    let req = MoveRequest {
                        target,
                        feed_mm_s: m.feed_mm_s,
                        seq: u32::MAX,
                    };
                    let _ = self.planner.push_move(&self.cfg, &req, BlockKind::Homing);
                    break false;
                }
                Next::Homed(axis) => {
                    let mut pos = self.stepgen.position();
                    let a = self.cfg.axis(axis);
                    pos[axis.index()] = libm::roundf(a.min_mm * a.steps_per_mm) as i32;
                    self.planner.set_position(pos);
                    self.stepgen.set_position(pos);
                    self.position_lost &= !(1 << axis.index());
                    self.homed.homed |= 1 << axis.index();
                    self.homed.fresh |= 1 << axis.index();
                }
                Next::Done => break true,
                Next::Failed(e) => {
                    self.homing = None;
                    // As Marlin: homing failed is fatal (the position is unknown).
                    let mut t: heapless::String<{ super::LINE_LEN }> = heapless::String::new();
                    let _ = core::fmt::Write::write_fmt(&mut t, format_args!("{e}"));
                    self.link.respond(crate::link::Response::Error(&t));
                    self.emergency_stop();
                    break true;
                }
            }
        };
        self.homing = if over { None } else { Some(h) };
        over
    }

    /// M112, kill or quick stop: homing ends at once.
    pub(super) fn abort_homing(&mut self) {
        if self.homing.take().is_some() {
            if let Some(Command::Home { .. }) = self.cmds.front() {
                let _ = self.cmds.pop_front();
            }
            self.say(format_args!("homing aborted"));
        }
    }

    /// M119: Marlin's endstop report.
    pub(super) fn m119(&mut self) {
        let mut e = Latched(self.endstops);
        for line in crate::homing::m119_lines(&mut e) {
            // As Marlin's `Endstops::report_states()`: plain lines, no `echo:`.
            self.link.respond(crate::link::Response::Plain(line));
        }
    }
}

/// Switch states as the driver last reported them.
struct Latched(u8);

impl crate::homing::Endstops for Latched {
    fn triggered(&mut self, axis: Axis) -> bool {
        self.0 & (1 << axis.index()) != 0
    }
}

/// Which axes were homed on their switches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct HomedAxes {
    /// Homed since power-up (bit i = X, Y, Z).
    homed: u8,
    /// Homed since the driver last asked ([`Printer::take_homed`]).
    fresh: u8,
}

impl HomedAxes {
    pub(super) const NONE: HomedAxes = HomedAxes { homed: 0, fresh: 0 };
}
