//! The host link: bytes from the serial port in, complete checked lines and realtime requests
//! out, responses back to the host. Speaks what Pronterface/printcore, OctoPrint and
//! Repetier-Host speak to Marlin.
//!
//! # Flow
//! 1. The driver calls [`HostLink::receive`] with every received byte. Realtime requests are
//!    picked out at once, ahead of everything queued ([`HostLink::take_realtime`]).
//! 2. Other lines are checked (line number, checksum) and wait in a small FIFO of
//!    [`LINE_QUEUE`] lines. The executive takes one with [`HostLink::pop_line`] **only when its
//!    command queue has room**, handles it, and answers `ok` with
//!    [`HostLink::respond`]`(`[`Response::Ok`]`)` (or the `ok T:…` of M105). The host sends
//!    the next line only after an `ok`, so no line is ever dropped and every line is answered.
//! 3. The driver sends what [`HostLink::write_output`] / [`HostLink::read_output`] give.
//!
//! # Lines
//! A line ends at `\n` or `\r`; empty lines are ignored (no `ok`, as in Marlin). A line may be
//! at most [`LINE_CAP`] bytes (line number and checksum included): a longer one is rejected with
//! `Error:Line too long` — never truncated — and the link resynchronises at the next line end.
//! Comment-only lines are passed on and acknowledged (they may carry layer markers); unlike
//! Marlin, which drops them silently. Hosts normally strip comments anyway.
//!
//! # Line numbers and checksums (Marlin behaviour)
//! `N<n> <command>*<checksum>`, checksum = XOR of every byte before `*`. With `L` the last line
//! number accepted:
//! - `n == L+1`, checksum right: accepted, `L = n`;
//! - bad checksum, or `N` without `*`: `Error:checksum mismatch, Last Line: L` (or
//!   `Error:No Checksum with line number, Last Line: L`), `Resend: L+1`, `ok`;
//! - `n > L+1` (a line was lost), or `n` far behind: `Error:Line Number is not Last Line
//!   Number+1, Last Line: L`, `Resend: L+1`, `ok`;
//! - `L-`[`DUPLICATE_WINDOW`]` < n <= L` (a line resent after a resend request we had already
//!   accepted): ignored and acknowledged with `ok`;
//! - `M110 N<m>` sets `L = m` (or `N<n> M110` sets `L = n`) and is answered `ok` at once.
//!
//! Lines without `N` are accepted as they come (with a checksum, if given, checked).
//!
//! # Realtime requests
//! Parsed out of the byte stream when their line ends, even when every queue is full: `M108`
//! BreakWait, `M112` EmergencyStop, `M410` QuickStop, `M25`/`M601` Pause at the layer
//! boundary, `M25 S1`/`M601 S1` Pause now, `M24`/`M602` Resume, `M524` Cancel — with or
//! without `N…` and `*…`. A realtime line is consumed by the realtime path (it never reaches
//! the FIFO) and answered `ok` at once. Its line number: if it is `L+1` it is consumed like any
//! line (`L = n`), so the host never sees a false `Resend`; if it is ahead (`n > L+1`, a line
//! before it was lost) the request still acts at once, the usual `Resend: L+1` follows, and
//! when the host resends line `n` it is accepted without acting a second time; a duplicate
//! (`n <= L`) does not act again. A realtime line with a bad checksum does not act (it is
//! resent like any line).
//!
//! Single control bytes act the moment they arrive, anywhere in the stream (they are removed
//! from the line they interrupt and never acknowledged): see [`control_byte`] —
//! `0x18` (Ctrl-X) emergency stop, `0x19` (Ctrl-Y) quick stop, `0x10` (Ctrl-P) pause at the
//! layer boundary, `0x0E` (Ctrl-N) pause now, `0x12` (Ctrl-R) resume, `0x03` (Ctrl-C) cancel,
//! `0x02` (Ctrl-B) break a wait. None is TAB/LF/CR or XON/XOFF (0x11/0x13).
//!
//! # Output
//! Responses are formatted into a byte ring of [`OUT_CAP`] bytes (ASCII: other characters are
//! written as `?`). [`HostLink::pop_line`] hands out a line only while at least
//! [`OUT_RESERVE`] bytes are free, so answering it can never overflow the ring.
//!
//! ```
//! use firmware::link::{HostLink, Response};
//! use firmware::motion::{PauseMode, Realtime};
//! let mut link = HostLink::new();
//! link.receive(b"N1 G1 X10*");
//! link.receive(b"80\nM25\n");
//! // The pause acted at once, ahead of the queued G1, and was acknowledged.
//! assert_eq!(link.take_realtime(), Some(Realtime::Pause(PauseMode::Layer)));
//! // The executive takes the G1 when its queue has room, then acknowledges it.
//! let line = link.pop_line().unwrap();
//! assert_eq!(line.text(), b"G1 X10");
//! assert_eq!(line.number(), Some(1));
//! link.respond(Response::Ok);
//! let mut out = String::new();
//! link.write_output(&mut out).unwrap();
//! assert_eq!(out, "ok\nok\n");
//! ```

