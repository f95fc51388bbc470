//! Portable drivers at the seam between the firmware and the board: generic over the
//! `embedded-hal` 1.0 pin traits (and pure state machines where no pin is needed), with no
//! embassy or register access, so a simulator or a test can supply its own pins. The board
//! instantiates them with embassy-stm32's `Output`/`Input`.

pub mod adc;
// Marlin's reversed-driver check before the drivers get power.
pub mod backward;
pub mod homing_watch;
// Re-timing of late step events: no burst after a stall.
pub mod retime;
pub mod tmc2209;
// The independent watchdog's timing from the fastest LSI.
pub mod watchdog;

use crate::motion::{PauseMode, Realtime, AXES};
use embedded_hal::digital::OutputPin;

/// STEP/DIR/EN outputs of the four stepper drivers (STEP/DIR mode, EN active low).
pub struct StepperPins<P: OutputPin> {
    step: [P; AXES],
    dir: [P; AXES],
    enable: [P; AXES],
    /// Bit i set: DIR of axis i is high for positive moves; clear: inverted wiring.
    dir_high_positive: u8,
    dir_mask: u8,
    /// Bit i set: the driver of axis i is enabled.
    enabled: u8,
}

impl<P: OutputPin> StepperPins<P> {
    /// Wraps the pins; `dir_high_positive` says per axis (bit i) whether DIR high means
    /// positive. Drivers start disabled, every DIR low.
    pub fn new(step: [P; AXES], dir: [P; AXES], enable: [P; AXES], dir_high_positive: u8) -> Self {
        let mut s = StepperPins {
            step,
            dir,
            enable,
            dir_high_positive,
            dir_mask: 0,
            enabled: 0b1111,
        };
        s.set_enabled(false);
        for d in s.dir.iter_mut() {
            let _ = d.set_low();
        }
        s
    }

    /// Switches every driver on (M17, any move) or off (M18/M84, idle timeout, halt).
    pub fn set_enabled(&mut self, on: bool) {
        self.set_axes_enabled(0b1111, on);
    }

    /// Switches the drivers of the axes in `mask` (bit i = axis i) on or off (M17/M18/M84
    /// with axes); the others keep their state.
    pub fn set_axes_enabled(&mut self, mask: u8, on: bool) {
        for (i, en) in self.enable.iter_mut().enumerate() {
            let bit = 1u8 << i;
            if mask & bit == 0 || (self.enabled & bit != 0) == on {
                continue;
            }
            let _ = if on { en.set_low() } else { en.set_high() };
            if on {
                self.enabled |= bit;
            } else {
                self.enabled &= !bit;
            }
        }
    }

    /// Bit i set: the driver of axis i is enabled.
    pub fn enabled_mask(&self) -> u8 {
        self.enabled
    }

    /// Sets DIR for the axes in `axis_mask` to the directions in `dir_mask` (bit set =
    /// positive). Returns true if any DIR line changed (the caller then waits the driver's
    /// direction setup time before the step edge).
    pub fn set_dirs(&mut self, axis_mask: u8, dir_mask: u8) -> bool {
        let want = (dir_mask ^ !self.dir_high_positive) & axis_mask;
        let have = self.dir_mask & axis_mask;
        if want == have {
            return false;
        }
        for (i, d) in self.dir.iter_mut().enumerate() {
            let bit = 1 << i;
            if axis_mask & bit != 0 && (want ^ have) & bit != 0 {
                let _ = if want & bit != 0 {
                    d.set_high()
                } else {
                    d.set_low()
                };
            }
        }
        self.dir_mask = (self.dir_mask & !axis_mask) | want;
        true
    }

    /// Raises STEP of the axes in `axis_mask` (the step happens on this edge).
    pub fn step_high(&mut self, axis_mask: u8) {
        for (i, s) in self.step.iter_mut().enumerate() {
            if axis_mask & (1 << i) != 0 {
                let _ = s.set_high();
            }
        }
    }

