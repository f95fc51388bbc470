//! The command queue's side of the executive: commands move into the planner in job order
//! (moves, layer marks, homing, waits, M400, M0/M600, stepper requests, schedules), the
//! pause schedule (M761) finds its boundary, and waiting lines get their keep-alives.

use super::state::{AfterStop, Pause, Stop};
use super::{steps, Command, Printer, Schedule, StepperRequest};
use crate::link::Response;
use crate::motion::{Axis, LayerMark, MoveRequest};
use crate::planner::BlockKind;

impl Printer {
    pub(super) fn motion_idle(&self) -> bool {
        self.planner.is_empty() && self.stepgen.current().is_none()
    }

    /// Move commands from the command queue into the planner while it has room. Returns at
    /// once, without touching the (large) planner state, when nothing could move: the main
    /// loop calls this every tick, mostly with a full ring.
    #[inline]
    pub(super) fn feed_planner(&mut self) {
        let stuck = match self.cmds.front() {
            None => !self.planner.has_pending(),
            Some(Command::Move(_)) => self.planner.room() == 0,
            Some(Command::Layer(_)) => self.planner.has_pending() && self.planner.room() == 0,
            Some(_) => false,
        };
        let tail_due = matches!(
            self.pause,
            Pause::Stopping {
                how: Stop::Tail {
                    countdown: Some(0),
                    ..
                },
                ..
            }
        );
        if stuck && !tail_due {
            return;
        }
        self.feed_planner_now();
    }

    #[inline(never)]
    pub(super) fn feed_planner_now(&mut self) {
        if self.is_halted() {
            return;
        }
        self.planner.refill();
        while let Some(cmd) = self.cmds.front().copied() {
            match cmd {
                Command::Move(req) => {
                    if !self.planner.can_accept() {
                        break;
                    }
                    if self.waits_for_heat(&req, &self.planner.end_position()) {
                        // Like a heater wait: the host's next line may wait for its `ok`.
                        self.keep_alive();
                        break;
                    }
                    let _ = self.planner.push_move(&self.cfg, &req, BlockKind::Job);
                }
                Command::Layer(mark) => {
                    if self.planner.has_pending() {
                        break;
                    }
                    match self.planner.push_mark(mark) {
                        Ok(true) => {
                            if let Pause::Stopping {
                                how: Stop::Barrier { layer },
                                ..
                            } = &mut self.pause
                            {
                                *layer = Some(mark.layer);
                            }
                        }
                        Ok(false) => {}
                        Err(_) => break,
                    }
                    self.check_schedule(mark);
                }
                Command::Home { mask } => {
                    // Homing runs before a pending layer barrier (it is part of the job before
                    // the boundary); never while parked or returning.
                    if !self.motion_idle()
                        || !matches!(self.pause, Pause::Run | Pause::Stopping { .. })
                    {
                        break;
                    }
                    if let Some(h) = self.homing_cfg {
                        if !self.home_with_endstops(mask, h) {
                            break;
                        }
                    } else {
                        let mut target = self.stepgen.position();
                        for ax in [Axis::X, Axis::Y, Axis::Z] {
                            if mask & (1 << ax.index()) != 0 {
                                let min = self.cfg.axis(ax).min_mm;
                                target[ax.index()] = steps(&self.cfg, ax, min);
                            }
                        }
                        self.position_lost &= !mask;
                        let req = MoveRequest {
                            target,
                            feed_mm_s: self.cfg.pause.park_feed_mm_s,
                            seq: u32::MAX,
                        };
                        let _ = self.planner.push_move(&self.cfg, &req, BlockKind::Homing);
                    }
                }
                Command::WaitHeater(id) => {
                    if !(self.thermal.reached(id) || self.break_wait) {
                        self.keep_alive();
                        self.heater_wait_report();
                        break;
                    }
                    self.break_wait = false;
                }
                Command::SetPosition(pos) => {
                    if !self.motion_idle()
                        || !matches!(self.pause, Pause::Run | Pause::Stopping { .. })
                    {
                        break;
                    }
                    self.planner.set_position(pos);
                    self.stepgen.set_position(pos);
                }
                Command::Dwell { ms } => {
                    if !self.motion_idle() {
                        break;
                    }
                    let until = *self
                        .dwell_until_us
                        .get_or_insert(self.now_us + u64::from(ms) * 1000);
                    if self.now_us < until && !self.break_wait {
                        break;
                    }
                    self.break_wait = false;
                    self.dwell_until_us = None;
                }
                Command::Sync => {
                    if !self.motion_idle() {
                        break;
                    }
                    self.pay_sync_ok();
                }
                Command::PauseHere => {
                    if self.planner.has_pending() {
                        break;
                    }
                    if matches!(self.pause, Pause::Run) {
                        let id = self.planner.next_id();
                        self.planner.set_barrier(id);
                        self.pause = Pause::Stopping {
                            how: Stop::Barrier { layer: None },
                            then: AfterStop::Park,
                        };
                        self.say(format_args!(
                            "pause here (M0/M600): stopping after the queued moves"
                        ));
                        self.update_state_record();
                    }
                }
                Command::Steppers(r) => {
                    if matches!(r, StepperRequest::Disable { .. }) && !self.motion_idle() {
                        break;
                    }
                    if let StepperRequest::Disable { mask } = r {
                        // A switched-off motor can be pushed by hand: the position in steps
                        // means nothing until the axis is homed again (Marlin: "not trusted").
                        let lost = mask & 0b111;
                        if lost & !self.position_lost != 0 {
                            self.position_lost |= lost;
                            let name = |i: usize| {
                                if lost & (1 << i) != 0 {
                                    ["X ", "Y ", "Z "][i]
                                } else {
                                    ""
                                }
                            };
                            self.say(format_args!(
                                "steppers off: {}{}{}position lost until G28",
                                name(0),
                                name(1),
                                name(2)
                            ));
                        }
                    }
                    self.push_stepper_request(r);
                }
                Command::Recover => {
                    if !self.motion_idle() || !matches!(self.pause, Pause::Run) {
                        break;
                    }
                    self.recover_now();
                }
                Command::SchedulePause(s) => {
                    self.schedule = Some(s);
                    self.say(format_args!("pause scheduled: {:?}", s));
                }
            }
            let _ = self.cmds.pop_front();
            if let Some(Some(n)) = self.pause.tail_countdown() {
                *n = n.saturating_sub(1);
            }
        }
        if !self.planner.has_pending() {
            if let Some(c @ Some(0)) = self.pause.tail_countdown() {
                *c = None;
                let id = self.planner.next_id();
                self.planner.set_barrier(id);
            }
        }
    }

