//! The step interrupt's re-timer (`firmware::drivers::retime`) on the step events of a real
//! sliced job, with the board's queue modelled: the motion loop queues events up to the
//! look-ahead before their time into a queue of the board's length, and stalls (an SD read,
//! USB, anything that holds the executor) stop the queueing for a while. The checks derive
//! everything from the fired times and the plan, not from the re-timer's state:
//!
//! * every axis keeps its floor (its limit) between two of its steps, to within the latency
//!   slack (2 ticks, 500 ns), whatever latency the model adds (up to 40 ticks, 10 µs);
//! * no axis ever steps faster than planned beyond the interrupt's latency and a drag held
//!   within the tolerance (an axis at its limit held back by a latency beyond the slack);
//! * without stalls and with latencies within the slack nothing is shifted (no drift), and
//!   the same model firing late events at once (the board before this change) does burst, so
//!   the checks have teeth;
//! * the delay left at the end is bounded by the stalls.
//!
//! Also prints what look-ahead costs in queue entries on this job (`--nocapture`).
//! Cost: about 1 s (one job section run through the executive once, then cheap models).
mod support;

use firmware::config::MachineConfig;
use firmware::drivers::retime::{axis_floor_ticks, RetimeConfig, Retimer};
use firmware::motion::{Axis, AXES};
use proptest::prelude::*;
use support::*;

/// The board's time base: 4 MHz (`board::clock`).
const TICK_HZ: u32 = 4_000_000;
const NS_PER_TICK: u64 = 250;
/// The board's queue length and look-ahead (`board::stepper`, `image/motion.rs`).
const QUEUE_LEN: usize = 256;
/// What the interrupt needs per event (DIR setup, pulse, bookkeeping), ticks (≈ 3 µs).
const ISR_TICKS: u64 = 12;
/// The latency tolerance and rest gap as on the board (20 µs, 20 ms).
const TOL: u32 = 80;
const REST: u32 = 80_000;
/// The latency the floors forgive, as on the board (500 ns).
const SLACK: u32 = 2;

fn config(cfg: &MachineConfig) -> RetimeConfig {
    let mut min_period_ticks = [8; AXES];
    for (a, p) in Axis::ALL.into_iter().zip(min_period_ticks.iter_mut()) {
        let ax = cfg.axis(a);
        *p = axis_floor_ticks(ax.steps_per_mm, ax.max_feed_mm_s, TICK_HZ, 8);
    }
    RetimeConfig {
        min_period_ticks,
        min_step_ticks: 8,
        latency_slack_ticks: SLACK,
        late_tolerance_ticks: TOL,
        rest_gap_ticks: REST,
    }
}

/// The step events of the first `lines` lines of a sliced job (heater waits removed): planned
/// time in ticks and the axes that step.
fn job_events(lines: usize) -> Vec<(u64, u8)> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/fixtures/slicer/prusaslicer.gcode"
    );
    let text = std::fs::read_to_string(path).expect("fixture");
    let lines: Vec<&str> = text
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with("M109") && !l.starts_with("M190"))
        .take(lines)
        .collect();
    let mut p = printer();
    let r = run_gcode(&mut p, &lines, &[], 600_000_000);
    let mut prev = [0i32; AXES];
    let mut out = Vec::with_capacity(r.trace.len());
    for (t_ns, pos) in r.trace {
        let mut mask = 0u8;
        for (i, (a, b)) in pos.iter().zip(prev.iter()).enumerate() {
            if a != b {
                mask |= 1 << i;
            }
        }
        prev = pos;
        out.push((t_ns / NS_PER_TICK, mask));
    }
    out
}

/// A stall of the motion loop: from `at` (ticks), for `len` ticks nothing is queued.
#[derive(Clone, Copy, Debug)]
struct Stall {
    at: u64,
    len: u64,
}

