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
                    logical_mm: self.reported_position_mm(),
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

    /// M114's logical position: while the job runs, the commanded position (Marlin's
    /// `current_position`); while a pause holds it (stopping, parked, returning), where the
    /// head is — the job's commanded position is then where its held lines lead, not where
    /// the nozzle stands (Marlin reports the parked position during M600/M125 too). X/Y/Z
    /// through the job's offsets (G92, M206); E as the job counts it.
    fn reported_position_mm(&self) -> [f64; crate::motion::AXES] {
        let m = self.intake.machine();
        let logical = m.logical_mm();
        if self.pause.running() {
            return logical;
        }
        let (machine, head) = (m.machine_mm(), self.motion.position());
        let cfg = self.settings.cfg();
        let mut out = logical;
        for ax in [
            crate::motion::Axis::X,
            crate::motion::Axis::Y,
            crate::motion::Axis::Z,
        ] {
            let i = ax.index();
            let spm = f64::from(cfg.axis(ax).steps_per_mm);
            if spm > 0.0 {
                out[i] = f64::from(head[i]) / spm - (machine[i] - logical[i]);
            }
        }
        out
    }
}
