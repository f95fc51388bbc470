//! Machine files: which printer the sim is (`sim run --machine`, `sim serve --machine`), and —
//! for `sim serve` — where its head is between sessions (the power-cut checks,
//! [`crate::powercut`]).
//!
//! A machine file is TOML:
//!
//! ```toml
//! head_steps = [800, 800, 4000, 0]   # written by `sim serve --machine` (steps from the switches)
//! name = "Creality K1 Max"
//! bed_min_mm = [-2.0, -2.0, 0.0]     # the volume the printer accepts moves in (X Y Z)
//! bed_max_mm = [300.0, 300.0, 300.0]
//! max_feed_mm_s = [600.0, 600.0, 20.0, 60.0]         # optional (X Y Z E)
//! max_accel_mm_s2 = [20000.0, 20000.0, 500.0, 5000.0] # optional
//! steps_per_mm = [80.0, 80.0, 400.0, 93.0]           # optional
//! park_mm = [290.0, 290.0]                            # optional: where a pause parks
//! ```
//!
//! Everything not given is the Ender-3's ([`MachineConfig::ENDER3`]). Profiles for common
//! printers ship with the sim (`sim/machines/`), by name: [`BUILT_IN`]. A file holding only four
//! numbers is the older form of `sim serve --machine` (an Ender-3 and its head's position).

use anyhow::{bail, Context};
use firmware::config::MachineConfig;
use firmware::motion::{Axis, StepPos};
use std::path::Path;

/// The profiles that ship with the sim: (name, TOML).
pub const BUILT_IN: &[(&str, &str)] = &[
    ("ender3", include_str!("../machines/ender3.toml")),
    ("k1max", include_str!("../machines/k1max.toml")),
    ("prusa-mk4", include_str!("../machines/prusa-mk4.toml")),
    ("prusa-mini", include_str!("../machines/prusa-mini.toml")),
    ("bambu-x1", include_str!("../machines/bambu-x1.toml")),
    ("voron300", include_str!("../machines/voron300.toml")),
];

/// What a machine file says.
#[derive(Clone, Debug, PartialEq)]
pub struct Machine {
    /// The printer's name.
    pub name: String,
    /// Its configuration, as the firmware takes it.
    pub config: MachineConfig,
    /// Where the head is (steps from the switches), if the file says.
    pub head_steps: Option<StepPos>,
    /// The file is the older four-number form (written back as such).
    pub legacy: bool,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Profile {
    name: String,
    head_steps: Option<[i32; 4]>,
    bed_min_mm: [f32; 3],
    bed_max_mm: [f32; 3],
    max_feed_mm_s: Option<[f32; 4]>,
    max_accel_mm_s2: Option<[f32; 4]>,
    steps_per_mm: Option<[f32; 4]>,
    park_mm: Option<[f32; 2]>,
}

/// Largest extent of the build volume the sim takes, mm (a 10 m printer).
const MAX_EXTENT_MM: f32 = 10_000.0;

fn check(what: &str, v: f32, range: std::ops::RangeInclusive<f32>) -> anyhow::Result<()> {
    if v.is_finite() && range.contains(&v) {
        Ok(())
    } else {
        bail!("{what} {v}: outside {}..={}", range.start(), range.end())
    }
}

impl Machine {
    /// The Ender-3 (the firmware's own defaults).
    pub fn ender3() -> Self {
        Machine {
            name: "Creality Ender-3".into(),
            config: MachineConfig::ENDER3,
            head_steps: None,
            legacy: false,
        }
    }

