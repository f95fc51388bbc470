//! The emulator as the USB host at the other end of the board's USB cable: it sees the
//! device's D+ pull-up, resets the bus, enumerates the device as Linux does (USB 2.0 §9.1.2,
//! chapter 9's standard requests; Linux's `hub_port_init` order), configures it, finds its
//! CDC ACM function (USB CDC 1.2 / PSTN 1.2: communication interface with SET_LINE_CODING and
//! SET_CONTROL_LINE_STATE, data interface with a bulk IN and a bulk OUT endpoint) and then
//! moves a serial port's bytes, as the kernel's `cdc-acm` driver does:
//!
//! * a program opening the port (the `open` flag) sends SET_LINE_CODING (115200 8N1) and
//!   SET_CONTROL_LINE_STATE with DTR and RTS; closing it sends SET_CONTROL_LINE_STATE 0. The
//!   IN endpoint is read only while the port is open (cdc-acm submits its read URBs at open
//!   and kills them at close), and bytes written go out as 64-byte OUT packets;
//! * a NAK is retried when the device changes an endpoint (`Otg::kicked`: a real host polls
//!   continuously) or at the next frame, so a device that NAKs holds the host's bytes back —
//!   the flow control the image relies on;
//! * unplugging stops the frames (the device suspends after 3 ms); plugging in again is a new
//!   attach: debounce, bus reset, enumeration.
//!
//! Timing (USB 2.0): 100 ms attach debounce (§7.1.7.3, TATTDB), 10 ms bus reset (§7.1.7.5,
//! TDRST), 10 ms reset recovery (§9.2.6.2, TRSTRCY), 2 ms after SET_ADDRESS (§9.2.6.3), 1 ms
//! frames with a SOF each; a transaction occupies the bus for its bytes plus about 20 bytes
//! of token, handshake, CRC, sync and gaps at 12 Mbit/s. A control transfer not done within
//! 5 s fails (Linux's USB_CTRL_GET_TIMEOUT). Not modelled: data toggles, retries of
//! corrupted packets, other devices on the bus, the interrupt endpoint (never polled: the
//! image sends no notifications), suspend by the host while plugged.

use crate::otg::{Handshake, Otg};
use crate::time::{cyc_from_ms, cyc_from_us, Cyc, CPU_HZ};
use serde::Serialize;
use std::collections::VecDeque;

/// The address the host gives the device.
const ADDRESS: u8 = 1;
/// Control transfer timeout.
const CTRL_TIMEOUT: Cyc = cyc_from_ms(5_000);
/// The host's reaction to a device that changed an endpoint.
const TURNAROUND: Cyc = cyc_from_us(2);
/// Bulk data per OUT packet (the data interface's endpoints are 64 bytes on full speed).
const PACKET: usize = 64;

/// Bus time of a transaction carrying `bytes` of data.
fn bus_time(bytes: usize) -> Cyc {
    (bytes as Cyc + 20) * 8 * CPU_HZ / 12_000_000
}

/// The bus as the host drives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Bus {
    /// Nothing attached (or the cable out).
    Detached,
    /// Attach seen; debouncing until then.
    Debounce(Cyc),
    /// Driving the reset until then.
    Reset(Cyc),
    /// Reset recovery until then.
    Recovery(Cyc),
    /// Frames run; transfers go on.
    Active,
    /// The cable was pulled at this time: the device suspends 3 ms later.
    Unplugged(Cyc),
}

/// What the host learnt of the device.
#[derive(Clone, Debug, Default, Serialize)]
pub struct DeviceInfo {
    /// idVendor, idProduct.
    pub vid_pid: (u16, u16),
    /// bMaxPacketSize0.
    pub ep0_size: u8,
    /// Manufacturer, product, serial strings.
    pub strings: Vec<String>,
    /// The CDC ACM communication interface's number.
    pub comm_interface: u8,
    /// Bulk IN and OUT endpoint numbers and their packet size.
    pub bulk_in: u8,
    /// See `bulk_in`.
    pub bulk_out: u8,
    /// See `bulk_in`.
    pub bulk_size: u16,
}

/// Counts for the report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct UsbStats {
    /// Bus resets driven.
    pub resets: u32,
    /// Enumerations completed (SET_CONFIGURATION accepted).
    pub enumerations: u32,
    /// Bulk packets sent and received.
    pub out_packets: u64,
    /// See `out_packets`.
    pub in_packets: u64,
    /// OUT packets the device NAKed (its flow control holding the host back).
    pub out_naks: u64,
    /// Bytes sent and received on the bulk endpoints.
    pub out_bytes: u64,
    /// See `out_bytes`.
    pub in_bytes: u64,
}

