//! GPIO ports A..E (RM0090 §8, "General-purpose I/Os"): the pin levels the board's models see,
//! and every edge, timestamped.
//!
//! Registers (RM0090 §8.4, table 39 "GPIO register map and reset values"): MODER 0x00 (2 bits
//! per pin: 00 input, 01 output, 10 alternate function, 11 analog; §8.4.1), OTYPER 0x04
//! (push-pull/open-drain, §8.4.2), OSPEEDR 0x08, PUPDR 0x0C (01 pull-up, 10 pull-down;
//! §8.4.4), IDR 0x10 (§8.4.5), ODR 0x14 (§8.4.6), BSRR 0x18 (BSy bits 15:0 set, BRy bits 31:16
//! reset, set wins; §8.4.7), LCKR 0x1C, AFRL/AFRH 0x20/0x24. Reset state (§8.4.1): every pin
//! an input (port A: PA13/14/15 and port B: PB3/PB4 are the debug pins in AF at reset; the
//! image reconfigures the ones it uses, so the model starts all as inputs).
//!
//! A pin's level: an output drives its ODR bit (open-drain: only low; high comes from the pull
//! or the outside); an input (or analog, or alternate function) is driven from outside (a
//! model of the board: endstop switch, driver module, TMC2209 UART reply) or else by its pull
//! resistor, or else by the board's own resistor (`board_pull`). Not modelled: the alternate
//! functions' own drive (USART1 TX, TIM4 PWM and SDIO pins are served by their peripheral
//! models directly), speeds, the lock register, EXTI edge detection.

use crate::time::Cyc;

/// Ports modelled: A, B, C, D, E (the LQFP100 package has no F..I).
pub const PORTS: usize = 5;

/// A pin: port (0 = A) and number.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Pin {
    /// Port index, 0 = A.
    pub port: u8,
    /// Pin number 0..15.
    pub n: u8,
}

impl Pin {
    /// `Pin::new('E', 2)` = PE2.
    pub const fn new(port: char, n: u8) -> Pin {
        Pin {
            port: port as u8 - b'A',
            n,
        }
    }
}

impl std::fmt::Display for Pin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "P{}{}", (b'A' + self.port) as char, self.n)
    }
}

/// A level change seen on a pin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Edge {
    /// When.
    pub t: Cyc,
    /// Which pin.
    pub pin: Pin,
    /// The new level.
    pub high: bool,
}

/// One port's registers.
#[derive(Clone, Debug, Default)]
struct Port {
    moder: u32,
    otyper: u32,
    ospeedr: u32,
    pupdr: u32,
    odr: u32,
    lckr: u32,
    afr: [u32; 2],
}

/// The five ports and the outside world's drive on them.
#[derive(Clone, Debug)]
pub struct Gpio {
    ports: [Port; PORTS],
    /// Driven from outside (None: not driven).
    pub ext: [[Option<bool>; 16]; PORTS],
    /// The board's own pull resistors (level of a floating input): None = floating, read low.
    pub board_pull: [[Option<bool>; 16]; PORTS],
    levels: [u16; PORTS],
}

impl Default for Gpio {
    fn default() -> Self {
        Gpio {
            ports: Default::default(),
            ext: [[None; 16]; PORTS],
            board_pull: [[None; 16]; PORTS],
            levels: [0; PORTS],
        }
    }
}

impl Gpio {
    /// Back to the reset state (RM0090 §8.4: every register at its reset value); the outside
    /// drive and the board's resistors stay.
    pub fn reset(&mut self) {
        self.ports = Default::default();
    }

    /// MODER of `pin`: 0 input, 1 output, 2 alternate, 3 analog.
    pub fn mode(&self, pin: Pin) -> u32 {
        (self.ports[usize::from(pin.port)].moder >> (2 * pin.n)) & 3
    }

    /// The pin is a push-pull or open-drain output.
    pub fn is_output(&self, pin: Pin) -> bool {
        self.mode(pin) == 1
    }