    /// A `busy:` keep-alive at most every M113 period (default [`super::BUSY_PERIOD_US`]) while a host line waits for its
    /// `ok` (heater wait, M400, a full queue during a pause), so the host does not time out:
    /// `busy: paused for user` while parked (Marlin's wording when it waits for the user),
    /// `busy: processing` otherwise.
    pub(super) fn keep_alive(&mut self) {
        let period = self.reports.busy_us;
        if period > 0 && self.now_us.saturating_sub(self.lines.last_busy_us) >= period {
            self.lines.last_busy_us = self.now_us;
            let r = if matches!(self.pause, Pause::Parked { .. }) {
                Response::BusyPaused
            } else {
                Response::Busy
            };
            self.link.respond(r);
        }
    }

    /// Send the `ok` an M400 owes (its wait is over, or the wait was dropped).
    pub(super) fn pay_sync_ok(&mut self) {
        if core::mem::take(&mut self.lines.sync_ok_owed) {
            self.link.respond(Response::Ok);
        }
    }

    /// Whether the pause schedule asks to stop before `mark`.
    pub(super) fn schedule_hit(&self, mark: &LayerMark) -> bool {
        match self.schedule {
            Some(Schedule::Layer(n)) => mark.layer >= n,
            Some(Schedule::Z(z)) => mark.z_um.is_some_and(|mz| mz >= z),
            None => false,
        }
    }

    /// A layer mark entered the planner: a matching schedule becomes the barrier. While a pause
    /// is already in progress the schedule waits: it is met by that pause if it stops at a
    /// matching boundary, or looked for again among the queued marks when the job resumes.
    pub(super) fn check_schedule(&mut self, mark: LayerMark) {
        if self.schedule_hit(&mark) && matches!(self.pause, Pause::Run) {
            self.schedule = None;
            if let Some((id, _)) = self.planner.marks().last() {
                self.planner.set_barrier(id);
            }
            self.pause = Pause::Stopping {
                how: Stop::Barrier {
                    layer: Some(mark.layer),
                },
                then: AfterStop::Park,
            };
            self.say(format_args!(
                "scheduled pause: stopping before layer {}",
                mark.layer
            ));
            self.update_state_record();
        }
    }

    /// Set a pause schedule now (M761 from the host). A matching layer mark already in the
    /// planner becomes the barrier at once.
    pub fn schedule_pause(&mut self, s: Option<Schedule>) {
        self.schedule = s;
        self.schedule_queued_marks();
    }

    /// Apply the schedule to the layer marks already queued in the planner.
    pub(super) fn schedule_queued_marks(&mut self) {
        if self.schedule.is_none() || !matches!(self.pause, Pause::Run) {
            return;
        }
        let mut hit = None;
        for (id, m) in self.planner.marks() {
            // A matching mark too close to brake for: the next reachable one (it matches too).
            if self.schedule_hit(&m) && self.planner.can_stop_before(id) {
                hit = Some((id, m));
                break;
            }
        }
        if let Some((id, m)) = hit {
            self.schedule = None;
            self.planner.set_barrier(id);
            self.pause = Pause::Stopping {
                how: Stop::Barrier {
                    layer: Some(m.layer),
                },
                then: AfterStop::Park,
            };
            self.say(format_args!(
                "scheduled pause: stopping before layer {}",
                m.layer
            ));
            self.update_state_record();
        }
    }

    /// The current pause schedule (M761 report).
    pub fn scheduled_pause(&self) -> Option<Schedule> {
        self.schedule
    }
}
