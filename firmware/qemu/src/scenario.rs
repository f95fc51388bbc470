//! The scenario shared by the host (build.rs computes the expected digest) and the emulated
//! Cortex-M4 (main.rs recomputes it and compares): a small four-layer print — perimeters with
//! extrusion, travels, Z steps and PrusaSlicer-style layer comments — streamed as G-code text
//! through the host link the way Pronterface does (send a line, wait for `ok`), with
//! `M601` (pause at the layer boundary) and `M602` (resume) in layer 2 and `M601 S1` (pause
//! now) and `M602` in layer 4, run through the firmware's executive (`Printer`) on virtual
//! time, 1 ms main-loop ticks, stepping every event on time.
//!
//! The digest is FNV-1a over every step event (time in ns, axis mask, direction mask), plus the
//! number of events, executed blocks and host-link lines and the final position.

use core::fmt::Write as _;
use firmware::config::MachineConfig;
use firmware::motion::{Axis, StepPos};
use firmware::printer::{Printer, Record, State};

/// Main-loop tick: commands are pushed and `poll` runs once per tick; step events are pulled
/// for each tick's window, as the board's timer interrupt would.
pub const TICK_US: u64 = 1000;
/// Give up after this much virtual time (a hang is a failure, not an endless run).
pub const LIMIT_US: u64 = 600_000_000;

/// Layers printed.
pub const LAYERS: u32 = 4;
/// Side of the printed square, mm.
pub const SIDE_MM: f32 = 20.0;
/// Perimeters per layer (each 1 mm inside the last).
pub const PERIMETERS: u32 = 2;

/// The result both sides must agree on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Digest {
    /// FNV-1a 64 over every step event.
    pub hash: u64,
    /// Step events.
    pub events: u32,
    /// Executed planner blocks (segments).
    pub blocks: u32,
    /// Host-link lines the printer wrote.
    pub lines: u32,
    /// Position at the end, steps.
    pub final_pos: StepPos,
}

/// Why the scenario did not finish.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScenarioError {
    /// Did not reach the end within [`LIMIT_US`] of virtual time.
    Timeout {
        /// State when it gave up.
        state: State,
        /// Script item it was at.
        item: u32,
    },
    /// Ended away from the last target.
    WrongEnd,
    /// The printer did not take a whole line from a host that waits for `ok` (flow control
    /// must never hold such a line back).
    LineNotTaken {
        /// Script item it was at.
        item: u32,
    },
}

/// What is being measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Work {
    /// Handing commands and realtime requests to the printer (`push_command`, `request`):
    /// segmenting and planning with lookahead happen here and in `poll`.
    Plan,
    /// The main loop's `poll` once per tick (feeding the planner, the pause state machine).
    Poll,
    /// Taking one step event (`next_step_ns` + `next_step`; loading the next block included).
    Step,
    /// The timer's look at the next event time when it lies beyond the current tick.
    Peek,
}

/// Instruction or cycle counting hooks (no-ops on the host).
pub trait Meter {
    /// Start measuring.
    fn begin(&mut self);
    /// Stop measuring and book the interval to `work`.
    fn end(&mut self, work: Work);
}

/// The host's meter: measures nothing.
pub struct NoMeter;

impl Meter for NoMeter {
    fn begin(&mut self) {}
    fn end(&mut self, _work: Work) {}
}

/// Longest line the script writes.
const LINE: usize = 64;

/// One G-code line (no allocation).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Line {
    buf: [u8; LINE],
    len: usize,
}

impl core::fmt::Write for Line {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        let end = self.len + s.len();
        let dst = self.buf.get_mut(self.len..end).ok_or(core::fmt::Error)?;
        dst.copy_from_slice(s.as_bytes());
        self.len = end;
        Ok(())
    }
}

impl Line {
    fn new(args: core::fmt::Arguments) -> Self {
        let mut l = Line {
            buf: [0; LINE],
            len: 0,
        };
        let _ = l.write_fmt(args);
        let _ = l.write_str("\n");
        l
    }

