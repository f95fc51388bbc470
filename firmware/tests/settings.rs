//! Runtime settings through the printer's host link: M92 M201 M203 M204 M205 M206 M301 M304
//! M760 M851 M906 change, refuse out-of-range values with `echo:`, M500/M501/M502 go through
//! the flash store (a NOR-flash model), and M503's output sent back gives the same settings.

use firmware::config::MachineConfig;
use firmware::gcode::{parse_line, Command, HeatCommand};
use firmware::printer::{Policy, Printer};
use firmware::storage::{Moment, NorFlashModel, RecordStore, Settings, SettingsStore};

/// Two 4 KiB sectors, 16-byte words.
type Flash = NorFlashModel<Vec<u8>, 16, 4096>;
type Store = SettingsStore<Flash>;

fn store() -> Store {
    SettingsStore::new(Flash::erased(vec![0; 8192]), 0..8192).unwrap()
}

/// A printer with a store, driven on virtual time the way the board's main loop does.
struct Bench {
    p: Printer,
    store: Store,
    now_us: u64,
}

impl Bench {
    fn new() -> Self {
        Self::with_store(store())
    }

    /// Boot with this store (loads the saved settings).
    fn with_store(mut store: Store) -> Self {
        let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
        p.load_settings(&mut store);
        Bench {
            p,
            store,
            now_us: 0,
        }
    }

    fn tick(&mut self) -> String {
        let t_ns = self.now_us * 1000;
        while let Some(t) = self.p.next_step_ns() {
            if t > t_ns {
                break;
            }
            self.p.next_step();
        }
        self.p.poll(self.now_us);
        self.p.service_store(&mut self.store);
        self.now_us += 1000;
        let mut s = String::new();
        self.p.write_output(&mut s).unwrap();
        s
    }

    /// Send one line; return everything written until its `ok` (and the ok).
    fn send(&mut self, line: &str) -> String {
        let bytes = format!("{line}\n");
        assert_eq!(self.p.receive(bytes.as_bytes(), self.now_us), bytes.len());
        let mut out = String::new();
        for _ in 0..120_000 {
            out.push_str(&self.tick());
            if out.lines().any(|l| l.starts_with("ok")) {
                // Let a pending store request finish too.
                for _ in 0..3 {
                    out.push_str(&self.tick());
                }
                return out;
            }
        }
        panic!("no ok for {line:?}: {out}");
    }

    fn settings(&self) -> Settings {
        self.p.settings()
    }

    /// Power off: the store's flash, to boot a new printer with.
    fn power_off(self) -> Store {
        self.store
    }
}

fn no_error(out: &str) {
    assert!(!out.contains("Error"), "{out}");
}

#[test]
fn each_setting_m_code_changes_its_value() {
    let mut b = Bench::new();
    for line in [
        "M92 X81.5 E95.25",
        "M203 Z12",
        "M201 X1500 E4000",
        "M204 P700 R1200 T900",
        "M205 J0.02",
        "M206 Z-0.3",
        "M301 P22 I1.125 D80",
        "M304 P70 I1.5 D400",
        "M906 X700 E650",
        "M760 R3 Z4",
    ] {
        no_error(&b.send(line));
    }
    let s = b.settings();
    assert_eq!(s.steps_per_mm, [81.5, 80.0, 400.0, 95.25]);
    assert_eq!(s.max_feed_mm_s[2], 12.0);
    assert_eq!(s.max_accel_mm_s2, [1500.0, 500.0, 100.0, 4000.0]);
    assert_eq!(
        (
            s.accel_print_mm_s2,
            s.accel_retract_mm_s2,
            s.accel_travel_mm_s2
        ),
        (700.0, 1200.0, 900.0)
    );
    assert_eq!(s.junction_deviation_mm, 0.02);
    assert_eq!(s.home_offset_mm, [0.0, 0.0, -0.3]);
    assert_eq!(
        s.hotend_pid.map(|g| (g.kp, g.ki, g.kd)),
        Some((22.0, 1.125, 80.0))
    );
    assert_eq!(s.bed_pid.map(|g| g.kd), Some(400.0));
    // Y and Z keep the Ender-3 defaults (580 mA, MachineConfig::ENDER3).
    assert_eq!(s.driver_current_ma, [700, 580, 580, 650]);
    assert_eq!((s.pause.retract_mm, s.pause.lift_z_mm), (3.0, 4.0));
    // Reports with no parameter, as G-code.
    assert!(b.send("M92").contains("echo:  M92 X81.5 Y80 Z400 E95.25"));
    assert!(b.send("M906").contains("M906 X700 Y580 Z580 E650"));
}

