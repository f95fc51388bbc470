//! Step re-timing in the step interrupt: what keeps a late step event from firing in a burst.
//!
//! The board's motion loop queues step events a few milliseconds ahead, each with its planned
//! time. If that loop stalls for longer than the queue covers (a blocking SD read, USB, a flash
//! operation), the queue runs dry and the motors stop abruptly; when the loop resumes, the
//! events it queues are already late. Fired as soon as possible they would run back to back at
//! the interrupt's own speed (~200 kHz) — a burst far above any axis limit, a layer shift.
//!
//! [`Retimer`] gives each event the earliest time it may fire ([`Retimer::due`]):
//!
//! * **shift, never compress**: event i fires no earlier than `t_i + shift`; when an event
//!   fires more than [`RetimeConfig::late_tolerance_ticks`] late, the shift grows to its
//!   lateness, so the rest of the schedule moves with it and every step keeps its planned
//!   spacing (no axis ever goes faster than planned after a stall);
//! * **per-axis floor**: an axis is never due sooner than [`RetimeConfig::min_period_ticks`]
//!   after its previous step (its limit: steps/mm × max feed, and never below the minimum step
//!   period), whatever the schedule says (an event held back by the floor shifts the rest
//!   too). The floor counts from the later of when the previous step was due and when it
//!   fired less [`RetimeConfig::latency_slack_ticks`]: two steps of an axis as fired are never
//!   closer than its floor less that slack (and the time base's resolution), whatever the
//!   interrupt latency — a latency up to the slack costs nothing, a longer one holds the
//!   axis's next step back by the excess (an axis running at its limit then runs that much
//!   behind its plan, which the shift takes up once it exceeds the tolerance);
//! * **minimum step period, in fired time**: two steps of one axis are never fired closer than
//!   [`RetimeConfig::min_step_ticks`] (the drivers' limit), whatever the latency;
//! * **the shift shrinks only at rest**: where the plan itself leaves a gap longer than
//!   [`RetimeConfig::rest_gap_ticks`] between two events (every axis nearly at rest: the end of
//!   a move, a dwell, a pause), the shift shrinks by what the gap exceeds that, so the next
//!   motion starts on time again, while two events are never closer than `rest_gap_ticks` (or
//!   their planned gap, if shorter).
//!
//! Small lateness (interrupt latency, a few events due at once) below the tolerance fires at
//! once without shifting the schedule, so latency never accumulates into a drift; only an axis
//! running at its limit is held back, by what a latency exceeds the slack (its floor).
//!
//! What re-timing cannot undo: during the stall the axes stopped abruptly, and after it they
//! resume at the speed the plan had there (the same speed step as the stop). Keeping stalls
//! shorter than the queue's look-ahead avoids both; every re-timed event is counted
//! ([`RetimeStats`]) and the board reports them.
//!
//! Times are in ticks of the board's time base (`u64`, monotonic). Pure state machine: no pins,
//! no clock; host-tested below and by `firmware/tests/retime.rs`.

use crate::motion::AXES;

/// The limits the re-timer enforces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RetimeConfig {
    /// Per axis: the shortest time between two of its steps as due, ticks (its limit).
    pub min_period_ticks: [u32; AXES],
    /// The shortest time between two fired steps of one axis, ticks (the minimum step period).
    pub min_step_ticks: u32,
    /// How much of a step's lateness its axis's floor forgives, ticks: the floor counts from
    /// the later of when the step was due and when it fired less this. It bounds how much
    /// shorter than its floor an axis's step interval can be (by design, not by how long
    /// the interrupt was kept waiting); a step fired later than this drags its axis's next
    /// step by the excess.
    pub latency_slack_ticks: u32,
    /// An event fired more than this late shifts the rest of the schedule, ticks.
    pub late_tolerance_ticks: u32,
    /// A planned gap at least this long between two consecutive events counts as rest: the
    /// shift may shrink by what the gap exceeds it, ticks.
    pub rest_gap_ticks: u32,
}

/// What the re-timer did, since it was made (the board takes and reports these).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RetimeStats {
    /// Events that fired more than the tolerance late in motion (each shifted the schedule);
    /// the first event after a rest is not counted (a late start is no stall).
    pub late: u32,
    /// Events held back by an axis's floor (the schedule itself was too fast for the axis).
    pub capped: u32,
    /// The worst lateness seen, ticks past the event's due time.
    pub worst_late_ticks: u64,
}

