//! The host side of the executive: lines from the link are parsed, interpreted by the machine
//! state, fed to the layer detector and queued as [`Command`]s; commands that are not motion
//! (temperatures, reports, M760/M761, ...) are answered here.

use super::state::Pause;
use super::{Command, PausedLines, Printer, Schedule, StepperRequest, LINE_LEN};
use crate::gcode::{self, Heater, PauseSchedule};
use crate::layer::MoveFacts;
use crate::link::{PositionReport, ReceivedLine, Response};

use crate::machine::Action;
use crate::motion::Realtime;
use crate::printer::service::ServiceMove;
use crate::printer::CMD_CAPACITY;
use crate::thermal::HeaterId;
use core::fmt::Write as _;
use heapless::String;

fn heater_id(h: Heater) -> HeaterId {
    match h {
        Heater::Hotend => HeaterId::Hotend,
        Heater::Bed => HeaterId::Bed,
    }
}

/// After a cancel, the host may still stream the rest of the job (printcore ignores
/// `//action:cancel`; lines were in flight): those lines are discarded (answered `ok`, never
/// executed) until the host starts anew — a numbered line whose number is not beyond `after`
/// (the host reset its line numbers with M110, as printcore and OctoPrint do at a job's start),
/// or any line after the host was silent for [`crate::printer::LAYER_PAUSE_IDLE_US`].
/// Unnumbered lines from a host that numbers its job (OctoPrint's cancel script, a console
/// command) are taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct AfterCancel {
    /// The last numbered line taken before the cancel.
    pub(super) after: Option<u32>,
    /// Lines discarded so far.
    pub(super) discarded: u32,
}

/// The host-line side of the executive (see docs/frontend.md, "Host rules").
#[derive(Clone, Debug, Default)]
pub(super) struct HostLines {
    /// A line taken from the link that waits for queue room (it needs room; lines that need
    /// none are answered at once, see [`answered_without_room`]).
    pub(super) held_line: Option<ReceivedLine>,
    /// The host has sent numbered lines (it numbers its job): with [`PausedLines::Auto`],
    /// unnumbered lines while paused are manual commands.
    pub(super) host_numbers: bool,
    /// Number of the last numbered line taken.
    pub(super) last_line_no: Option<u32>,
    /// The job was cancelled: the rest of the host's stream is discarded until it starts anew.
    pub(super) after_cancel: Option<AfterCancel>,
    /// An M400 waits for the motion to end: its `ok` is owed, and no further line is taken.
    pub(super) sync_ok_owed: bool,
    /// When the last `busy:` keep-alive went out, µs.
    pub(super) last_busy_us: u64,
}

impl Printer {
    pub(super) fn take_realtime(&mut self) {
        while let Some(rt) = self.link.take_realtime() {
            let now = self.now_us;
            self.request(rt, now);
        }
    }

    fn queued_moves(&self) -> usize {
        self.cmds
            .iter()
            .filter(|c| !matches!(c, Command::Layer(_)))
            .count()
    }

    /// Command slots kept free while a pause is on its way (stopping, parking): the line the
    /// host has in flight when the printer announces `//action:paused` always fits, so its
    /// `ok` follows the announcement and the host can send its resume next (docs/frontend.md,
    /// "host rules").
    fn reserved_lines(&self) -> usize {
        usize::from(matches!(
            self.pause,
            Pause::Stopping { .. } | Pause::Parking { .. }
        ))
    }

    /// Room for one more host line: the policy's limit on waiting commands (layer marks do not
    /// count) less the pause's reserve, and physical room for a mark plus a command.
    fn line_room(&self) -> bool {
        let reserve = self.reserved_lines();
        self.queued_moves() + reserve < self.policy.cmd_limit.clamp(1, CMD_CAPACITY)
            && self.cmds.len() + 2 + reserve <= CMD_CAPACITY
    }

    /// Whether a host line taken now is a manual command (while parked, see [`PausedLines`]).
    fn is_manual(&self, line: &ReceivedLine) -> bool {
        matches!(self.pause, Pause::Parked { .. })
            && match self.policy.paused_lines {
                PausedLines::Queue => false,
                PausedLines::Manual => true,
                PausedLines::Auto => self.lines.host_numbers && line.number().is_none(),
            }
    }

