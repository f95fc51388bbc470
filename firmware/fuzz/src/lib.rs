//! Shared harness of the fuzz targets: the real `Printer` on virtual time, fed through its
//! ports with flow control, heaters answered by a model (perfect, or a faulty sensor), every
//! step event checked. The targets: `executive.rs`, `host_stream.rs`, `parse_stream.rs`,
//! `card.rs` (card images).
//!
//! Invariants checked on every run (a panic is a finding):
//! - no panic anywhere (link, parser, executive, planner, step generator);
//! - every X/Y/Z step stays within the machine's travel (`min_mm..=max_mm`, ±1 step);
//! - no axis steps faster than its `max_feed_mm_s` (every 8 consecutive steps of one axis take
//!   at least `0.9 × 8 / (max_feed × steps/mm)`: single intervals carry the Bresenham jitter
//!   of multi-axis moves; the speed-up of a layer pause is capped at the limit too);
//! - no wedge: after the input, a final `M400` is answered (the `M118` after it is echoed), every pause reaches Paused (then it
//!   is resumed), and the printer comes to rest within a bounded virtual time;
//! - no heater is driven after a thermal fault (a sensor reading NaN, ±∞, or room temperature
//!   while heating).

mod card;
mod executive;
mod host_stream;
mod parse_stream;

pub use card::run_card_image;
pub use executive::{policy_of, run_executive, DICT, POLICIES};
pub use host_stream::{host_stream, run_host_stream, Noise, HOST_TIMEOUT_US, USER_RETRY_US};
pub use parse_stream::run_parse_stream;

use firmware::config::MachineConfig;
use firmware::link::PortId;
use firmware::motion::{Axis, Realtime, StepPos};
use firmware::planner::BlockKind;
use firmware::printer::{Policy, Printer, Record, State};
use firmware::thermal::HeaterId;

/// Steps over which an axis' speed is measured.
pub const SPEED_WINDOW: usize = 8;
/// Main-loop tick while moving, µs.
pub const TICK_US: u64 = 1000;
/// Tick while nothing moves (dwells, heater waits), µs.
pub const IDLE_TICK_US: u64 = 1_000_000;
/// How long a parked printer may take to answer an `M400` and an `M105` (every byte taken
/// before them): the parked intake's pace is at most 3 s a line (docs/frontend.md).
pub const PARKED_ANSWER_US: u64 = 10_000_000;
/// Longest dwell the parser allows is P1e7 ms (2.8 h): the final drain may take this long.
pub const DRAIN_LIMIT_US: u64 = 4 * 3600 * 1_000_000;

/// What a heater's temperature sensor reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sensor {
    /// The heater's target at once (ambient when off): a perfect heater.
    Perfect,
    /// A fault marker the board passes on: NaN (unreadable), +∞ (shorted), −∞ (open).
    Marker(f32),
    /// Fallen out of the heater block: room temperature whatever the heater does (the
    /// firmware must see the heating fail).
    Detached,
}

/// Room temperature of the heater model, °C.
pub const AMBIENT_C: f32 = 25.0;

/// The printer, its ports' senders and the checks.
pub struct Harness {
    pub p: Printer,
    pub cfg: MachineConfig,
    pub now_us: u64,
    /// Bytes written to each port and not yet taken (flow control).
    pub pending: [Vec<u8>; 2],
    /// What each port answered.
    pub out: [String; 2],
    /// Times of the last [`SPEED_WINDOW`] steps of each axis, ns (a ring).
    last_steps_ns: [[Option<u64>; SPEED_WINDOW]; 3],
    /// Steps seen per axis (ring position).
    steps_seen: [usize; 3],
    /// Position followed from the step events (X, Y, Z), steps.
    pos: StepPos,
    /// End positions of the job moves executed (their last segment), in order.
    pub executed: Vec<StepPos>,
    /// Pause states reached.
    pub paused: u32,
    /// The last state recorded.
    last_state: State,
    /// A `//action:cancel` was written since the last state record.
    cancel_announced: bool,
    /// Hot end and bed sensors.
    pub sensors: [Sensor; 2],
}

