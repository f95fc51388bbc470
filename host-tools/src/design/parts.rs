//! Library parts: helix (spiral wall), flat disc bottom (Archimedean spiral) and cylinder
//! (a disc bottom followed by a helix). Each returns a [`Model`] whose axis is the part's
//! centre, with a turn marker at the start of every helix turn.

use crate::design::model::{Arc, MarkerKind, Model, Step, Str};
use glam::DVec3;
use std::f64::consts::TAU;

/// Largest number of strings one part may have (guards scripts against runaway sizes): the
/// model's limit for any operation.
pub const MAX_PART_STRINGS: usize = crate::design::model::MAX_STRINGS;

/// A helix around a vertical axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Helix {
    /// Axis (X, Y), mm.
    pub center_xy: [f64; 2],
    /// Height of the first point, mm.
    pub z0_mm: f64,
    /// Radius, mm.
    pub radius_mm: f64,
    /// Rise per turn, mm.
    pub pitch_mm: f64,
    /// Number of turns (may be fractional).
    pub turns: f64,
    /// Strings per turn.
    pub per_turn: usize,
    /// Cross-section, mm².
    pub cross_mm2: f64,
    /// Head speed, mm/s.
    pub speed_mm_s: f64,
    /// Write true helical arcs (G2/G3 with Z) instead of chords.
    pub arcs: bool,
    /// Start angle, radians (0 = +X).
    pub start_rad: f64,
}

impl Default for Helix {
    fn default() -> Self {
        Helix {
            center_xy: [117.5, 117.5],
            z0_mm: 0.2,
            radius_mm: 10.0,
            pitch_mm: 0.4,
            turns: 10.0,
            per_turn: 72,
            cross_mm2: 0.2,
            speed_mm_s: 20.0,
            arcs: false,
            start_rad: 0.0,
        }
    }
}

/// Part errors (bad parameters).
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{0}")]
pub struct PartError(pub String);

fn check(name: &str, v: f64, min: f64) -> Result<(), PartError> {
    if v.is_finite() && v >= min {
        Ok(())
    } else {
        Err(PartError(format!(
            "{name} must be finite and ≥ {min}, got {v}"
        )))
    }
}

impl Helix {
    fn validate(&self) -> Result<usize, PartError> {
        check("radius", self.radius_mm, 1e-6)?;
        check("pitch", self.pitch_mm, 0.0)?;
        check("turns", self.turns, 0.0)?;
        check("cross-section", self.cross_mm2, 0.0)?;
        check("speed", self.speed_mm_s, 1e-9)?;
        check("z0", self.z0_mm, f64::MIN)?;
        check("centre x", self.center_xy[0], f64::MIN)?;
        check("centre y", self.center_xy[1], f64::MIN)?;
        check("start angle", self.start_rad, f64::MIN)?;
        if self.per_turn < 1 {
            return Err(PartError("points per turn must be ≥ 1".into()));
        }
        let n = (self.turns * self.per_turn as f64).round();
        if n > MAX_PART_STRINGS as f64 {
            return Err(PartError(format!(
                "helix would have {n} strings (limit {MAX_PART_STRINGS})"
            )));
        }
        Ok(n as usize)
    }

    /// Point at step `k` (k = 0 is the start).
    pub fn point(&self, k: usize) -> DVec3 {
        let t = k as f64 / self.per_turn as f64;
        let a = self.start_rad + TAU * t;
        DVec3::new(
            self.center_xy[0] + self.radius_mm * a.cos(),
            self.center_xy[1] + self.radius_mm * a.sin(),
            self.z0_mm + self.pitch_mm * t,
        )
    }

    /// The helix as a model: one string per step, counter-clockwise, a turn marker at the
    /// start of each turn.
    pub fn build(&self) -> Result<Model, PartError> {
        let mut m = Model::new(self.center_xy);
        self.build_into(&mut m)?;
        Ok(m)
    }

    /// Appends the helix's steps to `m` (after whatever `m` already holds, e.g. a comment;
    /// `m`'s axis is left as it is).
    pub fn build_into(&self, m: &mut Model) -> Result<(), PartError> {
        let n = self.validate()?;
        m.steps.reserve(n + n / self.per_turn + 2);
        let mut prev = self.point(0);
        for k in 0..n {
            if k % self.per_turn == 0 {
                m.steps.push(Step::Marker {
                    kind: MarkerKind::Turn,
                    z_mm: prev.z,
                    height_mm: self.pitch_mm,
                });
            }
            let p = self.point(k + 1);
            let mut s = Str::line(prev, p, self.cross_mm2, self.speed_mm_s);
            if self.arcs {
                s.arc = Some(Arc {
                    center_xy: self.center_xy,
                    ccw: true,
                });
            }
            m.steps.push(Step::String(s));
            prev = p;
        }
        Ok(())
    }
}

