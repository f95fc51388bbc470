//! The executive's command handlers: commands the machine state leaves to the executive
//! (temperatures, fans, reports, acceleration, overrides, M400, pause/resume/cancel lines,
//! PID, steppers, M0/M600, M760/M761, unknown commands) answered or queued here.

use super::{Command, Printer, Schedule, StepperRequest};
use crate::gcode::{self, Heater, PauseSchedule};
use crate::link::{PositionReport, Response};
use crate::motion::Realtime;
use crate::thermal::HeaterId;

fn heater_id(h: Heater) -> HeaterId {
    match h {
        Heater::Hotend => HeaterId::Hotend,
        Heater::Bed => HeaterId::Bed,
    }
}

impl Printer {
    /// Commands the machine state leaves to the executive. Returns true when the `ok` was
    /// already sent (M105 answers `ok T:...`).
    pub(super) fn executive(&mut self, cmd: &gcode::Command) -> bool {
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
                    (Heater::Hotend, false) => "M104",
                    (Heater::Hotend, true) => "M109",
                    (Heater::Bed, false) => "M140",
                    (Heater::Bed, true) => "M190",
                };
                // Marlin's `get_target_extruder_from_command`: an extruder that is not there is
                // refused, never applied to the one that is (FlashPrint's `M104 S0 T1` for a
                // second hotend switched the only one off; issue 31/32).
                if let Some(t) = tool.filter(|t| *t != 0) {
                    self.warn(format_args!(
                        "{code} T{t}: invalid extruder (this printer has T0 only)"
                    ));
                    return false;
                }
                let id = heater_id(*heater);
                let word = if r.is_some() { 'R' } else { 'S' };
                if let Some(t) = r.or(*s) {
                    if let Err(e) = self.thermal.set_target(id, t) {
                        self.warn(format_args!("{code} {word}{t}: {e}"));
                        return false;
                    }
                }
                if *wait {
                    let _ = self.cmds.push_back(Command::WaitHeater(id));
                }
            }
            G::ReportTemperatures => {
                // The report is its own `ok`.
                return self.report_temperatures();
            }
            G::FanOn { fan: Some(f), .. } | G::FanOff { fan: Some(f) } if *f != 0 => {
                // Marlin ignores a fan it does not have (`M106 P9`); here it is said.
                let code = if matches!(cmd, G::FanOn { .. }) {
                    "M106"
                } else {
                    "M107"
                };
                self.warn(format_args!(
                    "{code} P{f}: no such fan (this printer has P0 only)"
                ));
            }
            G::FanOn { speed, .. } => {
                let v = speed.unwrap_or(255.0);
                self.fan_pwm = if v.is_finite() {
                    v.clamp(0.0, 255.0) as u8
                } else {
                    0
                };
            }
            G::FanOff { .. } => self.fan_pwm = 0,
            G::ReportPosition => {
                let r = PositionReport {
                    logical_mm: self.machine.logical_mm(),
                    steps: self.stepgen.position(),
                };
                self.link.respond(Response::Position(r));
            }
            G::FirmwareInfo => {
                self.link.respond(Response::FirmwareInfo);
                self.report_board_stats();
            }
            G::Message(t) | G::Echo(t) => {
                self.link.respond(Response::Echo(t));
            }
            G::SetAcceleration {
                print,
                retract,
                travel,
                s,
            } => {
                // The settings store's range (one table): all or nothing.
                let b = crate::ranges::ACCEL;
                let given = [('S', s), ('P', print), ('R', retract), ('T', travel)];
                if let Some((l, Some(v))) = given
                    .iter()
                    .find(|(_, v)| v.is_some_and(|v| !b.contains(v)))
                {
                    self.say(format_args!(
                        "refused: M204 {l}{v}: {} out of range ({}..{} {}); nothing changed",
                        b.name, b.min, b.max, b.unit
                    ));
                    return false;
                }
                if let Some(a) = *s {
                    self.cfg.accel_print_mm_s2 = a;
                    self.cfg.accel_travel_mm_s2 = a;
                }
                if let Some(a) = *print {
                    self.cfg.accel_print_mm_s2 = a;
                }
                if let Some(a) = *retract {
                    self.cfg.accel_retract_mm_s2 = a;
                }
                if let Some(a) = *travel {
                    self.cfg.accel_travel_mm_s2 = a;
                }
            }
            G::FeedOverride(None) => {
                let v = self.machine.feed_override_pct();
                self.say(format_args!("FR:{v:.0}%"));
            }
            G::FlowOverride(None) => {
                let v = self.machine.flow_override_pct();
                self.say(format_args!("E0 Flow: {v:.0}%"));
            }
            G::WaitMoves => {
                // As Marlin: the `ok` comes when the moves queued before it have ended.
                let queued = self.cmds.push_back(Command::Sync).is_ok();
                self.lines.sync_ok_owed = queued;
                return queued;
            }
            G::PauseParams(p) => match super::guards::check_pause_params(p, &self.cfg) {
                Ok(()) => self.m760(p),
                Err(r) => self.warn(format_args!("{r}")),
            },
            G::ColdExtrusion { min_temp_c, allow } => self.m302(*min_temp_c, *allow),
            G::ReportEndstops => self.m119(),
            G::SchedulePause(s) => self.m761(s),
            G::Pause { now, .. } => {
                let mode = if *now {
                    crate::motion::PauseMode::Now
                } else {
                    crate::motion::PauseMode::Layer
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
                let id = heater_id(*heater);
                match (self.thermal.pid(id), p, i, d) {
                    (Some(g), None, None, None) => {
                        self.say(format_args!("p:{:.2} i:{:.2} d:{:.2}", g.kp, g.ki, g.kd));
                    }
                    (cur, _, _, _) => {
                        let base = cur.unwrap_or(crate::thermal::pid::PidGains {
                            kp: 0.0,
                            ki: 0.0,
                            kd: 0.0,
                        });
                        let g = crate::thermal::pid::PidGains {
                            kp: p.unwrap_or(base.kp),
                            ki: i.unwrap_or(base.ki),
                            kd: d.unwrap_or(base.kd),
                        };
                        if let Err(e) = self.thermal.set_pid(id, g) {
                            self.warn(format_args!("{e}"));
                        }
                    }
                }
            }
            G::Autotune {
                heater_index,
                target_c,
                cycles,
                use_result,
            } => {
                // Marlin's M303: E-1 the bed, E0 the hotend, else "Bad heater id".
                let id = match heater_index {
                    Some(-1) => HeaterId::Bed,
                    None | Some(0) => HeaterId::Hotend,
                    Some(e) => {
                        self.warn(format_args!(
                            "M303 E{e}: no such heater (E0 the hotend, E-1 the bed)"
                        ));
                        return false;
                    }
                };
                let t = target_c.unwrap_or(if id == HeaterId::Bed { 70.0 } else { 200.0 });
                let c = cycles.unwrap_or(5).min(255) as u8;
                let now = self.now_us;
                if let Err(e) = self.thermal.start_autotune(id, t, c, *use_result, now) {
                    self.warn(format_args!("M303 S{t}: {e}"));
                }
            }
            G::EnableSteppers(axes) => {
                let mask = axis_mask(axes);
                let _ = self
                    .cmds
                    .push_back(Command::Steppers(StepperRequest::Enable { mask }));
            }
            G::DisableSteppers { axes, s, .. } => match s {
                Some(s) if s.is_finite() && *s >= 0.0 => {
                    let _ = self
                        .cmds
                        .push_back(Command::Steppers(StepperRequest::IdleTimeout { s: *s }));
                }
                Some(_) => self.warn(format_args!("M84 S: timeout must be >= 0 s")),
                None => {
                    let mask = axis_mask(axes);
                    let _ = self
                        .cmds
                        .push_back(Command::Steppers(StepperRequest::Disable { mask }));
                }
            },
            G::Tool(0) => {}
            G::Progress(p) => self.note_progress(p),
            G::Report(c) => self.report_command(c),
            G::PrintStatsInfo { .. } | G::SetLineNumber(_) => {}
            // Marlin on a single-extruder machine: `invalid_extruder_error`, nothing changes.
            G::Tool(n) => self.warn(format_args!(
                "T{n}: invalid extruder (this printer has T0 only)"
            )),
            G::Stop { ms, s, .. } => {
                if ms.is_some() || s.is_some() {
                    match crate::machine::dwell_ms(*ms, *s) {
                        Ok(ms) => {
                            let _ = self.cmds.push_back(Command::Dwell { ms });
                        }
                        Err(e) => self.warn(format_args!("{e}")),
                    }
                } else {
                    let _ = self.cmds.push_back(Command::PauseHere);
                }
            }
            G::FilamentChange(_) => {
                // Park at the pause position; the user unloads/loads, then resumes (M24).
                let _ = self.cmds.push_back(Command::PauseHere);
            }
            G::Settings(c) => self.settings_command(c),
            G::Driver(c) => self.driver_command(c),
            G::Sd(c) => return self.sd_command(c),
            G::Recovery(c) => return self.recovery_command(c),
            G::Unknown(t) => {
                self.link.respond(Response::UnknownCommand(t));
            }
            _ => {}
        }
        false
    }

    pub(super) fn report_temperatures(&mut self) -> bool {
        let report = self.temp_report();
        self.link.respond(Response::Temperatures {
            report,
            with_ok: true,
        });
        true
    }

    pub(super) fn m760(&mut self, p: &gcode::PauseParams) {
        if p.is_empty() {
            let c = self.cfg.pause;
            let t = self.thermal.idle_config().map_or(0, |i| i.timeout_s);
            self.say(format_args!(
                "M760 R{:.2} Z{:.2} X{:.1} Y{:.1} F{:.0} S{:.2} V{:.1} L{:.3} T{t}",
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
            self.thermal
                .set_idle((secs > 0).then_some(crate::thermal::IdleConfig {
                    timeout_s: secs,
                    nozzle_c: 0.0,
                }));
        }
        let pos = |v: Option<f32>| v.filter(|x| x.is_finite() && *x >= 0.0);
        let c = &mut self.cfg.pause;
        if let Some(v) = pos(p.retract_mm) {
            c.retract_mm = v.min(20.0);
        }
        if let Some(v) = pos(p.lift_z_mm) {
            c.lift_z_mm = v;
        }
        if let Some(v) = pos(p.park_x_mm) {
            c.park_x_mm = v;
        }
        if let Some(v) = pos(p.park_y_mm) {
            c.park_y_mm = v;
        }
        if let Some(v) = pos(p.park_feed_mm_min).filter(|v| *v > 0.0) {
            c.park_feed_mm_s = v / 60.0;
        }
        if let Some(v) = pos(p.speedup_factor).filter(|v| *v >= 1.0) {
            c.speedup_factor = v;
        }
        if let Some(v) = pos(p.max_volumetric_mm3_s).filter(|v| *v > 0.0) {
            c.max_volumetric_mm3_s = v;
        }
        if let Some(v) = pos(p.segment_len_mm) {
            // 0 turns segmentation off; tiny values would flood the ring.
            c.segment_len_mm = if v == 0.0 { 0.0 } else { v.max(0.05) };
        }
    }

    pub(super) fn m761(&mut self, s: &PauseSchedule) {
        match *s {
            PauseSchedule::Report => match self.schedule {
                Some(Schedule::Layer(n)) => self.say(format_args!("pause scheduled at layer {n}")),
                Some(Schedule::Z(z)) => {
                    self.say(format_args!("pause scheduled at Z{:.3}", z as f32 / 1000.0))
                }
                None => self.say(format_args!("no pause scheduled")),
            },
            PauseSchedule::Clear => {
                self.schedule = None;
                self.say(format_args!("pause schedule cleared"));
            }
            PauseSchedule::Layer(n) => self.m761_layer(n),
            PauseSchedule::Z(z) => {
                let um = libm::roundf(z * 1000.0);
                let um = if um.is_finite() {
                    um.clamp(i32::MIN as f32, i32::MAX as f32) as i32
                } else {
                    0
                };
                self.schedule = Some(Schedule::Z(um));
                self.say(format_args!("pause scheduled at Z{z:.3}"));
                self.schedule_queued_marks();
            }
        }
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
