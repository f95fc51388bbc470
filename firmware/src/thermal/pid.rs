//! PID heater control in Marlin's units, so M301/M304 values from Marlin carry over unchanged.
//!
//! The output is in PWM counts 0..=255 (Marlin's `PID_MAX`), `kp` in counts per °C, `ki` in
//! counts per °C·s and `kd` in counts·s per °C (the per-second values M301/M303 print).
//! Like Marlin: outside a ±10 °C band around the target the heater is fully on or off
//! (`PID_FUNCTIONAL_RANGE`) and the integral is cleared; inside it, P on the error, I with
//! anti-windup (conditional integration plus a clamp so the I term alone never exceeds full
//! power), and D on the measurement (no kick when the target changes), low-pass filtered.

/// Full-scale PID output, PWM counts (Marlin's `PID_MAX`).
pub const PID_MAX: f32 = 255.0;
/// Outside this distance from the target the heater is simply full on or off, °C.
pub const FUNCTIONAL_RANGE_C: f32 = 10.0;
/// Time constant of the derivative low-pass filter, seconds.
pub const D_FILTER_TAU_S: f32 = 1.0;

/// PID gains as M301/M304 set them and M303 reports them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PidGains {
    /// Proportional gain, PWM counts per °C.
    pub kp: f32,
    /// Integral gain, PWM counts per (°C·s).
    pub ki: f32,
    /// Derivative gain, PWM counts per (°C/s).
    pub kd: f32,
}

impl PidGains {
    /// True when every gain is within [`crate::ranges::PID_GAIN`] (finite, not negative, not
    /// absurd): the range M500 saves.
    pub fn is_valid(&self) -> bool {
        [self.kp, self.ki, self.kd]
            .iter()
            .all(|g| crate::ranges::PID_GAIN.contains(*g))
    }
}

/// One PID loop's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pid {
    /// Current gains.
    pub gains: PidGains,
    integral: f32,
    d_term: f32,
    last: Option<(f32, u64)>,
}

impl Pid {
    /// A loop at rest with `gains`.
    pub const fn new(gains: PidGains) -> Self {
        Pid {
            gains,
            integral: 0.0,
            d_term: 0.0,
            last: None,
        }
    }

    /// Forgets the integral and derivative history (target off, fault, gains changed).
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.d_term = 0.0;
        self.last = None;
    }

    /// The accumulated integral, °C·s (for tests and reports).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// One control step: output in PWM counts 0..=[`PID_MAX`] for `measured_c` at `now_us`.
    pub fn update(&mut self, target_c: f32, measured_c: f32, now_us: u64) -> f32 {
        let (dt_s, prev_c) = match self.last {
            Some((prev_c, t)) => (now_us.saturating_sub(t) as f32 * 1e-6, Some(prev_c)),
            None => (0.0, None),
        };
        self.last = Some((measured_c, now_us));
        if target_c <= 0.0 {
            self.integral = 0.0;
            self.d_term = 0.0;
            return 0.0;
        }
        let error = target_c - measured_c;
        if error > FUNCTIONAL_RANGE_C {
            self.integral = 0.0;
            self.d_term = 0.0;
            return PID_MAX;
        }
        if error < -FUNCTIONAL_RANGE_C {
            self.integral = 0.0;
            self.d_term = 0.0;
            return 0.0;
        }
        // Derivative on the measurement, filtered.
        if let (Some(prev_c), true) = (prev_c, dt_s > 0.0) {
            let raw = -self.gains.kd * (measured_c - prev_c) / dt_s;
            let alpha = dt_s / (dt_s + D_FILTER_TAU_S);
            self.d_term += alpha * (raw - self.d_term);
        }
        let p_term = self.gains.kp * error;
        let candidate = self.integral + error * dt_s;
        let i_max = if self.gains.ki > 0.0 {
            PID_MAX / self.gains.ki
        } else {
            0.0
        };
        let candidate = candidate.clamp(0.0, i_max);
        let out = p_term + self.gains.ki * candidate + self.d_term;
        // Conditional integration: do not wind further into a saturated output.
        let saturated_high = out > PID_MAX && error > 0.0;
        let saturated_low = out < 0.0 && error < 0.0;
        if !(saturated_high || saturated_low) {
            self.integral = candidate;
        }
        let out = p_term + self.gains.ki * self.integral + self.d_term;
        if out.is_nan() {
            return 0.0;
        }
        out.clamp(0.0, PID_MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: PidGains = PidGains {
        kp: 21.73,
        ki: 1.54,
        kd: 76.55,
    };

    #[test]
    fn bang_outside_functional_range() {
        let mut pid = Pid::new(G);
        assert_eq!(pid.update(200.0, 20.0, 0), PID_MAX);
        assert_eq!(pid.update(200.0, 230.0, 100_000), 0.0);
        assert_eq!(pid.update(0.0, 20.0, 200_000), 0.0);
    }

    #[test]
    fn integral_is_bounded_while_saturated() {
        let mut pid = Pid::new(G);
        // 9 °C below target for ten minutes: the output saturates, the integral must not grow
        // without bound.
        for i in 0..6000u64 {
            let out = pid.update(200.0, 191.0, i * 100_000);
            assert!((0.0..=PID_MAX).contains(&out));
        }
        assert!(pid.gains.ki * pid.integral() <= PID_MAX + 1e-3);
        // Once at target the output drops back from full scale within a few samples.
        let mut out = PID_MAX;
        for i in 6000..6020u64 {
            out = pid.update(200.0, 200.5, i * 100_000);
        }
        assert!(out < PID_MAX);
    }

    #[test]
    fn validity() {
        assert!(G.is_valid());
        assert!(!PidGains { kp: f32::NAN, ..G }.is_valid());
        assert!(!PidGains { ki: -1.0, ..G }.is_valid());
    }
}
