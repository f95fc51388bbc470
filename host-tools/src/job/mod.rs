//! G-code jobs: reading them with the firmware's parser ([`crate::gcode::read`]), their statistics
//! ([`stats`]), the preview ([`preview`]) and the interactive sender ([`sender`]); and the job
//! model of SPEC §1: start code (heating, homing), main code as a list of layers (each a
//! list of commands) and end code (cooling, park). Built from any slicer's G-code with the
//! firmware's own parser and layer detector ([`gcode`]), and from our compiled designs (their
//! writer emits layer/turn markers the same detector reads). Operations that edit the rest of a
//! job at a paused layer boundary live in [`ops`].

pub mod gcode;
pub mod modal;
pub mod ops;
pub mod preview;
pub mod preview_html;
pub mod preview_moves;
pub mod sender;
pub mod stats;

use firmware::motion::LayerSource;
use modal::Modal;

/// One layer of the main code.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    /// Layer number as the firmware's detector counts it in the file it came from (the n-th layer
    /// printed, from 1).
    pub number: u32,
    /// Height the detector reported for the layer (from the marker), mm.
    pub z_mm: Option<f64>,
    /// Z of the layer's extruding moves (the height actually printed), mm.
    pub print_z_mm: Option<f64>,
    /// What produced the boundary.
    pub source: LayerSource,
    /// The raw lines, comments included, the first being the one that produced the boundary.
    pub lines: Vec<String>,
}

impl Layer {
    /// Best known height of the layer: the printed Z, else the marker's Z.
    pub fn top_mm(&self) -> Option<f64> {
        self.print_z_mm.or(self.z_mm)
    }
}

/// A job: start code, layers, end code.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Job {
    /// Lines before the first layer.
    pub start: Vec<String>,
    /// The main code.
    pub layers: Vec<Layer>,
    /// Lines after the last extruding move of the last layer.
    pub end: Vec<String>,
    /// Lines the firmware's machine state refuses (the printer would answer an error and skip
    /// them), with their 1-based line numbers.
    pub warnings: Vec<String>,
}

/// Reading a job failed.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// A line the firmware's parser rejects.
    #[error("line {line}: {msg}")]
    Gcode {
        /// 1-based line number in the input.
        line: usize,
        /// The parser's message.
        msg: String,
    },
    /// No layer boundary anywhere in the file.
    #[error("no layers found (no slicer layer markers and no Z rise before an extruding move)")]
    NoLayers,
    /// An operation's arguments do not fit the job.
    #[error("{0}")]
    Op(String),
}

/// Where a line sits in a job.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Section {
    /// Start code.
    Start,
    /// Layer with this index in [`Job::layers`].
    Layer(usize),
    /// End code.
    End,
}

impl Job {
    /// Builds a job from G-code text.
    pub fn from_gcode(text: &str) -> Result<Job, JobError> {
        let mut det = gcode::LayerDetector::new();
        let mut modal = Modal::default();
        let mut job = Job::default();
        // Index (in the last layer) just after its last extruding move, to cut the end code.
        let mut last_extrude: Option<(usize, usize)> = None;
        for (i, raw) in text.lines().enumerate() {
            let line = raw.trim_end_matches('\r');
            let fed = det.feed(line).map_err(|e| JobError::Gcode {
                line: i + 1,
                msg: e.0,
            })?;
            if let Some(w) = fed.refused {
                job.warnings.push(format!("line {}: {w}: {line}", i + 1));
            }
            if let Some(mark) = fed.mark {
                job.layers.push(Layer {
                    number: mark.layer,
                    z_mm: mark.z_um.map(|z| z as f64 / 1000.0),
                    print_z_mm: None,
                    source: mark.source,
                    lines: Vec::new(),
                });
            }
            let cmd = gcode::parse(line).map_err(|e| JobError::Gcode {
                line: i + 1,
                msg: e.0,
            })?;
            let mv = cmd.as_ref().and_then(|c| modal.apply(c));
            let n_layers = job.layers.len();
            match job.layers.last_mut() {
                None => job.start.push(line.to_string()),
                Some(layer) => {
                    layer.lines.push(line.to_string());
                    if let Some(m) = mv.filter(|m| m.extrudes()) {
                        layer.print_z_mm = Some(m.to_mm[modal::Z]);
                        last_extrude = Some((n_layers - 1, layer.lines.len()));
                    }
                }
            }
        }
        if let Some(mark) = det.finish() {
            // A marker after the last command: an empty last layer.
            job.layers.push(Layer {
                number: mark.layer,
                z_mm: mark.z_um.map(|z| z as f64 / 1000.0),
                print_z_mm: None,
                source: mark.source,
                lines: Vec::new(),
            });
        }
        if job.layers.is_empty() {
            return Err(JobError::NoLayers);
        }
        if let Some((li, cut)) = last_extrude {
            if li + 1 == job.layers.len() {
                if let Some(last) = job.layers.last_mut() {
                    job.end = last.lines.split_off(cut.min(last.lines.len()));
                }
            }
        }
        Ok(job)
    }

