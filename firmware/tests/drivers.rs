//! The portable `embedded-hal` drivers (`firmware::drivers`) with mock pins: what a simulator
//! or a test supplies instead of the board's GPIOs.

use core::cell::Cell;
use core::convert::Infallible;
use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
use firmware::config::MachineConfig;
use firmware::drivers::{
    IdleTimeout, PauseButton, StepExecutor, StepperPins, TravelFrame, BUTTON_DEBOUNCE_US,
    BUTTON_LONG_US,
};
use firmware::homing::{Endstops, PinEndstops};
use firmware::motion::{Axis, PauseMode, Realtime};

/// An output pin recording its level as one bit of a shared word.
struct MockOut<'a> {
    levels: &'a Cell<u32>,
    bit: u32,
}

impl ErrorType for MockOut<'_> {
    type Error = Infallible;
}

impl OutputPin for MockOut<'_> {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.levels.set(self.levels.get() & !(1 << self.bit));
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.levels.set(self.levels.get() | (1 << self.bit));
        Ok(())
    }
}

/// An input pin reading a shared level; `fail` makes every read an error.
struct MockIn<'a> {
    level: &'a Cell<bool>,
    fail: bool,
}

#[derive(Debug)]
struct ReadError;

impl embedded_hal::digital::Error for ReadError {
    fn kind(&self) -> embedded_hal::digital::ErrorKind {
        embedded_hal::digital::ErrorKind::Other
    }
}

impl ErrorType for MockIn<'_> {
    type Error = ReadError;
}

impl InputPin for MockIn<'_> {
    fn is_high(&mut self) -> Result<bool, ReadError> {
        if self.fail {
            Err(ReadError)
        } else {
            Ok(self.level.get())
        }
    }
    fn is_low(&mut self) -> Result<bool, ReadError> {
        self.is_high().map(|h| !h)
    }
}

fn steppers(levels: &Cell<u32>) -> StepperPins<MockOut<'_>> {
    let pin = |bit| MockOut { levels, bit };
    // Bits 0..3 STEP, 4..7 DIR, 8..11 EN (active low). E's DIR is wired inverted.
    StepperPins::new(
        [pin(0), pin(1), pin(2), pin(3)],
        [pin(4), pin(5), pin(6), pin(7)],
        [pin(8), pin(9), pin(10), pin(11)],
        0b0111,
    )
}

#[test]
fn stepper_pins_enable_dir_step() {
    let levels = Cell::new(0);
    let mut s = steppers(&levels);
    assert_eq!(
        levels.get() & 0xF00,
        0xF00,
        "drivers start disabled (EN high)"
    );
    assert_eq!(s.enabled_mask(), 0);
    s.set_enabled(true);
    assert_eq!(levels.get() & 0xF00, 0);
    s.set_axes_enabled(0b0100, false);
    assert_eq!(levels.get() & 0xF00, 0x400, "only Z off");
    assert_eq!(s.enabled_mask(), 0b1011);
    // X and E positive: X DIR high, E DIR low (inverted wiring).
    assert!(s.set_dirs(0b1001, 0b1001));
    assert_eq!(levels.get() & 0xF0, 0x10);
    assert!(!s.set_dirs(0b1001, 0b1001), "no change, no setup wait");
    s.step_high(0b0011);
    assert_eq!(levels.get() & 0xF, 0b0011);
    s.step_low();
    assert_eq!(levels.get() & 0xF, 0);
}

#[test]
fn endstops_polarity_and_read_errors() {
    let (x, y, z) = (Cell::new(false), Cell::new(true), Cell::new(false));
    let mut e = PinEndstops {
        x: MockIn {
            level: &x,
            fail: false,
        },
        y: MockIn {
            level: &y,
            fail: false,
        },
        z: MockIn {
            level: &z,
            fail: true,
        },
        // X and Y read high when pressed, Z low.
        pressed_high: 0b011,
    };
    assert!(!e.triggered(Axis::X), "X reads low, triggers high");
    assert!(e.triggered(Axis::Y), "Y reads high");
    assert!(e.triggered(Axis::Z), "a read error counts as triggered");
    assert!(!e.triggered(Axis::E), "E has no endstop");
    x.set(true);
    assert!(e.triggered(Axis::X));
}

