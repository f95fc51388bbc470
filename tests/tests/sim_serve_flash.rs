//! `sim serve --flash FILE`: settings saved with M500 in one session are there in the next
//! (the file is the board's settings area, driven through the firmware's own store).

use sim::run::Policy;
use sim::serve::{serve_with, ServeArgs};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// One `sim serve` session: send `lines` (each waits for its `ok`), return everything read.
fn session(flash: &Path, lines: &[&str]) -> Vec<String> {
    let (tx, rx) = mpsc::channel();
    let flash: PathBuf = flash.to_path_buf();
    let server = std::thread::spawn(move || {
        serve_with(
            ServeArgs {
                speed: 20.0,
                record: None,
                policy: Policy::Firmware,
                exit_after_idle: 0.5,
                link: None,
                flash: Some(flash),
            },
            move |p| {
                let _ = tx.send(p.to_path_buf());
            },
        )
    });
    let path = rx
        .recv_timeout(Duration::from_secs(10))
        .expect("sim serve printed no device path");
    let mut dev = std::fs::OpenOptions::new()
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
    let mut seen = Vec::new();
    for l in lines {
        dev.write_all(format!("{l}\n").as_bytes()).expect("write");
        let end = Instant::now() + Duration::from_secs(30);
        loop {
            let left = end.saturating_duration_since(Instant::now());
            let got = lrx
                .recv_timeout(left)
                .unwrap_or_else(|_| panic!("no ok for {l:?}; saw {seen:?}"));
            let ok = got.starts_with("ok");
            seen.push(got);
            if ok {
                break;
            }
        }
    }
    // The store runs in the session loop right after the `ok`: wait for its answer.
    if lines.contains(&"M500") {
        let end = Instant::now() + Duration::from_secs(30);
        while !seen.iter().any(|l| l.contains("Settings Stored")) {
            let left = end.saturating_duration_since(Instant::now());
            let got = lrx
                .recv_timeout(left)
                .unwrap_or_else(|_| panic!("M500 never stored; saw {seen:?}"));
            seen.push(got);
        }
    }
    drop(dev);
    server
        .join()
        .expect("server thread")
        .expect("serve session");
    seen
}

#[test]
fn settings_saved_in_one_session_are_reported_in_the_next() {
    let file = std::env::temp_dir().join(format!("sim-serve-flash-{}.bin", std::process::id()));
    let _ = std::fs::remove_file(&file);
    let first = session(&file, &["M92 X81.25 E97", "M203 Z12", "M500"]);
    assert!(
        first.iter().any(|l| l.starts_with("echo:Settings Stored")),
        "{first:?}"
    );
    assert_eq!(std::fs::metadata(&file).unwrap().len(), 262_144);

    let second = session(&file, &["M503"]);
    assert!(
        second
            .iter()
            .any(|l| l == "echo:Settings loaded from flash"),
        "{second:?}"
    );
    assert!(
        second.iter().any(|l| l == "echo:  M92 X81.25 Y80 Z400 E97"),
        "{second:?}"
    );
    assert!(
        second.iter().any(|l| l == "echo:  M203 X500 Y500 Z12 E25"),
        "{second:?}"
    );
    // Without the file, a session starts from the factory values.
    let third =
        std::env::temp_dir().join(format!("sim-serve-flash-{}-new.bin", std::process::id()));
    let _ = std::fs::remove_file(&third);
    let fresh = session(&third, &["M92"]);
    assert!(
        fresh.iter().any(|l| l == "echo:  M92 X80 Y80 Z400 E93"),
        "{fresh:?}"
    );
    let _ = std::fs::remove_file(&file);
    let _ = std::fs::remove_file(&third);
}
