//! The report M-codes hosts expect of a Marlin-class firmware: their parameters as parsed, and
//! their G-code text. The executive's handlers are in `printer/report.rs`.

use super::format::{opt, opt_int, text};
use super::{ParseError, ParseErrorKind, Text, Words};
use core::fmt::{self, Write};

/// Longest period M155/M113 accept, s (Marlin takes a byte: 0–60 for M155, 1–60 for M113).
pub const MAX_REPORT_PERIOD_S: u32 = 60;

/// M73 progress parameters (Marlin, Prusa and Orca spellings); `None` = not given.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Progress {
    /// `P`: percent done (normal mode).
    pub percent: Option<f32>,
    /// `R`: minutes remaining (normal mode).
    pub remaining_min: Option<f32>,
    /// `Q`: percent done (silent mode, Prusa).
    pub silent_percent: Option<f32>,
    /// `S`: minutes remaining (silent mode, Prusa).
    pub silent_remaining_min: Option<f32>,
    /// `C`: minutes to the next colour change (Prusa).
    pub change_min: Option<f32>,
    /// `L`: current layer (Orca, Bambu): a layer marker for [`crate::layer`].
    pub layer: Option<u32>,
}

/// A report command.
#[derive(Clone, Debug, PartialEq)]
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
    /// `M110 [N<n>]`: set the current line number (handled by [`crate::link`]).
    SetLineNumber(Option<u32>),
    /// `M114`: report the position.
    Position,
    /// `M115`: report firmware name and capabilities.
    FirmwareInfo,
    /// `M117 <text>`: show a message.
    Message(Text),
    /// `M118 <text>`: echo text to the host.
    Echo(Text),
    /// `M73`: print progress; `L` is a layer marker.
    Progress(Progress),
    /// `M119`: report the endstop states.
    Endstops,
    /// Klipper's `SET_PRINT_STATS_INFO [CURRENT_LAYER=<n>] [TOTAL_LAYER=<n>]`; CURRENT_LAYER is a
    /// layer marker for [`crate::layer`].
    PrintStatsInfo {
        /// `CURRENT_LAYER=`.
        current_layer: Option<u32>,
        /// `TOTAL_LAYER=`.
        total_layer: Option<u32>,
    },
}

/// The M-codes parsed here.
pub(super) fn is_report_code(n: u16) -> bool {
    matches!(n, 155 | 113 | 31 | 27 | 110 | 114 | 115 | 73 | 119)
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
        110 => {
            w.check(b"N", b"")?;
            // printcore opens a session with `N-1 M110` / `M110 N-1` (Marlin accepts it):
            // -1 is "before line 0", kept as u32::MAX so the next expected line wraps to 0.
            let n = match w.u32(b'N') {
                Ok(n) => n,
                Err(e) if w.i32(b'N') == Ok(Some(-1)) => {
                    let _ = e;
                    Some(u32::MAX)
                }
                Err(e) => return Err(e),
            };
            ReportCommand::SetLineNumber(n)
        }
        114 => {
            // Marlin's D (detail), E (stepper E), R (real) are accepted and ignored.
            w.check(b"DER", b"DER")?;
            ReportCommand::Position
        }
        115 => {
            w.ignore_all()?;
            ReportCommand::FirmwareInfo
        }
        73 => {
            w.check(b"PRQSCL", b"")?;
            ReportCommand::Progress(Progress {
                percent: w.f32(b'P')?,
                remaining_min: w.f32(b'R')?,
                silent_percent: w.f32(b'Q')?,
                silent_remaining_min: w.f32(b'S')?,
                change_min: w.f32(b'C')?,
                layer: w.u32(b'L')?,
            })
        }
        119 => {
            w.ignore_all()?;
            ReportCommand::Endstops
        }
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
        ReportCommand::SetLineNumber(n) => {
            w.write_str("M110")?;
            return opt_int(w, 'N', *n);
        }
        ReportCommand::Position => return w.write_str("M114"),
        ReportCommand::FirmwareInfo => return w.write_str("M115"),
        ReportCommand::Message(t) => return text(w, "M117", t),
        ReportCommand::Echo(t) => return text(w, "M118", t),
        ReportCommand::Progress(p) => {
            w.write_str("M73")?;
            opt(w, 'P', p.percent)?;
            opt(w, 'R', p.remaining_min)?;
            opt(w, 'Q', p.silent_percent)?;
            opt(w, 'S', p.silent_remaining_min)?;
            opt(w, 'C', p.change_min)?;
            return opt_int(w, 'L', p.layer);
        }
        ReportCommand::Endstops => return w.write_str("M119"),
        ReportCommand::PrintStatsInfo {
            current_layer,
            total_layer,
        } => {
            w.write_str("SET_PRINT_STATS_INFO")?;
            if let Some(l) = current_layer {
                write!(w, " CURRENT_LAYER={l}")?;
            }
            if let Some(l) = total_layer {
                write!(w, " TOTAL_LAYER={l}")?;
            }
            return Ok(());
        }
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
            assert_eq!(parse(text), Ok(Some(Command::Report(c.clone()))), "{text}");
            let emitted = format!("{}", Command::Report(c.clone()));
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
