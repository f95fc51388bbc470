//! Heater control and thermal protection: pure state machines fed with temperature samples and
//! time, returning heater duty. No I/O: the board feeds ADC readings and drives PWM, the
//! simulator feeds its heater model, the tests feed whatever they like.
//!
//! # Using it
//! ```
//! use firmware::thermal::{HeaterId, Thermal, ThermalConfig};
//! let mut thermal = Thermal::new(&ThermalConfig::ENDER3);
//! thermal.set_target(HeaterId::Hotend, 200.0).unwrap();           // M104 S200
//! // Every sample period (the board: 10 Hz), per heater:
//! let duty = thermal.update(HeaterId::Hotend, 25.0, 0);          // or update_adc(id, raw, t)
//! assert_eq!(duty, 1.0);                                          // far below: full power
//! assert!(!thermal.reached(HeaterId::Hotend));                    // M109 keeps waiting
//! assert!(thermal.fault().is_none());                             // else: all heaters off
//! ```
//! * Duty is 0.0..=1.0 of the heater's PWM period (already limited to the heater's maximum
//!   power). After a fault every duty is 0 until the board is reset.
//! * [`Thermal::fault`] is latched: runaway, heating failed, min/max temperature, sensor open or
//!   short. The executive reports it with [`Fault`]'s `Display` (Marlin's wording, after an
//!   `Error:` prefix), stops motion, and keeps the state until reset.
//! * M301/M304: [`Thermal::set_pid`]; M303: [`Thermal::start_autotune`] then
//!   [`Thermal::autotune_status`]; M105: [`Thermal::write_report`]; the automatic hot-end fan:
//!   [`Thermal::hotend_fan_on`]; pause idle cooling: [`Thermal::pause_idle_start`] /
//!   [`Thermal::pause_idle_end`].
//!
//! Submodules: [`thermistor`] (ADC → °C), [`pid`], [`autotune`] (M303), [`protection`]
//! (runaway and heating watchdogs), `config` (heaters and their limits), `fault` (latched
//! faults and refusals), `heater` (one heater's control loop).

pub mod autotune;
mod config;
mod fault;
mod heater;
pub mod pid;
pub mod protection;
pub mod thermistor;

use core::fmt;

pub use config::{
    Control, HeaterConfig, HeaterId, IdleConfig, ThermalConfig, HEATERS, TARGET_MARGIN_C,
};
pub use fault::{Fault, FaultKind, ThermalError};
use heater::Heater;

pub use autotune::{Autotune, AutotuneError, AutotuneStatus};
pub use pid::{Pid, PidGains, PID_MAX};
pub use protection::{Protection, ProtectionConfig, WatchdogTrip};
pub use thermistor::{Curve, SensorFault, Thermistor, ThermistorTable};

#[derive(Clone, Copy, Debug, PartialEq)]
struct IdleState {
    since_us: Option<u64>,
    /// The timeout has lowered the nozzle's target.
    lowered: bool,
    /// Both heaters' targets when the pause parked (the job's): what the resume heats to,
    /// whatever was set while parked.
    job_c: Option<[f32; HEATERS]>,
}

/// Both heaters, their protection, the automatic hot-end fan and the pause idle timeout.
#[derive(Clone, Debug, PartialEq)]
pub struct Thermal {
    heaters: [Heater; HEATERS],
    fault: Option<Fault>,
    fault_samples: u8,
    fan_c: f32,
    fan_on: bool,
    idle_cfg: Option<IdleConfig>,
    idle: IdleState,
}

impl Thermal {
    /// Heaters off, no fault, thermistor tables built from `cfg`.
    pub fn new(cfg: &ThermalConfig) -> Self {
        Thermal {
            heaters: [Heater::new(&cfg.hotend), Heater::new(&cfg.bed)],
            fault: None,
            fault_samples: cfg.range_fault_samples,
            fan_c: cfg.hotend_fan_c,
            fan_on: false,
            idle_cfg: cfg.idle,
            idle: IdleState {
                since_us: None,
                lowered: false,
                job_c: None,
            },
        }
    }

