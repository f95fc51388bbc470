//! The pause, as the executive owns it: the pause machine's state ([`Pause`], one enum whose
//! variants carry their data), the pause schedule (M761), and what they do to motion — the
//! layer barrier and its speed-up, the feed hold, the park and return in the service lane, the
//! release of the held job. It drives the motion and heat parts it is lent ([`Cx`]); what the
//! other parts must do (drop the queued job for a cancel, keep the paused-job record, take
//! manual lines while parked...) it returns as [`PauseEvent`]s, which the executive routes.
//!
//! ```text
//! Printing ─Pause(layer)─► Stopping: barrier at the next layer mark, rest of layer sped up
//! Printing ─Pause(now)───► Stopping: feed hold (brake at the block's acceleration)
//! Stopping ─stopped──────► Parking: retract, lift, park (service lane) ─► Paused
//! Paused ───Resume───────► Returning: XY, then Z, then un-retract ─► release held ─► Printing
//! ```
//!
//! Files: `state` (the state type), this one (requests: pause, resume, cancel, stops),
//! `park` (stop detection, park, return, release), `schedule` (M761).

mod park;
mod schedule;
mod state;

pub(super) use state::{AfterStop, Held, Pause, Stop};

use super::cx::Cx;
use super::motion::Dropped;
use super::types::{Record, Schedule};
use crate::motion::PauseMode;

/// What the pause asks of the other parts; drained by the executive after each call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum PauseEvent {
    /// A cancel dropped the planned job: the intake drops the rest (queue, spill, arc) and
    /// discards the stream's tail; the counts are for the message.
    JobDropped(Dropped),
    /// The cancel is complete, the head where it stopped: the job's modal state is there.
    CancelDone,
    /// Parked in this mode: manual lines are taken; a layer pause keeps its record. `resume`:
    /// a resume came while parking — the executive starts it ([`PauseCtl::resume_deferred`])
    /// once the parked state has been noted.
    Parked {
        /// The pause's mode.
        mode: PauseMode,
        /// A resume waits.
        resume: bool,
    },
    /// The return began: the paused-job record goes.
    ResumeStarted,
    /// The held job runs again. `resumed`: after a return (announce `//action:resumed`);
    /// `repause`: a pause asked for while returning, to request now.
    Released {
        /// Back from a park.
        resumed: bool,
        /// The pause that waited for the return.
        repause: Option<PauseMode>,
    },
}

/// What one call of the pause asks of the other parts, in order (a call produces at most two:
/// a cancel of a parked job drops it and completes).
#[derive(Clone, Copy, Debug, Default)]
#[must_use = "the other parts must do what the pause asks"]
pub(super) struct Events {
    list: [Option<PauseEvent>; 2],
}

impl Events {
    /// Nothing asked (the common case: the executive skips the routing).
    #[inline]
    pub(super) fn is_empty(&self) -> bool {
        self.list[0].is_none()
    }

    fn push(&mut self, e: PauseEvent) {
        if let Some(slot) = self.list.iter_mut().find(|s| s.is_none()) {
            *slot = Some(e);
        }
    }
}

impl IntoIterator for Events {
    type Item = PauseEvent;
    type IntoIter = core::iter::Flatten<core::array::IntoIter<Option<PauseEvent>, 2>>;

    fn into_iter(self) -> Self::IntoIter {
        self.list.into_iter().flatten()
    }
}

/// The pause part (see the module documentation).
#[derive(Clone, Debug)]
pub(super) struct PauseCtl {
    state: Pause,
    schedule: Option<Schedule>,
    /// A pause acts only after everything queued before it (the conventional policy).
    at_tail: bool,
}

impl PauseCtl {
    pub(super) const fn new() -> Self {
        Self {
            state: Pause::Run,
            schedule: None,
            at_tail: false,
        }
    }

    /// The conventional policy's pause at the tail, or ours.
    pub(super) fn set_at_tail(&mut self, at_tail: bool) {
        self.at_tail = at_tail;
    }

    /// The pause machine's state (read-only: it changes only here).
    pub(super) fn state(&self) -> &Pause {
        &self.state
    }

    /// Nothing paused, stopping or halted.
    pub(super) fn running(&self) -> bool {
        matches!(self.state, Pause::Run)
    }

    /// Parked, the held job waiting.
    pub(super) fn parked(&self) -> bool {
        matches!(self.state, Pause::Parked { .. })
    }

    /// The pause machine has somewhere to go by itself (stopping, parking, returning).
    pub(super) fn moving_on(&self) -> bool {
        matches!(
            self.state,
            Pause::Stopping { .. } | Pause::Parking { .. } | Pause::Returning { .. }
        )
    }

