//! A held job is held whole (issue 27), with the real printcore: it streams the first layers of
//! PrusaSlicer's fixture (heat-up, body, end code) and keeps streaming into the parked printer
//! through a pause longer than the nozzle timeout (45 s by default: the nozzle goes cold while
//! job lines arrive). Each run is judged by its move trace (`sim serve --trace`: every executed
//! job move's start and end in steps, E included) against an unpaused run of the same lines —
//! 0 lost, 0 extra, in order — by the sim's record (`lost_moves` 0, finished) and by the
//! nozzle's temperature when the held job starts again (an M105 sent at `//action:resumed`:
//! the resume re-heats and waits before it moves back), at least the job's 200 °C − 5.
//! Needs `bash scripts/setup-hosts.sh`.

mod hosts_common;

use hosts_common::{host_python, run_bounded, Sim};
use std::process::Command;
use std::time::Duration;

const SPEED: &str = "1000";
const FILE: &str = "tests/fixtures/slicer/prusaslicer.gcode";
const LAYERS: &str = "3";

/// The move trace `sim serve --trace` wrote to `path` (removed after).
fn read_trace(path: &std::path::Path) -> Vec<String> {
    let lines = std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .map(str::to_string)
        .collect();
    let _ = std::fs::remove_file(path);
    lines
}

/// One session: `sim serve` (`more` arguments) with printcore's driver (`args`); returns the
/// driver's JSON, the sim's record and the move trace's lines.
fn session(
    tag: &str,
    more: &[&str],
    args: &[&str],
) -> (serde_json::Value, serde_json::Value, Vec<String>) {
    let py = host_python("printrun");
    let trace = std::env::temp_dir().join(format!("held_{tag}_{}.trace", std::process::id()));
    let _ = std::fs::remove_file(&trace);
    let mut sim_args = vec!["--host-paced", "--trace", trace.to_str().unwrap()];
    sim_args.extend_from_slice(more);
    let sim = Sim::start_with(&format!("held_{tag}"), SPEED, "120", &sim_args);
    let mut cmd = Command::new(py);
    cmd.args([
        "tests/hosts/printcore_held.py",
        "--port",
        &sim.device,
        "--file",
        FILE,
        "--layers",
        LAYERS,
    ])
    .args(args);
    let t0 = std::time::Instant::now();
    let (ok, out, err) = run_bounded(cmd, Duration::from_secs(300));
    let r = sim.finish();
    let lines = read_trace(&trace);
    assert!(ok, "driver failed: {out}\n{err}");
    let d: serde_json::Value = serde_json::from_str(out.trim()).expect("driver JSON");
    eprintln!(
        "{tag}: wall {:.1} s; driver {d}\nsession {}",
        t0.elapsed().as_secs_f64(),
        r["session"]
    );
    (d, r, lines)
}

/// The unpaused run's move trace (one per test: ≈ 3 s of wall time); `tag` names its files
/// (the tests run in parallel in one process).
fn reference(tag: &str) -> Vec<String> {
    let (d, r, trace) = session(tag, &[], &["--pause-line", "0"]);
    assert_eq!(d["end"], true, "{d}");
    assert_eq!(r["session"]["finished"], true, "{}", r["session"]);
    assert!(
        trace.len() > 100,
        "reference trace of {} moves",
        trace.len()
    );
    trace
}

/// Moves of `want` missing from `got` and moves of `got` not in `want` (as multisets).
fn diff(want: &[String], got: &[String]) -> (usize, usize) {
    let mut count = std::collections::HashMap::<&str, i64>::new();
    for l in want {
        *count.entry(l).or_default() += 1;
    }
    for l in got {
        *count.entry(l).or_default() -= 1;
    }
    let lost = count
        .values()
        .filter(|n| **n > 0)
        .map(|n| *n as usize)
        .sum();
    let extra = count
        .values()
        .filter(|n| **n < 0)
        .map(|n| (-*n) as usize)
        .sum();
    (lost, extra)
}

/// The paused run held its job whole and printed it hot after the resume.
fn assert_held_whole(
    tag: &str,
    base: &[String],
    d: &serde_json::Value,
    r: &serde_json::Value,
    trace: &[String],
) {
    assert_eq!(d["paused"], true, "{tag}: {d}");
    assert_eq!(d["resumed"], true, "{tag}: {d}");
    assert_eq!(d["end"], true, "{tag}: {d}");
    assert_eq!(
        d["nozzle_off_noted"], true,
        "{tag}: the nozzle timeout never fired: {d}"
    );
    assert_eq!(d["refused"].as_array().map(Vec::len), Some(0), "{tag}: {d}");
    assert_eq!(d["errors"].as_array().map(Vec::len), Some(0), "{tag}: {d}");
    let (lost, extra) = diff(base, trace);
    eprintln!(
        "{tag}: {} moves, {lost} lost, {extra} extra against the unpaused run",
        trace.len()
    );
    assert_eq!((lost, extra), (0, 0), "{tag}: moves lost/extra");
    assert_eq!(trace, base, "{tag}: the moves in the unpaused run's order");
    let s = &r["session"];
    assert_eq!(s["lost_moves"], 0, "{tag}: {s}");
    assert_eq!(s["refused_job_lines"], 0, "{tag}: {s}");
    assert_eq!(s["finished"], true, "{tag}: {s}");
    let c = d["nozzle_c_at_resume"].as_f64().unwrap_or(0.0);
    let target = d["nozzle_target_c_at_resume"].as_f64().unwrap_or(0.0);
    assert_eq!(target, 200.0, "{tag}: the job's target: {d}");
    assert!(
        c >= target - 5.0,
        "{tag}: nozzle at {c} °C when the held job went on: {d}"
    );
}

