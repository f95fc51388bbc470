//! End to end: `host-tools send` streams a real PrusaSlicer job to `sim serve` (the firmware on a
//! pseudo-terminal), pauses at a layer, swaps in a file re-sliced with another infill density,
//! resumes and finishes; the sim's `--record` shows the stop at the layer boundary, no lost or
//! duplicated move, and the step count of the new infill from the next layer on. The host-side
//! fallback runs against the sim configured as a FIFO firmware.
//!
//! The binaries are taken from the target directory this test runs from, built with cargo when
//! missing.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use firmware::config::MachineConfig;
use firmware::gcode::parse_line;
use firmware::machine::MachineState;
use host_tools::job::{ops, Job};
use layerref::Comments;
use tests::judge::boundary_positions_xyz;
use tests::pty::reachable;
use tests::workspace_root;

mod hosts_common;
use hosts_common::bin;

struct Sim {
    child: Child,
    device: String,
    record: PathBuf,
}

impl Sim {
    fn start(policy: &str, tag: &str) -> Sim {
        // Build the sender first: the sim ends after some idle seconds without host bytes
        // while nothing moves (a paused printer counts; a heater wait does not), so nothing
        // may be built between the sim's start and the sender's.
        bin("host-tools", "host-tools");
        bin("sim", "sim");
        let record =
            std::env::temp_dir().join(format!("send_sim_{tag}_{}.json", std::process::id()));
        let _ = std::fs::remove_file(&record);
        let mut child = Command::new(bin("sim", "sim"))
            .args([
                "serve",
                "--speed",
                "20",
                "--exit-after-idle",
                "15",
                "--policy",
                policy,
            ])
            .arg("--record")
            .arg(&record)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start sim serve");
        let mut line = String::new();
        let out = child.stdout.take().expect("stdout");
        BufReader::new(out)
            .read_line(&mut line)
            .expect("device path");
        let device = line.trim().to_string();
        assert!(device.starts_with("/dev/"), "sim printed {device:?}");
        let device = reachable(&device, child.id());
        Sim {
            child,
            device,
            record,
        }
    }

