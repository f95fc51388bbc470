//! `sim serve --flash FILE`: settings saved with M500 in one session are there in the next
//! (the file is the board's settings area, driven through the firmware's own store).

use sim::run::Policy;
use sim::serve::ServeArgs;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tests::pty::{checksum, serve_in_thread};

/// One `sim serve` session: send `lines` (each waits for its `ok`), return everything read.
fn session(flash: &Path, lines: &[&str]) -> Vec<String> {
    session_with(flash, lines, None)
}

/// A `sim serve` session: send `lines` (each waits for its `ok`); with `pause_after = Some(k)`,
/// write a realtime `M25` (layer pause) after the k-th line and, once every line is sent, read
/// until the printer says it keeps the paused job. Returns everything read.
fn session_with(flash: &Path, lines: &[&str], pause_after: Option<usize>) -> Vec<String> {
    let flash: PathBuf = flash.to_path_buf();
    let (server, mut host) = serve_in_thread(
        ServeArgs {
            speed: 20.0,
            record: None,
            policy: Policy::Firmware,
            exit_after_idle: 0.5,
            link: None,
            flash: Some(flash),
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
    let pausing = pause_after.is_some();
    // The pause's record: kept, or said not to be (not a kept job discarded by a new job).
    let keeps = |l: &str| {
        l.contains("power-cut resume: keeping job")
            || l.contains("power-cut resume: job at layer")
            || l.contains("power-cut resume: not kept")
    };
    for (i, l) in lines.iter().enumerate() {
        if pausing && host.seen.iter().any(|s| keeps(s)) {
            break; // parked: the queue is full, the rest of the job waits (the power goes now)
        }
        if pause_after == Some(i) {
            host.write("M25");
        }
        host.write(l);
        host.until(&format!("ok for {l:?}"), Duration::from_secs(30), |s| {
            s.starts_with("ok") || (pausing && keeps(s))
        });
    }
    if pausing && !host.seen.iter().any(|s| keeps(s)) {
        host.until("the paused-job record", Duration::from_secs(60), keeps);
    }
    // The store runs in the session loop right after the `ok`: wait for its answer.
    let stored = |l: &str| l.contains("Settings Stored");
    if lines.contains(&"M500") && !host.seen.iter().any(|s| stored(s)) {
        host.until("M500's store", Duration::from_secs(30), stored);
    }
    let seen = std::mem::take(&mut host.seen);
    drop(host);
    server.record().expect("serve session");
    seen
}

#[test]
fn settings_saved_in_one_session_are_reported_in_the_next() {
    let file = std::env::temp_dir().join(format!("sim-serve-flash-{}.bin", std::process::id()));
    let _ = std::fs::remove_file(&file);
    let first = session(&file, &["M92 X81.25 E97", "M203 Z12", "M500"]);
    assert!(
        first.iter().any(|l| l.starts_with("echo:Settings Stored")),
        "{first:?}"
    );
    assert_eq!(std::fs::metadata(&file).unwrap().len(), 262_144);

    let second = session(&file, &["M503"]);
    assert!(
        second
            .iter()
            .any(|l| l == "echo:Settings loaded from flash"),
        "{second:?}"
    );
    assert!(
        second.iter().any(|l| l == "echo:  M92 X81.25 Y80 Z400 E97"),
        "{second:?}"
    );
    assert!(
        second.iter().any(|l| l == "echo:  M203 X500 Y500 Z12 E25"),
        "{second:?}"
    );
    // Without the file, a session starts from the factory values.
    let third =
        std::env::temp_dir().join(format!("sim-serve-flash-{}-new.bin", std::process::id()));
    let _ = std::fs::remove_file(&third);
    let fresh = session(&third, &["M92"]);
    assert!(
        fresh.iter().any(|l| l == "echo:  M92 X80 Y80 Z400 E93"),
        "{fresh:?}"
    );
    let _ = std::fs::remove_file(&file);
    let _ = std::fs::remove_file(&third);
}

/// A numbered job of 4 layers (Cura markers). Returns the lines (with `N` and checksum) and, per
/// layer, the `N` of its first motion line (index 0: layer 1 in the one numbering, the n-th
/// layer printed from 1).
fn numbered_job() -> (Vec<String>, Vec<u32>) {
    let mut body: Vec<String> = ["G28", "M83", "G92 E0"].map(String::from).to_vec();
    let mut first = Vec::new();
    for layer in 0..4 {
        body.push(format!(";LAYER:{layer}"));
        first.push(body.len() as u32 + 1);
        body.push(format!("G1 Z{:.1} F600", 0.2 * (layer + 1) as f32));
        for i in 0..16 {
            let (x, y) = [(20, 20), (120, 20), (120, 120), (20, 120)][i % 4];
            body.push(format!("G1 X{x} Y{y} E3 F1800"));
        }
    }
    let lines = body
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let l = format!("N{} {b}", i + 1);
            format!("{l}*{}", checksum(&l))
        })
        .collect();
    (lines, first)
}

