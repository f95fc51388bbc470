//! OctoPrint disconnecting from a paused printer and connecting again (issue 22;
//! docs/frontend.md, "A session that ends while paused"): `tests/hosts/octoprint_drive.py
//! --reconnect` prints PrusaSlicer's fixture, pauses with its button, disconnects, connects
//! (OctoPrint has no job now). The firmware tells the new session the job is held and only
//! M524 ends it; the terminal's M602 is refused (before issue 22 it printed the held lines and
//! left the head on the part, unparked); M524 cancels with the head parked (M114 at least the
//! pause's lift above the pause point). `sim serve --speed 10`. Needs
//! `bash scripts/setup-hosts.sh`.

mod hosts_common;

use hosts_common::{host_python, run_bounded, Sim};
use std::process::Command;
use std::time::Duration;

#[test]
fn octoprint_reconnecting_to_a_paused_printer_cancels_with_the_head_parked() {
    let py = host_python("octoprint");
    let octoprint = py.with_file_name("octoprint");
    let sim = Sim::start("octo_reconnect", "10", "300");
    let t0 = std::time::Instant::now();
    let mut cmd = Command::new(py);
    cmd.args([
        "tests/hosts/octoprint_drive.py",
        "--reconnect",
        "--port",
        &sim.device,
        "--file",
        "tests/fixtures/slicer/prusaslicer.gcode",
        "--layers",
        "99",
        "--wait",
        "20",
    ])
    .arg("--octoprint")
    .arg(octoprint);
    let (_, out, err) = run_bounded(cmd, Duration::from_secs(300));
    let r = sim.finish();
    eprintln!("wall {:.0} s", t0.elapsed().as_secs_f64());
    let d: serde_json::Value = serde_json::from_str(out.trim())
        .unwrap_or_else(|e| panic!("driver JSON ({e}): {out}\n{err}"));
    eprintln!("driver: {d}\nrecord: {r}");
    assert!(d.get("error").is_none(), "{d}");
    let sc = &d["scenarios"]["reconnect"];
    assert_eq!(sc["paused"], true, "{sc}");
    assert!(
        sc["reconnected_state"]
            .as_str()
            .unwrap_or("")
            .starts_with("Operational"),
        "{sc}"
    );
    let told = sc["told"][0].as_str().unwrap_or("");
    assert!(told.contains("M524 ends it"), "{sc}");
    assert!(
        sc["m602"][0]
            .as_str()
            .unwrap_or("")
            .contains("refused: resume"),
        "{sc}"
    );
    assert_eq!(sc["cancel_action"], true, "{sc}");
    let pauses = r["pauses"].as_array().expect("pauses");
    let fw: Vec<_> = pauses.iter().filter(|p| p["mode"] == "layer").collect();
    assert_eq!(fw.len(), 1, "{r}");
    let cfg = firmware::config::MachineConfig::ENDER3;
    let spm_z = cfg.axes[2].steps_per_mm as f64;
    let stop_z_mm = fw[0]["pause_point_steps"][2].as_f64().expect("pause point") / spm_z;
    let z_mm: f64 = sc["m114_after_cancel"]
        .as_str()
        .unwrap_or("")
        .split_whitespace()
        .find_map(|w| w.strip_prefix("Z:"))
        .and_then(|z| z.parse().ok())
        .unwrap_or_else(|| panic!("M114 after the cancel: {sc}"));
    assert!(
        z_mm >= stop_z_mm + cfg.pause.lift_z_mm as f64 - 0.05,
        "head at Z {z_mm} after the cancel, paused at Z {stop_z_mm}"
    );
    let end_z = r["end_position_steps"][2].as_f64().expect("end position") / spm_z;
    assert!(
        end_z >= stop_z_mm + cfg.pause.lift_z_mm as f64 - 0.05,
        "ended at Z {end_z}"
    );
    let s = &r["session"];
    assert_eq!(s["lost_moves"], 0, "{s}");
    assert_eq!(s["duplicated_moves"], 0, "{s}");
    assert_eq!(s["cancelled"], true, "{s}");
}