    /// Waits for the session to end (idle exit) and returns its pause records.
    fn finish(mut self) -> Vec<serde_json::Value> {
        let t0 = Instant::now();
        loop {
            if let Ok(Some(_)) = self.child.try_wait() {
                break;
            }
            if t0.elapsed() > Duration::from_secs(60) {
                let _ = self.child.kill();
                let _ = self.child.wait();
                panic!("sim serve did not end");
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        let text = std::fs::read_to_string(&self.record).expect("record");
        let _ = std::fs::remove_file(&self.record);
        let v: serde_json::Value = serde_json::from_str(&text).expect("record JSON");
        v["pauses"].as_array().cloned().expect("pauses array")
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

fn send(device: &str, args: &[&str]) -> (bool, String) {
    let child = Command::new(bin("host-tools", "host-tools"))
        .arg("send")
        .args(args)
        .args(["--port", device, "--plain", "--connect-timeout", "20"])
        .current_dir(workspace_root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run host-tools send");
    // Never hang the test suite: the job takes about a minute at 20x.
    let pid = child.id();
    let t0 = Instant::now();
    let guard = std::thread::spawn(move || {
        while t0.elapsed() < Duration::from_secs(300) {
            std::thread::sleep(Duration::from_millis(200));
            if !Path::new(&format!("/proc/{pid}")).exists() {
                return;
            }
        }
        let _ = Command::new("kill").arg(pid.to_string()).status();
    });
    let out = child.wait_with_output().expect("host-tools send output");
    let _ = guard.join();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

fn load(rel: &str) -> Job {
    let text = std::fs::read_to_string(workspace_root().join(rel)).expect(rel);
    Job::from_gcode(&text).expect("job")
}

/// The position (steps) the firmware's machine state commands after every line of a job.
fn final_position(job: &Job) -> [i32; 4] {
    let cfg = MachineConfig::ENDER3;
    let mut m = MachineState::new(&cfg);
    for (_, l) in job.lines() {
        if let Ok(line) = parse_line(l.as_bytes()) {
            if let Some(c) = &line.command {
                let _ = m.apply(c, &cfg);
            }
        }
    }
    m.position_steps(&cfg)
}

/// Where the firmware's machine state is after every line before layer `n` of `job` (the
/// n-th layer printed, from 1: docs/planner.md, "What a layer is").
fn position_before_layer(job: &Job, n: u32) -> [i32; 4] {
    let i = job.index_of_layer(n).expect("layer in the job");
    final_position(&Job {
        start: job.start.clone(),
        layers: job.layers[..i].to_vec(),
        end: vec![],
        warnings: vec![],
    })
}

/// The independent judge (`layerref`, which shares no code with the firmware's layer detector)
/// of "the boundary before layer `n`" in the file `rel` as sent (comments kept): the X Y Z
/// (steps) a stop at that boundary can have.
fn reference_boundary_xyz(rel: &str, n: u32) -> Vec<[i32; 3]> {
    let text = std::fs::read_to_string(workspace_root().join(rel)).expect(rel);
    let all = boundary_positions_xyz(&text, Comments::Keep, &MachineConfig::ENDER3);
    let at: Vec<[i32; 3]> = all
        .into_iter()
        .filter(|(k, _)| *k == n)
        .map(|(_, p)| p)
        .collect();
    assert!(!at.is_empty(), "{rel}: no boundary before layer {n}");
    at
}

/// The stop point's X Y Z from a pause record.
fn stop_xyz(r: &serde_json::Value) -> [i32; 3] {
    let p = &r["pause_point_steps"];
    let at = |i: usize| p[i].as_i64().and_then(|v| i32::try_from(v).ok());
    [at(0), at(1), at(2)].map(|v| v.expect("pause point"))
}

/// Total motor steps (all axes) the firmware's machine state commands for a job.
fn commanded_steps(job: &Job) -> u64 {
    let cfg = MachineConfig::ENDER3;
    let mut m = MachineState::new(&cfg);
    let mut prev = m.position_steps(&cfg);
    let mut total = 0u64;
    for (_, l) in job.lines() {
        let Ok(line) = parse_line(l.as_bytes()) else {
            continue;
        };
        if let Some(c) = &line.command {
            if m.apply(c, &cfg).is_ok() {
                let now = m.position_steps(&cfg);
                total += now
                    .iter()
                    .zip(prev.iter())
                    .map(|(a, b)| u64::from((a - b).unsigned_abs()))
                    .sum::<u64>();
                prev = now;
            }
        }
    }
    total
}

const BASE: &str = "tests/fixtures/sender/base-infill20.gcode";
const SWAP: &str = "tests/fixtures/sender/swap-infill60.gcode";

#[test]
fn send_pauses_at_a_layer_swaps_the_infill_and_finishes() {
    let sim = Sim::start("firmware", "swap");
    let (ok, log) = send(
        &sim.device,
        &[
            BASE,
            "--pause-at-layer",
            "12",
            "--resume-after",
            "1",
            "--swap-at-pause",
            SWAP,
        ],
    );
    assert!(ok, "send failed:\n{log}");
    assert!(log.contains("pause method Firmware"), "{log}");
    assert!(
        log.contains("paused at the boundary before layer 12"),
        "{log}"
    );
    assert!(log.contains("continuing with its layer 12"), "{log}");
    assert!(log.contains("job complete"), "{log}");
    let rec = sim.finish();
    assert_eq!(rec.len(), 1, "{rec:?}");
    let r = &rec[0];
    // The head stopped exactly where layer 11 ends: the position the firmware's machine state
    // commands after every line before layer 12's mark — a boundary before layer 12 as the
    // independent reference numbers the layers (layers from 1, docs/planner.md).
    let base = load(BASE);
    let want_stop = position_before_layer(&base, 12);
    let p = &r["pause_point_steps"];
    for (i, w) in want_stop.iter().enumerate().take(3) {
        assert_eq!(p[i].as_i64(), Some(i64::from(*w)), "axis {i}: {r}");
    }
    assert!(
        reference_boundary_xyz(BASE, 12).contains(&stop_xyz(r)),
        "not at layerref's boundary before layer 12: {r}"
    );
    // The sim's own record says so too (from the firmware's Stopped record): at the end of
    // layer 11, the boundary before layer 12.
    assert_eq!(r["stopped_at_layer_boundary"], true, "{r}");
    assert_eq!(r["stop_layer"], 11, "{r}");
    assert_eq!(r["lost_moves"], 0, "{r}");
    assert_eq!(r["duplicated_moves"], 0, "{r}");
    assert_eq!(r["resume_position_error_steps"], 0, "{r}");
    assert_eq!(r["finished"], true, "{r}");
    // The printer executed the new infill from layer 12 on: its step count is the swapped
    // job's plus the park and return (computed from the pause point), not the original job's.
    let mut swapped = base.clone();
    let at = base.index_of_layer(12).expect("layer 12");
    ops::continue_with(&mut swapped, at, &load(SWAP)).expect("swap");
    let want = commanded_steps(&swapped) as f64;
    let orig = commanded_steps(&base) as f64;
    let got = r["steps"].as_f64().expect("steps");
    let cfg = MachineConfig::ENDER3;
    let spm = |i: usize| f64::from(cfg.axes[i].steps_per_mm);
    let p = &r["pause_point_steps"];
    let at = |i: usize| p[i].as_f64().expect("pause point");
    let park = 2.0
        * ((f64::from(cfg.pause.park_x_mm) * spm(0) - at(0)).abs()
            + (f64::from(cfg.pause.park_y_mm) * spm(1) - at(1)).abs()
            + f64::from(cfg.pause.lift_z_mm) * spm(2)
            + f64::from(cfg.pause.retract_mm) * spm(3));
    assert!(
        (got - want - park).abs() < 2_000.0,
        "steps {got}: swapped job {want} + park {park} (original job {orig})"
    );
    assert!(
        (want - orig).abs() > 50_000.0,
        "the fixtures differ too little to tell: {want} vs {orig}"
    );
}

#[test]
fn send_fallback_on_fifo_firmware_pauses_at_the_layer_end() {
    let sim = Sim::start("fifo", "fifo");
    let (ok, log) = send(
        &sim.device,
        &[
            BASE,
            "--method",
            "host",
            "--pause-at-layer",
            "12",
            "--resume-after",
            "1",
        ],
    );
    assert!(ok, "send failed:\n{log}");
    assert!(log.contains("pause method HostSide"), "{log}");
    assert!(
        log.contains("paused at the boundary before layer 12"),
        "{log}"
    );
    assert!(log.contains("job complete"), "{log}");
    // The host-side pause sends no realtime request; the sim finds it as a standstill between
    // two extruding moves (mode `host`) and judges it from the executed blocks: the last
    // extrusion before it is the end of layer 11, the first after it is in layer 12, and the
    // host's return put the head (E included) back exactly where it stopped.
    let rec = sim.finish();
    assert_eq!(rec.len(), 1, "{rec:?}");
    let r = &rec[0];
    assert_eq!(r["mode"], "host", "{r}");
    assert_eq!(r["policy"], "fifo", "{r}");
    assert_eq!(r["stopped_at_layer_boundary"], true, "{r}");
    assert_eq!(r["stop_layer"], 11, "{r}");
    assert_eq!(r["resume_position_error_steps"], 0, "{r}");
    assert_eq!(r["lost_moves"], 0, "{r}");
    assert_eq!(r["duplicated_moves"], 0, "{r}");
    assert_eq!(r["finished"], true, "{r}");
    // The stop point is where the firmware's machine state is after every line of layer 11.
    let base = load(BASE);
    let want_stop = position_before_layer(&base, 12);
    let p = &r["pause_point_steps"];
    for (i, w) in want_stop.iter().enumerate().take(2) {
        assert_eq!(p[i].as_i64(), Some(i64::from(*w)), "axis {i}: {r}");
    }
    assert!(
        reference_boundary_xyz(BASE, 12).contains(&stop_xyz(r)),
        "not at layerref's boundary before layer 12: {r}"
    );
}