mod response;

pub use response::{
    HostAction, PositionReport, Response, TempReport, CAPABILITIES, FIRMWARE_NAME,
    FIRMWARE_VERSION, PROTOCOL_VERSION,
};

use crate::gcode::{self, Command};
use crate::motion::{PauseMode, Realtime};
use core::fmt::{self, Write};
use heapless::{Deque, Vec};

/// Longest line accepted, bytes, line number and checksum included, line end excluded.
pub const LINE_CAP: usize = 128;
/// Checked lines waiting for the executive. A host that waits for `ok` before each line (every
/// common host) never has more than one; send-ahead hosts may have up to this many in flight.
pub const LINE_QUEUE: usize = 4;
/// Realtime requests waiting for the executive (an emergency stop is never lost: it is latched
/// separately).
pub const REALTIME_QUEUE: usize = 8;
/// Output ring, bytes.
pub const OUT_CAP: usize = 4096;
/// Free output space needed before [`HostLink::pop_line`] hands out a line: the longest answer
/// (the M115 report) fits.
pub const OUT_RESERVE: usize = 1024;
/// How far behind the last line number a line may be and still count as a harmless duplicate.
pub const DUPLICATE_WINDOW: u32 = 16;

/// Control byte: emergency stop (Ctrl-X, CAN).
pub const BYTE_EMERGENCY_STOP: u8 = 0x18;
/// Control byte: quick stop (Ctrl-Y, EM).
pub const BYTE_QUICK_STOP: u8 = 0x19;
/// Control byte: pause at the layer boundary (Ctrl-P, DLE).
pub const BYTE_PAUSE_LAYER: u8 = 0x10;
/// Control byte: pause now (Ctrl-N, SO).
pub const BYTE_PAUSE_NOW: u8 = 0x0E;
/// Control byte: resume (Ctrl-R, DC2).
pub const BYTE_RESUME: u8 = 0x12;
/// Control byte: cancel the job (Ctrl-C, ETX).
pub const BYTE_CANCEL: u8 = 0x03;
/// Control byte: break out of a heater wait (Ctrl-B, STX).
pub const BYTE_BREAK_WAIT: u8 = 0x02;

/// The realtime request of a single control byte, if it is one.
pub const fn control_byte(b: u8) -> Option<Realtime> {
    match b {
        BYTE_EMERGENCY_STOP => Some(Realtime::EmergencyStop),
        BYTE_QUICK_STOP => Some(Realtime::QuickStop),
        BYTE_PAUSE_LAYER => Some(Realtime::Pause(PauseMode::Layer)),
        BYTE_PAUSE_NOW => Some(Realtime::Pause(PauseMode::Now)),
        BYTE_RESUME => Some(Realtime::Resume),
        BYTE_CANCEL => Some(Realtime::Cancel),
        BYTE_BREAK_WAIT => Some(Realtime::BreakWait),
        _ => None,
    }
}

/// The realtime request a parsed command stands for, if any (the host-link spellings).
pub fn realtime_of(cmd: &Command) -> Option<Realtime> {
    match cmd {
        Command::BreakWait => Some(Realtime::BreakWait),
        Command::EmergencyStop => Some(Realtime::EmergencyStop),
        Command::QuickStop => Some(Realtime::QuickStop),
        Command::Pause { now: false, .. } => Some(Realtime::Pause(PauseMode::Layer)),
        Command::Pause { now: true, .. } => Some(Realtime::Pause(PauseMode::Now)),
        Command::Resume { .. } => Some(Realtime::Resume),
        Command::Cancel => Some(Realtime::Cancel),
        _ => None,
    }
}

