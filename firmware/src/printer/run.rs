//! The job in order: commands leave the intake's queue for the part that carries them out —
//! moves and layer marks into the planner, homing, heater waits, position sets, dwells, M400,
//! M0/M600, stepper requests, schedules — each when the motion before it allows. (What a line
//! asks of the executive at once is dispatched by family in `commands/`.)

use super::motion::homing::HomeStep;
use super::{Command, Printer, StepperRequest};
use crate::planner::BlockKind;

impl Printer {
    /// Move commands from the command queue into the planner while it has room. Returns at
    /// once, without touching the (large) planner state, when nothing could move: the main
    /// loop calls this every tick, mostly with a full ring.
    #[inline]
    pub(super) fn feed_planner(&mut self) {
        let stuck = match self.intake.front() {
            None => !self.motion.has_pending(),
            Some(Command::Move(_)) => self.motion.room() == 0,
            Some(Command::Layer(_)) => self.motion.has_pending() && self.motion.room() == 0,
            Some(_) => false,
        };
        if stuck && !self.pause.tail_due() {
            return;
        }
        self.feed_planner_breaking(false);
    }

    /// [`Printer::feed_planner`] without the shortcut; `break_wait`: an M108 breaks the first
    /// heater wait or dwell at the front of the queue.
    #[inline(never)]
    pub(super) fn feed_planner_breaking(&mut self, mut break_wait: bool) {
        if self.pause.halted() {
            return;
        }
        self.motion.refill();
        while let Some(cmd) = self.intake.front().copied() {
            let cfg = self.settings.cfg();
            match cmd {
                Command::Move(req) => {
                    if !self.motion.can_accept() {
                        break;
                    }
                    let moves_e = req.target[crate::motion::Axis::E.index()]
                        != self.motion.end_position()[crate::motion::Axis::E.index()];
                    if moves_e && self.heat.waits_for_heat() {
                        // Like a heater wait: the host's next line may wait for its `ok`.
                        self.keep_alive();
                        break;
                    }
                    self.motion.push_move(cfg, &req, BlockKind::Job);
                }
                Command::Layer(mark) => {
                    if self.motion.has_pending() {
                        break;
                    }
                    match self.motion.push_mark(mark) {
                        Ok(barrier) => self.pause.mark_queued(mark, barrier, cx!(self)),
                        Err(()) => break,
                    }
                }
                Command::Home { mask } => {
                    // Homing runs before a pending layer barrier (it is part of the job before
                    // the boundary); never while parked or returning.
                    if !self.motion.idle() || !self.pause.may_home() {
                        break;
                    }
                    let feed = cfg.pause.park_feed_mm_s;
                    match self.motion.home(mask, cfg, feed) {
                        HomeStep::Moving => break,
                        HomeStep::Done => {}
                        HomeStep::Failed(e) => {
                            self.host.error_here(format_args!("{e}"));
                            self.emergency_stop();
                        }
                    }
                }
                Command::WaitHeater(id) => {
                    if !(self.heat.reached(id) || break_wait) {
                        self.keep_alive();
                        let temps = self.heat.report();
                        self.host.heater_wait_report(self.now_us, temps);
                        break;
                    }
                    break_wait = false;
                }
                Command::SetPosition(pos) => {
                    if !self.motion.idle() || !self.pause.may_home() {
                        break;
                    }
                    self.motion.set_position(pos);
                }
                Command::Dwell { ms } => {
                    if !self.motion.idle() {
                        break;
                    }
                    if !self.motion.dwell_over(self.now_us, ms, break_wait) {
                        break;
                    }
                    break_wait = false;
                }
                Command::Sync => {
                    if !self.motion.idle() {
                        break;
                    }
                    if self.intake.sync_reached() {
                        self.host.ok();
                    }
                }
                Command::PauseHere => {
                    if self.motion.has_pending() {
                        break;
                    }
                    self.pause.pause_here(cx!(self));
                    self.update_state_record();
                }
                Command::Steppers(r) => {
                    if matches!(r, StepperRequest::Disable { .. }) && !self.motion.idle() {
                        break;
                    }
                    if let StepperRequest::Disable { mask } = r {
                        // A switched-off motor can be pushed by hand: the position in steps
                        // means nothing until the axis is homed again (Marlin: "not trusted").
                        let lost = self.motion.lose_position(mask);
                        if lost != 0 {
                            let name = |i: usize| {
                                if lost & (1 << i) != 0 {
                                    ["X ", "Y ", "Z "][i]
                                } else {
                                    ""
                                }
                            };
                            self.host.say(format_args!(
                                "steppers off: {}{}{}position lost until G28",
                                name(0),
                                name(1),
                                name(2)
                            ));
                        }
                    }
                    self.board.push_stepper_request(r);
                }
                Command::Recover => {
                    if !self.motion.idle() || !self.pause.running() {
                        break;
                    }
                    self.recover_now();
                }
                Command::SchedulePause(s) => {
                    self.pause.schedule_from_job(s, &mut self.host);
                }
            }
            self.intake.pop_front();
            self.pause.command_fed();
        }
        if !self.motion.has_pending() {
            self.pause.set_tail_barrier(cx!(self));
        }
    }

    /// Send the `ok` an M400 owes (its wait is over, or the wait was dropped).
    pub(super) fn pay_sync_ok(&mut self) {
        if self.intake.pay_sync() {
            self.host.ok();
        }
    }
}
