//! The emitter: [`Command`] → G-code text, symmetrical with the parser.
//!
//! Numbers are written with Rust's shortest round-trip decimal (`{}` of `f32`), which the parser
//! reads back to the same bits, so `parse_line(emit(c)) == c` for every command whose numbers are
//! in range (property-tested). Canonical spelling: upper-case letters, one space between words,
//! codes without leading zeros.

use super::{AxisFlags, AxisWords, Command, Line};
use core::fmt::{self, Write};

/// Write ` L<v>` if the value is present.
pub(super) fn opt<W: Write>(w: &mut W, letter: char, v: Option<f32>) -> fmt::Result {
    match v {
        Some(v) => write!(w, " {letter}{v}"),
        None => Ok(()),
    }
}

/// Write ` L<v>` for an integer value if present.
pub(super) fn opt_int<W: Write, T: fmt::Display>(
    w: &mut W,
    letter: char,
    v: Option<T>,
) -> fmt::Result {
    match v {
        Some(v) => write!(w, " {letter}{v}"),
        None => Ok(()),
    }
}

pub(super) fn axes<W: Write>(w: &mut W, a: &AxisWords) -> fmt::Result {
    for (letter, v) in ['X', 'Y', 'Z', 'E'].into_iter().zip(a.0) {
        opt(w, letter, v)?;
    }
    Ok(())
}

pub(super) fn flags<W: Write>(w: &mut W, f: &AxisFlags) -> fmt::Result {
    for (letter, on) in ['X', 'Y', 'Z', 'E'].into_iter().zip(f.0) {
        if on {
            write!(w, " {letter}")?;
        }
    }
    Ok(())
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_command(f, self)
    }
}

/// Write a command as one line of G-code (no line end).
pub fn write_command<W: Write>(w: &mut W, c: &Command) -> fmt::Result {
    match c {
        Command::Motion(c) => super::motion::write(w, c),
        Command::Heat(c) => super::heat::write(w, c),
        Command::Pause(c) => super::pause::write(w, c),
        Command::Settings(c) => super::settings::write(w, c),
        Command::Report(c) => super::report::write(w, c),
        Command::Driver(c) => super::driver::write(w, c),
        Command::Sd(c) => super::sd::write(w, c),
        Command::Recovery(c) => super::recovery::write(w, c),
        Command::Tool(t) => write!(w, "T{t}"),
        Command::Unknown(t) => w.write_str(t),
    }
}

pub(super) fn text<W: Write>(w: &mut W, code: &str, t: &str) -> fmt::Result {
    w.write_str(code)?;
    if !t.is_empty() {
        w.write_char(' ')?;
        w.write_str(t)?;
    }
    Ok(())
}

impl fmt::Display for Line<'_> {
    /// The command, then ` ;comment` if there is one (non-UTF-8 comment bytes are written as
    /// U+FFFD).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(c) = &self.command {
            write_command(f, c)?;
        }
        if let Some(comment) = self.comment {
            if self.command.is_some() {
                f.write_char(' ')?;
            }
            f.write_char(';')?;
            for chunk in comment.utf8_chunks() {
                f.write_str(chunk.valid())?;
                if !chunk.invalid().is_empty() {
                    f.write_char('\u{FFFD}')?;
                }
            }
        }
        Ok(())
    }
}
