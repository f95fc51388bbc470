//! The settings M-codes in the executive: M92 M201 M203 M205 M206 M851 M906 change the
//! configuration at once (M204 and M760's pause values are set here too; M301/M304 are the heat part's); M500/M501 are
//! requests the driver carries out with its flash ([`Printer::service_store`]); M502 restores
//! the factory values; M503 reports every setting as G-code that can be sent back.
//!
//! A value out of range is refused with `echo:refused: …` (the executive's convention for
//! refusals) naming it and its range, and nothing of that command changes (no `Error:`: a host
//! would stop the job for it). Steps per mm change only
//! while nothing is queued or moving: the position is re-expressed in the new steps then, as
//! Marlin's M92 does, so no move jumps.

use super::host::Host;
use super::Printer;
use crate::drivers::TravelFrame;
use crate::gcode::{self, AxisWords, Heater, PauseParams, SettingsCommand};
use crate::gcode::{HeatCommand, PauseCommand};
use crate::link::Response;
use crate::motion::{Axis, StepPos, AXES};
use crate::storage::{
    Bound, Settings, DRIVER_CURRENT, HOME_OFFSET, JUNCTION_DEVIATION, MAX_FEED, STEPS_PER_MM,
};
use crate::thermal::HeaterId;
use core::fmt::Write as _;
use heapless::String;

/// A request for the driver's settings store.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum StoreRequest {
    /// M500: save these (a snapshot taken when the M500 was read).
    Save(Settings),
    /// M501: load and apply.
    Load,
}

/// The executive's settings state: the factory values and a pending store request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SettingsLink {
    /// The machine's configuration (what the settings commands change).
    cfg: crate::config::MachineConfig,
    factory: Option<Settings>,
    request: Option<StoreRequest>,
    /// Idle since (µs), for the store's erase-ahead.
    idle_since_us: Option<u64>,
    /// The store's reserve was checked in this idle period (or nothing was stored since).
    reserve_checked: bool,
    /// Configuration changes so far (any M-code that changes it): the board's step interrupt
    /// takes its floors (M92, M203) again when this changes.
    config_epoch: u32,
    /// Step frame changes so far (steps per mm), and the position they left.
    frame_epoch: u32,
    frame_pos: StepPos,
}

impl SettingsLink {
    pub(super) const fn new(cfg: crate::config::MachineConfig) -> Self {
        Self {
            cfg,
            factory: None,
            request: None,
            idle_since_us: None,
            reserve_checked: false,
            config_epoch: 0,
            frame_epoch: 0,
            frame_pos: [0; AXES],
        }
    }

    /// The machine's configuration.
    pub(super) fn cfg(&self) -> &crate::config::MachineConfig {
        &self.cfg
    }

    /// The configuration, to change (the driver's configuration, M760's pause values): counted
    /// as a change ([`Printer::config_epoch`]).
    pub(super) fn cfg_mut(&mut self) -> &mut crate::config::MachineConfig {
        self.config_epoch = self.config_epoch.wrapping_add(1);
        &mut self.cfg
    }

    /// The factory values are known.
    pub(super) fn has_factory(&self) -> bool {
        self.factory.is_some()
    }

    /// The store's request, for its service (which re-checks the reserve afterwards).
    pub(super) fn take_request(&mut self) -> Option<StoreRequest> {
        self.reserve_checked = false;
        self.request.take()
    }

    /// An M500/M501 waits for the store.
    pub(super) fn request_pending(&self) -> bool {
        self.request.is_some()
    }

    /// Whether the store's erase-ahead is due: the printer has been `idle` for `period_us`
    /// and it was not done in this idle period (then it counts as done).
    pub(super) fn erase_ahead_due(&mut self, idle: bool, now_us: u64, period_us: u64) -> bool {
        if !idle {
            self.idle_since_us = None;
            return false;
        }
        let since = *self.idle_since_us.get_or_insert(now_us);
        if self.reserve_checked || now_us.saturating_sub(since) < period_us {
            return false;
        }
        self.reserve_checked = true;
        true
    }

    /// M204: set the accelerations given (S sets print and travel), all or nothing: a value
    /// outside the settings store's range (one table) refuses the whole line.
    pub(super) fn m204(
        &mut self,
        print: Option<f32>,
        retract: Option<f32>,
        travel: Option<f32>,
        s: Option<f32>,
        host: &mut Host,
    ) {
        let b = crate::ranges::ACCEL;
        let given = [('S', s), ('P', print), ('R', retract), ('T', travel)];
        if let Some((l, Some(v))) = given
            .iter()
            .find(|(_, v)| v.is_some_and(|v| !b.contains(v)))
        {
            host.say(format_args!(
                "refused: M204 {l}{v}: {} out of range ({}..{} {}); nothing changed",
                b.name, b.min, b.max, b.unit
            ));
            return;
        }
        let c = &mut self.cfg;
        if let Some(a) = s {
            c.accel_print_mm_s2 = a;
            c.accel_travel_mm_s2 = a;
        }
        if let Some(a) = print {
            c.accel_print_mm_s2 = a;
        }
        if let Some(a) = retract {
            c.accel_retract_mm_s2 = a;
        }
        if let Some(a) = travel {
            c.accel_travel_mm_s2 = a;
        }
    }

