//! A real OctoPrint (1.11.8 from PyPI, with this repository's plugin `hosts/octoprint_layerpause`)
//! against `sim serve`, driven through its REST API by `tests/hosts/octoprint_drive.py`: one
//! OctoPrint session prints PrusaSlicer's fixture and goes through heat-up, its Pause/Resume
//! buttons, its terminal (M601/M602, M25/M24), pause at layer N (M761 through the plugin) and its
//! Cancel button; then each session prints a second file — the first session one with `M73 L`
//! markers, the second the same file again — and pauses at the same layer N. The sim's record
//! judges where the firmware stopped (layers from the extrusion heights) and that nothing was
//! lost; the slicer's own `;Z:` lines and `sim run --pause-at-layer N` on the same file say
//! where layer N is. Needs `bash scripts/setup-hosts.sh`. One session ≈ 60–90 s (the reprint
//! adds ≈ 40 s). `sim serve --speed 10`: at 20× the first print ended before the layer
//! scenario (the pause at the layer two above the counter's) could run. The two sessions run
//! in parallel.

mod hosts_common;

use hosts_common::{host_python, run_bounded, same_stop_xyz, sim_run_pause_point, Sim};
use std::process::Command;
use std::time::Duration;

/// The first print's file (comments only: OctoPrint strips them, the layers come from the
/// heights).
const STRIPPED: &str = "tests/fixtures/slicer/prusaslicer.gcode";
/// A file whose layers OctoPrint's stream still marks (`M73 L<n>`, which stays when the
/// comments are stripped).
const MARKERS: &str = "tests/fixtures/corpus/family-m73.gcode";

