//! The paused-job record: a layer pause of a numbered host stream parks at a boundary, the
//! record kept in flash names the line to restart from, the boundary position, the modal state
//! and the temperatures; resuming clears it. The expected values are worked out here from the
//! G-code text itself, not from the firmware's interpretation of it.

use firmware::config::MachineConfig;
use firmware::motion::{PauseMode, Realtime};
use firmware::printer::{Policy, Printer, State};
use firmware::storage::{JobSource, NorFlashModel, RecordStore, SettingsStore};

type Flash = NorFlashModel<Vec<u8>, 16, 4096>;

fn checksum(s: &str) -> u8 {
    s.bytes().fold(0, |a, b| a ^ b)
}

/// The job: three layers of squares, Cura markers (`;LAYER:0` is layer 1). Returns (lines
/// without numbers, index of the first motion line after `;LAYER:1`, the end of layer 1 in mm
/// X Y Z E).
fn job() -> (Vec<String>, usize, [f32; 4]) {
    let mut v: Vec<String> = ["G28", "M83", "M104 S205", "M140 S60", "M106 S128", "G92 E0"]
        .map(String::from)
        .to_vec();
    let mut end = [0.0f32; 4];
    let mut first_after = 0;
    let mut e_total = 0.0;
    for layer in 0..3 {
        v.push(format!(";LAYER:{layer}"));
        let z = 0.2 * (layer + 1) as f32;
        if layer == 1 {
            first_after = v.len();
        }
        v.push(format!("G1 Z{z:.1} F600"));
        v.push("G1 F1800".into());
        for i in 0..12 {
            let (x, y) = [(20.0, 20.0), (60.0, 20.0), (60.0, 60.0), (20.0, 60.0)][i % 4];
            v.push(format!("G1 X{x} Y{y} E1.25"));
            if layer == 0 {
                e_total += 1.25;
                end = [x, y, z, e_total];
            }
        }
    }
    (v, first_after, end)
}

#[test]
fn a_layer_pause_keeps_the_job_and_a_resume_forgets_it() {
    let cfg = MachineConfig::ENDER3;
    let mut p = Printer::with_policy(cfg, Policy::FIRMWARE);
    // No heater model here: extrude cold, as M302 P1.
    p.extrusion_guard_mut().allow_cold = true;
    let mut store = SettingsStore::new(Flash::erased(vec![0; 8192]), 0..8192).unwrap();
    p.load_settings(&mut store);
    let (lines, first_after, end) = job();
    let mut out = String::new();
    let mut now = 0u64;
    let mut next = 0usize;
    let mut waiting = false;
    let mut requested = false;
    let tick = |p: &mut Printer, store: &mut SettingsStore<Flash>, now: &mut u64| {
        let t_ns = *now * 1000;
        while let Some(t) = p.next_step_ns() {
            if t > t_ns {
                break;
            }
            p.next_step();
        }
        p.poll(*now);
        p.service_store(store);
        *now += 1000;
        let mut s = String::new();
        p.write_output(&mut s).unwrap();
        s
    };
    // Stream with ok flow; ask for a layer pause during layer 1.
    for _ in 0..200_000 {
        if !waiting && next < lines.len() {
            let body = format!("N{} {}", next + 1, lines[next]);
            let l = format!("{body}*{}\n", checksum(&body));
            assert_eq!(
                p.receive(l.as_bytes(), now),
                l.len(),
                "one line per ok is taken"
            );
            next += 1;
            waiting = true;
        }
        if !requested && next > 12 {
            p.request(Realtime::Pause(PauseMode::Layer), now);
            requested = true;
        }
        let s = tick(&mut p, &mut store, &mut now);
        if s.lines().any(|l| l.starts_with("ok")) {
            waiting = false;
        }
        out.push_str(&s);
        if p.status().state == State::Paused && !p.store_request_pending() {
            break;
        }
    }
    assert_eq!(p.status().state, State::Paused, "{out}");
    assert!(
        out.contains("power-cut resume: keeping job at layer 2"),
        "{out}"
    );
    let job = store.load_job().unwrap().expect("a record");
    // Restart from the first motion line of layer 2 (line numbers are 1-based).
    assert_eq!(
        job.source,
        JobSource::Host {
            line: first_after as u32 + 1
        }
    );
    assert_eq!(job.layer, 2);
    let steps = |mm: f32, spm: f32| (mm * spm).round() as i32;
    let want = [
        steps(end[0], 80.0),
        steps(end[1], 80.0),
        steps(end[2], 400.0),
        steps(end[3], 93.0),
    ];
    assert_eq!(job.boundary_steps, want, "the end of layer 1");
    assert_eq!(
        job.boundary_z_um, 400,
        "layer 2's height, from the marker's Z move"
    );
    assert_ne!(job.park_steps, job.boundary_steps);
    assert!(job.modal.relative_e && !job.modal.relative_xyz, "M83, G90");
    assert_eq!(job.modal.feed_mm_s, 30.0, "F1800 of layer 1");
    assert_eq!(
        job.modal.logical_e_mm,
        f64::from(end[3]),
        "G92 E0, then layer 1's E"
    );
    assert_eq!((job.hotend_c, job.bed_c, job.fan_pwm), (205.0, 60.0, 128));
    assert_eq!(job.retract_mm, 2.0);

    // A power cut now: the next power-up tells the host where the job can continue.
    let flash = store.into_flash();
    let mut copy = SettingsStore::new(Flash::new(flash.bytes().to_vec()), 0..8192).unwrap();
    let mut after = Printer::with_policy(cfg, Policy::FIRMWARE);
    // No heater model here: extrude cold, as M302 P1.
    after.extrusion_guard_mut().allow_cold = true;
    after.load_settings(&mut copy);
    let mut boot = String::new();
    after.write_output(&mut boot).unwrap();
    assert!(
        boot.contains(&format!(
            "//action:notification Paused job kept: layer 2 at Z0.400, continue from host line {}",
            first_after + 1
        )),
        "{boot}"
    );
    let mut store = SettingsStore::new(flash, 0..8192).unwrap();

    // Resume: the record is forgotten once the job continues.
    p.request(Realtime::Resume, now);
    for _ in 0..5_000 {
        let s = tick(&mut p, &mut store, &mut now);
        out.push_str(&s);
        if p.status().state == State::Printing && !p.store_request_pending() {
            break;
        }
    }
    assert_eq!(store.load_job(), Ok(None), "{out}");
}

