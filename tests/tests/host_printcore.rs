//! Printrun's printcore (the engine of Pronterface and pronsole, from PyPI) against `sim serve`:
//! it streams PrusaSlicer's fixture with its own `startprint`, and pauses, resumes and cancels
//! through its normal send path (`send_now`), driven by `tests/hosts/printcore_drive.py`: M601
//! while streaming; at `//action:paused` printcore's own `pause()` (stops its stream), then
//! M602 (or the realtime byte 0x12) and printcore's `resume()`; M524 and `cancelprint()`.
//! (`send_now("M602")` while printcore still streams cannot get out once the firmware's queue
//! is full behind the barrier: every `ok` would invite one more job line. docs/hosts.md.)
//! Judged by the sim's record (layers from the extrusion heights, moves from the executed
//! steps), not by the driver. Needs `bash scripts/setup-hosts.sh`. One session ≈ 15 s.

mod hosts_common;

use hosts_common::{host_python, run_bounded, Sim};
use std::process::Command;
use std::time::Duration;

/// One session: pause with M601 in the first layer and resume with M602, pause again in the
/// second layer and resume with the realtime byte, cancel with M524 in the third layer, M400.
/// Returns the driver's report and the sim's record.
fn session(tag: &str) -> (serde_json::Value, serde_json::Value) {
    let py = host_python("printrun");
    let sim = Sim::start(tag, "20", "60");
    let mut cmd = Command::new(py);
    cmd.args([
        "tests/hosts/printcore_drive.py",
        "--port",
        &sim.device,
        "--file",
        "tests/fixtures/slicer/prusaslicer.gcode",
        "--layers",
        "4",
        "--pause-line",
        "150",
        "--pause2-line",
        "500",
        "--cancel-line",
        "1000",
        "--wait",
        "10",
    ]);
    let (ok, out, err) = run_bounded(cmd, Duration::from_secs(180));
    let record = sim.finish();
    assert!(ok, "driver failed: {out}\n{err}");
    let report: serde_json::Value = serde_json::from_str(out.trim()).expect("driver JSON");
    eprintln!("driver: {report}\nrecord: {record}");
    (report, record)
}

#[test]
fn printcore_pauses_at_the_first_layer_boundary_resumes_and_cancels() {
    let (d, r) = session("pc");
    let sc = &d["scenarios"];
    for name in ["pause", "pause_byte"] {
        assert_eq!(sc[name]["paused"], true, "{name}: {d}");
        assert_eq!(sc[name]["resumed"], true, "{name}: {d}");
    }
    assert_eq!(sc["cancel"]["action_cancel"], true, "{d}");
    assert_eq!(sc["end"]["m400_ok"], true, "{d}");
    assert_eq!(d["errors"].as_array().map(Vec::len), Some(0), "{d}");
    let pauses = r["pauses"].as_array().expect("pauses");
    assert_eq!(pauses.len(), 2, "{r}");
    for p in pauses {
        assert_eq!(p["mode"], "layer", "{p}");
        // From the extrusion heights: the last extrusion before the stop is of the request's
        // layer, the first after it (after the resume) of the next.
        assert_eq!(p["first_boundary_after_request"], true, "{p}");
        assert!(p["parked_s"].is_number(), "never parked: {p}");
        // printcore's restore lines come after the job lines the firmware holds: the head
        // returns exactly to the pause point.
        assert_eq!(p["resume_position_error_steps"], 0, "{p}");
    }
    let s = &r["session"];
    assert_eq!(s["lost_moves"], 0, "{s}");
    assert_eq!(s["duplicated_moves"], 0, "{s}");
    assert_eq!(s["cancelled"], true, "{s}");
    assert_eq!(s["finished"], false, "a cancelled job is not finished: {s}");
    assert!(s["layers_extruded"].as_u64().is_some_and(|l| l >= 3), "{s}");
}