/// The XOR checksum of a line (every byte before `*`).
pub fn checksum(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0, |a, b| a ^ b)
}

/// A checked line from the host, without line number and checksum (comments kept).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReceivedLine {
    text: Vec<u8, LINE_CAP>,
    number: Option<u32>,
}

impl ReceivedLine {
    /// The command text (line number and checksum stripped, surrounding spaces trimmed).
    pub fn text(&self) -> &[u8] {
        &self.text
    }

    /// The line number the host gave it, if any.
    pub fn number(&self) -> Option<u32> {
        self.number
    }

    /// Parse the text with [`gcode::parse_line`].
    pub fn parse(&self) -> Result<gcode::Line<'_>, gcode::ParseError> {
        gcode::parse_line(&self.text)
    }
}

/// Counters, for reports and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Lines put into the FIFO for the executive.
    pub lines: u32,
    /// Realtime requests taken out of the stream (lines and control bytes).
    pub realtime: u32,
    /// `Resend` requests sent.
    pub resends: u32,
    /// Lines rejected (checksum, line number, too long, queue full).
    pub rejected: u32,
    /// Duplicate lines ignored.
    pub duplicates: u32,
    /// Responses dropped because the output ring was full (the driver did not drain it).
    pub output_dropped: u32,
}

/// The host link state. See the module documentation.
#[derive(Clone, Debug)]
pub struct HostLink {
    buf: Vec<u8, LINE_CAP>,
    overlong: bool,
    last_line: u32,
    lines: Deque<ReceivedLine, LINE_QUEUE>,
    realtime: Deque<Realtime, REALTIME_QUEUE>,
    estop: bool,
    /// A realtime line that acted ahead of its turn: (line number, request).
    early: Option<(u32, Realtime)>,
    out: Deque<u8, OUT_CAP>,
    stats: LinkStats,
}

impl Default for HostLink {
    fn default() -> Self {
        Self::new()
    }
}

/// How a line's number compares with the expected one.
enum Seq {
    Next,
    Duplicate,
    Gap,
}

impl HostLink {
    /// An idle link: no line numbers seen yet (`L = 0`), empty queues.
    pub const fn new() -> Self {
        HostLink {
            buf: Vec::new(),
            overlong: false,
            last_line: 0,
            lines: Deque::new(),
            realtime: Deque::new(),
            estop: false,
            early: None,
            out: Deque::new(),
            stats: LinkStats {
                lines: 0,
                realtime: 0,
                resends: 0,
                rejected: 0,
                duplicates: 0,
                output_dropped: 0,
            },
        }
    }

    /// Feed received bytes (any amount, any split). Never blocks, never panics.
    pub fn receive(&mut self, bytes: &[u8]) {
        let mut rest = bytes;
        let mut scan = 0;
        loop {
            // The next C0 byte: a line end, a control byte, or another control character
            // (that one stays in the line, for the parser to reject).
            let tail = rest.get(scan..).unwrap_or(&[]);
            let j = scan + first_c0(tail);
            let Some(&b) = rest.get(j) else {
                self.append(rest);
                return;
            };
            let rt = control_byte(b);
            if rt.is_none() && b != b'\n' && b != b'\r' {
                scan = j + 1;
                continue;
            }
            self.append(rest.get(..j).unwrap_or(&[]));
            match rt {
                Some(rt) => self.push_realtime(rt),
                None => self.end_line(),
            }
            rest = rest.get(j + 1..).unwrap_or(&[]);
            scan = 0;
        }
    }

    /// Add line bytes; past [`LINE_CAP`] the line is marked over-long (its head is kept).
    fn append(&mut self, text: &[u8]) {
        if !self.overlong && self.buf.extend_from_slice(text).is_err() {
            let room = LINE_CAP - self.buf.len();
            let _ = self.buf.extend_from_slice(text.get(..room).unwrap_or(&[]));
            self.overlong = true;
        }
    }

