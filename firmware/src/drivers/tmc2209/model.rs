//! A register-level TMC2209 on its single-wire UART (datasheet §4: datagrams, IFCNT, IOIN
//! version 0x21): the model the driver's tests talk to, and what the emulated SKR 2
//! (`board-emu`) answers with on each driver's UART pin. CRCs are checked and made with the
//! `tmc2209` crate's own implementation (independent of [`super::crc8`]). Host builds only:
//! `cfg(test)` or the `tmc-model` feature (never in the board image).

use super::SingleWire;
use alloc::vec::Vec;

/// How the modelled driver behaves on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Behaviour {
    /// A healthy driver.
    Answers,
    /// No reply at all (unpowered, jumper missing, wrong pin).
    Silent,
    /// Replies with one bit flipped in the data.
    CorruptsReplies,
    /// Replies, but drops every write (as if each write's CRC failed on the line).
    DropsWrites,
    /// Replies cut after this many bytes.
    CutsReplies(usize),
}

/// A register-level TMC2209: parses datagrams, keeps registers, counts writes in IFCNT, answers
/// reads addressed to it.
pub struct Model {
    /// Its address on the line (MS1/MS2 pins; 0 on the SKR 2).
    pub addr: u8,
    /// How it behaves on the wire.
    pub behaviour: Behaviour,
    /// The registers, by address.
    pub regs: [u32; 128],
    /// IFCNT: successful writes, modulo 256.
    pub ifcnt: u8,
    /// Reply bytes not yet read by the master.
    pub reply: Vec<u8>,
    /// Every datagram seen on the line, for inspection.
    pub seen: Vec<Vec<u8>>,
}

impl Model {
    /// A driver at `addr` with its power-on register values.
    pub fn new(addr: u8, behaviour: Behaviour) -> Self {
        let mut regs = [0u32; 128];
        // Power-on values (datasheet): GCONF 0x41 (I_scale_analog, pdn_disable), GSTAT reset
        // flag, IOIN version 0x21, CHOPCONF 0x10000053.
        regs[0x00] = 0x41;
        regs[0x01] = 0x1;
        regs[0x06] = 0x21 << 24;
        regs[0x6C] = 0x1000_0053;
        Model {
            addr,
            behaviour,
            regs,
            ifcnt: 0,
            reply: Vec::new(),
            seen: Vec::new(),
        }
    }

    /// What a read of register `r` answers.
    pub fn read_reg(&self, r: u8) -> u32 {
        match r {
            0x02 => u32::from(self.ifcnt),
            // DRV_STATUS: CS_ACTUAL follows IRUN (moving), stealth bit from GCONF.
            0x6F => {
                let irun = (self.regs[0x10] >> 8) & 0x1F;
                let stealth = u32::from(self.regs[0x00] & 4 == 0);
                (irun << 16) | (stealth << 30)
            }
            // Write-only registers read as 0.
            0x10 | 0x11 | 0x13 => 0,
            _ => self.regs[usize::from(r & 0x7F)],
        }
    }
}

impl SingleWire for Model {
    fn send(&mut self, bytes: &[u8]) {
        self.seen.push(Vec::from(bytes));
        self.reply.clear();
        let Some((&crc, body)) = bytes.split_last() else {
            return;
        };
        if tmc2209::crc(body) != crc || body.first().map(|b| b & 0x0F) != Some(0x05) {
            return;
        }
        if body.get(1) != Some(&self.addr) {
            return;
        }
        match body.len() {
            7 if body[2] & 0x80 != 0 => {
                if self.behaviour == Behaviour::DropsWrites {
                    return;
                }
                let r = body[2] & 0x7F;
                let v = u32::from_be_bytes([body[3], body[4], body[5], body[6]]);
                match r {
                    0x01 => self.regs[1] &= !v, // write 1 to clear
                    0x02 | 0x06 | 0x6F => {}    // read-only
                    _ => self.regs[usize::from(r)] = v,
                }
                self.ifcnt = self.ifcnt.wrapping_add(1);
            }
            3 => {
                if self.behaviour == Behaviour::Silent {
                    return;
                }
                let r = body[2];
                let d = self.read_reg(r).to_be_bytes();
                let mut g = Vec::from([0x05, 0xFF, r, d[0], d[1], d[2], d[3]]);
                g.push(tmc2209::crc(&g));
                match self.behaviour {
                    Behaviour::CorruptsReplies => g[5] ^= 0x10,
                    Behaviour::CutsReplies(n) => g.truncate(n),
                    _ => {}
                }
                self.reply = g;
            }
            _ => {}
        }
    }

    fn receive(&mut self, buf: &mut [u8]) -> usize {
        let n = self.reply.len().min(buf.len());
        buf[..n].copy_from_slice(&self.reply[..n]);
        self.reply.drain(..n);
        n
    }
}
