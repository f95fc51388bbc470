//! The job in order: commands leave the intake's queue for the part that carries them out —
//! moves and layer marks into the planner, homing, heater waits, position sets, dwells, M400,
//! M0/M600, stepper requests, schedules — each when the motion before it allows; and the
//! commands a line asks the executive to carry out at once (temperatures, fans, reports,
//! settings, pause requests, SD and power-cut commands), dispatched to the part that owns them.

use super::heat::heater_id;
use super::motion::homing::{HomeStep, Latched};
use super::{Command, Printer, StepperRequest};
use crate::gcode;
use crate::link::{PositionReport, Response};
use crate::motion::{PauseMode, Realtime};
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
                    self.pay_sync_ok();
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

    /// M104/M109/M140/M190 with T0 (or no T): set the target (a refusal is said); returns the
    /// heater to wait for (M109/M190).
    fn set_temperature(
        &mut self,
        heater: gcode::Heater,
        wait: bool,
        s: Option<f32>,
        r: Option<f32>,
    ) -> Option<crate::thermal::HeaterId> {
        let id = heater_id(heater);
        if let Some(t) = r.or(s) {
            if let Err(e) = self.heat.set_target(id, t) {
                let code = match (heater, wait) {
                    (gcode::Heater::Hotend, false) => "M104",
                    (gcode::Heater::Hotend, true) => "M109",
                    (gcode::Heater::Bed, false) => "M140",
                    (gcode::Heater::Bed, true) => "M190",
                };
                let word = if r.is_some() { 'R' } else { 'S' };
                self.host.warn(format_args!("{code} {word}{t}: {e}"));
                return None;
            }
        }
        wait.then_some(id)
    }

    /// Send the `ok` an M400 owes (its wait is over, or the wait was dropped).
    pub(super) fn pay_sync_ok(&mut self) {
        if self.intake.pay_sync() {
            self.host.ok();
        }
    }

    /// Carry out a command a line asks of the executive. Returns true when the `ok` was
    /// already sent (M105 answers `ok T:...`).
    pub(super) fn execute(&mut self, cmd: &gcode::Command) -> bool {
        use gcode::Command as G;
        match cmd {
            G::SetTemperature {
                heater,
                wait,
                s,
                r,
                tool,
            } => {
                let code = match (heater, wait) {
                    (gcode::Heater::Hotend, false) => "M104",
                    (gcode::Heater::Hotend, true) => "M109",
                    (gcode::Heater::Bed, false) => "M140",
                    (gcode::Heater::Bed, true) => "M190",
                };
                // Marlin's `get_target_extruder_from_command`: an extruder that is not there is
                // refused, never applied to the one that is (FlashPrint's `M104 S0 T1` for a
                // second hotend switched the only one off; issue 31/32).
                if let Some(t) = tool.filter(|t| *t != 0) {
                    self.host.warn(format_args!(
                        "{code} T{t}: invalid extruder (this printer has T0 only)"
                    ));
                    return false;
                }
                // A console line (a job's waits its turn as a `Command::Setting`).
                if let Some(id) = self.set_temperature(*heater, *wait, *s, *r) {
                    self.intake.push(Command::WaitHeater(id));
                }
            }
            G::ReportTemperatures => {
                // The report is its own `ok`.
                let r = self.heat.report();
                self.host.temperatures(r);
                return true;
            }
            G::FanOn { fan: Some(f), .. } | G::FanOff { fan: Some(f) } if *f != 0 => {
                // Marlin ignores a fan it does not have (`M106 P9`); here it is said.
                let code = if matches!(cmd, G::FanOn { .. }) {
                    "M106"
                } else {
                    "M107"
                };
                self.host.warn(format_args!(
                    "{code} P{f}: no such fan (this printer has P0 only)"
                ));
            }
            G::FanOn { speed, .. } => self.heat.set_fan(*speed),
            G::FanOff { .. } => self.heat.set_fan(Some(0.0)),
            G::ReportPosition => {
                let r = PositionReport {
                    logical_mm: self.intake.machine().logical_mm(),
                    steps: self.motion.position(),
                };
                self.host.respond(Response::Position(r));
            }
            G::FirmwareInfo => {
                self.host.respond(Response::FirmwareInfo);
                self.board.report_stats(&mut self.host);
            }
            G::Message(t) | G::Echo(t) => {
                self.host.respond(Response::Echo(t));
            }
            G::SetAcceleration {
                print,
                retract,
                travel,
                s,
            } => self
                .settings
                .m204(*print, *retract, *travel, *s, &mut self.host),
            G::FeedOverride(None) => {
                let v = self.intake.machine().feed_override_pct();
                self.host.say(format_args!("FR:{v:.0}%"));
            }
            G::FlowOverride(None) => {
                let v = self.intake.machine().flow_override_pct();
                self.host.say(format_args!("E0 Flow: {v:.0}%"));
            }
            G::WaitMoves => {
                // As Marlin: the `ok` comes when the moves queued before it have ended.
                self.intake.push(Command::Sync);
                self.intake.owe_sync();
                return true;
            }
            G::PauseParams(p) => self.m760(p),
            G::ColdExtrusion { min_temp_c, allow } => {
                self.heat.m302(*min_temp_c, *allow, &mut self.host)
            }
            G::ReportEndstops => {
                let mut e = Latched(self.motion.endstops());
                for line in crate::homing::m119_lines(&mut e) {
                    self.host.respond(Response::Plain(line));
                }
            }
            G::SchedulePause(s) => {
                let printing = self.job.layer().filter(|_| self.in_job());
                self.pause.m761(s, printing, cx!(self));
            }
            G::Pause { now, .. } => {
                let mode = if *now {
                    PauseMode::Now
                } else {
                    PauseMode::Layer
                };
                let t = self.now_us;
                self.request(Realtime::Pause(mode), t);
            }
            G::Resume { .. } => {
                let t = self.now_us;
                self.request(Realtime::Resume, t);
            }
            G::Cancel => {
                let t = self.now_us;
                self.request(Realtime::Cancel, t);
            }
            G::QuickStop => {
                let t = self.now_us;
                self.request(Realtime::QuickStop, t);
            }
            G::EmergencyStop => {
                let t = self.now_us;
                self.request(Realtime::EmergencyStop, t);
            }
            G::BreakWait => {
                let t = self.now_us;
                self.request(Realtime::BreakWait, t);
            }
            G::SetPid { heater, p, i, d } => {
                self.heat.pid_command(*heater, *p, *i, *d, &mut self.host)
            }
            G::Autotune {
                heater_index,
                target_c,
                cycles,
                use_result,
            } => self.heat.autotune(
                *heater_index,
                *target_c,
                *cycles,
                *use_result,
                self.now_us,
                &mut self.host,
            ),
            G::EnableSteppers(axes) => {
                let mask = axis_mask(axes);
                self.intake
                    .push(Command::Steppers(StepperRequest::Enable { mask }));
            }
            G::DisableSteppers { axes, s, .. } => match s {
                Some(s) if s.is_finite() && *s >= 0.0 => {
                    self.intake
                        .push(Command::Steppers(StepperRequest::IdleTimeout { s: *s }));
                }
                Some(_) => self
                    .host
                    .warn(format_args!("M84 S: timeout must be >= 0 s")),
                None => {
                    let mask = axis_mask(axes);
                    self.intake
                        .push(Command::Steppers(StepperRequest::Disable { mask }));
                }
            },
            G::Tool(0) => {}
            G::Progress(p) => self.host.note_progress(p),
            G::Report(c) => {
                if matches!(c, gcode::ReportCommand::JobStatus) && !self.sd_status() {
                    self.host.say(format_args!("Not SD printing"));
                }
                let view = self.job_view();
                self.host.report_command(c, self.now_us, view);
            }
            G::PrintStatsInfo { .. } | G::SetLineNumber(_) => {}
            // Marlin on a single-extruder machine: `invalid_extruder_error`, nothing changes.
            G::Tool(n) => self.host.warn(format_args!(
                "T{n}: invalid extruder (this printer has T0 only)"
            )),
            G::Stop { ms, s, .. } => {
                if ms.is_some() || s.is_some() {
                    match crate::machine::dwell_ms(*ms, *s) {
                        Ok(ms) => self.intake.push(Command::Dwell { ms }),
                        Err(e) => self.host.warn(format_args!("{e}")),
                    }
                } else {
                    self.intake.push(Command::PauseHere);
                }
            }
            G::FilamentChange(_) => {
                // Park at the pause position; the user unloads/loads, then resumes (M24).
                self.intake.push(Command::PauseHere);
            }
            G::Settings(c) => self.settings_command(c),
            G::Driver(c) => self.driver_command(c),
            G::Sd(c) => return self.sd_command(c),
            G::Recovery(c) => return self.recovery_command(c),
            G::Unknown(t) => {
                self.host.respond(Response::UnknownCommand(t));
            }
            _ => {}
        }
        false
    }

    /// M760: report, or check against the machine and set, the pause's parameters.
    fn m760(&mut self, p: &gcode::PauseParams) {
        if let Err(r) = super::guards::check_pause_params(p, self.settings.cfg()) {
            self.host.warn(format_args!("{r}"));
            return;
        }
        let timeout_s = self.heat.thermal().idle_config().map_or(0, |i| i.timeout_s);
        if p.is_empty() {
            let c = self.settings.cfg().pause;
            self.host.say(format_args!(
                "M760 R{:.2} Z{:.2} X{:.1} Y{:.1} F{:.0} S{:.2} V{:.1} L{:.3} T{timeout_s}",
                c.retract_mm,
                c.lift_z_mm,
                c.park_x_mm,
                c.park_y_mm,
                c.park_feed_mm_s * 60.0,
                c.speedup_factor,
                c.max_volumetric_mm3_s,
                c.segment_len_mm
            ));
            return;
        }
        if let Some(t) = p.nozzle_timeout_s.filter(|t| t.is_finite() && *t >= 0.0) {
            // Whole seconds; 0 = the nozzle stays hot however long the pause.
            let secs = libm::roundf(t) as u32;
            self.heat
                .thermal_mut()
                .set_idle((secs > 0).then_some(crate::thermal::IdleConfig {
                    timeout_s: secs,
                    nozzle_c: 0.0,
                }));
        }
        self.settings.m760(p);
    }
}

/// Axis flags as a mask (bit i = axis i); no axis named = every axis.
fn axis_mask(axes: &gcode::AxisFlags) -> u8 {
    let mut mask = 0u8;
    for i in 0..crate::motion::AXES {
        if axes.is_empty() || axes.0.get(i).copied().unwrap_or(false) {
            mask |= 1 << i;
        }
    }
    mask
}
