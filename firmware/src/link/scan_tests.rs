//! The emergency scan (`scan.rs`) and the per-port control bytes, on the link alone.

use super::*;
use proptest::prelude::*;
use std::string::String;
use std::vec::Vec as StdVec;

fn numbered(n: u32, cmd: &str) -> String {
    let body = format!("N{n} {cmd}");
    format!("{body}*{}\n", checksum(body.as_bytes()))
}

fn out(link: &mut HostLink) -> String {
    let mut s = String::new();
    link.write_output(&mut s).unwrap();
    s
}

/// A link whose FIFO is full (the executive's queue is: nothing is popped).
fn full_link() -> HostLink {
    let mut l = HostLink::new();
    for n in 1..=LINE_QUEUE as u32 {
        let line = numbered(n, &format!("G1 X{n}"));
        assert_eq!(l.receive(line.as_bytes()), line.len());
    }
    let _ = out(&mut l);
    l
}

/// 100 job lines written ahead of their `ok`s, then `tail`.
fn burst(from: u32, tail: &str) -> StdVec<u8> {
    let mut b = StdVec::new();
    for n in from..from + 100 {
        b.extend_from_slice(numbered(n, &format!("G1 X{} Y20 E{}.5 F1800", n % 200, n)).as_bytes());
    }
    b.extend_from_slice(tail.as_bytes());
    b
}

#[test]
fn m112_behind_a_hundred_unread_lines_acts_at_once() {
    let mut l = full_link();
    let first = LINE_QUEUE as u32 + 1;
    let bytes = burst(first, &numbered(first + 100, "M112"));
    assert!(bytes.len() < SCAN_WINDOW, "{} bytes", bytes.len());
    // Kill: every byte is taken and ignored, nothing answered (Marlin's kill()).
    assert_eq!(l.receive(&bytes), bytes.len());
    assert_eq!(l.take_realtime(), Some(Realtime::EmergencyStop));
    assert_eq!(l.stats().emergency_ahead, 1);
    assert!(l.is_halted());
    assert!(l.pop_line().is_none());
    assert_eq!(out(&mut l), "");
}

#[test]
fn m410_and_m108_ahead_act_once_and_are_answered_when_taken() {
    let mut l = full_link();
    let first = LINE_QUEUE as u32 + 1;
    let mut bytes = burst(first, &numbered(first + 100, "M410"));
    bytes.extend_from_slice(numbered(first + 101, "M108").as_bytes());
    bytes.extend_from_slice(b"M410\n");
    let mut pending = bytes.clone();
    let taken = l.receive(&pending);
    // An empty offer in between (a driver with nothing new) changes nothing.
    assert_eq!(l.receive(&[]), 0);
    assert!(taken < bytes.len(), "flow control holds the lines back");
    assert_eq!(l.take_realtime(), Some(Realtime::QuickStop));
    assert_eq!(l.take_realtime(), Some(Realtime::BreakWait));
    assert_eq!(l.take_realtime(), Some(Realtime::QuickStop));
    assert_eq!(l.take_realtime(), None);
    assert_eq!(l.stats().emergency_ahead, 3);
    // The executive takes the lines one by one; the bytes are offered again each time.
    pending.drain(..taken);
    let mut popped = 0;
    while !pending.is_empty() {
        while l.pop_line().is_some() {
            popped += 1;
            l.respond(Response::Ok);
        }
        let k = l.receive(&pending);
        pending.drain(..k);
        assert_eq!(l.take_realtime(), None, "acted twice");
    }
    while l.pop_line().is_some() {
        popped += 1;
        l.respond(Response::Ok);
    }
    assert_eq!(popped, LINE_QUEUE + 100);
    assert_eq!(l.last_line(), first + 101);
    // Every line answered once: the job lines, the three emergency lines.
    let o = out(&mut l);
    assert_eq!(o.lines().filter(|x| *x == "ok").count(), popped + 3, "{o}");
    assert!(!o.contains("Error"), "{o}");
}

#[test]
fn a_line_that_fails_its_checksum_does_not_act_ahead() {
    let mut l = full_link();
    let n = LINE_QUEUE as u32 + 1;
    let mut bytes = numbered(n, "G1 X9").into_bytes();
    bytes.extend_from_slice(format!("N{} M410*1\n", n + 1).as_bytes());
    bytes.extend_from_slice(b"M1125\n");
    let _ = l.receive(&bytes);
    assert_eq!(l.take_realtime(), None);
    assert_eq!(l.stats().emergency_ahead, 0);
}