/// The USB host.
#[derive(Clone, Debug)]
pub struct UsbHost {
    plugged: bool,
    bus: Bus,
    next_at: Option<Cyc>,
    frame: u32,
    next_frame: Cyc,
    addr: u8,
    pending: VecDeque<Req>,
    ctrl: Option<Ctrl>,
    /// A NAK or nothing to do: waiting for the device or the next frame.
    waiting: bool,
    /// The next bulk turn is IN (else OUT).
    turn_in: bool,
    /// The device as enumerated.
    pub device: Option<DeviceInfo>,
    /// SET_CONFIGURATION done since the last reset.
    pub configured: bool,
    /// A program holds the serial port.
    open: bool,
    /// DTR as last sent to the device.
    pub dtr: bool,
    /// Bytes the program wrote, not yet sent.
    pub host_tx: VecDeque<u8>,
    /// Bytes the device sent, with their time.
    pub rx_log: Vec<(Cyc, u8)>,
    /// What happened on the bus, with its time (attach, reset, requests done, DTR…).
    pub events: Vec<(Cyc, String)>,
    /// Transfers that failed.
    pub errors: Vec<String>,
    /// Counts.
    pub stats: UsbStats,
    /// The string descriptors' indices to fetch (manufacturer, product, serial).
    string_ids: Vec<u8>,
    /// No transaction before this time (the SET_ADDRESS recovery interval).
    quiet_until: Cyc,
}

impl UsbHost {
    /// A host with the cable `plugged` in or not, and the port closed.
    pub fn new(plugged: bool) -> Self {
        UsbHost {
            plugged,
            bus: Bus::Detached,
            next_at: Some(0),
            frame: 0,
            next_frame: 0,
            addr: 0,
            pending: VecDeque::new(),
            ctrl: None,
            waiting: false,
            turn_in: false,
            device: None,
            configured: false,
            open: false,
            dtr: false,
            host_tx: VecDeque::new(),
            rx_log: Vec::new(),
            events: Vec::new(),
            errors: Vec::new(),
            stats: UsbStats::default(),
            string_ids: Vec::new(),
            quiet_until: 0,
        }
    }

    fn event(&mut self, t: Cyc, what: impl Into<String>) {
        if self.events.len() < 10_000 {
            self.events.push((t, what.into()));
        }
    }

    /// Whether the port is open.
    pub fn is_open(&self) -> bool {
        self.open
    }

    /// A program opens (`true`) or closes the serial port: DTR follows once configured.
    pub fn set_open(&mut self, now: Cyc, open: bool) {
        if open == self.open {
            return;
        }
        self.open = open;
        if !open {
            self.host_tx.clear();
        }
        if self.configured {
            self.line_state_requests();
        }
        self.poke(now);
    }

    fn line_state_requests(&mut self) {
        if self.open {
            self.pending.push_back(Req::SetLineCoding);
            self.pending.push_back(Req::LineState(3));
        } else {
            self.pending.push_back(Req::LineState(0));
        }
    }

    /// Pulls the cable out (`false`) or plugs it back in.
    pub fn set_plugged(&mut self, now: Cyc, plugged: bool) {
        if plugged == self.plugged {
            return;
        }
        self.plugged = plugged;
        self.event(now, if plugged { "plugged in" } else { "unplugged" });
        if !plugged {
            self.bus = Bus::Unplugged(now);
            self.forget(now);
            self.next_at = Some(now + cyc_from_ms(3));
        } else {
            self.bus = Bus::Detached;
            self.next_at = Some(now);
        }
    }

    /// The device is gone (unplugged, detached): everything of it is forgotten.
    fn forget(&mut self, now: Cyc) {
        if self.dtr {
            self.event(now, "session lost with the device");
        }
        self.configured = false;
        self.dtr = false;
        self.ctrl = None;
        self.pending.clear();
        self.addr = 0;
    }

    /// The device changed an endpoint or its connection: look again soon.
    pub fn kick(&mut self, now: Cyc) {
        match self.bus {
            Bus::Active if self.waiting => {
                self.waiting = false;
                self.next_at = Some(self.next_at.map_or(now, |t| t.min(now + TURNAROUND)));
            }
            Bus::Detached if self.plugged => self.next_at = Some(now),
            _ => {}
        }
    }

    fn poke(&mut self, now: Cyc) {
        if self.bus == Bus::Active {
            self.waiting = false;
            self.next_at = Some(self.next_at.map_or(now, |t| t.min(now)));
        }
    }

    /// Bytes the program writes to the port.
    pub fn write(&mut self, now: Cyc, bytes: &[u8]) {
        self.host_tx.extend(bytes);
        self.poke(now);
    }

    /// The next time the host does something on its own.
    pub fn next_event(&self) -> Option<Cyc> {
        self.next_at
    }

