//! G28 through the planner with endstops ([`crate::homing`]): the executive side. The driver
//! (board, simulator, test) reports each switch with [`Printer::set_endstop`] as soon as it
//! changes (the board from its pins, the simulator after every step from where the axis really
//! is); an approach stops at the step its switch triggers. Without switches
//! ([`Printer::enable_endstops`] not called) G28 moves each named axis to its minimum, as
//! before.

use super::{Command, Printer};
use crate::homing::{Homing, HomingConfig, MoveEnd, Next};
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

    /// Run the homing sequence of the G28 at the head of the command queue. True when it is
    /// over (done or failed): the command is then taken off the queue.
    pub(super) fn home_with_endstops(&mut self, mask: u8, cfg: HomingConfig) -> bool {
        if !self.motion_idle() {
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
            self.link.respond(crate::link::Response::Echo(line));
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