    /// The next host line: the one waiting for room, else the link's next (only while the
    /// output ring can take its answer).
    fn next_line(&mut self) -> Option<ReceivedLine> {
        if self.lines.held_line.is_some() {
            if self.link.line_output_free() < crate::link::OUT_RESERVE {
                return None;
            }
            self.link.answer_line_port();
            return self.lines.held_line.take();
        }
        self.link.pop_line()
    }

    /// Take lines from the link while there is room, and answer each. A line that needs no
    /// queue room (reports, messages) is answered even when the queue is full; one that needs
    /// room waits in `held_line`, with `busy:` keep-alives while a pause holds the queue.
    pub(super) fn process_lines(&mut self) {
        for _ in 0..64 {
            if self.is_halted() {
                return;
            }
            if self.arc.is_some() {
                self.push_arc();
                if self.arc.is_some() {
                    return;
                }
                self.link.respond(Response::Ok);
            }
            if self.lines.sync_ok_owed {
                // M400 is waiting for the motion to end: the next line waits too.
                return;
            }
            if let Some(held) = &self.lines.held_line {
                // Known to need room: wait for it without parsing again.
                let fits = if self.is_manual(held) {
                    !self.service.is_full()
                } else {
                    self.line_room()
                };
                if !fits {
                    if !matches!(self.pause, Pause::Run) {
                        self.keep_alive();
                    }
                    return;
                }
            }
            if self.pause.cancelling() {
                // The cancel is still parking: lines wait (a move taken now would be dropped
                // with the planner when the cancel completes).
                if self.link.lines_waiting() > 0 || self.lines.held_line.is_some() {
                    self.keep_alive();
                }
                return;
            }
            let Some(line) = self.next_line() else {
                return;
            };
            if self.discard_after_cancel(&line) {
                self.link.respond(Response::Ok);
                continue;
            }
            let manual = self.is_manual(&line);
            let fits = if manual {
                !self.service.is_full()
            } else {
                self.line_room()
            };
            if !fits {
                if answered_without_room(&line) {
                    self.answer_report(&line);
                    continue;
                }
                self.lines.held_line = Some(line);
                if !matches!(self.pause, Pause::Run) {
                    // A pause holds the queue: keep the host from timing out.
                    self.keep_alive();
                }
                return;
            }
            if line.number().is_some() {
                self.lines.host_numbers = true;
                self.lines.last_line_no = line.number();
            }
            self.last_activity_us = self.now_us;
            if manual {
                self.swap_manual_machine();
                self.handle_line(&line, true);
                self.swap_manual_machine();
            } else {
                self.handle_line(&line, false);
            }
            self.feed_planner();
        }
    }

    /// Swap the job's modal state with the manual one of the parked pause (if any): manual
    /// lines are interpreted between two swaps.
    fn swap_manual_machine(&mut self) {
        if let Pause::Parked {
            manual: Some(m), ..
        } = &mut self.pause
        {
            core::mem::swap(&mut self.machine, m);
        }
    }

    /// Whether `line` is the rest of a cancelled job (see [`AfterCancel`]): then it is
    /// counted and must be answered `ok` without being executed. Ends the discarding when the
    /// host has started anew.
    fn discard_after_cancel(&mut self, line: &ReceivedLine) -> bool {
        let Some(mut a) = self.lines.after_cancel else {
            return false;
        };
        let silent_us = self.now_us.saturating_sub(self.last_activity_us);
        let fresh = silent_us >= crate::printer::LAYER_PAUSE_IDLE_US
            || match (line.number(), a.after) {
                // Numbers restarted (M110): a new job.
                (Some(n), Some(after)) => n <= after,
                (Some(_), None) => false,
                // A host that numbers its job sends its own commands unnumbered.
                (None, _) => self.lines.host_numbers,
            };
        self.last_activity_us = self.now_us;
        if fresh {
            if line.number().is_some() || silent_us >= crate::printer::LAYER_PAUSE_IDLE_US {
                if a.discarded > 0 {
                    self.say(format_args!(
                        "cancelled: {} lines of the cancelled job discarded",
                        a.discarded
                    ));
                }
                self.lines.after_cancel = None;
            }
            return false;
        }
        if a.discarded == 0 {
            self.say(format_args!(
                "cancelled: discarding the rest of the job until the host starts anew"
            ));
        }
        a.discarded = a.discarded.saturating_add(1);
        self.lines.after_cancel = Some(a);
        true
    }