    fn heater(&self, id: HeaterId) -> &Heater {
        &self.heaters[id.index()]
    }

    fn heater_mut(&mut self, id: HeaterId) -> &mut Heater {
        &mut self.heaters[id.index()]
    }

    /// Sets a target (M104/M109/M140/M190); 0 turns the heater off. Refused after a fault,
    /// above `max_c − 15`, or for NaN/negative values; a running autotune on that heater is
    /// cancelled.
    pub fn set_target(&mut self, id: HeaterId, target_c: f32) -> Result<(), ThermalError> {
        if let Some(fault) = self.fault {
            return Err(ThermalError::Faulted(fault));
        }
        if !target_c.is_finite() || target_c < 0.0 {
            return Err(ThermalError::Invalid);
        }
        let max_c = self.heater(id).max_target_c();
        if target_c > max_c {
            return Err(ThermalError::TooHot { max_c });
        }
        let heater = self.heater_mut(id);
        if let Some(tune) = heater.autotune.as_mut() {
            tune.abort(AutotuneError::Cancelled);
        }
        heater.set_target(target_c);
        Ok(())
    }

    /// Feeds one temperature sample in °C and returns the heater's duty 0..=1. Runs the
    /// protection; on a fault every heater goes off and stays off. Sensor faults are passed as
    /// markers (what [`ThermistorTable::celsius_marked`] returns): NaN or −∞ = open sensor,
    /// +∞ = shorted sensor.
    pub fn update(&mut self, id: HeaterId, measured_c: f32, now_us: u64) -> f32 {
        let sample = if measured_c == f32::INFINITY {
            Err(SensorFault::Short)
        } else if measured_c.is_nan() || measured_c == f32::NEG_INFINITY {
            Err(SensorFault::Open)
        } else {
            Ok(measured_c)
        };
        self.feed(id, sample, now_us)
    }

    /// Feeds one raw 12-bit ADC reading of the heater's thermistor input (converted with its
    /// table; open and short sensors detected) and returns the duty 0..=1.
    pub fn update_adc(&mut self, id: HeaterId, raw: u16, now_us: u64) -> f32 {
        let sample = self.heater(id).table.celsius(raw);
        self.feed(id, sample, now_us)
    }

    fn feed(&mut self, id: HeaterId, sample: Result<f32, SensorFault>, now_us: u64) -> f32 {
        if self.fault.is_some() {
            let h = self.heater_mut(id);
            h.last_us = now_us;
            if let Ok(c) = sample {
                if c.is_finite() {
                    h.measured_c = c;
                    h.have_sample = true;
                }
            }
            h.duty = 0.0;
            self.update_fan();
            return 0.0;
        }
        if id == HeaterId::Hotend {
            self.idle_tick(now_us);
        }
        let samples = self.fault_samples;
        let result = self.heater_mut(id).sample(sample, now_us, samples);
        let duty = match result {
            Ok(duty) => duty,
            Err(kind) => {
                let measured_c = self.heater(id).measured_c;
                self.latch(Fault {
                    heater: id,
                    kind,
                    at_us: now_us,
                    measured_c,
                });
                0.0
            }
        };
        self.update_fan();
        duty
    }

    fn latch(&mut self, fault: Fault) {
        if self.fault.is_none() {
            self.fault = Some(fault);
        }
        for h in self.heaters.iter_mut() {
            h.off();
        }
    }

    /// Turns every heater off and latches [`FaultKind::Killed`] (M112, a motion fault, the
    /// panic path): nothing heats again until reset.
    pub fn kill(&mut self, now_us: u64) {
        let measured_c = self.heater(HeaterId::Hotend).measured_c;
        self.latch(Fault {
            heater: HeaterId::Hotend,
            kind: FaultKind::Killed,
            at_us: now_us,
            measured_c,
        });
    }

