//! The micro-SD slot: the SDIO host controller (RM0090 §31), DMA2 stream 3 that moves its data
//! (RM0090 §10), and an SDHC card answering from an image file (the FAT image `sim serve
//! --sd` builds, `sim::sd::write_image`).
//!
//! SDIO registers (RM0090 §31.9, table 174 "SDIO register map"): POWER 0x00 (PWRCTRL 1:0),
//! CLKCR 0x04 (CLKDIV 7:0: SDIO_CK = SDIOCLK / (CLKDIV + 2), BYPASS 10, WIDBUS 12:11;
//! §31.9.2), ARG 0x08, CMD 0x0C (CMDINDEX 5:0, WAITRESP 7:6: 00/10 none, 01 short, 11 long,
//! CPSMEN 10; §31.9.4), RESPCMD 0x10, RESP1..4 0x14..0x20 (a short response's card status in
//! RESP1; a long one's bits 127:0 in RESP1..RESP4; §31.9.6), DTIMER 0x24, DLEN 0x28, DCTRL
//! 0x2C (DTEN 0, DTDIR 1, DTMODE 2, DMAEN 3, DBLOCKSIZE 7:4; §31.9.9), DCOUNT 0x30, STA 0x34
//! (CCRCFAIL 0, DCRCFAIL 1, CTIMEOUT 2, DTIMEOUT 3, TXUNDERR 4, RXOVERR 5, CMDREND 6, CMDSENT
//! 7, DATAEND 8, STBITERR 9, DBCKEND 10, CMDACT 11, TXACT 12, RXACT 13; §31.9.11), ICR 0x38
//! (write 1 to clear, §31.9.12), MASK 0x3C (§31.9.13). A command takes 48 SDIO_CK cycles out
//! and, with a response, N_CR = 2 + 48 (136 for a long one) back (SD Physical Layer
//! Simplified Specification v9.10, §4.12.4 timings, simplified); a response to a command the
//! card does not answer is CTIMEOUT after 64 SDIO_CK cycles. R3 (ACMD41) has no valid CRC:
//! the controller reports CCRCFAIL, as RM0090 §31.4.4 says for R3.
//!
//! The card (SD Physical Layer Simplified Specification v9.10, §4.7.4 table 4-22 commands,
//! §4.9 responses, §5 registers): CMD0, CMD8 (R7 echoing the check pattern), CMD55 + ACMD41
//! (R3: OCR ready, CCS = 1: SDHC, block addressed), CMD2 (CID), CMD3 (R6, RCA 0x1234), CMD9
//! (CSD version 2.0 with C_SIZE from the image size), CMD7, CMD13 (R1, state `tran`), CMD16,
//! ACMD6, ACMD51 (SCR: 1- and 4-bit bus), ACMD13 (64 bytes of SD status), CMD6 (64 bytes,
//! function group 1 switched to 1 = SDR25), CMD17/CMD18 (blocks from the image), CMD12. The
//! data of a read goes out after N_AC = 100 SDIO_CK cycles, at 4 bits per clock on a 4-bit
//! bus (WIDBUS = 01), plus 17 clocks of CRC and end bit per block.
//!
//! DMA2 stream 3 (RM0090 §10.5, table 44 "DMA register map"): LISR 0x00 (stream 3: FEIF3 22,
//! DMEIF3 24, TEIF3 25, HTIF3 26, TCIF3 27; §10.5.1), LIFCR 0x08, S3CR 0x58 (EN 0, TCIE 4,
//! PFCTRL 5, DIR 7:6; §10.5.5), S3NDTR 0x5C, S3PAR 0x60, S3M0AR 0x64, S3FCR 0x6C. With
//! peripheral flow control the SDIO says when the transfer ends; the data is written to memory
//! at S3M0AR when the card's data ends (the CPU model applies [`Sdio::take_dma_writes`]
//! before the next instruction), then TCIF3 is set and EN cleared.
//!
//! Not modelled: writes to the card (the image only reads it), SDIO interrupts from the card,
//! the FIFO as registers (FIFOCNT/FIFO), 1-bit and 8-bit data timing differences beyond the
//! bus width, CRC errors, card removal while running, DMA streams other than 2/3.