    /// Lowers every STEP line (after the minimum pulse width).
    pub fn step_low(&mut self) {
        for s in self.step.iter_mut() {
            let _ = s.set_low();
        }
    }
}

/// The executive's step frame, which the step interrupt's position and travel limits must
/// follow: steps per mm (M92, M350, M501, M502) re-express the position in new steps
/// (`Printer::travel_frame`); `epoch` counts those changes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TravelFrame {
    /// Changes of the frame so far (0: the boot configuration).
    pub epoch: u32,
    /// The position in the new steps, where the change left it.
    pub pos: [i32; AXES],
    /// The travel limits of X, Y, Z in the new steps.
    pub limits: [(i32, i32); 3],
}

/// What the step interrupt does with one event, portable: software limits per homed axis,
/// DIR changes with their setup time, the STEP pulse, and the position in steps. `delay_ns`
/// is the board's busy wait.
///
/// Axes not homed move as Marlin's default moves them (no `NO_MOTION_BEFORE_HOMING`): from
/// where they stood at power-on or the last G92, the limits not applied (Marlin's soft
/// endstops clamp an axis only once it was homed: `apply_motion_limits`,
/// `if (axis_was_homed(X_AXIS))`). The executive checks every target against the build
/// volume before it answers; these limits are the interrupt's own guard of the homed volume,
/// in the executive's step frame ([`StepExecutor::follow`]).
pub struct StepExecutor<P: OutputPin> {
    /// The driver pins.
    pub pins: StepperPins<P>,
    /// Position in steps as executed.
    pub pos: [i32; AXES],
    /// Software limits in steps for X, Y, Z (enforced on homed axes).
    pub limits: [(i32, i32); 3],
    /// Homed axes (bit i = axis i): their steps stay inside `limits`.
    pub homed: u8,
    /// Steps refused (a homed axis outside its limits) since last taken.
    pub refused: u32,
    /// The [`TravelFrame::epoch`] followed.
    frame_epoch: u32,
}

impl<P: OutputPin> StepExecutor<P> {
    /// Nothing homed, no limits yet.
    pub fn new(pins: StepperPins<P>) -> Self {
        StepExecutor {
            pins,
            pos: [0; AXES],
            limits: [(i32::MIN, i32::MAX); 3],
            homed: 0,
            refused: 0,
            frame_epoch: 0,
        }
    }

    /// The frame followed ([`TravelFrame::epoch`]).
    pub fn frame_epoch(&self) -> u32 {
        self.frame_epoch
    }

    /// Takes the executive's frame: its position and limits. Call only with no event of the
    /// old frame still queued (the board waits for its step queue to run dry: steps per mm
    /// change only while nothing moves).
    pub fn follow(&mut self, frame: &TravelFrame) {
        self.pos = frame.pos;
        self.limits = frame.limits;
        self.frame_epoch = frame.epoch;
    }

    /// Follow the executive's homed axes: `homed` = `Printer::homed_axes`, `fresh` =
    /// `Printer::take_homed` (axes set to their minimum, `home_steps`, since last asked: their
    /// position here is set to it). An axis no longer homed (drivers off) moves unguarded
    /// again until the next G28, as before its first one.
    pub fn set_homed(&mut self, homed: u8, fresh: u8, home_steps: [i32; 3]) {
        for (i, home) in home_steps.into_iter().enumerate() {
            if fresh & (1 << i) != 0 {
                self.pos[i] = home;
            }
        }
        self.homed = homed & 0b111;
    }

