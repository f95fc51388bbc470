//! A host on `sim serve`'s pseudo-terminal, as the end-to-end tests play it: lines written to
//! the device, the printer's lines read on a thread and handed out one by one with a deadline.

use std::fs::File;
use std::io::{Read, Write};
use std::path::Path;
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// XOR checksum of a numbered line (`N<n> <cmd>`), as printcore computes it.
pub fn checksum(s: &str) -> u8 {
    s.bytes().fold(0, |a, b| a ^ b)
}

/// The device path, or, where this sandbox's /dev/pts does not show the pseudo-terminal (some
/// container setups), the sim process's own open descriptor of it under /proc, which opens the
/// same terminal.
pub fn reachable(device: &str, pid: u32) -> String {
    if Path::new(device).exists() {
        return device.to_string();
    }
    if let Ok(entries) = std::fs::read_dir(format!("/proc/{pid}/fd")) {
        for e in entries.flatten() {
            if std::fs::read_link(e.path()).is_ok_and(|t| t == Path::new(device)) {
                return e.path().display().to_string();
            }
        }
    }
    device.to_string()
}

/// A host connected to a pseudo-terminal.
pub struct PtyHost {
    dev: File,
    lines: mpsc::Receiver<String>,
    /// Every line the printer sent so far, in order (trimmed).
    pub seen: Vec<String>,
}

impl PtyHost {
    /// Open the device and start reading its lines.
    pub fn open(path: &Path) -> PtyHost {
        let dev = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .expect("open the pty");
        let mut reader = dev.try_clone().expect("clone the pty handle");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = [0u8; 1024];
            let mut line = Vec::new();
            while let Ok(n) = reader.read(&mut buf) {
                if n == 0 {
                    break;
                }
                for &b in &buf[..n] {
                    if b == b'\n' {
                        let _ = tx.send(String::from_utf8_lossy(&line).trim().to_string());
                        line.clear();
                    } else {
                        line.push(b);
                    }
                }
            }
        });
        PtyHost {
            dev,
            lines,
            seen: Vec::new(),
        }
    }

    /// Write `text` and a line end.
    pub fn write(&mut self, text: &str) {
        self.dev
            .write_all(format!("{text}\n").as_bytes())
            .expect("write to the pty");
    }

    /// Write `cmd` as line `n` with its checksum.
    pub fn send_numbered(&mut self, n: u32, cmd: &str) {
        let pre = format!("N{n} {cmd}");
        let cs = checksum(&pre);
        self.write(&format!("{pre}*{cs}"));
    }

    /// Read lines until one satisfies `pred` (within `limit`); returns it. Panics with
    /// everything seen when the time runs out.
    pub fn until(&mut self, what: &str, limit: Duration, pred: impl Fn(&str) -> bool) -> String {
        let end = Instant::now() + limit;
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

    /// Read lines until an `ok` (within `limit`).
    pub fn ok(&mut self, limit: Duration) {
        self.until("ok", limit, |l| l.starts_with("ok"));
    }
}

/// `sim serve` running on a thread of the test process (see [`serve_in_thread`]).
pub struct ServeThread(std::thread::JoinHandle<Result<sim::serve::ServeRecord, String>>);

impl ServeThread {
    /// Wait for the session to end; its record, or why it failed (the thread's panic too).
    pub fn record(self) -> Result<sim::serve::ServeRecord, String> {
        self.0
            .join()
            .unwrap_or_else(|_| Err("the sim serve thread panicked".to_string()))
    }
}

/// Start `sim serve` with `args` on a thread and open a host on its pseudo-terminal once it
/// has printed the device's path (panics when that takes longer than `ready_limit`).
pub fn serve_in_thread(
    args: sim::serve::ServeArgs,
    ready_limit: Duration,
) -> (ServeThread, PtyHost) {
    let (tx, rx) = mpsc::channel();
    let server = std::thread::spawn(move || {
        sim::serve::serve_with(args, move |p| {
            let _ = tx.send(p.to_path_buf());
        })
        .map_err(|e| format!("{e:#}"))
    });
    let path = rx
        .recv_timeout(ready_limit)
        .expect("sim serve printed no device path");
    (ServeThread(server), PtyHost::open(&path))
}
