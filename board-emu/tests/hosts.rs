//! Real host programs on the unmodified image, over its USB port: `board-emu --serve` (the
//! emulated SKR 2 paced to the wall clock, its USB CDC port on a pseudo-terminal) with
//! Printrun's printcore (`tests/hosts/printcore_image.py`) and OctoPrint 1.11.8 with the
//! LayerPause plugin (`tests/hosts/octoprint_image.py`), both installed by
//! `scripts/setup-hosts.sh`. Judged by the emulated board's pins (net steps against the test's
//! own count of the file; the park's start against `layerref`'s layer boundaries), not by
//! the host or the image's own account.

mod support;

use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use support::*;

/// The Python of a host venv made by `scripts/setup-hosts.sh`.
fn host_python(venv: &str) -> PathBuf {
    let dir = std::env::var_os("HOSTS_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".hosts"));
    let py = dir.join(venv).join("bin").join("python");
    assert!(
        py.exists(),
        "{} is missing: run `bash scripts/setup-hosts.sh`",
        py.display()
    );
    py
}

/// `board-emu --serve` running the image.
struct Served {
    child: Child,
    usb: String,
    json: PathBuf,
}

impl Served {
    fn start(tag: &str) -> Served {
        let (bin, elf) = image();
        let json = temp(&format!("{tag}-serve.json"));
        let _ = std::fs::remove_file(&json);
        let mut child = Command::new(env!("CARGO_BIN_EXE_board-emu"))
            .arg("--serve")
            .arg("--image")
            .arg(bin)
            .arg("--elf")
            .arg(elf)
            .args(["--start-mm", "10,10,2", "--json"])
            .arg(&json)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("board-emu --serve starts");
        let mut out = BufReader::new(child.stdout.take().expect("stdout"));
        let mut line = String::new();
        out.read_line(&mut line).expect("the usb: line");
        let usb = line
            .trim()
            .strip_prefix("usb: ")
            .expect("`usb: PATH` first")
            .to_string();
        line.clear();
        out.read_line(&mut line).expect("the tft: line");
        assert!(line.starts_with("tft: /dev/"), "{line:?}");
        Served { child, usb, json }
    }

    /// SIGTERM, then the report it writes.
    fn finish(mut self) -> serde_json::Value {
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        let _ = nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM);
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(60) {
            if let Ok(Some(_)) = self.child.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let text = std::fs::read_to_string(&self.json).expect("the report written at SIGTERM");
        let _ = std::fs::remove_file(&self.json);
        serde_json::from_str(&text).expect("JSON report")
    }
}

/// Runs `cmd` for at most `limit`: (success, stdout, stderr).
fn run_bounded(mut cmd: Command, limit: Duration) -> (bool, String, String) {
    let mut child = cmd
        .current_dir(root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("host driver starts");
    let mut so = child.stdout.take().expect("stdout");
    let mut se = child.stderr.take().expect("stderr");
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = so.read_to_string(&mut s);
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = se.read_to_string(&mut s);
        s
    });
    let t = Instant::now();
    let ok = loop {
        if let Ok(Some(st)) = child.try_wait() {
            break st.success();
        }
        if t.elapsed() > limit {
            let _ = child.kill();
            break false;
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    (
        ok,
        out.join().unwrap_or_default(),
        err.join().unwrap_or_default(),
    )
}

/// A job in a file (with its comments: the host decides what to send).
fn job_file(tag: &str, job: &[&str]) -> PathBuf {
    let p = temp(&format!("{tag}-job.gcode"));
    std::fs::write(&p, job.join("\n") + "\n").expect("job file");
    p
}

/// Three 10 mm square layers like [`THREE_LAYERS`], each side cut into 0.5 mm moves (80 lines
/// a layer): more lines than the printer queues, so a host still streams while it prints.
fn fine_layers() -> Vec<String> {
    // The same start: M302 P1, G28, modes, the first layer's height and corner.
    let start = THREE_LAYERS
        .iter()
        .position(|l| l.starts_with(";LAYER"))
        .unwrap_or(0);
    let mut v: Vec<String> = THREE_LAYERS[..start]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let mut e = 0.0f64;
    for layer in 0..3 {
        v.push(format!(";LAYER:{layer}"));
        if layer > 0 {
            v.push(format!("G1 Z{:.1} F600", 0.2 * f64::from(layer + 1)));
        }
        let corners = [
            (20.0, 20.0),
            (30.0, 20.0),
            (30.0, 30.0),
            (20.0, 30.0),
            (20.0, 20.0),
        ];
        for w in corners.windows(2) {
            let ((x0, y0), (x1, y1)) = (w[0], w[1]);
            for k in 1..=20 {
                let f = f64::from(k) / 20.0;
                e += 0.025;
                let feed = if k == 1 { " F1800" } else { "" };
                v.push(format!(
                    "G1 X{:.2} Y{:.2} E{e:.4}{feed}",
                    x0 + (x1 - x0) * f,
                    y0 + (y1 - y0) * f
                ));
            }
        }
    }
    v.push("G1 X40 Y40 F6000".into());
    v
}

fn steps(v: &serde_json::Value) -> [i64; 4] {
    ["X", "Y", "Z", "E"].map(|a| v[a].as_i64().expect("steps"))
}

fn point(v: &serde_json::Value) -> Option<[i64; 4]> {
    let a = v.as_array()?;
    Some([0, 1, 2, 3].map(|i| a[i].as_i64().unwrap_or(i64::MIN)))
}

/// printcore: M601 while it streams, parked, M602, the job to its end.
fn printcore(tag: &str, park_s: f64) {
    let job = job_file(tag, THREE_LAYERS);
    let served = Served::start(tag);
    let mut cmd = Command::new(host_python("printrun"));
    cmd.arg("tests/hosts/printcore_image.py")
        .args(["--port", &served.usb, "--file"])
        .arg(&job)
        .args(["--pause-in-layer", "1", "--park-s", &park_s.to_string()]);
    let (ok, out, err) = run_bounded(cmd, Duration::from_secs_f64(600.0 + 2.0 * park_s));
    let r = served.finish();
    let _ = std::fs::remove_file(&job);
    assert!(ok, "driver failed: {out}\n{err}");
    let d: serde_json::Value = serde_json::from_str(out.trim()).expect("driver JSON");
    eprintln!("driver: {d}");
    for e in ["online", "paused", "resumed", "end"] {
        let ev = d["events"]
            .as_array()
            .and_then(|v| v.iter().find(|x| x["event"] == e))
            .unwrap_or_else(|| panic!("no {e}: {d}"));
        assert_eq!(ev["ok"], true, "{e}: {d}");
    }
    assert_eq!(d["refused"].as_array().map(Vec::len), Some(0), "{d}");
    assert_eq!(d["errors"].as_array().map(Vec::len), Some(0), "{d}");
    // The pins: every step of the file (counted here, not by the library) and a park that
    // began at a layer boundary as `layerref` finds them in the comment-free stream printcore
    // sends.
    assert_eq!(
        steps(&r["net_steps"]),
        expected_net_steps(THREE_LAYERS, START_MM),
        "{:?}",
        r["serve"]["usb_lines"]
    );
    let stop = point(&r["pause_point_net_steps"]).expect("parked");
    let bounds = layerref_boundaries(THREE_LAYERS, layerref::Comments::Strip);
    assert!(
        bounds.contains(&stop),
        "park began at {stop:?}; layerref's boundaries: {bounds:?}; the steps before: {}",
        r["park_moves"]
    );
    assert!(
        r["faults"].as_array().is_some_and(Vec::is_empty),
        "{}",
        r["faults"]
    );
    assert!(
        r["resets"].as_array().is_some_and(Vec::is_empty),
        "{}",
        r["resets"]
    );
    eprintln!(
        "printcore on the image: {} s wall, {} virtual s ({:.2} virtual/wall)",
        r["wall_s"], r["virtual_s"], r["serve"]["virtual_per_wall"]
    );
}

#[test]
fn printcore_over_usb_pauses_at_a_layer_parks_resumes_and_ends_with_every_step() {
    printcore("printcore", 2.0);
}

#[test]
#[ignore = "a long pause on the emulated board (real time): `LAYERPAUSE_PAUSE_S=600 cargo test -p board-emu --test hosts -- --ignored --nocapture`"]
fn printcore_over_usb_through_a_long_pause() {
    let s: f64 = std::env::var("LAYERPAUSE_PAUSE_S")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(600.0);
    printcore("printcore-long", s);
}

#[test]
fn octoprint_over_usb_pause_resume_cancel_and_a_reconnect_that_sees_the_held_job() {
    let fine = fine_layers();
    let fine: Vec<&str> = fine.iter().map(String::as_str).collect();
    let job = job_file("octoprint", &fine);
    let served = Served::start("octoprint");
    let octo = host_python("octoprint").with_file_name("octoprint");
    let mut cmd = Command::new(host_python("octoprint"));
    cmd.arg("tests/hosts/octoprint_image.py")
        .args(["--port", &served.usb, "--file"])
        .arg(&job)
        .arg("--octoprint")
        .arg(&octo);
    let (ok, out, err) = run_bounded(cmd, Duration::from_secs(900));
    let r = served.finish();
    let _ = std::fs::remove_file(&job);
    assert!(ok, "driver failed: {out}\n{err}");
    let d: serde_json::Value = serde_json::from_str(out.trim()).expect("driver JSON");
    eprintln!("driver: {d}");
    assert_eq!(d["plugin"]["active"], true, "{d}");
    let b = &d["scenarios"]["button"];
    for k in ["printing", "paused", "parked", "resumed", "resumed_action"] {
        assert_eq!(b[k], true, "button {k}: {d}");
    }
    assert_eq!(
        d["scenarios"]["cancel"]["operational_after_cancel"], true,
        "{d}"
    );
    let c = &d["scenarios"]["reconnect"];
    for k in [
        "printing",
        "paused",
        "disconnected",
        "reconnected",
        "cancel_action",
    ] {
        assert_eq!(c[k], true, "reconnect {k}: {d}");
    }
    let told = c["told"].as_str().unwrap_or("");
    assert!(
        told.contains("paused: job held") && told.contains("M524 ends it"),
        "{d}"
    );
    // The first pause: at a layer boundary of the comment-free stream OctoPrint sends.
    let stop = point(&r["pause_point_net_steps"]).expect("parked");
    let bounds = layerref_boundaries(&fine, layerref::Comments::Strip);
    assert!(
        bounds.contains(&stop),
        "park began at {stop:?}; layerref's boundaries: {bounds:?}; the steps before: {}",
        r["park_moves"]
    );
    // Four sessions on the USB port: DTR raised and dropped by OctoPrint's connects.
    let dtr: Vec<&str> = r["usb"]["events"]
        .as_array()
        .expect("events")
        .iter()
        .filter_map(|e| e[1].as_str())
        .filter(|e| e.starts_with("DTR"))
        .collect();
    assert!(dtr.len() >= 4, "{dtr:?}");
    assert!(
        r["faults"].as_array().is_some_and(Vec::is_empty),
        "{}",
        r["faults"]
    );
    eprintln!(
        "OctoPrint on the image: {} s wall, {} virtual s ({:.2} virtual/wall)",
        r["wall_s"], r["virtual_s"], r["serve"]["virtual_per_wall"]
    );
}
