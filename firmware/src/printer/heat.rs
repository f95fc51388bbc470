//! The heaters and the part-cooling fan, as the executive owns them: the thermal control
//! ([`Thermal`]: PID, protection, the pause's nozzle timeout), the fan's PWM, and the
//! cold/over-long extrusion guard that reads the hotend's temperature (`guards.rs` has the
//! rules). The temperature and fan commands are carried out here; a thermal fault is returned
//! to the executive, which halts.

use super::guards::{ExtrusionGuard, Refusal};
use super::host::Host;
use crate::gcode::Heater;
use crate::link::{Response, TempReport};
use crate::thermal::{AutotuneError, AutotuneStatus, Fault, HeaterId, Thermal, ThermalConfig};
use core::fmt::Write;
use heapless::String;

/// The heater of a temperature or PID command.
pub(super) fn heater_id(h: Heater) -> HeaterId {
    match h {
        Heater::Hotend => HeaterId::Hotend,
        Heater::Bed => HeaterId::Bed,
    }
}

/// Heaters, fan and extrusion guard (see the module documentation).
#[derive(Clone, Debug)]
pub(super) struct Heat {
    thermal: Thermal,
    /// Part-cooling fan PWM 0..=255 (M106/M107).
    fan_pwm: u8,
    /// Cold/long-extrusion protection (M302).
    guard: ExtrusionGuard,
}

impl Heat {
    pub(super) fn new() -> Self {
        Self {
            thermal: Thermal::new(&ThermalConfig::ENDER3),
            fan_pwm: 0,
            guard: ExtrusionGuard::MARLIN,
        }
    }

    /// The thermal control, read-only.
    pub(super) fn thermal(&self) -> &Thermal {
        &self.thermal
    }

    /// The thermal control (the board's configuration, the pause's timers).
    pub(super) fn thermal_mut(&mut self) -> &mut Thermal {
        &mut self.thermal
    }

    /// The extrusion guard.
    pub(super) fn guard(&self) -> &ExtrusionGuard {
        &self.guard
    }

    /// The extrusion guard, to change (M302, drivers without heaters).
    pub(super) fn guard_mut(&mut self) -> &mut ExtrusionGuard {
        &mut self.guard
    }

    /// The fan's PWM.
    pub(super) fn fan_pwm(&self) -> u8 {
        self.fan_pwm
    }

    /// A heater sample (°C, NaN = unreadable) in, its duty 0..=1 out. The end of an M303 tune
    /// and the pause's nozzle timeout are said here; a new thermal fault is returned (the
    /// executive halts).
    pub(super) fn sample(
        &mut self,
        id: HeaterId,
        measured_c: f32,
        now_us: u64,
        host: &mut Host,
    ) -> (f32, Option<Fault>) {
        let had_fault = self.thermal.fault().is_some();
        let tune = self.thermal.autotune_status(id);
        let was_lowered = self.thermal.idle_lowered();
        let duty = self.thermal.update(id, measured_c, now_us);
        self.report_autotune(id, tune, host);
        if !was_lowered && self.thermal.idle_lowered() {
            let s = self.thermal.idle_config().map_or(0, |i| i.timeout_s);
            host.notice(format_args!(
                "pause: nozzle heater off after {s} s parked (M760 T); the resume heats it \
                 again and waits before the head moves"
            ));
        }
        let fault = if had_fault {
            None
        } else {
            self.thermal.fault()
        };
        (duty, fault)
    }

    /// After each sample, with the tune's status before it: a tune that has just ended is
    /// reported once, as Marlin's `PID_autotune()` prints it (Marlin
    /// `Marlin/src/module/temperature.cpp` with the strings of `Marlin/src/core/language.h`:
    /// `STR_PID_AUTOTUNE_FINISHED`, the `#define DEFAULT_Kp …` lines, `STR_PID_TEMP_TOO_HIGH`,
    /// `STR_PID_TIMEOUT`; plain lines, no `echo:`).
    fn report_autotune(&mut self, id: HeaterId, before: Option<AutotuneStatus>, host: &mut Host) {
        if !matches!(before, Some(AutotuneStatus::Running { .. })) {
            return;
        }
        match self.thermal.autotune_status(id) {
            Some(AutotuneStatus::Done(g)) => {
                host.notify(Response::Plain(
                    "PID Autotune finished! Put the last Kp, Ki and Kd constants from below into Configuration.h",
                ));
                let prefix = if id == HeaterId::Bed { "bed" } else { "" };
                for (name, v) in [("Kp", g.kp), ("Ki", g.ki), ("Kd", g.kd)] {
                    let mut t: String<48> = String::new();
                    let _ = write!(t, "#define DEFAULT_{prefix}{name} {v:.2}");
                    host.notify(Response::Plain(&t));
                }
            }
            Some(AutotuneStatus::Failed(e)) => {
                host.notify(Response::Plain(match e {
                    AutotuneError::TooHot => "PID Autotune failed! Temperature too high",
                    AutotuneError::Timeout => "PID Autotune failed! timeout",
                    AutotuneError::Fault | AutotuneError::Cancelled => "PID Autotune failed!",
                }));
            }
            _ => {}
        }
    }

    /// The temperatures as M105 and the auto-report print them.
    pub(super) fn report(&self) -> TempReport {
        let t = &self.thermal;
        TempReport {
            hotend_c: t.temperature_c(HeaterId::Hotend),
            hotend_target_c: t.target_c(HeaterId::Hotend),
            bed_c: Some((t.temperature_c(HeaterId::Bed), t.target_c(HeaterId::Bed))),
            hotend_duty: t.duty(HeaterId::Hotend),
            bed_duty: t.duty(HeaterId::Bed),
        }
    }

