//! The image's USB port on the emulated board (docs/board-emu.md, "USB"): enumeration by the
//! emulated host, CDC ACM with DTR sessions, a job over USB with the slicer's layer comments
//! kept (the markers reach the image), and the cable pulled and plugged in again.

mod support;

use board_emu::scenario::HostPort;
use support::*;

#[test]
fn a_job_over_usb_with_its_comments_pauses_at_the_marker_of_its_layer() {
    let job: Vec<String> = THREE_LAYERS.iter().map(|s| s.to_string()).collect();
    // `sim run` on the same lines, comments kept: the same library on virtual time.
    let mut sc = sim::run::Scenario::new(sim::run::Policy::Firmware, sim::run::Mode::Layer);
    sc.pause = Some(sim::run::PauseWhen::AtLayer(2));
    sc.resume_after_us = Some(1_000_000);
    sc.link.strip_comments = false;
    let out = sim::run::run(&sim::exec::PrinterFactory, &sc, &job).expect("sim runs");
    let sim_stop = out.report.pause_point_steps.expect("sim paused");

    let mut o = options();
    o.port = HostPort::Usb;
    o.keep_comments = true;
    o.job = job;
    o.pause_at_layer = Some(2);
    let r = run(&o);
    let usb = r.usb.as_ref().expect("the USB report");
    let dev = usb.device.as_ref().expect("enumerated");
    assert_eq!(dev.vid_pid, (0x0483, 0x5740), "{usb:?}");
    assert_eq!(
        dev.strings,
        vec!["pause firmware", "SKR 2 printer", "skr2"],
        "{usb:?}"
    );
    assert!(
        usb.configured && usb.dtr && usb.errors.is_empty(),
        "{usb:?}"
    );
    assert!(r.m115.is_some(), "M115 answered over USB: {:?}", r.lines);

    let got = r.pause_point_net_steps.expect("paused and parked");
    let stops = layerref_stops(THREE_LAYERS, 2, layerref::Comments::Keep);
    assert!(
        stops.contains(&got),
        "the park began at {got:?}, layerref's boundary of layer 2 (at its marker) is {stops:?}"
    );
    // Kept comments: the barrier is the marker, before layer 2's Z move; stripped, it is
    // after it (the first extrusion): the two differ, so the markers did reach the image.
    assert_ne!(
        got[2],
        expected_net_steps(&THREE_LAYERS[..14], START_MM)[2],
        "stopped after layer 2's Z move: the marker was not seen"
    );
    let want: Vec<i64> = sim_stop.iter().map(|&v| i64::from(v)).collect();
    assert_eq!(
        r.pause_point_steps.map(|p| p.to_vec()),
        Some(want),
        "emulated vs sim run (comments kept)"
    );
    // Resumed and finished: every step of the job.
    assert_eq!(net_steps(&r), expected_net_steps(THREE_LAYERS, START_MM));
}

#[test]
#[ignore = "CI's time: the same path as hosts.rs' OctoPrint reconnect, which runs in CI; `cargo test -p board-emu --test usb -- --include-ignored`"]
fn a_host_that_closes_the_port_while_paused_and_opens_it_again_sees_the_held_job() {
    let mut o = options();
    o.port = HostPort::Usb;
    o.commands = vec![
        "M302 P1".into(),
        "G28".into(),
        "G1 X100 F1200".into(),
        "M25 S1".into(),
        "@until //action:paused".into(),
        // The program closes the port: DTR drops, the job's host went away.
        "@close".into(),
        "@wait 300".into(),
        "@open".into(),
        "@until paused: job held".into(),
        "M524".into(),
    ];
    o.max_virtual_s = 40.0;
    let r = run(&o);
    let usb = r.usb.as_ref().expect("USB report");
    let dtr: Vec<&str> = usb
        .events
        .iter()
        .map(|(_, e)| e.as_str())
        .filter(|e| e.starts_with("DTR"))
        .collect();
    assert_eq!(
        dtr,
        ["DTR raised", "DTR dropped", "DTR raised"],
        "{:?}",
        usb.events
    );
    let held = r
        .lines
        .iter()
        .position(|l| l.contains("paused: job held"))
        .expect("the held job told to the new session");
    assert!(
        r.lines[held].contains("M524 ends it"),
        "orphaned: {}",
        r.lines[held]
    );
    assert!(
        r.lines[held..].iter().any(|l| l == "//action:paused"),
        "{:?}",
        &r.lines[held..]
    );
    assert!(
        r.lines[held..]
            .iter()
            .any(|l| l.contains("//action:cancel") || l.contains("cancel")),
        "M524 ended it: {:?}",
        &r.lines[held..]
    );
}

#[test]
fn the_cable_pulled_and_plugged_in_again_enumerates_again_and_the_port_answers() {
    let mut o = options();
    o.port = HostPort::Usb;
    o.commands = vec![
        "M105".into(),
        "@unplug".into(),
        "@wait 200".into(),
        "@plug".into(),
        "M115".into(),
    ];
    o.max_virtual_s = 10.0;
    let r = run(&o);
    let usb = r.usb.as_ref().expect("USB report");
    assert_eq!(usb.stats.enumerations, 2, "{:?}", usb.events);
    assert!(usb.stats.resets >= 2, "{:?}", usb.stats);
    let plugged = usb
        .events
        .iter()
        .find(|(_, e)| e == "plugged in")
        .map(|(t, _)| *t)
        .expect("plugged in again");
    let t_m115 = r
        .lines
        .iter()
        .zip(&r.line_times_s)
        .find(|(l, _)| l.contains("FIRMWARE_NAME"))
        .map(|(_, t)| *t)
        .expect("M115 answered after the plug");
    assert!(t_m115 > plugged, "{t_m115} after {plugged}");
    assert!(usb.errors.is_empty(), "{:?}", usb.errors);
}
