//! Modulation by a bitmap (Kanada): each string is mapped to one pixel; an ink pixel prints the
//! string slower and thicker, a blank pixel at the nominal speed and cross-section. The
//! volumetric flow (cross-section × speed) stays the same for both, so the extruder, whose
//! lag can be seconds, never has to change speed: only the head does, and it responds at once.
//!
//! The contrast is the speed ratio, default 1 : 1.3; above 1 : 1.4 a warning is returned
//! (the paper's prints failed beyond that).
//!
//! The globe ([`globe`]): a 300 × 150 equirectangular map on a sphere made from a helix of
//! 150 turns × 300 strings, one pixel per string, thinned near the poles at emission.

use crate::design::deform::{helix_to_sphere, DeformError};
use crate::design::model::{MarkerKind, Model, Step};
use crate::design::parts::Helix;

/// Default contrast (speed ratio) of the paper.
pub const DEFAULT_CONTRAST: f64 = 1.3;
/// Above this contrast a warning is issued.
pub const WARN_CONTRAST: f64 = 1.4;

/// A 1-bit picture: `true` = ink (dark).
#[derive(Clone, Debug, PartialEq)]
pub struct Bitmap {
    width: u32,
    height: u32,
    ink: Vec<bool>,
}

/// The binarised world map shipped in `host-tools/assets/` (see its README for the source).
pub const WORLD_MAP_PNG: &[u8] = include_bytes!("../../assets/world_300x150.png");

/// Modulation errors.
#[derive(Debug, thiserror::Error)]
pub enum ModulateError {
    /// The picture could not be read.
    #[error("bitmap: {0}")]
    Image(String),
    /// A parameter is out of range.
    #[error("{0}")]
    Bad(String),
    /// The underlying deformation failed.
    #[error(transparent)]
    Deform(#[from] DeformError),
}

impl Bitmap {
    /// From raw ink values, row-major, row 0 at the top.
    pub fn from_ink(width: u32, height: u32, ink: Vec<bool>) -> Result<Bitmap, ModulateError> {
        if width == 0 || height == 0 || ink.len() != (width as usize) * (height as usize) {
            return Err(ModulateError::Bad(format!(
                "bitmap {width}×{height} needs {} pixels, got {}",
                width as u64 * height as u64,
                ink.len()
            )));
        }
        Ok(Bitmap { width, height, ink })
    }

    /// Decodes a PNG (any colour type); pixels darker than 50 % grey are ink.
    pub fn from_png(bytes: &[u8]) -> Result<Bitmap, ModulateError> {
        let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
            .map_err(|e| ModulateError::Image(e.to_string()))?
            .to_luma8();
        let (w, h) = img.dimensions();
        let ink = img.pixels().map(|p| p.0[0] < 128).collect();
        Bitmap::from_ink(w, h, ink)
    }

    /// Reads a PNG file.
    pub fn load(path: &std::path::Path) -> Result<Bitmap, ModulateError> {
        let bytes = crate::fileio::read_bounded(path, crate::fileio::Limit::Drawing)
            .map_err(|e| ModulateError::Image(format!("{e:#}")))?;
        Bitmap::from_png(&bytes)
    }

    /// The shipped world map (300 × 150).
    pub fn world_map() -> Result<Bitmap, ModulateError> {
        Bitmap::from_png(WORLD_MAP_PNG)
    }

    /// Width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Ink at (x, y), row 0 at the top; outside is blank.
    pub fn ink(&self, x: u32, y: u32) -> bool {
        if x >= self.width || y >= self.height {
            return false;
        }
        self.ink
            .get(y as usize * self.width as usize + x as usize)
            .copied()
            .unwrap_or(false)
    }

