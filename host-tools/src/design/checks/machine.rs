//! The machine state the checks follow between the moves: the hot-end target (the design's
//! temperatures and raw `M104`/`M109`), cold-extrusion permission (raw `M302`), and where raw
//! lines take the head (`G0`/`G1`, `G28`) — so a heater switched off before an extrusion and a
//! `G28` in the middle of a print are flagged like any other design step.

use super::{CheckOptions, CheckReport, IssueKind};
use crate::design::model::{StateChange, Step, Str};
use crate::design::profile::Profile;
use crate::design::raw::RawTracker;
use glam::DVec3;

/// Lowest hot-end temperature at which the printer moves E: the firmware's own guard
/// (Marlin's `EXTRUDE_MINTEMP`), °C.
pub const MIN_EXTRUDE_C: f64 = firmware::printer::ExtrusionGuard::MARLIN.min_temp_c as f64;

/// What set the hot-end target last.
#[derive(Clone, Debug)]
struct TargetSource {
    step: usize,
    what: &'static str,
}

/// The followed state.
pub(super) struct Machine {
    /// The printer heats its nozzle (a filament printer); paste printers are not checked.
    heated: bool,
    hotend_c: f64,
    set_by: Option<TargetSource>,
    cold_allowed: bool,
    min_c: f64,
    /// A cold extrusion was reported since the target last changed.
    reported: bool,
    home: DVec3,
}

impl Machine {
    /// The state at the design's start: the hot-end target of the start code (the design's,
    /// set before its first move, else the profile's).
    pub(super) fn new(steps: &[Step], profile: &Profile) -> Machine {
        let mut hotend_c = profile.hotend_c;
        for s in steps {
            match s {
                Step::String(_) | Step::Travel { .. } => break,
                Step::State(StateChange::HotendTemp { celsius, .. }) => hotend_c = *celsius,
                _ => {}
            }
        }
        Machine {
            heated: profile.hotend_c >= MIN_EXTRUDE_C,
            hotend_c,
            set_by: None,
            cold_allowed: false,
            min_c: MIN_EXTRUDE_C,
            reported: false,
            home: DVec3::new(profile.bed.x_min_mm, profile.bed.y_min_mm, 0.0),
        }
    }

    fn target(&mut self, c: f64, step: usize, what: &'static str) {
        self.hotend_c = c;
        self.set_by = Some(TargetSource { step, what });
        self.reported = false;
    }

    /// A state change at step `i`; `pos` is where the head is (raw moves change it),
    /// `printing` whether anything was printed yet.
    pub(super) fn state(
        &mut self,
        i: usize,
        sc: &StateChange,
        pos: &mut Option<DVec3>,
        printing: bool,
        o: &CheckOptions,
        rep: &mut CheckReport,
    ) {
        match sc {
            StateChange::HotendTemp { celsius, .. } => {
                self.target(*celsius, i, "the design's hot-end temperature");
            }
            StateChange::Gcode(text) => {
                let from = pos.map_or([None; 3], |p| [Some(p.x), Some(p.y), Some(p.z)]);
                let mut t = RawTracker::new(from, 0.0, true, self.home);
                let fx = t.apply(text);
                if let Some(c) = fx.hotend_c {
                    self.target(c, i, "raw G-code");
                }
                if let Some(a) = fx.cold_allowed {
                    self.cold_allowed = a;
                    self.reported = false;
                }
                if let Some(c) = fx.cold_min_c {
                    self.min_c = c;
                    self.reported = false;
                }
                if fx.moved {
                    *pos = t.position();
                }
                if fx.homes && printing {
                    let at = pos.unwrap_or(self.home);
                    rep.add(o.max_listed, IssueKind::HomesMidPrint, i, at, || format!(
                                "raw G-code `{}` homes in the middle of the print: the head drives to its endstops through or across what is printed",
                                text.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join("\\n")
                            ));
                }
            }
            _ => {}
        }
    }

    /// An extruding string at step `i`: flagged when the hot end is set below the firmware's
    /// extrusion minimum (once until the target changes).
    pub(super) fn extrusion(&mut self, i: usize, s: &Str, o: &CheckOptions, rep: &mut CheckReport) {
        if !self.heated || self.cold_allowed || self.reported || self.hotend_c >= self.min_c {
            return;
        }
        self.reported = true;
        let by = match &self.set_by {
            Some(t) => format!(" by {} at step {}", t.what, t.step),
            None => String::new(),
        };
        rep.add(o.max_listed, IssueKind::ColdExtrusion, i, s.start, || format!(
                    "extruding with the hot end set to {:.0} °C{by}: below {:.0} °C the firmware refuses to move the extruder (M302)",
                    self.hotend_c, self.min_c
                ));
    }
}
