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
mod classify;
// Lines read from a file (the SD card), by the same assembler rules.
mod file;
mod output;
mod ports;
mod realtime;
mod response;
mod sequence;

pub use file::{FileLine, FileLines};
pub use ports::{HostPorts, PortId, PORTS};
pub use realtime::{
    control_byte, realtime_of, BYTE_BREAK_WAIT, BYTE_CANCEL, BYTE_EMERGENCY_STOP, BYTE_PAUSE_LAYER,
    BYTE_PAUSE_NOW, BYTE_QUICK_STOP, BYTE_RESUME,
};

pub use response::{
    HostAction, PositionReport, Response, TempReport, CAPABILITIES, FIRMWARE_NAME,
    FIRMWARE_VERSION, PROTOCOL_VERSION,
};

use crate::gcode;
use crate::motion::Realtime;
use assemble::Assembler;
use classify::{classify, split_number, Verdict, TOO_LONG};
use heapless::{Deque, Vec};
// What the tests' `use super::*` found here before the split.
#[cfg(test)]
use crate::{gcode::Command, motion::PauseMode};

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

    /// A line taken earlier and kept (the parked intake's spill file): its text and number
    /// as the host sent them. `None` when the text is longer than [`LINE_CAP`].
    pub fn kept(text: &[u8], number: Option<u32>) -> Option<Self> {
        Some(Self {
            text: Vec::from_slice(text).ok()?,
            number,
        })
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
}

#[cfg(test)]
mod tests;
