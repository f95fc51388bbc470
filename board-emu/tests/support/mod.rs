//! Shared by the emulated-board tests: the image (built here, as `scripts/build-firmware.sh`
//! builds it, so the tests always run the current source), an independent G-code step count,
//! and small jobs.

#![allow(dead_code)]

use board_emu::report::Report;
use board_emu::scenario::{self, Options};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target"))
}

/// The F407 image and its ELF, built once per test binary with the `fw` profile and
/// `arm-none-eabi-objcopy -O binary`, exactly as `scripts/build-firmware.sh` makes them.
pub fn image() -> &'static (PathBuf, PathBuf) {
    static IMAGE: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    IMAGE.get_or_init(|| {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let st = Command::new(cargo)
            .current_dir(root())
            .args([
                "build",
                "--quiet",
                "-p",
                "firmware",
                "--bin",
                "skr2",
                "--features",
                "board",
                "--target",
                "thumbv7em-none-eabihf",
                "--profile",
                "fw",
            ])
            .status()
            .expect("cargo runs");
        assert!(st.success(), "the image builds");
        let elf = target_dir().join("thumbv7em-none-eabihf/fw/skr2");
        let dir = target_dir().join("board-emu-tests");
        std::fs::create_dir_all(&dir).expect("test dir");
        let bin = dir.join("firmware-f407.bin");
        let elf_copy = dir.join("skr2-f407.elf");
        std::fs::copy(&elf, &elf_copy).expect("ELF copied");
        let st = Command::new("arm-none-eabi-objcopy")
            .args(["-O", "binary"])
            .arg(&elf_copy)
            .arg(&bin)
            .status()
            .expect("arm-none-eabi-objcopy runs (scripts/setup.sh installs it)");
        assert!(st.success());
        (bin, elf_copy)
    })
}

/// Options for the F407 image.
pub fn options() -> Options {
    let (bin, elf) = image();
    Options {
        image: bin.clone(),
        elf: Some(elf.clone()),
        start_mm: [10.0, 10.0, 2.0],
        max_virtual_s: 40.0,
        ..Options::default()
    }
}

/// Runs and reports.
pub fn run(o: &Options) -> Report {
    scenario::run(o).expect("the emulated board runs")
}

/// A temporary path unique to this test.
pub fn temp(name: &str) -> PathBuf {
    let dir = target_dir().join("board-emu-tests");
    std::fs::create_dir_all(&dir).expect("test dir");
    dir.join(format!("{}-{name}", std::process::id()))
}

/// Lines received after the last one containing `marker`.
pub fn lines_after<'a>(r: &'a Report, marker: &str) -> &'a [String] {
    let i = r
        .lines
        .iter()
        .rposition(|l| l.contains(marker))
        .map_or(r.lines.len(), |i| i + 1);
    &r.lines[i..]
}

/// The net steps the run made, X Y Z E (the order of [`expected_net_steps`]).
pub fn net_steps(r: &Report) -> [i64; 4] {
    ["X", "Y", "Z", "E"].map(|axis| r.net_steps[axis])
}

/// Steps per mm X, Y, Z, E of the Ender-3: Marlin's `DEFAULT_AXIS_STEPS_PER_UNIT { 80, 80,
/// 400, 93 }` (config/examples/Creality/Ender-3, Configuration.h), written here rather than
/// read from the firmware's `MachineConfig`, so the count below is independent of its code.
pub const STEPS_PER_MM: [f64; 4] = [80.0, 80.0, 400.0, 93.0];

/// The net steps a job makes from where the carriage starts (`start_mm` from the switches),
/// counted from the G-code alone: G28 puts X/Y/Z at 0 (the switches), G90/G91, M82/M83 and
/// G92 as Marlin reads them, each absolute position rounded to whole steps.
pub fn expected_net_steps(job: &[&str], start_mm: [f32; 3]) -> [i64; 4] {
    let mut pos = [0f64; 4];
    let mut origin = [0f64; 4]; // G92 offsets: logical = machine - origin
    let mut rel = false;
    let mut rel_e = false;
    let mut e_done_steps: i64 = 0; // E steps of finished G92 intervals
    let mut e_base = 0f64; // machine E at the last G92
    for raw in job {
        let line = raw.split(';').next().unwrap_or("").trim();
        let mut words = line.split_whitespace();
        let Some(cmd) = words.next() else { continue };
        let args: Vec<(char, f64)> = words
            .filter_map(|w| {
                let mut c = w.chars();
                let k = c.next()?.to_ascii_uppercase();
                Some((k, c.as_str().parse().unwrap_or(0.0)))
            })
            .collect();
        let axis = |k: char| "XYZE".find(k);
        match cmd.to_ascii_uppercase().as_str() {
            "G90" => {
                rel = false;
                rel_e = false;
            }
            "G91" => {
                rel = true;
                rel_e = true;
            }
            "M82" => rel_e = false,
            "M83" => rel_e = true,
            "G28" => {
                for i in 0..3 {
                    pos[i] = 0.0;
                    origin[i] = 0.0;
                }
            }
            "G92" => {
                for (k, v) in args {
                    if let Some(i) = axis(k) {
                        if i == 3 {
                            e_done_steps += ((pos[3] * STEPS_PER_MM[3]).round()
                                - (e_base * STEPS_PER_MM[3]).round())
                                as i64;
                            e_base = pos[3];
                        }
                        origin[i] = pos[i] - v;
                    }
                }
            }
            "G0" | "G1" => {
                for (k, v) in args {
                    if let Some(i) = axis(k) {
                        let r = if i == 3 { rel_e } else { rel };
                        pos[i] = if r { pos[i] + v } else { origin[i] + v };
                    }
                }
            }
            _ => {}
        }
    }
    let mut out = [0i64; 4];
    for i in 0..3 {
        let start = f64::from(start_mm[i]);
        // Before the first G28 the firmware believes it is at 0; after it, the carriage
        // is where its position says, the switch being 0.
        out[i] =
            (pos[i] * STEPS_PER_MM[i]).round() as i64 - (start * STEPS_PER_MM[i]).round() as i64;
    }
    out[3] = e_done_steps
        + ((pos[3] * STEPS_PER_MM[3]).round() - (e_base * STEPS_PER_MM[3]).round()) as i64;
    out
}

/// Three 10 mm square layers, extruding (cold extrusion allowed with M302 P1), with the
/// layer comments a slicer writes.
pub const THREE_LAYERS: &[&str] = &[
    "M302 P1",
    "G28",
    "G90",
    "M82",
    "G92 E0",
    "G1 Z0.2 F600",
    "G1 X20 Y20 F6000",
    ";LAYER:0",
    "G1 X30 Y20 E0.5 F1800",
    "G1 X30 Y30 E1.0",
    "G1 X20 Y30 E1.5",
    "G1 X20 Y20 E2.0",
    ";LAYER:1",
    "G1 Z0.4 F600",
    "G1 X30 Y20 E2.5 F1800",
    "G1 X30 Y30 E3.0",
    "G1 X20 Y30 E3.5",
    "G1 X20 Y20 E4.0",
    ";LAYER:2",
    "G1 Z0.6 F600",
    "G1 X30 Y20 E4.5 F1800",
    "G1 X30 Y30 E5.0",
    "G1 X20 Y30 E5.5",
    "G1 X20 Y20 E6.0",
    "G1 X40 Y40 F6000",
];
