//! Property (fixed seed, deterministic): a numbered, checksummed host with a window of lines in
//! flight, over a wire that splits its writes anywhere, delivers them in bursts and corrupts
//! bytes (substitutes, drops, breaks lines) — through the real `Printer`. Every line executes
//! exactly once, in order, and every `Error:` is part of a resend.

use firmware::config::MachineConfig;
use firmware::link::checksum;
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
