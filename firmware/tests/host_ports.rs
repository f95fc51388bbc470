//! The host link in front of the real executive: flow control (bursts wait in the sender,
//! never refused), two ports (USB and the TFT's UART), M112.

use firmware::config::MachineConfig;
use firmware::link::{checksum, PortId};
use firmware::planner::BlockKind;
use firmware::printer::{Printer, Record, State};

const TICK_US: u64 = 1000;

/// A port's sender: bytes written but not yet taken by the printer (flow control), and what
/// the printer answered on that port.
#[derive(Default)]
struct Wire {
    pending: Vec<u8>,
    out: String,
}

struct Bench {
    p: Printer,
    now: u64,
    wires: [Wire; 2],
    /// Job moves whose last segment has run (sequence numbers, in order).
    executed: Vec<u32>,
}

impl Bench {
    fn new() -> Self {
        Bench {
            p: Printer::new(MachineConfig::ENDER3),
            now: 0,
            wires: [Wire::default(), Wire::default()],
            executed: Vec::new(),
        }
    }

    fn write(&mut self, port: PortId, bytes: &[u8]) {
        self.wires[port.index()].pending.extend_from_slice(bytes);
        self.offer(port);
    }

    fn offer(&mut self, port: PortId) {
        let w = &mut self.wires[port.index()];
        let n = self.p.receive_on(port, &w.pending, self.now);
        w.pending.drain(..n);
    }

    /// One main-loop tick: offer what waits, poll, run the steps due, collect output.
    fn tick(&mut self) {
        for port in PortId::ALL {
            self.offer(port);
        }
        self.p.poll(self.now);
        while let Some(t) = self.p.next_step_ns() {
            if t > (self.now + TICK_US) * 1000 {
                break;
            }
            self.p.next_step();
        }
        while let Some(r) = self.p.pop_record() {
            if let Record::Executed {
                seq,
                seg,
                segs,
                kind: BlockKind::Job,
                ..
            } = r
            {
                if seg + 1 == segs {
                    self.executed.push(seq);
                }
            }
        }
        for port in PortId::ALL {
            let w = &mut self.wires[port.index()];
            self.p.write_output_on(port, &mut w.out).unwrap();
        }
        self.now += TICK_US;
    }

    fn run_until(&mut self, limit_us: u64, mut done: impl FnMut(&mut Self) -> bool) {
        while self.now < limit_us {
            self.tick();
            if done(self) {
                return;
            }
        }
        panic!(
            "not done within {limit_us} µs; state {:?}",
            self.p.status().state
        );
    }

    fn idle(&mut self) -> bool {
        self.wires.iter().all(|w| w.pending.is_empty())
            && self.p.status().state == State::Idle
            && self.p.next_step_ns().is_none()
    }

    fn out(&self, port: PortId) -> &str {
        &self.wires[port.index()].out
    }
}

fn numbered(n: u32, cmd: &str) -> String {
    let body = format!("N{n} {cmd}");
    format!("{body}*{}\n", checksum(body.as_bytes()))
}

fn oks(s: &str) -> usize {
    s.lines().filter(|l| l.starts_with("ok")).count()
}

#[test]
fn burst_of_short_lines_to_an_idle_printer_all_run() {
    // Issue 12: eight short lines in one write got four `Error:Line queue full` and were lost.
    let mut b = Bench::new();
    let burst: String = (1..=8).map(|i| format!("G1 X{} F6000\n", i * 5)).collect();
    b.write(PortId::Usb, burst.as_bytes());
    b.run_until(20_000_000, Bench::idle);
    assert!(
        !b.out(PortId::Usb).contains("Error"),
        "{}",
        b.out(PortId::Usb)
    );
    assert_eq!(oks(b.out(PortId::Usb)), 8);
    assert_eq!(b.executed.len(), 8);
    assert_eq!(b.p.status().position[0], 40 * 80);
}

#[test]
fn a_burst_far_beyond_every_queue_waits_in_the_sender() {
    // 300 lines in one write: far more than the link FIFO and the command queue hold. The rest
    // stays with the sender until there is room; every line runs once, in order.
    let mut b = Bench::new();
    let burst: String = (1..=300)
        .map(|i| format!("G1 X{} Y{} F12000\n", i % 100 + 1, i % 7 + 1))
        .collect();
    b.write(PortId::Usb, burst.as_bytes());
    assert!(
        !b.wires[0].pending.is_empty(),
        "flow control held bytes back"
    );
    b.run_until(200_000_000, Bench::idle);
    assert!(!b.out(PortId::Usb).contains("Error"));
    assert_eq!(oks(b.out(PortId::Usb)), 300);
    let mut sorted = b.executed.clone();
    sorted.sort();
    sorted.dedup();
    assert!(b.executed == sorted, "in order, once each");
    assert_eq!(sorted.len(), 300);
}

