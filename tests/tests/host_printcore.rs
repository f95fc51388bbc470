//! Printrun's printcore (the engine of Pronterface and pronsole, from PyPI) against `sim serve`:
//! it streams PrusaSlicer's fixture with its own `startprint`, and pauses, resumes and cancels
//! through its normal send path (`send_now`, a priority queue sent after the stream's next
//! `ok`) while it keeps streaming, driven by `tests/hosts/printcore_drive.py`: M601, then M105
//! and a jog while paused, then M602; a pause at layer N (`M761 L<n>`); printcore's own
//! `pause()`/`resume()`; M524; then the same file printed three more times in the same session,
//! `M27` at the same point of each (the count restarts at printcore's `N-1 M110`). printcore ignores `//action:paused` and streams on: the
//! firmware's parked intake (docs/frontend.md, "Host rules") gives its job lines `ok`s, paced,
//! and each `ok` lets its priority lines out. Judged by the sim's record (layers from the
//! extrusion heights, moves from the executed steps), not by the driver or the firmware's
//! layer detector. Needs `bash scripts/setup-hosts.sh`. One session ≈ 20 s.

mod hosts_common;

use hosts_common::{host_python, run_bounded, same_stop_xyz, sim_run_pause_point, Sim};
use std::process::Command;
use std::time::Duration;

/// One session: M601 in the first layer (M105, a jog, M602 while paused), `M761 L3` sent in
/// the first layer, printcore's own pause in the third layer, M524 in the fourth, M400; then
/// three more prints, each asked `M27` at job line 800 (in layer 3) and cancelled.
/// Returns the driver's report and the sim's record.
fn session(tag: &str) -> (serde_json::Value, serde_json::Value) {
    drive(
        tag,
        "tests/fixtures/slicer/prusaslicer.gcode",
        &[
            "--layers",
            "5",
            "--pause-line",
            "150",
            "--layer-request-line",
            "250",
            "--pause-layer",
            "3",
            "--host-pause-line",
            "800",
            "--cancel-line",
            "1000",
            "--wait",
            "20",
            "--repeat",
            "3",
            "--m27-line",
            "800",
        ],
    )
}

/// `tests/hosts/printcore_drive.py` printing `file` (relative to the workspace root) to a
/// fresh `sim serve` (×20, ending after 60 idle s) with the driver's further `args`.
/// Returns the driver's report and the sim's record.
fn drive(tag: &str, file: &str, args: &[&str]) -> (serde_json::Value, serde_json::Value) {
    let py = host_python("printrun");
    let sim = Sim::start(tag, "20", "60");
    let mut cmd = Command::new(py);
    cmd.args([
        "tests/hosts/printcore_drive.py",
        "--port",
        &sim.device,
        "--file",
        file,
    ])
    .args(args);
    let (ok, out, err) = run_bounded(cmd, Duration::from_secs(300));
    let record = sim.finish();
    assert!(ok, "driver failed: {out}\n{err}");
    let report: serde_json::Value = serde_json::from_str(out.trim()).expect("driver JSON");
    eprintln!("driver: {report}\nrecord: {record}");
    (report, record)
}

/// Z of the extrusions of each layer of the fixture, from its own `;Z:` lines (the slicer's
/// statement, not the firmware's detector), in mm: layer n (as the slicer's preview numbers
/// it, and the firmware) is `z[n - 1]`.
fn slicer_layer_z() -> Vec<f64> {
    let text = std::fs::read_to_string(
        tests::workspace_root().join("tests/fixtures/slicer/prusaslicer.gcode"),
    )
    .expect("fixture");
    text.lines()
        .filter_map(|l| l.strip_prefix(";Z:"))
        .filter_map(|z| z.trim().parse().ok())
        .collect()
}