#[test]
fn out_of_range_values_are_refused_with_echo_and_nothing_changes() {
    let mut b = Bench::new();
    let before = b.settings();
    for line in [
        "M92 X0",
        "M92 X100 Y-80",
        "M203 Z0",
        "M201 E0",
        "M205 J0.5",
        "M206 Z5000",
        "M906 X5000",
        "M906 Y50",
    ] {
        let out = b.send(line);
        assert!(
            out.contains("echo:") && out.contains("out of range"),
            "{line}: {out}"
        );
        assert!(out.contains("nothing changed"), "{line}: {out}");
        no_error(&out);
    }
    assert_eq!(b.settings(), before);
    // Marlin's jerk words are not ours: said so, J still applies.
    let out = b.send("M205 J0.05 X8 Y8");
    assert!(out.contains("not used"), "{out}");
    assert_eq!(b.settings().junction_deviation_mm, 0.05);
    let out = b.send("M851 Z-1");
    assert!(out.contains("no Z probe"), "{out}");
    no_error(&out);
}

#[test]
fn steps_per_mm_change_only_when_idle_and_keep_the_head_where_it_is() {
    let mut b = Bench::new();
    b.send("G28");
    b.send("G1 X100 F6000");
    b.send("M400");
    let pos = b.p.status().position;
    assert_eq!(pos[0], 8000);
    b.send("M92 X160");
    // Same place, new steps: 100 mm × 160.
    assert_eq!(b.p.status().position[0], 16_000);
    b.send("G1 X50");
    b.send("M400");
    assert_eq!(b.p.status().position[0], 8000, "50 mm × 160 steps/mm");
    // While moving: refused, nothing changes.
    assert_eq!(b.p.receive(b"G1 X200 F600\n", b.now_us), 13);
    for _ in 0..50 {
        b.tick();
    }
    let out = b.send("M92 X80");
    assert!(out.contains("only while idle"), "{out}");
    no_error(&out);
    assert_eq!(b.settings().steps_per_mm[0], 160.0);
}

#[test]
fn m503_sent_back_gives_the_same_settings() {
    let mut b = Bench::new();
    for line in [
        // M350 scales steps/mm: M503 must print it before M92 for the paste-back to hold.
        "M350 X32 E8",
        "M569 S0 Y E",
        "M92 X81.5 Y79.875 Z401 E95.25",
        "M203 X300 Y250 Z12 E40",
        "M201 X1500 Y1400 Z150 E4000",
        "M204 P700 R1200 T900",
        "M205 J0.021",
        "M206 X-1.5 Y2.25 Z-0.3",
        "M301 P22.2 I1.08 D114",
        "M304 P70.5 I1.5 D400.125",
        "M906 X700 Y710 Z900 E650",
        "M760 R3.5 Z4 X200 Y210 F4800 S2.5 V15 L0.25",
    ] {
        no_error(&b.send(line));
    }
    let want = b.settings();
    let report = b.send("M503");
    let mut fresh = Bench::new();
    assert_ne!(fresh.settings(), want);
    let mut sent = 0;
    for line in report.lines().filter_map(|l| l.strip_prefix("echo:")) {
        let g = line.trim_start();
        // Everything the report prints is G-code our own parser reads.
        let parsed = parse_line(g.as_bytes()).unwrap_or_else(|e| panic!("{g:?}: {e:?}"));
        if let Some(Command::Settings(_) | Command::Heat(HeatCommand::SetPid { .. })) =
            parsed.command
        {
            sent += 1;
        }
        no_error(&fresh.send(g));
    }
    assert!(sent >= 7, "{report}");
    assert_eq!(want.microsteps, [32, 16, 16, 8]);
    assert_eq!(want.stealthchop, [true, false, true, false]);
    assert_eq!(fresh.settings(), want, "{report}");
}

#[test]
fn m500_saves_and_a_new_boot_loads_m501_and_m502() {
    let mut b = Bench::new();
    let factory = b.settings();
    no_error(&b.send("M92 E97"));
    no_error(&b.send("M203 X250"));
    no_error(&b.send("M350 Z4"));
    no_error(&b.send("M569 S0 X"));
    let out = b.send("M500");
    assert!(out.contains("Settings Stored"), "{out}");
    let saved = b.settings();
    // A new boot on the same flash has them.
    let mut b = Bench::with_store(b.power_off());
    assert_eq!(b.settings(), saved);
    // Changed, then M501: back to the saved ones; M502: factory (not saved).
    b.send("M203 X100");
    let out = b.send("M501");
    assert!(out.contains("Settings loaded"), "{out}");
    assert_eq!(b.settings(), saved);
    let out = b.send("M502");
    assert!(out.contains("Default Settings Loaded"), "{out}");
    assert_eq!(b.settings(), factory);
    let b = Bench::with_store(b.power_off());
    assert_eq!(b.settings(), saved, "M502 alone does not touch the store");
}

