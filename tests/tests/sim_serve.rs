//! `sim serve` as a host sees it: open the pseudo-terminal, speak printcore's protocol (line
//! numbers, checksums, `ok` flow control, a resend), send a realtime pause, wait for
//! `//action:paused`, resume, and see the job complete; then check the session's pause record.

use sim::run::Policy;
use sim::serve::ServeArgs;
use std::time::Duration;
use tests::pty::serve_in_thread;

/// How long the host waits for any one answer.
const WAIT: Duration = Duration::from_secs(60);

#[test]
fn a_host_prints_pauses_and_resumes_over_the_pseudo_terminal() {
    let (server, mut host) = serve_in_thread(
        ServeArgs {
            speed: 20.0,
            record: None,
            policy: Policy::Firmware,
            exit_after_idle: 1.0,
            link: None,
            flash: None,
            machine: None,
            trace: None,
            sd: None,
            tft: false,
            host_paced: false,
        },
        Duration::from_secs(10),
    );

    host.write("M110 N0");
    host.ok(WAIT);
    // A line with a wrong checksum is asked for again.
    host.write("N1 G90*0");
    let resend = host.until("Resend", WAIT, |l| l.starts_with("Resend:"));
    assert!(resend.contains('1'), "{resend}");
    host.ok(WAIT);

    let mut job = vec![
        "G90".to_string(),
        "M83".into(),
        "G92 X10 Y10 Z0.2 E0".into(),
    ];
    for i in 0..24 {
        let x = if i % 2 == 0 { 60 } else { 10 };
        job.push(format!("G1 X{x} Y{} E1.5 F1800", 10 + i));
    }
    let mut n = 1;
    for (i, line) in job.iter().enumerate() {
        host.send_numbered(n, line);
        n += 1;
        host.ok(WAIT);
        if i == 8 {
            // Realtime pause: unnumbered, written at once.
            host.write("M25 S1");
            host.until("//action:paused", WAIT, |l| l.contains("//action:paused"));
            host.write("M24");
            host.until("//action:resume", WAIT, |l| l.contains("//action:resume"));
        }
    }
    // M400 is answered once every move has run: the job completed.
    host.send_numbered(n, "M400");
    host.ok(WAIT);
    drop(host);

    let record = server.record().expect("serve session");
    let s = &record.session;
    assert!(s.finished && !s.cancelled, "{s:#?}");
    assert_eq!(s.lost_moves + s.duplicated_moves, 0, "{s:#?}");
    assert!(s.moves_executed >= 24, "{s:#?}");
    // M110, the bad line, its resend, the job and M400, plus the realtime M25 S1 and M24.
    assert!(s.lines_received >= job.len() as u64 + 4, "{s:#?}");
    let reports = record.pauses;
    assert_eq!(reports.len(), 1, "{reports:#?}");
    let r = &reports[0];
    assert_eq!(r.mode, "now");
    assert!(r.stop_s.is_some_and(|s| s < 0.2), "{r:#?}");
    assert_eq!(r.resume_position_error_steps, Some(0), "{r:#?}");
    assert_eq!(r.lost_moves + r.duplicated_moves, 0, "{r:#?}");
    assert!(r.finished, "{r:#?}");
}
