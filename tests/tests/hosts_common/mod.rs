//! What the real-host tests share: the binaries of this workspace, a `sim serve` session on a
//! pseudo-terminal with its `--record`, the host programs that `scripts/setup-hosts.sh`
//! installed under `.hosts/`, and bounded runs of them.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use tests::workspace_root;

/// `target/<profile>` of this test binary.
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test exe");
    exe.parent()
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .expect("target dir")
}

/// A workspace binary (`sim` or `host-tools`), built with cargo first.
///
/// Both binaries are built in one cargo run, once per test process, before any of them is
/// started: a later `cargo build -p <one package>` may rebuild shared crates with another
/// feature set (tens of seconds), and a `sim serve` already started would see an idle host
/// and end meanwhile.
///
/// `LAYERPAUSE_WORKSPACE_BINS=1` (set by `scripts/test.sh`) says the binaries in this target
/// directory were just built by the `cargo test --workspace` running this test (it builds the
/// bins of `sim` and `host-tools` for their own integration tests before it runs any test):
/// they are used as they are. `cargo build -p sim -p host-tools` would resolve features for
/// those two packages alone (no `tmc-model` from board-emu, no dev-dependency features),
/// rebuild most of their dependency tree and overwrite them: ≈ 2 min of CI's test time.
pub fn bin(_package: &str, name: &str) -> PathBuf {
    static BUILT: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let dir = profile_dir();
    if std::env::var_os("LAYERPAUSE_WORKSPACE_BINS").is_some_and(|v| v == "1") {
        let path = dir.join(name);
        assert!(
            path.exists(),
            "LAYERPAUSE_WORKSPACE_BINS=1 but {} is missing: run `cargo test --workspace`",
            path.display()
        );
        return path;
    }
    let built = BUILT.get_or_init(|| {
        let target = dir.parent().expect("target root");
        let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
        c.args(["build", "-q", "-p", "sim", "-p", "host-tools", "--bins"])
            .current_dir(workspace_root())
            .env("CARGO_TARGET_DIR", target);
        if dir.file_name().is_some_and(|n| n == "release") {
            c.arg("--release");
        }
        c.status().is_ok_and(|s| s.success())
    });
    assert!(*built, "building the workspace binaries failed");
    dir.join(name)
}

/// The Python of a host venv made by `scripts/setup-hosts.sh` (`printrun` or `octoprint`).
pub fn host_python(venv: &str) -> PathBuf {
    let dir = std::env::var_os("HOSTS_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join(".hosts"));
    let py = dir.join(venv).join("bin").join("python");
    assert!(
        py.exists(),
        "{} is missing: run `bash scripts/setup-hosts.sh` (installs the real hosts from PyPI)",
        py.display()
    );
    py
}

/// A `sim serve` process on a pseudo-terminal, writing its record on exit.
pub struct Sim {
    child: Child,
    /// The device path it printed.
    pub device: String,
    /// The TFT port's device path (`--tft`).
    #[allow(dead_code)]
    pub tft: Option<String>,
    record: PathBuf,
}

impl Sim {
    /// Start `sim serve --speed <speed> --exit-after-idle <idle_s> --record …`.
    pub fn start(tag: &str, speed: &str, idle_s: &str) -> Sim {
        Self::start_with(tag, speed, idle_s, &[])
    }

    /// [`Sim::start`] with more `sim serve` arguments (`--sd DIR`, ...).
    pub fn start_with(tag: &str, speed: &str, idle_s: &str, more: &[&str]) -> Sim {
        let record = std::env::temp_dir().join(format!("hosts_{tag}_{}.json", std::process::id()));
        let _ = std::fs::remove_file(&record);
        let mut child = Command::new(bin("sim", "sim"))
            .args(["serve", "--speed", speed, "--exit-after-idle", idle_s])
            .args(more)
            .arg("--record")
            .arg(&record)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start sim serve");
        let mut line = String::new();
        let out = child.stdout.take().expect("stdout");
        let mut out = BufReader::new(out);
        out.read_line(&mut line).expect("device path");
        let device = line.trim().to_string();
        assert!(device.starts_with("/dev/"), "sim printed {device:?}");
        let tft = more.contains(&"--tft").then(|| {
            line.clear();
            out.read_line(&mut line).expect("TFT device path");
            let tft = line.trim().to_string();
            assert!(tft.starts_with("/dev/"), "sim printed {tft:?}");
            tft
        });
        Sim {
            child,
            device,
            tft,
            record,
        }
    }

    /// The session's peak resident memory so far (`VmHWM`), kB.
    pub fn peak_rss_kb(&self) -> Option<u64> {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).ok()?;
        status
            .lines()
            .find_map(|l| l.strip_prefix("VmHWM:"))
            .and_then(|v| v.split_whitespace().next()?.parse().ok())
    }

    /// End the session (SIGTERM, as Ctrl-C would) and return its record.
    pub fn finish(mut self) -> serde_json::Value {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let t0 = Instant::now();
        loop {
            if let Ok(Some(_)) = self.child.try_wait() {
                break;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(30),
                "sim serve did not end"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        let text = std::fs::read_to_string(&self.record).expect("record");
        let _ = std::fs::remove_file(&self.record);
        serde_json::from_str(&text).expect("record JSON")
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

/// Run a command to its end, killed after `limit`; returns (success, stdout, stderr).
pub fn run_bounded(mut cmd: Command, limit: Duration) -> (bool, String, String) {
    let child = cmd
        .current_dir(workspace_root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let pid = child.id();
    let t0 = Instant::now();
    let guard = std::thread::spawn(move || {
        while t0.elapsed() < limit {
            std::thread::sleep(Duration::from_millis(100));
            if !Path::new(&format!("/proc/{pid}")).exists() {
                return;
            }
        }
        let _ = Command::new("kill").arg(pid.to_string()).status();
    });
    let out = child.wait_with_output().expect("output");
    let _ = guard.join();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Where `sim run <file> --pause-at-layer <layer> --json` stops (its `pause_point_steps`,
/// X Y Z E): the layer the simulator names `layer` in the stream a host sends (comments
/// stripped, `sim run`'s default), to compare a real host's pause at layer N with. `file` is
/// relative to the workspace root. ≈ 2 s of CPU (both runs of the whole file).
pub fn sim_run_pause_point(file: &str, layer: u32) -> Vec<i64> {
    let mut cmd = Command::new(bin("sim", "sim"));
    cmd.args([
        "run",
        file,
        "--pause-at-layer",
        &layer.to_string(),
        "--json",
    ]);
    let (ok, out, err) = run_bounded(cmd, Duration::from_secs(300));
    assert!(ok, "sim run failed: {out}\n{err}");
    let r: serde_json::Value = serde_json::from_str(out.trim()).expect("sim run JSON");
    assert_eq!(r["first_boundary_after_request"], true, "sim run: {r}");
    r["pause_point_steps"]
        .as_array()
        .expect("sim run paused")
        .iter()
        .map(|v| v.as_i64().expect("steps"))
        .collect()
}

/// `p`'s pause point (X Y Z, steps) is `want`'s: the same place of the same layer.
pub fn same_stop_xyz(p: &serde_json::Value, want: &[i64], what: &str) {
    let got: Vec<i64> = p["pause_point_steps"]
        .as_array()
        .unwrap_or_else(|| panic!("{what}: no pause point: {p}"))
        .iter()
        .map(|v| v.as_i64().expect("steps"))
        .collect();
    assert_eq!(
        got[..3],
        want[..3],
        "{what}: stopped at {got:?} steps, sim run --pause-at-layer at {want:?}: {p}"
    );
}
