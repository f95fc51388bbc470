//! Requests on the link through the real `Printer` (issue 31): `M112` written behind lines the
//! printer has no room for acts at once (the emergency scan), while printing and while
//! parked; a pause written in the same burst as the moves it should stop pauses them; noise
//! on the TFT's UART neither halts nor cancels. Cost: well under a second.

mod support;

use firmware::link::{checksum, PortId, BYTE_CANCEL, BYTE_EMERGENCY_STOP};
use firmware::printer::{Printer, State};

fn numbered(n: u32, cmd: &str) -> String {
    let body = format!("N{n} {cmd}");
    format!("{body}*{}\n", checksum(body.as_bytes()))
}

fn output(p: &mut Printer, port: PortId) -> String {
    let mut s = String::new();
    p.write_output_on(port, &mut s).unwrap();
    s
}

/// Run the printer for `ms` of virtual time from `now` (steps included); returns the new time.
fn run_ms(p: &mut Printer, mut now: u64, ms: u64) -> u64 {
    for _ in 0..ms {
        now += 1000;
        p.poll(now);
        while p.next_step_ns().is_some_and(|t| t <= now * 1000) {
            if p.next_step().is_none() {
                break;
            }
        }
    }
    now
}

/// `count` numbered long moves from line `from` (each 100 mm at 30 mm/s: 3.3 s).
fn moves(from: u32, count: u32) -> String {
    (from..from + count)
        .map(|n| {
            let x = if n % 2 == 0 { 10 } else { 110 };
            numbered(n, &format!("G1 X{x} Y{} F1800", 20 + n % 100))
        })
        .collect()
}

#[test]
fn m112_behind_a_hundred_unanswered_lines_halts_at_once() {
    // Issue 31: a host that does not wait for `ok` wrote 100 lines, then M112; it acted after
    // 75 s, when the lines ahead of it had run.
    let mut p = support::printer();
    let mut bytes = numbered(0, "M110").into_bytes();
    bytes.extend_from_slice(moves(1, 100).as_bytes());
    bytes.extend_from_slice(numbered(101, "M112").as_bytes());
    assert!(bytes.len() < firmware::link::SCAN_WINDOW);
    // Offered as the sim's pty and the board's driver offer it: the bytes not taken again.
    let taken = p.receive(&bytes, 1000);
    assert_eq!(p.state(), State::Halted, "M112 waited behind the lines");
    assert_eq!(
        taken,
        bytes.len(),
        "halted: everything is taken and ignored"
    );
    let out = output(&mut p, PortId::Usb);
    assert!(
        out.contains("Error:Printer halted. kill() called!"),
        "{out}"
    );
    // Only the lines that fitted the queue were answered; nothing moves afterwards.
    let oks = out.lines().filter(|l| l.starts_with("ok")).count();
    assert!(oks < 50, "{oks} oks before the halt: {out}");
    run_ms(&mut p, 1000, 100);
    assert_eq!(p.next_step_ns(), None);
}

#[test]
fn m112_behind_lines_written_into_a_parked_printer_halts_at_once() {
    // Issue 31: while parked, 40 lines ahead of M112 delayed it 4 s (the parked intake takes
    // one line a second).
    let mut p = support::printer();
    let mut now = 1000;
    let start = [numbered(0, "M110"), moves(1, 4)].concat();
    assert_eq!(p.receive(start.as_bytes(), now), start.len());
    now = run_ms(&mut p, now, 500);
    assert_eq!(p.receive(b"M25 S1\n", now), 7);
    for _ in 0..200 {
        now = run_ms(&mut p, now, 50);
        if p.state() == State::Paused {
            break;
        }
    }
    assert_eq!(p.state(), State::Paused);
    let _ = output(&mut p, PortId::Usb);
    let mut bytes = moves(5, 40).into_bytes();
    bytes.extend_from_slice(numbered(45, "M112").as_bytes());
    let taken = p.receive(&bytes, now);
    assert_eq!(
        p.state(),
        State::Halted,
        "M112 waited behind the parked intake"
    );
    assert_eq!(taken, bytes.len());
    assert!(output(&mut p, PortId::Usb).contains("kill() called!"));
}

#[test]
fn a_pause_written_with_the_moves_it_should_stop_pauses_them() {
    // Issue 31: `G1`, `G1`, `M25` in one write to an idle printer answered
    // `pause: nothing to pause` and ran both moves.
    for (pause, mode) in [("M25 S1", "now"), ("M25", "layer")] {
        let mut p = support::printer();
        let burst = format!("G1 X50 F1800\nG1 X100\n{pause}\n");
        assert_eq!(p.receive(burst.as_bytes(), 1000), burst.len());
        let out = output(&mut p, PortId::Usb);
        assert!(!out.contains("nothing to pause"), "{mode}: {out}");
        assert!(out.contains("echo:pause: stopping"), "{mode}: {out}");
        let mut now = 1000;
        for _ in 0..400 {
            now = run_ms(&mut p, now, 50);
            if p.state() == State::Paused {
                break;
            }
        }
        assert_eq!(p.state(), State::Paused, "{mode}");
        // Resumed, the moves end where the file says.
        assert_eq!(p.receive(b"M24\n", now), 4);
        for _ in 0..400 {
            now = run_ms(&mut p, now, 50);
            if p.state() == State::Idle && p.next_step_ns().is_none() {
                break;
            }
        }
        let x_steps = p.status().position[0];
        assert_eq!(x_steps, 100 * 80, "{mode}: X at 100 mm after the resume");
    }
    // A pause before the moves, in the same burst, finds nothing to pause (stream order).
    let mut p = support::printer();
    let burst = b"M25\nG1 X10 F1800\n";
    assert_eq!(p.receive(burst, 1000), burst.len());
    assert!(output(&mut p, PortId::Usb).contains("nothing to pause"));
}

#[test]
fn noise_on_the_tft_wire_neither_halts_nor_cancels() {
    // Issue 31: one stray byte on the display's cable ended the print (0x18 halted, 0x03
    // cancelled: single control bytes were requests on every port).
    let mut p = support::printer();
    let job = "G1 X100 F1800\n";
    assert_eq!(p.receive(job.as_bytes(), 1000), job.len());
    let noisy = [
        b"M1".as_slice(),
        &[BYTE_EMERGENCY_STOP, BYTE_CANCEL],
        b"05\n",
        &[BYTE_EMERGENCY_STOP],
    ]
    .concat();
    assert_eq!(p.receive_on(PortId::Tft, &noisy, 2000), noisy.len());
    let now = run_ms(&mut p, 2000, 5);
    assert_ne!(p.state(), State::Halted);
    assert_ne!(p.state(), State::Cancelled);
    let tft = output(&mut p, PortId::Tft);
    assert!(tft.contains("ok T:"), "the M105 around the noise: {tft}");
    assert_eq!(p.port(PortId::Tft).stats().controls_ignored, 3);
    // Where a host chose them (the USB port), they act.
    assert_eq!(p.receive(&[BYTE_EMERGENCY_STOP], now), 1);
    assert_eq!(p.state(), State::Halted);
}
