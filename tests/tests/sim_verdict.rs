//! `sim run --json`'s verdict (`stopped_at_layer_boundary`, `first_boundary_after_request`,
//! `stop_layer`) comes from the independent reference (`layerref`), never from the firmware's
//! layer detector (issue 21: it used to say `true` for mid-turn stops on a Slic3r vase, because
//! it trusted the firmware's marks).
//!
//! Proof by disagreement: the Slic3r vase (no markers at all), comments stripped, with a
//! `layer` pause requested in the middle of turn 10. The executive is the real firmware, but
//! one test feeds it a forged marker (`M73 L99`, numbered as a job line — the host's later
//! lines renumbered after it — its `ok` swallowed; an unnumbered line from a host that numbers
//! its job would be a console line, whose marker is no job boundary) between two moves in the
//! middle of that turn: the firmware's detector then has a boundary there and
//! stops at it — mid-turn by the reference. The sim must say "not at a boundary" for that
//! run, and "at the first boundary" for the same request without the forgery (where the
//! firmware stops at the end of the turn). Cost: 4 runs of ≈ 25 s of printing, ≈ 3 s of test
//! time (debug build).

use firmware::config::MachineConfig;
use firmware::motion::Realtime;
use firmware::printer::Record;
use layerref::Comments;
use sim::exec::{PrinterExec, PrinterFactory};
use sim::port::{ExecStatus, Executive, FirmwareKnobs, StepEvent};
use sim::run::{self, Factory, PauseWhen};
use tests::judge::{judge_request, Job};

/// The real executive, with `inject` fed to it once just before the first host line that
/// contains `before` (see the module documentation).
struct Forged {
    inner: PrinterExec,
    before: Option<String>,
    inject: Vec<u8>,
    /// Injected and not yet answered: its `ok` is not the host's.
    swallow_ok: bool,
    /// The forged line reached the firmware.
    injected: bool,
    /// Host bytes taken and rewritten, not yet all taken by the firmware.
    pending: Vec<u8>,
}

impl Forged {
    /// `line` (one host line, `\n` included) as the firmware gets it: numbered lines after
    /// the forgery one higher, the forgery itself numbered where its line was.
    fn rewrite(&mut self, line: &[u8]) -> Vec<u8> {
        let text = String::from_utf8_lossy(line);
        let text = text.trim_end();
        let numbered = text
            .strip_prefix('N')
            .and_then(|rest| rest.split_once(' '))
            .and_then(|(n, rest)| Some((n.parse::<i64>().ok()?, rest.rsplit_once('*')?.0)));
        let Some((n, body)) = numbered else {
            return line.to_vec();
        };
        let with = |n: i64, body: &str| {
            let pre = format!("N{n} {body}");
            format!("{pre}*{}\n", firmware::link::checksum(pre.as_bytes()))
        };
        let due = self
            .before
            .as_ref()
            .is_some_and(|t| body.contains(t.as_str()));
        if due {
            self.before = None;
            self.swallow_ok = true;
            self.injected = true;
            let inject = String::from_utf8_lossy(&self.inject).trim().to_string();
            return [with(n, &inject), with(n + 1, body)].concat().into_bytes();
        }
        with(n + i64::from(self.injected), body).into_bytes()
    }
}

impl Executive for Forged {
    fn receive(&mut self, bytes: &[u8], now_us: u64) -> usize {
        // What was rewritten goes first; the host waits meanwhile.
        if !self.pending.is_empty() {
            let k = self.inner.receive(&self.pending, now_us);
            self.pending.drain(..k);
            if !self.pending.is_empty() {
                return 0;
            }
        }
        // One host line at a time, rewritten whole.
        let Some(end) = bytes.iter().position(|&b| b == b'\n') else {
            return 0;
        };
        self.pending = self.rewrite(&bytes[..=end]);
        let k = self.inner.receive(&self.pending, now_us);
        self.pending.drain(..k);
        end + 1
    }
    fn request(&mut self, req: Realtime, now_us: u64) {
        self.inner.request(req, now_us);
    }
    fn poll(&mut self, now_us: u64) {
        self.inner.poll(now_us);
    }
    fn next_step_us(&mut self, now_us: u64) -> Option<u64> {
        self.inner.next_step_us(now_us)
    }
    fn pop_step(&mut self, now_us: u64) -> Option<StepEvent> {
        self.inner.pop_step(now_us)
    }
    fn take_output(&mut self, out: &mut String) {
        let mut s = String::new();
        self.inner.take_output(&mut s);
        if self.swallow_ok {
            // The oks come in line order: dropping one after the injection keeps the host's
            // count of its own lines right.
            if let Some(i) = s.lines().position(|l| l == "ok") {
                let kept: Vec<&str> = s
                    .lines()
                    .enumerate()
                    .filter(|(k, _)| *k != i)
                    .map(|(_, l)| l)
                    .collect();
                let mut joined = kept.join("\n");
                if !joined.is_empty() {
                    joined.push('\n');
                }
                s = joined;
                self.swallow_ok = false;
            }
        }
        out.push_str(&s);
    }
    fn status(&self) -> ExecStatus {
        self.inner.status()
    }
    fn next_seq(&self) -> Option<u32> {
        self.inner.next_seq()
    }
    fn thermal(&mut self, bed: bool, measured_c: f32, now_us: u64) -> f32 {
        self.inner.thermal(bed, measured_c, now_us)
    }
}

