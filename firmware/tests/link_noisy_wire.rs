//! Property (fixed seed, deterministic): a numbered, checksummed host with a window of lines in
//! flight, over a wire that splits its writes anywhere, delivers them in bursts and corrupts
//! bytes (substitutes, drops, breaks lines) — through the real `Printer`. Every line executes
//! exactly once, in order, and every `Error:` is part of a resend.

use firmware::config::MachineConfig;
use firmware::link::{checksum, PortId};
use firmware::motion::StepPos;
use firmware::planner::BlockKind;
use firmware::printer::{Printer, Record};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

/// What the wire does to one attempt at sending a line.
#[derive(Clone, Copy, Debug)]
enum Noise {
    /// Replace the byte at (position mod length) with this printable byte or a line end.
    Substitute(usize, u8),
    /// Drop the byte at (position mod length), the line end included.
    Drop(usize),
}

#[derive(Clone, Debug)]
struct Case {
    lines: usize,
    /// Lines the host keeps in flight (1 = one per `ok`, as printcore and OctoPrint).
    window: usize,
    /// Chunk sizes the wire splits the byte stream into (cycled).
    chunks: Vec<usize>,
    /// Chunks delivered per millisecond (cycled): bursts.
    bursts: Vec<usize>,
    /// (attempt number, noise): corrupts that attempt.
    noise: Vec<(usize, Noise)>,
}

fn case() -> impl Strategy<Value = Case> {
    let noise = prop_oneof![
        (0usize..64, prop_oneof![Just(b'\n'), b' '..=b'~'])
            .prop_map(|(p, b)| Noise::Substitute(p, b)),
        (0usize..64).prop_map(Noise::Drop),
    ];
    (
        1usize..40,
        1usize..5,
        prop::collection::vec(1usize..40, 1..6),
        prop::collection::vec(1usize..4, 1..6),
        prop::collection::vec((0usize..80, noise), 0..12),
    )
        .prop_map(|(lines, window, chunks, bursts, noise)| Case {
            lines,
            window,
            chunks,
            bursts,
            noise,
        })
}

fn target_mm(i: usize) -> (u32, u32) {
    (10 + (i as u32 * 7) % 150, 10 + (i as u32 * 13) % 150)
}

fn numbered(n: usize, cmd: &str) -> Vec<u8> {
    let body = format!("N{n} {cmd}");
    format!("{body}*{}\n", checksum(body.as_bytes())).into_bytes()
}

/// The executive's 1 ms main-loop tick at `now` µs: poll, take the steps due before the
/// tick's end, and add to `executed` the end position of each job move finished (its last
/// segment).
fn tick_1ms(p: &mut Printer, now: u64, executed: &mut Vec<StepPos>) {
    p.poll(now);
    while let Some(t) = p.next_step_ns() {
        if t > (now + 1000) * 1000 {
            break;
        }
        p.next_step();
    }
    while let Some(r) = p.pop_record() {
        if let Record::Executed {
            seg,
            segs,
            kind: BlockKind::Job,
            pos,
            ..
        } = r
        {
            if seg + 1 == segs {
                executed.push(pos);
            }
        }
    }
}

/// Runs the case; returns the end position of each executed job move, in order.
fn run(c: &Case) -> Result<Vec<StepPos>, TestCaseError> {
    let cfg = MachineConfig::ENDER3;
    let mut p = Printer::new(cfg);
    let job: Vec<String> = (0..c.lines)
        .map(|i| {
            let (x, y) = target_mm(i);
            format!("G1 X{x} Y{y} F9000")
        })
        .collect();
    let mut wire: Vec<u8> = numbered(0, "M110").to_vec();
    let mut next = 1usize; // next line number to send (job line next-1)
    let mut in_flight = 1usize;
    let mut attempt = 0usize;
    let mut out = String::new();
    let mut partial = String::new();
    let mut executed = Vec::new();
    let (mut k_chunk, mut k_burst) = (0usize, 0usize);
    let mut now = 0u64;
    while now < 300_000_000 {
        // The host: send while its window has room.
        while in_flight < c.window && next <= c.lines {
            let mut bytes = numbered(next, &job[next - 1]);
            if let Some(&(_, n)) = c.noise.iter().find(|(a, _)| *a == attempt) {
                match n {
                    Noise::Substitute(pos, b) => {
                        let i = pos % bytes.len();
                        bytes[i] = b;
                    }
                    Noise::Drop(pos) => {
                        bytes.remove(pos % bytes.len());
                    }
                }
            }
            attempt += 1;
            wire.extend_from_slice(&bytes);
            next += 1;
            in_flight += 1;
        }
        // The wire: a burst of chunks this millisecond; what is not taken stays on the wire.
        let burst = c.bursts[k_burst % c.bursts.len()];
        k_burst += 1;
        for _ in 0..burst {
            let n = c.chunks[k_chunk % c.chunks.len()].min(wire.len());
            k_chunk += 1;
            let taken = p.receive(&wire[..n], now);
            wire.drain(..taken);
        }
        tick_1ms(&mut p, now, &mut executed);
        // The host reads its answers.
        out.clear();
        p.write_output(&mut out).unwrap();
        partial.push_str(&out);
        while let Some(i) = partial.find('\n') {
            let line: String = partial.drain(..=i).collect();
            let line = line.trim_end();
            if line.starts_with("ok") {
                in_flight = in_flight.saturating_sub(1);
            } else if let Some(n) = line.strip_prefix("Resend: ") {
                next = n.parse().unwrap();
            } else if let Some(e) = line.strip_prefix("Error:") {
                // Resend errors, or the parser refusing the checksum digits cut off a line by
                // a corrupted line end (an unnumbered, unchecked fragment, as in Marlin).
                prop_assert!(
                    e.contains("checksum")
                        || e.contains("Line Number")
                        || e.contains("line number")
                        || e.contains("(column 1)"),
                    "an Error: that is not part of a resend: {line}"
                );
            }
        }
        now += 1000;
        if next > c.lines && in_flight == 0 && wire.is_empty() && p.next_step_ns().is_none() {
            break;
        }
    }
    Ok(executed)
}

