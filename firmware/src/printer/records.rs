//! The execution record the executive keeps for its driver (the simulator's timeline, the
//! tests): blocks executed, layers crossed, state changes, the pause's speed-up, brake and
//! stop. A fixed ring: when the driver does not take them in time the oldest go, counted.

use super::types::{Record, State};
use heapless::Deque;

/// Execution records kept until the driver takes them.
pub const RECORD_CAPACITY: usize = 256;

/// The record ring and the last state recorded.
#[derive(Clone, Debug)]
pub(super) struct Records {
    ring: Deque<Record, RECORD_CAPACITY>,
    dropped: u32,
    last_state: State,
}

impl Records {
    pub(super) const fn new() -> Self {
        Self {
            ring: Deque::new(),
            dropped: 0,
            last_state: State::Idle,
        }
    }

    /// Keep `r` (the oldest goes when the ring is full).
    pub(super) fn push(&mut self, r: Record) {
        if self.ring.is_full() {
            let _ = self.ring.pop_front();
            self.dropped = self.dropped.saturating_add(1);
        }
        let _ = self.ring.push_back(r);
    }

    /// Whether `state` is not the last one recorded.
    #[inline]
    pub(super) fn state_changed(&self, state: State) -> bool {
        state != self.last_state
    }

    /// A [`Record::State`] when the state is not the last one recorded.
    pub(super) fn state(&mut self, state: State, t_us: u64) {
        if state != self.last_state {
            self.last_state = state;
            self.push(Record::State { state, t_us });
        }
    }

    /// The oldest record.
    pub(super) fn pop(&mut self) -> Option<Record> {
        self.ring.pop_front()
    }

    /// Records lost because the driver did not take them in time.
    pub(super) fn dropped(&self) -> u32 {
        self.dropped
    }
}
