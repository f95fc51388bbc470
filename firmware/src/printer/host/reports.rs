//! Reports hosts expect of a Marlin-class firmware, and their timers:
//!
//! - temperatures about once a second while a line waits in M109/M190, as Marlin's
//!   `Temperature::wait_for_hotend`/`wait_for_bed` print them ("Print temp & remaining time
//!   every 1s while waiting": `print_heater_states()` then ` W:?`, Marlin
//!   `src/module/temperature.cpp`); OctoPrint does not poll M105 while the firmware is busy, so
//!   this is all it sees of a heat-up;
//! - M155 S<s>: temperatures every s seconds (`Cap:AUTOREPORT_TEMP:1`);
//! - M113 S<s>: the `busy: processing` period (0 = off; Marlin's default 2 s);
//! - M73 P<percent>: the progress a host or slicer sends, reported by M27 (`Cap:PROGRESS:1`);
//! - M31: the print job's time (Marlin's `echo:Print time: 1h 2m 3s` style), counted from the
//!   first heater wait or job motion while no job is timed, paused time excluded, until the
//!   printer is idle with its heaters off, or the job is cancelled;
//! - M27: without an SD card Marlin answers `Not SD printing`; this firmware adds its layer
//!   counter, state and M73 progress on an `echo:` line (read by the OctoPrint plugin).

use super::Host;
use crate::gcode::{Progress, ReportCommand};
use crate::link::{Response, TempReport};
use crate::printer::types::State;

/// One second, µs: the period of the temperature lines during heater waits (Marlin's).
pub const WAIT_REPORT_US: u64 = 1_000_000;
/// Marlin's default host keep-alive period (`DEFAULT_KEEPALIVE_INTERVAL`), µs.
pub const DEFAULT_BUSY_US: u64 = 2_000_000;

/// The report timers and what M73 said.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Reports {
    /// M155 period, µs (0 = off), and when the next report is due.
    auto_temp_us: u64,
    next_auto_us: u64,
    /// When the next temperature line of a heater wait is due.
    next_wait_us: u64,
    /// M113 period, µs (0 = no `busy:` lines).
    busy_us: u64,
    /// The print job timer: µs counted so far, and the time of the last tick while running.
    job_us: u64,
    job_tick_us: Option<u64>,
    /// Last M73 percent (0..=100).
    progress_percent: Option<u8>,
}

impl Reports {
    pub(super) const fn new() -> Self {
        Self {
            auto_temp_us: 0,
            next_auto_us: 0,
            next_wait_us: 0,
            busy_us: DEFAULT_BUSY_US,
            job_us: 0,
            job_tick_us: None,
            progress_percent: None,
        }
    }

    /// The `busy:` period (M113), µs.
    pub(super) fn busy_us(&self) -> u64 {
        self.busy_us
    }
}

/// What M27 needs to know of the printer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::printer) struct JobView {
    /// The run state.
    pub(in crate::printer) state: State,
    /// M27's layer (the last one the head crossed).
    pub(in crate::printer) layer: Option<u32>,
    /// The card job's bytes read and size, when one prints.
    pub(in crate::printer) sd_progress: Option<(u32, u32)>,
}

/// `1h 2m 3s` / `2m 3s` / `3s`, as Marlin's `duration_t::toString` writes M31's time.
struct Duration(u64);

impl core::fmt::Display for Duration {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let s = self.0;
        let (d, h, m, sec) = (s / 86_400, s / 3600 % 24, s / 60 % 60, s % 60);
        if d > 0 {
            write!(f, "{d}d {h}h {m}m {sec}s")
        } else if h > 0 {
            write!(f, "{h}h {m}m {sec}s")
        } else if m > 0 {
            write!(f, "{m}m {sec}s")
        } else {
            write!(f, "{sec}s")
        }
    }
}

impl Host {
    /// M105's answer: the temperatures with its `ok`.
    pub(in crate::printer) fn temperatures(&mut self, report: TempReport) {
        self.ports.respond(Response::Temperatures {
            report,
            with_ok: true,
        });
    }

    fn temp_line(&mut self, report: TempReport) {
        self.ports.respond(Response::Temperatures {
            report,
            with_ok: false,
        });
    }

