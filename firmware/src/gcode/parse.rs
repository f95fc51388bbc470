//! The line parser: comments split off, the command word recognised (G/M/T code or a
//! Klipper-style extended command), text commands read, words handed to [`build_known`].

use super::decode::build_known;
use super::lex::{is_space, paren};
use super::words::{scan_words, Words};
use super::ReportCommand;
use super::{err, number, sd, Command, ParseError, ParseErrorKind, Text, TEXT_CAP};

/// One parsed line: a command and/or a comment.
#[derive(Clone, Debug, PartialEq)]
pub struct Line<'a> {
    /// The command, or `None` for an empty or comment-only line.
    pub command: Option<Command>,
    /// The text after `;` (without the `;`, trailing whitespace removed), or else the text of
    /// the first `( … )` comment. Raw bytes: slicers write comments in any encoding.
    pub comment: Option<&'a [u8]>,
    /// Parameter letters taken and ignored, bit `n` = letter `'A' + n`: words of a command that
    /// reads none (`M400 P100` from BambuStudio), which Marlin ignores too; the executive says so
    /// with an `echo:` line. 0 for every other line.
    pub ignored: u32,
}

/// Remove trailing spaces, tabs, CR and LF.
fn trim_end(s: &[u8]) -> &[u8] {
    let mut end = s.len();
    while end > 0 && matches!(s.get(end - 1), Some(b' ' | b'\t' | b'\r' | b'\n')) {
        end -= 1;
    }
    s.get(..end).unwrap_or(s)
}

/// Split off the `;` comment: (code part, comment text).
fn split_comment(line: &[u8]) -> (&[u8], Option<&[u8]>) {
    match line.iter().position(|&c| c == b';') {
        Some(p) => (
            line.get(..p).unwrap_or(line),
            Some(trim_end(line.get(p + 1..).unwrap_or(&[]))),
        ),
        None => (line, None),
    }
}

/// Parse one line (without line number and checksum; a trailing CR/LF is ignored).
///
/// Returns the command (if any) and the comment text. Never panics, never allocates.
pub fn parse_line(line: &[u8]) -> Result<Line<'_>, ParseError> {
    // One pass: the `;` comment is found where the words end (text commands and unknown
    // commands look for it themselves).
    let mut i = 0;
    while line.get(i).copied().is_some_and(is_space) {
        i += 1;
    }
    let mut paren_comment: Option<&[u8]> = None;
    // Leading ( comments.
    while line.get(i) == Some(&b'(') {
        let (c, next) = paren(line, i)?;
        paren_comment = paren_comment.or(Some(c));
        i = next;
        while line.get(i).copied().is_some_and(is_space) {
            i += 1;
        }
    }
    let first = match line.get(i) {
        None | Some(b'\r' | b'\n') => {
            return Ok(Line {
                command: None,
                comment: paren_comment,
                ignored: 0,
            })
        }
        Some(b';') => {
            return Ok(Line {
                command: None,
                comment: Some(trim_end(line.get(i + 1..).unwrap_or(&[]))),
                ignored: 0,
            })
        }
        Some(&c) => c,
    };
    let second = line.get(i + 1).copied().filter(|c| *c != b';');
    let upper = first.to_ascii_uppercase();
    let gmt = matches!(upper, b'G' | b'M' | b'T');
    let mut ignored = 0;
    let (command, semi) = if gmt && second.is_none_or(|c| c.is_ascii_digit() || is_space(c)) {
        parse_classic(line, i, &mut paren_comment, &mut ignored)?
    } else if (first.is_ascii_alphabetic() || first == b'_')
        && second.is_some_and(|c| c.is_ascii_alphabetic() || c == b'_')
    {
        let (code, semi) = split_comment(line);
        (parse_extended(code, i)?, semi)
    } else {
        return Err(err(ParseErrorKind::NoCommand, i));
    };
    Ok(Line {
        command: Some(command),
        comment: semi.or(paren_comment),
        ignored,
    })
}

