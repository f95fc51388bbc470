//! The pause state machine: requests (pause, resume, cancel, stops), the stop detection, the
//! park and return sequences in the service lane, and the release of the held blocks.

use super::{steps, PausedLines, Phase, Printer, Record, ServiceMove};
use crate::link::HostAction;
use crate::motion::{Axis, PauseMode};
use crate::planner::{Barrier, BlockKind};
use crate::printer::LAYER_PAUSE_IDLE_US;

impl Printer {
    pub(super) fn begin_hold(&mut self) {
        if self
            .stepgen
            .current()
            .is_some_and(|e| e.planned.block.kind == BlockKind::Homing && !e.finished())
        {
            self.hold_deferred = true;
            self.mode = Some(PauseMode::Now);
            return;
        }
        let now = self.now_ns();
        let v = self.stepgen.hold(now);
        let a = self
            .stepgen
            .current()
            .map_or(0.0, |e| e.planned.block.accel_mm_s2);
        self.mode = Some(PauseMode::Now);
        let t_us = self.t_us();
        self.record(Record::Brake {
            v_mm_s: v,
            accel_mm_s2: a,
            t_us,
        });
    }

    pub(super) fn request_pause(&mut self, mode: PauseMode) {
        match self.phase {
            Phase::Run => {
                // An idle printer is still in a job while the host streams it (between lines,
                // or at a boundary the host drained with M400): the pause is taken unless
                // nothing has moved or arrived for `LAYER_PAUSE_IDLE_US`.
                let idle_us = self.now_us.saturating_sub(self.last_activity_us);
                if !self.has_work()
                    && (self.cancelled
                        || self.last_activity_us == 0
                        || idle_us >= LAYER_PAUSE_IDLE_US)
                {
                    self.say(format_args!("pause: nothing to pause"));
                    return;
                }
                self.phase = Phase::Stopping;
                self.withdraw_after_stop = false;
                if self.policy.pause_at_tail {
                    self.mode = Some(mode);
                    self.fifo_countdown = Some(self.cmds.len());
                    self.feed_planner();
                    self.say(format_args!("pause queued behind the buffered moves"));
                    return;
                }
                match mode {
                    PauseMode::Layer => {
                        self.mode = Some(PauseMode::Layer);
                        if let Some((id, m)) = self.planner.first_reachable_mark() {
                            self.planner.set_barrier(id);
                            self.barrier_layer = Some(m.layer);
                            self.say(format_args!("pause: stopping before layer {}", m.layer));
                        } else {
                            self.planner.set_barrier_next_mark();
                            self.say(format_args!("pause: stopping at the next layer"));
                        }
                        if self.cfg.pause.speedup_factor > 1.0 {
                            self.planner.speed_up();
                            let t_us = self.t_us();
                            self.record(Record::SpeedUp { t_us });
                        }
                    }
                    PauseMode::Now => {
                        self.begin_hold();
                        self.say(format_args!("pause: stopping now"));
                    }
                }
            }
            Phase::Stopping => {
                if mode == PauseMode::Now
                    && self.mode == Some(PauseMode::Layer)
                    && !self.policy.pause_at_tail
                {
                    self.begin_hold();
                    self.say(format_args!("pause: stopping now"));
                } else {
                    self.say(format_args!("pause already in progress"));
                }
                self.withdraw_after_stop = false;
            }
            Phase::Parking | Phase::Parked => {
                self.say(format_args!("already paused"));
            }
            Phase::Returning => {
                self.deferred_pause = Some(mode);
                self.say(format_args!("pause deferred until the resume completes"));
            }
        }
    }

    pub(super) fn request_resume(&mut self) {
        match self.phase {
            Phase::Parked => self.start_resume(),
            Phase::Parking => {
                self.deferred_resume = true;
                self.say(format_args!("resume deferred until parked"));
            }
            Phase::Stopping => {
                if self.mode == Some(PauseMode::Now) || self.hold_deferred {
                    self.withdraw_after_stop = true;
                } else {
                    self.planner.clear_barrier();
                    self.fifo_countdown = None;
                    self.phase = Phase::Run;
                    self.mode = None;
                    self.barrier_layer = None;
                }
                self.say(format_args!("pause withdrawn"));
            }
            Phase::Run => self.say(format_args!("not paused")),
            Phase::Returning => self.say(format_args!("already resuming")),
        }
    }

    pub(super) fn drop_job(&mut self) {
        let cmds = self.cmds.len();
        let held = usize::from(self.held.take().is_some());
        let pos = self.stepgen.position();
        let (blocks, segs, marks) = self.planner.clear(pos);
        self.cmds.clear();
        self.pay_sync_ok();
        self.arc = None;
        self.fifo_countdown = None;
        self.schedule = None;
        self.action(HostAction::Cancel);
        self.say(format_args!(
            "cancelled: dropped {} commands, {} blocks, {} uncut segments, {} layer marks",
            cmds,
            blocks + held,
            segs,
            marks
        ));
    }

