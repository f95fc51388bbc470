//! `sim serve --flash FILE`: settings saved with M500 in one session are there in the next
//! (the file is the board's settings area, driven through the firmware's own store).

use sim::run::Policy;
use sim::serve::ServeArgs;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tests::pty::{checksum, serve_in_thread};

/// One `sim serve` session: send `lines` (each waits for its `ok`), return everything read.
fn session(flash: &Path, lines: &[&str]) -> Vec<String> {
    session_with(flash, lines, None)
}

/// A `sim serve` session: send `lines` (each waits for its `ok`); with `pause_after = Some(k)`,
/// write a realtime `M25` (layer pause) after the k-th line and, once every line is sent, read
/// until the printer says it keeps the paused job. Returns everything read.
fn session_with(flash: &Path, lines: &[&str], pause_after: Option<usize>) -> Vec<String> {
    let flash: PathBuf = flash.to_path_buf();
    let (server, mut host) = serve_in_thread(
        ServeArgs {
            speed: 20.0,
            record: None,
            policy: Policy::Firmware,
            exit_after_idle: 0.5,
            link: None,
            flash: Some(flash),
            machine: None,
            trace: None,
            sd: None,
            // The job extrudes without heating (no heater lines): as M302 P1 allows.
            allow_cold_extrusion: true,
            tft: false,
            tft_control_bytes: false,
            host_paced: false,
        },
        Duration::from_secs(10),
    );
    let pausing = pause_after.is_some();
    let keeps = |l: &str| l.contains("power-cut resume:");
    for (i, l) in lines.iter().enumerate() {
        if pausing && host.seen.iter().any(|s| keeps(s)) {
            break; // parked: the queue is full, the rest of the job waits (the power goes now)
        }
        if pause_after == Some(i) {
            host.write("M25");
        }
        host.write(l);
        host.until(&format!("ok for {l:?}"), Duration::from_secs(30), |s| {
            s.starts_with("ok") || (pausing && keeps(s))
        });
    }
    if pausing && !host.seen.iter().any(|s| keeps(s)) {
        host.until("the paused-job record", Duration::from_secs(60), keeps);
    }
    // The store runs in the session loop right after the `ok`: wait for its answer.
    let stored = |l: &str| l.contains("Settings Stored");
    if lines.contains(&"M500") && !host.seen.iter().any(|s| stored(s)) {
        host.until("M500's store", Duration::from_secs(30), stored);
    }
    let seen = std::mem::take(&mut host.seen);
    drop(host);
    server.record().expect("serve session");
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

/// A numbered job of 4 layers (Cura markers). Returns the lines (with `N` and checksum) and, per
/// layer, the `N` of its first motion line (index 0: layer 1 in the one numbering, the n-th
/// layer printed from 1).
fn numbered_job() -> (Vec<String>, Vec<u32>) {
    let mut body: Vec<String> = ["G28", "M83", "G92 E0"].map(String::from).to_vec();
    let mut first = Vec::new();
    for layer in 0..4 {
        body.push(format!(";LAYER:{layer}"));
        first.push(body.len() as u32 + 1);
        body.push(format!("G1 Z{:.1} F600", 0.2 * (layer + 1) as f32));
        for i in 0..16 {
            let (x, y) = [(20, 20), (120, 20), (120, 120), (20, 120)][i % 4];
            body.push(format!("G1 X{x} Y{y} E3 F1800"));
        }
    }
    let lines = body
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let l = format!("N{} {b}", i + 1);
            format!("{l}*{}", checksum(&l))
        })
        .collect();
    (lines, first)
}

#[test]
fn a_paused_job_kept_in_one_session_is_announced_in_the_next() {
    let file = std::env::temp_dir().join(format!("sim-serve-job-{}.bin", std::process::id()));
    let _ = std::fs::remove_file(&file);
    let (lines, first) = numbered_job();
    let refs: Vec<&str> = lines.iter().map(String::as_str).collect();
    let mut all = vec!["M110 N0"];
    all.extend(refs);
    let seen = session_with(&file, &all, Some(12));
    let kept = seen
        .iter()
        .find(|l| l.contains("power-cut resume: keeping job at layer"))
        .unwrap_or_else(|| panic!("{seen:?}"));
    // "… keeping job at layer L, host line N": N is the first motion line of layer L (layers
    // numbered from 1: `first[L - 1]`).
    let words: Vec<&str> = kept.split([' ', ',']).collect();
    let layer: usize = words[words.iter().position(|w| *w == "layer").unwrap() + 1]
        .parse()
        .unwrap();
    let line: u32 = words.last().unwrap().parse().unwrap();
    assert!(layer >= 1, "{kept}");
    assert_eq!(line, first[layer - 1], "{kept}");

    // The power goes (the session ends while paused); the next session announces the job.
    let next = session(&file, &["M105"]);
    let want = format!(
        "//action:notification Paused job kept: layer {layer} at Z{:.3}, continue from host line {line}",
        0.2 * layer as f32
    );
    assert!(
        next.iter().any(|l| l.starts_with(&want)),
        "{want}\n{next:?}"
    );
    let _ = std::fs::remove_file(&file);
}
