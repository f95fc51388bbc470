//! The host side of the executive: the two ports' links (bytes in, checked lines and realtime
//! requests out, answers back), the messages the other parts write to the hosts, the `busy:`
//! keep-alive, and the reports hosts poll or expect ([`reports`]). It owns the wire: every
//! other part writes through it, none touches a port.

mod reports;

pub(super) use reports::JobView;
use reports::Reports;
pub use reports::DEFAULT_BUSY_US;

use super::types::LINE_LEN;
use crate::link::{HostAction, HostLink, HostPorts, PortId, ReceivedLine, Response};
use crate::motion::Realtime;
use core::fmt::Write as _;
use heapless::String;

/// The host side (see the module documentation).
#[derive(Clone, Debug)]
pub(super) struct Host {
    ports: HostPorts,
    reports: Reports,
    /// When the last `busy:` keep-alive went out, µs.
    last_busy_us: u64,
}

impl Host {
    pub(super) const fn new() -> Self {
        Self {
            ports: HostPorts::new(),
            reports: Reports::new(),
            last_busy_us: 0,
        }
    }

    // ---- lines and requests in ----

    /// Bytes received on `port`; returns how many were taken (flow control: the rest stays
    /// with the driver).
    pub(super) fn receive(&mut self, port: PortId, bytes: &[u8]) -> usize {
        self.ports.receive(port, bytes)
    }

    /// The next realtime request of any port; answers go to its port until the next line.
    pub(super) fn take_realtime(&mut self) -> Option<Realtime> {
        self.ports.take_realtime()
    }

    /// Whether any port holds a realtime request (an idle poll's one compare).
    #[inline]
    pub(super) fn has_realtime(&self) -> bool {
        self.ports.has_realtime()
    }

    /// Lines that were received before the pending request and are not taken yet (a pause
    /// written in the same burst as the moves it should stop).
    pub(super) fn request_lines_ahead(&self) -> usize {
        self.ports.request_lines_ahead()
    }

    /// Whether single control bytes are requests on `port`.
    pub(super) fn set_control_bytes(&mut self, port: PortId, on: bool) {
        self.ports.set_control_bytes(port, on);
    }

    /// The next checked line of any port; its answers go to its port.
    pub(super) fn pop_line(&mut self) -> Option<ReceivedLine> {
        self.ports.pop_line()
    }

    /// Lines checked and waiting on every port.
    pub(super) fn lines_waiting(&self) -> usize {
        self.ports.lines_waiting()
    }

    /// Free output bytes of `port` (a listing answers in batches that fit).
    pub(super) fn output_free_on(&self, port: PortId) -> usize {
        self.ports.output_free_on(port)
    }

    /// Whether the port of the last line has room for a line's answers.
    pub(super) fn room_for_answers(&self) -> bool {
        self.ports.line_output_free() >= crate::link::OUT_RESERVE
    }

    /// Answers go to the port of the last line handed out again (a line that waited for room).
    pub(super) fn answer_line_port(&mut self) {
        self.ports.answer_line_port();
    }

    /// The lines handled from now on come from the SD card (their `ok` goes nowhere).
    pub(super) fn answer_file(&mut self) {
        self.ports.answer_file();
    }

    /// The port answers go to now.
    pub(super) fn reply_port(&self) -> PortId {
        self.ports.reply_port()
    }

    /// One port's link, read-only.
    pub(super) fn port(&self, port: PortId) -> &HostLink {
        self.ports.port(port)
    }

    /// The host on `port` went away: its link starts afresh.
    pub(super) fn reset_port(&mut self, port: PortId) {
        self.ports.reset_port(port);
    }

    /// Marlin's `kill()`: an error to every port, then no answer to anything until reset.
    pub(super) fn halt(&mut self) {
        self.ports
            .notify(Response::Error("Printer halted. kill() called!"));
        self.ports.halt();
    }

    // ---- answers out ----

    /// Answer the port that asked.
    pub(super) fn respond(&mut self, r: Response<'_>) {
        self.ports.respond(r);
    }