/// When each event is fired, by a model of the board: the motion loop queues event i once
/// its time is within `lookahead` and the queue has room (event i − QUEUE_LEN has fired),
/// except during stalls; the interrupt fires the queue's head at its due time (the re-timer's,
/// or the planned time when `retimer` is None: the old behaviour), at least `ISR_TICKS` after
/// the previous one, plus a latency from `jitter` (< the tolerance).
fn fire_times(
    events: &[(u64, u8)],
    lookahead: u64,
    stalls: &[Stall],
    mut retimer: Option<&mut Retimer>,
    jitter: &[u64],
) -> Vec<u64> {
    let mut fired: Vec<u64> = Vec::with_capacity(events.len());
    let mut prev = 0u64;
    for (i, &(t, mask)) in events.iter().enumerate() {
        // Queued: the motion loop runs every 1 ms (4000 ticks).
        let mut avail = t.saturating_sub(lookahead);
        if i >= QUEUE_LEN {
            avail = avail.max(fired[i - QUEUE_LEN]);
        }
        avail = avail.div_ceil(4000) * 4000;
        for s in stalls {
            if avail >= s.at && avail < s.at + s.len {
                avail = s.at + s.len;
            }
        }
        let due = match retimer.as_deref_mut() {
            Some(r) => r.due(t, mask),
            None => t,
        };
        let at = due.max(avail).max(prev + ISR_TICKS) + jitter[i % jitter.len()];
        if let Some(r) = retimer.as_deref_mut() {
            r.fired(mask, at);
        }
        fired.push(at);
        prev = at;
    }
    fired
}

/// Per axis, the shortest gap between two of its steps, and the worst "faster than planned":
/// the most a gap fell short of its planned gap (capped at the rest gap).
fn spacing(events: &[(u64, u8)], fired: &[u64]) -> ([u64; AXES], u64) {
    let mut last: [Option<(u64, u64)>; AXES] = [None; AXES];
    let mut min_gap = [u64::MAX; AXES];
    let mut worst_short = 0u64;
    for (&(t, mask), &at) in events.iter().zip(fired) {
        for a in 0..AXES {
            if mask & (1 << a) == 0 {
                continue;
            }
            if let Some((pt, pat)) = last[a] {
                let gap = at - pat;
                min_gap[a] = min_gap[a].min(gap);
                let planned = (t - pt).min(u64::from(REST));
                worst_short = worst_short.max(planned.saturating_sub(gap));
            }
            last[a] = Some((t, at));
        }
    }
    (min_gap, worst_short)
}

/// Latencies within the slack (a step interrupt that nothing holds back); the proptest below
/// adds up to 40 ticks.
const SMALL_JITTER: [u64; 5] = [0, 1, 2, 0, 1];

fn events() -> &'static [(u64, u8)] {
    use std::sync::OnceLock;
    static EV: OnceLock<Vec<(u64, u8)>> = OnceLock::new();
    EV.get_or_init(|| job_events(1200))
}

#[test]
fn no_burst_after_stalls_and_every_axis_keeps_its_floor() {
    let ev = events();
    assert!(ev.len() > 20_000, "{} events", ev.len());
    let cfg = config(&MachineConfig::ENDER3);
    let lookahead = 2_000_000 / NS_PER_TICK;
    let t_end = ev.last().unwrap().0;
    // Ten 8 ms stalls spread over the job (each longer than the 2 ms look-ahead), each
    // starting just before an event is queued: mid-motion.
    let stalls: Vec<Stall> = (1..=10)
        .map(|k| Stall {
            at: ev[ev.len() * k / 11].0 - lookahead - 1,
            len: 32_000,
        })
        .collect();

    // The old behaviour (late events at once) bursts: the model is not trivially safe.
    let old = fire_times(ev, lookahead, &stalls, None, &SMALL_JITTER);
    let (old_min, _) = spacing(ev, &old);
    assert!(
        (0..AXES).any(|a| old_min[a] < u64::from(cfg.min_period_ticks[a])),
        "{old_min:?}"
    );

    let mut r = Retimer::new(cfg);
    let new = fire_times(ev, lookahead, &stalls, Some(&mut r), &SMALL_JITTER);
    let (min_gap, worst_short) = spacing(ev, &new);
    for (a, (gap, floor)) in min_gap.iter().zip(cfg.min_period_ticks).enumerate() {
        assert!(*gap >= u64::from(cfg.min_step_ticks), "axis {a}: {gap}");
        // The floor less the slack, by design, though the model's latencies reach 40 ticks.
        assert!(
            gap + u64::from(SLACK) >= u64::from(floor),
            "axis {a}: {gap} < {floor}"
        );
    }
    // Never faster than planned by more than the latency the model adds and a drag within
    // the tolerance (an axis at its limit held back by latencies beyond the slack, on time
    // again once it slows down).
    assert!(
        worst_short <= u64::from(TOL) + 40,
        "{worst_short} ticks faster than planned"
    );
    // The first stall shifts the schedule; while it stays shifted the queue holds that much
    // more, so later stalls up to the shift are absorbed: fewer late events than stalls.
    let s = r.stats();
    assert!(s.late >= 1, "{s:?}");
    // The delay left is bounded by the stalls (80 ms) and the floors.
    let end_delay = new.last().unwrap() - t_end;
    assert!(end_delay <= 10 * 32_000 + 4 * 4000, "{end_delay}");
    println!(
        "{} events, 10 stalls of 8 ms: {} late, {} held to a floor, worst late {} us, \
         {:.1} ms behind the plan at the end; fire-at-once model: shortest X gap {} ticks",
        ev.len(),
        s.late,
        s.capped,
        s.worst_late_ticks * NS_PER_TICK / 1000,
        end_delay as f64 * NS_PER_TICK as f64 / 1e6,
        old_min[0]
    );
}

