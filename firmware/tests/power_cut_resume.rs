//! Power-cut resume (M1000) in the firmware library: a numbered host job is layer-paused, the
//! power goes while parked (the printer and its RAM are dropped; the flash bytes and the head's
//! physical position survive), a new printer boots from the same flash, M1000 re-heats, homes
//! X/Y through endstops, returns to the boundary and the host sends the rest from the line
//! M1000 names. The job moves executed across both power-ups must equal an uninterrupted run's,
//! to the step, in the head's physical coordinates.
//!
//! The rig here is the checker, independent of the firmware's own bookkeeping: it integrates
//! every step event into a physical position (steps from the minimum endstops), reports the
//! endstop switches from it, and groups the job's step events into moves.

use firmware::config::MachineConfig;
use firmware::homing::HomingConfig;
use firmware::motion::{Axis, PauseMode, Realtime};
use firmware::planner::BlockKind;
use firmware::printer::{Policy, Printer, Record, State};
use firmware::storage::{NorFlashModel, RecordStore, SettingsStore};
use firmware::thermal::HeaterId;

type Flash = NorFlashModel<Vec<u8>, 16, 4096>;

/// Where the head is at the first power-on, steps from the switches (not homed).
const START: [i64; 4] = [3_000, 2_000, 900, 0];

fn checksum(s: &str) -> u8 {
    s.bytes().fold(0, |a, b| a ^ b)
}

/// The job (Cura markers, M83, heaters set without waiting); line i is numbered i + 1. Also
/// returns the index of the first motion line of each layer.
fn job() -> (Vec<String>, Vec<usize>) {
    // M400 after G28: the pause is asked for with the head homed (a pause during G28 is
    // tested in homing.rs).
    let mut v: Vec<String> = [
        "G28",
        "M400",
        "M83",
        "M104 S205",
        "M140 S60",
        "M106 S128",
        "G92 E0",
    ]
    .map(String::from)
    .to_vec();
    let mut first = Vec::new();
    for layer in 0..4 {
        v.push(format!(";LAYER:{layer}"));
        first.push(v.len());
        v.push(format!("G1 Z{:.1} F600", 0.2 * (layer + 1) as f32));
        v.push("G1 F1800".into());
        for i in 0..10 {
            let (x, y) = [(20.5, 20.0), (60.25, 20.0), (60.25, 61.3), (20.5, 61.3)][i % 4];
            v.push(format!("G1 X{x} Y{y} E1.37"));
        }
    }
    (v, first)
}

/// A job move as the rig saw it: sequence number (per power-up), physical start and end.
type Move = (u32, [i64; 4], [i64; 4]);

struct Rig {
    p: Printer,
    store: SettingsStore<Flash>,
    phys: [i64; 4],
    now_us: u64,
    out: String,
    moves: Vec<Move>,
    /// The last step was a job step of this sequence number (a move continues).
    in_move: Option<u32>,
    /// Heaters report their target from this time on (ambient before).
    hot_from_us: u64,
    /// Time of the first job or service step.
    first_motion_us: Option<u64>,
    /// The layer marks the head crossed (their numbers), in order.
    layers: Vec<u32>,
}

impl Rig {
    /// Power-up with the flash `bytes` and the head at `phys`.
    fn boot(bytes: Vec<u8>, phys: [i64; 4]) -> Rig {
        let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
        p.extrusion_guard_mut().allow_cold = true;
        p.enable_endstops(HomingConfig::ENDER3);
        let mut store = SettingsStore::new(Flash::new(bytes), 0..8192).unwrap();
        p.load_settings(&mut store);
        let mut r = Rig {
            p,
            store,
            phys,
            now_us: 0,
            out: String::new(),
            moves: Vec::new(),
            in_move: None,
            hot_from_us: 0,
            first_motion_us: None,
            layers: Vec::new(),
        };
        r.switches();
        r
    }

    fn switches(&mut self) {
        for ax in [Axis::X, Axis::Y, Axis::Z] {
            self.p.set_endstop(ax, self.phys[ax.index()] <= 0);
        }
    }

