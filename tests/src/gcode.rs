//! A small G-code tracker of the tests' own (G90/G91, M82/M83, G92 E, G0/G1, G28), to check
//! the firmware against a sliced file without reusing the firmware's interpreter or its layer
//! detector: where the head is, and how much filament was fed, at each of the file's layer
//! markers.

/// The state at one layer marker of a file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Marker {
    /// Byte offset of the marker's line in the file.
    pub offset: usize,
    /// The head's XYZ, mm (machine = logical: the files here set no XYZ offset).
    pub pos_mm: [f64; 3],
    /// Filament fed so far, mm (net of retractions).
    pub fed_mm: f64,
}

/// The command word and its parameters of a line (comments removed); None for a blank or
/// comment-only line.
fn words(raw: &str) -> Option<(&str, Vec<(char, f64)>)> {
    let code = raw.split(';').next().unwrap_or("").trim();
    let mut w = code.split_whitespace();
    let cmd = w.next()?;
    let params = w
        .filter_map(|w| {
            let c = w.chars().next()?.to_ascii_uppercase();
            Some((c, w.get(1..)?.parse().ok()?))
        })
        .collect();
    Some((cmd, params))
}

/// Whether a line can move the head or the extruder (a G0-G3 with an axis word, or G28).
pub fn moves_head(raw: &str) -> bool {
    match words(raw) {
        Some(("G28", _)) => true,
        Some(("G0" | "G1" | "G2" | "G3", p)) => p.iter().any(|(c, _)| "XYZE".contains(*c)),
        _ => false,
    }
}

/// The state at every line of `gcode` that starts with `marker` (e.g. `;LAYER_CHANGE`).
pub fn layer_markers(gcode: &str, marker: &str) -> Vec<Marker> {
    let mut pos = [0.0f64; 3];
    let (mut e_logical, mut fed) = (0.0f64, 0.0f64);
    let (mut relative, mut relative_e) = (false, false);
    let mut out = Vec::new();
    let mut offset = 0;
    for raw in gcode.split_inclusive('\n') {
        let at = offset;
        offset += raw.len();
        if raw.trim_start().starts_with(marker) {
            out.push(Marker {
                offset: at,
                pos_mm: pos,
                fed_mm: fed,
            });
        }
        let Some((cmd, params)) = words(raw) else {
            continue;
        };
        match cmd {
            "G90" => relative = false,
            "G91" => relative = true,
            "M82" => relative_e = false,
            "M83" => relative_e = true,
            "G92" => {
                for (c, v) in &params {
                    if *c == 'E' {
                        e_logical = *v;
                    }
                }
            }
            "G28" => {
                let named: Vec<usize> = params.iter().filter_map(|(c, _)| "XYZ".find(*c)).collect();
                for (i, p) in pos.iter_mut().enumerate() {
                    if named.is_empty() || named.contains(&i) {
                        *p = 0.0;
                    }
                }
            }
            "G0" | "G1" => {
                for (c, v) in params {
                    if let Some(i) = "XYZ".find(c) {
                        pos[i] = if relative { pos[i] + v } else { v };
                    } else if c == 'E' {
                        let d = if relative_e { v } else { v - e_logical };
                        e_logical += d;
                        fed += d;
                    }
                }
            }
            _ => {}
        }
    }
    out
}
