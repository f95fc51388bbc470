//! The settings M-codes (Marlin's spelling): their parameters as parsed, and their G-code text.
//! The executive's handlers are in `printer/settings.rs`; ranges and units in
//! [`crate::storage`] and `docs/settings.md`.

use super::format::opt;
use super::{err, AxisWords, ParseError, ParseErrorKind, Words};
use core::fmt::{self, Write};

/// `M205` parameters (Marlin's); `None` = not given.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Advanced {
    /// `J`: junction deviation, mm.
    pub junction_mm: Option<f32>,
    /// `X Y Z E`: classic jerk, mm/s (this firmware plans with junction deviation: refused).
    pub jerk: AxisWords,
    /// `B`: minimum segment time, µs (not used here: refused).
    pub min_segment_us: Option<f32>,
    /// `S`: minimum print feed rate, mm/s (not used here: refused).
    pub min_feed_mm_s: Option<f32>,
    /// `T`: minimum travel feed rate, mm/s (not used here: refused).
    pub min_travel_mm_s: Option<f32>,
}

/// A settings command. With no parameter, each setting command reports its current values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SettingsCommand {
    /// `M92 [X Y Z E]`: steps per mm.
    StepsPerUnit(AxisWords),
    /// `M201 [X Y Z E]`: maximum acceleration per axis, mm/s².
    MaxAccel(AxisWords),
    /// `M203 [X Y Z E]`: maximum feed rate per axis, mm/s (Marlin's unit, not mm/min).
    MaxFeed(AxisWords),
    /// `M205 [J] [X Y Z E] [B S T]`: junction deviation (and Marlin's other motion values).
    Advanced(Advanced),
    /// `M206 [X Y Z]`: home offsets, mm.
    HomeOffset(AxisWords),
    /// `M851 [X Y Z]`: Z-probe offsets, mm (this machine has no probe: answered so).
    ProbeOffset(AxisWords),
    /// `M906 [X Y Z E]`: stepper driver RMS current, mA.
    DriverCurrent(AxisWords),
    /// `M500`: save the settings to flash.
    Save,
    /// `M501`: load the saved settings.
    Load,
    /// `M502`: factory defaults (not saved until M500).
    FactoryReset,
    /// `M503`: report every setting as G-code that can be sent back.
    Report,
    /// `M204 [P] [R] [T] [S]`: accelerations, mm/s² (print, retract, travel, both).
    Acceleration {
        /// `P`: printing moves.
        print: Option<f32>,
        /// `R`: retract/prime moves.
        retract: Option<f32>,
        /// `T`: travel moves.
        travel: Option<f32>,
        /// `S`: printing and travel (legacy).
        s: Option<f32>,
    },
}

/// The M-codes parsed here.
pub(super) fn is_settings_code(n: u16) -> bool {
    matches!(n, 92 | 201 | 203 | 204 | 205 | 206 | 851 | 906 | 500..=503)
}

/// Parse one of [`is_settings_code`]'s codes.
pub(super) fn build(n: u16, w: &Words<'_>) -> Result<SettingsCommand, ParseError> {
    use SettingsCommand as S;
    let c = match n {
        204 => {
            w.check(b"PRTS", b"")?;
            S::Acceleration {
                print: w.f32(b'P')?,
                retract: w.f32(b'R')?,
                travel: w.f32(b'T')?,
                s: w.f32(b'S')?,
            }
        }
        92 | 201 | 203 | 906 => {
            w.check(b"XYZE", b"")?;
            let a = w.axes()?;
            match n {
                92 => S::StepsPerUnit(a),
                201 => S::MaxAccel(a),
                203 => S::MaxFeed(a),
                _ => S::DriverCurrent(a),
            }
        }
        205 => {
            w.check(b"JXYZEBST", b"")?;
            S::Advanced(Advanced {
                junction_mm: w.f32(b'J')?,
                jerk: w.axes()?,
                min_segment_us: w.f32(b'B')?,
                min_feed_mm_s: w.f32(b'S')?,
                min_travel_mm_s: w.f32(b'T')?,
            })
        }
        206 | 851 => {
            w.check(b"XYZ", b"")?;
            let a = w.axes()?;
            if n == 206 {
                S::HomeOffset(a)
            } else {
                S::ProbeOffset(a)
            }
        }
        500..=503 => {
            w.check(b"", b"")?;
            match n {
                500 => S::Save,
                501 => S::Load,
                502 => S::FactoryReset,
                _ => S::Report,
            }
        }
        _ => return Err(err(ParseErrorKind::BadCode, 0)),
    };
    Ok(c)
}

fn axes<W: Write>(w: &mut W, code: &str, a: &AxisWords) -> fmt::Result {
    w.write_str(code)?;
    for (letter, v) in ['X', 'Y', 'Z', 'E'].into_iter().zip(a.0) {
        if let Some(v) = v {
            write!(w, " {letter}{v}")?;
        }
    }
    Ok(())
}

