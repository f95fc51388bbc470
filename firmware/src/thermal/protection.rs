//! Thermal protection as Marlin does it (`THERMAL_PROTECTION_HOTENDS/BED`, `WATCH_TEMP_*`):
//! two independent watchdogs per heater, fed with the target, the measurement and the time.
//!
//! * **Runaway while holding**: once the temperature has first reached the target, it must not
//!   stay more than `runaway_hysteresis_c` below it for longer than `runaway_period_s` (a
//!   thermistor that fell out of the block, a heater cartridge that came loose).
//! * **Heating too slowly**: while heating towards a target more than `watch_increase_c + 4` °C
//!   away, the temperature must rise by `watch_increase_c` within every `watch_period_s`
//!   (a dead heater, a broken wire, a thermistor not in the block).
//!
//! The min/max-temperature and sensor checks live in the heater itself (they do not need
//! history beyond a consecutive-sample count).

/// Limits of one heater's watchdogs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProtectionConfig {
    /// Runaway: how long the temperature may stay below `target − hysteresis`, seconds.
    pub runaway_period_s: u32,
    /// Runaway: allowed droop below the target once reached, °C.
    pub runaway_hysteresis_c: f32,
    /// Heating too slowly: the window in which the temperature must rise, seconds.
    pub watch_period_s: u32,
    /// Heating too slowly: the rise required in each window, °C.
    pub watch_increase_c: f32,
}

impl ProtectionConfig {
    /// Marlin's hot-end defaults: 40 s / 4 °C runaway, 20 s / +2 °C heating watch.
    pub const HOTEND: ProtectionConfig = ProtectionConfig {
        runaway_period_s: 40,
        runaway_hysteresis_c: 4.0,
        watch_period_s: 20,
        watch_increase_c: 2.0,
    };
    /// Marlin's bed defaults: 20 s / 2 °C runaway, 60 s / +2 °C heating watch.
    pub const BED: ProtectionConfig = ProtectionConfig {
        runaway_period_s: 20,
        runaway_hysteresis_c: 2.0,
        watch_period_s: 60,
        watch_increase_c: 2.0,
    };
}

/// What a watchdog found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WatchdogTrip {
    /// Runaway while holding the target.
    Runaway,
    /// Heating too slowly.
    HeatingFailed,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Runaway {
    Inactive,
    FirstHeating,
    Holding { deadline_us: u64 },
}

/// Both watchdogs of one heater.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Protection {
    cfg: ProtectionConfig,
    tracked_target_c: f32,
    runaway: Runaway,
    /// (temperature to beat, deadline) of the running heating watch.
    watch: Option<(f32, u64)>,
    rearm_watch: bool,
}

impl Protection {
    /// Idle watchdogs with limits `cfg`.
    pub const fn new(cfg: ProtectionConfig) -> Self {
        Protection {
            cfg,
            tracked_target_c: 0.0,
            runaway: Runaway::Inactive,
            watch: None,
            rearm_watch: false,
        }
    }

    /// The limits in force.
    pub fn config(&self) -> &ProtectionConfig {
        &self.cfg
    }

    /// True while the heating watch runs (the heater is still far below its target).
    pub fn watching(&self) -> bool {
        self.watch.is_some()
    }

    /// Call when the target changes (M104/M140/...): restarts both watchdogs. The heating
    /// watch is armed with the next sample.
    pub fn target_changed(&mut self, target_c: f32) {
        self.tracked_target_c = target_c;
        self.runaway = if target_c > 0.0 {
            Runaway::FirstHeating
        } else {
            Runaway::Inactive
        };
        self.watch = None;
        self.rearm_watch = target_c > 0.0;
    }

    fn arm_watch(&mut self, measured_c: f32, now_us: u64) {
        let margin = self.cfg.watch_increase_c + 4.0;
        self.watch = if self.tracked_target_c > 0.0 && measured_c < self.tracked_target_c - margin {
            Some((
                measured_c + self.cfg.watch_increase_c,
                now_us + self.cfg.watch_period_s as u64 * 1_000_000,
            ))
        } else {
            None
        };
    }

    /// Checks one sample against both watchdogs.
    pub fn check(&mut self, measured_c: f32, now_us: u64) -> Result<(), WatchdogTrip> {
        let target = self.tracked_target_c;
        if self.rearm_watch {
            self.rearm_watch = false;
            self.arm_watch(measured_c, now_us);
        }
        if let Some((beat_c, deadline)) = self.watch {
            if now_us >= deadline {
                if measured_c < beat_c {
                    self.watch = None;
                    return Err(WatchdogTrip::HeatingFailed);
                }
                // Risen enough: watch the next window while still far below the target.
                self.arm_watch(measured_c, now_us);
            }
        }
        let period_us = self.cfg.runaway_period_s as u64 * 1_000_000;
        match self.runaway {
            Runaway::Inactive => {}
            Runaway::FirstHeating => {
                if measured_c >= target {
                    self.runaway = Runaway::Holding {
                        deadline_us: now_us + period_us,
                    };
                }
            }
            Runaway::Holding { deadline_us } => {
                if measured_c >= target - self.cfg.runaway_hysteresis_c {
                    self.runaway = Runaway::Holding {
                        deadline_us: now_us + period_us,
                    };
                } else if now_us >= deadline_us {
                    self.runaway = Runaway::Inactive;
                    return Err(WatchdogTrip::Runaway);
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000;

    #[test]
    fn runaway_after_period_below_band() {
        let mut p = Protection::new(ProtectionConfig::HOTEND);
        p.target_changed(200.0);
        assert_eq!(p.check(200.5, 0), Ok(()));
        // Droops 10 °C and stays there: trips after 40 s, not before.
        for t in 1..40 {
            assert_eq!(p.check(190.0, t * S), Ok(()), "t={t}");
        }
        assert_eq!(p.check(190.0, 41 * S), Err(WatchdogTrip::Runaway));
    }

    #[test]
    fn small_droop_is_fine() {
        let mut p = Protection::new(ProtectionConfig::HOTEND);
        p.target_changed(200.0);
        assert_eq!(p.check(200.0, 0), Ok(()));
        for t in 1..200 {
            assert_eq!(p.check(196.5, t * S), Ok(()));
        }
    }

    #[test]
    fn heating_too_slowly() {
        let mut p = Protection::new(ProtectionConfig::HOTEND);
        p.target_changed(200.0);
        // Rises 1 °C per 20 s: less than the required 2 °C.
        for t in 0..20 {
            assert_eq!(p.check(25.0 + t as f32 * 0.05, t * S), Ok(()));
        }
        assert_eq!(p.check(26.0, 20 * S), Err(WatchdogTrip::HeatingFailed));
    }

    #[test]
    fn heating_normally_is_fine() {
        let mut p = Protection::new(ProtectionConfig::HOTEND);
        p.target_changed(200.0);
        for t in 0..200 {
            let c = (25.0 + t as f32 * 1.5).min(200.0);
            assert_eq!(p.check(c, t * S), Ok(()));
        }
    }
}
