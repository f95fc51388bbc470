//! Reading G-code for the model: each line becomes one [`Item`] — a move with where it starts
//! and ends, a layer marker, a slicer header, a line-number reset, an end-of-job command —
//! from this crate's own word splitter and modal state (G90/G91, M82/M83, G92, G20/G21, G28,
//! G0–G3). Nothing here comes from the firmware: it is the reference the firmware is judged by.

/// Marker families (the slicers' layer markers), told apart by what the file writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Family {
    /// `;LAYER_CHANGE` (PrusaSlicer, SuperSlicer, Slic3r PE, OrcaSlicer).
    Prusa,
    /// `; CHANGE_LAYER` (BambuStudio, OrcaSlicer for Bambu printers, Creality Print 5+).
    Bambu,
    /// `;LAYER:<n>` (Cura, ideaMaker, MatterControl, Creality Print 4).
    Cura,
    /// `; layer <n>, Z = <mm>` (Simplify3D).
    Simplify3d,
    /// `;layer:<layer height>` (FlashPrint: lower case, a decimal).
    FlashPrint,
    /// `; BEGIN_LAYER_OBJECT z=<mm>` (KISSlicer).
    KisSlicer,
    /// `;; --- layer <n> (<height> @ <z>) ---` (Kiri:Moto).
    KiriMoto,
    /// `; <layer>` (IceSL).
    IceSl,
    /// `;TURN`, `;TURN:<n>` (this project's host compiler).
    Turn,
    /// `SET_PRINT_STATS_INFO CURRENT_LAYER=<n>` (Klipper).
    Klipper,
    /// `M73 L<n>`.
    M73,
}

/// What one line is, for the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Item {
    /// Nothing the model needs.
    Other,
    /// A move (G0–G3) from `from` to `to` (X, Y, Z, E in mm, machine coordinates; E as fed).
    Move {
        /// Start.
        from: [f64; 4],
        /// End.
        to: [f64; 4],
    },
    /// A layer marker of a family, with the number it carries (command markers).
    Marker(Family, Option<i64>),
    /// The host reset its line numbers (`M110`): a job starts.
    Reset,
    /// An end-of-job command: hotend off (`M104 S0`, `M109 S0`) or motors off (`M84`/`M18`
    /// without a time, all axes or X or Y).
    End,
}

/// The modal state a reader keeps.
#[derive(Clone, Copy, Debug)]
pub struct Reader {
    pos: [f64; 4],
    relative: bool,
    relative_e: bool,
    inches: bool,
}

impl Default for Reader {
    fn default() -> Self {
        Reader {
            pos: [0.0; 4],
            relative: false,
            relative_e: false,
            inches: false,
        }
    }
}

/// The code part of a line: framing (`N<n>`, `*<sum>`) and, when `strip`, the comment gone.
fn split(raw: &str) -> (&str, Option<&str>) {
    let (code, comment) = match raw.find(';') {
        Some(i) => (&raw[..i], Some(&raw[i + 1..])),
        None => (raw, None),
    };
    let mut code = code.trim();
    if let Some(star) = code.rfind('*') {
        if code[star + 1..].chars().all(|c| c.is_ascii_digit()) {
            code = code[..star].trim_end();
        }
    }
    if let Some(rest) = code.strip_prefix(['N', 'n']) {
        let digits = rest.trim_start_matches('-');
        if digits.starts_with(|c: char| c.is_ascii_digit()) {
            let end = digits
                .find(|c: char| !c.is_ascii_digit())
                .unwrap_or(digits.len());
            code = digits[end..].trim_start();
        }
    }
    (code, comment)
}

/// Parameter `letter` of the code words (`X10.5`), if present and a number.
fn param(words: &[&str], letter: char) -> Option<f64> {
    words.iter().skip(1).find_map(|w| {
        let mut c = w.chars();
        let l = c.next()?;
        (l.eq_ignore_ascii_case(&letter))
            .then(|| c.as_str().parse::<f64>().ok())
            .flatten()
    })
}

fn has_letter(words: &[&str], letter: char) -> bool {
    words.iter().skip(1).any(|w| {
        w.chars()
            .next()
            .is_some_and(|l| l.eq_ignore_ascii_case(&letter))
    })
}

