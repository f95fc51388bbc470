//! The host's control transfers (USB 2.0 §8.5.3, §9.3): the requests it makes to enumerate
//! and configure the device and to drive the CDC ACM line (SET_LINE_CODING,
//! SET_CONTROL_LINE_STATE), each carried through its setup, data and status stages, and what
//! each answer means (the device descriptor, the configuration with its CDC ACM function, the
//! strings).

use super::*;

/// A standard or class request the host makes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum Req {
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
pub(super) enum Stage {
    Setup,
    DataIn,
    DataOut,
    /// The handshake: an IN zero-length packet (no data or OUT data) or an OUT one.
    StatusIn,
    StatusOut,
}

#[derive(Clone, Debug)]
pub(super) struct Ctrl {
    req: Req,
    setup: [u8; 8],
    stage: Stage,
    got: Vec<u8>,
    out: Vec<u8>,
    sent: usize,
    pub(super) since: Cyc,
}

impl UsbHost {
    /// One control transaction; the bus time it took, or None when the device NAKed.
    pub(super) fn control(&mut self, t: Cyc, otg: &mut Otg) -> Option<Cyc> {
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