    /// Fraction of ink pixels.
    pub fn ink_fraction(&self) -> f64 {
        self.ink.iter().filter(|b| **b).count() as f64 / self.ink.len() as f64
    }
}

/// Checks a contrast: must be ≥ 1; returns a warning above [`WARN_CONTRAST`].
pub fn check_contrast(contrast: f64) -> Result<Option<String>, ModulateError> {
    if !(contrast.is_finite() && contrast >= 1.0) {
        return Err(ModulateError::Bad(format!(
            "contrast must be a speed ratio ≥ 1, got {contrast}"
        )));
    }
    Ok((contrast > WARN_CONTRAST).then(|| {
        format!(
            "contrast 1:{contrast} is above 1:{WARN_CONTRAST}; the paper's prints failed beyond it"
        )
    }))
}

/// Modulates strings by pixels: `pixel_of(i)` gives the pixel of the i-th string (or `None`
/// to leave it). Ink strings get speed ÷ contrast and cross-section × contrast (same flow).
/// Returns the model and any warning.
pub fn modulate_by(
    model: Model,
    bitmap: &Bitmap,
    contrast: f64,
    mut pixel_of: impl FnMut(usize) -> Option<(u32, u32)>,
) -> Result<(Model, Vec<String>), ModulateError> {
    let warn = check_contrast(contrast)?;
    let m = model.map_strings(|i, s| {
        if let Some((x, y)) = pixel_of(i) {
            if bitmap.ink(x, y) {
                s.speed_mm_s /= contrast;
                s.cross_mm2 *= contrast;
            }
        }
    });
    Ok((m, warn.into_iter().collect()))
}

/// Modulates a helix-like model with `per_turn` strings per turn: string `i` is turn
/// `i / per_turn` (from the bottom, mapped to picture rows from the bottom) and column
/// `i % per_turn` (mapped to picture columns), both scaled to the picture size. Strings are
/// counted from the first turn marker: a floor before the helix (`cylinder()`'s disc) is not
/// part of the picture and is left as it is (a model without turn markers counts them all).
pub fn modulate_helix(
    model: Model,
    bitmap: &Bitmap,
    per_turn: usize,
    contrast: f64,
) -> Result<(Model, Vec<String>), ModulateError> {
    if per_turn == 0 {
        return Err(ModulateError::Bad("strings per turn must be ≥ 1".into()));
    }
    let floor = model
        .steps
        .iter()
        .position(|s| {
            matches!(
                s,
                Step::Marker {
                    kind: MarkerKind::Turn,
                    ..
                }
            )
        })
        .map_or(0, |k| {
            model.steps[..k]
                .iter()
                .filter(|s| matches!(s, Step::String(_)))
                .count()
        });
    let n = model.string_count() - floor;
    let turns = n.div_ceil(per_turn).max(1);
    let (w, h) = (bitmap.width() as usize, bitmap.height() as usize);
    modulate_by(model, bitmap, contrast, |i| {
        let i = i.checked_sub(floor)?;
        let turn = i / per_turn;
        let col = i % per_turn;
        let x = col * w / per_turn;
        let row_from_bottom = turn * h / turns;
        let y = h.checked_sub(1 + row_from_bottom)?;
        Some((x as u32, y as u32))
    })
}

/// Parameters of the globe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Globe {
    /// Centre of the sphere (X, Y), mm.
    pub center_xy: [f64; 2],
    /// Height of the bottom point, mm.
    pub z0_mm: f64,
    /// Turns (picture rows).
    pub turns: usize,
    /// Strings per turn (picture columns).
    pub per_turn: usize,
    /// Distance between turns along the meridian, mm.
    pub pitch_mm: f64,
    /// Nominal cross-section, mm² (×1.2 by the sphere deformation).
    pub cross_mm2: f64,
    /// Nominal speed, mm/s (scaled by the sphere deformation).
    pub speed_mm_s: f64,
    /// Contrast (speed ratio).
    pub contrast: f64,
    /// Emission thinning: strings shorter than this are merged when written, mm.
    pub thin_min_len_mm: f64,
}

impl Default for Globe {
    fn default() -> Self {
        Globe {
            center_xy: [117.5, 117.5],
            z0_mm: 0.3,
            turns: 150,
            per_turn: 300,
            pitch_mm: 0.4,
            cross_mm2: 0.16,
            speed_mm_s: 25.0,
            contrast: DEFAULT_CONTRAST,
            thin_min_len_mm: 0.2,
        }
    }
}

