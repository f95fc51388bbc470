//! The one seam between the host and the firmware's G-code front end: every G-code line the
//! host reads goes through `firmware::gcode` (parsing) and `firmware::layer` (layer detection)
//! here, so the host reads exactly what the printer reads. Nothing else in the job or sender
//! modules looks inside a G-code line.

use firmware::motion::LayerMark;

/// One command as the host needs it: letter, number and parameter words in millimetres/units as
/// written.
#[derive(Clone, Debug, PartialEq)]
pub struct Command {
    /// `G`, `M` or `T`.
    pub letter: char,
    /// Command number (`1` in `G1`).
    pub number: u16,
    /// Parameter words in the order written.
    pub params: Vec<(char, f64)>,
}

impl Command {
    /// Value of parameter `c`, if present with a value.
    pub fn get(&self, c: char) -> Option<f64> {
        self.params.iter().find(|(l, _)| *l == c).map(|(_, v)| *v)
    }

    /// True when parameter `c` is present.
    pub fn has(&self, c: char) -> bool {
        self.params.iter().any(|(l, _)| *l == c)
    }

    /// True for `letter number`.
    pub fn is(&self, letter: char, number: u16) -> bool {
        self.letter == letter && self.number == number
    }
}

/// A line the firmware's parser rejects.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct GcodeError(pub String);

/// Reads one line with the firmware's parser. `Ok(None)` for blank and comment-only lines.
pub fn parse(line: &str) -> Result<Option<Command>, GcodeError> {
    backend::parse(line)
}

/// The straight segments the firmware cuts a `G2`/`G3` arc into (`firmware::machine`'s arc code:
/// centre from I/J or R, chord tolerance, Z and E linear in the angle), as the end point of each
/// segment in logical millimetres (X Y Z E). `from`/`to` are the logical start and end of the
/// arc (the host's modal state before and after it); the last point is exactly `to`. The arc
/// geometry does not depend on where it lies, so it is computed around the origin of an
/// unbounded machine (the printer checks its own build volume) at 0.1 µm resolution.
pub fn arc_points(
    cmd: &Command,
    from: [f64; 4],
    to: [f64; 4],
) -> Result<Vec<[f64; 4]>, GcodeError> {
    backend::arc_points(cmd, from, to)
}

/// The firmware's front end for layer detection (`firmware::machine::Interpreter`: machine
/// state + `firmware::layer::LayerDetector`), fed line by line exactly as the printer feeds it.
pub struct LayerDetector {
    inner: backend::Detector,
}

impl Default for LayerDetector {
    fn default() -> Self {
        Self::new()
    }
}

/// What feeding one line gave.
#[derive(Clone, Debug, PartialEq)]
pub struct Fed {
    /// A layer starts before this line's command.
    pub mark: Option<LayerMark>,
    /// The firmware's machine state refuses the line (e.g. a move outside the build volume):
    /// the printer would answer an error and skip it; the detector did not see it.
    pub refused: Option<String>,
}

impl LayerDetector {
    /// A detector at the start of a job, for the default machine (`MachineConfig::ENDER3`).
    pub fn new() -> Self {
        LayerDetector {
            inner: backend::Detector::new(),
        }
    }

    /// Feeds one raw line (comments included). A mark returned belongs **before** this line.
    pub fn feed(&mut self, line: &str) -> Result<Fed, GcodeError> {
        self.inner.feed(line)
    }

    /// End of the file: a marker after the last command.
    pub fn finish(&mut self) -> Option<LayerMark> {
        self.inner.finish()
    }
}

mod backend {
    //! Adapter to `firmware::gcode` / `firmware::layer`.
    use super::{Command, GcodeError};
    use firmware::gcode as fw;
    use firmware::motion::LayerMark;

    pub fn parse(line: &str) -> Result<Option<Command>, GcodeError> {
        let parsed = fw::parse_line(line.as_bytes()).map_err(|e| GcodeError(e.to_string()))?;
        Ok(parsed.command.map(|c| convert(&c)))
    }

    fn axes(params: &mut Vec<(char, f64)>, a: &fw::AxisWords) {
        for (l, v) in ['X', 'Y', 'Z', 'E'].iter().zip(a.0.iter()) {
            if let Some(v) = v {
                params.push((*l, *v as f64));
            }
        }
    }

    fn opt(params: &mut Vec<(char, f64)>, l: char, v: Option<f32>) {
        if let Some(v) = v {
            params.push((l, v as f64));
        }
    }

