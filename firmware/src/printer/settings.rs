//! The settings M-codes in the executive: M92 M201 M203 M205 M206 M851 M906 change the
//! configuration at once (M204 M301 M304 M760 are handled in `host.rs`); M500/M501 are
//! requests the driver carries out with its flash ([`Printer::service_store`]); M502 restores
//! the factory values; M503 reports every setting as G-code that can be sent back.
//!
//! A value out of range is refused with `echo:refused: …` (the executive's convention for
//! refusals) naming it and its range, and nothing of that command changes (no `Error:`: a host
//! would stop the job for it). Steps per mm change only
//! while nothing is queued or moving: the position is re-expressed in the new steps then, as
//! Marlin's M92 does, so no move jumps.

use super::state::Pause;
use super::Printer;
use crate::drivers::TravelFrame;
use crate::gcode::{self, AxisWords, Heater, PauseParams, SettingsCommand};
use crate::link::Response;
use crate::motion::{Axis, StepPos, AXES};
use crate::storage::{
    Bound, Settings, SettingsStore, StoreError, Stored, ACCEL, DRIVER_CURRENT, HOME_OFFSET,
    JUNCTION_DEVIATION, MAX_FEED, STEPS_PER_MM,
};
use crate::thermal::HeaterId;
use core::fmt::Write as _;
use embedded_storage::nor_flash::NorFlash;
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
    pub(super) const fn new() -> Self {
        Self {
            factory: None,
            request: None,
            idle_since_us: None,
            reserve_checked: false,
            config_epoch: 0,
            frame_epoch: 0,
            frame_pos: [0; AXES],
        }
    }
}

/// What a store says when it had to reclaim the area (nothing when it appended).
pub(super) struct Reclaim(pub(super) Stored);

impl core::fmt::Display for Reclaim {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Stored::Appended => Ok(()),
            Stored::Reclaimed => f.write_str("; the unreadable settings area was erased first"),
        }
    }
}

/// How long the printer must have been idle before the store may erase a sector ahead, µs
/// (`storage::reserve`: the erase stalls the MCU for up to 2 s, heaters off meanwhile).
pub const ERASE_AHEAD_IDLE_US: u64 = 10_000_000;

/// Longest M503 line (`echo:  ` and a command with every number at full length).
const REPORT_LEN: usize = 192;

const LETTERS: [char; AXES] = ['X', 'Y', 'Z', 'E'];

impl Printer {
    /// The current settings (what M500 would save).
    pub fn settings(&self) -> Settings {
        Settings::from_config(
            &self.cfg,
            self.thermal.pid(HeaterId::Hotend),
            self.thermal.pid(HeaterId::Bed),
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
            limits: self.cfg.travel_limits_steps(),
        }
    }

    /// True when nothing is queued or moving and no pause is under way: steps per mm may
    /// change.
    fn settings_idle(&self) -> bool {
        matches!(self.pause, Pause::Run) && !self.has_work()
    }

