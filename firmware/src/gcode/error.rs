//! Why a line did not parse: the kind of syntax error, where, and its static message.

use core::fmt;

/// What went wrong in a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParseErrorKind {
    /// A letter that needs a number has none (`G1 X`, `G1 Xnan`, `G1 Xinf`).
    MissingNumber,
    /// A number with more than [`MAX_SIG_DIGITS`](super::MAX_SIG_DIGITS) significant digits.
    TooManyDigits,
    /// A number longer than [`MAX_NUMBER_LEN`](super::MAX_NUMBER_LEN) characters.
    NumberTooLong,
    /// A number beyond ±[`MAX_ABS_VALUE`](super::MAX_ABS_VALUE), a non-zero number smaller than [`MIN_ABS_VALUE`](super::MIN_ABS_VALUE), or
    /// beyond its parameter's range.
    OutOfRange,
    /// A number where only a whole number makes sense has a fraction.
    NotWhole,
    /// A negative number where only non-negative ones make sense.
    Negative,
    /// Malformed number text.
    BadNumber,
    /// A parameter letter the command does not take.
    UnexpectedLetter,
    /// The same parameter letter twice.
    DuplicateLetter,
    /// A byte that is not part of G-code (control characters, punctuation, non-ASCII outside
    /// comments and text).
    BadByte,
    /// The line does not start with a G, M or T command.
    NoCommand,
    /// A command code beyond 65535 or a malformed subcode.
    BadCode,
    /// A `(` comment without `)`.
    UnclosedComment,
    /// Text longer than [`TEXT_CAP`](super::TEXT_CAP) (no longer produced: display text is cut instead).
    TextTooLong,
    /// Text that is not valid UTF-8 or has control characters.
    BadText,
    /// A parameter value is not valid for this command (e.g. `M761` with two schedules).
    BadValue,
    /// An extended command parameter that is not `KEY=value`.
    BadExtendedParam,
}

impl ParseErrorKind {
    /// A short, static, human-readable description.
    pub const fn message(self) -> &'static str {
        match self {
            Self::MissingNumber => "letter without a number",
            Self::TooManyDigits => "number has too many digits",
            Self::NumberTooLong => "number is too long",
            Self::OutOfRange => "number out of range",
            Self::NotWhole => "expected a whole number",
            Self::Negative => "expected a non-negative number",
            Self::BadNumber => "malformed number",
            Self::UnexpectedLetter => "parameter not accepted by this command",
            Self::DuplicateLetter => "parameter given twice",
            Self::BadByte => "unexpected character",
            Self::NoCommand => "line does not start with a G, M or T command",
            Self::BadCode => "malformed command code",
            Self::UnclosedComment => "unclosed ( comment",
            Self::TextTooLong => "text too long",
            Self::BadText => "text has invalid characters",
            Self::BadValue => "invalid parameter value",
            Self::BadExtendedParam => "malformed KEY=value parameter",
        }
    }
}

/// A syntax error in a line: what and where.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// What went wrong.
    pub kind: ParseErrorKind,
    /// Byte offset in the line where it was found.
    pub at: usize,
}

impl ParseError {
    /// The static message of the error kind.
    pub const fn message(&self) -> &'static str {
        self.kind.message()
    }
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (column {})", self.kind.message(), self.at + 1)
    }
}

pub(super) const fn err(kind: ParseErrorKind, at: usize) -> ParseError {
    ParseError { kind, at }
}
