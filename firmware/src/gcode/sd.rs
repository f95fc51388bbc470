//! The SD-card M-codes (Marlin's `gcode/sd/M20.cpp` … `M32.cpp`): their parameters as parsed,
//! and their G-code text. The executive's handlers are in `printer/sd/commands.rs`. M24
//! (start/resume), M25 (pause) and M524 (cancel) are the realtime [`PauseCommand::Resume`],
//! [`PauseCommand::Pause`] and [`PauseCommand::Cancel`]; plain M27 is
//! [`super::ReportCommand::JobStatus`].
//!
//! [`PauseCommand::Resume`]: super::PauseCommand::Resume
//! [`PauseCommand::Pause`]: super::PauseCommand::Pause
//! [`PauseCommand::Cancel`]: super::PauseCommand::Cancel

use super::{err, ParseError, ParseErrorKind, Text, Words};
use core::fmt::{self, Write};

/// Longest SD status auto-report period, s (Marlin takes a byte).
pub const MAX_SD_REPORT_S: u32 = 255;

/// An SD-card command.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SdCommand {
    /// `M20 [L]`: list the card's files with their sizes (`L`: and their long names).
    List {
        /// `L`: long names too.
        long: bool,
    },
    /// `M21`: initialise (mount) the card.
    Init,
    /// `M22`: release the card.
    Release,
    /// `M23 <name>`: select (open) a file for printing.
    Select(Text),
    /// `M26 S<byte>`: set the read position in the selected file.
    Seek(u32),
    /// `M27 S<s>`: report the SD status every s seconds while printing (0 = off).
    AutoReport(u32),
    /// `M27 C`: the selected file's name.
    CurrentFile,
    /// `M32 <name>`: select a file and start it.
    SelectAndStart(Text),
}

/// The M-codes parsed here with parameter words (M23 and M32 take a name: [`parse_name`]).
pub(super) fn is_sd_code(n: u16, w: &Words<'_>) -> bool {
    match n {
        20..=22 | 26 => true,
        27 => w.has(b'S') || w.has(b'C'),
        _ => false,
    }
}

/// The M-codes whose argument is a file name.
pub(super) fn is_name_code(n: u16) -> bool {
    matches!(n, 23 | 32)
}

/// Parse one of [`is_sd_code`]'s codes.
pub(super) fn build(n: u16, w: &Words<'_>) -> Result<SdCommand, ParseError> {
    Ok(match n {
        20 => {
            w.check(b"LT", b"LT")?;
            SdCommand::List { long: w.has(b'L') }
        }
        21 => {
            w.check(b"", b"")?;
            SdCommand::Init
        }
        22 => {
            w.check(b"", b"")?;
            SdCommand::Release
        }
        26 => {
            w.check(b"S", b"")?;
            SdCommand::Seek(w.u32(b'S')?.ok_or(err(ParseErrorKind::MissingNumber, 0))?)
        }
        _ => {
            w.check(b"SC", b"C")?;
            match w.u32(b'S')? {
                Some(s) if s > MAX_SD_REPORT_S => {
                    return Err(w.refuse(b'S', ParseErrorKind::OutOfRange))
                }
                Some(s) => SdCommand::AutoReport(s),
                None => SdCommand::CurrentFile,
            }
        }
    })
}

/// Build M23/M32 from the name text (the line's text after the code, comment removed): as
/// Marlin, the name ends at the first blank (Simplify3D writes the size after it, #7227).
pub(super) fn build_name(n: u16, text: Text, at: usize) -> Result<SdCommand, ParseError> {
    let name = text.split([' ', '\t']).next().unwrap_or("");
    if name.is_empty() {
        return Err(err(ParseErrorKind::MissingNumber, at));
    }
    let mut t = Text::new();
    // A prefix of `text`, so it fits.
    let _ = t.push_str(name);
    Ok(if n == 23 {
        SdCommand::Select(t)
    } else {
        SdCommand::SelectAndStart(t)
    })
}

/// The G-code text of an SD command (what the parser reads back).
pub(super) fn write<W: Write>(w: &mut W, c: &SdCommand) -> fmt::Result {
    match c {
        SdCommand::List { long: false } => w.write_str("M20"),
        SdCommand::List { long: true } => w.write_str("M20 L"),
        SdCommand::Init => w.write_str("M21"),
        SdCommand::Release => w.write_str("M22"),
        SdCommand::Select(n) => write!(w, "M23 {n}"),
        SdCommand::Seek(s) => write!(w, "M26 S{s}"),
        SdCommand::AutoReport(s) => write!(w, "M27 S{s}"),
        SdCommand::CurrentFile => w.write_str("M27 C"),
        SdCommand::SelectAndStart(n) => write!(w, "M32 {n}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::{parse_line, Command};

    fn parse(s: &str) -> Result<Option<Command>, crate::gcode::ParseError> {
        parse_line(s.as_bytes()).map(|l| l.command)
    }

    fn text(s: &str) -> Text {
        Text::try_from(s).unwrap()
    }

    #[test]
    fn sd_codes_parse_and_emit_round_trip() {
        for (t, c) in [
            ("M20", SdCommand::List { long: false }),
            ("M20 L", SdCommand::List { long: true }),
            ("M21", SdCommand::Init),
            ("M22", SdCommand::Release),
            ("M23 CUBE.GCO", SdCommand::Select(text("CUBE.GCO"))),
            ("M26 S1234", SdCommand::Seek(1234)),
            ("M27 S2", SdCommand::AutoReport(2)),
            ("M27 C", SdCommand::CurrentFile),
            (
                "M32 /a long name.gcode",
                SdCommand::SelectAndStart(text("/a")),
            ),
        ] {
            assert_eq!(parse(t), Ok(Some(Command::Sd(c.clone()))), "{t}");
            let emitted = format!("{}", Command::Sd(c.clone()));
            assert_eq!(parse(&emitted), Ok(Some(Command::Sd(c))), "{emitted}");
        }
        // Simplify3D's size after the name, and a comment.
        assert_eq!(
            parse("M23 part.gco 12345 ; go"),
            Ok(Some(Command::Sd(SdCommand::Select(text("part.gco")))))
        );
        // Plain M27 stays the report command.
        assert!(matches!(parse("M27"), Ok(Some(Command::Report(_)))));
    }

    #[test]
    fn bad_sd_parameters_are_parse_errors() {
        for t in [
            "M23", "M23   ", "M32", "M26", "M26 S-1", "M26 S1.5", "M27 S256", "M21 X1",
        ] {
            assert!(parse(t).is_err(), "{t}");
        }
    }
}
