//! Pieces the sender tests share: the byte glue of an in-memory printer (lines in, replies
//! out) and the loop that runs a session to its end.
#![allow(dead_code)]

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::time::Duration;

use host_tools::job::sender::Session;

/// Append written bytes to `inbuf` and return the lines they complete (without the `\n`); a
/// partial line stays in `inbuf` for the next write.
pub fn complete_lines(inbuf: &mut Vec<u8>, buf: &[u8]) -> Vec<String> {
    let mut lines = Vec::new();
    for &b in buf {
        if b == b'\n' {
            lines.push(String::from_utf8_lossy(inbuf).into_owned());
            inbuf.clear();
        } else {
            inbuf.push(b);
        }
    }
    lines
}

/// Hand the sender at most `chunk` bytes of the printer's pending output (a serial port
/// delivers replies in pieces); returns how many.
pub fn read_replies(out: &mut VecDeque<u8>, buf: &mut [u8], chunk: usize) -> usize {
    let n = buf.len().min(out.len()).min(chunk);
    for b in buf.iter_mut().take(n) {
        *b = out.pop_front().unwrap_or(b'\n');
    }
    n
}

/// Poll every 100 ms of virtual time until the session ends or `limit` passes.
pub fn run_to_end<P: Read + Write>(s: &mut Session<P>, limit: Duration) {
    let mut now = Duration::ZERO;
    while !s.finished() && now < limit {
        s.poll(now).expect("in-memory port");
        let _ = s.drain_events();
        now += Duration::from_millis(100);
    }
}