/// Parse `G`/`M`/`T` + code and its words.
/// Returns the command and the `;` comment text.
fn parse_classic<'a>(
    line: &'a [u8],
    start: usize,
    paren_comment: &mut Option<&'a [u8]>,
    ignored: &mut u32,
) -> Result<(Command, Option<&'a [u8]>), ParseError> {
    let code = line;
    let letter = code.get(start).map_or(b'G', u8::to_ascii_uppercase);
    // The code number: digits, optional `.digits` subcode.
    let mut i = start + 1;
    let mut num: u32 = 0;
    let mut nd = 0;
    while let Some(&c) = code.get(i) {
        if !c.is_ascii_digit() {
            break;
        }
        num = num * 10 + u32::from(c - b'0');
        nd += 1;
        if num > u32::from(u16::MAX) || nd > 6 {
            return Err(err(ParseErrorKind::BadCode, start));
        }
        i += 1;
    }
    if nd == 0 {
        return Err(err(ParseErrorKind::MissingNumber, start + 1));
    }
    let mut sub = false;
    if code.get(i) == Some(&b'.') {
        i += 1;
        let s = i;
        while code.get(i).is_some_and(u8::is_ascii_digit) {
            i += 1;
        }
        if i == s || i - s > 3 {
            return Err(err(ParseErrorKind::BadCode, start));
        }
        sub = true;
    }
    // After the code: end, space, a `(`, or (for parameter words) a letter.
    let code_end = i;
    let cmd_code = (letter, num as u16);
    if !sub {
        if let (b'M', n) = cmd_code {
            if sd::is_name_code(n) {
                let (code, semi) = split_comment(line);
                let text = parse_text(code, code_end)?;
                return Ok((Command::Sd(sd::build_name(n, text, code_end)?), semi));
            }
        }
        if let (b'M', 117 | 118) = cmd_code {
            let (code, semi) = split_comment(line);
            let text = parse_text(code, code_end)?;
            let c = if num == 117 {
                Command::Report(ReportCommand::Message(text))
            } else {
                Command::Report(ReportCommand::Echo(text))
            };
            return Ok((c, semi));
        }
    }
    if sub {
        // Subcodes (`M862.3`) are never known; their arguments are free text.
        let (code, semi) = split_comment(line);
        return Ok((unknown(code, start)?, semi));
    }
    let mut words = Words::new(line);
    let semi_at = match scan_words(line, code_end, paren_comment, &mut words) {
        Ok(at) => at,
        Err(e) => {
            // Unknown commands are never executed: their arguments are kept as text.
            let (code, semi) = split_comment(line);
            return match build_known(cmd_code, &Words::new(line)) {
                None => Ok((unknown(code, start)?, semi)),
                Some(_) => Err(e),
            };
        }
    };
    let semi = semi_at.map(|p| trim_end(line.get(p + 1..).unwrap_or(&[])));
    let c = match build_known(cmd_code, &words) {
        Some(r) => {
            *ignored = words.ignored.get();
            r?
        }
        None => {
            let code = line.get(..semi_at.unwrap_or(line.len())).unwrap_or(line);
            unknown(code, start)?
        }
    };
    Ok((c, semi))
}

/// The text argument of M117/M118: after the code and one run of spaces, to the end (the `;`
/// comment is already split off), trailing whitespace removed.
fn parse_text(code: &[u8], mut i: usize) -> Result<Text, ParseError> {
    match code.get(i) {
        None => return Ok(Text::new()),
        Some(&c) if is_space(c) => {}
        Some(_) => return Err(err(ParseErrorKind::BadByte, i)),
    }
    while code.get(i).copied().is_some_and(is_space) {
        i += 1;
    }
    let raw = trim_end(code.get(i..).unwrap_or(&[]));
    to_text(raw, i)
}

