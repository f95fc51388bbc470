//! The device's side of each bus transaction the host makes (RM0090 §34.17.6, "Operational
//! model", device mode): SETUP, OUT with data, IN, bus reset and its end, SOF, suspend. See
//! the parent module for what each one does to the registers and FIFOs.

use super::*;

impl Otg {
    fn active_in(&self, n: usize) -> bool {
        n == 0 || self.ins[n].ctl & USBAEP != 0
    }

    fn active_out(&self, n: usize) -> bool {
        n == 0 || self.outs[n].ctl & USBAEP != 0
    }

    /// The host drives a bus reset (SE0 ≥ 10 ms): USBRST; endpoints 1..3 deactivated.
    pub fn bus_reset(&mut self) {
        self.gintsts |= USBRST;
        self.old_address = None;
        self.suspended = false;
        self.enumerated = false;
        for ep in self.ins.iter_mut().skip(1) {
            ep.ctl &= !USBAEP;
            ep.enabled = false;
            ep.nak = true;
        }
        for ep in self.outs.iter_mut().skip(1) {
            ep.ctl &= !USBAEP;
            ep.enabled = false;
            ep.nak = true;
        }
    }

    /// The end of the bus reset: the speed is known (ENUMDNE, DSTS.ENUMSPD = full speed).
    pub fn reset_done(&mut self) {
        self.gintsts |= ENUMDNE;
        self.enumerated = true;
    }

    /// Start of frame `frame` (SOF; the frame number in DSTS.FNSOF). Bus activity after a
    /// suspend is a wake-up (WKUPINT).
    pub fn sof(&mut self, frame: u32) {
        if self.suspended {
            self.suspended = false;
            self.gintsts |= WKUPINT;
        }
        self.frame = frame & 0x3FFF;
        self.gintsts |= SOF;
    }

    /// Three milliseconds without bus activity: ESUSP, USBSUSP (§34.17.5 "Suspend").
    pub fn suspend(&mut self) {
        if !self.suspended {
            self.suspended = true;
            self.gintsts |= ESUSP | USBSUSP;
        }
    }

    fn addressed(&mut self, addr: u8) -> bool {
        if !self.attached() {
            return false;
        }
        if addr == self.address() {
            self.old_address = None;
            return true;
        }
        self.old_address == Some(addr)
    }

    /// A SETUP transaction to EP0 at `addr` with its 8 bytes.
    pub fn setup(&mut self, addr: u8, data: [u8; 8]) -> Handshake {
        if !self.addressed(addr) {
            return Handshake::Timeout;
        }
        if self.rx_used_words() + 4 > self.rx_depth() {
            // The core keeps room for SETUP packets (the application sizes RXFD with it);
            // none here: the packet is lost, the host sees no handshake.
            self.note("SETUP packet with the receive FIFO full");
            return Handshake::Timeout;
        }
        let w0 = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
        let w1 = u32::from_le_bytes([data[4], data[5], data[6], data[7]]);
        self.rx.push_back(RxEntry {
            status: (SETUP_DATA << 17) | (8 << 4),
            data: vec![w0, w1],
        });
        self.rx.push_back(RxEntry {
            status: SETUP_DONE << 17,
            data: Vec::new(),
        });
        let t = &mut self.outs[0].tsiz;
        let cnt = (*t >> 29) & 3;
        *t = (*t & !(3 << 29)) | (cnt.saturating_sub(1) << 29);
        for ctl in [&mut self.ins[0].ctl, &mut self.outs[0].ctl] {
            *ctl &= !STALL;
        }
        self.ins[0].nak = true;
        self.outs[0].nak = true;
        Handshake::Ack
    }

