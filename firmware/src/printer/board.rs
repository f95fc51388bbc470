//! What a board tells the executive about itself, and the executive's answers to it: the
//! reversed-driver check's result (Marlin's `stepper_driver_backward_error`, then a halt), and
//! the board's own measurements (stack high-water mark, re-timed step events), which M115
//! reports after the capabilities; and what the executive asks of the board's drivers (the
//! stepper drivers' enables, M17/M18/M84, and the TMC2209s' registers, M569/M350/M906/M122),
//! queued until the board takes them.

use super::drivers::{DriverRequest, DRIVER_REQ_CAPACITY};
use super::host::Host;
use super::types::StepperRequest;
use super::Printer;
use crate::link::Response;
use crate::motion::Realtime;
use core::fmt::Write;
use heapless::Deque;

/// Stepper-driver requests kept until the board takes them.
pub const STEPPER_REQ_CAPACITY: usize = 4;

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
#[derive(Clone, Debug)]
pub(super) struct BoardLink {
    stats: Option<BoardStats>,
    stepper_reqs: Deque<StepperRequest, STEPPER_REQ_CAPACITY>,
    driver_reqs: Deque<DriverRequest, DRIVER_REQ_CAPACITY>,
}

impl BoardLink {
    pub(super) const fn new() -> Self {
        Self {
            stats: None,
            stepper_reqs: Deque::new(),
            driver_reqs: Deque::new(),
        }
    }

    /// A request for the stepper drivers (the oldest goes when the board does not take them).
    pub(super) fn push_stepper_request(&mut self, r: StepperRequest) {
        if self.stepper_reqs.is_full() {
            let _ = self.stepper_reqs.pop_front();
        }
        let _ = self.stepper_reqs.push_back(r);
    }

    /// The oldest stepper-driver request.
    pub(super) fn take_stepper_request(&mut self) -> Option<StepperRequest> {
        self.stepper_reqs.pop_front()
    }

    /// A request for the TMC2209 drivers (the oldest goes when the board does not take them).
    pub(super) fn push_driver_request(&mut self, r: DriverRequest) {
        if self.driver_reqs.is_full() {
            let _ = self.driver_reqs.pop_front();
        }
        let _ = self.driver_reqs.push_back(r);
    }

    /// The oldest TMC2209 request.
    pub(super) fn take_driver_request(&mut self) -> Option<DriverRequest> {
        self.driver_reqs.pop_front()
    }

    /// After M115's capabilities: one `echo:` line with the board's measurements (nothing on
    /// a driver that sets none: the simulator, the tests).
    pub(super) fn report_stats(&self, host: &mut Host) {
        let Some(s) = self.stats else { return };
        let mut t: heapless::String<192> = heapless::String::new();
        let _ = write!(
            t,
            "board: stack high water {} of {} bytes; step events late after a stall {} \
             (worst {} us, re-timed), held to an axis limit {}",
            s.stack_used_bytes, s.stack_size_bytes, s.steps_late, s.worst_late_us, s.steps_capped
        );
        host.respond(Response::Echo(&t));
    }
}

impl Printer {
    /// The board's latest measurements (M115 reports them).
    pub fn set_board_stats(&mut self, s: BoardStats) {
        self.board.stats = Some(s);
    }

    /// A notice of the board's, to every port (a reset's cause at start-up).
    pub fn board_notice(&mut self, text: &str) {
        self.host.notify(Response::Echo(text));
    }

    /// The measurements last set, if the board sets any.
    pub fn board_stats(&self) -> Option<BoardStats> {
        self.board.stats
    }

    /// The board found driver modules plugged in backwards (the sockets named in `sockets`)
    /// and keeps the drivers' power off: `Error:<socket> driver is backward!` on every port
    /// for each (Marlin's `stepper_driver_backward_error`), what to do, then a halt (heaters
    /// off, nothing moves, until reset).
    pub fn drivers_backward(&mut self, sockets: &[&str]) {
        for s in sockets {
            let mut t: heapless::String<48> = heapless::String::new();
            let _ = write!(t, "{s} driver is backward!");
            self.host.notify(Response::Error(&t));
        }
        self.host.notify(Response::Echo(
            "driver power (SAFE_POWER) kept off: switch off, turn the module round (its EN pin \
             to the socket's EN mark), switch on again",
        ));
        let now = self.now_us;
        self.request(Realtime::EmergencyStop, now);
    }
}