    /// Turns every heater off without a fault (M104 S0 + M140 S0, end of job, cancel).
    pub fn all_off(&mut self) {
        for id in HeaterId::ALL {
            let h = self.heater_mut(id);
            if let Some(tune) = h.autotune.as_mut() {
                tune.abort(AutotuneError::Cancelled);
            }
            h.set_target(0.0);
            h.duty = 0.0;
        }
        self.idle.lowered = false;
        self.idle.job_c = None;
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// Last valid measured temperature, °C (0 before the first sample).
    pub fn temperature_c(&self, id: HeaterId) -> f32 {
        self.heater(id).measured_c
    }

    /// True once a valid sample has been seen for this heater.
    pub fn has_sample(&self, id: HeaterId) -> bool {
        self.heater(id).have_sample
    }

    /// Current target, °C (0 = off).
    pub fn target_c(&self, id: HeaterId) -> f32 {
        self.heater(id).target_c
    }

    /// Last duty returned for this heater, 0..=1.
    pub fn duty(&self, id: HeaterId) -> f32 {
        self.heater(id).duty
    }

    /// True when the heater is off, or has been within its window of the target for its
    /// residency time: what M109/M190 wait for. Never true after a fault (the wait must end
    /// through the fault path instead).
    pub fn reached(&self, id: HeaterId) -> bool {
        self.fault.is_none() && self.heater(id).reached()
    }

    /// The heater's PID gains (M301/M304 without parameters), None for bang-bang control.
    pub fn pid(&self, id: HeaterId) -> Option<PidGains> {
        match self.heater(id).cfg.control {
            Control::Pid(_) => Some(self.heater(id).pid.gains),
            Control::BangBang { .. } => None,
        }
    }

    /// Sets PID gains (M301 P I D for the hot end, M304 for the bed); switches a bang-bang
    /// heater to PID.
    pub fn set_pid(&mut self, id: HeaterId, gains: PidGains) -> Result<(), ThermalError> {
        if !gains.is_valid() {
            return Err(ThermalError::Invalid);
        }
        let h = self.heater_mut(id);
        h.cfg.control = Control::Pid(gains);
        h.pid = Pid::new(gains);
        Ok(())
    }

    /// Starts M303 on `id` at `target_c` for `cycles` cycles. The tune drives the heater until
    /// [`Thermal::autotune_status`] is `Done` or `Failed`; the heater is then off (target 0)
    /// and, when `apply` is true (M303 U1), the result becomes the heater's gains.
    pub fn start_autotune(
        &mut self,
        id: HeaterId,
        target_c: f32,
        cycles: u8,
        apply: bool,
        now_us: u64,
    ) -> Result<(), ThermalError> {
        if let Some(fault) = self.fault {
            return Err(ThermalError::Faulted(fault));
        }
        if !target_c.is_finite() || target_c <= 0.0 {
            return Err(ThermalError::Invalid);
        }
        let max_c = self.heater(id).max_target_c();
        if target_c > max_c {
            return Err(ThermalError::TooHot { max_c });
        }
        if self.heaters.iter().any(|h| h.tuning()) {
            return Err(ThermalError::Busy);
        }
        let h = self.heater_mut(id);
        h.set_target(0.0);
        h.pid.reset();
        let max_out = h.cfg.max_duty * PID_MAX;
        h.autotune = Some(Autotune::new(target_c, cycles, max_out, now_us));
        h.tune_apply = apply;
        Ok(())
    }

    /// The heater's autotune: None if none was started since power-up.
    pub fn autotune_status(&self, id: HeaterId) -> Option<AutotuneStatus> {
        self.heater(id).autotune.map(|t| t.status())
    }

    /// Cancels a running autotune (M108, cancel).
    pub fn cancel_autotune(&mut self) {
        for h in self.heaters.iter_mut() {
            if let Some(tune) = h.autotune.as_mut() {
                tune.abort(AutotuneError::Cancelled);
            }
        }
    }

    /// True while the hot-end fan must run (nozzle at or above the configured threshold, with
    /// 2 °C hysteresis). Stays on after a fault while the nozzle is hot.
    pub fn hotend_fan_on(&self) -> bool {
        self.fan_on
    }

    fn update_fan(&mut self) {
        let c = self.heater(HeaterId::Hotend).measured_c;
        if c >= self.fan_c {
            self.fan_on = true;
        } else if c < self.fan_c - 2.0 {
            self.fan_on = false;
        }
    }

    /// The executive entered a pause (parked): the job's targets are kept for the resume and
    /// the idle timer starts if configured.
    pub fn pause_idle_start(&mut self, now_us: u64) {
        if self.idle.job_c.is_none() {
            self.idle.job_c = Some([
                self.heater(HeaterId::Hotend).target_c,
                self.heater(HeaterId::Bed).target_c,
            ]);
        }
        if self.idle_cfg.is_some() && self.idle.since_us.is_none() {
            self.idle.since_us = Some(now_us);
        }
    }

    /// The pause's nozzle timeout (`M760 T`); `None` turns it off. A nozzle already lowered
    /// stays so until the resume.
    pub fn set_idle(&mut self, cfg: Option<IdleConfig>) {
        self.idle_cfg = cfg;
    }

    /// The pause's nozzle timeout in force.
    pub fn idle_config(&self) -> Option<IdleConfig> {
        self.idle_cfg
    }

    /// The pause ends without a return (a cancel): the timer stops and a lowered nozzle stays
    /// lowered (a cancel never heats).
    pub fn pause_idle_forget(&mut self) {
        self.idle = IdleState {
            since_us: None,
            lowered: false,
            job_c: None,
        };
    }

    /// True while the idle timeout holds the nozzle at its lowered target.
    pub fn idle_lowered(&self) -> bool {
        self.idle.lowered
    }

    /// The pause ends (resume): stops the idle timer and sets both heaters back to the job's
    /// targets of the park (a console `M104` while parked, or the timeout, changed them for
    /// the pause only). Returns the nozzle's target when a target changed: the executive must
    /// then wait for [`Thermal::reached`] on both heaters before the head moves.
    pub fn pause_idle_end(&mut self) -> Option<f32> {
        self.idle.since_us = None;
        self.idle.lowered = false;
        let job = self.idle.job_c.take()?;
        if self.fault.is_some() {
            return None;
        }
        let mut changed = false;
        for (h, c) in self.heaters.iter_mut().zip(job) {
            if h.target_c != c {
                h.set_target(c);
                changed = true;
            }
        }
        changed.then_some(job[HeaterId::Hotend.index()])
    }

    fn idle_tick(&mut self, now_us: u64) {
        let (Some(cfg), Some(since)) = (self.idle_cfg, self.idle.since_us) else {
            return;
        };
        if self.idle.lowered {
            return;
        }
        if now_us.saturating_sub(since) >= cfg.timeout_s as u64 * 1_000_000 {
            let h = self.heater_mut(HeaterId::Hotend);
            if h.target_c > cfg.nozzle_c {
                h.set_target(cfg.nozzle_c);
                self.idle.lowered = true;
            }
        }
    }

    /// Writes the M105 temperature fields, Marlin style:
    /// `T:201.3 /200.0 B:60.1 /60.0 @:127 B@:89` (the caller adds `ok ` in front).
    pub fn write_report(&self, w: &mut impl fmt::Write) -> fmt::Result {
        let t = self.heater(HeaterId::Hotend);
        let b = self.heater(HeaterId::Bed);
        write!(
            w,
            "T:{:.1} /{:.1} B:{:.1} /{:.1} @:{} B@:{}",
            t.measured_c,
            t.target_c,
            b.measured_c,
            b.target_c,
            libm::roundf(t.duty * PID_MAX) as u32,
            libm::roundf(b.duty * PID_MAX) as u32
        )
    }
}