    /// The next realtime request (an emergency stop first), if any.
    pub fn take_realtime(&mut self) -> Option<Realtime> {
        if self.estop {
            self.estop = false;
            return Some(Realtime::EmergencyStop);
        }
        self.realtime.pop_front()
    }

    /// Take the oldest checked line — call only when the command queue has room for it, then
    /// answer it with `ok`. `None` when no line waits, or while the output ring is too full to
    /// answer (drain it with [`HostLink::write_output`]).
    pub fn pop_line(&mut self) -> Option<ReceivedLine> {
        if self.output_free() < OUT_RESERVE {
            return None;
        }
        self.lines.pop_front()
    }

    /// Number of checked lines waiting for the executive.
    pub fn lines_waiting(&self) -> usize {
        self.lines.len()
    }

    /// Queue one response (a line end is added). Returns false, and counts it in
    /// [`LinkStats::output_dropped`], if it does not fit the output ring: it is then dropped
    /// whole, never cut.
    pub fn respond(&mut self, r: Response<'_>) -> bool {
        let before = self.out.len();
        let written = match r {
            // The most frequent answer, without the formatting machinery.
            Response::Ok if self.output_free() >= 3 => {
                for b in *b"ok\n" {
                    let _ = self.out.push_back(b);
                }
                Ok(())
            }
            r => writeln!(Ring(&mut self.out), "{r}"),
        };
        if written.is_err() {
            // Did not fit: take back what was written, so a response is never cut.
            self.out.truncate(before);
            self.stats.output_dropped = self.stats.output_dropped.saturating_add(1);
            return false;
        }
        true
    }

    /// Bytes free in the output ring.
    pub fn output_free(&self) -> usize {
        OUT_CAP - self.out.len()
    }

    /// Bytes waiting in the output ring.
    pub fn output_len(&self) -> usize {
        self.out.len()
    }

    /// Move all pending output into `w` (each response is followed by `\n`).
    pub fn write_output<W: Write>(&mut self, w: &mut W) -> fmt::Result {
        let mut chunk = [0u8; 64];
        while !self.out.is_empty() {
            let n = self.read_output(&mut chunk);
            // The ring holds ASCII only.
            let s = core::str::from_utf8(chunk.get(..n).unwrap_or(&[])).map_err(|_| fmt::Error)?;
            w.write_str(s)?;
        }
        Ok(())
    }

    /// Move up to `buf.len()` bytes of pending output into `buf` (for a UART/DMA driver);
    /// returns the count.
    pub fn read_output(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        for slot in buf.iter_mut() {
            match self.out.pop_front() {
                Some(b) => {
                    *slot = b;
                    n += 1;
                }
                None => break,
            }
        }
        n
    }

    /// The last line number accepted (`L`).
    pub fn last_line(&self) -> u32 {
        self.last_line
    }

