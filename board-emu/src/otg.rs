//! USB OTG FS in device mode (RM0090 §34, "USB on-the-go full-speed (OTG_FS)"): the registers
//! the image's driver (embassy-usb-synopsys-otg 0.3, under embassy-stm32 0.6) uses, the shared
//! receive FIFO and the four transmit FIFOs, and the device's side of each bus transaction
//! the emulated host ([`crate::usbhost`]) makes: SETUP, OUT with data, IN, bus reset,
//! suspend.
//!
//! Registers (RM0090 §34.16.6, table 194 "OTG_FS register map and reset values"; each one's
//! description in §34.16.2 "OTG_FS global registers", §34.16.4 "Device-mode registers",
//! §34.16.5 "power and clock gating"):
//!
//! * GOTGCTL 0x000, GOTGINT 0x004 (rc_w1), GAHBCFG 0x008 (GINT bit 0, TXFELVL bit 7: a TX FIFO
//!   interrupt at half empty when 0, empty when 1), GUSBCFG 0x00C (kept), GRSTCTL 0x010 (CSRST
//!   bit 0, RXFFLSH bit 4, TXFFLSH bit 5 with TXFNUM bits 10:6, 0x10 = all: done at once and
//!   self-clearing; AHBIDL bit 31 always set), GINTSTS 0x014, GINTMSK 0x018, GRXSTSR 0x01C /
//!   GRXSTSP 0x020 (read / pop the receive status: EPNUM 3:0, BCNT 14:4, DPID 16:15, PKTSTS
//!   20:17 — 2 OUT data packet received, 3 OUT transfer completed, 4 SETUP transaction
//!   completed, 6 SETUP data packet received), GRXFSIZ 0x024 (RXFD, words), DIEPTXF0 0x028
//!   (TX0FSA 15:0, TX0FD 31:16), GCCFG 0x038 (PWRDWN bit 16: the transceiver on; NOVBUSSENS
//!   bit 21), CID 0x03C (0x0000_1200, the ID embassy looks for), DIEPTXF1..3 0x104..0x10C.
//! * GINTSTS bits: CMOD 0 (0, device), OTGINT 2 (GOTGINT non-zero), SOF 3, RXFLVL 4 (the
//!   receive FIFO holds an entry), GONAKEFF 7, ESUSP 10, USBSUSP 11, USBRST 12, ENUMDNE 13,
//!   EOPF 15, IEPINT 18, OEPINT 19 (from DAINT), SRQINT 30, WKUPINT 31; the latched ones are
//!   cleared by writing 1 (rc_w1), RXFLVL/IEPINT/OEPINT/OTGINT follow their sources. The
//!   interrupt line is GAHBCFG.GINT and any GINTSTS bit set whose GINTMSK bit is set.
//! * DCFG 0x800 (DSPD 1:0, DAD 10:4: the address the device answers), DCTL 0x804 (SDIS bit 1:
//!   soft disconnect, the D+ pull-up off; SGONAK/CGONAK bits 9/10), DSTS 0x808 (SUSPSTS bit 0,
//!   ENUMSPD 2:1 = 3 full speed after the bus reset, FNSOF 21:8), DIEPMSK 0x810, DOEPMSK
//!   0x814, DAINT 0x818 (IEPINT 15:0, OEPINT 31:16: an endpoint's interrupt bits under its
//!   mask), DAINTMSK 0x81C, DIEPEMPMSK 0x834 (TXFE interrupt per IN endpoint).
//! * Per endpoint n = 0..3: DIEPCTLn 0x900+0x20n / DOEPCTLn 0xB00+0x20n (MPSIZ, USBAEP bit 15 —
//!   always 1 on EP0 —, NAKSTS bit 17, EPTYP 19:18, STALL bit 21, TXFNUM 25:22, CNAK bit 26 and
//!   SNAK bit 27 clear and set the NAK, SD0PID/SD1PID 28/29, EPDIS bit 30, EPENA bit 31),
//!   DIEPINTn/DOEPINTn +0x08 (XFRC bit 0, EPDISD bit 1, STUP bit 3 on OUT EP0, INEPNE bit 6,
//!   TXFE bit 7 read-only: the TX FIFO half empty or empty as TXFELVL says; rc_w1),
//!   DIEPTSIZn/DOEPTSIZn +0x10 (XFRSIZ, PKTCNT; STUPCNT bits 30:29 on OUT EP0), DTXFSTSn +0x18
//!   (INEPTFSAV: free words of the TX FIFO).
//! * The data FIFOs at 0x1000 + 0x1000·n: a write pushes a word into IN endpoint n's TX FIFO,
//!   a read pops a word of the receive FIFO (whichever address is read).
//!
//! Behaviour (§34.17.6 "Operational model", device mode):
//!
//! * A SETUP packet to EP0 is always taken (ACK) when addressed to DAD: its 8 bytes and a
//!   "SETUP data packet received" status, then "SETUP transaction completed", go into the
//!   receive FIFO; STUPCNT counts down; the NAK of EP0 IN and OUT is set and their STALL
//!   cleared (a control endpoint's STALL ends with the next SETUP). Popping the "completed"
//!   status sets DOEPINT0.STUP.
//! * An OUT packet is ACKed when its endpoint is active, not STALLed, not NAKing and the
//!   receive FIFO has room for it; else NAK (STALL for a STALLed endpoint). Taken, it goes
//!   into the FIFO with an "OUT data packet received" status; PKTCNT counts down, and when it
//!   reaches 0 or the packet is short the transfer completes: an "OUT transfer completed"
//!   status (its pop sets DOEPINTn.XFRC), EPENA cleared and the NAK set, so the next packet is
//!   NAKed until the application clears it (CNAK) — the flow control the host meets. EPENA
//!   is not required to take a packet: the OTG_FS core of the STM32F4 takes OUT data on an
//!   active endpoint whose NAK is clear, which embassy-usb-synopsys-otg 0.3 relies on (it
//!   re-arms a bulk OUT endpoint with CNAK alone; its later versions set EPENA too, "newer
//!   DWC2 cores clear EPENA after each transfer and NAK everything until it is set again").
//! * An IN token gets a packet when the endpoint is enabled (EPENA), not NAKing and its TX
//!   FIFO holds the whole packet (MPSIZ or what is left of XFRSIZ, zero bytes for a
//!   zero-length packet); else NAK (STALL when STALLed). PKTCNT and XFRSIZ count down; at
//!   PKTCNT 0 the transfer completes: DIEPINTn.XFRC, EPENA cleared.
//! * A bus reset raises USBRST and deactivates endpoints 1..3 (USBAEP, EPENA cleared, NAK
//!   set); its end raises ENUMDNE with ENUMSPD = full speed. Three idle milliseconds on the
//!   bus (the host gone or suspending) raise ESUSP and USBSUSP; bus activity after it WKUPINT.
//!
//! Not modelled: host and OTG modes (HNP, SRP, the host-mode registers), VBUS sensing (the
//! image turns it off), isochronous and interrupt timing (the image's notification endpoint
//! is never written), data toggles (every packet is taken as in sequence), the FIFO RAM's
//! addresses (each FIFO has its configured depth but its own storage), low-power clock gating
//! (PCGCCTL is kept), SOF interrupts' timing beyond the frame count.