    /// Both heaters' targets are off.
    pub(super) fn heaters_off(&self) -> bool {
        self.thermal.target_c(HeaterId::Hotend) <= 0.0
            && self.thermal.target_c(HeaterId::Bed) <= 0.0
    }

    /// The hotend's temperature, NaN before its first sample.
    fn hotend_c(&self) -> f32 {
        if self.thermal.has_sample(HeaterId::Hotend) {
            self.thermal.temperature_c(HeaterId::Hotend)
        } else {
            f32::NAN
        }
    }

    /// May one move feed `de_mm` of filament at all ([`ExtrusionGuard::check_length`])?
    /// Judged when the line comes: it does not depend on the state the move runs in.
    pub(super) fn check_length(&self, de_mm: f32) -> Result<(), Refusal> {
        self.guard.check_length(de_mm)
    }

    /// May a move feed `de_mm` of filament now ([`ExtrusionGuard::check_cold`])? Judged when
    /// the move enters the planner (Marlin: `Planner::_populate_block`), in the state it runs
    /// in.
    pub(super) fn check_cold(&self, de_mm: f32) -> Result<(), Refusal> {
        let target = self.thermal.target_c(HeaterId::Hotend);
        self.guard.check_cold(de_mm, self.hotend_c(), target)
    }

    /// A move of E waits before the planner while the hotend heats towards the minimum (taken
    /// while heating, see [`ExtrusionGuard::check`]).
    pub(super) fn waits_for_heat(&self) -> bool {
        self.guard.too_cold(self.hotend_c())
            && !self.guard.too_cold(self.thermal.target_c(HeaterId::Hotend))
            && self.thermal.fault().is_none()
    }

    /// Whether the heater has reached its target (a heater wait ends).
    pub(super) fn reached(&self, id: HeaterId) -> bool {
        self.thermal.reached(id)
    }

    /// M104/M140 (and the target of M109/M190): set a target (the caller says a refusal).
    pub(super) fn set_target(
        &mut self,
        id: HeaterId,
        c: f32,
    ) -> Result<(), crate::thermal::ThermalError> {
        self.thermal.set_target(id, c)
    }

    /// M106 S<speed> (no S: full) and M107.
    pub(super) fn set_fan(&mut self, speed: Option<f32>) {
        let v = speed.unwrap_or(255.0);
        self.fan_pwm = if v.is_finite() {
            v.clamp(0.0, 255.0) as u8
        } else {
            0
        };
    }

    /// The fan's PWM as a power-cut record kept it (M1000).
    pub(super) fn restore_fan(&mut self, pwm: u8) {
        self.fan_pwm = pwm;
    }

    /// M301/M304: report the gains, or change the ones given.
    pub(super) fn pid_command(
        &mut self,
        heater: Heater,
        p: Option<f32>,
        i: Option<f32>,
        d: Option<f32>,
        host: &mut Host,
    ) {
        use crate::thermal::pid::PidGains;
        let id = heater_id(heater);
        match (self.thermal.pid(id), p, i, d) {
            (Some(g), None, None, None) => {
                host.say(format_args!("p:{:.2} i:{:.2} d:{:.2}", g.kp, g.ki, g.kd));
            }
            (cur, _, _, _) => {
                let base = cur.unwrap_or(PidGains {
                    kp: 0.0,
                    ki: 0.0,
                    kd: 0.0,
                });
                let g = PidGains {
                    kp: p.unwrap_or(base.kp),
                    ki: i.unwrap_or(base.ki),
                    kd: d.unwrap_or(base.kd),
                };
                if let Err(e) = self.thermal.set_pid(id, g) {
                    host.warn(format_args!("{e}"));
                }
            }
        }
    }

    /// M303: start a tune.
    pub(super) fn autotune(
        &mut self,
        heater_index: Option<i32>,
        target_c: Option<f32>,
        cycles: Option<u32>,
        use_result: bool,
        now_us: u64,
        host: &mut Host,
    ) {
        // Marlin's M303: E-1 the bed, E0 the hotend, else "Bad heater id".
        let id = match heater_index {
            Some(-1) => HeaterId::Bed,
            None | Some(0) => HeaterId::Hotend,
            Some(e) => {
                host.warn(format_args!(
                    "M303 E{e}: no such heater (E0 the hotend, E-1 the bed)"
                ));
                return;
            }
        };
        let t = target_c.unwrap_or(if id == HeaterId::Bed { 70.0 } else { 200.0 });
        let c = cycles.unwrap_or(5).min(255) as u8;
        if let Err(e) = self.thermal.start_autotune(id, t, c, use_result, now_us) {
            host.warn(format_args!("M303 S{t}: {e}"));
        }
    }

    /// M302: set, or (without parameters) report, the cold-extrusion protection.
    pub(super) fn m302(&mut self, min_temp_c: Option<f32>, allow: Option<bool>, host: &mut Host) {
        if let Some(t) = min_temp_c {
            if !(0.0..=400.0).contains(&t) {
                host.warn(format_args!("M302 S{t:.0} outside 0..400 C"));
                return;
            }
            self.guard.min_temp_c = t;
        }
        if let Some(a) = allow {
            self.guard.allow_cold = a;
        }
        if min_temp_c.is_none() && allow.is_none() {
            // Marlin: "Cold extrudes are enabled|disabled (min temp 170C)".
            let g = self.guard;
            host.say(format_args!(
                "Cold extrudes are {} (min temp {:.0}C)",
                if g.allow_cold { "enabled" } else { "disabled" },
                g.min_temp_c
            ));
        }
    }
}