    fn bytes(&self) -> &[u8] {
        self.buf.get(..self.len).unwrap_or(&[])
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Item {
    /// Send a line and wait for its `ok`.
    Send(Line),
    WaitPaused,
    WaitUs(u64),
}

/// The script: an iterator of items computed from the part's geometry (no allocation).
struct Script {
    i: u32,
    e_mm: f32,
    /// Queue of up to 8 items produced by one `i`.
    buf: [Option<Item>; 8],
    head: usize,
}

impl Script {
    fn new() -> Self {
        Script {
            i: 0,
            e_mm: 0.0,
            buf: [None; 8],
            head: 8,
        }
    }

    fn mv(&mut self, x: f32, y: f32, z: f32, e: f32, feed_mm_s: f32) -> Item {
        Item::Send(Line::new(format_args!(
            "G1 X{x:.3} Y{y:.3} Z{z:.3} E{e:.5} F{:.0}",
            feed_mm_s * 60.0
        )))
    }

    fn send(args: core::fmt::Arguments) -> Item {
        Item::Send(Line::new(args))
    }

    /// Produces the items of script step `i` into `buf`; false when the script is over.
    fn fill(&mut self) -> bool {
        let mut items: [Option<Item>; 8] = [None; 8];
        if self.i == 0 {
            items[0] = Some(Self::send(format_args!("M110 N0")));
            items[1] = Some(Self::send(format_args!("G21")));
            items[2] = Some(Self::send(format_args!("G90")));
            items[3] = Some(Self::send(format_args!("M82")));
            items[4] = Some(Self::send(format_args!("G28")));
            items[5] = Some(Self::send(format_args!("G92 E0")));
            self.buf = items;
            self.head = 0;
            self.i += 1;
            return true;
        }
        let step = self.i - 1;
        let per_layer = 2 + PERIMETERS * 5;
        let layer = step / per_layer;
        let k = step % per_layer;
        if layer >= LAYERS {
            return false;
        }
        let z = 0.2 + 0.2 * layer as f32;
        match k {
            0 => {
                items[0] = Some(Self::send(format_args!(";LAYER_CHANGE")));
                items[1] = Some(Self::send(format_args!(";Z:{z:.1}")));
                items[2] = Some(self.mv(10.0, 10.0, z, self.e_mm, 5.0));
            }
            1 => {
                // Retract-free travel to the first perimeter's corner.
                items[0] = Some(self.mv(10.0, 10.0, z, self.e_mm, 120.0));
                if layer == 2 {
                    // The operator asks for a pause at the layer boundary early in layer 2.
                    items[1] = Some(Self::send(format_args!("M601")));
                    items[2] = Some(Item::WaitPaused);
                    items[3] = Some(Item::WaitUs(2_000_000));
                    items[4] = Some(Self::send(format_args!("M602")));
                }
            }
            _ => {
                let idx = k - 2;
                let perimeter = idx / 5;
                let corner = idx % 5;
                let inset = perimeter as f32;
                let (x0, y0) = (10.0 + inset, 10.0 + inset);
                let side = SIDE_MM - 2.0 * inset;
                let (x, y) = match corner {
                    0 => (x0, y0),
                    1 => (x0 + side, y0),
                    2 => (x0 + side, y0 + side),
                    3 => (x0, y0 + side),
                    _ => (x0, y0),
                };
                let (feed, extrude) = if corner == 0 {
                    (120.0, false)
                } else {
                    (40.0, true)
                };
                if extrude {
                    // 0.4 × 0.2 mm line from 1.75 mm filament: 0.0333 mm of filament per mm.
                    self.e_mm += side * 0.0333;
                }
                let e = self.e_mm;
                items[0] = Some(self.mv(x, y, z, e, feed));
                if layer == 3 && perimeter == 0 && corner == 2 {
                    // Pause now, in the middle of the perimeter.
                    items[1] = Some(Self::send(format_args!("M601 S1")));
                    items[2] = Some(Item::WaitPaused);
                    items[3] = Some(Item::WaitUs(1_000_000));
                    items[4] = Some(Self::send(format_args!("M602")));
                }
            }
        }
        self.buf = items;
        self.head = 0;
        self.i += 1;
        true
    }

    fn next(&mut self) -> Option<Item> {
        loop {
            while self.head < self.buf.len() {
                let it = self.buf[self.head].take();
                self.head += 1;
                if it.is_some() {
                    return it;
                }
            }
            if !self.fill() {
                return None;
            }
        }
    }
}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

fn fnv(hash: &mut u64, bytes: &[u8]) {
    for b in bytes {
        *hash ^= u64::from(*b);
        *hash = hash.wrapping_mul(FNV_PRIME);
    }
}

/// Runs the scenario; `meter` is told where the time goes. Never inlined into its caller, so
/// the code measured does not depend on what else the binary contains.
#[inline(never)]
pub fn run(meter: &mut impl Meter) -> Result<Digest, ScenarioError> {
    let cfg = MachineConfig::ENDER3;
    let mut p = Printer::new(cfg);
    let mut script = Script::new();
    let mut pending: Option<Item> = None;
    let mut wait_until: Option<u64> = None;
    let mut digest = Digest {
        hash: FNV_OFFSET,
        events: 0,
        blocks: 0,
        lines: 0,
        final_pos: [0; 4],
    };
    let mut now: u64 = 0;
    let mut script_done = false;
    let mut item_no: u32 = 0;
    // The host's side of the link: waiting for an `ok`, and the start of the line being read.
    let mut awaiting_ok = false;
    let mut col = 0usize;
    let mut head = [0u8; 2];
    let mut out = [0u8; 256];
    loop {
        if now > LIMIT_US {
            return Err(ScenarioError::Timeout {
                state: p.state(),
                item: item_no,
            });
        }
        // The host (and the operator) feed the printer as far as it accepts.
        while !script_done {
            let item = match pending.take().or_else(|| script.next()) {
                Some(i) => i,
                None => {
                    script_done = true;
                    break;
                }
            };
            let done = match item {
                Item::Send(line) => {
                    if awaiting_ok {
                        false
                    } else {
                        meter.begin();
                        let taken = p.receive(line.bytes(), now);
                        meter.end(Work::Plan);
                        if taken < line.bytes().len() {
                            return Err(ScenarioError::LineNotTaken { item: item_no });
                        }
                        awaiting_ok = true;
                        true
                    }
                }
                Item::WaitPaused => p.state() == State::Paused,
                Item::WaitUs(us) => {
                    let until = *wait_until.get_or_insert(now + us);
                    if now >= until {
                        wait_until = None;
                        true
                    } else {
                        false
                    }
                }
            };
            if !done {
                pending = Some(item);
                break;
            }
            item_no += 1;
        }
        meter.begin();
        p.poll(now);
        meter.end(Work::Poll);
        // Read what the printer answered: count lines, notice `ok`.
        loop {
            let n = p.read_output(&mut out);
            if n == 0 {
                break;
            }
            for &b in out.get(..n).unwrap_or(&[]) {
                if b == b'\n' {
                    if head == *b"ok" {
                        awaiting_ok = false;
                    }
                    digest.lines += 1;
                    col = 0;
                    head = [0; 2];
                } else {
                    if let Some(h) = head.get_mut(col) {
                        *h = b;
                    }
                    col += 1;
                }
            }
        }
        // The step timer: every event due in this tick.
        let horizon_ns = (now + TICK_US) * 1000;
        loop {
            meter.begin();
            let due = matches!(p.next_step_ns(), Some(t) if t <= horizon_ns);
            let ev = if due { p.next_step() } else { None };
            meter.end(if ev.is_some() { Work::Step } else { Work::Peek });
            let Some(ev) = ev else { break };
            digest.events += 1;
            fnv(&mut digest.hash, &ev.t_ns.to_le_bytes());
            fnv(&mut digest.hash, &[ev.axis_mask, ev.dir_mask]);
        }
        while let Some(r) = p.pop_record() {
            if let Record::Executed { .. } = r {
                digest.blocks += 1;
            }
        }
        now += TICK_US;
        if script_done && !awaiting_ok && p.state() == State::Idle && p.next_step_ns().is_none() {
            break;
        }
    }
    digest.final_pos = p.status().position;
    if digest.final_pos[0] != libm::roundf(11.0 * cfg.axis(Axis::X).steps_per_mm) as i32 {
        return Err(ScenarioError::WrongEnd);
    }
    Ok(digest)
}
