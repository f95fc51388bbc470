//! The motion family's executive side: what is left once the intake's interpreter took the
//! moves and modal state (the overrides' reports, M400's deferred `ok`).

use crate::gcode::MotionCommand;
use crate::printer::{Command, Printer};

impl Printer {
    /// M220/M221 without S (report) and M400; the rest of the family is the interpreter's.
    /// Returns true when the `ok` is owed for later (M400).
    pub(super) fn motion_command(&mut self, c: &MotionCommand) -> bool {
        match c {
            MotionCommand::FeedOverride(None) => {
                let v = self.intake.machine().feed_override_pct();
                self.host.say(format_args!("FR:{v:.0}%"));
            }
            MotionCommand::FlowOverride(None) => {
                let v = self.intake.machine().flow_override_pct();
                self.host.say(format_args!("E0 Flow: {v:.0}%"));
            }
            MotionCommand::WaitMoves => {
                // As Marlin: the `ok` comes when the moves queued before it have ended.
                self.intake.push(Command::Sync);
                self.intake.owe_sync();
                return true;
            }
            _ => {}
        }
        false
    }
}
