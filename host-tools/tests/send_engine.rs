//! The sender engine against a scripted fake printer (in-memory Read/Write): numbering and
//! checksums, `ok` flow control, resends, errors, notifications, the firmware pause and the
//! host-side fallback.

mod common;

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::time::Duration;

use firmware::motion::LayerSource;
use host_tools::job::sender::protocol::checksum;
use host_tools::job::sender::{Event, Options, PauseMethod, Request, Session, State};
use host_tools::job::{Job, Layer};

/// A scripted printer: answers `ok` to every numbered line with a good checksum and the
/// expected number, `Resend:` otherwise; M115 with a configurable capability report; realtime
/// pause/resume requests with `//action:` notifications.
#[derive(Default)]
struct FakePrinter {
    inbuf: Vec<u8>,
    out: VecDeque<u8>,
    expected: u32,
    /// Numbered commands accepted, in order (body without N and checksum).
    executed: Vec<String>,
    /// Realtime lines received, with the count of executed lines at that moment.
    realtime: Vec<(String, usize)>,
    /// Line numbers whose first transmission is "corrupted" (answered with a checksum error).
    corrupt_once: Vec<u32>,
    layer_pause_cap: bool,
    /// Answer `ok` to M110 probes only after this many probes (a board that is booting).
    ignore_probes: usize,
    /// Extra line sent before every `ok` (e.g. `busy: processing`).
    chatter: Option<String>,
    /// Stop answering after this many executed lines.
    die_after: Option<usize>,
    /// Paused: held lines are not acknowledged.
    paused: bool,
    held: usize,
    /// A `;LAYER_CHANGE` came; the mark is placed before the next command (as the firmware's
    /// detector does).
    pending_mark: bool,
    /// The last command received was the one a mark was placed before.
    mark_just_delivered: bool,
    pause_at_next_mark: bool,
    /// After this many executed lines the printer's line counter goes back to 0 once (a reset
    /// that printed no `start`, or an `M110` from another host).
    counter_reset_after: Option<usize>,
    /// After this many executed lines the printer's line counter jumps ahead by 5 once.
    counter_jump_after: Option<usize>,
}

impl FakePrinter {
    fn say(&mut self, s: &str) {
        self.out.extend(s.as_bytes());
        self.out.push_back(b'\n');
    }