    /// Homing and position sets may run: no pause holds the job (a stopping one has not
    /// stopped yet: what runs before its barrier is part of the job).
    pub(super) fn may_home(&self) -> bool {
        matches!(self.state, Pause::Run | Pause::Stopping { .. })
    }

    /// The command at the front of the intake's queue may run now: no pause holds the job,
    /// or it is ahead of the stop (a layer barrier still waiting for its mark, a conventional
    /// tail stop's countdown). Everything queued behind a stop — moves, settings, waits,
    /// the end code — runs after the resume, in order, judged in the state it runs in.
    pub(super) fn queue_runs(&self, motion: &super::motion::Motion) -> bool {
        match self.state {
            Pause::Run => true,
            Pause::Stopping {
                how: Stop::Barrier { .. },
                then,
                ..
            } => then != AfterStop::Cancel && motion.barrier_waits_for_mark(),
            Pause::Stopping {
                how: Stop::Tail { countdown },
                then,
                ..
            } => then != AfterStop::Cancel && countdown.is_some_and(|n| n > 0),
            _ => false,
        }
    }

    /// Emergency-stopped.
    pub(super) fn halted(&self) -> bool {
        matches!(self.state, Pause::Halted)
    }

    /// Feed hold for the stopping pause: brake from the executing block on (the stop becomes
    /// [`Stop::Hold`]). While a homing move runs, the brake waits for its end.
    fn begin_hold(&mut self, cx: &mut Cx) {
        let homing = cx.motion.homing_move_running();
        if let Pause::Stopping { how, mode, .. } = &mut self.state {
            *how = Stop::Hold {
                after_homing: homing,
            };
            if *mode == PauseMode::Layer {
                *mode = PauseMode::Now;
            }
        }
        if homing {
            return;
        }
        let now = cx.now_ns();
        let b = cx.motion.hold(now);
        let t_us = cx.t_us();
        cx.record(Record::Brake {
            v_mm_s: b.v_mm_s,
            accel_mm_s2: b.accel_mm_s2,
            t_us,
        });
    }

    /// A homing move finished: a feed hold that waited for it brakes now.
    pub(super) fn homing_move_done(&mut self, cx: &mut Cx) {
        if matches!(
            self.state,
            Pause::Stopping {
                how: Stop::Hold { after_homing: true },
                ..
            }
        ) {
            self.begin_hold(cx);
        }
    }

    /// A pause request in `mode`. `in_job`: the printer is in a job (work queued or moving,
    /// or a host streaming one); `queued`: commands waiting before the planner (the tail
    /// stop's countdown).
    pub(super) fn request_pause(
        &mut self,
        mode: PauseMode,
        in_job: bool,
        queued: usize,
        cx: &mut Cx,
    ) {
        match &mut self.state {
            Pause::Run => {
                if !in_job {
                    cx.host.say(format_args!("pause: nothing to pause"));
                    return;
                }
                if self.at_tail {
                    self.state = Pause::Stopping {
                        how: Stop::Tail {
                            countdown: Some(queued),
                        },
                        mode,
                        then: AfterStop::Park,
                    };
                    cx.host
                        .say(format_args!("pause queued behind the buffered moves"));
                    return;
                }
                match mode {
                    PauseMode::Layer => {
                        let layer = cx.motion.barrier_at_reachable_mark().map(|m| m.layer);
                        match layer {
                            Some(l) => cx
                                .host
                                .say(format_args!("pause: stopping before layer {l}")),
                            None => {
                                cx.motion.barrier_at_next_mark();
                                cx.host
                                    .say(format_args!("pause: stopping at the next layer"));
                            }
                        }
                        self.state = Pause::Stopping {
                            how: Stop::Barrier { layer },
                            mode,
                            then: AfterStop::Park,
                        };
                        if cx.cfg.pause.speedup_factor > 1.0 {
                            cx.motion.speed_up();
                            let t_us = cx.t_us();
                            cx.record(Record::SpeedUp { t_us });
                        }
                    }
                    PauseMode::Now => {
                        self.state = Pause::Stopping {
                            how: Stop::Hold {
                                after_homing: false,
                            },
                            mode,
                            then: AfterStop::Park,
                        };
                        self.begin_hold(cx);
                        cx.host.say(format_args!("pause: stopping now"));
                    }
                }
            }
            Pause::Stopping { how, then, .. } => {
                // A new pause request takes back a withdrawal (never a cancel).
                if *then == AfterStop::Continue {
                    *then = AfterStop::Park;
                }
                if mode == PauseMode::Now && matches!(how, Stop::Barrier { .. }) {
                    self.begin_hold(cx);
                    cx.host.say(format_args!("pause: stopping now"));
                } else {
                    cx.host.say(format_args!("pause already in progress"));
                }
            }
            Pause::Parking { .. } | Pause::Parked { .. } => {
                cx.host.say(format_args!("already paused"));
            }
            Pause::Returning { then, .. } => {
                if *then != state::AfterReturn::Cancel {
                    *then = state::AfterReturn::Pause(mode);
                }
                cx.host
                    .say(format_args!("pause deferred until the resume completes"));
            }
            Pause::Halted => {}
        }
    }

