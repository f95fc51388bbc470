//! The four TMC2209 driver modules on their single-wire UART pins (X PE0, Y PD3, Z PD0, E0 PC6,
//! docs/board.md): the bytes the image bit-bangs are decoded from the pin's edges at 19200 Bd
//! (Marlin's `TMC_BAUD_RATE`), datagrams are handed to the project's own register-level model
//! (`firmware::drivers::tmc2209::model::Model`, the one the driver's tests use), and the
//! model's reply is driven back on the pin, bit by bit, after the driver's SENDDELAY.
//!
//! The wire format (TMC2209 datasheet rev 1.09, §4.1 "UART Signals" and §4.1.1): 8N1 frames,
//! LSB first; a read request is 4 bytes (sync 0x05, address, register, CRC), a write 8
//! (sync, address, register | 0x80, 4 data bytes MSB first, CRC); the reply (8 bytes) starts
//! SENDDELAY bit times (default 8, SLAVECONF) after the request's last stop bit. A byte is
//! sampled at the middle of each bit from the start bit's falling edge; a frame whose stop bit
//! reads low is dropped (a framing error), as is a datagram not starting with sync.
//!
//! Each module also has its EN pin (X PE3, Y PD6, Z PD1, E0 PC7): a module seated the right
//! way pulls it up (the TMC2209 modules' EN pull-up; it reads high while the MCU leaves it an
//! input), a module plugged in backwards puts its GND pin there (it reads low) — what Marlin's
//! `stepper_driver_backward_check()` (`feature/stepper_driver_safety.cpp`) looks at before it
//! powers the drivers through SAFE_POWER. A backwards module does not answer on its UART.

use crate::gpio::{Gpio, Pin};
use crate::time::{Cyc, CPU_HZ};
use firmware::drivers::tmc2209::model::{Behaviour, Model};
use firmware::drivers::tmc2209::SingleWire;

/// UART pins X, Y, Z, E0.
pub const UART_PINS: [Pin; 4] = [
    Pin::new('E', 0),
    Pin::new('D', 3),
    Pin::new('D', 0),
    Pin::new('C', 6),
];

/// One bit at 19200 Bd, cycles.
pub const BIT_CYC: Cyc = CPU_HZ / 19_200;

/// How a module sits in its socket.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Seating {
    /// The right way round: answers, EN pulled up.
    Correct,
    /// Plugged in backwards: silent, EN reads low.
    Reversed,
}

/// One module and its line.
pub struct Module {
    /// The register model.
    pub model: Model,
    /// How it sits.
    pub seating: Seating,
    /// Level history of the frame being received: (time, level), from the start bit.
    frame: Vec<(Cyc, bool)>,
    /// When the frame being received is complete enough to decode (9.5 bits after its start).
    decode_at: Option<Cyc>,
    /// The datagram being assembled.
    datagram: Vec<u8>,
    /// Reply levels to drive: (time, level), in order; `None` releases the line.
    reply: std::collections::VecDeque<(Cyc, Option<bool>)>,
    /// Frames dropped (framing error) and datagrams not understood.
    pub bad_frames: u64,
    /// Datagrams taken.
    pub datagrams: u64,
}

impl Module {
    fn new(seating: Seating) -> Self {
        let behaviour = match seating {
            Seating::Correct => Behaviour::Answers,
            Seating::Reversed => Behaviour::Silent,
        };
        Module {
            model: Model::new(0, behaviour),
            seating,
            frame: Vec::new(),
            decode_at: None,
            datagram: Vec::new(),
            reply: Default::default(),
            bad_frames: 0,
            datagrams: 0,
        }
    }

    /// The level at `t` from the frame's history.
    fn level_at(&self, t: Cyc) -> bool {
        self.frame
            .iter()
            .take_while(|(te, _)| *te <= t)
            .last()
            .is_none_or(|(_, l)| *l)
    }
}

/// The four modules.
pub struct Drivers {
    /// X, Y, Z, E0.
    pub modules: [Module; 4],
}

impl Drivers {
    /// Four modules seated as given.
    pub fn new(seating: [Seating; 4]) -> Self {
        Drivers {
            modules: seating.map(Module::new),
        }
    }

    /// Power cycle (a board reset does not reset the modules, but SAFE_POWER off does):
    /// registers back to their power-on values.
    pub fn power_cycle(&mut self) {
        for m in &mut self.modules {
            *m = Module::new(m.seating);
        }
    }

    /// An edge on UART pin `i`, driven by the MCU.
    pub fn mcu_edge(&mut self, i: usize, t: Cyc, high: bool) {
        let m = &mut self.modules[i];
        if m.decode_at.is_none() {
            if !high {
                m.frame.clear();
                m.frame.push((t, false));
                m.decode_at = Some(t + BIT_CYC * 19 / 2);
            }
        } else {
            m.frame.push((t, high));
        }
    }

    /// The next decode or reply edge.
    pub fn next_event(&self) -> Option<Cyc> {
        self.modules
            .iter()
            .flat_map(|m| [m.decode_at, m.reply.front().map(|(t, _)| *t)])
            .flatten()
            .min()
    }

