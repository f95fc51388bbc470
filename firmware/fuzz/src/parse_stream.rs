//! The `parse_stream` target: bytes through the whole front end.

use firmware::config::MachineConfig;
use firmware::gcode::MotionCommand;
use firmware::gcode::{
    parse_line, Command, MAX_ABS_VALUE, MAX_NUMBER_LEN, MAX_SIG_DIGITS, MIN_ABS_VALUE,
};
use firmware::link::{HostLink, ReceivedLine, Response, LINE_CAP, LINE_QUEUE};
use firmware::machine::{Action, Interpreter};

/// The `parse_stream` target: arbitrary bytes through the whole front end (host link → parser →
/// emitter round trip → machine state and layer detection). The first byte picks the chunk
/// size. Panics when an invariant breaks: at most `LINE_QUEUE` lines waiting, no line over
/// `LINE_CAP`, emitted commands parse back to themselves, a refused line leaves the interpreter
/// unchanged, an arc ends exactly at the commanded position, output is ASCII, every bytes is
/// taken in the end (the link's flow control: the bytes not taken are offered again, first),
/// and every number-like token reads as core's `str::parse` reads it (exponents included) or
/// is refused.
pub fn run_parse_stream(data: &[u8]) {
    let cfg = MachineConfig::ENDER3;
    let mut link = HostLink::new();
    let mut it = Interpreter::new(&cfg);
    let chunk = usize::from(data.first().copied().unwrap_or(1)).max(1);
    let mut pending: Vec<u8> = Vec::new();
    for piece in data.chunks(chunk) {
        pending.extend_from_slice(piece);
        // As a driver does: offer what is not taken again while the link takes some.
        loop {
            let k = link.receive(&pending);
            pending.drain(..k);
            assert!(link.lines_waiting() <= LINE_QUEUE);
            while link.take_realtime().is_some() {}
            while let Some(line) = link.pop_line() {
                check_line(&line, &mut it, &cfg);
                link.respond(Response::Ok);
            }
            let mut out = String::new();
            link.write_output(&mut out).unwrap();
            assert!(out.is_ascii());
            if k == 0 || pending.is_empty() {
                break;
            }
        }
    }
    // Each line is popped as soon as it is there: everything is taken (or swallowed after a
    // halt).
    assert!(
        pending.is_empty() || link.is_halted(),
        "{} bytes never taken",
        pending.len()
    );
    // Every line of the raw input parses or errors cleanly too (file path of host tools).
    for l in data.split(|&b| b == b'\n') {
        let _ = parse_line(l);
    }
    for token in data.split(|b| !matches!(b, b'0'..=b'9' | b'.' | b'e' | b'E' | b'+' | b'-')) {
        check_number(token);
    }
}

/// One line the link handed out: parse, emit and parse again, interpret.
fn check_line(line: &ReceivedLine, it: &mut Interpreter, cfg: &MachineConfig) {
    use std::fmt::Write;
    assert!(line.text().len() <= LINE_CAP);
    let Ok(parsed) = parse_line(line.text()) else {
        return;
    };
    if let Some(cmd) = &parsed.command {
        // Emit and parse again: the same command.
        let mut s = String::new();
        write!(s, "{cmd}").unwrap();
        let again = parse_line(s.as_bytes()).map(|l| l.command);
        assert_eq!(again, Ok(Some(cmd.clone())), "{s:?}");
    }
    let saved = *it;
    match it.line(&parsed, cfg) {
        Err(_) => assert_eq!(*it, saved),
        Ok(step) => {
            if let Action::Arc(arc) = step.action {
                let end = arc.last().map(|r| r.target);
                assert_eq!(end, Some(it.machine.position_steps(cfg)));
            }
        }
    }
}

/// A number-like token as a `G4 P` value: the value core's correctly rounded `str::parse`
/// gives, or refused — refused exactly when that value is out of range or the text has more
/// digits than the parser keeps (never read as a number and an extra word).
fn check_number(token: &[u8]) {
    let Ok(text) = std::str::from_utf8(token) else {
        return;
    };
    if text.is_empty() || text.len() > MAX_NUMBER_LEN {
        return;
    }
    let line = format!("G4 P{text}");
    let ours = parse_line(line.as_bytes()).map(|l| l.command);
    let core = text.parse::<f32>();
    let mantissa = text.split(['e', 'E']).next().unwrap_or("");
    let significant = mantissa
        .trim_start_matches(['+', '-'])
        .replace('.', "")
        .trim_start_matches('0')
        .len();
    match (ours, core.clone()) {
        (
            Ok(Some(Command::Motion(MotionCommand::Dwell {
                ms: Some(v),
                s: None,
            }))),
            Ok(want),
        ) => {
            assert_eq!(v.to_bits(), want.to_bits(), "{text}");
        }
        (Ok(c), _) => panic!("{text}: read as {c:?}, core: {core:?}"),
        (Err(e), Ok(want)) => {
            let m = want.abs();
            // Zero only when written as zero: `1e-51` rounds to 0 in `f32` but is a non-zero
            // value below the smallest accepted (refused, as documented).
            let zero = !mantissa.bytes().any(|b| matches!(b, b'1'..=b'9'));
            let in_range = (m == 0.0 && zero) || (MIN_ABS_VALUE..=MAX_ABS_VALUE).contains(&m);
            // Core takes any digit count and `inf`-free forms the parser refuses as too long.
            let too_many = significant > usize::from(MAX_SIG_DIGITS);
            assert!(
                !in_range || too_many,
                "{text}: refused ({e}) though core reads {want}"
            );
        }
        (Err(_), Err(_)) => {}
    }
}