    /// The level of `pin` now.
    pub fn level(&self, pin: Pin) -> bool {
        let p = &self.ports[usize::from(pin.port)];
        let bit = 1u32 << pin.n;
        let outside = || {
            self.ext[usize::from(pin.port)][usize::from(pin.n)].unwrap_or_else(|| {
                match (p.pupdr >> (2 * pin.n)) & 3 {
                    1 => true,
                    2 => false,
                    _ => {
                        self.board_pull[usize::from(pin.port)][usize::from(pin.n)].unwrap_or(false)
                    }
                }
            })
        };
        match self.mode(pin) {
            1 if p.otyper & bit == 0 => p.odr & bit != 0,
            1 => p.odr & bit != 0 && outside(),
            _ => outside(),
        }
    }

    fn port_levels(&self, port: usize) -> u16 {
        (0..16).fold(0, |acc, n| {
            if self.level(Pin {
                port: port as u8,
                n,
            }) {
                acc | (1 << n)
            } else {
                acc
            }
        })
    }

    /// Re-evaluates every pin and appends the edges since the last evaluation at time `t`.
    pub fn sample(&mut self, t: Cyc, edges: &mut Vec<Edge>) {
        for port in 0..PORTS {
            let now = self.port_levels(port);
            let changed = now ^ self.levels[port];
            if changed != 0 {
                for n in 0..16u8 {
                    if changed & (1 << n) != 0 {
                        edges.push(Edge {
                            t,
                            pin: Pin {
                                port: port as u8,
                                n,
                            },
                            high: now & (1 << n) != 0,
                        });
                    }
                }
                self.levels[port] = now;
            }
        }
    }

    /// Re-evaluates one port only (after a write to it).
    pub fn sample_port(&mut self, port: usize, t: Cyc, edges: &mut Vec<Edge>) {
        let now = self.port_levels(port);
        let changed = now ^ self.levels[port];
        for n in 0..16u8 {
            if changed & (1 << n) != 0 {
                edges.push(Edge {
                    t,
                    pin: Pin {
                        port: port as u8,
                        n,
                    },
                    high: now & (1 << n) != 0,
                });
            }
        }
        self.levels[port] = now;
    }

    /// A register read (`off` within the port's 1 KiB block).
    pub fn read(&self, port: usize, off: u32) -> u32 {
        let p = &self.ports[port];
        match off {
            0x00 => p.moder,
            0x04 => p.otyper,
            0x08 => p.ospeedr,
            0x0C => p.pupdr,
            0x10 => u32::from(self.port_levels(port)),
            0x14 => p.odr,
            0x18 => 0,
            0x1C => p.lckr,
            0x20 => p.afr[0],
            0x24 => p.afr[1],
            _ => 0,
        }
    }

    /// A register write; the edges it makes are appended to `edges`.
    pub fn write(&mut self, port: usize, off: u32, v: u32, t: Cyc, edges: &mut Vec<Edge>) {
        let p = &mut self.ports[port];
        match off {
            0x00 => p.moder = v,
            0x04 => p.otyper = v & 0xFFFF,
            0x08 => p.ospeedr = v,
            0x0C => p.pupdr = v,
            0x14 => p.odr = v & 0xFFFF,
            // BSRR: set bits 15:0, reset bits 31:16; "if both BSx and BRx are set, BSx has
            // priority".
            0x18 => p.odr = (p.odr & !(v >> 16)) | (v & 0xFFFF),
            0x1C => p.lckr = v,
            0x20 => p.afr[0] = v,
            0x24 => p.afr[1] = v,
            _ => {}
        }
        self.sample_port(port, t, edges);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bsrr_edges_and_inputs() {
        let mut g = Gpio::default();
        let mut e = Vec::new();
        let pe2 = Pin::new('E', 2);
        g.write(4, 0x00, 1 << 4, 10, &mut e); // PE2 output
        g.write(4, 0x18, 1 << 2, 20, &mut e);
        g.write(4, 0x18, 1 << 18, 30, &mut e);
        assert_eq!(
            e,
            vec![
                Edge {
                    t: 20,
                    pin: pe2,
                    high: true
                },
                Edge {
                    t: 30,
                    pin: pe2,
                    high: false
                }
            ]
        );
        // PC1 input with pull-up, driven low from outside.
        let pc1 = Pin::new('C', 1);
        g.write(2, 0x0C, 1 << 2, 40, &mut e);
        assert!(g.level(pc1));
        g.ext[2][1] = Some(false);
        assert!(!g.level(pc1));
        assert_eq!(g.read(2, 0x10) & 2, 0);
    }
}
