//! One heater's control loop: range checks with a glitch filter, the protection watchdogs,
//! PID or bang-bang duty, an M303 tune in progress, and the M109/M190 residency timer.

use super::{
    Autotune, AutotuneError, AutotuneStatus, Control, FaultKind, HeaterConfig, Pid, PidGains,
    Protection, SensorFault, ThermistorTable, WatchdogTrip, PID_MAX, TARGET_MARGIN_C,
};

/// One heater: its configuration and the state of its control loop.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Heater {
    pub(super) cfg: HeaterConfig,
    pub(super) table: ThermistorTable,
    pub(super) target_c: f32,
    pub(super) measured_c: f32,
    pub(super) have_sample: bool,
    pub(super) pid: Pid,
    pub(super) bang_on: bool,
    pub(super) protection: Protection,
    pub(super) duty: f32,
    pub(super) last_us: u64,
    pub(super) within_since_us: Option<u64>,
    pub(super) bad_samples: u8,
    pub(super) autotune: Option<Autotune>,
    pub(super) tune_apply: bool,
}

impl Heater {
    pub(super) fn new(cfg: &HeaterConfig) -> Self {
        let gains = match cfg.control {
            Control::Pid(g) => g,
            Control::BangBang { .. } => PidGains {
                kp: 0.0,
                ki: 0.0,
                kd: 0.0,
            },
        };
        Heater {
            cfg: *cfg,
            table: ThermistorTable::new(&cfg.thermistor),
            target_c: 0.0,
            measured_c: 0.0,
            have_sample: false,
            pid: Pid::new(gains),
            bang_on: false,
            protection: Protection::new(cfg.protection),
            duty: 0.0,
            last_us: 0,
            within_since_us: None,
            bad_samples: 0,
            autotune: None,
            tune_apply: false,
        }
    }

    pub(super) fn max_target_c(&self) -> f32 {
        self.cfg.max_c - TARGET_MARGIN_C
    }

    pub(super) fn set_target(&mut self, c: f32) {
        if c != self.target_c {
            self.target_c = c;
            self.protection.target_changed(c);
            self.within_since_us = None;
            if c <= 0.0 {
                self.pid.reset();
            }
        }
    }

    pub(super) fn off(&mut self) {
        self.target_c = 0.0;
        self.duty = 0.0;
        self.pid.reset();
        self.bang_on = false;
        self.protection.target_changed(0.0);
        if let Some(tune) = self.autotune.as_mut() {
            tune.abort(AutotuneError::Fault);
        }
    }

    /// One sample: Ok(duty) or the fault it shows.
    pub(super) fn sample(
        &mut self,
        sample: Result<f32, SensorFault>,
        now_us: u64,
        fault_samples: u8,
    ) -> Result<f32, FaultKind> {
        self.last_us = now_us;
        let heating = self.target_c > 0.0 || self.duty > 0.0 || self.tuning();
        // Range checks with a consecutive-sample filter. MINTEMP and an open sensor only
        // matter while heating (Marlin does the same: a cold or unplugged idle heater is safe).
        let range = match sample {
            Err(SensorFault::Short) => Some(FaultKind::SensorShort),
            Err(SensorFault::Open) if heating => Some(FaultKind::SensorOpen),
            Err(SensorFault::Open) => None,
            Ok(c) if c.is_nan() => heating.then_some(FaultKind::SensorOpen),
            Ok(c) if c > self.cfg.max_c => Some(FaultKind::MaxTemp),
            Ok(c) if c < self.cfg.min_c && heating => Some(FaultKind::MinTemp),
            Ok(_) => None,
        };
        match range {
            Some(kind) => {
                self.bad_samples = self.bad_samples.saturating_add(1);
                if self.bad_samples >= fault_samples.max(1) {
                    return Err(kind);
                }
                // Hold the previous duty through a glitch shorter than the filter.
                return Ok(self.duty);
            }
            None => self.bad_samples = 0,
        }
        let measured = match sample {
            Ok(c) if c.is_finite() => c,
            // Open sensor on an idle heater: nothing to control, nothing to measure.
            _ => {
                self.duty = 0.0;
                return Ok(0.0);
            }
        };
        self.measured_c = measured;
        self.have_sample = true;

        if let Some(tune) = self.autotune.as_mut() {
            if matches!(tune.status(), AutotuneStatus::Running { .. }) {
                let counts = tune.update(measured, now_us);
                if let (AutotuneStatus::Done(gains), true) = (tune.status(), self.tune_apply) {
                    self.cfg.control = Control::Pid(gains);
                    self.pid = Pid::new(gains);
                }
                // During a tune the normal watchdogs are replaced by the tune's own limits
                // (overshoot, half-cycle timeout) plus the range checks above.
                self.duty = (counts / PID_MAX).clamp(0.0, self.cfg.max_duty);
                return Ok(self.duty);
            }
        }

        match self.protection.check(measured, now_us) {
            Ok(()) => {}
            Err(WatchdogTrip::Runaway) => return Err(FaultKind::Runaway),
            Err(WatchdogTrip::HeatingFailed) => return Err(FaultKind::HeatingFailed),
        }

        // Residency for M109/M190.
        if self.target_c > 0.0 && (measured - self.target_c).abs() <= self.cfg.window_c {
            self.within_since_us.get_or_insert(now_us);
        } else {
            self.within_since_us = None;
        }

        let duty = match self.cfg.control {
            Control::Pid(_) => self.pid.update(self.target_c, measured, now_us) / PID_MAX,
            Control::BangBang { hysteresis_c } => {
                if self.target_c <= 0.0 || measured >= self.target_c + hysteresis_c {
                    self.bang_on = false;
                } else if measured <= self.target_c - hysteresis_c {
                    self.bang_on = true;
                }
                if self.bang_on {
                    1.0
                } else {
                    0.0
                }
            }
        };
        self.duty = duty.clamp(0.0, self.cfg.max_duty);
        Ok(self.duty)
    }

    pub(super) fn tuning(&self) -> bool {
        matches!(
            self.autotune.map(|t| t.status()),
            Some(AutotuneStatus::Running { .. })
        )
    }

    pub(super) fn reached(&self) -> bool {
        if self.target_c <= 0.0 {
            return true;
        }
        match self.within_since_us {
            Some(since) => self.last_us.saturating_sub(since) as f32 * 1e-6 >= self.cfg.residency_s,
            None => false,
        }
    }
}
