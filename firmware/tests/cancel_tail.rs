//! Issue 31: what hosts really send around a cancel and a pause. A cancel switches the heaters
//! and the fan off; the cancelled stream's tail may still cool, switch motors off and report
//! (M105 always answers with temperatures), but never moves or heats; a host that polls
//! faster than the tail's 2 s silence does not keep the discarding going; an M400 while
//! parked — a console line or a job line — is answered in bounded time (docs/frontend.md,
//! "Cancel" and "Host rules").

use firmware::config::MachineConfig;
use firmware::link::checksum;
use firmware::printer::{Printer, State};
use firmware::thermal::HeaterId;

/// A printer on virtual time, driven one line per `ok` by a test host.
struct Bench {
    p: Printer,
    now_us: u64,
    /// Everything the printer said.
    out: String,
    /// The host's next line number (numbered lines).
    next_no: u32,
}

/// The longest a line may wait for its `ok` here (printer time): far beyond the parked
/// intake's pace (1 s) and the cancel's park, far below "for ever".
const OK_BOUND_US: u64 = 10_000_000;

impl Bench {
    fn new() -> Self {
        let mut p = Printer::new(MachineConfig::ENDER3);
        // No heater model: the jobs extrude cold (as M302 P1).
        p.extrusion_guard_mut().allow_cold = true;
        Bench {
            p,
            now_us: 0,
            out: String::new(),
            next_no: 1,
        }
    }

    /// Run the printer for `us` of virtual time; returns what it said meanwhile.
    fn tick(&mut self, us: u64) -> String {
        let mut said = String::new();
        let end = self.now_us + us;
        while self.now_us < end {
            self.p.poll(self.now_us);
            let until_ns = (self.now_us + 1000) * 1000;
            while let Some(t) = self.p.next_step_ns() {
                if t > until_ns || self.p.next_step().is_none() {
                    break;
                }
            }
            while self.p.pop_record().is_some() {}
            self.now_us += 1000;
            self.p.write_output(&mut said).unwrap();
        }
        self.out.push_str(&said);
        said
    }

    /// Write `line` and run until its `ok` (at most [`OK_BOUND_US`]): what the printer said
    /// up to and including the `ok`, and how long it took.
    fn send(&mut self, line: &str) -> (String, u64) {
        let bytes = format!("{line}\n");
        assert_eq!(self.p.receive(bytes.as_bytes(), self.now_us), bytes.len());
        let start = self.now_us;
        let mut said = String::new();
        while self.now_us - start < OK_BOUND_US {
            said.push_str(&self.tick(1000));
            if said.lines().any(|l| l.starts_with("ok")) {
                return (said, self.now_us - start);
            }
        }
        panic!(
            "`{line}` not answered within {} s: {said}\nall: {}",
            OK_BOUND_US / 1_000_000,
            self.out
        );
    }

    /// A numbered, checksummed job line.
    fn send_numbered(&mut self, cmd: &str) -> (String, u64) {
        let pre = format!("N{} {cmd}", self.next_no);
        self.next_no += 1;
        let line = format!("{pre}*{}", checksum(pre.as_bytes()));
        self.send(&line)
    }

    /// A realtime request's bytes (the host does not wait for its `ok`).
    fn request(&mut self, line: &str) {
        let bytes = format!("{line}\n");
        assert_eq!(self.p.receive(bytes.as_bytes(), self.now_us), bytes.len());
    }

    /// Run until the state is `s` (at most 30 s).
    fn until(&mut self, s: State) {
        for _ in 0..30_000 {
            if self.p.status().state == s {
                return;
            }
            self.tick(1000);
        }
        panic!("never {s:?}: {}", self.out);
    }

    fn targets(&self) -> (f32, f32) {
        let t = self.p.thermal();
        (t.target_c(HeaterId::Hotend), t.target_c(HeaterId::Bed))
    }
}

/// A long job of slow moves, numbered when `numbered`: heats, fan on, then moves.
fn start_job(b: &mut Bench, numbered: bool) {
    let lines = [
        "M104 S200",
        "M140 S60",
        "M106 S255",
        "G1 Z5 F600",
        "G1 X100 F3000",
        "G1 Y100 F3000",
        "G1 X10 F3000",
    ];
    for l in lines {
        if numbered {
            b.send_numbered(l);
        } else {
            b.send(l);
        }
    }
    assert_eq!(b.targets(), (200.0, 60.0));
    assert_eq!(b.p.fan_pwm(), 255);
}

/// Cancel and wait for the park to end.
fn cancel(b: &mut Bench) {
    b.request("M524");
    b.until(State::Cancelled);
    assert!(b.out.contains("//action:cancel"), "{}", b.out);
}

/// Issue 31: after M524 the nozzle stayed at 200 °C and the bed at 60 °C.
#[test]
fn a_cancel_switches_the_heaters_and_the_fan_off() {
    let mut b = Bench::new();
    start_job(&mut b, true);
    cancel(&mut b);
    assert_eq!(b.targets(), (0.0, 0.0), "{}", b.out);
    assert_eq!(b.p.fan_pwm(), 0);
    // The host says otherwise: its console line heats again.
    b.send("M104 S150");
    assert_eq!(b.targets().0, 150.0);
}

