//! G28 as the SKR 2 image runs it, without the board: the executive (`Printer`) homes through
//! the planner while a model of the board's step interrupt runs its events from a queue filled
//! up to 2 ms ahead (`board::stepper`'s `LOOKAHEAD_NS`), with the same portable pieces the image
//! uses: `StepExecutor` (homed axes, limits, `fire_homing`), `EndstopWatch` (the approach's
//! switch read before each event, the rest dropped and counted), and the motion loop's calls
//! (`endstop_trip`, `sample_endstops`, `set_steps_in_flight`, `take_homed`/`homed_axes`) in
//! `main.rs`'s order. The machine is a [`World`]: true positions, each minimum switch pressed
//! at and below a known true position.
//!
//! Shared source: `checks.rs` runs [`run`] on the emulated Cortex-M4 and on the host
//! (`scripts/qemu-test.sh`), and `firmware/tests/homing.rs` includes this file and runs it in
//! `cargo test`. No allocation (heapless), so it runs on the emulated core.

use core::convert::Infallible;
use embedded_hal::digital::{ErrorType, OutputPin};
use firmware::config::MachineConfig;
use firmware::drivers::homing_watch::{EndstopWatch, EventFlags};
use firmware::drivers::{StepExecutor, StepperPins};
use firmware::homing::{Endstops, HomingConfig};
use firmware::motion::Axis;
use firmware::printer::{Printer, State};

/// How far ahead the motion loop queues events, ns (as the board).
pub const LOOKAHEAD_NS: u64 = 2_000_000;
/// Events the queue holds (as the board).
const QUEUE_LEN: usize = 256;
/// Output kept per run (more is counted, not kept).
const OUT_LEN: usize = 2048;

/// A failed check: what was expected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Failed(pub &'static str);

fn check(ok: bool, what: &'static str) -> Result<(), Failed> {
    if ok {
        Ok(())
    } else {
        Err(Failed(what))
    }
}

/// A pin that goes nowhere (the world moves by what `StepExecutor` reports as stepped).
struct NullPin;

impl ErrorType for NullPin {
    type Error = Infallible;
}

impl OutputPin for NullPin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

/// The machine: where X, Y, Z really are (steps), and where their switches close.
#[derive(Clone, Copy, Debug)]
pub struct World {
    /// True positions.
    pub real: [i32; 3],
    /// Each switch is pressed at and below this true position (`None`: never).
    pub switch: [Option<i32>; 3],
}

impl Endstops for World {
    fn triggered(&mut self, axis: Axis) -> bool {
        let i = axis.index();
        match (self.switch.get(i), self.real.get(i)) {
            (Some(Some(s)), Some(r)) => r <= s,
            _ => false,
        }
    }
}

#[derive(Clone, Copy)]
struct Ev {
    t_ns: u64,
    axis_mask: u8,
    dir_mask: u8,
    flags: EventFlags,
}

/// The board model around a printer.
pub struct Board {
    /// The executive.
    pub p: Printer,
    /// The machine.
    pub w: World,
    exec: StepExecutor<NullPin>,
    watch: EndstopWatch,
    queue: heapless::Deque<Ev, QUEUE_LEN>,
    held: Option<Ev>,
    home: [i32; 3],
    /// Board time, µs.
    pub now_us: u64,
    /// Approaches the step interrupt stopped at their switch.
    pub trips: u32,
    /// Highest true Z before X or Y first moved.
    pub z_peak_before_xy: i32,
    xy_moved: bool,
    /// The host-link output (the first `OUT_LEN` bytes).
    pub out: heapless::String<OUT_LEN>,
}