use std::collections::VecDeque;

/// Endpoints of the F407's OTG_FS (RM0090 §34.1: "4 bidirectional endpoints").
pub const ENDPOINTS: usize = 4;
/// Its data FIFO RAM, words (RM0090 §34.1: 1.25 Kbytes).
pub const FIFO_WORDS: u32 = 320;

// GINTSTS bits (§34.16.2).
const SOF: u32 = 1 << 3;
const RXFLVL: u32 = 1 << 4;
const OTGINT: u32 = 1 << 2;
const GONAKEFF: u32 = 1 << 7;
const ESUSP: u32 = 1 << 10;
const USBSUSP: u32 = 1 << 11;
const USBRST: u32 = 1 << 12;
const ENUMDNE: u32 = 1 << 13;
const IEPINT: u32 = 1 << 18;
const OEPINT: u32 = 1 << 19;
const WKUPINT: u32 = 1 << 31;
/// GINTSTS bits cleared by writing 1.
const GINTSTS_W1C: u32 =
    (1 << 1) | SOF | ESUSP | USBSUSP | USBRST | ENUMDNE | (0x3 << 14) | (0x3 << 20) | 0xF << 28;

// DxEPCTL bits.
const USBAEP: u32 = 1 << 15;
const NAKSTS: u32 = 1 << 17;
const STALL: u32 = 1 << 21;
const CNAK: u32 = 1 << 26;
const SNAK: u32 = 1 << 27;
const SD0PID: u32 = 1 << 28;
const SD1PID: u32 = 1 << 29;
const EPDIS: u32 = 1 << 30;
const EPENA: u32 = 1 << 31;
/// Bits of DxEPCTL the application writes and reads back (MPSIZ, USBAEP, EPTYP, SNPM,
/// STALL, TXFNUM).
const CTL_KEPT: u32 = 0x7FF | USBAEP | (3 << 18) | (1 << 20) | STALL | (0xF << 22);

