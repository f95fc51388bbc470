//! The virtual clock and the event loop.
//!
//! Time only moves from one event to the next: a step event from the firmware's step
//! generator, a chunk of bytes arriving at either end of the serial line, a tick of the
//! firmware's main loop (`poll`, every `poll_tick_us` while anything is going on, so heater
//! waits and dwell time pass), or a deadline the caller sets (a host action such as a pause
//! request). Nothing here knows about motion planning.

use crate::hostlink::{Host, Origin};
use crate::port::{BlockTag, Executive, Lane, State, StepEvent};
use crate::recorder::Recorder;
use crate::thermal::Heaters;

/// Why [`Engine::advance`] returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The deadline was reached (the clock now equals it).
    Deadline,
    /// A step event was processed (only when asked to stop on steps).
    Step(StepEvent),
    /// Everything is finished: the host has sent and had acknowledged every line, the wire is
    /// quiet and the firmware has no more steps and is idle.
    Finished,
    /// Nothing moved and the host sent nothing for `stall_limit_us` (waiting forever).
    Stalled,
}

/// Virtual time without a step and without a byte from the host after which a run has
/// stalled (a wedge: the printer only answers `busy:` or reports): 3 h, longer than the
/// longest dwell the firmware accepts (G4 P1e7 = 2.8 h) and any heat-up.
pub const STALL_LIMIT_US: u64 = 3 * 3600 * 1_000_000;

/// The simulator's event loop around one executive.
pub struct Engine<E: Executive> {
    /// Virtual time now, µs.
    pub now_us: u64,
    /// The firmware executive.
    pub fw: E,
    /// The host at the other end of the serial line.
    pub host: Host,
    /// What was executed.
    pub rec: Recorder,
    /// Heater models, when thermal simulation is on.
    pub heaters: Option<Heaters>,
    /// Main-loop tick while busy, µs.
    pub poll_tick_us: u64,
    /// Give up waiting after this long without a step or a host byte, µs
    /// ([`STALL_LIMIT_US`]).
    pub stall_limit_us: u64,
    /// Last step or host byte (the stall's clock).
    last_progress_us: u64,
    /// Last event other than a main-loop tick (the poll rate's clock).
    last_event_us: u64,
    next_poll_us: u64,
    out: String,
    /// Events handled (steps, byte chunks, ticks).
    pub events: u64,
    /// Which host line each job sequence number came from.
    pub seqs: SeqMap,
    /// Bytes that arrived but that the firmware has not taken yet (flow control: they wait on
    /// the wire and are offered again at every poll).
    rx_pending: Vec<u8>,
}

/// Job sequence numbers → the host line that produced them. The firmware numbers moves itself
/// (a counter); the engine watches the counter after every call into the firmware and gives
/// the new numbers to the last numbered line the host sent (with `ok` flow control that is the
/// line being handled).
#[derive(Clone, Debug, Default)]
pub struct SeqMap {
    /// (first seq of a range, origin), ascending.
    ranges: Vec<(u32, Origin)>,
    last_next: Option<u32>,
}

impl SeqMap {
    /// The firmware's next sequence number is now `next`; `origin` is the line being handled.
    pub fn observe(&mut self, next: u32, origin: Option<Origin>) {
        match self.last_next {
            None => self.last_next = Some(next),
            Some(prev) if next > prev => {
                if let Some(o) = origin {
                    self.ranges.push((prev, o));
                }
                self.last_next = Some(next);
            }
            Some(_) => {}
        }
    }

    /// The line a sequence number came from, if known.
    pub fn origin(&self, seq: u32) -> Option<Origin> {
        let i = self.ranges.partition_point(|(s, _)| *s <= seq);
        i.checked_sub(1)
            .and_then(|i| self.ranges.get(i))
            .map(|r| r.1)
    }

    /// Forget the lines of sequence numbers below `seq` (kept: the range holding `seq`). Done
    /// in halves, so amortised O(1) per range.
    pub fn forget_before(&mut self, seq: u32) {
        // A number not handed out yet (a homing block's `u32::MAX`) says nothing.
        if self.last_next.is_none_or(|next| seq >= next) {
            return;
        }
        let i = self.ranges.partition_point(|(s, _)| *s <= seq);
        let drop = i.saturating_sub(1);
        if drop > 0 && drop * 2 >= self.ranges.len() {
            self.ranges.drain(..drop);
        }
    }

    /// Ranges held (for tests of the memory bound).
    pub fn held(&self) -> usize {
        self.ranges.len()
    }

    /// True once the firmware has reported any sequence number.
    pub fn active(&self) -> bool {
        self.last_next.is_some()
    }
}

impl<E: Executive> Engine<E> {
    /// An engine at time 0.
    pub fn new(fw: E, host: Host) -> Self {
        Self {
            now_us: 0,
            fw,
            host,
            rec: Recorder::new(),
            heaters: Some(Heaters::ender3()),
            poll_tick_us: 1_000,
            stall_limit_us: STALL_LIMIT_US,
            last_progress_us: 0,
            last_event_us: 0,
            next_poll_us: 0,
            out: String::new(),
            events: 0,
            seqs: SeqMap::default(),
            rx_pending: Vec::new(),
        }
    }

    /// Offer the bytes waiting on the wire to the firmware.
    fn offer_pending(&mut self) {
        if self.rx_pending.is_empty() {
            return;
        }
        self.track_seq();
        let n = self.fw.receive(&self.rx_pending, self.now_us);
        self.rx_pending.drain(..n.min(self.rx_pending.len()));
        self.track_seq();
    }

