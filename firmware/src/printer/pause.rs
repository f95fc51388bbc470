//! Requests to the pause machine ([`super::state::Pause`]): pause, resume, cancel, quick and
//! emergency stops, and the notion of "in a job" they share. What happens once the head has
//! stopped (park, return, release) is in `park.rs`.

use super::state::{AfterPark, AfterReturn, AfterStop, Pause, Stop};
use super::{AfterCancel, Printer, Record};
use crate::link::{HostAction, Response};
use crate::motion::PauseMode;
use crate::planner::BlockKind;
use crate::printer::LAYER_PAUSE_IDLE_US;

impl Printer {
    /// Feed hold for the stopping pause: brake from the executing block on (the stop becomes
    /// [`Stop::Hold`]). While a homing move runs, the brake waits for its end.
    pub(super) fn begin_hold(&mut self) {
        let homing = self
            .stepgen
            .current()
            .is_some_and(|e| e.planned.block.kind == BlockKind::Homing && !e.finished());
        if let Pause::Stopping { how, .. } = &mut self.pause {
            *how = Stop::Hold {
                after_homing: homing,
            };
        }
        if homing {
            return;
        }
        let now = self.now_ns();
        let v = self.stepgen.hold(now);
        let a = self
            .stepgen
            .current()
            .map_or(0.0, |e| e.planned.block.accel_mm_s2);
        let t_us = self.t_us();
        self.record(Record::Brake {
            v_mm_s: v,
            accel_mm_s2: a,
            t_us,
        });
    }

    /// Whether the printer is in a job — the same notion for pause and cancel: work queued or
    /// moving, lines received before the request and not taken yet (a pause written in the
    /// same burst as the moves it should stop: the link sees it before the executive takes
    /// them, issue 31), or a host streaming one (a line taken or a move ended within
    /// [`LAYER_PAUSE_IDLE_US`]: between lines, or at a boundary the host drained with M400),
    /// and not a job just cancelled.
    pub(super) fn in_job(&self) -> bool {
        if self.has_work() || self.link.request_lines_ahead() > 0 || self.lines.held_line.is_some()
        {
            return true;
        }
        let idle_us = self.now_us.saturating_sub(self.last_activity_us);
        self.lines.after_cancel.is_none()
            && self.last_activity_us != 0
            && idle_us < LAYER_PAUSE_IDLE_US
    }

    pub(super) fn request_pause(&mut self, mode: PauseMode) {
        match &mut self.pause {
            Pause::Run => {
                if !self.in_job() {
                    self.say(format_args!("pause: nothing to pause"));
                    return;
                }
                if self.policy.pause_at_tail {
                    self.pause = Pause::Stopping {
                        how: Stop::Tail {
                            mode,
                            countdown: Some(self.cmds.len()),
                        },
                        then: AfterStop::Park,
                    };
                    self.feed_planner();
                    self.say(format_args!("pause queued behind the buffered moves"));
                    return;
                }
                match mode {
                    PauseMode::Layer => {
                        let mut layer = None;
                        if let Some((id, m)) = self.planner.first_reachable_mark() {
                            self.planner.set_barrier(id);
                            layer = Some(m.layer);
                            self.say(format_args!("pause: stopping before layer {}", m.layer));
                        } else {
                            self.planner.set_barrier_next_mark();
                            self.say(format_args!("pause: stopping at the next layer"));
                        }
                        self.pause = Pause::Stopping {
                            how: Stop::Barrier { layer },
                            then: AfterStop::Park,
                        };
                        if self.cfg.pause.speedup_factor > 1.0 {
                            self.planner.speed_up();
                            let t_us = self.t_us();
                            self.record(Record::SpeedUp { t_us });
                        }
                    }
                    PauseMode::Now => {
                        self.pause = Pause::Stopping {
                            how: Stop::Hold {
                                after_homing: false,
                            },
                            then: AfterStop::Park,
                        };
                        self.begin_hold();
                        self.say(format_args!("pause: stopping now"));
                    }
                }
            }
            Pause::Stopping { how, then } => {
                // A new pause request takes back a withdrawal (never a cancel).
                if *then == AfterStop::Continue {
                    *then = AfterStop::Park;
                }
                if mode == PauseMode::Now && matches!(how, Stop::Barrier { .. }) {
                    self.begin_hold();
                    self.say(format_args!("pause: stopping now"));
                } else {
                    self.say(format_args!("pause already in progress"));
                }
            }
            Pause::Parking { .. } | Pause::Parked { .. } => {
                self.say(format_args!("already paused"));
            }
            Pause::Returning { then, .. } => {
                if *then != AfterReturn::Cancel {
                    *then = AfterReturn::Pause(mode);
                }
                self.say(format_args!("pause deferred until the resume completes"));
            }
            Pause::Halted => {}
        }
    }