#[test]
fn a_resent_emergency_line_does_not_act_again() {
    let mut l = full_link();
    let n = LINE_QUEUE as u32 + 1;
    // Line n lost on the way: the host got `Resend: n` and sends n, n+1 and n+2 again.
    let mut bytes = numbered(n + 1, "M410").into_bytes();
    bytes.extend_from_slice(numbered(n + 2, "M108").as_bytes());
    bytes.extend_from_slice(numbered(n, "G1 X9").as_bytes());
    bytes.extend_from_slice(numbered(n + 1, "M410").as_bytes());
    bytes.extend_from_slice(numbered(n + 2, "M108").as_bytes());
    let mut pending = bytes;
    let k = l.receive(&pending);
    pending.drain(..k);
    assert_eq!(l.take_realtime(), Some(Realtime::QuickStop));
    assert_eq!(l.take_realtime(), Some(Realtime::BreakWait));
    for _ in 0..8 {
        while l.pop_line().is_some() {
            l.respond(Response::Ok);
        }
        let k = l.receive(&pending);
        pending.drain(..k);
    }
    assert!(pending.is_empty());
    assert_eq!(l.take_realtime(), None);
    assert_eq!(l.last_line(), n + 2);
}

#[test]
fn a_control_byte_ahead_acts_once() {
    let mut l = full_link();
    let mut bytes = burst(LINE_QUEUE as u32 + 1, "");
    bytes.push(BYTE_QUICK_STOP);
    bytes.push(BYTE_CANCEL);
    let mut pending = bytes;
    let k = l.receive(&pending);
    pending.drain(..k);
    // The quick stop acts at once; the cancel (not an emergency request) when it is taken.
    assert_eq!(l.take_realtime(), Some(Realtime::QuickStop));
    assert_eq!(l.take_realtime(), None);
    while !pending.is_empty() {
        while l.pop_line().is_some() {
            l.respond(Response::Ok);
        }
        let k = l.receive(&pending);
        pending.drain(..k);
    }
    assert_eq!(l.take_realtime(), Some(Realtime::Cancel));
    assert_eq!(l.take_realtime(), None);
}

#[test]
fn a_driver_that_offers_other_bytes_does_not_lose_an_emergency_stop() {
    // Against the contract (the bytes not taken must be offered again, first): the scan
    // starts again, and what it did not judge acts when it is taken.
    let mut l = HostLink::new();
    for _ in 0..REALTIME_QUEUE {
        assert_eq!(l.receive(&[BYTE_RESUME]), 1);
    }
    // The realtime queue is full: nothing is taken, the line behind the byte is scanned.
    assert_eq!(l.receive(&[BYTE_RESUME, b'G', b'1', b'\n']), 0);
    while l.take_realtime().is_some() {}
    // Other bytes than those: the M112 still acts.
    assert_eq!(l.receive(b"M112\n"), 5);
    assert_eq!(l.take_realtime(), Some(Realtime::EmergencyStop));
}

#[test]
fn the_tft_port_drops_control_bytes_unless_configured() {
    let mut p = HostPorts::new();
    assert!(p.port(PortId::Usb).control_bytes());
    assert!(!p.port(PortId::Tft).control_bytes());
    // Noise on the display's cable: never a halt or a cancel, and the line it fell into is
    // whole.
    let noisy = [
        b"M1".as_slice(),
        &[BYTE_EMERGENCY_STOP, BYTE_CANCEL],
        b"05\n",
    ]
    .concat();
    assert_eq!(p.receive(PortId::Tft, &noisy), noisy.len());
    assert_eq!(p.take_realtime(), None);
    assert_eq!(
        p.pop_line().map(|l| l.text().to_vec()),
        Some(b"M105".to_vec())
    );
    assert_eq!(p.port(PortId::Tft).stats().controls_ignored, 2);
    // Configured: they act.
    p.set_control_bytes(PortId::Tft, true);
    assert_eq!(p.receive(PortId::Tft, &[BYTE_CANCEL]), 1);
    assert_eq!(p.take_realtime(), Some(Realtime::Cancel));
    // The setting outlives a new session on the port.
    p.reset_port(PortId::Tft);
    assert!(p.port(PortId::Tft).control_bytes());
    // The USB port by default.
    assert_eq!(p.receive(PortId::Usb, &[BYTE_EMERGENCY_STOP]), 1);
    assert_eq!(p.take_realtime(), Some(Realtime::EmergencyStop));
}