    /// One millisecond: steps due, heaters, poll, store, output.
    fn tick(&mut self) -> String {
        let t_ns = self.now_us * 1000;
        while let Some(t) = self.p.next_step_ns() {
            if t > t_ns {
                break;
            }
            let Some(ev) = self.p.next_step() else { break };
            let before = self.phys;
            for i in 0..4 {
                if ev.axis_mask & (1 << i) != 0 {
                    self.phys[i] += if ev.dir_mask & (1 << i) != 0 { 1 } else { -1 };
                }
            }
            self.switches();
            if ev.kind != BlockKind::Homing {
                self.first_motion_us.get_or_insert(self.now_us);
            }
            if ev.kind == BlockKind::Job {
                match self.moves.last_mut() {
                    Some(m) if self.in_move == Some(ev.seq) => m.2 = self.phys,
                    _ => self.moves.push((ev.seq, before, self.phys)),
                }
                self.in_move = Some(ev.seq);
            } else {
                self.in_move = None;
            }
        }
        for id in [HeaterId::Hotend, HeaterId::Bed] {
            let t = if self.now_us >= self.hot_from_us {
                self.p.thermal().target_c(id)
            } else {
                20.0
            };
            self.p.heater_sample(id, t, self.now_us);
        }
        self.p.poll(self.now_us);
        self.p.service_store(&mut self.store);
        while let Some(r) = self.p.pop_record() {
            if let Record::Layer { layer, .. } = r {
                self.layers.push(layer);
            }
        }
        self.now_us += 1000;
        let mut s = String::new();
        self.p.write_output(&mut s).unwrap();
        self.out.push_str(&s);
        s
    }

    /// Send `line` and run until its `ok`.
    fn send(&mut self, line: &str) {
        let l = format!("{line}\n");
        let mut taken = 0;
        for _ in 0..60_000 {
            if taken < l.len() {
                taken += self.p.receive(&l.as_bytes()[taken..], self.now_us);
            }
            if self.tick().lines().any(|l| l.starts_with("ok")) {
                return;
            }
        }
        panic!("no ok for {line:?}: {}", self.out);
    }

    /// Send job line `i` (numbered i + 1).
    fn send_job_line(&mut self, lines: &[String], i: usize) {
        let body = format!("N{} {}", i + 1, lines[i]);
        self.send(&format!("{body}*{}", checksum(&body)));
    }

    fn run_until(&mut self, done: impl Fn(&Rig) -> bool) {
        for _ in 0..300_000 {
            if done(self) {
                return;
            }
            self.tick();
        }
        panic!("never done: {}", self.out);
    }

    fn idle(&self) -> bool {
        self.p.status().state == State::Idle && !self.p.store_request_pending()
    }
}

/// Stream the job and ask for a layer pause when the host sends layer 2 (`;LAYER:1`); run
/// until parked and kept.
fn pause_in_layer_2(a: &mut Rig, lines: &[String], first: &[usize]) {
    let mut i = 0;
    let mut ticks = 0;
    while a.p.status().state != State::Paused {
        if i < lines.len() {
            if i == first[1] + 3 {
                a.p.request(Realtime::Pause(PauseMode::Layer), a.now_us);
            }
            a.send_job_line(lines, i);
            i += 1;
        } else {
            a.tick();
            ticks += 1;
            assert!(
                ticks < 300_000,
                "never paused: {:?}\n{}",
                a.p.status(),
                a.out
            );
        }
    }
    a.run_until(|r| !r.p.store_request_pending());
}

fn erased() -> Vec<u8> {
    vec![0xFF; 8192]
}

