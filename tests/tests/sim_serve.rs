//! `sim serve` as a host sees it: open the pseudo-terminal, speak printcore's protocol (line
//! numbers, checksums, `ok` flow control, a resend), send a realtime pause, wait for
//! `//action:paused`, resume, and see the job complete; then check the session's pause record.

use sim::run::Policy;
use sim::serve::{serve_with, ServeArgs};
use std::io::{Read, Write};
use std::sync::mpsc;
use std::time::{Duration, Instant};

fn checksum(s: &str) -> u8 {
    s.bytes().fold(0, |a, b| a ^ b)
}

struct Host {
    dev: std::fs::File,
    lines: mpsc::Receiver<String>,
    seen: Vec<String>,
}

impl Host {
    fn write(&mut self, text: &str) {
        self.dev
            .write_all(format!("{text}\n").as_bytes())
            .expect("write to the pty");
    }

    fn send(&mut self, n: u32, cmd: &str) {
        let pre = format!("N{n} {cmd}");
        let cs = checksum(&pre);
        self.write(&format!("{pre}*{cs}"));
    }

    /// Read lines until one satisfies `pred`; returns it.
    fn until(&mut self, what: &str, pred: impl Fn(&str) -> bool) -> String {
        let end = Instant::now() + Duration::from_secs(60);
        loop {
            let left = end.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(l) => {
                    self.seen.push(l.clone());
                    if pred(&l) {
                        return l;
                    }
                }
                Err(_) => panic!("timed out waiting for {what}; saw {:?}", self.seen),
            }
        }
    }

    fn ok(&mut self) {
        self.until("ok", |l| l.starts_with("ok"));
    }
}

#[test]
fn a_host_prints_pauses_and_resumes_over_the_pseudo_terminal() {
    let (tx, rx) = mpsc::channel();
    let server = std::thread::spawn(move || {
        serve_with(
            ServeArgs {
                speed: 20.0,
                record: None,
                policy: Policy::Firmware,
                exit_after_idle: 1.0,
                link: None,
                flash: None,
                machine: None,
                trace: None,
                sd: None,
            },
            move |p| {
                let _ = tx.send(p.to_path_buf());
            },
        )
    });
    let path = rx
        .recv_timeout(Duration::from_secs(10))
        .expect("sim serve printed no device path");
    let dev = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&path)
        .expect("open the pty");
    let mut reader = dev.try_clone().expect("clone the pty handle");
    let (ltx, lrx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut buf = [0u8; 1024];
        let mut line = Vec::new();
        while let Ok(n) = reader.read(&mut buf) {
            if n == 0 {
                break;
            }
            for &b in &buf[..n] {
                if b == b'\n' {
                    let _ = ltx.send(String::from_utf8_lossy(&line).trim().to_string());
                    line.clear();
                } else {
                    line.push(b);
                }
            }
        }
    });
    let mut host = Host {
        dev,
        lines: lrx,
        seen: Vec::new(),
    };

    host.write("M110 N0");
    host.ok();
    // A line with a wrong checksum is asked for again.
    host.write("N1 G90*0");
    let resend = host.until("Resend", |l| l.starts_with("Resend:"));
    assert!(resend.contains('1'), "{resend}");
    host.ok();

    let mut job = vec![
        "G90".to_string(),
        "M83".into(),
        "G92 X10 Y10 Z0.2 E0".into(),
    ];
    for i in 0..24 {
        let x = if i % 2 == 0 { 60 } else { 10 };
        job.push(format!("G1 X{x} Y{} E1.5 F1800", 10 + i));
    }
    let mut n = 1;
    for (i, line) in job.iter().enumerate() {
        host.send(n, line);
        n += 1;
        host.ok();
        if i == 8 {
            // Realtime pause: unnumbered, written at once.
            host.write("M25 S1");
            host.until("//action:paused", |l| l.contains("//action:paused"));
            host.write("M24");
            host.until("//action:resume", |l| l.contains("//action:resume"));
        }
    }
    // M400 is answered once every move has run: the job completed.
    host.send(n, "M400");
    host.ok();
    drop(host);

    let record = server
        .join()
        .expect("server thread")
        .expect("serve session");
    let s = &record.session;
    assert!(s.finished && !s.cancelled, "{s:#?}");
    assert_eq!(s.lost_moves + s.duplicated_moves, 0, "{s:#?}");
    assert!(s.moves_executed >= 24, "{s:#?}");
    // M110, the bad line, its resend, the job and M400, plus the realtime M25 S1 and M24.
    assert!(s.lines_received >= job.len() as u64 + 4, "{s:#?}");
    let reports = record.pauses;
    assert_eq!(reports.len(), 1, "{reports:#?}");
    let r = &reports[0];
    assert_eq!(r.mode, "now");
    assert!(r.stop_s.is_some_and(|s| s < 0.2), "{r:#?}");
    assert_eq!(r.resume_position_error_steps, Some(0), "{r:#?}");
    assert_eq!(r.lost_moves + r.duplicated_moves, 0, "{r:#?}");
    assert!(r.finished, "{r:#?}");
}
