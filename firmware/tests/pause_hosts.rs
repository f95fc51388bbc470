//! The host rules (docs/frontend.md, "host rules"): models of the two hosts' send paths, driven
//! through the byte link on virtual time, must never deadlock around a firmware pause.
//!
//! - printcore (Printrun): job lines numbered and checksummed, one per `ok`; `send_now()` lines
//!   go to a priority queue that is sent, unnumbered, before the next job line after an `ok`.
//!   It ignores `//action:` and keeps streaming while the printer is paused.
//! - OctoPrint: one line per `ok`; on `//action:paused` it stops streaming, waits for the `ok`
//!   of its in-flight line, then sends terminal lines (unnumbered while paused) and resumes
//!   streaming on `//action:resumed`.
mod support;

use firmware::config::MachineConfig;
use firmware::link::checksum;
use firmware::planner::BlockKind;
use firmware::printer::{Printer, Record, State};
use std::collections::VecDeque;

/// A comment-free layered job (what printcore and OctoPrint send): `layers` layers of a
/// zigzag of `moves` extruding lines each, layer changes by a Z rise.
fn job(layers: u32, moves: u32) -> Vec<String> {
    let mut v = vec!["G90".to_string(), "M83".into(), "G92 E0".into()];
    for l in 0..layers {
        let z = 0.2 * (l + 1) as f32;
        v.push(format!("G1 Z{z:.2} F600"));
        v.push("G1 X10 Y10 F6000".into());
        for i in 0..moves {
            let x = if i % 2 == 0 { 40 } else { 10 };
            v.push(format!("G1 X{x} Y{} E0.8 F2400", 10 + i));
        }
    }
    v
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Kind {
    Printcore,
    OctoPrint,
}

/// A host on the byte link: see the module documentation.
struct Host {
    kind: Kind,
    job: Vec<String>,
    next: usize,
    lineno: u32,
    in_flight: bool,
    /// printcore's priority queue / OctoPrint's terminal lines.
    pri: VecDeque<String>,
    /// OctoPrint: streaming stopped by `//action:paused` until `//action:resumed`.
    held: bool,
    out: String,
    paused_at_us: Option<u64>,
    /// When the first `ok` after `//action:paused` arrived.
    ok_after_paused_us: Option<u64>,
    /// Wait this long after an `ok` before the next job line (a slow host).
    gap_us: u64,
    last_ok_us: u64,
    /// Raw bytes to write at once, outside the line protocol (control bytes).
    raw: Vec<u8>,
    cancelled_at_us: Option<u64>,
    /// When the first job block ran.
    printing_since_us: Option<u64>,
}

impl Host {
    fn new(kind: Kind, job: Vec<String>) -> Self {
        Host {
            kind,
            job,
            next: 0,
            lineno: 1,
            in_flight: false,
            pri: VecDeque::new(),
            held: false,
            out: String::new(),
            paused_at_us: None,
            ok_after_paused_us: None,
            gap_us: 0,
            last_ok_us: 0,
            raw: Vec::new(),
            cancelled_at_us: None,
            printing_since_us: None,
        }
    }

    /// Start a new job the way the host does: printcore sends `N-1 M110` and numbers from 0,
    /// OctoPrint sends `M110 N0` and numbers from 1.
    fn start_job(&mut self, job: Vec<String>) {
        let (reset, first) = match self.kind {
            Kind::Printcore => {
                let pre = "N-1 M110";
                (format!("{pre}*{}", checksum(pre.as_bytes())), 0)
            }
            Kind::OctoPrint => ("M110 N0".to_string(), 1),
        };
        self.pri.push_back(reset);
        self.job = job;
        self.next = 0;
        self.lineno = first;
        self.held = false;
    }

    fn done(&self) -> bool {
        self.next >= self.job.len() && !self.in_flight && self.pri.is_empty()
    }

    /// Read the printer's output; returns the lines.
    fn read(&mut self, p: &mut Printer, now: u64) -> Vec<String> {
        let mut s = String::new();
        p.write_output(&mut s).unwrap();
        self.out.push_str(&s);
        let lines: Vec<String> = s.lines().map(str::to_string).collect();
        for l in &lines {
            if l.starts_with("ok") {
                self.in_flight = false;
                self.last_ok_us = now;
                if self.paused_at_us.is_some() && self.ok_after_paused_us.is_none() {
                    self.ok_after_paused_us = Some(now);
                }
            } else if l == "//action:paused" {
                self.paused_at_us = Some(now);
                if self.kind == Kind::OctoPrint {
                    self.held = true;
                }
            } else if l == "//action:resumed" {
                self.held = false;
            } else if l == "//action:cancel" {
                self.cancelled_at_us = Some(now);
                if self.kind == Kind::OctoPrint {
                    // OctoPrint cancels its job: no more job lines.
                    self.next = self.job.len();
                }
            }
            assert!(!l.starts_with("Resend") && !l.starts_with("Error"), "{l}");
        }
        lines
    }

    /// Send the next line if none is in flight.
    fn send(&mut self, p: &mut Printer, now: u64) {
        if !self.raw.is_empty() {
            let raw = std::mem::take(&mut self.raw);
            assert_eq!(p.receive(&raw, now), raw.len());
        }
        if self.in_flight {
            return;
        }
        let line = if let Some(l) = self.pri.pop_front() {
            format!("{l}\n")
        } else if !self.held && self.next < self.job.len() && now >= self.last_ok_us + self.gap_us {
            let pre = format!("N{} {}", self.lineno, self.job[self.next]);
            self.next += 1;
            self.lineno += 1;
            format!("{pre}*{}\n", checksum(pre.as_bytes()))
        } else {
            return;
        };
        self.in_flight = true;
        let taken = p.receive(line.as_bytes(), now);
        assert_eq!(
            taken,
            line.len(),
            "a one-line-per-ok host's line is always taken"
        );
    }
}

struct Outcome {
    host: Host,
    executed: Vec<(u32, u32)>,
    /// Job blocks executed after `//action:cancel`: (seq, seg, position after).
    after_cancel: Vec<(u32, u32, [i32; 4])>,
    stops: usize,
    end_state: State,
    /// Highest Z the head reached, steps.
    max_z: i32,
    /// Z where the head stopped for the (last) pause, steps.
    stop_z: i32,
    /// The nozzle's temperature at each extruding job block after the resume, °C (heated
    /// runs).
    extruding_c_after_resume: Vec<f32>,
    /// When the last job block ended, µs.
    last_job_block_us: u64,
}

/// Run `host` against a printer: `on_tick(host, now, output lines)` queues terminal lines.
fn drive(host: Host, limit_us: u64, on_tick: impl FnMut(&mut Host, u64, &[String])) -> Outcome {
    drive_with(host, limit_us, false, on_tick)
}

/// A heater's first-order plant, sampled every 100 ms: `gain_c_s` °C/s at full duty, losing
/// `loss_per_s` of its rise above 25 °C per second (an Ender-3's hotend heats at about
/// 2.5 °C/s near 200 °C and, off, falls below 170 °C within half a minute).
struct Plant {
    c: f32,
    duty: f32,
    gain_c_s: f32,
    loss_per_s: f32,
}

impl Plant {
    fn step(&mut self, p: &mut Printer, id: firmware::thermal::HeaterId, now: u64) {
        self.c += (self.duty * self.gain_c_s - (self.c - 25.0) * self.loss_per_s) * 0.1;
        self.duty = p.thermal_sample(id, self.c, now);
    }
}

/// [`drive`]; `heated`: the heaters are modelled ([`Plant`]) and the cold-extrusion guard is
/// on, and the outcome notes the nozzle's temperature at each extruding job block after the
/// first `//action:resumed`.
fn drive_with(
    mut host: Host,
    limit_us: u64,
    heated: bool,
    mut on_tick: impl FnMut(&mut Host, u64, &[String]),
) -> Outcome {
    use firmware::thermal::HeaterId;
    let mut p = Printer::new(MachineConfig::ENDER3);
    // No heater model: the jobs extrude cold (as M302 P1).
    p.extrusion_guard_mut().allow_cold = !heated;
    let mut hotend = Plant {
        c: 25.0,
        duty: 0.0,
        gain_c_s: 4.0,
        loss_per_s: 0.01,
    };
    let mut bed = Plant {
        c: 25.0,
        duty: 0.0,
        gain_c_s: 1.0,
        loss_per_s: 0.01,
    };
    let mut resumed = false;
    let mut last_e = 0i32;
    let mut extruding_c_after_resume = Vec::new();
    let mut executed = Vec::new();
    let mut last_job_block_us = 0;
    let mut after_cancel = Vec::new();
    let mut stops = 0;
    let mut max_z = i32::MIN;
    let mut stop_z = 0;
    let mut now = 0u64;
    while now < limit_us {
        if heated && now.is_multiple_of(100_000) {
            hotend.step(&mut p, HeaterId::Hotend, now);
            bed.step(&mut p, HeaterId::Bed, now);
        }
        host.send(&mut p, now);
        p.poll(now);
        let until_ns = (now + 1000) * 1000;
        while let Some(t) = p.next_step_ns() {
            if t > until_ns || p.next_step().is_none() {
                break;
            }
            max_z = max_z.max(p.status().position[2]);
        }
        p.poll(now + 1000);
        while let Some(r) = p.pop_record() {
            match r {
                Record::Executed {
                    seq,
                    seg,
                    kind: BlockKind::Job,
                    pos,
                    ..
                } => {
                    executed.push((seq, seg));
                    last_job_block_us = now;
                    if host.printing_since_us.is_none() {
                        host.printing_since_us = Some(now);
                    }
                    if resumed && pos[3] > last_e {
                        extruding_c_after_resume.push(hotend.c);
                    }
                    last_e = pos[3];
                    if host.cancelled_at_us.is_some() {
                        after_cancel.push((seq, seg, pos));
                    }
                }
                Record::Stopped { pos, .. } => {
                    stops += 1;
                    stop_z = pos[2];
                }
                _ => {}
            }
        }
        let lines = host.read(&mut p, now);
        resumed |= lines.iter().any(|l| l == "//action:resumed");
        on_tick(&mut host, now, &lines);
        now += 1000;
        if host.done() && p.status().state == State::Idle && p.next_step_ns().is_none() {
            break;
        }
    }
    Outcome {
        host,
        executed,
        after_cancel,
        stops,
        end_state: p.status().state,
        max_z,
        stop_z,
        extruding_c_after_resume,
        last_job_block_us,
    }
}

fn baseline(job: &[String]) -> Vec<(u32, u32)> {
    drive(
        Host::new(Kind::Printcore, job.to_vec()),
        600_000_000,
        |_, _, _| {},
    )
    .executed
}

/// printcore keeps streaming job lines through the pause; `send_now("M602")` after the
/// printer announced `//action:paused` goes out with the next `ok` and resumes the job.
/// The host sent the whole job, the printer stopped once and ends idle, and every job segment
/// ran once, in order, as in the unpaused `base`.
fn assert_one_stop_and_the_whole_job(o: &Outcome, base: &[(u32, u32)], tail: &str) {
    assert!(o.host.done(), "job not sent to the end:\n{tail}");
    assert_eq!(o.end_state, State::Idle);
    assert_eq!(o.stops, 1);
    assert_eq!(o.executed, base, "every segment once, in order");
}

/// The host's jog (`G91`, `G1 Z5`) ran from the parked position: the highest Z is 5 mm above
/// the park height (stop Z + the pause's lift).
fn assert_jogged_5mm_above_park(o: &Outcome) {
    let cfg = MachineConfig::ENDER3;
    let spm = cfg.axes[2].steps_per_mm;
    let top_mm = o.stop_z as f32 / spm + cfg.pause.lift_z_mm + 5.0;
    assert!(
        (o.max_z as f32 / spm - top_mm).abs() < 0.3,
        "max Z {} mm, expected about {top_mm} mm (the jog)",
        o.max_z as f32 / spm
    );
}

#[test]
fn printcore_streaming_through_a_pause_can_send_its_resume() {
    let job = job(6, 30);
    let base = baseline(&job);
    let mut asked = false;
    let mut resumed_asked = false;
    let o = drive(
        Host::new(Kind::Printcore, job.clone()),
        600_000_000,
        |h, now, lines| {
            if !asked && now >= 3_000_000 {
                h.pri.push_back("M601".into());
                asked = true;
            }
            if !resumed_asked && lines.iter().any(|l| l == "//action:paused") {
                h.pri.push_back("M602".into());
                resumed_asked = true;
            }
        },
    );
    let out = &o.host.out;
    let tail: String = out.lines().rev().take(12).collect::<Vec<_>>().join("\n");
    assert!(resumed_asked, "never paused:\n{tail}");
    assert!(
        out.contains("//action:resumed"),
        "M602 never got through:\n{tail}"
    );
    assert_one_stop_and_the_whole_job(&o, &base, &tail);
}

/// OctoPrint stops streaming at `//action:paused` and stays "Pausing" until its in-flight line
/// is acknowledged: that `ok` must come. Then its terminal works while paused: a status line
/// is answered, a jog (unnumbered while paused) moves the parked head and changes nothing of
/// the job, and M602 resumes.
#[test]
fn octoprint_gets_its_in_flight_ok_and_its_terminal_works_while_paused() {
    let job = job(6, 30);
    let base = baseline(&job);
    let mut asked = false;
    let mut terminal = false;
    let o = drive(
        Host::new(Kind::OctoPrint, job.clone()),
        600_000_000,
        |h, now, _| {
            if !asked && now >= 3_000_000 {
                h.pri.push_back("M601".into());
                asked = true;
            }
            if let Some(ok_us) = h.ok_after_paused_us {
                if !terminal && now >= ok_us + 2_000_000 {
                    for l in [
                        "M105",
                        "M114",
                        "G91",
                        "G1 Z5 F600",
                        "G1 X10 F3000",
                        "G90",
                        "M602",
                    ] {
                        h.pri.push_back(l.into());
                    }
                    terminal = true;
                }
            }
        },
    );
    let out = &o.host.out;
    let tail: String = out.lines().rev().take(16).collect::<Vec<_>>().join("\n");
    let paused = o.host.paused_at_us.expect("never paused");
    let ok = o
        .host
        .ok_after_paused_us
        .expect("in-flight line never acknowledged");
    // The in-flight line is answered at once (same tick or the next).
    assert!(ok <= paused + 1_000, "ok {ok} µs after paused {paused} µs");
    assert!(
        out.contains("ok T:"),
        "M105 not answered while paused:\n{tail}"
    );
    // The jog ran at once from the parked position.
    assert_jogged_5mm_above_park(&o);
    assert!(out.contains("//action:resumed"), "{tail}");
    // The jog is not a job move.
    assert_one_stop_and_the_whole_job(&o, &base, &tail);
}

/// `Error:` only for what hosts treat as a resend or a real fault: a move outside the volume,
/// a line that does not parse, an unknown word, an over-limit temperature are `echo:`
/// warnings, and the machine's state is as before them (refused, not clamped).
#[test]
fn refusals_are_echo_warnings_and_change_nothing() {
    let mut p = Printer::new(MachineConfig::ENDER3);
    // No heater model: the jobs extrude cold (as M302 P1).
    p.extrusion_guard_mut().allow_cold = true;
    let mut out = String::new();
    let mut t = 0;
    for l in [
        "G1 X20 Y20 F3000",
        "M104 S200",
        "M400",
        "M114",
        "M105",
        "G1 X400",
        "G1 X10 Y",
        "G1 X10 Q5",
        "G1 X30 F-5",
        "M104 S999",
        "G1 X-50",
        "T3",
        "M84 S-1",
        "FOO",
        "M400",
        "M114",
        "M105",
    ] {
        let line = format!("{l}\n");
        assert_eq!(p.receive(line.as_bytes(), t), line.len());
        for _ in 0..2000 {
            t += 1000;
            p.poll(t);
            while p.next_step_ns().is_some_and(|s| s <= t * 1000) {
                p.next_step();
            }
        }
        p.write_output(&mut out).unwrap();
    }
    assert!(!out.contains("Error"), "{out}");
    let refused = out
        .lines()
        .filter(|l| l.starts_with("echo:refused:"))
        .count();
    let unknown = out
        .lines()
        .filter(|l| l.starts_with("echo:Unknown command"))
        .count();
    assert!(refused + unknown >= 9, "{out}");
    let oks = out.lines().filter(|l| l.starts_with("ok")).count();
    assert_eq!(oks, 17, "every line answered: {out}");
    let pos: Vec<&str> = out.lines().filter(|l| l.starts_with("X:")).collect();
    assert_eq!(pos.len(), 2, "{out}");
    assert_eq!(pos[0], pos[1], "position unchanged by the refused lines");
    assert_eq!(
        p.thermal().target_c(firmware::thermal::HeaterId::Hotend),
        200.0
    );
}

fn xy_steps(x: f32, y: f32) -> (i32, i32) {
    let cfg = MachineConfig::ENDER3;
    (
        (x * cfg.axes[0].steps_per_mm).round() as i32,
        (y * cfg.axes[1].steps_per_mm).round() as i32,
    )
}

/// printcore ignores `//action:cancel` and streams the rest of the job: none of it prints
/// (discarded, each answered `ok`); its next job, after its `N-1 M110`, prints.
#[test]
fn printcore_streaming_after_a_cancel_does_not_print_the_rest_of_the_job() {
    let mut asked = false;
    let mut restarted = false;
    let o = drive(
        Host::new(Kind::Printcore, job(6, 30)),
        600_000_000,
        |h, now, _| {
            if !asked && now >= 3_000_000 {
                h.pri.push_back("M524".into());
                asked = true;
            }
            if !restarted && h.cancelled_at_us.is_some() && h.next >= h.job.len() && !h.in_flight {
                h.start_job(vec!["G90".into(), "G1 X5 Y5 F3000".into()]);
                restarted = true;
            }
        },
    );
    let out = &o.host.out;
    assert!(o.host.cancelled_at_us.is_some(), "{out}");
    assert!(restarted && o.host.done());
    assert!(
        out.contains("lines of the cancelled job discarded"),
        "{out}"
    );
    // After the cancel only the new job's move ran.
    let (x, y) = xy_steps(5.0, 5.0);
    let last = o.after_cancel.last().expect("the new job ran");
    assert_eq!((last.2[0], last.2[1]), (x, y));
    let seqs: std::collections::BTreeSet<u32> = o.after_cancel.iter().map(|e| e.0).collect();
    assert_eq!(
        seqs.len(),
        1,
        "only the new job's move after the cancel: {seqs:?}"
    );
    assert_eq!(o.end_state, State::Idle);
}

/// OctoPrint stops at `//action:cancel`, sends its cancel script unnumbered (taken and run),
/// then starts a new job with `M110 N0` (printed).
#[test]
fn octoprint_cancel_script_and_next_job_run_after_a_cancel() {
    let mut asked = false;
    let mut script = false;
    let mut restarted = false;
    let o = drive(
        Host::new(Kind::OctoPrint, job(6, 30)),
        600_000_000,
        |h, now, _| {
            if !asked && now >= 3_000_000 {
                h.pri.push_back("M524".into());
                asked = true;
            }
            if let Some(t) = h.cancelled_at_us {
                if !script {
                    for l in ["M104 S0", "G91", "G1 Z2 F600", "G90"] {
                        h.pri.push_back(l.into());
                    }
                    script = true;
                }
                if !restarted && now > t + 500_000 && h.pri.is_empty() && !h.in_flight {
                    h.start_job(vec!["G1 X5 Y5 F3000".into()]);
                    restarted = true;
                }
            }
        },
    );
    let out = &o.host.out;
    assert!(restarted && o.host.done(), "{out}");
    let (x, y) = xy_steps(5.0, 5.0);
    let last = o.after_cancel.last().expect("moves after the cancel");
    assert_eq!((last.2[0], last.2[1]), (x, y), "{out}");
    // The script's Z lift ran: 2 mm above where the cancel parked.
    let cfg = MachineConfig::ENDER3;
    let spm = cfg.axes[2].steps_per_mm;
    let lifted = o.stop_z as f32 / spm + cfg.pause.lift_z_mm + 2.0;
    assert!(
        (o.max_z as f32 / spm - lifted).abs() < 0.05,
        "max Z {}",
        o.max_z as f32 / spm
    );
    assert_eq!(o.end_state, State::Idle);
}

/// A slow host (the queue runs empty between its lines): M524 is still "in a job", as the
/// pause is, and the lines that follow are not printed.
#[test]
fn cancel_between_the_lines_of_a_slow_host_cancels() {
    let mut h = Host::new(Kind::Printcore, job(2, 10));
    h.gap_us = 1_200_000;
    let mut asked = false;
    let o = drive(h, 600_000_000, |h, now, _| {
        // Right after a short move has ended, before the next line.
        if !asked && h.next > 8 && now >= h.last_ok_us + 900_000 {
            h.pri.push_back("M524".into());
            asked = true;
        }
    });
    let out = &o.host.out;
    assert!(!out.contains("nothing to cancel"), "{out}");
    assert!(o.host.cancelled_at_us.is_some(), "{out}");
    assert!(
        o.after_cancel.is_empty(),
        "job moves after the cancel: {:?}",
        o.after_cancel
    );
    assert!(
        out.contains("lines of the cancelled job discarded") || out.contains("discarding"),
        "{out}"
    );
}

/// printcore streams on into a parked printer (it ignores `//action:paused`) and the user
/// asks for things *late*, through `send_now`: a status line, a jog, then the resume, a
/// minute after the pause. The parked intake takes one job line per pace period and answers
/// its `ok`, so each priority line gets out within the pace; the jog moves the parked head,
/// not the job; every segment runs once, in order.
#[test]
fn printcore_streaming_into_a_parked_printer_sends_late_priority_lines() {
    let job = job(12, 30);
    let base = baseline(&job);
    let mut asked = false;
    let mut status_at = None;
    let mut resume_at = None;
    let o = drive(
        Host::new(Kind::Printcore, job.clone()),
        900_000_000,
        |h, now, lines| {
            if !asked && now >= 3_000_000 {
                h.pri.push_back("M601".into());
                asked = true;
            }
            let Some(t) = h.paused_at_us else { return };
            if status_at.is_none() && now >= t + 30_000_000 {
                for l in ["M105", "G91", "G1 Z5 F600", "G90"] {
                    h.pri.push_back(l.into());
                }
                status_at = Some(now);
            }
            if resume_at.is_none() && now >= t + 60_000_000 {
                h.pri.push_back("M602".into());
                resume_at = Some(now);
            }
            if let Some(r) = resume_at {
                if lines.iter().any(|l| l == "//action:resume") {
                    // From the request to the firmware: within the pace (≤ 3 s) plus a tick.
                    assert!(now - r <= 3_001_000, "resume took {} µs", now - r);
                }
            }
        },
    );
    let out = &o.host.out;
    let tail: String = out.lines().rev().take(16).collect::<Vec<_>>().join("\n");
    assert!(resume_at.is_some(), "never paused:\n{tail}");
    assert!(
        out.contains("ok T:"),
        "M105 not answered while paused:\n{tail}"
    );
    assert_jogged_5mm_above_park(&o);
    assert!(out.contains("//action:resumed"), "{tail}");
    assert_one_stop_and_the_whole_job(&o, &base, &tail);
}

/// printcore streams on into a parked printer and asks for the cancel late, with `send_now`:
/// it gets out, nothing more of the job prints.
#[test]
fn printcore_streaming_into_a_parked_printer_cancels_late() {
    let mut asked = false;
    let mut cancel_at = None;
    let o = drive(
        Host::new(Kind::Printcore, job(12, 30)),
        900_000_000,
        |h, now, _| {
            if !asked && now >= 3_000_000 {
                h.pri.push_back("M601".into());
                asked = true;
            }
            if let Some(t) = h.paused_at_us {
                if cancel_at.is_none() && now >= t + 45_000_000 {
                    h.pri.push_back("M524".into());
                    cancel_at = Some(now);
                }
            }
        },
    );
    let out = &o.host.out;
    let c = o.host.cancelled_at_us.expect("M524 never got out");
    assert!(
        c - cancel_at.unwrap() <= 3_001_000,
        "cancel took {} µs",
        c - cancel_at.unwrap()
    );
    assert!(
        o.after_cancel.is_empty(),
        "job moves after the cancel: {:?}",
        o.after_cancel
    );
    assert!(out.contains("lines of the cancelled job discarded") || out.contains("discarding"));
    assert_eq!(o.end_state, State::Cancelled);
}

/// The bound of the parked intake: printcore streams on into a parked printer and nobody asks
/// for anything for 300 s. The intake takes [`PARKED_EXTRA`] lines (192 s), then the next job
/// line waits with `busy: paused for user` keep-alives (the host does not time out); a
/// `send_now` would not leave the host now (docs/frontend.md, "Host rules": no finite buffer
/// helps a host that streams on for ever), the control byte still resumes, nothing is lost.
#[test]
fn a_very_late_resume_from_a_streaming_host_goes_by_the_control_byte() {
    let job = job(12, 30);
    let base = baseline(&job);
    let mut asked = false;
    let mut resumed = false;
    let mut busy_after_intake = false;
    let o = drive(
        Host::new(Kind::Printcore, job.clone()),
        900_000_000,
        |h, now, lines| {
            if !asked && now >= 3_000_000 {
                h.pri.push_back("M601".into());
                asked = true;
            }
            if let Some(t) = h.paused_at_us {
                if now >= t + 200_000_000 && lines.iter().any(|l| l == "busy: paused for user") {
                    busy_after_intake = true;
                }
                if !resumed && now >= t + 300_000_000 {
                    // A raw byte, outside the line protocol (Ctrl-R).
                    h.raw.push(0x12);
                    resumed = true;
                }
            }
        },
    );
    let out = &o.host.out;
    assert!(busy_after_intake, "no keep-alive once the intake was full");
    assert!(out.contains("//action:resumed"), "{out}");
    assert!(o.host.done());
    assert_eq!(o.executed, base, "every segment once, in order");
    let _ = firmware::printer::PARKED_EXTRA;
}

/// [`job`] with its heat-up (bed 60 °C, nozzle 200 °C, both waited for) and an end code that
/// turns the heaters and the fan off, as a slicer writes it.
fn heated_job(layers: u32, moves: u32) -> Vec<String> {
    let mut v: Vec<String> = [
        "M140 S60",
        "M104 S200",
        "M190 S60",
        "M109 S200",
        "M106 S255",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    v.extend(job(layers, moves));
    v.extend(["M104 S0", "M140 S0", "M107"].iter().map(|s| s.to_string()));
    v
}

/// [`baseline`] with the heaters modelled (`heated_job`s: the heat-up takes its time).
fn heated_baseline(job: &[String]) -> Vec<(u32, u32)> {
    drive_with(
        Host::new(Kind::Printcore, job.to_vec()),
        900_000_000,
        true,
        |_, _, _| {},
    )
    .executed
}

/// The held job ran as if never paused (every segment once, in order, as the unpaused run),
/// no line was refused, and the nozzle was at the job's 200 °C (− 5) for every extrusion after
/// the resume.
fn assert_held_job_whole_and_hot(o: &Outcome, base: &[(u32, u32)]) {
    let out = &o.host.out;
    let tail: String = out.lines().rev().take(16).collect::<Vec<_>>().join("\n");
    assert!(out.contains("//action:resumed"), "{tail}");
    assert!(!out.contains("refused"), "a job line was refused:\n{out}");
    assert_one_stop_and_the_whole_job(o, base, &tail);
    let first = o.extruding_c_after_resume.first().copied();
    assert!(
        first.is_some_and(|c| c >= 195.0),
        "first extrusion after the resume at {first:?} °C"
    );
    let min = o
        .extruding_c_after_resume
        .iter()
        .copied()
        .fold(f32::MAX, f32::min);
    assert!(min >= 195.0, "an extrusion after the resume at {min} °C");
}

/// Issue 27: printcore streams on through a pause that outlasts the nozzle timeout (M760 T10):
/// the nozzle goes cold while job lines keep arriving. They are held, not judged cold at
/// arrival; the resume heats the nozzle again and waits; nothing is lost.
#[test]
fn a_pause_outlasting_the_nozzle_timeout_loses_nothing() {
    // Long enough that printcore still streams when the return starts (a line in flight).
    let job = heated_job(12, 30);
    let base = heated_baseline(&job);
    let (mut asked, mut resume_asked) = (false, false);
    // A console M105 sent when the return starts (the re-heat ahead of it): when, and when
    // answered; when the held job was released.
    let (mut m105_at, mut m105_ok_at, mut resumed_at) = (None, None, None);
    let o = drive_with(
        Host::new(Kind::Printcore, job.clone()),
        900_000_000,
        true,
        |h, now, lines| {
            if h.printing_since_us.is_some_and(|t| now == t + 1000) {
                h.pri.push_back("M760 T10".into());
            }
            if !asked && h.printing_since_us.is_some_and(|t| now >= t + 3_000_000) {
                h.pri.push_back("M601".into());
                asked = true;
            }
            if !resume_asked && h.paused_at_us.is_some_and(|t| now >= t + 120_000_000) {
                h.pri.push_back("M602".into());
                resume_asked = true;
            }
            if m105_at.is_none() && lines.iter().any(|l| l == "//action:resume") {
                h.pri.push_back("M105".into());
                m105_at = Some(now);
            }
            if m105_at.is_some()
                && m105_ok_at.is_none()
                && lines.iter().any(|l| l.starts_with("ok T:"))
            {
                m105_ok_at = Some(now);
            }
            if resumed_at.is_none() && lines.iter().any(|l| l == "//action:resumed") {
                resumed_at = Some(now);
            }
        },
    );
    assert!(
        o.host.out.contains("nozzle heater off"),
        "the timeout never fired"
    );
    assert_held_job_whole_and_hot(&o, &base);
    // The console during the re-heat: answered within the parked intake's pace (no card here:
    // ≤ 3 s), while the re-heat itself took longer.
    let (Some(sent), Some(answered), Some(released)) = (m105_at, m105_ok_at, resumed_at) else {
        panic!("M105 at {m105_at:?}, answered {m105_ok_at:?}, released {resumed_at:?}");
    };
    assert!(
        released - sent > 10_000_000,
        "no re-heat to wait for: {} µs",
        released - sent
    );
    assert!(
        answered - sent <= 3_100_000,
        "M105 answered {} µs after it was sent during the re-heat",
        answered - sent
    );
}

/// Issue 27: a pause requested in the last but one layer holds the last layer and the end
/// code (printcore streams them into the parked printer): the end code's `M104 S0` runs after
/// the held layer, never during the pause, and the held layer prints hot.
#[test]
fn a_pause_before_the_last_layer_holds_the_end_code() {
    let job = heated_job(4, 30);
    let base = heated_baseline(&job);
    let (mut asked, mut resume_asked) = (false, false);
    let mut target_while_parked = Vec::new();
    let o = drive_with(
        Host::new(Kind::Printcore, job.clone()),
        900_000_000,
        true,
        |h, now, _| {
            // The sender is a queue's length ahead of the head: the pause stops before the
            // last layer or the one before it, and the rest comes into the parked printer.
            if !asked && h.next >= h.job.len() - 40 {
                h.pri.push_back("M601".into());
                asked = true;
            }
            if let Some(t) = h.paused_at_us {
                if h.next >= h.job.len() && !resume_asked {
                    target_while_parked.push(now);
                }
                if !resume_asked && h.next >= h.job.len() && now >= t + 30_000_000 {
                    h.pri.push_back("M602".into());
                    resume_asked = true;
                }
            }
        },
    );
    assert!(
        !target_while_parked.is_empty(),
        "the end code was not sent while parked"
    );
    assert_held_job_whole_and_hot(&o, &base);
}

/// Issue 27: a console jog (`send_now`: `G91`, `G1 Z1`, `G90`) that reaches the printer only
/// after the resume — it waited in printcore's queue behind a job line, as without a card —
/// never runs inside the job: the move is refused with an `echo:`, the `G91` never touches the
/// job's modal state, and the job runs as the unpaused one, no higher.
#[test]
fn a_console_jog_arriving_after_the_resume_never_runs_inside_the_job() {
    let job = job(6, 30);
    let base = baseline(&job);
    let (mut asked, mut resume_asked, mut jogged) = (false, false, false);
    let o = drive(
        Host::new(Kind::Printcore, job.clone()),
        600_000_000,
        |h, now, lines| {
            if !asked && now >= 3_000_000 {
                h.pri.push_back("M601".into());
                asked = true;
            }
            if !resume_asked && h.paused_at_us.is_some_and(|t| now >= t + 5_000_000) {
                h.pri.push_back("M602".into());
                resume_asked = true;
            }
            if !jogged && lines.iter().any(|l| l == "//action:resumed") {
                for l in ["G91", "G1 Z1 F600", "G90"] {
                    h.pri.push_back(l.into());
                }
                jogged = true;
            }
        },
    );
    let out = &o.host.out;
    let tail: String = out.lines().rev().take(16).collect::<Vec<_>>().join("\n");
    assert!(jogged, "never resumed:\n{tail}");
    assert!(
        out.contains("echo:refused: console move while printing"),
        "{out}"
    );
    assert_one_stop_and_the_whole_job(&o, &base, &tail);
    let cfg = MachineConfig::ENDER3;
    let top = (0.2 * 6.0 + cfg.pause.lift_z_mm) * cfg.axes[2].steps_per_mm;
    assert!(o.max_z as f32 <= top + 1.0, "max Z {} steps", o.max_z);
}

/// Issue 27: two jobs on one connection (printcore resets its line numbers between them); the
/// second is paused past the nozzle timeout while printcore streams, after the first job's end
/// code turned the heaters off: nothing of either job is lost and the second prints hot.
#[test]
fn a_second_job_on_one_connection_paused_past_the_timeout_loses_nothing() {
    let job = heated_job(3, 30);
    let two = |pause: bool| {
        let (mut second, mut asked, mut resume_asked) = (false, false, false);
        let (mut timeout_set, mut second_from) = (false, None);
        drive_with(
            Host::new(Kind::Printcore, job.clone()),
            1_200_000_000,
            true,
            |h, now, _| {
                if !second && h.done() {
                    h.start_job(job.clone());
                    second = true;
                    second_from = Some(now);
                }
                if !pause {
                    return;
                }
                let Some(t2) = second_from else { return };
                if !timeout_set {
                    h.pri.push_back("M760 T10".into());
                    timeout_set = true;
                }
                if !asked && h.next >= 60 && now > t2 {
                    h.pri.push_back("M601".into());
                    asked = true;
                }
                if !resume_asked
                    && h.paused_at_us
                        .is_some_and(|t| t > t2 && now >= t + 90_000_000)
                {
                    h.pri.push_back("M602".into());
                    resume_asked = true;
                }
            },
        )
    };
    let base = two(false).executed;
    let o = two(true);
    assert!(
        o.host.out.contains("nozzle heater off"),
        "the timeout never fired"
    );
    assert_held_job_whole_and_hot(&o, &base);
}

/// printcore's end of a job: `send_now("M400")` and `send_now("M118 …")` once the last job
/// line is sent, unnumbered, while the job's moves still run. The M400 is a console line
/// (the job's host, unnumbered: the held job's rule), but not parked it waits for every move
/// queued before it, as Marlin's: the M118 after it is answered only once the job's last
/// block has run (found by `tests/tests/host_long_pause.rs`: answered when the head stood
/// still between the spilled lines, printcore disconnected mid-job and the printer paused
/// for the orphaned job).
#[test]
fn a_console_m400_while_the_job_runs_waits_for_the_job_s_moves() {
    // A dwell near the end: the head stands still while moves are still queued behind it (as
    // when the planner runs dry while spilled lines are read back from the card).
    let mut job = job(3, 20);
    job.extend(["G4 P1000", "G1 X20 Y20 E0.5 F2400", "G1 X30 Y30 E0.5"].map(String::from));
    let base = baseline(&job);
    let mut sent = false;
    let mut echoed_us = None;
    let o = drive(
        Host::new(Kind::Printcore, job),
        600_000_000,
        |h, now, lines| {
            if !sent && h.next >= h.job.len() && !h.in_flight {
                h.pri.push_back("M400".into());
                h.pri.push_back("M118 job-end".into());
                sent = true;
            }
            if lines.iter().any(|l| l.contains("job-end")) {
                echoed_us.get_or_insert(now);
            }
        },
    );
    assert_eq!(o.executed, base, "every segment once, in order");
    let echoed_us = echoed_us.expect("the M118 after the M400 was answered");
    assert!(
        echoed_us >= o.last_job_block_us,
        "M400 answered at {echoed_us} µs, the job's last block ended at {} µs",
        o.last_job_block_us
    );
}
