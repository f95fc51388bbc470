//! End to end: power-cut resume through `sim serve`. The test plays the host over the
//! pseudo-terminal. A numbered job is layer-paused (realtime `M25`); once the paused-job record
//! is in the flash file, the sim process is killed (`kill -9`: the power goes). A new `sim
//! serve` on the same `--flash` and `--machine` files announces the kept job; the host sends
//! `M1000`, then the job from the line the firmware names, and the job completes. The moves the
//! sim executed across both processes (`--trace`: the sim's own record of the steps, in the
//! head's physical coordinates from its endstops) must equal an unpaused run's, move for move,
//! to the step.
//!
//! The same for a job printed from the SD card (`--sd DIR`, a real PrusaSlicer file): the
//! second session is started with the same card, and `M1000` alone continues the file from the
//! kept byte offset; the host sends nothing else. Beyond the trace's equality, the boundary is
//! checked against the file itself (a tracker of the test's own, not the firmware's detector):
//! the kept offset is the start of a line of the layer the file marks there, and the head
//! stopped where the file has that marker, to the step.
//!
//! The sim binary is taken from the target directory this test runs from (built by cargo).

use firmware::config::MachineConfig;
use firmware::storage::{JobSource, PausedJob, RecordStore, SettingsStore, Skr2FlashModel};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tests::gcode::{layer_markers, moves_head};
use tests::pty::{checksum, reachable, PtyHost};

mod hosts_common;
use hosts_common::bin;

/// The job: home (M400: a layer pause is asked for after homing), heaters set without
/// waiting, 5 layers of squares with Cura markers. Line i is numbered i + 1.
fn job() -> Vec<String> {
    let mut v: Vec<String> = [
        "G28",
        "M400",
        "M83",
        "M104 S205",
        "M140 S60",
        "M106 S200",
        "G92 E0",
    ]
    .map(String::from)
    .to_vec();
    for layer in 0..5 {
        v.push(format!(";LAYER:{layer}"));
        v.push(format!("G1 Z{:.1} F600", 0.2 * (layer + 1) as f32));
        v.push("G1 F2400".into());
        for i in 0..12 {
            let (x, y) = [(30.5, 30.0), (90.25, 30.0), (90.25, 91.3), (30.5, 91.3)][i % 4];
            v.push(format!("G1 X{x} Y{y} E2.11"));
        }
    }
    v
}

fn numbered(lines: &[String], i: usize) -> String {
    let body = format!("N{} {}", i + 1, lines[i]);
    format!("{body}*{}", checksum(&body))
}

/// One `sim serve` process and the host's end of its pseudo-terminal.
struct Session {
    child: Child,
    host: PtyHost,
}

impl Session {
    /// `sim serve` at `speed` times real time, with the card `sd` when given.
    fn start(f: &Files, sd: Option<&Path>, speed: &str) -> Session {
        let mut cmd = Command::new(bin("sim", "sim"));
        cmd.args(["serve", "--speed", speed])
            .arg("--flash")
            .arg(&f.flash)
            .arg("--machine")
            .arg(&f.machine)
            .arg("--trace")
            .arg(&f.trace);
        if let Some(d) = sd {
            cmd.arg("--sd").arg(d);
        }
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start sim serve");
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("device path");
        let device = reachable(line.trim(), child.id());
        let host = PtyHost::open(Path::new(&device));
        Session { child, host }
    }

    /// Read lines until one satisfies `f` (within 60 s); returns it.
    fn until(&mut self, what: &str, f: impl Fn(&str) -> bool) -> String {
        self.host.until(what, Duration::from_secs(60), f)
    }

    fn write(&mut self, l: &str) {
        self.host.write(l);
    }

    /// Send a line and wait for its `ok`.
    fn send(&mut self, l: &str) {
        self.write(l);
        self.until(&format!("ok for {l}"), |s| s.starts_with("ok"));
    }