    /// An OUT transaction to endpoint `n` at `addr` with `data`.
    pub fn out(&mut self, addr: u8, n: usize, data: &[u8]) -> Handshake {
        if !self.addressed(addr) || n >= ENDPOINTS || !self.active_out(n) {
            return Handshake::Timeout;
        }
        if self.outs[n].ctl & STALL != 0 {
            return Handshake::Stall;
        }
        let words = data.len().div_ceil(4) as u32;
        if self.outs[n].nak
            || self.dctl & (1 << 9) != 0
            || self.rx_used_words() + words + 2 > self.rx_depth()
        {
            return Handshake::Nak;
        }
        let mps = self.out_mps(n).max(1);
        self.rx.push_back(RxEntry {
            status: (OUT_DATA << 17) | ((data.len() as u32) << 4) | n as u32,
            data: data
                .chunks(4)
                .map(|c| {
                    let mut b = [0u8; 4];
                    b[..c.len()].copy_from_slice(c);
                    u32::from_le_bytes(b)
                })
                .collect(),
        });
        let ep = &mut self.outs[n];
        let (xfr_mask, cnt_mask) = if n == 0 {
            (0x7F, 1 << 19)
        } else {
            (0x7_FFFF, 0x3FF << 19)
        };
        let xfr = (ep.tsiz & xfr_mask).saturating_sub(data.len() as u32);
        let cnt = ((ep.tsiz & cnt_mask) >> 19).saturating_sub(1);
        ep.tsiz = (ep.tsiz & !(xfr_mask | cnt_mask)) | xfr | (cnt << 19);
        if cnt == 0 || (data.len() as u32) < mps {
            self.rx.push_back(RxEntry {
                status: (OUT_DONE << 17) | n as u32,
                data: Vec::new(),
            });
            let ep = &mut self.outs[n];
            ep.enabled = false;
            ep.nak = true;
        }
        Handshake::Ack
    }