    fn on_line(&mut self, line: &str) {
        let line = line.trim();
        if line.is_empty() {
            return;
        }
        if !line.starts_with('N') {
            self.realtime.push((line.to_string(), self.executed.len()));
            match line {
                l if l.starts_with("M110") => panic!("unchecked {l}: send N<n> M110*<cs>"),
                "M25 S1" | "M601 S1" => {
                    self.say("ok");
                    self.paused = true;
                    self.say("//action:paused");
                }
                "M25" | "M601" => {
                    // Layer pause, as the firmware does it (with instant execution): stop at
                    // the mark just delivered, else at the next one.
                    self.say("ok");
                    if self.mark_just_delivered {
                        self.paused = true;
                        self.say("//action:paused");
                    } else {
                        self.pause_at_next_mark = true;
                    }
                }
                "M24" | "M602" => {
                    self.say("ok");
                    self.paused = false;
                    self.say("//action:resumed");
                    for _ in 0..self.held {
                        self.say("ok");
                    }
                    self.held = 0;
                }
                "M524" => {
                    self.say("ok");
                    self.say("//action:cancel");
                }
                "M112" => {}
                _ => self.say("ok"),
            }
            return;
        }
        let (body, cs) = line.rsplit_once('*').expect("checksum");
        let cs: u8 = cs.parse().expect("checksum number");
        assert_eq!(checksum(body), cs, "bad checksum on {line}");
        let (n, cmd) = body.split_once(' ').unwrap_or((body, ""));
        let n: u32 = n[1..].parse().expect("line number");
        if cmd == "M110" {
            // The connection probe (N0) and the resync (N<last acknowledged>), as Marlin.
            self.realtime
                .push((format!("M110 N{n}"), self.executed.len()));
            if n == 0 && self.ignore_probes > 0 {
                self.ignore_probes -= 1;
                return;
            }
            self.expected = n + 1;
            self.say("ok");
            return;
        }
        if self.die_after.is_some_and(|d| self.executed.len() >= d) {
            return;
        }
        if self.counter_reset_after == Some(self.executed.len()) {
            self.counter_reset_after = None;
            self.expected = 1;
        }
        if self.counter_jump_after == Some(self.executed.len()) {
            self.counter_jump_after = None;
            self.expected += 5;
        }
        if self.corrupt_once.contains(&n) {
            self.corrupt_once.retain(|&c| c != n);
            self.say(&format!("Error:checksum mismatch, Last Line: {}", n - 1));
            self.say(&format!("Resend: {n}"));
            self.say("ok");
            return;
        }
        if n != self.expected {
            self.say(&format!(
                "Error:Line Number is not Last Line Number+1, Last Line: {}",
                self.expected - 1
            ));
            self.say(&format!("Resend: {}", self.expected));
            self.say("ok");
            return;
        }
        self.expected += 1;
        self.executed.push(cmd.to_string());
        if cmd.starts_with(';') {
            self.pending_mark |= cmd == ";LAYER_CHANGE";
            self.say("ok");
            return;
        }
        self.mark_just_delivered = std::mem::take(&mut self.pending_mark);
        if self.mark_just_delivered && self.pause_at_next_mark {
            // Stop at the mark: this command is held until resume.
            self.pause_at_next_mark = false;
            self.paused = true;
            self.held += 1;
            self.say("//action:paused");
            return;
        }
        if cmd == "M115" {
            self.say("FIRMWARE_NAME:FakeFirmware 1.0");
            if self.layer_pause_cap {
                self.say("Cap:LAYER_PAUSE:1");
            }
            self.say("Cap:EMERGENCY_PARSER:1");
        }
        if cmd == "M105" {
            self.say("ok T:210.3 /215.0 B:60.1 /60.0 @:100 B@:0");
            return;
        }
        if let Some(c) = self.chatter.clone() {
            self.say(&c);
        }
        if self.paused {
            self.held += 1;
        } else {
            self.say("ok");
        }
    }
}

impl Write for FakePrinter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        for l in common::complete_lines(&mut self.inbuf, buf) {
            self.on_line(&l);
        }
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Read for FakePrinter {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        Ok(common::read_replies(&mut self.out, buf, usize::MAX))
    }
}

fn layer(i: u32, z: f64, lines: &[&str]) -> Layer {
    Layer {
        number: i,
        z_mm: Some(z),
        print_z_mm: Some(z),
        source: LayerSource::Comment,
        lines: lines.iter().map(|s| s.to_string()).collect(),
    }
}

/// Three layers of a 10 mm square, absolute E, laid out as the firmware's detector splits a
/// PrusaSlicer file: the `;LAYER_CHANGE` marker ends the previous section and the layer starts
/// at the first command after it (its Z move).
fn square_job() -> Job {
    let mut layers = Vec::new();
    let mut e = 0.0;
    for i in 0..3u32 {
        let z = 0.2 * (i + 1) as f64;
        let mut lines = vec![format!("G1 Z{z:.1} F600")];
        for (x, y) in [(10.0, 0.0), (10.0, 10.0), (0.0, 10.0), (0.0, 0.0)] {
            e += 0.4;
            lines.push(format!("G1 X{x} Y{y} E{e:.2} F1800 ; wall"));
        }
        if i < 2 {
            lines.push(";LAYER_CHANGE".to_string());
        }
        let refs: Vec<&str> = lines.iter().map(String::as_str).collect();
        layers.push(layer(i, z, &refs));
    }
    Job {
        start: vec![
            "G28".into(),
            "G90".into(),
            "M82".into(),
            "G92 E0".into(),
            ";LAYER_CHANGE".into(),
        ],
        layers,
        end: vec!["M104 S0".into(), "M84".into()],
        warnings: vec![],
    }
}

fn expected_stream(job: &Job, with_comments: bool) -> Vec<String> {
    job.lines()
        .filter_map(|(_, l)| {
            let code = l.split(';').next().unwrap_or("").trim();
            if code.is_empty() {
                (with_comments && l.trim().starts_with(';')).then(|| l.trim().to_string())
            } else {
                Some(code.to_string())
            }
        })
        .collect()
}

