//! A slicer-style G-code job through the host link: ok flow control, layer markers from
//! comments, realtime M25/M24 in the byte stream, modal state around the pause.
mod support;

use firmware::printer::Record;
use support::*;

/// The runs `parts`, one after the other, executed the same job blocks to the same positions as
/// `base`, and ended where it did.
fn assert_same_job(parts: &[&support::Run], base: &support::Run) {
    let executed: Vec<_> = parts
        .iter()
        .flat_map(|r| r.executed.iter().copied())
        .collect();
    let job_pos: Vec<_> = parts
        .iter()
        .flat_map(|r| r.job_pos.iter().copied())
        .collect();
    assert_eq!(executed, base.executed);
    assert_eq!(job_pos, base.job_pos);
    assert_eq!(parts.last().map(|r| r.end), Some(base.end));
}

fn job() -> Vec<String> {
    let mut v = vec![
        "M83".to_string(),
        "G28".to_string(),
        "G1 Z0.2 F600".to_string(),
        "G92 E0".to_string(),
    ];
    for layer in 0..3 {
        v.push(";LAYER_CHANGE".into());
        v.push(format!(";Z:{:.1}", 0.2 * (layer + 1) as f32));
        v.push(format!("G1 Z{:.1} F600", 0.2 * (layer + 1) as f32));
        v.push("G1 X20 Y20 F6000".into());
        v.push("G1 E0.8 F2400".into());
        for (x, y) in [(60, 20), (60, 60), (20, 60), (20, 20)] {
            v.push(format!("G1 X{x} Y{y} E1.33 F2400"));
        }
        v.push("G1 E-0.8 F2400".into());
    }
    v
}

#[test]
fn gcode_job_pause_resume_via_link() {
    let lines = job();
    let lines: Vec<&str> = lines.iter().map(|s| s.as_str()).collect();
    let base = run_gcode(&mut printer(), &lines, &[], 120_000_000);
    assert!(!base.executed.is_empty());
    assert!(!base.out.contains("Error"), "{}", base.out);
    let mut p = printer();
    let r = run_gcode(
        &mut p,
        &lines,
        &[(2_500_000, "M25\n"), (15_000_000, "M24\n")],
        120_000_000,
    );
    assert!(r.out.contains("//action:paused"), "{}", r.out);
    assert!(r.out.contains("//action:resumed"), "{}", r.out);
    assert_eq!(r.executed, base.executed);
    assert_eq!(r.job_pos, base.job_pos);
    assert_eq!(r.end, base.end);
    // Layer-mode stop: at a layer boundary, not mid-block.
    let stop = r.stop().expect("stopped");
    let (layer, mid) = (stop.layer, stop.mid_block);
    assert!(!mid);
    assert!(layer.is_some());
}

#[test]
fn reports_and_errors() {
    let mut p = printer();
    let r = run_gcode(
        &mut p,
        &["M105", "M114", "G1 X400", "M760", "M761 L3", "M761", "FOO"],
        &[],
        5_000_000,
    );
    assert!(r.out.contains("ok T:"), "{}", r.out);
    assert!(r.out.contains("Count X:"), "{}", r.out);
    assert!(
        r.out
            .contains("echo:refused: move outside the build volume")
            && !r.out.contains("Error:"),
        "{}",
        r.out
    );
    assert!(r.out.contains("M760 R2.00"), "{}", r.out);
    assert!(r.out.contains("pause scheduled at layer 3"), "{}", r.out);
}

#[test]
fn m600_in_the_job_pauses_there_and_resumes() {
    let lines = [
        "G28",
        "G1 Z0.2 F600",
        "G1 X20 Y20 F6000",
        "G1 X40 Y20 E1 F1800",
        "M600",
        "G1 X40 Y40 E2 F1800",
        "G1 X20 Y40 E3 F1800",
    ];
    let mut p = printer();
    let r = run_gcode(&mut p, &lines, &[], 60_000_000);
    assert_eq!(
        p.status().state,
        firmware::printer::State::Paused,
        "{}",
        r.out
    );
    assert_eq!(r.stop().map(|s| s.pos), Some([3200, 1600, 80, 93]));
    // Nothing after the M600 ran yet.
    assert!(r.executed.iter().all(|e| e.0 <= 4), "{:?}", r.executed);
    p.request(firmware::motion::Realtime::Resume, 70_000_000);
    let r2 = run_gcode(&mut p, &[], &[], 200_000_000);
    assert_eq!(r2.end, [1600, 3200, 80, 279]);
}

