//! The pause machine's progress: has the head stopped, the park and return sequences in the
//! service lane, and the release of the held job.

use super::state::{AfterPark, AfterReturn, AfterStop, Held, Pause, Stop};
use super::{Events, PauseCtl, PauseEvent};
use crate::link::HostAction;
use crate::motion::{Axis, LayerMark};
use crate::printer::cx::Cx;
use crate::printer::guards::within_travel;
use crate::printer::heat::Heat;
use crate::printer::motion::homing::steps_at;
use crate::printer::motion::service::ServiceMove;
use crate::printer::motion::Motion;
use crate::printer::types::Record;
use crate::thermal::HeaterId;

impl PauseCtl {
    /// Whether the stopping pause has stopped (see [`Stop`]).
    fn stopped(&self, cx: &Cx) -> bool {
        let Pause::Stopping { how, .. } = self.state else {
            return false;
        };
        match how {
            Stop::Hold { after_homing: true } => false,
            Stop::Hold { .. } => cx.motion.hold_stopped(),
            Stop::Barrier { .. } | Stop::Tail { .. } => cx.motion.at_barrier(),
        }
    }

    /// A layer pause waits for a boundary that will not come: nothing executes or is planned,
    /// the barrier waits for a mark that has not entered the planner. The executive then
    /// decides whether the job has ended ([`PauseCtl::stop_at_job_end`]).
    pub(in crate::printer) fn waits_for_a_mark(&self, motion: &Motion) -> bool {
        matches!(
            self.state,
            Pause::Stopping {
                how: Stop::Barrier { .. },
                ..
            }
        ) && !motion.executing()
            && motion.barrier_waits_for_mark()
            && motion.idle()
    }

    /// The job ended before any layer boundary: the stop is at its end — at the boundary of a
    /// marker comment seen with no motion after it (`mark`), else where the head is.
    pub(in crate::printer) fn stop_at_job_end(&mut self, mark: Option<LayerMark>, cx: &mut Cx) {
        if let Some(mark) = mark {
            if let Ok(true) = cx.motion.push_mark(mark) {
                self.barrier_at(mark.layer);
                return;
            }
        }
        cx.motion.barrier_here();
    }

    /// The barrier now stands at layer mark `layer` (it entered the planner).
    pub(in crate::printer) fn barrier_at(&mut self, layer: u32) {
        if let Pause::Stopping {
            how: Stop::Barrier { layer: l },
            ..
        } = &mut self.state
        {
            *l = Some(layer);
        }
    }

    /// Advance the pause machine: stop → park → parked, return → release.
    pub(in crate::printer) fn update(&mut self, cx: &mut Cx) -> Events {
        let mut ev = Events::default();
        match self.state {
            Pause::Run | Pause::Parked { .. } | Pause::Halted => {}
            Pause::Stopping { how, mode, then } => {
                if !self.stopped(cx) {
                    return ev;
                }
                let mid = cx.motion.executing();
                let stop = cx.motion.take_stop();
                let t_us = cx.t_us();
                let layer = match how {
                    Stop::Barrier { layer } => layer,
                    _ => None,
                };
                cx.record(Record::Stopped {
                    pos: stop.pos,
                    layer,
                    mid_block: mid,
                    t_us,
                });
                // A layer stop at a boundary the schedule asks for meets the schedule too.
                if layer.is_some() {
                    if let Some(m) = cx.motion.first_mark() {
                        if self.schedule_hit(&m) {
                            self.schedule = None;
                            cx.host.say(format_args!(
                                "scheduled pause met by this pause (layer {})",
                                m.layer
                            ));
                        }
                    }
                }
                let held = Held {
                    block: stop.block,
                    pos: stop.pos,
                    retracted_steps: 0,
                    mode,
                    before_layer: layer,
                };
                match then {
                    AfterStop::Continue => self.release(held.block, false, None, cx, &mut ev),
                    AfterStop::Park => {
                        self.state = Pause::Parking {
                            held,
                            then: AfterPark::Wait,
                        };
                        self.start_park(cx);
                    }
                    AfterStop::Cancel => {
                        self.state = Pause::Parking {
                            held,
                            then: AfterPark::Cancel,
                        };
                        self.drop_job(cx, &mut ev);
                        self.start_park(cx);
                    }
                }
            }
            Pause::Parking { held, then } => {
                if cx.motion.service_busy() {
                    return ev;
                }
                if then == AfterPark::Cancel {
                    self.finish_cancel(cx, &mut ev);
                    return ev;
                }
                self.state = Pause::Parked { held };
                cx.heat.thermal_mut().pause_idle_start(cx.now_us);
                cx.host.action(HostAction::Paused);
                ev.push(PauseEvent::Parked {
                    mode: held.mode,
                    resume: then == AfterPark::Resume,
                });
            }
            Pause::Returning { held, reheat, then } => {
                if cx.motion.service_busy() || reheat {
                    return ev;
                }
                if then == AfterReturn::Cancel {
                    self.finish_cancel(cx, &mut ev);
                    return ev;
                }
                // Logical E: the job continues from the held E count (no E jump).
                let mut pos = cx.motion.position();
                pos[Axis::E.index()] = held.pos[Axis::E.index()];
                cx.motion.set_stepper_position(pos);
                let repause = match then {
                    AfterReturn::Pause(m) => Some(m),
                    _ => None,
                };
                self.release(held.block, true, repause, cx, &mut ev);
            }
        }
        ev
    }

