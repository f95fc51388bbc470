//! The report M-codes hosts expect of a Marlin-class firmware: their parameters as parsed, and
//! their G-code text. The executive's handlers are in `printer/report.rs`.

use super::{ParseError, ParseErrorKind, Words};
use core::fmt::{self, Write};

/// Longest period M155/M113 accept, s (Marlin takes a byte: 0–60 for M155, 1–60 for M113).
pub const MAX_REPORT_PERIOD_S: u32 = 60;

/// A report command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReportCommand {
    /// `M155 S<s>`: report the temperatures every s seconds (0 = off). No S: report the
    /// current interval.
    AutoTemp(Option<u32>),
    /// `M113 S<s>`: the host keep-alive (`busy:`) period, s (0 = off). No S: report it.
    HostKeepalive(Option<u32>),
    /// `M31`: the print job's elapsed time.
    PrintTime,
    /// `M27`: the job status (this printer has no SD card: "Not SD printing" and the layer).
    JobStatus,
}

/// The M-codes parsed here.
pub(super) fn is_report_code(n: u16) -> bool {
    matches!(n, 155 | 113 | 31 | 27)
}

/// Parse one of [`is_report_code`]'s codes.
pub(super) fn build(n: u16, w: &Words<'_>) -> Result<ReportCommand, ParseError> {
    let period = |w: &Words<'_>| -> Result<Option<u32>, ParseError> {
        w.check(b"S", b"")?;
        match w.u32(b'S')? {
            Some(s) if s > MAX_REPORT_PERIOD_S => Err(w.refuse(b'S', ParseErrorKind::OutOfRange)),
            s => Ok(s),
        }
    };
    Ok(match n {
        155 => ReportCommand::AutoTemp(period(w)?),
        113 => ReportCommand::HostKeepalive(period(w)?),
        31 => {
            w.check(b"", b"")?;
            ReportCommand::PrintTime
        }
        _ => {
            // M27 S<s> (SD status auto-report) and C (file name) are SD commands (gcode/sd.rs).
            w.check(b"", b"")?;
            ReportCommand::JobStatus
        }
    })
}

/// The G-code text of a report command (what [`build`] reads back).
pub(super) fn write<W: Write>(w: &mut W, c: &ReportCommand) -> fmt::Result {
    let (code, s) = match c {
        ReportCommand::AutoTemp(s) => ("M155", s),
        ReportCommand::HostKeepalive(s) => ("M113", s),
        ReportCommand::PrintTime => return w.write_str("M31"),
        ReportCommand::JobStatus => return w.write_str("M27"),
    };
    w.write_str(code)?;
    match s {
        Some(s) => write!(w, " S{s}"),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::{parse_line, Command};

    fn parse(s: &str) -> Result<Option<Command>, crate::gcode::ParseError> {
        parse_line(s.as_bytes()).map(|l| l.command)
    }

    #[test]
    fn report_codes_parse_and_emit_round_trip() {
        for (text, c) in [
            ("M155 S1", ReportCommand::AutoTemp(Some(1))),
            ("M155 S0", ReportCommand::AutoTemp(Some(0))),
            ("M155", ReportCommand::AutoTemp(None)),
            ("M113 S2", ReportCommand::HostKeepalive(Some(2))),
            ("M113", ReportCommand::HostKeepalive(None)),
            ("M31", ReportCommand::PrintTime),
            ("M27", ReportCommand::JobStatus),
        ] {
            assert_eq!(parse(text), Ok(Some(Command::Report(c))), "{text}");
            let emitted = format!("{}", Command::Report(c));
            assert_eq!(emitted, text);
            assert_eq!(parse(&emitted), Ok(Some(Command::Report(c))));
        }
    }

    #[test]
    fn bad_report_parameters_are_parse_errors() {
        for text in [
            "M155 S61",
            "M155 S-1",
            "M155 S1.5",
            "M113 X1",
            "M27 X5",
            "M31 P1",
        ] {
            assert!(parse(text).is_err(), "{text}");
        }
    }
}