#[test]
fn layer_pause_during_start_heater_wait_then_homing() {
    // Cura-style start: heater wait, then G28; the pause arrives during the wait.
    let lines = [
        "M104 S200",
        "M109 S200",
        "G28",
        "G1 Z15 F6000",
        "G92 E0",
        ";LAYER:0",
        "G0 F3600 X50 Y50 Z0.3",
        "G1 F1800 X60 Y50 E1",
        "G1 X60 Y60 E2",
        ";LAYER:1",
        "G0 X50 Y50 Z0.5",
        "G1 X60 Y50 E3",
    ];
    let mut p = printer();
    let r = run_gcode(
        &mut p,
        &lines,
        &[(1_000_000, "M25\n"), (2_000_000, "M108\n")],
        60_000_000,
    );
    assert_eq!(
        p.status().state,
        firmware::printer::State::Paused,
        "{}",
        r.out
    );
    let stop = r.stop().expect("stopped");
    // Before the first layer (numbered 1: Cura's ;LAYER:0).
    assert_eq!(stop.layer, Some(1), "stopped at the first layer boundary");
    // The start code ran (homing, Z up 15 mm); the job's first layer did not.
    assert_eq!(stop.pos, [0, 0, 6000, 0]);
}

/// A job in relative coordinates: home, go to (20, 20), `G91` and `extra` lines, then `layers`
/// layers of `rows` zigzag rows (±10 mm in X, 1 mm up in Y, 0.4 mm of E) and a travel back.
fn relative_zigzag(extra: &[&str], layers: usize, rows: usize) -> Vec<String> {
    let mut v: Vec<String> = ["G28", "G1 Z0.2 F600", "G1 X20 Y20 F6000", "G91"]
        .iter()
        .chain(extra)
        .map(|l| l.to_string())
        .collect();
    for _ in 0..layers {
        v.push(";LAYER_CHANGE".into());
        v.push("G1 Z0.2 F600".into());
        for k in 0..rows {
            let dx = if k % 2 == 0 { 10 } else { -10 };
            v.push(format!("G1 X{dx} Y1 E0.4 F1800"));
        }
        v.push(format!("G1 Y-{rows} F6000"));
    }
    v
}

#[test]
fn job_lines_sent_while_paused_queue_behind_the_barrier() {
    // A long job in relative coordinates; the pause comes early, so most lines arrive while
    // the printer is pausing or paused and must keep their meaning.
    let v = relative_zigzag(&[], 4, 20);
    let lines: Vec<&str> = v.iter().map(|s| s.as_str()).collect();
    let base = run_gcode(&mut printer(), &lines, &[], 200_000_000);
    // First part, then a pause; the second part (fits the command queue) is sent while
    // parked; then resume and send the rest.
    let (first, rest) = lines.split_at(12);
    let (second, third) = rest.split_at(25);
    let mut p = printer();
    let r1 = run_gcode(&mut p, first, &[(500_000, "M25 S1\n")], 200_000_000);
    assert!(r1.out.contains("//action:paused"), "{}", r1.out);
    let r2 = run_gcode(&mut p, second, &[], 200_000_000);
    assert_eq!(p.status().state, firmware::printer::State::Paused);
    assert!(r2.executed.is_empty());
    p.request(firmware::motion::Realtime::Resume, 300_000_000);
    let r3 = run_gcode(&mut p, third, &[], 900_000_000);
    assert_same_job(&[&r1, &r3], &base);
}

