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
//! - `M110 N<m>` sets `L = m` (or `N<n> M110` sets `L = n`) and is answered `ok` at once; the
//!   next line handed to the executive carries the reset ([`ReceivedLine::take_reset`]: hosts
//!   reset their numbers when a print starts, so the executive starts a job there, in order).
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
// M112/M108/M410 seen in bytes not taken yet.
mod scan;
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
pub use scan::{SCAN_LINE, SCAN_WINDOW};

use crate::gcode;
use crate::motion::Realtime;
use assemble::Assembler;
use classify::{classify, split_number, Verdict, TOO_LONG};
use heapless::{Deque, Vec};
use scan::{is_emergency, Judged, Scan};
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
    /// The host reset its line numbers (`M110`) before this line: a new job starts here.
    after_reset: bool,
}

impl ReceivedLine {
    /// A line without a line number (a line read from a file).
    pub(super) fn unnumbered(text: Vec<u8, LINE_CAP>) -> Self {
        Self {
            text,
            number: None,
            after_reset: false,
        }
    }

    /// Whether the host reset its line numbers (`M110`, which OctoPrint and printcore send
    /// when a print starts) between the previous line and this one — the executive's job
    /// start, in stream order. True once: the flag is cleared.
    pub fn take_reset(&mut self) -> bool {
        core::mem::take(&mut self.after_reset)
    }