/// Write a settings command as G-code (numbers as Rust's shortest round-trip decimal, which
/// the parser reads back to the same bits).
pub(super) fn write<W: Write>(w: &mut W, c: &SettingsCommand) -> fmt::Result {
    use SettingsCommand as S;
    match c {
        S::Acceleration {
            print,
            retract,
            travel,
            s,
        } => {
            w.write_str("M204")?;
            opt(w, 'P', *print)?;
            opt(w, 'R', *retract)?;
            opt(w, 'T', *travel)?;
            opt(w, 'S', *s)
        }
        S::StepsPerUnit(a) => axes(w, "M92", a),
        S::MaxAccel(a) => axes(w, "M201", a),
        S::MaxFeed(a) => axes(w, "M203", a),
        S::Advanced(p) => {
            w.write_str("M205")?;
            if let Some(j) = p.junction_mm {
                write!(w, " J{j}")?;
            }
            axes(w, "", &p.jerk)?;
            for (letter, v) in [
                ('B', p.min_segment_us),
                ('S', p.min_feed_mm_s),
                ('T', p.min_travel_mm_s),
            ] {
                if let Some(v) = v {
                    write!(w, " {letter}{v}")?;
                }
            }
            Ok(())
        }
        S::HomeOffset(a) => axes(w, "M206", a),
        S::ProbeOffset(a) => axes(w, "M851", a),
        S::DriverCurrent(a) => axes(w, "M906", a),
        S::Save => w.write_str("M500"),
        S::Load => w.write_str("M501"),
        S::FactoryReset => w.write_str("M502"),
        S::Report => w.write_str("M503"),
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::kind;
    use super::super::{Command, ParseErrorKind};
    use super::*;
    use proptest::prelude::*;

    fn cmd(s: &str) -> SettingsCommand {
        match super::super::tests::cmd(s) {
            Command::Settings(c) => c,
            other => panic!("{s:?}: {other:?}"),
        }
    }

    #[test]
    fn marlin_spellings_parse() {
        assert_eq!(
            cmd("M92 X80 Y80 Z400 E93"),
            SettingsCommand::StepsPerUnit(AxisWords([
                Some(80.0),
                Some(80.0),
                Some(400.0),
                Some(93.0)
            ]))
        );
        assert_eq!(
            cmd("M92"),
            SettingsCommand::StepsPerUnit(AxisWords::default())
        );
        assert_eq!(
            cmd("m203 z10"),
            SettingsCommand::MaxFeed(AxisWords([None, None, Some(10.0), None]))
        );
        assert_eq!(
            cmd("M205 J0.02 X8 Y8"),
            SettingsCommand::Advanced(Advanced {
                junction_mm: Some(0.02),
                jerk: AxisWords([Some(8.0), Some(8.0), None, None]),
                ..Advanced::default()
            })
        );
        assert_eq!(
            cmd("M206 Z-0.5"),
            SettingsCommand::HomeOffset(AxisWords([None, None, Some(-0.5), None]))
        );
        assert_eq!(
            cmd("M906 E650"),
            SettingsCommand::DriverCurrent(AxisWords([None, None, None, Some(650.0)]))
        );
        assert_eq!(cmd("M500"), SettingsCommand::Save);
        assert_eq!(cmd("M501"), SettingsCommand::Load);
        assert_eq!(cmd("M502"), SettingsCommand::FactoryReset);
        assert_eq!(cmd("M503"), SettingsCommand::Report);
    }

    #[test]
    fn wrong_letters_are_parse_errors() {
        assert_eq!(kind("M92 Q1"), ParseErrorKind::UnexpectedLetter);
        assert_eq!(kind("M206 E1"), ParseErrorKind::UnexpectedLetter);
        assert_eq!(kind("M500 S1"), ParseErrorKind::UnexpectedLetter);
        assert_eq!(kind("M92 X"), ParseErrorKind::MissingNumber);
        assert_eq!(kind("M203 X1 X2"), ParseErrorKind::DuplicateLetter);
    }

    fn num() -> impl Strategy<Value = Option<f32>> {
        proptest::option::of(prop_oneof![
            -1.0e6f32..1.0e6,
            (-1000i32..1000).prop_map(|v| v as f32 / 8.0)
        ])
    }

    fn axes4() -> impl Strategy<Value = AxisWords> {
        (num(), num(), num(), num()).prop_map(|(x, y, z, e)| AxisWords([x, y, z, e]))
    }

    fn axes3() -> impl Strategy<Value = AxisWords> {
        (num(), num(), num()).prop_map(|(x, y, z)| AxisWords([x, y, z, None]))
    }

    fn settings_command() -> impl Strategy<Value = SettingsCommand> {
        use SettingsCommand as S;
        prop_oneof![
            axes4().prop_map(S::StepsPerUnit),
            axes4().prop_map(S::MaxAccel),
            axes4().prop_map(S::MaxFeed),
            axes4().prop_map(S::DriverCurrent),
            axes3().prop_map(S::HomeOffset),
            axes3().prop_map(S::ProbeOffset),
            (num(), axes4(), num(), num(), num()).prop_map(|(j, jerk, b, s, t)| {
                S::Advanced(Advanced {
                    junction_mm: j,
                    jerk,
                    min_segment_us: b,
                    min_feed_mm_s: s,
                    min_travel_mm_s: t,
                })
            }),
            Just(S::Save),
            Just(S::Load),
            Just(S::FactoryReset),
            Just(S::Report),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 512,
            rng_seed: proptest::test_runner::RngSeed::Fixed(13),
            ..ProptestConfig::default()
        })]
        /// emit → parse gives the same command, to the bit.
        #[test]
        fn emitted_settings_parse_back(c in settings_command()) {
            let mut s: heapless::String<160> = heapless::String::new();
            write!(s, "{}", Command::Settings(c)).unwrap();
            prop_assert_eq!(cmd(&s), c);
        }
    }
}