    /// M760's pause values (checked against the machine by the caller).
    pub(super) fn m760(&mut self, p: &PauseParams) {
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
}

/// Longest M503 line (`echo:  ` and a command with every number at full length).
const REPORT_LEN: usize = 192;

const LETTERS: [char; AXES] = ['X', 'Y', 'Z', 'E'];

impl Printer {
    /// The current settings (what M500 would save).
    pub fn settings(&self) -> Settings {
        let t = self.heat.thermal();
        Settings::from_config(
            &self.settings.cfg,
            t.pid(HeaterId::Hotend),
            t.pid(HeaterId::Bed),
        )
    }

    /// The factory settings: what this printer was built with (M502 restores them).
    pub fn factory_settings(&self) -> Settings {
        self.settings.factory.unwrap_or_else(|| self.settings())
    }

    /// Remember the current settings as the factory ones (the constructor does this; a driver
    /// that changes the configuration before the first command calls it again).
    pub fn set_factory_settings(&mut self) {
        self.settings.factory = Some(self.settings());
    }

    /// Counts every change of the configuration (M92 M201 M203 M205 M206 M350 M501 M502 …):
    /// a driver that derives something from it (the step interrupt's floors from steps per mm
    /// and max feed) takes it again when this changes.
    pub fn config_epoch(&self) -> u32 {
        self.settings.config_epoch
    }

    /// The step frame the step interrupt must follow: the travel limits in the current steps
    /// per mm and, after a change of them, the position re-expressed in the new steps (see
    /// [`TravelFrame`]).
    pub fn travel_frame(&self) -> TravelFrame {
        TravelFrame {
            epoch: self.settings.frame_epoch,
            pos: self.settings.frame_pos,
            limits: self.settings.cfg.travel_limits_steps(),
        }
    }

    /// True when nothing is queued or moving and no pause is under way: steps per mm may
    /// change.
    fn settings_idle(&self) -> bool {
        self.pause.running() && !self.has_work()
    }

    /// Apply `s`. Refused (nothing changes) when the steps per mm differ while motion is
    /// queued, or when a value is out of range.
    pub fn apply_settings(&mut self, s: &Settings) -> Result<(), &'static str> {
        s.validate().map_err(|_| "settings out of range")?;
        // The pause values as M760 would take them on this machine (park inside the travel).
        super::guards::check_pause_config(&s.pause, &self.settings.cfg)
            .map_err(|_| "pause values outside this machine's limits")?;
        let steps_change = self
            .settings
            .cfg
            .axes
            .iter()
            .zip(s.steps_per_mm)
            .any(|(a, v)| a.steps_per_mm != v);
        if steps_change && !self.settings_idle() {
            return Err("steps/mm change only while idle (send M400 first)");
        }
        let old = self.settings();
        s.apply_to(self.settings.cfg_mut());
        // M350/M569 values changed: the board writes them to the drivers.
        let mask = (0..AXES)
            .filter(|&i| {
                old.microsteps[i] != s.microsteps[i] || old.stealthchop[i] != s.stealthchop[i]
            })
            .fold(0u8, |m, i| m | 1 << i);
        if mask != 0 {
            self.board
                .push_driver_request(super::DriverRequest::Apply { mask });
        }
        for (id, pid) in [(HeaterId::Hotend, s.hotend_pid), (HeaterId::Bed, s.bed_pid)] {
            if let Some(g) = pid {
                // Checked by validate(): in range, so set_pid accepts it.
                let _ = self.heat.thermal_mut().set_pid(id, g);
            }
        }
        if steps_change {
            self.restep_position();
        }
        Ok(())
    }

    /// Re-express the commanded position in the current steps per mm (after M92), as Marlin's
    /// `planner.refresh_positioning()`: the head does not move.
    fn restep_position(&mut self) {
        let mm = self.intake.machine().machine_mm();
        let cfg = &self.settings.cfg;
        let mut pos = [0i32; AXES];
        for ax in Axis::ALL {
            let v = libm::round(mm[ax.index()] * f64::from(cfg.axis(ax).steps_per_mm));
            pos[ax.index()] = if v.is_finite() {
                v.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
            } else {
                0
            };
        }
        self.intake.machine_at(&pos, &self.settings.cfg);
        self.motion.set_position(pos);
        self.settings.frame_epoch = self.settings.frame_epoch.wrapping_add(1);
        self.settings.frame_pos = pos;
    }

