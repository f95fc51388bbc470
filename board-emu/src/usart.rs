//! USART1, the TFT header (PA9 TX, PA10 RX), as the host's port: bytes leave and arrive at the
//! pace of the programmed baud rate (RM0090 §30, "Universal synchronous asynchronous receiver
//! transmitter").
//!
//! Registers (RM0090 §30.6, table 145 "USART register map and reset values"): SR 0x00 (PE 0,
//! FE 1, NF 2, ORE 3, IDLE 4, RXNE 5, TC 6, TXE 7; §30.6.1), DR 0x04 (§30.6.2), BRR 0x08
//! (§30.6.3: with OVER8 = 0, baud = fPCLK / USARTDIV and BRR holds USARTDIV in 12.4 fixed
//! point, so one bit lasts BRR PCLK2 cycles), CR1 0x0C (RE 2, TE 3, IDLEIE 4, RXNEIE 5, TCIE 6,
//! TXEIE 7, M 12, UE 13, OVER8 15; §30.6.4), CR2 0x10, CR3 0x14 (EIE 0, DMAR 6, DMAT 7), GTPR
//! 0x18. Flag clearing (§30.6.1): RXNE by a read of DR; ORE, IDLE, NF, FE, PE by a read of SR
//! followed by a read of DR; TC by a write of DR after a read of SR (or by writing 0 to it).
//!
//! Transmission (§30.3.2): a write of DR goes to the shift register at once when it is empty
//! (TXE stays set), otherwise waits in TDR (TXE clear); a frame is 1 start + 8 data + 1 stop
//! bit; TC sets when the last frame ends with TDR empty. Reception (§30.3.3): a byte completes
//! one frame after the host started it; a byte completing while RXNE is still set is lost and
//! sets ORE ("the RDR register content will not be lost but the shift register will be
//! overwritten"). IDLE sets one frame of silence after the last byte. Not modelled: parity,
//! 9-bit words, the fractional divider's exact rounding, DMA, LIN/IrDA/smartcard, noise.

use crate::time::{Cyc, CPU_HZ, PCLK2_HZ};
use std::collections::VecDeque;

const SR_ORE: u32 = 1 << 3;
const SR_IDLE: u32 = 1 << 4;
const SR_RXNE: u32 = 1 << 5;
const SR_TC: u32 = 1 << 6;
const SR_TXE: u32 = 1 << 7;

/// The USART and both ends of its line.
#[derive(Clone, Debug, Default)]
pub struct Usart {
    sr_flags: u32,
    dr_rx: u8,
    brr: u32,
    cr1: u32,
    cr2: u32,
    cr3: u32,
    gtpr: u32,
    tdr: Option<u8>,
    /// The frame in the shift register and when it ends.
    shifting: Option<(u8, Cyc)>,
    /// An SR read happened (for the SR-then-DR clearing sequences).
    sr_read: bool,
    /// Bytes the host has put on the line and not yet sent.
    pub host_tx: VecDeque<u8>,
    /// The frame arriving now and when it completes.
    arriving: Option<(u8, Cyc)>,
    /// When the line goes idle (IDLE flag) after the last received byte.
    idle_at: Option<Cyc>,
    /// When the last received frame ended.
    arrival_end: Cyc,
    /// Every byte the board sent, with the time its stop bit ended.
    pub tx_log: Vec<(Cyc, u8)>,
    /// Bytes lost to overrun.
    pub overruns: u64,
}

impl Usart {
    /// Back to the reset state; the host's queue stays (it is the host's).
    pub fn reset(&mut self) {
        let host_tx = std::mem::take(&mut self.host_tx);
        let tx_log = std::mem::take(&mut self.tx_log);
        let overruns = self.overruns;
        *self = Usart {
            host_tx,
            tx_log,
            overruns,
            ..Default::default()
        };
    }

    fn enabled(&self) -> bool {
        self.cr1 & (1 << 13) != 0
    }

    /// CPU cycles per frame (10 bits of BRR PCLK2 cycles each); None until BRR is set.
    pub fn frame_cyc(&self) -> Option<Cyc> {
        if self.brr == 0 {
            return None;
        }
        let oversampling = if self.cr1 & (1 << 15) != 0 { 2 } else { 1 };
        let bit = u64::from(self.brr) * CPU_HZ / PCLK2_HZ / oversampling;
        Some(10 * bit.max(1))
    }

    /// The baud rate programmed, for reports.
    pub fn baud(&self) -> Option<u64> {
        self.frame_cyc().map(|f| 10 * CPU_HZ / f)
    }

    fn sr(&self) -> u32 {
        let mut v = self.sr_flags;
        if self.tdr.is_none() {
            v |= SR_TXE;
        }
        v
    }

    /// The interrupt line: an enabled flag set (CR1 TXEIE/TCIE/RXNEIE/IDLEIE; RXNEIE also
    /// covers ORE, §30.4 table 144).
    pub fn irq(&self) -> bool {
        let sr = self.sr();
        let cr1 = self.cr1;
        (cr1 & (1 << 7) != 0 && sr & SR_TXE != 0)
            || (cr1 & (1 << 6) != 0 && sr & SR_TC != 0)
            || (cr1 & (1 << 5) != 0 && sr & (SR_RXNE | SR_ORE) != 0)
            || (cr1 & (1 << 4) != 0 && sr & SR_IDLE != 0)
    }

