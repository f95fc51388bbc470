//! The reversed-driver check before the drivers get power, as Marlin does it
//! (`Marlin/src/feature/stepper_driver_safety.cpp`, `stepper_driver_backward_check`, called from
//! `MarlinCore.cpp` `setup()` when the board has a `SAFE_POWER_PIN`, before
//! `settings.first_load()`; MarlinFirmware/Marlin at 04a17e72):
//!
//! 1. the driver power switch (the SKR 2's SAFE_POWER, PC13) is driven **low**;
//! 2. for each socket in turn: its EN pin becomes an input, its STEP pin is driven **low**, 20 ms pass,
//!    and EN is read: **low means the module sits in its socket the wrong way round**;
//! 3. the power switch goes high only if no socket failed.
//!
//! Why it works: a StepStick-format module turned by 180° puts its GND pins on the socket's
//! EN and STEP positions, so the module's ground net joins the MCU's EN and STEP lines. With
//! STEP driven low that net is at the MCU's ground, and EN reads low; a module the right way
//! round (or an empty socket) leaves EN high. STEP must be driven low, not left floating, or
//! the reversed module's ground net floats and EN may read high.
//!
//! One difference from Marlin, on purpose: Marlin's `SET_INPUT` leaves EN floating; here the
//! board passes EN with the MCU's pull-up (30–50 kΩ). A reversed module still reads low (its
//! ground net is held by the STEP output, a few tens of ohms), and a module whose EN has its
//! own pull-down (A4988 carriers pull EN low through 100 kΩ) no longer reads low by accident.
//!
//! This module only sequences pins (embedded-hal traits, a delay): the board wires its pins;
//! the report (`Error:X driver is backward!`, Marlin's `stepper_driver_backward_error`) and
//! the halt are `Printer::drivers_backward`.

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};

/// Time between driving STEP low and reading EN, ms (Marlin's `delay(20)`).
pub const SETTLE_MS: u32 = 20;

/// Most sockets one check handles (the SKR 2 has five: X, Y, Z, E0, E1).
pub const MAX_SOCKETS: usize = 8;

/// The sockets holding a module plugged in backwards: bit i = socket i of [`check`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Backward(pub u8);

impl Backward {
    /// No socket failed: the drivers may have power.
    pub fn none(self) -> bool {
        self.0 == 0
    }

    /// Socket `i` holds a reversed module.
    pub fn socket(self, i: usize) -> bool {
        i < MAX_SOCKETS && self.0 & (1 << i) != 0
    }
}

