//! What a complete line is: its line number and checksum checked, then sorted into a command
//! for the FIFO, a realtime request, M110, too long, or a refusal that asks for a resend.

use super::assemble::{trim, Assembled};
use super::{realtime_of, ReceivedLine};
use crate::gcode::ReportCommand;
use crate::gcode::{self, Command};
use crate::motion::Realtime;
use heapless::Vec;

/// The answer to a line longer than [`LINE_CAP`] that is not display text.
pub(super) const TOO_LONG: &str = "Line too long (max 128 bytes), ignored";

/// What a complete line is, decided without changing any state.
pub(super) enum Verdict {
    /// Refused with `Resend: L+1`: the line looked numbered or carried a checksum, and did not
    /// check out.
    Resend(&'static str),
    /// M110: the new last line number, if one was given.
    SetLineNumber(Option<u32>),
    /// A realtime request (line number, request).
    Realtime(Option<u32>, Realtime),
    /// A command line for the FIFO.
    Command(ReceivedLine),
    /// A checked line longer than [`LINE_CAP`] that is not display text: ignored, `echo:`.
    TooLong(Option<u32>),
}

pub(super) fn classify(a: &Assembled<'_>) -> Verdict {
    let (number, rest) = split_number(a.raw);
    let number = match number {
        Some(Ok(n)) => Some(n),
        Some(Err(())) => return Verdict::Resend("Bad line number"),
        None => None,
    };
    match (number, a.checksum) {
        (Some(_), None) => return Verdict::Resend("No Checksum with line number"),
        // Hosts send a checksum only with a line number: a checksum without one is a numbered
        // line whose `N` was corrupted, or the tail of a line broken in two by a corrupted
        // line end. Either way the host must send L+1 again.
        (None, Some(_)) => return Verdict::Resend("No Line Number with checksum"),
        // A wrong checksum means a corrupted line, whatever happened to its `N` (a corrupted
        // `N` makes the line look unnumbered: it is resent all the same).
        (_, Some(_)) if !a.sum_ok => return Verdict::Resend("checksum mismatch"),
        // Two lines merged by a lost line end (`N19 M400*31` + its own resend): the XOR of the
        // repeated text cancels and the sum of the merge can be right. A checksum followed by
        // the start of a numbered line is refused, so the host resends instead of the line
        // being lost; a `*` in comment text is not (the checksum is the last `*`'s, as
        // Marlin's).
        (_, Some(_)) if a.merged => return Verdict::Resend("checksum mismatch"),
        _ => {}
    }
    let text = trim(rest);
    // Commands the link handles itself: M110 and the realtime requests.
    let command = if a.cut || matches!(text.first(), Some(b'M' | b'm')) {
        gcode::parse_line(text).ok().and_then(|l| l.command)
    } else {
        None
    };
    if a.cut {
        // Only display text may be cut (M117/M118, unknown commands that are only echoed);
        // anything else cut short could do the wrong thing.
        if !matches!(
            command,
            Some(
                Command::Report(ReportCommand::Message(_))
                    | Command::Report(ReportCommand::Echo(_))
                    | Command::Unknown(_)
            )
        ) {
            return Verdict::TooLong(number);
        }
    }
    match command {
        Some(Command::Report(ReportCommand::SetLineNumber(m))) => {
            return Verdict::SetLineNumber(m.or(number))
        }
        Some(ref c) => {
            if let Some(rt) = realtime_of(c) {
                return Verdict::Realtime(number, rt);
            }
        }
        None => {}
    }
    let mut t = Vec::new();
    // Part of a line of at most LINE_CAP bytes, so it fits.
    let _ = t.extend_from_slice(text);
    Verdict::Command(ReceivedLine {
        text: t,
        number,
        after_reset: false,
    })
}

/// Split a leading `N<digits>`: (number or error, rest). `None` when the line has no number.
pub(super) fn split_number(raw: &[u8]) -> (Option<Result<u32, ()>>, &[u8]) {
    // `N-1` (printcore's `N-1 M110` at connect, accepted by Marlin): the line before 0, kept as
    // u32::MAX so that `last_line + 1` wraps to 0. Any other negative number is refused.
    if let (Some(b'N' | b'n'), Some(b'-'), Some(b'1')) = (raw.first(), raw.get(1), raw.get(2)) {
        if !raw.get(3).is_some_and(u8::is_ascii_digit) {
            return (Some(Ok(u32::MAX)), raw.get(3..).unwrap_or(&[]));
        }
    }
    match (raw.first(), raw.get(1)) {
        (Some(b'N' | b'n'), Some(d)) if d.is_ascii_digit() => {}
        _ => return (None, raw),
    }
    let mut n: u64 = 0;
    let mut i = 1;
    while let Some(d) = raw.get(i).filter(|d| d.is_ascii_digit()) {
        n = n * 10 + u64::from(d - b'0');
        if n > u64::from(u32::MAX) {
            return (Some(Err(())), &[]);
        }
        i += 1;
    }
    (Some(Ok(n as u32)), raw.get(i..).unwrap_or(&[]))
}
