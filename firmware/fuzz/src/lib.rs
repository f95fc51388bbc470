//! Shared harness of the fuzz targets: the real `Printer` on virtual time, fed through its
//! ports with flow control, heaters answered by a perfect model, every step event checked.
//!
//! Invariants checked on every run (a panic is a finding):
//! - no panic anywhere (link, parser, executive, planner, step generator);
//! - every X/Y/Z step stays within the machine's travel (`min_mm..=max_mm`, ±1 step);
//! - no axis steps faster than its `max_feed_mm_s` (every 8 consecutive steps of one axis take
//!   at least `0.9 × 8 / (max_feed × steps/mm)`: single intervals carry the Bresenham jitter
//!   of multi-axis moves; the speed-up of a layer pause is capped at the limit too);
//! - no wedge: after the input, a final `M400` is answered (the `M118` after it is echoed), every pause reaches Paused (then it
//!   is resumed), and the printer comes to rest within a bounded virtual time.

use firmware::config::MachineConfig;
use firmware::gcode::parse_line;
use firmware::link::{HostLink, PortId, Response, LINE_CAP, LINE_QUEUE};
use firmware::machine::{Action, Interpreter};
use firmware::motion::{Axis, PauseMode, Realtime, StepPos};
use firmware::planner::BlockKind;
use firmware::printer::{Printer, Record, State};
use firmware::thermal::HeaterId;

/// Steps over which an axis' speed is measured.
pub const SPEED_WINDOW: usize = 8;
/// Main-loop tick while moving, µs.
pub const TICK_US: u64 = 1000;
/// Tick while nothing moves (dwells, heater waits), µs.
pub const IDLE_TICK_US: u64 = 1_000_000;
/// Longest dwell the parser allows is P1e7 ms (2.8 h): the final drain may take this long.
pub const DRAIN_LIMIT_US: u64 = 4 * 3600 * 1_000_000;

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
}

