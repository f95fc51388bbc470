//! The executive's side of the TMC2209 stepper drivers: M569 (stealthChop/spreadCycle), M350
//! (microsteps; steps/mm follow), M122 (driver report), and the messages for the board's
//! results. The board owns the UART lines: it takes [`DriverRequest`]s, talks to the drivers
//! (`crate::drivers::tmc2209`) once the step queue is idle, and hands the outcome back through
//! [`Printer::driver_configured`] and [`Printer::driver_report`]. M906 (run current) is a
//! settings command; the board re-applies a driver whose current changed.

use super::{Command, Printer, StepperRequest};
use crate::drivers::tmc2209::{DriverReport, DriverSettings, TmcError};
use crate::gcode::{AxisFlags, DriverCommand};
use crate::link::Response;
use crate::motion::{Axis, AXES};
use core::fmt::Write;

/// Requests queued for the board (oldest dropped when full: each one re-reads the config).
pub const DRIVER_REQ_CAPACITY: usize = 4;

/// What the board is asked to do with the drivers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriverRequest {
    /// Write the settings of these axes (bit i = axis i) from [`Printer::driver_settings`].
    Apply {
        /// Axes.
        mask: u8,
    },
    /// Read these axes' drivers and report (M122).
    Report {
        /// Axes.
        mask: u8,
    },
}

const LETTERS: [char; AXES] = ['X', 'Y', 'Z', 'E'];

fn mask_of(f: &AxisFlags) -> u8 {
    (0..AXES)
        .filter(|&i| f.is_empty() || f.0[i])
        .fold(0, |m, i| m | 1 << i)
}

impl Printer {
    /// The next request for the board.
    pub fn take_driver_request(&mut self) -> Option<DriverRequest> {
        self.board.take_driver_request()
    }

    /// What the driver of `axis` should be set to, from the configuration (microsteps, M906
    /// current, M569 mode).
    pub fn driver_settings(&self, axis: Axis) -> DriverSettings {
        DriverSettings::of_axis(self.settings.cfg(), axis)
    }

    /// The board's outcome of configuring the driver of `axis`, on every host port (it comes at
    /// start-up or after a settings change, not as an answer). A failure is an `Error:` line
    /// naming the axis and what to check; the board then keeps motion disabled.
    pub fn driver_configured(&mut self, axis: Axis, r: Result<(), TmcError>) {
        let letter = LETTERS[axis.index()];
        let mut t: heapless::String<160> = heapless::String::new();
        match r {
            Ok(()) => {
                let s = self.driver_settings(axis);
                let _ = write!(
                    t,
                    "TMC2209 {letter}: {} mA, 1/{} microsteps, {}",
                    s.run_ma,
                    s.microsteps,
                    if s.stealthchop {
                        "stealthChop"
                    } else {
                        "spreadCycle"
                    }
                );
                self.host.notify(Response::Echo(&t));
            }
            Err(e) => {
                let _ = write!(
                    t,
                    "TMC2209 {letter}: {e}: motion disabled. Check that the driver sits in its \
                     socket, its UART jumper is fitted and the 24 V supply is on"
                );
                self.host.notify(Response::Error(&t));
            }
        }
    }

    /// The board's M122 reading of the driver of `axis`: one `echo:` line.
    pub fn driver_report(&mut self, axis: Axis, r: Result<DriverReport, TmcError>) {
        let letter = LETTERS[axis.index()];
        let rsense = self.driver_settings(axis).rsense_ohm;
        let mut t: heapless::String<160> = heapless::String::new();
        let _ = match r {
            Ok(rep) => {
                let (otpw, ot) = rep.overtemp();
                write!(
                    t,
                    "{letter}: TMC2209 ok, {} mA actual, 1/{}, {}, GSTAT 0x{:X}{}{}{}{}",
                    libm::roundf(rep.actual_ma(rsense)) as u32,
                    rep.microsteps(),
                    if rep.stealthchop() {
                        "stealthChop"
                    } else {
                        "spreadCycle"
                    },
                    rep.gstat,
                    if otpw {
                        ", over-temperature warning"
                    } else {
                        ""
                    },
                    if ot {
                        ", OVER-TEMPERATURE SHUTDOWN"
                    } else {
                        ""
                    },
                    if rep.short() { ", SHORT" } else { "" },
                    if rep.open_load() { ", open load" } else { "" },
                )
            }
            Err(e) => write!(t, "{letter}: TMC2209 {e}"),
        };
        self.host.respond(Response::Echo(&t));
    }

