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
            // The job extrudes without heating (no heater lines): as M302 P1 allows.
            allow_cold_extrusion: true,
            tft: false,
            tft_control_bytes: false,
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

/// Issue 24 over the pty: the conventional-firmware model (`--policy fifo`), `G1 X1` and
/// `G1 X2` in one write, then `M25 S1` as soon as both are taken. It used to stand at X1 for ever (never parked,
/// M24 "pause withdrawn", M400 `busy: processing`); now the pause runs the queued moves, parks,
/// resumes, and M400/M114 answer with the head at X2.
#[test]
fn the_fifo_model_parks_and_resumes_a_pause_now_behind_two_moves() {
    let (server, mut host) = serve_in_thread(
        ServeArgs {
            speed: 20.0,
            record: None,
            policy: Policy::Fifo,
            exit_after_idle: 1.0,
            link: None,
            flash: None,
            machine: None,
            trace: None,
            sd: None,
            allow_cold_extrusion: false,
            tft: false,
            tft_control_bytes: false,
            host_paced: false,
        },
        Duration::from_secs(10),
    );
    // As the user typed them: both lines taken, then the request at once, while the
    // first move runs (1 s virtual at 1 mm/s, 50 ms real at --speed 20; the two join at
    // speed, as the did).
    host.write("G1 X1 F60\nG1 X2");
    host.ok(WAIT);
    host.ok(WAIT);
    host.write("M25 S1");
    host.until("//action:paused", WAIT, |l| l.contains("//action:paused"));
    host.write("M24");
    host.until("//action:resumed", WAIT, |l| l.contains("//action:resumed"));
    host.write("M400");
    host.write("M114");
    let pos = host.until("M114's answer", WAIT, |l| l.starts_with("X:"));
    assert!(pos.contains("X:2.00"), "{pos}");
    assert!(
        !host.seen.iter().any(|l| l.contains("pause withdrawn")),
        "{:?}",
        host.seen
    );
    server.record().expect("session record");
}

/// Issue 31 over the pty: a host that does not wait for `ok` writes 100 job lines and then
/// `M112` in one go. The firmware's emergency scan reads the M112 in the bytes the sim holds
/// for it (it keeps reading the device while fewer than `SCAN_WINDOW` bytes wait), so the
/// printer halts before the lines ahead of it have run: only the lines that fitted the queue
/// were answered (before: all 100 `ok`s, 75 s of moves, then the halt).
#[test]
fn m112_written_behind_a_hundred_lines_halts_before_they_run() {
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
            allow_cold_extrusion: true,
            tft: false,
            tft_control_bytes: false,
            host_paced: false,
        },
        Duration::from_secs(10),
    );
    host.write("M110 N0");
    host.ok(WAIT);
    let mut text = String::new();
    for n in 1..=100u32 {
        let x = if n % 2 == 0 { 10 } else { 110 };
        let pre = format!("N{n} G1 X{x} Y{} F1800", 20 + n);
        text.push_str(&format!("{pre}*{}\n", tests::pty::checksum(&pre)));
    }
    let pre = "N101 M112";
    text.push_str(&format!("{pre}*{}", tests::pty::checksum(pre)));
    assert!(text.len() < firmware::link::SCAN_WINDOW);
    host.write(&text);
    host.until("the halt", WAIT, |l| l.contains("kill() called!"));
    let oks = host.seen.iter().filter(|l| l.starts_with("ok")).count();
    assert!(
        oks < 50,
        "{oks} lines answered before the halt: {:?}",
        host.seen
    );
    drop(host);
    let record = server.record().expect("serve session");
    let s = &record.session;
    assert!(s.moves_executed < 50, "{s:#?}");
}

/// Issue 31: `--speed 1e-300` was accepted (a clock that never moves); outside
/// 0.001..=1000000 the session is refused before the pseudo-terminal opens.
#[test]
fn nonsense_speeds_are_refused() {
    for speed in [1e-300, 0.0, -1.0, f64::NAN, f64::INFINITY, 2e6] {
        let args = ServeArgs {
            speed,
            record: None,
            policy: Policy::Firmware,
            exit_after_idle: 1.0,
            link: None,
            flash: None,
            machine: None,
            trace: None,
            sd: None,
            allow_cold_extrusion: false,
            tft: false,
            tft_control_bytes: false,
            host_paced: false,
        };
        let err = sim::serve::serve_ports(args, |_| panic!("opened at --speed {speed}"))
            .expect_err("refused");
        assert!(format!("{err}").contains("--speed"), "{err}");
    }
}

/// Issue 31 over the two ptys (`sim serve --tft`): bytes of noise on the TFT's wire (0x18 and
/// 0x03 inside a display's `M105`) neither halt nor cancel the USB host's move, and the M105
/// around them is answered; with `--tft-control-bytes` the same 0x18 halts.
#[test]
fn noise_on_the_tft_pty_neither_halts_nor_cancels() {
    for chosen in [false, true] {
        let args = ServeArgs {
            speed: 20.0,
            record: None,
            policy: Policy::Firmware,
            exit_after_idle: 1.0,
            link: None,
            flash: None,
            machine: None,
            trace: None,
            sd: None,
            allow_cold_extrusion: true,
            tft: true,
            tft_control_bytes: chosen,
            host_paced: false,
        };
        let (tx, rx) = std::sync::mpsc::channel();
        let server = std::thread::spawn(move || {
            sim::serve::serve_ports(args, move |paths| {
                let _ = tx.send(paths.to_vec());
            })
            .map_err(|e| format!("{e:#}"))
        });
        let paths = rx
            .recv_timeout(Duration::from_secs(10))
            .expect("sim serve printed no device paths");
        let mut usb = tests::pty::PtyHost::open(&paths[0]);
        let mut tft = tests::pty::PtyHost::open(&paths[1]);
        usb.write("G1 X100 F1800");
        usb.ok(WAIT);
        tft.write("M1\u{18}\u{3}05");
        if chosen {
            tft.until("the halt", WAIT, |l| l.contains("kill() called!"));
        } else {
            tft.until("M105's answer", WAIT, |l| l.starts_with("ok T:"));
            usb.write("M400");
            usb.ok(WAIT);
            usb.write("M114");
            let pos = usb.until("M114's answer", WAIT, |l| l.starts_with("X:"));
            assert!(pos.contains("X:100.00"), "{pos}");
            let all = [&usb.seen[..], &tft.seen[..]].concat();
            assert!(
                !all.iter()
                    .any(|l| l.contains("kill()") || l.contains("cancel")),
                "{all:?}"
            );
        }
        drop((usb, tft));
        let record = server.join().expect("serve thread").expect("serve session");
        assert!(!record.session.cancelled, "{:#?}", record.session);
    }
}
