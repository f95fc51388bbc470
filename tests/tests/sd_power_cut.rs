//! Power-cut resume (M1000) of a job printed from the SD card, in the firmware library: a job
//! file on a FAT image (written by an independent FAT writer, `fatfs` through
//! `sim::sd::write_image`) is started with M23/M24 and layer-paused; the power goes while parked
//! (the printer and its RAM are dropped; the flash bytes, the card and the head's physical
//! position survive); a new printer boots from the same flash and card, and `M1000` alone
//! re-heats, homes X/Y through endstops, returns to the boundary and continues the file from
//! the kept byte offset. The job moves executed across both power-ups must equal an unpaused
//! run's, to the step, in the head's physical coordinates; the kept offset must be the first
//! byte of the boundary layer's first motion line, found here by reading the file.
//!
//! Also: M1000 refuses (and changes nothing) when the kept file is gone, when it changed
//! (the offset is inside a line), and when there is no card slot.
//!
//! The rig is the checker, independent of the firmware's bookkeeping: it integrates every step
//! event into a physical position (steps from the minimum endstops), reports the switches from
//! it, and groups the job's step events into moves.

use firmware::config::MachineConfig;
use firmware::homing::HomingConfig;
use firmware::motion::{Axis, PauseMode, Realtime};
use firmware::planner::BlockKind;
use firmware::printer::{Policy, Printer, State};
use firmware::storage::sd::Card;
use firmware::storage::{JobSource, NorFlashModel, RecordStore, SettingsStore};
use firmware::thermal::HeaterId;
use sim::sd::{write_image, ImageDevice};
use std::path::{Path, PathBuf};

type Flash = NorFlashModel<Vec<u8>, 16, 4096>;

/// Where the head is at the first power-on, steps from the switches (not homed).
const START: [i64; 4] = [3_000, 2_000, 900, 0];

/// The job's file on the card, in a sub-directory, by long names (the record keeps the short
/// path).
const NAME: &str = "print-jobs/power-cut-job.gcode";

/// The job file (Cura markers, M83, heaters set without waiting) and the byte offset of the
/// first motion line of each layer (the `G1 Z` after `;LAYER:n`).
fn job() -> (String, Vec<usize>) {
    let mut s = String::from("G28\nM400\nM83\nM104 S205\nM140 S60\nM106 S128\nG92 E0\n");
    let mut first = Vec::new();
    for layer in 0..4 {
        s += &format!(";LAYER:{layer}\n");
        first.push(s.len());
        s += &format!(
            "G1 Z{:.1} F600\nG1 F1800 ; speed\n",
            0.2 * (layer + 1) as f32
        );
        for i in 0..10 {
            let (x, y) = [(20.5, 20.0), (60.25, 20.0), (60.25, 61.3), (20.5, 61.3)][i % 4];
            s += &format!("G1 X{x} Y{y} E1.37\n");
        }
    }
    (s, first)
}

/// A card image in a temporary file, deleted on drop.
struct Image(PathBuf);

