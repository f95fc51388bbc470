//! G28 in the motion part: the homing state machine ([`crate::homing`]) run through the
//! planner on the endstops, as Marlin's `G28` does. The switches come from the driver
//! ([`Motion::set_endstop`], or with the board's step interrupt watching them,
//! [`Motion::endstop_trip`]); an approach that triggers ends at once and the planner starts
//! again from where the head stopped. Without endstops ([`HomingState::enabled`] false) G28
//! moves to the axes' minimum and trusts it.

use super::Motion;
use crate::config::MachineConfig;
use crate::homing::{Endstops, Homing, HomingConfig, HomingError, MoveEnd, Next};
use crate::motion::{Axis, MoveRequest, StepPos, AXES};
use crate::planner::{Barrier, BlockKind};

/// Axes homed on their switches since power-on (bit i = axis i), and those homed since the
/// driver last asked ([`Motion::take_homed`]: the board's step interrupt lifts its travel
/// limits for them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct HomedAxes {
    homed: u8,
    fresh: u8,
}

/// The homing part of the motion state.
#[derive(Clone, Copy, Debug)]
pub(in crate::printer) struct HomingState {
    /// Homing with endstops (None: G28 moves to the minimum, no switches).
    cfg: Option<HomingConfig>,
    /// The G28 in progress.
    current: Option<Homing>,
    /// Endstop switch states as the driver reported them, bit i = axis i pressed.
    endstops: u8,
    /// The driver still has step events queued or running: homing waits for them.
    steps_in_flight: bool,
    homed: HomedAxes,
}

impl HomingState {
    pub(super) const fn new() -> Self {
        Self {
            cfg: None,
            current: None,
            endstops: 0,
            steps_in_flight: false,
            homed: HomedAxes { homed: 0, fresh: 0 },
        }
    }

    /// Forget a G28 in progress; whether there was one.
    pub(super) fn abort(&mut self) -> bool {
        self.current.take().is_some()
    }
}

/// How a step of G28 went.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::printer) enum HomeStep {
    /// A move is planned or the motion must end first: G28 goes on.
    Moving,
    /// Every axis is homed.
    Done,
    /// An endstop was not reached: the printer must halt.
    Failed(HomingError),
}

impl Motion {
    /// Home with the endstops (the driver reports them).
    pub(in crate::printer) fn enable_endstops(&mut self, cfg: HomingConfig) {
        self.homing.cfg = Some(cfg);
    }

    /// The driver's endstop reading. A switch that closes during an approach towards it ends
    /// the approach at once: the block is dropped where the head is.
    pub(in crate::printer) fn set_endstop(&mut self, axis: Axis, pressed: bool) {
        let bit = 1u8 << axis.index();
        let was = self.homing.endstops & bit != 0;
        if pressed {
            self.homing.endstops |= bit;
        } else {
            self.homing.endstops &= !bit;
        }
        if !pressed || was || !self.approaching(axis) {
            return;
        }
        let _ = self.stepgen.unload();
        let pos = self.stepgen.position();
        self.end_approach(pos);
    }

    /// The board's step interrupt stopped an approach at its switch: `undone` are the steps of
    /// the events it dropped (generated here, never taken).
    pub(in crate::printer) fn endstop_trip(&mut self, axis: Axis, undone: [i32; AXES]) {
        self.homing.endstops |= 1 << axis.index();
        if !self.approaching(axis) {
            return;
        }
        let _ = self.stepgen.unload();
        let mut pos = self.stepgen.position();
        for (p, u) in pos.iter_mut().zip(undone) {
            *p = p.wrapping_sub(u);
        }
        self.stepgen.set_position(pos);
        self.end_approach(pos);
    }

    fn approaching(&self, axis: Axis) -> bool {
        self.homing
            .current
            .and_then(|h| h.current())
            .is_some_and(|m| m.stop_at_switch && m.axis == axis)
    }

    /// The approach ended at `pos`: the rest of the move is dropped, the barrier kept.
    fn end_approach(&mut self, pos: StepPos) {
        let barrier = self.planner.barrier();
        self.planner.clear(pos);
        match barrier {
            Barrier::None => {}
            Barrier::NextMark => self.planner.set_barrier_next_mark(),
            Barrier::At(id) => self.planner.set_barrier(id),
        }
        self.planner.exec_done();
        if let Some(h) = self.homing.current.as_mut() {
            h.finished(MoveEnd::Triggered);
        }
    }

    /// The switches as last reported, bit i = axis i pressed.
    pub(in crate::printer) fn endstops(&self) -> u8 {
        self.homing.endstops
    }

    /// The board's step queue still holds or runs events of the executive.
    pub(in crate::printer) fn set_steps_in_flight(&mut self, in_flight: bool) {
        self.homing.steps_in_flight = in_flight;
    }