    /// Answer `port` (a deferred answer).
    pub(super) fn respond_on(&mut self, port: PortId, r: Response<'_>) {
        self.ports.respond_on(port, r);
    }

    /// A line to every port.
    pub(super) fn notify(&mut self, r: Response<'_>) {
        self.ports.notify(r);
    }

    /// `ok` to the port that asked.
    pub(super) fn ok(&mut self) {
        self.ports.respond(Response::Ok);
    }

    /// An `echo:` line to the port that asked.
    pub(super) fn say(&mut self, args: core::fmt::Arguments) {
        let t = text(args);
        self.ports.respond(Response::Echo(&t));
    }

    /// An `echo:` line to every port (a notification, not an answer: pause state changes).
    pub(super) fn notice(&mut self, args: core::fmt::Arguments) {
        let t = text(args);
        self.ports.notify(Response::Echo(&t));
    }

    /// An `Error:` line to the port that asked (a fault of its command: G28's switch not
    /// reached).
    pub(super) fn error_here(&mut self, args: core::fmt::Arguments) {
        let t = text(args);
        self.ports.respond(Response::Error(&t));
    }

    /// An `Error:` line to every port (a real fault).
    pub(super) fn error(&mut self, args: core::fmt::Arguments) {
        let t = text(args);
        self.ports.notify(Response::Error(&t));
    }

    /// A refused line: `echo:refused: <why>`, never `Error:` (OctoPrint cancels the print on
    /// any `Error:` that is not about line numbers or checksums). See the response table in
    /// docs/frontend.md.
    pub(super) fn warn(&mut self, args: core::fmt::Arguments) {
        let mut t: String<LINE_LEN> = String::new();
        let _ = t.write_str("refused: ");
        let _ = t.write_fmt(args);
        self.ports.respond(Response::Echo(&t));
    }

    /// Words of a command that reads none, taken as Marlin takes them:
    /// `echo:ignored P: not used by this command` (not `refused:`: the line is executed).
    pub(super) fn note_ignored(&mut self, letters: u32) {
        let mut t: String<LINE_LEN> = String::new();
        let _ = t.write_str("ignored");
        for (n, c) in (b'A'..=b'Z').enumerate() {
            if letters & (1 << n) != 0 {
                let _ = t.write_char(' ');
                let _ = t.write_char(char::from(c));
            }
        }
        let _ = t.write_str(": not used by this command");
        self.ports.respond(Response::Echo(&t));
    }

    /// A host action, to every port.
    pub(super) fn action(&mut self, a: HostAction) {
        self.ports.notify(Response::Action(a, ""));
    }

    /// A `busy:` keep-alive at most every M113 period while a host line waits for its `ok`
    /// (heater wait, M400, a full queue during a pause), so the host does not time out:
    /// `busy: paused for user` while parked (Marlin's wording when it waits for the user),
    /// `busy: processing` otherwise.
    pub(super) fn keep_alive(&mut self, now_us: u64, parked: bool) {
        let period = self.reports.busy_us();
        if period > 0 && now_us.saturating_sub(self.last_busy_us) >= period {
            self.last_busy_us = now_us;
            self.ports.respond(if parked {
                Response::BusyPaused
            } else {
                Response::Busy
            });
        }
    }

    // ---- the driver's side ----

    /// Write every pending line of `port` to `w`.
    pub(super) fn write_output<W: core::fmt::Write>(
        &mut self,
        port: PortId,
        w: &mut W,
    ) -> core::fmt::Result {
        self.ports.write_output(port, w)
    }

    /// Copy pending output bytes of `port` into `buf`; returns how many.
    pub(super) fn read_output(&mut self, port: PortId, buf: &mut [u8]) -> usize {
        self.ports.read_output(port, buf)
    }
}

/// A message line from format arguments (cut at [`LINE_LEN`]).
fn text(args: core::fmt::Arguments) -> String<LINE_LEN> {
    let mut t: String<LINE_LEN> = String::new();
    let _ = t.write_fmt(args);
    t
}