    /// Executes one event: the axes in `axis_mask` step in the directions of `dir_mask`
    /// (bit set = positive); a homed X/Y/Z only inside its limits. Returns the axes that
    /// stepped.
    pub fn fire(
        &mut self,
        axis_mask: u8,
        dir_mask: u8,
        dir_setup_ns: u32,
        pulse_ns: u32,
        delay_ns: impl FnMut(u32),
    ) -> u8 {
        let mut mask = axis_mask & 0x0F;
        for axis in 0..3 {
            let bit = 1u8 << axis;
            if mask & bit == 0 {
                continue;
            }
            let next = if dir_mask & bit != 0 {
                self.pos[axis].saturating_add(1)
            } else {
                self.pos[axis].saturating_sub(1)
            };
            let allowed = self.homed & bit == 0
                || (next >= self.limits[axis].0 && next <= self.limits[axis].1);
            if !allowed {
                mask &= !bit;
                self.refused = self.refused.saturating_add(1);
            }
        }
        self.pulse(mask, dir_mask, dir_setup_ns, pulse_ns, delay_ns)
    }

    /// Executes one event of a homing move: like [`StepExecutor::fire`] but allowed on axes
    /// not homed yet and outside the limits (the raise of Z and the approaches start from an
    /// unknown position; the endstop watch ends them).
    pub fn fire_homing(
        &mut self,
        axis_mask: u8,
        dir_mask: u8,
        dir_setup_ns: u32,
        pulse_ns: u32,
        delay_ns: impl FnMut(u32),
    ) -> u8 {
        self.pulse(axis_mask & 0x0F, dir_mask, dir_setup_ns, pulse_ns, delay_ns)
    }

    #[inline(always)]
    fn pulse(
        &mut self,
        mask: u8,
        dir_mask: u8,
        dir_setup_ns: u32,
        pulse_ns: u32,
        mut delay_ns: impl FnMut(u32),
    ) -> u8 {
        if mask == 0 {
            return 0;
        }
        if self.pins.set_dirs(mask, dir_mask) {
            delay_ns(dir_setup_ns);
        }
        self.pins.step_high(mask);
        for (axis, p) in self.pos.iter_mut().enumerate() {
            let bit = 1u8 << axis;
            if mask & bit != 0 {
                *p = if dir_mask & bit != 0 {
                    p.saturating_add(1)
                } else {
                    p.saturating_sub(1)
                };
            }
        }
        delay_ns(pulse_ns);
        self.pins.step_low();
        mask
    }
}

/// Debounce time of the pause button, µs.
pub const BUTTON_DEBOUNCE_US: u64 = 20_000;
/// Holding the button this long means "pause now", µs.
pub const BUTTON_LONG_US: u64 = 1_500_000;

/// The pause button, debounced: a short press (released before 1.5 s) asks for a pause at
/// the next layer boundary, holding it for 1.5 s asks for a pause now (raised while still
/// held), and any press while paused resumes. It raises exactly the `Realtime` requests the
/// host link raises for M601 / M601 S1 / M602.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct PauseButton {
    stable: bool,
    candidate: bool,
    candidate_since_us: u64,
    pressed_since_us: Option<u64>,
    fired: bool,
}

impl PauseButton {
    /// A released button.
    pub const fn new() -> Self {
        PauseButton {
            stable: false,
            candidate: false,
            candidate_since_us: 0,
            pressed_since_us: None,
            fired: false,
        }
    }

    /// Feeds one reading (`pressed` after the pin's polarity is applied), at least every few
    /// milliseconds; `paused` is whether the printer is paused (or pausing). Returns the
    /// request to raise, if any.
    pub fn update(&mut self, pressed: bool, now_us: u64, paused: bool) -> Option<Realtime> {
        if pressed != self.candidate {
            self.candidate = pressed;
            self.candidate_since_us = now_us;
        }
        let settled = now_us.saturating_sub(self.candidate_since_us) >= BUTTON_DEBOUNCE_US;
        if settled && self.candidate != self.stable {
            self.stable = self.candidate;
            if self.stable {
                self.pressed_since_us = Some(now_us);
                self.fired = false;
                if paused {
                    self.fired = true;
                    return Some(Realtime::Resume);
                }
            } else {
                let was = self.pressed_since_us.take();
                if !self.fired && was.is_some() {
                    return Some(Realtime::Pause(PauseMode::Layer));
                }
            }
        }
        if let (true, Some(since), false) = (self.stable, self.pressed_since_us, self.fired) {
            if now_us.saturating_sub(since) >= BUTTON_LONG_US {
                self.fired = true;
                return Some(Realtime::Pause(PauseMode::Now));
            }
        }
        None
    }
}

