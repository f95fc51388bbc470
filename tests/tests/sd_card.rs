//! SD-card printing: the firmware's FAT job source (embedded-sdmmc) on images made in the test
//! by an independent FAT writer (the `fatfs` crate, through `sim::sd::write_image`), and the
//! SD M-codes as the executive answers them (Marlin's replies).

use embedded_sdmmc::{Block, BlockCount, BlockDevice, BlockIdx};
use firmware::config::MachineConfig;
use firmware::planner::BlockKind;
use firmware::printer::{Printer, Record, State};
use firmware::storage::sd::{Card, CardError};
use sim::sd::{write_image, ImageDevice};
use std::path::PathBuf;

const TICK_US: u64 = 1000;

/// A temporary image of `files`, deleted on drop.
struct Image(PathBuf);

impl Image {
    fn new(tag: &str, files: &[(&str, Vec<u8>)]) -> Self {
        let p = std::env::temp_dir().join(format!("sd-card-test-{}-{tag}.img", std::process::id()));
        let files: Vec<(String, Vec<u8>)> = files
            .iter()
            .map(|(n, c)| (n.to_string(), c.clone()))
            .collect();
        write_image(&p, &files).expect("image");
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

/// A card slot with no card: every read fails.
struct NoCard;

impl BlockDevice for NoCard {
    type Error = ();
    fn read(&self, _: &mut [Block], _: BlockIdx) -> Result<(), ()> {
        Err(())
    }
    fn write(&self, _: &[Block], _: BlockIdx) -> Result<(), ()> {
        Err(())
    }
    fn num_blocks(&self) -> Result<BlockCount, ()> {
        Err(())
    }
}

/// Deterministic G-code-like text of `n` bytes.
fn text(n: usize, seed: u32) -> Vec<u8> {
    let mut v = Vec::with_capacity(n);
    let mut i = seed;
    while v.len() < n {
        v.extend_from_slice(format!("G1 X{} Y{} ; line {i}\n", i % 200, (i * 7) % 200).as_bytes());
        i += 1;
    }
    v.truncate(n);
    v
}

fn read_all<D: BlockDevice>(card: &mut Card<D>, chunk: usize) -> Vec<u8>
where
    D::Error: core::fmt::Debug,
{
    let mut out = Vec::new();
    let mut buf = vec![0u8; chunk];
    loop {
        let n = card.read_at(out.len() as u32, &mut buf).expect("read");
        if n == 0 {
            return out;
        }
        out.extend_from_slice(&buf[..n]);
    }
}

#[test]
fn files_of_several_sizes_read_back_exactly_at_any_offset() {
    let sizes = [0usize, 1, 511, 512, 513, 4096, 100_000, 1_000_003];
    let files: Vec<(String, Vec<u8>)> = sizes
        .iter()
        .enumerate()
        .map(|(i, &n)| (format!("F{i}.GCO"), text(n, i as u32)))
        .collect();
    let refs: Vec<(&str, Vec<u8>)> = files.iter().map(|(n, c)| (n.as_str(), c.clone())).collect();
    let img = Image::new("sizes", &refs);
    let mut card = img.card();
    card.mount().expect("mount");
    let mut listed = Vec::new();
    let n = card
        .for_each_file(|_, e| listed.push((e.short.to_string(), e.size)))
        .unwrap();
    assert_eq!(n, files.len());
    for (name, contents) in &files {
        assert!(
            listed.contains(&(name.clone(), contents.len() as u32)),
            "{name} in {listed:?}"
        );
        let e = card.open(name).expect("open");
        assert_eq!(e.size as usize, contents.len());
        for chunk in [1, 97, 512, 4096] {
            if contents.len() > 200_000 && chunk < 512 {
                continue;
            }
            assert_eq!(
                &read_all(&mut card, chunk),
                contents,
                "{name} in {chunk}-byte reads"
            );
        }
        // Reads at arbitrary offsets (a seek, M26) agree with the source.
        for off in [0usize, 1, 511, 512, 777, contents.len() / 2, contents.len()] {
            let mut buf = [0u8; 300];
            let got = card.read_at(off as u32, &mut buf).unwrap();
            let want = &contents[off.min(contents.len())..(off + 300).min(contents.len())];
            assert_eq!(&buf[..got], want, "{name} at {off}");
        }
    }
}

#[test]
fn long_names_are_listed_and_open_by_either_name() {
    let img = Image::new(
        "lfn",
        &[
            ("Benchy with a long name.gcode", text(2000, 1)),
            ("short.g", text(10, 2)),
        ],
    );
    let mut card = img.card();
    card.mount().unwrap();
    let mut listed = Vec::new();
    card.for_each_file(|_, e| listed.push(e.clone())).unwrap();
    let long = listed
        .iter()
        .find(|e| e.long.as_deref() == Some("Benchy with a long name.gcode"))
        .unwrap_or_else(|| panic!("long name missing: {listed:?}"));
    assert!(long.short.contains('~'), "{long:?}");
    assert_eq!(long.size, 2000);
    let short = long.short.clone();
    assert_eq!(
        card.open("Benchy with a long name.gcode").unwrap().size,
        2000
    );
    assert_eq!(card.open(&short).unwrap().size, 2000);
    assert_eq!(card.open(&short.to_lowercase()).unwrap().size, 2000);
    assert_eq!(card.open("/SHORT.G").unwrap().size, 10);
    assert_eq!(card.open("missing.gco"), Err(CardError::NotFound));
    for bad in [
        "",
        "/",
        "a/b.gco",
        "\u{0}",
        "x".repeat(300).as_str(),
        "*?:<>|",
    ] {
        assert!(card.open(bad).is_err(), "{bad:?}");
    }
}

/// Files in nested directories: (path written by `fatfs`, size). The last one is 7
/// directories down, one more than the firmware reads.
fn nested_files() -> Vec<(String, Vec<u8>)> {
    [
        ("ROOT.GCO", 101),
        ("prints/Benchy long name.gcode", 202),
        ("prints/CUBES/CUBE.GCO", 303),
        ("prints/cubes two/cube two.gcode", 404),
        ("a/b/c/d/e/f/SIX.GCO", 505),
        ("a/b/c/d/e/f/g/SEVEN.GCO", 606),
    ]
    .iter()
    .enumerate()
    .map(|(i, (p, n))| (p.to_string(), text(*n, 10 + i as u32)))
    .collect()
}

#[test]
fn nested_directories_are_listed_and_opened_by_path() {
    let files = nested_files();
    let refs: Vec<(&str, Vec<u8>)> = files.iter().map(|(n, c)| (n.as_str(), c.clone())).collect();
    let img = Image::new("nested", &refs);
    let mut card = img.card();
    card.mount().unwrap();
    let mut listed = Vec::new();
    let n = card.for_each_file(|_, e| listed.push(e.clone())).unwrap();
    assert_eq!(n, listed.len());
    // Every file down to 6 levels, by its long path (what was written; every path here has
    // a lower-case component, so a long name) and its short path (upper case, 8.3 components,
    // as many as the long path).
    for (path, contents) in &files[..5] {
        let e = listed
            .iter()
            .find(|e| e.long.as_deref() == Some(path.as_str()))
            .unwrap_or_else(|| panic!("{path} not listed: {listed:?}"));
        assert_eq!(e.size as usize, contents.len(), "{path}");
        assert_eq!(e.short.split('/').count(), path.split('/').count(), "{e:?}");
        for c in e.short.split('/') {
            let (base, ext) = c.split_once('.').unwrap_or((c, ""));
            assert!(
                base.len() <= 8 && ext.len() <= 3 && c == c.to_uppercase(),
                "{e:?}"
            );
        }
        // Opened by the short path, the long path, a mix, lower case, a leading `/`.
        let mixed: Vec<&str> = e
            .short
            .split('/')
            .zip(path.split('/'))
            .enumerate()
            .map(|(i, (s, l))| if i % 2 == 0 { l } else { s })
            .collect();
        for name in [
            e.short.to_string(),
            path.clone(),
            mixed.join("/"),
            e.short.to_lowercase(),
            format!("/{path}"),
        ] {
            let got = card
                .open(&name)
                .unwrap_or_else(|err| panic!("{name}: {err:?}"));
            assert_eq!(got, *e, "{name}");
            assert_eq!(&read_all(&mut card, 512), contents, "{name}");
        }
    }
    assert_eq!(
        listed.len(),
        5,
        "the 7-level file is not listed: {listed:?}"
    );
    assert!(listed.iter().any(|e| e.short == "ROOT.GCO"), "{listed:?}");
    // Refused cleanly: too deep, a directory, missing, a file as a directory, empty parts.
    assert_eq!(
        card.open("a/b/c/d/e/f/g/SEVEN.GCO"),
        Err(CardError::TooDeep)
    );
    assert_eq!(card.open("prints"), Err(CardError::BadName));
    assert_eq!(card.open("prints/missing.gco"), Err(CardError::NotFound));
    assert_eq!(card.open("nowhere/CUBE.GCO"), Err(CardError::NotFound));
    assert_eq!(card.open("ROOT.GCO/CUBE.GCO"), Err(CardError::NotFound));
    for bad in [
        "prints//CUBES/CUBE.GCO",
        "prints/",
        "./ROOT.GCO",
        "prints/../ROOT.GCO",
    ] {
        assert_eq!(card.open(bad), Err(CardError::BadName), "{bad}");
    }
    // Nothing stays open after a refusal: every file still opens.
    for _ in 0..20 {
        assert!(card.open("a/b/c/d/e/nowhere/SIX.GCO").is_err());
        assert!(card.open("prints/cubes/missing").is_err());
    }
    assert_eq!(card.open("a/b/c/d/e/f/six.gco").unwrap().size, 505);
}

/// 3000 random paths (fixed seed) over the nested card: none panics; one that opens gives the
/// file whose contents its listed entry names; refusals leave no directory handle open (every
/// file still opens after them).
#[test]
fn random_paths_never_panic_and_leave_the_card_usable() {
    let files = nested_files();
    let refs: Vec<(&str, Vec<u8>)> = files.iter().map(|(n, c)| (n.as_str(), c.clone())).collect();
    let img = Image::new("random-paths", &refs);
    let mut card = img.card();
    card.mount().unwrap();
    let mut listed = Vec::new();
    card.for_each_file(|_, e| listed.push(e.clone())).unwrap();
    let parts = [
        "prints",
        "PRINTS",
        "cubes",
        "CUBE.GCO",
        "cube.gco",
        "a",
        "b",
        "c",
        "d",
        "e",
        "f",
        "g",
        "SIX.GCO",
        "SEVEN.GCO",
        "ROOT.GCO",
        "..",
        ".",
        "",
        "Benchy long name.gcode",
        "\u{e9}",
        "~1",
        "CUBEST~1",
        "x",
    ];
    let mut x: u64 = 0x2545_F491_4F6C_DD1D;
    let mut next = move |n: usize| {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x % n as u64) as usize
    };
    let mut opened = 0;
    for _ in 0..3000 {
        let n = next(10);
        let mut path: Vec<&str> = (0..n).map(|_| parts[next(parts.len())]).collect();
        if next(4) == 0 {
            path.insert(0, "");
        }
        let path = path.join("/");
        if let Ok(e) = card.open(&path) {
            opened += 1;
            assert!(listed.contains(&e), "{path}: {e:?}");
            let written = files
                .iter()
                .find(|(p, _)| e.long.as_deref() == Some(p.as_str()))
                .unwrap();
            assert_eq!(read_all(&mut card, 512), written.1, "{path}");
        }
    }
    assert!(opened >= 10, "{opened} of 3000 opened");
    for e in &listed {
        assert_eq!(card.open(&e.short).as_ref(), Ok(e));
    }
}

#[test]
fn an_absent_card_is_an_error_not_a_panic() {
    let mut card = Card::new(NoCard);
    assert_eq!(card.mount(), Err(CardError::NoCard));
    assert!(!card.is_mounted());
    assert_eq!(card.open("A.GCO"), Err(CardError::NoCard));
    assert_eq!(card.for_each_file(|_, _| {}), Err(CardError::NoCard));
    let mut buf = [0u8; 8];
    assert_eq!(card.read_at(0, &mut buf), Err(CardError::NoCard));
}

/// The printer with a card, driven as the sim and the board drive it.
struct Bench<D: BlockDevice>
where
    D::Error: core::fmt::Debug,
{
    p: Printer,
    card: Card<D>,
    now: u64,
    out: String,
    pending: Vec<u8>,
    executed: Vec<u32>,
}

impl<D: BlockDevice> Bench<D>
where
    D::Error: core::fmt::Debug,
{
    fn new(card: Card<D>) -> Self {
        let mut p = Printer::new(MachineConfig::ENDER3);
        p.attach_card();
        let mut b = Bench {
            p,
            card,
            now: 0,
            out: String::new(),
            pending: Vec::new(),
            executed: Vec::new(),
        };
        b.tick();
        b
    }

    fn tick(&mut self) {
        let n = self.p.receive(&self.pending, self.now);
        self.pending.drain(..n);
        self.p.service_card(&mut self.card, self.now);
        self.p.poll(self.now);
        while let Some(t) = self.p.next_step_ns() {
            if t > (self.now + TICK_US) * 1000 {
                break;
            }
            self.p.next_step();
        }
        while let Some(r) = self.p.pop_record() {
            if let Record::Executed {
                seq,
                seg,
                segs,
                kind: BlockKind::Job,
                ..
            } = r
            {
                if seg + 1 == segs {
                    self.executed.push(seq);
                }
            }
        }
        self.p.write_output(&mut self.out).unwrap();
        self.now += TICK_US;
    }

    /// Send a line and run until the answers to it have come (its `ok`; at most 30 virtual
    /// seconds: a cancel parks before lines are taken again): returns them.
    fn cmd(&mut self, line: &str) -> String {
        self.out.clear();
        self.pending
            .extend_from_slice(format!("{line}\n").as_bytes());
        for _ in 0..30_000 {
            self.tick();
            if self.out.lines().any(|l| l.starts_with("ok")) {
                break;
            }
        }
        std::mem::take(&mut self.out)
    }

    fn run_until(&mut self, what: &str, max_s: u64, pred: impl Fn(&Self) -> bool) {
        for _ in 0..max_s * 1000 {
            if pred(self) {
                return;
            }
            self.tick();
        }
        panic!("{what} not reached; output {}", self.out);
    }
}

fn job(lines: usize, crlf: bool, final_newline: bool) -> Vec<u8> {
    let nl = if crlf { "\r\n" } else { "\n" };
    let mut s = format!("G90{nl}M83{nl}M302 P1{nl}G92 X10 Y10 Z0 E0{nl}");
    for i in 0..lines {
        if i % 10 == 0 {
            s += &format!(
                ";LAYER:{}{nl}G1 Z{:.2} F600{nl}",
                i / 10,
                0.2 + 0.2 * (i / 10) as f64
            );
        }
        let x = if i % 2 == 0 { 60 } else { 10 };
        s += &format!("G1 X{x} Y{} E0.5 F3000{nl}", 10 + i % 50);
    }
    if !final_newline {
        s += "G1 X20 Y20";
    }
    s.into_bytes()
}

#[test]
fn m_codes_answer_as_marlin_and_a_job_runs_to_done() {
    let j = job(40, true, false);
    let img = Image::new(
        "mcodes",
        &[
            ("CUBE.GCO", j.clone()),
            ("A long name.gcode", text(3000, 5)),
        ],
    );
    let mut b = Bench::new(img.card());
    assert!(b.cmd("M21").contains("echo:SD card ok"));
    let list = b.cmd("M20");
    let lines: Vec<&str> = list.lines().collect();
    let begin = lines
        .iter()
        .position(|l| *l == "Begin file list")
        .expect(&list);
    let end = lines
        .iter()
        .position(|l| *l == "End file list")
        .expect(&list);
    assert_eq!(end - begin, 3, "{list}");
    assert!(
        lines.contains(&format!("CUBE.GCO {}", j.len()).as_str()),
        "{list}"
    );
    assert_eq!(lines.last(), Some(&"ok"), "the ok follows the list: {list}");
    let long = b.cmd("M20 L");
    assert!(long.contains(" 3000 A long name.gcode"), "{long}");
    let missing = b.cmd("M23 NOPE.GCO");
    assert!(
        missing.contains("open failed, File: NOPE.GCO."),
        "{missing}"
    );
    assert!(b.cmd("M27").contains("Not SD printing"));
    let sel = b.cmd("M23 cube.gco");
    assert!(
        sel.contains(&format!("File opened: CUBE.GCO Size: {}", j.len()))
            && sel.contains("File selected"),
        "{sel}"
    );
    assert!(b.cmd("M27 C").contains("Current file: CUBE.GCO"));
    assert!(b.cmd("M26 S999999").contains("refused"));
    b.cmd("M27 S1");
    b.out.clear();
    b.pending.extend_from_slice(b"M24\n");
    b.run_until("SD printing", 5, |b| b.p.sd_printing());
    b.run_until("a status report", 3, |b| {
        b.out.contains("SD printing byte ")
    });
    let status = b.cmd("M27");
    assert!(
        status.contains("SD printing byte ") && status.contains(" progress "),
        "{status}"
    );
    // SD lines are never answered `ok`: only the host's M27 above was.
    b.run_until("Done printing file", 600, |b| {
        b.out.contains("Done printing file")
    });
    assert_eq!(b.p.state(), State::Idle);
    // Every move of the file ran once, in order (the last line had no newline).
    let moves = j
        .split(|&c| c == b'\n')
        .filter(|l| l.starts_with(b"G1"))
        .count();
    assert_eq!(b.executed.len(), moves, "{:?}", b.executed);
    assert!(b.executed.windows(2).all(|w| w[0] < w[1]));
    // The last line (no line end) ran: the head is at X20 (G92 X10 set machine 0 = X10).
    let spm = MachineConfig::ENDER3.axes[0].steps_per_mm;
    assert_eq!(b.p.status().position[0], (10.0 * spm).round() as i32);
    assert!(b.cmd("M27").contains("Not SD printing"));
    assert!(b.cmd("M22").contains("SD card released"));
    assert!(b.cmd("M23 CUBE.GCO").contains("No media"));
}

/// M20 and M20 L list the nested files as Marlin does (`DIR/FILE.GCO size`, `... long/path`),
/// read back here line by line; M23 opens a nested file by the listed path and M24 prints it;
/// a path too deep is refused as Marlin refuses a missing file.
#[test]
fn m20_lists_and_m23_opens_files_in_directories() {
    let j = job(30, false, true);
    let mut files = nested_files();
    files.push(("jobs/Part one/part.gcode".into(), j.clone()));
    let refs: Vec<(&str, Vec<u8>)> = files.iter().map(|(n, c)| (n.as_str(), c.clone())).collect();
    let img = Image::new("m20-nested", &refs);
    let mut b = Bench::new(img.card());
    let listing = |text: &str| -> Vec<Vec<String>> {
        let lines: Vec<&str> = text.lines().collect();
        let begin = lines
            .iter()
            .position(|l| *l == "Begin file list")
            .expect(text);
        let end = lines
            .iter()
            .position(|l| *l == "End file list")
            .expect(text);
        lines[begin + 1..end]
            .iter()
            .map(|l| l.splitn(3, ' ').map(String::from).collect())
            .collect()
    };
    let short = listing(&b.cmd("M20"));
    let long = listing(&b.cmd("M20 L"));
    assert_eq!(short.len(), 6, "every file but the 7-level one: {short:?}");
    assert_eq!(long.len(), 6);
    for (path, contents) in files.iter().filter(|(p, _)| !p.contains("SEVEN")) {
        // M20 L: short path, size, long path (the written one).
        let l = long
            .iter()
            .find(|l| l.get(2) == Some(path))
            .unwrap_or_else(|| panic!("{path} in {long:?}"));
        assert_eq!(l[1], contents.len().to_string(), "{l:?}");
        assert!(!l[0].starts_with('/') && l[0].split('/').count() == path.split('/').count());
        // M20: the same short path and size.
        assert!(
            short.contains(&vec![l[0].clone(), l[1].clone()]),
            "{l:?} in {short:?}"
        );
        // M23 by the listed short path: Marlin's replies, the file's own name.
        let sel = b.cmd(&format!("M23 {}", l[0]));
        let name = l[0].rsplit('/').next().unwrap();
        assert!(
            sel.contains(&format!("File opened: {name} Size: {}", contents.len()))
                && sel.contains("File selected"),
            "{sel}"
        );
    }
    let deep = b.cmd("M23 a/b/c/d/e/f/g/SEVEN.GCO");
    assert!(
        deep.contains("open failed, File: a/b/c/d/e/f/g/SEVEN.GCO."),
        "{deep}"
    );
    // A nested job runs to its end, every move once.
    // (M23 ends the name at a space, as Marlin's M23 does: the directory by its short name,
    // lower case, the file by its long name, a leading `/`.)
    let part = &long
        .iter()
        .find(|l| l[2] == "jobs/Part one/part.gcode")
        .unwrap()[0];
    let dir = part.rsplit_once('/').unwrap().0.to_lowercase();
    let sel = b.cmd(&format!("M23 /{dir}/part.gcode"));
    assert!(sel.contains("File selected"), "{sel}");
    assert!(b.cmd("M27 C").contains(&format!("Current file: {part}")));
    b.pending.extend_from_slice(b"M24\n");
    b.run_until("Done printing file", 600, |b| {
        b.out.contains("Done printing file")
    });
    let moves = j
        .split(|&c| c == b'\n')
        .filter(|l| l.starts_with(b"G1"))
        .count();
    assert_eq!(b.executed.len(), moves);
}

#[test]
fn without_a_card_commands_say_so() {
    let mut b = Bench::new(Card::new(NoCard));
    assert!(b.out.contains("SD init fail") || b.cmd("M21").contains("SD init fail"));
    for c in ["M20", "M23 A.GCO", "M32 A.GCO"] {
        let r = b.cmd(c);
        assert!(r.contains("No media"), "{c}: {r}");
    }
    // No card slot at all (a driver without one).
    let mut p = Printer::new(MachineConfig::ENDER3);
    assert_eq!(p.receive(b"M20\nM24\nM27\n", 0), 12);
    p.poll(0);
    let mut out = String::new();
    p.write_output(&mut out).unwrap();
    assert!(
        out.contains("No media") && out.contains("Not SD printing"),
        "{out}"
    );
}

#[test]
fn bad_names_and_arguments_never_panic() {
    let img = Image::new("bad", &[("A.GCO", text(100, 1))]);
    let mut b = Bench::new(img.card());
    for c in [
        "M23 ",
        "M23 /",
        "M23 ../../etc/passwd",
        "M23 a/b/c.gco",
        "M23 \u{7f}\u{1}",
        "M23 名前.gcode",
        "M26 S-5",
        "M26 S4294967295",
        "M27 S9999",
        "M32 nothing.gco",
        "M20 Q",
        "M24",
        "M25",
        "M524",
    ] {
        let r = b.cmd(c);
        assert!(r.contains("ok"), "{c}: {r}");
    }
}

/// Random SD command lines (names of random bytes, random arguments, commands while a job
/// prints): no panic, and every line is answered with exactly one `ok` (none lost, none
/// doubled: file lines never answer). Fixed seed: the same lines on every run.
#[test]
fn random_sd_command_lines_are_each_answered_once() {
    let img = Image::new(
        "random",
        &[("A.GCO", job(30, false, true)), ("B b.gcode", text(700, 3))],
    );
    let mut b = Bench::new(img.card());
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let heads = [
        "M20", "M20 L", "M21", "M22", "M23 ", "M24", "M26 S", "M27", "M27 S", "M27 C", "M32 ",
        "M25", "M524",
    ];
    let names = [
        "A.GCO",
        "a.gco",
        "B b.gcode",
        "B~1.GCO",
        "/A.GCO",
        "",
        "..",
        "A.GCO 123",
    ];
    let mut history: Vec<String> = Vec::new();
    for _ in 0..300 {
        let h = heads[(next() % heads.len() as u64) as usize];
        let mut line = h.to_string();
        match h {
            "M23 " | "M32 " => match next() % 3 {
                0 => line += names[(next() % names.len() as u64) as usize],
                _ => {
                    for _ in 0..next() % 20 {
                        line.push(char::from(32 + (next() % 95) as u8));
                    }
                }
            },
            "M26 S" | "M27 S" => line += &(next() % 100_000).to_string(),
            _ => {}
        }
        let line = line.replace(['\n', '\r'], "");
        let out = b.cmd(&line);
        history.push(format!("{line:?} -> {out:?}"));
        let oks = out.lines().filter(|l| l.starts_with("ok")).count();
        assert_eq!(
            oks,
            1,
            "{line:?} answered {out:?} in state {:?} after {:#?}",
            b.p.state(),
            &history[history.len().saturating_sub(8)..]
        );
    }
}

/// M524 while printing from the card: the job ends, the printer reports `Cancelled` (as after a
/// host job's cancel), the host's next unnumbered lines are taken (not discarded as the rest
/// of a cancelled stream: the stream was not the job), and while a layer pause holds a full
/// queue M20 is still answered.
#[test]
fn cancel_and_list_while_paused() {
    let img = Image::new("cancel", &[("A.GCO", job(400, false, true))]);
    let mut b = Bench::new(img.card());
    b.cmd("M23 A.GCO");
    b.pending.extend_from_slice(b"M24\n");
    b.run_until("queue full", 20, |b| b.p.status().commands >= 8);
    b.pending.extend_from_slice(b"M25\n");
    b.run_until("paused", 120, |b| b.p.state() == State::Paused);
    let list = b.cmd("M20");
    assert!(
        list.contains("End file list") && list.contains("A.GCO"),
        "{list}"
    );
    assert!(b.p.sd_printing());
    b.cmd("M524");
    b.run_until("cancelled", 60, |b| b.p.state() == State::Cancelled);
    assert!(!b.p.sd_printing());
    let before = b.executed.len();
    let out = b.cmd("G1 X30 F3000");
    assert!(!out.contains("discarding"), "{out}");
    b.run_until("the host's move ran", 20, |b| b.executed.len() > before);
    b.run_until("idle", 20, |b| b.p.state() == State::Idle);
}

/// A job started at a line's byte offset (M26 S<offset> + M24, and `start_sd_job` as the
/// power-cut resume uses it) runs exactly the moves from that line on.
#[test]
fn a_job_starts_at_a_line_offset() {
    let j = job(60, true, true);
    let text = String::from_utf8(j.clone()).unwrap();
    // The offset of the 31st G1 line and the moves from there.
    let starts: Vec<usize> = std::iter::once(0)
        .chain(text.match_indices('\n').map(|(i, _)| i + 1))
        .filter(|&i| i < text.len())
        .collect();
    let g1: Vec<usize> = starts
        .iter()
        .copied()
        .filter(|&i| text[i..].starts_with("G1"))
        .collect();
    let from = g1[30];
    let expected = g1.len() - 30;
    for how in ["M26", "start_sd_job"] {
        let img = Image::new(&format!("offset-{how}"), &[("A.GCO", j.clone())]);
        let mut b = Bench::new(img.card());
        // The modal state a resume restores first (here: the file's header).
        b.cmd("G90");
        b.cmd("M83");
        b.cmd("M302 P1");
        if how == "M26" {
            b.cmd("M23 A.GCO");
            assert!(b.cmd(&format!("M26 S{from}")).lines().any(|l| l == "ok"));
            b.pending.extend_from_slice(b"M24\n");
        } else {
            b.p.start_sd_job("A.GCO", from as u32);
        }
        b.run_until("Done printing file", 600, |b| {
            b.out.contains("Done printing file")
        });
        assert_eq!(b.executed.len(), expected, "{how}");
    }
}

/// A listing longer than the port's output ring (4 KiB) goes out whole, over several service
/// calls, with its `ok` last.
#[test]
fn a_long_listing_is_never_cut() {
    let files: Vec<(String, Vec<u8>)> = (0..80)
        .map(|i| {
            (
                format!("a rather long file name number {i:03}.gcode"),
                text(10 + i, i as u32),
            )
        })
        .collect();
    let refs: Vec<(&str, Vec<u8>)> = files.iter().map(|(n, c)| (n.as_str(), c.clone())).collect();
    let img = Image::new("long-list", &refs);
    let mut b = Bench::new(img.card());
    let out = b.cmd("M20 L");
    let lines: Vec<&str> = out.lines().collect();
    let begin = lines
        .iter()
        .position(|l| *l == "Begin file list")
        .expect(&out);
    let end = lines
        .iter()
        .position(|l| *l == "End file list")
        .expect(&out);
    assert!(out.len() > 4096, "{}", out.len());
    for (name, c) in &files {
        let want = format!(" {} {name}", c.len());
        assert_eq!(
            lines[begin..end]
                .iter()
                .filter(|l| l.ends_with(&want))
                .count(),
            1,
            "{name}"
        );
    }
    assert_eq!(end - begin - 1, files.len());
    assert_eq!(lines.last(), Some(&"ok"));
    assert_eq!(
        b.p.port(firmware::link::PortId::Usb).stats().output_dropped,
        0
    );
}