    /// Moves the line forward to `now`: frames end, host bytes start and arrive.
    pub fn advance(&mut self, now: Cyc) {
        loop {
            let next = [
                self.shifting.map(|(_, t)| t),
                self.arriving.map(|(_, t)| t),
                self.idle_at,
            ]
            .into_iter()
            .flatten()
            .min();
            // A host byte starts as soon as the line is free and the receiver is on.
            if self.arriving.is_none() && self.enabled() && self.cr1 & 4 != 0 {
                if let (Some(&b), Some(f)) = (self.host_tx.front(), self.frame_cyc()) {
                    self.host_tx.pop_front();
                    // The host's next byte starts right after the previous one, or now.
                    self.arriving = Some((b, now.max(self.last_arrival_end()) + f));
                    continue;
                }
            }
            let Some(t) = next else { return };
            if t > now {
                return;
            }
            if self.shifting.is_some_and(|(_, e)| e == t) {
                if let Some((b, e)) = self.shifting.take() {
                    self.tx_log.push((e, b));
                }
                match (self.tdr.take(), self.frame_cyc()) {
                    (Some(b), Some(f)) => self.shifting = Some((b, t + f)),
                    _ => self.sr_flags |= SR_TC,
                }
            } else if self.arriving.is_some_and(|(_, e)| e == t) {
                if let Some((b, _)) = self.arriving.take() {
                    self.arrival_end = t;
                    if self.sr_flags & SR_RXNE != 0 {
                        self.sr_flags |= SR_ORE;
                        self.overruns += 1;
                    } else {
                        self.dr_rx = b;
                        self.sr_flags |= SR_RXNE;
                    }
                    self.idle_at = self.frame_cyc().map(|f| t + f);
                }
            } else if self.idle_at == Some(t) {
                self.idle_at = None;
                if self.arriving.is_none() {
                    self.sr_flags |= SR_IDLE;
                }
            }
        }
    }

    fn last_arrival_end(&self) -> Cyc {
        self.arrival_end
    }

    /// The next time something changes on the line.
    pub fn next_event(&self, now: Cyc) -> Option<Cyc> {
        let mut t = [
            self.shifting.map(|(_, t)| t),
            self.arriving.map(|(_, t)| t),
            self.idle_at,
        ]
        .into_iter()
        .flatten()
        .min();
        if self.arriving.is_none()
            && !self.host_tx.is_empty()
            && self.enabled()
            && self.cr1 & 4 != 0
        {
            t = Some(t.map_or(now, |x| x.min(now)));
        }
        t
    }

    /// A register's value as a read would return it, without the read's side effects (what
    /// a sub-word store merges its bytes with: a store reads nothing, so it must not clear
    /// RXNE or take the received byte, as a DR read does).
    pub fn peek(&self, off: u32) -> u32 {
        match off {
            0x00 => self.sr(),
            0x04 => u32::from(self.dr_rx),
            0x08 => self.brr,
            0x0C => self.cr1,
            0x10 => self.cr2,
            0x14 => self.cr3,
            0x18 => self.gtpr,
            _ => 0,
        }
    }

    /// A register read.
    pub fn read(&mut self, off: u32, now: Cyc) -> u32 {
        self.advance(now);
        match off {
            0x00 => {
                self.sr_read = true;
                self.sr()
            }
            0x04 => {
                let v = u32::from(self.dr_rx);
                self.sr_flags &= !SR_RXNE;
                if self.sr_read {
                    self.sr_flags &= !(SR_ORE | SR_IDLE | 0x7);
                }
                self.sr_read = false;
                v
            }
            _ => self.peek(off),
        }
    }

    /// A register write.
    pub fn write(&mut self, off: u32, v: u32, now: Cyc) {
        self.advance(now);
        match off {
            // SR: only RXNE and TC can be cleared by writing 0 (rc_w0).
            0x00 => self.sr_flags &= v | !(SR_RXNE | SR_TC),
            0x04 => {
                if self.sr_read {
                    self.sr_flags &= !SR_TC;
                }
                self.sr_read = false;
                if !self.enabled() || self.cr1 & 8 == 0 {
                    return;
                }
                let b = v as u8;
                match (self.shifting, self.frame_cyc()) {
                    (None, Some(f)) => {
                        self.shifting = Some((b, now + f));
                        self.sr_flags &= !SR_TC;
                    }
                    (Some(_), _) => self.tdr = Some(b),
                    (None, None) => {}
                }
            }
            0x08 => self.brr = v & 0xFFFF,
            0x0C => {
                let was_te = self.cr1 & 8 != 0;
                self.cr1 = v & 0xBFFF;
                // TE set: the idle frame, then TC (RM0090 §30.3.2: "TC … is set after the idle
                // frame"); modelled as TC set at once.
                if !was_te && self.cr1 & 8 != 0 && self.shifting.is_none() {
                    self.sr_flags |= SR_TC;
                }
            }
            0x10 => self.cr2 = v,
            0x14 => self.cr3 = v,
            0x18 => self.gtpr = v,
            _ => {}
        }
    }
}