/// Makes [`Forged`] executives around the real firmware.
struct ForgedFactory {
    before: Option<String>,
}

impl Factory for ForgedFactory {
    type Exec = Forged;
    fn make(&self, machine: &MachineConfig, knobs: &FirmwareKnobs) -> Forged {
        Forged {
            inner: {
                let mut e = PrinterFactory.make(machine, knobs);
                e.keep_notes = true;
                e
            },
            before: self.before.clone(),
            inject: b"M73 L99\n".to_vec(),
            swallow_ok: false,
            injected: false,
            pending: Vec::new(),
        }
    }
}

fn vase() -> Job {
    let path = format!(
        "{}/fixtures/corpus/slic3r-vase.gcode",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    Job::new(text.lines().map(str::to_string).collect(), Comments::Strip)
}

#[test]
fn the_verdict_is_the_reference_s_not_the_firmware_s() {
    let job = vase();
    let turn = job
        .model
        .layers()
        .iter()
        .find(|l| l.number == 10)
        .copied()
        .expect("turn 10");
    assert!(turn.last_line > turn.first_line + 20, "{turn:?}");
    // A move in the middle of the turn (the forgery goes before it), and a request a quarter
    // of the way round: the first boundary after it is the end of turn 10.
    let mid = (turn.first_line..=turn.last_line)
        .skip((turn.last_line - turn.first_line) / 2)
        .find(|&i| job.model.extrudes(i))
        .expect("an extrusion mid-turn");
    let quarter = turn.first_line + (turn.last_line - turn.first_line) / 4;
    let plain = run::run(&PrinterFactory, &job.scenario(), &job.lines).expect("reference run");
    let t_req = plain
        .run
        .rec
        .records
        .iter()
        .find(|r| tests::judge::job_line(&plain, r.tag.seq) == Some(quarter))
        .expect("the quarter line ran")
        .t_end_us;
    let mut sc = job.scenario();
    sc.pause = Some(PauseWhen::AtUs(t_req));
    sc.resume_after_us = Some(200_000);
    sc.max_time_us = t_req + 60_000_000;

    // The firmware as it is: stops at the end of the turn; the sim and the judge agree.
    let o = run::run(&PrinterFactory, &sc, &job.lines).expect("run");
    judge_request(&o, t_req, &job).expect("the firmware stops at the first boundary");
    assert!(o.report.stopped_at_layer_boundary, "{:#?}", o.report);
    assert!(o.report.first_boundary_after_request, "{:#?}", o.report);
    assert_eq!(o.report.stop_layer, Some(10), "{:#?}", o.report);

    // The firmware misled into a mid-turn boundary: it stops there, and the sim says so.
    let forged = ForgedFactory {
        before: Some(job.lines[mid].trim().to_string()),
    };
    let o = run::run(&forged, &sc, &job.lines).expect("forged run");
    assert!(o.run.fw.injected, "the forged marker reached the firmware");
    // The firmware took it for a layer boundary and stopped at its mark (its own record says
    // so; being the first marker of its family, the firmware even numbers it layer 1: what
    // printed before is a prelude to it).
    let stopped: Vec<Option<u32>> = o
        .run
        .fw
        .inner
        .notes
        .iter()
        .filter_map(|r| match r {
            Record::Stopped { layer, .. } => Some(*layer),
            _ => None,
        })
        .collect();
    assert_eq!(stopped, [Some(1)], "{:#?}", o.report);
    let stop = o.report.pause_point_steps.expect("paused");
    let stop_z_mm = f64::from(stop[2]) / 400.0;
    assert!(
        !o.report.stopped_at_layer_boundary && !o.report.first_boundary_after_request,
        "mid-turn stop (Z {stop_z_mm:.3} mm) judged a boundary: {:#?}",
        o.report
    );
    assert_eq!(o.report.stop_layer, Some(10), "{:#?}", o.report);
}
