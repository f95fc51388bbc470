//! Heaters during a long pause, as Marlin's pause does it (issue 22; docs/frontend.md, "Heaters
//! during a long pause"): after `M760 T` seconds parked (Marlin's `PAUSE_PARK_NOZZLE_TIMEOUT`,
//! 45 s by default) the nozzle heater goes off, the bed keeps its target; the resume heats the
//! nozzle to its old target and the head does not move before it is there. The temperatures
//! are the sim's heater model's (`sim::thermal`, an independent plant), not the firmware's.

use firmware::config::MachineConfig;
use firmware::link::PortId;
use firmware::printer::Printer;
use sim::exec::PrinterExec;
use sim::port::{Executive, State};
use sim::thermal::Heaters;

struct Rig {
    fw: PrinterExec,
    heaters: Heaters,
    now: u64,
    out: String,
}

impl Rig {
    fn new() -> Self {
        let mut p = Printer::new(MachineConfig::ENDER3);
        p.extrusion_guard_mut().allow_cold = false;
        Rig {
            fw: PrinterExec::new(p),
            heaters: Heaters::ender3(),
            now: 0,
            out: String::new(),
        }
    }

    /// Send a line with flow control: what the firmware does not take yet is offered again
    /// after a tick.
    fn send(&mut self, line: &str) {
        let l = format!("{line}\n");
        let mut at = 0;
        while at < l.len() {
            at += self
                .fw
                .receive_on(PortId::Usb, &l.as_bytes()[at..], self.now);
            if at < l.len() {
                self.run(1_000, |_, _| {});
            }
        }
    }

    /// Run `us` of virtual time in 1 ms ticks; returns the nozzle temperature at the first
    /// step after `watch_from_us` (if any).
    fn run(&mut self, us: u64, mut on_step: impl FnMut(u64, f32)) {
        let end = self.now + us;
        while self.now < end {
            self.now += 1000;
            while let Some(t) = self.fw.next_step_us(self.now) {
                if t > self.now {
                    break;
                }
                if self.fw.pop_step(t).is_some() {
                    on_step(t, self.heaters.temperatures_c().0);
                }
            }
            self.heaters.tick(&mut self.fw, self.now);
            self.fw.poll(self.now);
            let mut s = String::new();
            self.fw.take_output_on(PortId::Usb, &mut s);
            self.out.push_str(&s);
        }
    }

    fn state(&self) -> State {
        self.fw.status().state
    }
}

/// A printing job at 200 °C / 60 °C, paused at a layer.
fn paused_rig(timeout: Option<&str>) -> Rig {
    let mut r = Rig::new();
    if let Some(t) = timeout {
        r.send(t);
    }
    for l in [
        "M140 S60",
        "M104 S200",
        "M190 S60",
        "M109 S200",
        "G28",
        "G90",
        "M83",
    ] {
        r.send(l);
        r.run(1_000, |_, _| {});
    }
    r.run(400_000_000, |_, _| {});
    assert!(r.out.matches("ok").count() >= 7, "heat-up: {}", r.out);
    for layer in 0..4 {
        r.send(&format!("G1 Z{:.1} F600", 0.2 * (layer + 1) as f32));
        for i in 0..20 {
            r.send(&format!("G1 X{} Y{} E0.5 F1800", 40 + (i % 2) * 40, 40 + i));
        }
    }
    r.run(2_000_000, |_, _| {});
    r.send("M601");
    let mut n = 0;
    while r.state() != State::Paused && n < 60_000 {
        r.run(1_000, |_, _| {});
        n += 1;
    }
    assert_eq!(r.state(), State::Paused, "{}", r.out);
    r
}

fn targets(r: &mut Rig) -> (f32, f32) {
    let mark = r.out.len();
    r.send("M105");
    r.run(2_000, |_, _| {});
    let line = r.out[mark..]
        .lines()
        .find(|l| l.starts_with("ok T:"))
        .expect("M105 answered")
        .to_string();
    // ok T:201.3 /200.0 B:60.1 /60.0 @:..
    let f: Vec<&str> = line.split_whitespace().collect();
    let t = f[2].trim_start_matches('/').parse().unwrap();
    let b = f[4].trim_start_matches('/').parse().unwrap();
    (t, b)
}

#[test]
fn the_nozzle_goes_off_after_45_s_parked_and_the_resume_heats_before_moving() {
    let mut r = paused_rig(None);
    r.run(40_000_000, |_, _| {});
    assert_eq!(targets(&mut r), (200.0, 60.0), "hot for the first 45 s");
    r.run(10_000_000, |_, _| {});
    assert!(
        r.out.contains("nozzle heater off after 45 s parked"),
        "{}",
        r.out
    );
    assert_eq!(targets(&mut r), (0.0, 60.0), "nozzle off, bed kept");
    // An hour parked: the nozzle cools to near room temperature, the bed stays at 60.
    r.run(3_600_000_000, |_, _| {});
    let (nozzle_c, bed_c) = r.heaters.temperatures_c();
    assert!(nozzle_c < 60.0, "nozzle {nozzle_c} °C after an hour off");
    assert!((bed_c - 60.0).abs() < 2.0, "bed {bed_c} °C");
    r.send("M602");
    let mut first_move_c = None;
    let t_resume = r.now;
    r.run(300_000_000, |_, c| {
        first_move_c.get_or_insert(c);
    });
    let c = first_move_c.expect("the head returned");
    assert!(c >= 198.0, "the head moved at {c} °C");
    assert!(r.out.contains("//action:resumed"), "{}", r.out);
    assert_eq!(targets(&mut r).0, 200.0, "old target back");
    eprintln!(
        "re-heat took {:.0} s of the resume",
        (r.now - t_resume) as f64 / 1e6
    );
}

#[test]
fn m760_t0_keeps_the_nozzle_hot_and_a_cancel_never_heats() {
    let mut r = paused_rig(Some("M760 T0"));
    r.run(120_000_000, |_, _| {});
    assert_eq!(targets(&mut r), (200.0, 60.0), "T0: the nozzle stays hot");
    assert!(!r.out.contains("nozzle heater off"));
    let mark = r.out.len();
    r.send("M760");
    r.run(1_000, |_, _| {});
    assert!(r.out[mark..].contains(" T0"), "{}", &r.out[mark..]);

    let mut r = paused_rig(Some("M760 T5"));
    r.run(10_000_000, |_, _| {});
    assert!(r.out.contains("nozzle heater off after 5 s parked"));
    r.send("M524");
    r.run(30_000_000, |_, _| {});
    assert!(r.out.contains("//action:cancel"), "{}", r.out);
    assert_eq!(targets(&mut r).0, 0.0, "a cancel leaves the nozzle off");
}