use crate::time::{Cyc, CPU_HZ, SDIOCLK_HZ};
use std::collections::BTreeMap;

const STA_CCRCFAIL: u32 = 1 << 0;
const STA_CTIMEOUT: u32 = 1 << 2;
const STA_CMDREND: u32 = 1 << 6;
const STA_CMDSENT: u32 = 1 << 7;
const STA_DATAEND: u32 = 1 << 8;
const STA_DBCKEND: u32 = 1 << 10;
const STA_CMDACT: u32 = 1 << 11;
const STA_RXACT: u32 = 1 << 13;

/// The relative card address the card publishes.
const RCA: u32 = 0x1234;

/// A command in flight: when it completes and with what.
#[derive(Clone, Debug)]
struct CmdDone {
    at: Cyc,
    flags: u32,
    resp: [u32; 4],
    respcmd: u32,
    /// Data the command makes the card send, starting after the response.
    data: Option<Vec<u8>>,
}

/// SDIO + DMA2 stream 3 + the card.
#[derive(Default)]
pub struct Sdio {
    regs: BTreeMap<u32, u32>,
    sta: u32,
    mask: u32,
    resp: [u32; 4],
    respcmd: u32,
    cmd: Option<CmdDone>,
    /// Data on its way: when it ends, the bytes, where they go.
    data: Option<(Cyc, Vec<u8>)>,
    dma: BTreeMap<u32, u32>,
    lisr: u32,
    dma_writes: Vec<(u32, Vec<u8>)>,
    /// The card's image (None: no card in the slot).
    pub card: Option<Vec<u8>>,
    app_cmd: bool,
    /// Blocks read.
    pub blocks_read: u64,
    /// Commands the card did not know.
    pub unknown_cmds: Vec<u32>,
}

impl Sdio {
    /// A slot holding `card`.
    pub fn with_card(card: Option<Vec<u8>>) -> Self {
        Sdio {
            card,
            ..Default::default()
        }
    }

    /// Controller and DMA back to their reset state (the card stays).
    pub fn reset(&mut self) {
        let card = self.card.take();
        let blocks = self.blocks_read;
        *self = Sdio {
            card,
            blocks_read: blocks,
            ..Default::default()
        };
    }

    /// CPU cycles per SDIO_CK cycle.
    fn ck_cyc(&self) -> u64 {
        let clkcr = self.regs.get(&0x04).copied().unwrap_or(0);
        let div = if clkcr & (1 << 10) != 0 {
            1
        } else {
            u64::from(clkcr & 0xFF) + 2
        };
        (div * CPU_HZ / SDIOCLK_HZ).max(1)
    }

    fn bus_bits(&self) -> u64 {
        match (self.regs.get(&0x04).copied().unwrap_or(0) >> 11) & 3 {
            1 => 4,
            2 => 8,
            _ => 1,
        }
    }

