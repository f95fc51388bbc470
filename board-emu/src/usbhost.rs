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

/// A standard or class request the host makes.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Req {
    /// GET_DESCRIPTOR(DEVICE) of this length.
    Device(u16),
    SetAddress,
    /// GET_DESCRIPTOR(CONFIGURATION) of this length (9, then wTotalLength).
    Config(u16),
    /// GET_DESCRIPTOR(STRING) index, language.
    Str(u8, u16),
    SetConfiguration,
    SetLineCoding,
    /// SET_CONTROL_LINE_STATE with this bitmap (DTR bit 0, RTS bit 1).
    LineState(u16),
}

impl Req {
    /// Its SETUP packet and the data stage's direction and length (USB 2.0 table 9-2; CDC
    /// PSTN 1.2 §6.3.10, §6.3.12).
    fn setup(&self, comm_if: u16) -> ([u8; 8], Vec<u8>) {
        let s = |rt: u8, r: u8, v: u16, i: u16, l: u16| {
            let [v0, v1] = v.to_le_bytes();
            let [i0, i1] = i.to_le_bytes();
            let [l0, l1] = l.to_le_bytes();
            [rt, r, v0, v1, i0, i1, l0, l1]
        };
        match *self {
            Req::Device(l) => (s(0x80, 6, 0x0100, 0, l), Vec::new()),
            Req::SetAddress => (s(0x00, 5, u16::from(ADDRESS), 0, 0), Vec::new()),
            Req::Config(l) => (s(0x80, 6, 0x0200, 0, l), Vec::new()),
            Req::Str(i, lang) => (s(0x80, 6, 0x0300 | u16::from(i), lang, 255), Vec::new()),
            Req::SetConfiguration => (s(0x00, 9, 1, 0, 0), Vec::new()),
            Req::SetLineCoding => {
                let mut d = 115_200u32.to_le_bytes().to_vec();
                d.extend_from_slice(&[0, 0, 8]);
                (s(0x21, 0x20, 0, comm_if, 7), d)
            }
            Req::LineState(v) => (s(0x21, 0x22, v, comm_if, 0), Vec::new()),
        }
    }
}

/// Where a control transfer is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Setup,
    DataIn,
    DataOut,
    /// The handshake: an IN zero-length packet (no data or OUT data) or an OUT one.
    StatusIn,
    StatusOut,
}

#[derive(Clone, Debug)]
struct Ctrl {
    req: Req,
    setup: [u8; 8],
    stage: Stage,
    got: Vec<u8>,
    out: Vec<u8>,
    sent: usize,
    since: Cyc,
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

