//! The machine behind the ports: the firmware on virtual time, its heaters, its storage (the
//! flash with `--flash`, the card with `--sd`), and — with `--machine`/`--trace` — the body
//! and the move trace a power cut leaves.

use super::ServeArgs;
use crate::exec::{PrinterExec, PrinterFactory};
use crate::port::{Executive, State};
use crate::recorder::Recorder;
use crate::run::{Factory, Scenario};
use crate::thermal::Heaters;

/// The firmware and what it drives.
pub(super) struct Machine {
    pub(super) fw: PrinterExec,
    pub(super) rec: Recorder,
    heaters: Heaters,
    flash: Option<crate::flash::FlashStore>,
    card: Option<firmware::storage::sd::Card<crate::sd::ImageDevice>>,
    body: Option<crate::powercut::MachineBody>,
    trace: Option<crate::powercut::MoveTrace>,
    last_poll_us: u64,
}

impl Machine {
    pub(super) fn open(a: &ServeArgs, sc: &Scenario) -> anyhow::Result<Self> {
        let flash = a
            .flash
            .as_deref()
            .map(crate::flash::FlashStore::open)
            .transpose()?;
        let card = match a.sd.as_deref() {
            Some(p) if p.is_dir() => Some(crate::sd::ImageDevice::from_dir(p)?),
            Some(p) => Some(crate::sd::ImageDevice::open(p)?),
            None => None,
        }
        .map(firmware::storage::sd::Card::new);
        // The machine file: which printer, and (power-cut checks) the head where the last
        // session left it, with endstops.
        let body = a
            .machine
            .as_deref()
            .map(crate::powercut::MachineBody::open)
            .transpose()?;
        let cfg = body.as_ref().map_or(sc.machine, |(_, m, _)| m.config);
        let mut fw: PrinterExec = PrinterFactory.make(&cfg, &sc.knobs());
        fw.keep_executed = true;
        fw.printer
            .set_control_bytes(firmware::link::PortId::Tft, a.tft_control_bytes);
        let mut rec = Recorder::new();
        let body = match body {
            Some((b, _, pos)) => {
                fw = fw.with_endstops([pos[0], pos[1], pos[2]]);
                rec.pos = pos;
                Some(b)
            }
            None => None,
        };
        let trace = a
            .trace
            .as_deref()
            .map(crate::powercut::MoveTrace::open)
            .transpose()?;
        Ok(Self {
            fw,
            rec,
            heaters: Heaters::ender3(),
            flash,
            card,
            body,
            trace,
            last_poll_us: 0,
        })
    }

    /// Storage: the first pass loads the saved settings (before any host byte is read, as at
    /// power-up), later passes carry out M500/M501; the card answers the commands waiting for
    /// it and gives the job's (and the parked intake's) lines while the queue has room.
    pub(super) fn service_storage(&mut self, now_us: u64) {
        if let Some(f) = self.flash.as_mut() {
            f.service(&mut self.fw.printer);
        }
        if let Some(c) = self.card.as_mut() {
            self.fw.printer.attach_card();
            self.fw.printer.service_card(c, now_us);
        }
    }

    /// Run the steps due by `now_us`, the heaters and the firmware's main loop.
    pub(super) fn run_until(&mut self, now_us: u64) {
        let mut n = 0;
        while let Some(t) = self.fw.next_step_us(now_us) {
            if t > now_us || n > 200_000 {
                break;
            }
            if let Some(ev) = self.fw.pop_step(t) {
                if self.rec.on_step(&ev) {
                    self.fw.poll(t);
                }
            }
            n += 1;
        }
        if now_us >= self.last_poll_us + 1000 || n > 0 {
            self.heaters.tick(&mut self.fw, now_us);
            self.fw.poll(now_us);
            self.last_poll_us = now_us;
        }
        self.rec.on_status(&self.fw.status(), now_us);
    }

    /// Whether nothing moves (idle, paused, halted, cancelled: anything but a running job or
    /// a wait); then the head's position and the finished moves are kept, so a killed
    /// session (a power cut) leaves them. Decided before the output is taken: asking for the
    /// next step can load a block and let a waiting command (M400) complete and answer, and
    /// that answer must go out before an idle exit.
    pub(super) fn idle(&mut self, now_us: u64) -> anyhow::Result<bool> {
        let st = self.fw.status().state;
        let idle = self.fw.next_step_us(now_us).is_none()
            && !matches!(st, State::Printing | State::Pausing | State::Resuming);
        if idle {
            self.keep()?;
        }
        Ok(idle)
    }

    /// Keep the body and the trace (the head stops where its last step left it, whatever
    /// the firmware had planned).
    pub(super) fn keep(&mut self) -> anyhow::Result<()> {
        if let Some(b) = self.body.as_mut() {
            b.keep(self.rec.pos)?;
        }
        if let Some(t) = self.trace.as_mut() {
            t.flush(&self.rec.records)?;
        }
        Ok(())
    }

    /// Real microseconds to sleep before the next step is due: at most 2 ms, and at most
    /// 0.2 s of virtual time (so a fast session still polls the firmware often enough for its
    /// 1 s pace of the parked intake and its keep-alives).
    pub(super) fn wait_us(&mut self, now_us: u64, speed: f64) -> u64 {
        let cap_us = (200_000.0 / speed).min(2000.0);
        match self.fw.next_step_us(now_us) {
            Some(t) if t > now_us => ((t - now_us) as f64 / speed).min(cap_us) as u64,
            Some(_) => 0,
            None => cap_us as u64,
        }
    }
}
