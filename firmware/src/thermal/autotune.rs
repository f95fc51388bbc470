//! M303 PID autotune: the relay (Åström–Hägglund) method as Marlin runs it, as a state machine
//! fed with samples.
//!
//! The heater switches between `bias + d` and `bias − d` each time the temperature crosses the
//! target (with at least 5 s between switches so sensor noise cannot chatter the relay). After
//! each full cycle the bias is re-centred so the heating and cooling half-periods match; from
//! the third cycle on, the oscillation's amplitude `a` and period `Tu` give the ultimate gain
//! `Ku = 4d / (π a)` and the Ziegler–Nichols gains `Kp = 0.6 Ku`, `Ki = 2 Kp / Tu`,
//! `Kd = Kp Tu / 8`. The result is the mean over those cycles (Marlin keeps the last one).
//! The tune fails if the temperature overshoots the target by more than 30 °C or a half-cycle
//! takes longer than 20 minutes.

use super::pid::{PidGains, PID_MAX};

/// Highest overshoot above the target allowed during a tune, °C (Marlin's
/// `MAX_OVERSHOOT_PID_AUTOTUNE`).
pub const MAX_OVERSHOOT_C: f32 = 30.0;
/// Longest half-cycle before the tune gives up, µs (Marlin: 20 minutes).
pub const MAX_HALF_CYCLE_US: u64 = 20 * 60 * 1_000_000;
/// Shortest time between relay switches, µs.
pub const MIN_SWITCH_US: u64 = 5_000_000;
/// Most cycles M303 may ask for.
pub const MAX_CYCLES: u8 = 20;

/// Why a tune stopped without a result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AutotuneError {
    /// The temperature went more than [`MAX_OVERSHOOT_C`] above the target.
    TooHot,
    /// A half-cycle took longer than 20 minutes (heater too weak for the target).
    Timeout,
    /// A thermal fault stopped the heaters.
    Fault,
    /// Cancelled (new target, M108, emergency stop).
    Cancelled,
}

/// Where a tune is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AutotuneStatus {
    /// Oscillating; `cycle` full cycles done so far.
    Running {
        /// Completed cycles.
        cycle: u8,
    },
    /// Finished: the tuned gains.
    Done(PidGains),
    /// Stopped without a result.
    Failed(AutotuneError),
}

/// A relay autotune in progress (or finished).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Autotune {
    target_c: f32,
    cycles_wanted: u8,
    max_out: f32,
    bias: f32,
    d: f32,
    heating: bool,
    t_on_us: u64,
    t_off_us: u64,
    t_high_us: u64,
    max_c: f32,
    min_c: f32,
    cycle: u8,
    sum: PidGains,
    summed: u8,
    status: AutotuneStatus,
    output: f32,
}

impl Autotune {
    /// Starts a tune at `target_c` for `cycles` cycles (clamped to 3..=[`MAX_CYCLES`]) with
    /// `max_out` the heater's power limit in PWM counts (255 = full power).
    pub fn new(target_c: f32, cycles: u8, max_out: f32, now_us: u64) -> Self {
        let max_out = max_out.clamp(1.0, PID_MAX);
        Autotune {
            target_c,
            cycles_wanted: cycles.clamp(3, MAX_CYCLES),
            max_out,
            bias: max_out / 2.0,
            d: max_out / 2.0,
            heating: true,
            t_on_us: now_us,
            t_off_us: now_us,
            t_high_us: 0,
            max_c: target_c,
            min_c: target_c,
            cycle: 0,
            sum: PidGains {
                kp: 0.0,
                ki: 0.0,
                kd: 0.0,
            },
            summed: 0,
            status: AutotuneStatus::Running { cycle: 0 },
            output: max_out,
        }
    }

    /// The tune's target, °C.
    pub fn target_c(&self) -> f32 {
        self.target_c
    }

    /// Where the tune is.
    pub fn status(&self) -> AutotuneStatus {
        self.status
    }

    /// Stops the tune with `why` (no effect once finished).
    pub fn abort(&mut self, why: AutotuneError) {
        if matches!(self.status, AutotuneStatus::Running { .. }) {
            self.status = AutotuneStatus::Failed(why);
            self.output = 0.0;
        }
    }

    /// Feeds one sample; returns the heater output in PWM counts (0 once finished).
    pub fn update(&mut self, measured_c: f32, now_us: u64) -> f32 {
        if !matches!(self.status, AutotuneStatus::Running { .. }) {
            return 0.0;
        }
        if measured_c > self.target_c + MAX_OVERSHOOT_C {
            self.abort(AutotuneError::TooHot);
            return 0.0;
        }
        self.max_c = self.max_c.max(measured_c);
        self.min_c = self.min_c.min(measured_c);
        let last_switch = self.t_on_us.max(self.t_off_us);
        if now_us.saturating_sub(last_switch) > MAX_HALF_CYCLE_US {
            self.abort(AutotuneError::Timeout);
            return 0.0;
        }
        if self.heating {
            if measured_c > self.target_c && now_us.saturating_sub(self.t_on_us) > MIN_SWITCH_US {
                self.heating = false;
                self.output = self.bias - self.d;
                self.t_off_us = now_us;
                self.t_high_us = now_us.saturating_sub(self.t_on_us);
                self.max_c = self.target_c;
            }
        } else if measured_c < self.target_c && now_us.saturating_sub(self.t_off_us) > MIN_SWITCH_US
        {
            self.heating = true;
            self.t_on_us = now_us;
            let t_low_us = now_us.saturating_sub(self.t_off_us);
            if self.cycle > 0 {
                self.finish_cycle(t_low_us);
            }
            self.output = self.bias + self.d;
            self.cycle = self.cycle.saturating_add(1);
            self.min_c = self.target_c;
            if self.cycle > self.cycles_wanted && self.summed > 0 {
                let n = self.summed as f32;
                self.status = AutotuneStatus::Done(PidGains {
                    kp: self.sum.kp / n,
                    ki: self.sum.ki / n,
                    kd: self.sum.kd / n,
                });
                self.output = 0.0;
                return 0.0;
            }
            self.status = AutotuneStatus::Running { cycle: self.cycle };
        }
        self.output.clamp(0.0, self.max_out)
    }

    fn finish_cycle(&mut self, t_low_us: u64) {
        let (t_high, t_low) = (self.t_high_us as f32, t_low_us as f32);
        if t_high + t_low <= 0.0 {
            return;
        }
        self.bias += self.d * (t_high - t_low) / (t_low + t_high);
        self.bias = self.bias.clamp(20.0_f32.min(self.max_out / 2.0), {
            (self.max_out - 20.0).max(self.max_out / 2.0)
        });
        self.d = if self.bias > self.max_out / 2.0 {
            self.max_out - 1.0 - self.bias
        } else {
            self.bias
        };
        let amplitude = (self.max_c - self.min_c) / 2.0;
        if self.cycle > 2 && amplitude > 0.0 {
            let ku = 4.0 * self.d / (core::f32::consts::PI * amplitude);
            let tu_s = (t_high + t_low) * 1e-6;
            let kp = 0.6 * ku;
            self.sum.kp += kp;
            self.sum.ki += 2.0 * kp / tu_s;
            self.sum.kd += kp * tu_s / 8.0;
            self.summed = self.summed.saturating_add(1);
        }
    }
}
