//! The emitter: [`Command`] → G-code text, symmetrical with the parser.
//!
//! Numbers are written with Rust's shortest round-trip decimal (`{}` of `f32`), which the parser
//! reads back to the same bits, so `parse_line(emit(c)) == c` for every command whose numbers are
//! in range (property-tested). Canonical spelling: upper-case letters, one space between words,
//! codes without leading zeros.

use super::{Command, Line};
use core::fmt::{self, Write};

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