    /// Decodes frames and drives replies up to `now`; sets the pins' outside drive.
    pub fn advance(&mut self, now: Cyc, gpio: &mut Gpio) {
        for (i, m) in self.modules.iter_mut().enumerate() {
            let pin = UART_PINS[i];
            while let Some(&(t, level)) = m.reply.front() {
                if t > now {
                    break;
                }
                m.reply.pop_front();
                gpio.ext[usize::from(pin.port)][usize::from(pin.n)] = level;
            }
            let Some(t_dec) = m.decode_at else { continue };
            if t_dec > now {
                continue;
            }
            m.decode_at = None;
            let start = m.frame.first().map_or(t_dec, |(t, _)| *t);
            let mut byte = 0u8;
            for bit in 0..8 {
                if m.level_at(start + BIT_CYC * (2 * bit + 3) / 2) {
                    byte |= 1 << bit;
                }
            }
            let stop_ok = m.level_at(start + BIT_CYC * 19 / 2);
            let tail = m.frame.last().copied();
            m.frame.clear();
            if let Some((t_last, false)) = tail {
                // The line is low again after the stop bit: the next start bit began already.
                if t_last > start + BIT_CYC * 19 / 2 {
                    m.frame.push((t_last, false));
                    m.decode_at = Some(t_last + BIT_CYC * 19 / 2);
                }
            }
            if !stop_ok {
                m.bad_frames += 1;
                m.datagram.clear();
                continue;
            }
            if m.datagram.is_empty() && byte & 0x0F != 0x05 {
                m.bad_frames += 1;
                continue;
            }
            m.datagram.push(byte);
            let want = match m.datagram.get(2) {
                Some(r) if r & 0x80 != 0 => 8,
                Some(_) => 4,
                None => continue,
            };
            if m.datagram.len() < want {
                continue;
            }
            let dg = std::mem::take(&mut m.datagram);
            m.datagrams += 1;
            m.model.send(&dg);
            let mut reply = [0u8; 8];
            let n = m.model.receive(&mut reply);
            // The reply starts SENDDELAY (8 bit times) after the request's stop bit ended.
            let mut t = start + BIT_CYC * 10 + 8 * BIT_CYC;
            for &b in &reply[..n] {
                m.reply.push_back((t, Some(false)));
                for bit in 0..8 {
                    m.reply
                        .push_back((t + BIT_CYC * (bit + 1), Some(b & (1 << bit) != 0)));
                }
                m.reply.push_back((t + BIT_CYC * 9, Some(true)));
                t += BIT_CYC * 10;
            }
            if n > 0 {
                m.reply.push_back((t, None));
            }
        }
    }

    /// The EN pins' outside level while the MCU does not drive them (the reversed-driver
    /// check): high for a seated module, low for a backwards one.
    pub fn en_levels(&self) -> [bool; 4] {
        [0, 1, 2, 3].map(|i| self.modules[i].seating == Seating::Correct)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The TMC2209's CRC8 (datasheet §4.2), for checking the decoded reply.
    fn tmc2209_crc(bytes: &[u8]) -> u8 {
        firmware::drivers::tmc2209::crc8(bytes)
    }

    /// Bit-bangs `bytes` as the MCU would, returning the edges.
    fn wire(bytes: &[u8], t0: Cyc) -> Vec<(Cyc, bool)> {
        let mut out = Vec::new();
        let mut level = true;
        let mut t = t0;
        for &b in bytes {
            let bits = std::iter::once(false)
                .chain((0..8).map(|i| b & (1 << i) != 0))
                .chain(std::iter::once(true));
            for l in bits {
                if l != level {
                    out.push((t, l));
                    level = l;
                }
                t += BIT_CYC;
            }
        }
        out
    }

    #[test]
    fn a_read_request_gets_the_version() {
        let mut d = Drivers::new([Seating::Correct; 4]);
        let mut g = Gpio::default();
        let req = firmware::drivers::tmc2209::read_request(0, 0x06);
        let edges = wire(&req, 1000);
        for &(t, l) in &edges {
            d.advance(t, &mut g);
            d.mcu_edge(0, t, l);
        }
        // Follow the driven reply and decode it at mid-bit, as a UART would.
        let mut levels: Vec<(Cyc, bool)> = Vec::new();
        while let Some(t) = d.next_event() {
            d.advance(t, &mut g);
            if let Some(l) = g.ext[4][0] {
                levels.push((t, l));
            }
        }
        assert_eq!(d.modules[0].datagrams, 1);
        let level_at = |t: Cyc| {
            levels
                .iter()
                .take_while(|(e, _)| *e <= t)
                .last()
                .is_none_or(|x| x.1)
        };
        let start = levels.first().expect("a reply was driven").0;
        let mut reply = Vec::new();
        for k in 0..8u64 {
            let s0 = start + k * 10 * BIT_CYC;
            assert!(!level_at(s0 + BIT_CYC / 2), "start bit of byte {k}");
            let b = (0..8).fold(0u8, |b, i| {
                if level_at(s0 + BIT_CYC * (2 * i + 3) / 2) {
                    b | (1 << i)
                } else {
                    b
                }
            });
            reply.push(b);
        }
        // Sync, master address, register 0x06, IOIN with VERSION 0x21 in the top byte.
        assert_eq!(&reply[..4], &[0x05, 0xFF, 0x06, 0x21]);
        assert_eq!(reply[7], tmc2209_crc(&reply[..7]));
        assert_eq!(d.modules[0].bad_frames, 0);
    }
}
