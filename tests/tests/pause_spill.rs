//! The parked intake's spill to the SD card and host sessions (issue 22; docs/frontend.md, "Host
//! rules" and "A session that ends while paused"), at the firmware's level: the executive
//! driven through its byte link on virtual time, the card an image made by an independent FAT
//! writer (`fatfs`, through `sim::sd::write_image`) whose writes go to `sim::sd::ImageDevice`'s
//! in-memory overlay.
//!
//! The host is a model of printcore's send path (numbered job lines, one per `ok`; `send_now`
//! lines go before the next job line; it ignores `//action:`), so it keeps streaming into the
//! parked printer: the lines past the RAM slots go to the spill file. The truth is the
//! unpaused run of the same job: the executed job segments (sequence, segment) must be the same,
//! in the same order — nothing lost, nothing run twice.

use firmware::config::MachineConfig;
use firmware::link::{checksum, PortId};
use firmware::planner::BlockKind;
use firmware::printer::{Printer, Record, State};
use firmware::storage::sd::{Card, SPILL_NAME};
use sim::sd::{write_image, ImageDevice};
use std::collections::VecDeque;
use std::path::PathBuf;

/// A layered job: `layers` layers of a zigzag of `moves` extruding lines, layer changes by a Z
/// rise (the layer detector's boundaries).
fn job(layers: u32, moves: u32) -> Vec<String> {
    let mut v = vec!["G90".to_string(), "M83".into(), "G92 E0".into()];
    for l in 0..layers {
        v.push(format!("G1 Z{:.2} F600", 0.2 * (l + 1) as f32));
        v.push("G1 X10 Y10 F6000".into());
        for i in 0..moves {
            let x = if i % 2 == 0 { 40 } else { 10 };
            v.push(format!("G1 X{x} Y{} E0.8 F2400", 10 + i % 100));
        }
    }
    v
}

/// A temporary card image, deleted on drop.
struct Image(PathBuf);

impl Image {
    fn new(tag: &str) -> Self {
        let p = std::env::temp_dir().join(format!("pause-spill-{}-{tag}.img", std::process::id()));
        write_image(&p, &[("README.TXT".into(), b"spill test\n".to_vec())]).expect("image");
        Image(p)
    }