/// A flat disc filled by an Archimedean spiral from the centre outwards, `spacing_mm` between
/// rings, chords no longer than `max_seg_mm`. It ends on the rim at angle 0 (+X), where a
/// helix of the same radius starts, so a cylinder's wall follows without a travel.
#[allow(clippy::too_many_arguments)]
pub fn disc(
    center_xy: [f64; 2],
    z_mm: f64,
    radius_mm: f64,
    spacing_mm: f64,
    max_seg_mm: f64,
    cross_mm2: f64,
    speed_mm_s: f64,
) -> Result<Model, PartError> {
    check("radius", radius_mm, 1e-6)?;
    check("spacing", spacing_mm, 1e-3)?;
    check("segment length", max_seg_mm, 1e-3)?;
    check("cross-section", cross_mm2, 0.0)?;
    check("speed", speed_mm_s, 1e-9)?;
    check("z", z_mm, f64::MIN)?;
    let mut m = Model::new(center_xy);
    m.push(Step::Marker {
        kind: MarkerKind::Layer,
        z_mm,
        height_mm: z_mm,
    });
    let r_min = 0.5 * spacing_mm;
    if radius_mm <= r_min {
        return Ok(m);
    }
    // r(a) = radius + spacing·a/2π for a from −a0 (r = r_min) up to 0 (r = radius).
    let a0 = (radius_mm - r_min) / spacing_mm * TAU;
    let at = |a: f64| {
        let r = radius_mm + spacing_mm * a / TAU;
        DVec3::new(center_xy[0] + r * a.cos(), center_xy[1] + r * a.sin(), z_mm)
    };
    let mut a = -a0;
    let mut prev = at(a);
    let mut count = 0usize;
    while a < 0.0 {
        let r = (radius_mm + spacing_mm * a / TAU).max(r_min);
        // The radius grows along the step: size it for the larger end.
        let da = (0.95 * max_seg_mm / (r + spacing_mm)).min(TAU / 8.0);
        a = (a + da).min(0.0);
        let p = at(a);
        m.push(Step::String(Str::line(prev, p, cross_mm2, speed_mm_s)));
        prev = p;
        count += 1;
        if count > MAX_PART_STRINGS {
            return Err(PartError("disc has too many strings".into()));
        }
    }
    Ok(m)
}

/// A cylinder: a disc bottom (first layer at `z0_mm`) followed by a helical wall of the same
/// radius rising `pitch_mm` per turn to `height_mm`.
#[allow(clippy::too_many_arguments)]
pub fn cylinder(
    center_xy: [f64; 2],
    z0_mm: f64,
    radius_mm: f64,
    height_mm: f64,
    pitch_mm: f64,
    per_turn: usize,
    cross_mm2: f64,
    speed_mm_s: f64,
) -> Result<Model, PartError> {
    check("height", height_mm, 0.0)?;
    check("pitch", pitch_mm, 1e-3)?;
    let bottom = disc(
        center_xy,
        z0_mm,
        radius_mm,
        pitch_mm.max(0.3),
        (TAU * radius_mm / per_turn.max(1) as f64).max(0.5),
        cross_mm2,
        speed_mm_s,
    )?;
    let wall = Helix {
        center_xy,
        z0_mm,
        radius_mm,
        pitch_mm,
        turns: (height_mm - z0_mm).max(0.0) / pitch_mm,
        per_turn,
        cross_mm2,
        speed_mm_s,
        arcs: false,
        start_rad: 0.0,
    }
    .build()?;
    Ok(bottom.then(wall))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helix_counts_and_pitch() {
        let h = Helix {
            turns: 16.0,
            per_turn: 72,
            ..Helix::default()
        };
        let m = h.build().expect("helix");
        assert_eq!(m.string_count(), 16 * 72);
        let markers = m
            .steps
            .iter()
            .filter(|s| matches!(s, Step::Marker { .. }))
            .count();
        assert_eq!(markers, 16);
        let bb = m.bbox();
        assert!((bb.max.z - bb.min.z - 6.4).abs() < 1e-9);
        assert!(Helix {
            radius_mm: f64::NAN,
            ..h
        }
        .build()
        .is_err());
    }

    #[test]
    fn disc_stays_inside_radius() {
        let m = disc([50.0, 50.0], 0.3, 10.0, 0.5, 1.0, 0.2, 20.0).expect("disc");
        assert!(m.string_count() > 100);
        for s in m.strings() {
            assert!((s.end.truncate() - glam::DVec2::new(50.0, 50.0)).length() <= 10.0 + 1e-9);
            assert!(s.len_mm() <= 1.0 + 1e-9);
        }
        let last = m.strings().last().map(|s| s.end).unwrap_or_default();
        assert!((last - DVec3::new(60.0, 50.0, 0.3)).length() < 1e-9);
    }

    #[test]
    fn cylinder_wall_follows_the_bottom_without_travel() {
        let m = cylinder([50.0, 50.0], 0.2, 10.0, 5.0, 0.4, 72, 0.2, 20.0).expect("cyl");
        let strs: Vec<_> = m.strings().collect();
        for w in strs.windows(2) {
            assert!((w[0].end - w[1].start).length() < 1e-9);
        }
    }
}