/// The re-timer's state. See the module documentation.
///
/// The step interrupt calls [`Retimer::due`] for the event at the head of its queue (as often
/// as it needs: it may arm the compare and come back), then [`Retimer::fired`] once the event
/// fired, which books that event. The per-event work runs in the step interrupt for every
/// event, so the state is kept in 32-bit ticks and compared by wrapping differences (the
/// 4 MHz time base wraps 32 bits every 1073 s; every difference taken here is far shorter:
/// a shift or a gap of more than 536 s would be misread, and the watchdog ends any stall long
/// before that). The emulated-core test measures the cost (`firmware/qemu`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Retimer {
    cfg: RetimeConfig,
    /// How far behind the plan the schedule runs now, ticks.
    shift: u32,
    /// Planned time of the previous event (valid once `started`), low 32 bits.
    prev_t: u32,
    started: bool,
    /// Per axis: the earliest its next step may be due (its floor after its last step as
    /// due, the minimum step period after it as fired), valid for axes in `seen`.
    next_ok: [u32; AXES],
    seen: u8,
    /// The event [`Retimer::due`] last answered for: planned time (low 32 bits), base shift,
    /// and how long after the planned time it is due.
    head: (u32, u32, u32),
    stats: RetimeStats,
}

// The axis loops index with `& 3`.
const _: () = assert!(AXES == 4);

impl Retimer {
    /// A re-timer with no history.
    pub const fn new(cfg: RetimeConfig) -> Self {
        Retimer {
            cfg,
            shift: 0,
            prev_t: 0,
            started: false,
            next_ok: [0; AXES],
            seen: 0,
            head: (0, 0, 0),
            stats: RetimeStats {
                late: 0,
                capped: 0,
                worst_late_ticks: 0,
            },
        }
    }

    /// The limits in force.
    pub fn config(&self) -> RetimeConfig {
        self.cfg
    }

    /// New limits (M92/M203 changed an axis): they apply from the next event.
    pub fn set_config(&mut self, cfg: RetimeConfig) {
        self.cfg = cfg;
    }

    /// How far behind the plan the schedule runs, ticks.
    pub fn shift_ticks(&self) -> u64 {
        u64::from(self.shift)
    }

    /// The counts so far.
    pub fn stats(&self) -> RetimeStats {
        self.stats
    }

    /// Forget the schedule (the queue was flushed: halt, quick stop). The per-axis floors
    /// keep their last steps.
    pub fn restart(&mut self) {
        self.shift = 0;
        self.started = false;
    }

    /// The earliest time the event planned at `t` for the axes in `axis_mask` may fire.
    /// Remembered for [`Retimer::fired`].
    #[inline]
    pub fn due(&mut self, t: u64, axis_mask: u8) -> u64 {
        let t32 = t as u32;
        // The shift, shrunk by what a planned rest before this event exceeds the rest gap.
        let base = if self.started {
            let gap = t32.wrapping_sub(self.prev_t);
            if gap > self.cfg.rest_gap_ticks {
                self.shift.saturating_sub(gap - self.cfg.rest_gap_ticks)
            } else {
                self.shift
            }
        } else {
            0
        };
        // How long after `t` it is due: the shift, or later where a floor says so.
        let mut after = base;
        let mut m = axis_mask & self.seen;
        while m != 0 {
            let a = (m.trailing_zeros() & 3) as usize;
            m &= m - 1;
            let need = self.next_ok[a].wrapping_sub(t32) as i32;
            if need > after as i32 {
                after = need as u32;
            }
        }
        self.head = (t32, base, after);
        t.saturating_add(u64::from(after))
    }

