//! Printer profiles (TOML): bed, filament, temperatures, start/end code, absolute or relative
//! E, retraction and motion limits. Two ship built in (`host-tools/profiles/`): `ender3`
//! (Ender-3-class, absolute E) and `skr2` (the same mechanics on an SKR 2 running our
//! firmware, relative E). Every tool that needs a printer (compile, stats, preview, checks,
//! the time-based resampler) takes a [`Profile`].

use serde::{Deserialize, Serialize};
use std::path::Path;

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
pub struct Retraction {
    /// Filament pulled back, mm (0 disables retraction).
    pub length_mm: f64,
    /// Retract and prime speed, mm/s.
    pub speed_mm_s: f64,
    /// Travels shorter than this do not retract, mm.
    pub min_travel_mm: f64,
}

/// Motion limits (Marlin's M203/M201/M204/M205 J), used by the time estimate and checks.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
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

/// Start and end code templates; `{hotend_c}`, `{bed_c}` are replaced.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GcodeTemplates {
    /// Written before the design.
    pub start: String,
    /// Written after the design.
    pub end: String,
}

/// A printer profile.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    /// Profile name.
    pub name: String,
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

const ENDER3_TOML: &str = include_str!("../../profiles/ender3.toml");
const SKR2_TOML: &str = include_str!("../../profiles/skr2.toml");

/// Names of the built-in profiles.
pub const BUILTIN: &[&str] = &["ender3", "skr2"];

impl Profile {
    /// Parses a profile from TOML text and validates it.
    pub fn from_toml(text: &str) -> anyhow::Result<Profile> {
        let p: Profile = toml::from_str(text)?;
        p.validate()?;
        Ok(p)
    }

    /// A built-in profile by name (`ender3`, `skr2`).
    pub fn builtin(name: &str) -> Option<Profile> {
        let text = match name {
            "ender3" => ENDER3_TOML,
            "skr2" => SKR2_TOML,
            _ => return None,
        };
        Profile::from_toml(text).ok()
    }

    /// The Ender-3 profile (the default).
    pub fn ender3() -> Profile {
        match Profile::from_toml(ENDER3_TOML) {
            Ok(p) => p,
            // The file is compiled in and covered by tests; this arm is unreachable in practice.
            Err(e) => panic!("built-in ender3 profile is invalid: {e}"),
        }
    }

    /// A built-in name or a path to a TOML file.
    pub fn load(name_or_path: &str) -> anyhow::Result<Profile> {
        if let Some(p) = Profile::builtin(name_or_path) {
            return Ok(p);
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

    /// Start code with the temperatures filled in.
    pub fn start_code(&self, hotend_c: f64, bed_c: f64) -> String {
        fill(&self.gcode.start, hotend_c, bed_c)
    }

    /// End code with the temperatures filled in.
    pub fn end_code(&self, hotend_c: f64, bed_c: f64) -> String {
        fill(&self.gcode.end, hotend_c, bed_c)
    }
}

/// Area of a filament of diameter `d_mm`, mm².
pub fn filament_area_mm2(d_mm: f64) -> f64 {
    std::f64::consts::PI * 0.25 * d_mm * d_mm
}

fn fill(t: &str, hotend_c: f64, bed_c: f64) -> String {
    t.replace("{hotend_c}", &format!("{}", hotend_c.round() as i64))
        .replace("{bed_c}", &format!("{}", bed_c.round() as i64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_parse_and_differ() {
        let e = Profile::builtin("ender3").expect("ender3");
        let s = Profile::builtin("skr2").expect("skr2");
        assert_eq!(e.e_mode, EMode::Absolute);
        assert_eq!(s.e_mode, EMode::Relative);
        assert!(e.start_code(200.0, 60.0).contains("M109 S200"));
        assert!(Profile::builtin("nope").is_none());
    }

    #[test]
    fn invalid_profile_is_rejected() {
        let bad = ENDER3_TOML.replace("filament_diameter_mm = 1.75", "filament_diameter_mm = -1");
        assert!(Profile::from_toml(&bad).is_err());
        assert!(Profile::from_toml("name = 3").is_err());
        assert!(Profile::load("/nonexistent/profile.toml").is_err());
    }
}