    pub(super) fn request_resume(&mut self) {
        match &mut self.pause {
            Pause::Parked { .. } if self.lines.orphaned => self.say(format_args!(
                "refused: resume: the host that streamed this job went away; M524 ends it (the \
                 head stays parked)"
            )),
            Pause::Parked { .. } => self.start_resume(),
            Pause::Parking { then, .. } => {
                if *then != AfterPark::Cancel {
                    *then = AfterPark::Resume;
                }
                self.say(format_args!("resume deferred until parked"));
            }
            Pause::Stopping { how, then } => {
                if how.brakes() {
                    // A feed hold cannot be taken back mid-brake: stop, then continue without
                    // parking.
                    if *then != AfterStop::Cancel {
                        *then = AfterStop::Continue;
                    }
                } else {
                    self.planner.clear_barrier();
                    self.pause = Pause::Run;
                }
                self.say(format_args!("pause withdrawn"));
            }
            Pause::Run => self.say(format_args!("not paused")),
            Pause::Returning { .. } => self.say(format_args!("already resuming")),
            Pause::Halted => {}
        }
    }

    /// Drop the queued and held job for a cancel; from here on the rest of the job a host still
    /// sends is discarded ([`AfterCancel`]).
    pub(super) fn drop_job(&mut self) {
        let cmds = self.cmds.len();
        let held = usize::from(self.pause.held_mut().and_then(|h| h.block.take()).is_some());
        let pos = self.stepgen.position();
        let (blocks, segs, marks) = self.planner.clear(pos);
        self.cmds.clear();
        self.spill_drop();
        self.lines.orphaned = false;
        self.pay_sync_ok();
        self.arc = None;
        self.schedule = None;
        self.lines.after_cancel = Some(AfterCancel {
            after: self.lines.last_line_no,
            discarded: 0,
        });
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
        match &mut self.pause {
            Pause::Parked { .. } => {
                self.drop_job();
                self.finish_cancel();
            }
            Pause::Parking { then, .. } => {
                *then = AfterPark::Cancel;
                self.drop_job();
            }
            Pause::Returning { then, .. } => {
                *then = AfterReturn::Cancel;
                self.service.clear();
                self.drop_job();
            }
            Pause::Stopping { .. } | Pause::Run => {
                if !self.in_job() {
                    self.say(format_args!("nothing to cancel"));
                    return;
                }
                // A feed hold already braking goes on as it is; anything else (a layer
                // barrier, a conventional tail stop) brakes now.
                let how = match self.pause {
                    Pause::Stopping { how, .. } if how.brakes() => Some(how),
                    _ => None,
                };
                self.pause = Pause::Stopping {
                    how: how.unwrap_or(Stop::Hold {
                        after_homing: false,
                    }),
                    then: AfterStop::Cancel,
                };
                if how.is_none() {
                    self.begin_hold();
                }
            }
            Pause::Halted => {}
        }
    }

    /// The cancel is complete: back to [`Pause::Run`] where the head is.
    pub(super) fn finish_cancel(&mut self) {
        self.on_job_continues();
        self.pause = Pause::Run;
        // The host's silence is measured from here: lines that waited during the cancel's
        // park are not a fresh start.
        self.last_activity_us = self.now_us;
        let pos = self.stepgen.position();
        self.planner.clear(pos);
        self.planner.exec_done();
        self.machine.set_position_steps(&pos, &self.cfg);
        // A nozzle the timeout turned off stays off: a cancel never heats.
        self.thermal.pause_idle_forget();
    }

    pub(super) fn emergency_stop(&mut self) {
        self.abort_homing();
        self.pause = Pause::Halted;
        self.thermal.kill(self.now_us);
        self.arc = None;
        let _ = self.stepgen.unload();
        let pos = self.stepgen.position();
        self.planner.clear(pos);
        self.cmds.clear();
        self.lines.sync_ok_owed = false;
        self.service.clear();
        // As Marlin's kill(): an error to every port, then no answer to anything until reset.
        self.link
            .notify(Response::Error("Printer halted. kill() called!"));
        self.link.halt();
    }

    pub(super) fn quick_stop(&mut self) {
        self.abort_homing();
        let _ = self.stepgen.unload();
        self.stepgen.end_hold();
        let pos = self.stepgen.position();
        let (blocks, segs, _) = self.planner.clear(pos);
        self.planner.exec_done();
        self.service.clear();
        self.pause = Pause::Run;
        self.lines.orphaned = false;
        self.arc = None;
        self.machine.set_position_steps(&pos, &self.cfg);
        self.say(format_args!(
            "quick stop (M410): dropped {} blocks, {} uncut segments",
            blocks, segs
        ));
    }
}