fn opts() -> Options {
    Options {
        temp_every: Duration::from_secs(3600),
        ..Options::default()
    }
}

/// Polls until the session ends or `max` steps of 1 ms pass; `hook` runs after every step.
fn run<F: FnMut(&mut Session<FakePrinter>, Duration, &[Event])>(
    s: &mut Session<FakePrinter>,
    max: u64,
    mut hook: F,
) -> Vec<Event> {
    let mut all = Vec::new();
    for i in 0..max {
        let now = Duration::from_millis(i);
        s.poll(now).expect("poll");
        let ev = s.drain_events();
        hook(s, now, &ev);
        all.extend(ev);
        if s.finished() {
            break;
        }
    }
    all
}

fn job_lines(p: &FakePrinter) -> Vec<String> {
    // Drop the handshake and the final sync.
    p.executed
        .iter()
        .filter(|l| *l != "M115" && *l != "M105")
        .cloned()
        .collect()
}

#[test]
fn streams_every_line_once_in_order() {
    let job = square_job();
    let printer = FakePrinter {
        layer_pause_cap: true,
        ..Default::default()
    };
    let mut s = Session::new(printer, job.clone(), opts());
    let ev = run(&mut s, 10_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done, "events: {ev:?}");
    assert!(ev.contains(&Event::Connected(PauseMethod::Firmware)));
    let mut expect = expected_stream(&job, true);
    expect.push("M400".into());
    assert_eq!(job_lines(s.port()), expect);
}

#[test]
fn resends_corrupted_lines_without_loss_or_duplication() {
    let job = square_job();
    let printer = FakePrinter {
        corrupt_once: vec![3, 7, 8, 15],
        chatter: Some("echo:busy: processing".into()),
        ..Default::default()
    };
    let mut s = Session::new(printer, job.clone(), opts());
    let ev = run(&mut s, 10_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done, "events: {ev:?}");
    assert_eq!(s.progress().resends, 4);
    let mut expect = expected_stream(&job, false);
    // Stock firmware: moves are split, so compare only the non-move lines and the final target.
    expect.push("M400".into());
    let got = job_lines(s.port());
    let non_moves = |v: &[String]| -> Vec<String> {
        v.iter().filter(|l| !l.starts_with("G1")).cloned().collect()
    };
    assert_eq!(non_moves(&got), non_moves(&expect));
}

#[test]
fn waits_for_a_booting_board() {
    let printer = FakePrinter {
        ignore_probes: 2,
        layer_pause_cap: true,
        ..Default::default()
    };
    let mut s = Session::new(printer, square_job(), opts());
    run(&mut s, 20_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done);
    let probes = s
        .port()
        .realtime
        .iter()
        .filter(|(l, _)| l == "M110 N0")
        .count();
    assert_eq!(probes, 3);
}

#[test]
fn fails_clearly_when_the_printer_goes_silent() {
    let printer = FakePrinter {
        die_after: Some(5),
        layer_pause_cap: true,
        ..Default::default()
    };
    let o = Options {
        silence_timeout: Duration::from_secs(2),
        ..opts()
    };
    let mut s = Session::new(printer, square_job(), o);
    run(&mut s, 10_000, |_, _, _| {});
    match s.state() {
        State::Failed(m) => assert!(m.contains("no reply"), "{m}"),
        other => panic!("expected a failure, got {other:?}"),
    }
}

#[test]
fn halts_on_a_fatal_printer_error() {
    let printer = FakePrinter {
        chatter: Some("Error:Printer halted. kill() called!".into()),
        ..Default::default()
    };
    let mut s = Session::new(printer, square_job(), opts());
    run(&mut s, 10_000, |_, _, _| {});
    assert!(matches!(s.state(), State::Failed(m) if m.contains("halted")));
}

#[test]
fn reads_temperatures() {
    let printer = FakePrinter::default();
    let o = Options {
        temp_every: Duration::from_millis(5),
        ..Options::default()
    };
    let mut s = Session::new(printer, square_job(), o);
    run(&mut s, 10_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done);
    assert_eq!(s.progress().temps.hotend_c, Some(210.3));
    assert_eq!(s.progress().temps.bed_target_c, Some(60.0));
}