// DxEPINT bits.
const XFRC: u32 = 1 << 0;
const EPDISD: u32 = 1 << 1;
const STUP: u32 = 1 << 3;
const INEPNE: u32 = 1 << 6;
const TXFE: u32 = 1 << 7;

// Receive status PKTSTS values (GRXSTSP bits 20:17).
const OUT_DATA: u32 = 2;
const OUT_DONE: u32 = 3;
const SETUP_DONE: u32 = 4;
const SETUP_DATA: u32 = 6;

/// The device's answer to a transaction.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Handshake {
    /// Taken (OUT, SETUP), or a data packet sent (IN).
    Ack,
    /// Not now: the host tries again.
    Nak,
    /// The endpoint is halted.
    Stall,
    /// No answer: not attached, another address, an endpoint that does not exist.
    Timeout,
}

/// An entry of the receive FIFO: its status word and data.
#[derive(Clone, Debug)]
struct RxEntry {
    status: u32,
    data: Vec<u32>,
}

/// One IN endpoint.
#[derive(Clone, Debug, Default)]
struct InEp {
    ctl: u32,
    nak: bool,
    enabled: bool,
    int: u32,
    tsiz: u32,
    fifo: VecDeque<u32>,
    /// TX FIFO depth, words.
    depth: u32,
}

/// One OUT endpoint.
#[derive(Clone, Debug, Default)]
struct OutEp {
    ctl: u32,
    nak: bool,
    enabled: bool,
    int: u32,
    tsiz: u32,
}

/// The OTG_FS core in device mode.
#[derive(Clone, Debug, Default)]
pub struct Otg {
    gotgctl: u32,
    gotgint: u32,
    gahbcfg: u32,
    gusbcfg: u32,
    gintsts: u32,
    gintmsk: u32,
    grxfsiz: u32,
    dieptxf0: u32,
    dieptxf: [u32; 3],
    gccfg: u32,
    dcfg: u32,
    /// The address before the last change of DAD: still answered until the host uses the
    /// new one (the application sets DAD before SET_ADDRESS's status stage, which the host
    /// makes at the old address: USB 2.0 §9.4.6).
    old_address: Option<u8>,
    dctl: u32,
    suspended: bool,
    enumerated: bool,
    frame: u32,
    diepmsk: u32,
    doepmsk: u32,
    daintmsk: u32,
    diepempmsk: u32,
    pcgcctl: u32,
    ins: [InEp; ENDPOINTS],
    outs: [OutEp; ENDPOINTS],
    rx: VecDeque<RxEntry>,
    /// Data words of the popped receive entry, read through the FIFO addresses.
    rx_words: VecDeque<u32>,
    /// The application changed something the host may be waiting for (an endpoint armed,
    /// a NAK cleared, data written, the pull-up switched): the host looks again at once.
    pub kicked: bool,
    /// Oddities the application did (for the report's notes).
    pub notes: Vec<String>,
}