#[test]
fn a_job_paused_resumed_after_a_power_cut_runs_the_same_moves_as_an_unpaused_one() {
    let (lines, first) = job();
    // The reference: the same job, no pause.
    let mut reference = Rig::boot(erased(), START);
    reference.send("M110 N0");
    for i in 0..lines.len() {
        reference.send_job_line(&lines, i);
    }
    reference.run_until(Rig::idle);

    // The job, layer-paused while the host sends layer 2 (the head prints layer 1).
    let mut a = Rig::boot(erased(), START);
    a.send("M110 N0");
    pause_in_layer_2(&mut a, &lines, &first);
    // The host runs ahead of the motion by the queue: the stop is at the first boundary the
    // plan could still reach, before layer 2 or 3. The record names that layer (numbered from
    // 1: `;LAYER:n` is layer n + 1) and its first motion line.
    let kept = a
        .out
        .lines()
        .find_map(|l| l.strip_prefix("echo:power-cut resume: keeping job at layer "))
        .unwrap_or_else(|| panic!("{}", a.out))
        .to_string();
    let (layer, line) = kept.split_once(", host line ").unwrap();
    let layer: usize = layer.parse().unwrap();
    let kept_line: u32 = line.parse().unwrap();
    assert!(layer >= 2, "{kept}");
    assert_eq!(kept_line, first[layer - 1] as u32 + 1, "{kept}");
    let z = 0.2 * layer as f32;

    // The power goes: RAM is lost, the flash and the head's position stay.
    let bytes = a.store.into_flash().bytes().to_vec();
    let parked = a.phys;
    let before_cut = a.moves;
    let mut b = Rig::boot(bytes, parked);
    b.tick();
    assert!(
        b.out.contains(&format!(
            "//action:notification Paused job kept: layer {layer} at Z{z:.3}, continue from host line {kept_line} (M1000 resumes, M1000 C discards)"
        )),
        "{}",
        b.out
    );
    // The heaters reach their targets only after 3 s: nothing moves before (M1000 waits).
    b.hot_from_us = b.now_us + 3_000_000;
    b.send("M1000");
    assert!(
        b.out.contains(&format!(
            "echo:power-cut resume: layer {layer} at Z{z:.3}: send the job from host line {kept_line} (M110 N{} first)",
            kept_line - 1
        )),
        "{}",
        b.out
    );
    assert_eq!(b.p.thermal().target_c(HeaterId::Hotend), 205.0);
    assert_eq!(b.p.thermal().target_c(HeaterId::Bed), 60.0);
    assert_eq!(b.p.fan_pwm(), 128);
    b.send(&format!("M110 N{}", kept_line - 1));
    for i in (kept_line as usize - 1)..lines.len() {
        b.send_job_line(&lines, i);
    }
    b.run_until(Rig::idle);
    assert!(
        b.first_motion_us.unwrap() >= b.hot_from_us,
        "moved before the heaters were at temperature: {:?}",
        b.first_motion_us
    );
    assert!(b.out.contains("//action:resumed"), "{}", b.out);
    assert_eq!(b.store.load_job(), Ok(None), "the record is cleared");

    // Nothing lost or duplicated, the boundary to the step: compare start and end of every
    // job move in physical steps (sequence numbers restart at power-up, so they are left out).
    let geo = |m: &[Move]| m.iter().map(|(_, s, e)| (*s, *e)).collect::<Vec<_>>();
    let resumed: Vec<_> = geo(&before_cut).into_iter().chain(geo(&b.moves)).collect();
    let want = geo(&reference.moves);
    assert_eq!(before_cut.len() + b.moves.len(), want.len(), "move count");
    assert_eq!(resumed, want);
    // The boundary: where the first session stopped is where the second one's job started.
    assert_eq!(before_cut.last().unwrap().2, b.moves[0].1);
    assert_eq!(reference.phys, b.phys, "the same end position");
    // One numbering across the power cut: the continued job's layers go on from the kept one
    // (the first session crossed the marks before it), as the uninterrupted run numbered them.
    assert_eq!(reference.layers, vec![1, 2, 3, 4]);
    let both: Vec<u32> = a.layers.iter().chain(&b.layers).copied().collect();
    assert_eq!(both, reference.layers, "{:?} + {:?}", a.layers, b.layers);
}

/// Power-up with a kept job, then `M1000 C`: discarded and cleared; a second M1000 refuses.
#[test]
fn m1000_c_discards_and_a_new_job_supersedes_the_kept_one() {
    let (lines, first) = job();
    let mut a = Rig::boot(erased(), START);
    a.send("M110 N0");
    pause_in_layer_2(&mut a, &lines, &first);
    let bytes = a.store.into_flash().bytes().to_vec();

    // M1000 C forgets it.
    let mut b = Rig::boot(bytes.clone(), a.phys);
    assert!(b.p.kept_job().is_some());
    b.send("M1000 C");
    b.run_until(|r| !r.p.store_request_pending());
    assert!(
        b.out.contains("echo:power-cut resume: kept job discarded"),
        "{}",
        b.out
    );
    assert_eq!(b.store.load_job(), Ok(None));
    b.send("M1000");
    assert!(
        b.out.contains("echo:refused: M1000: no paused job kept"),
        "{}",
        b.out
    );

    // A new job's first move forgets it too (it would otherwise be offered at every power-up).
    let mut c = Rig::boot(bytes, a.phys);
    c.send("G28");
    c.send("G1 X10 F3000");
    c.run_until(Rig::idle);
    assert!(
        c.out
            .contains("power-cut resume: kept job discarded (a new job moves the head)"),
        "{}",
        c.out
    );
    assert_eq!(c.store.load_job(), Ok(None));
}