    /// M17, M18/M84 (in the job's order, through the intake), M569, M350, M122.
    pub(super) fn driver_command(&mut self, c: &DriverCommand) {
        match c {
            DriverCommand::EnableSteppers(axes) => {
                let mask = mask_of(axes);
                self.intake
                    .push(Command::Steppers(StepperRequest::Enable { mask }));
            }
            DriverCommand::DisableSteppers { axes, s, .. } => match s {
                Some(s) if s.is_finite() && *s >= 0.0 => {
                    self.intake
                        .push(Command::Steppers(StepperRequest::IdleTimeout { s: *s }));
                }
                Some(_) => self
                    .host
                    .warn(format_args!("M84 S: timeout must be >= 0 s")),
                None => {
                    let mask = mask_of(axes);
                    self.intake
                        .push(Command::Steppers(StepperRequest::Disable { mask }));
                }
            },
            DriverCommand::Chopper { axes, stealthchop } => {
                let mask = mask_of(axes);
                match stealthchop {
                    Some(on) => {
                        for i in (0..AXES).filter(|i| mask & 1 << i != 0) {
                            self.settings.cfg_mut().driver_stealthchop[i] = *on;
                        }
                        self.board
                            .push_driver_request(DriverRequest::Apply { mask });
                    }
                    None => {
                        let mut t: heapless::String<96> = heapless::String::new();
                        let _ = t.push_str("M569:");
                        for i in (0..AXES).filter(|i| mask & 1 << i != 0) {
                            let mode = if self.settings.cfg().driver_stealthchop[i] {
                                "stealthChop"
                            } else {
                                "spreadCycle"
                            };
                            let _ = write!(t, " {}:{mode}", LETTERS[i]);
                        }
                        self.host.respond(Response::Echo(&t));
                    }
                }
            }
            DriverCommand::Microsteps { all, axes } => self.m350(*all, axes.0),
            DriverCommand::Report(axes) => {
                let mask = mask_of(axes);
                self.board
                    .push_driver_request(DriverRequest::Report { mask });
            }
        }
    }

    /// M350: every value checked first (a refusal changes nothing), then steps/mm scaled
    /// through the settings path (which also moves the position counters), then the drivers.
    fn m350(&mut self, all: Option<f32>, axes: [Option<f32>; AXES]) {
        let want: [Option<f32>; AXES] = core::array::from_fn(|i| axes[i].or(all));
        if want.iter().all(Option::is_none) {
            let mut t: heapless::String<96> = heapless::String::new();
            let _ = t.push_str("M350");
            for (i, a) in self.settings.cfg().axes.iter().enumerate() {
                let _ = write!(t, " {}{}", LETTERS[i], a.microsteps);
            }
            self.host.respond(Response::Echo(&t));
            return;
        }
        let mut next = *self.settings.cfg();
        for (i, v) in want.iter().enumerate() {
            let Some(v) = v else { continue };
            let ok = libm::truncf(*v) == *v
                && (1.0..=256.0).contains(v)
                && next.set_microsteps(Axis::ALL[i], *v as u16);
            if !ok {
                self.host.say(format_args!(
                    "refused: M350 {}{v}: microsteps must be 1, 2, 4, ... or 256",
                    LETTERS[i]
                ));
                return;
            }
        }
        let mut s = self.settings();
        s.steps_per_mm = core::array::from_fn(|i| next.axes[i].steps_per_mm);
        if let Err(e) = self.apply_settings(&s) {
            self.host.say(format_args!("refused: M350: {e}"));
            return;
        }
        let mut mask = 0;
        for (i, v) in want.iter().enumerate() {
            if v.is_some() {
                self.settings.cfg_mut().axes[i].microsteps = next.axes[i].microsteps;
                mask |= 1 << i;
            }
        }
        self.board
            .push_driver_request(DriverRequest::Apply { mask });
    }
}
