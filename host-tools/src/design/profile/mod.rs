//! Printer profiles (TOML): bed, filament, temperatures, start/end code, absolute or relative
//! E, retraction and motion limits. Two ship built in (`host-tools/profiles/`): `ender3`
//! (Ender-3-class, absolute E) and `skr2` (the same mechanics on an SKR 2 running our
//! firmware, relative E). Every tool that needs a printer (compile, stats, preview, checks,
//! the time-based resampler) takes a [`Profile`].

use serde::{Deserialize, Serialize};
use std::path::Path;

mod template;
pub use template::{Primer, TemplateValues, PLACEHOLDERS};

/// Absolute (M82) or relative (M83) extrusion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EMode {
    /// E is a running total (M82).
    Absolute,
    /// E is per move (M83).
    Relative,
}

/// Printable area, mm.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bed {
    /// Lowest X, mm.
    pub x_min_mm: f64,
    /// Highest X, mm.
    pub x_max_mm: f64,
    /// Lowest Y, mm.
    pub y_min_mm: f64,
    /// Highest Y, mm.
    pub y_max_mm: f64,
    /// Highest Z, mm (lowest is 0).
    pub z_max_mm: f64,
}

/// Retraction on travels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Retraction {
    /// Filament pulled back, mm (0 disables retraction).
    pub length_mm: f64,
    /// Retract and prime speed, mm/s.
    pub speed_mm_s: f64,
    /// Travels shorter than this do not retract, mm.
    pub min_travel_mm: f64,
}

/// The error text for a design's speed `v_mm_s` above the printer's `limit_mm_s` (`axis`:
/// "axis" or "extruder"): speeds are mm/s everywhere, and a value above the limit is almost
/// always one in FullControl's mm/min, so the conversion is named. Huge values are written
/// in exponent form (a `1e308` would otherwise be 309 digits).
pub fn speed_beyond_limit(what: &str, v_mm_s: f64, axis: &str, limit_mm_s: f64) -> String {
    let num = |x: f64, decimals: usize| {
        if x.abs() < 1e9 {
            format!("{x:.decimals$}")
        } else {
            format!("{x:.3e}")
        }
    };
    let v = format!("{v_mm_s}");
    let v = if v.len() < 12 { v } else { num(v_mm_s, 1) };
    format!(
        "{what} {v} mm/s is beyond the printer's {limit_mm_s} mm/s {axis} limit (speeds here are \
         mm/s; FullControl's are mm/min: {v} mm/min = {} mm/s)",
        num(v_mm_s / 60.0, 1)
    )
}

impl Profile {
    /// The fastest retraction a design may ask for, mm/s: the extruder's limit, or the
    /// profile's own retraction speed where that is higher (vendor profiles retract above the
    /// firmware's E limit, which then clamps: the Ender 3's 60 mm/s against 50). A design's
    /// value above it is refused as a likely mm/min number.
    pub fn max_retract_mm_s(&self) -> f64 {
        self.limits.max_feed_e_mm_s.max(self.retraction.speed_mm_s)
    }
}

/// Motion limits (Marlin's M203/M201/M204/M205 J), used by the time estimate and checks.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Highest X/Y feed, mm/s.
    pub max_feed_xy_mm_s: f64,
    /// Highest Z feed, mm/s.
    pub max_feed_z_mm_s: f64,
    /// Highest E feed, mm/s.
    pub max_feed_e_mm_s: f64,
    /// Highest X acceleration, mm/s².
    pub max_accel_x_mm_s2: f64,
    /// Highest Y acceleration, mm/s².
    pub max_accel_y_mm_s2: f64,
    /// Highest Z acceleration, mm/s².
    pub max_accel_z_mm_s2: f64,
    /// Highest E acceleration, mm/s².
    pub max_accel_e_mm_s2: f64,
    /// Acceleration of printing moves, mm/s².
    pub accel_print_mm_s2: f64,
    /// Acceleration of travel moves, mm/s².
    pub accel_travel_mm_s2: f64,
    /// Acceleration of extruder-only moves, mm/s².
    pub accel_retract_mm_s2: f64,
    /// Junction deviation, mm.
    pub junction_deviation_mm: f64,
    /// Highest volumetric flow the hotend melts, mm³/s.
    pub max_volumetric_mm3_s: f64,
}