    /// One control transaction; the bus time it took, or None when the device NAKed.
    fn control(&mut self, t: Cyc, otg: &mut Otg) -> Option<Cyc> {
        if self.ctrl.is_none() {
            let req = self.pending.pop_front()?;
            let comm = self
                .device
                .as_ref()
                .map_or(0, |d| u16::from(d.comm_interface));
            let (setup, out) = req.setup(comm);
            self.ctrl = Some(Ctrl {
                req,
                setup,
                stage: Stage::Setup,
                got: Vec::new(),
                out,
                sent: 0,
                since: t,
            });
        }
        let mut c = self.ctrl.take()?;
        if t >= c.since + CTRL_TIMEOUT {
            self.fail(t, &c.req, "timed out");
            return Some(bus_time(0));
        }
        let wlen = usize::from(u16::from_le_bytes([c.setup[6], c.setup[7]]));
        // Before the device descriptor is known, 64 (Linux's first GET_DESCRIPTOR on a
        // full-speed device asks for 64 bytes with a 64-byte packet).
        let mps = self
            .device
            .as_ref()
            .map_or(64, |d| usize::from(d.ep0_size.max(8)));
        let dir_in = c.setup[0] & 0x80 != 0;
        let (hs, bytes) = match c.stage {
            Stage::Setup => {
                let hs = otg.setup(self.addr, c.setup);
                if hs == Handshake::Ack {
                    c.stage = match (wlen, dir_in) {
                        (0, _) => Stage::StatusIn,
                        (_, true) => Stage::DataIn,
                        (_, false) => Stage::DataOut,
                    };
                }
                (hs, 8)
            }
            Stage::DataIn => match otg.input(self.addr, 0) {
                Ok(p) => {
                    let n = p.len();
                    c.got.extend_from_slice(&p);
                    if n < mps || c.got.len() >= wlen {
                        c.got.truncate(wlen);
                        c.stage = Stage::StatusOut;
                    }
                    (Handshake::Ack, n)
                }
                Err(h) => (h, 0),
            },
            Stage::DataOut => {
                let end = (c.sent + mps).min(c.out.len());
                let n = end - c.sent;
                let hs = otg.out(self.addr, 0, &c.out[c.sent..end]);
                if hs == Handshake::Ack {
                    c.sent = end;
                    if c.sent >= c.out.len() {
                        c.stage = Stage::StatusIn;
                    }
                }
                (hs, n)
            }
            Stage::StatusIn => match otg.input(self.addr, 0) {
                Ok(_) => {
                    self.done(t, c, otg);
                    return Some(bus_time(0));
                }
                Err(h) => (h, 0),
            },
            Stage::StatusOut => {
                let hs = otg.out(self.addr, 0, &[]);
                if hs == Handshake::Ack {
                    self.done(t, c, otg);
                    return Some(bus_time(0));
                }
                (hs, 0)
            }
        };
        match hs {
            Handshake::Ack => {
                self.ctrl = Some(c);
                Some(bus_time(bytes))
            }
            Handshake::Nak => {
                self.ctrl = Some(c);
                None
            }
            Handshake::Stall => {
                self.fail(t, &c.req, "STALL");
                Some(bus_time(0))
            }
            Handshake::Timeout => {
                // No answer: tried again on the next frame until the transfer times out.
                self.ctrl = Some(c);
                None
            }
        }
    }

    fn fail(&mut self, t: Cyc, req: &Req, why: &str) {
        let what = format!("{req:?}: {why}");
        self.event(t, format!("request failed: {what}"));
        if self.errors.len() < 100 {
            self.errors.push(what);
        }
        // A failed enumeration step leaves the device unconfigured: stop asking it.
        if !self.configured {
            self.pending.clear();
        }
    }

    /// A control transfer completed: what its answer means.
    fn done(&mut self, t: Cyc, c: Ctrl, otg: &Otg) {
        let _ = otg;
        match c.req {
            Req::Device(_) => {
                let d = &c.got;
                if d.len() < 8 || d[1] != 1 {
                    self.fail(t, &c.req, "not a device descriptor");
                    return;
                }
                let mut info = self.device.take().unwrap_or_default();
                info.ep0_size = d[7];
                if c.req == Req::Device(18) && d.len() >= 18 {
                    info.vid_pid = (
                        u16::from_le_bytes([d[8], d[9]]),
                        u16::from_le_bytes([d[10], d[11]]),
                    );
                    self.string_ids = [d[14], d[15], d[16]].to_vec();
                    self.pending.push_back(Req::Config(9));
                }
                self.device = Some(info);
            }
            Req::SetAddress => {
                self.addr = ADDRESS;
                self.event(t, format!("address {ADDRESS}"));
                self.quiet_until = t + cyc_from_ms(2);
            }
            Req::Config(9) => {
                let total = c
                    .got
                    .get(2..4)
                    .map_or(9, |b| u16::from_le_bytes([b[0], b[1]]));
                self.pending.push_front(Req::Config(total.max(10)));
            }
            Req::Config(_) => {
                if let Err(why) = self.parse_config(&c.got) {
                    self.fail(t, &c.req, &why);
                    return;
                }
                self.pending.push_back(Req::Str(0, 0));
                for i in self.string_ids.clone().into_iter().filter(|&i| i != 0) {
                    self.pending.push_back(Req::Str(i, 0x0409));
                }
                self.pending.push_back(Req::SetConfiguration);
            }
            Req::Str(0, _) => {}
            Req::Str(_, _) => {
                let s = c.got.get(2..).unwrap_or(&[]);
                let units: Vec<u16> = s
                    .chunks_exact(2)
                    .map(|b| u16::from_le_bytes([b[0], b[1]]))
                    .collect();
                if let Some(d) = &mut self.device {
                    d.strings.push(String::from_utf16_lossy(&units));
                }
            }
            Req::SetConfiguration => {
                self.configured = true;
                self.stats.enumerations += 1;
                self.event(t, "configured");
                if self.open {
                    self.line_state_requests();
                }
            }
            Req::SetLineCoding => self.event(t, "line coding 115200 8N1"),
            Req::LineState(v) => {
                self.dtr = v & 1 != 0;
                self.event(
                    t,
                    if self.dtr {
                        "DTR raised"
                    } else {
                        "DTR dropped"
                    },
                );
            }
        }
        self.ctrl = None;
    }

