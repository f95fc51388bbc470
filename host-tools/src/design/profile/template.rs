//! Start and end code templates: `{name}` placeholders filled from the profile and the design
//! (temperatures, the print's top for the end code's lifts), `{{`/`}}` for literal braces, and
//! the `{primer}` line — the profile's purge, which a design may leave out
//! ([`Primer::None`]).

use super::Profile;
use serde::{Deserialize, Serialize};

/// Placeholders of start/end code, with what they become.
pub const PLACEHOLDERS: &[(&str, &str)] = &[
    (
        "hotend_c",
        "hotend temperature, °C (the design's, else the profile's)",
    ),
    (
        "bed_c",
        "bed temperature, °C (the design's, else the profile's)",
    ),
    ("nozzle_mm", "nozzle diameter, mm"),
    ("bed_x_min", "lowest X of the bed, mm"),
    ("bed_x_max", "highest X of the bed, mm"),
    ("bed_y_min", "lowest Y of the bed, mm"),
    ("bed_y_max", "highest Y of the bed, mm"),
    ("z_max", "highest Z, mm"),
    (
        "lift_z",
        "top of the print + 2 mm, at most z_max (end code: clear the part)",
    ),
    (
        "park_z",
        "top of the print + 50 mm, at most z_max (end code: present the part)",
    ),
    ("travel_f", "travel feed, mm/min"),
    (
        "primer",
        "the profile's `primer` (its purge line), on a line of its own; left out when the design asks for no primer",
    ),
];

/// Whether the start code primes the nozzle with the profile's purge (`{primer}`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Primer {
    /// The profile's purge line, as its slicer writes it.
    #[default]
    Profile,
    /// No purge: the design primes (or not) itself.
    None,
}

impl Primer {
    /// `"profile"` or `"none"`.
    pub fn parse(s: &str) -> Result<Primer, String> {
        match s {
            "profile" => Ok(Primer::Profile),
            "none" => Ok(Primer::None),
            other => Err(format!(
                "primer is \"profile\" (the printer's purge line) or \"none\", got \"{other}\""
            )),
        }
    }
}

/// Values the placeholders take in one write.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TemplateValues {
    /// Hotend temperature, °C.
    pub hotend_c: f64,
    /// Bed temperature, °C.
    pub bed_c: f64,
    /// Highest Z the print reaches, mm (`None`: unknown, the lifts go to `z_max`).
    pub top_z_mm: Option<f64>,
    /// The profile's primer or none.
    pub primer: Primer,
}

impl TemplateValues {
    /// The profile's primer, no known top.
    pub fn temperatures(hotend_c: f64, bed_c: f64) -> Self {
        TemplateValues {
            hotend_c,
            bed_c,
            top_z_mm: None,
            primer: Primer::Profile,
        }
    }
}

/// Checks a template when the profile is loaded: every placeholder is known, braces close,
/// `{primer}` stands on a line of its own (so leaving it out leaves no blank line).
pub(super) fn validate(t: &str, primer_allowed: bool) -> Result<(), String> {
    expand(t, &mut |n| {
        (PLACEHOLDERS.iter().any(|(k, _)| *k == n) && (primer_allowed || n != "primer"))
            .then(String::new)
    })?;
    for line in t.lines() {
        if line.contains("{primer}") && line.trim() != "{primer}" {
            return Err(format!(
                "`{{primer}}` must stand on a line of its own, got `{line}`"
            ));
        }
    }
    Ok(())
}

impl Profile {
    /// A template with its placeholders filled in. Templates were checked when the profile
    /// was loaded; an unknown placeholder in a hand-built profile is left as written.
    pub fn fill(&self, template: &str, v: &TemplateValues) -> String {
        let b = &self.bed;
        let zmax = b.z_max_mm;
        let lift = |dz: f64| match v.top_z_mm {
            Some(top) if top.is_finite() && zmax > 0.0 => (top + dz).min(zmax),
            Some(top) if top.is_finite() => top + dz,
            _ => zmax,
        };
        let num = |x: f64| {
            let r = (x * 1000.0).round() / 1000.0;
            format!("{r}")
        };
        let value = |name: &str| -> Option<String> {
            Some(match name {
                "hotend_c" => format!("{}", v.hotend_c.round() as i64),
                "bed_c" => format!("{}", v.bed_c.round() as i64),
                "nozzle_mm" => num(self.nozzle_diameter_mm),
                "bed_x_min" => num(b.x_min_mm),
                "bed_x_max" => num(b.x_max_mm),
                "bed_y_min" => num(b.y_min_mm),
                "bed_y_max" => num(b.y_max_mm),
                "z_max" => num(zmax),
                "lift_z" => num(lift(2.0)),
                "park_z" => num(lift(50.0)),
                "travel_f" => format!("{}", (self.travel_speed_mm_s * 60.0).round() as i64),
                _ => return None,
            })
        };
        let fill_one = |t: &str| match expand(t, &mut |n| value(n)) {
            Ok(s) => s,
            Err(_) => t.to_string(),
        };
        let primer = fill_one(&self.gcode.primer);
        let mut out = String::with_capacity(template.len() + primer.len());
        for piece in template.split_inclusive('\n') {
            if piece.trim() == "{primer}" {
                if v.primer == Primer::Profile && !primer.is_empty() {
                    out.push_str(&primer);
                    if piece.ends_with('\n') && !primer.ends_with('\n') {
                        out.push('\n');
                    }
                }
            } else {
                out.push_str(&fill_one(piece));
            }
        }
        out
    }
}

/// Expands `{name}` placeholders with `value`; `{{`/`}}` are literal braces. Errors name an
/// unknown placeholder or an unclosed brace.
pub(super) fn expand(
    t: &str,
    value: &mut dyn FnMut(&str) -> Option<String>,
) -> Result<String, String> {
    let mut out = String::with_capacity(t.len() + 16);
    let mut rest = t;
    while let Some(i) = rest.find(['{', '}']) {
        out.push_str(&rest[..i]);
        let tail = &rest[i..];
        if let Some(r) = tail.strip_prefix("{{") {
            out.push('{');
            rest = r;
        } else if let Some(r) = tail.strip_prefix("}}") {
            out.push('}');
            rest = r;
        } else if tail.starts_with('}') {
            return Err("a lone `}` (write `}}` for a literal brace)".into());
        } else {
            let Some(end) = tail.find('}') else {
                return Err(format!(
                    "unclosed placeholder `{}` (write `{{{{` for a literal brace)",
                    tail.lines().next().unwrap_or(tail)
                ));
            };
            let name = &tail[1..end];
            match value(name) {
                Some(v) => out.push_str(&v),
                None => {
                    return Err(format!(
                        "unknown placeholder `{{{name}}}` (known: {})",
                        PLACEHOLDERS
                            .iter()
                            .map(|(n, _)| *n)
                            .collect::<Vec<_>>()
                            .join(", ")
                    ))
                }
            }
            rest = &tail[end + 1..];
        }
    }
    out.push_str(rest);
    Ok(out)
}