impl Harness {
    pub fn new() -> Self {
        Self::with_policy(Policy::FIRMWARE)
    }

    /// The printer with `policy` (the conventional-firmware models too).
    pub fn with_policy(policy: Policy) -> Self {
        let cfg = MachineConfig::ENDER3;
        Harness {
            p: Printer::with_policy(cfg, policy),
            cfg,
            now_us: 0,
            pending: [Vec::new(), Vec::new()],
            out: [String::new(), String::new()],
            last_steps_ns: [[None; SPEED_WINDOW]; 3],
            steps_seen: [0; 3],
            pos: [0; 4],
            executed: Vec::new(),
            paused: 0,
            last_state: State::Idle,
            cancel_announced: false,
            sensors: [Sensor::Perfect; 2],
        }
    }

    /// Write bytes to a port (they wait until the printer takes them).
    pub fn write(&mut self, port: PortId, bytes: &[u8]) {
        self.pending[port.index()].extend_from_slice(bytes);
        self.offer(port);
    }

    fn offer(&mut self, port: PortId) {
        let w = &mut self.pending[port.index()];
        if w.is_empty() {
            return;
        }
        let n = self.p.receive_on(port, w, self.now_us);
        assert!(n <= w.len());
        w.drain(..n);
    }

    pub fn request(&mut self, r: Realtime) {
        self.p.request(r, self.now_us);
    }

    /// One main-loop tick of `dt_us`.
    pub fn tick(&mut self, dt_us: u64) {
        for port in PortId::ALL {
            self.offer(port);
        }
        for (k, id) in [HeaterId::Hotend, HeaterId::Bed].into_iter().enumerate() {
            let t = self.p.thermal().target_c(id);
            let measured = match self.sensors[k] {
                // A perfect heater: at its target at once (ambient when off).
                Sensor::Perfect => t.max(AMBIENT_C),
                Sensor::Marker(v) => v,
                Sensor::Detached => AMBIENT_C,
            };
            let duty = self.p.heater_sample(id, measured, self.now_us);
            if let Some(f) = self.p.thermal().fault() {
                assert_eq!(duty, 0.0, "{id:?} driven at {duty} after the fault {f:?}");
            }
        }
        self.p.poll(self.now_us);
        let end_ns = (self.now_us + dt_us) * 1000;
        while let Some(t) = self.p.next_step_ns() {
            if t > end_ns {
                break;
            }
            let Some(ev) = self.p.next_step() else { break };
            self.check_step(ev.t_ns, ev.axis_mask, ev.dir_mask, ev.kind);
        }
        for port in PortId::ALL {
            let mut s = String::new();
            self.p.write_output_on(port, &mut s).unwrap();
            self.cancel_announced |= s.contains("//action:cancel");
            let o = &mut self.out[port.index()];
            o.push_str(&s);
            // Keep the tail only (memory stays flat over long runs).
            if o.len() > 8192 {
                let cut = o.len() - 4096;
                let cut = (cut..o.len()).find(|&i| o.is_char_boundary(i)).unwrap_or(0);
                o.drain(..cut);
            }
        }
        // After the output: a cancel's announcement is seen with its state record.
        while let Some(r) = self.p.pop_record() {
            match r {
                Record::Executed {
                    seg,
                    segs,
                    kind: BlockKind::Job,
                    pos,
                    ..
                } if seg + 1 == segs => self.executed.push(pos),
                Record::State { state, .. } => {
                    if state == State::Paused {
                        self.paused += 1;
                    }
                    let from_a_stop = matches!(
                        self.last_state,
                        State::Pausing | State::Paused | State::Resuming
                    );
                    if state == State::Cancelled && from_a_stop && self.cancel_announced {
                        // Issue 31: a cancel leaves nothing hot. Straight from its stop to
                        // Cancelled, no line was taken after the cancel's end (one taken
                        // then, such as a console's M104, may heat again; a withdrawn
                        // pause in a cancelled tail goes this way too, hence the
                        // announcement).
                        let t = self.p.thermal();
                        let targets = [HeaterId::Hotend, HeaterId::Bed].map(|id| t.target_c(id));
                        assert_eq!(targets, [0.0; 2], "heaters on after a cancel");
                        assert_eq!(self.p.fan_pwm(), 0, "fan on after a cancel");
                    }
                    self.last_state = state;
                    self.cancel_announced = false;
                }
                _ => {}
            }
        }
        self.now_us += dt_us;
    }