    /// Finds the CDC ACM function in a configuration descriptor.
    fn parse_config(&mut self, d: &[u8]) -> Result<(), String> {
        let mut comm = None;
        let mut in_data_if = false;
        let (mut bulk_in, mut bulk_out, mut size) = (None, None, 0);
        let mut i = 0;
        while i + 2 <= d.len() {
            let len = usize::from(d[i]);
            if len < 2 || i + len > d.len() {
                return Err(format!("descriptor of length {len} at {i}"));
            }
            let x = &d[i..i + len];
            match x[1] {
                4 if len >= 9 => {
                    // Interface: class 2 subclass 2 (ACM), class 0x0A (CDC data).
                    if x[5] == 2 && x[6] == 2 {
                        comm = Some(x[2]);
                    }
                    in_data_if = x[5] == 0x0A;
                }
                5 if len >= 7 && in_data_if && x[3] & 3 == 2 => {
                    size = u16::from_le_bytes([x[4], x[5]]);
                    if x[2] & 0x80 != 0 {
                        bulk_in = Some(x[2] & 0xF);
                    } else {
                        bulk_out = Some(x[2] & 0xF);
                    }
                }
                _ => {}
            }
            i += len;
        }
        let (Some(c), Some(bi), Some(bo)) = (comm, bulk_in, bulk_out) else {
            return Err("no CDC ACM function".into());
        };
        let info = self.device.get_or_insert_with(Default::default);
        info.comm_interface = c;
        info.bulk_in = bi;
        info.bulk_out = bo;
        info.bulk_size = size;
        Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_laid_out_as_chapter_9_says() {
        let (s, d) = Req::Device(18).setup(0);
        assert_eq!(s, [0x80, 6, 0, 1, 0, 0, 18, 0]);
        assert!(d.is_empty());
        let (s, d) = Req::SetLineCoding.setup(2);
        assert_eq!(s, [0x21, 0x20, 0, 0, 2, 0, 7, 0]);
        assert_eq!(d, vec![0x00, 0xC2, 0x01, 0x00, 0, 0, 8]);
        let (s, _) = Req::LineState(3).setup(2);
        assert_eq!(s, [0x21, 0x22, 3, 0, 2, 0, 0, 0]);
    }

    #[test]
    fn a_cdc_acm_configuration_is_found() {
        // embassy-usb's CDC ACM layout: IAD, comm interface 0 (class 2/2) with its
        // functional descriptors and interrupt endpoint 0x81, data interface 1 (0x0A) with
        // bulk 0x02 OUT and 0x82 IN of 64 bytes.
        let d = [
            9, 2, 75, 0, 2, 1, 0, 0x80, 50, // configuration
            8, 11, 0, 2, 2, 2, 1, 0, // IAD
            9, 4, 0, 0, 1, 2, 2, 1, 0, // comm interface
            5, 0x24, 0, 0x10, 1, // header
            4, 0x24, 2, 2, // ACM
            5, 0x24, 6, 0, 1, // union
            5, 0x24, 1, 0, 1, // call management
            7, 5, 0x81, 3, 8, 0, 255, // notification
            9, 4, 1, 0, 2, 0x0A, 0, 0, 0, // data interface
            7, 5, 0x02, 2, 64, 0, 0, // bulk OUT
            7, 5, 0x82, 2, 64, 0, 0, // bulk IN
        ];
        let mut h = UsbHost::new(true);
        h.parse_config(&d).unwrap();
        let info = h.device.unwrap();
        assert_eq!(
            (
                info.comm_interface,
                info.bulk_in,
                info.bulk_out,
                info.bulk_size
            ),
            (0, 2, 2, 64)
        );
        let mut h = UsbHost::new(true);
        assert!(h.parse_config(&d[..40]).is_err());
    }
}