#[test]
fn manual_policy_job_lines_during_the_return_keep_the_job_state() {
    use firmware::config::MachineConfig;
    use firmware::printer::{PausedLines, Policy, Printer};
    // Relative coordinates, so a line interpreted in the wrong (parked) state lands elsewhere.
    let v = relative_zigzag(&["M83"], 3, 16);
    let lines: Vec<&str> = v.iter().map(|s| s.as_str()).collect();
    let manual = Policy {
        paused_lines: PausedLines::Manual,
        ..Policy::FIRMWARE
    };
    let base = run_gcode(
        &mut Printer::with_policy(MachineConfig::ENDER3, manual),
        &lines,
        &[],
        300_000_000,
    );
    let (first, rest) = lines.split_at(14);
    let mut p = Printer::with_policy(MachineConfig::ENDER3, manual);
    let r1 = run_gcode(&mut p, first, &[(600_000, "M25 S1\n")], 200_000_000);
    assert!(r1.out.contains("//action:paused"), "{}", r1.out);
    // While parked the host jogs and purges (manual commands, relative).
    let r2 = run_gcode(&mut p, &["G1 X-5 Z3 F3000", "G1 E3 F300"], &[], 200_000_000);
    assert!(!r2.out.contains("Error"), "{}", r2.out);
    assert_eq!(p.status().state, firmware::printer::State::Paused);
    // Resume, and stream the rest at once: these lines arrive while the head returns.
    p.request(firmware::motion::Realtime::Resume, 210_000_000);
    let r3 = run_gcode(&mut p, rest, &[], 900_000_000);
    assert!(!r3.out.contains("Error"), "{}", r3.out);
    assert_same_job(&[&r1, &r3], &base);
}

#[test]
fn m400_is_answered_when_the_moves_before_it_have_ended() {
    let mut p = printer();
    let mut out = String::new();
    assert_eq!(p.receive(b"G1 X100 F3000\n", 0), 14);
    let _ = p.write_output(&mut out);
    assert_eq!(out, "ok\n");
    out.clear();
    assert_eq!(p.receive(b"M400\nM105\n", 1000), 10);
    p.poll(1000);
    let _ = p.write_output(&mut out);
    assert_eq!(out, "", "M400 answered before the move ran");
    // Run the move (100 mm at 50 mm/s: about 2 s), polling like the main loop.
    let mut now = 1000u64;
    let mut ok_at = None;
    let mut busy = 0;
    while now < 10_000_000 && ok_at.is_none() {
        while let Some(t) = p.next_step_ns() {
            if t > now * 1000 {
                break;
            }
            let _ = p.next_step();
        }
        p.poll(now);
        out.clear();
        let _ = p.write_output(&mut out);
        busy += out.matches("busy:").count();
        if out.contains("ok") {
            ok_at = Some(now);
            // The line behind M400 is taken only after it: `ok` then `ok T:`.
            assert!(
                out.starts_with("busy: processing\n") || out.starts_with("ok\n"),
                "{out}"
            );
        }
        now += 1000;
    }
    let ok_at = ok_at.expect("M400 answered");
    assert!(
        ok_at >= 1_900_000,
        "answered at {ok_at} µs, before the move ended"
    );
    assert_eq!(p.status().position[0], 8000);
    assert!(busy >= 1, "no busy: keep-alive while M400 waited 2 s");
    // Next line (M105) taken after the M400's ok.
    let mut rest = String::new();
    p.poll(now);
    let _ = p.write_output(&mut rest);
    let all = format!("{out}{rest}");
    assert!(all.contains("ok T:"), "{all}");
}