/// The words of the code: split at spaces, and (classic G-code written without spaces,
/// `G1X10Y5`) at each letter; an extended command (`SET_PRINT_STATS_INFO CURRENT_LAYER=3`)
/// only at spaces.
fn words_of(code: &str) -> Vec<&str> {
    let extended = code.split_whitespace().next().is_some_and(|w| {
        w.chars()
            .nth(1)
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
    });
    let mut out = Vec::new();
    for w in code.split_whitespace() {
        if extended {
            out.push(w);
            continue;
        }
        let mut start = 0;
        for (i, c) in w.char_indices() {
            if i > start && c.is_ascii_alphabetic() {
                out.push(&w[start..i]);
                start = i;
            }
        }
        out.push(&w[start..]);
    }
    out
}

/// What a comment says, if it is a layer marker. The comment's text is read without the `;`s
/// and spaces around it, so every marker is found with or without a space after the `;`.
fn comment_item(c: &str) -> Option<Item> {
    let t = c
        .trim_start_matches(|ch: char| ch == ';' || ch.is_whitespace())
        .trim_end();
    let marker = |f| Some(Item::Marker(f, None));
    match t {
        "LAYER_CHANGE" => return marker(Family::Prusa),
        "CHANGE_LAYER" => return marker(Family::Bambu),
        "<layer>" => return marker(Family::IceSl),
        "TURN" => return marker(Family::Turn),
        _ => {}
    }
    let number = |n: &str| n.trim().parse::<i64>().ok();
    if let Some(n) = t.strip_prefix("TURN:") {
        return number(n).map(|n| Item::Marker(Family::Turn, Some(n)));
    }
    if let Some(n) = t.strip_prefix("LAYER:") {
        return number(n).map(|n| Item::Marker(Family::Cura, Some(n)));
    }
    if let Some(h) = t.strip_prefix("layer:") {
        // FlashPrint's layer height: a number with a fraction.
        let h = h.trim();
        return (h.contains('.') && h.parse::<f64>().is_ok())
            .then_some(Item::Marker(Family::FlashPrint, None));
    }
    if t.starts_with("BEGIN_LAYER_OBJECT") {
        return marker(Family::KisSlicer);
    }
    if let Some(rest) = t.strip_prefix("--- layer ") {
        let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
        return digits
            .parse()
            .ok()
            .map(|n| Item::Marker(Family::KiriMoto, Some(n)));
    }
    let lower = t.to_ascii_lowercase();
    if let Some(rest) = lower.strip_prefix("layer ") {
        let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
        let after = &rest[digits.len()..];
        if !digits.is_empty() && (after.is_empty() || after.starts_with(',')) {
            return digits
                .parse()
                .ok()
                .map(|n| Item::Marker(Family::Simplify3d, Some(n)));
        }
    }
    None
}

impl Reader {
    /// Read one line (with its comment unless `strip`).
    pub fn line(&mut self, raw: &str, strip: bool) -> Item {
        let (code, comment) = split(raw);
        let words = words_of(code);
        let Some(first) = words.first() else {
            return match comment {
                Some(c) if !strip => comment_item(c).unwrap_or(Item::Other),
                _ => Item::Other,
            };
        };
        let cmd = first.to_ascii_uppercase();
        let item = self.command(&cmd, &words);
        if item == Item::Other && !strip {
            if let Some(c) = comment {
                // A marker comment after a command (rare): the marker counts.
                if let Some(m @ Item::Marker(..)) = comment_item(c) {
                    return m;
                }
            }
        }
        item
    }