impl Otg {
    /// The core after a reset of the chip (RCC: registers at their reset values).
    pub fn reset(&mut self) {
        *self = Otg::default();
        self.reset_endpoints();
    }

    fn reset_endpoints(&mut self) {
        for ep in self.ins.iter_mut() {
            ep.nak = true;
        }
        for ep in self.outs.iter_mut() {
            ep.nak = true;
        }
    }

    /// D+ pulled up: the transceiver is on (GCCFG.PWRDWN) and the device not soft
    /// disconnected (DCTL.SDIS), in device mode (GUSBCFG.FDMOD, or not forced host).
    pub fn attached(&self) -> bool {
        self.gccfg & (1 << 16) != 0 && self.dctl & 2 == 0 && self.gusbcfg & (1 << 29) == 0
    }

    /// The device's address (DCFG.DAD).
    pub fn address(&self) -> u8 {
        ((self.dcfg >> 4) & 0x7F) as u8
    }

    fn rx_used_words(&self) -> u32 {
        self.rx.iter().map(|e| 1 + e.data.len() as u32).sum::<u32>() + self.rx_words.len() as u32
    }

    fn rx_depth(&self) -> u32 {
        self.grxfsiz & 0xFFFF
    }

    fn in_mps(&self, n: usize) -> u32 {
        let m = self.ins[n].ctl & 0x7FF;
        if n == 0 {
            ep0_mps(m)
        } else {
            m
        }
    }

    fn out_mps(&self, n: usize) -> u32 {
        let m = self.outs[n].ctl & 0x7FF;
        if n == 0 {
            ep0_mps(m)
        } else {
            m
        }
    }

    /// TXFE: the TX FIFO half empty (GAHBCFG.TXFELVL = 0) or empty (1).
    fn txfe(&self, n: usize) -> bool {
        let ep = &self.ins[n];
        let used = ep.fifo.len() as u32;
        if self.gahbcfg & (1 << 7) != 0 {
            used == 0
        } else {
            used <= ep.depth / 2
        }
    }

    fn diepint(&self, n: usize) -> u32 {
        self.ins[n].int | if self.txfe(n) { TXFE } else { 0 }
    }

    /// DAINT: each endpoint's interrupt bits under DIEPMSK/DOEPMSK (TXFE under DIEPEMPMSK).
    fn daint(&self) -> u32 {
        let mut v = 0;
        for n in 0..ENDPOINTS {
            let i = self.diepint(n);
            let txfe = i & TXFE != 0 && self.diepempmsk & (1 << n) != 0;
            if i & self.diepmsk & 0x7F != 0 || txfe {
                v |= 1 << n;
            }
            if self.outs[n].int & self.doepmsk != 0 {
                v |= 1 << (16 + n);
            }
        }
        v
    }

    fn gintsts(&self) -> u32 {
        let mut v = self.gintsts;
        if !self.rx.is_empty() {
            v |= RXFLVL;
        }
        if self.gotgint != 0 {
            v |= OTGINT;
        }
        if self.dctl & (1 << 9) != 0 {
            v |= GONAKEFF;
        }
        let d = self.daint() & self.daintmsk;
        if d & 0xFFFF != 0 {
            v |= IEPINT;
        }
        if d >> 16 != 0 {
            v |= OEPINT;
        }
        v
    }

    /// The interrupt line (OTG_FS global interrupt, position 67).
    pub fn irq(&self) -> bool {
        self.gahbcfg & 1 != 0 && self.gintsts() & self.gintmsk != 0
    }

    fn ctl_read(ep_ctl: u32, nak: bool, enabled: bool, ep0: bool) -> u32 {
        let mut v = ep_ctl & CTL_KEPT;
        if ep0 {
            v |= USBAEP;
        }
        if nak {
            v |= NAKSTS;
        }
        if enabled {
            v |= EPENA;
        }
        v
    }