    /// Answer a report/message line out of turn (the queue is full): it changes nothing the
    /// job depends on, so its place in the stream does not matter.
    fn answer_report(&mut self, line: &ReceivedLine) {
        match line.parse() {
            Ok(gcode::Line {
                command: Some(cmd), ..
            }) => {
                if !self.executive(&cmd) {
                    self.link.respond(Response::Ok);
                }
            }
            Ok(_) => {
                self.link.respond(Response::Ok);
            }
            Err(e) => {
                self.warn(format_args!("{e}"));
                self.link.respond(Response::Ok);
            }
        }
    }

    fn push_arc(&mut self) {
        while self.arc.is_some() {
            if !self.line_room() {
                return;
            }
            match self.arc.as_mut().and_then(|a| a.next()) {
                Some(m) => {
                    let _ = self.cmds.push_back(Command::Move(m));
                }
                None => self.arc = None,
            }
        }
    }

    /// A refused line: `echo:refused: <why>`, never `Error:` (OctoPrint cancels the print on
    /// any `Error:` that is not about line numbers or checksums). The line changed nothing:
    /// the machine's state is as before it. See the response table in docs/frontend.md.
    fn warn(&mut self, args: core::fmt::Arguments) {
        let mut t: String<LINE_LEN> = String::new();
        let _ = t.write_str("refused: ");
        let _ = t.write_fmt(args);
        self.link.respond(Response::Echo(&t));
    }

    fn handle_line(&mut self, line: &ReceivedLine, manual: bool) {
        let parsed = match line.parse() {
            Ok(l) => l,
            Err(e) => {
                self.warn(format_args!("{e}"));
                self.link.respond(Response::Ok);
                return;
            }
        };
        let before = self.machine.position_steps(&self.cfg);
        let action = match &parsed.command {
            Some(cmd) => match self.machine.apply(cmd, &self.cfg) {
                Ok(a) => a,
                Err(e) => {
                    self.warn(format_args!("{e}"));
                    self.link.respond(Response::Ok);
                    return;
                }
            },
            None => Action::None,
        };
        let after = self.machine.position_steps(&self.cfg);
        if !manual {
            let facts = MoveFacts::between(&before, &after, &self.cfg);
            if let Some(mark) = self.layers.feed(&parsed, facts) {
                let _ = self.cmds.push_back(Command::Layer(mark));
            }
            // M400 after a layer's marker comments: the boundary is here (a host that drains
            // the queue at a boundary, then pauses, stops at this layer, not the next).
            if matches!(parsed.command, Some(gcode::Command::WaitMoves)) {
                if let Some(mark) = self.layers.finish() {
                    let _ = self.cmds.push_back(Command::Layer(mark));
                }
            }
        }
        let mut answered = false;
        match action {
            Action::None => {}
            Action::Move(m) => {
                if manual {
                    let _ = self.service.push_back(ServiceMove {
                        target: m.target,
                        feed_mm_s: m.feed_mm_s,
                    });
                } else {
                    let _ = self.cmds.push_back(Command::Move(m));
                }
            }
            Action::Arc(a) => {
                if manual {
                    self.warn(format_args!("arcs are not taken while paused"));
                } else {
                    self.arc = Some(a);
                    self.push_arc();
                    if self.arc.is_some() {
                        return; // `ok` once the whole arc is queued
                    }
                }
            }
            Action::Home(flags) => {
                if manual {
                    self.warn(format_args!("homing is not allowed while paused"));
                } else {
                    let mut mask = 0u8;
                    for (i, on) in flags.0.iter().enumerate() {
                        if *on {
                            mask |= 1 << i;
                        }
                    }
                    let _ = self.cmds.push_back(Command::Home { mask });
                }
            }
            Action::Dwell { ms } => {
                if !manual {
                    let _ = self.cmds.push_back(Command::Dwell { ms });
                }
            }
            Action::Executive => {
                if let Some(cmd) = &parsed.command {
                    answered = self.executive(cmd);
                }
            }
        }
        if !answered {
            self.link.respond(Response::Ok);
        }
    }

