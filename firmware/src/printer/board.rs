//! What a board tells the executive about itself, and the executive's answers to it: the
//! reversed-driver check's result (Marlin's `stepper_driver_backward_error`, then a halt), and
//! the board's own measurements (stack high-water mark, re-timed step events), which M115
//! reports after the capabilities.

use super::Printer;
use crate::link::Response;
use crate::motion::Realtime;
use core::fmt::Write;

/// The board's measurements of itself, for M115.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BoardStats {
    /// Deepest the main stack has been since reset, bytes (stack paint scanned).
    pub stack_used_bytes: u32,
    /// The stack's size, bytes (RAM above the statics and the overflow guard).
    pub stack_size_bytes: u32,
    /// Step events that fired late after a stall, each shifting the rest of the schedule.
    pub steps_late: u32,
    /// Step events held back to an axis's limit.
    pub steps_capped: u32,
    /// The worst lateness of a step event, µs.
    pub worst_late_us: u32,
}

/// The board's part of the executive's state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct BoardLink {
    stats: Option<BoardStats>,
}

impl BoardLink {
    pub(super) const fn new() -> Self {
        Self { stats: None }
    }
}

impl Printer {
    /// The board's latest measurements (M115 reports them).
    pub fn set_board_stats(&mut self, s: BoardStats) {
        self.board.stats = Some(s);
    }

    /// The measurements last set, if the board sets any.
    pub fn board_stats(&self) -> Option<BoardStats> {
        self.board.stats
    }

    /// After M115's capabilities: one `echo:` line with the board's measurements (nothing on
    /// a driver that sets none: the simulator, the tests).
    pub(super) fn report_board_stats(&mut self) {
        let Some(s) = self.board.stats else { return };
        let mut t: heapless::String<192> = heapless::String::new();
        let _ = write!(
            t,
            "board: stack high water {} of {} bytes; step events late after a stall {} \
             (worst {} us, re-timed), held to an axis limit {}",
            s.stack_used_bytes, s.stack_size_bytes, s.steps_late, s.worst_late_us, s.steps_capped
        );
        self.link.respond(Response::Echo(&t));
    }

    /// The board found driver modules plugged in backwards (the sockets named in `sockets`)
    /// and keeps the drivers' power off: `Error:<socket> driver is backward!` on every port
    /// for each (Marlin's `stepper_driver_backward_error`), what to do, then a halt (heaters
    /// off, nothing moves, until reset).
    pub fn drivers_backward(&mut self, sockets: &[&str]) {
        for s in sockets {
            let mut t: heapless::String<48> = heapless::String::new();
            let _ = write!(t, "{s} driver is backward!");
            self.link.notify(Response::Error(&t));
        }
        self.link.notify(Response::Echo(
            "driver power (SAFE_POWER) kept off: switch off, turn the module round (its EN pin \
             to the socket's EN mark), switch on again",
        ));
        let now = self.now_us;
        self.request(Realtime::EmergencyStop, now);
    }
}