/// Runs the check with the driver power switch `power` on the sockets whose EN lines (as
/// inputs, with the MCU's pull-up) are `en` and STEP lines (outputs) are `step`, socket i =
/// `en[i]`, `step[i]` (the shorter slice sets the count, at most [`MAX_SOCKETS`]): power low
/// first, each socket sampled with its STEP low after [`SETTLE_MS`], power high only if none
/// is backward. A read error counts as backward (the drivers stay unpowered). Leaves every
/// STEP line low.
pub fn check<P, E, S, D>(power: &mut P, en: &mut [E], step: &mut [S], delay: &mut D) -> Backward
where
    P: OutputPin,
    E: InputPin,
    S: OutputPin,
    D: DelayNs,
{
    // A failed write on the power switch cannot be made safer by anything here: go on
    // (the result still says which sockets are backward).
    let _ = power.set_low();
    let mut found = 0u8;
    for (i, (en, step)) in en
        .iter_mut()
        .zip(step.iter_mut())
        .enumerate()
        .take(MAX_SOCKETS)
    {
        let _ = step.set_low();
        delay.delay_ms(SETTLE_MS);
        if en.is_low().unwrap_or(true) {
            found |= 1 << i;
        }
    }
    if found == 0 {
        let _ = power.set_high();
    }
    Backward(found)
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::cell::{Cell, RefCell};
    use core::convert::Infallible;
    use embedded_hal::digital::ErrorType;

    /// How a socket is fitted, electrically (the test's own model, not the check's).
    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Fitted {
        /// A module the right way round: EN is the driver's input, pulled up.
        Right,
        /// No module: EN floats, pulled up by the MCU.
        Empty,
        /// A module turned by 180°: its ground net joins the socket's EN and STEP lines, so
        /// EN reads whatever STEP drives (and floats high through the pull-up when STEP is
        /// not driven low).
        Reversed,
    }

    /// The bench: one power switch, five sockets, a clock in ms, and a log of pin actions.
    struct Bench {
        fitted: Vec<Fitted>,
        /// STEP levels as driven (None: not driven yet).
        step: RefCell<Vec<Option<bool>>>,
        power: Cell<Option<bool>>,
        now_ms: Cell<u32>,
        /// (socket, time of its STEP going low).
        step_low_at: RefCell<Vec<Option<u32>>>,
        /// (socket, time EN was read, power level then).
        reads: RefCell<Vec<(usize, u32, Option<bool>)>>,
        power_high_at: Cell<Option<u32>>,
    }

    impl Bench {
        fn new(fitted: &[Fitted]) -> Self {
            Bench {
                fitted: fitted.to_vec(),
                step: RefCell::new(vec![None; fitted.len()]),
                power: Cell::new(None),
                now_ms: Cell::new(0),
                step_low_at: RefCell::new(vec![None; fitted.len()]),
                reads: RefCell::new(Vec::new()),
                power_high_at: Cell::new(None),
            }
        }
    }

    struct Power<'a>(&'a Bench);
    struct En<'a>(&'a Bench, usize);
    struct Step<'a>(&'a Bench, usize);
    struct Clock<'a>(&'a Bench);

    impl ErrorType for Power<'_> {
        type Error = Infallible;
    }
    impl OutputPin for Power<'_> {
        fn set_low(&mut self) -> Result<(), Infallible> {
            self.0.power.set(Some(false));
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Infallible> {
            self.0.power.set(Some(true));
            self.0.power_high_at.set(Some(self.0.now_ms.get()));
            Ok(())
        }
    }
    impl ErrorType for Step<'_> {
        type Error = Infallible;
    }
    impl OutputPin for Step<'_> {
        fn set_low(&mut self) -> Result<(), Infallible> {
            self.0.step.borrow_mut()[self.1] = Some(false);
            self.0.step_low_at.borrow_mut()[self.1] = Some(self.0.now_ms.get());
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Infallible> {
            self.0.step.borrow_mut()[self.1] = Some(true);
            Ok(())
        }
    }
    impl ErrorType for En<'_> {
        type Error = Infallible;
    }
    impl InputPin for En<'_> {
        fn is_high(&mut self) -> Result<bool, Infallible> {
            let b = self.0;
            b.reads
                .borrow_mut()
                .push((self.1, b.now_ms.get(), b.power.get()));
            Ok(match b.fitted[self.1] {
                Fitted::Right | Fitted::Empty => true,
                Fitted::Reversed => b.step.borrow()[self.1] != Some(false),
            })
        }
        fn is_low(&mut self) -> Result<bool, Infallible> {
            self.is_high().map(|h| !h)
        }
    }
    impl DelayNs for Clock<'_> {
        fn delay_ns(&mut self, ns: u32) {
            self.0
                .now_ms
                .set(self.0.now_ms.get() + ns.div_ceil(1_000_000));
        }
    }

    fn run(b: &Bench) -> Backward {
        let n = b.fitted.len();
        let mut en: Vec<_> = (0..n).map(|i| En(b, i)).collect();
        let mut step: Vec<_> = (0..n).map(|i| Step(b, i)).collect();
        check(&mut Power(b), &mut en, &mut step, &mut Clock(b))
    }

    /// Every socket sampled with the power off and its STEP low for at least 20 ms.
    fn sampled_as_marlin(b: &Bench) {
        let reads = b.reads.borrow();
        assert_eq!(reads.len(), b.fitted.len(), "each socket read once");
        for &(i, t, power) in reads.iter() {
            assert_eq!(power, Some(false), "socket {i} read with power not off");
            let low_at = b.step_low_at.borrow()[i].expect("STEP driven low before the read");
            assert!(
                t >= low_at + SETTLE_MS,
                "socket {i}: read {t} ms, STEP low at {low_at}"
            );
        }
    }

    #[test]
    fn all_right_way_round_powers_the_drivers_after_the_check() {
        use Fitted::*;
        let b = Bench::new(&[Right, Right, Right, Right, Empty]);
        let r = run(&b);
        assert!(r.none());
        sampled_as_marlin(&b);
        assert_eq!(b.power.get(), Some(true));
        let last_read = b.reads.borrow().iter().map(|r| r.1).max().unwrap();
        assert!(b.power_high_at.get().unwrap() >= last_read);
        assert!(b.step.borrow().iter().all(|s| *s == Some(false)));
    }

    #[test]
    fn one_reversed_module_keeps_the_power_off_and_is_named() {
        use Fitted::*;
        for bad in 0..5 {
            let mut fitted = vec![Right; 5];
            fitted[bad] = Reversed;
            let b = Bench::new(&fitted);
            let r = run(&b);
            sampled_as_marlin(&b);
            assert_eq!(r, Backward(1 << bad), "socket {bad}");
            assert!((0..5).all(|i| r.socket(i) == (i == bad)));
            assert_eq!(b.power.get(), Some(false), "power stays off");
            assert_eq!(b.power_high_at.get(), None, "never switched on");
        }
        let b = Bench::new(&[Reversed, Right, Reversed, Empty, Reversed]);
        assert_eq!(run(&b), Backward(0b10101));
        assert_eq!(b.power.get(), Some(false));
    }

    /// The reason STEP is driven low: with STEP left high, a reversed module is missed.
    #[test]
    fn the_model_misses_a_reversed_module_when_step_is_high() {
        let b = Bench::new(&[Fitted::Reversed]);
        b.step.borrow_mut()[0] = Some(true);
        assert!(
            En(&b, 0).is_high().unwrap(),
            "the bench's model is not trivial"
        );
        assert_eq!(run(&b), Backward(1));
    }
}