#[test]
fn every_line_runs_once_in_order_over_a_noisy_wire() {
    let cfg = MachineConfig::ENDER3;
    let mut runner = TestRunner::new_with_rng(
        Config {
            cases: 96,
            failure_persistence: None,
            ..Config::default()
        },
        TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]),
    );
    runner
        .run(&case(), |c| {
            let executed = run(&c)?;
            let want: Vec<StepPos> = (0..c.lines)
                .map(|i| {
                    let (x, y) = target_mm(i);
                    [
                        (x as f32 * cfg.axis(firmware::motion::Axis::X).steps_per_mm) as i32,
                        (y as f32 * cfg.axis(firmware::motion::Axis::Y).steps_per_mm) as i32,
                        0,
                        0,
                    ]
                })
                .collect();
            prop_assert_eq!(executed, want);
            Ok(())
        })
        .unwrap();
}

/// One host on one port of the two-port test: its job, its wire, its window.
struct PortHost {
    port: PortId,
    job: Vec<String>,
    window: usize,
    chunks: Vec<usize>,
    bursts: Vec<usize>,
    noise: Vec<(usize, Noise)>,
    wire: Vec<u8>,
    next: usize,
    in_flight: usize,
    attempt: usize,
    k_chunk: usize,
    k_burst: usize,
    partial: String,
    /// When the printer last wrote a line to this port, µs (the host's timeout counts from it).
    heard_us: u64,
}

/// Silence after which a host sends an `M105` to provoke an answer (OctoPrint does after its
/// communication timeout): a line whose line end the wire lost is otherwise never answered.
const HOST_TIMEOUT_US: u64 = 10_000_000;

impl PortHost {
    fn new(port: PortId, c: &Case, job: Vec<String>) -> Self {
        PortHost {
            port,
            job,
            window: c.window,
            chunks: c.chunks.clone(),
            bursts: c.bursts.clone(),
            noise: c.noise.clone(),
            wire: numbered(0, "M110"),
            next: 1,
            in_flight: 1,
            attempt: 0,
            k_chunk: 0,
            k_burst: 0,
            partial: String::new(),
            heard_us: 0,
        }
    }

    fn done(&self) -> bool {
        self.next > self.job.len() && self.in_flight == 0 && self.wire.is_empty()
    }

    fn send(&mut self, p: &mut Printer, now: u64) {
        while self.in_flight < self.window && self.next <= self.job.len() {
            let mut bytes = numbered(self.next, &self.job[self.next - 1]);
            if let Some(&(_, n)) = self.noise.iter().find(|(a, _)| *a == self.attempt) {
                match n {
                    Noise::Substitute(pos, b) => {
                        let i = pos % bytes.len();
                        bytes[i] = b;
                    }
                    Noise::Drop(pos) => {
                        bytes.remove(pos % bytes.len());
                    }
                }
            }
            self.attempt += 1;
            self.wire.extend_from_slice(&bytes);
            self.next += 1;
            self.in_flight += 1;
        }
        if self.in_flight > 0 && self.wire.is_empty() && now - self.heard_us > HOST_TIMEOUT_US {
            self.wire.extend_from_slice(b"M105\n");
            self.heard_us = now;
        }
        let burst = self.bursts[self.k_burst % self.bursts.len()];
        self.k_burst += 1;
        for _ in 0..burst {
            let n = self.chunks[self.k_chunk % self.chunks.len()].min(self.wire.len());
            self.k_chunk += 1;
            let taken = p.receive_on(self.port, &self.wire[..n], now);
            self.wire.drain(..taken);
        }
    }

