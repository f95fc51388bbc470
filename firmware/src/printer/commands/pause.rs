//! The pause family's executive side: a pause, resume, cancel, stop or M108 that arrived as a
//! queued line (the link acts on the same requests as they arrive: `link/realtime.rs`), M0/M1
//! and M600 in the job's order, M760's values and M761's schedule.

use crate::gcode::PauseCommand;
use crate::motion::Realtime;
use crate::printer::{Command, Printer};

impl Printer {
    pub(super) fn pause_command(&mut self, c: &PauseCommand) {
        let t = self.now_us;
        match c {
            PauseCommand::Pause { mode, .. } => self.request(Realtime::Pause(*mode), t),
            PauseCommand::Resume { .. } => self.request(Realtime::Resume, t),
            PauseCommand::Cancel => self.request(Realtime::Cancel, t),
            PauseCommand::QuickStop => self.request(Realtime::QuickStop, t),
            PauseCommand::EmergencyStop => self.request(Realtime::EmergencyStop, t),
            PauseCommand::BreakWait => self.request(Realtime::BreakWait, t),
            PauseCommand::Stop { ms, s, .. } => {
                if ms.is_some() || s.is_some() {
                    match crate::machine::dwell_ms(*ms, *s) {
                        Ok(ms) => self.intake.push(Command::Dwell { ms }),
                        Err(e) => self.host.warn(format_args!("{e}")),
                    }
                } else {
                    self.intake.push(Command::PauseHere);
                }
            }
            PauseCommand::FilamentChange(_) => {
                // Park at the pause position; the user unloads/loads, then resumes (M24).
                self.intake.push(Command::PauseHere);
            }
            PauseCommand::Params(p) => self.m760(p),
            PauseCommand::Schedule(s) => {
                let printing = self.job.layer().filter(|_| self.in_job());
                self.pause.m761(s, printing, cx!(self));
            }
        }
    }

    /// M760: report, or check against the machine and set, the pause's parameters.
    fn m760(&mut self, p: &crate::gcode::PauseParams) {
        if let Err(r) = crate::printer::guards::check_pause_params(p, self.settings.cfg()) {
            self.host.warn(format_args!("{r}"));
            return;
        }
        let timeout_s = self.heat.thermal().idle_config().map_or(0, |i| i.timeout_s);
        if p.is_empty() {
            let c = self.settings.cfg().pause;
            self.host.say(format_args!(
                "M760 R{:.2} Z{:.2} X{:.1} Y{:.1} F{:.0} S{:.2} V{:.1} L{:.3} T{timeout_s}",
                c.retract_mm,
                c.lift_z_mm,
                c.park_x_mm,
                c.park_y_mm,
                c.park_feed_mm_s * 60.0,
                c.speedup_factor,
                c.max_volumetric_mm3_s,
                c.segment_len_mm
            ));
            return;
        }
        if let Some(t) = p.nozzle_timeout_s.filter(|t| t.is_finite() && *t >= 0.0) {
            // Whole seconds; 0 = the nozzle stays hot however long the pause.
            let secs = libm::roundf(t) as u32;
            self.heat
                .thermal_mut()
                .set_idle((secs > 0).then_some(crate::thermal::IdleConfig {
                    timeout_s: secs,
                    nozzle_c: 0.0,
                }));
        }
        self.settings.m760(p);
    }
}
