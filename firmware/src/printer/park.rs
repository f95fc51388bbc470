//! The pause machine's progress ([`super::state::Pause`]): has the head stopped, the park and
//! return sequences in the service lane, and the release of the held job.

use super::state::{AfterPark, AfterReturn, AfterStop, Held, Pause, Stop};
use super::{steps, PausedLines, Printer, Record, ServiceMove};
use crate::link::HostAction;
use crate::motion::Axis;
use crate::planner::Barrier;
use crate::printer::LAYER_PAUSE_IDLE_US;
use crate::stepgen::ExecBlock;

impl Printer {
    /// Whether the stopping pause has stopped (see [`Stop`]).
    fn stopped_for_pause(&mut self) -> bool {
        let Pause::Stopping { how, .. } = self.pause else {
            return false;
        };
        match how {
            Stop::Hold { after_homing: true } => false,
            _ if how.brakes() => {
                // Stopped: no step left in the loaded block (held mid-way), or between blocks
                // with nothing to brake through. A brake that ends exactly at the last queued
                // point may leave a rounding-sized exit speed with no block after it: the head
                // is at the end of the queued motion, and that is the stop (issue 14 item 7).
                self.stepgen.is_stopped()
                    && (self.stepgen.current().is_some()
                        || self.stepgen.exit_speed_mm_s() <= 0.0
                        || self.planner.is_empty()
                        || self.planner.at_barrier())
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
                            if let Pause::Stopping {
                                how: Stop::Barrier { layer },
                                ..
                            } = &mut self.pause
                            {
                                *layer = Some(mark.layer);
                            }
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

    /// Advance the pause machine: stop → park → parked, return → release.
    pub(super) fn update_pause(&mut self) {
        self.retire_finished();
        match &mut self.pause {
            Pause::Run | Pause::Parked { .. } | Pause::Halted => {}
            Pause::Stopping { how, then } => {
                let (how, then) = (*how, *then);
                if !self.stopped_for_pause() {
                    return;
                }
                // `stopped_for_pause` may have learnt the barrier's layer.
                let how = match self.pause {
                    Pause::Stopping { how, .. } => how,
                    _ => how,
                };
                let mid = self.stepgen.current().is_some();
                let block = self.stepgen.unload();
                self.stepgen.end_hold();
                let pos = self.stepgen.position();
                let t_us = self.t_us();
                let layer = match how {
                    Stop::Barrier { layer } => layer,
                    _ => None,
                };
                self.record(Record::Stopped {
                    pos,
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
                let held = Held {
                    block,
                    pos,
                    retracted_steps: 0,
                    mode: how.mode(),
                    before_layer: layer,
                };
                match then {
                    AfterStop::Continue => self.release(held.block),
                    AfterStop::Park => {
                        self.pause = Pause::Parking {
                            held,
                            then: AfterPark::Wait,
                        };
                        self.start_park();
                    }
                    AfterStop::Cancel => {
                        self.pause = Pause::Parking {
                            held,
                            then: AfterPark::Cancel,
                        };
                        self.drop_job();
                        self.start_park();
                    }
                }
            }
            Pause::Parking { held, then } => {
                if !self.service.is_empty() || self.stepgen.current().is_some() {
                    return;
                }
                let (held, then) = (*held, *then);
                if then == AfterPark::Cancel {
                    self.finish_cancel();
                    return;
                }
                // Manual commands while paused are interpreted in a copy of the job's modal
                // state that starts at the parked position: they cannot change what the job
                // resumes with. (Job lines while paused keep using the job's state.)
                let manual = (self.policy.paused_lines != PausedLines::Queue).then(|| {
                    let mut m = self.machine;
                    let here = self.stepgen.position();
                    m.set_position_steps(&here, &self.cfg);
                    m
                });
                self.pause = Pause::Parked { held, manual };
                self.on_parked();
                self.thermal.pause_idle_start(self.now_us);
                self.action(HostAction::Paused);
                if then == AfterPark::Resume {
                    self.start_resume();
                }
            }
            Pause::Returning { held, reheat, then } => {
                if !self.service.is_empty() || self.stepgen.current().is_some() || *reheat {
                    return;
                }
                let (held, then) = (*held, *then);
                if then == AfterReturn::Cancel {
                    self.finish_cancel();
                    return;
                }
                // Logical E: the job continues from the held E count (no E jump).
                let mut pos = self.stepgen.position();
                pos[Axis::E.index()] = held.pos[Axis::E.index()];
                self.stepgen.set_position(pos);
                self.release(held.block);
                self.action(HostAction::Resumed);
                if let AfterReturn::Pause(m) = then {
                    self.request_pause(m);
                }
            }
        }
    }

    /// Release the held job: the interrupted block (if any) continues from standstill, the
    /// planner's barrier goes, and the pause machine is back at [`Pause::Run`].
    fn release(&mut self, block: Option<ExecBlock>) {
        let rem = block.map(|e| {
            let b = e.planned.block;
            (e.remaining_mm(), b.accel_mm_s2, b.base_v2)
        });
        let exit = self.planner.release(rem);
        if let Some(mut e) = block {
            e.planned.block.nominal_v2 = e.planned.block.base_v2;
            self.stepgen.restore(e);
            let now = self.now_ns();
            self.stepgen.resume_held(exit, now);
        }
        self.pause = Pause::Run;
        self.feed_planner();
        // A schedule that came due while this pause was in progress stops at its boundary.
        self.schedule_queued_marks();
    }

    /// Queue the park in the service lane: retract, lift, park (XY only when X/Y are trusted).
    fn start_park(&mut self) {
        self.service.clear();
        let c = self.cfg;
        let r = steps(&c, Axis::E, c.pause.retract_mm);
        let Some(held) = self.pause.held_mut() else {
            return;
        };
        held.retracted_steps = r;
        let p = held.pos;
        let mut cur = p;
        cur[Axis::E.index()] = cur[Axis::E.index()].wrapping_sub(r);
        let _ = self.service.push_back(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.retract_feed_mm_s,
        });
        let zmax = steps(&c, Axis::Z, c.axis(Axis::Z).max_mm);
        let lift = steps(&c, Axis::Z, c.pause.lift_z_mm);
        let z = Axis::Z.index();
        cur[z] = p[z].saturating_add(lift).min(zmax).max(p[z]);
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
        // Inside the travel whatever the configuration says (M760 checks its values).
        let park = |a, mm| steps(&c, a, super::guards::within_travel(&c, a, mm));
        cur[Axis::X.index()] = park(Axis::X, c.pause.park_x_mm);
        cur[Axis::Y.index()] = park(Axis::Y, c.pause.park_y_mm);
        let _ = self.service.push_back(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.park_feed_mm_s,
        });
    }

    /// From parked: queue the return (XY, then Z, then un-retract) and announce it. Host lines
    /// from here on are job lines again, interpreted in the job's modal state (the manual copy
    /// goes with the `Parked` state).
    pub(super) fn start_resume(&mut self) {
        let Pause::Parked { held, .. } = self.pause else {
            return;
        };
        // A nozzle cooled by the pause idle timeout must be hot again before the return.
        let reheat = self.thermal.pause_idle_end().is_some();
        self.pause = Pause::Returning {
            held,
            reheat,
            then: AfterReturn::Print,
        };
        self.on_job_continues();
        self.service.clear();
        let p = held.pos;
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
        cur[Axis::E.index()] = cur[Axis::E.index()].wrapping_add(held.retracted_steps);
        let _ = self.service.push_back(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.retract_feed_mm_s,
        });
        self.action(HostAction::Resume);
    }
}