    fn check_step(&mut self, t_ns: u64, axis_mask: u8, dir_mask: u8, kind: BlockKind) {
        for (i, axis) in [Axis::X, Axis::Y, Axis::Z].into_iter().enumerate() {
            if axis_mask & (1 << i) == 0 {
                continue;
            }
            let a = self.cfg.axis(axis);
            self.pos[i] += if dir_mask & (1 << i) != 0 { 1 } else { -1 };
            // Homing runs towards the switch from an unknown place: only its speed is checked.
            if kind != BlockKind::Homing {
                let lo = (a.min_mm * a.steps_per_mm).floor() as i32 - 1;
                let hi = (a.max_mm * a.steps_per_mm).ceil() as i32 + 1;
                let p = self.p.status().position[i];
                assert!(
                    (lo..=hi).contains(&p),
                    "{axis:?} at {p} steps, outside {lo}..={hi}"
                );
            }
            // Over SPEED_WINDOW steps: one step's interval carries the Bresenham jitter of a
            // multi-axis move (up to one period of the fastest axis), the average does not.
            let min_ns = (0.9e9 * SPEED_WINDOW as f64
                / (a.max_feed_mm_s as f64 * a.steps_per_mm as f64)) as u64;
            let k = self.steps_seen[i] % SPEED_WINDOW;
            if let Some(old) = self.last_steps_ns[i][k] {
                let dt = t_ns.saturating_sub(old);
                assert!(
                    dt >= min_ns,
                    "{axis:?} made {SPEED_WINDOW} steps in {dt} ns (limit {min_ns} ns, {kind:?})"
                );
            }
            self.last_steps_ns[i][k] = Some(t_ns);
            self.steps_seen[i] += 1;
        }
    }

    /// Nothing moves, and either paused (the user's turn: bytes may wait behind a line that
    /// waits for the resume, e.g. an M400) or done with every byte taken.
    fn at_rest(&mut self) -> bool {
        if self.p.next_step_ns().is_some() {
            return false;
        }
        match self.p.status().state {
            State::Paused => true,
            State::Idle | State::Cancelled | State::Halted => {
                self.pending.iter().all(|w| w.is_empty())
            }
            _ => false,
        }
    }

    /// Run until at rest or `limit_us` more virtual time; true when at rest.
    pub fn run_to_rest(&mut self, limit_us: u64) -> bool {
        let end = self.now_us + limit_us;
        while self.now_us < end {
            let dt = if self.p.next_step_ns().is_some() {
                TICK_US
            } else {
                IDLE_TICK_US
            };
            self.tick(dt);
            if self.at_rest() {
                // Once more: answers owed at rest (M400) are written on the next poll.
                self.tick(TICK_US);
                if self.at_rest() {
                    return true;
                }
            }
        }
        false
    }

    /// Run to rest, resuming every pause (the user's button), up to [`RESUMES`] times; the
    /// state reached, or `None` when the printer was still pausing again after them (a job
    /// with more `M0`/`M600` stops than that: each is a stop for the user, not a wedge).
    /// Panics when the printer does not come to rest (a wedge).
    fn settle(&mut self) -> Option<State> {
        for _ in 0..RESUMES {
            let rest = self.run_to_rest(DRAIN_LIMIT_US);
            let st = self.p.status().state;
            assert!(
                rest,
                "wedged: state {st:?}, pending {:?}",
                self.pending.iter().map(Vec::len).collect::<Vec<_>>()
            );
            if st != State::Paused {
                return Some(st);
            }
            self.request(Realtime::Resume);
        }
        None
    }

