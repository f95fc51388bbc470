//! The commands a line asks the executive to carry out at once, by family: the family's
//! parse and write are in `gcode/` (`motion.rs`, `heat.rs`, `pause.rs`, `report.rs`,
//! `settings.rs`, `driver.rs`, `sd.rs`, `recovery.rs`), its execution here — the motion, heat,
//! pause and report families in this folder, the settings, driver, SD and power-cut families
//! in the link files of the parts they change (`settings.rs`, `drivers.rs`, `sd.rs`,
//! `recovery.rs`). Moves, homing and the modal state never come here: the intake's
//! interpreter turns them into queued commands (`intake/interpret.rs`).

mod heat;
mod motion;
mod pause;
mod report;

use super::Printer;
use crate::gcode::Command;
use crate::link::Response;

impl Printer {
    /// Carry out a command a line asks of the executive, by its family. Returns true when
    /// the `ok` was already sent (M105 answers `ok T:...`; M400 answers once the moves before
    /// it have ended).
    pub(super) fn execute(&mut self, cmd: &Command) -> bool {
        match cmd {
            Command::Motion(c) => return self.motion_command(c),
            Command::Heat(c) => return self.heat_command(c),
            Command::Pause(c) => self.pause_command(c),
            Command::Report(c) => self.report_family(c),
            Command::Settings(c) => self.settings_command(c),
            Command::Driver(c) => self.driver_command(c),
            Command::Sd(c) => return self.sd_command(c),
            Command::Recovery(c) => return self.recovery_command(c),
            Command::Tool(0) => {}
            // Marlin on a single-extruder machine: `invalid_extruder_error`, nothing changes.
            Command::Tool(n) => self.host.warn(format_args!(
                "T{n}: invalid extruder (this printer has T0 only)"
            )),
            Command::Unknown(t) => self.host.respond(Response::UnknownCommand(t)),
        }
        false
    }
}