#[test]
fn firmware_pause_at_layer_stops_sending_at_the_boundary_and_resumes() {
    let job = square_job();
    let printer = FakePrinter {
        layer_pause_cap: true,
        ..Default::default()
    };
    let mut s = Session::new(printer, job.clone(), opts());
    s.pause_before_layer(2);
    let mut paused_at = None;
    let ev = run(&mut s, 20_000, |s, now, ev| {
        if ev.iter().any(|e| matches!(e, Event::Paused(_))) {
            paused_at = Some(now);
        }
        if let Some(t) = paused_at {
            if now > t + Duration::from_millis(50) && matches!(s.state(), State::Paused { .. }) {
                s.request(Request::Resume, now).expect("resume");
            }
        }
    });
    assert_eq!(s.state(), &State::Done, "{ev:?}");
    assert!(ev.contains(&Event::Paused(Some(2))), "{ev:?}");
    let p = s.port();
    // The pause was scheduled in the firmware (M761, same layer numbering), cleared on resume...
    assert_eq!(p.executed[1], "M761 L2");
    assert!(p.executed.iter().any(|l| l == "M761 C"));
    // ... and the host sent every line of layers 0 and 1 (with the marker comment that the
    // firmware's detector reads), then only a harmless command to deliver the mark, then M25.
    let trigger = p
        .executed
        .iter()
        .position(|l| l == "M400")
        .expect("trigger command");
    let before: Vec<String> = p.executed[2..trigger].to_vec();
    let (_, m25_at) = p.realtime.iter().find(|(l, _)| l == "M25").expect("M25");
    assert_eq!(*m25_at, trigger + 1);
    let expect_before = expected_stream(
        &Job {
            start: job.start.clone(),
            layers: job.layers[..2].to_vec(),
            end: vec![],
            warnings: vec![],
        },
        true,
    );
    assert_eq!(before, expect_before);
    assert!(p.realtime.iter().any(|(l, _)| l == "M24"));
    // Nothing lost or duplicated over the whole job.
    let all: Vec<String> = job_lines(p)
        .into_iter()
        .filter(|l| l != "M400" && !l.starts_with("M761"))
        .collect();
    assert_eq!(all, expected_stream(&job, true));
}

#[test]
fn interactive_layer_pause_reacts_at_once_and_holds_the_next_layer() {
    let job = square_job();
    let printer = FakePrinter {
        layer_pause_cap: true,
        ..Default::default()
    };
    let mut s = Session::new(printer, job.clone(), opts());
    let mut asked = false;
    let ev = run(&mut s, 5_000, |s, now, _| {
        if !asked && s.progress().layer == Some(1) {
            asked = true;
            s.request(Request::PauseAtLayer, now).expect("pause");
        }
    });
    assert!(ev.contains(&Event::Paused(Some(2))), "{ev:?}");
    let p = s.port();
    // M25 went out at once, while layer 1 was being sent.
    let (_, at) = p.realtime.iter().find(|(l, _)| l == "M25").expect("M25");
    let layer1_start = p
        .executed
        .iter()
        .position(|l| l == "G1 Z0.4 F600")
        .expect("layer 1");
    assert!(*at <= layer1_start + 1, "M25 after {at} lines");
    // No line of layer 2 was sent.
    assert!(!p.executed.iter().any(|l| l == "G1 Z0.6 F600"));
}

#[test]
fn pause_now_is_sent_ahead_of_queued_lines() {
    let printer = FakePrinter {
        layer_pause_cap: true,
        ..Default::default()
    };
    let mut s = Session::new(printer, square_job(), opts());
    let mut asked = false;
    let ev = run(&mut s, 3_000, |s, now, _| {
        if !asked && s.progress().lines_sent >= 8 {
            asked = true;
            s.request(Request::PauseNow, now).expect("pause");
        }
    });
    assert!(matches!(s.state(), State::Paused { .. }), "{ev:?}");
    let p = s.port();
    let (_, at) = p
        .realtime
        .iter()
        .find(|(l, _)| l == "M25 S1")
        .expect("M25 S1 sent");
    // No job line was sent after the request.
    assert_eq!(*at, p.executed.len());
}