    /// Called while a line waits for a heater (M109/M190): a temperature line about once a
    /// second, and the print job timer starts.
    pub(in crate::printer) fn heater_wait_report(&mut self, now_us: u64, report: TempReport) {
        let r = &mut self.reports;
        if r.job_tick_us.is_none() {
            r.job_tick_us = Some(now_us);
        }
        if now_us >= r.next_wait_us {
            r.next_wait_us = now_us + WAIT_REPORT_US;
            self.temp_line(report);
        }
    }

    /// Called every main-loop tick: the M155 auto-report and the print job timer. The
    /// temperatures and whether the heaters are off are asked for only when needed (the idle
    /// tick stays cheap).
    pub(in crate::printer) fn report_tick(
        &mut self,
        now: u64,
        state: State,
        temps: impl FnOnce() -> TempReport,
        heaters_off: impl FnOnce() -> bool,
    ) {
        let r = &mut self.reports;
        if r.auto_temp_us > 0 && now >= r.next_auto_us {
            r.next_auto_us = now + r.auto_temp_us;
            self.temp_line(temps());
        }
        let r = &mut self.reports;
        match (r.job_tick_us, state) {
            (None, State::Printing) => r.job_tick_us = Some(now),
            (Some(_), State::Cancelled | State::Halted) => r.job_tick_us = None,
            (Some(_), State::Idle) if heaters_off() => r.job_tick_us = None,
            (Some(t), State::Paused) => r.job_tick_us = Some(t.max(now)),
            (Some(t), _) => {
                r.job_us += now.saturating_sub(t);
                r.job_tick_us = Some(now);
            }
            (None, _) => {}
        }
    }

    /// M73: remember the percent (reported by M27).
    pub(in crate::printer) fn note_progress(&mut self, p: &Progress) {
        if let Some(pc) = p.percent.filter(|v| v.is_finite()) {
            self.reports.progress_percent = Some(pc.clamp(0.0, 100.0) as u8);
        }
    }

    /// M155, M113, M31, M27 (its layer line; the card's byte line is the SD part's).
    pub(in crate::printer) fn report_command(&mut self, c: &ReportCommand, now: u64, job: JobView) {
        match *c {
            ReportCommand::AutoTemp(Some(s)) => {
                self.reports.auto_temp_us = u64::from(s) * 1_000_000;
                self.reports.next_auto_us = now;
            }
            ReportCommand::AutoTemp(None) => {
                let s = self.reports.auto_temp_us / 1_000_000;
                self.say(format_args!("M155 S{s}"));
            }
            ReportCommand::HostKeepalive(Some(s)) => {
                self.reports.busy_us = u64::from(s) * 1_000_000;
            }
            ReportCommand::HostKeepalive(None) => {
                let s = self.reports.busy_us / 1_000_000;
                self.say(format_args!("M113 S{s}"));
            }
            ReportCommand::PrintTime => {
                let s = self.reports.job_us / 1_000_000;
                self.say(format_args!("Print time: {}", Duration(s)));
            }
            ReportCommand::JobStatus => {
                let state = match job.state {
                    State::Idle => "idle",
                    State::Printing => "printing",
                    State::Pausing => "pausing",
                    State::Paused => "paused",
                    State::Resuming => "resuming",
                    State::Cancelled => "cancelled",
                    State::Halted => "halted",
                };
                // M73's percent, else the card job's bytes read.
                let progress = self.reports.progress_percent.or_else(|| {
                    job.sd_progress
                        .filter(|(_, b)| *b > 0)
                        .map(|(a, b)| (u64::from(a) * 100 / u64::from(b)) as u8)
                });
                match (job.layer, progress) {
                    (Some(l), Some(p)) => {
                        self.say(format_args!("layer {l} state {state} progress {p}%"))
                    }
                    (Some(l), None) => self.say(format_args!("layer {l} state {state}")),
                    (None, Some(p)) => {
                        self.say(format_args!("layer - state {state} progress {p}%"))
                    }
                    (None, None) => self.say(format_args!("layer - state {state}")),
                }
            }
            // The executive's own reports (printer/commands/report.rs).
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Duration;

    #[test]
    fn print_time_is_written_like_marlin() {
        assert_eq!(format!("{}", Duration(0)), "0s");
        assert_eq!(format!("{}", Duration(83)), "1m 23s");
        assert_eq!(format!("{}", Duration(3723)), "1h 2m 3s");
        assert_eq!(format!("{}", Duration(90_061)), "1d 1h 1m 1s");
    }
}
