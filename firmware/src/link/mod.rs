//! The host link: bytes from the serial port in, complete checked lines and realtime requests
//! out, responses back to the host. Speaks what Pronterface/printcore, OctoPrint and
//! Repetier-Host speak to Marlin. One [`HostLink`] per port; [`HostPorts`] puts the USB port
//! and the TFT's UART in front of one executive.
//!
//! # Flow
//! 1. The driver calls [`HostLink::receive`] with received bytes; it takes what it has room
//!    for and returns how many it took — the driver keeps the rest and offers it again later
//!    (**flow control, never refusal**: the bytes stay in the pty, the USB endpoint NAKs).
//!    Realtime requests are picked out of every byte taken, ahead of everything queued
//!    ([`HostLink::take_realtime`]).
//! 2. Other lines are checked (line number, checksum) and wait in a small FIFO of
//!    [`LINE_QUEUE`] lines. The executive takes one with [`HostLink::pop_line`] **only when its
//!    command queue has room**, handles it, and answers `ok` with
//!    [`HostLink::respond`]`(`[`Response::Ok`]`)` (or the `ok T:…` of M105). When the FIFO is
//!    full, the link stops before the next command line's end; so no line is ever dropped and
//!    every line is answered.
//! 3. The driver sends what [`HostLink::write_output`] / [`HostLink::read_output`] give.
//!
//! The rule that keeps realtime requests reachable: a host that waits for `ok` (or keeps its
//! own window of lines in flight) never has more than its window outstanding, so its resume
//! and cancel lines are always within the bytes the link takes. Marlin's emergency parser works
//! the same way on its receive ring.
//!
//! # Lines
//! A line ends at `\n` or `\r`; empty lines are ignored (no `ok`, as in Marlin). Command text
//! is kept up to [`LINE_CAP`] bytes; comment text (after `;`) up to [`COMMENT_KEEP`] bytes and
//! the rest of a comment is dropped as it arrives, never an error (the checksum is still
//! computed over every byte). A line whose command text is longer than [`LINE_CAP`] is passed
//! on cut if it is display text (`M117`, `M118`, unknown commands that are only echoed, such
//! as Klipper's `EXCLUDE_OBJECT_DEFINE`), otherwise ignored with
//! `echo:Line too long (max 128 bytes), ignored` and `ok` — never an `Error:`, which would
//! end an OctoPrint print. Comment-only lines are passed on and acknowledged (they may carry
//! layer markers); unlike Marlin, which drops them silently. Hosts normally strip comments.
//!
//! # Line numbers and checksums (Marlin behaviour)
//! `N<n> <command>*<checksum>`, checksum = XOR of every byte before `*`. With `L` the last line
//! number accepted:
//! - `n == L+1`, checksum right: accepted, `L = n`;
//! - bad checksum, or `N` without `*`: `Error:checksum mismatch, Last Line: L` (or
//!   `Error:No Checksum with line number, Last Line: L`), `Resend: L+1`, `ok`;
//! - a checksum without `N` (`Error:No Line Number with checksum`) asks for `L+1` again too:
//!   hosts send checksums only with line numbers, so it is a numbered line whose `N` was
//!   corrupted or the tail of a line broken by a corrupted line end; dropping it would lose
//!   the line silently (Marlin would even run it);
//! - `n > L+1` (a line was lost), or `n` far behind: `Error:Line Number is not Last Line
//!   Number+1, Last Line: L`, `Resend: L+1`, `ok`;
//! - `L-`[`DUPLICATE_WINDOW`]` < n <= L` (a line resent after a resend request we had already
//!   accepted): ignored and acknowledged with `ok`;
//! - `M110 N<m>` sets `L = m` (or `N<n> M110` sets `L = n`) and is answered `ok` at once.
//!
//! Lines without `N` and without a checksum are accepted as they come (a terminal).
//!
//! # Realtime requests
//! Parsed out of the byte stream when their line ends, even when the line FIFO is full: `M108`
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
//! `M112` (line or control byte) halts the link as Marlin's `kill()` does: no `ok`, and from
//! then on every byte is taken and ignored, unanswered; the executive reports
//! `Error:Printer halted. kill() called!` on every port.
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
//! [`OUT_RESERVE`] bytes are free, so answering it can never overflow the ring; the link takes
//! a line end only while [`LINK_RESERVE`] bytes are free for its own answers.
//!
//! ```
//! use firmware::link::{HostLink, Response};
//! use firmware::motion::{PauseMode, Realtime};
//! let mut link = HostLink::new();
//! assert_eq!(link.receive(b"N1 G1 X10*"), 10);
//! assert_eq!(link.receive(b"80\nM25\n"), 7);
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

