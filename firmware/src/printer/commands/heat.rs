//! The heat family's executive side: targets and waits, the temperature report, the fan,
//! PID gains, autotune and M302, carried out by the heat part (`printer/heat.rs`).

use crate::gcode::{HeatCommand, Heater};
use crate::printer::heat::heater_id;
use crate::printer::{Command, Printer};
use crate::thermal::HeaterId;

impl Printer {
    /// Returns true when the `ok` was already sent (M105's report is its own `ok`).
    pub(super) fn heat_command(&mut self, c: &HeatCommand) -> bool {
        match c {
            HeatCommand::SetTemperature {
                heater,
                wait,
                s,
                r,
                tool,
            } => {
                let code = heater.target_code(*wait);
                // Marlin's `get_target_extruder_from_command`: an extruder that is not there is
                // refused, never applied to the one that is (FlashPrint's `M104 S0 T1` for a
                // second hotend switched the only one off; issue 31/32).
                if let Some(t) = tool.filter(|t| *t != 0) {
                    self.host.warn(format_args!(
                        "{code} T{t}: invalid extruder (this printer has T0 only)"
                    ));
                    return false;
                }
                // A console line (a job's waits its turn as a `Command::Setting`).
                if let Some(id) = self.set_temperature(*heater, *wait, *s, *r) {
                    self.intake.push(Command::WaitHeater(id));
                }
            }
            HeatCommand::Report => {
                let r = self.heat.report();
                self.host.temperatures(r);
                return true;
            }
            HeatCommand::FanOn { fan: Some(f), .. } | HeatCommand::FanOff { fan: Some(f) }
                if *f != 0 =>
            {
                // Marlin ignores a fan it does not have (`M106 P9`); here it is said, as a
                // note, not a refusal: slicers address fans a printer may lack (Bambu's
                // auxiliary `M106 P2`, chamber `P3`), and nothing of the job is lost.
                let code = if matches!(c, HeatCommand::FanOn { .. }) {
                    "M106"
                } else {
                    "M107"
                };
                self.host.say(format_args!(
                    "{code} P{f}: no such fan, ignored (this printer has P0 only)"
                ));
            }
            HeatCommand::FanOn { speed, .. } => self.heat.set_fan(*speed),
            HeatCommand::FanOff { .. } => self.heat.set_fan(Some(0.0)),
            HeatCommand::ColdExtrusion { min_temp_c, allow } => {
                self.heat.m302(*min_temp_c, *allow, &mut self.host)
            }
            HeatCommand::SetPid { heater, p, i, d } => {
                self.heat.pid_command(*heater, *p, *i, *d, &mut self.host)
            }
            HeatCommand::Autotune {
                heater_index,
                target_c,
                cycles,
                use_result,
            } => self.heat.autotune(
                *heater_index,
                *target_c,
                *cycles,
                *use_result,
                self.now_us,
                &mut self.host,
            ),
        }
        false
    }

    /// M104/M109/M140/M190 with T0 (or no T): set the target (a refusal is said); returns the
    /// heater to wait for (M109/M190). The console's line and the job's queued one
    /// (`JobSetting::Temperature`, when it reaches the front) both come here.
    pub(in crate::printer) fn set_temperature(
        &mut self,
        heater: Heater,
        wait: bool,
        s: Option<f32>,
        r: Option<f32>,
    ) -> Option<HeaterId> {
        let id = heater_id(heater);
        if let Some(t) = r.or(s) {
            if let Err(e) = self.heat.set_target(id, t) {
                let code = heater.target_code(wait);
                let word = if r.is_some() { 'R' } else { 'S' };
                self.host.warn(format_args!("{code} {word}{t}: {e}"));
                return None;
            }
        }
        wait.then_some(id)
    }
}