    pub(super) fn request_cancel(&mut self) {
        match self.phase {
            Phase::Parked => {
                self.drop_job();
                self.finish_cancel();
            }
            Phase::Parking => {
                self.drop_job();
                self.cancel_pending = true;
            }
            Phase::Returning => {
                self.service.clear();
                self.drop_job();
                self.cancel_pending = true;
            }
            Phase::Stopping | Phase::Run => {
                if !self.has_work() {
                    self.say(format_args!("nothing to cancel"));
                    return;
                }
                self.cancel_pending = true;
                self.phase = Phase::Stopping;
                if self.mode != Some(PauseMode::Now) {
                    self.begin_hold();
                }
            }
        }
    }

    pub(super) fn finish_cancel(&mut self) {
        self.phase = Phase::Run;
        self.mode = None;
        self.cancel_pending = false;
        self.cancelled = true;
        self.deferred_pause = None;
        self.deferred_resume = false;
        self.held = None;
        self.barrier_layer = None;
        if let Some(m) = self.saved_machine.take() {
            self.machine = m;
        }
        let pos = self.stepgen.position();
        self.planner.clear(pos);
        self.planner.exec_done();
        self.machine.set_position_steps(&pos, &self.cfg);
        self.thermal.pause_idle_end();
    }

    pub(super) fn emergency_stop(&mut self) {
        self.halted = true;
        self.thermal.kill(self.now_us);
        self.arc = None;
        let _ = self.stepgen.unload();
        let pos = self.stepgen.position();
        self.planner.clear(pos);
        self.cmds.clear();
        self.sync_ok_owed = false;
        self.service.clear();
        self.held = None;
        self.say(format_args!(
            "emergency stop (M112): motors and heaters off, reset required"
        ));
    }

    pub(super) fn quick_stop(&mut self) {
        let _ = self.stepgen.unload();
        self.stepgen.end_hold();
        let pos = self.stepgen.position();
        let (blocks, segs, _) = self.planner.clear(pos);
        self.planner.exec_done();
        self.service.clear();
        self.held = None;
        self.phase = Phase::Run;
        self.mode = None;
        self.barrier_layer = None;
        self.fifo_countdown = None;
        self.arc = None;
        if let Some(m) = self.saved_machine.take() {
            self.machine = m;
        }
        self.machine.set_position_steps(&pos, &self.cfg);
        self.say(format_args!(
            "quick stop (M410): dropped {} blocks, {} uncut segments",
            blocks, segs
        ));
    }

    pub(super) fn stopped_for_pause(&mut self) -> bool {
        if self.hold_deferred {
            return false;
        }
        match self.mode {
            Some(PauseMode::Now) => {
                self.stepgen.is_stopped()
                    && (self.stepgen.current().is_some() || self.stepgen.exit_speed_mm_s() <= 0.0)
            }
            _ => {
                if self.stepgen.current().is_some() {
                    return false;
                }
                if self.planner.at_barrier() {
                    return true;
                }
                // The job ended before any layer boundary: stop at its end.
                if self.planner.barrier() == Barrier::NextMark
                    && self.cmds.is_empty()
                    && self.planner.is_empty()
                    && self.now_us.saturating_sub(self.last_activity_us) >= LAYER_PAUSE_IDLE_US
                {
                    // A marker comment seen but no motion after it: the head is at that
                    // boundary (the host stopped streaming there).
                    if let Some(mark) = self.layers.finish() {
                        if let Ok(true) = self.planner.push_mark(mark) {
                            self.barrier_layer = Some(mark.layer);
                            return true;
                        }
                    }
                    let id = self.planner.next_id();
                    self.planner.set_barrier(id);
                    return true;
                }
                false
            }
        }
    }