mod assemble;
// Lines read from a file (the SD card), by the same assembler rules.
mod file;
mod ports;
mod response;

pub use file::{FileLine, FileLines};
pub use ports::{HostPorts, PortId, PORTS};

pub use response::{
    HostAction, PositionReport, Response, TempReport, CAPABILITIES, FIRMWARE_NAME,
    FIRMWARE_VERSION, PROTOCOL_VERSION,
};

use crate::gcode::{self, Command};
use crate::motion::{PauseMode, Realtime};
use assemble::{trim, Assembled, Assembler};
use core::fmt::{self, Write};
use heapless::{Deque, Vec};

/// Longest command text kept per line, bytes, line number, comment head and checksum included,
/// line end excluded (longer lines: see the module documentation).
pub const LINE_CAP: usize = 128;
/// Checked lines waiting for the executive. A host that waits for `ok` before each line (every
/// common host) never has more than one; beyond this many the link stops taking bytes.
pub const LINE_QUEUE: usize = 4;
/// Realtime requests waiting for the executive (an emergency stop is latched separately);
/// beyond this many the link stops taking bytes.
pub const REALTIME_QUEUE: usize = 8;
/// Comment text kept per line, bytes after the `;` (every layer marker is shorter); the rest
/// of a comment is dropped as it arrives, never an error.
pub const COMMENT_KEEP: usize = 64;
/// Free output bytes the link needs before it takes a line end: room for its own answers
/// (`Error:…`, `Resend:`, `ok`, about 100 bytes at most).
pub const LINK_RESERVE: usize = 160;
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
    /// A line without a line number (a line read from a file).
    pub(super) fn unnumbered(text: Vec<u8, LINE_CAP>) -> Self {
        Self { text, number: None }
    }

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
    /// Lines refused (checksum, line number, too long).
    pub rejected: u32,
    /// Duplicate lines ignored.
    pub duplicates: u32,
    /// Responses dropped because the output ring was full (the driver did not drain it).
    pub output_dropped: u32,
}

/// The host link state of one port. See the module documentation.
#[derive(Clone, Debug)]
pub struct HostLink {
    asm: Assembler,
    last_line: u32,
    lines: Deque<ReceivedLine, LINE_QUEUE>,
    realtime: Deque<Realtime, REALTIME_QUEUE>,
    estop: bool,
    /// An emergency stop was received or [`HostLink::halt`] called: input is swallowed unanswered.
    halted: bool,
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
            asm: Assembler::new(),
            last_line: 0,
            lines: Deque::new(),
            realtime: Deque::new(),
            estop: false,
            halted: false,
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

    /// Feed received bytes (any amount, any split). Takes only what it has room for and returns
    /// how many bytes it took, from the front: the caller keeps the rest and offers them again
    /// later (flow control — the bytes stay in the pty or the USB endpoint NAKs). It stops
    /// before a line end when the line FIFO is full, before a control byte or realtime line
    /// when the realtime queue is full, and before any line end while fewer than
    /// [`LINK_RESERVE`] output bytes are free. Realtime requests and control bytes are seen for
    /// every byte taken. After an emergency stop every byte is taken and ignored, unanswered.
    /// Never blocks, never panics.
    #[must_use = "bytes not taken must be offered again later (flow control)"]
    pub fn receive(&mut self, bytes: &[u8]) -> usize {
        for (i, &b) in bytes.iter().enumerate() {
            if self.halted {
                return bytes.len();
            }
            if let Some(rt) = control_byte(b) {
                if rt != Realtime::EmergencyStop && self.realtime.is_full() {
                    return i;
                }
                self.push_realtime(rt);
            } else if b == b'\n' || b == b'\r' {
                if !self.end_line() {
                    return i;
                }
            } else {
                self.asm.push(b);
            }
        }
        bytes.len()
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
    /// answer (drain it with [`HostLink::write_output`]), or once halted.
    pub fn pop_line(&mut self) -> Option<ReceivedLine> {
        if self.halted || self.output_free() < OUT_RESERVE {
            return None;
        }
        self.lines.pop_front()
    }

    /// Number of checked lines waiting for the executive.
    pub fn lines_waiting(&self) -> usize {
        self.lines.len()
    }

    /// Stop for good (emergency stop): from now on every received byte is taken and ignored
    /// without an answer, and no waiting line is handed out — as Marlin's `kill()`, which
    /// answers nothing until reset. Output already queued is still sent.
    pub fn halt(&mut self) {
        self.halted = true;
    }

    /// Whether [`HostLink::halt`] was called or an emergency stop received.
    pub fn is_halted(&self) -> bool {
        self.halted
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
            self.halted = true;
        } else {
            // The callers checked for room.
            let _ = self.realtime.push_back(rt);
        }
    }

