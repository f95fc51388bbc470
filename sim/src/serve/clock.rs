//! The session's virtual clock: `--speed` times real time, and with `--host-paced` a clock
//! that waits for the hosts.
//!
//! At a high `--speed` a real host's reaction time becomes long in virtual time (printcore
//! answers an `ok` with its next line after 1–20 ms of real time on a loaded machine: at 500×,
//! 0.5–10 s virtual), and so does any stall of the sim itself. A test that judges virtual
//! delays (a console line within 2 s of a long pause) then measures the machine's load, not
//! the firmware. With `--host-paced`:
//!
//! * while a host owes its reply to an `ok` the sim wrote to it (no byte from it since, for up
//!   to [`HOST_TURN_GRACE`] of real time: a host with nothing to send never replies), the
//!   clock runs at most [`HOST_TURN_SPEED`]× real time — a 20 ms reaction is 0.2 s virtual,
//!   as fast a host as a real one at 1× on a slow PC;
//! * the clock never advances more than [`MAX_ADVANCE_US`] per pass of the loop, so a stall of
//!   the sim (descheduled, a page fault) is not virtual time either.
//!
//! The firmware sees a monotonic clock either way; only how virtual time maps to real time
//! changes (the record's `realtime_factor` says what it was).

use std::time::{Duration, Instant};

/// Highest virtual speed while a host owes a reply, × real time.
pub const HOST_TURN_SPEED: f64 = 10.0;
/// How long (real time) a host may owe its reply before the clock runs at full speed again.
pub const HOST_TURN_GRACE: Duration = Duration::from_millis(100);
/// Most virtual time one pass of the loop adds, µs (the loop waits at most 0.2 s virtual).
/// A stall while the firmware holds a line for its 1 s pace can lengthen that hold by this
/// much at most; smaller values make a loaded machine's session slower in wall time.
pub const MAX_ADVANCE_US: f64 = 500_000.0;

/// See the module documentation.
pub(super) struct Clock {
    speed: f64,
    paced: bool,
    virtual_us: f64,
    last: Instant,
}

impl Clock {
    pub(super) fn new(speed: f64, paced: bool) -> Self {
        Self {
            speed,
            paced,
            virtual_us: 0.0,
            last: Instant::now(),
        }
    }

    /// Advance by the real time since the last call; `host_owes`: a host owes a reply.
    /// Returns the virtual time, µs.
    pub(super) fn now_us(&mut self, host_owes: bool) -> u64 {
        let now = Instant::now();
        let dt_s = now.duration_since(self.last).as_secs_f64();
        self.last = now;
        let mut adv = if self.paced && host_owes {
            dt_s * self.speed.min(HOST_TURN_SPEED) * 1e6
        } else {
            dt_s * self.speed * 1e6
        };
        if self.paced {
            adv = adv.min(MAX_ADVANCE_US);
        }
        self.virtual_us += adv;
        self.virtual_us as u64
    }
}