    /// A register read at `off` from 0x5000_0000.
    pub fn read(&mut self, off: u32) -> u32 {
        match off {
            0x000 => self.gotgctl,
            0x004 => self.gotgint,
            0x008 => self.gahbcfg,
            0x00C => self.gusbcfg,
            0x010 => 1 << 31,
            0x014 => self.gintsts(),
            0x018 => self.gintmsk,
            0x01C => self.rx.front().map_or(0, |e| e.status),
            0x020 => self.pop_rx(),
            0x024 => self.grxfsiz,
            0x028 => self.dieptxf0,
            0x038 => self.gccfg,
            0x03C => 0x0000_1200,
            0x104..=0x10C => self.dieptxf[((off - 0x104) / 4) as usize],
            0x800 => self.dcfg,
            0x804 => self.dctl & !(0xF << 7),
            0x808 => {
                u32::from(self.suspended)
                    | if self.enumerated { 3 << 1 } else { 0 }
                    | (self.frame & 0x3FFF) << 8
            }
            0x810 => self.diepmsk,
            0x814 => self.doepmsk,
            0x818 => self.daint(),
            0x81C => self.daintmsk,
            0x834 => self.diepempmsk,
            0x900..=0x97F => {
                let n = ((off - 0x900) / 0x20) as usize;
                let ep = &self.ins[n];
                match off & 0x1F {
                    0x00 => Self::ctl_read(ep.ctl, ep.nak, ep.enabled, n == 0),
                    0x08 => self.diepint(n),
                    0x10 => ep.tsiz,
                    0x18 => ep.depth.saturating_sub(ep.fifo.len() as u32),
                    _ => 0,
                }
            }
            0xB00..=0xB7F => {
                let n = ((off - 0xB00) / 0x20) as usize;
                let ep = &self.outs[n];
                match off & 0x1F {
                    0x00 => Self::ctl_read(ep.ctl, ep.nak, ep.enabled, n == 0),
                    0x08 => ep.int,
                    0x10 => ep.tsiz,
                    _ => 0,
                }
            }
            0xE00 => self.pcgcctl,
            0x1000..=0x3_FFFF => match self.rx_words.pop_front() {
                Some(w) => w,
                None => {
                    self.note("receive FIFO read with no data popped");
                    0
                }
            },
            _ => 0,
        }
    }

    fn note(&mut self, what: &str) {
        if self.notes.len() < 20 && !self.notes.iter().any(|n| n == what) {
            self.notes.push(what.to_string());
        }
    }

    /// GRXSTSP: pops the receive status; its data follow through the FIFO address. Popping
    /// "SETUP transaction completed" sets STUP, "OUT transfer completed" XFRC (§34.17.6).
    fn pop_rx(&mut self) -> u32 {
        let Some(e) = self.rx.pop_front() else {
            return 0;
        };
        if !self.rx_words.is_empty() {
            self.note("receive status popped before the previous packet's data were read");
        }
        self.rx_words = e.data.into();
        let n = (e.status & 0xF) as usize % ENDPOINTS;
        match (e.status >> 17) & 0xF {
            SETUP_DONE => self.outs[0].int |= STUP,
            OUT_DONE => self.outs[n].int |= XFRC,
            _ => {}
        }
        e.status
    }