#[test]
fn host_side_pause_splits_moves_and_parks_after_the_layer() {
    let job = square_job();
    let printer = FakePrinter::default(); // stock firmware: no LAYER_PAUSE capability
    let mut s = Session::new(printer, job.clone(), opts());
    s.pause_before_layer(1);
    let mut resumed = false;
    let ev = run(&mut s, 50_000, |s, now, _| {
        if !resumed && matches!(s.state(), State::Paused { .. }) {
            resumed = true;
            s.request(Request::Resume, now).expect("resume");
        }
    });
    assert_eq!(s.state(), &State::Done, "{ev:?}");
    assert!(ev.contains(&Event::Connected(PauseMethod::HostSide)));
    assert!(ev.contains(&Event::Paused(Some(1))));
    let got = job_lines(s.port());
    // The pause sequence follows the last piece of layer 0's last move (to X0 Y0).
    let park = got
        .iter()
        .position(|l| l.starts_with("G0 X235 Y235"))
        .expect("park move");
    assert_eq!(
        &got[park - 5..park - 1],
        ["M83", "G1 E-2 F1500", "M82", "G90"]
    );
    assert!(
        got[park - 6].starts_with("G1 X0 Y0 E1.6"),
        "{}",
        got[park - 6]
    );
    // Every printing move of the layers is at most 0.2 mm long (10 mm sides: 50 pieces).
    let pieces = got
        .iter()
        .filter(|l| l.starts_with("G1 X") && l.contains('E'))
        .count();
    assert_eq!(pieces, 3 * 4 * 50);
    // A pause scheduled ahead of time keeps the job's speeds (the speed-up answers a request).
    assert!(!got.iter().any(|l| l.contains("F5400")));
    // Resume: back to X0 Y0, Z, un-retract, E mode and position restored.
    let back = got
        .iter()
        .position(|l| l == "G0 X0 Y0 F3600")
        .expect("return move");
    assert_eq!(got[back + 1], "G0 Z0.2 F600");
    assert_eq!(got[back + 2], "M83");
    assert_eq!(got[back + 3], "G1 E2 F1500");
    assert!(got[back + 4..back + 8].contains(&"M82".to_string()));
    assert!(got[back + 4..back + 8].contains(&"G92 E1.6".to_string()));
}

#[test]
fn printer_cancel_notification_ends_the_session() {
    let printer = FakePrinter {
        chatter: Some("//action:cancel".into()),
        layer_pause_cap: true,
        ..Default::default()
    };
    let mut s = Session::new(printer, square_job(), opts());
    run(&mut s, 10_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Cancelled);
}

/// The proptest seed `cc 4004088a…` (send_garbage.proptest-regressions): before the sender has
/// written anything the printer says `Resend: 0` and `ok` (left over from an earlier host, or
/// noise after a reset). The sender must not give up or stall: it ignores both, connects and
/// streams the whole job.
#[test]
fn resend_zero_before_connecting_is_ignored() {
    let mut printer = FakePrinter {
        layer_pause_cap: true,
        ..Default::default()
    };
    printer.say("Resend: 0");
    printer.say("ok");
    let job = square_job();
    let mut s = Session::new(printer, job.clone(), opts());
    let ev = run(&mut s, 10_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done, "{ev:?}");
    assert!(
        ev.iter()
            .any(|e| matches!(e, Event::Note(m) if m.contains("Resend: 0 before the connection"))),
        "{ev:?}"
    );
    // The leftover `ok` was not taken for the probe's: M115 was answered and the layer pause
    // detected.
    assert!(ev.contains(&Event::Connected(PauseMethod::Firmware)));
    let mut expect = expected_stream(&job, true);
    expect.push("M400".into());
    assert_eq!(job_lines(s.port()), expect);
}