    /// Apply `s`. Refused (nothing changes) when the steps per mm differ while motion is
    /// queued, or when a value is out of range.
    pub fn apply_settings(&mut self, s: &Settings) -> Result<(), &'static str> {
        s.validate().map_err(|_| "settings out of range")?;
        // The pause values as M760 would take them on this machine (park inside the travel).
        super::guards::check_pause_config(&s.pause, &self.cfg)
            .map_err(|_| "pause values outside this machine's limits")?;
        let steps_change = self
            .cfg
            .axes
            .iter()
            .zip(s.steps_per_mm)
            .any(|(a, v)| a.steps_per_mm != v);
        if steps_change && !self.settings_idle() {
            return Err("steps/mm change only while idle (send M400 first)");
        }
        let old = self.settings();
        s.apply_to(&mut self.cfg);
        self.settings.config_epoch = self.settings.config_epoch.wrapping_add(1);
        // M350/M569 values changed: the board writes them to the drivers.
        let mask = (0..AXES)
            .filter(|&i| {
                old.microsteps[i] != s.microsteps[i] || old.stealthchop[i] != s.stealthchop[i]
            })
            .fold(0u8, |m, i| m | 1 << i);
        if mask != 0 {
            self.push_driver_request(super::DriverRequest::Apply { mask });
        }
        for (id, pid) in [(HeaterId::Hotend, s.hotend_pid), (HeaterId::Bed, s.bed_pid)] {
            if let Some(g) = pid {
                // Checked by validate(): in range, so set_pid accepts it.
                let _ = self.thermal.set_pid(id, g);
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
        let mm = self.machine.machine_mm();
        let mut pos = [0i32; AXES];
        for ax in Axis::ALL {
            let v = libm::round(mm[ax.index()] * f64::from(self.cfg.axis(ax).steps_per_mm));
            pos[ax.index()] = if v.is_finite() {
                v.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
            } else {
                0
            };
        }
        self.machine.set_position_steps(&pos, &self.cfg);
        self.planner.set_position(pos);
        self.stepgen.set_position(pos);
        self.settings.frame_epoch = self.settings.frame_epoch.wrapping_add(1);
        self.settings.frame_pos = pos;
    }

    /// Boot: load the saved settings and apply them. Nothing saved: the factory values stay,
    /// silently. A store that cannot be read or a record that is refused (corrupt, another
    /// format version, out of range): the factory values stay, with an `echo:` saying why.
    pub fn load_settings<F: NorFlash>(&mut self, store: &mut SettingsStore<F>) {
        if self.settings.factory.is_none() {
            self.set_factory_settings();
        }
        self.job.attached = true;
        self.load_and_apply(store, false);
        self.announce_kept_job(store);
    }

    fn load_and_apply<F: NorFlash>(&mut self, store: &mut SettingsStore<F>, report_empty: bool) {
        match store.load() {
            Ok(Some(s)) => match self.apply_settings(&s) {
                Ok(()) => self.say(format_args!("Settings loaded from flash")),
                Err(e) => self.say(format_args!("saved settings not applied: {e}")),
            },
            Ok(None) => {
                if report_empty {
                    self.say(format_args!("no saved settings: nothing changed"));
                }
            }
            Err(e) => self.fall_back(e),
        }
    }

    fn fall_back(&mut self, e: StoreError) {
        let f = self.factory_settings();
        match self.apply_settings(&f) {
            Ok(()) => self.say(format_args!(
                "saved settings unusable ({e}): factory defaults loaded{}",
                if matches!(e, StoreError::Corrupted | StoreError::Full) {
                    " (M500 erases the area and saves)"
                } else {
                    ""
                }
            )),
            Err(why) => self.say(format_args!(
                "saved settings unusable ({e}); factory defaults not applied: {why}"
            )),
        }
    }

    /// Main loop: carry out a pending M500/M501 and paused-job save/clear with the driver's
    /// store once nothing moves (a flash erase on the STM32F4 stalls every read of the flash,
    /// so code running from it stalls too: never while stepping).
    ///
    /// With nothing to do, after [`ERASE_AHEAD_IDLE_US`] of idle (no job, nothing moving or
    /// paused), once per idle period: the store's erase-ahead (`storage::reserve`), so the
    /// saves of the next print (a power-cut record at every layer pause) find erased room.
    pub fn service_store<F: NorFlash>(&mut self, store: &mut SettingsStore<F>) {
        if !self.store_request_pending() {
            self.erase_ahead_when_idle(store);
            return;
        }
        if !self.still() {
            return;
        }
        self.settings.reserve_checked = false;
        match self.settings.request.take() {
            Some(StoreRequest::Save(s)) => match store.save(&s) {
                Ok(how) => self.say(format_args!(
                    "Settings Stored ({} bytes, format {}{})",
                    crate::storage::RECORD_LEN,
                    crate::storage::FORMAT_VERSION,
                    Reclaim(how)
                )),
                Err(e) => self.say(format_args!("settings not saved: {e}")),
            },
            Some(StoreRequest::Load) => self.load_and_apply(store, true),
            None => {}
        }
        match self.job.request.take() {
            Some(super::job::JobRequest::Save(j)) => {
                let saved = store.save_job(&j);
                self.job_saved(&j, saved);
            }
            Some(super::job::JobRequest::Clear) => {
                if let Err(e) = store.clear_job() {
                    self.say(format_args!(
                        "power-cut resume: the kept job was not cleared: {e}"
                    ));
                }
            }
            None => {}
        }
    }

    fn erase_ahead_when_idle<F: NorFlash>(&mut self, store: &mut SettingsStore<F>) {
        if self.state() != super::State::Idle {
            self.settings.idle_since_us = None;
            return;
        }
        let since = *self.settings.idle_since_us.get_or_insert(self.now_us);
        if self.settings.reserve_checked || self.now_us.saturating_sub(since) < ERASE_AHEAD_IDLE_US
        {
            return;
        }
        self.settings.reserve_checked = true;
        if let Err(e) = store.erase_ahead() {
            self.say(format_args!("settings flash: erase ahead failed: {e}"));
        }
    }

    /// Nothing steps now: the printer is idle, or paused (the held job waits in the planner)
    /// with no service move running (parked, or about to return and waiting for this store).
    fn still(&self) -> bool {
        self.stepgen.current().is_none()
            && (self.planner.is_empty()
                || matches!(self.pause, Pause::Parked { .. } | Pause::Returning { .. }))
    }

    /// True while an M500/M501 or a paused-job save/clear waits for the driver.
    pub fn store_request_pending(&self) -> bool {
        self.settings.request.is_some() || self.job.request.is_some()
    }

    /// Handle a settings command (the `ok` is sent by the caller).
    pub(super) fn settings_command(&mut self, c: &SettingsCommand) {
        use SettingsCommand as S;
        match c {
            S::StepsPerUnit(a) => self.m92(a),
            S::MaxAccel(a) => self.set_axes("M201", a, &ACCEL, |cfg, i, v| {
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
                self.say(format_args!("refused: M851: this machine has no Z probe"));
            }
            S::DriverCurrent(a) => self.m906(a),
            S::Save => self.settings.request = Some(StoreRequest::Save(self.settings())),
            S::Load => self.settings.request = Some(StoreRequest::Load),
            S::FactoryReset => {
                let f = self.factory_settings();
                match self.apply_settings(&f) {
                    Ok(()) => self.say(format_args!("Hardcoded Default Settings Loaded")),
                    Err(e) => self.say(format_args!("refused: M502: {e}")),
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
        self.say(format_args!(
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
                set(&mut self.cfg, i, *v);
            }
        }
        self.settings.config_epoch = self.settings.config_epoch.wrapping_add(1);
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
            self.say(format_args!("refused: M92: {e}"));
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
                self.say(format_args!(
                    "refused: M205 J{j}: {} out of range ({}..{} {}); nothing changed",
                    b.name, b.min, b.max, b.unit
                ));
                return;
            }
            self.cfg.junction_deviation_mm = j;
        }
        if unused {
            self.say(format_args!(
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
                self.cfg.driver_current_ma[i] = libm::roundf(*v) as u16;
            }
        }
    }

    /// The current values of one settings M-code, as a command.
    fn current(&self, code: &str) -> gcode::Command {
        let c = &self.cfg;
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
        self.link.respond(Response::Echo(&t));
    }

    /// M503: every setting as G-code a user can paste back (strip the `echo:`).
    fn m503(&mut self) {
        self.say(format_args!(
            "; Settings (M500 saves, M501 loads, M502 factory):"
        ));
        // M350 before M92: sent back, M350 scales steps/mm, then M92 sets them exactly.
        let c = &self.cfg;
        self.report_line(&gcode::Command::Driver(gcode::DriverCommand::Microsteps {
            all: None,
            axes: AxisWords(core::array::from_fn(|i| {
                Some(f32::from(c.axes[i].microsteps))
            })),
        }));
        for on in [true, false] {
            let axes = gcode::AxisFlags(core::array::from_fn(|i| {
                self.cfg.driver_stealthchop[i] == on
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
        let c = &self.cfg;
        let accel = gcode::Command::SetAcceleration {
            print: Some(c.accel_print_mm_s2),
            retract: Some(c.accel_retract_mm_s2),
            travel: Some(c.accel_travel_mm_s2),
            s: None,
        };
        self.report_line(&accel);
        for code in ["M205", "M206"] {
            let c = self.current(code);
            self.report_line(&c);
        }
        for (id, heater) in [
            (HeaterId::Hotend, Heater::Hotend),
            (HeaterId::Bed, Heater::Bed),
        ] {
            if let Some(g) = self.thermal.pid(id) {
                self.report_line(&gcode::Command::SetPid {
                    heater,
                    p: Some(g.kp),
                    i: Some(g.ki),
                    d: Some(g.kd),
                });
            }
        }
        let c = self.current("M906");
        self.report_line(&c);
        let timeout_s = self.thermal.idle_config().map_or(0, |i| i.timeout_s);
        self.report_line(&gcode::Command::PauseParams(PauseParams::from_config(
            &self.cfg.pause,
            Some(timeout_s as f32),
        )));
    }
}