#[test]
fn without_stalls_nothing_is_shifted() {
    let ev = events();
    let mut r = Retimer::new(config(&MachineConfig::ENDER3));
    let fired = fire_times(
        ev,
        2_000_000 / NS_PER_TICK,
        &[],
        Some(&mut r),
        &SMALL_JITTER,
    );
    let drift = ev
        .iter()
        .zip(&fired)
        .map(|(e, f)| f - e.0)
        .max()
        .unwrap_or(0);
    println!("latencies within the slack: worst {drift} ticks behind the plan");
    assert!(drift <= u64::from(TOL), "{drift} ticks");
    assert_eq!(r.stats().late, 0);
    assert_eq!(r.shift_ticks(), 0);
}

/// What the look-ahead costs: the most events due within any window of that length on this
/// job (the queue must hold them), 16 bytes each in RAM; and the most the machine can produce
/// (every event steps the fastest axis at its limit).
#[test]
fn lookahead_cost_report() {
    let ev = events();
    let cfg = MachineConfig::ENDER3;
    let max_rate = Axis::ALL
        .into_iter()
        .map(|a| cfg.axis(a).steps_per_mm * cfg.axis(a).max_feed_mm_s)
        .fold(0.0f32, f32::max);
    for ms in [1u64, 2, 4, 6, 8] {
        let w = ms * 4000;
        let mut most = 0usize;
        let mut j = 0usize;
        for i in 0..ev.len() {
            while ev[i].0 - ev[j].0 > w {
                j += 1;
            }
            most = most.max(i - j + 1);
        }
        let worst = (max_rate as f64 * ms as f64 / 1000.0).ceil() as usize;
        println!(
            "look-ahead {ms} ms: job needs {most} entries ({} B), machine limit {worst} \
             entries ({} B)",
            most * 16,
            worst * 16
        );
        if ms <= 4 {
            // The board's 256 entries hold 4 ms at the machine's fastest event rate.
            assert!(
                worst <= QUEUE_LEN && most <= QUEUE_LEN,
                "{ms} ms: {most}, {worst}"
            );
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// Random stalls (1–20 ms, anywhere) and latencies: the floors and the planned spacing
    /// always hold.
    #[test]
    fn random_stalls_keep_the_limits(
        stalls in prop::collection::vec((0.0f64..1.0, 4_000u64..80_000), 0..12),
        jitter in prop::collection::vec(0u64..=40, 1..16),
    ) {
        let ev = events();
        let t_end = ev.last().unwrap().0;
        let stalls: Vec<Stall> = stalls
            .into_iter()
            .map(|(f, len)| Stall { at: (t_end as f64 * f) as u64, len })
            .collect();
        let cfg = config(&MachineConfig::ENDER3);
        let mut r = Retimer::new(cfg);
        let fired = fire_times(ev, 2_000_000 / NS_PER_TICK, &stalls, Some(&mut r), &jitter);
        let (min_gap, worst_short) = spacing(ev, &fired);
        for (gap, floor) in min_gap.iter().zip(cfg.min_period_ticks) {
            prop_assert!(*gap >= u64::from(cfg.min_step_ticks));
            prop_assert!(gap + u64::from(SLACK) >= u64::from(floor));
        }
        prop_assert!(worst_short <= u64::from(TOL) + 40);
    }
}
