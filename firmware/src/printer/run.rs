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
            if !self.pause.queue_runs(&self.motion) {
                // A pause holds the job: what is queued after its stop runs after the resume,
                // in order, judged then (docs/frontend.md, "The held job").
                break;
            }
            let cfg = self.settings.cfg();
            match cmd {
                Command::Move(req) => {
                    if !self.motion.can_accept() {
                        break;
                    }
                    let e = crate::motion::Axis::E.index();
                    let from_e = self.motion.end_position()[e];
                    let moves_e = req.target[e] != from_e;
                    if moves_e && self.heat.waits_for_heat() {
                        // Like a heater wait: the host's next line may wait for its `ok`.
                        self.keep_alive();
                        break;
                    }
                    self.plan_job_move(req, from_e);
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
                Command::Setting(s) => {
                    if let Some(id) = self.job_setting(s) {
                        // M109/M190: the wait takes the setting's place at the front.
                        self.intake.replace_front(Command::WaitHeater(id));
                        continue;
                    }
                }
            }
            self.intake.pop_front();
            self.pause.command_fed();
        }
        if !self.motion.has_pending() {
            self.pause.set_tail_barrier(cx!(self));
        }
    }

    /// Plan a job move whose E starts at `from_e` steps. The cold-extrusion guard judges it
    /// here, in the state it runs in (Marlin `Planner::_populate_block`): too cold (and not
    /// heating), its E part is dropped with Marlin's message and the rest planned; the
    /// record says what was not extruded.
    fn plan_job_move(&mut self, mut req: crate::motion::MoveRequest, from_e: i32) {
        let cfg = self.settings.cfg();
        let e = crate::motion::Axis::E.index();
        let de_steps = req.target[e].wrapping_sub(from_e);
        let de_mm = de_steps as f32 / cfg.axis(crate::motion::Axis::E).steps_per_mm;
        let refused = self.heat.check_cold(de_mm).err();
        let to_e = req.target[e];
        if let Some(r) = refused {
            self.host.warn(format_args!("{r}"));
            req.target[e] = from_e;
        }
        self.motion.push_move(cfg, &req, BlockKind::Job);
        if refused.is_some() {
            self.motion.skip_e(to_e);
            let t_us = self.now_us;
            self.records.push(super::Record::ColdRefused {
                seq: req.seq,
                e_steps: de_steps,
                t_us,
            });
        }
    }

    /// A job's state command at the front of the queue (see [`super::JobSetting`]); returns
    /// the heater an M109/M190 then waits for.
    fn job_setting(&mut self, s: super::JobSetting) -> Option<crate::thermal::HeaterId> {
        use super::JobSetting as S;
        match s {
            S::Temperature { heater, wait, s, r } => self.set_temperature(heater, wait, s, r),
            S::Fan(speed) => {
                self.heat.set_fan(speed);
                None
            }
            S::Acceleration {
                print,
                retract,
                travel,
                s,
            } => {
                let given = |v: f32| (!v.is_nan()).then_some(v);
                self.settings.m204(
                    given(print),
                    given(retract),
                    given(travel),
                    given(s),
                    &mut self.host,
                );
                None
            }
            S::ColdExtrusion { min_temp_c, allow } => {
                self.heat.m302(min_temp_c, allow, &mut self.host);
                None
            }
        }
    }

    /// Send the `ok` an M400 owes (its wait is over, or the wait was dropped).
    pub(super) fn pay_sync_ok(&mut self) {
        if self.intake.pay_sync() {
            self.host.ok();
        }
    }
}