    /// Issue 31: parked, a host's `M400` and `M105` (unnumbered: a console's; manual lines for
    /// a host that numbers its job) get their answers within [`PARKED_ANSWER_US`], plus 3 s
    /// for each of up to 8 lines still waiting before them; before, an M400 answered `busy:
    /// paused for user` for ever.
    pub fn answers_while_parked(&mut self) {
        if !self.run_to_rest(DRAIN_LIMIT_US) || self.p.status().state != State::Paused {
            return;
        }
        // Lines still waiting (flow control) are read first, each within the parked intake's
        // pace; behind many of them the RAM fallback without a card may end the intake
        // (docs/frontend.md): not judged here.
        let waiting = self.pending[0].iter().filter(|&&b| b == b'\n').count() as u64;
        if waiting > 8 || !self.pending[1].is_empty() {
            return;
        }
        let limit_us = PARKED_ANSWER_US + waiting * 3_000_000;
        // Only the answers from here on are looked at. The M105 is read only after the
        // M400's `ok` (an owed M400 holds the next line), so its `ok T:` answers both.
        self.out[0].clear();
        self.write(PortId::Usb, b"\nM400\nM105\n");
        let start = self.now_us;
        let mut answered = false;
        while self.now_us - start < limit_us {
            self.tick(TICK_US);
            if self.out[0].contains("ok T:") {
                answered = true;
                break;
            }
            if self.p.status().state != State::Paused {
                return;
            }
        }
        assert!(
            answered,
            "parked: M400/M105 not answered within {limit_us} µs: {:?}",
            self.out[0]
        );
    }

    /// The end of a run: a final `M400` on the USB port, every pause resumed, and the checks
    /// that nothing is wedged.
    pub fn finish(&mut self) {
        // Every byte of the input taken first, pauses resumed: while paused, bytes may still
        // wait (flow control), among them an `M524`, and a final `M400` queued behind it would
        // be part of the cancelled job.
        if self.settle().is_none() {
            return;
        }
        // After a cancel the printer discards the rest of a streamed job until the host starts
        // anew (docs/frontend.md "Cancel": a line after 2 s of host silence): stay silent for
        // 3 s, as a host starting a new job does.
        for _ in 0..3 {
            self.tick(IDLE_TICK_US);
        }
        // The M118 is taken only after the M400 has been answered (M400 holds the next line).
        self.write(PortId::Usb, b"\nM400\nM118 fuzz-end\n");
        let Some(st) = self.settle() else {
            return;
        };
        assert_ne!(st, State::Paused, "still paused after resumes");
        if st != State::Halted {
            let usb = &self.out[0];
            assert!(
                usb.contains("fuzz-end"),
                "the final M400 was not answered: {usb:?}"
            );
        }
    }
}

/// Pauses the harness resumes at the end of a run ([`Harness::settle`]): a job's `M0` lines
/// (the `executive` dictionary has one) each stop for the user again. Found when issue 27 kept
/// the `M0`s streamed into a parked printer for after the resume: the 120 of
/// `finds/executive/many-m0-aec8569a` outlasted the 8 resumes of before (replayed whole now;
/// an input with more stops than this is not judged at its end).
const RESUMES: usize = 256;

impl Default for Harness {
    fn default() -> Self {
        Self::new()
    }
}

/// The fuzz targets, by name (`fuzz_targets/<name>.rs`, `seeds/<name>/`, `finds/<name>/`).
pub const TARGETS: [&str; 4] = ["parse_stream", "executive", "host_stream", "card_image"];

/// Run one input through the named target's checks (the regression test replays the committed
/// inputs with this).
pub fn run_target(target: &str, data: &[u8]) {
    match target {
        "parse_stream" => run_parse_stream(data),
        "executive" => run_executive(data),
        "host_stream" => run_host_stream(data),
        "card_image" => run_card_image(data),
        other => panic!("unknown fuzz target {other}"),
    }
}