/// What the session prints a second time.
#[derive(Clone, Copy)]
enum Reprint {
    /// The same file.
    Same,
    /// Another file.
    File(&'static str),
}

fn session(tag: &str, reprint: Reprint) -> (serde_json::Value, serde_json::Value) {
    let py = host_python("octoprint");
    let octoprint = py.with_file_name("octoprint");
    let sim = Sim::start(tag, "10", "300");
    let mut cmd = Command::new(py);
    cmd.args([
        "tests/hosts/octoprint_drive.py",
        "--port",
        &sim.device,
        "--file",
        STRIPPED,
        "--layers",
        "8",
        "--pause-layer",
        "3",
        "--wait",
        "15",
    ])
    .arg("--octoprint")
    .arg(octoprint);
    match reprint {
        Reprint::Same => {
            cmd.arg("--reprint");
        }
        Reprint::File(f) => {
            cmd.args(["--reprint", "--reprint-file", f]);
        }
    }
    let (_, out, err) = run_bounded(cmd, Duration::from_secs(300));
    let record = sim.finish();
    let report: serde_json::Value = serde_json::from_str(out.trim())
        .unwrap_or_else(|e| panic!("driver JSON ({e}): {out}\n{err}"));
    eprintln!("driver: {report}\nrecord: {record}");
    assert!(report.get("error").is_none(), "{report}");
    (report, record)
}

/// What the firmware did for OctoPrint, from the sim's record: each pause stopped at the first
/// layer boundary after its request and parked, no move lost or duplicated, the job cancelled
/// (not finished); and OctoPrint's Cancel brought it back to Operational.
fn check_firmware_side(d: &serde_json::Value, r: &serde_json::Value) {
    let sc = &d["scenarios"];
    assert_eq!(d["connected"], true, "{d}");
    assert_eq!(d["plugin"]["active"], true, "plugin not active: {d}");
    assert_eq!(sc["cancel"]["operational_after_cancel"], true, "{d}");
    let pauses = r["pauses"].as_array().expect("pauses");
    assert!(pauses.len() >= 2, "{r}");
    for p in pauses {
        assert_eq!(p["mode"], "layer", "{p}");
        assert!(p["parked_s"].is_number(), "never parked: {p}");
        // Judged only when the job printed on after the pause (the last may be cancelled).
        if p["resumed_s"].is_number() {
            assert_eq!(p["first_boundary_after_request"], true, "{p}");
            assert_eq!(p["resume_position_error_steps"], 0, "{p}");
        }
    }
    let s = &r["session"];
    assert_eq!(s["lost_moves"], 0, "{s}");
    assert_eq!(s["duplicated_moves"], 0, "{s}");
    assert_eq!(s["cancelled"], true, "{s}");
    assert_eq!(s["finished"], false, "{s}");
}

/// Also: a second print, of a file with `M73 L` markers, paused at layer N through the plugin
/// stops where `sim run --pause-at-layer N` stops on that file, and M27 says N − 1 while paused
/// (the reprint adds ≈ 40 s).
#[test]
fn octoprint_pauses_at_layer_boundaries_shows_heatup_and_cancels() {
    let (d, r) = session("op", Reprint::File(MARKERS));
    check_firmware_side(&d, &r);
    let sc = &d["scenarios"]["reprint"];
    let n = sc["pause_layer"].as_u64().expect("pause layer");
    assert!(n >= 2, "{d}");
    assert_eq!(sc["paused"], true, "{d}");
    assert_eq!(sc["layer_when_paused"], n - 1, "{d}");
    let pauses = r["pauses"].as_array().expect("pauses");
    // The button, terminal, M25, layer and reprint pauses, in order.
    assert_eq!(pauses.len(), 5, "{r}");
    let want = sim_run_pause_point(MARKERS, n as u32);
    same_stop_xyz(
        &pauses[4],
        &want,
        "OctoPrint's pause at layer N of the M73 L file",
    );
    // Temperatures during the firmware's M109/M190 waits (Marlin prints them about once a
    // second; OctoPrint does not poll M105 while the firmware is busy heating).
    let h = &d["scenarios"]["heatup"];
    assert!(
        h["distinct_tool0"].as_u64().is_some_and(|n| n >= 3),
        "OctoPrint saw no heat-up: {h}"
    );
}

#[test]
fn octoprint_shows_paused_for_its_buttons_terminal_and_layer_pause() {
    let (d, r) = session("op_states", Reprint::Same);
    check_firmware_side(&d, &r);
    same_layer_in_both_prints(&d, &r);
    for name in ["button", "terminal", "m25", "layer"] {
        let sc = &d["scenarios"][name];
        assert_eq!(sc["paused"], true, "{name}: {sc}");
        assert_eq!(sc["resumed"], true, "{name}: {sc}");
        // Back at the job and streaming before the next scenario (bounded wait in the driver).
        assert_eq!(sc["printing_on"], true, "{name}: {sc}");
    }
}

/// Z of the extrusions of each layer of the fixture, from its own `;Z:` lines (the slicer's
/// statement, not the firmware's detector), in mm: layer n (as the slicer's preview numbers it)
/// is `z[n - 1]`.
fn slicer_layer_z() -> Vec<f64> {
    let text = std::fs::read_to_string(tests::workspace_root().join(STRIPPED)).expect("fixture");
    text.lines()
        .filter_map(|l| l.strip_prefix(";Z:"))
        .filter_map(|z| z.trim().parse().ok())
        .collect()
}

/// The plugin's "pause at layer N" names the same physical layer in the first print and in a
/// second print of the same file in the same OctoPrint session (the firmware's count restarts
/// at OctoPrint's `M110 N0`): both stop where the slicer's layer N begins (OctoPrint strips the
/// comments, so the boundary is the first extrusion of layer N, after its Z move), and M27
/// reports layer N − 1 (the last one printed) while paused, both times.
fn same_layer_in_both_prints(d: &serde_json::Value, r: &serde_json::Value) {
    let sc = &d["scenarios"];
    let n = sc["layer"]["pause_layer"].as_u64().expect("pause layer") as usize;
    assert!(n >= 2, "{d}");
    assert_eq!(sc["reprint"]["pause_layer"], n as u64, "{d}");
    assert_eq!(sc["reprint"]["paused"], true, "{d}");
    assert_eq!(sc["layer"]["layer_when_paused"], (n - 1) as u64, "{d}");
    assert_eq!(sc["reprint"]["layer_when_paused"], (n - 1) as u64, "{d}");
    let pauses = r["pauses"].as_array().expect("pauses");
    let z = slicer_layer_z();
    let stop_z =
        |p: &serde_json::Value| p["pause_point_steps"][2].as_f64().expect("stop Z") / 400.0;
    // The button, terminal, M25, layer and reprint pauses, in order.
    assert_eq!(pauses.len(), 5, "{r}");
    let want = sim_run_pause_point(STRIPPED, n as u32);
    for p in &pauses[3..] {
        assert!(
            (stop_z(p) - z[n - 1]).abs() < 0.003,
            "pause at layer {n} stopped at Z {} mm, layer {n} is at {} mm: {p}",
            stop_z(p),
            z[n - 1]
        );
        // Where `sim run --pause-at-layer N` stops on the same file: one numbering.
        same_stop_xyz(p, &want, "OctoPrint's pause at layer N");
    }
}