impl Board {
    /// An Ender-3 executive with endstops, cold extrusion allowed, and the machine `w`.
    pub fn new(w: World) -> Self {
        let cfg = MachineConfig::ENDER3;
        let steps = |a: Axis, mm: f32| libm::roundf(mm * cfg.axis(a).steps_per_mm) as i32;
        let limits = [Axis::X, Axis::Y, Axis::Z]
            .map(|a| (steps(a, cfg.axis(a).min_mm), steps(a, cfg.axis(a).max_mm)));
        let pins = StepperPins::new(
            [NullPin, NullPin, NullPin, NullPin],
            [NullPin, NullPin, NullPin, NullPin],
            [NullPin, NullPin, NullPin, NullPin],
            cfg.dir_high_positive_mask(),
        );
        let mut exec = StepExecutor::new(pins);
        exec.limits = limits;
        exec.pins.set_enabled(true);
        // The executive is built in place (it is large: no copies on the emulated stack).
        let mut b = Board {
            p: Printer::new(cfg),
            w,
            exec,
            watch: EndstopWatch::new(),
            queue: heapless::Deque::new(),
            held: None,
            home: limits.map(|(min, _)| min),
            now_us: 0,
            trips: 0,
            z_peak_before_xy: w.real[2],
            xy_moved: false,
            out: heapless::String::new(),
        };
        b.p.enable_endstops(HomingConfig::ENDER3);
        b.p.extrusion_guard_mut().allow_cold = true;
        b
    }

    /// Position the step interrupt believes (steps).
    pub fn isr_pos(&self) -> [i32; 3] {
        [self.exec.pos[0], self.exec.pos[1], self.exec.pos[2]]
    }

    /// Watch for the highest Z again, until X or Y next move.
    pub fn watch_z_raise(&mut self) {
        self.xy_moved = false;
        self.z_peak_before_xy = self.w.real[2];
    }

    /// Steps the interrupt refused (a homed axis outside its limits).
    pub fn refused(&self) -> u32 {
        self.exec.refused
    }

    /// One 1 ms tick: the interrupt's due events, then the motion loop.
    pub fn tick(&mut self) {
        let now_ns = self.now_us * 1000;
        // The step interrupt.
        while self.queue.front().is_some_and(|e| e.t_ns <= now_ns) {
            let Some(ev) = self.queue.pop_front() else {
                break;
            };
            if !self
                .watch
                .admit(ev.flags, ev.axis_mask, ev.dir_mask, &mut self.w)
            {
                self.drop_queued();
                break;
            }
            let stepped = if ev.flags.homing() {
                self.exec
                    .fire_homing(ev.axis_mask, ev.dir_mask, 650, 1000, |_| {})
            } else {
                self.exec.fire(ev.axis_mask, ev.dir_mask, 650, 1000, |_| {})
            };
            for i in 0..3 {
                if stepped & (1 << i) != 0 {
                    self.w.real[i] += if ev.dir_mask & (1 << i) != 0 { 1 } else { -1 };
                    if i < 2 {
                        self.xy_moved = true;
                    }
                }
            }
            if !self.xy_moved {
                self.z_peak_before_xy = self.z_peak_before_xy.max(self.w.real[2]);
            }
        }
        // The motion loop (main.rs: homing_before_poll, poll, homing_after_poll, feed_steps).
        if self.watch.tripped() {
            self.drop_queued();
            if let Some(mut trip) = self.watch.take() {
                if let Some(ev) = self.held.take() {
                    trip.add(ev.axis_mask, ev.dir_mask);
                }
                self.trips += 1;
                self.p.endstop_trip(trip.axis, trip.undone);
            }
        }
        self.p.sample_endstops(&mut self.w);
        let in_flight = !self.queue.is_empty() || self.held.is_some();
        self.p.set_steps_in_flight(in_flight);
        self.p.poll(self.now_us);
        let fresh = self.p.take_homed();
        self.exec.set_homed(self.p.homed_axes(), fresh, self.home);
        if self.p.state() == State::Halted {
            self.queue.clear();
            self.held = None;
        } else {
            self.feed(now_ns);
        }
        let mut buf = [0u8; 256];
        loop {
            let n = self.p.read_output(&mut buf);
            if n == 0 {
                break;
            }
            for &b in buf.get(..n).unwrap_or(&[]) {
                let _ = self.out.push(char::from(b));
            }
        }
        self.now_us += 1000;
    }