#[test]
fn m500_while_moving_is_carried_out_when_the_motion_ends() {
    let mut b = Bench::new();
    b.send("G28");
    b.send("M92 E99");
    b.send("G1 X200 F3000");
    let out = b.send("M500");
    assert!(
        !out.contains("Settings Stored"),
        "saved while moving: {out}"
    );
    assert!(b.p.store_request_pending());
    let out = b.send("M400");
    let out = out + &b.tick();
    assert!(out.contains("Settings Stored"), "{out}");
    let b = Bench::with_store(b.power_off());
    assert_eq!(b.settings().steps_per_mm[3], 99.0);
}

#[test]
fn a_corrupt_store_boots_with_factory_defaults_and_says_so() {
    let mut b = Bench::new();
    b.send("M92 E97");
    b.send("M500");
    let factory = Printer::new(MachineConfig::ENDER3).settings();
    let mut flash = b.power_off().into_flash();
    // Damage every byte of the saved record's two frames (208 bytes each from offset 32,
    // after the sector's header) but their heads: neither copy is whole, no older one exists.
    let used = flash.bytes().iter().rposition(|b| *b != 0xFF).unwrap();
    for i in 32..=used {
        if (i - 32) % 208 >= 16 {
            flash.bytes_mut()[i] ^= 0x5A;
        }
    }
    let mut store = SettingsStore::new(flash, 0..8192).unwrap();
    let mut p = Printer::with_policy(MachineConfig::ENDER3, Policy::FIRMWARE);
    p.load_settings(&mut store);
    let mut out = String::new();
    p.write_output(&mut out).unwrap();
    assert_eq!(p.settings(), factory, "{out}");
    assert!(
        out.contains("echo:saved settings unusable") && out.contains("factory defaults"),
        "{out}"
    );
    assert!(!out.contains("Error"), "{out}");
}

#[test]
fn an_older_format_falls_back_with_an_echo() {
    let mut store = store();
    let mut old = Printer::new(MachineConfig::ENDER3).settings();
    old.steps_per_mm[3] = 120.0;
    let mut bytes = old.encode();
    bytes[0] = 0; // format 0
    let n = bytes.len();
    let crc = crc32(&bytes[..n - 4]);
    bytes[n - 4..].copy_from_slice(&crc.to_le_bytes());
    store
        .write(firmware::storage::SETTINGS_KEY, &bytes, Moment::Idle)
        .unwrap();
    let mut p = Printer::new(MachineConfig::ENDER3);
    p.load_settings(&mut store);
    let mut out = String::new();
    p.write_output(&mut out).unwrap();
    assert!(
        out.contains("echo:saved settings unusable (record format 0"),
        "{out}"
    );
    assert!(out.contains("factory defaults loaded"), "{out}");
    assert_eq!(p.settings().steps_per_mm[3], 93.0);
}