    fn read(&mut self, p: &mut Printer, now: u64) -> Result<(), TestCaseError> {
        let mut out = String::new();
        p.write_output_on(self.port, &mut out).unwrap();
        self.partial.push_str(&out);
        while let Some(i) = self.partial.find('\n') {
            let line: String = self.partial.drain(..=i).collect();
            let line = line.trim_end();
            self.heard_us = now;
            if line.starts_with("ok") {
                self.in_flight = self.in_flight.saturating_sub(1);
            } else if let Some(n) = line.strip_prefix("Resend: ") {
                self.next = n.parse().unwrap();
            } else if let Some(e) = line.strip_prefix("Error:") {
                prop_assert!(
                    e.contains("checksum")
                        || e.contains("Line Number")
                        || e.contains("line number")
                        || e.contains("(column 1)"),
                    "{:?}: an Error: that is not part of a resend: {line}",
                    self.port
                );
            }
        }
        Ok(())
    }
}

/// Both ports at once (issue 12, item 7): a numbered host on the USB port and another on the
/// TFT UART, each with its own line numbers, window, write splits, bursts and noise, their
/// lines interleaved in the one executive. Returns the executed job moves' end positions.
fn run_two_ports(usb: &Case, tft: &Case) -> Result<Vec<StepPos>, TestCaseError> {
    let mut p = Printer::new(MachineConfig::ENDER3);
    let mut hosts = [
        PortHost::new(PortId::Usb, usb, usb_job(usb.lines)),
        PortHost::new(PortId::Tft, tft, tft_job(tft.lines)),
    ];
    let mut executed = Vec::new();
    let mut now = 0u64;
    while now < 600_000_000 {
        for h in hosts.iter_mut() {
            h.send(&mut p, now);
        }
        tick_1ms(&mut p, now, &mut executed);
        for h in hosts.iter_mut() {
            h.read(&mut p, now)?;
        }
        now += 1000;
        if hosts.iter().all(PortHost::done) && p.next_step_ns().is_none() {
            break;
        }
    }
    Ok(executed)
}

/// USB lines move in Y 10..100 mm, TFT lines in Y 150..220 mm: each executed move tells its
/// port by its Y (the moves are absolute, so interleaving does not change their end points).
fn usb_job(n: usize) -> Vec<String> {
    (0..n)
        .map(|i| format!("G1 X{} Y{} F9000", 10 + (i * 7) % 150, 10 + (i * 13) % 90))
        .collect()
}

fn tft_job(n: usize) -> Vec<String> {
    (0..n)
        .map(|i| format!("G1 X{} Y{} F9000", 10 + (i * 11) % 150, 150 + (i * 17) % 70))
        .collect()
}

fn steps_of(line: &str) -> StepPos {
    let cfg = MachineConfig::ENDER3;
    let num = |k: char| -> f32 {
        let w = line.split(' ').find(|w| w.starts_with(k)).unwrap();
        w[1..].parse().unwrap()
    };
    [
        (num('X') * cfg.axis(firmware::motion::Axis::X).steps_per_mm) as i32,
        (num('Y') * cfg.axis(firmware::motion::Axis::Y).steps_per_mm) as i32,
        0,
        0,
    ]
}

#[test]
fn both_ports_every_line_runs_once_in_order_over_noisy_wires() {
    let cfg = MachineConfig::ENDER3;
    let y_split = (120.0 * cfg.axis(firmware::motion::Axis::Y).steps_per_mm) as i32;
    let mut runner = TestRunner::new_with_rng(
        Config {
            cases: 48,
            failure_persistence: None,
            ..Config::default()
        },
        TestRng::from_seed(RngAlgorithm::ChaCha, &[12; 32]),
    );
    runner
        .run(&(case(), case()), |(usb, tft)| {
            let executed = run_two_ports(&usb, &tft)?;
            let (from_usb, from_tft): (Vec<StepPos>, Vec<StepPos>) =
                executed.iter().partition(|p| p[1] < y_split);
            let want_usb: Vec<StepPos> = usb_job(usb.lines).iter().map(|l| steps_of(l)).collect();
            let want_tft: Vec<StepPos> = tft_job(tft.lines).iter().map(|l| steps_of(l)).collect();
            prop_assert_eq!(from_usb, want_usb, "USB port");
            prop_assert_eq!(from_tft, want_tft, "TFT port");
            Ok(())
        })
        .unwrap();
}