    /// The service lane's next move may start: a return waits for the heaters the pause's
    /// timeout (or a console line while parked) took off the job's targets (the reheat)
    /// before it moves.
    pub(in crate::printer) fn service_lane_ready(&mut self, heat: &Heat) -> bool {
        if let Pause::Returning { reheat, .. } = &mut self.state {
            if *reheat {
                if !(heat.reached(HeaterId::Hotend) && heat.reached(HeaterId::Bed)) {
                    return false;
                }
                *reheat = false;
            }
        }
        true
    }

    /// Release the held job: the interrupted block (if any) continues from standstill, the
    /// planner's barrier goes, and the pause machine is back at [`Pause::Run`] (`resumed`:
    /// from a park; `repause`: a pause that waited for the return).
    fn release(
        &mut self,
        block: Option<crate::stepgen::ExecBlock>,
        resumed: bool,
        repause: Option<crate::motion::PauseMode>,
        cx: &mut Cx,
        ev: &mut Events,
    ) {
        let now = cx.now_ns();
        cx.motion.release(block, now);
        self.state = Pause::Run;
        ev.push(PauseEvent::Released { resumed, repause });
    }

    /// A resume that came while parking, once the parked state has been noted.
    pub(in crate::printer) fn resume_deferred(&mut self, cx: &mut Cx) -> Events {
        let mut ev = Events::default();
        self.start_resume(cx, &mut ev);
        ev
    }

