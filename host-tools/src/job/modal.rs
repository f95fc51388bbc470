//! Modal state of a G-code stream as the host tracks it: the last commanded logical position
//! (after G92), absolute/relative modes, units and feed rate. The host needs it to resume where a
//! pause was taken, to split moves, and to keep E continuous when job pieces are spliced.
//!
//! Modes follow Marlin (and our firmware): `G90`/`G91` switch every axis including E, `M82`/`M83`
//! switch only E, `G92` sets the logical position (no argument: all axes to 0), `G28` homes the
//! named axes (all when none) to 0.

use super::gcode::Command;

/// Axis indices into [`Modal::pos`].
pub const X: usize = 0;
/// Y index.
pub const Y: usize = 1;
/// Z index.
pub const Z: usize = 2;
/// E index.
pub const E: usize = 3;
const LETTERS: [char; 4] = ['X', 'Y', 'Z', 'E'];

/// The modal state after some prefix of a job.
#[derive(Clone, Debug, PartialEq)]
pub struct Modal {
    /// Last commanded logical position, mm (X, Y, Z, E).
    pub pos_mm: [f64; 4],
    /// Whether each axis position is known (set by a move, G92 or G28).
    pub known: [bool; 4],
    /// Absolute XYZ (G90) or relative (G91).
    pub abs_xyz: bool,
    /// Absolute E (M82) or relative (M83).
    pub abs_e: bool,
    /// Inches (G20) instead of millimetres (G21).
    pub inches: bool,
    /// Last feed rate, mm/min, as written in the file (F words).
    pub feed_mm_min: Option<f64>,
}

impl Default for Modal {
    fn default() -> Self {
        Modal {
            pos_mm: [0.0; 4],
            known: [false; 4],
            abs_xyz: true,
            abs_e: true,
            inches: false,
            feed_mm_min: None,
        }
    }
}

/// A straight or arc move as seen by the host, in logical millimetres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Move {
    /// Start position.
    pub from_mm: [f64; 4],
    /// End position.
    pub to_mm: [f64; 4],
    /// Feed rate in force for this move, mm/min.
    pub feed_mm_min: Option<f64>,
    /// G0/G1 (true) or G2/G3 arcs (false).
    pub linear: bool,
}

impl Move {
    /// XY length, mm.
    pub fn xy_len_mm(&self) -> f64 {
        let dx = self.to_mm[X] - self.from_mm[X];
        let dy = self.to_mm[Y] - self.from_mm[Y];
        (dx * dx + dy * dy).sqrt()
    }

    /// XYZ length, mm.
    pub fn xyz_len_mm(&self) -> f64 {
        let dz = self.to_mm[Z] - self.from_mm[Z];
        (self.xy_len_mm().powi(2) + dz * dz).sqrt()
    }

    /// Filament fed, mm (negative: retract).
    pub fn e_mm(&self) -> f64 {
        self.to_mm[E] - self.from_mm[E]
    }

    /// True when the move deposits material along a path (E increases while XY moves).
    pub fn extrudes(&self) -> bool {
        self.e_mm() > 1e-9 && self.xy_len_mm() > 1e-9
    }

    /// Estimated duration, s, at the commanded feed (no acceleration): for progress and time left.
    pub fn est_time_s(&self) -> f64 {
        let len = self.xyz_len_mm().max(self.e_mm().abs());
        match self.feed_mm_min {
            Some(f) if f > 0.0 => len / (f / 60.0),
            _ => len / 25.0,
        }
    }
}

impl Modal {
    /// Applies one command; returns the move it makes, if it is a move.
    pub fn apply(&mut self, cmd: &Command) -> Option<Move> {
        let scale = if self.inches { 25.4 } else { 1.0 };
        match (cmd.letter, cmd.number) {
            ('G', 0..=3) => {
                if let Some(f) = cmd.get('F') {
                    self.feed_mm_min = Some(f * scale);
                }
                let from = self.pos_mm;
                let mut any = false;
                for (i, l) in LETTERS.iter().enumerate() {
                    if let Some(v) = cmd.get(*l) {
                        any = true;
                        let v = v * scale;
                        let abs = if i == E { self.abs_e } else { self.abs_xyz };
                        self.pos_mm[i] = if abs { v } else { self.pos_mm[i] + v };
                        self.known[i] = true;
                    }
                }
                any.then_some(Move {
                    from_mm: from,
                    to_mm: self.pos_mm,
                    feed_mm_min: self.feed_mm_min,
                    linear: cmd.number <= 1,
                })
            }
            ('G', 20) => {
                self.inches = true;
                None
            }
            ('G', 21) => {
                self.inches = false;
                None
            }
            ('G', 28) => {
                let named: Vec<usize> = (0..3).filter(|&i| cmd.has(LETTERS[i])).collect();
                let axes = if named.is_empty() {
                    vec![X, Y, Z]
                } else {
                    named
                };
                for i in axes {
                    self.pos_mm[i] = 0.0;
                    self.known[i] = true;
                }
                None
            }
            ('G', 90) => {
                self.abs_xyz = true;
                self.abs_e = true;
                None
            }
            ('G', 91) => {
                self.abs_xyz = false;
                self.abs_e = false;
                None
            }
            ('G', 92) => {
                let mut any = false;
                for (i, l) in LETTERS.iter().enumerate() {
                    if let Some(v) = cmd.get(*l) {
                        any = true;
                        self.pos_mm[i] = v * scale;
                        self.known[i] = true;
                    }
                }
                if !any {
                    self.pos_mm = [0.0; 4];
                    self.known = [true; 4];
                }
                None
            }
            ('M', 82) => {
                self.abs_e = true;
                None
            }
            ('M', 83) => {
                self.abs_e = false;
                None
            }
            _ => None,
        }
    }

    /// G-code lines that put a printer whose modal state is unknown into this state for E and
    /// feed: the E mode, the logical E position (`G92 E`) and the feed rate. Positioning mode
    /// is restored too. Used after spliced or inserted code.
    pub fn restore_lines(&self) -> Vec<String> {
        let mut out = vec![if self.abs_xyz { "G90" } else { "G91" }.to_string()];
        out.push(if self.abs_e { "M82" } else { "M83" }.to_string());
        out.push(format!("G92 E{}", fmt_mm(self.pos_mm[E])));
        if let Some(f) = self.feed_mm_min {
            out.push(format!("G1 F{}", fmt_mm(f)));
        }
        out
    }
}

/// Formats a length for G-code: up to 5 decimals, trailing zeros trimmed, never `-0`.
pub fn fmt_mm(v: f64) -> String {
    let mut s = format!("{v:.5}");
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
        if s.ends_with('.') {
            s.pop();
        }
    }
    if s == "-0" {
        s = "0".into();
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_lengths() {
        assert_eq!(fmt_mm(1.0), "1");
        assert_eq!(fmt_mm(0.2), "0.2");
        assert_eq!(fmt_mm(-0.000001), "0");
        assert_eq!(fmt_mm(12.345678), "12.34568");
    }
}