#[test]
fn homing_waits_until_the_last_segment_has_run() {
    // G28 acts on an idle machine only (its move starts from where the head is): the last
    // segment of the move before it must have run first, whatever the timing of the step
    // generator's block loads. Homing X must leave Y where the job put it.
    let mut p = printer();
    let lines = ["G1 X100 Y50 F3000", "G28 X"];
    let mut next = 0;
    let mut waiting = false;
    let mut y_steps = 0i64;
    let mut now = 0u64;
    while now < 20_000_000 {
        if !waiting && next < lines.len() {
            let l = format!("{}\n", lines[next]);
            assert_eq!(p.receive(l.as_bytes(), now), l.len());
            next += 1;
            waiting = true;
        }
        p.poll(now);
        while let Some(t) = p.next_step_ns() {
            if t > now * 1000 {
                break;
            }
            if let Some(ev) = p.next_step() {
                if ev.axis_mask & 2 != 0 {
                    y_steps += if ev.dir_mask & 2 != 0 { 1 } else { -1 };
                }
            }
        }
        let mut out = String::new();
        let _ = p.write_output(&mut out);
        if out.contains("ok") {
            waiting = false;
        }
        now += 1000;
    }
    assert_eq!(y_steps, 4000, "Y moved back by the homing move");
    assert_eq!(p.status().position[..2], [0, 4000]);
}

#[test]
fn layer_pause_at_a_boundary_the_host_drained_with_m400_parks_there() {
    // The sender's layer gate: the layer's marker comments, then M400; when its `ok` comes
    // (motion ended) it sends M25. The idle printer is still in the job: it stops at this
    // boundary at once and parks.
    let lines = [
        "G28",
        ";LAYER_CHANGE",
        ";Z:0.2",
        "G1 Z0.2 F600",
        "G1 X20 Y20 F6000",
        "G1 X60 Y20 E2 F2400",
        ";LAYER_CHANGE",
        ";Z:0.4",
        "M400",
    ];
    let mut p = printer();
    let r = run_gcode(&mut p, &lines, &[], 60_000_000);
    assert_eq!(p.status().state, firmware::printer::State::Idle);
    let t = r.end_us;
    let r2 = run_gcode(&mut p, &[], &[(t, "M25\n")], 120_000_000);
    assert!(r2.out.contains("//action:paused"), "{}", r2.out);
    assert_eq!(
        r2.stop(),
        Some(Stop {
            pos: r.end,
            layer: Some(2),
            mid_block: false
        })
    );
    // Much later, with nothing queued or moving, there is nothing to pause.
    p.request(firmware::motion::Realtime::Resume, 200_000_000);
    let r3 = run_gcode(&mut p, &["G1 X20 Y40 Z0.4 E3"], &[], 260_000_000);
    assert!(r3.out.contains("//action:resumed"), "{}", r3.out);
    let mut q = String::new();
    p.request(
        firmware::motion::Realtime::Pause(firmware::motion::PauseMode::Layer),
        300_000_000,
    );
    let _ = p.write_output(&mut q);
    assert!(q.contains("nothing to pause"), "{q}");
}

#[test]
fn layer_pause_when_the_host_stops_after_a_marker_reports_that_layer() {
    // No M400: the host sent the layer's marker comments and stopped streaming. After the
    // idle time the stop is at that boundary, before layer 2.
    let lines = [
        ";LAYER_CHANGE",
        ";Z:0.2",
        "G1 Z0.2 F600",
        "G1 X20 Y20 F6000",
        "G1 X60 Y20 E2 F2400",
        ";LAYER_CHANGE",
        ";Z:0.4",
    ];
    let mut p = printer();
    let r = run_gcode(&mut p, &lines, &[(300_000, "M25\n")], 60_000_000);
    assert!(r.out.contains("//action:paused"), "{}", r.out);
    let stop = r.stop().map(|s| (s.layer, s.mid_block));
    assert_eq!(stop, Some((Some(2), false)));
    // The resumed job's next move gets no second mark for the same layer.
    p.request(firmware::motion::Realtime::Resume, 100_000_000);
    let r2 = run_gcode(&mut p, &["G1 X20 Y40 Z0.4 E3"], &[], 200_000_000);
    let marks = r2
        .records
        .iter()
        .filter(|x| matches!(x, Record::Layer { .. }))
        .count();
    assert_eq!(marks, 1, "{:?}", r2.records);
}