    /// Counters since power-on.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    fn push_realtime(&mut self, rt: Realtime) {
        self.stats.realtime = self.stats.realtime.saturating_add(1);
        if rt == Realtime::EmergencyStop {
            self.estop = true;
        } else if self.realtime.push_back(rt).is_err() {
            self.respond(Response::Error("realtime queue full, request dropped"));
        }
    }

    fn reject(&mut self, msg: &str, resend: bool) {
        self.stats.rejected = self.stats.rejected.saturating_add(1);
        if resend {
            self.respond(Response::LineError(msg, self.last_line));
            self.stats.resends = self.stats.resends.saturating_add(1);
            self.respond(Response::Resend(self.last_line.wrapping_add(1)));
        } else {
            self.respond(Response::Error(msg));
        }
        self.respond(Response::Ok);
    }

    /// A line end arrived: check and route the line in `buf`.
    fn end_line(&mut self) {
        let overlong = core::mem::replace(&mut self.overlong, false);
        match classify(&self.buf, overlong) {
            Verdict::Empty => {}
            Verdict::Reject(msg, resend) => self.reject(msg, resend),
            Verdict::SetLineNumber(l) => {
                if let Some(l) = l {
                    self.last_line = l;
                }
                self.early = None;
                self.respond(Response::Ok);
            }
            Verdict::Realtime(number, rt) => self.realtime_line(number, rt),
            Verdict::Command(number, start, end) => self.command_line(number, start, end),
        }
        self.buf.clear();
    }

    fn seq(&self, n: u32) -> Seq {
        if n == self.last_line.wrapping_add(1) {
            Seq::Next
        } else if n <= self.last_line && self.last_line - n < DUPLICATE_WINDOW {
            Seq::Duplicate
        } else {
            Seq::Gap
        }
    }

    fn realtime_line(&mut self, number: Option<u32>, rt: Realtime) {
        let Some(n) = number else {
            self.push_realtime(rt);
            self.respond(Response::Ok);
            return;
        };
        match self.seq(n) {
            Seq::Next => {
                // Acted already when it first arrived ahead of its turn?
                if self.early != Some((n, rt)) {
                    self.push_realtime(rt);
                }
                self.early = None;
                self.last_line = n;
                self.respond(Response::Ok);
            }
            Seq::Duplicate => {
                self.stats.duplicates = self.stats.duplicates.saturating_add(1);
                self.respond(Response::Ok);
            }
            Seq::Gap => {
                if self.early != Some((n, rt)) {
                    self.push_realtime(rt);
                    self.early = Some((n, rt));
                }
                self.reject("Line Number is not Last Line Number+1", true);
            }
        }
    }

    /// A checked command line: `buf[start..end]` is its text.
    fn command_line(&mut self, number: Option<u32>, start: usize, end: usize) {
        if let Some(n) = number {
            match self.seq(n) {
                Seq::Next => {}
                Seq::Duplicate => {
                    self.stats.duplicates = self.stats.duplicates.saturating_add(1);
                    self.respond(Response::Ok);
                    return;
                }
                Seq::Gap => {
                    self.reject("Line Number is not Last Line Number+1", true);
                    return;
                }
            }
        }
        let mut t = Vec::new();
        // Part of a line of at most LINE_CAP bytes, so it fits.
        let _ = t.extend_from_slice(self.buf.get(start..end).unwrap_or(&[]));
        let line = ReceivedLine { text: t, number };
        if self.lines.push_back(line).is_err() {
            self.reject("Line queue full (send one line per ok)", number.is_some());
            return;
        }
        if let Some(n) = number {
            self.last_line = n;
        }
        self.stats.lines = self.stats.lines.saturating_add(1);
    }
}