/// One range table (issue 24: `M204 S0.000001` ran, and M500 refused it): every settings
/// command takes the ends of its range in `firmware::ranges` and M500 saves them (a new boot
/// loads the same), and refuses a value just outside with nothing changed.
#[test]
fn what_a_command_takes_m500_saves_and_what_it_refuses_changes_nothing() {
    use firmware::ranges::*;
    let per_min = |b: Bound| (b.min * 60.0, b.max * 60.0);
    let cases: Vec<(&str, f32, f32, f32)> = vec![
        (
            "M92 E",
            STEPS_PER_MM.min,
            STEPS_PER_MM.max,
            STEPS_PER_MM.max * 2.0,
        ),
        ("M201 X", ACCEL.min, ACCEL.max, ACCEL.min / 2.0),
        ("M203 Y", MAX_FEED.min, MAX_FEED.max, MAX_FEED.max * 2.0),
        ("M204 S", ACCEL.min, ACCEL.max, 0.000001),
        ("M204 P", ACCEL.min, ACCEL.max, ACCEL.max * 2.0),
        ("M204 R", ACCEL.min, ACCEL.max, -1.0),
        ("M204 T", ACCEL.min, ACCEL.max, 1e30),
        (
            "M205 J",
            JUNCTION_DEVIATION.min,
            JUNCTION_DEVIATION.max,
            0.5,
        ),
        (
            "M206 Z",
            HOME_OFFSET.min,
            HOME_OFFSET.max,
            HOME_OFFSET.max * 2.0,
        ),
        ("M301 P", PID_GAIN.min, PID_GAIN.max, 1e30),
        ("M304 D", PID_GAIN.min, PID_GAIN.max, -0.5),
        (
            "M906 X",
            DRIVER_CURRENT.min,
            DRIVER_CURRENT.max,
            DRIVER_CURRENT.max + 100.0,
        ),
        (
            "M760 R",
            PAUSE_RETRACT.min,
            PAUSE_RETRACT.max,
            PAUSE_RETRACT.max + 1.0,
        ),
        ("M760 S", SPEEDUP.min, SPEEDUP.max, 0.5),
        ("M760 V", VOLUMETRIC.min, VOLUMETRIC.max, 0.0),
        ("M760 L", SEGMENT.min, SEGMENT.max, 0.001),
        ("M760 L", 0.0, SEGMENT.max, 0.049),
        // Machine-limited: Z within the travel, X/Y inside it, F within the X/Y limits.
        ("M760 Z", PAUSE_LIFT.min, 250.0, 251.0),
        ("M760 X", 0.0, 235.0, 236.0),
        (
            "M760 F",
            per_min(PARK_FEED).0,
            500.0 * 60.0,
            500.0 * 60.0 + 60.0,
        ),
    ];
    for (code, lo, hi, bad) in cases {
        for v in [lo, hi] {
            let mut b = Bench::new();
            let out = b.send(&format!("{code}{v}"));
            assert!(!out.contains("refused"), "{code}{v}: {out}");
            let set = b.settings();
            let out = b.send("M500");
            assert!(out.contains("Settings Stored"), "{code}{v}: {out}");
            let b = Bench::with_store(b.power_off());
            assert_eq!(b.settings(), set, "{code}{v} after a reboot");
        }
        let mut b = Bench::new();
        let before = b.settings();
        let out = b.send(&format!("{code}{bad}"));
        assert!(out.contains("echo:refused:"), "{code}{bad}: {out}");
        assert_eq!(b.settings(), before, "{code}{bad}");
    }
}

/// Areas a store cannot use (issue 24): every byte 0 (zeroed, or another firmware's), random
/// bytes, a half-erased first sector over zeros.
fn foreign_areas() -> Vec<(&'static str, Vec<u8>)> {
    let mut seed = 0x2024_0024u32;
    let random: Vec<u8> = (0..8192)
        .map(|_| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as u8
        })
        .collect();
    let mut half = vec![0u8; 8192];
    half[..1024].fill(0xFF);
    vec![
        ("zeros", vec![0; 8192]),
        ("random bytes", random),
        ("half-erased", half),
    ]
}

#[test]
fn a_foreign_settings_area_loads_defaults_and_the_next_m500_takes_a_sector_of_it() {
    let factory = Printer::new(MachineConfig::ENDER3).settings();
    for (what, bytes) in foreign_areas() {
        let mut b = Bench::with_store(SettingsStore::new(Flash::new(bytes), 0..8192).unwrap());
        let mut boot = String::new();
        b.p.write_output(&mut boot).unwrap();
        assert_eq!(b.settings(), factory, "{what}: {boot}");
        no_error(&boot);
        b.send("M92 E97");
        let out = b.send("M500");
        assert!(out.contains("Settings Stored"), "{what}: {out}");
        no_error(&out);
        let saved = b.settings();
        // A new boot has them; the area works as any other from then on.
        let mut b = Bench::with_store(b.power_off());
        assert_eq!(b.settings(), saved, "{what}");
        b.send("M92 E98");
        let out = b.send("M500");
        assert!(
            out.contains("Settings Stored") && !out.contains("erased first"),
            "{what}: {out}"
        );
        let b = Bench::with_store(b.power_off());
        assert_eq!(b.settings().steps_per_mm[3], 98.0, "{what}");
    }
    // What the first boot and the M500 say on the zeroed area.
    let mut b = Bench::with_store(SettingsStore::new(Flash::new(vec![0; 8192]), 0..8192).unwrap());
    let mut boot = String::new();
    b.p.write_output(&mut boot).unwrap();
    assert!(
        boot.contains("echo:no saved settings: the flash area holds nothing this firmware saved whole (factory defaults; M500 saves over it)"),
        "{boot}"
    );
    let out = b.send("M500");
    assert!(out.contains("; a flash sector was erased first)"), "{out}");
}

