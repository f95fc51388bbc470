//! The four TMC2209 drivers: configured with the executive's settings at start-up, re-applied
//! when those change, and reported on request (M122), only while nothing moves.

use firmware::drivers::tmc2209::DriverSettings;
use firmware::motion::{Axis, Realtime};
use firmware::printer::{DriverRequest, Printer};

use super::printer_now_us;
use crate::board::tmc;

/// The four TMC2209 drivers and what was last written to each (None: not configured).
pub(super) struct Drivers {
    pub(super) tmc: [tmc::Driver; 4],
    pub(super) applied: [Option<DriverSettings>; 4],
}

/// Configures the drivers in `mask` with the executive's settings for them, reports each
/// outcome on the host link, and halts the printer if any does not answer or hold its
/// settings (motion stays disabled: the halted motion loop keeps the drivers off).
pub(super) fn configure_drivers(p: &mut Printer, d: &mut Drivers, mask: u8) {
    let mut ok = true;
    for (i, axis) in Axis::ALL.into_iter().enumerate() {
        if mask & (1 << i) == 0 {
            continue;
        }
        let s = p.driver_settings(axis);
        let r = d.tmc[i].configure(&s);
        d.applied[i] = r.ok().map(|_| s);
        if let Err(e) = r {
            defmt::error!("TMC2209 {}: {}", i, defmt::Display2Format(&e));
            ok = false;
        }
        p.driver_configured(axis, r);
    }
    if !ok {
        p.request(Realtime::EmergencyStop, printer_now_us());
    }
}

/// Serves the executive's driver requests and re-applies a driver whose settings changed
/// (M906, M569, M350, M501/M502), only while nothing moves.
pub(super) fn service_drivers(p: &mut Printer, d: &mut Drivers) {
    let mut reports = 0u8;
    while let Some(r) = p.take_driver_request() {
        if let DriverRequest::Report { mask } = r {
            reports |= mask;
        }
    }
    let mut changed = 0u8;
    for (i, axis) in Axis::ALL.into_iter().enumerate() {
        if d.applied[i].is_some_and(|a| a != p.driver_settings(axis)) {
            changed |= 1 << i;
        }
    }
    if changed != 0 {
        configure_drivers(p, d, changed);
    }
    for (i, axis) in Axis::ALL.into_iter().enumerate() {
        if reports & (1 << i) != 0 {
            let r = d.tmc[i].report();
            p.driver_report(axis, r);
        }
    }
}