    /// A line taken earlier and kept (the parked intake's spill file): its text and number
    /// as the host sent them, and whether the host reset its line numbers before it (see
    /// [`Self::take_reset`]). `None` when the text is longer than [`LINE_CAP`].
    pub fn kept(text: &[u8], number: Option<u32>, after_reset: bool) -> Option<Self> {
        Some(Self {
            text: Vec::from_slice(text).ok()?,
            number,
            after_reset,
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
    /// Emergency requests (M112, M108, M410, their control bytes) acted on from bytes not yet
    /// taken (the emergency scan, `link/scan.rs`).
    pub emergency_ahead: u32,
    /// Control bytes dropped as noise on a port where they are not requests
    /// ([`HostLink::set_control_bytes`]).
    pub controls_ignored: u32,
}

/// The host link state of one port. See the module documentation.
#[derive(Clone, Debug)]
pub struct HostLink {
    asm: Assembler,
    last_line: u32,
    lines: Deque<ReceivedLine, LINE_QUEUE>,
    /// Realtime requests, each with the number of lines that waited in the FIFO when it came
    /// (lines received before it: [`HostPorts::request_lines_ahead`]).
    realtime: Deque<(Realtime, u8), REALTIME_QUEUE>,
    estop: bool,
    /// An emergency stop was received or [`HostLink::halt`] called: input is swallowed unanswered.
    halted: bool,
    /// A realtime line that acted ahead of its turn: (line number, request).
    early: Option<(u32, Realtime)>,
    /// `M110` reset the line numbers: the next line put into the FIFO says so
    /// ([`ReceivedLine::take_reset`]).
    reset_pending: bool,
    out: Deque<u8, OUT_CAP>,
    stats: LinkStats,
    /// Single control bytes are requests on this port (else dropped as noise).
    control_bytes: bool,
    /// The emergency scan of bytes not taken yet.
    scan: Scan,
    /// Events (line ends, control bytes) taken so far, counted as the scan counts them.
    events: u32,
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
            reset_pending: false,
            out: Deque::new(),
            stats: LinkStats {
                lines: 0,
                realtime: 0,
                resends: 0,
                rejected: 0,
                duplicates: 0,
                output_dropped: 0,
                emergency_ahead: 0,
                controls_ignored: 0,
            },
            control_bytes: true,
            scan: Scan::new(),
            events: 0,
        }
    }

    /// Whether single control bytes (Ctrl-X, Ctrl-C, …, [`control_byte`]) are requests on this
    /// port (the default of a new link) or noise to drop (a display's UART: one stray byte on
    /// its cable must not halt the printer).
    /// Changing it restarts the emergency scan at the taken point (set it before bytes
    /// arrive).
    pub fn set_control_bytes(&mut self, on: bool) {
        if on != self.control_bytes {
            self.control_bytes = on;
            self.scan.restart(self.events, !self.asm.is_empty());
        }
    }

    /// See [`HostLink::set_control_bytes`].
    pub fn control_bytes(&self) -> bool {
        self.control_bytes
    }

    /// Feed received bytes (any amount, any split). Takes only what it has room for and returns
    /// how many bytes it took, from the front: the caller keeps the rest and offers them again
    /// later, first (flow control — the bytes stay in the pty or the USB endpoint NAKs). It
    /// stops before a line end when the line FIFO is full, before a control byte or realtime
    /// line when the realtime queue is full, and before any line end while fewer than
    /// [`LINK_RESERVE`] output bytes are free. Realtime requests and control bytes are seen for
    /// every byte taken; `M112`, `M108`, `M410` and their control bytes also in the bytes not
    /// taken, up to [`SCAN_WINDOW`] past the last one taken (the emergency scan, `scan.rs`).
    /// After an emergency stop every byte is taken and ignored, unanswered. Never blocks, never
    /// panics.
    #[must_use = "bytes not taken must be offered again later (flow control)"]
    pub fn receive(&mut self, bytes: &[u8]) -> usize {
        if self.halted {
            return bytes.len();
        }
        if self.scan.ahead > 0
            && matches!((self.scan.first, bytes.first()), (Some(f), Some(b)) if f != *b)
        {
            // Not the bytes left over last time: scan again from here.
            self.scan.restart(self.events, !self.asm.is_empty());
        }
        // bytes[..front] are scanned (the scan may have seen more than is offered now).
        let mut front = usize::from(self.scan.ahead);
        let mut taken = bytes.len();
        for (i, &b) in bytes.iter().enumerate() {
            if i >= front {
                if !self.scan_byte(b) {
                    taken = i;
                    break;
                }
                front = i + 1;
            }
            if !self.take_byte(b) {
                taken = i;
                break;
            }
        }
        if self.halted {
            // M112 (or Ctrl-X): as Marlin's kill(), everything is taken and ignored.
            return bytes.len();
        }
        // Read on through what is not taken: the emergency scan.
        let limit = bytes.len().min(taken.saturating_add(SCAN_WINDOW));
        while front < limit {
            let Some(&b) = bytes.get(front) else { break };
            if !self.scan_byte(b) {
                break;
            }
            front += 1;
            if self.halted {
                // An M112 ahead: as Marlin's kill(), everything is taken and ignored.
                return bytes.len();
            }
        }
        // At most SCAN_WINDOW (the read-ahead stops there, and an earlier frontier was
        // within it of a taken point no later than this one).
        self.scan.ahead = u16::try_from(front.saturating_sub(taken)).unwrap_or(u16::MAX);
        // Unknown when the offer ended at the taken point (a shorter offer than before).
        self.scan.first = bytes.get(taken).copied();
        taken
    }

    /// Take one byte (scanned already). False: no room, the byte is not taken. Once halted
    /// every byte is taken and ignored.
    fn take_byte(&mut self, b: u8) -> bool {
        if self.halted {
            return true;
        }
        if let Some(rt) = control_byte(b) {
            if !self.control_bytes {
                self.stats.controls_ignored = self.stats.controls_ignored.saturating_add(1);
                return true;
            }
            if self.scan.take_decided(self.events) {
                // The scan acted on it already.
            } else {
                if rt != Realtime::EmergencyStop && self.realtime.is_full() {
                    return false;
                }
                self.push_realtime(rt);
            }
            self.events = self.events.wrapping_add(1);
        } else if b == b'\n' || b == b'\r' {
            if !self.end_line() {
                return false;
            }
            self.events = self.events.wrapping_add(1);
        } else {
            self.asm.push(b);
        }
        true
    }

    /// Scan one byte not taken yet (see `scan.rs`). False: the scan must wait here (no room to
    /// record or queue what it found).
    fn scan_byte(&mut self, b: u8) -> bool {
        if self.halted {
            return true;
        }
        if let Some(rt) = control_byte(b) {
            if !self.control_bytes {
                return true;
            }
            if is_emergency(rt) {
                if !self.scan.has_room()
                    || (rt != Realtime::EmergencyStop && self.realtime.is_full())
                {
                    return false;
                }
                self.scan.decide(self.scan.events);
                self.act_ahead(rt);
            }
            self.scan.end_control();
        } else if b == b'\n' || b == b'\r' {
            if let Some(judged) = self.scan.judge_line() {
                let act = match judged {
                    Judged::Act(rt, _) => Some(rt),
                    Judged::Again => None,
                };
                if !self.scan.has_room()
                    || act
                        .is_some_and(|rt| rt != Realtime::EmergencyStop && self.realtime.is_full())
                {
                    return false;
                }
                self.scan.decide(self.scan.events);
                if let Judged::Act(rt, number) = judged {
                    self.scan.acted(rt, number);
                    self.act_ahead(rt);
                }
            }
            self.scan.end_line();
        } else {
            self.scan.push(b);
        }
        true
    }

    /// An emergency request found by the scan (room was checked).
    fn act_ahead(&mut self, rt: Realtime) {
        self.stats.emergency_ahead = self.stats.emergency_ahead.saturating_add(1);
        self.push_realtime(rt);
    }

    /// The next realtime request (an emergency stop first), if any.
    pub fn take_realtime(&mut self) -> Option<Realtime> {
        self.take_request().map(|(rt, _)| rt)
    }

    /// [`HostLink::take_realtime`], and how many lines received before the request were
    /// waiting in the FIFO when it came.
    fn take_request(&mut self) -> Option<(Realtime, usize)> {
        if self.estop {
            self.estop = false;
            return Some((Realtime::EmergencyStop, self.lines.len()));
        }
        self.realtime
            .pop_front()
            .map(|(rt, ahead)| (rt, usize::from(ahead)))
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
            // LINE_QUEUE lines at most: fits in u8.
            let ahead = u8::try_from(self.lines.len()).unwrap_or(u8::MAX);
            let _ = self.realtime.push_back((rt, ahead));
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
                if *rt != Realtime::EmergencyStop
                    && self.realtime.is_full()
                    && self.scan.decided.front() != Some(&self.events) =>
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
                self.reset_pending = true;
                self.respond(Response::Ok);
            }
            Verdict::Realtime(number, rt) => {
                // Judged by the emergency scan: it acted (or knew not to) already.
                let acted = self.scan.take_decided(self.events);
                self.realtime_line(number, rt, acted)
            }
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
mod scan_tests;
#[cfg(test)]
mod tests;