    /// Runs the bus up to `now`.
    pub fn advance(&mut self, now: Cyc, otg: &mut Otg) {
        if std::mem::take(&mut otg.kicked) {
            self.kick(now);
        }
        let mut guard = 0;
        while let Some(t) = self.next_at.filter(|&t| t <= now) {
            self.step(t, otg);
            guard += 1;
            if guard > 10_000 {
                break;
            }
        }
    }

    fn step(&mut self, t: Cyc, otg: &mut Otg) {
        let present = self.plugged && otg.attached();
        match self.bus {
            Bus::Unplugged(_) => {
                otg.suspend();
                self.bus = Bus::Detached;
                self.next_at = None;
            }
            Bus::Detached => {
                if present {
                    self.event(t, "device attached (D+ pull-up)");
                    self.bus = Bus::Debounce(t + cyc_from_ms(100));
                    self.next_at = Some(t + cyc_from_ms(100));
                } else {
                    self.next_at = None;
                }
            }
            Bus::Debounce(_) if !present => self.detach(t),
            Bus::Debounce(_) => {
                self.event(t, "bus reset");
                self.stats.resets += 1;
                otg.bus_reset();
                self.forget(t);
                self.bus = Bus::Reset(t + cyc_from_ms(10));
                self.next_at = Some(t + cyc_from_ms(10));
            }
            Bus::Reset(_) => {
                otg.reset_done();
                self.bus = Bus::Recovery(t + cyc_from_ms(10));
                self.next_frame = t;
                self.next_at = Some(t + cyc_from_ms(10));
            }
            Bus::Recovery(_) => {
                self.bus = Bus::Active;
                self.device = None;
                self.string_ids.clear();
                self.pending
                    .extend([Req::Device(64), Req::SetAddress, Req::Device(18)]);
                self.waiting = false;
                self.next_at = Some(t);
            }
            Bus::Active if !present => self.detach(t),
            Bus::Active => self.active(t, otg),
        }
    }

    fn detach(&mut self, t: Cyc) {
        self.event(t, "device detached");
        self.forget(t);
        self.bus = Bus::Detached;
        self.next_at = None;
    }

    /// One turn of an active bus: the frame's SOF when due, then one transaction.
    fn active(&mut self, t: Cyc, otg: &mut Otg) {
        while self.next_frame <= t {
            otg.sof(self.frame);
            self.frame = self.frame.wrapping_add(1);
            self.next_frame += cyc_from_ms(1);
        }
        if t < self.quiet_until {
            self.next_at = Some(self.quiet_until);
            return;
        }
        let busy = if self.ctrl.is_some() || !self.pending.is_empty() {
            self.control(t, otg)
        } else if self.configured && self.open {
            self.bulk(t, otg)
        } else {
            None
        };
        match busy {
            Some(dt) => {
                self.waiting = false;
                self.next_at = Some(t + dt);
            }
            None => {
                self.waiting = true;
                let mut next = self.next_frame;
                if let Some(c) = &self.ctrl {
                    next = next.min(c.since + CTRL_TIMEOUT);
                }
                self.next_at = Some(next);
            }
        }
    }

    /// One bulk transaction (OUT and IN take turns); None when there is nothing to do or the
    /// device NAKed.
    fn bulk(&mut self, t: Cyc, otg: &mut Otg) -> Option<Cyc> {
        let d = self.device.clone()?;
        for _ in 0..2 {
            self.turn_in = !self.turn_in;
            if !self.turn_in {
                if self.host_tx.is_empty() {
                    continue;
                }
                let n = self.host_tx.len().min(PACKET).min(usize::from(d.bulk_size));
                let chunk: Vec<u8> = self.host_tx.iter().take(n).copied().collect();
                match otg.out(self.addr, usize::from(d.bulk_out), &chunk) {
                    Handshake::Ack => {
                        self.host_tx.drain(..n);
                        self.stats.out_packets += 1;
                        self.stats.out_bytes += n as u64;
                        return Some(bus_time(n));
                    }
                    Handshake::Nak => self.stats.out_naks += 1,
                    h => self.bulk_error(t, "OUT", h),
                }
            } else {
                match otg.input(self.addr, usize::from(d.bulk_in)) {
                    Ok(p) => {
                        let end = t + bus_time(p.len());
                        self.rx_log.extend(p.iter().map(|&b| (end, b)));
                        self.stats.in_packets += 1;
                        self.stats.in_bytes += p.len() as u64;
                        return Some(bus_time(p.len()));
                    }
                    Err(Handshake::Nak) => {}
                    Err(h) => self.bulk_error(t, "IN", h),
                }
            }
        }
        None
    }

    fn bulk_error(&mut self, t: Cyc, dir: &str, h: Handshake) {
        let what = format!("bulk {dir}: {h:?}");
        if !self.errors.contains(&what) {
            self.event(t, what.clone());
            self.errors.push(what);
        }
    }
}

mod control;
use control::{Ctrl, Req};