/// The printer's line counter goes back to 0 in the middle of the job and it asks for line 1,
/// which it acknowledged long ago. Resending from line 1 would run the job's first lines twice;
/// sending on would be rejected line after line. The sender sets the counter back (`M110 N<last
/// acknowledged>`), resends the rejected line, and says so; every job line runs exactly once.
#[test]
fn resend_of_an_acknowledged_line_resyncs_without_duplicates() {
    let job = square_job();
    let printer = FakePrinter {
        layer_pause_cap: true,
        counter_reset_after: Some(9),
        ..Default::default()
    };
    let mut s = Session::new(printer, job.clone(), opts());
    let ev = run(&mut s, 10_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done, "{ev:?}");
    assert!(ev.contains(&Event::Resend(1)), "{ev:?}");
    assert!(
        ev.iter()
            .any(|e| matches!(e, Event::Note(m) if m.contains("N9 M110"))),
        "{ev:?}"
    );
    let p = s.port();
    assert!(p.realtime.iter().any(|(l, at)| l == "M110 N9" && *at == 9));
    let mut expect = expected_stream(&job, true);
    expect.push("M400".into());
    assert_eq!(job_lines(p), expect);
}

/// The printer's counter jumps ahead (it asks for a line never sent): same recovery, nothing
/// skipped.
#[test]
fn resend_of_a_line_never_sent_resyncs_without_loss() {
    let job = square_job();
    let printer = FakePrinter {
        layer_pause_cap: true,
        counter_jump_after: Some(6),
        ..Default::default()
    };
    let mut s = Session::new(printer, job.clone(), opts());
    let ev = run(&mut s, 10_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done, "{ev:?}");
    assert!(ev.contains(&Event::Resend(12)), "{ev:?}");
    let mut expect = expected_stream(&job, true);
    expect.push("M400".into());
    assert_eq!(job_lines(s.port()), expect);
}

/// A printer that keeps asking for a line it acknowledged (it ignores M110) ends the session
/// with a message after [`host_tools::job::sender::MAX_RESENDS`] requests instead of looping.
#[test]
fn endless_resync_gives_up_with_a_message() {
    struct Stubborn(FakePrinter);
    impl Read for Stubborn {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            self.0.read(buf)
        }
    }
    impl Write for Stubborn {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            let text = String::from_utf8_lossy(buf).into_owned();
            if text.contains(" M110*") && !text.starts_with("N0 ") {
                self.0.say("ok"); // acknowledged, but the counter stays where it is
                return Ok(buf.len());
            }
            self.0.write(buf)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let printer = Stubborn(FakePrinter {
        layer_pause_cap: true,
        counter_reset_after: Some(9),
        ..Default::default()
    });
    let mut s = Session::new(printer, square_job(), opts());
    for i in 0..10_000 {
        s.poll(Duration::from_millis(i)).expect("poll");
        if s.finished() {
            break;
        }
    }
    match s.state() {
        State::Failed(m) => assert!(m.contains("rejected line 1"), "{m}"),
        other => panic!("expected a failure, got {other:?}"),
    }
    assert!(s.port().0.executed.len() <= 10);
}