    fn drop_queued(&mut self) {
        while let Some(ev) = self.queue.pop_front() {
            let _ = self
                .watch
                .admit(ev.flags, ev.axis_mask, ev.dir_mask, &mut self.w);
        }
    }

    fn feed(&mut self, now_ns: u64) {
        if let Some(ev) = self.held.take() {
            if let Err(ev) = self.queue.push_back(ev) {
                self.held = Some(ev);
                return;
            }
        }
        while !self.queue.is_full() {
            let Some(t) = self.p.next_step_ns() else {
                break;
            };
            if t > now_ns + LOOKAHEAD_NS {
                break;
            }
            let Some(ev) = self.p.next_step() else {
                break;
            };
            let e = Ev {
                t_ns: ev.t_ns,
                axis_mask: ev.axis_mask,
                dir_mask: ev.dir_mask,
                flags: EventFlags::of(self.p.homing_watch(), &ev),
            };
            if let Err(e) = self.queue.push_back(e) {
                self.held = Some(e);
                break;
            }
        }
    }

    /// Sends `line` (one line, newline added) and ticks until its `ok` and the motion it
    /// started are over, or `limit_us` passes. False on the time limit.
    pub fn run_line(&mut self, line: &str, limit_us: u64) -> bool {
        let mut l: heapless::String<96> = heapless::String::new();
        let _ = l.push_str(line);
        let _ = l.push('\n');
        let oks = self.count("ok");
        let _ = self.p.receive(l.as_bytes(), self.now_us);
        let end = self.now_us + limit_us;
        while self.now_us < end {
            self.tick();
            let idle = matches!(self.p.state(), State::Idle | State::Halted)
                && self.p.next_step_ns().is_none()
                && self.queue.is_empty();
            if (self.count("ok") > oks || self.p.state() == State::Halted) && idle {
                return true;
            }
        }
        false
    }

    /// Sends realtime bytes (e.g. `M112\n`) now.
    pub fn send(&mut self, bytes: &str) {
        let _ = self.p.receive(bytes.as_bytes(), self.now_us);
    }

    /// Lines of the output equal to `line`.
    pub fn count(&self, line: &str) -> usize {
        self.out
            .lines()
            .filter(|l| *l == line || (line == "ok" && l.starts_with("ok")))
            .count()
    }

    /// Forget the output so far.
    pub fn clear_output(&mut self) {
        self.out.clear();
    }
}

/// The checks, in groups. Returns the number of groups passed. One board at a time (each
/// group in its own frame: a `Board` holds a whole executive, and the emulated core's stack
/// is small).
pub fn run() -> Result<u32, Failed> {
    g28_and_m119()?;
    m112_during_homing()?;
    switch_missing_or_far()?;
    Ok(3)
}

