//! The `host_stream` target: a numbered host over a noisy wire against a clean one.

use super::{Harness, TICK_US};
use firmware::link::PortId;
use firmware::motion::StepPos;
use firmware::printer::State;

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