#[test]
fn pause_button_short_long_and_resume() {
    let mut b = PauseButton::new();
    // A bounce shorter than the debounce time does nothing.
    assert_eq!(b.update(true, 0, false), None);
    assert_eq!(b.update(false, 5_000, false), None);
    assert_eq!(b.update(false, 50_000, false), None);
    // Short press: pause at the layer boundary on release.
    let t = 100_000;
    assert_eq!(b.update(true, t, false), None);
    assert_eq!(b.update(true, t + BUTTON_DEBOUNCE_US, false), None);
    assert_eq!(b.update(false, t + 200_000, false), None);
    assert_eq!(
        b.update(false, t + 200_000 + BUTTON_DEBOUNCE_US, false),
        Some(Realtime::Pause(PauseMode::Layer))
    );
    // Long press: pause now while still held, nothing on release.
    let t = 1_000_000;
    b.update(true, t, false);
    b.update(true, t + BUTTON_DEBOUNCE_US, false);
    assert_eq!(
        b.update(true, t + BUTTON_DEBOUNCE_US + BUTTON_LONG_US, false),
        Some(Realtime::Pause(PauseMode::Now))
    );
    b.update(false, t + 3_000_000, true);
    assert_eq!(
        b.update(false, t + 3_000_000 + BUTTON_DEBOUNCE_US, true),
        None
    );
    // Any press while paused resumes.
    let t = 10_000_000;
    b.update(true, t, true);
    assert_eq!(
        b.update(true, t + BUTTON_DEBOUNCE_US, true),
        Some(Realtime::Resume)
    );
}

#[test]
fn idle_timeout_and_m84_s() {
    let mut idle = IdleTimeout::new(120);
    assert!(!idle.update(true, 0));
    assert!(!idle.update(false, 119_000_000));
    assert!(idle.update(false, 120_000_000));
    idle.set_timeout_s(5.0);
    assert!(!idle.update(true, 200_000_000));
    assert!(idle.update(false, 205_000_000));
    idle.set_timeout_s(-1.0);
    assert_eq!(idle.timeout_us, 5_000_000, "bad values ignored");
    idle.set_timeout_s(0.0);
    assert!(!idle.update(false, 900_000_000), "0 = never");
}

/// Axes not homed step from where they stood (Marlin without `NO_MOTION_BEFORE_HOMING`: the
/// image refused every X/Y/Z step before G28 while the executive answered `ok`); a homed axis
/// stays inside its limits; a new step frame (M92) moves the limits and the position with it.
#[test]
fn step_executor_moves_unhomed_axes_and_follows_the_frame() {
    let levels = Cell::new(0);
    let mut x = StepExecutor::new(steppers(&levels));
    let cfg = MachineConfig::ENDER3;
    x.follow(&TravelFrame {
        epoch: 0,
        pos: [0; 4],
        limits: cfg.travel_limits_steps(),
    });
    assert_eq!(x.limits[0], (0, 18_800));
    let nowait = |_| {};
    // Unhomed: X steps below its minimum (the carriage's true place is unknown).
    assert_eq!(x.fire(0b0001, 0, 0, 0, nowait), 0b0001);
    assert_eq!(x.pos[0], -1);
    assert_eq!(x.refused, 0);
    // Homed at 0: no step below the minimum.
    x.set_homed(0b0111, 0b0111, [0, 0, 0]);
    assert_eq!(x.fire(0b0001, 0, 0, 0, nowait), 0);
    assert_eq!(x.refused, 1);
    // At 18_800 (235 mm at 80 steps/mm) the maximum.
    x.pos[0] = 18_800;
    assert_eq!(x.fire(0b0001, 0b0001, 0, 0, nowait), 0);
    // M92 X160 at X 117.5 mm: the frame is 18_800 of 37_600; the limit follows.
    let mut c2 = cfg;
    c2.axes[0].steps_per_mm = 160.0;
    x.pos[0] = 9_400;
    x.follow(&TravelFrame {
        epoch: 1,
        pos: [18_800, 0, 0, 0],
        limits: c2.travel_limits_steps(),
    });
    assert_eq!((x.frame_epoch(), x.limits[0]), (1, (0, 37_600)));
    assert_eq!(x.fire(0b0001, 0b0001, 0, 0, nowait), 0b0001);
    assert_eq!(x.pos[0], 18_801);
}