/// Start and end code templates. Placeholders (see [`PLACEHOLDERS`]) are written `{name}`;
/// `{{` and `}}` stand for literal braces. An unknown placeholder is an error when the profile
/// is loaded, naming it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GcodeTemplates {
    /// Written before the design.
    pub start: String,
    /// Written after the design.
    pub end: String,
    /// The purge line, written where the start code has `{primer}` (on a line of its own)
    /// unless the design asks for none ([`Primer::None`]); empty when the start code has no
    /// purge of its own (e.g. a Klipper macro purges).
    #[serde(default)]
    pub primer: String,
}

/// The firmware family the profile's start/end code is written for (what the printer runs;
/// the writer's moves are the same for all).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Firmware {
    /// Marlin 1.x/2.x (Creality, Anycubic stock boards).
    #[default]
    Marlin,
    /// Prusa's Marlin fork (MK3S) or Prusa-Firmware-Buddy (MK4): `M862.x` checks, `G80`/`G29` mesh.
    Prusa,
    /// Klipper with `PRINT_START`/`PRINT_END` macros (Voron).
    Klipper,
    /// This project's firmware (the SKR 2 build).
    Layerpause,
}

impl Firmware {
    /// Lower-case name as written in profiles.
    pub fn name(self) -> &'static str {
        match self {
            Firmware::Marlin => "marlin",
            Firmware::Prusa => "prusa",
            Firmware::Klipper => "klipper",
            Firmware::Layerpause => "layerpause",
        }
    }
}

/// How layers are marked in the G-code, as the slicer the printer's owners use would mark them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Markers {
    /// PrusaSlicer: `;LAYER_CHANGE`, `;Z:<mm>`, `;HEIGHT:<mm>` before each layer's Z move.
    #[default]
    Prusa,
    /// Cura: `;FLAVOR:Marlin` and `;LAYER_COUNT:<n>` before the start code, `;LAYER:<n>`
    /// (from 0) before each layer.
    Cura,
}

/// A printer profile. Unknown keys are errors (`deny_unknown_fields`), naming the key.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// Profile name.
    pub name: String,
    /// One line for `host-tools profiles`: the printer and what the profile is for.
    #[serde(default)]
    pub description: String,
    /// Where the values come from (vendor slicer profile files, with sections).
    #[serde(default)]
    pub source: String,
    /// Firmware family the start/end code is written for.
    #[serde(default)]
    pub firmware: Firmware,
    /// Nozzle diameter, mm (the `{nozzle_mm}` placeholder; designs choose their own widths).
    #[serde(default = "default_nozzle_mm")]
    pub nozzle_diameter_mm: f64,
    /// Filament diameter, mm.
    pub filament_diameter_mm: f64,
    /// Filament density, g/cm³ (for mass).
    pub filament_density_g_cm3: f64,
    /// Default hotend temperature, °C.
    pub hotend_c: f64,
    /// Default bed temperature, °C.
    pub bed_c: f64,
    /// Default part-fan duty, 0..=1.
    pub fan: f64,
    /// Layers printed with the part fan off before it comes on (slicers' "disable fan for the
    /// first N layers"; 0 = on from the start code).
    #[serde(default)]
    pub fan_off_layers: u32,
    /// Layer marker style.
    #[serde(default)]
    pub markers: Markers,
    /// Write `M73 P<percent> R<minutes left>` at every layer (PrusaSlicer; the printer's
    /// display shows progress and time left).
    #[serde(default)]
    pub progress: bool,
    /// Absolute or relative E.
    pub e_mode: EMode,
    /// Travel speed, mm/s.
    pub travel_speed_mm_s: f64,
    /// Decimals written for X/Y/Z/E (3 = µm).
    pub decimals: u32,
    /// Printable area.
    pub bed: Bed,
    /// Retraction on travels.
    pub retraction: Retraction,
    /// Motion limits.
    pub limits: Limits,
    /// Start/end code.
    pub gcode: GcodeTemplates,
}

fn default_nozzle_mm() -> f64 {
    0.4
}