#[test]
fn a_paused_job_kept_in_one_session_is_announced_in_the_next() {
    let file = std::env::temp_dir().join(format!("sim-serve-job-{}.bin", std::process::id()));
    let _ = std::fs::remove_file(&file);
    let (lines, first) = numbered_job();
    let refs: Vec<&str> = lines.iter().map(String::as_str).collect();
    let mut all = vec!["M110 N0"];
    all.extend(refs);
    let seen = session_with(&file, &all, Some(12));
    let kept = seen
        .iter()
        .find(|l| l.contains("power-cut resume: keeping job at layer"))
        .unwrap_or_else(|| panic!("{seen:?}"));
    // "… keeping job at layer L, host line N": N is the first motion line of layer L (layers
    // numbered from 1: `first[L - 1]`).
    let words: Vec<&str> = kept.split([' ', ',']).collect();
    let layer: usize = words[words.iter().position(|w| *w == "layer").unwrap() + 1]
        .parse()
        .unwrap();
    let line: u32 = words.last().unwrap().parse().unwrap();
    assert!(layer >= 1, "{kept}");
    assert_eq!(line, first[layer - 1], "{kept}");

    // The power goes (the session ends while paused); the next session announces the job.
    let next = session(&file, &["M105"]);
    let want = format!(
        "//action:notification Paused job kept: layer {layer} at Z{:.3}, continue from host line {line}",
        0.2 * layer as f32
    );
    assert!(
        next.iter().any(|l| l.starts_with(&want)),
        "{want}\n{next:?}"
    );
    let _ = std::fs::remove_file(&file);
}

/// The settings area as issue 29 found it losing records: saved settings (M92 X81, not the
/// factory X80) and a kept paused job in one sector, data of another program in the other
/// (`foreign`), crafted with the firmware's own store on the SKR 2's geometry.
fn crafted_area(foreign: &[u8], records_in: usize) -> Vec<u8> {
    use firmware::config::MachineConfig;
    use firmware::printer::Printer;
    use firmware::storage::{Moment, RecordStore, SettingsStore, Skr2FlashModel};
    const SECTOR: usize = 128 * 1024;
    let mut s = Printer::new(MachineConfig::ENDER3).settings();
    s.steps_per_mm[0] = 81.0;
    let model = Skr2FlashModel::new(vec![0xFF; 2 * SECTOR]);
    let mut st = SettingsStore::new(model, 0..2 * SECTOR as u32).unwrap();
    st.save_settings(&s, Moment::Idle).unwrap();
    st.save_job(&kept_job(), Moment::Idle).unwrap();
    let mut bytes = st.into_flash().into_inner();
    if records_in == 1 {
        let (a, b) = bytes.split_at_mut(SECTOR);
        a.swap_with_slice(b);
    }
    let other = 1 - records_in;
    bytes[other * SECTOR..][..SECTOR].copy_from_slice(foreign);
    bytes
}

/// A paused job of an earlier print, kept in the crafted area.
fn kept_job() -> firmware::storage::PausedJob {
    use firmware::storage::{JobSource, ModalState, PausedJob};
    PausedJob {
        source: JobSource::Host { line: 4242 },
        layer: 7,
        boundary_z_um: 1400,
        boundary_steps: [8000, 8000, 560, 0],
        park_steps: [18_800, 18_800, 2560, -186],
        modal: ModalState {
            relative_xyz: false,
            relative_e: true,
            inches: false,
            retracted: false,
            feed_mm_s: 30.0,
            feed_pct: 100.0,
            flow_pct: 100.0,
            offset_mm: [0.0; 3],
            logical_e_mm: 0.0,
            machine_mm: [100.0, 100.0, 1.4, 0.0],
        },
        retract_mm: 2.0,
        hotend_c: 0.0,
        bed_c: 0.0,
        fan_pwm: 0,
    }
}

/// What another program may leave in a 128 KiB sector.
fn foreign_sectors() -> Vec<(&'static str, Vec<u8>)> {
    const SECTOR: usize = 128 * 1024;
    let mut seed = 0x2911_u32;
    let random: Vec<u8> = (0..SECTOR)
        .map(|_| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as u8
        })
        .collect();
    let mut half = vec![0u8; SECTOR];
    half[SECTOR / 2..].fill(0xFF);
    let mut first_word = vec![0xFFu8; SECTOR];
    first_word[..4].fill(0);
    // Marlin's flash EEPROM emulation (HAL/STM32/eeprom_flash.cpp) in sector 11: 4 KiB EEPROM
    // images, their data from offset 100 ("V90", then the CRC and the values); at the start of
    // the sector, or with FLASH_EEPROM_LEVELING in slots from its end down.
    let image = |at: usize, b: &mut Vec<u8>| {
        b[at + 100..at + 104].copy_from_slice(b"V90\0");
        b[at + 104..at + 4096].copy_from_slice(&random[at + 104..at + 4096]);
    };
    let mut marlin = vec![0xFFu8; SECTOR];
    image(0, &mut marlin);
    let mut levelled = vec![0xFFu8; SECTOR];
    image(SECTOR - 4096, &mut levelled);
    image(SECTOR - 8192, &mut levelled);
    vec![
        ("zeros", vec![0; SECTOR]),
        ("random bytes", random.clone()),
        ("zeros, then erased", half),
        ("a zero first word", first_word),
        ("Marlin's EEPROM image", marlin),
        ("Marlin's levelled EEPROM slots", levelled),
    ]
}

