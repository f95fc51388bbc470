//! The SD listing across the seam to a real host: `sim serve --sd DIR` with files in nested
//! directories answers `M20 L`, and OctoPrint's own M20 line parser
//! (`octoprint.util.comm.parse_file_list_line`, OctoPrint 1.11.8 from PyPI, run in the venv
//! `scripts/setup-hosts.sh` makes) reads back every file's short path, size and long path as
//! written. Then each file is selected as OctoPrint selects a card file (`M23 /<short path>`:
//! OctoPrint puts a `/` before a name from the card's list) and the firmware answers
//! `File opened: <its name> Size: <size>`. Needs `bash scripts/setup-hosts.sh`. ≈ 5 s (3 of them the
//! session's idle end).

mod hosts_common;

use hosts_common::host_python;
use sim::run::Policy;
use sim::serve::ServeArgs;
use std::io::Write;
use std::process::{Command, Stdio};
use std::time::Duration;
use tests::pty::serve_in_thread;

const WAIT: Duration = Duration::from_secs(30);

/// (path under DIR, size).
const FILES: [(&str, usize); 5] = [
    ("Root file.gcode", 101),
    ("prints/Benchy long name.gcode", 202),
    ("prints/CUBES/CUBE.GCO", 303),
    ("prints/cubes two/cube two.gcode", 404),
    ("a/b/c/d/e/f/six.gcode", 505),
];

#[test]
fn octoprint_reads_the_nested_listing_and_its_selection_opens_each_file() {
    let py = host_python("octoprint");
    let dir = std::env::temp_dir().join(format!("octoprint-sd-{}", std::process::id()));
    for (path, n) in FILES {
        let p = dir.join(path);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, "G1 X1 ; filler\n".repeat(n / 15 + 1).get(..n).unwrap()).unwrap();
    }
    // OctoPrint's parser, started first and waited for (its import takes 0.5 s on an idle
    // machine, 3.3 s with a load average of 16; the session ends after 3 s without a line),
    // then fed the lines as they came.
    let mut child = Command::new(&py)
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .args([
            "-c",
            "import sys, json\n\
             from octoprint.util.comm import parse_file_list_line\n\
             print('ready', flush=True)\n\
             print(json.dumps([list(parse_file_list_line(l)) for l in sys.stdin.read().splitlines()]))",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("octoprint's python");
    let mut parsed_out = std::io::BufReader::new(child.stdout.take().expect("stdout"));
    let mut ready = String::new();
    std::io::BufRead::read_line(&mut parsed_out, &mut ready).expect("parser ready");
    assert_eq!(ready.trim(), "ready", "OctoPrint's parser did not start");
    let sd = dir.clone();
    let (server, mut host) = serve_in_thread(
        ServeArgs {
            speed: 10.0,
            record: None,
            policy: Policy::Firmware,
            exit_after_idle: 3.0,
            link: None,
            flash: None,
            sd: Some(sd),
            tft: false,
            tft_control_bytes: false,
            host_paced: false,
            machine: None,
            trace: None,
            allow_cold_extrusion: false,
        },
        Duration::from_secs(20),
    );
    host.write("M20 L");
    host.until("Begin file list", WAIT, |l| l == "Begin file list");
    let mut lines = Vec::new();
    loop {
        let l = host.until("a listing line", WAIT, |_| true);
        if l == "End file list" {
            break;
        }
        lines.push(l);
    }
    host.ok(WAIT);

    child
        .stdin
        .take()
        .unwrap()
        .write_all(lines.join("\n").as_bytes())
        .unwrap();
    let mut out = String::new();
    std::io::Read::read_to_string(&mut parsed_out, &mut out).unwrap();
    child.wait().unwrap();
    let parsed: Vec<(String, u64, Option<String>, Option<String>)> =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(parsed.len(), FILES.len(), "{lines:?}");
    for (path, n) in FILES {
        let (short, size, _, _) = parsed
            .iter()
            .find(|p| p.3.as_deref() == Some(path))
            .unwrap_or_else(|| panic!("{path} not read back by OctoPrint: {parsed:?}"));
        assert_eq!(*size as usize, n, "{path}");
        assert_eq!(short.split('/').count(), path.split('/').count(), "{short}");
        // Selected as OctoPrint selects a card file: a `/` before the listed name.
        host.write(&format!("M23 /{short}"));
        let opened = host.until("File opened", WAIT, |l| {
            l.starts_with("File opened: ") || l.starts_with("open failed")
        });
        let name = short.rsplit('/').next().unwrap();
        assert_eq!(opened, format!("File opened: {name} Size: {n}"), "{short}");
        host.ok(WAIT);
    }
    drop(host);
    let _ = server.record();
    let _ = std::fs::remove_dir_all(&dir);
}
