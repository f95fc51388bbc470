//! A real OctoPrint (1.11.8 from PyPI, with this repository's plugin `hosts/octoprint_layerpause`)
//! against `sim serve`, driven through its REST API by `tests/hosts/octoprint_drive.py`: one
//! OctoPrint session prints PrusaSlicer's fixture and goes through heat-up, its Pause/Resume
//! buttons, its terminal (M601/M602, M25/M24), pause at layer N (M761 through the plugin) and its
//! Cancel button. The sim's record judges where the firmware stopped (layers from the extrusion
//! heights) and that nothing was lost. Needs `bash scripts/setup-hosts.sh`. One session, `sim
//! serve --speed 20` (OctoPrint still sees 21 distinct temperatures during the heat-up): 20 s
//! of test wall time on the loaded 2-core machine (two sessions at 10×, one per test: 45 s).

mod hosts_common;

use hosts_common::{host_python, run_bounded, Sim};
use std::process::Command;
use std::time::Duration;

fn session(tag: &str) -> (serde_json::Value, serde_json::Value) {
    let py = host_python("octoprint");
    let octoprint = py.with_file_name("octoprint");
    let sim = Sim::start(tag, "20", "300");
    let mut cmd = Command::new(py);
    cmd.args([
        "tests/hosts/octoprint_drive.py",
        "--port",
        &sim.device,
        "--file",
        "tests/fixtures/slicer/prusaslicer.gcode",
        "--layers",
        "8",
        "--pause-layer",
        "3",
        "--wait",
        "15",
    ])
    .arg("--octoprint")
    .arg(octoprint);
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

/// One OctoPrint session for every check (two identical sessions in parallel, one per test,
/// cost twice the CPU on the 2-core machine).
#[test]
fn octoprint_pauses_at_layer_boundaries_shows_heatup_states_and_cancels() {
    let (d, r) = session("op");
    check_firmware_side(&d, &r);
    // Temperatures during the firmware's M109/M190 waits (Marlin prints them about once a
    // second; OctoPrint does not poll M105 while the firmware is busy heating).
    let h = &d["scenarios"]["heatup"];
    assert!(
        h["distinct_tool0"].as_u64().is_some_and(|n| n >= 3),
        "OctoPrint saw no heat-up: {h}"
    );
    // OctoPrint shows Paused for its buttons, its terminal, M25 and the layer pause.
    for name in ["button", "terminal", "m25", "layer"] {
        let sc = &d["scenarios"][name];
        assert_eq!(sc["paused"], true, "{name}: {sc}");
        assert_eq!(sc["resumed"], true, "{name}: {sc}");
        // Back at the job and streaming before the next scenario (bounded wait in the driver).
        assert_eq!(sc["printing_on"], true, "{name}: {sc}");
    }
}