    /// A resume request. `orphaned`: the held job's host went away (a resume would print the
    /// held lines and leave the head on the part).
    pub(super) fn request_resume(&mut self, orphaned: bool, cx: &mut Cx) -> Events {
        let mut ev = Events::default();
        match &mut self.state {
            Pause::Parked { .. } if orphaned => cx.host.say(format_args!(
                "refused: resume: the host that streamed this job went away; M524 ends it (the \
                 head stays parked)"
            )),
            Pause::Parked { .. } => self.start_resume(cx, &mut ev),
            Pause::Parking { then, .. } => {
                if *then != state::AfterPark::Cancel {
                    *then = state::AfterPark::Resume;
                }
                cx.host.say(format_args!("resume deferred until parked"));
            }
            Pause::Stopping { how, then, .. } => {
                if how.brakes() {
                    // A feed hold cannot be taken back mid-brake: stop, then continue without
                    // parking.
                    if *then != AfterStop::Cancel {
                        *then = AfterStop::Continue;
                    }
                } else {
                    cx.motion.clear_barrier();
                    self.state = Pause::Run;
                }
                cx.host.say(format_args!("pause withdrawn"));
            }
            Pause::Run => cx.host.say(format_args!("not paused")),
            Pause::Returning { .. } => cx.host.say(format_args!("already resuming")),
            Pause::Halted => {}
        }
        ev
    }

    /// Drop the planned and held job for a cancel (the intake drops the rest on
    /// [`PauseEvent::JobDropped`]).
    fn drop_job(&mut self, cx: &mut Cx, ev: &mut Events) {
        let held = u32::from(self.state.held_mut().and_then(|h| h.block.take()).is_some());
        let mut d = cx.motion.drop_job();
        d.blocks += held;
        self.schedule = None;
        ev.push(PauseEvent::JobDropped(d));
    }

    /// A cancel request. `in_job` as for [`PauseCtl::request_pause`].
    pub(super) fn request_cancel(&mut self, in_job: bool, cx: &mut Cx) -> Events {
        let mut ev = Events::default();
        match &mut self.state {
            Pause::Parked { .. } => {
                self.drop_job(cx, &mut ev);
                self.finish_cancel(cx, &mut ev);
            }
            Pause::Parking { then, .. } => {
                *then = state::AfterPark::Cancel;
                self.drop_job(cx, &mut ev);
            }
            Pause::Returning { then, .. } => {
                *then = state::AfterReturn::Cancel;
                cx.motion.clear_service();
                self.drop_job(cx, &mut ev);
            }
            Pause::Stopping { .. } | Pause::Run => {
                if !in_job {
                    cx.host.say(format_args!("nothing to cancel"));
                    return ev;
                }
                // A feed hold already braking goes on as it is; anything else (a layer
                // barrier, a conventional tail stop) brakes now.
                let braking = match self.state {
                    Pause::Stopping { how, .. } if how.brakes() => Some(how),
                    _ => None,
                };
                self.state = Pause::Stopping {
                    how: braking.unwrap_or(Stop::Hold {
                        after_homing: false,
                    }),
                    mode: PauseMode::Now,
                    then: AfterStop::Cancel,
                };
                if braking.is_none() {
                    self.begin_hold(cx);
                }
            }
            Pause::Halted => {}
        }
        ev
    }

    /// The cancel is complete: back to [`Pause::Run`] where the head is.
    fn finish_cancel(&mut self, cx: &mut Cx, ev: &mut Events) {
        self.state = Pause::Run;
        cx.motion.reset_planner();
        // A nozzle the timeout turned off stays off: a cancel never heats.
        cx.heat.thermal_mut().pause_idle_forget();
        ev.push(PauseEvent::CancelDone);
    }

    /// M112 / a thermal fault: nothing moves until reset.
    pub(super) fn halt(&mut self) {
        self.state = Pause::Halted;
    }

    /// M410: the motion was dropped; no pause is left. A cancel that was stopping or parking
    /// ends there, as when its park completes ([`PauseEvent::CancelDone`]: its tail's silence
    /// restarts, the idle timeout's bookkeeping and the kept record are forgotten).
    pub(super) fn quick_stop(&mut self, cx: &mut Cx) -> Events {
        let mut ev = Events::default();
        if self.state.cancelling() {
            self.finish_cancel(cx, &mut ev);
        } else {
            self.state = Pause::Run;
        }
        ev
    }
}
