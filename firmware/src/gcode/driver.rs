//! The stepper-driver M-codes (Marlin's spelling) besides M906 (run current, a settings
//! command): M569 chopper mode, M350 microsteps, M122 driver report. The executive's handlers
//! are in `printer/drivers.rs`; the registers behind them in [`crate::drivers::tmc2209`].

use super::format::opt;
use super::{err, AxisFlags, AxisWords, ParseError, ParseErrorKind, Words};
use core::fmt::{self, Write};

/// A driver command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DriverCommand {
    /// `M569 S<0|1> [X Y Z E]`: stealthChop (S1) or spreadCycle (S0) on the named axes (none
    /// named = all); without `S`, report each axis's mode.
    Chopper {
        /// The axes named.
        axes: AxisFlags,
        /// `S`: stealthChop on (true) or off; `None` = report.
        stealthchop: Option<bool>,
    },
    /// `M350 [S<n>] [X<n> Y<n> Z<n> E<n>]`: microsteps per full step (1, 2, 4, ..., 256), `S`
    /// for every axis; each axis's steps/mm scale with it (the distance of a mm stays a mm).
    /// Without a word, report.
    Microsteps {
        /// `S`: every axis.
        all: Option<f32>,
        /// Per-axis values (override `S`).
        axes: AxisWords,
    },
    /// `M122 [X Y Z E]`: read the drivers and report their state (none named = all).
    Report(AxisFlags),
    /// `M17 [X Y Z E]`: enable steppers.
    EnableSteppers(AxisFlags),
    /// `M18` / `M84 [X Y Z E] [S<s>]`: disable steppers (or set the idle timeout with S).
    DisableSteppers {
        /// Written as M18 rather than M84.
        m18: bool,
        /// Axes named.
        axes: AxisFlags,
        /// `S`: idle timeout, seconds.
        s: Option<f32>,
    },
}

/// The M-codes parsed here.
pub(super) fn is_driver_code(n: u16) -> bool {
    matches!(n, 17 | 18 | 84 | 122 | 350 | 569)
}

/// Parse one of [`is_driver_code`]'s codes.
pub(super) fn build(n: u16, w: &Words<'_>) -> Result<DriverCommand, ParseError> {
    let c = match n {
        17 => {
            w.check(b"XYZE", b"XYZE")?;
            DriverCommand::EnableSteppers(w.flags())
        }
        n @ (18 | 84) => {
            w.check(b"XYZES", b"XYZE")?;
            DriverCommand::DisableSteppers {
                m18: n == 18,
                axes: w.flags(),
                s: w.f32(b'S')?,
            }
        }
        569 => {
            w.check(b"SXYZE", b"XYZE")?;
            let stealthchop = match w.u8(b'S')? {
                None => None,
                Some(0) => Some(false),
                Some(1) => Some(true),
                Some(_) => return Err(w.refuse(b'S', ParseErrorKind::OutOfRange)),
            };
            DriverCommand::Chopper {
                axes: w.flags(),
                stealthchop,
            }
        }
        350 => {
            w.check(b"SXYZE", b"")?;
            DriverCommand::Microsteps {
                all: w.f32(b'S')?,
                axes: w.axes()?,
            }
        }
        122 => {
            w.check(b"XYZE", b"XYZE")?;
            DriverCommand::Report(w.flags())
        }
        _ => return Err(err(ParseErrorKind::BadCode, 0)),
    };
    Ok(c)
}

fn flags<W: Write>(w: &mut W, f: &AxisFlags) -> fmt::Result {
    for (letter, on) in ['X', 'Y', 'Z', 'E'].into_iter().zip(f.0) {
        if on {
            write!(w, " {letter}")?;
        }
    }
    Ok(())
}

/// Write a driver command as G-code.
pub(super) fn write<W: Write>(w: &mut W, c: &DriverCommand) -> fmt::Result {
    match c {
        DriverCommand::EnableSteppers(fl) => {
            w.write_str("M17")?;
            flags(w, fl)
        }
        DriverCommand::DisableSteppers { m18, axes: fl, s } => {
            w.write_str(if *m18 { "M18" } else { "M84" })?;
            flags(w, fl)?;
            opt(w, 'S', *s)
        }
        DriverCommand::Chopper { axes, stealthchop } => {
            w.write_str("M569")?;
            if let Some(s) = stealthchop {
                write!(w, " S{}", u8::from(*s))?;
            }
            flags(w, axes)
        }
        DriverCommand::Microsteps { all, axes } => {
            w.write_str("M350")?;
            if let Some(s) = all {
                write!(w, " S{s}")?;
            }
            for (letter, v) in ['X', 'Y', 'Z', 'E'].into_iter().zip(axes.0) {
                if let Some(v) = v {
                    write!(w, " {letter}{v}")?;
                }
            }
            Ok(())
        }
        DriverCommand::Report(axes) => {
            w.write_str("M122")?;
            flags(w, axes)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::kind;
    use super::super::{write_command, Command};
    use super::*;
    use proptest::prelude::*;

    fn cmd(s: &str) -> DriverCommand {
        match super::super::tests::cmd(s) {
            Command::Driver(c) => c,
            other => panic!("{s:?}: {other:?}"),
        }
    }

    #[test]
    fn marlin_spellings_parse() {
        assert_eq!(
            cmd("M569 S1 X Y"),
            DriverCommand::Chopper {
                axes: AxisFlags([true, true, false, false]),
                stealthchop: Some(true)
            }
        );
        assert_eq!(
            cmd("M569"),
            DriverCommand::Chopper {
                axes: AxisFlags::default(),
                stealthchop: None
            }
        );
        assert_eq!(
            cmd("M350 S16 E8"),
            DriverCommand::Microsteps {
                all: Some(16.0),
                axes: AxisWords([None, None, None, Some(8.0)])
            }
        );
        assert_eq!(cmd("M122"), DriverCommand::Report(AxisFlags::default()));
        assert_eq!(
            cmd("m122 z"),
            DriverCommand::Report(AxisFlags([false, false, true, false]))
        );
    }

    #[test]
    fn wrong_words_are_parse_errors() {
        assert_eq!(kind("M569 S2"), ParseErrorKind::OutOfRange);
        assert_eq!(kind("M569 P1"), ParseErrorKind::UnexpectedLetter);
        assert_eq!(kind("M350 X"), ParseErrorKind::MissingNumber);
        assert_eq!(kind("M122 S1"), ParseErrorKind::UnexpectedLetter);
    }

    fn num() -> impl Strategy<Value = Option<f32>> {
        proptest::option::of((0u32..=512).prop_map(|v| v as f32))
    }

    fn flags4() -> impl Strategy<Value = AxisFlags> {
        proptest::array::uniform4(any::<bool>()).prop_map(AxisFlags)
    }

    fn driver_command() -> impl Strategy<Value = DriverCommand> {
        prop_oneof![
            (flags4(), proptest::option::of(any::<bool>()))
                .prop_map(|(axes, stealthchop)| DriverCommand::Chopper { axes, stealthchop }),
            (num(), num(), num(), num(), num()).prop_map(|(all, x, y, z, e)| {
                DriverCommand::Microsteps {
                    all,
                    axes: AxisWords([x, y, z, e]),
                }
            }),
            flags4().prop_map(DriverCommand::Report),
        ]
    }

    proptest! {
        /// Every driver command written as G-code parses back to itself.
        #[test]
        fn round_trip(c in driver_command()) {
            let mut s = heapless::String::<128>::new();
            write_command(&mut s, &Command::Driver(c)).unwrap();
            prop_assert_eq!(cmd(&s), c, "{}", s);
        }
    }
}