    /// Index in [`Job::layers`] of the layer the firmware numbers `number` (the n-th layer
    /// printed, from 1: docs/planner.md, "What a layer is"); the first such layer when the file
    /// holds more than one job.
    pub fn index_of_layer(&self, number: u32) -> Option<usize> {
        self.layers.iter().position(|l| l.number == number)
    }

    /// The boundary before layer index `at` in words, with the firmware's number: `layer 12`,
    /// or `the end code` at the end (what the sender tells the user).
    pub fn boundary_name(&self, at: usize) -> String {
        match self.layers.get(at) {
            Some(l) => format!("layer {}", l.number),
            None => "the end code".into(),
        }
    }

    /// Number of lines in the whole job.
    pub fn line_count(&self) -> usize {
        self.start.len() + self.layers.iter().map(|l| l.lines.len()).sum::<usize>() + self.end.len()
    }

    /// The lines of one section (empty for a layer index out of range).
    pub fn section(&self, s: Section) -> &[String] {
        match s {
            Section::Start => &self.start,
            Section::Layer(i) => self
                .layers
                .get(i)
                .map(|l| l.lines.as_slice())
                .unwrap_or(&[]),
            Section::End => &self.end,
        }
    }

    /// All lines in order with their section.
    pub fn lines(&self) -> impl Iterator<Item = (Section, &str)> {
        let start = self.start.iter().map(|l| (Section::Start, l.as_str()));
        let layers = self
            .layers
            .iter()
            .enumerate()
            .flat_map(|(i, l)| l.lines.iter().map(move |s| (Section::Layer(i), s.as_str())));
        let end = self.end.iter().map(|l| (Section::End, l.as_str()));
        start.chain(layers).chain(end)
    }

    /// The whole job as G-code text (one `\n`-terminated line each).
    pub fn to_gcode(&self) -> String {
        let mut s = String::new();
        for (_, l) in self.lines() {
            s.push_str(l);
            s.push('\n');
        }
        s
    }

    /// Modal state after the start code and the first `layer` layers (i.e. at the boundary
    /// before layer index `layer`). Lines the parser rejects are skipped (they were rejected when
    /// the job was built, so this only happens for lines inserted by hand).
    pub fn modal_at(&self, layer: usize) -> Modal {
        let mut m = Modal::default();
        let lines = self
            .start
            .iter()
            .chain(self.layers.iter().take(layer).flat_map(|l| l.lines.iter()));
        for l in lines {
            if let Ok(Some(c)) = gcode::parse(l) {
                m.apply(&c);
            }
        }
        m
    }

    /// Estimated duration of each section's lines at commanded feeds (no acceleration), s:
    /// `(start, per layer, end)`. Used for progress and time left.
    pub fn est_times_s(&self) -> (f64, Vec<f64>, f64) {
        let mut m = Modal::default();
        let sum = |lines: &[String], m: &mut Modal| -> f64 {
            lines
                .iter()
                .filter_map(|l| gcode::parse(l).ok().flatten())
                .filter_map(|c| m.apply(&c))
                .map(|mv| mv.est_time_s())
                .sum()
        };
        let start = sum(&self.start, &mut m);
        let layers = self.layers.iter().map(|l| sum(&l.lines, &mut m)).collect();
        let end = sum(&self.end, &mut m);
        (start, layers, end)
    }
}
