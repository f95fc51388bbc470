//! Lines read from a file (a job on the SD card): the host link's own [`Assembler`] cuts them,
//! so a file line is kept, cut and trimmed exactly as the same line sent by a host — command
//! text up to [`LINE_CAP`] bytes, comment text up to [`COMMENT_KEEP`] bytes (every layer
//! marker fits), longer display text cut, other over-long lines refused. What differs from a
//! host stream is only what a file cannot have: a line number (`N…`) is ignored, a checksum is
//! not checked (there is no one to ask for a resend; Marlin ignores both on its card too), and
//! M110 does nothing. Realtime commands in a file (`M25`, `M601`, `M24`, `M524`, `M108`,
//! `M112`, `M410`) are handed back as requests, as the link does. A line ends at `\n` or `\r`
//! (so CRLF files work); the last line needs no line end ([`FileLines::finish`]).
//!
//! [`COMMENT_KEEP`]: super::COMMENT_KEEP

use super::assemble::{trim, Assembler};
use super::{realtime_of, split_number, ReceivedLine, LINE_CAP};
use crate::gcode::ReportCommand;
use crate::gcode::{self, Command};
use crate::motion::Realtime;
use heapless::Vec;

/// A complete line of a file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FileLine {
    /// A command or comment line for the executive (no line number).
    Line(ReceivedLine),
    /// A realtime command (acts as the host link's would).
    Realtime(Realtime),
    /// A line longer than [`LINE_CAP`] that is not display text: skipped, with a warning.
    TooLong,
}

/// Cuts a file's bytes into [`FileLine`]s. ≈ 150 bytes. See the module documentation.
#[derive(Clone, Debug, Default)]
pub struct FileLines {
    asm: Assembler,
}

impl FileLines {
    /// Nothing assembled yet.
    pub const fn new() -> Self {
        Self {
            asm: Assembler::new(),
        }
    }

    /// Forget the line being assembled (the file was closed or seeked).
    pub fn clear(&mut self) {
        self.asm.clear();
    }

    /// Whether `b` ends a line.
    pub const fn is_line_end(b: u8) -> bool {
        b == b'\n' || b == b'\r'
    }

    /// One byte of the file. Returns the line a line end completes (`None` for a blank line
    /// or any other byte).
    pub fn push(&mut self, b: u8) -> Option<FileLine> {
        if Self::is_line_end(b) {
            self.finish()
        } else {
            self.asm.push(b);
            None
        }
    }

    /// The end of the file: the last line, if it had no line end.
    pub fn finish(&mut self) -> Option<FileLine> {
        if self.asm.is_empty() {
            self.asm.clear();
            return None;
        }
        let line = {
            let a = self.asm.line();
            let (_, rest) = split_number(a.raw);
            let text = trim(rest);
            let command = if a.cut || matches!(text.first(), Some(b'M' | b'm')) {
                gcode::parse_line(text).ok().and_then(|l| l.command)
            } else {
                None
            };
            let display = matches!(
                command,
                Some(
                    Command::Report(ReportCommand::Message(_))
                        | Command::Report(ReportCommand::Echo(_))
                        | Command::Unknown(_)
                )
            );
            match command.as_ref().and_then(realtime_of) {
                Some(rt) => Some(FileLine::Realtime(rt)),
                None if a.cut && !display => Some(FileLine::TooLong),
                None if matches!(
                    command,
                    Some(Command::Report(ReportCommand::SetLineNumber(_)))
                ) =>
                {
                    None
                }
                None => {
                    let mut t: Vec<u8, LINE_CAP> = Vec::new();
                    // At most LINE_CAP bytes were kept.
                    let _ = t.extend_from_slice(text);
                    Some(FileLine::Line(ReceivedLine::unnumbered(t)))
                }
            }
        };
        self.asm.clear();
        line
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::PauseMode;

    fn lines(bytes: &[u8]) -> std::vec::Vec<FileLine> {
        let mut f = FileLines::new();
        let mut out: std::vec::Vec<FileLine> = bytes.iter().filter_map(|&b| f.push(b)).collect();
        out.extend(f.finish());
        out
    }

    fn text(l: &FileLine) -> &[u8] {
        match l {
            FileLine::Line(l) => l.text(),
            _ => b"",
        }
    }

    #[test]
    fn crlf_blank_lines_and_a_last_line_without_newline() {
        let out = lines(b"G1 X1\r\n\r\n  ;LAYER:0\r\nN5 G1 X2*99\nG1 X3");
        let t: std::vec::Vec<&[u8]> = out.iter().map(text).collect();
        assert_eq!(t, [&b"G1 X1"[..], b";LAYER:0", b"G1 X2", b"G1 X3"]);
    }

    #[test]
    fn realtime_commands_are_requests_and_long_lines_are_refused() {
        let mut long = b"G1 X1 ".to_vec();
        long.extend(std::iter::repeat_n(b'Y', 200));
        long.push(b'\n');
        long.extend_from_slice(b"M601\nM110 N5\n");
        let mut m117 = b"M117 ".to_vec();
        m117.extend(std::iter::repeat_n(b'a', 200));
        long.extend_from_slice(&m117);
        let out = lines(&long);
        assert_eq!(out[0], FileLine::TooLong);
        assert_eq!(
            out[1],
            FileLine::Realtime(Realtime::Pause(PauseMode::Layer))
        );
        assert!(text(&out[2]).starts_with(b"M117 aaa"), "{out:?}");
        assert_eq!(out.len(), 3);
    }

    #[test]
    fn long_comments_keep_their_head() {
        let mut l = b";LAYER_CHANGE ".to_vec();
        l.extend(std::iter::repeat_n(b'x', 500));
        let out = lines(&l);
        assert!(text(&out[0]).starts_with(b";LAYER_CHANGE x"));
    }
}
