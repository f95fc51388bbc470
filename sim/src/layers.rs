//! Layer boundaries of a job as the firmware's own layer detector ([`firmware::layer`]) sees
//! them, run host-side over the whole file (comments included) with the firmware's machine
//! state ([`firmware::machine`]), so the host and the printer agree on what a layer is.

use firmware::config::MachineConfig;
use firmware::gcode::parse_line;
use firmware::layer::{LayerDetector, MoveFacts};
use firmware::machine::MachineState;

/// For each line, the layer number whose mark is placed before that line (the n-th layer of
/// the job, from 1: docs/planner.md, "What a layer is"), if any.
pub fn detect<S: AsRef<str>>(lines: &[S]) -> Vec<Option<u32>> {
    analyse(lines).into_iter().map(|l| l.mark).collect()
}

/// What the firmware's front end makes of one line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineFacts {
    /// Layer mark placed before the line.
    pub mark: Option<u32>,
    /// The line moves X or Y and advances E by at least one step (the firmware's definition of
    /// an extruding move).
    pub extrudes: bool,
    /// The line moves some axis by at least one step.
    pub moved: bool,
}

/// Run the firmware's machine state and layer detector over the job.
pub fn analyse<S: AsRef<str>>(lines: &[S]) -> Vec<LineFacts> {
    analyse_lines(lines.iter().map(AsRef::as_ref), lines.len())
}

/// [`analyse`] over `n` lines given one by one.
pub fn analyse_lines<'a>(lines: impl Iterator<Item = &'a str>, n: usize) -> Vec<LineFacts> {
    let mut an = Analyser::new();
    let mut out = Vec::with_capacity(n);
    out.extend(lines.map(|text| an.feed(text)));
    out
}

/// [`analyse`] one line at a time (memory flat with job length).
pub struct Analyser {
    cfg: MachineConfig,
    m: MachineState,
    d: LayerDetector,
}

impl Default for Analyser {
    fn default() -> Self {
        Self::new()
    }
}

impl Analyser {
    /// At the start of a job, on the Ender-3.
    pub fn new() -> Self {
        Self::with_config(MachineConfig::ENDER3)
    }

    /// At the start of a job, on the machine `cfg` (its build volume decides which moves the
    /// machine state takes).
    pub fn with_config(cfg: MachineConfig) -> Self {
        Self {
            m: MachineState::new(&cfg),
            d: LayerDetector::new(),
            cfg,
        }
    }

    /// The facts of the next line.
    pub fn feed(&mut self, text: &str) -> LineFacts {
        let cfg = &self.cfg;
        let Ok(line) = parse_line(text.as_bytes()) else {
            return LineFacts::default();
        };
        let before = self.m;
        if let Some(cmd) = &line.command {
            // A command the machine rejects changes nothing (as on the printer).
            let _ = self.m.apply(cmd, cfg);
        }
        let facts = MoveFacts::of(&before, &self.m, cfg);
        LineFacts {
            mark: self.d.feed(&line, facts).map(|mark| mark.layer),
            extrudes: facts.extrudes,
            moved: facts.moved,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prusaslicer_markers() {
        let lines: Vec<String> = [
            "G90",
            ";LAYER_CHANGE",
            ";Z:0.2",
            "G1 Z0.2",
            "G1 X10 E1",
            ";LAYER_CHANGE",
            ";Z:0.4",
            "G1 Z0.4",
            "G1 X0 E2",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let l = detect(&lines);
        let marks: Vec<(usize, u32)> = l
            .iter()
            .enumerate()
            .filter_map(|(i, m)| m.map(|m| (i, m)))
            .collect();
        assert_eq!(marks.len(), 2);
        // Layers count from 1 (the slicer preview's numbers).
        assert_eq!(marks[0].1, 1);
        assert_eq!(marks[1].1, 2);
        assert!(marks[1].0 > 4 && marks[1].0 <= 7);
    }
}
