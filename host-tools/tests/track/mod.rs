//! A G-code reader written for the tests, independent of the code under test (neither the
//! firmware's parser nor `gcode::read`): absolute/relative XYZ and E, `G92`, `G28`, fan and
//! temperature commands, and feed. Enough for the files host-tools writes.

#![allow(dead_code)]

/// One motion line as the tracker saw it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Move {
    /// 1-based line number.
    pub line: usize,
    /// `G0` rather than `G1`.
    pub rapid: bool,
    /// Position before, X Y Z.
    pub from: [f64; 3],
    /// Position after.
    pub to: [f64; 3],
    /// Filament fed by this move, mm (negative: retract).
    pub de: f64,
    /// Feed in force, mm/min.
    pub f: f64,
    /// Part fan duty in force, 0..=1.
    pub fan: f64,
    /// Hot-end target in force, °C.
    pub hotend: f64,
}

impl Move {
    /// Deposits material: E grows while XY moves.
    pub fn extrudes(&self) -> bool {
        self.de > 1e-9 && ((self.to[0] - self.from[0]).hypot(self.to[1] - self.from[1])) > 1e-9
    }
}

/// Everything the tracker found.
#[derive(Clone, Debug, Default)]
pub struct Track {
    /// Every move, in order.
    pub moves: Vec<Move>,
    /// Total filament fed by extruding moves (E growth while moving XY), mm.
    pub extruded_mm: f64,
    /// Lines that are `M106`/`M107`, with their line number and duty.
    pub fan_lines: Vec<(usize, f64)>,
    /// Hot-end targets set (`M104`/`M109 S`), with line numbers.
    pub hotend_lines: Vec<(usize, f64)>,
}

fn word(line: &str, letter: char) -> Option<f64> {
    line.split_whitespace()
        .skip(1)
        .find_map(|w| w.strip_prefix(letter).and_then(|v| v.parse().ok()))
}

/// Reads `text` from the machine's power-on state (absolute, position 0, fan off).
pub fn track(text: &str) -> Track {
    let mut t = Track::default();
    let (mut pos, mut e) = ([0.0f64; 3], 0.0f64);
    let (mut abs, mut abs_e, mut f, mut fan, mut hot) = (true, true, 0.0, 0.0, 0.0);
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split(';').next().unwrap_or("").trim();
        let cmd = line.split_whitespace().next().unwrap_or("");
        match cmd {
            "G90" => {
                abs = true;
                abs_e = true;
            }
            "G91" => {
                abs = false;
                abs_e = false;
            }
            "M82" => abs_e = true,
            "M83" => abs_e = false,
            "G92" => {
                if let Some(v) = word(line, 'E') {
                    e = v;
                }
                for (k, l) in ['X', 'Y', 'Z'].into_iter().enumerate() {
                    if let Some(v) = word(line, l) {
                        pos[k] = v;
                    }
                }
            }
            "G28" => pos = [0.0; 3],
            "M106" => {
                fan = word(line, 'S').unwrap_or(255.0) / 255.0;
                t.fan_lines.push((i + 1, fan));
            }
            "M107" => {
                fan = 0.0;
                t.fan_lines.push((i + 1, 0.0));
            }
            "M104" | "M109" => {
                if let Some(v) = word(line, 'S') {
                    hot = v;
                    t.hotend_lines.push((i + 1, v));
                }
            }
            "G0" | "G1" => {
                if let Some(v) = word(line, 'F') {
                    f = v;
                }
                let from = pos;
                for (k, l) in ['X', 'Y', 'Z'].into_iter().enumerate() {
                    if let Some(v) = word(line, l) {
                        pos[k] = if abs { v } else { pos[k] + v };
                    }
                }
                let de = match word(line, 'E') {
                    Some(v) if abs_e => {
                        let d = v - e;
                        e = v;
                        d
                    }
                    Some(v) => v,
                    None => 0.0,
                };
                let m = Move {
                    line: i + 1,
                    rapid: cmd == "G0",
                    from,
                    to: pos,
                    de,
                    f,
                    fan,
                    hotend: hot,
                };
                if m.extrudes() {
                    t.extruded_mm += de;
                }
                t.moves.push(m);
            }
            _ => {}
        }
    }
    t
}

/// Distance from `p` to the segment `a`–`b`.
pub fn seg_dist(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    let t = if l2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let q = [a[0] + ab[0] * t, a[1] + ab[1] * t, a[2] + ab[2] * t];
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}