    fn flush_output(&mut self) {
        self.out.clear();
        self.fw.take_output(&mut self.out);
        if !self.out.is_empty() {
            let bytes = std::mem::take(&mut self.out);
            self.host.printer_wrote(bytes.as_bytes(), self.now_us);
            self.out = bytes;
            self.out.clear();
        }
    }

    fn track_seq(&mut self) {
        if let Some(n) = self.fw.next_seq() {
            let o = self.host.last_numbered_origin();
            self.seqs.observe(n, o);
        }
    }

    /// The host line a job sequence number came from.
    pub fn origin_of_seq(&self, seq: u32) -> Option<Origin> {
        if self.seqs.active() {
            self.seqs.origin(seq)
        } else {
            // Executives that number moves with the host's line numbers.
            self.host.origin_of(i64::from(seq))
        }
    }

    fn poll_fw(&mut self) {
        self.track_seq();
        self.fw.poll(self.now_us);
        self.track_seq();
        self.offer_pending();
        self.flush_output();
        let st = self.fw.status();
        self.rec.on_status(&st, self.now_us);
    }

    /// Everything is done (see [`Stop::Finished`]).
    pub fn finished(&mut self) -> bool {
        let st = self.fw.status().state;
        self.host.done()
            && self.host.rx.is_idle()
            && self.rx_pending.is_empty()
            && self.fw.next_step_us(self.now_us).is_none()
            && matches!(st, State::Idle | State::Cancelled | State::Halted)
    }

    /// Run events until `deadline_us` (inclusive of events at that time), until finished, or
    /// (with `stop_on_step`) until one step event has been processed.
    pub fn advance(&mut self, deadline_us: u64, stop_on_step: bool) -> Stop {
        loop {
            self.host.pump(self.now_us);
            let t_step = self.fw.next_step_us(self.now_us);
            let t_tx = self.host.tx.next_arrival_us();
            let t_rx = self.host.rx.next_arrival_us();
            let state = self.fw.status().state;
            let busy = t_step.is_some()
                || t_tx.is_some()
                || t_rx.is_some()
                || !self.host.done()
                || !self.rx_pending.is_empty()
                || state != State::Idle;
            if !busy {
                return Stop::Finished;
            }
            let t_poll = self.next_poll_us.max(self.now_us);
            let mut t = t_poll;
            for c in [t_step, t_tx, t_rx].into_iter().flatten() {
                t = t.min(c);
            }
            if t > deadline_us {
                self.now_us = deadline_us.max(self.now_us);
                return Stop::Deadline;
            }
            self.now_us = self.now_us.max(t);
            self.events += 1;
            if t != t_poll {
                self.last_event_us = self.now_us;
            }
            // Progress: a step, or bytes from the host. What the printer writes is not: a
            // wedged printer keeps answering `busy:`. (A host that means to act later — a
            // resume after a long pause — calls `reset_stall`.)
            if t_step == Some(t) || t_tx == Some(t) {
                self.last_progress_us = self.now_us;
            } else if self.now_us.saturating_sub(self.last_progress_us) > self.stall_limit_us {
                return Stop::Stalled;
            }
            if t_tx.is_some_and(|x| x <= self.now_us) {
                while let Some(bytes) = self.host.tx.take_arrived(self.now_us) {
                    self.rx_pending.extend_from_slice(&bytes);
                    self.offer_pending();
                }
                self.poll_fw();
                continue;
            }
            if t_rx.is_some_and(|x| x <= self.now_us) {
                self.host.receive_arrived(self.now_us);
                continue;
            }
            if t_step.is_some_and(|x| x <= self.now_us) {
                if let Some(ev) = self.fw.pop_step(self.now_us) {
                    let new_block = self.rec.on_step(&ev);
                    if new_block {
                        if !self.rec.keep_records && BlockTag::of(&ev).lane == Lane::Job {
                            // Nothing will ask where an executed block came from: memory
                            // stays flat with job length.
                            self.seqs.forget_before(ev.seq);
                        }
                        self.poll_fw();
                    }
                    if stop_on_step {
                        return Stop::Step(ev);
                    }
                }
                continue;
            }
            // Main-loop tick: heaters, then the firmware.
            if let Some(h) = self.heaters.as_mut() {
                h.tick(&mut self.fw, self.now_us);
            }
            self.poll_fw();
            // Waiting (heaters, dwell, paused): tick ten times slower after a second of calm.
            let calm = self.now_us.saturating_sub(self.last_event_us) > 1_000_000;
            self.next_poll_us = self.now_us + self.poll_tick_us * if calm { 10 } else { 1 };
        }
    }

    /// Start the stall's clock again (the host means to act later: waiting is not a stall).
    pub fn reset_stall(&mut self) {
        self.last_progress_us = self.now_us;
    }

    /// Advance to `deadline_us` however long nothing happens before it (a host that acts at
    /// that time: a resume after a long pause); stops early only when finished.
    pub fn wait_until(&mut self, deadline_us: u64) -> Stop {
        loop {
            match self.advance(deadline_us, false) {
                Stop::Stalled => self.reset_stall(),
                other => return other,
            }
        }
    }

    /// Run to completion or until `deadline_us`; returns true when finished.
    pub fn run_to_end(&mut self, deadline_us: u64) -> bool {
        matches!(self.advance(deadline_us, false), Stop::Finished)
    }
}
