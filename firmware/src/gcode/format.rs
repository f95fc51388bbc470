//! The words of a command's text, written the way the parser reads them back: a letter and
//! its value (`opt`, `opt_int`), the axis words (`axes`), bare axis letters (`flags`), a text
//! command's text (`text`). Each family's `write` uses them (`motion.rs`, `heat.rs`, …).

use super::{AxisFlags, AxisWords};
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

pub(super) fn text<W: Write>(w: &mut W, code: &str, t: &str) -> fmt::Result {
    w.write_str(code)?;
    if !t.is_empty() {
        w.write_char(' ')?;
        w.write_str(t)?;
    }
    Ok(())
}