/// Builds the globe: helix (radius R = H/π, so the meridian keeps the pitch) → sphere →
/// modulated by `bitmap`, with emission thinning near the poles.
pub fn globe(g: &Globe, bitmap: &Bitmap) -> Result<(Model, Vec<String>), ModulateError> {
    if g.turns == 0 || g.per_turn == 0 {
        return Err(ModulateError::Bad(
            "globe needs turns and strings per turn".into(),
        ));
    }
    let height = g.turns as f64 * g.pitch_mm;
    let radius = height / std::f64::consts::PI;
    // The comment goes first; the helix is built after it (no shifting of 45,000 steps).
    let mut helix = Model::new(g.center_xy);
    helix.steps.push(Step::Comment(format!(
        "globe: {} turns x {} strings, radius {:.2} mm, contrast 1:{}",
        g.turns, g.per_turn, radius, g.contrast
    )));
    Helix {
        center_xy: g.center_xy,
        z0_mm: g.z0_mm,
        radius_mm: radius,
        pitch_mm: g.pitch_mm,
        turns: g.turns as f64,
        per_turn: g.per_turn,
        cross_mm2: g.cross_mm2,
        speed_mm_s: g.speed_mm_s,
        arcs: false,
        start_rad: 0.0,
    }
    .build_into(&mut helix)
    .map_err(|e| ModulateError::Bad(e.to_string()))?;
    let sphere = helix_to_sphere(helix, radius, height, g.z0_mm, None)?;
    let (m, warnings) = modulate_helix(sphere, bitmap, g.per_turn, g.contrast)?;
    let m = m.thin_at_emission(g.thin_min_len_mm);
    Ok((m, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn world_map_loads() {
        let b = Bitmap::world_map().expect("map");
        assert_eq!((b.width(), b.height()), (300, 150));
        let f = b.ink_fraction();
        assert!(f > 0.2 && f < 0.45, "land fraction {f}");
        // Antarctica: the bottom row is land, the middle of the Pacific is not.
        assert!(b.ink(150, 149));
        assert!(!b.ink(5, 75));
    }

    #[test]
    fn contrast_rules() {
        assert!(check_contrast(0.9).is_err());
        assert!(check_contrast(f64::NAN).is_err());
        assert_eq!(check_contrast(1.3).ok(), Some(None));
        assert!(matches!(check_contrast(1.5), Ok(Some(_))));
    }

    #[test]
    fn globe_has_45000_strings_and_constant_flow() {
        let (m, w) = globe(&Globe::default(), &Bitmap::world_map().expect("map")).expect("globe");
        assert!(w.is_empty());
        assert_eq!(m.string_count(), 45_000);
        // Same flow with and without modulation: only speed and cross-section trade.
        let plain = Globe {
            contrast: 1.0,
            ..Globe::default()
        };
        let (p, _) = globe(&plain, &Bitmap::world_map().expect("map")).expect("globe");
        let mut slowed = 0;
        for (a, b) in m.strings().zip(p.strings()) {
            assert!((a.flow_mm3_s() - b.flow_mm3_s()).abs() < 1e-9);
            if a.speed_mm_s < b.speed_mm_s - 1e-9 {
                slowed += 1;
            }
        }
        let frac = slowed as f64 / 45_000.0;
        assert!(frac > 0.2 && frac < 0.45, "ink fraction {frac}");
        assert!(m.emission.thin_min_len_mm.is_some());
    }

    /// A cylinder's floor disc is not part of the picture: a picture of two vertical halves
    /// (ink on the left) slows exactly the first half of every wall turn, the floor not at all.
    #[test]
    fn cylinder_floor_does_not_shear_the_picture() {
        let per_turn = 40;
        let m = crate::design::parts::cylinder(
            [100.0, 100.0],
            0.2,
            10.0,
            4.2,
            0.4,
            per_turn,
            0.2,
            20.0,
        )
        .expect("cylinder");
        let floor = m
            .steps
            .iter()
            .take_while(|s| {
                !matches!(
                    s,
                    Step::Marker {
                        kind: MarkerKind::Turn,
                        ..
                    }
                )
            })
            .filter(|s| matches!(s, Step::String(_)))
            .count();
        assert!(floor > 0);
        let (w, h) = (8u32, 4u32);
        let ink = (0..w * h).map(|k| k % w < w / 2).collect();
        let b = Bitmap::from_ink(w, h, ink).expect("bitmap");
        let (out, _) = modulate_helix(m, &b, per_turn, 1.3).expect("modulate");
        for (i, s) in out.strings().enumerate() {
            let slowed = s.speed_mm_s < 20.0 - 1e-9;
            let want = i >= floor && (i - floor) % per_turn < per_turn / 2;
            assert_eq!(slowed, want, "string {i} (floor {floor})");
        }
    }
}