    /// The card's answer to command `idx` with `arg`: (flags, response words, data).
    fn card_answer(&mut self, idx: u32, arg: u32, long: bool) -> (u32, [u32; 4], Option<Vec<u8>>) {
        let Some(card) = &self.card else {
            return (STA_CTIMEOUT, [0; 4], None);
        };
        let blocks = (card.len() / 512) as u64;
        let app = std::mem::take(&mut self.app_cmd);
        // R1 card status: READY_FOR_DATA (bit 8), CURRENT_STATE tran (4) in 12:9.
        let r1 = (4 << 9) | (1 << 8);
        let ok = |r: u32| (STA_CMDREND, [r, 0, 0, 0], None);
        let block = |card: &Vec<u8>, lba: u64| -> Vec<u8> {
            let o = (lba * 512) as usize;
            card.get(o..o + 512)
                .map(<[u8]>::to_vec)
                .unwrap_or_else(|| vec![0; 512])
        };
        match (app, idx) {
            (_, 0) => (STA_CMDSENT, [0; 4], None),
            (_, 8) => ok(arg & 0xFFF),
            (_, 55) => {
                self.app_cmd = true;
                ok(r1 | (1 << 5))
            }
            // OCR: power-up done (31), CCS (30), 2.7-3.6 V.
            (true, 41) => (STA_CCRCFAIL, [0xC0FF_8000, 0, 0, 0], None),
            (_, 2) if long => (
                STA_CMDREND,
                [0x0353_4445, 0x4D55_534B, 0x5232_1000, 0x0001_6A01],
                None,
            ),
            (_, 3) => ok(RCA << 16),
            (_, 9) if long => {
                // CSD 2.0: C_SIZE (bits 69:48) = size / 512 KiB - 1.
                let c_size = (blocks / 1024).saturating_sub(1) as u128;
                let csd: u128 = (1u128 << 126)
                    | (0x0E << 112)
                    | (0x32 << 96)
                    | (0x5B5 << 84)
                    | (9 << 80)
                    | (c_size << 48)
                    | (1 << 46)
                    | (0x7F << 39)
                    | (2 << 26)
                    | (9 << 22)
                    | 1;
                (
                    STA_CMDREND,
                    [
                        (csd >> 96) as u32,
                        (csd >> 64) as u32,
                        (csd >> 32) as u32,
                        csd as u32,
                    ],
                    None,
                )
            }
            (_, 7) | (false, 13) | (_, 16) | (_, 12) => ok(r1),
            (true, 6) => ok(r1),
            // SCR: structure 0, SD_SPEC 2, security SDHC, bus widths 1 and 4.
            (true, 51) => (
                STA_CMDREND,
                [r1, 0, 0, 0],
                Some(vec![0x02, 0x35, 0x80, 0, 0, 0, 0, 0]),
            ),
            (true, 13) => (STA_CMDREND, [r1, 0, 0, 0], Some(vec![0; 64])),
            (false, 6) => {
                let mut d = vec![0u8; 64];
                d[16] = 0x01;
                (STA_CMDREND, [r1, 0, 0, 0], Some(d))
            }
            (_, 17) => {
                self.blocks_read += 1;
                (
                    STA_CMDREND,
                    [r1, 0, 0, 0],
                    Some(block(card, u64::from(arg))),
                )
            }
            (_, 18) => {
                let dlen = self.regs.get(&0x28).copied().unwrap_or(512) as u64;
                let n = dlen.div_ceil(512);
                let mut d = Vec::new();
                for i in 0..n {
                    d.extend(block(card, u64::from(arg) + i));
                }
                self.blocks_read += n;
                (STA_CMDREND, [r1, 0, 0, 0], Some(d))
            }
            _ => {
                self.unknown_cmds.push(idx);
                (STA_CTIMEOUT, [0; 4], None)
            }
        }
    }

    /// Completes commands and data transfers due by `now`. `dma`: the CPU model is between
    /// instructions and applies DMA writes now (a data end waits for that).
    pub fn advance_with(&mut self, now: Cyc, dma: bool) {
        if let Some(c) = self.cmd.take_if(|c| c.at <= now) {
            self.sta = (self.sta & !STA_CMDACT) | c.flags;
            self.resp = c.resp;
            self.respcmd = c.respcmd;
            if let Some(d) = c.data {
                let ck = self.ck_cyc();
                let bits = self.bus_bits();
                let blocks = (d.len() as u64).div_ceil(512).max(1);
                let clocks = 100 + (d.len() as u64) * 8 / bits + 17 * blocks;
                self.sta |= STA_RXACT;
                self.data = Some((c.at + clocks * ck, d));
            }
        }
        if dma {
            if let Some((_, d)) = self.data.take_if(|(t, _)| *t <= now) {
                let dctrl = self.regs.get(&0x2C).copied().unwrap_or(0);
                let s3cr = self.dma.get(&0x58).copied().unwrap_or(0);
                let dlen = self.regs.get(&0x28).copied().unwrap_or(0) as usize;
                if dctrl & 1 != 0 && dctrl & 2 != 0 {
                    if dctrl & 8 != 0 && s3cr & 1 != 0 {
                        let m0 = self.dma.get(&0x64).copied().unwrap_or(0);
                        let n = dlen.min(d.len());
                        self.dma_writes.push((m0, d[..n].to_vec()));
                        self.dma.insert(0x58, s3cr & !1);
                        self.lisr |= 1 << 27;
                    }
                    self.sta = (self.sta & !STA_RXACT) | STA_DATAEND | STA_DBCKEND;
                } else {
                    self.sta &= !STA_RXACT;
                }
            }
        }
    }

