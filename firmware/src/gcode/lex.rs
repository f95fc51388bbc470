//! Lexical pieces every part of the line parser uses: blanks and `( … )` comments. Below both
//! the line parser (`parse`) and the word scanner (`words`), so neither depends on the other's
//! internals.

use super::{err, ParseError, ParseErrorKind};

/// A blank between words (space or tab).
pub(super) fn is_space(c: u8) -> bool {
    c == b' ' || c == b'\t'
}

/// A `( … )` comment starting at `i`: (content, position after `)`). A `;` before the `)`
/// leaves it unclosed.
pub(super) fn paren(code: &[u8], i: usize) -> Result<(&[u8], usize), ParseError> {
    let rest = code.get(i + 1..).unwrap_or(&[]);
    match rest.iter().position(|&c| c == b')' || c == b';') {
        Some(p) if rest.get(p) == Some(&b')') => Ok((rest.get(..p).unwrap_or(&[]), i + 2 + p)),
        _ => Err(err(ParseErrorKind::UnclosedComment, i)),
    }
}