#[test]
fn an_unnumbered_stream_keeps_no_record_and_says_so() {
    let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
    // No heater model here: extrude cold, as M302 P1.
    p.extrusion_guard_mut().allow_cold = true;
    let mut store = SettingsStore::new(Flash::erased(vec![0; 8192]), 0..8192).unwrap();
    p.load_settings(&mut store);
    let (lines, _, _) = job();
    let mut out = String::new();
    let mut now = 0u64;
    let mut next = 0;
    let mut waiting = false;
    for _ in 0..200_000u64 {
        if !waiting && next < lines.len() {
            let l = format!("{}\n", lines[next]);
            assert_eq!(
                p.receive(l.as_bytes(), now),
                l.len(),
                "one line per ok is taken"
            );
            next += 1;
            waiting = true;
        }
        if next == 12 {
            p.request(Realtime::Pause(PauseMode::Layer), now);
        }
        while let Some(t) = p.next_step_ns() {
            if t > now * 1000 {
                break;
            }
            p.next_step();
        }
        p.poll(now);
        p.service_store(&mut store);
        let mut s = String::new();
        p.write_output(&mut s).unwrap();
        if s.lines().any(|l| l.starts_with("ok")) {
            waiting = false;
        }
        out.push_str(&s);
        now += 1000;
        if p.status().state == State::Paused {
            break;
        }
    }
    assert_eq!(p.status().state, State::Paused, "{out}");
    assert!(out.contains("power-cut resume: not kept"), "{out}");
    assert_eq!(store.load_job(), Ok(None));
}

#[test]
fn without_a_store_nothing_is_kept_and_the_resume_does_not_wait() {
    // A driver that never attached a store (no load_settings): the pause and resume behave as
    // before, with no record requested.
    let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
    // No heater model here: extrude cold, as M302 P1.
    p.extrusion_guard_mut().allow_cold = true;
    let (lines, _, _) = job();
    let mut now = 0u64;
    let mut next = 0;
    let mut waiting = false;
    let mut out = String::new();
    let mut resumed = false;
    for _ in 0..400_000u64 {
        if !waiting && next < lines.len() {
            let body = format!("N{} {}", next + 1, lines[next]);
            let l = format!("{body}*{}\n", checksum(&body));
            assert_eq!(
                p.receive(l.as_bytes(), now),
                l.len(),
                "one line per ok is taken"
            );
            next += 1;
            waiting = true;
        }
        if next == 12 {
            p.request(Realtime::Pause(PauseMode::Layer), now);
        }
        if p.status().state == State::Paused && !resumed {
            assert!(!p.store_request_pending());
            p.request(Realtime::Resume, now);
            resumed = true;
        }
        while let Some(t) = p.next_step_ns() {
            if t > now * 1000 {
                break;
            }
            p.next_step();
        }
        p.poll(now);
        let mut s = String::new();
        p.write_output(&mut s).unwrap();
        if s.lines().any(|l| l.starts_with("ok")) {
            waiting = false;
        }
        out.push_str(&s);
        now += 1000;
        if resumed && next == lines.len() && p.status().state == State::Idle {
            break;
        }
    }
    assert!(resumed, "{out}");
    assert_eq!(p.status().state, State::Idle, "the job completed: {out}");
    assert!(!out.contains("power-cut resume"), "{out}");
}