    /// Completes what is due, without DMA (from a register access).
    pub fn advance(&mut self, now: Cyc) {
        self.advance_with(now, false);
    }

    /// DMA writes to apply to memory.
    pub fn take_dma_writes(&mut self) -> Vec<(u32, Vec<u8>)> {
        std::mem::take(&mut self.dma_writes)
    }

    /// The next completion.
    pub fn next_event(&self) -> Option<Cyc> {
        [
            self.cmd.as_ref().map(|c| c.at),
            self.data.as_ref().map(|d| d.0),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// SDIO interrupt line.
    pub fn irq(&self) -> bool {
        self.sta & self.mask & 0x3F_FFFF != 0
    }

    /// DMA2 stream 3 interrupt line (TCIE with TCIF3, TEIE with TEIF3).
    pub fn dma_irq(&self) -> bool {
        let cr = self.dma.get(&0x58).copied().unwrap_or(0);
        (cr & (1 << 4) != 0 && self.lisr & (1 << 27) != 0)
            || (cr & (1 << 2) != 0 && self.lisr & (1 << 25) != 0)
    }

    /// SDIO register read.
    pub fn read(&mut self, off: u32, now: Cyc) -> u32 {
        self.advance(now);
        match off {
            0x10 => self.respcmd,
            0x14..=0x20 => self.resp[((off - 0x14) / 4) as usize],
            0x34 => self.sta,
            0x3C => self.mask,
            _ => self.regs.get(&off).copied().unwrap_or(0),
        }
    }

    /// SDIO register write.
    pub fn write(&mut self, off: u32, v: u32, now: Cyc) {
        self.advance(now);
        match off {
            0x38 => self.sta &= !(v & 0x00C0_07FF),
            0x3C => self.mask = v,
            0x0C => {
                self.regs.insert(off, v);
                if v & (1 << 10) == 0 {
                    return;
                }
                let idx = v & 0x3F;
                let waitresp = (v >> 6) & 3;
                let arg = self.regs.get(&0x08).copied().unwrap_or(0);
                let long = waitresp == 3;
                let ck = self.ck_cyc();
                let powered = self.regs.get(&0x00).copied().unwrap_or(0) & 3 == 3;
                let (flags, resp, data) = if powered {
                    self.card_answer(idx, arg, long)
                } else {
                    (STA_CTIMEOUT, [0; 4], None)
                };
                let (flags, clocks) = match (waitresp, flags) {
                    (0 | 2, _) => (STA_CMDSENT, 48),
                    (_, f) if f == STA_CTIMEOUT => (STA_CTIMEOUT, 48 + 64),
                    (_, STA_CMDSENT) => (STA_CTIMEOUT, 48 + 64),
                    (3, f) => (f, 48 + 2 + 136),
                    (_, f) => (f, 48 + 2 + 48),
                };
                self.sta |= STA_CMDACT;
                self.cmd = Some(CmdDone {
                    at: now + clocks * ck,
                    flags,
                    resp,
                    respcmd: idx,
                    data,
                });
            }
            _ => {
                self.regs.insert(off, v);
            }
        }
    }

    /// DMA2 register read.
    pub fn dma_read(&mut self, off: u32) -> u32 {
        match off {
            0x00 => self.lisr,
            _ => self.dma.get(&off).copied().unwrap_or(0),
        }
    }

    /// DMA2 register write.
    pub fn dma_write(&mut self, off: u32, v: u32, _now: Cyc) {
        match off {
            0x08 => self.lisr &= !v,
            _ => {
                self.dma.insert(off, v);
            }
        }
    }
}
