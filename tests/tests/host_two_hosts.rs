//! Two real hosts on the firmware's two ports during one print (issue 22): OctoPrint (with the
//! plugin) prints PrusaSlicer's fixture on the USB port (`tests/hosts/octoprint_drive.py
//! --two-hosts`), printcore sits on the TFT port (`sim serve --tft`,
//! `tests/hosts/printcore_tft.py`). Replies go to the port that asked (printcore's M118 comes
//! back to it, never to OctoPrint; OctoPrint's M105 answers never reach printcore), the
//! notifications to both: printcore's M601 pauses OctoPrint's job (OctoPrint shows Paused),
//! OctoPrint's Resume is seen by printcore, OctoPrint's Pause too, printcore's M602 resumes
//! it (OctoPrint shows Printing), OctoPrint's Cancel is seen by printcore. The sim's record:
//! both pauses at the first boundary after their request, nothing lost.
//! `sim serve --speed 10`. Needs `bash scripts/setup-hosts.sh`.

mod hosts_common;

use hosts_common::{host_python, run_bounded, Sim};
use std::process::Command;
use std::time::Duration;

#[test]
fn octoprint_on_usb_and_printcore_on_the_tft_port_share_one_print() {
    let octo_py = host_python("octoprint");
    let octoprint = octo_py.with_file_name("octoprint");
    let pc_py = host_python("printrun");
    let sim = Sim::start_with("twohosts", "10", "300", &["--tft"]);
    let tft = sim.tft.clone().expect("TFT port");
    let t0 = std::time::Instant::now();
    let mut pc = Command::new(pc_py);
    pc.args(["tests/hosts/printcore_tft.py", "--port", &tft]);
    let printcore = std::thread::spawn(move || run_bounded(pc, Duration::from_secs(400)));
    let mut octo = Command::new(octo_py);
    octo.args([
        "tests/hosts/octoprint_drive.py",
        "--two-hosts",
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
    let (_, out, err) = run_bounded(octo, Duration::from_secs(400));
    let (_, pc_out, pc_err) = printcore.join().expect("printcore thread");
    let r = sim.finish();
    eprintln!("wall {:.0} s", t0.elapsed().as_secs_f64());
    let d: serde_json::Value = serde_json::from_str(out.trim())
        .unwrap_or_else(|e| panic!("OctoPrint driver JSON ({e}): {out}\n{err}"));
    let p: serde_json::Value = serde_json::from_str(pc_out.trim())
        .unwrap_or_else(|e| panic!("printcore driver JSON ({e}): {pc_out}\n{pc_err}"));
    eprintln!("octoprint: {d}\nprintcore: {p}\nrecord: {r}");
    assert!(d.get("error").is_none(), "{d}");
    assert_eq!(d["plugin"]["active"], true, "{d}");
    let sc = &d["scenarios"]["twohosts"];
    // The replies: to the asker only.
    assert!(p["reply_here"].is_string(), "{p}");
    assert_eq!(
        sc["recv_other_hosts_reply"].as_array().map(Vec::len),
        Some(0),
        "{sc}"
    );
    assert_eq!(p["others_temperature_answers"], 0, "{p}");
    // The notifications: to both, whoever asked.
    assert!(p["printing_seen"].is_string(), "{p}");
    assert_eq!(p["paused_by_me"], true, "{p}");
    assert_eq!(sc["paused_by_other"], true, "{sc}");
    assert_eq!(sc["resumed_here"], true, "{sc}");
    assert_eq!(p["resumed_by_other"], true, "{p}");
    assert_eq!(sc["paused_here"], true, "{sc}");
    assert_eq!(p["paused_by_other"], true, "{p}");
    assert_eq!(p["resumed_by_me"], true, "{p}");
    assert_eq!(sc["resumed_by_other"], true, "{sc}");
    assert_eq!(sc["operational_after_cancel"], true, "{sc}");
    assert_eq!(p["cancel_seen"], true, "{p}");
    assert_eq!(p["errors"].as_array().map(Vec::len), Some(0), "{p}");
    let pauses = r["pauses"].as_array().expect("pauses");
    let layer: Vec<_> = pauses.iter().filter(|p| p["mode"] == "layer").collect();
    assert_eq!(layer.len(), 2, "{r}");
    for q in layer {
        assert_eq!(q["first_boundary_after_request"], true, "{q}");
        assert_eq!(q["resume_position_error_steps"], 0, "{q}");
    }
    let s = &r["session"];
    assert_eq!(s["lost_moves"], 0, "{s}");
    assert_eq!(s["duplicated_moves"], 0, "{s}");
}