    /// A register write at `off` from 0x5000_0000.
    pub fn write(&mut self, off: u32, v: u32) {
        match off {
            0x000 => self.gotgctl = v,
            0x004 => self.gotgint &= !v,
            0x008 => self.gahbcfg = v,
            0x00C => self.gusbcfg = v,
            0x010 => {
                if v & (1 << 4) != 0 {
                    self.rx.clear();
                    self.rx_words.clear();
                }
                if v & (1 << 5) != 0 {
                    let n = (v >> 6) & 0x1F;
                    for (i, ep) in self.ins.iter_mut().enumerate() {
                        if n == 0x10 || n as usize == i {
                            ep.fifo.clear();
                        }
                    }
                }
                if v & 1 != 0 {
                    // Core soft reset: the interrupt state and the FIFOs' content.
                    self.gintsts = 0;
                    self.rx.clear();
                    self.rx_words.clear();
                    for ep in self.ins.iter_mut() {
                        ep.fifo.clear();
                    }
                }
            }
            0x014 => self.gintsts &= !(v & GINTSTS_W1C),
            0x018 => self.gintmsk = v,
            0x024 => self.grxfsiz = v & 0xFFFF,
            0x028 => {
                self.dieptxf0 = v;
                self.ins[0].depth = v >> 16;
            }
            0x038 => {
                self.gccfg = v;
                self.kicked = true;
            }
            0x104..=0x10C => {
                let i = ((off - 0x104) / 4) as usize;
                self.dieptxf[i] = v;
                self.ins[i + 1].depth = v >> 16;
            }
            0x800 => {
                let old = self.address();
                self.dcfg = v;
                if self.address() != old {
                    self.old_address = Some(old);
                }
            }
            0x804 => {
                // SGONAK/CGONAK (bits 9/10) set and clear the global OUT NAK.
                let mut d = v & !(0xF << 7);
                if v & (1 << 9) != 0 {
                    d |= 1 << 9;
                } else if v & (1 << 10) == 0 {
                    d |= self.dctl & (1 << 9);
                }
                self.dctl = d;
                self.kicked = true;
            }
            0x810 => self.diepmsk = v,
            0x814 => self.doepmsk = v,
            0x81C => self.daintmsk = v,
            0x834 => self.diepempmsk = v,
            0x900..=0x97F => {
                let n = ((off - 0x900) / 0x20) as usize;
                match off & 0x1F {
                    0x00 => self.write_in_ctl(n, v),
                    0x08 => self.ins[n].int &= !v,
                    0x10 => self.ins[n].tsiz = v,
                    _ => {}
                }
            }
            0xB00..=0xB7F => {
                let n = ((off - 0xB00) / 0x20) as usize;
                match off & 0x1F {
                    0x00 => self.write_out_ctl(n, v),
                    0x08 => self.outs[n].int &= !v,
                    0x10 => self.outs[n].tsiz = v,
                    _ => {}
                }
            }
            0xE00 => self.pcgcctl = v,
            0x1000..=0x3_FFFF => {
                let n = ((off - 0x1000) / 0x1000) as usize;
                if n < ENDPOINTS {
                    let ep = &mut self.ins[n];
                    if (ep.fifo.len() as u32) < ep.depth.max(1) {
                        ep.fifo.push_back(v);
                    } else {
                        self.note("TX FIFO written past its depth (word dropped)");
                    }
                    self.kicked = true;
                }
            }
            _ => {}
        }
    }

    fn write_in_ctl(&mut self, n: usize, v: u32) {
        let ep = &mut self.ins[n];
        if ctl_write(&mut ep.ctl, &mut ep.nak, &mut ep.enabled, &mut ep.int, v) {
            ep.int |= INEPNE;
        }
        self.kicked = true;
    }

    fn write_out_ctl(&mut self, n: usize, v: u32) {
        let ep = &mut self.outs[n];
        ctl_write(&mut ep.ctl, &mut ep.nak, &mut ep.enabled, &mut ep.int, v);
        self.kicked = true;
    }
}

/// A write of DIEPCTLx/DOEPCTLx: the kept bits, SNAK/CNAK on the NAK, EPDIS (EPDISD when it
/// was enabled), EPENA; SD0PID/SD1PID are not modelled (no data toggles). Returns whether SNAK
/// was set (an IN endpoint then says INEPNE).
fn ctl_write(ctl: &mut u32, nak: &mut bool, enabled: &mut bool, int: &mut u32, v: u32) -> bool {
    *ctl = v & CTL_KEPT;
    if v & SNAK != 0 {
        *nak = true;
    }
    if v & CNAK != 0 {
        *nak = false;
    }
    if v & EPDIS != 0 && *enabled {
        *enabled = false;
        *int |= EPDISD;
    }
    if v & EPENA != 0 {
        *enabled = true;
    }
    let _ = (SD0PID, SD1PID);
    v & SNAK != 0
}

/// EP0's MPSIZ code (DIEPCTL0/DOEPCTL0 bits 1:0): 64, 32, 16, 8 bytes.
fn ep0_mps(code: u32) -> u32 {
    [64, 32, 16, 8][(code & 3) as usize]
}

mod bus;