    /// Refuse a line and ask for `L+1` again (Marlin: error, `Resend:`, `ok`).
    fn resend(&mut self, msg: &str) {
        self.stats.rejected = self.stats.rejected.saturating_add(1);
        self.respond(Response::LineError(msg, self.last_line));
        self.stats.resends = self.stats.resends.saturating_add(1);
        self.respond(Response::Resend(self.last_line.wrapping_add(1)));
        self.respond(Response::Ok);
    }

    /// A line end arrived: check and route the line. Returns false, leaving everything as it
    /// was, when there is no room for what the line needs (the line end is then not taken).
    fn end_line(&mut self) -> bool {
        if self.asm.is_empty() {
            // Blank: ignored, no `ok` (Marlin).
            self.asm.clear();
            return true;
        }
        if self.output_free() < LINK_RESERVE {
            return false;
        }
        let verdict = classify(&self.asm.line());
        match &verdict {
            Verdict::Command(line) if self.lines.is_full() && self.takes_slot(line.number) => {
                return false;
            }
            Verdict::Realtime(_, rt)
                if *rt != Realtime::EmergencyStop && self.realtime.is_full() =>
            {
                return false;
            }
            _ => {}
        }
        self.asm.clear();
        match verdict {
            Verdict::Resend(msg) => self.resend(msg),
            Verdict::SetLineNumber(l) => {
                if let Some(l) = l {
                    self.last_line = l;
                }
                self.early = None;
                self.respond(Response::Ok);
            }
            Verdict::Realtime(number, rt) => self.realtime_line(number, rt),
            Verdict::Command(line) => self.command_line(line),
            Verdict::TooLong(number) => {
                if self.number_ok(number) {
                    self.stats.rejected = self.stats.rejected.saturating_add(1);
                    self.respond(Response::Echo(TOO_LONG));
                    self.respond(Response::Ok);
                }
            }
        }
        true
    }

    /// Whether a command line with this number would go into the FIFO.
    fn takes_slot(&self, number: Option<u32>) -> bool {
        number.is_none_or(|n| matches!(self.seq(n), Seq::Next))
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

    /// Line-number bookkeeping for a line that is not realtime: true (and `L` advanced) when
    /// the line is to be handled; a duplicate is acknowledged, a gap asks for a resend.
    fn number_ok(&mut self, number: Option<u32>) -> bool {
        let Some(n) = number else {
            return true;
        };
        match self.seq(n) {
            Seq::Next => {
                self.last_line = n;
                true
            }
            Seq::Duplicate => {
                self.stats.duplicates = self.stats.duplicates.saturating_add(1);
                self.respond(Response::Ok);
                false
            }
            Seq::Gap => {
                self.resend("Line Number is not Last Line Number+1");
                false
            }
        }
    }

    fn realtime_line(&mut self, number: Option<u32>, rt: Realtime) {
        // M112 halts: like Marlin's kill(), no `ok`.
        let answer = rt != Realtime::EmergencyStop;
        let Some(n) = number else {
            self.push_realtime(rt);
            if answer {
                self.respond(Response::Ok);
            }
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
                if answer {
                    self.respond(Response::Ok);
                }
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
                if answer {
                    self.resend("Line Number is not Last Line Number+1");
                }
            }
        }
    }

    /// A checked command line for the FIFO (room was checked).
    fn command_line(&mut self, line: ReceivedLine) {
        if !self.number_ok(line.number) {
            return;
        }
        if self.lines.push_back(line).is_ok() {
            self.stats.lines = self.stats.lines.saturating_add(1);
        }
    }
}

/// The answer to a line longer than [`LINE_CAP`] that is not display text.
const TOO_LONG: &str = "Line too long (max 128 bytes), ignored";

/// What a complete line is, decided without changing any state.
enum Verdict {
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

fn classify(a: &Assembled<'_>) -> Verdict {
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
        // repeated text cancels and the sum of the merge can be right. A checksum-like
        // `*<digit>` inside the text is refused as Marlin does (it checks up to the first
        // `*`), so the host resends instead of the line being lost.
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
            Some(Command::Message(_) | Command::Echo(_) | Command::Unknown(_))
        ) {
            return Verdict::TooLong(number);
        }
    }
    match command {
        Some(Command::SetLineNumber(m)) => return Verdict::SetLineNumber(m.or(number)),
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
    Verdict::Command(ReceivedLine { text: t, number })
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