    /// An IN transaction to endpoint `n` at `addr`: the packet, or why not.
    pub fn input(&mut self, addr: u8, n: usize) -> Result<Vec<u8>, Handshake> {
        if !self.addressed(addr) || n >= ENDPOINTS || !self.active_in(n) {
            return Err(Handshake::Timeout);
        }
        if self.ins[n].ctl & STALL != 0 {
            return Err(Handshake::Stall);
        }
        let mps = self.in_mps(n).max(1);
        let ep = &mut self.ins[n];
        if !ep.enabled || ep.nak {
            return Err(Handshake::Nak);
        }
        let (xfr_mask, cnt_mask) = if n == 0 {
            (0x7F, 3 << 19)
        } else {
            (0x7_FFFF, 0x3FF << 19)
        };
        let left = ep.tsiz & xfr_mask;
        let len = left.min(mps) as usize;
        let words = len.div_ceil(4);
        if ep.fifo.len() < words {
            // The application has not written the whole packet yet.
            return Err(Handshake::Nak);
        }
        let mut packet: Vec<u8> = ep.fifo.drain(..words).flat_map(u32::to_le_bytes).collect();
        packet.truncate(len);
        let cnt = ((ep.tsiz & cnt_mask) >> 19).saturating_sub(1);
        ep.tsiz = (ep.tsiz & !(xfr_mask | cnt_mask)) | (left - len as u32) | (cnt << 19);
        if cnt == 0 {
            ep.enabled = false;
            ep.int |= XFRC;
        }
        Ok(packet)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The core as embassy's driver leaves it after its bus-reset handling: FIFOs sized,
    /// EP0 configured, interrupts unmasked, attached.
    fn configured() -> Otg {
        let mut o = Otg::default();
        o.reset();
        o.write(0x038, 1 << 16); // PWRDWN
        o.write(0x024, 64 + 30);
        o.write(0x028, (16 << 16) | 94);
        o.write(0x104, (16 << 16) | 110);
        o.write(0x008, 1);
        o.write(0x018, USBRST | ENUMDNE | (1 << 4) | IEPINT | OEPINT);
        o.write(0x810, 1);
        o.write(0x814, 1 << 3);
        o.write(0x81C, 0x0003_0003);
        o
    }

    #[test]
    fn setup_goes_to_the_receive_fifo_and_sets_stup_when_popped() {
        let mut o = configured();
        assert!(o.attached());
        assert_eq!(o.setup(0, [0x80, 6, 0, 1, 0, 0, 64, 0]), Handshake::Ack);
        assert!(o.irq(), "RXFLVL");
        let st = o.read(0x020);
        assert_eq!((st >> 17) & 0xF, SETUP_DATA);
        assert_eq!((st >> 4) & 0x7FF, 8);
        assert_eq!(o.read(0x1000), 0x0100_0680);
        assert_eq!(o.read(0x1000), 0x0040_0000);
        let st = o.read(0x020);
        assert_eq!((st >> 17) & 0xF, SETUP_DONE);
        assert_eq!(o.read(0xB08) & STUP, STUP);
        assert_ne!(o.read(0x014) & OEPINT, 0);
        // Another address: no answer.
        assert_eq!(o.setup(5, [0; 8]), Handshake::Timeout);
    }

    #[test]
    fn out_is_nakked_until_the_nak_is_cleared_then_completes() {
        let mut o = configured();
        o.write(0xB20, USBAEP | 64 | (2 << 18)); // EP1 OUT bulk, 64 bytes
        o.write(0xB30, (1 << 19) | 64);
        assert_eq!(o.out(0, 1, b"G28\n"), Handshake::Nak);
        o.write(0xB20, USBAEP | 64 | (2 << 18) | CNAK | EPENA);
        assert_eq!(o.out(0, 1, b"G28\n"), Handshake::Ack);
        // Short packet: the transfer completed, NAK set until the application clears it.
        assert_eq!(o.out(0, 1, b"M105\n"), Handshake::Nak);
        let st = o.read(0x020);
        assert_eq!(
            ((st >> 17) & 0xF, (st >> 4) & 0x7FF, st & 0xF),
            (OUT_DATA, 4, 1)
        );
        assert_eq!(o.read(0x2000), u32::from_le_bytes(*b"G28\n"));
        let st = o.read(0x020);
        assert_eq!((st >> 17) & 0xF, OUT_DONE);
        assert_eq!(o.read(0xB28) & XFRC, XFRC);
        // Re-armed with CNAK alone (as embassy 0.3 does): taken again.
        o.write(0xB30, (1 << 19) | 64);
        o.write(0xB20, USBAEP | 64 | (2 << 18) | CNAK);
        assert_eq!(o.out(0, 1, b"M105\n"), Handshake::Ack);
    }

    #[test]
    fn in_waits_for_the_whole_packet_in_the_fifo() {
        let mut o = configured();
        o.write(0x920, USBAEP | 64 | (2 << 18) | (1 << 22)); // EP1 IN bulk
        assert_eq!(o.input(0, 1), Err(Handshake::Nak));
        o.write(0x930, (1 << 19) | 6);
        o.write(0x920, USBAEP | 64 | (2 << 18) | (1 << 22) | CNAK | EPENA);
        o.write(0x2000, u32::from_le_bytes(*b"ok T"));
        assert_eq!(
            o.input(0, 1),
            Err(Handshake::Nak),
            "half the packet written"
        );
        o.write(0x2000, u32::from_le_bytes([b':', b'\n', 0, 0]));
        assert_eq!(o.input(0, 1), Ok(b"ok T:\n".to_vec()));
        assert_eq!(o.read(0x928) & XFRC, XFRC);
        assert_eq!(o.input(0, 1), Err(Handshake::Nak), "transfer done");
        // A stalled endpoint says so.
        o.write(0x920, USBAEP | STALL | 64);
        assert_eq!(o.input(0, 1), Err(Handshake::Stall));
    }

    #[test]
    fn bus_reset_deactivates_the_endpoints() {
        let mut o = configured();
        o.write(0x920, USBAEP | 64);
        o.bus_reset();
        assert_eq!(o.read(0x920) & USBAEP, 0);
        assert_ne!(o.read(0x900) & USBAEP, 0, "EP0 always active");
        assert_ne!(o.read(0x014) & USBRST, 0);
        o.write(0x014, USBRST);
        assert_eq!(o.read(0x014) & USBRST, 0);
        o.reset_done();
        assert_eq!(o.read(0x808) & 6, 6);
    }
}