/// The built-in profiles: name and TOML text (`host-tools/profiles/<name>.toml`).
const BUILTIN_TOML: &[(&str, &str)] = &[
    ("ender3", include_str!("../../../profiles/ender3.toml")),
    ("ender3v2", include_str!("../../../profiles/ender3v2.toml")),
    ("ender3s1", include_str!("../../../profiles/ender3s1.toml")),
    ("cr10", include_str!("../../../profiles/cr10.toml")),
    ("i3mega", include_str!("../../../profiles/i3mega.toml")),
    ("mk3s", include_str!("../../../profiles/mk3s.toml")),
    ("mk4", include_str!("../../../profiles/mk4.toml")),
    (
        "voron24-350",
        include_str!("../../../profiles/voron24-350.toml"),
    ),
    ("skr2", include_str!("../../../profiles/skr2.toml")),
    ("paste", include_str!("../../../profiles/paste.toml")),
    (
        "eazao-zero",
        include_str!("../../../profiles/eazao-zero.toml"),
    ),
];

/// The reference profile behind [`Profile::ender3`].
const REFERENCE_TOML: &str = include_str!("../../../profiles/reference.toml");

/// Names of the built-in profiles, in listing order.
pub const BUILTIN: &[&str] = &[
    "ender3",
    "ender3v2",
    "ender3s1",
    "cr10",
    "i3mega",
    "mk3s",
    "mk4",
    "voron24-350",
    "skr2",
    "paste",
    "eazao-zero",
];

impl Profile {
    /// Parses a profile from TOML text and validates it. Unknown keys and unknown
    /// placeholders in the start/end code are errors that name them.
    pub fn from_toml(text: &str) -> anyhow::Result<Profile> {
        let p: Profile = toml::from_str(text)?;
        p.validate()?;
        Ok(p)
    }

    /// A built-in profile by name (see [`BUILTIN`]).
    pub fn builtin(name: &str) -> Option<Profile> {
        let text = BUILTIN_TOML.iter().find(|(n, _)| *n == name)?.1;
        Profile::from_toml(text).ok()
    }

    /// The library's reference profile (`profiles/reference.toml`): Ender-3-class mechanics,
    /// a minimal start code without purge line, PrusaSlicer-style markers — what the golden
    /// and property tests pin. Not the vendor-sourced `ender3` named profile
    /// (`Profile::builtin("ender3")`, Cura-style, with the purge line).
    pub fn ender3() -> Profile {
        match Profile::from_toml(REFERENCE_TOML) {
            Ok(p) => p,
            // The file is compiled in and covered by tests; this arm is unreachable in practice.
            Err(e) => panic!("built-in reference profile is invalid: {e}"),
        }
    }

