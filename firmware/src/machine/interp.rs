//! The whole front end for one parsed line: machine state + layer detection, in the order the
//! executive needs them.

use super::{Action, MachineError, MachineState};
use crate::config::MachineConfig;
use crate::gcode::Line;
use crate::layer::{LayerDetector, MoveFacts};
use crate::motion::LayerMark;

impl MoveFacts {
    /// Facts of the command that took the machine state from `before` to `after`, as
    /// commanded (see [`MoveFacts::commanded`]). Here, on the interpreter's side, so the layer
    /// detector needs nothing of the machine state: imports run one way, `machine` → `layer`.
    pub fn of(before: &MachineState, after: &MachineState, _cfg: &MachineConfig) -> Self {
        MoveFacts::commanded(&before.machine_mm(), &after.machine_mm())
    }
}

/// What one line asks for: first queue `mark` (if any), then do `action`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// A layer starts before this line's action.
    pub mark: Option<LayerMark>,
    /// The line's action ([`Action::None`] for comment-only lines).
    pub action: Action,
}

/// [`MachineState`] and [`LayerDetector`] together: feed parsed lines, get layer marks and
/// actions in stream order. `Clone` so the executive can save and restore it across a pause.
///
/// ```
/// use firmware::config::MachineConfig;
/// use firmware::gcode::parse_line;
/// use firmware::machine::{Action, Interpreter};
/// let cfg = MachineConfig::ENDER3;
/// let mut it = Interpreter::new(&cfg);
/// let mut layers = 0;
/// for text in [";LAYER_CHANGE", ";Z:0.2", "G1 Z0.2", "G1 X5 E1"] {
///     let step = it.line(&parse_line(text.as_bytes()).unwrap(), &cfg).unwrap();
///     layers += step.mark.is_some() as u32;
/// }
/// assert_eq!(layers, 1);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interpreter {
    /// Modal state and commanded position.
    pub machine: MachineState,
    /// Layer detection.
    pub layers: LayerDetector,
}

impl Interpreter {
    /// Power-on state, start of a file.
    pub fn new(cfg: &MachineConfig) -> Self {
        Interpreter {
            machine: MachineState::new(cfg),
            layers: LayerDetector::new(),
        }
    }

    /// Interpret one line. On error neither the machine state nor the layer detector changes
    /// (a marker in the comment of a refused line is lost with it).
    pub fn line(&mut self, line: &Line<'_>, cfg: &MachineConfig) -> Result<Step, MachineError> {
        let before = self.machine;
        let action = match &line.command {
            Some(c) => self.machine.apply(c, cfg)?,
            None => Action::None,
        };
        let facts = MoveFacts::of(&before, &self.machine, cfg);
        let mark = self.layers.feed(line, facts);
        Ok(Step { mark, action })
    }

    /// End of the file: a layer marker after the last command.
    pub fn finish(&mut self) -> Option<LayerMark> {
        self.layers.finish()
    }
}
