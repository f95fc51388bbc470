//! G-code: a streaming, allocation-free parser of one line into a typed [`Command`], and the
//! symmetrical emitter ([`Command`] implements [`core::fmt::Display`]).
//!
//! One line in, one [`Line`] out: the command (if any) and the comment text (if any), which
//! [`crate::layer`] reads for slicer layer markers. Line numbers (`N…`) and checksums (`*…`) are
//! the host link's business ([`crate::link`]) and are stripped before a line reaches this parser.
//!
//! Grammar (case-insensitive letters, spaces between words optional):
//! - a command word: `G`, `M` or `T` with a whole number (`G1`, `G01`, `M104`, `T0`; a subcode
//!   such as `M862.3` makes an [`Command::Unknown`]), or a Klipper-style extended command name
//!   (`SET_PRINT_STATS_INFO CURRENT_LAYER=3`; any other name is [`Command::Unknown`]);
//! - parameter words: a letter and a decimal number (`X-1.5`, `E.03321`, `F7800`), an exponent
//!   part of the number as C's `strtof` reads it (`X1e-05` is X = 0.00001, never X1 and an
//!   `E-05` word), magnitude at most [`MAX_ABS_VALUE`] and, unless zero, at least
//!   [`MIN_ABS_VALUE`] (beyond: refused, never cut); some letters are flags that may stand alone
//!   (`G28 X Y`);
//! - comments: `;` to the end of the line, and `( … )` anywhere between words;
//! - text commands (M117, M118): the rest of the line up to `;`, cut to [`TEXT_CAP`] bytes.
//!
//! Every G/M code without a meaning here parses to [`Command::Unknown`] (the executive answers
//! `echo:Unknown command`, like Marlin). Syntax errors — a letter without a number where one is
//! required, a letter the command does not take, the same letter twice, `nan`, `inf`, numbers
//! out of range, bytes that are not G-code — are a [`ParseError`] with a static message.
//!
//! ```
//! use firmware::gcode::{parse_line, Command, MotionCommand};
//! let line = parse_line(b"G1 X10.5 Y-3 E.25 F1800 ; perimeter").unwrap();
//! let Some(Command::Motion(MotionCommand::Move { rapid: false, axes, feed })) = line.command
//! else {
//!     panic!()
//! };
//! assert_eq!(axes.0, [Some(10.5), Some(-3.0), None, Some(0.25)]);
//! assert_eq!(feed, Some(1800.0));
//! assert_eq!(line.comment, Some(&b" perimeter"[..]));
//! // The emitter writes what the parser reads.
//! assert_eq!(
//!     format!("{}", line.command.unwrap()),
//!     "G1 X10.5 Y-3 E0.25 F1800"
//! );
//! assert!(parse_line(b"G1 Xnan").is_err());
//! ```

// The typed command and the values its variants carry.
mod command;
// The known G/M/T codes: letters taken, command built.
mod decode;
// Command → G-code text.
mod emit;
mod format;
// Parse errors and their messages.
mod error;
// Blanks and `( … )` comments (below `parse` and `words`).
mod lex;
// Decimal numbers as G-code writes them.
mod number;
// One line → comment + command word + words.
mod parse;
// The parameter words of one command.
mod words;
// Settings M-codes (M92 M201 M203 M205 M206 M851 M906 M500-M503): parse and emit.
mod settings;
pub use settings::{Advanced, SettingsCommand};
// Report M-codes hosts expect (M155 M113 M31 M27): parse and emit.
mod report;
pub use report::{Progress, ReportCommand, MAX_REPORT_PERIOD_S};
// Stepper-driver M-codes (M122 M350 M569; M906 is a settings command): parse and emit.
mod driver;
pub use driver::DriverCommand;
// SD-card M-codes (M20 M21 M22 M23 M26 M27 S/C M32): parse and emit.
mod sd;
pub use sd::{SdCommand, MAX_SD_REPORT_S};
// Power-cut resume (M1000, M1000 C): parse and emit.
mod recovery;
pub use recovery::RecoveryCommand;
mod motion;
pub use motion::MotionCommand;
mod heat;
pub use heat::{HeatCommand, Heater};
mod pause;
pub use pause::{FilamentChange, PauseCommand, PauseParams, PauseSchedule};

pub use command::{AxisFlags, AxisWords, Command, Text, TEXT_CAP};
pub use emit::write_command;
use error::err;
pub use error::{ParseError, ParseErrorKind};
pub(crate) use number::decimal;
pub use number::{MAX_ABS_VALUE, MAX_NUMBER_LEN, MAX_SIG_DIGITS, MIN_ABS_VALUE};
pub use parse::{parse_line, Line};

/// Most extra circles of `G2`/`G3 P<n>` (Marlin's `ARC_P_CIRCLES` refuses n outside 0..=100
/// with `G2/G3 bad parameters`; a larger P is a parse error here, the line changes nothing).
pub const ARC_MAX_CIRCLES: u8 = 100;
use words::Words;

#[cfg(test)]
mod tests;