/// printcore streams on after the cancel: the tail's cool-down, motors-off and report lines
/// run; its moves, homing and heat-ups do not.
#[test]
fn a_cancelled_tail_cools_and_reports_but_neither_moves_nor_heats() {
    let mut b = Bench::new();
    start_job(&mut b, true);
    cancel(&mut b);
    // The host heats the nozzle from its console (unnumbered: taken).
    b.send("M104 S150");
    let parked = b.p.status().position;
    for l in [
        "G1 X50 Y50 F6000",
        "M104 S210",
        "M140 S70",
        "G28",
        "M106 S200",
    ] {
        b.send_numbered(l);
    }
    assert_eq!(b.targets(), (150.0, 0.0), "heat-ups discarded: {}", b.out);
    assert_eq!(b.p.fan_pwm(), 0);
    let (said, _) = b.send_numbered("M105");
    assert!(said.contains("T:"), "M105 reports temperatures: {said}");
    let (said, _) = b.send_numbered("M114");
    assert!(said.contains("X:"), "M114 reports the position: {said}");
    b.send_numbered("M104 S0");
    assert_eq!(b.targets().0, 0.0, "the tail's M104 S0 ran: {}", b.out);
    b.send_numbered("M84");
    assert_eq!(b.p.status().position_lost, 0b111, "M84 ran: {}", b.out);
    b.tick(500_000);
    assert_eq!(b.p.status().position, parked, "nothing moved");
    assert!(
        b.out.contains("discarding the rest of the job"),
        "the tail is still discarded: {}",
        b.out
    );
}

/// A host that numbers nothing and polls M105 every second: before issue 31 each poll
/// renewed the discarding (bare `ok`s, no temperatures) and the next G1 and M114 were
/// discarded too. The polls are answered with temperatures and do not count as the tail.
#[test]
fn polling_faster_than_the_tail_silence_does_not_discard_for_ever() {
    let mut b = Bench::new();
    start_job(&mut b, false);
    cancel(&mut b);
    // The rest of the job, then the host's own polling.
    for l in ["G1 X60 F6000", "G1 X70 F6000"] {
        b.send(l);
    }
    let parked = b.p.status().position;
    for _ in 0..5 {
        let (said, _) = b.send("M105");
        assert!(said.contains("T:"), "M105 reports temperatures: {said}");
        b.tick(1_000_000);
    }
    assert_eq!(b.p.status().position, parked, "the tail did not move");
    b.send("G1 X20 F6000");
    b.tick(5_000_000);
    let x = b.p.status().position[0];
    assert_eq!(x, 20 * 80, "the G1 after the tail ran: {}", b.out);
    let (said, _) = b.send("M114");
    assert!(said.contains("X:20.00"), "{said}");
}

/// Park a numbered job with the pause realtime line.
fn park(b: &mut Bench) {
    start_job(b, true);
    b.request("M601 S1");
    b.until(State::Paused);
}

/// Issue 31: a console M400 while parked answered `busy: paused for user` for ever; the host
/// waits for its `ok` before it sends the resume.
#[test]
fn a_console_m400_while_parked_is_answered() {
    let mut b = Bench::new();
    park(&mut b);
    let (said, _) = b.send("M400");
    assert!(said.lines().any(|l| l == "ok"), "{said}");
    // After a manual jog: the `ok` waits for the jog (not for the held job).
    let before = b.p.status().position;
    b.send("G91");
    b.send("G1 Z1 F600");
    let (_, waited_us) = b.send("M400");
    assert_eq!(
        b.p.status().position[2],
        before[2] + 400,
        "the jog ended first"
    );
    assert!(waited_us > 0);
    b.send("G90");
    b.request("M602");
    b.until(State::Printing);
    b.send_numbered("M400");
    assert_eq!(
        b.p.status().state,
        State::Idle,
        "the job's M400 after the resume waits for the job"
    );
}

/// printcore streams into the parked printer: a job M400 taken by the parked intake is
/// answered once the machine rests (its held moves run after the resume, in order), and
/// the resume sent behind it gets out.
#[test]
fn a_job_m400_taken_while_parked_is_answered_and_the_job_completes() {
    let mut b = Bench::new();
    park(&mut b);
    let (said, _) = b.send_numbered("M400");
    assert!(said.lines().any(|l| l == "ok"), "{said}");
    b.send_numbered("G1 X30 F6000");
    let (said, _) = b.send_numbered("M400");
    assert!(said.lines().any(|l| l == "ok"), "{said}");
    b.request("M602");
    b.until(State::Printing);
    // The job's last M400, after the resume: answered when everything before it has run.
    let (_, _) = b.send_numbered("M400");
    assert_eq!(b.p.status().position[0], 30 * 80, "{}", b.out);
    assert_eq!(b.p.status().commands, 0);
}
