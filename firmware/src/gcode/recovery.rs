//! M1000, power-cut resume (Marlin's `M1000` of `POWER_LOSS_RECOVERY`): resume the job a layer
//! pause kept in flash before the power went, or (`M1000 C`) discard it. The executive's
//! handler is `printer/recovery.rs`; `docs/settings.md` describes the sequence and its limits.

use super::{ParseError, Words};
use core::fmt::{self, Write};

/// What M1000 asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecoveryCommand {
    /// `M1000`: re-heat, home X/Y, return to the saved boundary and continue the job.
    Resume,
    /// `M1000 C`: discard the kept job (Marlin: cancel the recovery).
    Discard,
}

/// The M-codes parsed here.
pub(super) fn is_recovery_code(n: u16) -> bool {
    n == 1000
}

/// Parse M1000 (`C` is a flag; Marlin's `S` — "show the LCD menu" — has no meaning here and is
/// refused as an unexpected letter).
pub(super) fn build(w: &Words<'_>) -> Result<RecoveryCommand, ParseError> {
    w.check(b"C", b"C")?;
    Ok(if w.has(b'C') {
        RecoveryCommand::Discard
    } else {
        RecoveryCommand::Resume
    })
}

/// The G-code text (what [`build`] reads back).
pub(super) fn write<W: Write>(w: &mut W, c: &RecoveryCommand) -> fmt::Result {
    match c {
        RecoveryCommand::Resume => w.write_str("M1000"),
        RecoveryCommand::Discard => w.write_str("M1000 C"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::{parse_line, Command};

    #[test]
    fn m1000_parses_and_emits_round_trip() {
        for (text, c) in [
            ("M1000", RecoveryCommand::Resume),
            ("M1000 C", RecoveryCommand::Discard),
        ] {
            let got = parse_line(text.as_bytes()).unwrap().command;
            assert_eq!(got, Some(Command::Recovery(c)), "{text}");
            assert_eq!(format!("{}", Command::Recovery(c)), text);
        }
        assert!(parse_line(b"M1000 S").is_err());
        assert!(parse_line(b"M1000 X1").is_err());
    }
}