    /// A built-in name or a path to a TOML file. `help` and `list` are not profiles: the
    /// error lists the built-in ones (`--profile help`).
    pub fn load(name_or_path: &str) -> anyhow::Result<Profile> {
        if let Some(p) = Profile::builtin(name_or_path) {
            return Ok(p);
        }
        if matches!(name_or_path, "help" | "list" | "?") {
            anyhow::bail!(
                "printer profiles (built in; or give a TOML file's path):\n{}",
                listing()
            );
        }
        let path = Path::new(name_or_path);
        let text =
            crate::fileio::read_text_bounded(path, crate::fileio::Limit::Profile).map_err(|e| {
                anyhow::anyhow!(
                    "printer profile `{name_or_path}`: not a built-in ({}) and not readable: {e:#}",
                    BUILTIN.join(", ")
                )
            })?;
        Profile::from_toml(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
    }

    /// Checks that every number is finite and in a sensible range.
    pub fn validate(&self) -> anyhow::Result<()> {
        let pos = [
            ("filament_diameter_mm", self.filament_diameter_mm),
            ("filament_density_g_cm3", self.filament_density_g_cm3),
            ("travel_speed_mm_s", self.travel_speed_mm_s),
            ("limits.max_feed_xy_mm_s", self.limits.max_feed_xy_mm_s),
            ("limits.max_feed_z_mm_s", self.limits.max_feed_z_mm_s),
            ("limits.max_feed_e_mm_s", self.limits.max_feed_e_mm_s),
            ("limits.max_accel_x_mm_s2", self.limits.max_accel_x_mm_s2),
            ("limits.max_accel_y_mm_s2", self.limits.max_accel_y_mm_s2),
            ("limits.max_accel_z_mm_s2", self.limits.max_accel_z_mm_s2),
            ("limits.max_accel_e_mm_s2", self.limits.max_accel_e_mm_s2),
            ("limits.accel_print_mm_s2", self.limits.accel_print_mm_s2),
            ("limits.accel_travel_mm_s2", self.limits.accel_travel_mm_s2),
            (
                "limits.accel_retract_mm_s2",
                self.limits.accel_retract_mm_s2,
            ),
            (
                "limits.max_volumetric_mm3_s",
                self.limits.max_volumetric_mm3_s,
            ),
        ];
        for (name, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                anyhow::bail!(
                    "profile {}: {name} must be a positive number, got {v}",
                    self.name
                );
            }
        }
        let nonneg = [
            ("retraction.length_mm", self.retraction.length_mm),
            ("retraction.min_travel_mm", self.retraction.min_travel_mm),
            (
                "limits.junction_deviation_mm",
                self.limits.junction_deviation_mm,
            ),
            ("bed.z_max_mm", self.bed.z_max_mm),
        ];
        for (name, v) in nonneg {
            if !(v.is_finite() && v >= 0.0) {
                anyhow::bail!("profile {}: {name} must be ≥ 0, got {v}", self.name);
            }
        }
        if self.retraction.length_mm > 0.0
            && !(self.retraction.speed_mm_s.is_finite() && self.retraction.speed_mm_s > 0.0)
        {
            anyhow::bail!("profile {}: retraction.speed_mm_s must be > 0", self.name);
        }
        let b = &self.bed;
        if !(b.x_min_mm.is_finite()
            && b.x_max_mm.is_finite()
            && b.y_min_mm.is_finite()
            && b.y_max_mm.is_finite()
            && b.x_min_mm < b.x_max_mm
            && b.y_min_mm < b.y_max_mm)
        {
            anyhow::bail!(
                "profile {}: bed limits are not a valid rectangle",
                self.name
            );
        }
        if !(0.0..=1.0).contains(&self.fan) {
            anyhow::bail!("profile {}: fan must be within 0..=1", self.name);
        }
        if self.decimals == 0 || self.decimals > 6 {
            anyhow::bail!("profile {}: decimals must be 1..=6", self.name);
        }
        if !(self.nozzle_diameter_mm.is_finite() && self.nozzle_diameter_mm > 0.0) {
            anyhow::bail!("profile {}: nozzle_diameter_mm must be > 0", self.name);
        }
        for (part, t, primer_allowed) in [
            ("gcode.start", &self.gcode.start, true),
            ("gcode.end", &self.gcode.end, false),
            ("gcode.primer", &self.gcode.primer, false),
        ] {
            template::validate(t, primer_allowed)
                .map_err(|e| anyhow::anyhow!("profile {}: {part}: {e}", self.name))?;
        }
        Ok(())
    }

    /// Cross-section of the filament, mm².
    pub fn filament_area_mm2(&self) -> f64 {
        filament_area_mm2(self.filament_diameter_mm)
    }

    /// Bed centre (X, Y), mm.
    pub fn bed_center(&self) -> [f64; 2] {
        [
            0.5 * (self.bed.x_min_mm + self.bed.x_max_mm),
            0.5 * (self.bed.y_min_mm + self.bed.y_max_mm),
        ]
    }

    /// Start code with the temperatures filled in (`{lift_z}`/`{park_z}` go to `z_max`).
    pub fn start_code(&self, hotend_c: f64, bed_c: f64) -> String {
        self.fill(
            &self.gcode.start,
            &TemplateValues::temperatures(hotend_c, bed_c),
        )
    }

    /// End code with the temperatures filled in (`{lift_z}`/`{park_z}` go to `z_max`; see
    /// [`Profile::fill`] for a known top).
    pub fn end_code(&self, hotend_c: f64, bed_c: f64) -> String {
        self.fill(
            &self.gcode.end,
            &TemplateValues::temperatures(hotend_c, bed_c),
        )
    }
}

/// The built-in profiles, one line each: name, firmware, bed, nozzle, description.
pub fn listing() -> String {
    let mut out = String::new();
    for name in BUILTIN {
        if let Some(p) = Profile::builtin(name) {
            let b = &p.bed;
            out.push_str(&format!(
                "  {:<13} {:<10} {:>4.0}×{:<4.0}×{:>4.0} mm  nozzle {:.2}  {}  {}\n",
                p.name,
                p.firmware.name(),
                b.x_max_mm - b.x_min_mm,
                b.y_max_mm - b.y_min_mm,
                b.z_max_mm,
                p.nozzle_diameter_mm,
                match p.markers {
                    Markers::Prusa => "prusa-markers",
                    Markers::Cura => "cura-markers ",
                },
                p.description
            ));
        }
    }
    out
}

