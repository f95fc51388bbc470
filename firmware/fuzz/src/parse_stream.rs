//! The `parse_stream` target: bytes through the whole front end.

use firmware::config::MachineConfig;
use firmware::gcode::parse_line;
use firmware::link::{HostLink, Response, LINE_CAP, LINE_QUEUE};
use firmware::machine::{Action, Interpreter};

/// The `parse_stream` target: arbitrary bytes through the whole front end (host link → parser →
/// emitter round trip → machine state and layer detection). The first byte picks the chunk
/// size. Panics when an invariant breaks: at most `LINE_QUEUE` lines waiting, no line over
/// `LINE_CAP`, emitted commands parse back to themselves, a refused line leaves the interpreter
/// unchanged, an arc ends exactly at the commanded position, output is ASCII.
pub fn run_parse_stream(data: &[u8]) {
    use std::fmt::Write;
    let cfg = MachineConfig::ENDER3;
    let mut link = HostLink::new();
    let mut it = Interpreter::new(&cfg);
    let chunk = usize::from(data.first().copied().unwrap_or(1)).max(1);
    for piece in data.chunks(chunk) {
        let _ = link.receive(piece);
        assert!(link.lines_waiting() <= LINE_QUEUE);
        while link.take_realtime().is_some() {}
        while let Some(line) = link.pop_line() {
            assert!(line.text().len() <= LINE_CAP);
            if let Ok(parsed) = parse_line(line.text()) {
                if let Some(cmd) = &parsed.command {
                    // Emit and parse again: the same command.
                    let mut s = String::new();
                    write!(s, "{cmd}").unwrap();
                    let again = parse_line(s.as_bytes()).map(|l| l.command);
                    assert_eq!(again, Ok(Some(cmd.clone())), "{s:?}");
                }
                let saved = it;
                match it.line(&parsed, &cfg) {
                    Err(_) => assert_eq!(it, saved),
                    Ok(step) => {
                        if let Action::Arc(arc) = step.action {
                            let end = arc.last().map(|r| r.target);
                            assert_eq!(end, Some(it.machine.position_steps(&cfg)));
                        }
                    }
                }
            }
            link.respond(Response::Ok);
        }
        let mut out = String::new();
        link.write_output(&mut out).unwrap();
        assert!(out.is_ascii());
    }
    // Every line of the raw input parses or errors cleanly too (file path of host tools).
    for l in data.split(|&b| b == b'\n') {
        let _ = parse_line(l);
    }
}