/// A layer pause says the job is kept only once its record is in flash: on a foreign area
/// the record's write reclaims it (and says so); on a flash that refuses every write, the
/// message says the job was not kept (issue 24: it said "keeping job" and then "record not
/// written").
#[test]
fn the_kept_job_is_announced_only_when_written() {
    let job = |b: &mut Bench| {
        b.send("M302 P1");
        b.send("G28");
        b.send("M400");
        b.send("M110 N1");
        let lines = [
            ";LAYER:0",
            "G1 Z0.2 F600",
            "G1 X50 Y50 E1 F3000",
            ";LAYER:1",
            "G1 Z0.4",
            "G1 X10 Y10 E2",
        ];
        let mut out = String::new();
        for (k, l) in lines.iter().enumerate() {
            let n = k + 2;
            let body = format!("N{n} {l}");
            let cs = body.bytes().fold(0u8, |a, b| a ^ b);
            if k == 2 {
                // The pause request in layer 0.
                assert_eq!(b.p.receive(b"M601\n", b.now_us), 5);
            }
            out.push_str(&b.send(&format!("{body}*{cs}")));
        }
        for _ in 0..30_000 {
            out.push_str(&b.tick());
            if out.contains("//action:paused") && !b.p.store_request_pending() {
                break;
            }
        }
        out.push_str(&b.tick());
        out
    };
    // A foreign area: the record is written (the area reclaimed) and only then announced.
    let mut b = Bench::with_store(SettingsStore::new(Flash::new(vec![0; 8192]), 0..8192).unwrap());
    let out = job(&mut b);
    assert!(out.contains("//action:paused"), "{out}");
    let kept = out
        .lines()
        // Paused at the end of the first layer printed (numbered 1): the job goes on with layer 2.
        .find(|l| l.contains("power-cut resume: keeping job at layer 2, host line"))
        .unwrap_or_else(|| panic!("{out}"));
    assert!(kept.contains("erased first"), "{kept}");
    assert!(!out.contains("not kept"), "{out}");
    assert!(b.power_off().load_job().unwrap().is_some());
    // A flash whose writes all fail (a worn part): nothing claims the job was kept.
    let mut flash = Flash::erased(vec![0; 8192]);
    flash.cut_power(0, firmware::storage::Cut::Before);
    let mut b = Bench::with_store(SettingsStore::new(flash, 0..8192).unwrap());
    let out = job(&mut b);
    assert!(out.contains("//action:paused"), "{out}");
    assert!(!out.contains("keeping job"), "{out}");
    assert!(
        out.contains("echo:power-cut resume: job at layer 2 not kept: flash error"),
        "{out}"
    );
}

/// CRC-32 (ISO-HDLC), bit by bit: an implementation independent of the firmware's.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for b in bytes {
        c ^= u32::from(*b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// M92 and M350 give the step interrupt a new frame (the position re-expressed in the new
/// steps, the limits at the new scale: `Printer::travel_frame`), M203 a new configuration
/// epoch (its floors): on the emulated board the interrupt kept the boot frame and stopped X
/// at 117.5 mm after `M92 X160` while M114 said 150 mm.
#[test]
fn m92_m350_m203_give_the_step_interrupt_its_new_frame_and_floors() {
    let mut b = Bench::new();
    let f0 = b.p.travel_frame();
    assert_eq!(f0.limits[0], (0, 18_800));
    let e0 = b.p.config_epoch();
    no_error(&b.send("G1 X5 F3000"));
    for _ in 0..2_000 {
        b.tick();
    }
    no_error(&b.send("M92 X160"));
    let f1 = b.p.travel_frame();
    assert_eq!(f1.epoch, f0.epoch + 1);
    assert_eq!(f1.limits[0], (0, 37_600));
    // 5 mm: 400 steps before, 800 now.
    assert_eq!(f1.pos[0], 800);
    no_error(&b.send("G1 X10 F3000"));
    for _ in 0..2_000 {
        b.tick();
    }
    no_error(&b.send("M350 Y32"));
    let f2 = b.p.travel_frame();
    assert_eq!(f2.epoch, f1.epoch + 1);
    assert_eq!(f2.limits[1], (0, 37_600));
    // X moved on to 10 mm: 1600 steps at 160 per mm.
    assert_eq!(f2.pos[0], 1_600);
    let e2 = b.p.config_epoch();
    assert!(e2 > e0);
    no_error(&b.send("M203 X50"));
    assert_eq!(b.p.travel_frame().epoch, f2.epoch, "no new frame");
    assert!(b.p.config_epoch() > e2, "new floors");
}