/// Area of a filament of diameter `d_mm`, mm².
pub fn filament_area_mm2(d_mm: f64) -> f64 {
    std::f64::consts::PI * 0.25 * d_mm * d_mm
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(name: &str) -> &'static str {
        BUILTIN_TOML
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, t)| *t)
            .unwrap_or("")
    }

    #[test]
    fn builtins_parse_and_differ() {
        assert_eq!(BUILTIN.len(), BUILTIN_TOML.len());
        for name in BUILTIN {
            let p = Profile::builtin(name).unwrap_or_else(|| panic!("{name} does not load"));
            assert_eq!(&p.name, name);
            assert!(!p.description.is_empty() && !p.source.is_empty(), "{name}");
        }
        let e = Profile::builtin("ender3").expect("ender3");
        let s = Profile::builtin("skr2").expect("skr2");
        assert_eq!(e.e_mode, EMode::Absolute);
        assert_eq!(s.e_mode, EMode::Relative);
        assert_eq!(e.markers, Markers::Cura);
        assert!(Profile::builtin("mk3s").expect("mk3s").progress);
        assert!(e.start_code(200.0, 60.0).contains("M109 S200"));
        assert!(Profile::builtin("nope").is_none());
    }

    #[test]
    fn invalid_profile_is_rejected() {
        let bad =
            text("ender3").replace("filament_diameter_mm = 1.75", "filament_diameter_mm = -1");
        assert!(Profile::from_toml(&bad).is_err());
        assert!(Profile::from_toml("name = 3").is_err());
        assert!(Profile::load("/nonexistent/profile.toml").is_err());
    }

    /// An unknown key is an error naming the key, at the top level and in a table.
    #[test]
    fn unknown_keys_are_named() {
        let t = text("ender3").replace("decimals = 3", "decimals = 3\nnozle_diameter_mm = 0.4");
        let e = format!("{:#}", Profile::from_toml(&t).expect_err("unknown key"));
        assert!(e.contains("nozle_diameter_mm"), "{e}");
        let t = text("ender3").replace("x_min_mm = 0.0", "x_min_mm = 0.0\nx_size_mm = 3.0");
        let e = format!("{:#}", Profile::from_toml(&t).expect_err("unknown key"));
        assert!(e.contains("x_size_mm"), "{e}");
    }

    /// An unknown placeholder is an error naming it; `{{`/`}}` are literal braces.
    #[test]
    fn unknown_placeholders_are_named() {
        let t = text("ender3").replace("M105\nM190", "M105 {bed_temp}\nM190");
        let e = format!(
            "{:#}",
            Profile::from_toml(&t).expect_err("unknown placeholder")
        );
        assert!(e.contains("{bed_temp}") && e.contains("gcode.start"), "{e}");
        let t = text("ender3").replace("M84 X Y E", "M84 X Y E {oops");
        let e = format!("{:#}", Profile::from_toml(&t).expect_err("unclosed"));
        assert!(e.contains("gcode.end") && e.contains("unclosed"), "{e}");
        let t = text("ender3").replace("M84 X Y E", "M84 X Y E ; {{literal}}");
        let p = Profile::from_toml(&t).expect("escaped braces");
        assert!(p.end_code(200.0, 60.0).contains("; {literal}"));
    }

    #[test]
    fn placeholders_fill() {
        let p = Profile::builtin("mk3s").expect("mk3s");
        let v = TemplateValues {
            top_z_mm: Some(20.0),
            ..TemplateValues::temperatures(214.6, 59.5)
        };
        let end = p.fill(&p.gcode.end, &v);
        assert!(end.contains("G1 Z22 F720"), "{end}");
        assert!(end.contains("G1 Z70 F720"), "{end}");
        let tall = TemplateValues {
            top_z_mm: Some(200.0),
            ..v
        };
        assert!(p.fill(&p.gcode.end, &tall).contains("G1 Z210 F720"));
        let start = p.fill(&p.gcode.start, &v);
        assert!(
            start.contains("M109 S215") && start.contains("M190 S60"),
            "{start}"
        );
        assert!(start.contains("M862.1 P0.4"), "{start}");
    }

    #[test]
    fn help_lists_every_builtin() {
        let e = format!(
            "{:#}",
            Profile::load("help").expect_err("help is a listing")
        );
        for name in BUILTIN {
            assert!(e.contains(name), "{name} missing from:\n{e}");
        }
    }
}