#[test]
fn the_spelled_out_requests_still_work_on_the_tft_port() {
    let mut p = HostPorts::new();
    assert_eq!(p.receive(PortId::Tft, b"M524\n"), 5);
    assert_eq!(p.take_realtime(), Some(Realtime::Cancel));
    assert_eq!(p.receive(PortId::Tft, b"M112\n"), 5);
    assert_eq!(p.take_realtime(), Some(Realtime::EmergencyStop));
}

/// One item a host writes: a job line, or an emergency line (numbered or not), or a control
/// byte.
#[derive(Clone, Debug)]
enum Item {
    Job,
    Emergency(u8, bool),
    Byte(u8),
}

fn item() -> impl Strategy<Value = Item> {
    prop_oneof![
        6 => Just(Item::Job),
        1 => (0u8..2, any::<bool>()).prop_map(|(k, n)| Item::Emergency(k, n)),
        1 => prop_oneof![Just(BYTE_QUICK_STOP), Just(BYTE_BREAK_WAIT), Just(BYTE_RESUME)]
            .prop_map(Item::Byte),
    ]
}

proptest! {
    /// Whatever the split of the bytes, however much of them the driver offers and however
    /// slowly the executive takes lines, every
    /// request acts exactly once — the emergency ones in the order written, the others in the
    /// order written (an emergency request may act before another written ahead of it: it is
    /// read ahead) — and every job line is handed out once, in order.
    #[test]
    fn every_request_acts_once_however_the_bytes_come(
        items in proptest::collection::vec(item(), 1..80),
        chunks in proptest::collection::vec(1usize..200, 1..8),
        pops in proptest::collection::vec(0usize..3, 1..8),
        offers in proptest::collection::vec(1usize..400, 1..8),
    ) {
        let mut bytes = StdVec::new();
        let mut want_rt = StdVec::new();
        let mut want_lines = StdVec::new();
        let mut n = 0u32;
        for it in &items {
            match it {
                Item::Job => {
                    n += 1;
                    let cmd = format!("G1 X{n}");
                    bytes.extend_from_slice(numbered(n, &cmd).as_bytes());
                    want_lines.push(cmd);
                }
                Item::Emergency(k, numbered_line) => {
                    let (cmd, rt) = if *k == 0 {
                        ("M410", Realtime::QuickStop)
                    } else {
                        ("M108", Realtime::BreakWait)
                    };
                    if *numbered_line {
                        n += 1;
                        bytes.extend_from_slice(numbered(n, cmd).as_bytes());
                    } else {
                        bytes.extend_from_slice(format!("{cmd}\n").as_bytes());
                    }
                    want_rt.push(rt);
                }
                Item::Byte(b) => {
                    bytes.push(*b);
                    want_rt.push(control_byte(*b).unwrap());
                }
            }
        }
        let mut l = HostLink::new();
        let mut got_rt = StdVec::new();
        let mut got_lines = StdVec::new();
        let mut pending = StdVec::new();
        let mut at = 0;
        for round in 0..100_000 {
            if at >= bytes.len() && pending.is_empty() {
                break;
            }
            let c = chunks[round % chunks.len()];
            let end = (at + c).min(bytes.len());
            pending.extend_from_slice(&bytes[at..end]);
            at = end;
            // The driver may offer less than it holds (a wire that delivers in pieces).
            let offer = pending.len().min(offers[round % offers.len()]);
            let k = l.receive(&pending[..offer]);
            pending.drain(..k);
            while let Some(rt) = l.take_realtime() {
                got_rt.push(rt);
            }
            // Now and then at least one line, so that the stream ends.
            for _ in 0..pops[round % pops.len()].max(usize::from(round % 7 == 0)) {
                if let Some(line) = l.pop_line() {
                    got_lines.push(String::from_utf8(line.text().to_vec()).unwrap());
                    l.respond(Response::Ok);
                }
            }
            let _ = out(&mut l);
        }
        while let Some(line) = l.pop_line() {
            got_lines.push(String::from_utf8(line.text().to_vec()).unwrap());
        }
        prop_assert!(pending.is_empty());
        prop_assert_eq!(got_lines, want_lines);
        let split = |v: &[Realtime]| -> (StdVec<Realtime>, StdVec<Realtime>) {
            v.iter().partition(|rt| super::scan::is_emergency(**rt))
        };
        prop_assert_eq!(split(&got_rt), split(&want_rt));
    }
}