    fn card(&self) -> Card<ImageDevice> {
        Card::new(ImageDevice::open(&self.0).expect("open image"))
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// printcore's send path on one port (see the module documentation).
struct Host {
    port: PortId,
    job: Vec<String>,
    next: usize,
    lineno: u32,
    in_flight: bool,
    pri: VecDeque<String>,
    out: String,
    /// A host holds the port (a closed port sends nothing and its output is lost).
    open: bool,
}

impl Host {
    fn new(port: PortId, job: Vec<String>) -> Self {
        Host {
            port,
            job,
            next: 0,
            lineno: 1,
            in_flight: false,
            pri: VecDeque::new(),
            out: String::new(),
            open: true,
        }
    }

    fn done(&self) -> bool {
        self.next >= self.job.len() && !self.in_flight && self.pri.is_empty()
    }

    /// Start the next print as printcore does: `N-1 M110`, then the job numbered from 0.
    fn start_job(&mut self, job: Vec<String>) {
        let pre = "N-1 M110";
        self.pri
            .push_back(format!("{pre}*{}", checksum(pre.as_bytes())));
        self.job = job;
        self.next = 0;
        self.lineno = 0;
    }

    fn read(&mut self, p: &mut Printer) -> Vec<String> {
        let mut s = String::new();
        p.write_output_on(self.port, &mut s).unwrap();
        if !self.open {
            return Vec::new();
        }
        self.out.push_str(&s);
        let lines: Vec<String> = s.lines().map(str::to_string).collect();
        for l in &lines {
            if l.starts_with("ok") {
                self.in_flight = false;
            }
            assert!(!l.starts_with("Resend"), "{l}");
        }
        lines
    }

    fn send(&mut self, p: &mut Printer, now: u64) {
        if self.in_flight || !self.open {
            return;
        }
        let line = if let Some(l) = self.pri.pop_front() {
            format!("{l}\n")
        } else if self.next < self.job.len() {
            let pre = format!("N{} {}", self.lineno, self.job[self.next]);
            self.next += 1;
            self.lineno += 1;
            format!("{pre}*{}\n", checksum(pre.as_bytes()))
        } else {
            return;
        };
        self.in_flight = true;
        let taken = p.receive_on(self.port, line.as_bytes(), now);
        assert_eq!(taken, line.len(), "a one-line-per-ok host's line is taken");
    }
}

/// The printer, its card and what ran.
struct Rig {
    p: Printer,
    card: Option<Card<ImageDevice>>,
    now: u64,
    executed: Vec<(u32, u32)>,
    /// The layers the head started, in order (`Record::Layer`).
    layers: Vec<u32>,
    stops: usize,
    /// Job segments executed since `mark_cancel`.
    after_cancel: Option<usize>,
}

impl Rig {
    fn new(card: Option<Card<ImageDevice>>) -> Self {
        let mut p = Printer::new(MachineConfig::ENDER3);
        // No heater model here: the jobs extrude cold (as M302 P1).
        p.extrusion_guard_mut().allow_cold = true;
        if card.is_some() {
            p.attach_card();
        }
        Rig {
            p,
            card,
            now: 0,
            executed: Vec::new(),
            layers: Vec::new(),
            stops: 0,
            after_cancel: None,
        }
    }

    /// One tick: the hosts send, the card is serviced, the steps due run. Ticks are 1 ms while
    /// something moves and 20 ms while nothing does (a parked printer: the intake's pace is
    /// 1 s).
    fn tick(&mut self, hosts: &mut [&mut Host]) -> Vec<Vec<String>> {
        for h in hosts.iter_mut() {
            h.send(&mut self.p, self.now);
        }
        if let Some(c) = self.card.as_mut() {
            self.p.service_card(c, self.now);
        }
        self.p.poll(self.now);
        let moving = self.p.next_step_ns().is_some();
        let step_us = if moving { 1000 } else { 20_000 };
        let until_ns = (self.now + step_us) * 1000;
        while let Some(t) = self.p.next_step_ns() {
            if t > until_ns || self.p.next_step().is_none() {
                break;
            }
        }
        self.now += step_us;
        self.p.poll(self.now);
        while let Some(r) = self.p.pop_record() {
            match r {
                Record::Executed {
                    seq,
                    seg,
                    kind: BlockKind::Job,
                    ..
                } => self.executed.push((seq, seg)),
                Record::Stopped { .. } => self.stops += 1,
                Record::Layer { layer, .. } => self.layers.push(layer),
                _ => {}
            }
        }
        hosts.iter_mut().map(|h| h.read(&mut self.p)).collect()
    }

    fn idle(&mut self) -> bool {
        self.p.status().state == State::Idle && self.p.next_step_ns().is_none()
    }

    /// The names on the card (M20's view through the firmware's own FAT reader).
    fn card_files(&mut self) -> Vec<String> {
        let mut v = Vec::new();
        if let Some(c) = self.card.as_mut() {
            c.for_each_file(|_, e| v.push(e.short.to_string()))
                .expect("list");
        }
        v
    }
}

/// The unpaused run's executed job segments.
fn baseline(job: &[String]) -> Vec<(u32, u32)> {
    let mut rig = Rig::new(None);
    let mut h = Host::new(PortId::Usb, job.to_vec());
    while rig.now < 3_600_000_000 {
        rig.tick(&mut [&mut h]);
        if h.done() && rig.idle() {
            break;
        }
    }
    assert!(h.done() && rig.idle(), "baseline never ended");
    rig.executed
}

/// Pause, stay parked `pause_s` with a console line (M105, then M114) every 37 s whose answer
/// must come within 2 s, then M602 (or M524 with `cancel`); runs until idle.
/// Returns the rig, the host and the worst console delivery, µs.
fn long_pause(job: &[String], card: bool, pause_s: u64, cancel: bool) -> (Rig, Host, u64) {
    let img = Image::new(if cancel { "cancel" } else { "resume" });
    let mut rig = Rig::new(card.then(|| img.card()));
    let mut h = Host::new(PortId::Usb, job.to_vec());
    let mut paused_at = None;
    let mut asked = None;
    let mut worst = 0u64;
    let mut ended = false;
    let mut pause_asked = false;
    let mut last_slot = None;
    while rig.now < 7_200_000_000 {
        if !pause_asked && h.next == 150 {
            h.pri.push_back("M601".into());
            pause_asked = true;
        }
        let lines = rig.tick(&mut [&mut h]).remove(0);
        if lines.iter().any(|l| l == "//action:paused") && paused_at.is_none() {
            paused_at = Some(rig.now);
        }
        if let Some((at, want)) = asked {
            if lines.iter().any(|l: &String| l.starts_with(want)) {
                worst = worst.max(rig.now - at);
                asked = None;
            } else {
                assert!(
                    rig.now - at <= 2_000_000,
                    "{want} not answered within 2 s ({} s into the pause)",
                    (rig.now - paused_at.unwrap_or(0)) / 1_000_000
                );
            }
        }
        if let Some(t0) = paused_at {
            let since = rig.now - t0;
            // One console line per 37 s slot, 1 s into it.
            let k = since / 37_000_000;
            if asked.is_none()
                && since < pause_s * 1_000_000
                && since % 37_000_000 >= 1_000_000
                && last_slot != Some(k)
            {
                let (cmd, want) = if k.is_multiple_of(2) {
                    ("M105", "ok T:")
                } else {
                    ("M114", "X:")
                };
                last_slot = Some(k);
                h.pri.push_back(cmd.into());
                asked = Some((rig.now, want));
            }
            if since >= pause_s * 1_000_000 && !ended {
                h.pri.push_back(if cancel { "M524" } else { "M602" }.into());
                ended = true;
                if cancel {
                    rig.after_cancel = Some(rig.executed.len());
                }
            }
        }
        if ended && h.done() && rig.idle() && h.pri.is_empty() && !h.in_flight {
            break;
        }
    }
    (rig, h, worst)
}

#[test]
fn a_long_pause_spills_to_the_card_and_runs_every_line_once_after_the_resume() {
    let job = job(12, 100);
    let base = baseline(&job);
    // 600 s parked at one job line a second: 96 lines into RAM, the rest onto the card.
    let (mut rig, h, worst) = long_pause(&job, true, 600, false);
    let out = &h.out;
    let tail: String = out.lines().rev().take(12).collect::<Vec<_>>().join("\n");
    assert!(
        out.contains(&format!("kept on the SD card ({SPILL_NAME})")),
        "never spilled:\n{tail}"
    );
    let parked = &out[out.find("//action:paused").unwrap()..out.find("//action:resumed").unwrap()];
    let taken_while_parked = parked.lines().filter(|l| *l == "ok").count();
    // One job line a second for 600 s (the console lines' own answers are `ok T:…`, `X:…`).
    assert!(
        taken_while_parked > 550,
        "{taken_while_parked} oks while parked"
    );
    assert!(
        out.contains("job lines kept on the SD card have run"),
        "{tail}"
    );
    eprintln!("worst console delivery {:.3} s", worst as f64 / 1e6);
    assert!(h.done(), "job not sent to the end:\n{tail}");
    assert_eq!(rig.stops, 1);
    assert_eq!(rig.executed, base, "every job segment once, in order");
    assert!(
        !rig.card_files().iter().any(|n| n == SPILL_NAME),
        "the spill file is deleted once its lines ran: {:?}",
        rig.card_files()
    );
    assert!(!out.contains("Error"), "{tail}");
}

/// printcore sends the whole rest of a print into the parked printer (one line a second, most
/// of it onto the card) and the user starts the next print before resuming: its `N-1 M110`
/// comes while the first job's lines still wait in the spill. The next job starts where its
/// first line is fed back, after the first job's last line (docs/planner.md, "Jobs"): the
/// first job's layers count on to 4 across the resume, the second's from 1, and every line of
/// both runs once, in order. (Fails when the job starts at the `M110`'s arrival: the first
/// job's spilled layers are numbered as the second job's.) ≈ 300 s parked, ≈ 3 s of test time.
#[test]
fn a_print_started_behind_spilled_lines_numbers_its_layers_after_them() {
    let job = job(4, 100);
    // The truth: both prints unpaused, the second started when the first was sent.
    let base = {
        let mut rig = Rig::new(None);
        let mut h = Host::new(PortId::Usb, job.clone());
        let mut second = false;
        while rig.now < 3_600_000_000 && !(second && h.done() && rig.idle()) {
            rig.tick(&mut [&mut h]);
            if !second && h.done() {
                h.start_job(job.clone());
                second = true;
            }
        }
        assert!(second && h.done() && rig.idle(), "baseline never ended");
        rig.executed
    };
    let img = Image::new("next-print");
    let mut rig = Rig::new(Some(img.card()));
    let mut h = Host::new(PortId::Usb, job.clone());
    let (mut pause_asked, mut paused, mut second_at, mut resumed) = (false, false, None, false);
    let mut in_spill_at_reset = 0;
    while rig.now < 3_600_000_000 {
        if !pause_asked && h.next == 150 {
            h.pri.push_back("M601".into());
            pause_asked = true;
        }
        let lines = rig.tick(&mut [&mut h]).remove(0);
        paused |= lines.iter().any(|l| l == "//action:paused");
        if paused && second_at.is_none() && h.done() {
            in_spill_at_reset = h.out.matches("kept on the SD card").count();
            h.start_job(job.clone());
            second_at = Some(rig.now);
        }
        if !resumed && second_at.is_some_and(|t| rig.now > t + 20_000_000) {
            h.pri.push_back("M602".into());
            resumed = true;
        }
        if resumed && h.done() && rig.idle() {
            break;
        }
    }
    let tail: String = h.out.lines().rev().take(12).collect::<Vec<_>>().join("\n");
    assert!(resumed && h.done(), "{tail}");
    assert_eq!(
        in_spill_at_reset, 1,
        "the first job's rest was spilled: {tail}"
    );
    assert_eq!(rig.stops, 1);
    assert_eq!(rig.layers, [1, 2, 3, 4, 1, 2, 3, 4], "{tail}");
    assert_eq!(
        rig.executed, base,
        "every segment of both jobs once, in order"
    );
    assert!(!h.out.contains("Error"), "{tail}");
}

#[test]
fn a_cancel_drops_the_spilled_lines_and_the_file() {
    let job = job(12, 100);
    let (mut rig, h, _) = long_pause(&job, true, 300, true);
    let out = &h.out;
    let tail: String = out.lines().rev().take(12).collect::<Vec<_>>().join("\n");
    assert!(out.contains("kept on the SD card"), "{tail}");
    assert!(
        out.contains("job lines kept on the SD card") && out.contains("cancelled: dropped"),
        "{tail}"
    );
    let after = rig.after_cancel.expect("cancelled");
    assert_eq!(
        rig.executed.len(),
        after,
        "no job segment runs after the cancel"
    );
    assert!(!rig.card_files().iter().any(|n| n == SPILL_NAME));
    assert!(!out.contains("Error"), "{tail}");
}

/// Without a card the intake is the RAM slots at a growing pace (192 s); then the host waits
/// with `busy:` and its console line is not delivered — the documented fallback, checked so a
/// change to it is seen.
#[test]
fn without_a_card_the_intake_ends_after_the_ram_slots() {
    let job = job(12, 100);
    let mut rig = Rig::new(None);
    let mut h = Host::new(PortId::Usb, job.clone());
    let mut paused_at = None;
    let mut pause_asked = false;
    while rig.now < 600_000_000 {
        if !pause_asked && h.next == 150 {
            h.pri.push_back("M601".into());
            pause_asked = true;
        }
        let lines = rig.tick(&mut [&mut h]).remove(0);
        if paused_at.is_none() && lines.iter().any(|l| l == "//action:paused") {
            paused_at = Some(rig.now);
        }
        if paused_at.is_some_and(|t| rig.now > t + 300_000_000) {
            break;
        }
    }
    let parked = &h.out[h.out.find("//action:paused").unwrap()..];
    let oks = parked.lines().filter(|l| *l == "ok").count();
    assert!(
        (95..=98).contains(&oks),
        "{oks} job lines taken while parked"
    );
    let since = h.out.rfind("\nok\n").unwrap();
    assert!(
        h.out[since..].matches("busy:").count() >= 40,
        "the host waits with keep-alives: {}",
        &h.out[since..]
    );
    assert!(!h.out.contains("SD card"));
}

/// The job's host goes away while parked: resume refused, a new host told what to do, M524
/// ends the job with the head parked; while running: the job stops at a layer and parks.
#[test]
fn a_session_that_ends_orphans_the_job() {
    let job = job(12, 100);
    // Paused, then the host leaves.
    let mut rig = Rig::new(None);
    let mut h = Host::new(PortId::Usb, job.clone());
    let mut paused = false;
    let mut pause_asked = false;
    while rig.now < 900_000_000 && !paused {
        if !pause_asked && h.next == 150 {
            h.pri.push_back("M601".into());
            pause_asked = true;
        }
        paused = rig
            .tick(&mut [&mut h])
            .remove(0)
            .iter()
            .any(|l| l == "//action:paused");
    }
    assert!(paused);
    let parked_z = rig.p.status().position[2];
    rig.p.port_session(PortId::Usb, false, rig.now);
    h.open = false;
    assert!(rig.p.job_orphaned());
    for _ in 0..100 {
        rig.tick(&mut [&mut h]);
    }
    // A new host (OctoPrint after a reconnect: no job, a terminal).
    let mut h2 = Host::new(PortId::Usb, Vec::new());
    rig.p.port_session(PortId::Usb, true, rig.now);
    let mut first = String::new();
    rig.p.write_output_on(PortId::Usb, &mut first).unwrap();
    let first: Vec<&str> = first.lines().collect();
    assert!(
        first
            .iter()
            .any(|l| l.contains("paused: job held") && l.contains("M524 ends it")),
        "{first:?}"
    );
    assert!(first.contains(&"//action:paused"), "{first:?}");
    // It names the layer the held job starts with: one above the last the head started, and
    // the one at whose height (0.2 mm per layer) or below it the head stopped (parked Z less
    // the lift; the boundary lies between two layers' extrusions, the Z move on either side).
    let next = rig.layers.last().expect("layers crossed") + 1;
    let lift_steps = (rig.p.config().pause.lift_z_mm * 400.0).round() as i32;
    let stop_z = parked_z - lift_steps;
    assert!(
        [80 * (next as i32 - 1), 80 * next as i32].contains(&stop_z),
        "stop Z {stop_z} steps, layer {next} next"
    );
    assert!(
        first
            .iter()
            .any(|l| l.contains(&format!("job held before layer {next};"))),
        "{first:?}"
    );
    h2.pri.push_back("M602".into());
    let mut out = Vec::new();
    for _ in 0..200 {
        out.extend(rig.tick(&mut [&mut h2]).remove(0));
    }
    assert!(out.iter().any(|l| l.contains("refused: resume")), "{out:?}");
    assert_eq!(rig.p.status().state, State::Paused);
    assert_eq!(rig.p.status().position[2], parked_z, "still parked");
    let ran = rig.executed.len();
    h2.pri.push_back("M524".into());
    for _ in 0..2000 {
        out.extend(rig.tick(&mut [&mut h2]).remove(0));
    }
    assert!(out.iter().any(|l| l == "//action:cancel"), "{out:?}");
    assert_eq!(rig.executed.len(), ran, "no job move after the host left");
    assert!(
        matches!(rig.p.status().state, State::Idle | State::Cancelled),
        "{:?}",
        rig.p.status().state
    );
    assert!(
        rig.p.status().position[2] >= parked_z,
        "the head stays parked (Z {} < {parked_z})",
        rig.p.status().position[2]
    );

    // Running, then the host leaves: a layer pause, parked.
    let mut rig = Rig::new(None);
    let mut h = Host::new(PortId::Usb, job.clone());
    while h.next < 150 {
        rig.tick(&mut [&mut h]);
    }
    rig.p.port_session(PortId::Usb, false, rig.now);
    h.open = false;
    for _ in 0..60_000 {
        rig.tick(&mut [&mut h]);
        if rig.p.status().state == State::Paused {
            break;
        }
    }
    assert_eq!(
        rig.p.status().state,
        State::Paused,
        "parked after the host left"
    );
    assert_eq!(rig.stops, 1);
    assert!(rig.p.job_orphaned());
}

/// A block device that counts the blocks read and written through it (the spill file's I/O
/// profile, below).
struct Counting {
    dev: ImageDevice,
    reads: std::rc::Rc<std::cell::Cell<u64>>,
    writes: std::rc::Rc<std::cell::Cell<u64>>,
}

impl embedded_sdmmc::BlockDevice for Counting {
    type Error = std::io::ErrorKind;

    fn read(
        &self,
        blocks: &mut [embedded_sdmmc::Block],
        start: embedded_sdmmc::BlockIdx,
    ) -> Result<(), Self::Error> {
        self.reads.set(self.reads.get() + blocks.len() as u64);
        self.dev.read(blocks, start)
    }

    fn write(
        &self,
        blocks: &[embedded_sdmmc::Block],
        start: embedded_sdmmc::BlockIdx,
    ) -> Result<(), Self::Error> {
        self.writes.set(self.writes.get() + blocks.len() as u64);
        self.dev.write(blocks, start)
    }

    fn num_blocks(&self) -> Result<embedded_sdmmc::BlockCount, Self::Error> {
        self.dev.num_blocks()
    }
}

/// The spill file's block I/O does not grow with its length: an eight-hour pause spills ≈ 1 MB
/// (one line a second), on the simulator's card in 2 048 clusters of 512 bytes (a FAT16 card
/// made by `fatfs`; sold cards have 4–64 KiB clusters). Each append (one [`SPILL_FLUSH`]
/// stage) and each replay read ([`SPILL_CHUNK`]) costs the same few blocks at the file's end
/// as at its start: the file is not searched for in the directory, nor its cluster chain
/// walked from the start, for each of them. Then the pattern of the replay after a resume
/// (reads, with an append every [`SPILL_FLUSH`] bytes of new lines) reads every byte back
/// in order.
#[test]
fn the_spill_file_costs_the_same_blocks_per_access_at_any_length() {
    use firmware::printer::{SPILL_CHUNK, SPILL_FLUSH};
    let img = Image::new("io");
    let (reads, writes) = (
        std::rc::Rc::new(std::cell::Cell::new(0)),
        std::rc::Rc::new(std::cell::Cell::new(0)),
    );
    let mut card = Card::new(Counting {
        dev: ImageDevice::open(&img.0).expect("open image"),
        reads: reads.clone(),
        writes: writes.clone(),
    });
    card.mount().expect("mount");
    let io = |_: &Card<Counting>| (reads.get(), writes.get());
    // 1 MiB in appends of SPILL_FLUSH bytes, lines of the spill's format.
    let mut content = Vec::new();
    let mut n = 0u32;
    let appends = (1 << 20) / SPILL_FLUSH;
    let mut append_cost = Vec::new();
    for _ in 0..appends {
        let mut chunk = Vec::new();
        while chunk.len() < SPILL_FLUSH {
            n += 1;
            chunk.extend_from_slice(
                format!("{n} G1 X{} Y{} E0.0412\n", n % 200, n % 170).as_bytes(),
            );
        }
        let before = io(&card);
        let len = card.spill_append(&chunk).expect("append");
        let after = io(&card);
        content.extend_from_slice(&chunk);
        assert_eq!(len as usize, content.len());
        append_cost.push((after.0 - before.0, after.1 - before.1));
    }
    // Replay: reads of SPILL_CHUNK bytes from the start.
    let mut read_cost = Vec::new();
    let mut at = 0usize;
    let mut buf = vec![0u8; SPILL_CHUNK];
    while at < content.len() {
        let before = io(&card);
        let got = card.spill_read_at(at as u32, &mut buf).expect("read");
        let after = io(&card);
        assert!(got > 0);
        assert_eq!(&buf[..got], &content[at..at + got], "at byte {at}");
        at += got;
        read_cost.push(after.0 - before.0);
    }
    let tenth = |v: &[u64], last: bool| -> u64 {
        let k = v.len() / 10;
        let s = if last { &v[v.len() - k..] } else { &v[..k] };
        s.iter().copied().max().unwrap_or(0)
    };
    let ar: Vec<u64> = append_cost.iter().map(|c| c.0).collect();
    let aw: Vec<u64> = append_cost.iter().map(|c| c.1).collect();
    eprintln!(
        "{} appends: blocks read per append max {} (first tenth) / {} (last tenth), written {} / {}; \
         {} reads: blocks read per read max {} / {}; total read {} written {}",
        ar.len(),
        tenth(&ar, false),
        tenth(&ar, true),
        tenth(&aw, false),
        tenth(&aw, true),
        read_cost.len(),
        tenth(&read_cost, false),
        tenth(&read_cost, true),
        io(&card).0,
        io(&card).1,
    );
    assert!(
        tenth(&ar, true) <= tenth(&ar, false).max(4),
        "appends read more blocks as the file grows"
    );
    assert!(
        tenth(&aw, true) <= tenth(&aw, false).max(4),
        "appends write more blocks as the file grows"
    );
    assert!(
        tenth(&read_cost, true) <= 3,
        "a replay read at the file's end reads {} blocks",
        tenth(&read_cost, true)
    );
}