/// What a complete line is, decided without changing any state.
enum Verdict {
    /// Blank: ignored, no `ok`.
    Empty,
    /// Refused: message, and whether to ask for a resend.
    Reject(&'static str, bool),
    /// M110: the new last line number, if one was given.
    SetLineNumber(Option<u32>),
    /// A realtime request (line number, request).
    Realtime(Option<u32>, Realtime),
    /// A command line for the FIFO: line number and the text's range in the buffer.
    Command(Option<u32>, usize, usize),
}

fn classify(buf: &[u8], overlong: bool) -> Verdict {
    let raw = trim(buf);
    let (number, rest) = split_number(raw);
    if overlong {
        return Verdict::Reject("Line too long (max 128 bytes)", number.is_some());
    }
    if raw.is_empty() {
        return Verdict::Empty;
    }
    let number = match number {
        Some(Ok(n)) => Some(n),
        Some(Err(())) => return Verdict::Reject("Bad line number", false),
        None => None,
    };
    // Checksum: `*` and 1-3 digits at the end.
    let (body, cs) = split_checksum(rest);
    match (number, cs) {
        (Some(_), None) => return Verdict::Reject("No Checksum with line number", true),
        (n, Some(cs)) => {
            let star = raw.len() - rest.len() + body.len();
            if checksum(raw.get(..star).unwrap_or(&[])) != cs {
                return Verdict::Reject("checksum mismatch", n.is_some());
            }
            // Two lines merged by a lost line end (`N19 M400*31` + its own resend): the XOR of
            // the repeated text cancels and the sum of the merge can be right. A checksum-like
            // `*<digit>` inside the text is refused as Marlin does (it checks up to the first
            // `*`), so the host resends instead of the line being lost.
            if body
                .windows(2)
                .any(|w| matches!(w, [b'*', d] if d.is_ascii_digit()))
            {
                return Verdict::Reject("checksum mismatch", n.is_some());
            }
        }
        (None, None) => {}
    }
    let text = trim(body);
    // `text` is a sub-slice of `buf`: its offset, without indexing arithmetic on `buf`.
    // (An empty `text` may be a static empty slice: then offset 0.)
    let start = if text.is_empty() {
        0
    } else {
        (text.as_ptr() as usize).saturating_sub(buf.as_ptr() as usize)
    };
    // Commands the link handles itself: M110 and the realtime requests.
    if let Some(b'M' | b'm') = text.first() {
        if let Ok(gcode::Line {
            command: Some(c), ..
        }) = gcode::parse_line(text)
        {
            if let Command::SetLineNumber(m) = c {
                return Verdict::SetLineNumber(m.or(number));
            }
            if let Some(rt) = realtime_of(&c) {
                return Verdict::Realtime(number, rt);
            }
        }
    }
    Verdict::Command(number, start, start + text.len())
}

/// Index of the first byte below 0x20 (or the length), eight bytes at a time.
fn first_c0(s: &[u8]) -> usize {
    const LOW: u64 = 0x2020_2020_2020_2020;
    const HIGH: u64 = 0x8080_8080_8080_8080;
    let mut chunks = s.chunks_exact(8);
    let mut i = 0;
    for c in &mut chunks {
        let mut a = [0u8; 8];
        a.copy_from_slice(c);
        let w = u64::from_le_bytes(a);
        // Sets the high bit of every byte < 0x20 (bytes >= 0x80 are masked by !w); borrows
        // only spill upwards, so the lowest flagged byte is a true one.
        let m = w.wrapping_sub(LOW) & !w & HIGH;
        if m != 0 {
            return i + (m.trailing_zeros() / 8) as usize;
        }
        i += 8;
    }
    let r = chunks.remainder();
    i + r.iter().position(|&b| b < 0x20).unwrap_or(r.len())
}

/// Trim spaces and tabs at both ends.
fn trim(s: &[u8]) -> &[u8] {
    let start = s.iter().position(|c| !matches!(c, b' ' | b'\t'));
    let end = s.iter().rposition(|c| !matches!(c, b' ' | b'\t'));
    match (start, end) {
        (Some(a), Some(b)) => s.get(a..=b).unwrap_or(&[]),
        _ => &[],
    }
}

/// Split a leading `N<digits>`: (number or error, rest). `None` when the line has no number.
fn split_number(raw: &[u8]) -> (Option<Result<u32, ()>>, &[u8]) {
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

/// Split a trailing `*<1-3 digits>` checksum (spaces allowed after it): (body before `*`,
/// checksum). Looks at the end of the line only.
fn split_checksum(s: &[u8]) -> (&[u8], Option<u8>) {
    let t = trim(s);
    let tail_digits = t
        .iter()
        .rev()
        .take(4)
        .take_while(|c| c.is_ascii_digit())
        .count();
    if tail_digits == 0 || tail_digits > 3 {
        return (s, None);
    }
    let Some(star) = t.len().checked_sub(tail_digits + 1) else {
        return (s, None);
    };
    if t.get(star) != Some(&b'*') {
        return (s, None);
    }
    let v = t
        .get(star + 1..)
        .unwrap_or(&[])
        .iter()
        .fold(0u32, |a, d| a * 10 + u32::from(d - b'0'));
    match u8::try_from(v) {
        // `t` starts where `s` does after leading spaces.
        Ok(cs) => {
            let lead = s.len() - trim_start(s).len();
            (s.get(..lead + star).unwrap_or(&[]), Some(cs))
        }
        Err(_) => (s, None),
    }
}

fn trim_start(s: &[u8]) -> &[u8] {
    let a = s
        .iter()
        .position(|c| !matches!(c, b' ' | b'\t'))
        .unwrap_or(s.len());
    s.get(a..).unwrap_or(&[])
}

/// Writes into the output ring, ASCII only (others become `?`).
struct Ring<'a>(&'a mut Deque<u8, OUT_CAP>);

impl Write for Ring<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        if s.is_ascii() {
            for &b in s.as_bytes() {
                self.0.push_back(b).map_err(|_| fmt::Error)?;
            }
            return Ok(());
        }
        for ch in s.chars() {
            let b = if ch.is_ascii() { ch as u8 } else { b'?' };
            self.0.push_back(b).map_err(|_| fmt::Error)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