    /// Queue the park in the service lane: retract, lift, park (XY only when X/Y are trusted).
    fn start_park(&mut self, cx: &mut Cx) {
        cx.motion.clear_service();
        let c = cx.cfg;
        let r = steps_at(c, Axis::E, c.pause.retract_mm);
        let Some(held) = self.state.held_mut() else {
            return;
        };
        held.retracted_steps = r;
        let p = held.pos;
        let mut cur = p;
        cur[Axis::E.index()] = cur[Axis::E.index()].wrapping_sub(r);
        cx.motion.push_service(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.retract_feed_mm_s,
        });
        let zmax = steps_at(c, Axis::Z, c.axis(Axis::Z).max_mm);
        let lift = steps_at(c, Axis::Z, c.pause.lift_z_mm);
        let z = Axis::Z.index();
        cur[z] = p[z].saturating_add(lift).min(zmax).max(p[z]);
        cx.motion.push_service(ServiceMove {
            target: cur,
            feed_mm_s: c.axis(Axis::Z).max_feed_mm_s,
        });
        if cx.motion.position_lost() & 0b011 != 0 {
            // X/Y not homed since their motors were off: a park to bed coordinates could
            // drive into a frame end. Retract and lift only.
            cx.host.say(format_args!(
                "pause: X/Y position lost (M18/M84), not parking"
            ));
            return;
        }
        // Inside the travel whatever the configuration says (M760 checks its values).
        let park = |a, mm| steps_at(c, a, within_travel(c, a, mm));
        cur[Axis::X.index()] = park(Axis::X, c.pause.park_x_mm);
        cur[Axis::Y.index()] = park(Axis::Y, c.pause.park_y_mm);
        cx.motion.push_service(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.park_feed_mm_s,
        });
    }

    /// From parked: queue the return (XY, then Z, then un-retract) and announce it. The
    /// heaters go back to the job's targets of the park; one the pause's timeout or a console
    /// line changed is heated again first (the return waits for it).
    pub(super) fn start_resume(&mut self, cx: &mut Cx, ev: &mut Events) {
        let Pause::Parked { held } = self.state else {
            return;
        };
        let reheat = cx.heat.thermal_mut().pause_idle_end().is_some();
        self.state = Pause::Returning {
            held,
            reheat,
            then: AfterReturn::Print,
        };
        ev.push(PauseEvent::ResumeStarted);
        cx.motion.clear_service();
        let p = held.pos;
        let c = cx.cfg;
        let mut cur = cx.motion.position();
        cur[Axis::X.index()] = p[Axis::X.index()];
        cur[Axis::Y.index()] = p[Axis::Y.index()];
        cx.motion.push_service(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.park_feed_mm_s,
        });
        cur[Axis::Z.index()] = p[Axis::Z.index()];
        cx.motion.push_service(ServiceMove {
            target: cur,
            feed_mm_s: c.axis(Axis::Z).max_feed_mm_s,
        });
        cur[Axis::E.index()] = cur[Axis::E.index()].wrapping_add(held.retracted_steps);
        cx.motion.push_service(ServiceMove {
            target: cur,
            feed_mm_s: c.pause.retract_feed_mm_s,
        });
        cx.host.action(HostAction::Resume);
    }

    /// A power-cut resume (M1000) returns to the kept job's boundary as a resume from a park
    /// at `held` does.
    pub(in crate::printer) fn resume_kept(&mut self, held: Held, cx: &mut Cx) -> Events {
        self.state = Pause::Parked { held };
        self.resume_deferred(cx)
    }

    /// The next block's lane while a pause holds the job: `true` for the service lane (the
    /// held job waits), `false` for job blocks (stopping: a layer or tail stop runs to its
    /// barrier; a feed hold brakes through the next blocks while it has speed, or waits for
    /// a homing move); `None` when nothing may be loaded (braked to a stop, halted).
    pub(in crate::printer) fn lane(&self, motion: &Motion) -> Option<bool> {
        match self.state {
            Pause::Run => Some(false),
            Pause::Stopping { how, .. } => {
                let job = !how.brakes()
                    || matches!(how, Stop::Hold { after_homing: true })
                    || motion.braking_on();
                job.then_some(false)
            }
            Pause::Parking { .. } | Pause::Parked { .. } | Pause::Returning { .. } => Some(true),
            Pause::Halted => None,
        }
    }

    /// The conventional tail stop: one command entered the planner (the countdown), and
    /// whether the barrier is due now (nothing of the job before it is still to be cut).
    pub(in crate::printer) fn command_fed(&mut self) {
        if let Pause::Stopping {
            how: Stop::Tail { countdown: Some(n) },
            ..
        } = &mut self.state
        {
            *n = n.saturating_sub(1);
        }
    }

    /// The tail stop's countdown has run out.
    pub(in crate::printer) fn tail_due(&self) -> bool {
        matches!(
            self.state,
            Pause::Stopping {
                how: Stop::Tail { countdown: Some(0) },
                ..
            }
        )
    }

    /// The tail stop's barrier goes behind everything planned now.
    pub(in crate::printer) fn set_tail_barrier(&mut self, cx: &mut Cx) {
        if let Pause::Stopping {
            how: Stop::Tail { countdown },
            ..
        } = &mut self.state
        {
            if *countdown == Some(0) {
                *countdown = None;
                cx.motion.barrier_here();
            }
        }
    }

    /// M0/M600 reached the front of the queue: stop once everything before it has run.
    pub(in crate::printer) fn pause_here(&mut self, cx: &mut Cx) {
        if matches!(self.state, Pause::Run) {
            cx.motion.barrier_here();
            self.state = Pause::Stopping {
                how: Stop::Barrier { layer: None },
                mode: crate::motion::PauseMode::Layer,
                then: AfterStop::Park,
            };
            cx.host.say(format_args!(
                "pause here (M0/M600): stopping after the queued moves"
            ));
        }
    }
}