#[test]
fn printcore_pauses_resumes_and_cancels_through_send_now_while_streaming() {
    let (d, r) = session("pc");
    let sc = &d["scenarios"];
    for name in ["pause", "layer"] {
        let s = &sc[name];
        assert_eq!(s["paused"], true, "{name}: {d}");
        // printcore kept streaming: the send_now lines got out through the parked intake.
        assert_eq!(s["printcore_streaming"], true, "{name}: {d}");
        assert_eq!(s["m105_answered"], true, "{name}: {d}");
        assert_eq!(s["resumed"], true, "{name}: {d}");
    }
    let h = &sc["host_pause"];
    for k in [
        "paused",
        "drained",
        "stream_stopped",
        "resumed",
        "streaming_again",
    ] {
        assert_eq!(h[k], true, "host_pause {k}: {d}");
    }
    assert_eq!(sc["cancel"]["action_cancel"], true, "{d}");
    assert_eq!(sc["end"]["m400_ok"], true, "{d}");
    assert_eq!(d["errors"].as_array().map(Vec::len), Some(0), "{d}");
    let pauses = r["pauses"].as_array().expect("pauses");
    let fw: Vec<_> = pauses.iter().filter(|p| p["mode"] == "layer").collect();
    assert_eq!(fw.len(), 2, "the M601 and the M761 pause: {r}");
    for p in &fw {
        // From the extrusion heights: the last extrusion before the stop is of the request's
        // layer, the first after it (after the resume) of the next.
        assert_eq!(p["first_boundary_after_request"], true, "{p}");
        assert!(p["parked_s"].is_number(), "never parked: {p}");
        // The jog ran on the service lane: the head returns exactly to the pause point.
        assert_eq!(p["resume_position_error_steps"], 0, "{p}");
    }
    // The pause at layer 3 stopped where the slicer's layer 3 begins: at its height (the
    // comment-free stream's boundary is the first extrusion of the layer, after its Z move).
    let z = slicer_layer_z();
    let stop_z_mm = fw[1]["pause_point_steps"][2].as_f64().expect("stop Z") / 400.0;
    assert!(
        (stop_z_mm - z[2]).abs() < 0.003,
        "M761 L3 stopped at Z {stop_z_mm} mm, layer 3 is at {} mm",
        z[2]
    );
    // ... and where `sim run --pause-at-layer 3` stops on the same file: one numbering.
    let want = sim_run_pause_point("tests/fixtures/slicer/prusaslicer.gcode", 3);
    same_stop_xyz(fw[1], &want, "printcore M761 L3");
    // The same point of three more prints of the file in the same session (job line 800, in
    // the slicer's layer 3): M27 says layer 3 each time — the count restarts at every print.
    let m27 = sc["repeat"]["m27"].as_array().expect("M27 answers");
    assert_eq!(m27.len(), 3, "{d}");
    for a in m27 {
        assert!(
            a.as_str().is_some_and(|t| t.starts_with("echo:layer 3 ")),
            "M27 at job line 800 of a reprint: {a} (want layer 3): {d}"
        );
    }
    let s = &r["session"];
    assert_eq!(s["lost_moves"], 0, "{s}");
    assert_eq!(s["duplicated_moves"], 0, "{s}");
    assert_eq!(s["cancelled"], true, "{s}");
    assert_eq!(s["finished"], false, "a cancelled job is not finished: {s}");
    assert!(s["layers_extruded"].as_u64().is_some_and(|l| l >= 4), "{s}");
}

/// A file whose layers printcore's stream still marks (`M73 L<n>`, which stays when printcore
/// strips the comments; tests/fixtures/corpus/family-m73.gcode, PrusaSlicer's output with
/// `M73 L` added): `M761 L4` sent in layer 2 stops where `sim run --pause-at-layer 4` stops,
/// the first boundary before layer 4 (after an M601 pause in layer 1). One session ≈ 25 s.
#[test]
fn printcore_pause_at_layer_on_a_marker_file_names_the_sim_run_layer() {
    const FILE: &str = "tests/fixtures/corpus/family-m73.gcode";
    // Lines (the file's): layer 1 from 24, 2 from 304, 3 from 529, 4 from 752, 5 from 842.
    let (d, r) = drive(
        "pc_m73",
        FILE,
        &[
            "--layers",
            "6",
            "--pause-line",
            "100",
            "--layer-request-line",
            "400",
            "--pause-layer",
            "4",
            "--cancel-line",
            "900",
            "--wait",
            "20",
        ],
    );
    let sc = &d["scenarios"]["layer"];
    assert_eq!(sc["paused"], true, "{d}");
    assert_eq!(sc["resumed"], true, "{d}");
    let pauses = r["pauses"].as_array().expect("pauses");
    let fw: Vec<_> = pauses.iter().filter(|p| p["mode"] == "layer").collect();
    assert_eq!(fw.len(), 2, "the M601 and the M761 pause: {r}");
    assert_eq!(fw[1]["first_boundary_after_request"], true, "{}", fw[1]);
    let want = sim_run_pause_point(FILE, 4);
    same_stop_xyz(fw[1], &want, "printcore M761 L4 on the M73 L file");
    let s = &r["session"];
    assert_eq!(s["lost_moves"], 0, "{s}");
    assert_eq!(s["duplicated_moves"], 0, "{s}");
}