impl Harness {
    pub fn new() -> Self {
        let cfg = MachineConfig::ENDER3;
        Harness {
            p: Printer::new(cfg),
            cfg,
            now_us: 0,
            pending: [Vec::new(), Vec::new()],
            out: [String::new(), String::new()],
            last_steps_ns: [[None; SPEED_WINDOW]; 3],
            steps_seen: [0; 3],
            pos: [0; 4],
            executed: Vec::new(),
            paused: 0,
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
        for id in [HeaterId::Hotend, HeaterId::Bed] {
            // A perfect heater: at its target at once (ambient when off).
            let t = self.p.thermal().target_c(id);
            let measured = if t > 25.0 { t } else { 25.0 };
            self.p.heater_sample(id, measured, self.now_us);
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
        while let Some(r) = self.p.pop_record() {
            match r {
                Record::Executed {
                    seg,
                    segs,
                    kind: BlockKind::Job,
                    pos,
                    ..
                } if seg + 1 == segs => self.executed.push(pos),
                Record::State {
                    state: State::Paused,
                    ..
                } => self.paused += 1,
                _ => {}
            }
        }
        for port in PortId::ALL {
            let mut s = String::new();
            self.p.write_output_on(port, &mut s).unwrap();
            let o = &mut self.out[port.index()];
            o.push_str(&s);
            // Keep the tail only (memory stays flat over long runs).
            if o.len() > 8192 {
                let cut = o.len() - 4096;
                let cut = (cut..o.len()).find(|&i| o.is_char_boundary(i)).unwrap_or(0);
                o.drain(..cut);
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

    /// Run to rest, resuming every pause (the user's button), up to 8 times; the state reached.
    /// Panics when the printer does not come to rest (a wedge).
    fn settle(&mut self) -> State {
        for _ in 0..8 {
            let rest = self.run_to_rest(DRAIN_LIMIT_US);
            let st = self.p.status().state;
            assert!(
                rest,
                "wedged: state {st:?}, pending {:?}",
                self.pending.iter().map(Vec::len).collect::<Vec<_>>()
            );
            if st != State::Paused {
                return st;
            }
            self.request(Realtime::Resume);
        }
        self.p.status().state
    }

    /// The end of a run: a final `M400` on the USB port, every pause resumed, and the checks
    /// that nothing is wedged.
    pub fn finish(&mut self) {
        // Every byte of the input taken first, pauses resumed: while paused, bytes may still
        // wait (flow control), among them an `M524`, and a final `M400` queued behind it would
        // be part of the cancelled job.
        self.settle();
        // After a cancel the printer discards the rest of a streamed job until the host starts
        // anew (docs/frontend.md "Cancel": a line after 2 s of host silence): stay silent for
        // 3 s, as a host starting a new job does.
        for _ in 0..3 {
            self.tick(IDLE_TICK_US);
        }
        // The M118 is taken only after the M400 has been answered (M400 holds the next line).
        self.write(PortId::Usb, b"\nM400\nM118 fuzz-end\n");
        let st = self.settle();
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

impl Default for Harness {
    fn default() -> Self {
        Self::new()
    }
}

/// What the wire does to one attempt at sending a line.
#[derive(Clone, Copy, Debug)]
pub enum Noise {
    /// Replace the byte at (position mod length).
    Flip(usize, u8),
    /// Drop the byte at (position mod length), the line end included.
    Drop(usize),
}

/// Silence after which the [`host_stream`] host sends an `M105` (OctoPrint's communication
/// timeout is 30 s; shorter here to keep fuzz runs fast, still far above the firmware's 2 s
/// `busy:` period).
pub const HOST_TIMEOUT_US: u64 = 10_000_000;

/// How long the [`host_stream`] user waits for the resume to start before pressing again.
pub const USER_RETRY_US: u64 = 5_000_000;

/// A numbered, checksummed host that keeps one line in flight (as printcore and OctoPrint), over
/// a wire that corrupts the attempts listed in `noise` and splits the stream into `chunks`.
/// Pauses (`M601`, numbered like any line) after job line `pause_after`, resumes (`M602`) once
/// the printer says `//action:paused`. Returns the end position of every job move, in order.
pub fn host_stream(
    job: &[String],
    pause_after: Option<usize>,
    noise: &[(usize, Noise)],
    chunks: &[usize],
) -> Vec<StepPos> {
    let mut h = Harness::new();
    // No heater model here: extrude cold, as M302 P1 would, so the job's moves execute.
    h.p.extrusion_guard_mut().allow_cold = true;
    let mut lines: Vec<String> = Vec::new();
    for (i, l) in job.iter().enumerate() {
        lines.push(l.clone());
        if pause_after == Some(i) {
            lines.push("M601".into());
        }
    }
    let numbered = |n: usize, cmd: &str| {
        let body = format!("N{n} {cmd}");
        format!("{body}*{}\n", firmware::link::checksum(body.as_bytes())).into_bytes()
    };
    let mut wire: Vec<u8> = numbered(0, "M110");
    let mut in_flight = 1usize;
    let mut next = 1usize;
    let mut attempt = 0usize;
    let mut partial = String::new();
    let mut read_upto = 0usize;
    let mut resumed = false;
    // When the host sent its (unnumbered) M602 and has not yet seen the resume start.
    let mut resume_sent_us: Option<u64> = None;
    let mut k = 0usize;
    // Virtual time of the last line the printer wrote (the host's timeout counts from it).
    let mut heard_us = 0u64;
    let limit = 3600 * 1_000_000u64;
    while h.now_us < limit {
        if in_flight == 0 && next <= lines.len() {
            let mut bytes = numbered(next, &lines[next - 1]);
            if let Some(&(_, n)) = noise.iter().find(|(a, _)| *a == attempt) {
                match n {
                    Noise::Flip(p, b) => {
                        let i = p % bytes.len();
                        // Control bytes are requests of their own, not noise on a line.
                        if b >= 0x20 || b == b'\n' {
                            bytes[i] = b;
                        }
                    }
                    Noise::Drop(p) => {
                        bytes.remove(p % bytes.len());
                    }
                }
            }
            attempt += 1;
            wire.extend_from_slice(&bytes);
            next += 1;
            in_flight += 1;
        }
        // The wire hands over one chunk per tick; the printer takes what it has room for.
        let n = chunks
            .get(k % chunks.len().max(1))
            .copied()
            .unwrap_or(64)
            .max(1)
            .min(wire.len());
        k += 1;
        let piece: Vec<u8> = wire.drain(..n).collect();
        h.write(PortId::Usb, &piece);
        h.tick(5 * TICK_US);
        // The host reads its answers (the harness keeps the tail of the output only).
        let out = &h.out[0];
        if out.len() < read_upto {
            read_upto = 0;
        }
        partial.push_str(out.get(read_upto..).unwrap_or(""));
        read_upto = out.len();
        while let Some(i) = partial.find('\n') {
            let line: String = partial.drain(..=i).collect();
            let line = line.trim_end();
            heard_us = h.now_us;
            if line.starts_with("ok") {
                in_flight = in_flight.saturating_sub(1);
            } else if let Some(r) = line.strip_prefix("Resend: ") {
                if let Ok(r) = r.parse() {
                    next = r;
                }
            } else if line == "//action:paused" && !resumed {
                resumed = true;
                wire.extend_from_slice(b"M602\n");
                in_flight += 1;
                resume_sent_us = Some(h.now_us);
            } else if line.starts_with("//action:resume") {
                resume_sent_us = None;
            }
        }
        // An unnumbered line the wire corrupts is gone (nothing can ask for it again): the
        // user, seeing no resume, presses the button again.
        if let Some(t) = resume_sent_us {
            if h.now_us - t > USER_RETRY_US {
                wire.extend_from_slice(b"M602\n");
                in_flight += 1;
                resume_sent_us = Some(h.now_us);
            }
        }
        // A line whose line end the wire lost is never answered (the printer cannot know it
        // ended; Marlin waits the same way). OctoPrint's answer to silence while printing
        // (`_handle_timeout`, after its communication timeout, 30 s by default) is an `M105`
        // to trigger a response: it completes the broken line, which then fails its checksum
        // and is resent. printcore has no such timeout and would wait for ever. The firmware
        // sends `busy:` every 2 s while it holds a line, so only real silence times out.
        if in_flight > 0 && wire.is_empty() && h.now_us - heard_us > HOST_TIMEOUT_US {
            wire.extend_from_slice(b"M105\n");
            heard_us = h.now_us;
        }
        if next > lines.len() && in_flight == 0 && wire.is_empty() && h.p.next_step_ns().is_none() {
            let st = h.p.status().state;
            if st == State::Idle {
                break;
            }
        }
    }
    assert!(
        h.now_us < limit,
        "host stream did not finish: {:?}, next line {next} of {}, {in_flight} in flight, \
         {} bytes on the wire; output tail: {:?}",
        h.p.status().state,
        lines.len(),
        wire.len(),
        h.out[0]
            .get(h.out[0].len().saturating_sub(600)..)
            .unwrap_or("")
    );
    h.executed
}

/// Lines a host or a slicer file sends, so the fuzzer reaches deep states quickly.
pub const DICT: [&str; 32] = [
    "G28",
    "G1 X100 Y100 F6000",
    "G1 X10 Y200 E2 F3000",
    "G1 Z0.3 F600",
    "G1 Z5",
    "G1 X220 Y220 Z2 F12000",
    "M400",
    "M601",
    "M601 S1",
    "M602",
    "M524",
    "M25",
    "M24",
    "M108",
    "M410",
    "M109 S200",
    "M190 S60",
    "G4 P200",
    ";LAYER_CHANGE",
    ";Z:0.6",
    "G1 X50 Y50 E1.5 F1800",
    "G91",
    "G90",
    "M83",
    "G2 X60 Y60 I5 J5",
    "M761 L1",
    "M220 S300",
    "M105",
    "G92 E0",
    "M84",
    "M0",
    "M114",
];

/// The `executive` target: the input is a little program, each byte an op (top 3 bits) and an
/// argument (low 5 bits): raw bytes to the USB (0, 1) or TFT (2) port, a dictionary line to
/// the USB (3) or TFT (4) port, time passing (5, 6), a button request (7). Panics on a finding.
pub fn run_executive(data: &[u8]) {
    let mut h = Harness::new();
    let mut i = 0;
    while let Some(&b) = data.get(i) {
        i += 1;
        let (op, arg) = (b >> 5, usize::from(b & 31));
        match op {
            0..=2 => {
                let port = if op == 2 { PortId::Tft } else { PortId::Usb };
                let end = (i + arg + 1).min(data.len());
                let raw = data.get(i..end).unwrap_or(&[]).to_vec();
                i = end;
                h.write(port, &raw);
            }
            3 | 4 => {
                let line = format!("{}\n", DICT[arg]);
                let port = if op == 4 { PortId::Tft } else { PortId::Usb };
                h.write(port, line.as_bytes());
            }
            5 => {
                for _ in 0..=arg * 4 {
                    h.tick(TICK_US);
                }
            }
            6 => {
                for _ in 0..=arg {
                    h.tick(100 * TICK_US);
                }
            }
            _ => {
                let r = match arg % 6 {
                    0 => Realtime::Pause(PauseMode::Layer),
                    1 => Realtime::Pause(PauseMode::Now),
                    2 => Realtime::Resume,
                    3 => Realtime::Cancel,
                    4 => Realtime::BreakWait,
                    _ => Realtime::QuickStop,
                };
                h.request(r);
            }
        }
    }
    h.finish();
}

/// The `host_stream` target: byte 0 = number of job lines, byte 1 = where to pause, byte 2.. =
/// chunk sizes until a 0, then noise records of 3 bytes (attempt, position, byte; 0xFF = drop).
/// Panics when the noisy run executes other moves than the clean one.
pub fn run_host_stream(data: &[u8]) {
    let n = usize::from(data.first().copied().unwrap_or(0) % 24) + 2;
    let pause_at = data
        .get(1)
        .map(|&b| usize::from(b) % (n + 1))
        .filter(|&p| p < n);
    let rest = data.get(2..).unwrap_or(&[]);
    let split = rest.iter().position(|&b| b == 0).unwrap_or(rest.len());
    let chunks: Vec<usize> = rest
        .get(..split)
        .unwrap_or(&[])
        .iter()
        .map(|&b| usize::from(b))
        .collect();
    let noise: Vec<(usize, Noise)> = rest
        .get(split + 1..)
        .unwrap_or(&[])
        .chunks_exact(3)
        .take(16)
        .map(|c| {
            let n = if c[2] == 0xFF {
                Noise::Drop(usize::from(c[1]))
            } else {
                Noise::Flip(usize::from(c[1]), c[2])
            };
            (usize::from(c[0]), n)
        })
        .collect();
    // Two layers of short moves and a few long ones; distinct consecutive targets.
    let mut job = vec![
        "G92 X20 Y20".to_string(),
        "M760 X25 Y25 Z1".into(),
        ";LAYER_CHANGE".into(),
        ";Z:0.2".into(),
        "G1 Z0.2 F600".into(),
    ];
    for i in 0..n {
        if i == n / 2 {
            job.push(";LAYER_CHANGE".into());
            job.push(";Z:0.4".into());
            job.push("G1 Z0.4".into());
        }
        let x = 20 + (i * 7) % 30;
        let y = 20 + (i * 11) % 30;
        job.push(format!("G1 X{x} Y{y} E{:.2} F9000", 0.5 * (i + 1) as f32));
    }
    let clean = host_stream(&job, pause_at, &[], &[64]);
    // Every G1 of the job is a move that executes (the Z moves included).
    assert!(
        clean.len() > n,
        "clean run executed {} moves of {}",
        clean.len(),
        n + 2
    );
    let noisy = host_stream(&job, pause_at, &noise, &chunks);
    assert_eq!(noisy, clean, "noise changed the executed moves");
}

/// The `parse_stream` target: arbitrary bytes through the whole front end (host link → parser →
/// emitter round trip → machine state and layer detection). The first byte picks the chunk
/// size. Panics when an invariant breaks: at most `LINE_QUEUE` lines waiting, no line over
/// `LINE_CAP`, emitted commands parse back to themselves, a refused line leaves the interpreter
/// unchanged, an arc ends exactly at the commanded position, output is ASCII.
pub fn run_parse_stream(data: &[u8]) {
    use std::fmt::Write;
    let cfg = MachineConfig::ENDER3;
    let mut link = HostLink::new();
    let mut it = Interpreter::new(&cfg);
    let chunk = usize::from(data.first().copied().unwrap_or(1)).max(1);
    for piece in data.chunks(chunk) {
        let _ = link.receive(piece);
        assert!(link.lines_waiting() <= LINE_QUEUE);
        while link.take_realtime().is_some() {}
        while let Some(line) = link.pop_line() {
            assert!(line.text().len() <= LINE_CAP);
            if let Ok(parsed) = parse_line(line.text()) {
                if let Some(cmd) = &parsed.command {
                    // Emit and parse again: the same command.
                    let mut s = String::new();
                    write!(s, "{cmd}").unwrap();
                    let again = parse_line(s.as_bytes()).map(|l| l.command);
                    assert_eq!(again, Ok(Some(cmd.clone())), "{s:?}");
                }
                let saved = it;
                match it.line(&parsed, &cfg) {
                    Err(_) => assert_eq!(it, saved),
                    Ok(step) => {
                        if let Action::Arc(arc) = step.action {
                            let end = arc.last().map(|r| r.target);
                            assert_eq!(end, Some(it.machine.position_steps(&cfg)));
                        }
                    }
                }
            }
            link.respond(Response::Ok);
        }
        let mut out = String::new();
        link.write_output(&mut out).unwrap();
        assert!(out.is_ascii());
    }
    // Every line of the raw input parses or errors cleanly too (file path of host tools).
    for l in data.split(|&b| b == b'\n') {
        let _ = parse_line(l);
    }
}

/// The fuzz targets, by name (`fuzz_targets/<name>.rs`, `seeds/<name>/`, `finds/<name>/`).
pub const TARGETS: [&str; 3] = ["parse_stream", "executive", "host_stream"];

/// Run one input through the named target's checks (the regression test replays the committed
/// inputs with this).
pub fn run_target(target: &str, data: &[u8]) {
    match target {
        "parse_stream" => run_parse_stream(data),
        "executive" => run_executive(data),
        "host_stream" => run_host_stream(data),
        other => panic!("unknown fuzz target {other}"),
    }
}
