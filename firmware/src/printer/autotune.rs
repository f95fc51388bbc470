//! M303's result on the host link, as Marlin's `PID_autotune()` prints it when the tune ends
//! (Marlin `Marlin/src/module/temperature.cpp` with the strings of `Marlin/src/core/language.h`:
//! `STR_PID_AUTOTUNE_FINISHED`, the `#define DEFAULT_Kp …` lines, `STR_PID_TEMP_TOO_HIGH`,
//! `STR_PID_TIMEOUT`; plain lines, no `echo:`). The tune itself is `thermal::autotune`.

use super::Printer;
use crate::link::Response;
use crate::thermal::{AutotuneError, AutotuneStatus, HeaterId};
use core::fmt::Write;
use heapless::String;

impl Printer {
    /// Called after each heater sample with the tune's status before the sample: a tune that
    /// has just ended is reported once.
    pub(super) fn report_autotune(&mut self, id: HeaterId, before: Option<AutotuneStatus>) {
        if !matches!(before, Some(AutotuneStatus::Running { .. })) {
            return;
        }
        match self.thermal.autotune_status(id) {
            Some(AutotuneStatus::Done(g)) => {
                self.link.notify(Response::Plain(
                    "PID Autotune finished! Put the last Kp, Ki and Kd constants from below into Configuration.h",
                ));
                let prefix = if id == HeaterId::Bed { "bed" } else { "" };
                for (name, v) in [("Kp", g.kp), ("Ki", g.ki), ("Kd", g.kd)] {
                    let mut t: String<48> = String::new();
                    let _ = write!(t, "#define DEFAULT_{prefix}{name} {v:.2}");
                    self.link.notify(Response::Plain(&t));
                }
            }
            Some(AutotuneStatus::Failed(e)) => {
                self.link.notify(Response::Plain(match e {
                    AutotuneError::TooHot => "PID Autotune failed! Temperature too high",
                    AutotuneError::Timeout => "PID Autotune failed! timeout",
                    AutotuneError::Fault | AutotuneError::Cancelled => "PID Autotune failed!",
                }));
            }
            _ => {}
        }
    }
}