impl Image {
    fn new(tag: &str, files: &[(&str, &str)]) -> Image {
        let p = std::env::temp_dir().join(format!("sd-power-cut-{}-{tag}.img", std::process::id()));
        let files: Vec<(String, Vec<u8>)> = files
            .iter()
            .map(|(n, c)| (n.to_string(), c.as_bytes().to_vec()))
            .collect();
        write_image(&p, &files).expect("image");
        Image(p)
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// A job move as the rig saw it: physical start and end, steps.
type Move = ([i64; 4], [i64; 4]);

struct Rig {
    p: Printer,
    store: SettingsStore<Flash>,
    card: Option<Card<ImageDevice>>,
    phys: [i64; 4],
    now_us: u64,
    out: String,
    moves: Vec<Move>,
    in_move: Option<u32>,
}

impl Rig {
    /// Power-up with the flash `bytes`, the card image `card` (None: no slot) and the head at
    /// `phys`.
    fn boot(bytes: Vec<u8>, card: Option<&Path>, phys: [i64; 4]) -> Rig {
        let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
        p.extrusion_guard_mut().allow_cold = true;
        p.enable_endstops(HomingConfig::ENDER3);
        let mut store = SettingsStore::new(Flash::new(bytes), 0..8192).unwrap();
        p.load_settings(&mut store);
        let card = card.map(|c| {
            p.attach_card();
            Card::new(ImageDevice::open(c).expect("open image"))
        });
        let mut r = Rig {
            p,
            store,
            card,
            phys,
            now_us: 0,
            out: String::new(),
            moves: Vec::new(),
            in_move: None,
        };
        r.tick();
        r
    }

    /// One millisecond: steps due, heaters (at their targets), poll, store, card, output.
    fn tick(&mut self) -> String {
        for ax in [Axis::X, Axis::Y, Axis::Z] {
            self.p.set_endstop(ax, self.phys[ax.index()] <= 0);
        }
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
            for ax in [Axis::X, Axis::Y, Axis::Z] {
                self.p.set_endstop(ax, self.phys[ax.index()] <= 0);
            }
            if ev.kind == BlockKind::Job {
                match self.moves.last_mut() {
                    Some(m) if self.in_move == Some(ev.seq) => m.1 = self.phys,
                    _ => self.moves.push((before, self.phys)),
                }
                self.in_move = Some(ev.seq);
            } else {
                self.in_move = None;
            }
        }
        for id in [HeaterId::Hotend, HeaterId::Bed] {
            let t = self.p.thermal().target_c(id).max(20.0);
            self.p.heater_sample(id, t, self.now_us);
        }
        self.p.poll(self.now_us);
        self.p.service_store(&mut self.store);
        if let Some(c) = self.card.as_mut() {
            self.p.service_card(c, self.now_us);
        }
        self.now_us += 1000;
        let mut s = String::new();
        self.p.write_output(&mut s).unwrap();
        self.out.push_str(&s);
        s
    }

    /// Send `line` and run until its `ok`; returns what came meanwhile.
    fn send(&mut self, line: &str) -> String {
        let l = format!("{line}\n");
        let mut taken = 0;
        let mut got = String::new();
        for _ in 0..60_000 {
            if taken < l.len() {
                taken += self.p.receive(&l.as_bytes()[taken..], self.now_us);
            }
            let s = self.tick();
            got.push_str(&s);
            if s.lines().any(|l| l.starts_with("ok")) {
                return got;
            }
        }
        panic!("no ok for {line:?}: {}", self.out);
    }

    fn run_until(&mut self, what: &str, done: impl Fn(&Rig) -> bool) {
        for _ in 0..600_000 {
            if done(self) {
                return;
            }
            self.tick();
        }
        panic!("{what}: never: {}", self.out);
    }

    fn done_printing(&self) -> bool {
        self.out.contains("Done printing file")
            && self.p.status().state == State::Idle
            && !self.p.store_request_pending()
    }
}

fn erased() -> Vec<u8> {
    vec![0xFF; 8192]
}

/// Print the file; ask for a layer pause once the head has made 3 moves of layer 1 (layer 0
/// has 11); run until parked and the record is in flash. Returns the rig.
fn print_and_pause(img: &Image) -> Rig {
    let mut a = Rig::boot(erased(), Some(&img.0), START);
    a.send(&format!("M23 {NAME}"));
    a.send("M24");
    a.run_until("in layer 1", |r| r.moves.len() >= 14);
    a.p.request(Realtime::Pause(PauseMode::Layer), a.now_us);
    a.run_until("parked and kept", |r| {
        r.p.status().state == State::Paused && !r.p.store_request_pending()
    });
    assert!(a.store.load_job().unwrap().is_some(), "{}", a.out);
    a
}

#[test]
fn an_sd_job_paused_resumes_after_a_power_cut_with_m1000_alone() {
    let (text, first) = job();
    let img = Image::new("resume", &[(NAME, &text)]);

    // The reference: the same file, no pause.
    let mut reference = Rig::boot(erased(), Some(&img.0), START);
    reference.send(&format!("M23 {NAME}"));
    reference.send("M24");
    reference.run_until("reference done", Rig::done_printing);
    let file_moves = text
        .lines()
        .filter(|l| l.starts_with("G1 ") && l.contains(['X', 'Y', 'Z', 'E']))
        .count();
    assert_eq!(reference.moves.len(), file_moves, "every move of the file");

    let mut a = print_and_pause(&img);
    let kept = a.store.load_job().unwrap().unwrap();
    let JobSource::Sd { path, offset, size } = &kept.source else {
        panic!("{kept:?}");
    };
    assert_eq!(*size as usize, text.len());
    // The boundary is a layer the file marks, and the offset is its first motion line.
    let layer = first
        .iter()
        .position(|&f| f == *offset as usize)
        .unwrap_or_else(|| panic!("offset {offset} is no layer's first line: {first:?}"));
    assert!(layer >= 2, "paused at layer {layer}");
    // `;LAYER:n` is layer n + 1 (the n-th layer printed, from 1).
    let number = layer + 1;
    assert_eq!(kept.layer as usize, number);
    let z = 0.2 * (layer + 1) as f32;
    assert!(
        a.out.contains(&format!(
            "echo:power-cut resume: keeping job at layer {number}, SD file {path} byte {offset}"
        )),
        "{}",
        a.out
    );

    // The power goes: RAM is lost; the flash, the card and the head's position stay.
    let bytes = a.store.into_flash().bytes().to_vec();
    let before_cut = a.moves;
    let mut b = Rig::boot(bytes, Some(&img.0), a.phys);
    assert!(
        b.out.contains(&format!(
            "//action:notification Paused job kept: layer {number} at Z{z:.3}, continue from SD file {path} byte {offset} (M1000 resumes, M1000 C discards)"
        )),
        "{}",
        b.out
    );
    let reply = b.send("M1000");
    let want = [
        format!(
            "File opened: {} Size: {}",
            path.rsplit('/').next().unwrap(),
            text.len()
        ),
        "File selected".to_string(),
        format!("echo:power-cut resume: layer {number} at Z{z:.3}: SD file {path} byte {offset} continues"),
    ];
    for w in &want {
        assert!(reply.lines().any(|l| l == w), "{w:?} in {reply}");
    }
    assert_eq!(b.p.thermal().target_c(HeaterId::Hotend), 205.0);
    assert_eq!(b.p.thermal().target_c(HeaterId::Bed), 60.0);
    assert_eq!(b.p.fan_pwm(), 128);
    b.run_until("resumed job done", Rig::done_printing);
    assert!(b.out.contains("//action:resumed"), "{}", b.out);
    assert_eq!(b.store.load_job(), Ok(None), "the record is cleared");

    // Nothing lost or duplicated, the boundary to the step.
    let resumed: Vec<Move> = before_cut.iter().chain(&b.moves).copied().collect();
    assert_eq!(
        (before_cut.len(), b.moves.len(), resumed.len()),
        (before_cut.len(), b.moves.len(), reference.moves.len()),
        "move counts"
    );
    assert_eq!(resumed, reference.moves);
    assert_eq!(before_cut.last().unwrap().1, b.moves[0].0, "the boundary");
    eprintln!(
        "paused before layer {layer} (byte {offset}): {} moves before the cut, {} after",
        before_cut.len(),
        b.moves.len()
    );
    assert_eq!(reference.phys, b.phys, "the same end position");
}

#[test]
fn m1000_refuses_a_kept_sd_job_whose_file_is_gone_or_changed_and_changes_nothing() {
    let (text, _) = job();
    let img = Image::new("refuse", &[(NAME, &text)]);
    let a = print_and_pause(&img);
    let bytes = a.store.into_flash().bytes().to_vec();

    // Another file under the same name: one byte longer; the same size, but the offset
    // inside a line.
    let longer = format!(" {text}");
    let rotated = format!("{}{}", &text[1..], &text[..1]);
    let cases: [(&str, Option<Image>, &str); 4] = [
        (
            "gone",
            Some(Image::new("gone", &[("OTHER.GCO", &text)])),
            "echo:refused: M1000: kept SD file: open failed (not found) (M1000 C discards the kept job)",
        ),
        (
            "longer",
            Some(Image::new("longer", &[(NAME, &longer)])),
            "echo:refused: M1000: kept SD file: the file changed",
        ),
        (
            "rotated",
            Some(Image::new("rotated", &[(NAME, &rotated)])),
            "echo:refused: M1000: kept SD file: the file changed",
        ),
        (
            "no slot",
            None,
            "echo:refused: M1000: the kept job is an SD file and there is no card slot",
        ),
    ];
    for (what, image, want) in cases {
        let mut b = Rig::boot(bytes.clone(), image.as_ref().map(|i| i.0.as_path()), a.phys);
        let reply = b.send("M1000");
        assert!(
            reply.lines().any(|l| l.starts_with(want)),
            "{what}: {reply}"
        );
        for _ in 0..2000 {
            b.tick();
        }
        assert!(b.moves.is_empty() && b.phys == a.phys, "{what}: moved");
        assert_eq!(b.p.thermal().target_c(HeaterId::Hotend), 0.0, "{what}");
        assert!(!b.p.sd_printing(), "{what}");
        assert_eq!(b.p.status().state, State::Idle, "{what}");
        // The record stays for another try, and M1000 C still discards it.
        assert!(b.p.kept_job().is_some(), "{what}");
        assert!(b.store.load_job().unwrap().is_some(), "{what}");
        b.send("M1000 C");
        b.run_until("cleared", |r| !r.p.store_request_pending());
        assert_eq!(b.store.load_job(), Ok(None), "{what}");
    }
}