    /// The power goes: SIGKILL, nothing runs after it.
    fn kill(mut self) -> Vec<String> {
        let _ = self.child.kill();
        let _ = self.child.wait();
        std::mem::take(&mut self.host.seen)
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// The trace's moves (one line each), waiting up to 20 s for `n` of them.
fn moves(trace: &Path, n: usize) -> Vec<String> {
    let end = Instant::now() + Duration::from_secs(20);
    loop {
        let v: Vec<String> = std::fs::read_to_string(trace)
            .unwrap_or_default()
            .lines()
            .map(String::from)
            .collect();
        if v.len() >= n || Instant::now() > end {
            return v;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The paused-job record in the flash image, if any (read through the firmware's store on a
/// copy of the file).
fn kept_job(flash: &Path) -> Option<PausedJob> {
    let bytes = std::fs::read(flash).ok()?;
    let len = bytes.len() as u32;
    let model: Skr2FlashModel<Vec<u8>> = Skr2FlashModel::new(bytes);
    SettingsStore::new(model, 0..len)
        .ok()
        .and_then(|mut s| s.load_job().ok().flatten())
}

fn job_in_flash(flash: &Path) -> bool {
    kept_job(flash).is_some()
}

/// Wait (10 s at most) until the record is in the flash file; returns it.
fn wait_kept(flash: &Path) -> PausedJob {
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        if let Some(j) = kept_job(flash) {
            return j;
        }
        assert!(
            Instant::now() < end,
            "the record never reached the flash file"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

struct Files {
    flash: PathBuf,
    machine: PathBuf,
    trace: PathBuf,
}

impl Files {
    fn new(tag: &str) -> Files {
        let d = std::env::temp_dir();
        let pid = std::process::id();
        let f = Files {
            flash: d.join(format!("power-cut-{tag}-{pid}.flash")),
            machine: d.join(format!("power-cut-{tag}-{pid}.machine")),
            trace: d.join(format!("power-cut-{tag}-{pid}.moves")),
        };
        f.remove();
        f
    }

    fn remove(&self) {
        for p in [&self.flash, &self.machine, &self.trace] {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Ends a resumed run whose last line (`M400`) is sent: the firmware said `//action:resumed`,
/// the record is gone from flash, and the moves traced (the cut run's `before` ones, then the
/// resumed run's) are the reference's `want`, in order. `first_seen` is what the host saw in
/// the cut run (for the message).
fn assert_resumed_as_reference(
    b: Session,
    f: &Files,
    want: &[String],
    before: usize,
    first_seen: &[String],
) {
    assert!(
        b.host.seen.iter().any(|l| l == "//action:resumed"),
        "{:?}",
        b.host.seen
    );
    let got = moves(&f.trace, want.len());
    let second_seen = b.kill();
    assert!(
        !job_in_flash(&f.flash),
        "the record is cleared once resumed"
    );
    assert_eq!(
        got.len(),
        want.len(),
        "moves: {} before the cut + {} after, want {}\n{first_seen:?}\n{second_seen:?}",
        before,
        got.len() - before,
        want.len()
    );
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(g, w, "move {k} (the cut was after move {before})");
    }
}

#[test]
fn a_job_killed_while_paused_resumes_with_m1000_and_runs_the_moves_of_an_unpaused_run() {
    let lines = job();

    // The reference: the same job without a pause.
    let r = Files::new("ref");
    let mut s = Session::start(&r, None, "200");
    s.send("M110 N0");
    for i in 0..lines.len() {
        let l = numbered(&lines, i);
        s.send(&l);
    }
    s.send("M400");
    let n = lines.iter().filter(|l| l.contains(" X")).count() + 5;
    let want = moves(&r.trace, n);
    assert_eq!(want.len(), n, "every move of the reference traced");
    s.kill();

    // The job, layer-paused during layer 1; killed once the record is in flash.
    let f = Files::new("cut");
    let mut a = Session::start(&f, None, "200");
    a.send("M110 N0");
    let pause_at = lines.iter().position(|l| l == ";LAYER:1").unwrap() + 4;
    let mut kept = None;
    for i in 0..lines.len() {
        if i == pause_at {
            a.write("M25");
        }
        let l = numbered(&lines, i);
        a.write(&l);
        let got = a.until("ok or a kept job", |s| {
            s.starts_with("ok") || s.contains("power-cut resume: keeping job")
        });
        if got.contains("keeping job") {
            kept = Some(got);
            break; // parked with the queue full: the host's line waits, the power goes
        }
    }
    let kept = match kept {
        Some(k) => k,
        None => a.until("a kept job", |s| {
            s.contains("power-cut resume: keeping job")
        }),
    };
    wait_kept(&f.flash);
    let first_seen = a.kill();
    let line: usize = kept
        .rsplit(' ')
        .next()
        .and_then(|w| w.parse().ok())
        .unwrap_or_else(|| panic!("{kept}"));
    let before = moves(&f.trace, 0).len();
    assert!(before > 0 && before < want.len(), "{kept}: {before} moves");

    // Power again: the same flash and machine; the host resumes from the line named.
    let mut b = Session::start(&f, None, "200");
    let note = b.until("the kept-job notification", |s| {
        s.starts_with("//action:notification Paused job kept")
    });
    assert!(
        note.contains(&format!("continue from host line {line} ")),
        "{note}"
    );
    b.write("M1000");
    let reply = b.until("M1000's reply", |s| s.contains("power-cut resume: layer"));
    assert!(
        reply.ends_with(&format!(
            "send the job from host line {line} (M110 N{} first)",
            line - 1
        )),
        "{reply}"
    );
    b.until("ok for M1000", |s| s.starts_with("ok"));
    b.send(&format!("M110 N{}", line - 1));
    for i in (line - 1)..lines.len() {
        let l = numbered(&lines, i);
        b.send(&l);
    }
    b.send("M400");
    assert_resumed_as_reference(b, &f, &want, before, &first_seen);
    r.remove();
    f.remove();
}

const SD_FIXTURE: &str = "prusa-zhop.gcode";

/// Start the card's file and wait for `Done printing file`; then M400 (its `ok` comes once
/// the sim has written the trace).
fn print_from_card(s: &mut Session) {
    s.send(&format!("M23 {SD_FIXTURE}"));
    s.send("M24");
    s.until("Done printing file", |l| l == "Done printing file");
    s.send("M400");
}

#[test]
fn an_sd_job_killed_while_paused_continues_with_m1000_alone_and_runs_the_moves_of_an_unpaused_run()
{
    let gcode = std::fs::read_to_string(
        tests::workspace_root()
            .join("tests/fixtures/corpus")
            .join(SD_FIXTURE),
    )
    .expect("fixture");
    let card = std::env::temp_dir().join(format!("power-cut-sd-{}", std::process::id()));
    std::fs::create_dir_all(&card).unwrap();
    std::fs::write(card.join(SD_FIXTURE), &gcode).unwrap();

    // The reference: the same file from the card, without a pause.
    let r = Files::new("sd-ref");
    let mut s = Session::start(&r, Some(&card), "200");
    print_from_card(&mut s);
    let want = moves(&r.trace, 0);
    s.kill();
    assert!(want.len() > 500, "{} moves", want.len());

    // The file, layer-paused (M25) once a third of it has been read; killed once the record
    // is in flash.
    let f = Files::new("sd-cut");
    // At 50 times real time: the file's last two thirds take seconds, so a loaded machine's
    // host still asks for the pause while the file prints.
    let mut a = Session::start(&f, Some(&card), "50");
    a.send("M27 S1");
    a.send(&format!("M23 {SD_FIXTURE}"));
    a.send("M24");
    loop {
        let l = a.until("SD progress", |l| l.starts_with("SD printing byte "));
        let read: usize = l["SD printing byte ".len()..]
            .split('/')
            .next()
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{l}"));
        if read > gcode.len() / 3 {
            break;
        }
    }
    a.write("M25");
    let keeping = a.until("a kept job", |l| {
        l.contains("power-cut resume: keeping job")
    });
    let kept = wait_kept(&f.flash);
    let first_seen = a.kill();
    let before = moves(&f.trace, 0).len();
    assert!(
        before > 0 && before < want.len(),
        "{keeping}: {before} moves"
    );
    let JobSource::Sd { path, offset, size } = &kept.source else {
        panic!("{kept:?}");
    };
    assert_eq!(*size as usize, gcode.len());
    let offset = *offset as usize;
    assert!(
        keeping.ends_with(&format!("SD file {path} byte {offset}")),
        "{keeping}"
    );

    // The boundary, from the file: the offset starts a line, after a layer marker with no
    // motion line between them; the head stopped where the file is at that marker.
    let markers = layer_markers(&gcode, ";LAYER_CHANGE");
    let k = markers
        .iter()
        .rposition(|m| m.offset <= offset)
        .filter(|&k| k > 0)
        .unwrap_or_else(|| panic!("offset {offset} after no layer marker but the first"));
    assert!(
        gcode.as_bytes()[offset - 1] == b'\n',
        "offset {offset} starts no line"
    );
    let between = &gcode[markers[k].offset..offset];
    assert!(
        !between.lines().any(moves_head),
        "motion between the marker and the kept offset:\n{between}"
    );
    let trace = moves(&f.trace, 0);
    let step = |l: &str| -> Vec<i64> { l.split(' ').map(|v| v.parse().unwrap()).collect() };
    // Homing sets the logical origin: the first job move (`G1 Z5` after G28) starts there.
    let origin = step(&want[0]);
    let stop = step(&trace[before - 1]);
    let cfg = MachineConfig::ENDER3;
    for i in 0..3 {
        let spm = f64::from(cfg.axes[i].steps_per_mm);
        let at = origin[i] + (markers[k].pos_mm[i] * spm).round() as i64;
        assert!(
            (stop[4 + i] - at).abs() <= 1,
            "axis {i}: stopped at {stop:?}, the file's marker {k} is at {at} steps"
        );
    }

    eprintln!(
        "paused before layer {} of {} (marker {k}, {path} byte {offset}): {before} of {} moves before the cut",
        kept.layer,
        markers.len(),
        want.len()
    );

    // Power again: the same flash, machine and card; M1000 alone finishes the file.
    let mut b = Session::start(&f, Some(&card), "200");
    let note = b.until("the kept-job notification", |s| {
        s.starts_with("//action:notification Paused job kept")
    });
    assert!(
        note.contains(&format!("continue from SD file {path} byte {offset} ")),
        "{note}"
    );
    b.write("M1000");
    let reply = b.until("M1000's reply", |s| s.contains("power-cut resume: layer"));
    assert!(
        reply.ends_with(&format!("SD file {path} byte {offset} continues")),
        "{reply}"
    );
    b.until("ok for M1000", |s| s.starts_with("ok"));
    b.until("Done printing file", |l| l == "Done printing file");
    b.send("M400");
    assert_resumed_as_reference(b, &f, &want, before, &first_seen);
    r.remove();
    f.remove();
    let _ = std::fs::remove_dir_all(&card);
}