#[test]
fn tft_line_split_around_a_usb_line_is_one_line() {
    // Issue 12 item 7: a TFT M105 split around a USB line gave a checksum error and a lost
    // line when both ports shared one assembler.
    let mut b = Bench::new();
    b.write(PortId::Tft, b"M1");
    b.write(PortId::Usb, numbered(1, "G1 X10 F6000").as_bytes());
    b.write(PortId::Tft, b"05\n");
    b.write(PortId::Usb, numbered(2, "G1 X20").as_bytes());
    b.write(PortId::Tft, b"N1 M11");
    b.write(PortId::Usb, numbered(3, "M114").as_bytes());
    // The TFT numbers its own lines (its own `L`).
    let body = "N2 M115";
    b.write(
        PortId::Tft,
        format!(
            "0*{}\n{body}*{}\n",
            checksum(b"N1 M110"),
            checksum(body.as_bytes())
        )
        .as_bytes(),
    );
    b.run_until(20_000_000, Bench::idle);
    let usb = b.out(PortId::Usb);
    let tft = b.out(PortId::Tft);
    assert!(
        !usb.contains("Error") && !tft.contains("Error"),
        "{usb}\n---\n{tft}"
    );
    assert!(!usb.contains("Resend") && !tft.contains("Resend"));
    // Answers went to the port that asked.
    assert_eq!(oks(usb), 3, "{usb}");
    assert!(usb.contains("X:") && !usb.contains("T:"), "{usb}");
    assert!(!usb.contains("FIRMWARE_NAME"));
    assert_eq!(oks(tft), 3, "{tft}");
    assert!(tft.contains("ok T:"), "{tft}");
    assert!(tft.contains("FIRMWARE_NAME"));
    assert!(!tft.contains("X:"));
    assert_eq!(b.p.port(PortId::Usb).last_line(), 3);
    assert_eq!(b.p.port(PortId::Tft).last_line(), 2);
    assert_eq!(b.executed.len(), 2);
}

#[test]
fn pause_from_the_tft_is_announced_on_both_ports() {
    let mut b = Bench::new();
    let job: String = (1..=20)
        .map(|i| format!("G1 X{} Y{} F3000\n", i * 5, i * 3))
        .collect();
    b.write(PortId::Usb, job.as_bytes());
    for _ in 0..200 {
        b.tick();
    }
    // Pause now from the TFT: its `ok` goes to the TFT, `//action:paused` to both.
    b.write(PortId::Tft, b"M601 S1\n");
    b.run_until(60_000_000, |b| b.p.status().state == State::Paused);
    for _ in 0..10 {
        b.tick();
    }
    assert!(
        b.out(PortId::Tft).starts_with("ok\n"),
        "{}",
        b.out(PortId::Tft)
    );
    for port in PortId::ALL {
        assert!(b.out(port).contains("//action:paused"), "{port:?}");
    }
    // Resume from USB: the rest of the job runs, nothing lost.
    b.write(PortId::Usb, b"M602\n");
    b.run_until(200_000_000, Bench::idle);
    assert_eq!(b.executed.len(), 20);
    assert_eq!(b.p.status().position[0], 100 * 80);
}

#[test]
fn m112_is_an_error_and_nothing_is_answered_after_it() {
    // Marlin: the emergency parser calls kill(): `Error:Printer halted. kill() called!`, then
    // no answer to anything until reset. OctoPrint and printcore treat that Error as fatal.
    let mut b = Bench::new();
    b.write(PortId::Usb, numbered(1, "G1 X50 F3000").as_bytes());
    for _ in 0..50 {
        b.tick();
    }
    let before = oks(b.out(PortId::Usb));
    assert_eq!(before, 1);
    b.write(PortId::Usb, numbered(2, "M112").as_bytes());
    b.write(PortId::Usb, numbered(3, "G1 X60").as_bytes());
    b.write(PortId::Usb, b"M105\nM602\n");
    b.write(PortId::Tft, b"M105\n");
    for _ in 0..50 {
        b.tick();
    }
    assert_eq!(b.p.status().state, State::Halted);
    for port in PortId::ALL {
        let o = b.out(port);
        assert!(
            o.contains("Error:Printer halted. kill() called!\n"),
            "{port:?}: {o}"
        );
        assert!(!o.contains("echo:"), "{port:?}: {o}");
    }
    assert_eq!(oks(b.out(PortId::Usb)), before, "no ok after the halt");
    assert_eq!(oks(b.out(PortId::Tft)), 0);
    // The bytes were taken (the host is not blocked on a dead printer), never answered.
    assert!(b.wires.iter().all(|w| w.pending.is_empty()));
}