/// Host-side method, pause requested in the middle of layer 1: from the next move on, every move
/// of the rest of the layer carries the sped-up feed (×3: F1800 -> F5400; 0.04 mm of filament
/// per mm at 90 mm/s is 8.7 mm³/s, under the 12 mm³/s bound); the pause sequence follows the
/// layer's last move; the resume restores the job's F1800, and layer 2 runs at the job's speed.
#[test]
fn host_side_layer_pause_speeds_up_the_rest_of_the_layer() {
    let job = square_job();
    let mut s = Session::new(FakePrinter::default(), job.clone(), opts());
    let mut asked_at = None;
    let mut resumed = false;
    let ev = run(&mut s, 50_000, |s, now, _| {
        // A quarter into layer 1's second side.
        if asked_at.is_none() && s.progress().layer == Some(1) && s.port().executed.len() > 290 {
            asked_at = Some(s.port().executed.len());
            s.request(Request::PauseAtLayer, now).expect("pause");
        }
        if !resumed && matches!(s.state(), State::Paused { .. }) {
            resumed = true;
            s.request(Request::Resume, now).expect("resume");
        }
    });
    assert_eq!(s.state(), &State::Done, "{ev:?}");
    assert!(ev.contains(&Event::Paused(Some(2))), "{ev:?}");
    let got = job_lines(s.port());
    let asked = asked_at.expect("requested") - 1; // job_lines drops M115
    let park = got
        .iter()
        .position(|l| l.starts_with("G0 X235 Y235"))
        .expect("park");
    let before: Vec<&String> = got[..asked].iter().filter(|l| l.contains(" F")).collect();
    assert!(
        before
            .iter()
            .all(|l| l.ends_with("F1800") || l.ends_with("F600")),
        "{before:?}"
    );
    // From the request to the pause sequence: every F written is the sped-up one, and there is
    // one per move still to come (the request fell in side 2: sides 3 and 4 follow).
    let rest: Vec<&String> = got[asked..park - 5]
        .iter()
        .filter(|l| l.contains(" F"))
        .collect();
    assert!(rest.len() >= 2, "{rest:?}");
    assert!(rest.iter().all(|l| l.ends_with("F5400")), "{rest:?}");
    // Every piece still ends where the job said: the layer's last move lands on X0 Y0.
    assert!(
        got[park - 6].starts_with("G1 X0 Y0 E3.2"),
        "{}",
        got[park - 6]
    );
    // The resume restores the job's feed; layer 2 has no sped-up move.
    let back = got[park..]
        .iter()
        .position(|l| l == "G1 F1800")
        .expect("feed restored")
        + park;
    assert!(!got[back..].iter().any(|l| l.contains("F5400")));
}

/// Host-side method: arcs of a layer are cut into chords of at most 0.2 mm before sending.
#[test]
fn host_side_cuts_arcs_into_short_chords() {
    let job = Job::from_gcode(
        "G28\nG90\nM82\nG92 E0\n;LAYER_CHANGE\n;Z:0.2\nG1 Z0.2 F600\nG1 X100 Y110 F3000\n\
         G2 X110 Y100 I0 J-10 E1 F1200\nG3 X100 Y110 R10 E2\nM84\n",
    )
    .expect("job");
    let mut s = Session::new(FakePrinter::default(), job, opts());
    let ev = run(&mut s, 50_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done, "{ev:?}");
    let got = job_lines(s.port());
    assert!(!got
        .iter()
        .any(|l| l.starts_with("G2 ") || l.starts_with("G3 ")));
    let mut m = host_tools::job::modal::Modal::default();
    let mut longest: f64 = 0.0;
    let mut chords = 0;
    for l in &got {
        if let Ok(Some(c)) = host_tools::job::gcode::parse(l) {
            if let Some(mv) = m.apply(&c) {
                if mv.e_mm() > 0.0 {
                    longest = longest.max(mv.xyz_len_mm());
                    chords += 1;
                }
            }
        }
    }
    // Two quarter circles of radius 10: 31.4 mm in pieces of at most 0.2 mm.
    assert!(longest <= 0.2 + 1e-4, "{longest}");
    assert!(chords >= 158, "{chords}");
    for (got, want) in m.pos_mm.iter().zip([100.0, 110.0, 0.2, 2.0]) {
        assert!((got - want).abs() < 1e-6, "{:?}", m.pos_mm);
    }
}

/// `--speedup`/`--max-flow` reach our firmware as `M760 S<f> V<v>` right after M115 (its own
/// speed-up then uses them); a stock printer never gets M760 (the sender applies them itself).
#[test]
fn firmware_setup_lines_go_to_our_firmware_only() {
    let o = Options {
        firmware_setup: vec!["M760 S2 V10".into()],
        ..opts()
    };
    let printer = FakePrinter {
        layer_pause_cap: true,
        ..Default::default()
    };
    let mut s = Session::new(printer, square_job(), o.clone());
    run(&mut s, 10_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done);
    assert_eq!(s.port().executed[..2], ["M115", "M760 S2 V10"]);
    let mut s = Session::new(FakePrinter::default(), square_job(), o);
    run(&mut s, 50_000, |_, _, _| {});
    assert_eq!(s.state(), &State::Done);
    assert!(!s.port().executed.iter().any(|l| l.starts_with("M760")));
}