    /// Bit i set: the running approach ends at axis i's switch.
    pub(in crate::printer) fn homing_watch(&self) -> u8 {
        self.homing
            .current
            .and_then(|h| h.current())
            .filter(|m| m.stop_at_switch)
            .map_or(0, |m| 1 << m.axis.index())
    }

    /// Read the switches (M119, idle): not during an approach, whose switch the driver watches.
    pub(in crate::printer) fn sample_endstops(&mut self, e: &mut impl Endstops) {
        if self.homing_watch() != 0 {
            return;
        }
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let bit = 1u8 << axis.index();
            if e.triggered(axis) {
                self.homing.endstops |= bit;
            } else {
                self.homing.endstops &= !bit;
            }
        }
    }

    /// Axes homed and not lost since (bit i = axis i).
    pub(in crate::printer) fn homed_axes(&self) -> u8 {
        self.homing.homed.homed & !self.position_lost
    }

    /// Axes homed since the last call.
    pub(in crate::printer) fn take_homed(&mut self) -> u8 {
        core::mem::take(&mut self.homing.homed.fresh)
    }

    /// Forget a G28 in progress (M112, M410); whether there was one.
    pub(in crate::printer) fn abort_homing(&mut self) -> bool {
        self.homing.abort()
    }

    /// G28 of the axes in `mask` at the front of the queue (motion idle): the next homing move
    /// into the planner, or the axes set at their minimum. Without endstops the home corner is
    /// trusted: one move to the axes' minimum.
    pub(in crate::printer) fn home(
        &mut self,
        mask: u8,
        cfg: &MachineConfig,
        feed_mm_s: f32,
    ) -> HomeStep {
        let Some(hc) = self.homing.cfg else {
            let mut target = self.stepgen.position();
            for ax in [Axis::X, Axis::Y, Axis::Z] {
                if mask & (1 << ax.index()) != 0 {
                    target[ax.index()] = steps_at(cfg, ax, cfg.axis(ax).min_mm);
                }
            }
            self.position_lost &= !mask;
            let req = MoveRequest {
                target,
                feed_mm_s,
                seq: u32::MAX,
            };
            let _ = self.planner.push_move(cfg, &req, BlockKind::Homing);
            return HomeStep::Done;
        };
        if !self.idle() || self.homing.steps_in_flight {
            return HomeStep::Moving;
        }
        let mut h = self
            .homing
            .current
            .unwrap_or_else(|| Homing::new(mask, &hc, cfg));
        let step = loop {
            if let Some(m) = h.current() {
                let switch = self.homing.endstops & (1 << m.axis.index()) != 0;
                h.finished(MoveEnd::Completed { switch });
            }
            match h.next_step() {
                Next::Move(m) => {
                    if m.stop_at_switch && self.homing.endstops & (1 << m.axis.index()) != 0 {
                        h.finished(MoveEnd::Triggered);
                        continue;
                    }
                    let mut target = self.stepgen.position();
                    let spm = cfg.axis(m.axis).steps_per_mm;
                    let d = libm::roundf(m.distance_mm * spm) as i32;
                    let i = m.axis.index();
                    target[i] = target[i].saturating_add(d);
                    let req = MoveRequest {
                        target,
                        feed_mm_s: m.feed_mm_s,
                        seq: u32::MAX,
                    };
                    let _ = self.planner.push_move(cfg, &req, BlockKind::Homing);
                    break HomeStep::Moving;
                }
                Next::Homed(axis) => {
                    let mut pos = self.stepgen.position();
                    let a = cfg.axis(axis);
                    pos[axis.index()] = libm::roundf(a.min_mm * a.steps_per_mm) as i32;
                    self.set_position(pos);
                    self.position_lost &= !(1 << axis.index());
                    self.homing.homed.homed |= 1 << axis.index();
                    self.homing.homed.fresh |= 1 << axis.index();
                }
                Next::Done => break HomeStep::Done,
                Next::Failed(e) => break HomeStep::Failed(e),
            }
        };
        self.homing.current = (step == HomeStep::Moving).then_some(h);
        step
    }
}

/// `mm` on `axis` in whole steps (clamped to the step range).
pub(in crate::printer) fn steps_at(cfg: &MachineConfig, axis: Axis, mm: f32) -> i32 {
    let v = libm::roundf(mm * cfg.axis(axis).steps_per_mm);
    if v.is_finite() {
        v.clamp(i32::MIN as f32, i32::MAX as f32) as i32
    } else {
        0
    }
}

/// The switches as the executive last saw them, for M119's lines.
pub(in crate::printer) struct Latched(pub(in crate::printer) u8);

impl Endstops for Latched {
    fn triggered(&mut self, axis: Axis) -> bool {
        self.0 & (1 << axis.index()) != 0
    }
}