    /// Handle a settings command (the `ok` is sent by the caller).
    pub(super) fn settings_command(&mut self, c: &SettingsCommand) {
        use SettingsCommand as S;
        match c {
            S::Acceleration {
                print,
                retract,
                travel,
                s,
            } => self
                .settings
                .m204(*print, *retract, *travel, *s, &mut self.host),
            S::StepsPerUnit(a) => self.m92(a),
            S::MaxAccel(a) => self.set_axes("M201", a, &crate::storage::ACCEL, |cfg, i, v| {
                cfg.axes[i].max_accel_mm_s2 = v
            }),
            S::MaxFeed(a) => self.set_axes("M203", a, &MAX_FEED, |cfg, i, v| {
                cfg.axes[i].max_feed_mm_s = v
            }),
            S::Advanced(p) => self.m205(p),
            S::HomeOffset(a) => self.set_axes("M206", a, &HOME_OFFSET, |cfg, i, v| {
                if let Some(h) = cfg.home_offset_mm.get_mut(i) {
                    *h = v;
                }
            }),
            S::ProbeOffset(_) => {
                self.host
                    .say(format_args!("refused: M851: this machine has no Z probe"));
            }
            S::DriverCurrent(a) => self.m906(a),
            S::Save => self.settings.request = Some(StoreRequest::Save(self.settings())),
            S::Load => self.settings.request = Some(StoreRequest::Load),
            S::FactoryReset => {
                let f = self.factory_settings();
                match self.apply_settings(&f) {
                    Ok(()) => self
                        .host
                        .say(format_args!("Hardcoded Default Settings Loaded")),
                    Err(e) => self.host.say(format_args!("refused: M502: {e}")),
                }
            }
            S::Report => self.m503(),
        }
    }

    /// The first given value outside `b`, as (axis index, value).
    fn out_of_range(a: &AxisWords, b: &Bound) -> Option<(usize, f32)> {
        a.0.iter()
            .enumerate()
            .find_map(|(i, v)| v.filter(|v| !b.contains(*v)).map(|v| (i, v)))
    }

    fn refuse(&mut self, code: &str, axis: usize, v: f32, b: &Bound) {
        let l = LETTERS.get(axis).copied().unwrap_or('?');
        self.host.say(format_args!(
            "refused: {code} {l}{v}: {} out of range ({}..{} {}); nothing changed",
            b.name, b.min, b.max, b.unit
        ));
    }

    /// Set (or with no value report) one per-axis value of the configuration.
    fn set_axes(
        &mut self,
        code: &str,
        a: &AxisWords,
        b: &Bound,
        set: impl Fn(&mut crate::config::MachineConfig, usize, f32),
    ) {
        if a.is_empty() {
            self.report_line(&self.current(code));
            return;
        }
        if let Some((i, v)) = Self::out_of_range(a, b) {
            self.refuse(code, i, v, b);
            return;
        }
        for (i, v) in a.0.iter().enumerate() {
            if let Some(v) = v {
                set(self.settings.cfg_mut(), i, *v);
            }
        }
    }

    fn m92(&mut self, a: &AxisWords) {
        if a.is_empty() {
            self.report_line(&self.current("M92"));
            return;
        }
        if let Some((i, v)) = Self::out_of_range(a, &STEPS_PER_MM) {
            self.refuse("M92", i, v, &STEPS_PER_MM);
            return;
        }
        let mut s = self.settings();
        for (i, v) in a.0.iter().enumerate() {
            if let Some(v) = v {
                s.steps_per_mm[i] = *v;
            }
        }
        if let Err(e) = self.apply_settings(&s) {
            self.host.say(format_args!("refused: M92: {e}"));
        }
    }

    fn m205(&mut self, p: &gcode::Advanced) {
        let unused = !p.jerk.is_empty()
            || p.min_segment_us.is_some()
            || p.min_feed_mm_s.is_some()
            || p.min_travel_mm_s.is_some();
        if let Some(j) = p.junction_mm {
            if !JUNCTION_DEVIATION.contains(j) {
                let b = JUNCTION_DEVIATION;
                self.host.say(format_args!(
                    "refused: M205 J{j}: {} out of range ({}..{} {}); nothing changed",
                    b.name, b.min, b.max, b.unit
                ));
                return;
            }
            self.settings.cfg.junction_deviation_mm = j;
        }
        if unused {
            self.host.say(format_args!(
                "refused: M205 X Y Z E (jerk), B, S, T: not used, corners are planned by junction deviation (J)"
            ));
        } else if p.junction_mm.is_none() {
            self.report_line(&self.current("M205"));
        }
    }