    pub(super) fn update_pause(&mut self) {
        self.retire_finished();
        match self.phase {
            Phase::Run => {
                if !self.has_work() && self.fifo_countdown.is_none() {
                    // Idle: nothing to do.
                }
            }
            Phase::Stopping => {
                if !self.stopped_for_pause() {
                    return;
                }
                let mid = self.stepgen.current().is_some();
                self.held = self.stepgen.unload();
                self.stepgen.end_hold();
                self.held_pos = self.stepgen.position();
                let t_us = self.t_us();
                let layer = if self.mode == Some(PauseMode::Now) {
                    None
                } else {
                    self.barrier_layer
                };
                self.record(Record::Stopped {
                    pos: self.held_pos,
                    layer,
                    mid_block: mid,
                    t_us,
                });
                // A layer stop at a boundary the schedule asks for meets the schedule too.
                if layer.is_some() {
                    if let Some((_, m)) = self.planner.first_mark() {
                        if self.schedule_hit(&m) {
                            self.schedule = None;
                            self.say(format_args!(
                                "scheduled pause met by this pause (layer {})",
                                m.layer
                            ));
                        }
                    }
                }
                if self.withdraw_after_stop && !self.cancel_pending {
                    self.withdraw_after_stop = false;
                    self.release_held();
                    return;
                }
                if self.cancel_pending {
                    self.drop_job();
                }
                self.start_park();
            }
            Phase::Parking => {
                if !self.service.is_empty() || self.stepgen.current().is_some() {
                    return;
                }
                if self.cancel_pending {
                    self.finish_cancel();
                    return;
                }
                self.phase = Phase::Parked;
                if self.policy.paused_lines == PausedLines::Manual {
                    // The job's modal state is kept aside; manual commands while paused start
                    // from the parked position and cannot change what the job resumes with.
                    // (With `Queue`, lines while paused are job lines: the state runs on.)
                    self.saved_machine = Some(self.machine);
                    let here = self.stepgen.position();
                    self.machine.set_position_steps(&here, &self.cfg);
                }
                self.thermal.pause_idle_start(self.now_us);
                self.action(HostAction::Paused);
                if self.deferred_resume {
                    self.deferred_resume = false;
                    self.start_resume();
                }
            }
            Phase::Parked => {}
            Phase::Returning => {
                if !self.service.is_empty() || self.stepgen.current().is_some() || self.reheat_wait
                {
                    return;
                }
                if self.cancel_pending {
                    self.finish_cancel();
                    return;
                }
                // Logical E: the job continues from the held E count (no E jump).
                let mut pos = self.stepgen.position();
                pos[Axis::E.index()] = self.held_pos[Axis::E.index()];
                self.stepgen.set_position(pos);
                self.release_held();
                self.action(HostAction::Resumed);
                if let Some(m) = self.deferred_pause.take() {
                    self.request_pause(m);
                }
            }
        }
    }

    pub(super) fn release_held(&mut self) {
        let rem = self.held.map(|e| {
            let b = e.planned.block;
            (e.remaining_mm(), b.accel_mm_s2, b.base_v2)
        });
        let exit = self.planner.release(rem);
        if let Some(mut e) = self.held.take() {
            e.planned.block.nominal_v2 = e.planned.block.base_v2;
            self.stepgen.restore(e);
            let now = self.now_ns();
            self.stepgen.resume_held(exit, now);
        }
        self.phase = Phase::Run;
        self.mode = None;
        self.barrier_layer = None;
        self.feed_planner();
        // A schedule that came due while this pause was in progress stops at its boundary.
        self.schedule_queued_marks();
    }

    pub(super) fn start_park(&mut self) {
        self.phase = Phase::Parking;
        self.service.clear();
        let p = self.held_pos;
        let c = self.cfg;
        let r = steps(&c, Axis::E, c.pause.retract_mm);
        self.retracted_steps = r;
        let mut cur = p;
        cur[Axis::E.index()] = cur[Axis::E.index()].wrapping_sub(r);
        let _ = self.service.push_back(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.retract_feed_mm_s,
        });
        let zmax = steps(&c, Axis::Z, c.axis(Axis::Z).max_mm);
        let lift = steps(&c, Axis::Z, c.pause.lift_z_mm);
        cur[Axis::Z.index()] = p[Axis::Z.index()].saturating_add(lift).min(zmax).max(p[2]);
        let _ = self.service.push_back(ServiceMove {
            target: cur,
            feed_mm_s: c.axis(Axis::Z).max_feed_mm_s,
        });
        if self.position_lost & 0b011 != 0 {
            // X/Y not homed since their motors were off: a park to bed coordinates could
            // drive into a frame end. Retract and lift only.
            self.say(format_args!(
                "pause: X/Y position lost (M18/M84), not parking"
            ));
            return;
        }
        cur[Axis::X.index()] = steps(&c, Axis::X, c.pause.park_x_mm);
        cur[Axis::Y.index()] = steps(&c, Axis::Y, c.pause.park_y_mm);
        let _ = self.service.push_back(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.park_feed_mm_s,
        });
    }

    pub(super) fn start_resume(&mut self) {
        self.phase = Phase::Returning;
        // From here on host lines are job lines again (they queue behind the held blocks while
        // the head returns): they must be interpreted in the job's modal state, not in the
        // parked one manual commands used.
        if let Some(m) = self.saved_machine.take() {
            self.machine = m;
        }
        // A nozzle cooled by the pause idle timeout must be hot again before the return.
        self.reheat_wait = self.thermal.pause_idle_end().is_some();
        self.service.clear();
        let p = self.held_pos;
        let c = self.cfg;
        let mut cur = self.stepgen.position();
        cur[Axis::X.index()] = p[Axis::X.index()];
        cur[Axis::Y.index()] = p[Axis::Y.index()];
        let _ = self.service.push_back(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.park_feed_mm_s,
        });
        cur[Axis::Z.index()] = p[Axis::Z.index()];
        let _ = self.service.push_back(ServiceMove {
            target: cur,
            feed_mm_s: c.axis(Axis::Z).max_feed_mm_s,
        });
        cur[Axis::E.index()] = cur[Axis::E.index()].wrapping_add(self.retracted_steps);
        let _ = self.service.push_back(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.retract_feed_mm_s,
        });
        self.action(HostAction::Resume);
    }
}