/// A pause of 300 s (the nozzle goes off after 45 s) while printcore streams with the SD card
/// (the parked lines go to RAM, then the card), and one of 150 s without (RAM only);
/// and one with the pause just before the end, so the end code's `M104 S0`/`M140 S0` comes
/// into the parked printer; one with a console jog while parked.
#[test]
fn printcore_held_job_survives_a_pause_past_the_nozzle_timeout() {
    let base = reference("ref");
    let card = std::env::temp_dir().join(format!("held_sd_{}", std::process::id()));
    std::fs::create_dir_all(&card).expect("card dir");
    std::fs::write(card.join("README.TXT"), b"card for the spill\n").expect("card file");
    let (d, r, t) = session(
        "card",
        &["--sd", card.to_str().unwrap()],
        &["--pause-line", "120", "--pause-virtual-s", "300", "--jog"],
    );
    assert_held_whole("card", &base, &d, &r, &t);
    let _ = std::fs::remove_dir_all(&card);
    // Without a card the RAM slots hold 192 s of printcore's stream (docs/frontend.md, rule
    // 5); then printcore waits for an `ok` and its `send_now("M602")` with it: 150 s.
    let (d, r, t) = session(
        "nocard",
        &[],
        &["--pause-line", "120", "--pause-virtual-s", "150"],
    );
    assert_held_whole("nocard", &base, &d, &r, &t);
    let (d, r, t) = session(
        "endcode",
        &[],
        &["--pause-line", "-40", "--pause-virtual-s", "120", "--jog"],
    );
    assert_held_whole("endcode", &base, &d, &r, &t);
}

/// Two jobs on one connection (printcore's `startprint` again after the first): the second is
/// paused past the nozzle timeout (the first job's end code set the nozzle to 0 °C; the second's
/// start code heats it again, and its pause must re-heat to that). Judged against two unpaused
/// jobs on one connection.
#[test]
fn printcore_second_job_on_one_connection_is_held_whole() {
    let (d, r, base) = session("ref2", &[], &["--pause-line", "0", "--jobs", "2"]);
    assert_eq!(d["end"], true, "{d}");
    assert_eq!(r["session"]["finished"], true, "{}", r["session"]);
    assert!(base.len() > 200, "reference trace of {} moves", base.len());
    let (d, r, t) = session(
        "second",
        &[],
        &[
            "--pause-line",
            "120",
            "--pause-virtual-s",
            "150",
            "--jobs",
            "2",
        ],
    );
    assert_held_whole("second", &base, &d, &r, &t);
}

/// The same with the real OctoPrint and the LayerPause plugin (`octoprint_drive.py --held`):
/// its Pause button (the firmware's layer pause), 300 s of printer time paused (the nozzle
/// off after 45 s), its Resume button, the print to its end. OctoPrint stops streaming when
/// it shows Paused, so what is held is what it had sent before: the lines the firmware took
/// ahead of the boundary. Judged as printcore's runs: the move trace against printcore's
/// unpaused run of the same lines (OctoPrint strips the comments; the moves are the same),
/// nothing refused, the record's `lost_moves` 0, the nozzle hot when the held job goes on.
#[test]
fn octoprint_with_the_plugin_holds_the_job_through_a_pause_past_the_nozzle_timeout() {
    let base = reference("ref_octo");
    let py = host_python("octoprint");
    let octoprint = py.with_file_name("octoprint");
    let trace = std::env::temp_dir().join(format!("held_octo_{}.trace", std::process::id()));
    let _ = std::fs::remove_file(&trace);
    let sim = Sim::start_with(
        "held_octo",
        "100",
        "300",
        &["--host-paced", "--trace", trace.to_str().unwrap()],
    );
    let mut cmd = Command::new(&py);
    cmd.args([
        "tests/hosts/octoprint_drive.py",
        "--held",
        "--port",
        &sim.device,
        "--file",
        FILE,
        "--layers",
        LAYERS,
        "--wait",
        "20",
        "--pause-virtual-s",
        "300",
        "--pause-wall",
        "120",
    ])
    .arg("--octoprint")
    .arg(octoprint);
    let (ok, out, err) = run_bounded(cmd, Duration::from_secs(400));
    let r = sim.finish();
    let got = read_trace(&trace);
    let d: serde_json::Value = serde_json::from_str(out.trim())
        .unwrap_or_else(|e| panic!("OctoPrint driver JSON ({e}): {out}\n{err}"));
    assert!(ok, "driver failed: {d}");
    let sc = &d["scenarios"]["held"];
    eprintln!("octoprint: {sc}\nsession {}", r["session"]);
    assert!(
        sc["pause_virtual_s"].as_f64().unwrap_or(0.0) >= 300.0,
        "{sc}"
    );
    assert_held_whole("octoprint", &base, sc, &r, &got);
}