    fn m906(&mut self, a: &AxisWords) {
        if a.is_empty() {
            self.report_line(&self.current("M906"));
            return;
        }
        if let Some((i, v)) = Self::out_of_range(a, &DRIVER_CURRENT) {
            self.refuse("M906", i, v, &DRIVER_CURRENT);
            return;
        }
        for (i, v) in a.0.iter().enumerate() {
            if let Some(v) = v {
                // In range (100..2000): the rounded value fits a u16.
                self.settings.cfg.driver_current_ma[i] = libm::roundf(*v) as u16;
            }
        }
    }

    /// The current values of one settings M-code, as a command.
    fn current(&self, code: &str) -> gcode::Command {
        let c = &self.settings.cfg;
        let per_axis = |f: &dyn Fn(usize) -> f32| AxisWords([0, 1, 2, 3].map(|i| Some(f(i))));
        use SettingsCommand as S;
        gcode::Command::Settings(match code {
            "M92" => S::StepsPerUnit(per_axis(&|i| c.axes[i].steps_per_mm)),
            "M201" => S::MaxAccel(per_axis(&|i| c.axes[i].max_accel_mm_s2)),
            "M203" => S::MaxFeed(per_axis(&|i| c.axes[i].max_feed_mm_s)),
            "M205" => S::Advanced(gcode::Advanced {
                junction_mm: Some(c.junction_deviation_mm),
                ..gcode::Advanced::default()
            }),
            "M206" => S::HomeOffset(AxisWords([
                Some(c.home_offset_mm[0]),
                Some(c.home_offset_mm[1]),
                Some(c.home_offset_mm[2]),
                None,
            ])),
            _ => S::DriverCurrent(per_axis(&|i| f32::from(c.driver_current_ma[i]))),
        })
    }

    /// One report line: `echo:  <command>`.
    fn report_line(&mut self, c: &gcode::Command) {
        let mut t: String<REPORT_LEN> = String::new();
        let _ = write!(t, "  {c}");
        self.host.respond(Response::Echo(&t));
    }

    /// M503: every setting as G-code a user can paste back (strip the `echo:`).
    fn m503(&mut self) {
        self.host.say(format_args!(
            "; Settings (M500 saves, M501 loads, M502 factory):"
        ));
        // M350 before M92: sent back, M350 scales steps/mm, then M92 sets them exactly.
        let c = &self.settings.cfg;
        self.report_line(&gcode::Command::Driver(gcode::DriverCommand::Microsteps {
            all: None,
            axes: AxisWords(core::array::from_fn(|i| {
                Some(f32::from(c.axes[i].microsteps))
            })),
        }));
        for on in [true, false] {
            let axes = gcode::AxisFlags(core::array::from_fn(|i| {
                self.settings.cfg.driver_stealthchop[i] == on
            }));
            if axes.0.iter().any(|a| *a) {
                self.report_line(&gcode::Command::Driver(gcode::DriverCommand::Chopper {
                    axes,
                    stealthchop: Some(on),
                }));
            }
        }
        for code in ["M92", "M203", "M201"] {
            let c = self.current(code);
            self.report_line(&c);
        }
        let c = &self.settings.cfg;
        let accel = gcode::Command::Settings(SettingsCommand::Acceleration {
            print: Some(c.accel_print_mm_s2),
            retract: Some(c.accel_retract_mm_s2),
            travel: Some(c.accel_travel_mm_s2),
            s: None,
        });
        self.report_line(&accel);
        for code in ["M205", "M206"] {
            let c = self.current(code);
            self.report_line(&c);
        }
        for (id, heater) in [
            (HeaterId::Hotend, Heater::Hotend),
            (HeaterId::Bed, Heater::Bed),
        ] {
            if let Some(g) = self.heat.thermal().pid(id) {
                self.report_line(&gcode::Command::Heat(HeatCommand::SetPid {
                    heater,
                    p: Some(g.kp),
                    i: Some(g.ki),
                    d: Some(g.kd),
                }));
            }
        }
        let c = self.current("M906");
        self.report_line(&c);
        let timeout_s = self.heat.thermal().idle_config().map_or(0, |i| i.timeout_s);
        self.report_line(&gcode::Command::Pause(PauseCommand::Params(
            PauseParams::from_config(&self.settings.cfg.pause, Some(timeout_s as f32)),
        )));
    }
}