    /// Commands the machine state leaves to the executive. Returns true when the `ok` was
    /// already sent (M105 answers `ok T:...`).
    fn executive(&mut self, cmd: &gcode::Command) -> bool {
        use gcode::Command as G;
        match cmd {
            G::SetTemperature {
                heater, wait, s, r, ..
            } => {
                let id = heater_id(*heater);
                if let Some(t) = r.or(*s) {
                    if let Err(e) = self.thermal.set_target(id, t) {
                        self.warn(format_args!("{e}"));
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
                let ok = |v: &Option<f32>| v.filter(|a| a.is_finite() && *a > 0.0);
                if let Some(a) = ok(s) {
                    self.cfg.accel_print_mm_s2 = a;
                    self.cfg.accel_travel_mm_s2 = a;
                }
                if let Some(a) = ok(print) {
                    self.cfg.accel_print_mm_s2 = a;
                }
                if let Some(a) = ok(retract) {
                    self.cfg.accel_retract_mm_s2 = a;
                }
                if let Some(a) = ok(travel) {
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
            G::PauseParams(p) => self.m760(p),
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
                let id = if *heater_index == Some(-1) {
                    HeaterId::Bed
                } else {
                    HeaterId::Hotend
                };
                let t = target_c.unwrap_or(if id == HeaterId::Bed { 70.0 } else { 200.0 });
                let c = cycles.unwrap_or(5).min(255) as u8;
                let now = self.now_us;
                if let Err(e) = self.thermal.start_autotune(id, t, c, *use_result, now) {
                    self.warn(format_args!("{e}"));
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
            G::Tool(n) => self.warn(format_args!("T{n}: only one extruder")),
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
            G::Unknown(t) => {
                self.link.respond(Response::UnknownCommand(t));
            }
            _ => {}
        }
        false
    }

    fn report_temperatures(&mut self) -> bool {
        let report = crate::link::TempReport {
            hotend_c: self.thermal.temperature_c(HeaterId::Hotend),
            hotend_target_c: self.thermal.target_c(HeaterId::Hotend),
            bed_c: Some((
                self.thermal.temperature_c(HeaterId::Bed),
                self.thermal.target_c(HeaterId::Bed),
            )),
            hotend_duty: self.thermal.duty(HeaterId::Hotend),
            bed_duty: self.thermal.duty(HeaterId::Bed),
        };
        self.link.respond(Response::Temperatures {
            report,
            with_ok: true,
        });
        true
    }

    fn m760(&mut self, p: &gcode::PauseParams) {
        if p.is_empty() {
            let c = self.cfg.pause;
            self.say(format_args!(
                "M760 R{:.2} Z{:.2} X{:.1} Y{:.1} F{:.0} S{:.2} V{:.1} L{:.3}",
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

    fn m761(&mut self, s: &PauseSchedule) {
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
            PauseSchedule::Layer(n) => {
                self.schedule = Some(Schedule::Layer(n));
                self.say(format_args!("pause scheduled at layer {n}"));
                self.schedule_queued_marks();
            }
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

/// Lines the executive answers without command-queue room, even while a pause holds a full
/// queue: reports and messages, which queue nothing and change no state a later job line is
/// interpreted in (and lines that do not parse: answered, nothing queued). Realtime lines
/// (M24/M25/M108/M112/M410/M524/M601/M602) never wait: the link acts on them as they arrive.
pub(super) fn answered_without_room(line: &ReceivedLine) -> bool {
    use gcode::Command as G;
    match line.parse() {
        Err(_) => true,
        Ok(gcode::Line { command: None, .. }) => false,
        Ok(gcode::Line {
            command: Some(c), ..
        }) => match c {
            G::ReportTemperatures
            | G::ReportPosition
            | G::FirmwareInfo
            | G::Message(_)
            | G::Echo(_)
            | G::Progress(_)
            | G::Report(_)
            | G::PrintStatsInfo { .. }
            | G::FeedOverride(None)
            | G::FlowOverride(None)
            | G::SchedulePause(PauseSchedule::Report)
            | G::SetLineNumber(_)
            | G::Tool(0)
            | G::Unknown(_) => true,
            G::PauseParams(p) => p.is_empty(),
            _ => false,
        },
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