    /// A built-in profile by name, or a machine file.
    pub fn load(spec: &str) -> anyhow::Result<Self> {
        if let Some((_, text)) = BUILT_IN.iter().find(|(n, _)| *n == spec) {
            return Self::parse(text).with_context(|| format!("built-in machine {spec}"));
        }
        let path = Path::new(spec);
        let text = std::fs::read_to_string(path).with_context(|| {
            format!(
                "reading machine file {spec} (built-in machines: {})",
                BUILT_IN
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?;
        Self::parse(&text).with_context(|| format!("machine file {spec}"))
    }

    /// Parse a machine file's text: TOML, or the older four numbers (an Ender-3's head).
    pub fn parse(text: &str) -> anyhow::Result<Self> {
        let numbers: Option<Vec<i32>> = text.split_whitespace().map(|w| w.parse().ok()).collect();
        if let Some(Ok(pos)) = numbers.map(<[i32; 4]>::try_from) {
            return Ok(Machine {
                head_steps: Some(pos),
                legacy: true,
                ..Self::ender3()
            });
        }
        let p: Profile = toml::from_str(text).context("not a machine file")?;
        let mut cfg = MachineConfig::ENDER3;
        for k in 0..3 {
            let (lo, hi) = (p.bed_min_mm[k], p.bed_max_mm[k]);
            check("bed_min_mm", lo, -MAX_EXTENT_MM..=MAX_EXTENT_MM)?;
            check("bed_max_mm", hi, -MAX_EXTENT_MM..=MAX_EXTENT_MM)?;
            if hi - lo < 1.0 {
                bail!("bed_max_mm {hi} must be at least 1 mm above bed_min_mm {lo}");
            }
            cfg.axes[k].min_mm = lo;
            cfg.axes[k].max_mm = hi;
        }
        for k in 0..4 {
            if let Some(v) = p.max_feed_mm_s {
                check("max_feed_mm_s", v[k], 0.1..=2_000.0)?;
                cfg.axes[k].max_feed_mm_s = v[k];
            }
            if let Some(v) = p.max_accel_mm_s2 {
                check("max_accel_mm_s2", v[k], 1.0..=100_000.0)?;
                cfg.axes[k].max_accel_mm_s2 = v[k];
            }
            if let Some(v) = p.steps_per_mm {
                check("steps_per_mm", v[k], 1.0..=10_000.0)?;
                cfg.axes[k].steps_per_mm = v[k];
            }
        }
        // Print and travel accelerations: as the X axis allows (the Ender-3's are its axes').
        let xy = cfg
            .axis(Axis::X)
            .max_accel_mm_s2
            .min(cfg.axis(Axis::Y).max_accel_mm_s2);
        cfg.accel_print_mm_s2 = xy;
        cfg.accel_travel_mm_s2 = xy;
        // A pause parks inside the bed: where the file says, else at the back corner.
        let park = p.park_mm.unwrap_or([p.bed_max_mm[0], p.bed_max_mm[1]]);
        for ((v, lo), hi) in park.iter().zip(&p.bed_min_mm).zip(&p.bed_max_mm) {
            check("park_mm", *v, *lo..=*hi)?;
        }
        cfg.pause.park_x_mm = park[0];
        cfg.pause.park_y_mm = park[1];
        Ok(Machine {
            name: p.name,
            config: cfg,
            head_steps: p.head_steps,
            legacy: false,
        })
    }
}

/// `text` (a TOML machine file) with its `head_steps` line set to `pos`: the first line, so
/// it stays a top-level key whatever tables follow; the rest of the file as it was.
pub fn with_head(text: &str, pos: StepPos) -> String {
    let mut out = format!(
        "head_steps = [{}, {}, {}, {}]\n",
        pos[0], pos[1], pos[2], pos[3]
    );
    for l in text.lines() {
        if !l.trim_start().starts_with("head_steps") {
            out.push_str(l);
            out.push('\n');
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_built_in_profile_loads_and_keeps_its_park_inside_its_bed() {
        for (name, _) in BUILT_IN {
            let m = Machine::load(name).unwrap();
            let c = &m.config;
            for k in 0..2 {
                let park = [c.pause.park_x_mm, c.pause.park_y_mm][k];
                assert!(
                    c.axes[k].min_mm <= park && park <= c.axes[k].max_mm,
                    "{name}"
                );
            }
            assert!(!m.name.is_empty());
        }
        assert_eq!(
            Machine::load("ender3").unwrap().config,
            MachineConfig::ENDER3
        );
        let k1 = Machine::load("k1max").unwrap();
        assert_eq!(k1.config.axes[0].max_mm, 300.0);
    }

    #[test]
    fn the_head_is_kept_in_the_file_and_the_older_form_still_reads() {
        let text = with_head(include_str!("../machines/k1max.toml"), [1, 2, 3, 4]);
        let m = Machine::parse(&text).unwrap();
        assert_eq!(m.head_steps, Some([1, 2, 3, 4]));
        assert_eq!(m.name, "Creality K1 Max");
        let again = with_head(&text, [5, 6, 7, 8]);
        assert_eq!(
            Machine::parse(&again).unwrap().head_steps,
            Some([5, 6, 7, 8])
        );
        assert_eq!(again.matches("head_steps").count(), 1);
        let old = Machine::parse("800 800 4000 0\n").unwrap();
        assert!(old.legacy);
        assert_eq!(old.config, MachineConfig::ENDER3);
        assert_eq!(old.head_steps, Some([800, 800, 4000, 0]));
    }

    #[test]
    fn bad_files_are_refused_with_a_reason() {
        for bad in [
            "name = \"x\"\nbed_min_mm = [0, 0, 0]\nbed_max_mm = [0.5, 100, 100]\n",
            "name = \"x\"\nbed_min_mm = [0, 0, 0]\nbed_max_mm = [1e9, 100, 100]\n",
            "name = \"x\"\nbed_min_mm = [0, 0, 0]\nbed_max_mm = [100, 100, 100]\npark_mm = [200, 0]\n",
            "name = \"x\"\nbed_min_mm = [0, 0, 0]\nbed_max_mm = [100, 100, 100]\nsteps_per_mm = [0, 80, 400, 93]\n",
            "name = \"x\"\nbed_max_mm = [100, 100, 100]\n",
            "name = \"x\"\nbed_min_mm = [0, 0, 0]\nbed_max_mm = [100, 100, 100]\ncolour = 3\n",
            "1 2 3",
            "",
        ] {
            assert!(Machine::parse(bad).is_err(), "{bad:?}");
        }
    }
}
