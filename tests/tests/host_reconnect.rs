//! A host that goes away while the printer is paused, and another that comes (issue 22;
//! docs/frontend.md, "A session that ends while paused"), with the real printcore: the first
//! streams PrusaSlicer's fixture, pauses it with M601 and disconnects; the second is told the
//! job is held and that only M524 ends it, its M602 is refused (the rest of the job went with
//! the first host), its M524 cancels with the head parked, and a new job then prints to its
//! end. The sim's record says where the head ended and that nothing was lost.
//! `sim serve --speed 20`. Needs `bash scripts/setup-hosts.sh`.

mod hosts_common;

use hosts_common::{host_python, run_bounded, Sim};
use std::process::Command;
use std::time::Duration;

#[test]
fn printcore_reconnecting_to_a_paused_printer_can_only_cancel_and_the_head_stays_parked() {
    let py = host_python("printrun");
    let sim = Sim::start("reconnect", "20", "4");
    let t0 = std::time::Instant::now();
    let mut cmd = Command::new(py);
    cmd.args([
        "tests/hosts/printcore_reconnect.py",
        "--port",
        &sim.device,
        "--file",
        "tests/fixtures/slicer/prusaslicer.gcode",
    ]);
    let (ok, out, err) = run_bounded(cmd, Duration::from_secs(300));
    let r = sim.finish();
    assert!(ok, "driver failed: {out}\n{err}");
    let d: serde_json::Value = serde_json::from_str(out.trim()).expect("driver JSON");
    eprintln!("driver ({:.0} s): {d}", t0.elapsed().as_secs_f64());
    assert_eq!(d["paused"], true, "{d}");
    assert_eq!(d["second_online"], true, "{d}");
    let told = d["told"].as_str().unwrap_or("");
    assert!(
        told.contains("its host went away") && told.contains("M524 ends it"),
        "{d}"
    );
    assert_eq!(d["told_paused_action"], true, "{d}");
    assert!(
        d["m602"].as_str().unwrap_or("").contains("refused: resume"),
        "{d}"
    );
    assert_eq!(d["cancelled"], true, "{d}");
    let pauses = r["pauses"].as_array().expect("pauses");
    let fw: Vec<_> = pauses.iter().filter(|p| p["mode"] == "layer").collect();
    assert_eq!(fw.len(), 1, "{r}");
    // After the cancel the head is where the pause parked it: at least the lift above the
    // pause point (M114's Z, mm).
    let cfg = firmware::config::MachineConfig::ENDER3;
    let spm_z = cfg.axes[2].steps_per_mm as f64;
    let stop_z_mm = fw[0]["pause_point_steps"][2].as_f64().expect("pause point") / spm_z;
    let m114 = d["m114_after_cancel"].as_str().unwrap_or("");
    let z_mm: f64 = m114
        .split_whitespace()
        .find_map(|w| w.strip_prefix("Z:"))
        .and_then(|z| z.parse().ok())
        .unwrap_or_else(|| panic!("M114 after the cancel: {d}"));
    assert!(
        z_mm >= stop_z_mm + cfg.pause.lift_z_mm as f64 - 0.05,
        "head at Z {z_mm} after the cancel, paused at Z {stop_z_mm}: {d}"
    );
    assert_eq!(d["end"], true, "{d}");
    assert_eq!(d["errors"].as_array().map(Vec::len), Some(0), "{d}");
    // Stopped at a layer boundary (which one is host_printcore's to judge: here the
    // record's resume fields describe the cancel's park, not a resume).
    assert_eq!(fw[0]["stopped_at_layer_boundary"], true, "{}", fw[0]);
    let s = &r["session"];
    assert_eq!(s["lost_moves"], 0, "{s}");
    assert_eq!(s["duplicated_moves"], 0, "{s}");
    assert_eq!(s["cancelled"], true, "{s}");
    assert_eq!(s["finished"], true, "the second job ran to its end: {s}");
}