/// Issue 29 end to end (it lost the records in 10 of 21 such variants: the kept job at the
/// next M500, or both records at a layer pause, after which M1000 resumed with the factory
/// M92 X80): records in one sector, foreign data in the other; a session takes an M500 and a
/// layer pause of a new job; the next session reports the saved M92 X81 with M503, announces
/// the new job, and M1000 resumes it with X81.
#[test]
fn records_beside_foreign_data_survive_m500_a_layer_pause_and_a_restart() {
    let variants: Vec<(String, Vec<u8>)> = foreign_sectors()
        .into_iter()
        .flat_map(|(name, foreign)| {
            (0..2).map(move |records_in| {
                let what = format!("{name} beside records in sector {records_in}");
                (what, crafted_area(&foreign, records_in))
            })
        })
        .collect();
    // The variants' sessions at once (each waits on its virtual printer's time).
    std::thread::scope(|s| {
        for (k, (what, area)) in variants.iter().enumerate() {
            s.spawn(move || foreign_beside_records(k, what, area));
        }
    });
    println!(
        "sim serve --flash: {} variants, no record lost",
        variants.len()
    );
}

/// One variant of the test above: `area` in a flash file of its own (`k`).
fn foreign_beside_records(k: usize, what: &str, area: &[u8]) {
    use firmware::storage::{JobSource, RecordStore, SettingsStore, Skr2FlashModel};
    let (lines, first) = numbered_job();
    let file =
        std::env::temp_dir().join(format!("sim-serve-foreign-{}-{k}.bin", std::process::id()));
    std::fs::write(&file, area).unwrap();
    let mut all = vec!["M503", "M203 Z12", "M500", "M110 N0"];
    all.extend(lines.iter().map(String::as_str));
    let seen = session_with(&file, &all, Some(12 + 3));
    let has = |seen: &[String], s: &str| seen.iter().any(|l| l.contains(s));
    assert!(has(&seen, "Paused job kept: layer 7"), "{what}: {seen:?}");
    assert!(
        has(&seen, "echo:  M92 X81 Y80 Z400 E93"),
        "{what}: {seen:?}"
    );
    assert!(has(&seen, "echo:Settings Stored"), "{what}: {seen:?}");
    let kept = seen
        .iter()
        .find(|l| l.contains("power-cut resume: keeping job at layer"))
        .unwrap_or_else(|| panic!("{what}: {seen:?}"));
    let words: Vec<&str> = kept.split([' ', ',']).collect();
    let layer: usize = words[words.iter().position(|w| *w == "layer").unwrap() + 1]
        .parse()
        .unwrap();
    let line: u32 = words.last().unwrap().parse().unwrap();
    assert_eq!(line, first[layer - 1], "{what}: {kept}");
    // In the file, read by the firmware's store: both records, the new ones.
    let bytes = std::fs::read(&file).unwrap();
    let mut st = SettingsStore::new(Skr2FlashModel::new(bytes), 0..2 * 128 * 1024).unwrap();
    let s = st.load_settings().unwrap().unwrap();
    assert_eq!(
        (s.steps_per_mm[0], s.max_feed_mm_s[2]),
        (81.0, 12.0),
        "{what}"
    );
    let j = st.load_job().unwrap().unwrap();
    assert_eq!(j.source, JobSource::Host { line }, "{what}");

    // The power goes; the next session.
    let next = session(&file, &["M503", "M1000", "M92"]);
    let _ = std::fs::remove_file(&file);
    assert!(
        next.iter()
            .filter(|l| *l == "echo:  M92 X81 Y80 Z400 E93")
            .count()
            == 2,
        "{what}: M503 and M92 after M1000: {next:?}"
    );
    assert!(
        has(&next, "echo:  M203 X500 Y500 Z12 E25"),
        "{what}: {next:?}"
    );
    assert!(
        has(&next, &format!("Paused job kept: layer {layer} ")),
        "{what}: {next:?}"
    );
    assert!(
        has(&next, &format!("send the job from host line {line} ")),
        "{what}: {next:?}"
    );
    assert!(!has(&next, "no saved settings"), "{what}: {next:?}");
}