/// Switches the stepper drivers off after a while without motion (Marlin's
/// `DEFAULT_STEPPER_DEACTIVE_TIME`, M18/M84 S<seconds>), but never while a print is running or
/// paused: a paused print must keep its position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IdleTimeout {
    /// Timeout, µs (0 = never).
    pub timeout_us: u64,
    last_activity_us: u64,
}

impl IdleTimeout {
    /// A timeout of `timeout_s` seconds.
    pub const fn new(timeout_s: u32) -> Self {
        IdleTimeout {
            timeout_us: timeout_s as u64 * 1_000_000,
            last_activity_us: 0,
        }
    }

    /// Change the timeout (M18/M84 `S<seconds>`; 0 = never). Negative or non-finite values
    /// are ignored (the executive already rejects them).
    pub fn set_timeout_s(&mut self, s: f32) {
        if s.is_finite() && s >= 0.0 {
            self.timeout_us = (s * 1.0e6) as u64;
        }
    }

    /// Call on every tick; `busy` is true while anything moves, is queued, or is paused.
    /// Returns true when the drivers should be switched off now.
    pub fn update(&mut self, busy: bool, now_us: u64) -> bool {
        if busy {
            self.last_activity_us = now_us;
            return false;
        }
        self.timeout_us != 0 && now_us.saturating_sub(self.last_activity_us) >= self.timeout_us
    }
}

/// Whether the loops that must run for the printer to be safe are still running, for the
/// independent watchdog: each loop calls [`Liveness::beat`] every pass, and the watchdog is fed
/// only while [`Liveness::all_alive`] holds. A stalled loop (or the whole executor stalled)
/// stops the feeding and the watchdog resets the MCU, which leaves every heater pin low.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Liveness<const N: usize> {
    last_us: [Option<u64>; N],
    max_gap_us: u64,
}

impl<const N: usize> Liveness<N> {
    /// `N` loops, each of which must beat at least every `max_gap_us`.
    pub const fn new(max_gap_us: u64) -> Self {
        Liveness {
            last_us: [None; N],
            max_gap_us,
        }
    }

    /// Loop `i` is alive at `now_us` (an index out of range is ignored).
    pub fn beat(&mut self, i: usize, now_us: u64) {
        if let Some(t) = self.last_us.get_mut(i) {
            *t = Some(now_us);
        }
    }

    /// Every loop has beaten, each within `max_gap_us` of `now_us`.
    pub fn all_alive(&self, now_us: u64) -> bool {
        self.last_us
            .iter()
            .all(|t| t.is_some_and(|t| now_us.saturating_sub(t) <= self.max_gap_us))
    }
}

#[cfg(test)]
mod liveness_tests {
    use super::Liveness;

    #[test]
    fn fed_only_while_both_loops_beat() {
        // Motion (0) and heaters (1), 250 ms allowed between beats.
        let mut l: Liveness<2> = Liveness::new(250_000);
        assert!(!l.all_alive(0), "nothing has run yet");
        l.beat(0, 1_000);
        assert!(!l.all_alive(1_000), "the heater loop has not run");
        l.beat(1, 2_000);
        assert!(l.all_alive(2_000));
        // The heater loop stalls; motion keeps beating.
        let mut t = 2_000;
        while t < 252_000 {
            t += 1_000;
            l.beat(0, t);
        }
        assert!(l.all_alive(252_000));
        assert!(!l.all_alive(253_000), "heater loop silent for 251 ms");
        // It comes back.
        l.beat(1, 253_000);
        assert!(l.all_alive(253_000));
        // The whole executor stalls: nobody beats.
        assert!(!l.all_alive(600_000));
        l.beat(7, 600_000);
        assert!(!l.all_alive(600_000));
    }
}