    /// Maps the firmware's typed command onto the letter/number/parameters view the host's
    /// modal tracker reads. Commands the host does not track keep their code with no
    /// parameters, or `?0` when they have no single code.
    fn convert(c: &fw::Command) -> Command {
        let mut p = Vec::new();
        let (letter, number) = match c {
            fw::Command::Motion(fw::MotionCommand::Move {
                rapid,
                axes: a,
                feed,
            }) => {
                axes(&mut p, a);
                opt(&mut p, 'F', *feed);
                ('G', if *rapid { 0 } else { 1 })
            }
            fw::Command::Motion(fw::MotionCommand::Arc {
                clockwise,
                axes: a,
                i,
                j,
                r,
                circles,
                feed,
            }) => {
                axes(&mut p, a);
                opt(&mut p, 'I', *i);
                opt(&mut p, 'J', *j);
                opt(&mut p, 'R', *r);
                if *circles > 0 {
                    opt(&mut p, 'P', Some(f32::from(*circles)));
                }
                opt(&mut p, 'F', *feed);
                ('G', if *clockwise { 2 } else { 3 })
            }
            fw::Command::Motion(fw::MotionCommand::Inches) => ('G', 20),
            fw::Command::Motion(fw::MotionCommand::Millimetres) => ('G', 21),
            fw::Command::Motion(fw::MotionCommand::Home(flags)) => {
                for (l, on) in ['X', 'Y', 'Z', 'E'].iter().zip(flags.0.iter()) {
                    if *on {
                        p.push((*l, 0.0));
                    }
                }
                ('G', 28)
            }
            fw::Command::Motion(fw::MotionCommand::Absolute) => ('G', 90),
            fw::Command::Motion(fw::MotionCommand::Relative) => ('G', 91),
            fw::Command::Motion(fw::MotionCommand::SetPosition(a)) => {
                axes(&mut p, a);
                ('G', 92)
            }
            fw::Command::Motion(fw::MotionCommand::AbsoluteE) => ('M', 82),
            fw::Command::Motion(fw::MotionCommand::RelativeE) => ('M', 83),
            fw::Command::Motion(fw::MotionCommand::WaitMoves) => ('M', 400),
            fw::Command::Motion(fw::MotionCommand::FlowOverride(s)) => {
                opt(&mut p, 'S', *s);
                ('M', 221)
            }
            fw::Command::Motion(fw::MotionCommand::FeedOverride(s)) => {
                opt(&mut p, 'S', *s);
                ('M', 220)
            }
            fw::Command::Motion(fw::MotionCommand::Dwell { .. }) => ('G', 4),
            _ => ('?', 0),
        };
        Command {
            letter,
            number,
            params: p,
        }
    }

    pub fn arc_points(
        cmd: &Command,
        from: [f64; 4],
        to: [f64; 4],
    ) -> Result<Vec<[f64; 4]>, GcodeError> {
        use firmware::config::MachineConfig;
        use firmware::machine::{Action, MachineState};
        if cmd.letter != 'G' || !(2..=3).contains(&cmd.number) {
            return Err(GcodeError(format!("G{} is not an arc", cmd.number)));
        }
        const SPM: f32 = 10_000.0;
        let mut cfg = MachineConfig::ENDER3;
        for a in cfg.axes.iter_mut() {
            a.steps_per_mm = SPM;
            a.min_mm = -1.0e5;
            a.max_mm = 1.0e5;
        }
        let mut m = MachineState::new(&cfg);
        let err = |e: firmware::machine::MachineError| GcodeError(e.to_string());
        m.apply(&fw::Command::Motion(fw::MotionCommand::Relative), &cfg)
            .map_err(err)?;
        let mut d = [None; 4];
        for (k, v) in d.iter_mut().enumerate() {
            *v = Some((to[k] - from[k]) as f32);
        }
        let arc = fw::Command::Motion(fw::MotionCommand::Arc {
            clockwise: cmd.number == 2,
            axes: fw::AxisWords(d),
            i: cmd.get('I').map(|v| v as f32),
            j: cmd.get('J').map(|v| v as f32),
            r: cmd.get('R').map(|v| v as f32),
            circles: cmd.get('P').map_or(0, |v| v.clamp(0.0, 255.0) as u8),
            feed: None,
        });
        let moves = match m.apply(&arc, &cfg).map_err(err)? {
            Action::Arc(moves) => moves,
            other => return Err(GcodeError(format!("not an arc: {other:?}"))),
        };
        let mut pts: Vec<[f64; 4]> = moves
            .map(|mv| {
                let mut p = [0.0; 4];
                for k in 0..4 {
                    p[k] = from[k] + f64::from(mv.target[k]) / f64::from(SPM);
                }
                p
            })
            .collect();
        match pts.last_mut() {
            Some(last) => *last = to,
            None => pts.push(to),
        }
        Ok(pts)
    }

    pub struct Detector {
        cfg: firmware::config::MachineConfig,
        it: firmware::machine::Interpreter,
    }

    impl Detector {
        pub fn new() -> Self {
            let cfg = firmware::config::MachineConfig::ENDER3;
            Detector {
                it: firmware::machine::Interpreter::new(&cfg),
                cfg,
            }
        }

        pub fn feed(&mut self, line: &str) -> Result<super::Fed, GcodeError> {
            let parsed = fw::parse_line(line.as_bytes()).map_err(|e| GcodeError(e.to_string()))?;
            Ok(match self.it.line(&parsed, &self.cfg) {
                Ok(step) => super::Fed {
                    mark: step.mark,
                    refused: None,
                },
                Err(e) => super::Fed {
                    mark: None,
                    refused: Some(e.to_string()),
                },
            })
        }

        pub fn finish(&mut self) -> Option<LayerMark> {
            self.it.finish()
        }
    }
}