    /// The event [`Retimer::due`] last answered for fired at `at` (never before its due
    /// time); `stepped` are the axes that really stepped (refused steps do not count for the
    /// floors).
    #[inline]
    pub fn fired(&mut self, stepped: u8, at: u64) {
        let (t, base, after) = self.head;
        let at = at as u32;
        let due = t.wrapping_add(after);
        let tol = self.cfg.late_tolerance_ticks;
        let late = (at.wrapping_sub(due) as i32).max(0) as u32;
        // How long a floor held the event back beyond the (shifted) plan.
        let held = after - base;
        if held > 0 {
            self.stats.capped = self.stats.capped.saturating_add(1);
        }
        // Lateness or a hold within the tolerance (interrupt latency, an axis running at its
        // limit) does not shift the rest, so no latency accumulates into a drift.
        self.shift = if late > tol {
            // The first event after a rest is late by construction (a move from rest is
            // planned to start when the executive is polled, and queued a little later): the
            // move starts that much later, which is no stall; only lateness in motion counts.
            let after_rest = !self.started || t.wrapping_sub(self.prev_t) > self.cfg.rest_gap_ticks;
            if !after_rest {
                self.stats.late = self.stats.late.saturating_add(1);
                self.stats.worst_late_ticks = self.stats.worst_late_ticks.max(u64::from(late));
            }
            after + late
        } else if held > tol {
            after
        } else {
            base
        };
        self.prev_t = t;
        self.started = true;
        // The floors count from when a step was due, or from when it fired less the slack
        // if that is later: a latency up to the slack never drags an axis running at its
        // limit (it would add up over a long move), and no latency, however long, lets two
        // steps of an axis come closer than its floor less the slack (a step fired 17 µs
        // late followed by one on time would otherwise be 17 µs short of the floor). The
        // minimum step period counts from when it fired, always.
        let by_fire = at.wrapping_sub(self.cfg.latency_slack_ticks);
        let from = if by_fire.wrapping_sub(due) as i32 > 0 {
            by_fire
        } else {
            due
        };
        let by_step = at.wrapping_add(self.cfg.min_step_ticks);
        let mut m = stepped & 0x0F;
        self.seen |= m;
        while m != 0 {
            let a = (m.trailing_zeros() & 3) as usize;
            m &= m - 1;
            let by_floor = from.wrapping_add(self.cfg.min_period_ticks[a]);
            self.next_ok[a] = if by_step.wrapping_sub(by_floor) as i32 > 0 {
                by_step
            } else {
                by_floor
            };
        }
    }
}

/// The floor of one axis: the period of its fastest allowed rate, `steps_per_mm ×
/// max_feed_mm_s` steps/s, in ticks of `tick_hz`, rounded down and less one tick (event times
/// are rounded down to the tick, so two steps planned exactly at the limit can come one tick
/// closer: such a plan is never held back), and never below `min_step_period_ticks`.
pub fn axis_floor_ticks(
    steps_per_mm: f32,
    max_feed_mm_s: f32,
    tick_hz: u32,
    min_step_period_ticks: u32,
) -> u32 {
    let rate = steps_per_mm * max_feed_mm_s;
    let ticks = if rate.is_finite() && rate > 0.0 {
        let t = tick_hz as f32 / rate;
        if t.is_finite() {
            t.clamp(0.0, u32::MAX as f32) as u32
        } else {
            0
        }
    } else {
        0
    };
    ticks.saturating_sub(1).max(min_step_period_ticks)
}

#[cfg(test)]
mod tests {
    use super::*;

    const CFG: RetimeConfig = RetimeConfig {
        // X 40 kHz (25 µs), Y 40 kHz, Z 2 kHz, E 2.3 kHz at 4 MHz ticks.
        min_period_ticks: [99, 99, 1999, 1719],
        min_step_ticks: 8,
        latency_slack_ticks: 2,
        late_tolerance_ticks: 80,
        rest_gap_ticks: 80_000,
    };

    #[test]
    fn on_time_events_keep_their_times() {
        let mut r = Retimer::new(CFG);
        for i in 0..100u64 {
            let t = 1_000 + i * 400;
            assert_eq!(r.due(t, 1), t);
            r.fired(1, t + 3); // interrupt latency
        }
        assert_eq!(r.shift_ticks(), 0);
        assert_eq!(r.stats(), RetimeStats::default());
    }

    #[test]
    fn a_late_event_shifts_the_rest_and_keeps_the_spacing() {
        let mut r = Retimer::new(CFG);
        r.due(0, 1);
        r.fired(1, 0);
        r.due(400, 1);
        r.fired(1, 400);
        // The queue ran dry; the next events arrive 5 ms (20 000 ticks) late.
        let late_at = 800 + 20_000;
        r.due(800, 1);
        r.fired(1, late_at);
        assert_eq!(r.shift_ticks(), 20_000);
        // The following ones keep the planned 400-tick spacing from there.
        assert_eq!(r.due(1_200, 1), late_at + 400);
        assert_eq!(r.due(1_600, 1), late_at + 800);
        let s = r.stats();
        assert_eq!((s.late, s.capped, s.worst_late_ticks), (1, 0, 20_000));
    }