/// G28 from anywhere: Z raised, each axis stopped exactly at its switch, twice; moves run
/// before it (from where the axes stood) and after it; M119; a second G28 homes again.
#[inline(never)]
fn g28_and_m119() -> Result<(), Failed> {
    // X 30 mm, Y 20 mm, Z 5 mm out; the switches at odd true positions.
    let mut b = Board::new(World {
        real: [2400, 1600, 2000],
        switch: [Some(-37), Some(11), Some(-3)],
    });
    // Before homing X/Y/Z move as Marlin's default moves them (no NO_MOTION_BEFORE_HOMING):
    // from where they stood, the executive's 0 (the limits guard homed axes only).
    check(b.run_line("G1 X10 F3000", 5_000_000), "G1 before G28 ends")?;
    check(b.refused() == 0, "steps before homing are taken")?;
    check(b.w.real[0] == 2400 + 800, "X moved 10 mm before homing")?;
    // G28's own Z raise comes before its X and Y: watched from here.
    b.watch_z_raise();
    check(b.run_line("G28", 60_000_000), "G28 ends within 60 s")?;
    check(!b.out.contains("Error"), "G28 without an error")?;
    check(
        b.w.real == [-37, 11, -3],
        "each axis stopped exactly at its switch",
    )?;
    check(
        b.p.status().position[..3] == [0, 0, 0],
        "the executive is at the minimum",
    )?;
    check(
        b.isr_pos() == [0, 0, 0],
        "the step interrupt is at the minimum",
    )?;
    check(b.p.homed_axes() == 0b111, "X, Y, Z homed")?;
    check(
        b.trips == 6,
        "fast and slow approach of each axis stop at the switch",
    )?;
    check(
        b.z_peak_before_xy == 2000 + 4 * 400,
        "Z raised 4 mm before X and Y",
    )?;
    // Homed: moves run, within the limits.
    check(
        b.run_line("G1 X10 Y5 F3000", 5_000_000),
        "G1 after G28 ends",
    )?;
    check(
        b.w.real[0] == -37 + 800 && b.w.real[1] == 11 + 400,
        "a move after homing runs from the switch",
    )?;
    // M119 as Marlin prints it.
    b.clear_output();
    check(b.run_line("G1 X0 Y0 Z5", 10_000_000), "back to X0 Y0 Z5")?;
    check(b.run_line("M119", 1_000_000), "M119 answers")?;
    check(
        b.count("Reporting endstop status") == 1
            && b.count("x_min: TRIGGERED") == 1
            && b.count("y_min: TRIGGERED") == 1
            && b.count("z_min: open") == 1,
        "M119 lines as Marlin's",
    )?;
    // A second G28 homes again (never skipped), from where the axes are.
    check(b.run_line("G1 X10", 5_000_000), "X out to 10 mm")?;
    b.clear_output();
    check(b.run_line("G28 X", 30_000_000), "G28 X ends")?;
    check(b.trips == 8, "G28 X at X0 still approaches twice")?;
    check(b.w.real[0] == -37, "X homed again at its switch")?;
    Ok(())
}

/// M112 during the Z approach: stepping stops within the queued 2 ms.
#[inline(never)]
fn m112_during_homing() -> Result<(), Failed> {
    let mut b = Board::new(World {
        real: [0, 0, 40_000],
        switch: [Some(0), Some(0), Some(0)],
    });
    let _ = b.p.receive(b"G28 Z\n", 0);
    for _ in 0..3000 {
        b.tick();
    }
    let z_at_kill = b.w.real[2];
    b.send("M112\n");
    for _ in 0..100 {
        b.tick();
    }
    check(b.p.state() == State::Halted, "M112 halts during homing")?;
    check(
        z_at_kill < 40_000 + 1600 && (z_at_kill - b.w.real[2]).abs() <= 8,
        "M112 stops Z within the queued 2 ms",
    )?;
    Ok(())
}

/// A switch that never closes: the approach runs 1.5 × the travel, then a clear error. A switch
/// reached by the search's last step still counts.
#[inline(never)]
fn switch_missing_or_far() -> Result<(), Failed> {
    let mut b = Board::new(World {
        real: [0, 0, 0],
        switch: [None, Some(0), Some(0)],
    });
    check(
        b.run_line("G28 X", 60_000_000),
        "G28 X without a switch ends",
    )?;
    check(
        b.out
            .contains("Error:Homing Failed: X endstop not hit within 352 mm"),
        "missing switch reported",
    )?;
    check(b.p.state() == State::Halted, "a failed homing halts")?;
    drop(b);
    // A switch reached by the search's last step (1.5 × 235 mm = 28,200 steps): the approach
    // is decided only once its last queued steps have run, so it counts.
    let mut b = Board::new(World {
        real: [28_199, 0, 0],
        switch: [Some(0), Some(0), Some(0)],
    });
    check(
        b.run_line("G28 X", 60_000_000),
        "G28 X from the far end ends",
    )?;
    check(
        !b.out.contains("Error"),
        "a switch on the search's last step is found",
    )?;
    check(b.w.real[0] == 0, "X homed at the switch from the far end")?;
    Ok(())
}