/// Text that is only displayed or echoed: cut to [`TEXT_CAP`] bytes (at a character boundary)
/// rather than refused, so a long `M117` or `EXCLUDE_OBJECT_DEFINE` line never stops a job.
fn to_text(raw: &[u8], at: usize) -> Result<Text, ParseError> {
    let cut = raw.len() > TEXT_CAP;
    // Cut, then trim again: a cut inside a run of blanks must not leave them at the end (the
    // text would not read back the same from the emitter; found by fuzzing).
    let head = trim_end(raw.get(..TEXT_CAP).unwrap_or(raw));
    let s = match core::str::from_utf8(head) {
        Ok(s) => s,
        // A character cut in two at the cap: drop its first bytes.
        Err(e) if cut && e.error_len().is_none() => {
            core::str::from_utf8(trim_end(head.get(..e.valid_up_to()).unwrap_or(&[])))
                .map_err(|_| err(ParseErrorKind::BadText, at))?
        }
        Err(e) => return Err(err(ParseErrorKind::BadText, at + e.valid_up_to())),
    };
    if let Some(p) = s.chars().position(char::is_control) {
        return Err(err(ParseErrorKind::BadText, at + p));
    }
    let mut t = Text::new();
    t.push_str(s)
        .map_err(|_| err(ParseErrorKind::TextTooLong, at + TEXT_CAP))?;
    Ok(t)
}

/// The command text for [`Command::Unknown`]: from the command word to the end, trimmed.
fn unknown(code: &[u8], start: usize) -> Result<Command, ParseError> {
    let raw = trim_end(code.get(start..).unwrap_or(&[]));
    Ok(Command::Unknown(to_text(raw, start)?))
}

/// Klipper-style extended command: `NAME [KEY=value ...]`.
fn parse_extended(code: &[u8], start: usize) -> Result<Command, ParseError> {
    let mut i = start;
    while code
        .get(i)
        .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_')
    {
        i += 1;
    }
    let name = code.get(start..i).unwrap_or(&[]);
    match code.get(i) {
        None => {}
        Some(&c) if is_space(c) => {}
        Some(_) => return Err(err(ParseErrorKind::BadByte, i)),
    }
    if !name.eq_ignore_ascii_case(b"SET_PRINT_STATS_INFO") {
        // Arguments of unknown extended commands are free text (Klipper passes them on).
        return unknown(code, start);
    }
    let mut current_layer = None;
    let mut total_layer = None;
    loop {
        while code.get(i).copied().is_some_and(is_space) {
            i += 1;
        }
        if i >= code.len() {
            break;
        }
        let ks = i;
        while code
            .get(i)
            .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_')
        {
            i += 1;
        }
        let key = code.get(ks..i).unwrap_or(&[]);
        if code.get(i) != Some(&b'=') || key.is_empty() {
            return Err(err(ParseErrorKind::BadExtendedParam, ks));
        }
        i += 1;
        let vs = i;
        let Some((n, next)) = number::lex(code, i).map_err(|k| err(k, vs))? else {
            return Err(err(ParseErrorKind::MissingNumber, vs));
        };
        if code.get(next).is_some_and(|c| !is_space(*c)) {
            return Err(err(ParseErrorKind::BadByte, next));
        }
        let v = n.to_u32().map_err(|k| err(k, vs))?;
        let slot = if key.eq_ignore_ascii_case(b"CURRENT_LAYER") {
            &mut current_layer
        } else if key.eq_ignore_ascii_case(b"TOTAL_LAYER") {
            &mut total_layer
        } else {
            return Err(err(ParseErrorKind::UnexpectedLetter, ks));
        };
        if slot.is_some() {
            return Err(err(ParseErrorKind::DuplicateLetter, ks));
        }
        *slot = Some(v);
        i = next;
    }
    Ok(Command::Report(ReportCommand::PrintStatsInfo {
        current_layer,
        total_layer,
    }))
}