    #[test]
    fn the_floor_holds_an_axis_to_its_limit() {
        let mut r = Retimer::new(CFG);
        r.due(0, 1);
        r.fired(1, 0);
        // Planned 10 ticks later: faster than X's 99-tick floor.
        assert_eq!(r.due(10, 1), 99);
        r.fired(1, 99);
        assert_eq!(r.stats().capped, 1);
        // Held 89 ticks, over the 80-tick tolerance: the rest shifts by it, another axis too.
        assert_eq!(r.due(20, 0b1000), 109);
        // A hold within the tolerance fires late but does not shift the rest.
        let mut r = Retimer::new(CFG);
        r.due(0, 1);
        r.fired(1, 0);
        assert_eq!(r.due(60, 1), 99);
        r.fired(1, 99);
        assert_eq!(r.shift_ticks(), 0);
        assert_eq!(r.due(70, 0b1000), 70);
    }

    #[test]
    fn a_late_step_shortens_the_next_interval_by_the_slack_at_most() {
        let mut r = Retimer::new(CFG);
        // Z (floor 1999 ticks) at its limit: planned 2000 ticks apart.
        r.due(0, 0b100);
        r.fired(0b100, 0);
        assert_eq!(r.due(2_000, 0b100), 2_000);
        // 17 µs (68 ticks) late: within the tolerance, nothing shifts...
        r.fired(0b100, 2_068);
        assert_eq!(r.shift_ticks(), 0);
        // ...but Z's next step waits for its floor after the late one, less the slack.
        assert_eq!(r.due(4_000, 0b100), 2_068 - 2 + 1_999);
        // Another axis is not held.
        assert_eq!(r.due(4_000, 0b001), 4_000);
        // A latency within the slack costs nothing.
        let mut r = Retimer::new(CFG);
        r.due(0, 0b100);
        r.fired(0b100, 2);
        assert_eq!(r.due(2_000, 0b100), 2_000);
    }

    #[test]
    fn the_minimum_step_period_holds_in_fired_time() {
        let cfg = RetimeConfig {
            min_period_ticks: [8, 8, 8, 8],
            ..CFG
        };
        let mut r = Retimer::new(cfg);
        r.due(0, 1);
        r.fired(1, 0);
        r.due(8, 1);
        r.fired(1, 30); // 22 late: within the tolerance, no shift
        assert_eq!(r.shift_ticks(), 0);
        // Planned at 16 (due 16 by the floor), but never within 8 ticks of the fired 30.
        assert_eq!(r.due(16, 1), 38);
    }

    #[test]
    fn the_shift_shrinks_across_a_rest_gap() {
        let mut r = Retimer::new(CFG);
        r.due(0, 1);
        r.fired(1, 30_000); // a start 30 000 late: shifted, not counted
        assert_eq!(r.shift_ticks(), 30_000);
        assert_eq!(r.stats().late, 0);
        // A planned gap of 100 000 (25 ms) > the 80 000 rest gap: the shift shrinks by 20 000.
        assert_eq!(r.due(100_000, 1), 100_000 + 10_000);
        // A longer rest: back on time.
        r.due(100_000, 1);
        r.fired(1, 110_000);
        assert_eq!(r.due(400_000, 1), 400_000);
    }

    #[test]
    fn floors_from_the_machine_limits() {
        // Ender-3 X: 80 steps/mm × 500 mm/s = 40 kHz → 100 ticks at 4 MHz, less one.
        assert_eq!(axis_floor_ticks(80.0, 500.0, 4_000_000, 8), 99);
        // Never below the minimum step period.
        assert_eq!(axis_floor_ticks(1280.0, 500.0, 4_000_000, 8), 8);
        // Nonsense limits fall back to the minimum step period.
        assert_eq!(axis_floor_ticks(0.0, 500.0, 4_000_000, 8), 8);
        assert_eq!(axis_floor_ticks(f32::NAN, 5.0, 4_000_000, 8), 8);
        assert_eq!(
            axis_floor_ticks(1e-3, 1e-3, 4_000_000, 8),
            u32::MAX - 1,
            "absurdly slow: clamped"
        );
    }
}