    fn command(&mut self, cmd: &str, w: &[&str]) -> Item {
        let unit = if self.inches { 25.4 } else { 1.0 };
        match cmd {
            "G0" | "G00" | "G1" | "G01" | "G2" | "G02" | "G3" | "G03" => {
                let from = self.pos;
                for (k, l) in ['X', 'Y', 'Z', 'E'].into_iter().enumerate() {
                    if let Some(v) = param(w, l) {
                        let rel = if k == 3 {
                            self.relative_e
                        } else {
                            self.relative
                        };
                        self.pos[k] = if rel {
                            self.pos[k] + v * unit
                        } else {
                            v * unit
                        };
                    }
                }
                Item::Move { from, to: self.pos }
            }
            "G28" => {
                let from = self.pos;
                let any = ['X', 'Y', 'Z'].iter().any(|&l| has_letter(w, l));
                for (k, l) in ['X', 'Y', 'Z'].into_iter().enumerate() {
                    if !any || has_letter(w, l) {
                        self.pos[k] = 0.0;
                    }
                }
                Item::Move { from, to: self.pos }
            }
            "G90" => {
                self.relative = false;
                self.relative_e = false;
                Item::Other
            }
            "G91" => {
                self.relative = true;
                self.relative_e = true;
                Item::Other
            }
            "M82" => {
                self.relative_e = false;
                Item::Other
            }
            "M83" => {
                self.relative_e = true;
                Item::Other
            }
            "G20" => {
                self.inches = true;
                Item::Other
            }
            "G21" => {
                self.inches = false;
                Item::Other
            }
            // G92 sets the coordinates the next moves are written in (the head does not move):
            // the model keeps positions as the G-code writes them.
            "G92" => {
                for (k, l) in ['X', 'Y', 'Z', 'E'].into_iter().enumerate() {
                    if let Some(v) = param(w, l) {
                        self.pos[k] = v * unit;
                    }
                }
                Item::Other
            }
            "M110" => Item::Reset,
            "M73" => match param(w, 'L') {
                Some(n) => Item::Marker(Family::M73, Some(n as i64)),
                None => Item::Other,
            },
            "SET_PRINT_STATS_INFO" => w
                .iter()
                .skip(1)
                .find_map(|x| {
                    let (k, v) = x.split_once('=')?;
                    k.eq_ignore_ascii_case("CURRENT_LAYER")
                        .then(|| v.parse::<i64>().ok())
                        .flatten()
                })
                .map_or(Item::Other, |n| Item::Marker(Family::Klipper, Some(n))),
            "M104" | "M109" => {
                let off = |l| param(w, l).is_some_and(|t| t <= 0.0);
                let hotend = param(w, 'T').is_none_or(|t| t == 0.0);
                if hotend && (off('S') || off('R')) && !(param(w, 'S').is_some_and(|t| t > 0.0)) {
                    Item::End
                } else {
                    Item::Other
                }
            }
            "M84" | "M18" => {
                let timed = has_letter(w, 'S');
                let axes = ['X', 'Y', 'Z', 'E'].iter().any(|&l| has_letter(w, l));
                if !timed && (!axes || has_letter(w, 'X') || has_letter(w, 'Y')) {
                    Item::End
                } else {
                    Item::Other
                }
            }
            _ => Item::Other,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_modes_and_markers() {
        let mut r = Reader::default();
        assert_eq!(
            r.line("G1 X10 Y5 E1 F1200", false),
            Item::Move {
                from: [0.0; 4],
                to: [10.0, 5.0, 0.0, 1.0]
            }
        );
        assert_eq!(r.line("N12 G91*99", false), Item::Other);
        assert_eq!(
            r.line("G1X1Y1E0.5", false),
            Item::Move {
                from: [10.0, 5.0, 0.0, 1.0],
                to: [11.0, 6.0, 0.0, 1.5]
            }
        );
        assert_eq!(
            r.line(";LAYER:3", false),
            Item::Marker(Family::Cura, Some(3))
        );
        assert_eq!(r.line(";LAYER:3", true), Item::Other);
        assert_eq!(
            r.line("; layer 2, Z = 0.4", false),
            Item::Marker(Family::Simplify3d, Some(2))
        );
        assert_eq!(
            r.line("M73 P10 L4", true),
            Item::Marker(Family::M73, Some(4))
        );
        assert_eq!(
            r.line("SET_PRINT_STATS_INFO CURRENT_LAYER=7", true),
            Item::Marker(Family::Klipper, Some(7))
        );
        assert_eq!(r.line("M104 S0", true), Item::End);
        assert_eq!(r.line("M140 S0", true), Item::Other);
        assert_eq!(r.line("M84 E", true), Item::Other);
        assert_eq!(r.line("N-1 M110*15", true), Item::Reset);
    }
}
