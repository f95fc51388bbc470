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
                "skr2",
                "--features",
                "f407",
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

/// Where the carriage starts in the tests, mm from the switches.
pub const START_MM: [f32; 3] = [10.0, 10.0, 2.0];

/// Options for the F407 image.
pub fn options() -> Options {
    let (bin, elf) = image();
    Options {
        image: bin.clone(),
        elf: Some(elf.clone()),
        start_mm: START_MM,
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
/// counted from the G-code alone: G28 puts X/Y/Z at 0 (the switches: the carriage moves back
/// by its start), G90/G91, M82/M83 and G92 as Marlin reads them, each absolute position
/// rounded to whole steps; M92 and M350 change the steps per mm, the position re-expressed in
/// the new steps (Marlin's `planner.refresh_positioning()`). Before the first G28 the
/// firmware believes it is at 0 where it stands (Marlin's default, moves allowed).
pub fn expected_net_steps(job: &[&str], start_mm: [f32; 3]) -> [i64; 4] {
    let mut spmm = STEPS_PER_MM;
    let mut micro = [16.0f64; 4];
    let mut pos = [0f64; 4]; // machine mm (E: since the last G92 E, see e_*)
    let mut origin = [0f64; 4]; // G92 offsets: logical = machine - origin
    let mut step_pos = [0i64; 4]; // the firmware's position in steps
    let mut phys = [0i64; 4]; // net steps the pins made
    let mut rel = false;
    let mut rel_e = false;
    let round = |v: f64| v.round() as i64;
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
                    // The switch is `start_mm` behind where the carriage stood at power-on.
                    phys[i] = -round(f64::from(start_mm[i]) * STEPS_PER_MM[i]);
                    pos[i] = 0.0;
                    origin[i] = 0.0;
                    step_pos[i] = 0;
                }
            }
            "G92" => {
                for (k, v) in args {
                    if let Some(i) = axis(k) {
                        if i == 3 {
                            // E restarts its count: machine E = the new logical value.
                            pos[3] = v;
                            origin[3] = 0.0;
                            step_pos[3] = round(v * spmm[3]);
                        } else {
                            origin[i] = pos[i] - v;
                        }
                    }
                }
            }
            "G0" | "G1" => {
                for (k, v) in args {
                    if let Some(i) = axis(k) {
                        let r = if i == 3 { rel_e } else { rel };
                        pos[i] = if r { pos[i] + v } else { origin[i] + v };
                        let s = round(pos[i] * spmm[i]);
                        phys[i] += s - step_pos[i];
                        step_pos[i] = s;
                    }
                }
            }
            "M92" | "M350" => {
                for (k, v) in args {
                    if let Some(i) = axis(k) {
                        if cmd.eq_ignore_ascii_case("M92") {
                            spmm[i] = v;
                        } else {
                            spmm[i] *= v / micro[i];
                            micro[i] = v;
                        }
                        step_pos[i] = round(pos[i] * spmm[i]);
                    }
                }
            }
            _ => {}
        }
    }
    phys
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

/// Where the park may begin for a pause at layer `n`, from `layerref` (the independent layer
/// model, no code shared with the firmware) and the test's own G-code count: after the line
/// before the layer's marker when the layer comes from a marker (the barrier is the marker),
/// else anywhere between the previous layer's last extrusion and the layer's first one.
pub fn layerref_stops(job: &[&str], n: u32, comments: layerref::Comments) -> Vec<[i64; 4]> {
    let model = layerref::Model::of_lines(job.iter().copied(), comments);
    let k = model.find(n).expect("layerref has the layer");
    let layer = model.layers()[k];
    let prev_last = model.layers()[..k]
        .iter()
        .rev()
        .find(|l| l.number > 0)
        .map(|l| l.last_line);
    let lines: Vec<usize> = match (layer.source, prev_last) {
        (layerref::Source::Marker(_), _) => {
            // The marker: the last comment line before the layer's first extrusion that
            // names a layer (the test's reading; layerref says the layer is a marker's).
            let m = (prev_last.unwrap_or(0)..layer.first_line)
                .rev()
                .find(|&i| job[i].trim_start().starts_with(";LAYER"))
                .expect("the marker line");
            vec![m - 1]
        }
        (_, Some(p)) => (p..layer.first_line).collect(),
        // The first layer: right before its first extrusion.
        (_, None) => vec![layer.first_line - 1],
    };
    lines
        .into_iter()
        .map(|i| expected_net_steps(&job[..=i], START_MM))
        .collect()
}

/// Every place a layer pause may stop in `job` (before any layer), by [`layerref_stops`].
pub fn layerref_boundaries(job: &[&str], comments: layerref::Comments) -> Vec<[i64; 4]> {
    let model = layerref::Model::of_lines(job.iter().copied(), comments);
    let numbers: Vec<u32> = model
        .layers()
        .iter()
        .map(|l| l.number)
        .filter(|&n| n >= 1)
        .collect();
    numbers
        .into_iter()
        .flat_map(|n| layerref_stops(job, n, comments))
        .collect()
}
