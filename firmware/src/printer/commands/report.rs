//! The report family's executive side: position, firmware and endstop reports, messages and
//! progress here; the host's own reports (M155, M113, M31, M27) by the host part
//! (`printer/host/reports.rs`).

use crate::gcode::ReportCommand;
use crate::link::{PositionReport, Response};
use crate::printer::motion::homing::Latched;
use crate::printer::Printer;

impl Printer {
    pub(super) fn report_family(&mut self, c: &ReportCommand) {
        match c {
            ReportCommand::Position => {
                let r = PositionReport {
                    logical_mm: self.intake.machine().logical_mm(),
                    steps: self.motion.position(),
                };
                self.host.respond(Response::Position(r));
            }
            ReportCommand::FirmwareInfo => {
                self.host.respond(Response::FirmwareInfo);
                self.board.report_stats(&mut self.host);
            }
            ReportCommand::Message(t) | ReportCommand::Echo(t) => {
                self.host.respond(Response::Echo(t));
            }
            ReportCommand::Endstops => {
                let mut e = Latched(self.motion.endstops());
                for line in crate::homing::m119_lines(&mut e) {
                    self.host.respond(Response::Plain(line));
                }
            }
            ReportCommand::Progress(p) => self.host.note_progress(p),
            // Layer marks and line numbers: the layer detector's and the link's.
            ReportCommand::PrintStatsInfo { .. } | ReportCommand::SetLineNumber(_) => {}
            ReportCommand::AutoTemp(_)
            | ReportCommand::HostKeepalive(_)
            | ReportCommand::PrintTime
            | ReportCommand::JobStatus => {
                if matches!(c, ReportCommand::JobStatus) && !self.sd_status() {
                    self.host.say(format_args!("Not SD printing"));
                }
                let view = self.job_view();
                self.host.report_command(c, self.now_us, view);
            }
        }
    }
}
