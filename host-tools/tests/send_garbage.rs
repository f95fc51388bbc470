//! Bad input from the printer never crashes the sender: random bytes and random reply lines.

use std::io::{Read, Write};
use std::time::Duration;

use host_tools::job::sender::protocol::Response;
use host_tools::job::sender::{Options, Session, State};
use host_tools::job::Job;
use proptest::prelude::*;

struct Noise {
    data: Vec<u8>,
    at: usize,
    written: usize,
}

impl Read for Noise {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = buf.len().min(self.data.len() - self.at).min(37);
        buf[..n].copy_from_slice(&self.data[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

impl Write for Noise {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.written += buf.len();
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn job() -> Job {
    Job::from_gcode(
        "G28\nG90\nM82\n;LAYER_CHANGE\n;Z:0.2\nG1 Z0.2\nG1 X10 Y10 E1\n;LAYER_CHANGE\n;Z:0.4\nG1 Z0.4\nG1 X0 Y0 E2\nM84\n",
    )
    .expect("job")
}

fn reply() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("ok".to_string()),
        Just("Cap:PAUSE_AT_LAYER:1".to_string()),
        Just("//action:paused".to_string()),
        Just("//action:resumed".to_string()),
        Just("//action:pause".to_string()),
        Just("busy: processing".to_string()),
        "Resend: [0-9]{0,12}",
        "ok N[0-9]{0,12} T:[0-9.]{0,8} /[0-9./]{0,8} B:[-0-9.a-z]{0,6}",
        "[ -~]{0,80}",
    ]
}

proptest! {
    // 64 cases by default; `PROPTEST_CASES=5000` for a longer hunt.
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(64)
    ))]

    #[test]
    fn reply_lines_never_panic(s in "\\PC{0,200}") {
        let _ = Response::parse(&s);
    }

    /// Whatever the printer says, the sender never panics and never stalls silently: it writes
    /// (the connection probe at least) unless the printer's first words were a fatal error, and
    /// once the printer falls silent it ends with a message within the timeouts — or waits in
    /// a pause the printer announced, which is a wait for the user, not a stall.
    #[test]
    fn random_printer_output_never_panics(
        lines in proptest::collection::vec(reply(), 0..200),
        bytes in proptest::collection::vec(any::<u8>(), 0..400),
    ) {
        let mut data = lines.join("\n").into_bytes();
        data.extend(bytes);
        let port = Noise { data, at: 0, written: 0 };
        let mut s = Session::new(port, job(), Options::default());
        let mut i = 0u64;
        while i < 400 || s.port().at < s.port().data.len() {
            s.poll(Duration::from_millis(i * 7)).expect("in-memory port");
            let _ = s.drain_events();
            let _ = s.progress();
            i += 1;
        }
        let fatal_first = matches!(s.state(), State::Failed(m) if m.starts_with("printer error"));
        prop_assert!(
            s.port().written > 0 || fatal_first,
            "nothing written, state {:?}",
            s.state()
        );
        // The noise is over: let time run past every timeout.
        let quiet = Duration::from_millis(i * 7);
        for k in 1..=2_000u64 {
            s.poll(quiet + Duration::from_secs(k)).expect("in-memory port");
            let _ = s.drain_events();
        }
        prop_assert!(
            s.finished() || matches!(s.state(), State::Paused { .. }),
            "stalled in {:?} after the printer fell silent",
            s.state()
        );
    }
}
